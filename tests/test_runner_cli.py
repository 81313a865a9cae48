"""The ``gyrolab`` and ``gyrolab-combine`` commands, end to end in subprocesses, on tiny grids.

Each subprocess costs ~1-2 s (Hydra, numba and xarray imports; JIT from cache).
"""

import os
import re
import shlex
import signal
import subprocess

import numpy as np
import pytest
import xarray as xr

from gyrolab import simulate
from gyrolab.results.layout import GRID_DIMS, SAMPLE_VARIABLES
from gyrolab.results.migrate import SOLVER_COUNTS

from helpers import (  # noqa: F401 (re-used by the tests below)
    BIN,
    SLOW,
    TINY,
    assert_ok,
    chunk_count,
    command,
    data,
    environment,
    gyrolab,
    start,
    tiny_reference,
    wait_for,
)


@pytest.mark.slow
def test_a_sweep_without_figures_never_imports_xarray_or_matplotlib(tmp_path):
    """The runner writes the results through h5py: a sweep with ``output.figures=false`` (scripts, CI,
    the regression configs) imports neither xarray (with pandas ~0.35 s) nor matplotlib (~0.2 s); every
    invocation paid both before (2.45 s -> 1.55 s for a tiny sweep on the development machine)."""
    res = gyrolab(
        *TINY,  # output.figures=false among them
        f"hydra.run.dir={tmp_path}",
        cwd=tmp_path,
        env=environment(PYTHONPROFILEIMPORTTIME=1),
    )
    assert_ok(res)
    imported = {line.rsplit("|", 1)[-1].strip() for line in res.stderr.splitlines() if line.startswith("import time:")}
    assert "gyrolab.runner.sweep" in imported  # the profile is there and covers the run
    assert not {"xarray", "matplotlib", "pandas"} & imported, sorted({"xarray", "matplotlib", "pandas"} & imported)


