"""Reading stored results and choosing runs: the helpers every figure shares.

A results file (gyrolab/results/layout.py) opens as an xarray Dataset with dims
``integrator, f, theta0, dt, time, xyz`` (``open_results`` renames the ``method`` dim
of files from before layout 3).  A *selection* is a dict (or the CLI
text ``integrator=seed_next,rk4 f=10 dt=1e-4``) of coordinate values; numbers
match their coordinate to a relative 1e-9, so ``dt=1e-4`` finds 0.0001.
"""

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import Locator, LogFormatterSciNotation, LogLocator

from ..kernels.invariants import INVARIANTS
from ..kernels.parameters import split_names
from ..results import ResultsError
from ..results.layout import GRID_DIMS
from ..results.members import MEMBER_DIMS
from ..safe_files import atomic_replace

plt.switch_backend("Agg")  # analysis is headless: files, never windows (pyplot picks its backend lazily)

FORMATS = ("png", "svg", "pdf")
# Fixed colours of the first methods and the peers; any other method gets one from PALETTE
# by its place in the registry, so a new method is drawn without touching this file.
METHOD_COLORS = {
    "seed_next": "#d62728",
    "seed_prev": "#1f77b4",
    "rk4": "#2ca02c",
    "lie_poisson": "#9467bd",
    "lie_poisson4": "#ff7f0e",
    "DOP853": "#000000",
    "RK45": "#7f7f7f",
    "Radau": "#e7ba52",
    "LSODA": "#6baed6",
}
DT_STYLES = ("-", "--", ":", "-.")
# Each invariant's symbol, from its one declaration (kernels/invariants.py).
QUANTITY_LABELS = {name: invariant.label for name, invariant in INVARIANTS.items()}


class SelectionError(ResultsError):
    """A selection naming a coordinate or value the file does not have (one-line message)."""


class MissingVariableError(SelectionError):
    """A figure needs a per-sample variable the file does not hold (output.variables left it out)."""


def absent_variable(ds, err):
    """The per-sample variable (gyrolab/results/layout.py) named in the KeyError/AttributeError ``err`` that
    ``ds`` does not hold, or None when ``err`` is about something else."""
    import re

    from ..results.layout import SAMPLE_VARIABLES

    for name in re.findall(r"'(\w+)'", str(err)) + [str(err.args[0]) if err.args else ""]:
        if name in SAMPLE_VARIABLES and name not in ds.data_vars:
            return name
    return None


def missing_variable_error(ds, name, figure):
    """The one-line MissingVariableError of figure ``figure`` needing variable ``name``."""
    from ..results.layout import absence_reason, held_variables

    held = ", ".join(held_variables(ds)) or "none"
    return MissingVariableError(
        f"figure {figure} needs variable {name}, which this file does not hold "
        f"(it holds {held}: {absence_reason(ds, name)})"
    )


# The grid dim's old name, still accepted in a selection (``method=rk4``: gyrolab-plot commands and
# scripts written before layout 3; the sweep's config key is still ``sweep.method``).
SELECTION_ALIASES = {"method": "integrator"}


def _canonical_method(name):
    """``name`` in the canonical form the runner stores (kernels/parameters.py: ``lie_poisson(axes=s-m-l)``
    is stored as ``lie_poisson(axes=S-M-L)``); any name the registry does not know, unchanged."""
    from ..kernels.registry import canonical_name

    try:
        return canonical_name(name)[0]
    except ValueError:
        return name


