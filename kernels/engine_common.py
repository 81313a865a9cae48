"""Pieces shared by the engine schemes (kernels/methods/mujoco_*, bullet_*, jolt_*, rapier_*, no_gyro).

Each is our own code, written to reproduce one operation of an engine's
rotation update in gyrolab's conventions (q = (a, b, c, d) scalar first,
R(q) body → lab; ω body frame; a body is (I1, I2, I3, mgl), indexed only):

- ``mj_normalize4`` / ``mj_quat_integrate``: MuJoCo's ``mju_normalize4``
  (src/engine/engine_util_blas.c: a quaternion is rescaled only when
  | |q| − 1 | > mjMINVAL = 1e-15) and ``mju_quatIntegrate``
  (src/engine/engine_util_spatial.c: normalise q, then q ⊗ axisAngle(v̂, h|v|)
  with v̂ from ``mju_normalize3``), which ``mj_integratePos`` applies to a
  ball joint's and a free joint's quaternion with the body-frame qvel;
- ``gyro_jacobian``: ∂(ω × Iω)/∂ω = [ω]× I − [Iω]× (body frame), the matrix
  MuJoCo's ``mjd_rne_vel``/``mjd_freeBias_vel`` and Bullet's
  ``computeGyroscopicImpulseImplicit_*`` differentiate;
- ``solve33``: a 3×3 linear solve (Gaussian elimination with partial
  pivoting, tuples only) for the linearly implicit steps;
- ``rescale_momentum_step``: Jolt's ``ApplyGyroscopicForceInternal`` /
  Rapier's ``gyroscopic_corrected_angvel``: L' = L − h ω × L in the principal
  frame, rescaled to |L|;
- ``physx_gyro_step``: PhysX's gyroscopic step (``Dy::copyToSolverBodyData``,
  PxRigidBodyFlag::eENABLE_GYROSCOPIC_FORCES): the same |L|-rescaled
  explicit step with PhysX's own arithmetic (I from the stored inverse,
  ω += (I⁻¹ L' − ω));
- ``bepu_conserve_momentum``: BEPUphysics v2's
  ``PoseIntegration.IntegrateAngularVelocityConserveMomentum``: the world
  angular momentum at the previous orientation, I_world⁻¹ of the new one
  applied to it (its local inertia from the stored inverse by
  ``Symmetric3x3Wide.Invert``'s cofactors);
- ``dexp_inv``: the inverse of the right-trivialised differential of exp on
  SO(3), exact (closed form), which MuJoCo 4.0's RK4 applies to the stage
  velocities (Runge–Kutta–Munthe-Kaas);
- ``exp_rotate``: q ⊗ Rot(ω h) with libm sin/cos (the engines' exponential
  map), optionally skipped below a threshold angle (Jolt's 1e-6).
"""

import math

from numba import njit

from .rigid_body import gravity_torque
from .rotation import body_to_lab, quat_mul

MJ_MINVAL = 1e-15  # MuJoCo's mjMINVAL (include/mujoco/mjtnum.h)


@njit(cache=True, error_model="numpy")
def mj_normalize4(q):
    """``mju_normalize4``: unit q, but left untouched when its norm is within 1e-15 of 1."""
    a, b, c, d = q
    norm = math.sqrt(a * a + b * b + c * c + d * d)
    if norm < MJ_MINVAL:
        return 1.0, 0.0, 0.0, 0.0
    if abs(norm - 1.0) > MJ_MINVAL:
        inv = 1.0 / norm
        return a * inv, b * inv, c * inv, d * inv
    return a, b, c, d


@njit(cache=True, error_model="numpy")
def mj_quat_integrate(q, v, h):
    """``mju_quatIntegrate(q, v, h)``: normalise4(q) ⊗ (cos(θ/2), v̂ sin(θ/2)), θ = h|v|.

    v is the body-frame angular velocity (rad/s); the result is not normalised
    again (MuJoCo normalises it at the start of the next integration and in
    ``mj_kinematics``).
    """
    v0, v1, v2 = v
    norm = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if norm < MJ_MINVAL:
        x, y, z = 1.0, 0.0, 0.0
    else:
        inv = 1.0 / norm
        x, y, z = v0 * inv, v1 * inv, v2 * inv
    angle = h * norm
    if angle == 0.0:
        qrot = (1.0, 0.0, 0.0, 0.0)
    else:
        s = math.sin(angle * 0.5)
        qrot = (math.cos(angle * 0.5), x * s, y * s, z * s)
    return quat_mul(mj_normalize4(q), qrot)


