"""``gyrolab-combine``: merge the results files of a multirun into one Dataset/file.

    gyrolab-combine multirun/2026-01-01/12-00-00-000000            # -> <dir>/combined.h5
    gyrolab-combine a/results.h5 b/results.h5 -o both.h5

Files made with the same scene, scene options, t_end, output.every and
divergence threshold are joined along the grid axes (method, f, theta0, dt;
their grids must tile without overlap).  Groups that differ in those are
stacked along a new dimension: ``scene`` when each group is a different
scene, else ``job``; the attrs that differ become coordinates along it, and
points missing from a group's grid are NaN with status -1.  Each input file's
provenance (config, git commit, creation time, path) is kept in variables
along a ``source`` dimension.  The inputs are loaded into memory.
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from .provenance import VOLATILE_ATTRS

IDENTITY_PREFIXES = ("scene",)
IDENTITY_KEYS = ("t_end", "every", "divergence_threshold")
PROVENANCE = ("config", "git_commit", "created", "gyrolab_version")
STATUS_ABSENT = -1


class CombineError(ValueError):
    """Inputs that cannot be combined; the message is one line."""


def find_results(paths, exclude=None):
    """Results files under the given files/directories (``*.h5``, not temporaries or partial chunks)."""
    found = []
    for path in map(Path, paths):
        if path.is_dir():
            candidates = sorted(path.rglob("*.h5"))
        elif path.is_file():
            candidates = [path]
        else:
            raise CombineError(f"{path}: no such file or directory")
        for c in candidates:
            if c.name.startswith(".") or any(p.name.endswith(".partial") for p in c.parents):
                continue
            if exclude is not None and c.resolve() == Path(exclude).resolve():
                continue
            found.append(c)
    if not found:
        raise CombineError(f"{' '.join(map(str, paths))}: no results files (*.h5) found")
    return found


def identity(ds):
    """The attrs that must agree for two files to share one grid."""
    return tuple(sorted((k, _plain(v)) for k, v in ds.attrs.items()
                        if k.startswith(IDENTITY_PREFIXES) or k in IDENTITY_KEYS))


def _plain(value):
    return value.item() if isinstance(value, np.generic) else value


def combine(paths):
    """One Dataset from the results files ``paths`` (see the module docstring)."""
    datasets = []
    for path in paths:
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            datasets.append(ds.load())
    sources = _sources(datasets, paths)
    groups = {}
    for ds in datasets:
        groups.setdefault(identity(ds), []).append(_strip(ds))
    merged = []
    for key, group in groups.items():
        try:
            merged.append(xr.combine_by_coords(group, combine_attrs="drop_conflicts") if len(group) > 1 else group[0])
        except ValueError as err:
            raise CombineError(f"files of {dict(key).get('scene', '?')} do not tile one grid: "
                               f"{str(err).splitlines()[0]}") from None
    if len(merged) == 1:
        out = merged[0]
    else:
        out = _stack(merged, [dict(k) for k in groups])
    out = out.merge(sources)
    out.attrs["combined_from"] = len(paths)
    return out


def _strip(ds):
    return ds.drop_attrs(deep=False).assign_attrs(
        {k: v for k, v in ds.attrs.items() if k not in VOLATILE_ATTRS and k != "config_hash"})


def _sources(datasets, paths):
    data = {}
    for name in PROVENANCE:
        data[f"source_{name}"] = ("source", np.array([str(ds.attrs.get(name, "")) for ds in datasets], dtype=object))
    data["source_path"] = ("source", np.array([str(Path(p).resolve()) for p in paths], dtype=object))
    return xr.Dataset(data)


def _stack(merged, identities):
    differing = sorted({k for ident in identities for k in ident
                        if len({_plain(i.get(k)) for i in identities}) > 1})
    scenes = [i.get("scene") for i in identities]
    dim = "scene" if len(set(scenes)) == len(scenes) else "job"
    fill = {"status": STATUS_ABSENT, "n_steps": 0}
    out = xr.concat(merged, dim=dim, join="outer", fill_value=fill, combine_attrs="drop_conflicts",
                    data_vars="all", coords="different", compat="equals")
    labels = {k: (dim, _label([i.get(k) for i in identities])) for k in differing}
    out = out.assign_coords(labels)
    for k in differing:
        out.attrs.pop(k, None)
    if "status" in out:
        out["status"] = out["status"].astype(np.int8)
        legend = out["status"].attrs.get("legend", "")
        out["status"].attrs["legend"] = f"{legend}; {STATUS_ABSENT}: not in this {dim}'s grid"
    return out


def _label(values):
    """Coordinate values of a differing attr (missing in some groups: "" or NaN)."""
    if any(isinstance(v, str) for v in values):
        return np.array(["" if v is None else str(v) for v in values], dtype=object)
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def write(ds, path):
    """Write ``ds`` to ``path`` (h5netcdf) through a temporary file renamed into place."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        ds.to_netcdf(tmp, engine="h5netcdf")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def main(argv=None):
    """Console entry point ``gyrolab-combine``."""
    parser = argparse.ArgumentParser(prog="gyrolab-combine", description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="+", help="results files or directories (searched recursively)")
    parser.add_argument("-o", "--output", help="combined file (default: <dir>/combined.h5 for one directory)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    args = parser.parse_args(argv)
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
        files = find_results(args.paths, exclude=out)
        ds = combine(files)
        write(ds, out)
    except CombineError as err:
        sys.stderr.write(f"gyrolab-combine: error: {' '.join(str(err).split())}\n")
        return 2
    dims = ", ".join(f"{k}: {v}" for k, v in ds.sizes.items())
    print(f"gyrolab-combine: {len(files)} files -> {out} ({dims})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
