"""Invariant drift: |X(t) − X0| / |X0| on a log scale for X = E, L_z, L_3.

Only invariants the file's scene declares (layout.conserved) are drawn.  One
panel per spin f (and θ0), wrapped into rows (analysis/figures/record.py); colour =
method, line style = dt; methods whose curves lie on top of each other are
named in the panel ("same curve: a = b").  Exact zeros
(an invariant a method keeps to the last bit, e.g. L_3 = I3 ω3 of a
symmetric top) are drawn at 1e-17, below double precision, and said so.
Runs that diverged (status ≠ 0) end where their samples turn NaN and are
marked "diverged" in the legend.
"""

import matplotlib.pyplot as plt
import numpy as np

from ...kernels import invariants as invariant_table
from ...kernels.invariants import invariant, needed_variables
from ...results.layout import conserved
from ..io import (
    DT_STYLES,
    FLOOR,
    QUANTITY_LABELS,
    SCALE_NAMES,
    drawable_invariants,
    error_series,
    fmt_dt,
    invariant_scale,
    line_style,
    missing_variable_error,
    relative_error,
    running_max,
    scene_label,
    scene_name,
    select,
)
from .record import (
    add_note,
    choose,
    coincidence_text,
    coincident,
    diverged_text,
    legend_below,
    method_groups,
    method_handles,
    methods_per_panel,
    panel_note,
    panel_size,
    refit_notes,
    run_title,
    subplots,
    suptitle,
)


def drift_table(ds, quantity="energy", sel=None):
    """{(method, f, theta0, dt): (max, final) relative error of ``quantity``} over each run."""
    sub = select(ds, sel)
    out = {}
    scale = _run_scales(sub, quantity)
    for m in sub.integrator.values:
        for f in sub.f.values:
            for th in sub.theta0.values:
                for dt in sub.dt.values:
                    at = {"integrator": m, "f": f, "theta0": th, "dt": dt}
                    run = sub[quantity].sel(at).values
                    err = relative_error(run, scale=None if scale is None else scale.sel(at).values)
                    finite = err[np.isfinite(err)]
                    final = err[-1] if np.isfinite(err[-1]) else np.inf
                    out[(str(m), float(f), float(th), float(dt))] = (
                        float(finite.max()) if finite.size else np.inf,
                        float(final),
                    )
    return out


def _check_quantity(ds, quantity):
    """ValueError unless the file's scene conserves ``quantity`` (layout.conserved)."""
    have = drawable_invariants(ds)
    if quantity not in have and quantity in conserved(ds):  # conserved, but the file does not hold it
        lacking = [v for v in needed_variables(quantity) if v not in ds.data_vars]
        raise missing_variable_error(ds, " and ".join(lacking), "energy")
    if not have:
        raise ValueError(f"the scene {scene_name(ds)} declares no conserved quantity: no drift to draw")
    if quantity not in have:
        raise ValueError(
            f"quantity={quantity}: the scene {scene_name(ds)} does not conserve it; choose from {', '.join(have)}"
        )


RUN_DIMS = ("integrator", "f", "theta0", "dt")


def _run_scales(sub, quantity):
    """``invariant_scale`` of ``quantity`` broadcast over the runs of ``sub`` (None: its own values)."""
    scale = invariant_scale(sub, quantity)
    return None if scale is None else scale.broadcast_like(sub.status).transpose(*RUN_DIMS)


def run_errors(sub, quantity):
    """{(method, f, θ0, dt): (error series, status)} of every run of ``sub``: the invariant computed once
    over the whole selection and each run's row taken from it (a figure draws thousands of runs, and
    selecting each run of the Dataset in turn took seconds)."""
    values = invariant(sub, quantity)
    values = values.transpose(*RUN_DIMS, "time", *(["xyz"] if "xyz" in values.dims else [])).values
    status = sub.status.transpose(*RUN_DIMS).values
    scale = _run_scales(sub, quantity)
    scale = np.full(status.shape, None) if scale is None else scale.values
    labels = [sub[d].values for d in RUN_DIMS]
    return {
        (str(m), float(f), float(th), float(dt)): (
            error_series(values[i, j, k, n], scale[i, j, k, n]),
            int(status[i, j, k, n]),
        )
        for i, m in enumerate(labels[0])
        for j, f in enumerate(labels[1])
        for k, th in enumerate(labels[2])
        for n, dt in enumerate(labels[3])
    }


