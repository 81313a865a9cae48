"""Rotations as Cayley–Klein parameters (unit quaternions), allocation-free.

Orientation is the unit quaternion q = (a, b, c, d) whose rotation matrix
R(q) is the write-up's CK matrix: its columns are the body axes in lab
coordinates, v_lab = R v_body.  Composing R(t) · Rot(v) is the quaternion
product q(t) ⊗ q_v, so the seed's product of CK matrices is carried exactly
without building any 3×3 matrix in the hot loop.

All functions take and return tuples of floats so numba keeps them in
registers.
"""

import math

import numpy as np
from numba import njit

# Below this rotation angle |v| (rad), i.e. h = |v|/2 < 0.1, the Taylor series of
# cos(h) and sin(h)/h through h^8 are faithfully rounded (< 1 ulp, 0.75 ulp at
# worst; tests/test_small_angle.py): the first dropped terms, h^10/10! and
# h^10/11!, are < 3e-17.  A step of any sensible dt turns the body by far less
# than this, so the hot loop needs no libm call.
SMALL_ANGLE = 0.2
# Below this angle (and from SMALL_ANGLE up) the same Taylor series is taken further, through h^14 (cos)
# and h^12 (sin(h)/h) (``_cos_sinc_half_wide``): faithfully rounded (0.58 and 0.55 ulp at worst,
# tests/test_small_angle.py), still no libm, so that the substeps of a splitting at a coarse dt
# (lie_poisson4 at dt = 1e-3 s on the 50 Hz top turns up to ~0.5 rad a substep) stay on the
# vectorised path of the block kernels (kernels/lanes.py).
WIDE_ANGLE = 0.8
# The Taylor coefficients the wide series adds: h^10, h^12, h^14 of cos h and h^10, h^12 of sin(h)/(2h).
WIDE_SERIES = (-1.0 / 3628800, 1.0 / 479001600, -1.0 / 87178291200, -1.0 / 79833600, 1.0 / 12454041600)


@njit(cache=True, error_model="numpy")
def _cos_sinc_half(angle2):
    """(cos(h), sin(h)/(2h)) with h = √angle2 / 2, for angle2 < SMALL_ANGLE² (Taylor, exact)."""
    h2 = 0.25 * angle2
    c = 1.0 + h2 * (-1.0 / 2 + h2 * (1.0 / 24 + h2 * (-1.0 / 720 + h2 * (1.0 / 40320))))
    s = 0.5 + h2 * (-1.0 / 12 + h2 * (1.0 / 240 + h2 * (-1.0 / 10080 + h2 * (1.0 / 725760))))
    return c, s


@njit(cache=True, error_model="numpy")
def _cos_sinc_half_wide(angle2):
    """(cos(h), sin(h)/(2h)) with h = √angle2 / 2, for angle2 < WIDE_ANGLE² (h² < 0.16): ``_cos_sinc_half``'s
    series three terms (cos) and two terms (sinc) longer (``cos_sinc_series`` with WIDE_SERIES).  The first
    dropped terms, h^16/16! and h^14/(2·15!), are < 3e-20 and < 1.1e-18."""
    c10, c12, c14, s10, s12 = WIDE_SERIES
    return cos_sinc_series(0.25 * angle2, c10, c12, c14, s10, s12)


@njit(cache=True, error_model="numpy")
def cos_sinc_series(h2, c10, c12, c14, s10, s12):
    """(cos(h), sin(h)/(2h)) from h² by Horner's rule, with the coefficients of h^10, h^12, h^14 (cos) and
    h^10, h^12 (sin(h)/(2h)) given: the Taylor ones for ``_cos_sinc_half_wide``, or 0, which leaves
    ``_cos_sinc_half``'s operations and bits (h2·(0 + h2·(0 + h2·0)) = +0 for h2 ≥ 0, and 1/40320 + 0 is
    1/40320).  Its first four levels are _cos_sinc_half's, so kernels/lanes.py evaluates both series as
    one polynomial with the last coefficients selected, without a branch."""
    c = c12 + h2 * c14
    c = 1.0 / 40320 + h2 * (c10 + h2 * c)
    c = 1.0 + h2 * (-1.0 / 2 + h2 * (1.0 / 24 + h2 * (-1.0 / 720 + h2 * c)))
    s = 1.0 / 725760 + h2 * (s10 + h2 * s12)
    s = 0.5 + h2 * (-1.0 / 12 + h2 * (1.0 / 240 + h2 * (-1.0 / 10080 + h2 * s)))
    return c, s


