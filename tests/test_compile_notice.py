"""The warm-up names a kernel that compiles (runner/execute.py _compile_notice): a line while it
compiles and one when done; nothing for a kernel loaded at once from a warm cache."""

import time

from gyrolab.runner.execute import _compile_notice


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
