"""chrono_euler against Project Chrono's own per-step arithmetic, its order, and its relation to mujoco_euler.

``chrono_step`` below is written from the Chrono source (projectchrono/chrono
7689fbc02d12, Chrono 10.0.0), in Chrono's variables and frames, in plain
Python floats: ChTimestepperEulerImplicitLinearized::OnAdvance
(src/chrono/timestepper/ChTimestepperImplicit.cpp), ChBody::IntLoadResidual_F,
IntLoadResidual_Mv, ComputeGyro, IntStateIncrement (src/chrono/physics/
ChBody.cpp), ChVariablesBodyOwnMass::SetBodyInertia and
ComputeMassInverseTimesVector (src/chrono/solver/ChVariablesBodyOwnMass.cpp,
the PSOR solver's first and, without constraints, only action), Eigen's 3×3
inverse (cofactors over the determinant), ChQuaternion::SetFromRotVec and
Cross (src/chrono/core/ChQuaternion.h), ChVector3 Vcross.  pychrono (the real
engine) is not on PyPI (the "pychrono" there is an unrelated package), so
this transcription is the reference.
"""

import math

import numpy as np
import pytest

from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.rigid_body import gravity_torque

CHRONO = METHODS["chrono_euler"]
MUJOCO = METHODS["mujoco_euler"]


def body_of(inertia, mgc=(0.0, 0.0, 0.0)):
    """A gyrolab body: (I1, I2, I3, mgl = M g c3, M g c1, M g c2, no drive)."""
    return (*map(float, inertia), float(mgc[2]), float(mgc[0]), float(mgc[1]), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


# ---------------------------------------------------------------- Chrono, transcribed


def eigen_inverse33(m):
    """Eigen's compute_inverse<…, 3>: cofactors of column 0, det = their dot with column 0, then cofactor · (1/det)."""

    def cof(i, j):
        i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
        return m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]

    c0 = (cof(0, 0), cof(1, 0), cof(2, 0))
    det = (c0[0] * m[0][0] + c0[1] * m[1][0]) + c0[2] * m[2][0]
    invdet = 1.0 / det
    # result(i, j) = cofactor(j, i) * invdet (the adjugate is the transposed cofactor matrix)
    return [[cof(j, i) * invdet for j in range(3)] for i in range(3)]


def mat_vec(m, v):
    return [(m[i][0] * v[0] + m[i][1] * v[1]) + m[i][2] * v[2] for i in range(3)]


def vcross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def set_from_rot_vec(v):
    theta_squared = (v[0] * v[0] + v[1] * v[1]) + v[2] * v[2]
    if theta_squared > 1e-30:
        theta = math.sqrt(theta_squared)
        half_theta = theta / 2
        k = math.sin(half_theta) / theta
        return [math.cos(half_theta), v[0] * k, v[1] * k, v[2] * k]
    return [1.0, v[0] * 0.5, v[1] * 0.5, v[2] * 0.5]


def cross_quat(qa, qb):
    w = qa[0] * qb[0] - qa[1] * qb[1] - qa[2] * qb[2] - qa[3] * qb[3]
    x = qa[0] * qb[1] + qa[1] * qb[0] - qa[3] * qb[2] + qa[2] * qb[3]
    y = qa[0] * qb[2] + qa[2] * qb[0] + qa[3] * qb[1] - qa[1] * qb[3]
    z = qa[0] * qb[3] + qa[3] * qb[0] - qa[2] * qb[1] + qa[1] * qb[2]
    return [w, x, y, z]


def chrono_step(W, rot, dt, inertia, Xtorque):
    """One OnAdvance of an unconstrained ChBody's rotation: W = GetAngVelLocal(), rot = GetRot(),
    inertia = the 3×3 body inertia, Xtorque = the applied torque, local frame, at the step start."""
    inv_inertia = eigen_inverse33(inertia)  # ChVariablesBodyOwnMass::SetBodyInertia
    gyro = vcross(W, mat_vec(inertia, W))  # ChBody::ComputeGyro (in Update, before the step)
    R = [0.0 + dt * (Xtorque[i] - gyro[i]) for i in range(3)]  # LoadResidual_F(R, dt): R += c (Xtorque - gyro)
    Iw = mat_vec(inertia, W)  # LoadResidual_Mv(R, V, 1.0): R += c I w
    R = [R[i] + Iw[i] * 1.0 for i in range(3)]
    V = mat_vec(inv_inertia, R)  # PSOR: q = M^-1 fb; no constraints, no iterations act
    Dv = [V[i] * dt for i in range(3)]  # X += V * dt -> IntStateIncrement
    rel_q = set_from_rot_vec(Dv)
    return V, cross_quat(rot, rel_q)  # q_new = q_old * rel_q, not normalised


