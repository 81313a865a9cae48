"""gyrolab-compile (runner/compile.py): methods' kernels compiled in worker processes into the cache that
sweeps and tests load from; only what the cache lacks; bad input refused in one line."""

import subprocess
import sys

import pytest

from helpers import _default_signals, command, environment


def compile_cli(*args, cache):
    # cwd is the cache's parent, not the checkout: from the checkout root, ``python -m``/``-c`` would import the
    # checkout's sources (gyrolab/__init__.py joins them) while the console script imports the installed package,
    # and numba keys its cache by source path, so the two would never share kernels under a non-editable install
    return subprocess.run(
        command("gyrolab-compile", "gyrolab.runner.compile") + list(args),
        cwd=cache.parent,
        capture_output=True,
        text=True,
        env=environment(NUMBA_CACHE_DIR=cache),
        timeout=900,
    )


def cached_files(cache):
    return sorted(p.name for p in cache.rglob("*") if p.suffix in (".nbi", ".nbc"))


@pytest.mark.slow
def test_unknown_method_and_bad_jobs_are_one_line(tmp_path):
    for args in (["no_such_method"], ["--jobs", "0", "rk4"]):
        result = compile_cli(*args, cache=tmp_path / "cache")
        assert result.returncode == 2, result
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not (tmp_path / "cache").exists() or not cached_files(tmp_path / "cache")


@pytest.mark.slow
def test_compiles_what_the_cache_lacks_and_a_sweep_process_then_loads_it(tmp_path):
    """no_gyro's run and block kernels compile in a worker into an empty cache; a second call finds them;
    a fresh process finds them cached and integrates no_gyro on both paths."""
    cache = tmp_path / "cache"
    first = compile_cli("no_gyro", "--jobs", "1", cache=cache)
    assert first.returncode == 0, first.stderr
    assert "no_gyro (runs, blocks) in" in first.stdout
    filled = cached_files(cache)
    assert any(name.endswith(".nbc") for name in filled)
    again = compile_cli("no_gyro", cache=cache)
    assert again.returncode == 0 and "all cached" in again.stdout, again
    load = (
        "from gyrolab.runner.compile import cold_kernels, compile_one; "
        "print(cold_kernels(['no_gyro'])); compile_one('no_gyro', ['runs', 'blocks'])"
    )
    loaded = subprocess.run(
        [sys.executable, "-c", load],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=environment(NUMBA_CACHE_DIR=cache),
    )
    assert loaded.returncode == 0, loaded.stderr
    assert loaded.stdout.strip() == "{}"  # a fresh process finds both kernels in the cache: it loads them


def _compilers_of(cache):
    """PIDs of live processes whose environment names ``cache`` as their NUMBA_CACHE_DIR (Linux /proc)."""
    import os

    mark = f"NUMBA_CACHE_DIR={cache}".encode()
    pids = []
    for name in os.listdir("/proc"):
        try:
            with open(f"/proc/{name}/environ", "rb") as f:
                if mark in f.read().split(b"\0"):
                    pids.append(int(name))
        except (OSError, ValueError):
            continue
    return pids


def _sigint_held_off(pid):
    """Whether process ``pid`` blocks or ignores SIGINT (Linux /proc: SigBlk and SigIgn bit masks); True for a
    process that has exited meanwhile."""
    try:
        with open(f"/proc/{pid}/status") as f:
            masks = dict(line.split(":\t", 1) for line in f if line.startswith(("SigBlk", "SigIgn")))
    except OSError:
        return True
    return any(int(masks[key], 16) >> (2 - 1) & 1 for key in ("SigBlk", "SigIgn"))  # SIGINT is signal 2


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_cold_sweep_compiles_its_kernels_in_parallel_and_ctrl_c_stops_the_compilers(tmp_path):
    """runner/execute.py warm_up: two or more cold kernels compile in worker processes, one per core and
    method, only the paths the sweep runs; a Ctrl-C to the terminal's process group during that compile
    is answered in one line and exit 130 within seconds, and leaves no compiler running."""
    import os
    import signal
    import time

    from gyrolab.runner.compile import compile_jobs

    if compile_jobs() < 2:
        pytest.skip("one core: the warm-up compiles in its own process")
    cache = tmp_path / "cache"
    sweep = ["sweep.f=[10]", "sweep.dt=[1e-3]", "sweep.t_end=0.01", "output.figures=false"]
    done = subprocess.run(
        command("gyrolab", "gyrolab.runner.app") + ["sweep.method=[no_gyro,explicit_euler]", *sweep],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=environment(NUMBA_CACHE_DIR=cache),
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "gyrolab: compiling 2 kernels of 2 methods, 2 at a time ..." in done.stdout
    assert "compiled no_gyro (runs) in" in done.stdout and "compiled explicit_euler (runs) in" in done.stdout
    assert "blocks" not in done.stdout  # 1 run per method: no block kernel is compiled
    # strang_exact4's run kernel takes ~25 s to compile: interrupt while it does
    slow = subprocess.Popen(
        command("gyrolab", "gyrolab.runner.app") + ["sweep.method=[strang_exact4,strang_exact]", *sweep],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment(NUMBA_CACHE_DIR=cache),
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=_default_signals,  # SIGINT not ignored, even where this test runs with it ignored (CI)
    )
    deadline = time.monotonic() + 120
    while len(_compilers_of(cache)) < 3 and time.monotonic() < deadline:  # gyrolab and its compilers
        time.sleep(0.2)
    assert len(_compilers_of(cache)) >= 3, "the compile workers never started"
    for pid in set(_compilers_of(cache)) - {slow.pid}:  # every worker holds SIGINT off from its first instruction
        assert _sigint_held_off(pid), pid
    time.sleep(1.0)
    os.killpg(slow.pid, signal.SIGINT)
    start = time.monotonic()
    out, err = slow.communicate(timeout=60)
    assert slow.returncode == 130, (out, err)
    assert time.monotonic() - start < 10
    assert "Traceback" not in err and err.strip().splitlines()[0].startswith("gyrolab: interrupted"), err
    time.sleep(0.5)
    assert _compilers_of(cache) == []
