"""Euler's equations, the gravity torque and the invariants, in the body frame.

A body is the tuple (I1, I2, I3, mgl): principal moments about the pivot
(kg m²) and M g l (N m), zero for a free body.  ω is the body angular
velocity (rad/s, components on the current body axes), q the orientation
quaternion (see rotation.py).
"""

from numba import njit

from .rotation import body_to_lab, lab_up_in_body


@njit(cache=True, error_model="numpy")
def gravity_torque(q, mgl):
    """τ_b = M g l (γ × e3) in the body frame (N m), with γ = Rᵀ ẑ.

    The centre of mass sits at l e3 and gravity is −g ẑ, so the lab torque is
    l e3 × (−M g ẑ) = M g l ẑ × e3; in body coordinates that is γ × e3.
    """
    if mgl == 0.0:
        return 0.0, 0.0, 0.0
    g1, g2, _ = lab_up_in_body(q)
    return mgl * g2, -mgl * g1, 0.0


@njit(cache=True, error_model="numpy")
def euler_rhs(w, tau, body):
    """ω̇ = I⁻¹ (τ − ω × Iω) (rad/s²), all in the body frame."""
    I1, I2, I3, _ = body
    w1, w2, w3 = w
    t1, t2, t3 = tau
    return (
        (t1 + (I2 - I3) * w2 * w3) / I1,
        (t2 + (I3 - I1) * w3 * w1) / I2,
        (t3 + (I1 - I2) * w1 * w2) / I3,
    )


@njit(cache=True, error_model="numpy")
def kinetic_energy(w, body):
    I1, I2, I3, _ = body
    w1, w2, w3 = w
    return 0.5 * (I1 * w1 * w1 + I2 * w2 * w2 + I3 * w3 * w3)


@njit(cache=True, error_model="numpy")
def energy(w, q, body):
    """E = ½ ω·Iω + M g l cos θ (J); cos θ = e3·ẑ = γ3."""
    return kinetic_energy(w, body) + body[3] * lab_up_in_body(q)[2]


@njit(cache=True, error_model="numpy")
def lab_momentum(w, q, body):
    """L = R I ω, the angular momentum about the pivot in the lab frame (kg m²/s)."""
    I1, I2, I3, _ = body
    return body_to_lab(q, I1 * w[0], I2 * w[1], I3 * w[2])


@njit(cache=True, error_model="numpy")
def axis_lab(q):
    """R e3: the symmetry axis (body e3) in lab coordinates."""
    a, b, c, d = q
    return 2.0 * (b * d + a * c), 2.0 * (c * d - a * b), a * a + d * d - b * b - c * c
