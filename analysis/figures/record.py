"""The record of one figure kind (the registry is analysis/figures/registry.py), and the layout rules every
figure shares: faceting (panels wrap into rows, bounded size), every method drawn (method groups of
at most MAX_METHODS curves a panel), selections of f, θ0, dt that say what they drew, notes where
curves coincide, panel titles in the problem's own terms, and the load a timing ran under.

It imports neither matplotlib nor xarray (analysis/io.py only where a figure is written): the dry run
costs the figure step from these limits (analysis/figures/cost.py) without them.
"""

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

MAX_COLS = 3  # panels per row before wrapping
MAX_PANELS = 9  # panels drawn before values are selected (and the figure says which)
MAX_METHODS = 8  # curves of different methods in one panel; more methods are faceted into more panels
MAX_CELLS = 60  # panels in one figure (panels per method group × method groups): past it, f and θ0 are selected
MAX_DT = 3  # line styles (dt values) in one panel
# Rows of panels in one figure (method groups × rows per group): past it a figure taller than MAX_HEIGHT
# shrinks every panel until its notes and tick labels collide, so a panel takes more methods instead
# (methods_per_panel).  12 is what the engines study's invariants figure (4 invariants × 3 groups) had.
MAX_ROWS = 12
MAX_WIDTH, MAX_HEIGHT = 15.5, 15.0  # inches (× 110 dpi in PNG)


@dataclass(frozen=True)
class Figure:
    """One figure kind.

    name: the CLI kind and the name in ``output.figures``; help: one line for
    ``--help``; draw(ds, sel, **options) -> matplotlib Figure, from a results
    Dataset and a selection dict; options: {flag: argparse kwargs} of its own
    CLI options (their ``dest`` names are the keyword arguments of draw);
    file_name: the PNG written by the figure step; render: optional
    render(ds, out, sel, **options) -> path for figures that are not a single
    matplotlib Figure (the animation writes a GIF).
    """

    name: str
    help: str
    draw: Callable = None
    options: dict = field(default_factory=dict)
    file_name: str = None
    render: Callable = None

    def write(self, ds, out, sel=None, formats=("png",), notes=None, **options):
        """Draw into ``out`` (suffix replaced per format); the written path.  ``notes`` (a list), when
        given, receives the figure's selection notes (what it drew, how to draw the rest)."""
        from ..io import absent_variable, missing_variable_error, save_figure

        try:
            if self.render is not None:
                return self.render(ds, out, sel=sel, **options)
            fig = self.draw(ds, sel, **options)
        except (KeyError, AttributeError) as err:
            missing = absent_variable(ds, err)
            if missing is None:
                raise
            raise missing_variable_error(ds, missing, self.name) from None
        if notes is not None:
            notes.extend(getattr(fig, "gyrolab_notes", []))
        return save_figure(fig, out, formats=formats)


def facet(n, max_cols=MAX_COLS):
    """(rows, cols) of ``n`` panels wrapped into rows of at most ``max_cols``."""
    cols = max(1, min(n, max_cols))
    return math.ceil(n / cols), cols


def panel_size(rows, cols, width, height, extra_w=0.6, extra_h=1.4):
    """Figure size (in) for rows × cols panels of width × height in, shrunk to the bounds."""
    w = cols * width + extra_w
    h = rows * height + extra_h
    s = min(1.0, MAX_WIDTH / w, MAX_HEIGHT / h)
    return w * s, h * s


def subplots(n, width=4.6, height=3.6, max_cols=MAX_COLS, **kwargs):
    """(fig, axes list of length n) with panels wrapped into rows; unused cells hidden."""
    import matplotlib.pyplot as plt

    rows, cols = facet(n, max_cols)
    fig, axes = plt.subplots(rows, cols, figsize=panel_size(rows, cols, width, height), squeeze=False, **kwargs)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def _fmt(key, v):
    return str(v) if key == "integrator" else f"{float(v):g}"


UNITS = {"f": " Hz", "theta0": "°", "dt": " s", "integrator": ""}
NAMES = {"f": "f", "theta0": "θ0", "dt": "dt", "integrator": "integrator"}