def _series(errors, f, th, envelope, methods, dts):
    """{(method, dt): error series} of one panel from ``run_errors``; the running maximum when ``envelope``."""
    out = {}
    for m in methods:
        for dt in dts:
            err = errors[(str(m), float(f), float(th), float(dt))][0]
            out[(str(m), float(dt))] = running_max(err) if envelope else err
    return out


def _kept_exactly(err, status):
    """The run finished (status 0) with error 0 at every sample: a run that stopped in its first step
    has only its t = 0 sample finite, and that zero says nothing."""
    return status == 0 and bool(np.all(err[np.isfinite(err)] == 0))


def _coincidences(series):
    """Groups of methods whose curves lie on top of each other (within 0.02 decades) at every dt drawn."""
    dts = sorted({dt for _, dt in series})
    per_dt = []
    for dt in dts:
        logs = {m: np.log10(np.maximum(e, FLOOR)) for (m, d), e in series.items() if d == dt}
        per_dt.append({frozenset(g) for g in coincident(logs, 0.02)})
    common = set.intersection(*per_dt) if per_dt else set()
    order = [m for m, _ in series]
    # in the panel's method order: a set's order changes with the process's string hashing
    return sorted((sorted(g, key=order.index) for g in common), key=lambda g: order.index(g[0]))


def _scale_note(runs, quantity):
    """[note] when a run of ``runs`` (one panel's) starts with ``quantity`` ~0, so that its error is relative
    to the quantity's physical size (io.invariant_scale) rather than to its start; [] otherwise."""
    scale = invariant_scale(runs, quantity)
    if scale is None:
        return []
    size = float(scale.max())
    start = np.abs(invariant(runs.isel(time=0), quantity).values)
    if not np.any(start <= 1e-9 * size):
        return []
    sym = QUANTITY_LABELS.get(quantity, quantity)
    units = invariant_table.INVARIANTS[quantity].units
    return [f"{sym}(0) ≈ 0: relative to {SCALE_NAMES[quantity]} = {size:.3g} {units} instead"]


def _panel(ax, sub, quantity, f, th, envelope=True, methods=None, errors=None):
    """One panel: the drift of ``quantity`` of ``methods`` (default: all) at (f, θ0), colour and marker =
    method, line style = dt; a run that stopped ends in an ×.  ``errors``: ``run_errors(sub, quantity)``
    when the caller has it."""
    time = sub.time.values
    t_plot = np.where(time > 0, time, np.nan)  # log-x friendly; t=0 error is 0 by definition
    methods = [str(m) for m in sub.integrator.values] if methods is None else methods
    errors = run_errors(sub, quantity) if errors is None else errors
    series = _series(errors, f, th, envelope, methods, sub.dt.values)
    any_zero = False
    for (m, dt), err in series.items():
        k = list(sub.dt.values).index(dt)
        status = errors[(m, float(f), float(th), dt)][1]
        any_zero |= _kept_exactly(err, status)
        label = f"{m}" + (f", {fmt_dt(dt)}" if sub.dt.size > 1 else "")
        style = line_style(m, time.size)
        if status != 0:
            label += " (diverged)"
            last = np.flatnonzero(np.isfinite(err))
            if last.size:
                ax.plot(t_plot[last[-1]], max(err[last[-1]], FLOOR), "x", color=style["color"], ms=7)
        ax.plot(t_plot, np.maximum(err, FLOOR), DT_STYLES[k % 4], lw=1.0, label=label, **style)
    ax.set_yscale("log")
    ax.set_xlabel("time t (s)")
    sym = QUANTITY_LABELS.get(quantity, quantity)
    ax.set_ylabel(f"|Δ{sym}| / |{sym}(0)|")
    ax.set_title(run_title(sub, f, th), fontsize=9)
    ax.grid(alpha=0.3, which="major")
    # one box for the panel's notes: two boxes in a narrow panel met each other (the coincidences grow
    # downwards from the top, the floor note upwards from the bottom)
    notes = [coincidence_text(groups, "same curve")] if (groups := _coincidences(series)) else []
    if any_zero:
        notes.append("at 1e-17: exactly conserved")
    notes += _scale_note(sub.sel({"f": f, "theta0": th}), quantity)
    if notes:
        panel_note(ax, notes)
    return series


