"""Euler's equations, the gravity torque and the invariants, in the body frame.

A body is kernels/body.py's Body (I1, I2, I3, mgl, mgc1, mgc2, then the
driving torque's fields): principal moments about the pivot (kg m²), the
weight times the centre of mass's body coordinates (M g c3, M g c1, M g c2;
N m), all zero for a free body, and a body-fixed torque that depends on time.  ω is the body angular
velocity (rad/s, components on the current body axes), q the orientation
quaternion (see rotation.py).
"""

import math

from numba import njit

from .rotation import body_to_lab, lab_up_in_body


@njit(cache=True, error_model="numpy")
def gravity_torque(q, body):
    """τ_b = γ × (M g c) in the body frame (N m), with γ = Rᵀ ẑ the lab vertical in body coordinates.

    The centre of mass sits at c (body coordinates) and gravity is −g ẑ, so the
    lab torque is R c × (−M g ẑ) = M g ẑ × R c; in body coordinates that is
    γ × (M g c).  For c = l e3 it is M g l (γ2, −γ1, 0), computed as such.
    """
    m3, m1, m2 = body[3], body[4], body[5]
    if m1 == 0.0 and m2 == 0.0:
        # Centre of mass on e3 (the top) or a free body: the two-product torque, not the cross
        # product (4 torque evaluations a step make the difference ~10 ns in rk4).  The block path
        # passes m1 = m2 = 0.0 as constants where every lane has them (block.py), so LLVM drops the
        # general branch there too.
        if m3 == 0.0:
            return 0.0, 0.0, 0.0
        g1, g2, _ = lab_up_in_body(q)
        return m3 * g2, -m3 * g1, 0.0
    g1, g2, g3 = lab_up_in_body(q)
    return g2 * m3 - g3 * m2, g3 * m1 - g1 * m3, g1 * m2 - g2 * m1


@njit(cache=True, error_model="numpy")
def drive_torque(t, body):
    """The driving torque's smooth part at time t (s), body frame (N m): (tau1, tau2, tau3)
    sin²(drive_rate t).  Whether it acts is decided per step, not here: the driver hands a step
    the body with the drive zeroed when the step's midpoint lies outside [drive_on, drive_off]
    (driver.make_advance_driven).  A composition's substeps reach times outside [t, t + dt]
    (lie_poisson4's middle substep runs backwards), and a window tested at those times would
    switch the torque off inside a step: at t = 0 that cost the fourth-order methods an order."""
    s = math.sin(body[9] * t)
    s2 = s * s
    return body[6] * s2, body[7] * s2, body[8] * s2


@njit(cache=True, error_model="numpy")
def torque_at(q, t, body):
    """Total body-frame torque (N m) at orientation q and time t (s): gravity plus the drive.

    An undriven body (tau1 = tau2 = tau3 = 0) gets ``gravity_torque``'s values themselves, not
    gravity + 0.0 (which turns a −0.0 into +0.0): so a time-aware step on an undriven body is, bit
    for bit, the step that never looks at time (methods/README.md).  Where the kernels pass the
    drive's amplitude as constants 0.0 (``body.without_drive``, the block path's lanes, the driver's
    axial loop) LLVM folds this branch and t is never read; elsewhere it is one predictable branch.
    """
    g1, g2, g3 = gravity_torque(q, body)
    if body[6] == 0.0 and body[7] == 0.0 and body[8] == 0.0:
        return g1, g2, g3
    d1, d2, d3 = drive_torque(t, body)
    return g1 + d1, g2 + d2, g3 + d3