def chrono_of(w, q, dt, body):
    inertia = [[body[0], 0.0, 0.0], [0.0, body[1], 0.0], [0.0, 0.0, body[2]]]
    return chrono_step(list(w), list(q), dt, inertia, list(gravity_torque.py_func(tuple(q), body)))


# ---------------------------------------------------------------- helpers


def ulps(a, b, scale):
    """max |a − b| in units of the spacing of ``scale`` (the vector's size: no blow-up at a small component)."""
    return float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float))) / np.spacing(scale))


def random_cases(n, seed=24):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        inertia = rng.uniform(0.2, 3.0, 3)
        mgc = rng.normal(size=3) * rng.choice([0.0, 1.0, 30.0])
        w = tuple(rng.normal(size=3) * rng.choice([0.1, 5.0, 300.0]))
        q = rng.normal(size=4)
        q = tuple(q / np.linalg.norm(q))
        dt = float(rng.choice([1e-4, 1e-3, 1e-2]))
        yield w, q, dt, body_of(inertia, mgc)


# ---------------------------------------------------------------- conformance


def step_scales(w, q, w1, dt, body):
    """The sizes the step's rounding is relative to: ω's (|ω|, |ω₁| and the kicks h|I⁻¹τ| and
    h|ω||Iω|/min I, the size of Vcross's products, which can dwarf both at a large h|ω| and cancel
    in ω × Iω) and q's (1, or the turn h|ω₁|
    when it is above 1 rad: its sin and cos carry an error of an ulp of the angle)."""
    inertia = np.array(body[:3])
    torque = np.array(gravity_torque.py_func(tuple(q), body)) / inertia
    # Vcross's products ω_j (I ω)_k, before they cancel in ω × Iω, over the smallest I_i
    gyro = np.linalg.norm(w) * np.linalg.norm(inertia * np.array(w)) / inertia.min()
    sizes = (np.linalg.norm(w), np.linalg.norm(w1), dt * np.linalg.norm(torque), dt * gyro)
    return max(sizes), max(1.0, dt * np.linalg.norm(w1))


def test_one_step_matches_chrono_arithmetic_to_a_few_ulp():
    """Over 2000 random states, bodies (centre of mass anywhere, |ω| up to ~1000 rad/s) and steps
    (1e-4 .. 1e-2 s): ω within 4 ulp of its scale, q within 4 ulp of its scale (step_scales) of
    Chrono's own arithmetic (measured: 3 and 2.3).  The differences: Eigen's cofactor inverse of
    diag(I) applied to I ω + h (τ − gyro) vs ω + h (τ − gyro)/I, Vcross vs (I3 − I2) ω2 ω3, and
    Cross's term order vs quat_mul's."""
    worst_w = worst_q = 0.0
    for w, q, dt, body in random_cases(2000):
        w1, q1 = CHRONO.step(w, q, dt, body)
        cw, cq = chrono_of(w, q, dt, body)
        sw, sq = step_scales(w, q, cw, dt, body)
        worst_w = max(worst_w, ulps(w1, cw, sw))
        worst_q = max(worst_q, ulps(q1, cq, sq))
    assert worst_w <= 4.0, worst_w
    assert worst_q <= 4.0, worst_q


def test_trajectory_follows_chrono_and_is_never_normalised():
    """1000 steps of a heavy asymmetric top: the state stays within rounding of the transcription
    (relative 1e-11), and |q| is left wherever rounding takes it, as in Chrono."""
    body = body_of((1.0, 2.0, 3.0), (0.3, -0.2, 9.81))
    w, q = (2.0, -1.0, 10.0), (math.cos(0.3), math.sin(0.3), 0.0, 0.0)
    cw, cq = list(w), list(q)
    for _ in range(1000):
        w, q = CHRONO.step(w, q, 1e-3, body)
        cw, cq = chrono_of(cw, cq, 1e-3, body)
    assert np.allclose(w, cw, rtol=1e-11, atol=1e-11 * np.linalg.norm(cw))
    assert np.allclose(q, cq, rtol=0, atol=1e-11)
    # a q off the unit sphere stays off it: Chrono never rescales (mujoco_euler does, mju_normalize4)
    q_big = tuple(1.001 * x for x in q)
    assert abs(np.linalg.norm(CHRONO.step(w, q_big, 1e-3, body)[1]) - 1.001) < 1e-14
    assert abs(np.linalg.norm(chrono_of(w, q_big, 1e-3, body)[1]) - 1.001) < 1e-14
    assert abs(np.linalg.norm(MUJOCO.step(w, q_big, 1e-3, body)[1]) - 1.0) < 1e-14