@njit(cache=True, error_model="numpy")
def exp_rotate(q, w, h, min_angle):
    """normalise(q ⊗ Rot(h ω)) with libm sin/cos; q unchanged when h|ω| <= min_angle.

    The world-frame form the engines write, Rot(h R ω) ⊗ q, is the same
    rotation as q ⊗ Rot(h ω) with the body-frame ω.
    """
    v0, v1, v2 = h * w[0], h * w[1], h * w[2]
    angle = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if not angle > min_angle:
        return q
    s = math.sin(0.5 * angle) / angle
    a, b, c, d = quat_mul(q, (math.cos(0.5 * angle), s * v0, s * v1, s * v2))
    inv = 1.0 / math.sqrt(a * a + b * b + c * c + d * d)
    return a * inv, b * inv, c * inv, d * inv


@njit(cache=True, error_model="numpy")
def gyro_bias(w, body):
    """ω × Iω (N m), body frame: the gyroscopic part of MuJoCo's qfrc_bias."""
    I1, I2, I3 = body[0], body[1], body[2]
    w1, w2, w3 = w
    return (I3 - I2) * w2 * w3, (I1 - I3) * w3 * w1, (I2 - I1) * w1 * w2


@njit(cache=True, error_model="numpy")
def gyro_jacobian(w, body):
    """J = ∂(ω × Iω)/∂ω = [ω]× I − [Iω]×, rows as three tuples (kg m²/s)."""
    I1, I2, I3 = body[0], body[1], body[2]
    w1, w2, w3 = w
    L1, L2, L3 = I1 * w1, I2 * w2, I3 * w3
    # [ω]× I = [[0, -w3 I2, w2 I3], [w3 I1, 0, -w1 I3], [-w2 I1, w1 I2, 0]]
    # [L]×   = [[0, -L3, L2], [L3, 0, -L1], [-L2, L1, 0]]
    return (
        (0.0, L3 - w3 * I2, w2 * I3 - L2),
        (w3 * I1 - L3, 0.0, L1 - w1 * I3),
        (L2 - w2 * I1, w1 * I2 - L1, 0.0),
    )


@njit(cache=True, error_model="numpy")
def linearly_implicit_matrix(w, h, body):
    """I + h J(ω): MuJoCo's M − h qDeriv for a body on a ball or standalone free joint."""
    J = gyro_jacobian(w, body)
    return (
        (body[0] + h * J[0][0], h * J[0][1], h * J[0][2]),
        (h * J[1][0], body[1] + h * J[1][1], h * J[1][2]),
        (h * J[2][0], h * J[2][1], body[2] + h * J[2][2]),
    )


@njit(cache=True, error_model="numpy")
def solve33(A, b):
    """x with A x = b for a 3×3 A given as row tuples (Gaussian elimination, partial pivoting).

    An exact zero in A or b stays an exact zero in the result where the
    algebra says it must (no pivoting happens on a zero column entry), so a
    symmetric body's third row (0, 0, I3 | 0) gives x3 = 0 exactly.
    """
    r0, r1, r2 = A
    b0, b1, b2 = b
    # pivot for column 0
    if abs(r1[0]) > abs(r0[0]) and abs(r1[0]) >= abs(r2[0]):
        r0, r1 = r1, r0
        b0, b1 = b1, b0
    elif abs(r2[0]) > abs(r0[0]):
        r0, r2 = r2, r0
        b0, b2 = b2, b0
    m1 = r1[0] / r0[0]
    m2 = r2[0] / r0[0]
    a11 = r1[1] - m1 * r0[1]
    a12 = r1[2] - m1 * r0[2]
    c1 = b1 - m1 * b0
    a21 = r2[1] - m2 * r0[1]
    a22 = r2[2] - m2 * r0[2]
    c2 = b2 - m2 * b0
    if abs(a21) > abs(a11):
        a11, a12, c1, a21, a22, c2 = a21, a22, c2, a11, a12, c1
    m = a21 / a11
    a22 = a22 - m * a12
    c2 = c2 - m * c1
    x2 = c2 / a22
    x1 = (c1 - a12 * x2) / a11
    x0 = (b0 - r0[1] * x1 - r0[2] * x2) / r0[0]
    return x0, x1, x2


@njit(cache=True, error_model="numpy")
def torque_kick(w, q, h, body):
    """ω + h I⁻¹ τ_g(q): an applied torque integrated explicitly over one step."""
    t1, t2, t3 = gravity_torque(q, body)
    return w[0] + h * t1 / body[0], w[1] + h * t2 / body[1], w[2] + h * t3 / body[2]


@njit(cache=True, error_model="numpy")
def rescale_momentum_step(w, h, body):
    """Jolt/Rapier: L' = L − h ω × L (body principal frame), rescaled to |L|; returns I⁻¹ L'.

    L' = 0 (only when L = 0) returns ω unchanged, as Rapier does (Jolt returns 0).
    """
    I1, I2, I3 = body[0], body[1], body[2]
    w1, w2, w3 = w
    L1, L2, L3 = I1 * w1, I2 * w2, I3 * w3
    n1 = L1 - h * (w2 * L3 - w3 * L2)
    n2 = L2 - h * (w3 * L1 - w1 * L3)
    n3 = L3 - h * (w1 * L2 - w2 * L1)
    new_sq = n1 * n1 + n2 * n2 + n3 * n3
    if not new_sq > 0.0:
        return w
    s = math.sqrt((L1 * L1 + L2 * L2 + L3 * L3) / new_sq)
    return n1 * s / I1, n2 * s / I2, n3 * s / I3


