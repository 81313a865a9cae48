"""The verdict figure ``verdict_<scene>.png``, one per scene, drawn from the verdict's records.

(a) the order fits, final-state error against dt with the fitted line over the
range used; (b) (|ω| dt)_crit per method; (c) one panel per declared invariant:
|e(t)| of the long run on log–log axes with the fitted class drawn dashed (the
fitted line |a + b t| over its span, a wander σ √t, bounded its max |e|; ▽ a
collapse's size and time; × where a run diverged).  gyrolab-verdict --figures
and the verdict study's callback (analysis/verdicts/study.py) call
``draw_figures``.
"""

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..io import FLOOR, color, save_figure
from .cells import fmt_threshold
from .classify import MIN_LADDER

MARKERS = "osv^<>DPX*h"  # with the colours: PALETTE repeats after 12 methods


def marker(method, methods):
    return MARKERS[methods.index(method) % len(MARKERS)] if method in methods else "o"


LINESTYLES = ("-", "--", ":", "-.")  # of the order fits, one per (f, θ0) group
MAX_DRIFT_ROWS = 4  # rows of drift panels, one per (f, θ0) group, in a scene's figure


def group_style(k):
    """(line style of the fit, marker face: 'none' hollow or None filled) of the k-th (f, θ0) group."""
    return LINESTYLES[k % len(LINESTYLES)], ("none", None)[k % 2]


def _order_panel(ax, orders, methods):
    if not orders:  # like the threshold panel: words, not an empty 0..1 frame
        words = f"no order: no dt ladder\n(an order needs >= {MIN_LADDER} values of sweep.dt)"
        ax.text(0.5, 0.5, words, ha="center", transform=ax.transAxes)
        ax.set_axis_off()
        return
    groups = list(dict.fromkeys((o["f"], o["theta0"]) for o in orders))
    for o in orders:
        style, face = group_style(groups.index((o["f"], o["theta0"])))
        dt, err = np.array(o["ladder_dt"], float), np.array(o["ladder_err"], float)
        ok = np.isfinite(err) & (err > 0)
        c = color(o["method"])
        ax.loglog(dt[ok], np.maximum(err[ok], FLOOR), marker(o["method"], methods), ms=3, color=c, alpha=0.6, mfc=face)
        if o["order"] is not None and math.isfinite(o["order"]):
            used = np.array(o["ladder_used"], bool)
            p = o["order"]
            logc = np.mean(np.log(err[used]) - p * np.log(dt[used]))
            x = np.geomspace(o["order_dt_range"][0], o["order_dt_range"][1], 10)
            ax.loglog(x, np.exp(logc) * x**p, style, color=c, lw=1.2)
    # Below the reference's own error the points measure the reference, not the method (left out of the fits).
    ref_errors = [o.get("reference_error") or 0.0 for o in orders]
    if ref_errors and max(ref_errors) > FLOOR:
        ax.axhspan(FLOOR, max(ref_errors), color="0.85", alpha=0.5, lw=0, zorder=0)
        ax.text(0.02, 0.02, "≤ reference (its own error)", transform=ax.transAxes, fontsize=6.5, color="0.35")
    ax.set_xlabel("time step dt (s)")
    ax.set_ylabel("final-state error (dimensionless)")
    if len(groups) > 1:  # several (f, θ0): the fits' line style says which
        keys = [
            plt.Line2D([], [], color="0.3", ls=group_style(k)[0], marker="o", ms=3, mfc=group_style(k)[1])
            for k in range(len(groups))
        ]
        ax.legend(keys, [group_words(*g) for g in groups], fontsize=6.5, loc="lower right")
    t_ends = list(dict.fromkeys(o["t_end"] for o in orders))
    refs = list(dict.fromkeys(o["reference"] for o in orders))
    when = f"t = {t_ends[0]:g} s" if len(t_ends) == 1 else f"t = {', '.join(f'{t:g}' for t in t_ends)} s"
    ref = refs[0] if len(refs) == 1 else f"{len(refs)} references, one per group (see the verdict table)"
    where = f"{group_words(*groups[0])}, " if len(groups) == 1 else ""
    ax.set_title(
        f"(a) order fits: lines over the asymptotic range, {where}final state at {when}\nreference: {ref}",
        fontsize=9,
    )
    ax.grid(alpha=0.3, which="both")


