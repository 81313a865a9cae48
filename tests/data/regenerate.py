"""Stored regression data: one file per (regression config, method), added or replaced on purpose only.

    python tests/data/regenerate.py                 # re-run everything, show how it differs from the stored files
    python tests/data/regenerate.py --add           # write the files that are missing (a new method or config)
    python tests/data/regenerate.py --write heavy_top_release:rk4 free_symmetric   # replace these on purpose

Each file ``tests/data/regression/<name>/<method>.h5`` is the output of the
real command ``gyrolab experiment=regression_<name> sweep.method=[<method>]``
(config in ``conf/experiment/regression_<name>.yaml``).  A registered scene
that no pinned config uses gets a dataset ``scene_<scene>`` of its own: a
short run with SCENE_OVERRIDES, so a new scene is covered by ``--add`` too.  Adding a method or a
regression config is ``--add``: it writes only the files that do not exist,
so every other method's stored bytes stay as they are.  ``--write`` replaces
the named files (``NAME`` for all methods of a config, ``NAME:METHOD`` for
one) after printing the comparison of each fresh run with the stored file,
so a regeneration is always a decision someone made after reading it.
Without options nothing is written.  The regression tests
(tests/test_regression.py) import ``run_config``, ``DATASETS``, ``stored_path``
and ``SCALED_TOL`` from here.
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

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


def stored_path(name, method):
    """The stored dataset of regression config ``name`` for ``method``."""
    return STORE / name / f"{method}.h5"


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
    """The ``gyrolab`` console script of the running interpreter's environment (else the one on PATH)."""
    local = Path(sys.executable).parent / "gyrolab"
    found = str(local) if local.exists() else shutil.which("gyrolab")
    if found is None:
        raise RuntimeError("the gyrolab command is not installed (pip install -e .)")
    return found


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
        gyrolab_command(),
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
    def step(w, q, dt, body):
        w, q = strang_step(w, q, w1 * dt, body)
        w, q = strang_step(w, q, w0 * dt, body)
        return strang_step(w, q, w1 * dt, body)

    advance = make_advance(step)

    @njit
    def run_batch(w0_, q0_, bodies, dts, strides, threshold, out, status, n_steps):
        for i in range(w0_.shape[0]):
            advance(i, w0_, q0_, bodies, dts, strides, threshold, out, status, n_steps)

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


def _store(new, path):
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(f".{path.name}.tmp")
    shutil.copyfile(new, part)
    os.replace(part, path)
    print(f"WROTE {path.relative_to(DATA_DIR.parent.parent)} ({path.stat().st_size / 1024:.0f} kB)")


def main(argv=None):
    from gyrolab.analysis.files.compare import CompareError, compare_files

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
    args = parser.parse_args(argv)
    pairs = _targets(args.targets, registered_methods())
    if args.add:
        pairs = [(n, m) for n, m in pairs if not stored_path(n, m).exists()]
        if not pairs:
            print("every (regression config, method) has its stored file; nothing to add")
    with tempfile.TemporaryDirectory(prefix="gyrolab-regen-") as tmp:
        for name, method in pairs:
            new = run_config(name, method, Path(tmp) / f"{name}_{method}.h5", tmp)
            old = stored_path(name, method)
            print(f"=== {name} / {method}: {old.relative_to(DATA_DIR.parent.parent)}")
            if old.exists():
                try:
                    report = compare_files(new, old, scaled=SCALED_TOL)
                    print(f"A = fresh run, B = stored file, tolerance {SCALED_TOL:g} x each variable's largest |value|")
                    print(report.text())
                except CompareError as err:
                    print(f"fresh run cannot be compared with the stored file: {err}")
            else:
                print("no stored file yet")
            if args.write or args.add:
                _store(new, old)
    total = sum(p.stat().st_size for p in STORE.rglob("*.h5"))
    print(
        f"stored datasets: {total / 1024:.0f} kB in all"
        + ("" if args.write or args.add else " (nothing written: add --add or --write)")
    )


if __name__ == "__main__":
    main()
