"""Numpy arithmetic the engine transcriptions share (tests/test_presets*.py, test_md_lammps_dlpoly.py,
kynema_genalpha.py): quaternions scalar first, R(q) body → lab, and the lab torque of the weight.  Written
out here, apart from gyrolab's kernels, so that a transcription checks a kernel against arithmetic not its own."""

import numpy as np


def qmul(p, q):
    a1, b1, c1, d1 = p
    a2, b2, c2, d2 = q
    return np.array(
        [
            a1 * a2 - b1 * b2 - c1 * c2 - d1 * d2,
            a1 * b2 + b1 * a2 + c1 * d2 - d1 * c2,
            a1 * c2 - b1 * d2 + c1 * a2 + d1 * b2,
            a1 * d2 + b1 * c2 - c1 * b2 + d1 * a2,
        ]
    )


def rot(q):
    """R(q): body → lab."""
    a, b, c, d = q
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
        ]
    )


def lab_torque(q, body):
    """The weight's torque about the pivot in the lab: R c × (−M g ẑ), from M g c = (mgc1, mgc2, mgl)."""
    mg_c = np.array([body.mgc1, body.mgc2, body.mgl])
    return np.cross(rot(q) @ mg_c, [0.0, 0.0, -1.0])
