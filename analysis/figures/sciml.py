"""SciMLBenchmarks' rigid-body work-precision diagram: gyrolab's methods beside scipy's solvers.

SciMLBenchmarks (docs.sciml.ai, NonStiffODE/RigidBody_wpd) integrate Euler's
equations of a driven free body, ω̇1 = −2 ω2 ω3, ω̇2 = 1.25 ω1 ω3,
ω̇3 = −0.5 ω1 ω2 + 0.25 sin² t, ω(0) = (1, 0, 0.9), t ∈ [0, 10], and chart the
error at t = 10 against the time each solver takes, its solvers at
abstol = 1e-6 … 1e-13 with reltol = 1e-3 … 1e-10 (paired), against a Vern7
reference at 1e-14.  Here (``gyrolab experiment=sciml_rigid_body``, the
scene forced_body with ``window: [0, 10]``):

- gyrolab's methods: one point per stored dt, error |ω(t_end) − ω_ref(t_end)|
  (Euclidean norm, rad/s) read from the file, time re-measured for this figure
  (one run alone on one thread after JIT warm-up, best of ``repeats``:
  work_precision.time_method), or the stored wall_time with ``retime=False``;
- peers: scipy's DOP853, RK45, Radau and LSODA on the same three equations
  (the state is ω alone, as SciML's; a free body's ω does not depend on its
  orientation; a body with gravity: the (ω, R) equations of
  kernels/reference.py) at SciML's tolerance pairs, timed alike (best of
  ``repeats``);
- reference, with its own error: for a body without gravity (SciML's) the
  extended-precision Taylor series of kernels/reference.py (error ~2e-16 rad/s,
  tests/test_forced_body.py pins it to a 30-digit ω(10)); with gravity DOP853
  on (ω, R) at rtol = atol = 1e-13 with |y(tol) − y(10 tol)| as its error.  An
  error below the reference's own reads "≤ reference" in the table and is drawn
  on the dotted line in the figure.

    python -m gyrolab.analysis.figures.sciml RESULTS.h5 -o docs/sciml_rigid_body.md \\
        --png docs/sciml_rigid_body_work_precision.png

writes the table (every point of the figure) and the figure.
"""

import argparse
import math
import sys
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ...results import open_results
from ...results.layout import GRID_DIMS
from ...safe_files import write_text
from ..io import SelectionError, build_run_scene, color, marker, scene_label, select
from .record import add_note, legend_below, load_text, machine_load, run_title, select_note, suptitle

METHOD_DIM = GRID_DIMS[0]
# SciMLBenchmarks RigidBody_wpd: abstols = 1 ./ 10 .^ (6:13), reltols = 1 ./ 10 .^ (3:10), paired.
TOLERANCES = tuple((10.0 ** -(6 + k), 10.0 ** -(3 + k)) for k in range(8))
PEERS = ("DOP853", "RK45", "Radau", "LSODA")
REPEATS = 7  # timing repeats per point, best kept: what docs/sciml_rigid_body.md says it took
REFERENCE_TOL = 1e-13


def omega_rhs(t, w, I1, I2, I3, tau1, tau2, tau3, rate, on, off):
    """ω̇ (rad/s²) of a free body under the body-frame drive (kernels/body.py): the SciML form."""
    drive = math.sin(rate * t) ** 2 if on <= t <= off else 0.0
    return (
        ((I2 - I3) * w[1] * w[2] + tau1 * drive) / I1,
        ((I3 - I1) * w[2] * w[0] + tau2 * drive) / I2,
        ((I1 - I2) * w[0] * w[1] + tau3 * drive) / I3,
    )


