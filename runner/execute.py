"""Run a grid's missing runs chunk by chunk on this machine, journaling each chunk.

The runs of a chunk go to the batch kernel in one call (parallel over runs);
each run's result does not depend on which chunk it is in nor on the thread
count, so a resumed sweep ends up with the same data as an uninterrupted one.

A numba kernel holds the interpreter until it returns, so a signal (Ctrl-C,
SIGTERM) is only seen between chunks.  Chunks are sized to ``chunk_seconds``,
but a single run cannot be split: a chunk estimated to take longer than
ISOLATE_SECONDS (a long run) is integrated in a worker process
(``ChunkWorker``, spawned once per sweep) while this process waits in slices
of POLL_SECONDS, so an interrupt is answered at once: the worker is killed and
the journal keeps every chunk stored before.  Same kernels, same inputs: the
worker's results are the same bits.

A chunk of long runs keeps MIN_BLOCK_RUNS runs on the block path (grid.plan_chunks) and is cut in
time instead (runner/segments.py): segments of about ``chunk_seconds``, each journaled with the
runs' state, so that a crash loses one segment and a resume goes on from the last one.
"""

import contextlib
import math
import multiprocessing
import os
import signal
import time

import numpy as np

from ..kernels.batch import MIN_BLOCK_RUNS, integrate
from ..kernels.real import is_real
from ..results.layout import solver_variables
from .compile import compile_jobs, compile_kernels, compile_seconds, die_with_parent, kernel_cached
from .grid import plan_chunks, runs_in_blocks, step_rate
from .segments import SegmentedChunk, cut_in_time, integrate_segment, segment_length, segment_writing_seconds

# Test hook: seconds to sleep after each stored chunk, so a test can kill a sweep mid-way.
DELAY_ENV = "GYROLAB_TEST_CHUNK_DELAY"
# Test hook: override ISOLATE_SECONDS (e.g. 0: every chunk in the worker process).
ISOLATE_ENV = "GYROLAB_TEST_ISOLATE_SECONDS"
ISOLATE_SECONDS = 2.0  # chunks estimated longer than this run in the worker (spawning it costs ~1.5 s)
POLL_SECONDS = 0.1


class BackendError(RuntimeError):
    """A backend failed mid-sweep (e.g. a Dask cluster gave up on a chunk); the journal keeps
    the chunks finished so far, so the sweep can be resumed."""


def chunk_delay():
    """Seconds of the GYROLAB_TEST_CHUNK_DELAY test hook (0 when unset)."""
    return float(os.environ.get(DELAY_ENV, "0") or 0)


def warm_up(grid):
    """Compile (or load from numba's cache) each method's kernels with the runner's argument
    types, so that JIT time is not charged to the first chunk's wall_time.  The block
    kernel (slow to compile cold) only when some chunk can have MIN_BLOCK_RUNS runs.

    Two or more cold kernels compile first in parallel worker processes, one per core and a fresh
    one per method (runner/compile.py ``compile_kernels``): numba compiles on one thread, and in this
    process every compiler's memory would stay (the verdict study's 61 cold kernels took it to 3.85 GB).
    The warm-up below then loads them from the cache."""
    blocks = grid.n_runs // len(grid.methods) >= MIN_BLOCK_RUNS
    cold = [kernel for kernel in warm_up_paths(grid) if not kernel_cached(*kernel)]
    if len(cold) >= 2 and compile_jobs() > 1 and not multiprocessing.current_process().daemon:
        compile_kernels(cold, compile_jobs(), report=lambda line: print(line, flush=True))
    warm_up_methods(grid.methods, grid.inputs(np.zeros(1, dtype=np.int64)), grid.threshold, blocks)


COMPILE_NOTICE_SECONDS = 3.0  # a warm-up still running after this long is compiling: say so on screen
# Resident memory one kernel compiled in the sweep's process adds and keeps (numba holds every compiled
# module), measured with benchmarks/peak_rss.py on a fresh NUMBA_CACHE_DIR against the warm run's 0.28 GB:
# the default study (5 run kernels) 0.56 GB; rk4 + lie_poisson4 with blocks (2 run, 2 block kernels)
# 0.72 GB; the verdict study's multirun (23 driven + 38 run kernels in one process) 3.85 GB.
COMPILE_BYTES = {"runs": 60e6, "driven": 60e6, "blocks": 160e6}


