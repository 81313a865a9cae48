"""Signals during a sweep: SIGTERM and SIGHUP interrupt like Ctrl-C, and an interrupt swallowed by a
finalizer is raised again where the sweep commits work (runner/sweep.py)."""

import signal
import sys

EXIT_FAILED = 1  # an I/O or backend error during the sweep; an interrupt exits 128 + the signal number
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread like Ctrl-C's KeyboardInterrupt."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


# Signals received, in order.  The exception a handler raises can land inside a finalizer (a weakref
# callback), where Python prints "Exception ignored" and carries on: the sweep would then finish as if
# never signalled.  raise_pending() raises it again at the points where a sweep commits work.
_PENDING = []


def _raise_interrupted(signum, frame):
    _PENDING.append(signum)
    raise Interrupted(signum)


def _raise_keyboard_interrupt(signum, frame):
    _PENDING.append(signum)
    raise KeyboardInterrupt


def raise_pending():
    """Raise the interrupt of a signal whose exception was swallowed; nothing when none came."""
    if _PENDING:
        raise KeyboardInterrupt if _PENDING[0] == signal.SIGINT else Interrupted(_PENDING[0])


def quiet_swallowed_interrupts(previous):
    """A sys.unraisablehook that drops an interrupt swallowed by a finalizer and passes anything else
    to ``previous``: the interrupt is recorded in _PENDING and raised again by raise_pending, so
    Python's "Exception ignored ... Traceback" would only break the sweep's one-line message."""

    def hook(unraisable):
        if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and _PENDING):
            previous(unraisable)

    hook.quiets_interrupts = True
    return hook


def handle_signals():
    """SIGTERM and SIGHUP interrupt like Ctrl-C (KeyboardInterrupt); every one is also recorded for
    raise_pending.  SIGINT keeps Python's meaning, and stays ignored where it was ignored at start."""
    if not getattr(sys.unraisablehook, "quiets_interrupts", False):
        sys.unraisablehook = quiet_swallowed_interrupts(sys.unraisablehook)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_interrupted)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _raise_keyboard_interrupt)


def ignore_signals():
    """While cleaning up after the first signal: a second one must not cut the clean-up short."""
    for sig in HANDLED_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def exit_status(interrupt):
    """128 + the signal number of a KeyboardInterrupt (SIGINT) or Interrupted."""
    return 128 + getattr(interrupt, "signum", signal.SIGINT)


def signal_name(interrupt):
    return signal.Signals(getattr(interrupt, "signum", signal.SIGINT)).name
