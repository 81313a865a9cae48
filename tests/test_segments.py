"""Long runs stay in blocks (runner/segments.py): a chunk of MIN_BLOCK_RUNS long runs is cut in time,
each segment journaled with the runs' state; the samples are the bits of one uninterrupted call,
divergences included, and a sweep killed mid-chunk resumes from its last segment to the same file."""

import signal

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

from gyrolab.kernels.batch import MIN_BLOCK_RUNS
from gyrolab.results.migrate import SOLVER_COUNTS
from gyrolab.runner import execute
from gyrolab.runner.config import register_configs
from gyrolab.runner.execute import run_chunk
from gyrolab.runner.grid import JOURNAL_RATE, build_grid, plan_chunks
from gyrolab.runner.segments import SegmentedChunk, integrate_segment, segmentable
from gyrolab.runner.store import Journal

from helpers import assert_ok, data, gyrolab, start, wait_for

register_configs()

# 64 runs of each dt: 8 spins up to 800 Hz (ω dt up to 100 rad at dt = 0.02 s: most of those diverge)
# times 8 tilts; 20 sample intervals.
LONG = (
    "sweep.f=[5,10,20,50,100,200,400,800]",
    "sweep.theta0=[15,30,45,60,75,85,89,90]",
    "sweep.dt=[1e-3,0.02]",
    "sweep.t_end=2",
    "output.every=0.1",
)


def grid_of(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=list(overrides)))


class Segments:
    """A stand-in journal that keeps every segment it is given."""

    def __init__(self):
        self.written = []

    def write_segment(self, number, **arrays):
        self.written.append(arrays["samples"].shape[1])


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk4", "lie_poisson4", "seed_next"])
def test_a_chunk_cut_in_time_gives_the_bits_of_one_call(method):
    grid = grid_of(f"sweep.method=[{method}]", *LONG)
    runs = np.arange(grid.n_runs)  # both dts: strides 100 and 5 in one chunk
    assert segmentable(grid, runs)
    whole = run_chunk(grid, runs, threads=2)
    if method == "rk4":  # the divergence test on continued segments is exercised, both kinds
        assert {0, 1, 2} <= set(whole["status"].tolist())
    for lengths in ([1], [3, 7], [19, 1]):
        chunk, journal, k = SegmentedChunk(grid, 0, runs), Segments(), 0
        while not chunk.finished:
            chunk.next(journal, lengths[k % len(lengths)], lambda *a: integrate_segment(*a, 2))
            k += 1
        cut = chunk.chunk()
        # every segment but the last journaled (the chunk file follows it)
        assert journal.written and journal.written[-1] < grid.n_samples
        for key in ("samples", "status", "n_steps", "solver_iterations", "solver_iterations_max"):
            np.testing.assert_array_equal(cut[key], whole[key])  # NaN == NaN here
        assert np.array_equal(np.signbit(cut["samples"]), np.signbit(whole["samples"]))


def test_long_runs_are_planned_in_blocks_here_and_not_on_dask():
    # 1e7 steps a run: at rk4's ~1.2e7 steps/s a chunk of 1 s holds 2 runs one by one, 13 in blocks
    grid = grid_of("sweep.method=[rk4]", *LONG[:2], "sweep.dt=[1e-4]", "sweep.t_end=1000", "output.every=10")
    runs = np.arange(grid.n_runs)
    here = plan_chunks(grid, runs, 2, 1.0)
    assert [len(c) for c in here] == [MIN_BLOCK_RUNS] and segmentable(grid, here[0])
    assert max(len(c) for c in plan_chunks(grid, runs, 2, 1.0, in_time=False)) < MIN_BLOCK_RUNS
    small = grid_of("sweep.method=[rk4]", "sweep.f=[5,10]", "sweep.dt=[1e-4]", "sweep.t_end=1000", "output.every=10")
    assert max(len(c) for c in plan_chunks(small, np.arange(small.n_runs), 2, 1.0)) <= 2  # < 64: as before