def parse_selection(words, members=False):
    """``["integrator=seed_next,rk4", "f=10"]`` -> {"integrator": ["seed_next", "rk4"], "f": [10.0]}
    (``method=`` is read as ``integrator=``).  With ``members``, also ``scene=NAME`` / ``job=K``
    (a combined file's member, MEMBER_DIMS).  A key given twice selects the values of both."""
    keys = GRID_DIMS + (MEMBER_DIMS if members else ())
    sel = {}
    for word in words or ():
        for item in str(word).split():
            key, eq, value = item.partition("=")
            key = SELECTION_ALIASES.get(key, key)
            if not eq or key not in keys:
                raise SelectionError(f"{item}: a selection is KEY=VALUE[,VALUE...] with KEY in {', '.join(keys)}")
            values = split_names(value) if key == "integrator" else [v for v in value.split(",") if v]
            if not values:
                raise SelectionError(f"{item}: no value given for {key}")
            if key in MEMBER_DIMS and len(values) > 1:
                raise SelectionError(f"{item}: one {key} at a time")
            if key == "integrator":  # a method with parameters as the file names it (canonical)
                values = [_canonical_method(v) for v in values]
            elif key not in MEMBER_DIMS:
                try:
                    values = [float(v) for v in values]
                except ValueError:
                    raise SelectionError(f"{key}={value}: not a number") from None
            if key in sel and key in MEMBER_DIMS:
                raise SelectionError(f"{item}: one {key} at a time ({key}={sel[key][0]} given before)")
            # f=10 f=50 is f=10,50 (the second dropped the first)
            sel[key] = list(dict.fromkeys(sel.get(key, []) + values))
    return sel


def _match(coord, wanted, key):
    """Coordinate values of ``coord`` matching ``wanted`` (numbers to rel. 1e-9)."""
    out = []
    have = coord.values
    for w in wanted:
        if key == "integrator":
            hits = [v for v in have if str(v) == str(w)]
        else:
            hits = [v for v in have if math.isclose(float(v), float(w), rel_tol=1e-9, abs_tol=1e-12)]
        if not hits:
            shown = ", ".join(f"{v:g}" if key != "integrator" else str(v) for v in have)
            raise SelectionError(f"{key}={w}: not in this file ({key} has {shown})")
        out.extend(hits)
    return out


def select(ds, sel=None):
    """Sub-Dataset with the grid values named in ``sel`` (dict of scalars or lists); dims kept."""
    sel = sel or {}
    idx = {}
    for key, wanted in sel.items():
        key = SELECTION_ALIASES.get(key, key)
        if wanted is None:
            continue
        if key not in GRID_DIMS:
            raise SelectionError(f"{key}: not a grid axis (choose from {', '.join(GRID_DIMS)})")
        wanted = wanted if isinstance(wanted, (list, tuple, np.ndarray)) else [wanted]
        idx[key] = _match(ds[key], wanted, key)
    return ds.sel(idx) if idx else ds


def pick(ds, key, value=None, prefer="first"):
    """One value of grid axis ``key``: ``value`` if given (checked), else first/last/smallest."""
    if value is not None:
        return _match(ds[key], [value], key)[0]
    values = ds[key].values
    if prefer == "min":
        return values.min()
    if prefer == "last":
        return values[-1]
    return values[0]


def scene_options(ds):
    """{option: value} of the scene, from the file attrs ``scene_<key>``."""
    opts = {}
    for key, value in ds.attrs.items():
        if key.startswith("scene_"):
            if isinstance(value, bytes):
                value = value.decode()
            if isinstance(value, np.generic):
                value = value.item()
            if isinstance(value, np.ndarray):  # a vector option (heavy_body's com)
                value = value.tolist()
            opts[key[len("scene_") :]] = value
    return opts


def scene_name(ds):
    name = ds.attrs.get("scene", "heavy_top")
    return name.decode() if isinstance(name, bytes) else str(name)


def build_run_scene(ds, f, theta0):
    """The kernel Scene of grid point (f Hz, theta0 deg) of this file: its stored body and
    initial state (``body``, ``omega0``, ``q0``), or for files written before those were
    stored, the scene rebuilt from the file's scene options."""
    from ..kernels.body import Body
    from ..kernels.scenes import Scene, build_scene

    if all(name in ds.data_vars for name in ("body", "omega0", "q0")):
        at = {"f": _match(ds["f"], [f], "f")[0], "theta0": _match(ds["theta0"], [theta0], "theta0")[0]}
        run = ds[["body", "omega0", "q0"]].sel(at)
        return Scene(
            scene_name(ds),
            Body(*map(float, run["body"].values)),
            tuple(map(float, run["omega0"].values)),
            tuple(map(float, run["q0"].values)),
        )
    return build_scene(scene_name(ds), float(f), float(theta0), **scene_options(ds))


