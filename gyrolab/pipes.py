"""A command whose reader stops early ends quietly.

``gyrolab-verdict FILE | head -3``: when ``head`` has its lines it closes the pipe, and the next write
raises BrokenPipeError.  Every console command stops then with no traceback and exit status
EXIT_BROKEN_PIPE, 141 (128 + SIGPIPE: what a shell reports for a program a closed pipe stopped, as
runner/signals.py exits 128 + the signal number after a signal).
"""

import functools
import os
import signal
import sys

EXIT_BROKEN_PIPE = 128 + getattr(signal, "SIGPIPE", 13)


def stop_on_broken_pipe():
    """Exit with EXIT_BROKEN_PIPE, stdout pointed at /dev/null: nothing writes to the closed pipe again
    (the interpreter's last flush would print an 'Exception ignored' trace)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    sys.exit(EXIT_BROKEN_PIPE)


def quiet_on_broken_pipe(main):
    """``main`` (a console entry point) that stops quietly, ``stop_on_broken_pipe``, when its reader
    closes stdout; its return value and other exceptions pass through."""

    @functools.wraps(main)
    def wrapped(*args, **kwargs):
        try:
            try:
                return main(*args, **kwargs)
            finally:  # what is still buffered fails here, not in the interpreter's exit
                sys.stdout.flush()
        except BrokenPipeError:
            stop_on_broken_pipe()

    return wrapped
