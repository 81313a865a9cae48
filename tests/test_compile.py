"""gyrolab-compile (runner/compile.py): methods' kernels compiled in worker processes into the cache that
sweeps and tests load from; only what the cache lacks; bad input refused in one line."""

import subprocess
import sys

import pytest

from helpers import command, environment


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
