"""The write-up's study from the results of ``gyrolab experiment=seed_figures`` (a 4-job multirun).

Each job is the heavy top at θ0 = 45° with one initial precession rate φ̇0
(scene.init = precession); the regime of a job is read off its closed-form
nutation: φ̇0 = 0 → cusps (fig. 6), φ̇0 < 0 → loops (fig. 7), a band narrower
than 0.01° → steady precession (fig. 9), else waves (fig. 8).  Three PNGs:

- ``seed_regimes.png``: the tip seen from above in the four regimes (seed_next,
  smallest dt, over the lie_poisson4 yardstick);
- ``seed_remark1.png``: Remark 1, release at f = 1, 10, 50 Hz, θ(t) and tip
  locus, with the write-up's ratio L/ΔL = I3 2π f² / (M g l sin θ0);
- ``seed_next_vs_prev.png``: ω(t+dt) vs ω(t): energy drift and θ(t) of
  seed_next and seed_prev in every regime.
"""

import math
import sys
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ...results import find_results, open_results
from ..io import (
    DT_STYLES,
    FLOOR,
    SelectionError,
    color,
    fmt_dt,
    invariant_error,
    running_max,
    save_figure,
    scene_options,
)
from .nutation import closed_form_nutation

REGIME_TITLES = {
    "cusp": "cusps (fig. 6)",
    "loop": "loops (fig. 7)",
    "wave": "waves (fig. 8)",
    "steady": "steady precession (fig. 9)",
}
WRITEUP_F = 20.0  # Hz: the write-up's steady case (impossible at 45 deg) and our f for figs 6-8
STEADY_NOTE = (
    "write-up: 20 Hz at 45° is impossible\nfor its body (steady precession needs\nf ≥ 22.07 Hz); nearest possible case"
)


def regime_of(ds):
    """(regime name, f to draw) of a seed_figures job, from φ̇0 and the closed form."""
    phidot0 = float(scene_options(ds).get("phidot0", 0.0))
    th = float(ds.theta0.values[0])
    fs = [float(f) for f in ds.f.values]
    widths = {}
    for f in fs:
        nut = closed_form_nutation(ds, f, th)
        widths[f] = math.inf if nut is None else nut.theta_max - nut.theta_min
    steady_f = min(widths, key=widths.get)
    if math.degrees(widths[steady_f]) < 0.01:
        return "steady", steady_f
    f_draw = WRITEUP_F if WRITEUP_F in fs else max(fs)
    if phidot0 == 0.0:
        return "cusp", f_draw
    return ("loop" if phidot0 < 0 else "wave"), f_draw


SEED_METHODS = ("seed_next", "seed_prev")  # every figure draws both


def check_job(path, ds):
    """SelectionError (one line naming ``path``) unless ``ds`` is a seed_figures job: the heavy top (its
    closed-form nutation), one θ0, and both seed methods; an ordinary results file is not one."""
    from ...results.layout import closed_form

    what = "gyrolab experiment=seed_figures"
    if closed_form(ds) != "heavy_top_nutation":
        raise SelectionError(f"FILE={path}: not a seed_figures job ({what}): its scene has no heavy-top nutation")
    missing = [m for m in SEED_METHODS if m not in ds.integrator.values]
    if missing:
        raise SelectionError(f"FILE={path}: not a seed_figures job ({what}): no integrator={','.join(missing)}")
    th = float(ds.theta0.values[0])
    if any(closed_form_nutation(ds, float(f), th) is None for f in ds.f.values):
        raise SelectionError(f"FILE={path}: not a seed_figures job ({what}): no closed-form nutation at θ0={th:g}")


def load_jobs(paths):
    """{regime: (Dataset, f)} of the seed_figures jobs found under ``paths``; SelectionError (one line)
    for a file that is not one."""
    jobs = {}
    for path in find_results(paths):
        ds = open_results(path)
        check_job(path, ds)
        name, f = regime_of(ds)
        jobs.setdefault(name, (ds, f))
    return jobs


def _tip(ax, ds, f, method, dt, t_max, **style):
    run = ds.sel({"integrator": method, "f": f, "theta0": ds.theta0.values[0], "dt": dt})
    mask = ds.time.values <= t_max + 1e-12
    xy = run.axis.values[mask]
    ax.plot(xy[:, 0], xy[:, 1], **style)
    return xy


