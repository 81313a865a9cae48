"""Invariant drift: |X(t) − X0| / |X0| on a log scale for X = E, L_z, L_3.

One panel per spin f (and θ0); colour = method, line style = dt.  Exact zeros
(an invariant a method keeps to the last bit, e.g. L_3 = I3 ω3 of a
symmetric top) are drawn at 1e-17, below double precision, and said so.
Runs that diverged (status ≠ 0) end where their samples turn NaN and are
marked "diverged" in the legend.
"""
import matplotlib.pyplot as plt
import numpy as np

from .io import (
    DT_STYLES,
    FLOOR,
    QUANTITY_LABELS,
    color,
    drawable_invariants,
    fmt_dt,
    invariant_error,
    relative_error,
    scene_label,
    select,
)


def drift_table(ds, quantity="energy", sel=None):
    """{(method, f, theta0, dt): (max, final) relative error of ``quantity``} over each run."""
    sub = select(ds, sel)
    out = {}
    for m in sub.method.values:
        for f in sub.f.values:
            for th in sub.theta0.values:
                for dt in sub.dt.values:
                    run = sub[quantity].sel({"method": m, "f": f, "theta0": th, "dt": dt}).values
                    err = relative_error(run)
                    finite = err[np.isfinite(err)]
                    final = err[-1] if np.isfinite(err[-1]) else np.inf
                    out[(str(m), float(f), float(th), float(dt))] = (float(finite.max()) if finite.size else np.inf,
                                                                      float(final))
    return out


def _panel(ax, sub, quantity, f, th, envelope=True):
    time = sub.time.values
    t_plot = np.where(time > 0, time, np.nan)  # log-x friendly; t=0 error is 0 by definition
    any_zero = False
    for m in sub.method.values:
        for k, dt in enumerate(sub.dt.values):
            run = sub.sel({"method": m, "f": f, "theta0": th, "dt": dt})
            err = invariant_error(run, quantity)
            if envelope:  # running maximum: the drift, without the oscillation within each nutation
                err = np.fmax.accumulate(err)
            any_zero |= bool(np.all(err[np.isfinite(err)] == 0))
            label = f"{m}" + (f", {fmt_dt(dt)}" if sub.dt.size > 1 else "")
            if int(run.status) != 0:
                label += " (diverged)"
                last = np.flatnonzero(np.isfinite(err))
                if last.size:
                    ax.plot(t_plot[last[-1]], max(err[last[-1]], FLOOR), "x", color=color(m), ms=7)
            ax.plot(t_plot, np.maximum(err, FLOOR), DT_STYLES[k % 4], color=color(m), lw=1.0, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("time t (s)")
    sym = QUANTITY_LABELS.get(quantity, quantity)
    text = f"|{sym}(t) − {sym}(0)| / |{sym}(0)|"
    ax.set_ylabel(f"max over s ≤ t of {text.replace('(t)', '(s)')}" if envelope else text)
    ax.set_title(f"f = {f:g} Hz, θ0 = {th:g}°", fontsize=9)
    ax.grid(alpha=0.3, which="major")
    ax.set_ylim(bottom=FLOOR / 3)
    if any_zero:
        ax.text(0.99, 0.02, "at 1e-17: exactly conserved", transform=ax.transAxes, ha="right", fontsize=7,
                color="0.3")


def drift_figure(ds, quantity="energy", sel=None, envelope=True):
    """Relative drift of ``quantity`` ('energy', 'Lz' or 'L3') vs time (s), one panel per f and θ0.

    ``envelope``: draw the running maximum of the error (the drift) rather
    than the raw error, which oscillates with every nutation.
    """
    if quantity not in QUANTITY_LABELS:
        raise ValueError(f"quantity={quantity}: choose from {', '.join(QUANTITY_LABELS)}")
    sub = select(ds, sel)
    panels = [(f, th) for f in sub.f.values for th in sub.theta0.values]
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n + 0.6, 4.2), squeeze=False, sharey=True)
    for ax, (f, th) in zip(axes[0], panels):
        _panel(ax, sub, quantity, f, th, envelope)
    for ax in axes[0, 1:]:
        ax.set_ylabel("")
    sym = QUANTITY_LABELS[quantity]
    fig.suptitle(f"Relative drift of {sym}: {scene_label(sub)}, {float(sub.time[-1]):g} s"
                 + (" (running maximum)" if envelope else ""), fontsize=11)
    fig.tight_layout()
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=min(len(labels), 5),
               fontsize=8, frameon=False)
    return fig


def invariants_figure(ds, sel=None, envelope=True):
    """One row per invariant the scene declares (layout.conserved), by columns f (θ0): every
    invariant's relative drift on log axes.  Quantities the scene does not conserve are not drawn."""
    sub = select(ds, sel)
    panels = [(f, th) for f in sub.f.values for th in sub.theta0.values]
    quantities = drawable_invariants(sub)
    if not quantities:
        raise ValueError("the file's scene declares no invariant that its variables hold")
    fig, axes = plt.subplots(len(quantities), len(panels), figsize=(4.4 * len(panels) + 0.6, 3.0 * len(quantities) + 0.5),
                             squeeze=False, sharex=True)
    for r, q in enumerate(quantities):
        for c, (f, th) in enumerate(panels):
            _panel(axes[r, c], sub, q, f, th, envelope)
            if r < len(quantities) - 1:
                axes[r, c].set_xlabel("")
            if r > 0:
                axes[r, c].set_title("")
    names = ", ".join(QUANTITY_LABELS.get(q, q) for q in quantities)
    fig.suptitle(f"Invariants {names}: relative drift, {scene_label(sub)}", fontsize=11)
    fig.tight_layout()
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=min(len(labels), 5),
               fontsize=8, frameon=False)
    return fig


def _make_figures():
    from .figure import Figure

    raw = {"--raw": {"action": "store_true", "help": "raw error instead of its running maximum"}}
    drift = Figure("energy", "relative drift of an invariant vs time (log scale)",
                   lambda ds, sel=None, quantity="energy", raw=False: drift_figure(ds, quantity, sel, not raw),
                   {"--quantity": {"choices": list(QUANTITY_LABELS), "default": "energy"}, **raw},
                   file_name="energy_drift.png")
    invariants = Figure("invariants", "drift of every invariant the scene conserves, in one figure",
                        lambda ds, sel=None, raw=False: invariants_figure(ds, sel, not raw), raw,
                        file_name="invariants.png")
    return drift, invariants


DRIFT, INVARIANTS = _make_figures()