def warm_up_paths(grid):
    """[(method, path)] of the kernels ``warm_up`` compiles or loads for ``grid``: 'runs' ('driven' for a
    driven body), and 'blocks' for a method that has them when some chunk can reach MIN_BLOCK_RUNS."""
    from ..kernels.registry import get_method, uses_blocks

    blocks = grid.n_runs // len(grid.methods) >= MIN_BLOCK_RUNS and not grid.driven
    out = []
    for method in grid.methods:
        if is_real(method):  # the engine package itself (kernels/real/): numba compiles nothing for it
            continue
        out.append((method, "driven" if grid.driven else "runs"))
        if blocks and uses_blocks(get_method(method)):
            out.append((method, "blocks"))
    return out


# (method, path) kernels a dry run in this process has already counted as compiling.  The jobs of a
# multirun run one after the other in one process, so the first job that needs a cold kernel compiles
# it and the later ones load it: a multirun's dry run counts each cold kernel once over its jobs.
_COUNTED = set()


def compile_memory(cold):
    """(bytes, where) the compiling of ``cold`` ([(method, path)], this job's cold kernels) adds: in
    compile_jobs() worker processes for two or more (each a fresh interpreter, ~0.3 GB, plus one
    method's kernels), else in this process, which keeps them."""
    if not cold:
        return 0.0, ""
    per_method = {}
    for method, path in cold:
        per_method[method] = per_method.get(method, 0.0) + COMPILE_BYTES[path]
    jobs = min(compile_jobs(), len(per_method))
    if len(cold) < 2 or compile_jobs() < 2:
        return sum(per_method.values()), "in this process"
    return jobs * (0.3e9 + max(per_method.values())), f"in {jobs} compile processes, one method each"


def compile_estimate(grid):
    """(seconds, [(method, path)] cold, [(method, path)] counted before): the wall seconds of compiling
    the kernels of ``grid`` that numba's cache does not hold (``compile_seconds`` each, shared out over the
    cores as ``warm_up`` compiles them: ``compile_wall_seconds``) and that no earlier
    dry run of this process (an earlier job of the same multirun) has counted; which they are; and the
    cold ones an earlier job compiles first."""
    cold = [(m, p) for m, p in warm_up_paths(grid) if not kernel_cached(m, p)]
    before = [kernel for kernel in cold if kernel in _COUNTED]
    cold = [kernel for kernel in cold if kernel not in _COUNTED]
    _COUNTED.update(cold)
    return compile_wall_seconds([compile_seconds(m, p) for m, p in cold]), cold, before


def compile_wall_seconds(seconds):
    """Wall time of compiling kernels that take ``seconds`` each as ``warm_up`` does: one after another
    for fewer than two, else on compile_jobs() worker processes, longest first (at least the longest
    one, at least the total shared out; + ~1.5 s per process to start an interpreter and import)."""
    jobs = compile_jobs()
    if len(seconds) < 2 or jobs < 2:
        return sum(seconds)
    return max(max(seconds), sum(seconds) / jobs) + 1.5 * math.ceil(len(seconds) / jobs)


def warm_up_methods(methods, inputs, threshold, blocks=False):
    """``warm_up`` without a grid: ``inputs`` are one run's kernel inputs (``Grid.inputs``).  A kernel
    that takes more than COMPILE_NOTICE_SECONDS (numba compiling it: its cache is cold) is named on
    stdout while it compiles ("compiling block kernels of lie_poisson4 (3/5) ...") and when done; one
    that numba's cache holds is said to be loading (a large kernel can take seconds to load on a busy
    machine), so the screen never claims a compile that is not happening."""
    bodies, omega0, q0, dt, _ = inputs
    jobs = [(m, path) for m in methods for path in (("runs", "blocks") if blocks else ("runs",))]
    for k, (method, path) in enumerate(jobs, 1):
        what = f"{'block' if path == 'blocks' else 'run'} kernels of {method} ({k}/{len(jobs)})"
        verbs = ("compiling", "compiled")
        if is_real(method):  # importing the engine package, compiling the samplers gyrolab calls on its state
            what = f"the engine package and samplers of {method} ({k}/{len(jobs)})"
        elif kernel_cached(method, path):
            verbs = ("loading", "loaded")
            what += " from the numba cache"
        with _compile_notice(what, verbs=verbs):
            integrate(method, bodies, omega0, q0, dt, np.ones(1, dtype=np.int64), 2, threshold, path=path)


