"""The engine presets of issue 23 item 3: physx_gyro, brax_spring, bepu_conserve_momentum.

- each preset against an independent numpy transcription of the engine's own update, written in the
  engine's own variables (world-frame ω, the world inverse inertia, the lab torque of the weight), over
  random states and bodies (centre of mass off every axis), to a few ulp;
- the hidden defaults act as stated: PhysX's cap and damping act before its gyroscopic step (which keeps
  |L|, not |ω|); Brax's ang_damping is 0 (ω·exp(0) = ω bit for bit) and exp(c h) when set; Bepu's
  ConserveMomentum keeps the world angular momentum of a free body to rounding while ω drifts toward the
  axis of least inertia (the kinetic energy rises).
"""

import math

import numpy as np
import pytest

from gyrolab.kernels.body import Body
from gyrolab.kernels.registry import METHODS

from transcribe import lab_torque, qmul, rot

RNG_SEED = 23


def random_cases(n, free=False, scale=30.0):
    """n (ω body, q, body) with random inertias (kg m²), centre of mass and rates up to ~``scale`` rad/s."""
    rng = np.random.default_rng(RNG_SEED)
    out = []
    for _ in range(n):
        inertia = rng.uniform(0.5e-4, 4e-4, 3)
        mg = (0.0, 0.0, 0.0) if free else rng.uniform(-0.03, 0.03, 3)
        body = Body(*inertia, mgl=mg[2], mgc1=mg[0], mgc2=mg[1])
        q = rng.normal(size=4)
        out.append((tuple(rng.uniform(-scale, scale, 3)), tuple(q / np.linalg.norm(q)), body))
    return out


def as_body(body):
    return tuple(map(float, body))


def run(name, w, q, h, body, n):
    """The preset's n steps from (ω, q): [(ω body, q)] after each."""
    out = []
    for _ in range(n):
        w, q = METHODS[name].step(w, q, h, as_body(body))
        out.append((np.array(w), np.array(q)))
    return out


def check_lab(name, lab_step, h, cases, n_steps=3, ulps=8):
    """The preset against ``lab_step`` (world ω, q) -> (world ω, q) from the same state for n_steps;
    returns the largest difference seen in units of eps·|ω| (ω) and eps (q)."""
    eps = np.finfo(float).eps
    worst = 0.0
    for w0, q0, body in cases:
        w_lab, q = rot(q0) @ np.array(w0), np.array(q0)
        for w, qq in run(name, w0, q0, h, body, n_steps):
            w_lab, q = lab_step(w_lab, q, h, body)
            dw = np.abs(w - rot(q).T @ w_lab).max() / (eps * np.linalg.norm(w_lab))
            dq = np.abs(qq - q).max() / eps
            worst = max(worst, dw, dq)
    assert worst <= ulps, worst
    return worst


# ---------------------------------------------------------------- PhysX 5.6.1 with eENABLE_GYROSCOPIC_FORCES


def physx_gyro_lab_step(w_lab, q, h, body, damping=0.05, max_w=100.0):
    """ScBodySim updateForces, DyBodyCoreIntegrator bodyCoreComputeUnconstrainedVelocity,
    DyRigidBodyToSolverBody copyToSolverBodyData (gyroscopicForces), DyBodyCoreIntegrator integrateCore."""
    R = rot(q)
    inv_inertia = 1.0 / np.array(body[:3])  # PxsBodyCore::inverseInertia
    w = w_lab + h * (R @ np.diag(inv_inertia) @ R.T) @ lab_torque(q, body)
    w = w * max(1.0 - damping * h, 0.0)
    if w @ w > max_w**2:
        w = w * math.sqrt(max_w**2 / (w @ w))
    # copyToSolverBodyData
    local_inertia = np.where(inv_inertia == 0.0, 0.0, 1.0 / inv_inertia)
    local_ang_vel = R.T @ w  # globalPose.q.rotateInv(ang)
    orig_mom = local_inertia * local_ang_vel
    torque = -np.cross(local_ang_vel, orig_mom)
    new_mom = orig_mom + torque * h
    denom = np.linalg.norm(new_mom)
    ratio = np.linalg.norm(orig_mom) / denom if denom > 0.0 else 0.0
    new_mom = new_mom * ratio
    w = w + R @ (inv_inertia * new_mom - local_ang_vel)
    # integrateCore: closed form quaternion integrator
    theta = np.linalg.norm(w)
    s = math.sin(0.5 * h * theta) / theta
    out = qmul(np.concatenate(([0.0], w * s)), q) + q * math.cos(0.5 * h * theta)
    return w, out / np.linalg.norm(out)


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_physx_gyro_is_physx_lab_frame_update(h):
    """3 steps from 20 random states and bodies (rates up to 30 rad/s, and up to 200 rad/s so that the cap
    acts): body ω and q equal PhysX's world-frame update to a few ulp (measured ≤ 4.9 eps·|ω| on ω, eps on q)."""
    check_lab("physx_gyro", physx_gyro_lab_step, h, random_cases(10))
    check_lab("physx_gyro", physx_gyro_lab_step, h, random_cases(10, scale=200.0))


