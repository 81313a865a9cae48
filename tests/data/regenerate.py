"""Stored regression data: one file per (regression config, method), added or replaced on purpose only.

    python tests/data/regenerate.py                 # re-run everything, show how it differs from the stored files
    python tests/data/regenerate.py --add           # write the files that are missing (a new method or config)
    python tests/data/regenerate.py --write heavy_top_release:rk4 free_symmetric   # replace these on purpose

Each file ``tests/data/regression/<name>/<method>.pack.xz`` holds the output of the
real command ``gyrolab experiment=regression_<name> sweep.method=[<method>]``
(config in ``conf/experiment/regression_<name>.yaml``).  A registered scene
that no pinned config uses gets a dataset ``scene_<scene>`` of its own: a
short run with SCENE_OVERRIDES, so a new scene is covered by ``--add`` too.  Adding a method or a
regression config is ``--add``: it writes only the files that do not exist,
so every other method's stored bytes stay as they are.  ``--write`` replaces
the named files (``NAME`` for all methods of a config, ``NAME:METHOD`` for
one) after printing the comparison of each fresh run with the stored file,
so a regeneration is always a decision someone made after reading it.
A stored file of an older layout is kept unless ``--relayout`` is given too:
tests/test_layout.py opens those packs as its fixtures of the older layouts,
and a ``--write`` that silently moved them to today's layout broke it once.
Without options nothing is written.  The regression tests
(tests/test_regression.py) import ``run_config``, ``DATASETS``, ``stored_path``,
``read_pack`` and ``SCALED_TOL`` from here.

A stored file is a *pack*, not the results file itself: an xz stream of one JSON
line (the Dataset's attrs, and each variable's dims, dtype, shape and attrs) and
then every variable's raw bytes, C order, in that line's order.  ``read_pack``
gives back the Dataset ``xr.open_dataset(results_file).load()`` gave, bit for bit;
``--export NAME:METHOD OUT.h5`` writes it as a results file again (for
``gyrolab-compare`` or ``gyrolab-plot``).  The pack drops the ~70 kB of
netCDF/HDF5 structure a results file of this size carries, so a method's data
over all the datasets is ~80 kB instead of ~630 kB.
"""

import argparse
import io
import json
import lzma
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent
STORE = DATA_DIR / "regression"
PINNED = ("heavy_top_release", "heavy_top_steady", "free_symmetric", "free_asymmetric")
# The grid of the dataset of a scene no pinned config uses: short, so the chaos stays out.
SCENE_OVERRIDES = (
    "sweep.f=[10]",
    "sweep.theta0=[30]",
    "sweep.dt=[1e-3]",
    "sweep.t_end=1",
    "output.every=1e-2",
    "output.figures=false",
)
# More overrides of one scene's dataset: forced_body's default window [3π, 4π] lies past the
# dataset's 1 s, so its drive acts from t = 0.
SCENE_EXTRA = {"forced_body": ("scene.window=[0,1]",)}
ADD_COMMAND = "python tests/data/regenerate.py --add"

# Regression tolerance (see tests/data/README.md): a value passes when
# |new − stored| <= SCALED_TOL × (largest |value| of that variable in the stored file);
# status and n_steps must match exactly, wall_time is not compared.
SCALED_TOL = 1e-10


def pinned_scene(name):
    """The scene a pinned regression config overrides (its ``override /scene: X`` default)."""
    import importlib.resources

    text = (importlib.resources.files("gyrolab.conf") / "experiment" / f"regression_{name}.yaml").read_text()
    for line in text.splitlines():
        if line.strip().startswith("- override /scene:"):
            return line.split(":", 1)[1].strip()
    raise RuntimeError(f"conf/experiment/regression_{name}.yaml names no scene")


def datasets():
    """Every regression dataset: the pinned configs, then scene_<scene> for each registered scene
    that none of them uses."""
    from gyrolab.kernels.scenes import SCENES

    covered = {pinned_scene(n) for n in PINNED}
    return PINNED + tuple(f"scene_{s}" for s in SCENES if s not in covered)


DATASETS = datasets()


