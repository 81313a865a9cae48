"""Long runs in blocks: a chunk cut in time, journaled segment by segment, resumed bit for bit.

The block kernels (kernels/block.py) integrate a chunk of MIN_BLOCK_RUNS runs or more several times
faster per step than one run after another, but a chunk is the journal's unit: while it runs nothing
of it is saved.  A chunk of long runs (a 1000 s run at dt = 1e-4 s is 1e7 steps) sized to
``chunk_seconds`` of work would hold a handful of runs and leave the block path.  So such a chunk
keeps its MIN_BLOCK_RUNS runs and is integrated a slice of its samples at a time ("segments" of
about ``chunk_seconds`` each): after each segment its samples so far and each run's state (ω, q)
go to the journal (``Journal.write_segment``), and the next segment starts the block kernel from
that state.  A step depends on (ω, q, dt, body) alone, so the samples are the bits one long call
gives.

Only the divergence test needs care: the kernel compares |E − E0| with the run's bound, where E0 is
the energy of the call's first sample.  A continuing segment is run with the largest bound a double
holds (it still stops at a non-finite state) and its samples are then tested here against the
run's own E0 and bound (``kernels.driver.tolerances``: the bits the kernel computes), with the
kernel's consequences: the status, NaN after the failing sample, the steps counted to it.
"""

import time

import numpy as np

from ..kernels.batch import integrate
from ..kernels.driver import ENERGY, STATUS_ENERGY, STATUS_NONFINITE, STATUS_OK, tolerances
from ..kernels.real import is_real
from ..results.layout import solver_variables
from ..results.migrate import NOT_COUNTED
from .grid import JOURNAL_RATE, runs_in_blocks

# The bound a continuing segment runs with: no finite energy error passes it.
NO_BOUND = float(np.finfo(np.float64).max)
# A segment is long enough that rewriting the samples so far (the segment file) costs at most
# 1/WRITE_SHARE of its integration.
WRITE_SHARE = 4


def segmentable(grid, runs):
    """Whether the chunk ``runs`` can be cut in time: its method's block kernel runs it (an own
    method with blocks, MIN_BLOCK_RUNS runs or more, an undriven body) and it has two sample
    intervals or more."""
    method = grid.methods[int(grid.index(runs[:1])[0][0])]
    return not is_real(method) and runs_in_blocks(method, len(runs), grid.driven) and grid.n_samples > 2


def cut_in_time(grid, runs, estimate_seconds, chunk_seconds):
    """Whether the chunk ``runs``, estimated at ``estimate_seconds`` of integration, is run in segments:
    it would take more than two ``chunk_seconds`` and can be cut (``segmentable``)."""
    return estimate_seconds > 2 * chunk_seconds and segmentable(grid, runs)


def segment_writing_seconds(grid, runs, estimate_seconds, chunk_seconds):
    """Estimated wall time (s) of the segment files of the chunk ``runs`` cut in time: after each segment
    but the last (whose samples go to the chunk file, grid.estimate_writing_seconds), its samples so far,
    at JOURNAL_RATE; the segments as ``segment_length`` makes them.  0 for a chunk not cut in time."""
    if not cut_in_time(grid, runs, estimate_seconds, chunk_seconds):
        return 0.0
    seconds, done, last = 0.0, 0, grid.n_samples - 1
    while True:
        done += segment_length(grid, runs, estimate_seconds, chunk_seconds, done)
        if done >= last:
            return seconds
        seconds += _samples_so_far_seconds(grid, runs, done)


def _samples_so_far_seconds(grid, runs, done):
    """Estimated seconds of journaling the samples 0..``done`` of the chunk ``runs`` (a segment file)."""
    return len(runs) * (done + 1) * grid.bytes_per_run() / grid.n_samples / JOURNAL_RATE


