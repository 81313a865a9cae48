"""The results layout: dims, variables, units and attrs, in one place for every writer and reader.

A results file (netCDF4/HDF5, written with h5netcdf, read by xarray and by
netCDF-C) holds, for a grid of runs over ``GRID_DIMS``:

- coordinates ``integrator`` (str: the sweep's ``sweep.method`` values), ``f`` (Hz),
  ``theta0`` (deg), ``dt`` (s),
  ``time`` (s), ``xyz`` (vector components), ``quat`` (a, b, c, d) and
  ``body_param`` (the fields of kernels/body.py's Body);
- per sample ``SAMPLE_VARIABLES`` (dims GRID_DIMS + time [+ xyz]), derived
  from the kernels' raw fields (kernels/driver.py FIELDS) by
  ``sample_variables``;
- per run ``RUN_VARIABLES`` (dims GRID_DIMS);
- each run's inputs ``INPUT_VARIABLES`` (dims f, theta0 + their own): the
  body and the initial state, so analysis never rebuilds physics from
  today's scene code;
- file attrs: ``layout_version``, the scene and its options (``scene_<key>``),
  the scene's declared invariants (``conserved``) and closed form, the
  resolved config as YAML and the provenance of the code
  (runner/provenance.py).

Layout versions (``LAYOUT_VERSION``, the file attr ``layout_version``): 0 before the attr, without
stored run inputs or L; 1 without gamma; 2 with a body of six fields; 3 the grid dim ``integrator``
(was ``method``); 4 the per-run solver counts ``solver_iterations`` and ``solver_iterations_max``.
Files of older layouts open with every reader through ``current``: layouts 0 to 2 called the
grid dim ``integrator`` ``method``, a keyword of xarray's ``.sel`` (``ds.sel(method="rk4")``
silently selected every method), and they lack what ``ABSENT_BEFORE`` lists (left absent, per-run
variables too: gyrolab/results/migrate.py).

Adding a per-sample variable (recipe, also in docs/design.md): a field in kernels/driver.py
(``FIELDS`` and ``_record``) and its formula in kernels/reference.py (``samples_from_states``) if the
kernels must compute it, and one entry at the end of
``SAMPLE_VARIABLES`` here; every writer, reader and size estimate follows.  No layout bump and no
``ABSENT_BEFORE`` entry: a file that does not name its variables (``VARIABLES_ATTR``) holds
``UNNAMED_HOLD`` (frozen), so every file written before the new variable reads as one without it,
and a file written after names what it holds.  Readers that need it say so in one line.
"""

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..kernels.body import FIELDS as BODY_FIELDS
from ..kernels.body import UNITS as BODY_UNITS
from ..kernels.driver import FIELDS as RAW_FIELDS
from ..kernels.driver import STATUS_LEGEND
from .migrate import ABSENT_BEFORE, NOT_COUNTED, file_layout_version

LAYOUT_VERSION = 4
GRID_DIMS = ("integrator", "f", "theta0", "dt")
INPUT_DIMS = ("f", "theta0")  # a run's body and initial state depend on these only
RAW_PER_SAMPLE = len(RAW_FIELDS)


def _raw(*names):
    """Column indices of the named raw kernel fields."""
    return [RAW_FIELDS.index(n) for n in names]


@dataclass(frozen=True)
class SampleVariable:
    """A per-sample variable: ``vector`` adds the xyz dim; ``derive(raw)`` maps raw
    kernel samples (..., time, RAW_PER_SAMPLE) to its values (..., time[, 3])."""

    units: str
    long_name: str
    derive: Callable
    vector: bool = False


def tilt_angle(x, y, z):
    """The angle (rad) between the lab vector (x, y, z) and lab z: atan2(√(x² + y²), z).  Not arccos z, which
    near the vertical turns a rounding ε of z into a tilt √(2ε) (a quaternion's norm drift of 1e-12 read as
    2e-6 rad of a top that sleeps exactly upright), and which needs the vector's length to be 1."""
    return np.arctan2(np.hypot(x, y), z)


def _theta(raw):
    return tilt_angle(*(raw[..., i] for i in _raw("axis_x", "axis_y", "axis_z")))


def _phi(raw):
    ax, ay = _raw("axis_x", "axis_y")
    return unwrap_nan(np.arctan2(raw[..., ay], raw[..., ax]))


