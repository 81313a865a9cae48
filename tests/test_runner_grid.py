"""The grid numbers runs like the results' dims; chunks cover every run once, one method and dt each."""

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from gyrolab.kernels.batch import MIN_BLOCK_RUNS
from gyrolab.kernels.scenes import build_scene
from gyrolab.runner.config import ConfigError, register_configs
from gyrolab.runner.execute import run_chunk
from gyrolab.runner.grid import build_grid, chunk_size, plan_chunks

register_configs()


def grid_of(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=list(overrides)))


GRID = (
    "sweep.method=[seed_next,rk4,lie_poisson]",
    "sweep.f=[1,10,50]",
    "sweep.theta0=[30,45]",
    "sweep.dt=[1e-3,5e-4,1e-4]",
    "sweep.t_end=0.2",
    "output.every=1e-3",
)


def test_run_numbers_follow_the_dims_in_c_order():
    grid = grid_of(*GRID)
    assert grid.shape == (3, 3, 2, 3) and grid.n_runs == 54
    run = 1 * 18 + 2 * 6 + 1 * 3 + 2  # rk4, f=50, theta0=45, dt=1e-4
    assert [int(i[0]) for i in grid.index([run])] == [1, 2, 1, 2]
    bodies, omega0, q0, dt, stride = grid.inputs([run])
    scene = build_scene("heavy_top", 50.0, 45.0)
    np.testing.assert_array_equal(bodies[0], scene.body)
    np.testing.assert_array_equal(omega0[0], scene.omega0)
    np.testing.assert_array_equal(q0[0], scene.q0)
    assert dt[0] == 1e-4 and stride[0] == 10 and grid.steps([run])[0] == 2000


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("seconds", [1e-6, 1e-4, 1.0])
def test_chunks_cover_every_run_once_with_one_method_each(threads, seconds):
    grid = grid_of(*GRID)
    rate = 1e7
    chunks = plan_chunks(grid, np.arange(grid.n_runs), threads, seconds, {m: rate for m in grid.methods})
    runs = np.concatenate(chunks)
    assert np.array_equal(np.sort(runs), np.arange(grid.n_runs))
    for chunk in chunks:
        im, _, _, ld = grid.index(chunk)
        assert len(set(im)) == 1
        work = grid.steps(chunk).sum() / (rate * threads)
        if len(set(ld)) > 1:  # pooled leftovers of several dt: within the time budget
            assert work <= seconds
        elif work > seconds * 1.0001:  # over budget only when one run per thread is already too long
            assert len(chunk) <= threads


def test_small_dt_groups_are_pooled_not_left_as_tiny_chunks():
    grid = grid_of(
        "sweep.method=[seed_next]",
        "sweep.f=[10]",
        "sweep.theta0=[45]",
        "sweep.dt=[1e-3,5e-4,2.5e-4,2e-4,1e-4]",
        "sweep.t_end=0.1",
    )
    (chunk,) = plan_chunks(grid, np.arange(grid.n_runs), 2, 1.0)
    assert sorted(chunk) == list(range(5))


def test_chunk_size_targets_the_time_and_respects_memory():
    # 2e6 steps/s per thread, 2 threads, 1 s: 4e6 steps = 4 runs of 1e6 steps (64 runs in
    # blocks, ~10x faster per run, would take 6.4 s: too long for one chunk)
    assert chunk_size(1e6, 2e6, 2, 1.0, bytes_per_run=1) == 4
    # 1e6 steps/s: 20 runs of 1e5 steps by time, but 64 runs in blocks take ~0.3 s: one block chunk
    assert chunk_size(1e5, 1e6, 2, 1.0, bytes_per_run=1, speedup=10) == MIN_BLOCK_RUNS  # 64 fit in blocks
    assert chunk_size(1e5, 1e6, 2, 1.0, bytes_per_run=1, speedup=1) == 20  # not without
    assert chunk_size(1e9, 1e6, 2, 1.0, bytes_per_run=1) == 2  # never fewer runs than threads...
    assert chunk_size(1e5, 1e6, 2, 1.0, bytes_per_run=100, max_bytes=1000) == 10  # ...nor over memory
    assert chunk_size(1e5, 1e6, 4, 1.0, bytes_per_run=100, max_bytes=250) == 2


def test_only_the_given_runs_are_planned():
    grid = grid_of(*GRID)
    todo = np.arange(5, 40, 3)
    assert np.array_equal(np.sort(np.concatenate(plan_chunks(grid, todo, 2, 1e-5))), todo)


def test_a_run_gives_the_same_bits_in_any_chunk():
    grid = grid_of(*GRID)
    alone = run_chunk(grid, np.array([10]), threads=1)
    together = run_chunk(grid, np.array([1, 4, 7, 10, 13, 16]), threads=2)
    np.testing.assert_array_equal(alone["samples"][0], together["samples"][3])
    assert alone["n_steps"][0] == together["n_steps"][3] == grid.steps([10])[0]


def test_wall_time_is_shared_by_steps_and_threads():
    grid = grid_of(*GRID)
    result = run_chunk(grid, np.array([1, 4]), threads=2)
    assert np.all(result["wall_time"] > 0)
    assert result["wall_time"][0] == pytest.approx(result["wall_time"][1])