def test_physx_gyro_defaults_and_step_order():
    """Damping 0.05/s and the 100 rad/s cap are physx_default's (Sc::BodyCore::BodyCore); the cap acts before
    the gyroscopic step, which keeps |L| of a free body, so |ω| may end off the cap; with the flag the only
    difference from physx_default is that step (ω × Iω = 0 on a principal axis: bit-identical there)."""
    gyro, default = METHODS["physx_gyro"], METHODS["physx_default"]
    assert (gyro.ANGULAR_DAMPING, gyro.MAX_ANGULAR_VELOCITY) == (0.05, 100.0)
    free = Body(1e-4, 3e-4, 2e-4, 0.0)
    h = 1e-3
    # on a principal axis: both give ω3 (1 − c h), the gyroscopic step only PhysX's rounding (I = 1/(1/I),
    # ω + (I⁻¹ L − ω): measured 1 ulp on ω3), and the same q
    w_axis = (0.0, 0.0, 50.0)
    (w, q), (wd, qd) = (m.step(w_axis, (1.0, 0.0, 0.0, 0.0), h, free) for m in (gyro, default))
    assert wd[2] == 50.0 * (1.0 - 0.05 * h) and w[:2] == wd[:2] == (0.0, 0.0)
    assert w[2] == pytest.approx(wd[2], rel=2 * np.finfo(float).eps)
    np.testing.assert_allclose(q, qd, rtol=0, atol=2 * np.finfo(float).eps)
    # above the cap, off the axes: capped to 100 rad/s, then the |L|-keeping gyroscopic step
    w0 = (120.0, -90.0, 160.0)
    capped = np.array(w0) * (1 - 0.05 * h)
    capped *= math.sqrt(100.0**2 / (capped @ capped))
    inertia = np.array(free[:3])
    w, _ = gyro.step(w0, (1.0, 0.0, 0.0, 0.0), h, free)
    assert np.linalg.norm(inertia * np.array(w)) == pytest.approx(np.linalg.norm(inertia * capped), rel=1e-15)
    assert abs(np.linalg.norm(w) - 100.0) > 1e-3  # |ω| is not the cap after the gyroscopic step
    wd, _ = default.step(w0, (1.0, 0.0, 0.0, 0.0), h, free)
    assert np.linalg.norm(wd) == pytest.approx(100.0, rel=1e-15)


# ---------------------------------------------------------------- Brax 0.14.2 spring pipeline


def brax_lab_step(w_lab, q, h, body, ang_damping=0.0):
    """brax/spring/pipeline.py step (xd_i += xdd_i dt, xdd_i.ang = i_inv @ xf_i.ang) and
    brax/spring/integrator.py integrate's op, for one link without contacts (xdv_i = 0)."""
    R = rot(q)
    i_inv = R @ np.diag(1.0 / np.array(body[:3])) @ R.T  # com.inv_inertia
    ang = w_lab + (i_inv @ lab_torque(q, body)) * h
    ang = np.exp(ang_damping * h) * ang + 0.0
    rot_at_ang_quat = np.concatenate(([0.0], ang)) * 0.5 * h  # math.ang_to_quat(ang) * 0.5 * dt
    r = q + qmul(rot_at_ang_quat, q)
    return ang, r / np.linalg.norm(r)


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_brax_spring_is_brax_lab_frame_update(h):
    """3 steps from 20 random states and bodies: body ω and q equal Brax's world-frame update to a few ulp
    (measured ≤ 2.7 eps·|ω| on ω, eps on q)."""
    check_lab("brax_spring", brax_lab_step, h, random_cases(20))


def test_brax_spring_default_ang_damping_is_zero():
    """ang_damping defaults to 0 (mjcf._get_custom): a free body's ω is untouched bit for bit over 1000 steps
    (no ω × Iω either); Brax's environments' -0.05/s multiplies ω by exp(-0.05 h) per step, not 1 − 0.05 h."""
    brax = METHODS["brax_spring"]
    assert brax.ANG_DAMPING == 0.0
    free = Body(1e-4, 3e-4, 2e-4, 0.0)
    w0, q = (6.0, -4.0, 14.0), (1.0, 0.0, 0.0, 0.0)
    w = w0
    for _ in range(1000):
        w, q = brax.step(w, q, 1e-3, free)
    assert w == w0
    h = 1e-2
    wd, _ = brax.brax_step(w0, (1.0, 0.0, 0.0, 0.0), h, free, -0.05)
    assert np.array(wd) / np.array(w0) == pytest.approx(math.exp(-0.05 * h), rel=1e-15)
    assert abs(wd[0] / w0[0] - (1 - 0.05 * h)) > 1e-7
    # the first-order step turns the body by 2 atan(h|ω|/2), not h|ω|
    _, q1 = brax.step(w0, (1.0, 0.0, 0.0, 0.0), h, free)
    turned = 2 * math.atan2(math.sqrt(q1[1] ** 2 + q1[2] ** 2 + q1[3] ** 2), q1[0])
    assert turned == pytest.approx(2 * math.atan(h * np.linalg.norm(w0) / 2), rel=1e-14)


