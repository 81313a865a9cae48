"""physx_default: PhysX 5's default rigid dynamic: no gyroscopic term, angular damping 0.05/s, |ω| capped at 100 rad/s.

Followed: NVIDIA-Omniverse/PhysX at commit a3d8a641de4c (PhysX 5.6.1,
physx/version.txt 5.6.1.51c1f783, 24 Jun 2026), CPU pipeline with the default
PGS solver (PxSceneDesc::solverType = ePGS).  Defaults:
physx/source/simulationcontroller/src/ScBodyCore.cpp ``Sc::BodyCore::BodyCore``
gives a PxRigidDynamic angular damping 0.05 and maxAngularVelocitySq = 100²
(physx/include/PxRigidBody.h ``setAngularDamping`` and ``setMaxAngularVelocity``
document the same) and no flags, so PxRigidBodyFlag::eENABLE_GYROSCOPIC_FORCES is
off.  Torque: physx/source/simulationcontroller/src/ScBodySim.cpp
``BodySim::updateForces`` (run by ScPipeline.cpp's ``ScBeforeSolverTask``) turns
a PxRigidDynamic::addTorque (PxForceMode::eFORCE) into ω += I_lab⁻¹ τ h.
Damping and cap: physx/source/lowleveldynamics/src/DyBodyCoreIntegrator.h
``bodyCoreComputeUnconstrainedVelocity`` (DyDynamics.cpp's pre-integration):
ω *= fsel(1 − c h, 1 − c h, 0), then ω *= sqrt(max² / |ω|²) when |ω|² > max².
Gyroscopic term: physx/source/lowleveldynamics/src/DyRigidBodyToSolverBody.cpp
``copyToSolverBodyData`` applies it (an |L|-rescaled explicit step, as Jolt's)
only when the flag is set, so not by default.  Rotation:
physx/source/lowleveldynamics/src/DyBodyCoreIntegrator.h ``integrateCore``
(called by DyDynamics.cpp's ``integrate``; "closed form quaternion
integrator"), with θ = |ω|,
q ← normalise((ω sin(θh/2)/θ, 0) ⊗ q + q cos(θh/2)): the exact rotation by θh
about the lab ω, skipped when ω = 0 (|ω| is capped again at 1e7 rad/s there,
never reached after the 100 rad/s cap).

Per step, written in the body frame (a rotation about ω leaves ω's body
components unchanged, so this is the same map as PhysX's lab-frame one; see
no_gyro):

    ω ← ω + h I⁻¹ τ(q)                       (updateForces)
    ω ← ω · max(0, 1 − ANGULAR_DAMPING h)     (bodyCoreComputeUnconstrainedVelocity)
    ω ← ω · sqrt(MAX² / |ω|²)  if |ω|² > MAX²,  MAX = MAX_ANGULAR_VELOCITY
    q ← normalise(q ⊗ Rot(ω h))               (integrateCore)

no_gyro is the same update without the damping and the cap.  The 100 rad/s
cap (16 Hz) clips the 50 Hz top (314 rad/s) on its first step; the damping
is a first-order factor 1 − c h per step (the solution of dω/dt = −c ω to
first order), not exp(−c h).  PhysX computes in single precision; this is
double.  The pivot of the heavy top is a gravity torque here, not a PhysX
joint.  Order 1 (for its own equation I ω̇ = τ − c I ω, below the cap).
"""

import math

from numba import njit

from ..engine_common import exp_rotate, torque_kick

ORDER = 1
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = "PhysX 5.6 default rigid dynamic: no gyroscopic term, shipped damping and cap"
# The damping changes ω, hence |L| and L3, even on a free body: nothing is kept to rounding.
PRESERVES = ()

ANGULAR_DAMPING = 0.05  # 1/s, Sc::BodyCore::BodyCore (PxsBodyCore::angularDamping; PxRigidBody::setAngularDamping)
MAX_ANGULAR_VELOCITY = 100.0  # rad/s, Sc::BodyCore::BodyCore maxAngularVelocitySq = 100² (setMaxAngularVelocity)


@njit(cache=True, error_model="numpy")
def physx_velocity(w, q, dt, body, angular_damping, max_angular_velocity):
    """PhysX's velocity update before the solver: torque (updateForces), then damping and cap
    (bodyCoreComputeUnconstrainedVelocity) with the given damping (1/s) and cap (rad/s)."""
    w = torque_kick(w, q, dt, body)
    # fsel(x, x, 0): x when x >= 0, else 0
    damp = max(0.0, 1.0 - angular_damping * dt)
    w = (w[0] * damp, w[1] * damp, w[2] * damp)
    # PhysX's own expression for the cap (not limit / |ω|): ω *= sqrt(max² / |ω|²)
    max_sq = max_angular_velocity * max_angular_velocity
    sq = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    if sq > max_sq:
        s = math.sqrt(max_sq / sq)
        w = (w[0] * s, w[1] * s, w[2] * s)
    return w


@njit(cache=True, error_model="numpy")
def physx_step(w, q, dt, body, angular_damping, max_angular_velocity):
    """One PhysX step with the given damping (1/s) and cap (rad/s)."""
    w = physx_velocity(w, q, dt, body, angular_damping, max_angular_velocity)
    return w, exp_rotate(q, w, dt, 0.0)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return physx_step(w, q, dt, body, ANGULAR_DAMPING, MAX_ANGULAR_VELOCITY)