def new_journal(tmp_path, grid):
    journal = Journal(tmp_path / "results.h5")
    journal.create({"config_hash": "test", "n_runs": grid.n_runs, "n_samples": grid.n_samples})
    return journal


def test_a_journal_goes_on_from_its_last_segment(tmp_path):
    grid = grid_of("sweep.method=[rk4]", *LONG)
    runs = np.arange(grid.n_runs)
    whole = run_chunk(grid, runs, threads=2)
    journal = new_journal(tmp_path, grid)
    chunk = SegmentedChunk(grid, 0, runs)
    for _ in range(2):  # then "killed": the segment file holds samples 0..6
        chunk.next(journal, 3, lambda *a: integrate_segment(*a, 2))
    assert [p.name for p in journal.segment_files()] == ["segment-00000.npz"]
    assert journal.done_runs()[1] == 1  # a new chunk would not take the open one's number
    steps = []
    execute.run_missing(grid, journal, runs, 2, 1e-6, 1, lambda r, s: steps.append((r, s)))
    assert steps[0] == (0, 6 * int(grid.inputs(runs)[4].sum()))  # the 6 intervals done count at once
    assert sum(s for _, s in steps) == int(grid.steps(runs).sum()) and sum(r for r, _ in steps) == grid.n_runs
    assert [p.name for p in journal.chunk_files()] == ["chunk-00000.npz"] and not journal.segment_files()
    (stored,) = journal.chunks()
    for key in ("runs", "samples", "status", "n_steps"):
        np.testing.assert_array_equal(stored[key], whole[key])


def test_a_damaged_or_foreign_segment_is_set_aside(tmp_path):
    grid = grid_of("sweep.method=[rk4]", *LONG)
    runs = np.arange(grid.n_runs)
    journal = new_journal(tmp_path, grid)
    SegmentedChunk(grid, 3, runs).next(journal, 2, lambda *a: integrate_segment(*a, 2))
    path = journal.dir / "segment-00003.npz"
    with np.load(path) as saved:
        arrays = {k: saved[k] for k in saved.files}
    arrays["samples"][0, 1, 0] += 1e-9  # a changed sample: its HMAC no longer matches
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    assert not journal.odd_entries()  # a segment file is one of the journal's own
    resumed, rejected = journal.open_segments(runs, grid.n_runs, grid.n_samples)
    assert resumed == [] and rejected[0][0] == "segment-00003.npz" and "HMAC" in rejected[0][1]
    assert not journal.segment_files() and (journal.rejected_dir / "segment-00003.npz").exists()
    # a segment whose runs are all stored in chunks (killed between the chunk and the removal) goes
    SegmentedChunk(grid, 4, runs).next(journal, 2, lambda *a: integrate_segment(*a, 2))
    assert journal.open_segments(np.zeros(0, np.int64), grid.n_runs, grid.n_samples) == ([], [])
    assert not journal.segment_files()


SWEEP = ("sweep.method=[rk4]", *LONG[:2], "sweep.dt=[1e-3]", "sweep.t_end=3", "output.every=0.1")
SEGMENTED = ("runner.chunk_seconds=1e-6", "runner.threads=2", "output.figures=false")  # the shortest segments


def segment_samples(partial, number=0):
    """Samples journaled so far in the segment file of chunk ``number`` under ``partial`` (0 if none)."""
    try:
        with np.load(partial / f"segment-{number:05d}.npz") as segment:
            return segment["samples"].shape[1]
    except (OSError, KeyError, ValueError):
        return 0