def _system(scene):
    """(rhs, y0, args) the peers solve: SciML's three equations in ω for a body without gravity (its ω
    does not depend on the orientation), else kernels/reference.py's (ω, R) equations; ω is y[:3]."""
    b = scene.body
    w0 = np.asarray(scene.omega0, dtype=float)
    if not (b.mgl or b.mgc1 or b.mgc2):
        return omega_rhs, w0, (b.I1, b.I2, b.I3, b.tau1, b.tau2, b.tau3, b.drive_rate, b.drive_on, b.drive_off)
    from ...kernels.closed_form import scene_rotation
    from ...kernels.reference import rhs

    y0 = np.concatenate((w0, scene_rotation(scene).as_matrix().ravel()))
    return rhs, y0, tuple(float(v) for v in b)


def best_time(call, repeats):
    """(best wall time (s) of ``repeats`` calls, the last call's result)."""
    best, result = math.inf, None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = call()
        best = min(best, time.perf_counter() - start)
    return best, result


def peer_points(scene, t_end, ref, solver, repeats=REPEATS, tolerances=TOLERANCES):
    """[(abstol, reltol, seconds, rhs evaluations, error)] of scipy ``solver`` on the scene (``_system``);
    a tolerance the solver fails at is left out."""
    from scipy.integrate import solve_ivp

    fun, y0, args = _system(scene)
    out = []
    for atol, rtol in tolerances:

        def solve():
            return solve_ivp(fun, (0.0, t_end), y0, method=solver, rtol=rtol, atol=atol, args=args)

        seconds, sol = best_time(solve, repeats)
        if sol.success:
            out.append((atol, rtol, seconds, int(sol.nfev), float(np.linalg.norm(sol.y[:3, -1] - ref))))
    return out


def reference_omega(scene, t_end):
    """(ω(t_end) (rad/s), its own error estimate (rad/s), label): for a body without gravity (SciML's)
    kernels/reference.py's extended-precision Taylor series (error ~2e-16), else DOP853 at rtol = atol =
    REFERENCE_TOL with |y(tol) − y(10 tol)| as its error."""
    from ...kernels.reference import dop853_with_error, free_omega_reference

    b = scene.body
    if not (b.mgl or b.mgc1 or b.mgc2):
        return free_omega_reference(b, scene.omega0, t_end)
    y, err = dop853_with_error(scene, t_end, t_end, tol=REFERENCE_TOL)
    e = float(err[-1, 3:6].max())
    return y[-1, 3:6], e, f"DOP853 (rtol = atol = {REFERENCE_TOL:g}; its error ≤ {e:.1e} rad/s)"


def fmt_error(error, ref_error):
    """An error (rad/s) as a table shows it: '≤ reference' below the reference's own error."""
    if not math.isfinite(error):
        return "diverged"
    return f"≤ reference ({ref_error:.1e})" if error <= ref_error else f"{error:.2g}"


