"""Work-precision diagram: error against cost on log-log axes, one line per method across dt.

Error: max over the stored samples of |axis(t) − axis_ref(t)| (the chord
between unit symmetry axes, ≈ the angle in rad), against the scene's exact
motion when it declares one that gives a trajectory (free bodies:
analysis/figures/yardstick.py; the free asymmetric body's Euler–Poinsot flow), else
against scipy DOP853 at rtol = atol = 1e-12 (kernels.reference), at the same
sample times.  Cost: wall time per simulated second (left) and method steps
per simulated second (right).  Steps are not equal work: a step of
seed_next is one torque evaluation, of rk4 four stages, and scipy's steps
are counted as RHS evaluations / 12 (DOP853) or / 6 (RK45); the figure says so.

This figure runs things, and says so in its title: the DOP853 reference; a
re-timing pass of every stored (method, dt) point (one run alone on one
thread, after JIT warm-up, best of ``repeats``), because the file's
wall_time is a chunk's time shared among its runs; and, as peers on the same
axes, scipy's DOP853 and RK45 on the (ω, R) formulation at several
tolerances (steps = RHS evaluations / 12 resp. / 6).  ``retime=False`` uses
the stored wall_time instead.
"""

import math
import time

import matplotlib.pyplot as plt
import numpy as np

from ..io import ShortMinorLabels, build_run_scene, color, marker, scene_label, select
from . import yardstick
from .record import (
    add_note,
    choose,
    coincidence_text,
    coincident,
    legend_below,
    load_text,
    machine_load,
    panel_size,
    run_title,
    suptitle,
)

PEER_TOLERANCES = {"DOP853": (1e-4, 1e-6, 1e-8, 1e-10), "RK45": (1e-4, 1e-6, 1e-8)}
STAGES = {"DOP853": 12, "RK45": 6}


def axis_error(axis, ref_axis):
    """max_t |axis − ref| (≈ rad) over samples (n, 3); inf when the run has NaN (diverged)."""
    d = np.linalg.norm(np.asarray(axis) - ref_axis, axis=-1)
    return float(d.max()) if np.all(np.isfinite(d)) else math.inf


def reference_axis(scene, t_end, every):
    from ...kernels.reference import dop853

    return dop853(scene, t_end, every)[:, 0:3]


def time_method(method, scene, dt, t_end, every, repeats=3):
    """Best-of-``repeats`` wall time (s) of one run on one thread, after a warm-up call."""
    import numba

    from ...kernels.batch import integrate, sample_schedule

    stride, n_samples = sample_schedule(dt, every, t_end)
    args = (
        method,
        np.array([scene.body]),
        np.array([scene.omega0]),
        np.array([scene.q0]),
        np.array([dt]),
        np.array([stride]),
        n_samples,
    )
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        integrate(*args[:6], min(n_samples, 2))  # JIT warm-up
        best = math.inf
        for _ in range(repeats):
            start = time.perf_counter()
            integrate(*args)
            best = min(best, time.perf_counter() - start)
    finally:
        numba.set_num_threads(old)
    return best


def peer_points(scene, t_end, every, ref_axis, solver):
    """[(tolerance, wall s, steps, error)] of scipy ``solver`` on the same scene."""
    from scipy.integrate import solve_ivp

    from ...kernels.closed_form import scene_rotation
    from ...kernels.reference import rhs

    times = np.arange(ref_axis.shape[0]) * every
    y0 = np.concatenate((np.asarray(scene.omega0, float), scene_rotation(scene).as_matrix().ravel()))
    out = []
    for tol in PEER_TOLERANCES[solver]:
        start = time.perf_counter()
        sol = solve_ivp(
            rhs,
            (0.0, times[-1]),
            y0,
            method=solver,
            t_eval=times,
            rtol=tol,
            atol=tol,
            args=tuple(float(v) for v in scene.body),
        )
        wall = time.perf_counter() - start
        if not sol.success:
            continue
        R = sol.y[3:].T.reshape(-1, 3, 3)
        out.append((tol, wall, sol.nfev / STAGES[solver], axis_error(R[:, :, 2], ref_axis)))
    return out


def work_precision_data(ds, sel=None, retime=True, peers=True, repeats=3):
    """{(f, theta0): {"methods": {m: [(dt, wall, steps, err)]}, "peers": {name: [(tol, wall, steps, err)]}}}.

    wall and steps are per simulated second; err in rad (axis chord vs DOP853 1e-12).
    """
    sub = select(ds, sel)
    every = float(sub.time[1] - sub.time[0])
    t_end = float(sub.time[-1])
    data = {}
    for f in sub.f.values:
        for th in sub.theta0.values:
            scene = build_run_scene(sub, f, th)
            loads = [machine_load()]  # the load the re-timing ran under, at its start and its end
            ref = yardstick.exact_axis(sub, f, th, sub.time.values)
            if ref is None:
                ref = reference_axis(scene, t_end, every)
            methods = {}
            for m in sub.integrator.values:
                pts = []
                for dt in sorted(sub.dt.values):
                    run = sub.sel({"integrator": m, "f": f, "theta0": th, "dt": dt})
                    err = axis_error(run.axis.values, ref)
                    if retime and math.isfinite(err):
                        wall = time_method(str(m), scene, float(dt), t_end, every, repeats)
                    else:
                        wall = float(run.wall_time)
                    pts.append((float(dt), wall / t_end, float(run.n_steps) / t_end, err))
                methods[str(m)] = pts
            peer = {}
            if peers:
                for name in PEER_TOLERANCES:
                    peer[name] = [
                        (tol, w / t_end, s / t_end, e) for tol, w, s, e in peer_points(scene, t_end, every, ref, name)
                    ]
            loads.append(machine_load())
            data[(float(f), float(th))] = {"methods": methods, "peers": peer, "load": loads}
    return data


