"""Run a grid's missing runs chunk by chunk on this machine, journaling each chunk.

The runs of a chunk go to the batch kernel in one call (parallel over runs);
each run's result does not depend on which chunk it is in nor on the thread
count, so a resumed sweep ends up with the same data as an uninterrupted one.
"""
import os
import time

import numpy as np

from ..kernels.batch import MIN_BLOCK_RUNS, integrate
from .grid import plan_chunks

# Test hook: seconds to sleep after each stored chunk, so a test can kill a sweep mid-way.
DELAY_ENV = "GYROLAB_TEST_CHUNK_DELAY"


class BackendError(RuntimeError):
    """A backend failed mid-sweep (e.g. a Dask cluster gave up on a chunk); the journal keeps
    the chunks finished so far, so the sweep can be resumed."""


def chunk_delay():
    """Seconds of the GYROLAB_TEST_CHUNK_DELAY test hook (0 when unset)."""
    return float(os.environ.get(DELAY_ENV, "0") or 0)


def warm_up(grid):
    """Compile (or load from numba's cache) each method's kernels with the runner's argument
    types, so that JIT time is not charged to the first chunk's wall_time.  The block
    kernel (slow to compile cold) only when some chunk can have MIN_BLOCK_RUNS runs."""
    blocks = grid.n_runs // len(grid.methods) >= MIN_BLOCK_RUNS
    warm_up_methods(grid.methods, grid.inputs(np.zeros(1, dtype=np.int64)), grid.threshold, blocks)


def warm_up_methods(methods, inputs, threshold, blocks=False):
    """``warm_up`` without a grid: ``inputs`` are one run's kernel inputs (``Grid.inputs``)."""
    bodies, omega0, q0, dt, _ = inputs
    for method in methods:
        for path in ("runs", "blocks") if blocks else ("runs",):
            integrate(method, bodies, omega0, q0, dt, np.ones(1, dtype=np.int64), 2, threshold, path=path)


def run_chunk(grid, runs, threads):
    """Integrate one chunk of ``grid`` on this process; returns the dict stored in the journal."""
    method = grid.methods[int(grid.index(runs[:1])[0][0])]
    return integrate_chunk(method, runs, grid.inputs(runs), grid.n_samples, grid.threshold, threads)


def integrate_chunk(method, runs, inputs, n_samples, threshold, threads):
    """Integrate the runs (flat numbers) of one chunk from their kernel inputs (``Grid.inputs``);
    returns the dict stored in the journal.

    wall_time (s) per run: the chunk's wall time × the threads it used, shared
    in proportion to the steps each run took.
    """
    bodies, omega0, q0, dt, stride = inputs
    start = time.perf_counter()
    samples, status, n_steps = integrate(method, bodies, omega0, q0, dt, stride, n_samples, threshold)
    wall = time.perf_counter() - start
    share = n_steps / max(int(n_steps.sum()), 1)
    wall_time = wall * min(threads, len(runs)) * share
    return {"runs": np.asarray(runs, dtype=np.int64), "samples": samples, "status": status,
            "n_steps": n_steps, "wall_time": wall_time}


def run_missing(grid, journal, todo, threads, chunk_seconds, first_number, progress=None):
    """Run the runs in ``todo`` (flat numbers) in chunks, storing each in ``journal``.

    Chunks are re-planned after each one with the measured speed of its method,
    so each takes about ``chunk_seconds``.  ``progress(runs, steps)`` is called
    after each stored chunk.
    """
    delay = chunk_delay()
    rates = {}
    number = first_number
    remaining = np.sort(np.asarray(todo, dtype=np.int64))
    while remaining.size:
        runs = plan_chunks(grid, remaining, threads, chunk_seconds, rates)[0]
        result = run_chunk(grid, runs, threads)
        steps = int(result["n_steps"].sum())
        wall = float(result["wall_time"].sum()) / min(threads, len(runs))
        if wall > 0 and steps == int(grid.steps(runs).sum()):  # diverged runs stop early: no speed sample
            method = grid.methods[int(grid.index(runs[:1])[0][0])]
            rates[method] = steps / wall / min(threads, len(runs))
        journal.write_chunk(number, **result)
        number += 1
        remaining = np.setdiff1d(remaining, runs, assume_unique=True)
        if progress is not None:
            progress(len(runs), int(grid.steps(runs).sum()))
        if delay:
            time.sleep(delay)
