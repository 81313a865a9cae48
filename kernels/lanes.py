"""A method's ``step`` recompiled for the vectorised loop over runs ("lanes").

``lane_step(step)`` compiles the same Python source as ``step`` and every
numba function it calls, with three changes and nothing else:

- ``error_model="numpy"``: a float division does not test its divisor for zero
  (Python's ZeroDivisionError check is a branch out of the loop that stops
  LLVM from vectorising it); the quotient itself is the same IEEE division;
- ``forceinline=True`` (LLVM's alwaysinline): the whole step is inlined into
  the loop over lanes (numba's own ``inline="always"`` does the same on its
  IR, but takes ~100 s for lie_poisson4's ~140 nested calls);
- ``quat_from_rotvec`` and ``half_angle``, the two helpers that branch between
  the small-angle series, its longer form (from SMALL_ANGLE) and libm (from
  WIDE_ANGLE), take the series and return NaN where the original would not
  (angle ≥ SMALL_ANGLE or NaN).  ``lane_step(step, wide=True)`` takes the series or
  its longer form (the last coefficients selected), NaN only where the original
  calls libm: a few more operations a rotation, for blocks whose lanes turn by
  more (block.py).

So on every lane where the result is finite it is bit for bit what ``step``
returns (same operations in the same order; numba never contracts a·b + c
into an FMA without fastmath).  A lane whose result is not finite (a large
rotation, or a run that is itself blowing up) is recomputed by the caller
with ``ieee_step(step)``.  Helpers must be called by their bare name (as
the kernels do), not as ``module.function``, to be recompiled.

``ieee_step(step)`` makes only the first change (and the second with
``inline=True``): bit for bit ``step``, except that where ``step`` would raise
ZeroDivisionError (a quaternion whose norm overflowed to inf and was scaled
to 0) it returns inf/NaN, which the drivers record as a non-finite run.
Inside a numba ``prange`` such an exception is lost, and the run would come
back half-written with status "ok".  Inlined into the loop over lanes it
vectorises too, the libm calls done one lane at a time: ~3x the cost of
``lane_step`` at small angles, but no lane needs redoing at large ones.
"""

import math
import types

from numba import njit
from numba.core.dispatcher import Dispatcher

from . import rotation
from .rotation import SMALL_ANGLE, WIDE_ANGLE, WIDE_SERIES, _cos_sinc_half, cos_sinc_series

_SMALL_ANGLE2 = SMALL_ANGLE * SMALL_ANGLE
_WIDE_ANGLE2 = WIDE_ANGLE * WIDE_ANGLE


@njit
def _quat_from_rotvec_or_nan(v0, v1, v2):
    """rotation.quat_from_rotvec's series branch; a = NaN where it would take another."""
    angle2 = v0 * v0 + v1 * v1 + v2 * v2
    a, s = _cos_sinc_half(angle2)
    if not angle2 < _SMALL_ANGLE2:
        a = math.nan
    return a, s * v0, s * v1, s * v2


@njit
def _half_angle_or_nan(phi):
    """rotation.half_angle's series branch; cos(φ/2) = NaN where it would take another."""
    phi2 = phi * phi
    c, s = _cos_sinc_half(phi2)
    if not phi2 < _SMALL_ANGLE2:
        c = math.nan
    return c, s * phi


@njit
def _cos_sinc_half_or_nan(angle2):
    """rotation's _cos_sinc_half below SMALL_ANGLE², _cos_sinc_half_wide up to WIDE_ANGLE², cos = NaN beyond
    (or for NaN); one polynomial, no branch: rotation.cos_sinc_series with its last coefficients selected
    to 0 below SMALL_ANGLE², where it has _cos_sinc_half's own operations and bits."""
    c10, c12, c14, s10, s12 = (0.0, 0.0, 0.0, 0.0, 0.0) if angle2 < _SMALL_ANGLE2 else WIDE_SERIES
    c, s = cos_sinc_series(0.25 * angle2, c10, c12, c14, s10, s12)
    if not angle2 < _WIDE_ANGLE2:
        c = math.nan
    return c, s


@njit
def _quat_from_rotvec_wide_or_nan(v0, v1, v2):
    """rotation.quat_from_rotvec's two polynomial branches; a = NaN where it would call libm."""
    angle2 = v0 * v0 + v1 * v1 + v2 * v2
    a, s = _cos_sinc_half_or_nan(angle2)
    return a, s * v0, s * v1, s * v2


@njit
def _half_angle_wide_or_nan(phi):
    """rotation.half_angle's two polynomial branches; cos(φ/2) = NaN where it would call libm."""
    c, s = _cos_sinc_half_or_nan(phi * phi)
    return c, s * phi


_REPLACED = {rotation.quat_from_rotvec: _quat_from_rotvec_or_nan, rotation.half_angle: _half_angle_or_nan}
_REPLACED_WIDE = {
    rotation.quat_from_rotvec: _quat_from_rotvec_wide_or_nan,
    rotation.half_angle: _half_angle_wide_or_nan,
}


def lane_step(step, wide=False):
    """njit ``(w, q, dt, body) -> (w, q)``: ``step`` recompiled as described above (``wide``: the
    longer series too, NaN only from WIDE_ANGLE); non-finite output means "recompute this lane
    with ``ieee_step(step)``"."""
    return _recompile(step, {}, _REPLACED_WIDE if wide else _REPLACED, {"forceinline": True})


def ieee_step(step, inline=False):
    """njit ``(w, q, dt, body) -> (w, q)``: ``step`` with IEEE division (no ZeroDivisionError)."""
    return _recompile(step, {}, {}, {"forceinline": True} if inline else {})


def has_series(step):
    """Whether ``step`` calls (at any depth) a helper that ``lane_step`` replaces.  If not,
    ``lane_step(step)``, ``lane_step(step, wide=True)`` and ``ieee_step(step, inline=True)`` are one
    function (the same source with the same options), so a block kernel needs only the one pass: a lane
    it leaves non-finite is a run that blows up, for ``ieee_step`` to redo (block.py)."""
    return _reaches(step, set(_REPLACED), set())


def _reaches(dispatcher, targets, seen):
    """Whether ``dispatcher`` is in ``targets`` or calls one of them, following the same globals and
    closure cells as ``_recompile``."""
    if dispatcher in targets:
        return True
    if dispatcher in seen:
        return False
    seen.add(dispatcher)
    func = dispatcher.py_func
    callees = [func.__globals__.get(name) for name in func.__code__.co_names]
    callees += [cell.cell_contents for cell in func.__closure__ or ()]
    return any(isinstance(c, Dispatcher) and _reaches(c, targets, seen) for c in callees)


def _recompile(dispatcher, done, replaced, options):
    """A fresh dispatcher of ``dispatcher``'s source, error_model="numpy", whose calls to
    other numba functions go to their recompiled copies (or to ``replaced[original]``)."""
    dispatcher = replaced.get(dispatcher, dispatcher)
    if dispatcher not in done:
        func = dispatcher.py_func
        names = dict(func.__globals__)
        for name in func.__code__.co_names:
            if isinstance(names.get(name), Dispatcher):
                names[name] = _recompile(names[name], done, replaced, options)
        cells = func.__closure__
        if cells:
            cells = tuple(
                types.CellType(_recompile(c.cell_contents, done, replaced, options))
                if isinstance(c.cell_contents, Dispatcher)
                else c
                for c in cells
            )
        copy = types.FunctionType(func.__code__, names, func.__name__, func.__defaults__, cells)
        done[dispatcher] = njit(error_model="numpy", **options)(copy)
    return done[dispatcher]