def scene_label(ds):
    """Short text naming the scene and its body, e.g. 'heavy_top (release)', 'heavy_body (I = (15.23, 0.4688,
    15.23) kg m², centre of mass (0, −1, 0) m)' (moments about the pivot, or the centre of mass of a free body)."""
    name = scene_name(ds)
    opts = scene_options(ds)
    extra = []
    if name == "heavy_top":
        init = opts.get("init", "release")
        extra.append(init if init != "precession" else f"precession, φ̇0 = {opts.get('phidot0', 0):g} rad/s")
    elif all(k in opts for k in ("I1", "I2", "I3")):  # the body itself: its moments (and centre of mass)
        extra.append("I = (" + ", ".join(f"{float(opts[k]):.4g}" for k in ("I1", "I2", "I3")) + ") kg m²")
        if "com" in opts:
            extra.append("centre of mass (" + ", ".join(f"{float(c):.4g}" for c in opts["com"]) + ") m")
    return f"{name} ({', '.join(extra)})" if extra else name


def fmt_dt(dt):
    """'dt = 1e-4 s', 'dt = 2.5e-4 s': the fewest significant digits that give the step back,
    so that two steps of a sweep never share a label (one digit called 2.5e-4 '3e-4' and 1.25e-4 '1e-4')."""
    dt = float(dt)
    for digits in range(17):
        text = f"{dt:.{digits}e}"
        if float(text) == dt:
            break
    mantissa, exponent = text.split("e")
    return f"dt = {mantissa}e{int(exponent)} s"


def relative_error(values, reference=None, scale=None):
    """|x(t) − x0| / |x0| along the last axis (x0 = first sample unless given).

    When |x0| is ~0 (below 1e-9 of the quantity's scale) the scale is the denominator instead, so the
    ratio stays meaningful: ``scale`` (broadcast against x0) is the quantity's physical size where the
    caller knows it (``invariant_scale``: T0 + |M g c| for the energy of a top released from rest
    level, |L| for L_z), else the run's largest |x|; a quantity that is 0 at every sample has error 0.
    """
    values = np.asarray(values, dtype=float)
    x0 = values[..., :1] if reference is None else np.asarray(reference, dtype=float)[..., None]
    if scale is None:
        size = np.nanmax(np.abs(values), axis=-1, keepdims=True)
    else:
        size = np.broadcast_to(np.asarray(scale, dtype=float), np.shape(x0))
    denom = np.where(np.abs(x0) > 1e-9 * size, np.abs(x0), size)
    diff = np.abs(values - x0)
    with np.errstate(divide="ignore", invalid="ignore"):
        # denom is 0 only for a quantity that is exactly 0 throughout (L_z of a top released from rest): error 0
        return np.where(denom == 0, 0.0, diff / denom)


# what ``invariant_scale`` measures each invariant against when it starts at ~0 (for figure notes)
SCALE_NAMES = {"energy": "T0 + |M g c|", "Lz": "|L|", "L3": "|L|"}


