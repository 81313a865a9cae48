"""Stability map: log10 of the worst error over a (dt × f) grid, one panel per method (rows of 5).

The error is the max relative energy error, or, for a scene whose closed
form gives the exact motion (free bodies, analysis/figures/yardstick.py), the max
deviation of the axis from the exact one (rad): energy alone cannot tell
methods apart that advance ω alike (seed_next, seed_prev and rk4 on the free
box).  Methods whose maps are identical are named in the panel titles.

Cells are drawn on log-log axes (dt in s, f in Hz), so lines of constant
ω3·dt = 2π f dt (rad of spin per step) are straight: dotted guides at
ω3·dt = 0.01, 0.1, 1.  Runs that diverged (status ≠ 0: NaN/inf or energy
past the runner's threshold) are grey, hatched and marked ×, runs whose
implicit solver did not converge (status unconverged) the same but marked ○: the worst
error a run reached before it stopped says nothing of how good it was (a
run that is exact until its state turns NaN would take the best colour).  A file from ``gyrolab-combine``
with a ``scene`` (or ``job``) dimension gets one row of panels per scene.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import NullFormatter

from ...kernels.driver import STATUS_UNCONVERGED
from ..io import invariant_scale, pick, relative_error, scene_label, select
from . import yardstick
from .record import add_note, facet, panel_size, suptitle, wrap_note

VMIN, VMAX = -16.0, 1.0


def _edges(values, log=True):
    """Cell edges around sorted ``values``: on a log axis (positive values) the geometric midpoints, on a
    linear one (``log=False``: a spin f = 0 among the rows) the arithmetic ones."""
    v = np.sort(np.asarray(values, dtype=float))
    if not log:
        if v.size == 1:
            return np.array([v[0] - 0.5, v[0] + 0.5])
        mids = 0.5 * (v[1:] + v[:-1])
        return np.concatenate(([2 * v[0] - mids[0]], mids, [2 * v[-1] - mids[-1]]))
    if v.size == 1:
        return np.array([v[0] / 1.6, v[0] * 1.6])
    mids = np.sqrt(v[1:] * v[:-1])
    return np.concatenate(([v[0] ** 2 / mids[0]], mids, [v[-1] ** 2 / mids[-1]]))


def max_energy_error(energy, scale=None):
    """log10 of max_t |E − E0|/|E0| per run; ``energy`` (..., time) in J; NaN samples skipped; ``scale``
    (...) J: the energy's size, for E0 ~ 0 (io.relative_error)."""
    err = relative_error(np.asarray(energy), scale=None if scale is None else np.asarray(scale)[..., None])
    with np.errstate(all="ignore"):
        worst = np.nanmax(np.where(np.isfinite(err), err, np.nan), axis=-1)
    return np.log10(np.maximum(worst, 1e-17))


def max_axis_error(axis, exact):
    """log10 of max_t |axis − axis_exact| (rad) per run; axis (..., time, 3), exact (time, 3) per f."""
    d = np.linalg.norm(np.asarray(axis) - exact, axis=-1)
    with np.errstate(all="ignore"):
        worst = np.nanmax(np.where(np.isfinite(d), d, np.nan), axis=-1)
    return np.log10(np.maximum(worst, 1e-17))


def _logerr(run, theta0, measure, full):
    """(f, dt) array of log10 errors of one method's runs (run: dims f, dt, time[, xyz]; full: the file's
    Dataset, for the stored run inputs)."""
    if measure == "energy":
        scale = invariant_scale(run, "energy")
        if scale is not None:
            scale = scale.broadcast_like(run.status).transpose("f", "dt").values
        return max_energy_error(run.energy.transpose("f", "dt", "time").values, scale)
    out = np.empty((run.f.size, run.dt.size))
    for i, f in enumerate(run.f.values):
        exact = yardstick.exact_axis(full, f, theta0, run.time.values)
        out[i] = max_axis_error(run.axis.sel({"f": f}).transpose("dt", "time", "xyz").values, exact)
    return out