def reference_name(ds):
    """What the errors are measured against: the scene's exact motion, or scipy DOP853 at 1e-12."""
    if yardstick.exact_axis(ds, ds.f.values[0], ds.theta0.values[0], ds.time.values[:2]) is not None:
        return yardstick.label(ds).replace("exact (", "the exact ").rstrip(")")
    return "scipy DOP853 (rtol = atol = 1e-12, re-run for this figure)"


def work_precision_figure(ds, sel=None, retime=True, peers=True, data=None):
    """Error (rad) vs wall time per simulated second and vs method steps per simulated second, log-log;
    one row per (f, θ0), at most 4 rows and 8 methods (the figure says what it left out)."""
    sub, note = choose(select(ds, sel), "work-precision", max_dt=ds.dt.size, max_panels=4)
    data = data if data is not None else work_precision_data(sub, retime=retime, peers=peers)
    keys = list(data)
    fig, axes = plt.subplots(len(keys), 2, figsize=panel_size(len(keys), 2, 5.8, 4.0), squeeze=False)
    for r, key in enumerate(keys):
        entry = data[key]
        for c, (col, xlabel) in enumerate(
            (
                (1, "wall time per simulated second (s/s)"),
                (2, "method steps per simulated second (1/s); not equal work"),
            )
        ):
            ax = axes[r, c]
            errs = {}
            for m, pts in entry["methods"].items():
                ok = [p for p in pts if math.isfinite(p[3])]
                if ok:
                    xs, ys = [p[col] for p in ok], [max(p[3], 1e-16) for p in ok]
                    ax.plot(xs, ys, "-", marker=marker(m), color=color(m), ms=4, label=m)
                    errs[m] = np.log10([max(p[3], 1e-16) for p in pts])
                n_bad = len(pts) - len(ok)
                if n_bad:
                    ax.plot([], [], "x", color=color(m), label=f"{m}: {n_bad} dt diverged")
            for name, pts in entry["peers"].items():
                if pts:
                    ax.plot(
                        [p[col] for p in pts],
                        [max(p[3], 1e-16) for p in pts],
                        "s--",
                        color=color(name),
                        ms=4,
                        mfc="none",
                        label=f"scipy {name} (tol {pts[0][0]:.0e}…{pts[-1][0]:.0e}; "
                        f"1 step = {STAGES[name]} RHS evaluations)",
                    )
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(ShortMinorLabels())  # two steps a factor 2 apart: < 1 decade
            ax.set_xlabel(xlabel, fontsize=9)
            ax.set_ylabel("max_t |axis − axis_ref| (rad)")
            ax.grid(alpha=0.3, which="both")
            ax.set_title(run_title(sub, *key), fontsize=9)
            groups = coincident(errs, 0.02) if c == 1 else []
            if groups:  # in the title: inside the axes it would cover points
                ax.set_title(f"{run_title(sub, *key)} ({coincidence_text(groups, 'same points')})", fontsize=9)
    t_end = float(ds.time[-1])
    loads = [x for entry in data.values() for x in entry.get("load", ())]
    timing = (
        f"re-timed: 1 thread, after JIT warm-up, best of 3, {load_text(loads)}"
        if retime
        else "stored wall_time (the load it ran under is not recorded)"
    )
    dts = sorted(float(v) for v in sub.dt.values)
    suptitle(
        fig,
        f"Work-precision: {scene_label(ds)}, {t_end:g} s; error against {reference_name(sub)}\n"
        f"our methods: one point per dt = {dts[0]:g} … {dts[-1]:g} s (smallest dt: most steps); "
        f"{timing}; scipy peers re-run",
        fontsize=9.5,
    )
    fig.tight_layout()
    add_note(
        fig,
        "right: steps are not equal work: a step of seed_next/seed_prev = 1 torque evaluation + RK4 on "
        "Euler's equations, rk4 = 4 stages, lie_poisson = 1 Strang splitting, lie_poisson4 = 3 of them; "
        "scipy's steps = RHS evaluations / 12 (DOP853) or / 6 (RK45): compare costs on the left",
    )
    add_note(fig, note)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    legend_below(fig, handles, labels, ncol=3)
    return fig


def _make_figure():
    from .record import Figure

    return Figure(
        "work-precision",
        "error vs cost on log-log axes, DOP853 as a peer",
        lambda ds, sel=None, no_peers=False, no_retime=False: work_precision_figure(
            ds, sel, retime=not no_retime, peers=not no_peers
        ),
        {
            "--no-peers": {"action": "store_true", "help": "do not run the scipy peers"},
            "--no-retime": {"action": "store_true", "help": "use the stored wall_time (no re-timing)"},
        },
        file_name="work_precision.png",
    )


FIGURE = _make_figure()
