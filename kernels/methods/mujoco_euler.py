"""mujoco_euler: MuJoCo's default "Euler" integrator (semi-implicit Euler), for a ball joint or a free body.

Followed: google-deepmind/mujoco at commit a7255075b003 (3.12.0-31-g, 22 Aug
2026), src/engine/engine_forward.c ``mj_EulerSkip`` and ``mj_advance``,
src/engine/engine_support.c ``mj_integratePosInd``,
src/engine/engine_util_spatial.c ``mju_quatIntegrate``; checked against the
``mujoco`` 4.0.0 wheel by tests/test_engines.py.  Per step:

    qacc = M⁻¹ (τ(q) − ω × Iω)          (mj_forward; qfrc_bias = Coriolis + gravity)
    ω   ← ω + h qacc                     (mju_addToScl in mj_advance)
    q   ← normalise₄(q) ⊗ axisAngle(ω̂, h|ω|)   (mju_quatIntegrate with the new ω)

For a ball joint at the pivot MuJoCo's generalized inertia M is the body's
inertia about the pivot (centre-of-mass inertia plus the offset), so it is
gyrolab's (I1, I2, I3) and qvel is the body-frame ω; a free body with its
centre of mass at the body origin and no gravity has the same rotational
update.  No hidden limits (MuJoCo clamps nothing; it only warns on NaN).
``normalise₄`` is ``mju_normalize4``: it leaves q alone within 1e-15 of unit
norm.  With joint damping MuJoCo's Euler is implicit in the damping; the
rigid body has none, so that branch is not reproduced.  Order 1.
"""

from numba import njit

from ..engine_common import gyro_bias, mj_normalize4, mj_quat_integrate
from ..rigid_body import gravity_torque

ORDER = 1
SYMPLECTIC = False
REPRODUCES = "MuJoCo 4.0 Euler (semi-implicit)"  # judged by conformance with the engine (tests/test_engines.py)
# For I1 = I2 the third components of τ and ω × Iω are exactly 0, so ω3 is carried unchanged.
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def qacc(w, q, body):
    """M⁻¹ (τ − ω × Iω) at the (MuJoCo-normalised) orientation q (rad/s²)."""
    t1, t2, t3 = gravity_torque(mj_normalize4(q), body)
    c1, c2, c3 = gyro_bias(w, body)
    return (t1 - c1) / body[0], (t2 - c2) / body[1], (t3 - c3) / body[2]


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    a = qacc(w, q, body)
    w_next = (w[0] + a[0] * dt, w[1] + a[1] * dt, w[2] + a[2] * dt)
    return w_next, mj_quat_integrate(q, w_next, dt)