def segment_length(grid, runs, estimate_seconds, chunk_seconds, done):
    """Sample intervals of the next segment of the chunk ``runs`` whose whole integration is estimated
    at ``estimate_seconds``, with samples 0..``done`` integrated: about ``chunk_seconds`` of work, and
    no less than WRITE_SHARE times the time of writing the samples so far, at least 1."""
    left = grid.n_samples - 1 - done
    per_interval = estimate_seconds / max(grid.n_samples - 1, 1)
    seconds = max(chunk_seconds, WRITE_SHARE * _samples_so_far_seconds(grid, runs, done))
    return max(1, min(left, int(seconds / max(per_interval, 1e-12))))


def integrate_segment(method, inputs, state, n_intervals, threshold, bound, e0, threads):
    """Integrate ``n_intervals`` sample intervals of runs with kernel ``inputs`` (Grid.inputs), from
    the start (``state`` None) or on from ``state`` (n, 7) (ω, q) with each run's E0 ``e0`` (J) and
    divergence ``bound`` (J).  Returns the journal's arrays for these samples: samples
    (n, n_intervals + 1, ·) (the first row is the starting sample), status, n_steps, wall_time
    (s, as execute.integrate_chunk shares it), the solver counts of these steps (0 on the block path,
    whose methods have no iterative solver), state."""
    bodies, omega0, q0, dt, stride = inputs
    if state is not None:
        omega0, q0 = np.ascontiguousarray(state[:, :3]), np.ascontiguousarray(state[:, 3:])
    iterations = np.zeros((len(bodies), 2), dtype=np.int64)
    start = time.perf_counter()
    limit = threshold if state is None else NO_BOUND
    samples, status, n_steps, final = integrate(
        method,
        bodies,
        omega0,
        q0,
        dt,
        stride,
        n_intervals + 1,
        limit,
        path="blocks",
        final_state=True,
        iterations=iterations,
    )
    wall = time.perf_counter() - start
    if state is not None:
        status, n_steps = _diverged(samples, status, n_steps, stride, e0, bound)
    share = n_steps / max(int(n_steps.sum()), 1)
    return {
        "samples": samples,
        "status": status,
        "n_steps": n_steps,
        "wall_time": wall * min(threads, len(bodies)) * share,
        **solver_variables(iterations),
        "state": final,
    }


def _more_iterations(so_far, part):
    """The solver counts (solver_iterations, solver_iterations_max) of runs that did ``so_far`` and
    then ``part``: totals added, the most in one step the larger; not counted (-1) in either stays so."""
    uncounted = (so_far["solver_iterations"] == NOT_COUNTED) | (part["solver_iterations"] == NOT_COUNTED)
    total = np.where(uncounted, NOT_COUNTED, so_far["solver_iterations"] + part["solver_iterations"])
    most = np.maximum(so_far["solver_iterations_max"], part["solver_iterations_max"])
    return {"solver_iterations": total, "solver_iterations_max": np.where(uncounted, NOT_COUNTED, most)}


def _diverged(samples, status, n_steps, stride, e0, bound):
    """The kernel's divergence test (driver._diverged) on samples 1.. of a continuing segment against
    each run's own E0 and bound: at the first sample that fails, status energy (non-finite if a field
    is), NaN after it, steps counted up to it.  Returns (status, n_steps)."""
    status = np.full_like(status, STATUS_OK)
    failed = ~(np.abs(samples[:, 1:, ENERGY] - e0[:, None]) <= bound[:, None])  # True for NaN too
    for i in np.flatnonzero(failed.any(axis=1)):
        k = int(np.argmax(failed[i])) + 1
        status[i] = STATUS_ENERGY if np.isfinite(samples[i, k]).all() else STATUS_NONFINITE
        samples[i, k + 1 :] = np.nan
        n_steps[i] = k * stride[i]
    return status, n_steps