@pytest.mark.parametrize(
    "override, message",
    [
        ("sweep.dt=[3e-4]", "sweep.dt=0.0003: must divide output.every"),
        ("scene.init=steady_fast", "sweep.f=1: steady precession"),
        ("scene.name=nope", "scene.name=nope: unknown scene"),
        ("sweep.method=[seed_next,nope]", "sweep.method=nope: unknown method"),
    ],
)
def test_build_grid_names_key_and_value(override, message):
    with pytest.raises(ConfigError) as info:
        grid_of(*GRID, override)
    assert str(info.value).startswith(message)


@pytest.mark.parametrize("threads", [1, 2])
def test_the_time_estimate_counts_every_run_at_its_own_dt(threads):
    """sweep.dt=[1e-3,1e-5]: a chunk pooling runs of both dts used to be costed at its first run's
    steps (120x too low); the estimate now follows the total number of steps."""
    from gyrolab.runner.grid import STEP_RATE, estimate_seconds, step_rate

    common = ("sweep.method=[seed_next]", "sweep.f=[1,10,50]", "sweep.theta0=[45]", "sweep.t_end=1")
    mixed, coarse = grid_of(*common, "sweep.dt=[1e-3,1e-5]"), grid_of(*common, "sweep.dt=[1e-3]")
    assert mixed.total_steps == 3 * (1000 + 100000) and coarse.total_steps == 3000
    for grid in (mixed, coarse):
        chunks = plan_chunks(grid, np.arange(grid.n_runs), threads, chunk_seconds=10.0)
        assert all(len(c) < MIN_BLOCK_RUNS for c in chunks) and step_rate("seed_next", 1) == STEP_RATE["seed_next"]
        seconds = estimate_seconds(grid, chunks, threads)
        lower = grid.total_steps / STEP_RATE["seed_next"] / threads  # every step, perfectly shared
        upper = grid.total_steps / STEP_RATE["seed_next"]  # every step on one thread
        assert lower * (1 - 1e-12) <= seconds <= upper * (1 + 1e-12)
        if threads == 1:
            assert seconds == pytest.approx(grid.total_steps / STEP_RATE["seed_next"], rel=1e-12)

    def one_thread(grid):
        return estimate_seconds(grid, plan_chunks(grid, np.arange(grid.n_runs), 1, 10.0), 1)

    ratio = one_thread(mixed) / one_thread(coarse)
    assert ratio == pytest.approx(mixed.total_steps / coarse.total_steps, rel=1e-12)  # 101x


def test_the_writing_estimate_follows_the_bytes():
    from gyrolab.runner.grid import estimate_writing_seconds

    common = ("sweep.method=[seed_next]", "sweep.f=[1,10]", "sweep.theta0=[45]", "sweep.dt=[1e-3]")
    short, long = grid_of(*common, "sweep.t_end=1"), grid_of(*common, "sweep.t_end=100")
    few = grid_of(*common, "sweep.t_end=100", "output.variables=[theta]")
    assert estimate_writing_seconds(long) > 50 * estimate_writing_seconds(short)
    assert estimate_writing_seconds(few) < estimate_writing_seconds(long)


def test_block_chunks_are_costed_at_the_block_paths_speed():
    """A chunk of MIN_BLOCK_RUNS runs or more runs on the vectorised block path, several times faster
    per step for most methods (docs/benchmarks.md): the dry run's estimate and the runner's
    chunk_estimate (which sends long chunks to the worker process) both take that speed-up; one
    chunk of fewer runs, the one-by-one speed."""
    from gyrolab.runner.execute import chunk_estimate
    from gyrolab.runner.grid import BLOCK_SPEEDUP, STEP_RATE, estimate_seconds, step_rate

    assert step_rate("seed_next", MIN_BLOCK_RUNS) == STEP_RATE["seed_next"] * BLOCK_SPEEDUP["seed_next"]
    assert step_rate("seed_next", MIN_BLOCK_RUNS - 1) == STEP_RATE["seed_next"]
    assert step_rate("seed_next", MIN_BLOCK_RUNS, driven=True) == STEP_RATE["seed_next"]  # one by one
    assert BLOCK_SPEEDUP["seed_next"] > 5
    # a method off the block path (BLOCKS = False) is costed one by one whatever the chunk's size
    assert step_rate("strang_exact4", 10 * MIN_BLOCK_RUNS) == step_rate("strang_exact4", 1)
    fs = "sweep.f=[" + ",".join(str(f) for f in range(1, MIN_BLOCK_RUNS + 1)) + "]"
    grid = grid_of("sweep.method=[seed_next]", fs, "sweep.theta0=[45]", "sweep.dt=[1e-3]", "sweep.t_end=1")
    runs = np.arange(grid.n_runs)
    blocks = chunk_estimate(grid, runs, 2, {})
    assert blocks == pytest.approx(grid.total_steps / 2 / (STEP_RATE["seed_next"] * BLOCK_SPEEDUP["seed_next"]))
    assert blocks == pytest.approx(estimate_seconds(grid, [runs], 2))
    one_by_one = sum(chunk_estimate(grid, runs[k : k + 8], 2, {}) for k in range(0, grid.n_runs, 8))
    assert one_by_one == pytest.approx(BLOCK_SPEEDUP["seed_next"] * blocks)
    # a speed measured on one path is not used for the other
    measured = {("seed_next", False): 1e6}
    assert chunk_estimate(grid, runs, 2, measured) == blocks
    assert chunk_estimate(grid, runs[:8], 2, measured) == pytest.approx(4 * 1000 / 1e6)