def _limits(axes):
    """Common log y-limits from the floor to above the largest finite value drawn (set after every panel)."""
    top = max(
        [
            np.nanmax(np.where(np.isfinite(y := ln.get_ydata()), y, np.nan), initial=FLOOR)
            for ax in axes
            for ln in ax.get_lines()
            if len(ln.get_ydata())
        ]
        or [1.0]
    )
    for ax in axes:
        ax.set_ylim(FLOOR / 3, max(top * 5, 1e-15))


def drift_figure(ds, quantity="energy", sel=None, envelope=True):
    """Relative drift of ``quantity`` (an invariant the scene conserves) vs time (s), one panel per f and
    θ0, wrapped into rows; a grid too large is drawn in part and the figure says which part.

    ``envelope``: draw the running maximum of the error (the drift) rather
    than the raw error, which oscillates with every nutation.
    """
    if quantity not in QUANTITY_LABELS:
        raise ValueError(f"quantity={quantity}: choose from {', '.join(QUANTITY_LABELS)}")
    _check_quantity(ds, quantity)
    sub, note = choose(select(ds, sel), "energy" + (f" --quantity {quantity}" if quantity != "energy" else ""))
    groups = method_groups(sub.integrator.values)
    panels = [(f, th) for f in sub.f.values for th in sub.theta0.values]
    if len(groups) == 1:  # panels wrap into rows of 3
        fig, axes = subplots(len(panels), width=4.6, height=3.6, sharey=True)
        cells = [(ax, f, th, groups[0]) for ax, (f, th) in zip(axes, panels)]
    else:  # one row per (f, θ0), one column per group of methods: every method drawn
        rows, cols = len(panels), len(groups)
        fig, grid = plt.subplots(rows, cols, figsize=panel_size(rows, cols, 4.2, 3.0), squeeze=False, sharey=True)
        cells = [(grid[r, c], f, th, g) for r, (f, th) in enumerate(panels) for c, g in enumerate(groups)]
        axes = list(grid.ravel())
    errors = run_errors(sub, quantity)
    for ax, f, th, methods in cells:
        _panel(ax, sub, quantity, f, th, envelope, methods, errors)
    _limits(axes)
    sym = QUANTITY_LABELS[quantity]
    suptitle(
        fig,
        f"Relative drift of {sym}: {scene_label(sub)}, {float(sub.time[-1]):g} s; "
        + (
            f"max over s ≤ t of |{sym}(s) − {sym}(0)| / |{sym}(0)|"
            if envelope
            else f"|{sym}(t) − {sym}(0)| / |{sym}(0)|"
        ),
        fontsize=10.5,
    )
    fig.tight_layout()
    refit_notes(fig)
    add_note(fig, note)
    handles, labels = method_handles([m for g in groups for m in g], list(sub.dt.values), diverged_text(sub))
    legend_below(fig, handles, labels, ncol=min(len(labels), 5))
    return fig


