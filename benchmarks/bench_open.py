"""Opening a results file: the reader through h5netcdf's own lookups against the reader keeping them.

    python benchmarks/bench_open.py [--repeat 9]

Every command and script opens results files through gyrolab/results/reader.py ``open_file``.  h5netcdf
looks each dimension of a variable up by path whenever the variable's shape is asked (h5netcdf/h5netcdf#195);
the reader hands it a read-only file that keeps what it looked up (``_LookupsKept``).  Here both ways open
the same files in the same process, alternated: ``xarray`` is ``open_file`` with ``xr.open_dataset(path,
engine="h5netcdf", phony_dims="access")`` in place of the reader's own opening (the reader before
2026-12-06), ``kept`` the reader as it is.  Each is timed eager (read whole, checked: ``open_results``) and
lazy (what the figure step does: per-run variables read, then closed).  Wall seconds, medians of
``--repeat``; the files are written first by the runner's grid, chunks and store (point NUMBA_CACHE_DIR at a
warm cache, or the first file compiles seed_next's run kernel).
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

# (label, overrides of BASE): a test's tiny file, the default study at 1 s and at 10 s, a 500-run grid
BASE = {"sweep.theta0": "[45]", "output.every": "1e-3"}
FILES = [
    (
        "tiny: 1 run, 21 samples",
        {"sweep.method": "[seed_next]", "sweep.f": "[10]", "sweep.dt": "[1e-3]", "sweep.t_end": "0.02"},
    ),
    ("default study, 1 s", {"sweep.t_end": "1"}),
    ("default study, 10 s", {}),
    (
        "500 runs, 1 s",
        {"sweep.f": "${linspace:1,100,25}", "sweep.theta0": "[30,60]", "sweep.dt": "[1e-3,1e-4]", "sweep.t_end": "1"},
    ),
]


def write_file(path, overrides):
    """The results file of BASE with ``overrides`` through the runner's grid, chunks and store."""
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import config_hash, register_configs
    from gyrolab.runner.execute import run_chunk
    from gyrolab.runner.grid import build_grid
    from gyrolab.runner.store import write_results
    from gyrolab.runner.sweep import file_attrs

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[f"{key}={value}" for key, value in (BASE | overrides).items()])
    grid = build_grid(cfg)
    chunk = run_chunk(grid, np.arange(grid.n_runs), 2)
    write_results(path, grid, [chunk], file_attrs(cfg, grid, 2, config_hash(cfg)))
    return grid.n_runs


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args(argv)

    import xarray as xr

    from gyrolab.results import reader

    kept = reader._open_dataset
    ways = {
        "xarray": lambda path: xr.open_dataset(path, engine="h5netcdf", phony_dims="access"),
        "kept": kept,
    }

    def opening(way, path, lazy):
        reader._open_dataset = ways[way]
        try:
            start = time.perf_counter()
            ds = reader.open_results(path, lazy=lazy)
            ds.close()
            return time.perf_counter() - start
        finally:
            reader._open_dataset = kept

    print("| file | runs | MB | eager: xarray | eager: kept | ratio | lazy: xarray | lazy: kept | ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for k, (label, overrides) in enumerate(FILES):
            path = Path(tmp) / f"file{k}.h5"
            n_runs = write_file(path, overrides)
            times = {(way, lazy): [] for way in ways for lazy in (False, True)}
            for way in ways:  # once each untimed: the page cache and the imports warm
                opening(way, path, False)
            for _ in range(args.repeat):
                for key in times:  # alternated, so that drift in the machine's load hits both ways alike
                    times[key].append(opening(key[0], path, key[1]))
            med = {key: statistics.median(t) for key, t in times.items()}
            row = [label, str(n_runs), f"{path.stat().st_size / 1e6:.1f}"]
            for lazy in (False, True):
                old, new = med[("xarray", lazy)], med[("kept", lazy)]
                row += [f"{old * 1e3:.0f} ms", f"{new * 1e3:.0f} ms", f"{old / new:.2f}x"]
            print("| " + " | ".join(row) + " |", flush=True)


if __name__ == "__main__":
    main()