def test_the_dry_run_counts_the_segment_files_a_run_writes(tmp_path, monkeypatch):
    """Issue 22: the segment files (each rewriting a chunk's samples so far) are part of the wait; the
    estimate execute.segment_files_seconds gives for a plan is what run_missing then writes."""
    grid = grid_of("sweep.method=[rk4]", *LONG[:2], "sweep.dt=[1e-3]", "sweep.t_end=20", "output.every=0.1")
    runs = np.arange(grid.n_runs)
    assert len(runs) == MIN_BLOCK_RUNS
    chunk_seconds = 1e-3  # 1.3e6 steps, estimated at ~0.01 s: cut into segments
    rows = []
    journal = new_journal(tmp_path, grid)
    write = Journal.write_segment
    monkeypatch.setattr(
        Journal, "write_segment", lambda self, n, **a: (rows.append(a["samples"].shape[1]), write(self, n, **a))
    )
    execute.run_missing(grid, journal, runs, 2, chunk_seconds, 0)
    assert len(rows) >= 2 and rows == sorted(rows) and rows[-1] < grid.n_samples
    written = len(runs) * sum(rows) * grid.bytes_per_run() / grid.n_samples / JOURNAL_RATE
    estimated = execute.segment_files_seconds(grid, [runs], 2, chunk_seconds)
    assert estimated == pytest.approx(written, rel=1e-12)
    assert execute.segment_files_seconds(grid, [runs], 2, 10.0) == 0  # not cut in time: no segment files


@pytest.mark.slow
def test_a_sweep_killed_mid_segment_resumes_to_identical_data(tmp_path):
    reference = tmp_path / "reference"
    assert_ok(gyrolab(*SWEEP, *SEGMENTED, f"hydra.run.dir={reference}", cwd=tmp_path))
    run = tmp_path / "run"
    partial = run / "results.h5.partial"
    proc = start(*SWEEP, *SEGMENTED, f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.3)

    wait_for(lambda: segment_samples(partial) >= 4, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not list(partial.glob("chunk-*.npz"))
    resumed = gyrolab(*SWEEP, *SEGMENTED, f"hydra.run.dir={run}", "runner.resume=true", cwd=tmp_path)
    assert_ok(resumed)
    xr.testing.assert_identical(data(run / "results.h5"), data(reference / "results.h5"))
    assert not partial.exists()


def test_the_solver_counts_of_segments_add_up_and_keep_the_most_in_one_step():
    """SegmentedChunk.absorb: a run's counts over its segments are the totals added and the larger of
    the most in one step (-1, not counted, stays so); runs no longer going keep theirs."""
    grid = grid_of("sweep.method=[rk4]", "sweep.f=[5,10,20]", "sweep.theta0=[30]", "sweep.dt=[1e-3]", "sweep.t_end=1")
    runs = np.arange(grid.n_runs)
    so_far = {
        "runs": runs,
        "samples": np.ones((3, 2, 17)),
        "status": np.array([0, 2, 0], np.int8),
        "n_steps": np.array([10, 7, 10], np.int64),
        "wall_time": np.ones(3),
        "solver_iterations": np.array([30, 20, -1], np.int64),
        "solver_iterations_max": np.array([4, 5, -1], np.int64),
        "state": np.ones((3, 7)),
    }
    chunk = SegmentedChunk(grid, 0, runs, so_far)
    assert chunk.task(1) is not None and chunk.going.tolist() == [0, 2]  # run 1 stopped (status 2)
    part = {
        "samples": np.full((2, 2, 17), 2.0),
        "status": np.zeros(2, np.int8),
        "n_steps": np.array([10, 10], np.int64),
        "wall_time": np.ones(2),
        "solver_iterations": np.array([25, 8], np.int64),
        "solver_iterations_max": np.array([6, 2], np.int64),
        "state": np.full((2, 7), 2.0),
    }
    journal = Segments()
    chunk.absorb(journal, part)
    assert journal.written == [3]
    assert chunk.arrays["solver_iterations"].tolist() == [55, 20, -1]
    assert chunk.arrays["solver_iterations_max"].tolist() == [6, 5, -1]
    assert chunk.arrays["n_steps"].tolist() == [20, 7, 20]
    assert set(chunk.chunk()) == {"runs", "samples", "status", "n_steps", "wall_time", *SOLVER_COUNTS}
