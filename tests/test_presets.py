"""The engine presets with their hidden defaults (issue 23): physx_default, newton_semi, midpoint_free.

- each preset against an independent numpy transcription of the engine's own update, written as the
  engine writes it (PhysX and Newton in the lab frame, with the world inertia and the lab torque of the
  weight; MuJoCo's midpoint solved by scipy's root finder and turned by a rotation matrix), for 3 steps of
  a tumbling asymmetric body whose centre of mass is off every axis;
- the hidden defaults act as stated: PhysX's cap clamps |ω| to 100 rad/s and its damping multiplies ω by
  max(0, 1 − c h) per step (not exp(−c h)); Newton's multiplies by 1 − c h, unclamped, after the rotation;
- the declared order, measured on a free asymmetric body against DOP853 of the equation each converges to
  (and midpoint_free's first order with a torque, which it holds over the step).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import root

from gyrolab.kernels.body import Body
from gyrolab.kernels.registry import METHODS

from transcribe import lab_torque, qmul, rot

PRESETS = ("physx_default", "newton_semi", "midpoint_free")

# an asymmetric body with its centre of mass off every axis (kg m², N m), tumbling at ~2.5 Hz
HEAVY_BODY = Body(2e-4, 3e-4, 1.5e-4, mgl=0.02, mgc1=0.015, mgc2=-0.01)
FREE_BODY = Body(1e-4, 3e-4, 2e-4, 0.0)
W0 = (6.0, -4.0, 14.0)
Q0 = tuple(np.array([0.9, 0.2, -0.3, 0.25]) / np.linalg.norm([0.9, 0.2, -0.3, 0.25]))


def as_body(body):
    return tuple(map(float, body))


# ---------------------------------------------------------------- the engines' updates, transcribed


def physx_lab_step(w_lab, q, h, body, damping=0.05, max_w=100.0):
    """Sc::BodySim::updateForces, Dy::bodyCoreComputeUnconstrainedVelocity, Dy::integrateCore (world ω)."""
    R = rot(q)
    inv_inertia_lab = R @ np.diag(1.0 / np.array(body[:3])) @ R.T
    w = w_lab + h * inv_inertia_lab @ lab_torque(q, body)
    w = w * max(1.0 - damping * h, 0.0)
    if w @ w > max_w**2:
        w = w * math.sqrt(max_w**2 / (w @ w))
    theta = np.linalg.norm(w)
    s = math.sin(0.5 * h * theta) / theta
    out = qmul(np.concatenate(([0.0], w * s)), q) + q * math.cos(0.5 * h * theta)
    return w, out / np.linalg.norm(out)


def newton_lab_step(w_lab, q, h, body, damping=0.05):
    """newton/_src/solvers/solver.py integrate_rigid_body's angular part (world ω stored)."""
    R = rot(q)
    inertia = np.array(body[:3])
    wb = R.T @ w_lab
    tb = R.T @ lab_torque(q, body) - np.cross(wb, inertia * wb)
    w1 = R @ (wb + tb / inertia * h)
    r1 = q + qmul(np.concatenate(([0.0], w1)), q) * 0.5 * h
    return w1 * (1.0 - damping * h), r1 / np.linalg.norm(r1)


def expm_so3(v):
    """Rot(v) as a matrix (Rodrigues)."""
    theta = np.linalg.norm(v)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]) / theta
    return np.eye(3) + math.sin(theta) * K + (1 - math.cos(theta)) * K @ K


def midpoint_residual(wm, w, tau, h, inertia):
    """f = (2/h) I (ω_m − ω) + ω_m × I ω_m − τ: MuJoCo's midpoint equation for ω_m = (ω + ω')/2."""
    return 2.0 / h * inertia * (wm - w) + np.cross(wm, inertia * wm) - tau