PACK_SUFFIX = ".pack.xz"
PACK_FORMAT = "gyrolab regression pack 1"


def stored_path(name, method):
    """The stored dataset (a pack) of regression config ``name`` for ``method``."""
    return STORE / name / f"{method}{PACK_SUFFIX}"


def _attr_json(value):
    """A JSON form of one attr value: a str as is, a number or array with its dtype (exact: JSON
    floats are written by repr, which round-trips)."""
    if isinstance(value, str):
        return value
    a = np.asarray(value)
    return {"dtype": a.dtype.str, "shape": list(a.shape), "data": a.ravel().tolist()}


def _attr_value(item):
    if isinstance(item, str):
        return item
    a = np.asarray(item["data"], dtype=item["dtype"]).reshape(item["shape"])
    return a[()] if a.ndim == 0 else a  # a 0-d attr reads back as a numpy scalar, as from HDF5


def write_pack(ds, path):
    """Write the loaded Dataset ``ds`` as a pack at ``path`` (atomically: a temp file, then rename)."""
    names = list(ds.coords) + list(ds.data_vars)
    header = {
        "format": PACK_FORMAT,
        "attrs": {k: _attr_json(v) for k, v in ds.attrs.items()},
        "coords": list(ds.coords),
        "variables": [
            {
                "name": n,
                "dims": list(ds[n].dims),
                "dtype": ds[n].dtype.str,
                "shape": list(ds[n].shape),
                "attrs": {k: _attr_json(v) for k, v in ds[n].attrs.items()},
            }
            for n in names
        ],
    }
    body = io.BytesIO()
    body.write(json.dumps(header).encode() + b"\n")  # json.dumps escapes newlines: one line
    for n in names:
        body.write(np.ascontiguousarray(ds[n].values).tobytes())
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(f".{path.name}.tmp")
    part.write_bytes(lzma.compress(body.getvalue(), preset=9 | lzma.PRESET_EXTREME))
    os.replace(part, path)


