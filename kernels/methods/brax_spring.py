"""brax_spring: Brax's spring pipeline body update: no ω × Iω, ω·exp(ang_damping h), first-order quaternion step.

Followed: google/brax at commit 0b96d056328d (pyproject version 0.14.2, 29 Jun
2026): brax/spring/pipeline.py ``step`` (the force's velocity update, then
collisions, then the integrator) and brax/spring/integrator.py ``integrate``
(the per-link ``op``).  Per step, in the world frame at the centre of mass:

    xd_i.ang += (i_inv @ xf_i.ang) dt               (pipeline.step: "semi-implicit euler",
                                                     i_inv = com.inv_inertia, the world I⁻¹)
    ang ← exp(sys.ang_damping dt) · ang + xdv_i.ang  (integrate: damping, then the collision
                                                     delta-velocity, zero without contacts)
    rot ← rot + quat_mul(ang_to_quat(ang) · 0.5 dt, rot);  rot ← rot / |rot|

There is no gyroscopic term anywhere in the spring pipeline (the torque
reaches ω through the world inverse inertia only, as in no_gyro) and no
angular-velocity clamp.  Hidden defaults: brax/io/mjcf.py ``_get_custom``
gives ``ang_damping`` = 0.0 (and ``spring_inertia_scale`` = 0.0, so
com.inv_inertia uses the body's inertia unchanged) unless the MJCF sets a
<custom><numeric name="ang_damping">; Brax's own environments set it
(-0.05 in humanoid.xml and hopper.xml, -0.01 in half_cheetah.xml, 0.0 in
ant.xml: a negative value damps, since the factor is exp(ang_damping dt)).
With the default the factor is exp(0) = 1 and ω is untouched bit for bit.
In the body frame ((0, ω_lab) ⊗ q = q ⊗ (0, ω_body); the first-order step
turns q about ω, which leaves ω's body components unchanged):

    ω ← ω + h I⁻¹ τ(q)
    ω ← ω · exp(ANG_DAMPING h)
    q ← normalise(q + q ⊗ (0, ½ h ω))

The first-order quaternion step turns the body by 2 atan(h|ω|/2), not h|ω|.
Brax (JAX) computes in single precision by default; this is double.  The
pivot of the heavy top is a gravity torque here, not a Brax spring joint.
Order 1 (for I ω̇ = τ + ANG_DAMPING I ω: the equation without ω × Iω; measured
slope 1.004 on the 50 Hz top against it, tests/test_engines.py).
"""

import math

from numba import njit

from ..engine_common import torque_kick
from ..rotation import quat_mul

ORDER = 1
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = "Brax 0.14 spring pipeline: no gyroscopic term, first-order quaternion step, shipped ang_damping 0"
# As no_gyro: torque-free, ω is constant (the default damping factor is exactly 1), so |Iω| and L3 are
# kept exactly; with gravity, τ3 = 0 keeps ω3.
PRESERVES = ("L_norm", "L3")

ANG_DAMPING = 0.0  # 1/s, brax/io/mjcf.py _get_custom default; ω *= exp(ang_damping h), negative damps


@njit(cache=True, error_model="numpy")
def brax_step(w, q, dt, body, ang_damping):
    """One step of Brax's spring pipeline rotation with the given ang_damping (1/s)."""
    w = torque_kick(w, q, dt, body)
    damp = math.exp(ang_damping * dt)
    w = (damp * w[0], damp * w[1], damp * w[2])
    # rot + quat_mul(ang_to_quat(ang) * 0.5 * dt, rot), in the body frame
    v = (w[0] * 0.5 * dt, w[1] * 0.5 * dt, w[2] * 0.5 * dt)
    d0, d1, d2, d3 = quat_mul(q, (0.0, v[0], v[1], v[2]))
    a, b, c, d = q[0] + d0, q[1] + d1, q[2] + d2, q[3] + d3
    norm = math.sqrt(a * a + b * b + c * c + d * d)
    return w, (a / norm, b / norm, c / norm, d / norm)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return brax_step(w, q, dt, body, ANG_DAMPING)