def sciml_data(ds, sel=None, retime=True, peers=PEERS, repeats=REPEATS, tolerances=TOLERANCES):
    """{"t_end", "f", "theta0", "reference", "methods": {m: [(dt, seconds, steps, error)]},
    "peers": {solver: [...]}, "note"} for one (f, θ0) of the selection (the first; ``note`` says how to
    draw the others).  Errors in rad/s; a diverged run has error inf."""
    from .work_precision import time_method

    whole = select(ds, sel)
    fs, thetas = list(whole.f.values), list(whole.theta0.values)
    f, theta0 = float(fs[0]), float(thetas[0])
    note = select_note("sciml", {"f": fs[:1], "theta0": thetas[:1]}, {"f": fs[1:], "theta0": thetas[1:]})
    sub = whole.sel(f=[f], theta0=[theta0])
    scene = build_run_scene(sub, f, theta0)
    t_end, every = float(sub.time[-1]), float(sub.time[1] - sub.time[0])
    ref, ref_error, ref_label = reference_omega(scene, t_end)
    loads = [machine_load()]  # the load the timing ran under, at its start and its end
    methods = {}
    for m in sub[METHOD_DIM].values:
        pts = []
        for dt in sorted(float(v) for v in sub.dt.values):
            run = sub.sel({METHOD_DIM: m, "f": f, "theta0": theta0, "dt": dt})
            final = run.omega.isel(time=-1).values
            ok = int(run.status) == 0 and np.all(np.isfinite(final))
            error = float(np.linalg.norm(final - ref)) if ok else math.inf
            seconds = time_method(str(m), scene, dt, t_end, every, repeats) if retime and ok else float(run.wall_time)
            pts.append((dt, seconds, int(run.n_steps), error))
        methods[str(m)] = pts
    peer = {}
    for name in peers:
        # a progress line per solver: on a fast spin (a 50 Hz heavy top over 1 s: 10.5 min in all, measured)
        # nothing else said that the figure was still being made
        start = time.perf_counter()
        print(
            f"sciml figure: scipy {name} at {len(tolerances)} tolerance pairs, best of {repeats} each ...",
            end="",
            file=sys.stderr,
            flush=True,
        )
        peer[name] = peer_points(scene, t_end, ref, name, repeats, tolerances)
        print(f" {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    loads.append(machine_load())
    return {
        "load": loads,
        "t_end": t_end,
        "f": f,
        "theta0": theta0,
        "reference": ref,
        "reference_error": ref_error,
        "reference_label": ref_label,
        "repeats": repeats,
        "retimed": retime,
        "methods": methods,
        "peers": peer,
        "note": note,
        "equations": "ω" if _system(scene)[0] is omega_rhs else "(ω, R)",
    }


def sciml_figure(ds, sel=None, retime=True, peers=PEERS, repeats=REPEATS, data=None):
    """Time (s) against the error at t_end (rad/s), log-log: one line per gyrolab method across dt
    (solid) and per scipy solver across SciML's tolerance pairs (dashed)."""
    data = data if data is not None else sciml_data(ds, sel, retime=retime, peers=peers, repeats=repeats)
    fig, ax = plt.subplots(figsize=(8.2, 6.2))
    floor = data["reference_error"]  # an error below the reference's own is drawn on this line
    ax.axvline(floor, color="0.4", ls=":", lw=1.0)
    # x is inverted: ha="right" keeps the label inside the axes, on the side of the larger errors
    ax.text(floor, 0.99, "≤ reference ", transform=ax.get_xaxis_transform(), fontsize=7, va="top", ha="right")
    for m, pts in data["methods"].items():
        ok = [p for p in pts if math.isfinite(p[3])]
        if ok:
            xs, ys = [max(p[3], floor) for p in ok], [p[1] for p in ok]
            ax.plot(xs, ys, "-", marker=marker(m), color=color(m), ms=4, label=m)
        if len(ok) < len(pts):
            ax.plot([], [], "x", color=color(m), label=f"{m}: {len(pts) - len(ok)} dt diverged")
    for name, pts in data["peers"].items():
        if pts:
            ax.plot(
                [max(p[4], floor) for p in pts],
                [p[2] for p in pts],
                "s--",
                color=color(name),
                ms=4,
                mfc="none",
                label=f"scipy {name}",
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.invert_xaxis()  # more accurate to the right, as one reads a work-precision diagram
    ax.set_xlabel(f"error |ω(t) − ω_ref(t)| at t = {data['t_end']:g} s (rad/s)")
    ax.set_title(run_title(ds, data["f"], data["theta0"]), fontsize=9)
    ax.set_ylabel("time (s)")
    ax.grid(alpha=0.3, which="both")
    dts = sorted({p[0] for pts in data["methods"].values() for p in pts})
    ours = "one thread after JIT warm-up" if data["retimed"] else "gyrolab's: the stored wall_time"
    timing = f"best of {data['repeats']}, {ours}, {load_text(data.get('load', ()))}"
    suptitle(
        fig,
        f"Work-precision at t_end, SciMLBenchmarks' rigid-body form: {scene_label(ds)}\n"
        f"gyrolab: one point per dt = {dts[0]:g} … {dts[-1]:g} s; scipy: abstol 1e-6 … 1e-13 with "
        f"reltol 1e-3 … 1e-10; reference: {data['reference_label']}",
        fontsize=9.5,
    )
    fig.tight_layout()
    peers = "ω alone (SciML's three equations)" if data["equations"] == "ω" else "(ω, R) (kernels/reference.py)"
    add_note(
        fig,
        f"times: {timing}; gyrolab integrates (ω, q) compiled (numba) and stores its samples; scipy "
        f"integrates {peers} and pays Python's cost per RHS evaluation, so read absolute times within "
        "a family and slopes across",
    )
    add_note(fig, data["note"])
    handles, labels = ax.get_legend_handles_labels()
    legend_below(fig, handles, labels, ncol=4)
    return fig


def table(data):
    """Markdown: every point of the figure (gyrolab per dt, scipy per tolerance pair)."""
    ref = ", ".join(f"{v:.15g}" for v in data["reference"])
    lines = [
        f"Reference ω({data['t_end']:g} s) = ({ref}) rad/s: {data['reference_label']}; an error below "
        "the reference's own reads '≤ reference'.",
        "",
        "| solver | setting | error at t_end (rad/s) | time (s) | steps / RHS evaluations |",
        "|---|---|---:|---:|---:|",
    ]
    for m, pts in data["methods"].items():
        for dt, seconds, steps, error in pts:
            err = fmt_error(error, data["reference_error"])
            lines.append(f"| `{m}` | dt = {dt:g} s | {err} | {seconds:.3g} | {steps} steps |")
    for name, pts in data["peers"].items():
        for atol, rtol, seconds, nfev, error in pts:
            lines.append(
                f"| scipy {name} | abstol {atol:.0e}, reltol {rtol:.0e} | {fmt_error(error, data['reference_error'])} "
                f"| {seconds:.3g} | {nfev} RHS |"
            )
    return "\n".join(lines)


def _make_figure():
    from .record import Figure

    return Figure(
        "sciml",
        "SciMLBenchmarks' rigid-body work-precision: error at t_end vs time, scipy solvers as peers",
        lambda ds, sel=None, no_retime=False, no_peers=False, repeats=REPEATS: sciml_figure(
            ds, sel, retime=not no_retime, peers=() if no_peers else PEERS, repeats=repeats
        ),
        {
            "--no-retime": {"action": "store_true", "help": "use the stored wall_time (no re-timing)"},
            "--no-peers": {"action": "store_true", "help": "do not run the scipy peers"},
            "--repeats": {"type": int, "default": REPEATS, "help": "timing repeats per point (best is kept)"},
        },
        file_name="sciml_work_precision.png",
    )


FIGURE = _make_figure()


def main(argv=None):
    """``python -m gyrolab.analysis.figures.sciml FILE -o TABLE.md [--png FIGURE.png]``."""
    p = argparse.ArgumentParser(
        prog="python -m gyrolab.analysis.figures.sciml",
        description=__doc__.split("\n\n")[0],
    )
    p.add_argument("file", help="results file of experiment=sciml_rigid_body")
    p.add_argument("-o", "--output", required=True, help="markdown table to write")
    p.add_argument("--png", help="also draw the figure into this PNG")
    p.add_argument("--repeats", type=int, default=REPEATS, help="timing repeats per point (best is kept)")
    args = p.parse_args(argv)
    try:
        ds = open_results(args.file)
        data = sciml_data(ds, repeats=args.repeats)
    except (OSError, SelectionError, ValueError) as err:
        sys.stderr.write(f"sciml: error: {args.file}: {' '.join(str(err).split())}\n")
        return 2
    text = (
        f"# SciMLBenchmarks rigid body (generated)\n\nWritten by `python -m gyrolab.analysis.figures.sciml` from "
        f"`{Path(args.file).name}`; times are best of {args.repeats} on this machine "
        f"({load_text(data['load'])}; compare times within one table only).\n\n{table(data)}\n"
    )
    write_text(args.output, text)  # never a half-written table, never through a link
    if args.png:
        from ..io import save_figure

        save_figure(sciml_figure(ds, data=data), args.png)
    print(f"wrote {args.output}" + (f" and {args.png}" if args.png else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
