"""Long runs in blocks: the runner's per-step cost against t_end, with chunks cut in time or not.

    NUMBA_NUM_THREADS=1 python benchmarks/bench_long_runs.py [--t-end 10 100 1000] [--runs 256]

256 heavy-top runs of ``seed_next`` (16 spins, 1-50 Hz, x 16 tilts, 15-89 deg) at dt = 1e-4 s, one
sample a second, through the runner's own loop (``execute.run_missing``: planning, the chunk worker
for long chunks, the journal) into a scratch journal, on the threads numba has.  Two plans:

- ``in time``: this machine's runner now: a dt group of MIN_BLOCK_RUNS runs or more keeps
  MIN_BLOCK_RUNS runs per chunk on the block path, a chunk longer than ``chunk_seconds`` is cut in
  time and journaled segment by segment (runner/segments.py);
- ``whole chunks``: chunks of ``chunk_seconds`` of work with no cutting (``plan_chunks(in_time=False)``,
  the rule before): long runs go a few per chunk, one by one.

Prints ns per step (wall time of integrating and journaling over the steps) for each t_end and plan,
and their ratio to t_end = 10 s.  The kernels are warmed first (numba's cache), so compiling is out.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def grid_for(t_end, runs):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs
    from gyrolab.runner.grid import build_grid

    side = int(round(runs**0.5))
    f = ",".join(f"{x:.6g}" for x in np.linspace(1, 50, side))
    theta0 = ",".join(f"{x:.6g}" for x in np.linspace(15, 89, side))
    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose(
            "config",
            overrides=[
                "sweep.method=[seed_next]",
                f"sweep.f=[{f}]",
                f"sweep.theta0=[{theta0}]",
                "sweep.dt=[1e-4]",
                f"sweep.t_end={t_end}",
                "output.every=1",
            ],
        )
    return build_grid(cfg)


def measure(grid, in_time, threads, chunk_seconds=1.0):
    """(seconds, chunks) of ``execute.run_missing`` on ``grid`` into a scratch journal."""
    from gyrolab.runner import execute
    from gyrolab.runner import grid as grid_module
    from gyrolab.runner.store import Journal

    plan = grid_module.plan_chunks
    if not in_time:
        execute.plan_chunks = lambda *a, **k: plan(*a, **k, in_time=False)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            journal = Journal(Path(tmp) / "results.h5")
            journal.create({"config_hash": "bench", "n_runs": grid.n_runs, "n_samples": grid.n_samples})
            start = time.perf_counter()
            execute.run_missing(grid, journal, np.arange(grid.n_runs), threads, chunk_seconds, 0)
            seconds = time.perf_counter() - start
            return seconds, len(journal.chunk_files())
    finally:
        execute.plan_chunks = plan


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--t-end", type=float, nargs="+", default=[10.0, 100.0, 1000.0])
    parser.add_argument("--runs", type=int, default=256, help="runs (a square number: spins x tilts)")
    args = parser.parse_args(argv)

    import numba

    from gyrolab.runner.execute import warm_up

    threads = numba.get_num_threads()
    warm_up(grid_for(1.0, args.runs))
    print(f"seed_next, heavy top, {args.runs} runs, dt = 1e-4 s, {threads} thread(s); ns per step (chunks)")
    print("| t_end (s) | in time | whole chunks | ratio |")
    print("|---|---|---|---|")
    first = {}
    for t_end in args.t_end:
        grid = grid_for(t_end, args.runs)
        steps = int(grid.steps(np.arange(grid.n_runs)).sum())
        row = []
        for in_time in (True, False):
            seconds, chunks = measure(grid, in_time, threads)
            ns = seconds / steps * 1e9
            first.setdefault(in_time, ns)
            row.append(f"{ns:.2f} ({chunks}; {ns / first[in_time]:.2f}x t_end {args.t_end[0]:g})")
        print(f"| {t_end:g} | {row[0]} | {row[1]} | {float(row[1].split()[0]) / float(row[0].split()[0]):.1f} |")


if __name__ == "__main__":
    main()
