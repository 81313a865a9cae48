"""newton_semi: Newton's SolverSemiImplicit body update: explicit ω × Iω, first-order quaternion step, damping 0.05/s.

Followed: newton-physics/newton at commit 41a5392c13b9 (v0.2.3-1079-g,
pyproject version 1.6.0.dev0, 22 Aug 2026): newton/_src/solvers/solver.py
``integrate_rigid_body`` (the @wp.func), run by the kernel ``integrate_bodies``
that ``SolverBase.integrate_bodies`` launches; newton/_src/solvers/
semi_implicit/solver_semi_implicit.py ``SolverSemiImplicit.__init__``
(``angular_damping: float = 0.05``) and ``SolverSemiImplicit.step``, which
passes ``self.angular_damping`` to ``integrate_bodies`` after the forces are
accumulated in body_f.  The angular part of ``integrate_rigid_body``:

    wb = R⁻¹ ω_lab;  tb = R⁻¹ τ_lab − wb × (I wb)          ("coriolis forces")
    ω₁ = R (wb + I⁻¹ tb h)
    r₁ = normalize(r₀ + (ω₁, 0) ⊗ r₀ · h/2)                  (world ω, left product)
    ω₁ ← ω₁ (1 − angular_damping h)                          (after the rotation)

In the body frame (r₀ + ½h (0, ω_lab) ⊗ r₀ = r₀ ⊗ (1, ½h ω_body); the first-order
step turns q about ω₁, which leaves ω₁'s body components unchanged):

    ω ← ω + h I⁻¹ (τ(q) − ω × Iω)
    q ← normalise(q + ½h q ⊗ (0, ω))
    ω ← ω (1 − ANGULAR_DAMPING h)

The damped ω is stored for the next step, but the rotation of this step used
the undamped one; the factor is not clamped at 0 (unlike PhysX's and Jolt's),
and there is no angular-velocity cap.  The first-order quaternion step turns
the body by 2 atan(h|ω|/2), not h|ω|.  Warp computes in single precision;
this is double, and ω × Iω is written (I3 − I2) ω2 ω3, ... (engine_common's
``gyro_bias``), the same product as Warp's wp.cross(wb, I wb) up to rounding.
The pivot of the heavy top is a gravity torque here, not a Newton joint
(SolverSemiImplicit holds joints with penalty springs, joint_attach_ke/kd).
Order 1 (for I ω̇ = τ − ω × Iω − c I ω).
"""

import math

from numba import njit

from ..engine_common import gyro_bias
from ..rigid_body import gravity_torque
from ..rotation import quat_mul

ORDER = 1
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = "Newton 1.6 SolverSemiImplicit rigid body, shipped damping"
# The damping scales ω every step, so neither |L| nor ω3 of the symmetric top is kept.
PRESERVES = ()

ANGULAR_DAMPING = 0.05  # 1/s, SolverSemiImplicit.__init__(angular_damping=0.05), applied as ω *= 1 − c h


@njit(cache=True, error_model="numpy")
def newton_step(w, q, dt, body, angular_damping):
    """One step of integrate_rigid_body's rotation with the given damping (1/s)."""
    t1, t2, t3 = gravity_torque(q, body)
    g1, g2, g3 = gyro_bias(w, body)
    w = (w[0] + (t1 - g1) / body[0] * dt, w[1] + (t2 - g2) / body[1] * dt, w[2] + (t3 - g3) / body[2] * dt)
    # r1 = normalize(r0 + quat(w1, 0) * r0 * 0.5 * dt), in the body frame
    h = 0.5 * dt
    d0, d1, d2, d3 = quat_mul(q, (0.0, w[0], w[1], w[2]))
    a, b, c, d = q[0] + d0 * h, q[1] + d1 * h, q[2] + d2 * h, q[3] + d3 * h
    inv = 1.0 / math.sqrt(a * a + b * b + c * c + d * d)
    damp = 1.0 - angular_damping * dt
    return (w[0] * damp, w[1] * damp, w[2] * damp), (a * inv, b * inv, c * inv, d * inv)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return newton_step(w, q, dt, body, ANGULAR_DAMPING)