def limit(ds, key, n, prefer=None):
    """(kept, dropped) values of grid axis ``key``: all when ≤ n, else n evenly spread ones (ends
    kept) or, with ``prefer`` (a list), those first."""
    values = list(ds[key].values)
    if len(values) <= n:
        return values, []
    if prefer:
        kept = [v for v in values if str(v) in set(map(str, prefer))][:n]
        kept += [v for v in values if v not in kept][: n - len(kept)]
    else:
        idx = np.unique(np.round(np.linspace(0, len(values) - 1, n)).astype(int))
        kept = [values[i] for i in idx]
    return kept, [v for v in values if v not in kept]


def select_note(kind, kept, dropped):
    """One line: which values were drawn and the command that draws the others; None if nothing dropped.

    kind: the figure kind, optionally followed by selections the command keeps ("tip integrator=rk4");
    kept, dropped: {key: [values]}."""
    dropped = {k: v for k, v in dropped.items() if len(v)}
    if not dropped:
        return None
    drew = "; ".join(f"{NAMES[k]} = {', '.join(_fmt(k, v) for v in kept[k])}{UNITS[k]}" for k in dropped)
    rest = " ".join(f"{k}={','.join(_fmt(k, v) for v in vals)}" for k, vals in dropped.items())
    kind, _, fixed = kind.partition(" ")  # "tip integrator=rk4": the kind, then selections it keeps
    return f"drawn: {drew}; the others: gyrolab-plot {kind} FILE {(fixed + ' ') if fixed else ''}{rest}"


def add_note(fig, text):
    """Keep ``text`` in ``fig.gyrolab_notes``: legend_below writes it under the figure, the CLI prints it."""
    if not text:
        return
    notes = getattr(fig, "gyrolab_notes", [])
    fig.gyrolab_notes = notes + [text]


def coincident(series, tol):
    """Groups (lists of ≥ 2 labels, in order) of ``series`` ({label: 1-d array}) that agree within
    ``tol`` everywhere both are finite, i.e. that would be drawn on top of each other."""
    labels = list(series)
    groups, seen = [], set()
    for i, a in enumerate(labels):
        if a in seen:
            continue
        group = [a]
        for b in labels[i + 1 :]:
            if b in seen:
                continue
            x, y = np.asarray(series[a], float), np.asarray(series[b], float)
            if x.shape != y.shape:
                continue
            both = np.isfinite(x) & np.isfinite(y)
            same_support = np.array_equal(np.isfinite(x), np.isfinite(y))
            if both.any() and same_support and np.max(np.abs(x[both] - y[both])) <= tol:
                group.append(b)
        if len(group) > 1:
            groups.append(group)
            seen.update(group)
    return groups


def coincidence_text(groups, what="curves coincide"):
    """'curves coincide: a = b; c = d' or '' for no groups."""
    return f"{what}: " + "; ".join(" = ".join(g) for g in groups) if groups else ""