# The description of the per-run solver counts (RUN_VARIABLES), one sentence for both.
SOLVER_COUNT_NOTE = (
    "{what} the run's steps; 0: the method has no iterative solver; "
    f"{NOT_COUNTED}: not counted (an engine package, whose solver is not visible)"
)
SAMPLE_VARIABLES = {
    "axis": SampleVariable(
        "1", "symmetry axis R e3 in the lab frame", lambda r: r[..., _raw("axis_x", "axis_y", "axis_z")], vector=True
    ),
    "theta": SampleVariable("rad", "tilt: angle between e3 and lab z", _theta),
    "phi": SampleVariable("rad", "azimuth of the axis tip, unwrapped", _phi),
    "energy": SampleVariable(
        "J",
        "total energy 1/2 w.Iw + M g c.gamma (M g l cos(theta) for c = l e3)",
        lambda r: r[..., RAW_FIELDS.index("energy")],
    ),
    "L": SampleVariable(
        "kg m2 s-1",
        "angular momentum about the pivot in the lab frame, R I w",
        lambda r: r[..., _raw("L_x", "L_y", "L_z")],
        vector=True,
    ),
    "Lz": SampleVariable(
        "kg m2 s-1", "lab vertical angular momentum (R I w).z", lambda r: r[..., RAW_FIELDS.index("L_z")]
    ),
    "L3": SampleVariable(
        "kg m2 s-1", "angular momentum along the symmetry axis I3 w3", lambda r: r[..., RAW_FIELDS.index("L3")]
    ),
    "omega": SampleVariable(
        "rad s-1",
        "body angular velocity (body-frame components)",
        lambda r: r[..., _raw("omega_1", "omega_2", "omega_3")],
        vector=True,
    ),
    "gamma": SampleVariable(
        "1",
        "lab vertical R^T z in body coordinates (body-frame components)",
        lambda r: r[..., _raw("gamma_1", "gamma_2", "gamma_3")],
        vector=True,
    ),
}
RUN_VARIABLES = {
    "status": (
        np.int8,
        {"units": "1", "long_name": "run status", "legend": "; ".join(f"{k}: {v}" for k, v in STATUS_LEGEND.items())},
    ),
    "n_steps": (np.int64, {"units": "1", "long_name": "time steps taken"}),
    "wall_time": (np.float64, {"units": "s", "long_name": "wall-clock time of the run"}),
    "solver_iterations": (
        np.int64,
        {
            "units": "1",
            "long_name": "implicit solver iterations over the run",
            "description": SOLVER_COUNT_NOTE.format(what="fixed-point sweeps or Newton iterations summed over"),
        },
    ),
    "solver_iterations_max": (
        np.int64,
        {
            "units": "1",
            "long_name": "most solver iterations in one step",
            "description": SOLVER_COUNT_NOTE.format(what="the most fixed-point sweeps or Newton iterations of one of"),
        },
    ),
}
# Status of a grid point that a combined file's member does not have (gyrolab-combine fills the union
# grid of its members; their data there is NaN).
STATUS_ABSENT = -1
INPUT_VARIABLES = {
    "body": (
        "body_param",
        {
            "units": ", ".join(f"{k}: {BODY_UNITS[k]}" for k in BODY_FIELDS),
            "long_name": "body parameters (kernels/body.py), one value per body_param",
        },
    ),
    "omega0": ("xyz", {"units": "rad s-1", "long_name": "initial body angular velocity"}),
    "q0": ("quat", {"units": "1", "long_name": "initial orientation quaternion (a, b, c, d), body to lab"}),
}
COORD_ATTRS = {
    "integrator": {"long_name": "integration method (sweep.method)"},
    "f": {"units": "Hz", "long_name": "spin frequency (w3 = 2 pi f)"},
    "theta0": {"units": "deg", "long_name": "initial tilt"},
    "dt": {"units": "s", "long_name": "time step"},
    "time": {"units": "s", "long_name": "time"},
    "xyz": {"long_name": "vector component (lab x, y, z or body 1, 2, 3)"},
    "quat": {"long_name": "quaternion component (scalar first)"},
    "body_param": {"long_name": "body parameter (kernels/body.py)"},
}
FIXED_COORDS = {"xyz": ["x", "y", "z"], "quat": ["a", "b", "c", "d"], "body_param": list(BODY_FIELDS)}
VARIABLE_ATTRS = {name: {"units": v.units, "long_name": v.long_name} for name, v in SAMPLE_VARIABLES.items()}
VARIABLE_ATTRS.update({name: attrs for name, (_, attrs) in RUN_VARIABLES.items()})
VARIABLE_ATTRS.update({name: attrs for name, (_, attrs) in INPUT_VARIABLES.items()})
# File attr naming the per-sample variables a file holds (space-separated, SAMPLE_VARIABLES order),
# written whenever they are not ``UNNAMED_HOLD`` (``output.variables`` chose others, or a variable was
# added since); a file without it holds ``UNNAMED_HOLD`` less what its layout lacks (ABSENT_BEFORE).
VARIABLES_ATTR = "variables"
# What a file that does not name its per-sample variables holds: SAMPLE_VARIABLES as they were
# when every file was written without the attr.  Frozen: never add to it (a variable added to
# SAMPLE_VARIABLES is then absent, automatically, from every file written before it).
UNNAMED_HOLD = ("axis", "theta", "phi", "energy", "L", "Lz", "L3", "omega", "gamma")


