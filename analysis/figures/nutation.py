"""Nutation figures: θ(t) per method against the scene's yardstick, and the tip locus from above.

θ is the tilt of the symmetry axis from lab z (stored in rad, drawn in deg).
The yardstick is what the scene declares (analysis/figures/yardstick.py): the heavy
top's closed-form θ_min/θ_max (bounds every exact trajectory of that run stays
between), the free symmetric top's exact θ(t), the free asymmetric body's
exact Euler–Poinsot θ(t) with its flips marked; none for a scene without one.
The tip locus is the lab x, y of the unit axis R e3 seen from above (z up),
the write-up's figures 6-9.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.gridspec import GridSpec

from ...results.layout import tilt_angle
from ..io import DT_STYLES, color, fmt_dt, line_style, pick, scene_label, select
from . import yardstick
from .record import (
    add_note,
    choose,
    coincidence_text,
    coincident,
    diverged_text,
    fixed_note,
    legend_below,
    method_groups,
    method_handles,
    panel_size,
    run_title,
    subplots,
    suptitle,
)

EXACT_STYLE = dict(color="k", ls=(0, (4, 3)), lw=0.9)


def closed_form_nutation(ds, f, theta0):
    """Closed-form Nutation of grid point (f, theta0), or None when the scene has none."""
    return yardstick.nutation(ds, f, theta0)


def _windows(time, period, n_periods):
    """(start, end) windows of about n_periods characteristic periods at the start and at the end of
    the run; one window (the whole run, or its first n_periods) when the run is too short for two
    distinct ones."""
    t0, t1 = float(time[0]), float(time[-1])
    width = n_periods * period.seconds if period is not None and period.seconds > 0 else (t1 - t0) / 5
    width = min(width, t1 - t0)
    if t1 - t0 < 3.0 * width:  # start and end would overlap or nearly touch: draw the run once
        return [(t0, t1, "whole run")]
    return [(t0, t0 + width, "start of the run"), (t1 - width, t1, "end of the run")]


def _theta_panel(ax, sub, f, th, lo, hi, exact_t, exact_theta, nut, flips, methods):
    time = sub.time.values
    mask = (time >= lo - 1e-12) & (time <= hi + 1e-12)
    series = {}
    lean = sub[["theta", "status"]]  # a run selected from the whole file indexes every variable
    for m in methods:
        for k, dt in enumerate(sub.dt.values):
            run = lean.sel({"integrator": m, "f": f, "theta0": th, "dt": dt})
            label = f"{m}" + (f", {fmt_dt(dt)}" if sub.dt.size > 1 else "")
            if int(run.status) != 0:
                label += " (diverged)"
            y = np.degrees(run.theta.values[mask])
            series[label] = y
            ax.plot(time[mask], y, DT_STYLES[k % 4], lw=1.1, label=label, **line_style(m, y.size))
    if exact_theta is not None:
        keep = (exact_t >= lo - 1e-12) & (exact_t <= hi + 1e-12)
        ax.plot(exact_t[keep], exact_theta[keep], **EXACT_STYLE, label=yardstick.label(sub))
    if nut is not None:
        for val in (nut.theta_min, nut.theta_max):
            ax.axhline(math.degrees(val), **EXACT_STYLE)
    for t in flips:
        if lo <= t <= hi:
            ax.axvline(t, color="0.45", ls=":", lw=0.9)
    ax.set_xlim(lo, hi)
    ax.grid(alpha=0.3)
    lo_y, hi_y = ax.get_ylim()
    groups = coincident(series, 0.004 * (hi_y - lo_y))  # closer than a line width: drawn on top of each other
    if groups:
        ax.text(
            0.99,
            0.02,
            coincidence_text(groups, "on top of each other"),
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=6.5,
            bbox=dict(fc="white", ec="0.7", alpha=0.85),
        )


def _yardstick_text(sub, f, th, nut, period):
    if nut is not None:
        return f"closed form θ ∈ [{math.degrees(nut.theta_min):.2f}°, {math.degrees(nut.theta_max):.2f}°], " + (
            f"T = {nut.period * 1e3:.1f} ms" if math.isfinite(nut.period) else "unstable vertical"
        )
    if period is not None:
        return f"exact; {period.label.split(' 2')[0]} {period.seconds:.3g} s"
    return "no closed form for this scene"


def theta_figure(ds, sel=None, n_periods=3.0):
    """θ(t) (deg) per method, one row per f (and θ0), with the scene's yardstick (see module doc).

    ``sel`` chooses grid values; by default every method at the smallest dt
    (the most accurate runs).  Two columns when the run is long enough: the
    first and the last ``n_periods`` characteristic periods (nutation,
    precession or flip period), so drift shows; otherwise the whole run.
    """
    sel = dict(sel or {})
    fixed = None
    if sel.get("dt") is None:
        sel["dt"] = [float(ds.dt.values.min())]
        fixed = fixed_note(ds, "nutation", {"dt": [ds.dt.values.min()]})
    picked = select(ds, sel)
    n_groups = len(method_groups(picked.integrator.values))
    sub, note = choose(picked, "nutation", max_dt=2, max_panels=max(1, 6 // n_groups))
    groups = method_groups(sub.integrator.values)
    # one row per (f, θ0) and group of methods: every method drawn, at most MAX_METHODS curves a panel
    rows = [(f, th, g) for f in sub.f.values for th in sub.theta0.values for g in range(len(groups))]
    time = sub.time.values
    periods = [yardstick.period(sub, f, th) for f, th, _ in rows]
    windows = [_windows(time, p, n_periods) for p in periods]
    ncols = max(len(w) for w in windows)
    fig = plt.figure(figsize=panel_size(len(rows), ncols, 6.0 if ncols == 1 else 5.2, 2.7, extra_w=1.0))
    grid = GridSpec(len(rows), ncols, figure=fig)
    first = None
    for r, ((f, th, g), wins, period) in enumerate(zip(rows, windows, periods)):
        nut = yardstick.nutation(sub, f, th)
        exact = yardstick.exact_axis(sub, f, th, time)
        exact_theta = None if exact is None else np.degrees(tilt_angle(exact[:, 0], exact[:, 1], exact[:, 2]))
        flips = yardstick.flip_times(sub, f, th, time)
        for c, (lo, hi, what) in enumerate(wins):
            ax = fig.add_subplot(grid[r, c] if len(wins) == ncols else grid[r, :])
            first = first or ax
            _theta_panel(ax, sub, f, th, lo, hi, time, exact_theta, nut, flips, groups[g])
            ax.set_xlabel("time t (s)")
            group = f"\nmethods {g + 1} of {len(groups)}" if len(groups) > 1 else ""
            ax.set_ylabel("tilt θ (deg)" + group if c == 0 else "", fontsize=9 if group else None)
            ax.set_title(
                run_title(sub, f, th) + (f": {what.split(' of')[0]}" if len(wins) > 1 else "")
                if c == 0
                else what.split(" of")[0],
                fontsize=9,
                loc="left",
            )
            if c == 0:
                ax.set_title(_yardstick_text(sub, f, th, nut, period), fontsize=7.5, loc="right")
    handles, labels = method_handles([m for g in groups for m in g], list(sub.dt.values), diverged_text(sub))
    exact_labels = [lab for lab in first.get_legend_handles_labels()[1] if lab == yardstick.label(sub)]
    if exact_labels:
        handles.append(plt.Line2D([], [], **EXACT_STYLE))
        labels.append(exact_labels[0])
    if yardstick.nutation(sub, *rows[0][:2]) is not None:
        handles.append(plt.Line2D([], [], **EXACT_STYLE))
        labels.append("closed-form θ_min, θ_max")
    if any(yardstick.flip_times(sub, f, th, time) for f, th, _ in rows):
        handles.append(plt.Line2D([], [], color="0.45", ls=":", lw=0.9))
        labels.append("exact flip times (ω3 changes sign)")
    dts = ", ".join(fmt_dt(d) for d in sub.dt.values)
    suptitle(fig, f"Nutation θ(t): {scene_label(sub)}, {dts}", fontsize=11)
    fig.tight_layout()
    add_note(fig, fixed)
    add_note(fig, note)
    legend_below(fig, handles, labels, ncol=min(len(labels), 4))
    return fig


def _tip_window(sub, f, th, t_max):
    """Last time (s) drawn: ``t_max``, else one turn of mean precession (heavy top), one precession
    period (free symmetric), two flip periods (free asymmetric), or the whole run."""
    time = sub.time.values
    if t_max is not None:
        return float(t_max)
    nut = yardstick.nutation(sub, f, th)
    if nut is not None and abs(nut.precession_rate) > 0:
        return min(float(time[-1]), 1.05 * 2 * math.pi / abs(nut.precession_rate))
    period = yardstick.period(sub, f, th)
    if period is not None:
        return min(float(time[-1]), (2.05 if yardstick.kind(sub) == "euler_poinsot" else 1.05) * period.seconds)
    return float(time[-1])


def _tip_note(ds, method, dt):
    """What the tip figure drew (one method, one dt) and how to draw another; None when that is all."""
    methods = [str(m) for m in ds.integrator.values if str(m) != str(method)]
    dts = [f"{v:g}" for v in ds.dt.values if not math.isclose(float(v), float(dt))]
    if not methods and not dts:
        return None
    other = (
        (f"methods {', '.join(methods)}" if methods else "")
        + ("; " if methods and dts else "")
        + (f"dt = {', '.join(dts)} s" if dts else "")
    )
    return (
        f"drawn: {method} at dt = {float(dt):g} s (one method and dt per figure); also in the file: {other}: "
        f"gyrolab-plot tip FILE integrator=M dt=DT"
    )


def tip_locus_figure(ds, method=None, f=None, theta0=None, dt=None, t_max=None):
    """Locus of the axis tip (lab x, y of R e3) seen from above for one method and dt.

    One panel per f (and θ0) unless ``f``/``theta0`` pick one, wrapped into
    rows.  Heavy top: dashed circles of radius sin θ_min, sin θ_max (the
    closed-form annulus) only where they bound the trace, θ_max ≤ 90°; past
    the horizon the panel says so and draws the horizon.  Free bodies: the
    exact trace, dashed.  ``t_max`` (s) limits the trace (default: _tip_window).
    """
    method = pick(ds, "integrator", method)
    dt = pick(ds, "dt", dt, prefer="min")
    fixed = _tip_note(ds, method, dt)
    sub = select(
        ds,
        {
            "integrator": [method],
            "dt": [dt],
            "f": None if f is None else [f],
            "theta0": None if theta0 is None else [theta0],
        },
    )
    sub, note = choose(sub, f"tip integrator={method} dt={dt:g}", max_panels=9)
    panels = [(fv, th) for fv in sub.f.values for th in sub.theta0.values]
    fig, axes = subplots(len(panels), width=4.0, height=4.1)
    time = sub.time.values
    circle = np.linspace(0, 2 * math.pi, 361)
    handles = {}
    for ax, (fv, th) in zip(axes, panels):
        run = sub.sel({"integrator": method, "dt": dt, "f": fv, "theta0": th})
        nut = yardstick.nutation(sub, fv, th)
        tm = _tip_window(sub, fv, th, t_max)
        mask = time <= tm + 1e-12
        xy = run.axis.values[mask]
        (h,) = ax.plot(xy[:, 0], xy[:, 1], color=color(method) or "C0", lw=0.9)
        handles[f"{method}, {fmt_dt(dt)}"] = h
        dense = np.linspace(0.0, float(time[mask][-1]), 2001)  # the exact trace is cheap: draw it smooth
        exact = yardstick.exact_axis(sub, fv, th, dense)
        if int(mask.sum()) < 60:  # a stored trace this sparse is drawn as straight segments: say so
            ax.text(
                0.98,
                0.02,
                f"{int(mask.sum())} stored samples\n(every {float(time[1] - time[0]):g} s)",
                transform=ax.transAxes,
                ha="right",
                va="bottom",
                fontsize=7,
                bbox=dict(fc="white", ec="0.7", alpha=0.85),
            )
        if exact is not None:
            (h,) = ax.plot(exact[:, 0], exact[:, 1], **EXACT_STYLE)
            handles[yardstick.label(sub)] = h
        lim = 1.05 * max(np.nanmax(np.abs(xy[:, :2])), 0.1)
        if nut is not None and nut.theta_max <= math.pi / 2:
            for val in (nut.theta_min, nut.theta_max):
                rr = math.sin(val)
                (h,) = ax.plot(rr * np.cos(circle), rr * np.sin(circle), color="k", ls=(0, (4, 3)), lw=0.7)
            handles["closed-form sin θ_min, sin θ_max"] = h
            lim = max(lim, 1.05 * math.sin(nut.theta_max))
        elif nut is not None:  # the tip dips below the pivot: the circles would not bound it
            (h,) = ax.plot(np.cos(circle), np.sin(circle), color="0.6", lw=0.7)
            handles["horizon (θ = 90°)"] = h
            ax.text(
                0.02,
                0.02,
                f"θ_max = {math.degrees(nut.theta_max):.0f}° > 90°:\nno bounding circles",
                transform=ax.transAxes,
                fontsize=7,
                va="bottom",
                bbox=dict(fc="white", ec="0.7", alpha=0.85),
            )
            lim = max(lim, 1.05)
        (h,) = ax.plot(xy[0, 0], xy[0, 1], "o", color="k", ms=4)
        handles["start (t = 0)"] = h
        (h,) = ax.plot(0, 0, "+", color="k", ms=7)
        handles["pivot (lab z axis)" if nut is not None else "lab z axis"] = h
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel("tip x (unit axis, lab)")
        ax.set_ylabel("tip y (unit axis, lab)")
        txt = f"{run_title(sub, fv, th)}, 0 ≤ t ≤ {time[mask][-1]:.2g} s"
        if int(run.status) != 0:
            txt += " (diverged)"
        ax.set_title(txt, fontsize=8.5)
        ax.grid(alpha=0.3)
    suptitle(fig, f"Axis tip seen from above: {scene_label(sub)}, {method}, {fmt_dt(dt)}", fontsize=10.5)
    fig.tight_layout()
    add_note(fig, fixed)
    add_note(fig, note)
    legend_below(fig, list(handles.values()), list(handles), ncol=3)
    return fig


def _tip(ds, sel=None, t_max=None):
    """tip_locus_figure from a CLI selection: one method and dt; f and θ0 when a single value is given."""
    sel = sel or {}

    def one(key):
        values = sel.get(key) or [None]
        return values[0] if len(values) == 1 else None

    sub = select(ds, {k: v for k, v in sel.items() if k in ("f", "theta0")})
    return tip_locus_figure(sub, one("integrator"), None, None, one("dt"), t_max=t_max)


def _best_method(ds):
    """The method drawn in the single-run figures: seed_next when present (the write-up's scheme)."""
    methods = [str(m) for m in ds.integrator.values]
    return "seed_next" if "seed_next" in methods else methods[0]


def _standard_tip(ds, sel=None, t_max=None):
    if not (sel or {}).get("integrator"):
        sel = {**(sel or {}), "integrator": [_best_method(ds)]}
    return _tip(ds, sel, t_max)


def _make_figures():
    from .record import Figure

    theta = Figure(
        "nutation",
        "θ(t) per method with the scene's closed form (bounds or exact θ(t))",
        lambda ds, sel=None, periods=3.0: theta_figure(ds, sel, n_periods=periods),
        {"--periods": {"type": float, "default": 3.0, "help": "characteristic periods per window (default 3)"}},
        file_name="nutation_theta.png",
    )
    tip = Figure(
        "tip",
        "locus of the axis tip seen from above (write-up figs 6-9)",
        _standard_tip,
        {"--t-max": {"type": float, "default": None, "help": "last time drawn (s); default one precession turn"}},
        file_name="tip_locus.png",
    )
    return theta, tip


THETA, TIP = _make_figures()
