"""seed_prev: the write-up's baseline, rotating with ω(t) instead of ω(t+dt).

Same RK4 update of ω as seed_next, but R(t+dt) = R(t) · CK(ω(t) dt).  The
write-up reports that this loses energy and lets the precession sink.
"""
from numba import njit, prange

from .block import make_advance_queue
from .driver import make_advance
from .rigid_body import gravity_torque
from .rotation import rotate_body_step
from .seed_next import rk4_frozen_torque

ORDER = 1
SYMPLECTIC = False


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w_next = rk4_frozen_torque(w, gravity_torque(q, body[3]), dt, body)
    return w_next, rotate_body_step(q, w[0] * dt, w[1] * dt, w[2] * dt)


advance_run = make_advance(step)


@njit(cache=True, parallel=True, error_model="numpy")
def run_batch(w0, q0, bodies, dts, strides, threshold, out, status, n_steps):
    for i in prange(w0.shape[0]):
        advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps)


advance_queue = make_advance_queue(step)


@njit(cache=True, parallel=True, error_model="numpy")
def run_blocks(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, runs, starts, queues):
    for t in prange(queues.size - 1):
        advance_queue(t, runs, starts, queues, w0, q0, bodies, dts, strides, threshold, out, status, n_steps)
