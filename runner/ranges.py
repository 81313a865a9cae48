"""Sweep axes as ranges: the OmegaConf resolvers ``linspace``, ``logspace`` and ``range``.

In a config file or on the command line (quoted, so the shell leaves ``$`` alone):

    gyrolab 'sweep.f=${linspace:1,100,100}'        # 1, 2, ..., 100 (num values, both ends included)
    gyrolab 'sweep.dt=${logspace:1e-5,1e-3,3}'     # 1e-5, 1e-4, 1e-3 (the ENDPOINTS, not exponents)
    gyrolab 'sweep.theta0=${range:15,90,15}'       # 15, 30, 45, 60, 75 (stop excluded, integers)

- ``linspace:start,stop,num``: ``num`` >= 1 evenly spaced values from start to stop, both
  included (numpy.linspace; num = 1 gives [start]).
- ``logspace:start,stop,num``: ``num`` values evenly spaced in log from start to stop, both
  included; start and stop are the values themselves (numpy.geomspace), both > 0.
- ``range:start,stop[,step]``: Python's range of integers (stop excluded, step default 1, not 0).

Values are in the axis' units (f in Hz, theta0 in degrees, dt in s) and are rounded to 12
significant digits, so that ``${logspace:1e-5,1e-3,3}`` gives exactly 1e-4 (a dt must divide
output.every).  A bad argument raises ``RangeError`` (one line); the runner reports it as
``sweep.<axis>=<expression>: <reason>`` before any work.
"""

import numpy as np

MAX_VALUES = 10**6  # more values on one axis than any machine could run
SIGNIFICANT = 12


class RangeError(ValueError):
    """A range resolver's arguments are wrong (one-line message)."""


def _number(name, value, what):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RangeError(f"{name}: {what} must be a number, got {value!r}")
    if not np.isfinite(value):
        raise RangeError(f"{name}: {what} must be finite, got {value!r}")
    return value


def _integer(name, value, what):
    _number(name, value, what)
    if float(value) != int(value):
        raise RangeError(f"{name}: {what} must be an integer, got {value!r}")
    return int(value)


def _count(name, num):
    num = _integer(name, num, "num")
    if not 1 <= num <= MAX_VALUES:
        raise RangeError(f"{name}: num must lie in 1..{MAX_VALUES}, got {num}")
    return num


def _rounded(values):
    return [float(f"{v:.{SIGNIFICANT}g}") for v in values]


def _arity(name, args, low, high, usage):
    if not low <= len(args) <= high:
        raise RangeError(f"{name}: takes {usage}, got {len(args)} argument(s)")


def linspace(*args):
    """``num`` evenly spaced values from ``start`` to ``stop``, both included."""
    _arity("linspace", args, 3, 3, "start,stop,num")
    start, stop = (_number("linspace", v, w) for v, w in zip(args[:2], ("start", "stop")))
    return _rounded(np.linspace(start, stop, _count("linspace", args[2])))


def logspace(*args):
    """``num`` values evenly spaced in log from ``start`` to ``stop`` (the endpoints themselves, > 0)."""
    _arity("logspace", args, 3, 3, "start,stop,num")
    start, stop = (_number("logspace", v, w) for v, w in zip(args[:2], ("start", "stop")))
    if not (start > 0 and stop > 0):
        raise RangeError(
            f"logspace: start and stop are the end values, not exponents, and must be > 0; got {start}, {stop}"
        )
    return _rounded(np.geomspace(start, stop, _count("logspace", args[2])))


def int_range(*args):
    """Python's ``range(start, stop[, step])`` as floats."""
    _arity("range", args, 2, 3, "start,stop[,step]")
    start, stop = (_integer("range", v, w) for v, w in zip(args[:2], ("start", "stop")))
    step = _integer("range", args[2], "step") if len(args) == 3 else 1
    if step == 0:
        raise RangeError("range: step must not be 0")
    values = range(start, stop, step)
    if not values:
        raise RangeError(f"range: range({start}, {stop}, {step}) is empty")
    if len(values) > MAX_VALUES:
        raise RangeError(f"range: {len(values)} values; at most {MAX_VALUES}")
    return [float(v) for v in values]


RESOLVERS = {"linspace": linspace, "logspace": logspace, "range": int_range}


def register_resolvers():
    """Register the resolvers with OmegaConf (once; later calls keep them)."""
    from omegaconf import OmegaConf

    for name, function in RESOLVERS.items():
        if not OmegaConf.has_resolver(name):
            OmegaConf.register_new_resolver(name, function)
