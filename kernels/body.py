"""The body record every kernel and the runner share: one definition, extended here only.

``Body(I1, I2, I3, mgl)``: principal moments of inertia (kg m²) about the
pivot (about the centre of mass for a free body) and M g l (N m), the weight
times the distance from the pivot to the centre of mass, which sits on body
e3; mgl = 0 is a free body and skips the gravity torque.  A namedtuple of
floats, so numba keeps it in registers exactly as a plain tuple (same
machine code, same bits) while kernels may read fields by name.

The runner stores bodies as float64 arrays whose last axis is ``FIELDS``;
results files carry that axis as the ``body_param`` coordinate.
"""

from collections import namedtuple

from numba import njit

Body = namedtuple("Body", ["I1", "I2", "I3", "mgl"])
FIELDS = Body._fields
N_FIELDS = len(FIELDS)
UNITS = {"I1": "kg m2", "I2": "kg m2", "I3": "kg m2", "mgl": "N m"}


@njit(cache=True, error_model="numpy")
def body_row(bodies, i):
    """Row i of a (n, N_FIELDS) body array as a Body."""
    return Body(bodies[i, 0], bodies[i, 1], bodies[i, 2], bodies[i, 3])


@njit(cache=True, error_model="numpy")
def body_lane(B, j):
    """Column j of a structure-of-arrays (N_FIELDS, n) body block as a Body."""
    return Body(B[0, j], B[1, j], B[2, j], B[3, j])


@njit(cache=True, error_model="numpy")
def body_lane_with_moments(B, j, I1, I2):
    """``body_lane(B, j)`` with I1 and I2 replaced (block.py's symmetric pass)."""
    return Body(I1, I2, B[2, j], B[3, j])
