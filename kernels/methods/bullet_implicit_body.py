"""bullet_implicit_body: Bullet's default gyroscopic mode, one Newton step on I ω1 + h ω1 × I ω1 = I ω0.

Followed: bulletphysics/bullet3 at commit 6c888f4abd7b (3.25-25-g, 29 Jan
2025): src/BulletDynamics/Dynamics/btRigidBody.cpp
``computeGyroscopicImpulseImplicit_Body`` (the default: btRigidBody's
constructor sets m_rigidbodyFlags = BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY),
src/BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.cpp
``convertBodies`` (the applied-torque impulse τ I⁻¹ h and the gyroscopic
impulse are added to the same start-of-step ω) and
src/LinearMath/btTransformUtil.h ``integrateTransform``.  Per step:

    f  = h ω0 × I ω0,   J = I + h ([ω0]× I − [I ω0]×)
    ω ← ω0 + h I⁻¹ τ(q) − J⁻¹ f                 (btMatrix3x3::solve33 in Bullet)
    q ← bullet_explicit.bullet_integrate_transform(q, ω, h)

The gyroscopic part is MuJoCo's implicit free-body update; the applied
torque is explicit (MuJoCo puts it through J too).  Bullet's
``computeGyroscopicImpulseImplicit_World`` is the same Newton step written
with the world-frame inertia, so the same map up to rounding: not a separate
file.  Hidden limit, on with Bullet's default: ANGULAR_MOTION_THRESHOLD = π/4
rad of rotation per step (bullet_explicit).  Double precision (Bullet's
default build is single).  The pivot is not a Bullet constraint here (see
bullet_explicit).  Order 1.
"""

from numba import njit

from ..engine_common import gyro_bias, linearly_implicit_matrix, solve33
from ..rigid_body import gravity_torque
from .bullet_explicit import ANGULAR_MOTION_THRESHOLD, bullet_integrate_transform

ORDER = 1
SYMPLECTIC = False
REPRODUCES = (
    "Bullet 3.25 implicit body-frame gyroscopic term"  # judged by conformance with the engine (tests/test_engines.py)
)
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    c1, c2, c3 = gyro_bias(w, body)
    d1, d2, d3 = solve33(linearly_implicit_matrix(w, dt, body), (dt * c1, dt * c2, dt * c3))
    t1, t2, t3 = gravity_torque(q, body)
    w_next = (
        w[0] + t1 / body[0] * dt - d1,
        w[1] + t2 / body[1] * dt - d2,
        w[2] + t3 / body[2] * dt - d3,
    )
    return w_next, bullet_integrate_transform(q, w_next, dt, ANGULAR_MOTION_THRESHOLD)
