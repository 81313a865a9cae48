"""Flows that the Lie–Poisson splittings are built from.

kick: the exact flow of the potential M g l cos θ: the orientation is frozen,
so the body angular momentum changes by τ_b h.

free_flow: the torque-free motion for a time h.  For a symmetric body
(I1 = I2) it is exact: R(t) = R0 · Rot(L_b0 t / I1) · Rot(e3 c t) with
c = (1/I3 − 1/I1) L3, while L_b turns by −c t about e3.  For an asymmetric
body it is the symmetric sub-splitting into rotations about single body axes
(McLachlan 1993; Touma & Wisdom 1994): e1(h/2) e2(h/2) e3(h) e2(h/2) e1(h/2),
each exact, second order and Poisson, conserving |L| exactly (``axis_splitting``
writes it in any of the six axis orders).
"""

from numba import njit

from .rigid_body import gravity_torque, torque_at
from .rotation import half_angle, quat_mul, quat_normalize, rotate_body_step


@njit(cache=True, error_model="numpy")
def _kick_by(w, h, tau, body):
    """ω after the body-frame torque tau (N m) acted for h seconds with the orientation frozen.

    Multiplied by 1/I_k rather than divided by I_k: inlined into a step, each 1/I_k is then one division
    for the whole step (LLVM merges the equal ones), where lie_poisson4's step had 18 divisions, the
    dearest operation of the vectorised loop (docs/benchmarks.md, "Reciprocals in the splittings' kicks").
    The rounded 1/I_k is the same all run long: the kick of moments off by ≤ ½ ulp.  For a symmetric top
    (1/I1 = 1/I2, no torque about e3) that is the kick of the potential scaled by 1 + O(eps), still
    Poisson; for other bodies an O(eps) perturbation of fixed sign per component, measured to add no drift
    above the plain rounding's (docs/benchmarks.md).  The free flows keep their divisions (_axis_rotation)."""
    return (
        w[0] + h * tau[0] * (1.0 / body[0]),
        w[1] + h * tau[1] * (1.0 / body[1]),
        w[2] + h * tau[2] * (1.0 / body[2]),
    )


@njit(cache=True, error_model="numpy")
def kick(w, q, h, body):
    """ω after the potential's flow for h seconds (q unchanged); the drive, if any, is left out."""
    return _kick_by(w, h, gravity_torque(q, body), body)


@njit(cache=True, error_model="numpy")
def kick_at(w, q, h, t, body):
    """ω after the flow of the torque at time t frozen (q, t unchanged) for h seconds: gravity plus
    the driving torque (rigid_body.torque_at); on an undriven body ``kick`` bit for bit.  In a
    splitting of the driven body, made autonomous with t as a coordinate, the free flow advances t
    and the kicks hold it."""
    return _kick_by(w, h, torque_at(q, t, body), body)


@njit(cache=True, error_model="numpy")
def _axis_rotation(w, q, axis, h, body):
    """Flow of L_k²/(2 I_k): the body turns by φ = ω_k h about e_k, L_b by −φ."""
    c, s = half_angle(w[axis] * h)
    cos_phi = 1.0 - 2.0 * s * s
    sin_phi = 2.0 * s * c
    I = (body[0], body[1], body[2])
    L = (I[0] * w[0], I[1] * w[1], I[2] * w[2])
    if axis == 0:
        q = quat_mul(q, (c, s, 0.0, 0.0))
        L = (L[0], cos_phi * L[1] + sin_phi * L[2], -sin_phi * L[1] + cos_phi * L[2])
    elif axis == 1:
        q = quat_mul(q, (c, 0.0, s, 0.0))
        L = (cos_phi * L[0] - sin_phi * L[2], L[1], sin_phi * L[0] + cos_phi * L[2])
    else:
        q = quat_mul(q, (c, 0.0, 0.0, s))
        L = (cos_phi * L[0] + sin_phi * L[1], -sin_phi * L[0] + cos_phi * L[1], L[2])
    # Divided, not multiplied by 1/I_k as the kick is: ω = L·fl(1/I) and L = I ω in the next rotation would
    # scale L by the same (1 + δ_k) every time, a drift of |L| (8e-8 over 1e8 steps of the racket, measured).
    return (L[0] / I[0], L[1] / I[1], L[2] / I[2]), q