def test_small_rotation_branch():
    """SetFromRotVec below θ² = 1e-30 is (1, v/2): ω = 0 leaves q as it is, bit for bit."""
    q = (0.5, 0.5, -0.5, 0.5)
    w, q1 = CHRONO.step((0.0, 0.0, 0.0), q, 1e-3, body_of((1.0, 2.0, 3.0)))
    assert w == (0.0, 0.0, 0.0) and q1 == q
    tiny = (1e-14, 0.0, 0.0)  # θ = 1e-17: (1, θ/2, 0, 0)
    assert CHRONO.chrono_rotvec_quat(*tiny) == (1.0, 0.5e-14, 0.0, 0.0)


# ---------------------------------------------------------------- order


def test_measured_order_is_one():
    """Error at t = 0.5 s of a heavy asymmetric top against rk4 at 2e-5: halving dt halves it
    (measured slopes 1.011 and 1.006)."""
    body = body_of((1.0, 1.5, 2.5), (0.2, 0.1, 5.0))
    w0, q0 = (1.0, -2.0, 8.0), (math.cos(0.2), 0.0, math.sin(0.2), 0.0)

    def run(step, dt, n):
        w, q = w0, q0
        for _ in range(n):
            w, q = step(w, q, dt, body)
        return np.array((*w, *q))

    ref = run(METHODS["rk4"].step, 2e-5, 25000)
    errs = [np.linalg.norm(run(CHRONO.step, 0.5 / n, n) - ref) for n in (250, 500, 1000)]
    slopes = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(0.9 < s < 1.1 for s in slopes), slopes
    assert CHRONO.ORDER == 1


# ---------------------------------------------------------------- relation to mujoco_euler


def test_same_map_as_mujoco_euler_from_a_unit_quaternion():
    """From a q within 1e-15 of unit norm (where mju_normalize4 does nothing) the velocity update is
    mujoco_euler's bit for bit and the quaternion agrees to 2 ulp of 1 (v sin(θ/2)/θ vs v̂ sin(θ/2));
    measured max 1.03 ulp (of max(1, h|ω|)) over 2000 random cases."""
    worst = 0.0
    for w, q, dt, body in random_cases(2000, seed=7):
        if abs(math.sqrt(sum(x * x for x in q)) - 1.0) > 1e-15:
            continue
        cw, cq = CHRONO.step(w, q, dt, body)
        mw, mq = MUJOCO.step(w, q, dt, body)
        assert cw == mw
        worst = max(worst, ulps(cq, mq, step_scales(w, q, cw, dt, body)[1]))
    assert worst <= 2.0, worst


def test_differs_from_mujoco_euler_by_the_normalisation_only():
    """Off the unit sphere: chrono_euler's step is mujoco_euler's on q/|q| (the torque at γ(q) is
    |q|² times γ(q/|q|), so the velocities agree to |q|² − 1) with its quaternion scaled by |q|."""
    body = body_of((1.0, 2.0, 3.0), (0.0, 0.0, 2.0))
    w, q = (0.3, 0.4, 5.0), (0.6, 0.0, 0.8, 0.0)
    s = 1.0 + 1e-9
    q_off = tuple(s * x for x in q)
    cw, cq = CHRONO.step(w, q_off, 1e-3, body)
    mw, mq = MUJOCO.step(w, q_off, 1e-3, body)
    assert np.allclose(cw, mw, rtol=0, atol=1e-11)
    assert np.allclose(np.array(cq) / s, mq, rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", ["chrono_euler", "mujoco_euler"])
def test_norm_drift_over_many_steps(name):
    """10⁴ steps of the free asymmetric body from a unit q: mujoco_euler's |q| stays within a few ulp
    of 1 (normalised each step; measured 1.1e-15); chrono_euler's wanders by rounding (a random
    walk, measured 3.8e-15) but stays below 1e-13."""
    step = METHODS[name].step
    body = body_of((1.0, 2.0, 3.0))
    w, q = (0.1, 3.0, 0.2), (1.0, 0.0, 0.0, 0.0)
    drift = 0.0
    for _ in range(10000):
        w, q = step(w, q, 1e-3, body)
        drift = max(drift, abs(math.sqrt(sum(x * x for x in q)) - 1.0))
    assert drift < (1e-13 if name == "chrono_euler" else 2e-15), drift


def test_no_damping_no_speed_limit_by_default():
    """ChBody's limit_speed is off (SetLimitSpeed(true) would clamp |ω| to max_wvel = 2π rad/s) and a
    ChBody has no damping: 1000 rad/s about a principal axis of a free body is carried exactly, and q
    turns by h|ω| about it."""
    w0 = (0.0, 0.0, 1000.0)
    w, q = CHRONO.step(w0, (1.0, 0.0, 0.0, 0.0), 1e-3, body_of((1.0, 2.0, 3.0)))
    assert w == w0
    assert q == pytest.approx((math.cos(0.5), 0.0, 0.0, math.sin(0.5)), abs=2e-16)
