"""The content of a results file checked once, in the one reader, so that every command inherits it.

The reader (reader.py ``check``) has already found the grid dims, the time dim and the layout's
variables with their dims; ``validate(where, ds)`` then checks what those hold, from what is in
memory even when the file is opened lazily (coordinates, per-run variables, run inputs, attrs, and
the dtypes, never the values, of the per-sample variables):

- the layout version is a whole number from 0 to today's;
- every grid dim has a run, its values are unique, f, θ0 and dt finite, dt > 0;
- time: at least two samples, finite, strictly increasing, its spacing and end those of the file's
  ``every`` and ``t_end`` attrs, and each finished run's steps (``n_steps`` x dt) span it;
- per-sample variables are float64 (the layout's; an int or float32 copy has lost digits);
- status is an integer in the legend (kernels/driver.py; -1 marks a combined file's absent runs),
  n_steps a whole number >= 0;
- the solver counts (layout 4 on; absent from older layouts, gyrolab/results/migrate.py) are
  integers >= -1 (-1: not counted), -1 in both or in neither, the most in one step at most the total;
- the fixed coordinates (xyz, quat, body_param) are the layout's, so a figure's ``.sel`` finds them;
- the scene, its declared invariants and closed form are ones this gyrolab knows (a combined file's
  member labels are data, see gyrolab/safe_files.py, and not checked against the scene names);
- each stored body has finite parameters and positive moments of inertia (kg m²), each initial
  state (rad/s, quaternion) is finite.

Each problem is one ``ValueError`` line naming the first one found; the reader adds the file.
"""

import math

import numpy as np

from .layout import FIXED_COORDS, GRID_DIMS, LAYOUT_VERSION, RUN_VARIABLES, SAMPLE_VARIABLES, STATUS_ABSENT
from .migrate import NOT_COUNTED, SOLVER_COUNTS

# Relative tolerance of times against the file's every/t_end and n_steps x dt: times are written as
# k x every, every as stride x dt (kernels/batch.py sample_schedule divides to 1e-9).
TIME_RTOL = 1e-6


def validate(ds):
    """None if the opened one-scene results Dataset ``ds`` (today's names) holds what its layout says;
    else ValueError (one line) naming the first problem.  Reads nothing the lazy reader left on disk."""
    _layout_version(ds.attrs)
    _grid(ds)
    _time(ds)
    _variables(ds)
    _fixed_coords(ds)
    _declarations(ds)
    _inputs(ds)


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def _layout_version(attrs):
    if "layout_version" not in attrs:
        return  # layout 0: a gyrolab file from before the attr (migrate.file_layout_version)
    value = attrs["layout_version"]
    if np.ndim(value) != 0 or not isinstance(value.item() if hasattr(value, "item") else value, int):
        raise ValueError(f"layout_version={_text(value)!r} is not a whole number")
    if isinstance(value, (bool, np.bool_)) or not 0 <= int(value) <= LAYOUT_VERSION:
        raise ValueError(f"layout_version={int(value)} is not a layout this gyrolab reads (0 to {LAYOUT_VERSION})")


def _grid(ds):
    for dim in GRID_DIMS:
        values = ds[dim].values
        if values.size == 0:
            raise ValueError(f"no runs: the {dim} axis is empty")
        if dim != "integrator":
            if values.dtype.kind not in "fiu":
                raise ValueError(f"{dim} values are not numbers ({values.dtype})")
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{dim} has a value that is not finite ({_first(values, ~np.isfinite(values))})")
        unique, counts = np.unique(values, return_counts=True)
        if np.any(counts > 1):
            raise ValueError(f"{dim}={unique[counts > 1][0]} appears {counts.max()} times")
    dt = ds["dt"].values
    if np.any(dt <= 0):
        raise ValueError(f"dt={_first(dt, dt <= 0)}: a time step must be > 0 s")


def _first(values, mask):
    return values[np.flatnonzero(mask)[0]]


