"""jolt_rescale: Jolt's gyroscopic step (explicit step of L, |L| restored), with Jolt's default limits.

Followed: jrouwe/JoltPhysics at commit 3b47ec390cb9 (v5.5.0-182-g, 30 Jun
2026): Jolt/Physics/Body/MotionProperties.inl
``ApplyGyroscopicForceInternal`` (added in PR #809 for issue #803, commit
9d7748ea, Dec 2023), ``ApplyForceTorqueAndDragInternal`` (torque, damping,
clamp), ``ClampAngularVelocity``; Jolt/Physics/PhysicsSystem.cpp
``JobApplyGravity`` (gyroscopic step, then forces) and
``JobIntegrateVelocity`` (clamp again, then ``Body::AddRotationStep``);
Jolt/Physics/Body/Body.inl ``AddRotationStep`` (exact axis-angle rotation,
skipped when |ω h| ≤ 1e-6, normalised); Jolt/Physics/Body/
BodyCreationSettings.h (defaults).  Per step:

    L  = I ω;  L' = L − h ω × L;  L' ← L' |L|/|L'|;  ω ← I⁻¹ L'
    ω ← ω + h I⁻¹ τ(q);  ω ← ω max(0, 1 − ANGULAR_DAMPING h);  |ω| capped to MAX_ANGULAR_VELOCITY
    q ← normalise(q ⊗ Rot(ω h))  (skipped when |ω h| ≤ 1e-6)

Hidden limits, on with Jolt's defaults (module constants, compiled in):
MAX_ANGULAR_VELOCITY = 0.25 π · 60 ≈ 47.1 rad/s (7.5 Hz: the 50 Hz top and
the 10 Hz free body are clamped on their first step and become other
bodies) and ANGULAR_DAMPING = 0.05 /s (BodyCreationSettings::mAngularDamping,
dω/dt = −c ω).  The gyroscopic step itself is opt-in in Jolt
(mApplyGyroscopicForce = false by default; with it off Jolt is no_gyro).
The bare scheme without these limits is jolt_rescale_bare.  Jolt computes in
single precision; this is double.  The pivot of the heavy top is a gravity
torque here, not a Jolt point constraint.  Order 1 (of the bare scheme; with
the clamp active it converges to a different motion).
"""

import math

from numba import njit

from ..engine_common import clamp_norm, exp_rotate, rescale_momentum_step, torque_kick

ORDER = 1
SYMPLECTIC = False
REPRODUCES = (
    "Jolt 5.5 gyroscopic |L|-rescale, shipped limits"  # judged by conformance with the engine (tests/test_engines.py)
)
# The clamp and the damping change |L| even on a free body, so nothing is kept to rounding.
PRESERVES = ()

MAX_ANGULAR_VELOCITY = 0.25 * math.pi * 60.0  # rad/s, BodyCreationSettings::mMaxAngularVelocity
ANGULAR_DAMPING = 0.05  # 1/s, BodyCreationSettings::mAngularDamping
MIN_ROTATION = 1.0e-6  # rad, Body::AddRotationStep


@njit(cache=True, error_model="numpy")
def jolt_step(w, q, dt, body, max_angular_velocity, angular_damping):
    w = rescale_momentum_step(w, dt, body)
    w = torque_kick(w, q, dt, body)
    damp = max(0.0, 1.0 - angular_damping * dt)
    w = (w[0] * damp, w[1] * damp, w[2] * damp)
    w = clamp_norm(w, max_angular_velocity)
    return w, exp_rotate(q, w, dt, MIN_ROTATION)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return jolt_step(w, q, dt, body, MAX_ANGULAR_VELOCITY, ANGULAR_DAMPING)
