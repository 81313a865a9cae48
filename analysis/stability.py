"""Stability map: log10 of the max relative energy error over a (dt × f) grid, one panel per method.

Cells are drawn on log-log axes (dt in s, f in Hz), so lines of constant
ω3·dt = 2π f dt (rad of spin per step) are straight: dotted guides at
ω3·dt = 0.01, 0.1, 1.  Runs that diverged (status ≠ 0: NaN/inf or energy
past the runner's threshold) are hatched and marked ×; their colour is the
worst error reached before they stopped.  A file from ``gyrolab-combine``
with a ``scene`` (or ``job``) dimension gets one row of panels per scene.
"""
import math

import matplotlib.pyplot as plt
import numpy as np

from .io import relative_error, scene_label, select

VMIN, VMAX = -16.0, 1.0


def _edges(values):
    """Cell edges on a log axis around sorted positive ``values`` (geometric midpoints)."""
    v = np.sort(np.asarray(values, dtype=float))
    if v.size == 1:
        return np.array([v[0] / 1.6, v[0] * 1.6])
    mids = np.sqrt(v[1:] * v[:-1])
    return np.concatenate(([v[0] ** 2 / mids[0]], mids, [v[-1] ** 2 / mids[-1]]))


def max_energy_error(energy):
    """log10 of max_t |E − E0|/|E0| per run; ``energy`` (..., time) in J; NaN samples skipped."""
    err = relative_error(np.asarray(energy))
    with np.errstate(all="ignore"):
        worst = np.nanmax(np.where(np.isfinite(err), err, np.nan), axis=-1)
    return np.log10(np.maximum(worst, 1e-17))


def _panel(ax, sub, method, theta0):
    run = sub.sel({"method": method, "theta0": theta0})  # dims f, dt (time)
    run = run.sortby("f").sortby("dt")
    logerr = max_energy_error(run.energy.transpose("f", "dt", "time").values)
    status = run.status.transpose("f", "dt").values
    f, dt = run.f.values, run.dt.values
    mesh = ax.pcolormesh(_edges(dt), _edges(f), logerr, cmap="viridis", vmin=VMIN, vmax=VMAX, shading="flat")
    for i, fv in enumerate(f):
        for j, dv in enumerate(dt):
            if status[i, j] != 0:
                ax.plot(dv, fv, "x", color="red", ms=9, mew=2)
            else:
                ax.text(dv, fv, f"{int(round(logerr[i, j]))}", ha="center", va="center", fontsize=6.5,
                        color="white" if logerr[i, j] < -6 else "black")
    bad = np.argwhere(status != 0)
    for i, j in bad:
        xe, ye = _edges(dt), _edges(f)
        ax.fill_between([xe[j], xe[j + 1]], ye[i], ye[i + 1], facecolor="none", edgecolor="red", hatch="///", lw=0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    xe, ye = _edges(dt), _edges(f)
    grid_dt = np.geomspace(xe[0], xe[-1], 50)
    for w in (0.01, 0.1, 1.0):
        ax.plot(grid_dt, w / (2 * math.pi * grid_dt), ":", color="white", lw=1.0)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel("time step dt (s)")
    ax.set_ylabel("spin f (Hz)")
    n_bad = int((status != 0).sum())
    ax.set_title(f"{method}" + (f" ({n_bad} diverged)" if n_bad else ""), fontsize=9)
    return mesh


def stability_figure(ds, sel=None, theta0=None):
    """Heatmap per method of log10 max relative energy error over dt × f (θ0 fixed: the first, or ``theta0``)."""
    sub = select(ds, sel)
    th = sub.theta0.values[0] if theta0 is None else theta0
    extra = [d for d in ("scene", "job") if d in sub.dims]
    rows = [(None, sub)] if not extra else [(v, sub.sel({extra[0]: v})) for v in sub[extra[0]].values]
    methods = [str(m) for m in sub.method.values]
    fig, axes = plt.subplots(len(rows), len(methods), figsize=(3.5 * len(methods) + 1.2, 3.3 * len(rows) + 0.9),
                             squeeze=False)
    mesh = None
    for r, (label, part) in enumerate(rows):
        for c, m in enumerate(methods):
            mesh = _panel(axes[r, c], part, m, th)
            if c > 0:
                axes[r, c].set_ylabel("")
            if label is not None and c == 0:
                axes[r, c].set_ylabel(f"{label}\nspin f (Hz)")
    cbar = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.04)
    cbar.set_label("log10 max_t |E(t) − E0| / |E0|")
    t_end = float(sub.time[-1])
    what = scene_label(sub) if not extra else ", ".join(str(v) for v, _ in rows)
    fig.suptitle(f"Stability map: {what}, θ0 = {float(th):g}°, {t_end:g} s "
                 "\nnumbers: log10 error; red × hatched: diverged; dotted: ω3·dt = 0.01, 0.1, 1 rad per step", fontsize=10.5,
                 y=1.06)
    return fig


def _make_figure():
    from .figure import Figure

    return Figure("stability", "heatmap of log10 max energy error over dt x f per method",
                  lambda ds, sel=None: stability_figure(ds, sel), file_name="stability_map.png", thinned=False)


FIGURE = _make_figure()
