"""The one way to find, open and check results files, for every command and script.

``open_results(path)`` gives a one-scene results file (or one member of a
combined file) in memory, as today's layout names it; ``open_members`` each
member of a combined file; ``open_file`` a whole file, combined or not, read
and migrated but not split.  Every problem with a file (missing, unreadable,
damaged, foreign, of a newer layout, lacking a layout variable, a member it
does not have) is one ``ResultsError`` whose message is one line naming the
file; every command turns it into that line and exit status ``EXIT_BAD_INPUT``.
"""

import sys
from pathlib import Path

import h5netcdf
import h5py
import xarray as xr

from ..limits import LimitError, check_file_sizes
from .errors import EXIT_BAD_INPUT, ResultsError  # noqa: F401 - the reader's names, as before
from .layout import GRID_DIMS, LAYOUT_VERSION, required_variables
from .members import member, member_dim, member_labels
from .migrate import current, file_layout_version
from .validate import validate


def _scene_name(ds):
    value = ds.attrs.get("scene", "heavy_top")
    return value.decode() if isinstance(value, bytes) else str(value)


class _LookupsKept(h5py.File):
    """An HDF5 file opened read-only whose objects, once looked up by path, are kept.

    h5netcdf looks a variable's dimensions up by path each time it asks for the variable's shape (and each
    dimension twice: its length, whether it is unlimited), about 1300 lookups to open one results file:
    ~0.1 s of the ~0.14 s ``xr.open_dataset`` took (h5netcdf/h5netcdf#195 is the upstream issue).  A
    file opened read-only never changes its objects, so each path is looked up once."""

    def __init__(self, path):
        self._kept = {}
        super().__init__(path, "r")

    def __getitem__(self, name):
        if not isinstance(name, str):  # object references and the like: as h5py does
            return super().__getitem__(name)
        try:
            return self._kept[name]
        except KeyError:
            found = self._kept[name] = super().__getitem__(name)
            return found

    def close(self):
        self._kept = {}
        super().close()


def _open_dataset(path):
    """``xr.open_dataset(path, engine="h5netcdf", phony_dims="access")`` through a file whose lookups are
    kept (``_LookupsKept``): the same Dataset, variables, attrs and encodings, lazy.  ``ds.close()``
    closes the file; a Dataset made from it (``assign``, a rename) closes it only once given
    ``set_close(ds.close)``."""
    h5 = _LookupsKept(path)
    try:
        # h5netcdf takes an open h5py file (and then leaves closing it to its owner); the kwargs are the
        # ones xarray's h5netcdf engine passes
        store = xr.backends.H5NetCDFStore(h5netcdf.File(h5, "r", phony_dims="access", decode_vlen_strings=True))
        ds = xr.open_dataset(store)
    except BaseException:
        h5.close()
        raise

    def close():
        store.close()
        h5.close()

    ds.set_close(close)
    return ds


def open_file(path, lazy=False):
    """(Dataset with today's names, its file's layout version or None) of ``path``, a results file
    combined or not, read whole and closed again; ResultsError (one line) when it is missing or
    unreadable (anything h5py/h5netcdf/xarray raise on damaged or foreign input).

    ``lazy``: only what has no time axis is read (per-run variables, coordinates, run inputs); the
    per-sample variables stay on disk, read slab by slab as a figure selects them, and the file stays
    open until the Dataset is closed (``ds.close()``): memory then follows what is drawn, not the
    file (the figure step's way)."""
    path = Path(path)
    if not path.is_file():
        raise ResultsError(f"FILE={path}: no such results file")
    opened = None
    try:
        if lazy:  # memory follows what is read, not the file; a crafted file is still refused
            check_file_sizes(path, budget=float("inf"))
            opened = _open_dataset(path)
            small = [name for name in opened.variables if "time" not in opened[name].dims]
            ds = opened.assign({name: opened[name].load() for name in small if name in opened.data_vars})
            ds = ds.assign_coords({name: ds[name].load() for name in small if name in ds.coords})
        else:
            check_file_sizes(path)  # before loading: a small file declaring gigabytes (gyrolab/limits.py)
            with _open_dataset(path) as ds:
                ds = ds.load()
    except LimitError as err:
        raise ResultsError(f"FILE={err}") from None
    except Exception as err:  # h5py/h5netcdf/xarray raise many kinds on damaged or foreign files
        if opened is not None:
            opened.close()
        text = " ".join(str(err).split())[:120]
        raise ResultsError(f"FILE={path}: not a readable results file ({type(err).__name__}: {text})") from None
    version = file_layout_version(ds)
    ds = current(ds)  # an older layout's ``method`` is ``integrator``, its body today's
    if opened is not None:  # assign and the renames make new Datasets without the file's close: it stayed open
        ds.set_close(opened.close)  # until collected
    return ds, version


def check(where, ds, version):
    """``ds`` (one scene's results, renamed by ``current``) if it is a gyrolab results file this
    gyrolab reads, else ResultsError (one line naming ``where`` and the first problem)."""
    missing = [d for d in GRID_DIMS + ("time",) if d not in ds.dims]
    if missing:
        raise ResultsError(f"FILE={where}: not a gyrolab results file (no dimension {missing[0]!r})")
    if version is None:
        raise ResultsError(f"FILE={where}: not a gyrolab results file (no layout_version attr)")
    if version > LAYOUT_VERSION:
        raise ResultsError(
            f"FILE={where}: layout_version={version} is newer than this gyrolab reads "
            f"({LAYOUT_VERSION}); upgrade gyrolab"
        )
    for name, dims in required_variables(version, ds).items():
        if name not in ds.data_vars:
            raise ResultsError(f"FILE={where}: not a complete gyrolab results file (no variable {name!r})")
        if ds[name].dims != dims:
            raise ResultsError(f"FILE={where}: variable {name} has dims {ds[name].dims}, expected {dims}")
    try:
        validate(ds)  # what the variables hold (gyrolab/results/validate.py)
    except ValueError as err:
        raise ResultsError(f"FILE={where}: {err}") from None
    return ds


