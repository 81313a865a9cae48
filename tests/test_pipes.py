"""Every console command ends quietly when its reader closes stdout (``gyrolab-verdict FILE | head``):
exit 141, no traceback (gyrolab/pipes.py)."""

import subprocess
import sys
from importlib.metadata import entry_points

from gyrolab.pipes import EXIT_BROKEN_PIPE, quiet_on_broken_pipe

LOUD = """
from gyrolab.pipes import quiet_on_broken_pipe

@quiet_on_broken_pipe
def main():
    for k in range(200000):
        print(f"line {k} " + "x" * 60)
    return 0

raise SystemExit(main())
"""


def _closed_early(code):
    """(exit status, stderr) of ``python -c code`` whose reader takes one line and closes the pipe."""
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    return proc.wait(timeout=60), err


def test_a_reader_that_closes_the_pipe_stops_the_command_quietly():
    status, err = _closed_early(LOUD)
    assert status == EXIT_BROKEN_PIPE == 141 and err == "", err
    # without the wrapper: the traceback this replaces
    status, err = _closed_early(LOUD.replace("@quiet_on_broken_pipe\n", ""))
    assert status != 0 and "BrokenPipeError" in err


def test_the_wrapper_passes_results_and_other_errors_through():
    assert quiet_on_broken_pipe(lambda x: x + 1)(1) == 2

    def fails():
        raise ValueError("not a pipe")

    try:
        quiet_on_broken_pipe(fails)()
    except ValueError as err:
        assert str(err) == "not a pipe"
    else:
        raise AssertionError("ValueError swallowed")


def test_every_console_command_is_wrapped():
    """The installed console scripts (pyproject.toml [project.scripts]): each main is the wrapped one."""
    scripts = [ep for ep in entry_points(group="console_scripts") if ep.value.startswith("gyrolab.")]
    assert len(scripts) >= 7, scripts
    for ep in scripts:
        assert getattr(ep.load(), "__wrapped__", None) is not None, f"{ep.name} ({ep.value}): not wrapped"
