"""Nutation figures: θ(t) per method against the closed-form bounds, and the tip locus from above.

θ is the tilt of the symmetry axis from lab z (stored in rad, drawn in deg);
the closed-form θ_min/θ_max of the heavy symmetric top (kernels.closed_form)
come from the run's initial state, so they are the bounds every exact
trajectory of that run stays between.  The tip locus is the lab x, y of the
unit axis R e3 seen from above (z up), the write-up's figures 6-9.
"""
import math

import matplotlib.pyplot as plt
import numpy as np

from .io import DT_STYLES, build_run_scene, color, fmt_dt, pick, scene_label, select


def closed_form_nutation(ds, f, theta0):
    """Closed-form Nutation of grid point (f, theta0), or None when the scene has none."""
    from ..layout import closed_form

    if closed_form(ds) != "heavy_top_nutation":
        return None
    from ..kernels.closed_form import heavy_top_nutation

    try:
        return heavy_top_nutation(build_run_scene(ds, f, theta0))
    except ValueError:
        return None


def _windows(time, nut, n_periods):
    """(start, end) windows of about n_periods nutation periods at the start and at the end."""
    t0, t1 = float(time[0]), float(time[-1])
    width = n_periods * nut.period if nut is not None and nut.period > 0 else (t1 - t0) / 5
    width = min(width, t1 - t0)
    if t1 - t0 <= 2.5 * width:
        return [(t0, t1)]
    return [(t0, t0 + width), (t1 - width, t1)]


def theta_figure(ds, sel=None, n_periods=3.0):
    """θ(t) (deg) per method, one row per f (and θ0), with the closed-form θ_min, θ_max as lines.

    ``sel`` chooses grid values; by default every method at the largest dt
    (where the methods differ most).  Two columns when the run is long: the
    first and the last ``n_periods`` nutation periods, so drift shows.
    """
    sel = dict(sel or {})
    if sel.get("dt") is None:
        sel["dt"] = [float(ds.dt.values.max())]
    sub = select(ds, sel)
    rows = [(f, th) for f in sub.f.values for th in sub.theta0.values]
    time = sub.time.values
    nuts = [closed_form_nutation(sub, f, th) for f, th in rows]
    ncols = max(len(_windows(time, n, n_periods)) for n in nuts)
    fig, axes = plt.subplots(len(rows), ncols, figsize=(5.2 * ncols + 1.5, 2.6 * len(rows) + 0.8),
                             squeeze=False, sharey="row")
    for r, ((f, th), nut) in enumerate(zip(rows, nuts)):
        wins = _windows(time, nut, n_periods)
        for c in range(ncols):
            ax = axes[r, c]
            lo, hi = wins[min(c, len(wins) - 1)]
            mask = (time >= lo - 1e-12) & (time <= hi + 1e-12)
            for m in sub.method.values:
                for k, dt in enumerate(sub.dt.values):
                    run = sub.sel({"method": m, "f": f, "theta0": th, "dt": dt})
                    label = f"{m}" + (f", {fmt_dt(dt)}" if sub.dt.size > 1 else "")
                    if int(run.status) != 0:
                        label += " (diverged)"
                    ax.plot(time[mask], np.degrees(run.theta.values[mask]), DT_STYLES[k % 4],
                            color=color(m), lw=1.1, label=label)
            if nut is not None:
                for val in (nut.theta_min, nut.theta_max):
                    ax.axhline(math.degrees(val), color="k", ls=(0, (4, 3)), lw=0.9)
                ax.text(1.0, 1.0, f"closed form: θ ∈ [{math.degrees(nut.theta_min):.2f}°, "
                        f"{math.degrees(nut.theta_max):.2f}°], period {nut.period * 1e3:.1f} ms",
                        transform=ax.transAxes, ha="right", va="bottom", fontsize=7.5)
            ax.set_xlim(lo, hi)
            ax.set_xlabel("time t (s)")
            ax.set_ylabel("tilt θ (deg)")
            if r == 0 and ncols > 1:
                ax.set_title(["start of the run", "end of the run"][c], fontsize=9, loc="left")
            ax.annotate(f"f = {f:g} Hz, θ0 = {th:g}°", (0.01, 0.03), xycoords="axes fraction", fontsize=8.5,
                        bbox=dict(fc="white", ec="none", alpha=0.7))
            ax.grid(alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], color="k", ls=(0, (4, 3)), lw=0.9))
    labels.append("closed-form θ_min, θ_max")
    dts = ", ".join(fmt_dt(d) for d in sub.dt.values)
    fig.suptitle(f"Nutation θ(t): {scene_label(sub)}, {dts}", fontsize=11)
    fig.tight_layout()
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 6), fontsize=8,
               bbox_to_anchor=(0.5, 0.0), frameon=False)
    return fig