def invariants_figure(ds, sel=None, envelope=True):
    """One row per invariant the scene declares (layout.conserved), one column per f (θ0), at most 4
    columns: every invariant's relative drift on log axes.  Quantities the scene does not conserve are
    not drawn; one that every drawn run keeps exactly (error 0) gets no row, the figure says so."""
    quantities = drawable_invariants(ds)
    if not quantities and conserved(ds):
        needed = sorted({v for q in conserved(ds) for v in needed_variables(q) if v not in ds.data_vars})
        raise missing_variable_error(ds, " or ".join(needed), "invariants")
    if not quantities and not conserved(ds):
        raise ValueError(f"the scene {scene_name(ds)} declares no conserved quantity: no invariant to draw")
    if not quantities:
        raise ValueError("the file's scene declares no invariant that its variables hold")
    # one row per invariant and group of methods, one column per (f, θ0): at most 5 columns
    per_panel = methods_per_panel(ds.integrator.size, len(quantities))
    n_groups = len(method_groups(ds.integrator.values, per_panel))
    sub, note = choose(select(ds, sel), "invariants", per_panel, max_panels=5, rows_each=len(quantities))
    groups = method_groups(sub.integrator.values, per_panel)
    panels = [(f, th) for f in sub.f.values for th in sub.theta0.values]
    exact, quantities_drawn = [], []
    errors = {q: run_errors(sub, q) for q in quantities}
    for q in quantities:
        (exact if all(_kept_exactly(*e) for e in errors[q].values()) else quantities_drawn).append(q)
    quantities_drawn = quantities_drawn or quantities[:1]
    rows = [(q, g) for q in quantities_drawn for g in range(n_groups)]
    width, height = panel_size(len(rows), len(panels), 4.4, 2.9)
    fig, axes = plt.subplots(len(rows), len(panels), figsize=(width, height), squeeze=False, sharex=True)
    for r, (q, g) in enumerate(rows):
        for c, (f, th) in enumerate(panels):
            _panel(axes[r, c], sub, q, f, th, envelope, groups[g], errors[q])
            if r < len(rows) - 1:
                axes[r, c].set_xlabel("")
            if r > 0:
                axes[r, c].set_title("")
            if c > 0:
                axes[r, c].set_ylabel("")
            elif n_groups > 1:
                axes[r, c].set_ylabel(axes[r, c].get_ylabel() + f"\nmethods {g + 1} of {n_groups}", fontsize=8)
    for q in quantities_drawn:  # one y range per invariant, over all its rows
        _limits([ax for r, (q2, _) in enumerate(rows) if q2 == q for ax in axes[r]])
    names = ", ".join(QUANTITY_LABELS.get(q, q) for q in quantities_drawn)
    suptitle(
        fig,
        f"Invariants {names}: relative drift (running maximum), {scene_label(sub)}, {float(sub.time[-1]):g} s",
        fontsize=10.5,
    )
    fig.tight_layout()
    refit_notes(fig)
    if exact:
        add_note(
            fig,
            ", ".join(QUANTITY_LABELS.get(q, q) for q in exact) + ": kept exactly (error 0) by every run drawn; no row",
        )
    add_note(fig, note)
    handles, labels = method_handles([m for g in groups for m in g], list(sub.dt.values), diverged_text(sub))
    legend_below(fig, handles, labels, ncol=min(len(labels), 5))
    return fig


def _make_figures():
    from .record import Figure

    raw = {"--raw": {"action": "store_true", "help": "raw error instead of its running maximum"}}
    drift = Figure(
        "energy",
        "relative drift of an invariant vs time (log scale)",
        lambda ds, sel=None, quantity="energy", raw=False: drift_figure(ds, quantity, sel, not raw),
        {"--quantity": {"choices": list(QUANTITY_LABELS), "default": "energy"}, **raw},
        file_name="energy_drift.png",
    )
    invariants = Figure(
        "invariants",
        "drift of every invariant the scene conserves, in one figure",
        lambda ds, sel=None, raw=False: invariants_figure(ds, sel, not raw),
        raw,
        file_name="invariants.png",
    )
    return drift, invariants


DRIFT, INVARIANTS = _make_figures()
