"""rk4: classic RK4 on the coupled system (ω, unit quaternion), normalised each step.

q̇ = ½ q ⊗ (0, ω) and I ω̇ = τ(q) − ω × Iω, both stages of every RK4
substep see the torque of the current stage orientation.  The quaternion is
renormalised after each step (a projection, so not symplectic).
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import euler_rhs, torque_at
from ..rotation import quat_mul, quat_normalize

ORDER = 4
SYMPLECTIC = False
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def _rates(w, q, tau, body):
    """(ω̇, q̇) under the body-frame torque tau."""
    wd = euler_rhs(w, tau, body)
    qd = quat_mul(q, (0.0, w[0], w[1], w[2]))
    return wd, (0.5 * qd[0], 0.5 * qd[1], 0.5 * qd[2], 0.5 * qd[3])


@njit(cache=True, error_model="numpy")
def _rhs_at(w, q, t, body):
    return _rates(w, q, torque_at(q, t, body), body)


@njit(cache=True, error_model="numpy")
def _stage(w, q, h, k):
    kw, kq = k
    return (
        (w[0] + h * kw[0], w[1] + h * kw[1], w[2] + h * kw[2]),
        (q[0] + h * kq[0], q[1] + h * kq[1], q[2] + h * kq[2], q[3] + h * kq[3]),
    )


@njit(cache=True, error_model="numpy")
def _combine(w, q, dt, k1, k2, k3, k4):
    """The RK4 update from the four stage slopes, the quaternion renormalised."""
    s = dt * (1.0 / 6.0)  # a multiplication: dt / 6 would be one more division a step (issue 22)
    w_next = (
        w[0] + s * (k1[0][0] + 2.0 * (k2[0][0] + k3[0][0]) + k4[0][0]),
        w[1] + s * (k1[0][1] + 2.0 * (k2[0][1] + k3[0][1]) + k4[0][1]),
        w[2] + s * (k1[0][2] + 2.0 * (k2[0][2] + k3[0][2]) + k4[0][2]),
    )
    q_next = (
        q[0] + s * (k1[1][0] + 2.0 * (k2[1][0] + k3[1][0]) + k4[1][0]),
        q[1] + s * (k1[1][1] + 2.0 * (k2[1][1] + k3[1][1]) + k4[1][1]),
        q[2] + s * (k1[1][2] + 2.0 * (k2[1][2] + k3[1][2]) + k4[1][2]),
        q[3] + s * (k1[1][3] + 2.0 * (k2[1][3] + k3[1][3]) + k4[1][3]),
    )
    return w_next, quat_normalize(q_next)


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): each stage sees the torque at its own time
    (t, t + dt/2, t + dt/2, t + dt), so the drive keeps the fourth order."""
    h = 0.5 * dt
    k1 = _rhs_at(w, q, t, body)
    w2, q2 = _stage(w, q, h, k1)
    k2 = _rhs_at(w2, q2, t + h, body)
    w3, q3 = _stage(w, q, h, k2)
    k3 = _rhs_at(w3, q3, t + h, body)
    w4, q4 = _stage(w, q, dt, k3)
    k4 = _rhs_at(w4, q4, t + dt, body)
    return _combine(w, q, dt, k1, k2, k3, k4)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