def mujoco_midpoint_newton(w, tau, h, inertia):
    """engine_forward.c midpointNewton transcribed: Newton from ω_m = ω, stop at |f| < 1e-13 (1 + (2/h)|Iω_m|),
    backtracking line search (≤ 20 halvings), ≤ 100 iterations; numpy's LU solve for J δ = −f."""
    wm = w.copy()
    dI = np.array([inertia[2] - inertia[1], inertia[0] - inertia[2], inertia[1] - inertia[0]])
    for _ in range(100):
        f = midpoint_residual(wm, w, tau, h, inertia)
        if np.linalg.norm(f) < 1e-13 * (1 + 2.0 / h * np.linalg.norm(inertia * wm)):
            break
        a, b, c = wm * dI[0], wm * dI[1], wm * dI[2]  # ∂(ω × Iω)/∂ω, rows
        dcross = [[0.0, a[2], a[1]], [b[2], 0.0, b[0]], [c[1], c[0], 0.0]]
        J = np.diag(2.0 / h * inertia) + np.array(dcross)
        delta = np.linalg.solve(J, -f)
        step = 1.0
        for _ in range(20):
            if np.linalg.norm(midpoint_residual(wm + step * delta, w, tau, h, inertia)) < np.linalg.norm(f):
                wm = wm + step * delta
                break
            step *= 0.5
    return wm


def midpoint_step(w, R, h, body, solve="mujoco"):
    """MuJoCo 3.7-3.10's free-body midpoint rule: ω' = 2 ω_m − ω with τ held at the start; R' = R Rot(h ω_m).
    ``solve``: "mujoco" (its Newton, transcribed) or "exact" (scipy's root, then Newton to the last bit)."""
    inertia = np.array(body[:3])
    tau = R.T @ lab_torque_matrix(R, body)
    if solve == "mujoco":
        wm = mujoco_midpoint_newton(w, tau, h, inertia)
    else:
        wm = root(midpoint_residual, w, args=(w, tau, h, inertia), method="hybr", tol=1e-15).x
    return 2 * wm - w, R @ expm_so3(h * wm)


def lab_torque_matrix(R, body):
    mg_c = np.array([body.mgc1, body.mgc2, body.mgl])
    return np.cross(R @ mg_c, [0.0, 0.0, -1.0])


# ---------------------------------------------------------------- the presets against the transcriptions


def preset_steps(name, w, q, h, body, n):
    out = []
    for _ in range(n):
        w, q = METHODS[name].step(w, q, h, as_body(body))
        out.append((np.array(w), np.array(q)))
    return out


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_physx_default_is_physx_lab_frame_update(h):
    """3 steps: body ω and q equal PhysX's world-frame update to rounding (measured ≤ 3.6e-16 on ω/|ω|, q)."""
    w_lab, q = rot(Q0) @ np.array(W0), np.array(Q0)
    for w, qq in preset_steps("physx_default", W0, Q0, h, HEAVY_BODY, 3):
        w_lab, q = physx_lab_step(w_lab, q, h, HEAVY_BODY)
        np.testing.assert_allclose(w, rot(q).T @ w_lab, rtol=0, atol=2e-15 * np.linalg.norm(w_lab))
        np.testing.assert_allclose(qq, q, rtol=0, atol=2e-15)


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_newton_semi_is_newton_lab_frame_update(h):
    """3 steps: body ω and q equal Newton's integrate_rigid_body to rounding (measured ≤ 9.6e-16 on ω/|ω|, q)."""
    w_lab, q = rot(Q0) @ np.array(W0), np.array(Q0)
    for w, qq in preset_steps("newton_semi", W0, Q0, h, HEAVY_BODY, 3):
        w_lab, q = newton_lab_step(w_lab, q, h, HEAVY_BODY)
        np.testing.assert_allclose(w, rot(q).T @ w_lab, rtol=0, atol=2e-15 * np.linalg.norm(w_lab))
        np.testing.assert_allclose(qq, q, rtol=0, atol=2e-15)