def stored_per_sample(names=None):
    """Float64 values per sample of one run for the per-sample variables ``names`` (None: all)."""
    names = SAMPLE_VARIABLES if names is None else names
    return sum(3 if SAMPLE_VARIABLES[n].vector else 1 for n in names)


def chosen_variables(names):
    """The per-sample variables ``names`` (output.variables; None: all) in SAMPLE_VARIABLES order;
    ValueError (one line) naming the first unknown or repeated name."""
    if names is None:
        return tuple(SAMPLE_VARIABLES)
    names = list(names)
    for name in names:
        if name not in SAMPLE_VARIABLES:
            raise ValueError(f"unknown variable {name!r}; choose from {', '.join(SAMPLE_VARIABLES)}")
        if names.count(name) > 1:
            raise ValueError(f"variable {name!r} appears twice")
    return tuple(n for n in SAMPLE_VARIABLES if n in names)


def held_variables(ds, version=None):
    """The per-sample variables an opened results file holds by its layout and its writer's choice
    (``VARIABLES_ATTR``), in SAMPLE_VARIABLES order."""
    version = file_layout_version(ds) if version is None else version
    absent = ABSENT_BEFORE.get(version, ())
    if VARIABLES_ATTR in ds.attrs:
        chosen = set(_text(ds.attrs[VARIABLES_ATTR]).split())
        return tuple(n for n in SAMPLE_VARIABLES if n in chosen and n not in absent)
    return tuple(n for n in SAMPLE_VARIABLES if n in UNNAMED_HOLD and n not in absent)


def variables_attr(names):
    """The ``VARIABLES_ATTR`` value of a file holding the per-sample variables ``names``, or None when
    the file need not name them (they are ``UNNAMED_HOLD``, as every file without the attr holds)."""
    names = tuple(n for n in SAMPLE_VARIABLES if n in names)
    return None if set(names) == set(UNNAMED_HOLD) else " ".join(names)


def absence_reason(ds, name):
    """Why the opened file ``ds`` does not hold per-sample variable ``name``, in a few words."""
    version = file_layout_version(ds)
    if name in ABSENT_BEFORE.get(version, ()):
        return f"its layout_version {version} has no {name}"
    if VARIABLES_ATTR not in ds.attrs and name not in UNNAMED_HOLD:
        return f"it was written before gyrolab stored {name}"
    return "output.variables chose them when it was written"


WALL_TIME_NOTE = (
    "chunk wall-clock time x threads used, shared among the chunk's runs in proportion to their steps "
    "(runs of one chunk run in parallel; JIT compilation excluded)"
)


def held_run_variables(version):
    """The per-run variables (RUN_VARIABLES order) every file of layout ``version`` holds: all but
    what the layout lacks (``ABSENT_BEFORE``: the solver counts before layout 4)."""
    absent = ABSENT_BEFORE.get(version, ())
    return tuple(name for name in RUN_VARIABLES if name not in absent)


