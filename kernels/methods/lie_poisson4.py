"""lie_poisson4: fourth-order composition of lie_poisson (Yoshida's triple jump).

S(w1 dt) S(w0 dt) S(w1 dt) with w1 = 1/(2 − 2^(1/3)), w0 = 1 − 2 w1, where S is
the symmetric second-order lie_poisson step.  Symplectic; the middle substep
runs backwards in time.  Source: Yoshida (1990), Suzuki (1990).
"""
from numba import njit, prange

from .block import make_advance_queue
from .driver import make_advance
from .lie_poisson import step as strang_step

ORDER = 4
SYMPLECTIC = True

W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = 1.0 - 2.0 * W1


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w, q = strang_step(w, q, W1 * dt, body)
    w, q = strang_step(w, q, W0 * dt, body)
    return strang_step(w, q, W1 * dt, body)


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
