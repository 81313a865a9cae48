"""Re-run the regression configs and, only with --write, replace the stored datasets.

    python tests/data/regenerate.py                  # re-run all, show how they differ from the stored files
    python tests/data/regenerate.py --write          # ... and replace the stored files
    python tests/data/regenerate.py --write free_symmetric heavy_top_steady   # only these

Each dataset ``tests/data/regression_<name>.h5`` is the output of the real
command ``gyrolab experiment=regression_<name>`` (config in
``conf/experiment/regression_<name>.yaml``).  Without --write nothing is
written: the script prints the comparison of each fresh run with the stored
file, so a regeneration is always a decision someone made after reading it.
The regression tests (tests/test_regression.py) import ``run_config``,
``DATASETS`` and ``SCALED_TOL`` from here.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

DATA_DIR = Path(__file__).resolve().parent
DATASETS = ("heavy_top_release", "heavy_top_steady", "free_symmetric", "free_asymmetric")

# Regression tolerance (see tests/data/README.md): a value passes when
# |new − stored| <= SCALED_TOL × (largest |value| of that variable in the stored file);
# status and n_steps must match exactly, wall_time is not compared.
SCALED_TOL = 1e-10


def stored_path(name):
    """The stored dataset of regression config ``name``."""
    return DATA_DIR / f"regression_{name}.h5"


def gyrolab_command():
    """The ``gyrolab`` console script of the running interpreter's environment (else the one on PATH)."""
    local = Path(sys.executable).parent / "gyrolab"
    found = str(local) if local.exists() else shutil.which("gyrolab")
    if found is None:
        raise RuntimeError("the gyrolab command is not installed (pip install -e .)")
    return found


def run_config(name, out, workdir, overrides=()):
    """Run ``gyrolab experiment=regression_<name> [overrides]`` writing ``out``; Hydra's run dir
    inside ``workdir``.  Raises RuntimeError with gyrolab's stderr if the command fails."""
    cmd = [gyrolab_command(), f"experiment=regression_{name}", f"output.path={Path(out).resolve()}",
           "output.overwrite=true", f"hydra.run.dir={Path(workdir).resolve() / ('run_' + name)}", *overrides]
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
    from gyrolab.kernels.lie_poisson import step as strang_step

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


def main(argv=None):
    from gyrolab.analysis.compare import CompareError, compare_files

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help=f"datasets to regenerate (default all: {', '.join(DATASETS)})")
    parser.add_argument("--write", action="store_true", help="replace the stored files (default: only compare)")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in DATASETS]
    if unknown:
        parser.error(f"{unknown[0]}: not a regression dataset; choose from {', '.join(DATASETS)}")
    with tempfile.TemporaryDirectory(prefix="gyrolab-regen-") as tmp:
        for name in args.names or DATASETS:
            new = run_config(name, Path(tmp) / f"regression_{name}.h5", tmp)
            old = stored_path(name)
            print(f"=== {name}: {old.relative_to(DATA_DIR.parent.parent)}")
            if old.exists():
                try:
                    report = compare_files(new, old, scaled=SCALED_TOL)
                    print(f"A = fresh run, B = stored file, tolerance {SCALED_TOL:g} x each variable's largest |value|")
                    print(report.text())
                except CompareError as err:
                    print(f"fresh run cannot be compared with the stored file: {err}")
            else:
                print("no stored file yet")
            if args.write:
                part = old.with_name(f".{old.name}.tmp")
                shutil.copyfile(new, part)
                os.replace(part, old)
                print(f"WROTE {old} ({old.stat().st_size / 1024:.0f} kB)")
    total = sum(stored_path(n).stat().st_size for n in DATASETS if stored_path(n).exists())
    print(f"stored datasets: {total / 1024:.0f} kB in all" + ("" if args.write else " (nothing written: add --write)"))


if __name__ == "__main__":
    main()