@pytest.mark.parametrize("body", [HEAVY_BODY, FREE_BODY], ids=["heavy_body", "free_body"])
@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_midpoint_free_is_mujocos_midpoint_rule(h, body):
    """3 steps: ω and R(q) equal MuJoCo's midpoint update transcribed in numpy (measured: ω bit-identical, R to
    5.6e-16); against the midpoint rule solved to the last bit (scipy) they agree to MuJoCo's Newton
    tolerance, residual < 1e-13 (1 + (2/h)|Iω_m|) N m (measured up to 2.8e-13 relative at h = 1e-2, where the
    absolute 1e-13 N m dominates for a 1e-4 kg m² body).  On the free body the kinetic energy and |Iω| are
    kept to 1e-13."""
    w, R = np.array(W0), rot(Q0)
    w_exact, R_exact = w, R
    inertia = np.array(body[:3])
    for wp, qp in preset_steps("midpoint_free", W0, Q0, h, body, 3):
        w_exact, R_exact = midpoint_step(w, R, h, body, solve="exact")  # one exact step from the same state
        w, R = midpoint_step(w, R, h, body)
        np.testing.assert_allclose(wp, w, rtol=0, atol=2e-15 * np.linalg.norm(w))
        np.testing.assert_allclose(rot(qp), R, rtol=0, atol=2e-15)
        # MuJoCo stops at |f| < 1e-13 (1 + (2/h)|Iω_m|): with this body's 1e-4 kg m² the absolute "1" (N m)
        # dominates, so ω_m = ω_exact + J⁻¹ f is off by up to 1e-13 (1 + (2/h)|Iω|) / ((2/h) I_min), ω' twice that
        bound = 2e-13 * (1 + 2.0 / h * np.linalg.norm(inertia * w_exact)) / (2.0 / h * inertia.min())
        np.testing.assert_allclose(wp, w_exact, rtol=0, atol=bound)
        np.testing.assert_allclose(rot(qp), R_exact, rtol=0, atol=2e-15 + h * bound)  # turned by h ω_m
        if body is FREE_BODY:
            assert abs(wp @ (inertia * wp) / (np.array(W0) @ (inertia * np.array(W0))) - 1) <= 1e-13
            assert abs(np.linalg.norm(inertia * wp) / np.linalg.norm(inertia * np.array(W0)) - 1) <= 1e-13


def test_midpoint_free_holds_the_torque_over_the_step():
    """MuJoCo's zero-order hold: the first step's ω' − ω is h I⁻¹ (τ(q0) − ω_m × I ω_m), τ at the start."""
    w, q = np.array(W0), np.array(Q0)
    h = 1e-2
    wp, _ = METHODS["midpoint_free"].step(W0, Q0, h, as_body(HEAVY_BODY))
    wp = np.array(wp)
    inertia = np.array(HEAVY_BODY[:3])
    wm = 0.5 * (w + wp)
    tau0 = rot(q).T @ lab_torque(q, HEAVY_BODY)
    np.testing.assert_allclose(inertia * (wp - w) / h, tau0 - np.cross(wm, inertia * wm), rtol=0, atol=1e-12)


# ---------------------------------------------------------------- the hidden defaults act as stated