@njit(cache=True, error_model="numpy")
def free_flow(w, q, h, body):
    """Torque-free motion of (ω, q) for h seconds; exact when I1 = I2, else the axis splitting in the
    axis order 1-2-3-2-1 of the body's own labels."""
    I1, I2, I3 = body[0], body[1], body[2]
    if I1 == I2:
        c = (1.0 - I3 / I1) * w[2]  # (1/I3 − 1/I1) L3
        q = rotate_body_step(q, w[0] * h, w[1] * h, I3 / I1 * w[2] * h)
        ch, sh = half_angle(c * h)
        q = quat_mul(q, (ch, 0.0, 0.0, sh))
        cp = 1.0 - 2.0 * sh * sh  # cos(c h)
        sp = 2.0 * sh * ch  # sin(c h)
        # Products of nearly constant unit quaternions round the same way every
        # substep, so |q| would drift linearly (2e-11 after 1e6 steps): renormalise.
        return (cp * w[0] + sp * w[1], -sp * w[0] + cp * w[1], w[2]), quat_normalize(q)
    # axis_splitting(w, q, h, body, (0, 1, 2)) written out with literal axes: through axis_splitting the
    # one-by-one path ran 13-20 % slower on asymmetric free bodies (benchmarks/bench_methods.py, lie_poisson
    # and lie_poisson4 on free_asymmetric; the block path was unchanged); tests/test_splitting_order.py
    # checks that the two are the same map bit for bit.
    half = 0.5 * h
    w, q = _axis_rotation(w, q, 0, half, body)
    w, q = _axis_rotation(w, q, 1, half, body)
    w, q = _axis_rotation(w, q, 2, h, body)
    w, q = _axis_rotation(w, q, 1, half, body)
    w, q = _axis_rotation(w, q, 0, half, body)
    return w, quat_normalize(q)


@njit(cache=True, error_model="numpy")
def moment_sorted_order(body):
    """The axes (0-based) by increasing moment, (smallest, middle, largest): as (outer, middle, inner) of
    ``axis_splitting`` the order S-M-L-M-S, the order that analysis/reports/splitting_order.py finds
    within 2.64× of the best of the six in energy (1.52× in orientation) over the inertia triangle (ties keep
    the label order)."""
    I1, I2, I3 = body[0], body[1], body[2]
    if I1 <= I2:
        if I2 <= I3:
            return (0, 1, 2)
        return (0, 2, 1) if I1 <= I3 else (2, 0, 1)
    if I1 <= I3:
        return (1, 0, 2)
    return (1, 2, 0) if I2 <= I3 else (2, 1, 0)


SORTED = (3, 4, 5)  # the axis order S-M-L in kernels/parameters.py's codes: smallest, middle, largest moment


@njit(cache=True, error_model="numpy")
def resolve_axes(body, axes):
    """The body axes (0-based) of an axis order in kernels/parameters.py's codes: 0, 1, 2 are the axes
    e1, e2, e3 themselves, 3, 4, 5 the axes of the smallest, middle and largest moment of ``body``
    (``moment_sorted_order``).  ``axes`` is a compile-time constant in every caller, so the branch folds."""
    if axes[0] < 3:
        return axes
    by_moment = moment_sorted_order(body)
    return by_moment[axes[0] - 3], by_moment[axes[1] - 3], by_moment[axes[2] - 3]


@njit(cache=True, error_model="numpy")
def free_flow_axes(w, q, h, body, axes):
    """free_flow with the axis splitting in the order ``axes`` (``resolve_axes``); exact when I1 = I2,
    as free_flow, where no axis order enters."""
    if body[0] == body[1]:
        return free_flow(w, q, h, body)  # the exact symmetric flow: no axis order
    return axis_splitting(w, q, h, body, resolve_axes(body, axes))


@njit(cache=True, error_model="numpy")
def free_flow_sorted(w, q, h, body):
    """free_flow with the axis splitting in the moment-sorted order S-M-L-M-S whatever the body's axis
    labels (``moment_sorted_order``); exact when I1 = I2, as free_flow."""
    return free_flow_axes(w, q, h, body, SORTED)


@njit(cache=True, error_model="numpy")
def axis_splitting(w, q, h, body, order):
    """Torque-free motion of (ω, q) for h seconds by the symmetric sub-splitting into exact rotations about
    single body axes, order[0](h/2) order[1](h/2) order[2](h) order[1](h/2) order[0](h/2) (0-based body
    axes): second order, Poisson, |L| kept exactly, q renormalised.  free_flow's order is (0, 1, 2)
    (written 1-2-3-2-1); NO_SQUISH as the MD codes ship it is (2, 1, 0) (methods/no_squish.py).  Which
    order is best depends on the moments (Fassò 2003); analysis/reports/splitting_order.py maps it."""
    half = 0.5 * h
    w, q = _axis_rotation(w, q, order[0], half, body)
    w, q = _axis_rotation(w, q, order[1], half, body)
    w, q = _axis_rotation(w, q, order[2], h, body)
    w, q = _axis_rotation(w, q, order[1], half, body)
    w, q = _axis_rotation(w, q, order[0], half, body)
    return w, quat_normalize(q)
