"""chrono_euler: Project Chrono's default EULER_IMPLICIT_LINEARIZED: explicit ω × Iω, exp-map q, never normalised.

Followed: projectchrono/chrono at commit 7689fbc02d12 (Chrono 10.0.0,
CMakeLists.txt CHRONO_VERSION 10.0.0, 18 Aug 2026).  The default timestepper
is src/chrono/physics/ChSystem.cpp ``ChSystem::ChSystem`` (``timestepper =
ChTimestepperEulerImplicitLinearized``) and the default solver PSOR
(src/chrono/physics/ChSystemNSC.cpp and ChSystemSMC.cpp, ``SetSolverType(
ChSolver::Type::PSOR)``).  src/chrono/timestepper/ChTimestepperImplicit.cpp
``ChTimestepperEulerImplicitLinearized::OnAdvance`` takes one Newton step of
implicit Euler from v_new = 0: R = h f + M v (``LoadResidual_F(R, dt)``,
``LoadResidual_Mv(R, V, 1)``), solves [M − h ∂f/∂v − h² ∂f/∂x] v_new = R
(``StateSolveCorrection``), then X += V h.  For a ChBody
(src/chrono/physics/ChBody.cpp):

- the angular part of f is ``IntLoadResidual_F``'s Xtorque − gyro, both in the
  body (local) frame, gyro = ω × Iω from ``ComputeGyro`` at the step's start
  (``Update``), so the gyroscopic term is explicit;
- ChBody loads no stiffness or damping block (no ``KRMmatricesLoad``): the
  matrix is M alone, block-diagonal, and ``ChSolverPSOR::Solve``
  (src/chrono/solver/ChSolverPSOR.cpp) starts from q = M⁻¹ fb
  (``ChVariablesBodyOwnMass::ComputeMassInverseTimesVector``); with no
  constraints its iterations do nothing, so the solve is exact:
  ω₁ = I⁻¹ (I ω + h (τ − ω × Iω));
- X += V h is ``operator+=`` of src/chrono/timestepper/ChIntegrable.h, which
  calls ``ChBody::IntStateIncrement``: q₁ = q ⊗ rel_q with
  ``ChQuaternion::SetFromRotVec(h ω₁)`` (src/chrono/core/ChQuaternion.h: the
  exact exponential map, (cos(θ/2), v sin(θ/2)/θ) with v = h ω₁ on the body
  axes, θ = |v|; (1, v/2) when θ² <= 1e-30), a local (right) product;
- nothing normalises q: ``IntStateScatter`` → ``ChFrame::SetCoordsys`` stores
  it and builds the rotation matrix from it as it is.

Hidden defaults (ChBody::ChBody, ChSystem::ChSystem): gyroscopic torque on
(``disable_gyrotorque(false)``, ``SetUseGyroTorque``); speed limits off
(``limit_speed(false)``: ``SetLimitSpeed(true)`` would clamp |ω| to max_wvel =
2π rad/s in ``ClampSpeed``); sleeping off (ChSystem ``use_sleeping(false)``);
no damping on a ChBody.  So nothing is clamped or damped by default.

Per step, in gyrolab's conventions (body-frame ω, q body → lab):

    ω ← ω + h I⁻¹ (τ(q) − ω × Iω)                (τ from gravity_torque at q_n)
    q ← q ⊗ (cos(θ/2), h ω sin(θ/2)/θ),  θ = h|ω|  (no normalisation)

This is mujoco_euler's map without MuJoCo's ``mju_normalize4``: MuJoCo
rescales q (when | |q| − 1 | > 1e-15) before the torque and the rotation each
step, Chrono never does, so its |q| wanders by rounding (a random walk of a
few ulp a step).  From a q within 1e-15 of unit norm the velocity update is
mujoco_euler's bit for bit (same expression, same helpers); the rotation
quaternion is built as v sin(θ/2)/θ (Chrono) instead of v̂ sin(θ/2) (MuJoCo),
which differs by rounding (tests/test_chrono_euler.py).  Rounding against
Chrono's own arithmetic (written out in tests/test_chrono_euler.py): Chrono
multiplies by Eigen's 3×3 inverse of diag(I) (cofactors / determinant, not
1/I_i) applied to I ω + h (τ − gyro), computes gyro as ω × (Iω) with
``Vcross``, and orders the terms of the quaternion product as ``Cross``;
here ω × Iω is engine_common's ``gyro_bias`` and the product gyrolab's
``quat_mul``, the same numbers to a few ulp.  The applied torque is the body
frame gravity torque at q_n (a user torque that Chrono evaluates in
``UpdateForces`` before the step), not a Chrono spherical joint (which PSOR
would hold iteratively).  Order 1.
"""

import math

from numba import njit

from ..engine_common import gyro_bias
from ..rigid_body import gravity_torque
from ..rotation import quat_mul

ORDER = 1
SYMPLECTIC = False
# judged by conformance with Chrono's arithmetic (tests/test_chrono_euler.py; pychrono is not on PyPI)
REPRODUCES = "Project Chrono 10.0 EULER_IMPLICIT_LINEARIZED rigid body"
# For I1 = I2 the third components of τ and ω × Iω are exactly 0, so ω3 is carried unchanged.
PRESERVES = ("L3",)

ROTVEC_SMALL = 1e-30  # ChQuaternion::SetFromRotVec: θ² at or below it gives (1, v/2)


@njit(cache=True, error_model="numpy")
def chrono_rotvec_quat(v0, v1, v2):
    """``ChQuaternion::SetFromRotVec(v)``: (cos(θ/2), v sin(θ/2)/θ), θ = |v|; (1, v/2) when θ² <= 1e-30."""
    theta_sq = v0 * v0 + v1 * v1 + v2 * v2
    if theta_sq > ROTVEC_SMALL:
        theta = math.sqrt(theta_sq)
        half = theta / 2.0
        k = math.sin(half) / theta
        return math.cos(half), v0 * k, v1 * k, v2 * k
    return 1.0, v0 * 0.5, v1 * 0.5, v2 * 0.5


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    # mujoco_euler's velocity update at q itself (Chrono never normalises q)
    t1, t2, t3 = gravity_torque(q, body)
    c1, c2, c3 = gyro_bias(w, body)
    a1, a2, a3 = (t1 - c1) / body[0], (t2 - c2) / body[1], (t3 - c3) / body[2]
    w = (w[0] + a1 * dt, w[1] + a2 * dt, w[2] + a3 * dt)
    # ChBody::IntStateIncrement: q ⊗ SetFromRotVec(h ω), kept as it comes out
    return w, quat_mul(q, chrono_rotvec_quat(w[0] * dt, w[1] * dt, w[2] * dt))
