"""seed_next: the 2014 write-up's scheme, exactly as docs/design.md states it.

Per step: torque from the orientation at t; classic RK4 on Euler's equations
with that torque frozen, giving ω(t+dt); then R(t+dt) = R(t) · CK(ω(t+dt) dt).
Source: the write-up's eq. (8) and its argument around eq. (9) for using
ω(t+dt).  Freezing the torque over the step makes it first order overall.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import euler_rhs, torque_at
from ..rotation import rotate_body_step

ORDER = 1
SYMPLECTIC = False
PRESERVES = ("L3",)  # ω3 is untouched when I1 = I2 and τ3 = 0


@njit(cache=True, error_model="numpy")
def rk4_frozen_torque(w, tau, dt, body):
    """ω(t+dt) from classic RK4 on I ω̇ = τ − ω × Iω with τ held constant."""
    h = 0.5 * dt
    k1 = euler_rhs(w, tau, body)
    k2 = euler_rhs((w[0] + h * k1[0], w[1] + h * k1[1], w[2] + h * k1[2]), tau, body)
    k3 = euler_rhs((w[0] + h * k2[0], w[1] + h * k2[1], w[2] + h * k2[2]), tau, body)
    k4 = euler_rhs((w[0] + dt * k3[0], w[1] + dt * k3[1], w[2] + dt * k3[2]), tau, body)
    s = dt * (1.0 / 6.0)  # a multiplication: dt / 6 would be one more division a step (issue 22)
    return (
        w[0] + s * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
        w[1] + s * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
        w[2] + s * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]),
    )


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the whole torque, drive included, frozen at t, as
    the write-up freezes gravity's."""
    w_next = rk4_frozen_torque(w, torque_at(q, t, body), dt, body)
    return w_next, rotate_body_step(q, w_next[0] * dt, w_next[1] * dt, w_next[2] * dt)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