def regimes_figure(jobs):
    """2 x 2 tip loci: cusps, loops, waves, steady precession (seed_next at the smallest dt)."""
    fig, axes = plt.subplots(2, 2, figsize=(9.5, 9.8))
    for ax, name in zip(axes.ravel(), ("cusp", "loop", "wave", "steady")):
        if name not in jobs:
            ax.text(0.5, 0.5, f"no {name} job found", ha="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        ds, f = jobs[name]
        th = float(ds.theta0.values[0])
        dt = float(ds.dt.values.min())
        nut = closed_form_nutation(ds, f, th)
        t_max = min(float(ds.time[-1]), 1.02 * 2 * math.pi / abs(nut.precession_rate))
        methods = [str(m) for m in ds.integrator.values]
        if "lie_poisson4" in methods:
            _tip(
                ax, ds, f, "lie_poisson4", dt, t_max, color="k", lw=2.6, alpha=0.25, label=f"lie_poisson4, {fmt_dt(dt)}"
            )
        xy = _tip(ax, ds, f, "seed_next", dt, t_max, color=color("seed_next"), lw=0.9, label=f"seed_next, {fmt_dt(dt)}")
        ax.plot(xy[0, 0], xy[0, 1], "ko", ms=4, label="start (t = 0)")
        circle = np.linspace(0, 2 * math.pi, 361)
        for k, val in enumerate((nut.theta_min, nut.theta_max)):
            ax.plot(
                math.sin(val) * np.cos(circle),
                math.sin(val) * np.sin(circle),
                "k",
                ls=(0, (4, 3)),
                lw=0.6,
                label="closed-form sin θ_min, sin θ_max" if k == 0 else None,
            )
        ax.set_aspect("equal")
        lim = 1.05 * np.abs(xy[:, :2]).max()
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        phidot0 = float(scene_options(ds).get("phidot0", 0.0))
        ax.set_title(
            f"{REGIME_TITLES[name]}\nf = {f:g} Hz, θ0 = {th:g}°, φ̇0 = {phidot0:.4g} rad/s, 0 ≤ t ≤ {t_max:.2g} s",
            fontsize=9,
        )
        ax.set_xlabel("tip x (unit axis, lab)")
        ax.set_ylabel("tip y (unit axis, lab)")
        ax.grid(alpha=0.3)
        if name == "steady":
            ax.text(
                0.5,
                0.5,
                STEADY_NOTE + f":\nf = {f:g} Hz, slow root of Goldstein 5.77",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=7.5,
                bbox=dict(fc="lightyellow", ec="0.6"),
            )
    fig.suptitle(
        "The write-up's figures 6-9: axis tip seen from above, heavy top (seed body)\n"
        "dashed: closed-form sin θ_min, sin θ_max",
        fontsize=11,
    )
    fig.tight_layout()
    handles, labels = {}, []
    for ax in axes.ravel():  # one legend for the four panels, under them: it covers no trace
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    labels = list(handles)
    fig.legend(
        list(handles.values()), labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2, fontsize=8, frameon=False
    )
    return fig


def remark1_figure(ds, fs=(1.0, 10.0, 50.0), method="seed_next"):
    """Remark 1: release at f = 1, 10, 50 Hz; θ(t) over 2 s and the tip locus, with L/ΔL."""
    th = float(ds.theta0.values[0])
    fs = [f for f in fs if np.any(np.isclose(ds.f.values, f))]
    dt = float(ds.dt.values.min())
    opts = scene_options(ds)
    I3 = opts.get("M", 1.0) * opts.get("r", 0.05) ** 2 / 2
    mgl = opts.get("M", 1.0) * opts.get("g", 10.0) * opts.get("l", 0.1)
    fig, axes = plt.subplots(2, len(fs), figsize=(4.3 * len(fs), 8.0), squeeze=False)
    time = ds.time.values
    for c, f in enumerate(fs):
        run = ds.sel({"integrator": method, "f": f, "theta0": th, "dt": dt})
        nut = closed_form_nutation(ds, f, th)
        ratio = I3 * 2 * math.pi * f * f / (mgl * math.sin(math.radians(th)))
        mask = time <= 2.0
        ax = axes[0, c]
        ax.plot(time[mask], np.degrees(run.theta.values[mask]), color=color(method), lw=1.0)
        for val in (nut.theta_min, nut.theta_max):
            ax.axhline(math.degrees(val), color="k", ls=(0, (4, 3)), lw=0.8)
        ax.set_title(
            f"f = {f:g} Hz: L/ΔL = I3·2πf²/(Mgl sin θ0) = {ratio:.3g}\n"
            f"closed form θ ∈ [{math.degrees(nut.theta_min):.1f}°, {math.degrees(nut.theta_max):.1f}°]",
            fontsize=9,
        )
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("tilt θ (deg)")
        ax.grid(alpha=0.3)
        ax = axes[1, c]
        t_max = min(float(time[-1]), 1.02 * 2 * math.pi / abs(nut.precession_rate))
        xy = _tip(ax, ds, f, method, dt, t_max, color=color(method), lw=0.8)
        ax.plot(xy[0, 0], xy[0, 1], "ko", ms=4)
        circle = np.linspace(0, 2 * math.pi, 361)
        ax.plot(np.cos(circle), np.sin(circle), color="0.6", lw=0.7)
        ax.set_aspect("equal")
        ax.set_xlim(-1.05, 1.05)
        ax.set_ylim(-1.05, 1.05)
        ax.set_title(f"tip from above, 0 ≤ t ≤ {t_max:.2g} s (grey: horizon; dot: start)", fontsize=9)
        ax.set_xlabel("tip x (unit axis, lab)")
        ax.set_ylabel("tip y (unit axis, lab)")
        ax.grid(alpha=0.3)
    fig.suptitle(
        f"Remark 1: released at θ0 = {th:g}° with spin only ({method}, {fmt_dt(dt)}); "
        "a slow top (L ≲ ΔL) just falls, precession and nutation need L ≫ ΔL",
        fontsize=10.5,
    )
    fig.tight_layout()
    return fig


def next_vs_prev_figure(jobs):
    """ω(t+dt) vs ω(t): per regime, energy drift (running max) and θ(t) of seed_next and seed_prev."""
    names = [n for n in ("cusp", "loop", "wave", "steady") if n in jobs]
    fig, axes = plt.subplots(2, len(names), figsize=(4.4 * len(names), 7.6), squeeze=False)
    for c, name in enumerate(names):
        ds, f = jobs[name]
        th = float(ds.theta0.values[0])
        t = ds.time.values
        tp = np.where(t > 0, t, np.nan)
        ax = axes[0, c]
        for m in ("seed_next", "seed_prev"):
            for k, dt in enumerate(ds.dt.values):
                e = invariant_error(ds.sel({"integrator": m, "f": f, "theta0": th, "dt": dt}), "energy")
                ax.plot(
                    tp,
                    np.maximum(running_max(e), FLOOR),
                    DT_STYLES[k % 4],
                    color=color(m),
                    lw=1.1,
                    label=f"{m}, {fmt_dt(dt)}",
                )
        ax.set_yscale("log")
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("max over s ≤ t of |E(s) − E0| / |E0|")
        ax.set_title(f"{REGIME_TITLES[name]}, f = {f:g} Hz", fontsize=9)
        ax.grid(alpha=0.3)
        ax = axes[1, c]
        dt = float(ds.dt.values.max())
        for m, lw in (("lie_poisson4", 2.4), ("seed_prev", 0.6), ("seed_next", 0.6)):
            if m not in ds.integrator.values:
                continue
            th_t = np.degrees(ds.theta.sel({"integrator": m, "f": f, "theta0": th, "dt": dt}).values)
            ax.plot(
                t,
                th_t,
                color=color(m) if m != "lie_poisson4" else "k",
                lw=lw,
                alpha=0.3 if m == "lie_poisson4" else 0.9,
                label=f"{m}, {fmt_dt(dt)}",
            )
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("tilt θ (deg)")
        ax.grid(alpha=0.3)
    for row, where in ((0, "energy"), (1, "θ(t)")):  # legends right of the last panel, not over the traces
        handles, labels = axes[row, 0].get_legend_handles_labels()
        axes[row, -1].legend(
            handles,
            labels,
            fontsize=7,
            loc="upper left",
            bbox_to_anchor=(1.02, 1.0),
            title=where,
            title_fontsize=7,
            frameon=False,
        )
    fig.suptitle(
        "ω(t+dt) (seed_next) vs ω(t) (seed_prev) in the rotation step: energy drift (top) and "
        "tilt θ(t) (bottom), heavy top θ0 = 45°",
        fontsize=10.5,
    )
    fig.tight_layout()
    return fig


def seed_figures(paths, out, formats=("png",)):
    """Write the three seed PNGs for the jobs under ``paths``; ``out`` is a directory or a .png in it."""
    out = Path(out)
    out_dir = out.parent if out.suffix else out
    jobs = load_jobs(paths)
    # every figure drawn before any is written: a failure leaves none of the three behind
    figures = {"seed_regimes.png": regimes_figure(jobs)}
    if "cusp" in jobs:
        figures["seed_remark1.png"] = remark1_figure(jobs["cusp"][0])
    figures["seed_next_vs_prev.png"] = next_vs_prev_figure(jobs)
    return [save_figure(fig, out_dir / name, formats) for name, fig in figures.items()]


try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - hydra is a dependency
    Callback = object


class SeedFiguresCallback(Callback):
    """Hydra callback of experiment=seed_figures: draw the seed figures when the multirun ends."""

    def on_multirun_end(self, config, **kwargs):
        sweep_dir = Path(config.hydra.sweep.dir)
        if (config.get("runner") or {}).get("dry_run"):  # nothing was run: nothing to draw, and nothing failed
            print("gyrolab: seed figures: none (dry run)")
            return
        try:
            paths = seed_figures([sweep_dir], sweep_dir)
        except Exception as err:  # the results are safe on disk; say what failed
            print(f"gyrolab: seed figures skipped: {type(err).__name__}: {err}", file=sys.stderr)
            return
        print(f"gyrolab: seed figures: {', '.join(str(p) for p in paths)}")