@njit(cache=True, error_model="numpy")
def euler_rhs(w, tau, body):
    """ω̇ = I⁻¹ (τ − ω × Iω) (rad/s²), all in the body frame.

    I⁻¹ is applied as a multiplication by the reciprocals 1/I_k, not as a division: a method that calls
    this several times a step (RK4: four) inlines the calls, LLVM computes the three reciprocals once
    and the step has three divisions instead of twelve (a division takes ~13 cycles where a
    multiplication takes 4; seed_next's block step 7.4 → 5.3 ns a lane on a Zen 4, docs/benchmarks.md).  The
    product differs from the quotient by at most one ulp: a change of the last bit, far below any
    method's truncation error (issue 22 item 3; the stored regression data agree with it to 7.7e-4 of their
    tolerance, docs/benchmarks.md).
    """
    I1, I2, I3 = body[0], body[1], body[2]
    w1, w2, w3 = w
    t1, t2, t3 = tau
    return (
        (t1 + (I2 - I3) * w2 * w3) * (1.0 / I1),
        (t2 + (I3 - I1) * w3 * w1) * (1.0 / I2),
        (t3 + (I1 - I2) * w1 * w2) * (1.0 / I3),
    )


@njit(cache=True, error_model="numpy")
def kinetic_energy(w, body):
    I1, I2, I3 = body[0], body[1], body[2]
    w1, w2, w3 = w
    return 0.5 * (I1 * w1 * w1 + I2 * w2 * w2 + I3 * w3 * w3)


@njit(cache=True, error_model="numpy")
def potential_energy(q, body):
    """V = M g c·γ (J): the height of the centre of mass times M g (for c = l e3, M g l cos θ)."""
    g1, g2, g3 = lab_up_in_body(q)
    return body[3] * g3 + body[4] * g1 + body[5] * g2


@njit(cache=True, error_model="numpy")
def potential_scale(body):
    """|M g c| (J): the largest change of V over orientations is twice this."""
    return math.sqrt(body[3] * body[3] + body[4] * body[4] + body[5] * body[5])


@njit(cache=True, error_model="numpy")
def divergence_scale(w, body):
    """The energy (J) a run's |E − E0| is held against (× runner.divergence_threshold): T0 + |M g c|,
    plus, for a body with a drive, the most kinetic energy the drive can give it.  The body-fixed
    torque τ sin²(rate t) turns and grows L by at most |τ| (t_off − t_on) over its window, and
    T = ½ L_b·I⁻¹L_b ≤ |L|²/(2 I_min), so T stays below (|L0| + |τ| (t_off − t_on))²/(2 I_min): a
    driven run is never stopped for energy it really gained (a body at rest, T0 = 0, was stopped at
    its first sample whatever the threshold).  Without a drive the term is 0 (the same bits as before)."""
    scale = kinetic_energy(w, body) + potential_scale(body)
    tau = math.sqrt(body[6] * body[6] + body[7] * body[7] + body[8] * body[8])
    if tau > 0.0:
        I1, I2, I3 = body[0], body[1], body[2]
        L0 = math.sqrt((I1 * w[0]) ** 2 + (I2 * w[1]) ** 2 + (I3 * w[2]) ** 2)
        reach = L0 + tau * max(body[11] - body[10], 0.0)
        scale += reach * reach / (2.0 * min(I1, I2, I3))
    return scale


@njit(cache=True, error_model="numpy")
def energy(w, q, body):
    """E = ½ ω·Iω + M g c·γ (J); for c = l e3 that is ½ ω·Iω + M g l cos θ (γ3 = cos θ)."""
    return kinetic_energy(w, body) + potential_energy(q, body)


@njit(cache=True, error_model="numpy")
def lab_momentum(w, q, body):
    """L = R I ω, the angular momentum about the pivot in the lab frame (kg m²/s)."""
    I1, I2, I3 = body[0], body[1], body[2]
    return body_to_lab(q, I1 * w[0], I2 * w[1], I3 * w[2])


@njit(cache=True, error_model="numpy")
def axis_lab(q):
    """R e3: the symmetry axis (body e3) in lab coordinates."""
    a, b, c, d = q
    return 2.0 * (b * d + a * c), 2.0 * (c * d - a * b), a * a + d * d - b * b - c * c
