"""physx_gyro: PhysX 5.6 with eENABLE_GYROSCOPIC_FORCES set: |L|-rescaled explicit ω × Iω step after damping and cap.

Followed: NVIDIA-Omniverse/PhysX at commit a3d8a641de4c (PhysX 5.6.1, the
commit physx_default follows), CPU pipeline, default PGS solver.  The flag
(physx/include/PxRigidBody.h PxRigidBodyFlag::eENABLE_GYROSCOPIC_FORCES =
1 << 10, "Enables computation of gyroscopic forces on the rigid body") is off
by default (Sc::BodyCore::BodyCore sets no flags); set, it is passed by
physx/source/lowleveldynamics/src/DyDynamics.cpp's pre-integration (the loop
calling ``bodyCoreComputeUnconstrainedVelocity`` then ``copyToSolverBodyData``
for each body) to physx/source/lowleveldynamics/src/DyRigidBodyToSolverBody.cpp
``Dy::copyToSolverBodyData``, which, in the body frame (localAngVel =
q.rotateInv(ω_lab)):

    localInertia = 1 / invInertia;  origMom = localInertia ω;  torque = −ω × origMom
    newMom = origMom + torque dt;  ratio = |origMom| / |newMom|  (0 when |newMom| = 0)
    newMom *= ratio;  ω_lab += q.rotate(invInertia newMom − ω)

The solver body's velocity is what ``integrateCore`` turns the body by and
what DyDynamics.cpp's ``integrate`` stores back (core.angularVelocity), so the
gyroscopic step comes after the torque, the damping and the cap, and before
the rotation.  Hidden defaults kept, as physx_default (Sc::BodyCore::BodyCore):
angular damping 0.05/s (ω *= max(0, 1 − c h)) and |ω| capped at 100 rad/s
(ω *= sqrt(100² / |ω|²)); the cap acts before the gyroscopic step, which keeps
|L| and so may leave |ω| slightly above 100 rad/s for an asymmetric body.  Per
step, body frame:

    ω ← ω + h I⁻¹ τ(q)                        (ScBodySim.cpp updateForces)
    ω ← ω · max(0, 1 − ANGULAR_DAMPING h)      (bodyCoreComputeUnconstrainedVelocity)
    ω ← ω · sqrt(MAX² / |ω|²)  if |ω|² > MAX²
    L = Iω;  L' = L − h ω × L;  L' ← L' |L|/|L'|;  ω ← ω + (I⁻¹ L' − ω)   (copyToSolverBodyData)
    q ← normalise(q ⊗ Rot(ω h))                (DyBodyCoreIntegrator.h integrateCore)

The gyroscopic step is Jolt's (jolt_rescale) with PhysX's own arithmetic
(engine_common ``physx_gyro_step``) and order of operations: Jolt rescales
before the torque and its damping, PhysX after both and after the cap.  PhysX
computes in single precision; this is double.  The pivot of the heavy top is a
gravity torque here, not a PhysX joint.  Order 1 (for I ω̇ = τ − ω × Iω − c I ω,
below the cap; measured slope 1.000 on the 5 Hz top, tests/test_engines.py).
"""

from numba import njit

from ..engine_common import exp_rotate, physx_gyro_step
from .physx_default import ANGULAR_DAMPING, MAX_ANGULAR_VELOCITY, physx_velocity

ORDER = 1
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = (
    "PhysX 5.6 rigid dynamic with eENABLE_GYROSCOPIC_FORCES: |L|-rescaled gyroscopic step, shipped damping and cap"
)
# The damping changes ω, hence |L| and L3, even on a free body: nothing is kept to rounding.
PRESERVES = ()


@njit(cache=True, error_model="numpy")
def physx_gyro_steps(w, q, dt, body, angular_damping, max_angular_velocity):
    """One PhysX step with the gyroscopic flag set, the given damping (1/s) and cap (rad/s)."""
    w = physx_velocity(w, q, dt, body, angular_damping, max_angular_velocity)
    w = physx_gyro_step(w, dt, body)
    return w, exp_rotate(q, w, dt, 0.0)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return physx_gyro_steps(w, q, dt, body, ANGULAR_DAMPING, MAX_ANGULAR_VELOCITY)