def test_physx_cap_clamps_omega_to_100():
    """A free box spun at 300 rad/s: after the first step |ω| is 100 rad/s (damped, then capped), after n steps
    100 (1 − c h)^(n − 1) (the cap no longer acts, the damping does); no gyroscopic term, so the direction of ω
    in the body does not move."""
    mod = METHODS["physx_default"]
    assert mod.MAX_ANGULAR_VELOCITY == 100.0 and mod.ANGULAR_DAMPING == 0.05
    h = 1e-3
    w0 = 300.0 * np.array([0.6, 0.0, 0.8])
    w, q = tuple(w0), (1.0, 0.0, 0.0, 0.0)
    for n in range(1, 11):
        w, q = mod.step(w, q, h, as_body(FREE_BODY))
        assert np.linalg.norm(w) == pytest.approx(100.0 * (1 - 0.05 * h) ** (n - 1), rel=1e-14)
        np.testing.assert_allclose(np.array(w) / np.linalg.norm(w), w0 / 300.0, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", ["physx_default", "newton_semi"])
def test_damping_factor_per_step_is_one_minus_c_h(name):
    """A free box spinning about a principal axis (no gyroscopic change) below the cap: ω3 falls by exactly
    1 − 0.05 h per step, not by exp(−0.05 h) (at h = 1e-2 they differ by 1.25e-7)."""
    h, c = 1e-2, METHODS[name].ANGULAR_DAMPING
    assert c == 0.05
    w, q = (0.0, 0.0, 50.0), (1.0, 0.0, 0.0, 0.0)
    for _ in range(5):
        w_next, q = METHODS[name].step(w, q, h, as_body(FREE_BODY))
        assert w_next[0] == 0.0 and w_next[1] == 0.0
        assert w_next[2] / w[2] == pytest.approx(1.0 - c * h, rel=1e-15, abs=0)
        assert abs(w_next[2] / w[2] - math.exp(-c * h)) > 1e-7
        w = w_next


def test_physx_damping_factor_is_clamped_at_zero_newton_is_not():
    """fsel(1 − c h, 1 − c h, 0) in PhysX: c h > 1 stops the body; Newton's 1 − c h turns ω around."""
    physx, newton = METHODS["physx_default"], METHODS["newton_semi"]
    body = as_body(FREE_BODY)
    w, _ = physx.physx_step((0.0, 0.0, 50.0), (1.0, 0.0, 0.0, 0.0), 1e-2, body, 200.0, 100.0)
    assert w == (0.0, 0.0, 0.0)
    w, _ = newton.newton_step((0.0, 0.0, 50.0), (1.0, 0.0, 0.0, 0.0), 1e-2, body, 200.0)
    assert w == (0.0, 0.0, -50.0)


def test_newton_turns_by_the_undamped_omega_with_no_cap():
    """Newton damps after the rotation and has no cap: spun at 1000 rad/s about e3 from q = 1, one step turns
    the body by 2 atan(h ω3 / 2) with the undamped ω3 (the first-order quaternion step, normalised), and
    ω3 becomes 1000 (1 − c h)."""
    h = 1e-3
    w, q = METHODS["newton_semi"].step((0.0, 0.0, 1000.0), (1.0, 0.0, 0.0, 0.0), h, as_body(FREE_BODY))
    assert w[2] == pytest.approx(1000.0 * (1 - 0.05 * h), rel=1e-15)
    assert 2 * math.atan2(q[3], q[0]) == pytest.approx(2 * math.atan(h * 1000.0 / 2), rel=1e-14)


# ---------------------------------------------------------------- declared order


def rhs(_t, y, body, damping, gyro):
    """(ω, R row-major)' for I ω̇ = τ(R) − [gyro] ω × Iω − damping I ω, Ṙ = R [ω]×."""
    inertia = np.array(body[:3])
    w, R = y[:3], y[3:].reshape(3, 3)
    tau = R.T @ lab_torque_matrix(R, body)
    dw = (tau - (np.cross(w, inertia * w) if gyro else 0.0)) / inertia - damping * w
    Wx = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return np.concatenate((dw, (R @ Wx).ravel()))


def measured_order(name, body, w0, q0, t_end, dts, step_loop, damping=0.0, gyro=True):
    y0 = np.concatenate((w0, rot(q0).ravel()))
    sol = solve_ivp(rhs, (0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13, args=(body, damping, gyro))
    w_ref, R_ref = sol.y[:3, -1], sol.y[3:, -1].reshape(3, 3)
    errors = []
    for dt in dts:
        w, q = step_loop(name)(tuple(w0), tuple(q0), dt, as_body(body), round(t_end / dt))
        errors.append(max(np.abs(rot(q) - R_ref).max(), np.abs(np.array(w) - w_ref).max() / np.linalg.norm(w0)))
    return np.polyfit(np.log(dts), np.log(errors), 1)[0], errors


# name: (body, damping and gyroscopic term of the equation it converges to, expected order)
ORDER_CASES = {
    "physx_default": (FREE_BODY, 0.05, False, METHODS["physx_default"].ORDER),
    "newton_semi": (FREE_BODY, 0.05, True, METHODS["newton_semi"].ORDER),
    "midpoint_free": (FREE_BODY, 0.0, True, METHODS["midpoint_free"].FREE_ORDER),
    "midpoint_free_heavy": (HEAVY_BODY, 0.0, True, METHODS["midpoint_free"].ORDER),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", ORDER_CASES)
def test_declared_order_on_a_free_asymmetric_body(case, step_loop):
    """Final state after 1 s (ω/|ω0| and R) against DOP853, dt = 2e-3 .. 1.25e-4: log-log slope within 0.1 of
    the declared order (FREE_ORDER on the free body for midpoint_free; its ORDER with the weight's torque,
    held over each step).  The tumbling box (|ω| ≈ 17 rad/s) stays below PhysX's 100 rad/s cap.  Measured
    slopes: physx_default 1.000, newton_semi 0.985, midpoint_free 2.000 (free) and 0.987 (with the torque)."""
    body, damping, gyro, order = ORDER_CASES[case]
    name = case.removesuffix("_heavy")
    dts = 2e-3 / 2.0 ** np.arange(5)
    slope, errors = measured_order(name, body, np.array(W0), np.array(Q0), 1.0, dts, step_loop, damping, gyro)
    assert abs(slope - order) <= 0.1, (slope, errors)