def read_pack(path):
    """The Dataset stored in the pack ``path`` (raw names, as the results file had them: pass it
    through ``layout.current`` or compare_datasets for today's)."""
    import xarray as xr

    raw = lzma.decompress(Path(path).read_bytes())
    line, _, data = raw.partition(b"\n")
    header = json.loads(line)
    if header.get("format") != PACK_FORMAT:
        raise ValueError(f"{path}: not a {PACK_FORMAT} file")
    arrays, offset = {}, 0
    for var in header["variables"]:
        dtype = np.dtype(var["dtype"])
        size = dtype.itemsize * int(np.prod(var["shape"], dtype=np.int64))
        if offset + size > len(data):
            raise ValueError(f"{path}: ends {offset + size - len(data)} bytes before its header's variables do")
        values = np.frombuffer(data, dtype, offset=offset, count=size // dtype.itemsize).reshape(var["shape"])
        arrays[var["name"]] = xr.Variable(
            var["dims"], values.copy(), {k: _attr_value(v) for k, v in var["attrs"].items()}
        )
        offset += size
    if offset != len(data):
        raise ValueError(f"{path}: {len(data) - offset} bytes more than its header declares")
    coords = {n: arrays.pop(n) for n in header["coords"]}
    return xr.Dataset(arrays, coords, {k: _attr_value(v) for k, v in header["attrs"].items()})


def pack_results(results, path):
    """Store the results file ``results`` (a path) as a pack at ``path``."""
    import xarray as xr

    with xr.open_dataset(results, engine="h5netcdf") as ds:
        write_pack(ds.load(), path)


def export_results(pack, out):
    """Write the pack ``pack`` as a results file ``out`` (netCDF4/HDF5, as gyrolab writes)."""
    read_pack(pack).to_netcdf(out, engine="h5netcdf")


def registered_methods():
    from gyrolab.kernels.registry import METHODS

    return tuple(METHODS)


def dataset_scene(name):
    """The scene of dataset ``name``."""
    return name[len("scene_") :] if name.startswith("scene_") else pinned_scene(name)


def dataset_methods(name):
    """The registered methods dataset ``name`` is stored for: every one, except on a scene that
    drives its body (a torque that depends on time), where only the methods that see time run."""
    from gyrolab.kernels.body import is_driven
    from gyrolab.kernels.registry import METHODS, sees_time
    from gyrolab.kernels.scenes import build_scene

    driven = is_driven([build_scene(dataset_scene(name), 1.0, 0.0).body])
    return tuple(m for m, module in METHODS.items() if not driven or sees_time(module))


def gyrolab_command():
    """The ``gyrolab`` console script of the running interpreter's environment, else the one on
    PATH, else ``python -m gyrolab.runner.app`` (the same command, from an uninstalled checkout)."""
    local = Path(sys.executable).parent / "gyrolab"
    found = str(local) if local.exists() else shutil.which("gyrolab")
    return [found] if found else [sys.executable, "-m", "gyrolab.runner.app"]


def config_overrides(name):
    """The overrides that select dataset ``name``'s config."""
    if name.startswith("scene_"):
        scene = name[len("scene_") :]
        return [f"scene={scene}", *SCENE_OVERRIDES, *SCENE_EXTRA.get(scene, ())]
    return [f"experiment=regression_{name}"]


def run_config(name, method, out, workdir, overrides=()):
    """Run ``gyrolab <dataset name's config> sweep.method=[<method>] [overrides]`` writing ``out`` (``method``
    may be a list: several methods in one run); Hydra's run dir inside ``workdir``.  Raises RuntimeError
    with gyrolab's stderr if the command fails."""
    methods = method if isinstance(method, (list, tuple)) else [method]
    tag = method if isinstance(method, str) else "all"
    cmd = [
        *gyrolab_command(),
        *config_overrides(name),
        f"sweep.method=[{','.join(methods)}]",
        f"output.path={Path(out).resolve()}",
        "output.overwrite=true",
        f"hydra.run.dir={Path(workdir).resolve() / f'run_{name}_{tag}'}",
        *overrides,
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=workdir)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {done.returncode}: {done.stderr.strip()[-2000:]}")
    return Path(out)


def lie_poisson4_with(w1):
    """A serial batch kernel of lie_poisson4 with the outer Yoshida weight ``w1``
    (middle 1 − 2 w1): a deliberate coefficient change for the sensitivity study
    and the regression test that must catch it."""
    from numba import njit

    from gyrolab.kernels.driver import make_advance
    from gyrolab.kernels.methods.lie_poisson import step as strang_step

    w0 = 1.0 - 2.0 * w1

    @njit
    def step_counted(w, q, dt, body):  # no solver: 0 iterations (kernels/entry.py, counted)
        w, q = strang_step(w, q, w1 * dt, body)
        w, q = strang_step(w, q, w0 * dt, body)
        w, q = strang_step(w, q, w1 * dt, body)
        return w, q, 0

    advance = make_advance(step_counted, False)

    @njit
    def run_batch(w0_, q0_, bodies, dts, strides, threshold, out, status, n_steps, iterations):
        for i in range(w0_.shape[0]):
            advance(i, w0_, q0_, bodies, dts, strides, threshold, out, status, n_steps, iterations)

    return run_batch


def _targets(words, methods):
    """(name, method) pairs of NAME / NAME:METHOD words (all pairs when none)."""
    if not words:
        return [(n, m) for n in DATASETS for m in methods if m in dataset_methods(n)]
    pairs = []
    for word in words:
        name, _, method = word.partition(":")
        if name not in DATASETS:
            raise SystemExit(
                f"regenerate.py: error: {name}: not a regression dataset; choose from {', '.join(DATASETS)}"
            )
        if method and method not in methods:
            raise SystemExit(
                f"regenerate.py: error: {method}: not a registered method; choose from {', '.join(methods)}"
            )
        if method and method not in dataset_methods(name):
            raise SystemExit(f"regenerate.py: error: {method}: does not run {name} (it does not see time)")
        pairs += [(name, m) for m in ([method] if method else dataset_methods(name))]
    return pairs


def _layout(ds):
    """The layout version a Dataset declares (gyrolab.results.migrate)."""
    from gyrolab.results.migrate import file_layout_version

    return file_layout_version(ds)


def _layout_of_file(path):
    import xarray as xr

    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return _layout(ds)


def _store(new, path):
    pack_results(new, path)
    print(f"WROTE {path.relative_to(DATA_DIR.parent.parent)} ({path.stat().st_size / 1024:.0f} kB)")


def compare_with_stored(fresh, path, names=("fresh run", None)):
    """gyrolab-compare's Report of the results file ``fresh`` (a path) against the pack ``path``,
    at the regression tolerance."""
    from gyrolab.analysis.files.compare import compare_datasets, open_results

    return compare_datasets(
        open_results(fresh, "A"), read_pack(path), scaled=SCALED_TOL, names=(names[0], names[1] or str(path))
    )


def main(argv=None):
    from gyrolab.analysis.files.compare import CompareError

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "targets",
        nargs="*",
        metavar="NAME[:METHOD]",
        help=f"datasets (default all: {', '.join(DATASETS)}), optionally one method of one",
    )
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--add", action="store_true", help="write only the files that are missing")
    what.add_argument("--write", action="store_true", help="replace the named stored files (default: only compare)")
    parser.add_argument(
        "--relayout",
        action="store_true",
        help="with --write: also replace a stored file of an older layout (test_layout's fixtures) in today's",
    )
    what.add_argument(
        "--export",
        metavar="OUT.h5",
        help="write the one stored NAME:METHOD as a results file OUT.h5 (for gyrolab-compare, gyrolab-plot)",
    )
    args = parser.parse_args(argv)
    if args.relayout and not args.write:
        parser.error("--relayout goes with --write")
    if args.export:
        words = args.targets
        if len(words) != 1 or ":" not in words[0]:
            parser.error("--export takes exactly one NAME:METHOD")
        (pair,) = _targets(words, registered_methods())
        if not stored_path(*pair).exists():
            parser.error(f"{words[0]}: no stored dataset; add it with: {ADD_COMMAND}")
        export_results(stored_path(*pair), args.export)
        print(f"WROTE {args.export} (stored {words[0]} as a results file)")
        return
    pairs = _targets(args.targets, registered_methods())
    if args.add:
        pairs = [(n, m) for n, m in pairs if not stored_path(n, m).exists()]
        if not pairs:
            print("every (regression config, method) has its stored file; nothing to add")
    refused = []
    with tempfile.TemporaryDirectory(prefix="gyrolab-regen-") as tmp:
        for name, method in pairs:
            new = run_config(name, method, Path(tmp) / f"{name}_{method}.h5", tmp)
            old = stored_path(name, method)
            print(f"=== {name} / {method}: {old.relative_to(DATA_DIR.parent.parent)}")
            if old.exists():
                try:
                    report = compare_with_stored(new, old)
                    print(f"A = fresh run, B = stored file, tolerance {SCALED_TOL:g} x each variable's largest |value|")
                    print(report.text())
                except CompareError as err:
                    print(f"fresh run cannot be compared with the stored file: {err}")
            else:
                print("no stored file yet")
            if args.write and old.exists() and not args.relayout:
                was, now = _layout(read_pack(old)), _layout_of_file(new)
                if was != now:  # the stored pack is also test_layout's fixture of its older layout
                    print(
                        f"NOT WRITTEN {old.relative_to(DATA_DIR.parent.parent)}: stored in layout {was}, a fresh run "
                        f"writes layout {now}; tests/test_layout.py opens the stored packs of older layouts to "
                        "check the migration.  Pass --relayout to rewrite it in today's layout anyway."
                    )
                    refused.append(f"{name}:{method}")
                    continue
            if args.write or args.add:
                _store(new, old)
    total = sum(p.stat().st_size for p in STORE.rglob(f"*{PACK_SUFFIX}"))
    print(
        f"stored datasets: {total / 1024:.0f} kB in all"
        + ("" if args.write or args.add else " (nothing written: add --add or --write)")
    )
    if refused:
        raise SystemExit(f"regenerate.py: {len(refused)} stored file(s) kept in their layout: {' '.join(refused)}")


if __name__ == "__main__":
    main()