@contextlib.contextmanager
def _compile_notice(what, after=None, verbs=("compiling", "compiled")):
    """Print 'gyrolab: compiling WHAT ...' if the block takes longer than ``after`` s (default
    COMPILE_NOTICE_SECONDS), then how long it took ('compiled WHAT in N s'); nothing for a block that is
    quick (a warm cache).  ``verbs``: the words for the two lines."""
    import threading

    start = time.perf_counter()
    said = threading.Event()

    def say():
        said.set()
        print(f"gyrolab: {verbs[0]} {what} ...", flush=True)

    timer = threading.Timer(COMPILE_NOTICE_SECONDS if after is None else after, say)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
        if said.is_set():
            print(f"gyrolab: {verbs[1]} {what} in {time.perf_counter() - start:.0f} s", flush=True)


def run_chunk(grid, runs, threads):
    """Integrate one chunk of ``grid`` on this process; returns the dict stored in the journal."""
    method = grid.methods[int(grid.index(runs[:1])[0][0])]
    return integrate_chunk(method, runs, grid.inputs(runs), grid.n_samples, grid.threshold, threads)


def integrate_chunk(method, runs, inputs, n_samples, threshold, threads):
    """Integrate the runs (flat numbers) of one chunk from their kernel inputs (``Grid.inputs``);
    returns the dict stored in the journal.

    wall_time (s) per run: the chunk's wall time × the threads it used, shared
    in proportion to the steps each run took.  solver_iterations and solver_iterations_max per
    run: as the kernel counts them (gyrolab/results/layout.py RUN_VARIABLES).
    """
    bodies, omega0, q0, dt, stride = inputs
    iterations = np.zeros((len(runs), 2), dtype=np.int64)
    start = time.perf_counter()
    samples, status, n_steps = integrate(
        method, bodies, omega0, q0, dt, stride, n_samples, threshold, iterations=iterations
    )
    wall = time.perf_counter() - start
    share = n_steps / max(int(n_steps.sum()), 1)
    wall_time = wall * min(threads, len(runs)) * share
    return {
        "runs": np.asarray(runs, dtype=np.int64),
        "samples": samples,
        "status": status,
        "n_steps": n_steps,
        "wall_time": wall_time,
        **solver_variables(iterations),
    }


def isolate_seconds():
    return float(os.environ.get(ISOLATE_ENV, "") or ISOLATE_SECONDS)


def rate_key(grid, runs):
    """(method, block path?) of the chunk ``runs``: measured speeds are kept per path, since the block
    path runs several times faster per step than one by one (grid.BLOCK_SPEEDUP)."""
    method = grid.methods[int(grid.index(runs[:1])[0][0])]
    return method, runs_in_blocks(method, len(runs), grid.driven)


def chunk_estimate(grid, runs, threads, rates):
    """Estimated seconds of integrating the chunk ``runs`` here: its runs' steps, each at its own dt,
    shared among the threads and never less than its longest run (as grid.estimate_seconds), at the
    speed measured for its method on its path (``rates``: {rate_key: steps/s per thread}), else at
    grid.step_rate (the block path's speed-up included)."""
    method, blocks = rate_key(grid, runs)
    rate = rates.get((method, blocks)) or step_rate(method, len(runs), grid.driven)
    steps = grid.steps(runs)
    return max(float(steps.sum()) / min(max(threads, 1), len(runs)), float(steps.max())) / rate


def segment_files_seconds(grid, chunks, threads, chunk_seconds):
    """Estimated wall time (s) of writing the segment files of the ``chunks`` (run indices) that a run
    on ``threads`` threads cuts in time (runner/segments.py), at the planner's speeds."""
    return sum(
        segment_writing_seconds(grid, runs, chunk_estimate(grid, runs, threads, {}), chunk_seconds) for runs in chunks
    )


class ChunkWorker:
    """A spawned process that integrates chunks of one grid; ``run(runs)`` waits for a result
    in slices of POLL_SECONDS, so signals reach this process while the worker computes.
    Any exception (KeyboardInterrupt included) while waiting kills the worker."""

    def __init__(self, grid, threads):
        self.grid, self.threads = grid, threads
        self.process = self.conn = None

    def start(self):
        ctx = multiprocessing.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker_main, args=(child, self.grid, self.threads), daemon=True)
        self.process.start()
        child.close()

    def run(self, runs):
        return self._ask(np.asarray(runs, dtype=np.int64))

    def run_segment(self, *args):
        """segments.integrate_segment(*args, threads) in the worker."""
        return self._ask(("segment", args))

    def _ask(self, task):
        if self.process is None:
            self.start()
        try:
            self.conn.send(task)
            while not self.conn.poll(POLL_SECONDS):
                if not self.process.is_alive():
                    raise RuntimeError(f"the chunk worker (pid {self.process.pid}) died (exit {self.process.exitcode})")
            return self.conn.recv()
        except BaseException:
            self.kill()
            raise

    def kill(self):
        if self.process is not None:
            if self.process.is_alive():
                self.process.kill()
            self.process.join(5)
            self.conn.close()
            self.process = self.conn = None

    def close(self):
        if self.process is not None:
            try:
                self.conn.send(None)
                self.process.join(5)
            except OSError:
                pass
            self.kill()