class SegmentedChunk:
    """One chunk integrated in segments: ``next(journal, n, run)`` integrates and journals one more
    segment with ``run(*task)`` (``integrate_segment`` here, in the chunk worker or on a Dask worker:
    ``task`` then ``absorb`` apart), ``finished`` when every sample is in; ``chunk()`` the whole
    chunk for ``Journal.write_chunk``.  ``arrays``: a segment file's, to go on from, or None."""

    def __init__(self, grid, number, runs, arrays=None):
        self.grid, self.number = grid, number
        self.method = grid.methods[int(grid.index(runs[:1])[0][0])]
        self.runs = np.asarray(runs, dtype=np.int64)
        self.inputs = grid.inputs(self.runs)
        self.bound = tolerances(self.inputs[1], self.inputs[0], float(grid.threshold))
        self.arrays = arrays
        self.pending, self.going = 0, None  # the last task's sample intervals and runs

    @property
    def done(self):
        """Sample intervals integrated so far."""
        return 0 if self.arrays is None else self.arrays["samples"].shape[1] - 1

    @property
    def finished(self):
        return self.done == self.grid.n_samples - 1

    def steps_done(self):
        """Steps planned for the sample intervals integrated so far (for the progress bar)."""
        return int(self.inputs[4].sum()) * self.done

    def task(self, n_intervals):
        """``integrate_segment``'s arguments (all but ``threads``) for the next ``n_intervals`` sample
        intervals of the runs still going, or None when none is (``absorb(None)`` then fills in NaN)."""
        self.pending = n_intervals = min(n_intervals, self.grid.n_samples - 1 - self.done)
        if self.arrays is None:
            return self.method, self.inputs, None, n_intervals, self.grid.threshold, self.bound, None
        self.going = going = np.flatnonzero(self.arrays["status"] == STATUS_OK)
        if not going.size:
            return None
        inputs = tuple(x[going] for x in self.inputs)
        e0 = self.arrays["samples"][going, 0, ENERGY]
        return self.method, inputs, self.arrays["state"][going], n_intervals, None, self.bound[going], e0

    def absorb(self, journal, part):
        """Add ``part`` (``integrate_segment``'s result for the last ``task``) to the samples so far
        and journal them (not after the last segment: the chunk file, written next, holds them; a sweep
        killed between the two goes on from the segment before); returns the steps planned for the
        segment (for the progress bar)."""
        n_intervals = self.pending
        if self.arrays is None:
            self.arrays = {"runs": self.runs, **part}
        else:
            a, going = self.arrays, self.going
            samples = np.full((len(self.runs), n_intervals, a["samples"].shape[2]), np.nan)
            status, n_steps, wall = a["status"].copy(), a["n_steps"].copy(), a["wall_time"].copy()
            counts = {k: a[k].copy() for k in ("solver_iterations", "solver_iterations_max")}
            state = a["state"].copy()
            if part is not None:
                samples[going] = part["samples"][:, 1:]
                status[going] = part["status"]
                n_steps[going] += part["n_steps"]
                wall[going] += part["wall_time"]
                for k, v in _more_iterations({k: v[going] for k, v in counts.items()}, part).items():
                    counts[k][going] = v
                state[going] = part["state"]
            self.arrays = {
                "runs": self.runs,
                "samples": np.concatenate([a["samples"], samples], axis=1),
                "status": status,
                "n_steps": n_steps,
                "wall_time": wall,
                **counts,
                "state": state,
            }
        if not self.finished:
            journal.write_segment(self.number, **self.arrays)
        return int(self.inputs[4].sum()) * n_intervals

    def next(self, journal, n_intervals, run):
        """Integrate the next ``n_intervals`` sample intervals of the runs still going with
        ``run(*task)`` and journal the samples so far; returns the steps planned for them."""
        task = self.task(n_intervals)
        return self.absorb(journal, None if task is None else run(*task))

    def chunk(self):
        """The finished chunk's arrays for Journal.write_chunk."""
        return {k: v for k, v in self.arrays.items() if k != "state"}