@njit(cache=True, error_model="numpy")
def quat_from_rotvec(v0, v1, v2):
    """CK parameters of the active rotation by |v| (rad) about v/|v|.

    a = cos(|v|/2), (b, c, d) = v̂ sin(|v|/2); exact for any angle.
    """
    angle2 = v0 * v0 + v1 * v1 + v2 * v2
    if angle2 < SMALL_ANGLE * SMALL_ANGLE:
        a, s = _cos_sinc_half(angle2)  # s = sin(|v|/2)/|v|
    elif angle2 < WIDE_ANGLE * WIDE_ANGLE:
        a, s = _cos_sinc_half_wide(angle2)
    else:
        angle = math.sqrt(angle2)
        a = math.cos(0.5 * angle)
        s = math.sin(0.5 * angle) / angle
    return a, s * v0, s * v1, s * v2


@njit(cache=True, error_model="numpy")
def half_angle(phi):
    """(cos(φ/2), sin(φ/2)) for a signed angle φ (rad), without libm when |φ| is small."""
    phi2 = phi * phi  # the branches test φ² as quat_from_rotvec does (and kernels/lanes.py's copy)
    if phi2 < SMALL_ANGLE * SMALL_ANGLE:
        c, s = _cos_sinc_half(phi2)
        return c, s * phi
    if phi2 < WIDE_ANGLE * WIDE_ANGLE:
        c, s = _cos_sinc_half_wide(phi2)
        return c, s * phi
    return math.cos(0.5 * phi), math.sin(0.5 * phi)


@njit(cache=True, error_model="numpy")
def quat_mul(p, q):
    """Hamilton product p ⊗ q, so that R(p ⊗ q) = R(p) R(q)."""
    pa, pb, pc, pd = p
    qa, qb, qc, qd = q
    return (
        pa * qa - pb * qb - pc * qc - pd * qd,
        pa * qb + pb * qa + pc * qd - pd * qc,
        pa * qc - pb * qd + pc * qa + pd * qb,
        pa * qd + pb * qc - pc * qb + pd * qa,
    )


@njit(cache=True, error_model="numpy")
def quat_normalize(q):
    a, b, c, d = q
    inv = 1.0 / math.sqrt(a * a + b * b + c * c + d * d)
    return a * inv, b * inv, c * inv, d * inv


@njit(cache=True, error_model="numpy")
def rotate_body_step(q, v0, v1, v2):
    """q ⊗ q_v: the orientation after rotating the body by v (body frame, rad)."""
    return quat_mul(q, quat_from_rotvec(v0, v1, v2))


@njit(cache=True, error_model="numpy")
def lab_up_in_body(q):
    """γ = Rᵀ ẑ: the lab's up direction in body coordinates (third row of R)."""
    a, b, c, d = q
    return (
        2.0 * (b * d - a * c),
        2.0 * (c * d + a * b),
        a * a + d * d - b * b - c * c,
    )


@njit(cache=True, error_model="numpy")
def body_to_lab(q, v0, v1, v2):
    """R v: a body-frame vector in lab coordinates."""
    a, b, c, d = q
    r00 = a * a + b * b - c * c - d * d
    r01 = 2.0 * (b * c - a * d)
    r02 = 2.0 * (b * d + a * c)
    r10 = 2.0 * (b * c + a * d)
    r11 = a * a + c * c - b * b - d * d
    r12 = 2.0 * (c * d - a * b)
    r20 = 2.0 * (b * d - a * c)
    r21 = 2.0 * (c * d + a * b)
    r22 = a * a + d * d - b * b - c * c
    return (
        r00 * v0 + r01 * v1 + r02 * v2,
        r10 * v0 + r11 * v1 + r12 * v2,
        r20 * v0 + r21 * v1 + r22 * v2,
    )


@njit(cache=True, error_model="numpy")
def ck_matrix(q):
    """The write-up's CK rotation matrix R(q) as a 3×3 array (tests, not hot loops)."""
    a, b, c, d = q
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2.0 * (b * c - a * d), 2.0 * (b * d + a * c)],
            [2.0 * (b * c + a * d), a * a + c * c - b * b - d * d, 2.0 * (c * d - a * b)],
            [2.0 * (b * d - a * c), 2.0 * (c * d + a * b), a * a + d * d - b * b - c * c],
        ]
    )