def _attr_number(ds, name):
    """The number the attr ``name`` holds, None when absent; ValueError when it is not a finite number > 0."""
    if name not in ds.attrs:
        return None
    try:
        value = float(ds.attrs[name])
    except (TypeError, ValueError):
        raise ValueError(f"attr {name}={_text(ds.attrs[name])!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"attr {name}={value} must be a finite number > 0 (s)")
    return value


def _time(ds):
    time = ds["time"].values
    if time.dtype.kind != "f":
        raise ValueError(f"time is not stored as floating point ({time.dtype})")
    if time.size < 2:
        raise ValueError(f"{time.size} sample{'s' * (time.size != 1)} per run: needs at least 2 to draw or compare")
    if not np.all(np.isfinite(time)):
        raise ValueError(f"time has a value that is not finite ({_first(time, ~np.isfinite(time))})")
    steps = np.diff(time)
    if not np.all(steps > 0) or not np.all(np.isfinite(steps)):
        k = int(np.flatnonzero(~(steps > 0) | ~np.isfinite(steps))[0])
        raise ValueError(f"time is not increasing (sample {k + 1}: {time[k + 1]} s after {time[k]} s)")
    span = time[-1] - time[0]
    every, t_end = _attr_number(ds, "every"), _attr_number(ds, "t_end")
    if every is not None and not np.allclose(steps, every, rtol=TIME_RTOL, atol=0):
        raise ValueError(
            f"time steps by {_first(steps, ~np.isclose(steps, every, rtol=TIME_RTOL, atol=0))} s, not every={every} s"
        )
    if t_end is not None and not (
        time[-1] <= t_end * (1 + TIME_RTOL) and time[-1] > t_end - (every or span) * (1 + TIME_RTOL)
    ):
        raise ValueError(f"time ends at {time[-1]} s, not at t_end={t_end} s")
    finished = ds["status"] == 0
    if finished.any():
        spans = ds["n_steps"] * ds["dt"]  # s: the steps each run took
        wrong = (finished & ~np.isclose(spans, span, rtol=TIME_RTOL, atol=0)).values
        if wrong.any():
            run = {d: _text(ds[d].values[i]) for d, i in zip(finished.dims, np.argwhere(wrong)[0])}
            raise ValueError(
                f"the finished run {' '.join(f'{d}={v}' for d, v in run.items())} took "
                f"{ds['n_steps'].sel(run).item()} steps, not the {span} s its samples span"
            )


def _variables(ds):
    for name in SAMPLE_VARIABLES:
        if name in ds.data_vars and ds[name].dtype != np.float64:
            raise ValueError(f"variable {name} is stored as {ds[name].dtype}, not float64")
    for name in RUN_VARIABLES:
        if name == "wall_time" or name not in ds.data_vars:  # an older layout's (the reader checked which)
            continue
        values = ds[name].values
        if values.dtype.kind not in "iu":
            raise ValueError(f"variable {name} is stored as {values.dtype}, not integers")
    from ..kernels.driver import STATUS_LEGEND

    allowed = set(STATUS_LEGEND) | ({STATUS_ABSENT} if "combined_member" in ds.attrs else set())
    status = ds["status"].values
    bad = ~np.isin(status, list(allowed))
    if bad.any():
        raise ValueError(f"status={_first(status.ravel(), bad.ravel())} is not in its legend ({sorted(allowed)})")
    steps = ds["n_steps"].values
    if np.any(steps < 0):
        raise ValueError(f"n_steps={_first(steps.ravel(), steps.ravel() < 0)} is negative")
    _solver_counts(ds)


def _solver_counts(ds):
    """The per-run solver counts, when the file holds them (layout 4 on)."""
    held = [name for name in SOLVER_COUNTS if name in ds.data_vars]
    if len(held) < len(SOLVER_COUNTS):
        if held:
            raise ValueError(f"variable {held[0]} without {next(n for n in SOLVER_COUNTS if n not in held)}")
        return
    total, most = ds["solver_iterations"].values.ravel(), ds["solver_iterations_max"].values.ravel()
    for name, values in (("solver_iterations", total), ("solver_iterations_max", most)):
        if np.any(values < NOT_COUNTED):
            raise ValueError(f"{name}={_first(values, values < NOT_COUNTED)} is below {NOT_COUNTED} (not counted)")
    odd = (total == NOT_COUNTED) != (most == NOT_COUNTED)
    if odd.any():
        k = int(np.flatnonzero(odd)[0])
        raise ValueError(
            f"solver_iterations={total[k]} with solver_iterations_max={most[k]}: "
            f"{NOT_COUNTED} (not counted) must be in both or in neither"
        )
    over = most > total
    if over.any():
        k = int(np.flatnonzero(over)[0])
        raise ValueError(f"solver_iterations_max={most[k]} exceeds the run's total solver_iterations={total[k]}")


def _fixed_coords(ds):
    for dim, labels in FIXED_COORDS.items():
        if dim in ds.dims and [_text(v) for v in ds[dim].values] != list(labels):
            raise ValueError(f"coordinate {dim} is {[_text(v) for v in ds[dim].values]}, not {labels}")


def _declarations(ds):
    from ..kernels.invariants import INVARIANTS
    from ..kernels.scenes import SCENES

    if "combined_member" not in ds.attrs:
        scene = _text(ds.attrs.get("scene", "heavy_top"))
        if scene not in SCENES:
            raise ValueError(f"scene={scene!r} is not a scene this gyrolab knows ({', '.join(SCENES)})")
    for name in _text(ds.attrs.get("conserved", "")).split():
        if name not in INVARIANTS:
            raise ValueError(f"conserved names {name!r}, not an invariant ({', '.join(INVARIANTS)})")
    known = {m.CLOSED_FORM for m in SCENES.values() if m.CLOSED_FORM}
    form = _text(ds.attrs.get("closed_form", ""))
    if form and form not in known:
        raise ValueError(f"closed_form={form!r} is not a closed form this gyrolab knows ({', '.join(sorted(known))})")


def _inputs(ds):
    for name in ("body", "omega0", "q0"):
        if name not in ds.data_vars:
            continue
        values = ds[name].values
        if values.dtype.kind != "f" or not np.all(np.isfinite(values)):
            raise ValueError(f"run input {name} has a value that is not a finite number")
    if "body" in ds.data_vars:
        moments = ds["body"].sel(body_param=["I1", "I2", "I3"]).values
        if np.any(moments <= 0):
            raise ValueError(
                f"body has a moment of inertia <= 0 kg m2 ({_first(moments.ravel(), moments.ravel() <= 0)})"
            )