def methods_per_panel(n_methods, rows_each=1):
    """Curves of different methods in one panel for a figure of ``rows_each`` rows per method group:
    MAX_METHODS, or as many more as keep the groups' rows within MAX_ROWS."""
    groups_that_fit = max(1, MAX_ROWS // max(int(rows_each), 1))
    return max(MAX_METHODS, math.ceil(n_methods / groups_that_fit))


def method_groups(methods, per_panel=MAX_METHODS):
    """``methods`` (in their order) split into the fewest groups of at most ``per_panel``, sizes within
    one of each other: every method is drawn, in as many panels side by side as it takes."""
    methods = [str(m) for m in methods]
    n = max(1, math.ceil(len(methods) / per_panel))
    size = math.ceil(len(methods) / n) if methods else 1
    return [methods[k : k + size] for k in range(0, len(methods), size)] or [[]]


def choose(ds, kind, max_methods=MAX_METHODS, max_dt=MAX_DT, max_panels=MAX_PANELS, dt_prefer=None, rows_each=1):
    """(sub-Dataset, note) of ``ds`` keeping every method, at most ``max_dt`` dt values and at most
    ``max_panels`` f × θ0 panels (fewer when the methods need several groups of ``max_methods``, each
    ``rows_each`` panels per f × θ0, so that the figure holds at most MAX_CELLS panels); the note (None
    when all is drawn) says what was drawn and how to draw the rest (select_note)."""
    kept, dropped = {}, {}
    n_groups = len(method_groups(ds.integrator.values, max_methods))
    max_panels = max(1, min(max_panels, MAX_CELLS // (n_groups * rows_each)))
    if dt_prefer == "min":
        dts = sorted(ds.dt.values)
        kept["dt"], dropped["dt"] = dts[:max_dt], dts[max_dt:]
    else:
        kept["dt"], dropped["dt"] = limit(ds, "dt", max_dt)
    n_th = ds.theta0.size if ds.f.size * ds.theta0.size <= max_panels else min(ds.theta0.size, 3, max_panels)
    kept["theta0"], dropped["theta0"] = limit(ds, "theta0", n_th)
    kept["f"], dropped["f"] = limit(ds, "f", max(1, max_panels // len(kept["theta0"])))
    sub = ds.sel({k: v for k, v in kept.items() if dropped[k]}) if any(map(len, dropped.values())) else ds
    return sub, select_note(kind, kept, dropped)


def method_handles(methods, dts=(), diverged=None):
    """Legend (handles, labels): one entry per method in its colour and marker (``diverged``:
    {method: text} appended to its label), then, for more than one dt, one grey line per dt style."""
    import matplotlib.lines as mlines

    from ..io import DT_STYLES, fmt_dt, line_style

    diverged = diverged or {}
    handles, labels = [], []
    for m in methods:
        style = {k: v for k, v in line_style(m, 1).items() if k != "markevery"}
        handles.append(mlines.Line2D([], [], lw=1.2, **style))
        labels.append(m + (f" ({diverged[m]})" if m in diverged else ""))
    if len(dts) > 1:
        for k, dt in enumerate(dts):
            handles.append(mlines.Line2D([], [], color="0.35", lw=1.2, ls=DT_STYLES[k % len(DT_STYLES)]))
            labels.append(fmt_dt(dt))
    return handles, labels


def diverged_text(sub):
    """{method: 'diverged at dt = 1e-2 s'} for each method of ``sub`` with a run that stopped (status ≠ 0)
    at some f, θ0 of ``sub``: the legend's words for it."""
    from ..io import fmt_dt

    out = {}
    for m in sub.integrator.values:
        bad = sub.status.sel({"integrator": m}) != 0
        dts = [dt for dt in sub.dt.values if bool(bad.sel({"dt": dt}).any())]
        if dts:
            out[str(m)] = "diverged at " + ", ".join(fmt_dt(d) for d in sorted(dts))
    return out


def fit_text(text, ax, fontsize, pad_in=0.12):
    """``text`` wrapped at its words to the width of ``ax`` less ``pad_in`` (in): each line's width is
    measured in the figure's own font (an estimate per character let long method names overflow)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    width_pt = (ax.get_position().width * ax.figure.get_figwidth() - pad_in) * 72
    font = FontProperties(size=fontsize)

    def fits(line):
        return TextToPath().get_text_width_height_descent(line, font, ismath=False)[0] <= width_pt

    lines = []
    for word in text.split():
        if lines and fits(lines[-1] + " " + word):
            lines[-1] += " " + word
        else:
            lines.append(word)  # a word wider than the panel gets a line of its own
    return "\n".join(lines)


def panel_note(ax, paragraphs, fontsize=7, **kwargs):
    """A boxed note in the upper left of ``ax``: ``paragraphs`` (one line each at least) wrapped to the
    panel's width.  Call ``refit_notes(fig)`` after the figure's layout: tight_layout narrows the panels
    after their notes were wrapped, and a note wrapped before it ran past its panel.  The note is drawn
    under the data (zorder 1.5, lines are at 2): a curve that runs through the box stays visible."""
    style = dict(
        ha="left", va="top", fontsize=fontsize, color="0.15", zorder=1.5, bbox=dict(fc="white", ec="0.7", alpha=0.75)
    )
    note = ax.text(0.02, 0.97, "", transform=ax.transAxes, **(style | kwargs))
    note.gyrolab_paragraphs = list(paragraphs)
    note.set_text("\n".join(fit_text(p, ax, fontsize) for p in paragraphs))
    return note


def refit_notes(fig):
    """Wrap every panel_note of ``fig`` again to its panel's width as laid out now."""
    for ax in fig.axes:
        for t in ax.texts:
            if hasattr(t, "gyrolab_paragraphs"):
                t.set_text("\n".join(fit_text(p, ax, t.get_fontsize()) for p in t.gyrolab_paragraphs))


def legend_below(fig, handles, labels, ncol=None, fontsize=8):
    """A legend under the axes, then the figure's notes under the legend."""
    legend = None
    if handles:
        ncol = ncol or min(len(labels), 4)
        legend = fig.legend(
            handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=ncol, fontsize=fontsize, frameon=False
        )
    notes = getattr(fig, "gyrolab_notes", [])
    if not notes:
        return legend
    y = 0.0
    if legend is not None:
        renderer = fig.canvas.get_renderer()
        y = fig.transFigure.inverted().transform(legend.get_window_extent(renderer))[0, 1]
    fig.text(
        0.01, y - 0.005, "\n".join(wrap_note(n, fig) for n in notes), ha="left", va="top", fontsize=7.5, color="0.25"
    )
    return legend


def wrap_note(text, fig):
    """``text`` wrapped to the figure's width (7.5 pt text: about 19 characters per inch)."""
    import textwrap

    return "\n".join(textwrap.wrap(text, max(60, int(fig.get_figwidth() * 19)), break_on_hyphens=False))


def fixed_note(ds, kind, drawn):
    """A select_note for values a figure fixes by design (``drawn``: {key: [values]}, e.g. the finest dt)
    when the file has others; None otherwise."""
    kept, dropped = {}, {}
    for key, values in drawn.items():
        wanted = set(map(str, values))
        kept[key] = [v for v in ds[key].values if str(v) in wanted]
        dropped[key] = [v for v in ds[key].values if str(v) not in wanted]
    return select_note(kind, kept, dropped)


SPIN_SCENES = ("heavy_top", "free_symmetric")  # the write-up's tops: f (Hz) is their spin, θ0 their tilt


def _num(x):
    return f"{x:.4g}".replace("-", "−")


def run_title(ds, f, th):
    """Panel title of grid point (f Hz, θ0 deg) in the problem's own terms: 'f = 10 Hz, θ0 = 45°' for
    the write-up's tops (SPIN_SCENES), whose spin f is, and for any sweep over f; for one problem of
    another scene, whose f and θ0 only parametrise the initial state (a peer problem's 150 rad/s top
    is f = 0.734561 Hz, θ0 = 180°), the run's stored initial body rates ω0 (rad/s, body frame), then
    θ0 when the file sweeps it."""
    from ..io import scene_name

    if scene_name(ds) in SPIN_SCENES or "omega0" not in ds.data_vars or ds.f.size > 1:  # a sweep: the f it swept
        return f"f = {float(f):g} Hz, θ0 = {float(th):g}°"
    w = np.asarray(ds["omega0"].sel({"f": f, "theta0": th}).values, dtype=float)
    text = f"ω0 = ({', '.join(_num(v) for v in w)}) rad/s"
    return text + (f", θ0 = {float(th):g}°" if ds.theta0.size > 1 else "")


def machine_load():
    """The machine's 1-minute load average (os.getloadavg; None where the OS has none): sampled when
    a figure times something, so that its times say what they were measured under."""
    import os

    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):  # pragma: no cover (not on Linux)
        return None


def load_text(samples):
    """'load average 0.4–3.1 on 2 CPUs while timing' of the machine_load samples taken during a
    timing; 'load not recorded' without any."""
    import os

    loads = [x for x in samples if x is not None]
    if not loads:
        return "machine load not recorded"
    lo, hi = min(loads), max(loads)
    span = f"{lo:.1f}" if round(lo, 1) == round(hi, 1) else f"{lo:.1f}–{hi:.1f}"
    return f"load average {span} on {os.cpu_count()} CPUs while timing"


def suptitle(fig, text, fontsize=10.5, **kwargs):
    """fig.suptitle with each line wrapped to the figure's width (about 130 / fontsize characters per inch),
    so that a narrow figure's title never runs past its panels."""
    import textwrap

    width = max(30, int(fig.get_figwidth() * 130 / fontsize))
    lines = [w for line in text.split("\n") for w in textwrap.wrap(line, width, break_on_hyphens=False) or [""]]
    return fig.suptitle("\n".join(lines), fontsize=fontsize, **kwargs)