def open_members(path, member_of=None, lazy=False):
    """[(label, Dataset)] of the results file ``path``: [(None, ds)] for a one-scene file; for a
    combined file (a leading ``scene`` or ``job`` dim) each member, or the one ``member_of`` names
    ({"scene": "heavy_top"} or {"job": "1"}), as a one-scene Dataset with its own attrs, each checked.
    ResultsError (one line) for a file no reader can open or a member it does not have.  ``lazy``:
    see ``open_file``."""
    ds, version = open_file(path, lazy)
    return members_of(path, ds, version, member_of)


def members_of(path, ds, version, member_of=None):
    """``open_members`` of a file already opened with ``open_file`` (``ds``, ``version``)."""
    dim = member_dim(ds)
    wanted_members = {k: v for k, v in (member_of or {}).items() if v is not None}
    if dim is None:
        for key, value in wanted_members.items():
            value = value[0] if isinstance(value, (list, tuple)) else value
            if not (key == "scene" and str(value) == _scene_name(ds)):
                raise ResultsError(f"{key}={value}: FILE={path} is not a combined file (one scene, {_scene_name(ds)})")
        return [(None, check(path, ds, version))]
    labels = member_labels(ds)
    for key in wanted_members:
        if key != dim:
            raise ResultsError(f"{key}=: FILE={path} is combined along {dim} ({dim} has {', '.join(labels)})")
    wanted = wanted_members.get(dim, labels)
    wanted = [str(v) for v in (wanted if isinstance(wanted, (list, tuple)) else [wanted])]
    for label in wanted:
        if label not in labels:
            raise ResultsError(f"{dim}={label}: not in FILE={path} ({dim} has {', '.join(labels)})")
    return [(label, check(f"{path} {dim}={label}", member(ds, label), version)) for label in wanted]


def open_results(path, member_of=None, lazy=False):
    """The results Dataset of ``path`` in memory (file closed afterwards), as today's layout names
    it (an older layout's ``method`` dim is ``integrator``, its body today's), checked against the
    layout.  A combined file (gyrolab-combine) opens as the one member ``member_of`` names
    ({"scene": NAME} or {"job": K}); without one, ResultsError naming its members and the selection
    that picks one.  ResultsError (one line naming the file) for any file it cannot use.  ``lazy``:
    see ``open_file`` (close the Dataset when done)."""
    members = open_members(path, member_of, lazy)
    if len(members) > 1:
        dim = members[0][1].attrs["combined_member"].partition("=")[0]
        for _, ds in members:
            ds.close()
        raise ResultsError(
            f"FILE={path}: a combined file of {len(members)} {dim}s ({', '.join(label for label, _ in members)}); "
            f"choose one with {dim}={members[0][0]}"
        )
    return members[0][1]


def find_results(paths, exclude=None, unfinished="ignore"):
    """Results files (``*.h5``) named by ``paths``: files as given, directories searched recursively,
    leaving out temporaries (names starting with ``.``), journals (``*.partial``) and ``exclude``.

    ``unfinished`` says what to do with a directory's unfinished job (a journal or a lock without
    its results file): "ignore" it, "refuse" (ResultsError naming it and how to finish it) or "skip"
    (a warning on stderr, its results file left out).  ResultsError for a path that does not exist,
    a directory without results files, or nothing found."""
    found = []
    for path in map(Path, paths):
        if path.is_dir():
            candidates = sorted(path.rglob("*.h5"))
            if unfinished != "ignore":
                for marker in sorted([*path.rglob("*.h5.partial"), *path.rglob("*.h5.lock")]):
                    target = marker.with_name(marker.name.rsplit(".", 1)[0])
                    what = "an interrupted sweep's journal" if marker.suffix == ".partial" else "a lock (running?)"
                    if target.exists() and marker.suffix == ".partial":
                        what = "a leftover journal next to its results file"
                    message = f"{marker.parent}: unfinished job: {what} {marker.name}"
                    if unfinished == "refuse":
                        raise ResultsError(
                            f"{message}; finish it with runner.resume=true, or pass --skip-unfinished to leave it out"
                        )
                    sys.stderr.write(f"warning: {message}; left out\n")
                    candidates = [c for c in candidates if c != target]
        elif path.is_file():
            candidates = [path]
        else:
            raise ResultsError(f"FILE={path}: no such results file or directory")
        mine = [
            c
            for c in candidates
            if not (c.name.startswith(".") or any(p.name.endswith(".partial") for p in c.parents))
            and not (exclude is not None and c.resolve() == Path(exclude).resolve())
        ]
        if not mine and path.is_dir():
            raise ResultsError(f"FILE={path}: a directory without results files (*.h5)")
        found.extend(mine)
    if not found:
        raise ResultsError(f"FILE={' '.join(map(str, paths))}: no results files (*.h5) found")
    return found