@njit(cache=True, error_model="numpy")
def physx_gyro_step(w, h, body):
    """PhysX 5.6 ``Dy::copyToSolverBodyData`` with gyroscopicForces: its arithmetic, in the body frame.

    PhysX keeps the inverse inertia, so I = 1/(1/I) (0 for a zero inverse, never here);
    L = I ω; L' = L + h (−ω × L); L' ← L' · (|L| / |L'|) (0 when |L'| = 0);
    ω ← ω + (I⁻¹ L' − ω) (PhysX adds the lab-frame difference to the lab ω).
    """
    inv1, inv2, inv3 = 1.0 / body[0], 1.0 / body[1], 1.0 / body[2]
    I1, I2, I3 = 1.0 / inv1, 1.0 / inv2, 1.0 / inv3
    w1, w2, w3 = w
    L1, L2, L3 = I1 * w1, I2 * w2, I3 * w3
    t1 = -(w2 * L3 - w3 * L2)
    t2 = -(w3 * L1 - w1 * L3)
    t3 = -(w1 * L2 - w2 * L1)
    n1, n2, n3 = L1 + t1 * h, L2 + t2 * h, L3 + t3 * h
    denom = math.sqrt(n1 * n1 + n2 * n2 + n3 * n3)
    ratio = math.sqrt(L1 * L1 + L2 * L2 + L3 * L3) / denom if denom > 0.0 else 0.0
    n1, n2, n3 = n1 * ratio, n2 * ratio, n3 * ratio
    return w1 + (inv1 * n1 - w1), w2 + (inv2 * n2 - w2), w3 + (inv3 * n3 - w3)


@njit(cache=True, error_model="numpy")
def bepu_conserve_momentum(w, q_prev, q_new, body):
    """BEPUphysics v2 ``IntegrateAngularVelocityConserveMomentum``, body frame in and out.

    Bepu stores the local inverse inertia (1/I1, 1/I2, 1/I3); ``Symmetric3x3Wide.Invert`` gives the local
    inertia by cofactors: I1 = (i2 i3) · 1/((i2 i3) i1), and so on.  L = R_prev (I ω); ω' = R_new⁻¹-frame
    I⁻¹ (R_newᵀ L), i.e. the world ω' = R_new I⁻¹ R_newᵀ L; a non-finite result keeps ω
    (``FallbackIfInertiaIncompatible``).
    """
    i1, i2, i3 = 1.0 / body[0], 1.0 / body[1], 1.0 / body[2]
    xx, yy, zz = i2 * i3, i3 * i1, i1 * i2
    det_inv = 1.0 / (xx * i1)
    L = body_to_lab(q_prev, xx * det_inv * w[0], yy * det_inv * w[1], zz * det_inv * w[2])
    a, b, c, d = q_new
    m1, m2, m3 = body_to_lab((a, -b, -c, -d), L[0], L[1], L[2])
    out = (i1 * m1, i2 * m2, i3 * m3)
    if not (abs(out[0]) < math.inf and abs(out[1]) < math.inf and abs(out[2]) < math.inf):
        return w
    return out


@njit(cache=True, error_model="numpy")
def clamp_norm(w, limit):
    """ω scaled down to |ω| = limit when |ω| > limit (Jolt's ClampAngularVelocity)."""
    sq = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    if sq > limit * limit:
        s = limit / math.sqrt(sq)
        return w[0] * s, w[1] * s, w[2] * s
    return w


@njit(cache=True, error_model="numpy")
def dexp_inv(u, w):
    """u̇ for q = q0 ⊗ exp(u) moving with body velocity ω: ω + ½ u × ω + c(θ) u × (u × ω).

    c(θ) = (1 − (θ/2) cot(θ/2)) / θ², θ = |u| (its series 1/12 + θ²/720 below θ = 1e-3).
    """
    u0, u1, u2 = u
    w0, w1, w2 = w
    x0 = u1 * w2 - u2 * w1
    x1 = u2 * w0 - u0 * w2
    x2 = u0 * w1 - u1 * w0
    y0 = u1 * x2 - u2 * x1
    y1 = u2 * x0 - u0 * x2
    y2 = u0 * x1 - u1 * x0
    th2 = u0 * u0 + u1 * u1 + u2 * u2
    if th2 < 1e-6:
        c = 1.0 / 12.0 + th2 / 720.0
    else:
        th = math.sqrt(th2)
        half = 0.5 * th
        c = (1.0 - half * math.cos(half) / math.sin(half)) / th2
    return w0 + 0.5 * x0 + c * y0, w1 + 0.5 * x1 + c * y1, w2 + 0.5 * x2 + c * y2
