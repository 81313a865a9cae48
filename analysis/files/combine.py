"""``gyrolab-combine``: merge the results files of a multirun into one Dataset/file.
Usage examples: README.md, "Using it".

Every input is checked before anything is written: a gyrolab results file
of a known ``layout_version`` with exactly the layout's variables, dims,
units and integer run variables (gyrolab/results/layout.py); no unfinished job (a
journal ``*.partial`` or a lock next to where a results file belongs) unless
``--skip-unfinished``.  Each refusal is one line naming the file and the
reason, exit status 2, and the output is not touched.

Files of every layout are read as today's (gyrolab/results/layout.py ``current``: the ``method`` dim of
layouts before 3 is ``integrator``, a four-field body gains mgc1 = mgc2 = 0) and the combined file
is of today's layout (a per-sample variable an older layout lacks is left out of its ``variables``
attr; the per-run solver counts a file of layout 0 to 3 lacks are -1, "not counted", for its runs:
gyrolab/results/migrate.py).

Files made with the same scene, scene options, t_end, output.every and
divergence threshold are joined along the grid axes (integrator, f, theta0, dt):
their grids must tile the union grid without overlap; with
``--allow-identical-overlap`` runs present in several files are accepted when
they are bit-identical (wall_time aside).  The run inputs (body, omega0, q0
over f, theta0) must agree wherever tiles share an (f, theta0).  Groups that
differ in those attrs are stacked along a new dimension: ``scene`` when each
group is a different scene, else ``job``; the attrs that differ become
coordinates along it, and points missing from a group's grid are NaN with
status -1 (n_steps 0, solver counts -1); every other attr that differs between the groups
(``conserved``, ``closed_form``, ``config``, ...) becomes such a coordinate too (a vector scene
option as JSON text, coordinate attr ``encoding: json``), so that a member read back
(analysis/io.py ``open_members``) carries its own attrs.  Each input file's provenance (config,
git commit and dirty flag, kernel source hash, creation time, path) is kept in variables along a
``source`` dimension.  The inputs are loaded into memory; the output is written through a temporary
file, fsync and rename (gyrolab/safe_files.py atomic_replace).
"""

import argparse
import json
import signal
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from ...pipes import quiet_on_broken_pipe
from ...results import ResultsError, find_results, open_file
from ...results.identity import VOLATILE_ATTRS
from ...results.layout import (
    COORD_ATTRS,
    GRID_DIMS,
    INPUT_DIMS,
    INPUT_VARIABLES,
    LAYOUT_VERSION,
    RUN_VARIABLES,
    SAMPLE_VARIABLES,
    STATUS_ABSENT,
    VARIABLE_ATTRS,
    VARIABLES_ATTR,
    held_run_variables,
    held_variables,
    sample_dims,
    variables_attr,
)
from ...results.migrate import NOT_COUNTED, SOLVER_COUNTS, file_layout_version
from ...results.validate import validate
from ...safe_files import (
    OutputBusyError,
    OutputLock,
    UnsafePathError,
    atomic_replace,
    check_replaceable,
    remove_stale_temporaries,
)

KNOWN_LAYOUTS = tuple(range(LAYOUT_VERSION + 1))
IDENTITY_PREFIXES = ("scene",)
IDENTITY_KEYS = ("t_end", "every", "divergence_threshold")
PROVENANCE = ("config", "git_commit", "git_dirty", "kernel_source_hash", "created", "gyrolab_version")
LAYOUT_DIMS = {name: GRID_DIMS + sample_dims(name) for name in SAMPLE_VARIABLES}
LAYOUT_DIMS.update({name: GRID_DIMS for name in RUN_VARIABLES})
LAYOUT_DIMS.update({name: INPUT_DIMS + (own,) for name, (own, _) in INPUT_VARIABLES.items()})


class CombineError(ValueError):
    """Inputs that cannot be combined; the message is one line."""