def _threshold_panel(ax, thresholds):
    if not thresholds:
        ax.text(
            0.5, 0.5, "no stability bisection\n(gyrolab-verdict --stability T)", ha="center", transform=ax.transAxes
        )
        ax.set_axis_off()
        return
    y = np.arange(len(thresholds))
    for k, r in enumerate(thresholds):
        lo, hi = r["omega_dt_bracket"]
        crit = r["omega_dt_crit"]
        c = color(r["method"])
        cell = fmt_threshold(r)  # the verdict table's own cell, '; fails at ≤ y' included
        if crit is not None and math.isfinite(crit):
            ax.barh(k, crit, color=c, alpha=0.8)
            ax.text(crit * 1.1, k, cell, va="center", fontsize=6.5)
        elif hi is not None and math.isfinite(hi):
            ax.plot(hi, k, "<", color=c)
            ax.text(hi * 1.3, k, cell, va="center", fontsize=6.5)
        elif lo is not None and math.isfinite(lo):
            ax.plot(lo, k, ">", color=c)
            ax.text(lo * 0.25, k, cell, va="center", fontsize=6.5)
    ax.set_yticks(y, [r["method"] for r in thresholds], fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlim(3e-4, 60)
    r = thresholds[0]
    ax.set_xlabel("(|ω| dt)_crit (rad)")
    ax.set_title(
        f"(b) stability threshold by bisection\nbounded over {r['stability_t_end']:g} s, "
        f"f = {r['f']:g} Hz, θ0 = {r['theta0']:g}°",
        fontsize=9,
    )
    ax.grid(alpha=0.3, axis="x", which="both")


def _drift_panel(ax, q, runs, datasets):
    from ...kernels.invariants import invariant
    from .classify import signed_error

    for r in runs:
        ds = next((d for d in datasets if _has_run(d, r)), None)
        if ds is None:
            continue
        run = ds.sel({"integrator": r["method"], "f": r["f"], "theta0": r["theta0"], "dt": r["dt"]})
        t = ds.time.values
        e = np.abs(signed_error(invariant(run, q).values))
        idx = np.unique(np.geomspace(1, t.size - 1, 300).astype(int))
        c = color(r["method"])
        ax.loglog(t[idx], np.maximum(e[idx], FLOOR), "-", color=c, lw=0.7, alpha=0.8)
        tt = t[idx]
        line = fitted_line(r, tt)
        if line is not None:
            ax.loglog(tt, np.maximum(np.abs(line), FLOOR), "--", color=c, lw=1.1)
        elif r["drift_class"] == "wander":
            ax.loglog(tt, np.maximum(r["drift_rate"] * np.sqrt(tt), FLOOR), "--", color=c, lw=1.1)
        elif r["drift_class"] == "bounded" and r["amplitude"]:
            ax.axhline(r["amplitude"], color=c, ls=":", lw=0.9)
        elif r["drift_class"] == "diverged" and r["t_diverged"] is not None and math.isfinite(r["t_diverged"]):
            ax.plot(max(r["t_diverged"], t[1]), 1.0, "x", color=c, ms=6)
        elif r["drift_class"] == "collapse" and r.get("collapse_time") is not None:
            ax.plot(max(r["collapse_time"], t[1]), abs(r["collapse_size"]), "v", color=c, ms=5)
    ax.set_title(
        f"(c) |e| of {q}: {drift_conditions(runs)}\ndashed: fitted line / √t; dotted: bounded max; ▽ collapse",
        fontsize=8.5,
    )
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(f"|{q}(t) − {q}(0)| / |{q}(0)|")
    ax.set_ylim(1e-17, 10)
    ax.grid(alpha=0.3, which="both")


def group_words(f, theta0):
    return f"f = {f:g} Hz, θ0 = {theta0:g}°"


def drift_conditions(runs):
    """'f = 10 Hz, θ0 = 45°, dt = 0.005 s' of the drift records ``runs`` (one (f, θ0) group, a panel's):
    its steps listed when the methods' runs differ (files of other sweeps)."""
    if not runs:
        return ""
    dts = sorted({r["dt"] for r in runs})
    steps = f"dt = {dts[0]:g} s" if len(dts) == 1 else f"dt = {', '.join(f'{d:g}' for d in dts)} s by method"
    return f"{group_words(runs[0]['f'], runs[0]['theta0'])}, {steps}"


def fitted_line(r, t):
    """The line e = intercept + rate·t a drift record fitted (linear, a slow oscillation's trend, a
    collapse's linear tail) at times t (s), NaN outside the span it was fitted on; None if no line."""
    if r["drift_class"] in ("linear", "slow_oscillation"):
        a, b = r.get("intercept"), r.get("drift_rate")
    elif r["drift_class"] == "collapse" and r.get("then_class") == "linear":
        a, b = r.get("then_intercept"), r.get("then_rate")
    else:
        return None
    if a is None or b is None or r.get("fit_t0") is None:
        return None
    t = np.asarray(t, dtype=float)
    return np.where((t >= r["fit_t0"]) & (t <= r["fit_t1"]), a + b * t, np.nan)


def _has_run(ds, r):
    from ..io import scene_name

    return (
        scene_name(ds) == r["scene"]
        and r["method"] in ds.integrator.values
        and ds.sizes["time"] > 2
        and np.any(np.isclose(ds.dt.values, r["dt"]))
        and np.any(np.isclose(ds.f.values, r["f"]))
        and np.any(np.isclose(ds.theta0.values, r["theta0"]))
    )


def scene_figure(scene, records, datasets):
    """The verdict figure of one scene (matplotlib Figure)."""
    orders = [r for r in records if r["kind"] == "order" and r["scene"] == scene]
    thresholds = [r for r in records if r["kind"] == "threshold" and r["scene"] == scene]
    summ = [r for r in records if r["kind"] == "summary" and r["scene"] == scene]
    quantities = [q for q in dict.fromkeys(r["quantity"] for r in summ) if q is not None]  # None: declares none
    methods = list(dict.fromkeys(r["method"] for r in summ))
    # one row of drift panels per (f, θ0) group with a drift run: each panel's curves and title its group's
    groups = list(
        dict.fromkeys((r["f"], r["theta0"]) for r in summ if r["quantity"] in quantities and r.get("drift_class"))
    )
    if quantities and not groups:
        groups = [None]  # a row of empty panels still shows the scene's invariants
    n_groups, groups = len(groups), groups[:MAX_DRIFT_ROWS]  # a 10 × 10 sweep: 4 rows, and the title says so
    ncol = max(3, len(quantities))
    rows = 1 + len(groups) if quantities else 1  # no conserved quantity (forced_body): no drift row
    fig = plt.figure(figsize=(4.2 * ncol, 5.8 + 4.7 * (rows - 1)))
    grid = fig.add_gridspec(rows, ncol, height_ratios=[1.1] + [1.0] * (rows - 1))
    half = ncol // 2 + ncol % 2
    _order_panel(fig.add_subplot(grid[0, :half]), orders, methods)
    _threshold_panel(fig.add_subplot(grid[0, half:]), thresholds)
    for row, group in enumerate(groups, start=1):
        for k, q in enumerate(quantities):
            runs = [
                r
                for r in summ
                if r["quantity"] == q
                and r.get("drift_class")
                and (r["f"], r["theta0"]) == (group or (r["f"], r["theta0"]))
            ]
            _drift_panel(fig.add_subplot(grid[row, k]), q, runs, datasets)
    handles = [plt.Line2D([], [], color=color(m), lw=2, marker=marker(m, methods), mfc="none") for m in methods]
    ncol_legend = min(10, len(methods))
    fig.legend(handles, methods, loc="lower center", ncol=ncol_legend, fontsize=7.5, bbox_to_anchor=(0.5, 0.0))
    measured = ", long-time invariant errors" if quantities else " (the scene declares no conserved quantity)"
    shown = (
        f"\n(c) rows: the first {len(groups)} of {n_groups} (f, θ0) groups; the verdict table has every group"
        if n_groups > len(groups)
        else ""
    )
    fig.suptitle(f"Verdicts measured on {scene}: order, stability threshold{measured}{shown}", fontsize=12)
    # the panels above the legend: ~0.17 in a legend row (7.5 pt), so that 39 methods' rows do not cover
    # the bottom panels' axis labels
    legend_rows = math.ceil(len(methods) / max(ncol_legend, 1))
    fig.tight_layout(rect=(0, (0.17 * legend_rows + 0.1) / fig.get_figheight(), 1, 1))
    return fig


def draw_figures(records, datasets, out_dir):
    """verdict_<scene>.png per scene of ``records`` into ``out_dir``; returns the paths."""
    from ...safe_files import inside, safe_name

    ds_list = [d for _, d in datasets]
    out = []
    scenes = dict.fromkeys(r["scene"] for r in records if r["kind"] == "summary")
    for k, scene in enumerate(scenes):
        # the scene is text from a file: a safe basename (else its index), checked to stay in out_dir
        path = inside(out_dir, Path(out_dir) / f"verdict_{safe_name(scene, k)}.png")
        out.append(save_figure(scene_figure(scene, records, ds_list), path))
    return out