def invariant_scale(ds, name):
    """The physical size of invariant ``name`` in each run of ``ds`` (a DataArray over its run dims), the
    denominator of its relative error when its initial value is ~0 (``relative_error``), or None for an
    invariant whose own values are its size: the energy's T0 + |M g c| (J; T0 = ½ ω0·Iω0 from the stored
    run inputs: a top released from rest level has E0 = 0 while it swaps M g l between V and T), and for
    L_z and L_3 the length of L at the start, or its largest over the run when it starts at 0."""
    if name == "energy" and {"body", "omega0"} <= set(ds.data_vars):
        body, w0 = ds["body"], ds["omega0"]
        inertia = body.sel(body_param=["I1", "I2", "I3"]).values
        T0 = 0.5 * np.sum(inertia * w0.transpose(*body.dims[:-1], "xyz").values ** 2, axis=-1)
        mgc = np.sqrt(sum(body.sel(body_param=k) ** 2 for k in ("mgc1", "mgc2", "mgl")))
        return mgc + T0
    if name in ("Lz", "L3") and "L" in ds.data_vars:
        L = np.sqrt((ds["L"] ** 2).sum("xyz", skipna=False))
        start = L.isel(time=0)
        return start.where(start > 0, L.max("time"))
    return None


def invariant_error(run, name):
    """Relative error series of invariant ``name`` of one run (a Dataset over time):
    |X(t) − X0| / |X0|, with |·| the vector norm for L (layout.invariant gives X), X0 ~ 0 measured
    against ``invariant_scale``."""
    from ..kernels.invariants import invariant

    scale = invariant_scale(run, name)
    return error_series(invariant(run, name).values, None if scale is None else scale.values)


def error_series(values, scale=None):
    """``invariant_error`` of one run's invariant values, (time,) or (time, xyz) for a vector: the
    distance from the initial value over its size (``scale``: ``relative_error``'s, for a scalar)."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 2:  # (time, xyz): the distance from the initial vector over its length
        size = np.linalg.norm(values[0]) or np.nanmax(np.linalg.norm(values, axis=-1))
        diff = np.linalg.norm(values - values[:1], axis=-1)
        return np.zeros_like(diff) if size == 0 else diff / size  # a vector that is 0 throughout: error 0
    return relative_error(values, scale=scale)


def running_max(err):
    """max over s ≤ t of ``err(s)`` along the last axis, NaN where ``err`` is NaN: the curve of a run that
    stopped ends at its last sample instead of running on flat to t_end."""
    err = np.asarray(err, dtype=float)
    return np.where(np.isnan(err), np.nan, np.fmax.accumulate(err, axis=-1))


def drawable_invariants(ds):
    """The invariants the file's scene declares (layout.conserved) that its variables can give."""
    from ..kernels.invariants import has_invariant
    from ..results.layout import conserved

    return [q for q in conserved(ds) if has_invariant(ds, q)]


FLOOR = 1e-17  # plotted instead of an exact 0 on log axes (below double precision)


class _InView(Locator):
    """A log axis's locator (``inner``) without the ticks outside the view: LogLocator gives a decade
    beyond each end, and matplotlib makes a Tick (~1 ms) for every location before it drops those it does
    not draw; a figure of many log panels (the stability map: ~100 minor ticks a panel, 25 panels) spent
    seconds there.  The ticks drawn are the same."""

    def __init__(self, inner):
        self.inner = inner

    def set_axis(self, axis):
        super().set_axis(axis)
        self.inner.set_axis(axis)

    def __call__(self):
        return self.tick_values(*self.axis.get_view_interval())

    def tick_values(self, vmin, vmax):
        lo, hi = sorted((vmin, vmax))
        ticks = np.asarray(self.inner.tick_values(vmin, vmax))
        if not lo > 0:  # no log view yet: matplotlib sorts them out
            return ticks
        # A tick at a limit is drawn: matplotlib keeps those within 1e-10 of the view's width in log
        # coordinates; keep those within 1e-9 (a factor, not a difference: the view spans decades).
        pad = (hi / lo) ** 1e-9
        return ticks[(ticks >= lo / pad) & (ticks <= hi * pad)]

    def view_limits(self, vmin, vmax):
        return self.inner.view_limits(vmin, vmax)

    def nonsingular(self, vmin, vmax):
        return self.inner.nonsingular(vmin, vmax)