def load(path):
    """The results Dataset of ``path`` in memory (results.open_file), checked against the layout as a
    file to combine (``layout_problem``); ResultsError or CombineError naming the file and the first
    problem."""
    ds, version = open_file(path)
    problem = layout_problem(ds, version)
    if problem:
        raise CombineError(f"{path}: {problem}")
    try:
        validate(ds)  # what it holds, as the reader checks it for every command (gyrolab/results/validate.py)
    except ValueError as err:
        raise CombineError(f"{path}: {err}") from None
    held = held_variables(ds, version)
    for name in RUN_VARIABLES:  # the solver counts of a file of layout 0 to 3: not counted
        if name not in ds.data_vars:
            dtype, attrs = RUN_VARIABLES[name]
            ds[name] = (GRID_DIMS, np.full(tuple(ds.sizes[d] for d in GRID_DIMS), NOT_COUNTED, dtype), attrs)
    ds.attrs["layout_version"] = LAYOUT_VERSION  # today's names and body now, what it holds named below
    if variables_attr(held) is not None:
        ds.attrs[VARIABLES_ATTR] = variables_attr(held)
    return ds


def layout_problem(ds, version=None):
    """Why ``ds`` (renamed by layout.current; ``version``: its file's layout) is not a gyrolab
    results file of a known layout, or None."""
    version = file_layout_version(ds) if version is None else version
    if version is None:
        return "not a gyrolab results file (no layout_version attr)"
    if "combined_from" in ds.attrs:
        return "already a combined file (combine the job files it came from)"
    if version not in KNOWN_LAYOUTS:
        return f"layout_version={version}: unknown (this gyrolab reads {', '.join(map(str, KNOWN_LAYOUTS))})"
    if "scene" not in ds.attrs:
        return "not a gyrolab results file (no scene attr)"
    held = held_variables(ds, version)
    expected = {
        name: dims
        for name, dims in LAYOUT_DIMS.items()
        if (name not in SAMPLE_VARIABLES or name in held)
        and not (name in INPUT_VARIABLES and version == 0)
        and (name not in RUN_VARIABLES or name in held_run_variables(version))
    }
    for name, dims in expected.items():
        if name not in ds.data_vars:
            return f"no variable {name!r} (not a complete gyrolab results file)"
        if ds[name].dims != dims:
            return f"variable {name} has dims {ds[name].dims}, expected {dims}"
        units = VARIABLE_ATTRS[name].get("units")
        if ds[name].attrs.get("units") != units:
            return f"variable {name} has units {ds[name].attrs.get('units')!r}, expected {units!r}"
    for name in held_run_variables(version):
        if ds[name].dtype.kind not in "iu" and name != "wall_time":
            return f"variable {name} has dtype {ds[name].dtype}, expected integers"
    for name in expected:
        if name in SAMPLE_VARIABLES and ds[name].dtype != np.float64:
            return f"variable {name} has dtype {ds[name].dtype}, expected float64"
    foreign = sorted(set(ds.data_vars) - set(expected))
    if foreign:
        return f"variable {foreign[0]!r} is not in the gyrolab layout"
    for dim in GRID_DIMS + ("time",):
        if dim not in ds.coords:
            return f"no coordinate {dim!r}"
        units = COORD_ATTRS[dim].get("units")
        if ds[dim].attrs.get("units") != units:
            return f"coordinate {dim} has units {ds[dim].attrs.get('units')!r}, expected {units!r}"
        if dim != "integrator" and not np.isfinite(np.asarray(ds[dim].values, dtype=float)).all():
            return f"coordinate {dim} has a non-finite value (NaN or inf)"
        if len(set(ds[dim].values.tolist())) != ds.sizes[dim]:
            return f"coordinate {dim} has repeated values"
    return None


def identity(ds):
    """The attrs that must agree for two files to share one grid."""
    return tuple(
        sorted(
            (k, _hashable(_plain(v)))
            for k, v in ds.attrs.items()
            if k.startswith(IDENTITY_PREFIXES) or k in IDENTITY_KEYS
        )
    )


def _hashable(value):
    """An attr value as a dict key: a vector (heavy_body's com) as a tuple."""
    return tuple(np.asarray(value).tolist()) if isinstance(value, np.ndarray) else value


def _plain(value):
    value = value.item() if isinstance(value, np.generic) else value
    return value.decode() if isinstance(value, bytes) else value