def tip_locus_figure(ds, method=None, f=None, theta0=None, dt=None, t_max=None):
    """Locus of the axis tip (lab x, y of R e3) seen from above for one method and dt.

    One panel per f (and θ0) unless ``f``/``theta0`` pick one.  Dashed circles:
    radius sin θ_min and sin θ_max from the closed form (the tip's annulus).
    ``t_max`` (s) limits the trace; by default one turn of mean precession
    (closed form) or the whole run.
    """
    method = pick(ds, "method", method)
    dt = pick(ds, "dt", dt, prefer="min")
    sub = select(ds, {"method": [method], "dt": [dt], "f": None if f is None else [f],
                      "theta0": None if theta0 is None else [theta0]})
    panels = [(fv, th) for fv in sub.f.values for th in sub.theta0.values]
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(3.9 * n + 0.4, 4.3), squeeze=False)
    time = sub.time.values
    for ax, (fv, th) in zip(axes[0], panels):
        run = sub.sel({"method": method, "dt": dt, "f": fv, "theta0": th})
        nut = closed_form_nutation(sub, fv, th)
        tm = t_max
        if tm is None and nut is not None and abs(nut.precession_rate) > 0:
            tm = 1.05 * 2 * math.pi / abs(nut.precession_rate)
        mask = time <= (tm if tm is not None else time[-1]) + 1e-12
        xy = run.axis.values[mask]
        ax.plot(xy[:, 0], xy[:, 1], color=color(method) or "C0", lw=0.9)
        ax.plot(xy[0, 0], xy[0, 1], "o", color="k", ms=4, label="start")
        circle = np.linspace(0, 2 * math.pi, 361)
        if nut is not None:
            for val in (nut.theta_min, nut.theta_max):
                rr = math.sin(val)
                ax.plot(rr * np.cos(circle), rr * np.sin(circle), color="k", ls=(0, (4, 3)), lw=0.7)
            if nut.theta_max > math.pi / 2:  # the tip dips below the pivot: mark the horizon
                ax.plot(np.cos(circle), np.sin(circle), color="0.6", lw=0.7)
                ax.text(0.0, -1.0, "horizon (θ = 90°)", fontsize=7, ha="center", va="top", color="0.4")
        ax.plot(0, 0, "+", color="k", ms=6)
        lim = 1.05 * max(np.nanmax(np.abs(xy[:, :2])), 0.1)
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel("tip x (unit axis, lab)")
        ax.set_ylabel("tip y (unit axis, lab)")
        shown = time[mask][-1]
        txt = f"f = {fv:g} Hz, θ0 = {th:g}°, 0 ≤ t ≤ {shown:.2g} s"
        if int(run.status) != 0:
            txt += " (diverged)"
        ax.set_title(txt, fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle(f"Axis tip seen from above: {scene_label(sub)}, {method}, {fmt_dt(dt)}\n"
                 "dashed: closed-form sin θ_min, sin θ_max", fontsize=10)
    fig.tight_layout()
    return fig


def _tip(ds, sel=None, t_max=None):
    """tip_locus_figure from a CLI selection: one method and dt; f and θ0 when a single value is given."""
    sel = sel or {}

    def one(key):
        values = sel.get(key) or [None]
        return values[0] if len(values) == 1 else None

    return tip_locus_figure(ds, one("method"), one("f"), one("theta0"), one("dt"), t_max=t_max)


def _best_method(ds):
    """The method drawn in the single-run figures: seed_next when present (the write-up's scheme)."""
    methods = [str(m) for m in ds.method.values]
    return "seed_next" if "seed_next" in methods else methods[0]


def _standard_tip(ds, sel=None, t_max=None):
    if not (sel or {}).get("method"):
        sel = {**(sel or {}), "method": [_best_method(ds)]}
    return _tip(ds, sel, t_max)


def _make_figures():
    from .figure import Figure

    theta = Figure("nutation", "θ(t) per method with the closed-form θ_min/θ_max",
                   lambda ds, sel=None, periods=3.0: theta_figure(ds, sel, n_periods=periods),
                   {"--periods": {"type": float, "default": 3.0, "help": "nutation periods per window (default 3)"}},
                   file_name="nutation_theta.png")
    tip = Figure("tip", "locus of the axis tip seen from above (write-up figs 6-9)", _standard_tip,
                 {"--t-max": {"type": float, "default": None,
                              "help": "last time drawn (s); default one precession turn"}},
                 file_name="tip_locus.png")
    return theta, tip


THETA, TIP = _make_figures()
