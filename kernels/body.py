"""The body record every kernel and the runner share: one definition, extended here only.

``Body(I1, I2, I3, mgl, mgc1, mgc2)``: principal moments of inertia (kg m²)
about the pivot (about the centre of mass for a free body) and the weight M g
times the body coordinates (c1, c2, c3) of the centre of mass (N m):
``mgl`` = M g c3 (for the symmetric top, M g l: the name it has had since the
centre of mass could only sit on e3), ``mgc1`` = M g c1, ``mgc2`` = M g c2.
All three zero is a free body and skips the gravity torque; mgc1 = mgc2 = 0
is the top with its centre of mass on e3.  ``Body(I1, I2, I3, mgl)`` still
builds that top (the last two default to 0).  A namedtuple of floats, so
numba keeps it in registers exactly as a plain tuple (same machine code, same
bits) while kernels may read fields by name.

The runner stores bodies as float64 arrays whose last axis is ``FIELDS``;
results files carry that axis as the ``body_param`` coordinate.
"""

from collections import namedtuple

from numba import njit

Body = namedtuple("Body", ["I1", "I2", "I3", "mgl", "mgc1", "mgc2"], defaults=(0.0, 0.0))
FIELDS = Body._fields
N_FIELDS = len(FIELDS)
UNITS = {"I1": "kg m2", "I2": "kg m2", "I3": "kg m2", "mgl": "N m", "mgc1": "N m", "mgc2": "N m"}


@njit(cache=True, error_model="numpy")
def body_row(bodies, i):
    """Row i of a (n, N_FIELDS) body array as a Body."""
    return Body(bodies[i, 0], bodies[i, 1], bodies[i, 2], bodies[i, 3], bodies[i, 4], bodies[i, 5])


@njit(cache=True, error_model="numpy")
def body_lane(B, j):
    """Column j of a structure-of-arrays (N_FIELDS, n) body block as a Body."""
    return Body(B[0, j], B[1, j], B[2, j], B[3, j], B[4, j], B[5, j])


@njit(cache=True, error_model="numpy")
def body_lane_symmetric_top(B, j, I1):
    """``body_lane(B, j)`` of a body with I1 = I2 and its centre of mass on e3, I1 given and
    mgc1 = mgc2 = 0.0 as constants (block.py's symmetric pass: LLVM folds the branches on them)."""
    return Body(I1, I1, B[2, j], B[3, j], 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def body_lane_free(B, j):
    """``body_lane(B, j)`` of a free body, with mgl = mgc1 = mgc2 = 0.0 as constants (block.py's FREE pass)."""
    return Body(B[0, j], B[1, j], B[2, j], 0.0, 0.0, 0.0)
