"""The warm-up names a kernel that compiles (runner/execute.py _compile_notice): a line while it
compiles and one when done; nothing for a kernel loaded at once from a warm cache."""

import time

import pytest

from gyrolab.runner.execute import _compile_notice


@pytest.mark.slow
def test_a_long_warm_up_is_named_while_it_lasts_and_when_done(capsys):
    with _compile_notice("block kernels of lie_poisson4 (3/5)", after=0.01):
        time.sleep(1.0)  # a hundred times the notice's delay: the line is printed inside the block
        during = capsys.readouterr().out
    after = capsys.readouterr().out
    assert during == "gyrolab: compiling block kernels of lie_poisson4 (3/5) ...\n"
    assert after.startswith("gyrolab: compiled block kernels of lie_poisson4 (3/5) in ")


def test_a_quick_warm_up_prints_nothing(capsys):
    with _compile_notice("run kernels of rk4 (1/1)", after=60.0):
        pass
    time.sleep(0.05)
    assert capsys.readouterr().out == ""


def test_a_kernel_in_the_cache_is_said_to_load_not_to_compile(capsys, monkeypatch):
    """A large cached kernel can take longer than the notice's delay to load on a busy machine: the
    screen then says 'loading ... from the numba cache', and 'compiling' only for a cold kernel."""
    import numpy as np

    from gyrolab.runner import execute

    monkeypatch.setattr(execute, "COMPILE_NOTICE_SECONDS", 0.01)
    monkeypatch.setattr(execute, "integrate", lambda *args, **kwargs: time.sleep(0.3))
    inputs = (np.zeros((1, 12)), np.zeros((1, 3)), np.zeros((1, 4)), np.ones(1), None)
    for cached, words in ((True, ("loading", "loaded")), (False, ("compiling", "compiled"))):
        monkeypatch.setattr(execute, "kernel_cached", lambda method, path, cached=cached: cached)
        execute.warm_up_methods(["rk4"], inputs, 10.0)
        lines = capsys.readouterr().out.splitlines()
        where = " from the numba cache" if cached else ""
        assert lines[0] == f"gyrolab: {words[0]} run kernels of rk4 (1/1){where} ...", lines
        assert lines[1].startswith(f"gyrolab: {words[1]} run kernels of rk4 (1/1){where} in "), lines