def _worker_main(conn, grid, threads):
    """The worker process: signals are the parent's business (it kills us); compile first, so
    that JIT time stays out of wall_time, then integrate each chunk sent until None."""
    for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    die_with_parent()
    import numba

    numba.set_num_threads(threads)
    warm_up(grid)
    while True:
        task = conn.recv()
        if task is None:
            return
        if isinstance(task, tuple):  # ("segment", integrate_segment's arguments)
            conn.send(integrate_segment(*task[1], threads))
        else:
            conn.send(run_chunk(grid, task, threads))


def run_missing(grid, journal, todo, threads, chunk_seconds, first_number, progress=None):
    """Run the runs in ``todo`` (flat numbers) in chunks, storing each in ``journal``.

    Chunks are re-planned after each one with the measured speed of its method,
    so each takes about ``chunk_seconds``; chunks that would take longer than
    ISOLATE_SECONDS (single long runs) go to a ``ChunkWorker``.
    ``progress(runs, steps)`` is called after each stored chunk.
    """
    worker = ChunkWorker(grid, threads)
    try:
        _run_missing(grid, journal, todo, threads, chunk_seconds, first_number, progress, worker)
    finally:
        worker.close()


def _run_missing(grid, journal, todo, threads, chunk_seconds, first_number, progress, worker):
    delay = chunk_delay()
    limit = isolate_seconds()
    rates = {}  # measured steps/s per thread by method, for planning (plan_chunks)
    path_rates = {}  # the same by (method, block path?), for chunk_estimate
    number = first_number
    remaining = np.sort(np.asarray(todo, dtype=np.int64))
    resumed, rejected = journal.open_segments(remaining, grid.n_runs, grid.n_samples)
    journal.report_set_aside(rejected)
    while remaining.size:
        if resumed:  # a chunk a killed sweep left part-way in time: go on from its last segment
            chunk_number, arrays = resumed.pop(0)
            runs = arrays["runs"]
            chunk = SegmentedChunk(grid, chunk_number, runs, arrays)
            if progress is not None:
                progress(0, chunk.steps_done())
        else:
            runs, chunk_number, chunk = plan_chunks(grid, remaining, threads, chunk_seconds, rates)[0], number, None
            number += 1
        estimate = chunk_estimate(grid, runs, threads, path_rates)
        if chunk is None and cut_in_time(grid, runs, estimate, chunk_seconds):
            chunk = SegmentedChunk(grid, chunk_number, runs)
        if chunk is not None:
            result = _run_segments(chunk, journal, estimate, chunk_seconds, limit, threads, worker, progress, delay)
        elif estimate > limit:
            result = worker.run(runs)
        else:
            result = run_chunk(grid, runs, threads)
        steps = int(result["n_steps"].sum())
        wall = float(result["wall_time"].sum()) / min(threads, len(runs))
        if wall > 0 and steps == int(grid.steps(runs).sum()):  # diverged runs stop early: no speed sample
            key = rate_key(grid, runs)
            rates[key[0]] = path_rates[key] = steps / wall / min(threads, len(runs))
        journal.write_chunk(chunk_number, **result)
        if chunk is not None:
            journal.remove_segment(chunk_number)
        remaining = np.setdiff1d(remaining, runs, assume_unique=True)
        if progress is not None:
            progress(len(runs), 0 if chunk is not None else int(grid.steps(runs).sum()))
        if delay:
            time.sleep(delay)


def _run_segments(chunk, journal, estimate, chunk_seconds, limit, threads, worker, progress, delay):
    """Integrate ``chunk`` (segments.SegmentedChunk) segment by segment, each journaled, in the chunk
    worker when a segment is estimated longer than ``limit`` s; returns the whole chunk's arrays."""
    grid = chunk.grid
    while not chunk.finished:
        n = segment_length(grid, chunk.runs, estimate, chunk_seconds, chunk.done)
        here = estimate * n / (grid.n_samples - 1) <= limit

        def run(*args):
            return integrate_segment(*args, threads) if here else worker.run_segment(*args)

        steps = chunk.next(journal, n, run)
        if progress is not None:
            progress(0, steps)
        if delay and not chunk.finished:
            time.sleep(delay)
    return chunk.chunk()
