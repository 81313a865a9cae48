"""The body record every kernel and the runner share: one definition, extended here only.

``Body(I1, I2, I3, mgl, mgc1, mgc2, tau1, tau2, tau3, drive_rate, drive_on, drive_off)``:

- principal moments of inertia (kg m²) about the pivot (about the centre of
  mass for a free body);
- the weight M g times the body coordinates (c1, c2, c3) of the centre of
  mass (N m): ``mgl`` = M g c3 (for the symmetric top, M g l: the name it has
  had since the centre of mass could only sit on e3), ``mgc1`` = M g c1,
  ``mgc2`` = M g c2.  All three zero is a free body and skips the gravity
  torque; mgc1 = mgc2 = 0 is the top with its centre of mass on e3;
- a driving torque fixed in the body that depends on time only,
  τ(t) = (tau1, tau2, tau3) sin²(drive_rate t) (N m, body frame, drive_rate in
  rad/s) on the steps whose midpoint lies in [drive_on, drive_off] (s), zero on
  the others (``rigid_body.drive_torque``, driver.make_advance_driven;
  Hairer–Nørsett–Wanner's EULR problem and SciMLBenchmarks' rigid body).
  All of tau zero is no drive; a body with a drive is integrated only by
  methods that see time (``step_driven``, methods/README.md), never by the
  others.

``Body(I1, I2, I3, mgl)`` still builds the top with its centre of mass on e3
(the rest default to 0).  A namedtuple of floats, so
numba keeps it in registers exactly as a plain tuple (same machine code, same
bits) while kernels may read fields by name.

The runner stores bodies as float64 arrays whose last axis is ``FIELDS``;
results files carry that axis as the ``body_param`` coordinate.
"""

from collections import namedtuple

import numpy as np
from numba import njit

Body = namedtuple(
    "Body",
    ["I1", "I2", "I3", "mgl", "mgc1", "mgc2", "tau1", "tau2", "tau3", "drive_rate", "drive_on", "drive_off"],
    defaults=(0.0,) * 8,
)
FIELDS = Body._fields
N_FIELDS = len(FIELDS)
UNITS = {
    "I1": "kg m2",
    "I2": "kg m2",
    "I3": "kg m2",
    "mgl": "N m",
    "mgc1": "N m",
    "mgc2": "N m",
    "tau1": "N m",
    "tau2": "N m",
    "tau3": "N m",
    "drive_rate": "rad s-1",
    "drive_on": "s",
    "drive_off": "s",
}
# Columns of the driving torque's amplitude: a body array with any of them non-zero is driven.
DRIVE = slice(FIELDS.index("tau1"), FIELDS.index("tau3") + 1)


def is_driven(bodies):
    """Whether any body (rows of FIELDS, any leading shape) has a driving torque."""
    return bool(np.any(np.asarray(bodies, dtype=float)[..., DRIVE] != 0.0))


@njit(cache=True, error_model="numpy")
def body_row(bodies, i):
    """Row i of a (n, N_FIELDS) body array as a Body."""
    return Body(
        bodies[i, 0],
        bodies[i, 1],
        bodies[i, 2],
        bodies[i, 3],
        bodies[i, 4],
        bodies[i, 5],
        bodies[i, 6],
        bodies[i, 7],
        bodies[i, 8],
        bodies[i, 9],
        bodies[i, 10],
        bodies[i, 11],
    )


@njit(cache=True, error_model="numpy")
def body_lane(B, j):
    """Column j of a structure-of-arrays (N_FIELDS, n) body block as a Body without a drive (the block
    path never runs a driven body: batch.integrate sends those to ``run_batch_driven``)."""
    return Body(B[0, j], B[1, j], B[2, j], B[3, j], B[4, j], B[5, j], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def body_lane_symmetric_top(B, j, I1):
    """``body_lane(B, j)`` of a body with I1 = I2 and its centre of mass on e3, I1 given and
    mgc1 = mgc2 = 0.0 as constants (block.py's symmetric pass: LLVM folds the branches on them)."""
    return Body(I1, I1, B[2, j], B[3, j], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def body_lane_free(B, j):
    """``body_lane(B, j)`` of a free body, with mgl = mgc1 = mgc2 = 0.0 as constants (block.py's FREE pass)."""
    return Body(B[0, j], B[1, j], B[2, j], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def without_drive(body):
    """``body`` with the drive's amplitude (tau1, tau2, tau3) as constants 0.0: what ``step`` integrates
    (methods/README.md).  LLVM then folds rigid_body.torque_at's branch on the drive, so a step made
    from ``step_driven`` costs an undriven run nothing and never reads t."""
    return Body(body[0], body[1], body[2], body[3], body[4], body[5], 0.0, 0.0, 0.0, body[9], body[10], body[11])
