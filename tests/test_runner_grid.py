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


# --------------------------------------------------------------------------- the grid's size, selectors expanded


@pytest.fixture
def max_runs_100(monkeypatch):
    """MAX_RUNS of 100: the selectors' expansion is checked on grids of a few runs."""
    from gyrolab.runner import grid as grid_module

    monkeypatch.setattr(grid_module, "MAX_RUNS", 100)


def test_a_selector_is_counted_as_its_methods_before_any_scene_is_built(max_runs_100, monkeypatch):
    """sweep.method=[all] on 1 x 1 x 5 grid points: 205 runs (41 methods), or at least 115 (the 23 of a
    driven scene): refused before a single scene is built (it used to count as 1 method, so a grid of
    41e6 runs passed the 1e7 limit, built 1e6 scenes and 2.9 GB of plan before anything said no)."""
    from gyrolab.runner import grid as grid_module

    def no_scene(*args, **kwargs):
        raise AssertionError("a scene was built before the grid's size was checked")

    monkeypatch.setattr(grid_module, "build_scene", no_scene)
    dts = "sweep.dt=[1e-3,5e-4,2.5e-4,2e-4,1e-4]"
    with pytest.raises(ConfigError, match=r"sweep: 23 method \(sweep.method=\[all\] selects at least 23\) x 1 f"):
        grid_of("sweep.method=[all]", "sweep.f=[10]", "sweep.theta0=[45]", dts, "sweep.t_end=0.01")


def test_a_selector_is_counted_exactly_once_the_scene_is_known(max_runs_100):
    """3 grid points: [all] is 41 methods (123 runs, refused) on the heavy top, 23 (69 runs, accepted) on
    a driven scene."""
    dts = "sweep.dt=[1e-3,5e-4,2.5e-4]"
    common = ("sweep.method=[all]", "sweep.f=[10]", "sweep.theta0=[45]", dts, "sweep.t_end=0.01")
    with pytest.raises(ConfigError, match=r"sweep: 41 method \(sweep.method=\[all\] selects 41\) x 1 f .* = 123 runs"):
        grid_of(*common)
    assert grid_of(*common, "scene=forced_body").n_runs == 69


# --------------------------------------------------------------------------- the file's size, estimated


@pytest.mark.parametrize(
    "overrides",
    [
        # many runs of few samples: the per-run variables and the runs' inputs are most of the file
        (
            "sweep.f=${linspace:1,40,40}",
            "sweep.theta0=${linspace:1,179,50}",
            "sweep.t_end=0.01",
            "output.every=1e-2",
            "output.variables=[theta]",
        ),
        # few runs of many samples: the per-sample variables are
        ("sweep.f=[10,50]", "sweep.t_end=1"),
    ],
    ids=["many_runs", "many_samples"],
)
def test_the_file_size_estimate_counts_all_the_file_holds(tmp_path, overrides):
    """The dry run's size of the results file, and the disk it checks for, count every variable the file
    holds (per sample, per run, per (f, theta0) input) and the coordinates: 1.6 MB were estimated for
    a file of 20.2 MB (100000 runs of 2 samples of theta).  Within 10 % of a real file's size (1 to 2 %)."""
    from gyrolab.results.layout import RAW_PER_SAMPLE
    from gyrolab.runner.preflight import disk_needed

    from helpers import FILE_BASE, make_file

    grid = grid_of(*FILE_BASE, *overrides)
    size = make_file(tmp_path / "results.h5", *overrides).stat().st_size
    assert grid.file_bytes() == pytest.approx(size, rel=0.1)
    assert disk_needed(grid) > 0.8 * size + grid.n_runs * grid.n_samples * RAW_PER_SAMPLE * 8  # + the journal


# --------------------------------------------------------------------------- t_end against output.every


@pytest.mark.parametrize(
    "t_end, every, last",
    [("999.9995", "1e-3", "999.999"), ("0.09999995", "1e-3", "0.099"), ("1.0000001", "1e-3", "1")],
)
def test_a_t_end_the_kernels_would_cut_short_is_refused(t_end, every, last):
    """The kernels store the samples of t = 0 to t_end rounded down to a multiple of output.every
    (kernels/batch.py sample_schedule); t_end=999.9995 with every=1e-3 passed the check (within 1e-6 x the
    sample count) and the runs ended at 999.999 s, exit 0, attr t_end 999.9995."""
    with pytest.raises(ConfigError) as info:
        grid_of(*GRID, f"sweep.t_end={t_end}", f"output.every={every}", "sweep.dt=[1e-3]")
    assert str(info.value).startswith(f"sweep.t_end={t_end}: not a multiple of output.every=")
    assert f"(the last sample would be at t = {last} s)" in str(info.value)


@pytest.mark.parametrize(
    "t_end, every, samples", [(1, 1e-3, 1001), (0.3, 0.1, 4), (0.7, 0.1, 8), (1.1, 0.1, 12), (1000, 1e-3, 1000001)]
)
def test_a_t_end_that_is_a_multiple_to_rounding_passes(t_end, every, samples):
    """0.3 / 0.1 is 2.9999999999999996, 1.1 / 0.1 is 11.000000000000002: multiples, to float rounding."""
    from gyrolab.runner.config import last_sample

    assert last_sample(t_end, every) is None
    grid = grid_of(*GRID, f"sweep.t_end={t_end}", f"output.every={every}", "sweep.dt=[1e-3]")
    assert grid.n_samples == samples