class ShortMinorLabels(LogFormatterSciNotation):
    """A log axis's minor tick labels as plain numbers (1200, 2e-06), where matplotlib labels them (an
    axis spanning less than a decade): its "1.6×10³ 1.8×10³ 2×10³" met each other in a narrow panel.
    Which ticks are labelled is matplotlib's rule; decades keep their 10ⁿ."""

    def __call__(self, x, pos=None):
        text = super().__call__(x, pos)
        if not text or x <= 0 or abs(math.log10(x) - round(math.log10(x))) < 1e-9:
            return text
        return f"{x:g}"


def ticks_in_view(fig):
    """Wrap each log axis's tick locators of ``fig`` in ``_InView`` (call after the axes' scales are set,
    before the layout and the save, which place and draw the ticks): the same figure, drawn faster."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() != "log":
                continue
            for get, put in (
                (axis.get_major_locator, axis.set_major_locator),
                (axis.get_minor_locator, axis.set_minor_locator),
            ):
                if type(get()) is LogLocator:
                    put(_InView(get()))


def save_figure(fig, out, formats=("png",)):
    """Save ``fig`` to ``out`` (its suffix replaced by each format); return the PNG/first path."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ticks_in_view(fig)
    paths = []
    for fmt in formats:
        if fmt not in FORMATS:
            raise SelectionError(f"--format={fmt}: choose from {', '.join(FORMATS)}")
        p = out.with_suffix("." + fmt)
        # through a private temporary (gyrolab/safe_files.py): never through a link planted at p
        atomic_replace(
            p, lambda tmp, fmt=fmt: fig.savefig(tmp, format=fmt, dpi=110 if fmt == "png" else None, bbox_inches="tight")
        )
        paths.append(p)
    plt.close(fig)
    return paths[0]


# Hues away from the fixed colours above (and from each other): brown, pink, cyan, olive, navy, teal,
# magenta, lime, maroon, salmon, tan, dark slate.
PALETTE = (
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#393b79",
    "#00796b",
    "#ff00ff",
    "#7fbc41",
    "#7f0000",
    "#fa8072",
    "#c8a86b",
    "#2f4f4f",
)
# Markers paired with PALETTE: 7 is prime to PALETTE's 12, so the k-th other method's (colour, marker)
# = (PALETTE[k % 12], MARKERS[k % 7]) repeats only after 84 methods, and two methods that share a
# colour (k and k + 12) never share a marker.
MARKERS = ("o", "s", "^", "D", "v", "P", "X")


def _rank(method):
    """The place of ``method`` among the methods without a fixed colour: its registry order, or for a
    name the registry does not know (a peer, a file from another version), a stable hash after them."""
    import zlib

    from ..kernels.registry import METHODS

    others = [m for m in METHODS if m not in METHOD_COLORS]
    if method in others:
        return others.index(method)
    return len(others) + zlib.crc32(method.encode()) % (len(PALETTE) * len(MARKERS))


def color(method):
    """The colour of ``method`` in every figure: fixed for the first methods and peers, else from
    PALETTE by its place among the registered methods (a new method needs no line here)."""
    method = str(method)
    if method in METHOD_COLORS:
        return METHOD_COLORS[method]
    return PALETTE[_rank(method) % len(PALETTE)]


def marker(method):
    """The marker of ``method`` in every figure: 'o' for the fixed-colour methods, else MARKERS by its
    place among the registered methods; with ``color`` a pair no other of the first 84 methods has."""
    method = str(method)
    if method in METHOD_COLORS:
        return "o"
    return MARKERS[_rank(method) % len(MARKERS)]


def line_style(method, n_points):
    """matplotlib keyword arguments (colour, a marker every tenth of the line's ``n_points``, open face)
    that draw ``method``'s curves in a time-series figure.  The stride is a whole number of points:
    matplotlib's fractional markevery=0.1 raises IndexError at draw time on a line without a finite
    point (a run that diverged before the window drawn)."""
    every = max(1, n_points // 10)
    return dict(color=color(method), marker=marker(method), markevery=every, ms=3.5, mfc="none", mew=0.8)