# ---------------------------------------------------------------- BEPUphysics v2.5 ConserveMomentum


def bepu_matrix(q):
    """Matrix3x3Wide.CreateFromQuaternion (rows X, Y, Z; Bepu's row vectors: v_world = v_local M)."""
    w, x, y, z = q
    x2, y2, z2 = x + x, y + y, z + z
    YY, ZZ, XX = y2 * y, z2 * z, x2 * x
    XY, ZW, XZ, YW, XW, YZ = x2 * y, z2 * w, x2 * z, y2 * w, x2 * w, y2 * z
    return np.array([[1 - YY - ZZ, XY + ZW, XZ - YW], [XY - ZW, 1 - XX - ZZ, YZ + XW], [XZ + YW, YZ - XW, 1 - XX - YY]])


def bepu_lab_step(w_lab, q, h, body, angular_damping=0.0):
    """The user's IntegrateVelocity (torque, the demos' damping), PoseIntegration.Integrate (with halfDt),
    RotateInverseInertia and IntegrateAngularVelocityConserveMomentum, in Bepu's row-vector conventions."""
    local_inv = np.diag(1.0 / np.array(body[:3]))  # BodyInertia.InverseInertiaTensor
    M = bepu_matrix(q)
    w = w_lab + h * ((lab_torque(q, body) @ M.T) @ local_inv) @ M  # world I⁻¹ τ, row vectors
    w = w * min(max(1.0 - angular_damping, 0.0), 1.0) ** h
    # Integrate(orientation, angularVelocity, halfDt): q ∘ Rot, Concatenate(a, b) = b ⊗ a (Hamilton)
    speed = np.linalg.norm(w)
    half_angle = speed * (0.5 * h)
    rot_q = np.concatenate(([math.cos(half_angle)], w * (math.sin(half_angle) / speed)))
    q_new = qmul(rot_q, q)
    q_new = q_new / np.linalg.norm(q_new) if speed > 1e-15 else q
    # IntegrateAngularVelocityConserveMomentum
    local_prev = w @ M.T  # TransformByTransposed
    local_inertia = np.linalg.inv(local_inv)  # Symmetric3x3Wide.Invert
    momentum = (local_prev @ local_inertia) @ M
    M_new = bepu_matrix(q_new)
    world_inv = M_new.T @ local_inv @ M_new  # RotationSandwich: Rᵀ-in-rows form of R I⁻¹ Rᵀ
    return momentum @ world_inv, q_new


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_bepu_conserve_momentum_is_bepu_update(h):
    """3 steps from 20 random states and bodies: body ω and q equal Bepu's world-frame update to a few ulp of
    |ω| scaled by the inertia ratio (≤ 8 here): ω = I⁻¹ (R L) carries L's rounding, eps |L| / I_min (measured
    ≤ 7.1 eps·|ω| at h = 1e-3, 14.0 at 1e-2)."""
    check_lab("bepu_conserve_momentum", bepu_lab_step, h, random_cases(20), ulps=32)


def test_bepu_conserve_momentum_keeps_L_and_drifts_to_least_inertia_axis():
    """Torque-free, 2·10⁴ steps of 1 ms of a body spun near its largest axis: the world L is kept to rounding
    (< 2e-11 relative), while the kinetic energy rises monotonically (ω drifts toward the axis of least inertia, as
    the enum's comment says; the exact motion keeps E): measured ×3.0 in 20 s, i.e. all the way to
    L²/(2 I_min) for this spin about the I3 = 3 I1 axis.  The default damping is the engine's 0 (the demos'
    .03 is the user's)."""
    bepu = METHODS["bepu_conserve_momentum"]
    assert bepu.ANGULAR_DAMPING == 0.0
    free = Body(1e-4, 2e-4, 3e-4, 0.0)
    inertia = np.array(free[:3])
    w, q = (1.0, 0.5, 20.0), (1.0, 0.0, 0.0, 0.0)
    L0 = rot(q) @ (inertia * np.array(w))
    energies = []
    drift = []
    for _ in range(20):
        for _ in range(1000):
            w, q = bepu.step(w, q, 1e-3, free)
        energies.append(0.5 * np.sum(inertia * np.square(w)))
        drift.append(np.abs(rot(q) @ (inertia * np.array(w)) - L0).max() / np.linalg.norm(L0))
    assert max(drift) < 2e-11, drift  # rounding only (measured: 5.0e-12, ~2.5e-16 per step)
    E0 = 0.5 * np.sum(inertia * np.square((1.0, 0.5, 20.0)))
    assert np.all(np.diff(energies) > 0) and energies[-1] > E0
    assert energies[-1] <= np.sum(L0**2) / (2 * inertia.min())
    # the demos' damping form: ω *= (1 − d)^h
    wd, _ = bepu.bepu_step((0.0, 0.0, 20.0), (1.0, 0.0, 0.0, 0.0), 1e-2, free, 0.03)
    assert wd[2] == pytest.approx(20.0 * 0.97**1e-2, rel=1e-15)