def _panel(ax, sub, method, theta0, measure="energy"):
    run = sub.sel({"integrator": method, "theta0": theta0})  # dims f, dt (time)
    run = run.sortby("f").sortby("dt")
    logerr = _logerr(run, theta0, measure, sub)
    status = run.status.transpose("f", "dt").values
    f, dt = run.f.values, run.dt.values
    f_log = bool(np.all(f > 0))  # a non-spinning row (f = 0) puts the spins on a linear axis
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.8")  # diverged cells: grey, no colour of the scale
    shown = np.ma.masked_where((status != 0) | ~np.isfinite(logerr), logerr)
    mesh = ax.pcolormesh(_edges(dt), _edges(f, f_log), shown, cmap=cmap, vmin=VMIN, vmax=VMAX, shading="flat")
    for i, fv in enumerate(f):
        for j, dv in enumerate(dt):
            if status[i, j] == STATUS_UNCONVERGED:  # the implicit solver gave up: a ring, not a cross
                ax.plot(dv, fv, "o", color="red", mfc="none", ms=8, mew=2)
            elif status[i, j] != 0:
                ax.plot(dv, fv, "x", color="red", ms=9, mew=2)
            else:
                ax.text(
                    dv,
                    fv,
                    f"{int(round(logerr[i, j]))}",
                    ha="center",
                    va="center",
                    fontsize=6.5,
                    color="white" if logerr[i, j] < -6 else "black",
                )
    bad = np.argwhere(status != 0)
    for i, j in bad:
        xe, ye = _edges(dt), _edges(f, f_log)
        ax.fill_between([xe[j], xe[j + 1]], ye[i], ye[i + 1], facecolor="none", edgecolor="red", hatch="///", lw=0)
    ax.set_xscale("log")
    ax.set_yscale("log" if f_log else "linear")
    for axis in (ax.xaxis, ax.yaxis):  # decade labels only: minor labels (2×10^-4, ...) collide
        axis.set_minor_formatter(NullFormatter())
    xe, ye = _edges(dt), _edges(f, f_log)
    grid_dt = np.geomspace(xe[0], xe[-1], 50)
    for w in (0.01, 0.1, 1.0):
        ax.plot(grid_dt, w / (2 * math.pi * grid_dt), ":", color="white", lw=1.0)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel("time step dt (s)")
    ax.set_ylabel("spin f (Hz)")
    n_unconverged = int((status == STATUS_UNCONVERGED).sum())
    n_bad = int((status != 0).sum()) - n_unconverged
    failed = ", ".join(
        [f"{n_bad} diverged (x)"] * bool(n_bad) + [f"{n_unconverged} solver failed (o)"] * bool(n_unconverged)
    )
    # what the map adds to the name goes on a line of its own: beside the name it ran into the next title
    ax.set_title(method + (f"\n{failed}" if failed else ""), fontsize=9)
    return mesh, np.where(status != 0, np.nan, logerr)


def default_measure(ds):
    """'axis' when the scene's closed form gives the exact motion, else 'energy'."""
    return (
        "axis"
        if yardstick.exact_axis(ds, ds.f.values[0], ds.theta0.values[0], ds.time.values[:2]) is not None
        else "energy"
    )


