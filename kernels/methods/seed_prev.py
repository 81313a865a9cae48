"""seed_prev: the write-up's baseline, rotating with ω(t) instead of ω(t+dt).

Same RK4 update of ω as seed_next, but R(t+dt) = R(t) · CK(ω(t) dt).  The
write-up reports that this loses energy and lets the precession sink.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import torque_at
from ..rotation import rotate_body_step
from .seed_next import rk4_frozen_torque

ORDER = 1
SYMPLECTIC = False
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the whole torque, drive included, frozen at t."""
    w_next = rk4_frozen_torque(w, torque_at(q, t, body), dt, body)
    return w_next, rotate_body_step(q, w[0] * dt, w[1] * dt, w[2] * dt)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