def combine(paths, allow_identical_overlap=False):
    """One Dataset from the results files ``paths`` (see the module docstring)."""
    datasets = [load(path) for path in paths]
    for ds, path in zip(datasets[1:], paths[1:]):
        if held_variables(ds) != held_variables(datasets[0]):
            raise CombineError(
                f"{path}: holds the variables {', '.join(held_variables(ds))}, {paths[0]} holds "
                f"{', '.join(held_variables(datasets[0]))}; combine files of the same output.variables"
            )
    sources = _sources(datasets, paths)
    groups = {}
    for ds, path in zip(datasets, paths):
        groups.setdefault(identity(ds), []).append((_strip(ds), path))
    merged = [
        join_tiles(group, allow_identical_overlap) if len(group) > 1 else group[0][0] for group in groups.values()
    ]
    if len(merged) == 1:
        out = merged[0]
    else:
        out = _stack(merged, [dict(k) for k in groups])
    out = out.merge(sources)
    out.attrs["combined_from"] = len(paths)
    return out


def _union(values_per_tile, dim):
    """The union grid axis: numbers ascending, integrators in order of first appearance."""
    seen = []
    for values in values_per_tile:
        seen.extend(v for v in values.tolist() if v not in seen)
    return seen if dim == "integrator" else sorted(seen)


def join_tiles(group, allow_identical_overlap=False):
    """Join the (Dataset, path) tiles of one grid along GRID_DIMS; CombineError when they do not
    tile the union grid (a hole, or an overlap that is not allowed or not bit-identical)."""
    first, first_path = group[0]
    for ds, path in group[1:]:
        if not np.array_equal(ds["time"].values, first["time"].values):
            raise CombineError(f"{path}: time coordinate differs from {first_path}'s")
    for ds, path in group[1:]:
        for name in (*held_variables(first), *RUN_VARIABLES):
            if ds[name].dtype != first[name].dtype:  # the tile would be cast to the first file's dtype
                raise CombineError(
                    f"{path}: variable {name} is {ds[name].dtype}, {first_path}'s is {first[name].dtype}"
                )
    axes = {d: _union([ds[d].values for ds, _ in group], d) for d in GRID_DIMS}
    shape = tuple(len(axes[d]) for d in GRID_DIMS)
    owner = np.full(shape, -1, dtype=np.int64)
    data = {
        name: np.zeros(shape + first[name].shape[len(GRID_DIMS) :], dtype=first[name].dtype)
        for name in (*held_variables(first), *RUN_VARIABLES)
    }
    inputs_shape = tuple(len(axes[d]) for d in INPUT_DIMS)
    stored = [name for name in INPUT_VARIABLES if name in first]  # none in a layout-0 file
    for ds, path in group[1:]:
        if [name for name in INPUT_VARIABLES if name in ds] != stored:
            raise CombineError(f"{path}: stores run inputs and {first_path} does not (or the reverse)")
    inputs = {name: np.full(inputs_shape + first[name].shape[len(INPUT_DIMS) :], np.nan) for name in stored}
    input_owner = np.full(inputs_shape, -1, dtype=np.int64)
    for t, (ds, path) in enumerate(group):
        at = np.ix_(*[[axes[d].index(v) for v in ds[d].values.tolist()] for d in GRID_DIMS])
        taken = owner[at] >= 0
        if taken.any():
            other = group[int(owner[at][taken][0])][1]
            if not allow_identical_overlap:
                raise CombineError(
                    f"{path}: its grid overlaps {other}'s ({int(taken.sum())} runs in both); "
                    "tiles must not overlap (--allow-identical-overlap accepts bit-identical runs)"
                )
            for name in data:
                mine, theirs = data[name][at][taken], ds[name].values[taken]
                if name in SOLVER_COUNTS:  # a file of layout 0 to 3 did not count them (load): either will do
                    counted = (mine != NOT_COUNTED) & (theirs != NOT_COUNTED)
                    mine, theirs = mine[counted], theirs[counted]
                if name != "wall_time" and not _same_bits(mine, theirs):
                    raise CombineError(
                        f"{path}: {name} of the runs it shares with {other} differs; "
                        "overlapping runs must be bit-identical"
                    )
        for name in data:
            block = data[name][at]
            fill = ~taken | (block == NOT_COUNTED) if name in SOLVER_COUNTS else ~taken
            block[fill] = ds[name].values[fill]
            data[name][at] = block
        owner[at] = np.where(taken, owner[at], t)
        iat = np.ix_(*[[axes[d].index(v) for v in ds[d].values.tolist()] for d in INPUT_DIMS])
        shared = input_owner[iat] >= 0
        for name in stored:
            if shared.any() and not _same_bits(inputs[name][iat][shared], ds[name].values[shared]):
                other = group[int(input_owner[iat][shared][0])][1]
                raise CombineError(f"{path}: run input {name} differs from {other}'s at the same (f, theta0)")
            inputs[name][iat] = ds[name].values
        input_owner[iat] = np.where(shared, input_owner[iat], t)
    if (owner < 0).any():
        hole = dict(zip(GRID_DIMS, (axes[d][int(i)] for d, i in zip(GRID_DIMS, np.argwhere(owner < 0)[0]))))
        point = ", ".join(f"{k}={v}" for k, v in hole.items())
        raise CombineError(
            f"files of {first.attrs.get('scene', '?')} do not tile one grid: run ({point}) is "
            f"in none of them ({int((owner < 0).sum())} of {owner.size} runs missing)"
        )
    kinds = {d: object if d == "integrator" else float for d in GRID_DIMS}
    coords = {d: (d, np.array(axes[d], dtype=kinds[d]), first[d].attrs) for d in GRID_DIMS}
    coords.update({d: (d, first[d].values, first[d].attrs) for d in first.coords if d not in GRID_DIMS})
    variables = {name: (first[name].dims, values, first[name].attrs) for name, values in data.items()}
    variables.update({name: (first[name].dims, values, first[name].attrs) for name, values in inputs.items()})
    attrs = dict(first.attrs)
    for ds, _ in group[1:]:
        attrs = {k: v for k, v in attrs.items() if k in ds.attrs and _equal(ds.attrs[k], v)}
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _equal(a, b):
    try:
        return bool(np.all(np.asarray(a) == np.asarray(b)))
    except Exception:  # unlike types
        return False