@pytest.mark.slow
def test_a_dry_run_costs_its_figures_without_importing_them(tmp_path):
    """The dry run checks the figures a config names and costs the figure step from the registry's names
    and the figures' cost model alone: the figure modules (matplotlib) and the reader (xarray, pandas) are
    imported only to draw (1.2 s of CPU instead of 2.0 for the default study's dry run, machine loaded)."""
    res = gyrolab(
        "runner.dry_run=true",
        "output.figures=[nutation,stability,work-precision]",
        f"hydra.run.dir={tmp_path}",
        cwd=tmp_path,
        env=environment(PYTHONPROFILEIMPORTTIME=1),
    )
    assert_ok(res)
    each = r"nutation [\d.]+ s, stability [\d.]+ s, work-precision [\d.]+ s"
    assert re.search(rf"\+ [\d.]+ s figures \({each}", res.stdout), res.stdout
    imported = {line.rsplit("|", 1)[-1].strip() for line in res.stderr.splitlines() if line.startswith("import time:")}
    assert "gyrolab.analysis.figures.cost" in imported  # the profile is there and covers the estimate
    assert not {"xarray", "matplotlib", "pandas"} & imported, sorted({"xarray", "matplotlib", "pandas"} & imported)
    # and a name the registry does not list is refused before any work, as before
    bad = gyrolab("runner.dry_run=true", "output.figures=[nutation,fancy]", f"hydra.run.dir={tmp_path}", cwd=tmp_path)
    assert bad.returncode == 2 and "output.figures=fancy: unknown figure; choose from nutation, tip" in bad.stderr


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run of TINY (+ SLOW chunking) on all threads."""
    return tiny_reference(tmp_path_factory.mktemp("reference"))


@pytest.mark.slow
def test_tiny_sweep_file_opens_with_xarray_and_matches_simulate(reference):
    with xr.open_dataset(reference, engine="h5netcdf") as ds:
        assert {k: ds.sizes[k] for k in GRID_DIMS + ("time", "xyz")} == {
            "integrator": 2,
            "f": 2,
            "theta0": 2,
            "dt": 2,
            "time": 101,
            "xyz": 3,
        }
        assert list(ds["integrator"].values) == ["seed_next", "lie_poisson"]
        assert list(ds["f"].values) == [10.0, 50.0] and list(ds["dt"].values) == [1e-3, 1e-4]
        assert ds["f"].attrs["units"] == "Hz" and ds["theta0"].attrs["units"] == "deg"
        assert "legend" in ds["status"].attrs and np.all(ds["status"].values == 0)
        for key in (
            "config",
            "gyrolab_version",
            "git_commit",
            "numba_version",
            "numpy_version",
            "threads",
            "created",
            "scene",
            "scene_M",
            "scene_init",
            "layout_version",
            "kernel_source_hash",
            "conserved",
            "scipy_version",
            "h5py_version",
            "xarray_version",
        ):
            assert key in ds.attrs, key
        assert "sweep:" in ds.attrs["config"] and ds.attrs["scene"] == "heavy_top"
        assert np.all(ds["wall_time"].values > 0)
        # Every run sits at its coordinates: the same bits as gyrolab.simulate of that point.
        for method in ds["integrator"].values:
            for f in ds["f"].values:
                for theta0 in ds["theta0"].values:
                    for dt in ds["dt"].values:
                        one = simulate(method=str(method), f=f, theta0=theta0, dt=dt, t_end=0.1, every=1e-3)
                        run = ds.sel({"integrator": method, "f": f, "theta0": theta0, "dt": dt})
                        for name in (*SAMPLE_VARIABLES, *SOLVER_COUNTS, "status", "n_steps", "body", "omega0", "q0"):
                            np.testing.assert_array_equal(run[name].values, one[name].values, err_msg=name)


@pytest.mark.slow
def test_results_and_where_they_are_printed(tmp_path):
    result = gyrolab("sweep=tiny", "output.figures=false", cwd=tmp_path)
    assert_ok(result)
    (path,) = tmp_path.glob("outputs/*/*/results.h5")
    assert f"results: {path}" in result.stdout
    assert sorted(p.name for p in path.parent.iterdir()) == ["results.h5"]  # no journal, lock or temp left


@pytest.mark.slow
def test_dry_run_of_the_default_study_estimates_and_writes_nothing(tmp_path):
    result = gyrolab("runner.dry_run=true", cwd=tmp_path)
    assert_ok(result)
    out = result.stdout
    assert "5 method x 3 f x 1 theta0 x 3 dt = 45 runs" in out
    for word in ("steps", "estimated time", "peak memory", "output"):
        assert word in out
    # the figures the study draws read the file slab by slab: their memory is stated (runner/app.py figure_memory)
    assert "figure step: peak memory ~" in out and "+ 0.001 x its" in out
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_dry_run_counts_compiling_from_the_numba_cache(tmp_path):
    """An empty numba cache: every kernel the sweep warms up is named and its compile time counted
    (runner/compile.py compile_seconds: COMPILE_SECONDS["runs"] per method's run kernels, in parallel on the
    cores); the dry run compiles nothing."""
    empty = tmp_path / "cache"
    result = gyrolab("runner.dry_run=true", cwd=tmp_path, env=environment(NUMBA_CACHE_DIR=empty))
    assert_ok(result)
    methods = ("seed_next", "seed_prev", "rk4", "lie_poisson", "lie_poisson4")  # the default study: no blocks
    assert f"compiling: 5 kernels not in the numba cache: {', '.join(f'{m} (runs)' for m in methods)}" in result.stdout
    # COMPILE_SECONDS each, on this machine's cores as warm_up compiles them (compile_wall_seconds)
    from gyrolab.runner.compile import COMPILE_SECONDS, compile_jobs
    from gyrolab.runner.execute import compile_memory, compile_wall_seconds

    assert f", {compile_wall_seconds([COMPILE_SECONDS['runs']] * 5):.0f} s compiling)" in result.stdout
    _, where = compile_memory([(m, "runs") for m in methods])
    assert f"while numba compiles 5 kernel(s) {where})" in result.stdout
    parallel = f"in {min(compile_jobs(), 5)} compile processes, one method each"
    assert where == ("in this process" if compile_jobs() < 2 else parallel)
    assert not list(empty.rglob("*.nbi"))  # estimated, not compiled


@pytest.mark.slow
def test_dry_run_of_a_multirun_leaves_nothing_behind(tmp_path):
    result = gyrolab("-m", "scene=heavy_top,free_asymmetric", "sweep.f=[5]", "runner.dry_run=true", cwd=tmp_path)
    assert_ok(result)
    assert result.stdout.count("gyrolab dry run:") == 2 and "skipped" not in result.stderr
    assert list(tmp_path.iterdir()) == []  # Hydra's multirun/<date>/<time>/multirun.yaml removed with its dirs


@pytest.mark.slow
def test_dry_run_of_a_multirun_keeps_directories_that_were_there(tmp_path):
    """The user's own empty directories above the sweep directory, and the sweep directory itself when it
    existed, stay: the dry run removes only what Hydra made for it (it removed two such parents)."""
    keep = tmp_path / "dd" / "keep"
    keep.mkdir(parents=True)
    for sweep in (keep / "mr", keep):
        result = gyrolab("-m", "sweep.t_end=0.1,0.2", f"hydra.sweep.dir={sweep}", "runner.dry_run=true", cwd=tmp_path)
        assert_ok(result)
        assert keep.is_dir() and not (keep / "mr").exists() and not list(keep.iterdir())


@pytest.mark.slow
def test_dry_run_figure_memory_follows_the_file_and_the_setting(tmp_path):
    """The model of docs/benchmarks.md against the sweeps' peak RSS with their figures: 501 MB for the
    8000-run sweep's 1.09 GB file, 518 MB for the 40000-run sweep's 5.45 GB one, each within 10 %;
    no figures, no figure step."""
    from types import SimpleNamespace

    from gyrolab.runner.preflight import figure_memory

    for file_bytes, measured in ((1.09e9, 501e6), (5.45e9, 518e6)):
        assert figure_memory(SimpleNamespace(file_bytes=lambda b=file_bytes: b)) == pytest.approx(measured, rel=0.1)
    result = gyrolab("runner.dry_run=true", "output.figures=false", cwd=tmp_path)
    assert_ok(result)
    assert "figure step: none (output.figures=false)" in result.stdout


@pytest.mark.slow
def test_killed_sweep_resumes_to_identical_data(tmp_path, reference):
    run = tmp_path / "run"
    proc = start(*TINY, *SLOW, f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.3)
    wait_for(lambda: chunk_count(run) >= 2, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (run / "results.h5").exists() and chunk_count(run) >= 2
    saved = sum(len(np.load(p)["runs"]) for p in (run / "results.h5.partial").glob("chunk-*.npz"))
    refused = gyrolab(*TINY, *SLOW, f"hydra.run.dir={run}", cwd=tmp_path)
    assert refused.returncode == 2 and "runner.resume=true" in refused.stderr
    resumed = gyrolab(*TINY, *SLOW, f"hydra.run.dir={run}", "runner.resume=true", cwd=tmp_path)
    assert_ok(resumed)
    assert f"resuming: {saved} runs already done, {16 - saved} to go" in resumed.stdout
    xr.testing.assert_identical(data(run / "results.h5"), data(reference))
    assert sorted(p.name for p in run.iterdir()) == ["results.h5"]
    again = gyrolab(*TINY, *SLOW, f"hydra.run.dir={run}", "runner.resume=true", cwd=tmp_path)
    assert_ok(again)
    assert "nothing to do" in again.stdout


@pytest.mark.slow
def test_ctrl_c_prints_the_command_that_finishes_the_sweep(tmp_path, reference):
    run = tmp_path / "run"
    proc = start(*TINY, *SLOW, f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=0.3)
    wait_for(lambda: chunk_count(run) >= 1, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err
    words = shlex.split(err.split("Finish with: ")[1].strip())
    assert words[0] == "gyrolab"
    finished = gyrolab(*words[1:], cwd=tmp_path)
    assert_ok(finished)
    xr.testing.assert_identical(data(run / "results.h5"), data(reference))


@pytest.mark.slow
def test_second_writer_to_the_same_output_is_refused(tmp_path, reference):
    run = tmp_path / "run"
    first = start(*TINY, *SLOW, f"hydra.run.dir={run}", cwd=tmp_path, GYROLAB_TEST_CHUNK_DELAY=1.0)
    wait_for(lambda: chunk_count(run) >= 1, first)
    # paused mid-run (it keeps its lock), so that three slow starts on a loaded machine cannot outlast it
    os.kill(first.pid, signal.SIGSTOP)
    try:
        for extra in ([], ["runner.resume=true"], ["output.overwrite=true"]):
            second = gyrolab(*TINY, *SLOW, f"hydra.run.dir={run}", *extra, cwd=tmp_path)
            assert first.poll() is None, "the first writer finished too soon for this test"
            assert second.returncode == 2, second.stderr
            assert f"another gyrolab (pid {first.pid}) is writing it" in second.stderr
    finally:
        os.kill(first.pid, signal.SIGCONT)
    assert first.wait(timeout=120) == 0, first.communicate()
    xr.testing.assert_identical(data(run / "results.h5"), data(reference))


@pytest.mark.slow
def test_one_thread_and_two_threads_give_identical_files(tmp_path, reference):
    result = gyrolab(*TINY, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path, env=environment(NUMBA_NUM_THREADS=1))
    assert_ok(result)
    with xr.open_dataset(tmp_path / "run" / "results.h5", engine="h5netcdf") as ds:
        assert ds.attrs["threads"] == 1
    xr.testing.assert_identical(data(tmp_path / "run" / "results.h5"), data(reference))


@pytest.mark.slow
def test_multirun_writes_one_file_per_job_and_combine_merges_them(tmp_path):
    sweep_dir = tmp_path / "mr"
    result = gyrolab("-m", "scene=heavy_top,free_asymmetric", *TINY, f"hydra.sweep.dir={sweep_dir}", cwd=tmp_path)
    assert_ok(result)
    files = sorted(sweep_dir.glob("*/results.h5"))
    assert [f.parent.name for f in files] == ["0", "1"]
    combined = subprocess.run(
        command("gyrolab-combine", "gyrolab.analysis.files.combine") + [str(sweep_dir)],
        capture_output=True,
        text=True,
        env=environment(),
        timeout=120,
    )
    assert combined.returncode == 0, combined.stderr
    with xr.open_dataset(sweep_dir / "combined.h5", engine="h5netcdf") as ds:
        assert list(ds["scene"].values) == ["heavy_top", "free_asymmetric"]
        assert ds["axis"].dims == ("scene", "integrator", "f", "theta0", "dt", "time", "xyz")
        for path, scene in zip(files, ("heavy_top", "free_asymmetric")):
            with xr.open_dataset(path, engine="h5netcdf") as one:
                np.testing.assert_array_equal(ds["energy"].sel(scene=scene).values, one["energy"].values)
                assert one.attrs["scene"] == scene
        assert np.isnan(ds["scene_M"].sel(scene="free_asymmetric")) and ds["scene_M"].sel(scene="heavy_top") == 1.0
        assert ds.sizes["source"] == 2 and "sweep:" in str(ds["source_config"].values[0])


@pytest.mark.slow
@pytest.mark.parametrize(
    "text, message",
    [
        ("sweep:\n  f: [10\n  dt: x\n", "badexp.yaml, line 4, column 5: YAML syntax error"),
        ("sweep:\n  t_end: ten\n", "sweep.t_end (in experiment/badexp.yaml): Value 'ten'"),
    ],
    ids=["syntax", "type"],
)
def test_bad_experiment_yaml_is_one_line_naming_the_file_and_key(tmp_path, text, message):
    (tmp_path / "conf" / "experiment").mkdir(parents=True)
    (tmp_path / "conf" / "experiment" / "badexp.yaml").write_text("# @package _global_\n" + text)
    result = gyrolab(f"--config-dir={tmp_path / 'conf'}", "experiment=badexp", cwd=tmp_path)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("gyrolab: error: ") and message in line and "Traceback" not in result.stderr


@pytest.mark.slow
def test_multirun_with_a_bad_job_stops_before_any_job_runs(tmp_path):
    result = gyrolab("-m", "scene.M=1,-1", *TINY, f"hydra.sweep.dir={tmp_path / 'mr'}", cwd=tmp_path)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("gyrolab: error: scene.M=-1.0: must be > 0 (in job scene.M=-1 ")
    assert list(tmp_path.iterdir()) == []


BIG_F = "sweep.f=[" + ",".join(str(v) for v in range(1, 101)) + "]"
BIG_THETA = "sweep.theta0=[" + ",".join(str(v) for v in range(1, 101)) + "]"
BAD_INPUTS = [
    (["sweep.dt=[0]"], "sweep.dt=0.0"),
    (["sweep.dt=[1e-3,-1e-4]"], "sweep.dt=-0.0001"),
    (["sweep.dt=[3e-4]"], "sweep.dt=0.0003: must divide output.every=0.001"),
    (["sweep.t_end=0"], "sweep.t_end=0.0"),
    (["sweep.t_end=-1"], "sweep.t_end=-1.0"),
    (["sweep.t_end=1e-4"], "sweep.t_end=0.0001"),
    (["sweep.theta0=[nan]"], "sweep.theta0=nan: must be a finite number"),
    (["scene.g=inf"], "scene.g=inf: must be a finite number"),
    (["output.every=nan"], "output.every=nan: must be a finite number"),
    (["sweep.theta0=[45,181]"], "sweep.theta0=181.0"),
    (["sweep.theta0=[-5]"], "sweep.theta0=-5.0"),
    (["sweep.f=[-1]"], "sweep.f=-1.0"),
    (["scene.M=-1"], "scene.M=-1.0"),
    (["scene.r=-0.05"], "scene.r=-0.05"),
    (["scene=free_asymmetric", "scene.I3=5e-4"], "scene.I3=0.0005: violates the triangle inequality"),
    (["sweep.method=[seed_next,euler]"], "sweep.method=euler: unknown method"),
    (["scene=spinning_plate"], "scene=spinning_plate: unknown scene"),
    (["scene.init=steady_slow", "sweep.f=[1,10,50]"], "sweep.f=1: steady precession"),
    (["output.path={existing}"], "output.path={existing}: exists"),
    (["output.path=/proc/gyrolab-test/results.h5"], "output.path=/proc/gyrolab-test/results.h5: cannot write"),
    (["sweep.t_end=1e4", "output.every=1e-6", "sweep.dt=[1e-6]"], "output.every=1e-06"),
    (["sweep.t_end=1000", BIG_F, BIG_THETA, "sweep.dt=[1e-3]"], "output.path="),
    (["sweep.t_end=ten"], "sweep.t_end=ten"),
    (["sweep.f=10"], "sweep.f=10"),
    (["sweep.tend=3"], "sweep.tend=3"),
    (["runner.backend=slurm"], "runner.backend=slurm"),
    # issue 16: overflowing sizes (also in a dry run), absurd spins, options that would be ignored
    (["sweep.t_end=1e20"], "sweep.t_end=1e+20"),
    (["sweep.dt=[1e-300]"], "sweep.dt=1e-300"),
    (["sweep.dt=[1e-300]", "runner.dry_run=true"], "sweep.dt=1e-300"),
    (["sweep.f=[1e200]"], "sweep.f=1e+200"),
    (["output.figures=2"], "output.figures=2"),
    (["scene.phidot0=3"], "scene.phidot0=3.0: only used with scene.init=precession"),
    (["runner.resume=true", "hydra.run.dir={tmp}/nothing"], "runner.resume=true: nothing to resume"),
    (["hydra.run.dir={existing}"], "hydra.run.dir={existing}: exists and is not a directory"),
    (["hydra.run.dir=/proc/gyrolab-test"], "hydra.run.dir=/proc/gyrolab-test: cannot write"),
    # a directory's name as output.path: the file took the name (sub/ wrote a file named sub)
    (["output.path=sub/"], "output.path=sub/: names a directory, not a file"),
    (["output.path={tmp}/sub/"], "output.path={tmp}/sub/: names a directory, not a file"),
    # a t_end just off a multiple of output.every: the runs ended at the multiple below it, exit 0
    (["sweep.t_end=0.09999995"], "sweep.t_end=0.09999995: not a multiple of output.every=0.001"),
]


@pytest.mark.slow
@pytest.mark.parametrize("args, message", BAD_INPUTS, ids=[" ".join(a)[:40] for a, _ in BAD_INPUTS])
def test_bad_input_is_refused_in_one_line_with_status_2_and_no_file(tmp_path, args, message):
    existing = tmp_path / "old.h5"
    existing.write_bytes(b"an earlier result")
    args = [a.format(existing=existing, tmp=tmp_path) for a in args]
    result = gyrolab(*args, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gyrolab: error: "), result.stderr
    assert message.format(existing=existing, tmp=tmp_path) in lines[0]
    assert "Traceback" not in result.stdout + result.stderr
    assert [p.name for p in tmp_path.rglob("*")] == ["old.h5"]
    assert existing.read_bytes() == b"an earlier result"


@pytest.mark.slow
@pytest.mark.parametrize("args", [["--help"], ["runner.dry_run=true", *TINY]], ids=["help", "dry_run"])
def test_a_reader_that_stops_early_ends_gyrolab_quietly(tmp_path, args):
    """gyrolab --help | head -5, gyrolab runner.dry_run=true ... | head -3: stdout closed before gyrolab
    writes; exit 141 (128 + SIGPIPE), nothing on stderr (it was a BrokenPipeError traceback, exit 1)."""
    proc = subprocess.Popen(
        command("gyrolab", "gyrolab.runner.app") + args,
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment(),
    )
    proc.stdout.close()  # the reader is gone before the first line
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == 141, err
    assert err == ""
    assert not list(tmp_path.iterdir())