def required_variables(version, ds=None):
    """{name: dims} every results file of layout ``version`` holds (grid dims first); with the
    opened file ``ds``, only the per-sample variables its writer chose (``held_variables``)."""
    absent = ABSENT_BEFORE.get(version, ())
    held = held_variables(ds, version) if ds is not None else SAMPLE_VARIABLES
    wanted = {name: GRID_DIMS + sample_dims(name) for name in SAMPLE_VARIABLES if name not in absent and name in held}
    wanted.update({name: GRID_DIMS for name in held_run_variables(version)})
    return wanted


def sample_dims(name):
    """Dims of per-sample variable ``name`` after the grid dims: (time,) or (time, xyz)."""
    return ("time", "xyz") if SAMPLE_VARIABLES[name].vector else ("time",)


def sample_variables(raw, names=None):
    """{name: values} of the per-sample variables ``names`` (None: every one) from raw kernel samples
    (..., time, RAW_PER_SAMPLE)."""
    return {name: v.derive(raw) for name, v in SAMPLE_VARIABLES.items() if names is None or name in names}


def solver_variables(iterations):
    """{solver_iterations, solver_iterations_max}: int64 (n,) of the (n, 2) array the kernels fill
    (kernels/batch.py ``integrate(..., iterations=)``: each run's total and most in one step)."""
    iterations = np.asarray(iterations, dtype=np.int64)
    return {
        "solver_iterations": iterations[..., 0].copy(),  # contiguous, and a 0-d array stays 0-d
        "solver_iterations_max": iterations[..., 1].copy(),
    }


def unwrap_nan(phase):
    """np.unwrap along the last axis that leaves trailing NaN (diverged runs) in place."""
    filled = np.where(np.isnan(phase), 0.0, phase)
    return np.where(np.isnan(phase), np.nan, np.unwrap(filled, axis=-1))


def scene_attrs(scene, options, conserved, closed_form):
    """File attrs naming the scene, its options and its declarations (space-separated invariant names)."""
    attrs = {
        "scene": scene,
        "conserved": " ".join(conserved),
        "closed_form": closed_form or "",
        "layout_version": LAYOUT_VERSION,
    }
    for key, value in options.items():
        attrs[f"scene_{key}"] = int(value) if isinstance(value, bool) else value
    return attrs


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def conserved(ds):
    """The invariants the file's scene declares: its ``conserved`` attr, or for files written
    before that attr existed, the scene's current declaration."""
    if "conserved" in ds.attrs:
        return tuple(_text(ds.attrs["conserved"]).split())
    from ..kernels.scenes import get_scene

    return tuple(get_scene(_text(ds.attrs.get("scene", "heavy_top"))).CONSERVED)


def closed_form(ds):
    """The name of the file's scene's closed form (kernels/closed_form.py), or None."""
    if "closed_form" in ds.attrs:
        return _text(ds.attrs["closed_form"]) or None
    from ..kernels.scenes import get_scene

    return get_scene(_text(ds.attrs.get("scene", "heavy_top"))).CLOSED_FORM


def to_dataset(raw, per_run, coords, inputs=None, attrs=None):
    """An in-memory results Dataset from raw kernel samples.

    raw: (*grid_shape, time, RAW_PER_SAMPLE); per_run: {name: (*grid_shape)};
    coords: {dim: values} for the grid dims (those of ``raw``'s leading axes,
    in GRID_DIMS order, or none for a single run) and ``time``; inputs:
    {"body", "omega0", "q0"} arrays over (f, theta0, ·) or one run's (·).
    """
    import xarray as xr

    grid = tuple(d for d in GRID_DIMS if d in coords)
    data = {}
    for name, values in sample_variables(raw).items():
        data[name] = (grid + sample_dims(name), values, VARIABLE_ATTRS[name])
    for name, values in per_run.items():
        data[name] = (grid, np.asarray(values, dtype=RUN_VARIABLES[name][0]), VARIABLE_ATTRS[name])
    for name, values in (inputs or {}).items():
        own = INPUT_VARIABLES[name][0]
        data[name] = (
            tuple(d for d in INPUT_DIMS if d in coords) + (own,),
            np.asarray(values, dtype=float),
            VARIABLE_ATTRS[name],
        )
    all_coords = {d: (d, np.asarray(v), COORD_ATTRS[d]) for d, v in coords.items()}
    for d, v in FIXED_COORDS.items():
        if any(d in spec[0] for spec in data.values()):
            all_coords[d] = (d, np.array(v), COORD_ATTRS[d])
    return xr.Dataset(data, coords=all_coords, attrs=dict(attrs or {}))