def _strip(ds):
    return ds.drop_attrs(deep=False).assign_attrs(
        {k: v for k, v in ds.attrs.items() if k not in VOLATILE_ATTRS and k != "config_hash"}
    )


def _sources(datasets, paths):
    data = {}
    for name in PROVENANCE:
        data[f"source_{name}"] = ("source", np.array([str(ds.attrs.get(name, "")) for ds in datasets], dtype=object))
    data["source_path"] = ("source", np.array([str(Path(p).resolve()) for p in paths], dtype=object))
    return xr.Dataset(data)


def _stack(merged, identities):
    attrs = [m.attrs for m in merged]
    keys = dict.fromkeys(k for a in attrs for k in a)
    differing = [k for k in keys if not all(k in a and _equal(a[k], attrs[0].get(k)) for a in attrs)]
    scenes = [i.get("scene") for i in identities]
    dim = "scene" if len(set(scenes)) == len(scenes) else "job"
    fill = {"status": STATUS_ABSENT, "n_steps": 0} | {name: NOT_COUNTED for name in SOLVER_COUNTS}
    common = {k: attrs[0][k] for k in keys if k not in differing}
    shared = [m.drop_attrs(deep=False).assign_attrs(common) for m in merged]
    out = xr.concat(
        shared,
        dim=dim,
        join="outer",
        fill_value=fill,
        combine_attrs="drop_conflicts",
        data_vars="all",
        coords="different",
        compat="equals",
    )
    out = out.assign_coords({k: _label([_plain(a.get(k)) for a in attrs], dim) for k in differing})
    for name, (dtype, _) in RUN_VARIABLES.items():  # integers, filled where a group has no run
        if name in out and np.dtype(dtype).kind in "iu":
            out[name] = out[name].astype(dtype)
    if "status" in out:
        legend = out["status"].attrs.get("legend", "")
        out["status"].attrs["legend"] = f"{legend}; {STATUS_ABSENT}: not in this {dim}'s grid"
    return out