def stability_figure(ds, sel=None, theta0=None, measure=None):
    """Heatmap per method of log10 worst error over dt × f (θ0 fixed: the first, or ``theta0``);
    ``measure`` 'energy' or 'axis' (default: default_measure).  Panels wrap into rows of 5."""
    sub = select(ds, sel)
    th = sub.theta0.values[0] if theta0 is None else pick(sub, "theta0", theta0)
    extra = [d for d in ("scene", "job") if d in sub.dims]
    note = None  # every method, f and dt is drawn (one map per method; θ0: the note below)
    measure = measure or (default_measure(sub) if not extra else "energy")
    if measure not in ("energy", "axis"):
        raise ValueError(f"measure={measure}: choose from energy, axis")
    if measure == "axis" and default_measure(sub) != "axis":
        raise ValueError(f"measure=axis: the scene {scene_label(sub)} has no exact motion to measure against")
    methods = [str(m) for m in sub.integrator.values]
    parts = [(v, sub.sel({extra[0]: v})) for v in sub[extra[0]].values] if extra else [(None, sub)]
    # every method drawn: rows of 5 maps, each scene (job) of a combined file starting its own rows
    per_part, cols = facet(len(methods), 5)
    rows = per_part * len(parts)
    cells = [
        (p * per_part + k // cols, k % cols, label, part, m)
        for p, (label, part) in enumerate(parts)
        for k, m in enumerate(methods)
    ]
    fig, axes = plt.subplots(
        rows, cols, figsize=panel_size(rows, cols, 3.4, 3.2, extra_w=1.4, extra_h=1.6), squeeze=False
    )
    mesh, maps = None, {}
    for r, c, label, part, m in cells:
        mesh, values = _panel(axes[r, c], part, m, th, measure)
        maps[(label, m)] = values
        if c > 0:
            axes[r, c].set_ylabel("")
            axes[r, c].tick_params(labelleft=False)  # every panel has the same f axis
        if label is not None and c == 0:
            axes[r, c].set_ylabel(f"{label}\nspin f (Hz)")
    used = {(r, c) for r, c, *_ in cells}
    for r, c in used:  # one dt label per column, under its lowest map (it ran into the titles below)
        if (r + 1, c) in used:
            axes[r, c].set_xlabel("")
    fig.subplots_adjust(hspace=0.5)
    for (r, c), ax in np.ndenumerate(axes):
        if (r, c) not in used:
            ax.set_visible(False)
    # identical maps (to 0.01 decades): a short tag in the title, the groups in the note under the figure
    # (the names in the titles printed over the row above once a group had more than two members)
    same_groups, tag_of = [], {}
    for label, part in parts:
        seen = set()
        for m in methods:
            if m in seen:
                continue
            group = [
                m2
                for m2 in methods
                if m2 not in seen
                and maps[(label, m2)].shape == maps[(label, m)].shape
                and np.allclose(maps[(label, m2)], maps[(label, m)], atol=0.01, equal_nan=True)
            ]
            if len(group) > 1:
                tag = chr(ord("A") + len(same_groups) % 26)
                same_groups.append((label, tag, group))
                seen.update(group)
                tag_of.update({(label, g): tag for g in group})
    for r, c, label, _, m in cells:
        if (label, m) in tag_of:
            title = axes[r, c].get_title()
            tag = f"map {tag_of[(label, m)]}"
            axes[r, c].set_title(f"{title}, {tag}" if "\n" in title else f"{title}\n{tag}", fontsize=9)
    if same_groups:
        add_note(
            fig,
            "identical maps (within 0.01 decades): "
            + "; ".join(
                f"{tag}{f' ({label})' if label is not None else ''}: {' = '.join(g)}" for label, tag, g in same_groups
            ),
        )
    cbar = fig.colorbar(mesh, ax=axes, shrink=0.9, pad=0.03)
    what_err = "max_t |E(t) − E0| / |E0|" if measure == "energy" else "max_t |axis − axis_exact| (rad)"
    cbar.set_label(f"log10 {what_err}")
    t_end = float(sub.time[-1])
    what = scene_label(sub) if not extra else ", ".join(str(v) for v in sub[extra[0]].values)
    against = (
        "" if measure == "energy" else f" against the {yardstick.label(sub)}".replace(" exact (", " exact motion (")
    )
    ringed = "; ○: solver did not converge" if bool((sub.status == STATUS_UNCONVERGED).any()) else ""
    suptitle(
        fig,
        f"Stability map: {what}, θ0 = {float(th):g}°, {t_end:g} s; {what_err}{against}\n"
        f"numbers: log10 error; grey, red × hatched: diverged{ringed}; dotted: ω3·dt = 0.01, 0.1, 1 rad per step",
        fontsize=10.5,
        y=1.0 + 0.12 / rows,
    )
    others = [f"{v:g}" for v in sub.theta0.values if float(v) != float(th)]
    if others:
        add_note(
            fig,
            f"drawn: θ0 = {float(th):g}° (one θ0 per map); the others, one per figure: "
            + ", ".join(f"gyrolab-plot stability FILE theta0={v}" for v in others),
        )
    add_note(fig, note)
    notes = getattr(fig, "gyrolab_notes", [])
    if notes:
        fig.text(0.01, -0.02, "\n".join(wrap_note(n, fig) for n in notes), fontsize=7.5, color="0.25", va="top")
    return fig


def _make_figure():
    from .record import Figure

    return Figure(
        "stability",
        "heatmap of log10 worst error (energy, or axis vs the exact motion) over dt x f",
        lambda ds, sel=None, measure=None: stability_figure(ds, sel, measure=measure),
        {
            "--measure": {
                "choices": ["energy", "axis"],
                "default": None,
                "help": "error drawn (default: axis against the exact motion when the scene has one, else energy)",
            }
        },
        file_name="stability_map.png",
    )


FIGURE = _make_figure()
