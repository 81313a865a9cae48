"""lie_poisson: second-order symplectic Lie–Poisson splitting (Strang).

Half kick by the gravity torque, free-body flow for dt (closed form for a
symmetric body, axis sub-splitting otherwise; see free_flow.py), half kick.
Symplectic on T*SO(3), so the energy error stays bounded with no drift.
Source: McLachlan (1993), Dullweber, Leimkuhler & McLachlan (1997).
"""
from numba import njit, prange

from .block import make_advance_queue
from .driver import make_advance
from .free_flow import free_flow, kick

ORDER = 2
SYMPLECTIC = True


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w = kick(w, q, 0.5 * dt, body)
    w, q = free_flow(w, q, dt, body)
    return kick(w, q, 0.5 * dt, body), q


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