def _label(values, dim):
    """The coordinate along ``dim`` of an attr that differs between groups (missing in some: "" or
    NaN); vectors (a scene option such as heavy_body's com) as JSON text, attr ``encoding: json``."""
    if any(isinstance(v, (np.ndarray, list, tuple)) for v in values):
        text = ["" if v is None else json.dumps(np.asarray(v).tolist()) for v in values]
        return (dim, np.array(text, dtype=object), {"encoding": "json"})
    if any(isinstance(v, str) for v in values):
        return (dim, np.array(["" if v is None else str(v) for v in values], dtype=object))
    return (dim, np.array([np.nan if v is None else v for v in values], dtype=float))


def write(ds, path):
    """Write ``ds`` to ``path`` (h5netcdf) through a temporary file, fsync and rename (holding
    ``<path>.lock``, removing temporaries a killed combine left).  A string variable drops the on-disk
    width its first input file gave it (encoding dtype ``<U3`` for "rk4"): kept, it would cut the longer
    names of the other inputs to that width, silently."""
    ds = ds.copy()
    for var in ds.variables.values():
        if var.dtype.kind in "OSU":
            var.encoding.pop("dtype", None)
    with OutputLock(path):
        remove_stale_temporaries(path)
        atomic_replace(path, lambda tmp: ds.to_netcdf(tmp, engine="h5netcdf"))


@quiet_on_broken_pipe
def main(argv=None):
    """Console entry point ``gyrolab-combine``."""
    parser = argparse.ArgumentParser(prog="gyrolab-combine", description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="+", help="results files or directories (searched recursively)")
    parser.add_argument("-o", "--output", help="combined file (default: <dir>/combined.h5 for one directory)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    parser.add_argument(
        "--allow-identical-overlap",
        action="store_true",
        help="accept runs present in several files when they are bit-identical",
    )
    parser.add_argument(
        "--skip-unfinished",
        action="store_true",
        help="leave out unfinished jobs (a journal or lock, no results file) with a warning",
    )
    args = parser.parse_args(argv)
    previous = {sig: signal.signal(sig, _interrupted) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        return _run(args)
    except KeyboardInterrupt as err:  # Ctrl-C, SIGTERM, SIGHUP: the temporary and the lock are gone by now
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_IGN)
        signum = getattr(err, "signum", signal.SIGINT)
        sys.stderr.write(
            f"gyrolab-combine: interrupted ({signal.Signals(signum).name}); {args.output or 'the output'} "
            "is untouched\n"
        )
        return 128 + signum
    finally:
        for sig, handler in previous.items():
            if signal.getsignal(sig) is _interrupted:
                signal.signal(sig, handler)


class _Interrupt(KeyboardInterrupt):
    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _interrupted(signum, frame):
    raise _Interrupt(signum)


def _run(args):
    try:
        for path in args.paths:
            if not Path(path).exists():
                raise CombineError(f"{path}: no such file or directory")
        if args.output is None:
            if len(args.paths) != 1 or not Path(args.paths[0]).is_dir():
                raise CombineError("-o/--output: needed unless one directory is given")
            args.output = str(Path(args.paths[0]) / "combined.h5")
        out = Path(args.output)
        if out.exists() and not args.overwrite:
            raise CombineError(f"--output={out}: exists; add --overwrite to replace it")
        if not out.parent.is_dir():
            raise CombineError(f"--output={out}: {out.parent} is not a directory")
        check_replaceable(out)  # a link or special file there: refused before any work
        files = find_results(args.paths, exclude=out, unfinished="skip" if args.skip_unfinished else "refuse")
        ds = combine(files, args.allow_identical_overlap)
        write(ds, out)
    except (CombineError, OutputBusyError, ResultsError, UnsafePathError) as err:
        sys.stderr.write(f"gyrolab-combine: error: {' '.join(str(err).split())}\n")
        return 2
    except OSError as err:  # a full disk while writing: the old output, if any, is untouched
        sys.stderr.write(f"gyrolab-combine: error: writing {args.output}: {err.strerror or err}\n")
        return 1
    dims = ", ".join(f"{k}: {v}" for k, v in ds.sizes.items())
    print(f"gyrolab-combine: {len(files)} file{'' if len(files) == 1 else 's'} -> {out} ({dims})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
