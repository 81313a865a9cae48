"""lie_poisson4: fourth-order composition of lie_poisson (Yoshida's triple jump).

S(w1 dt) S(w0 dt) S(w1 dt) with w1 = 1/(2 − 2^(1/3)), w0 = 1 − 2 w1, where S is
the symmetric second-order lie_poisson step.  Symplectic; the middle substep
runs backwards in time.  Source: Yoshida (1990), Suzuki (1990).
"""

from numba import njit

from .lie_poisson import step as strang_step
from .lie_poisson import step_driven as strang_driven

ORDER = 4
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz", "L3")

W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = 1.0 - 2.0 * W1


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w, q = strang_step(w, q, W1 * dt, body)
    w, q = strang_step(w, q, W0 * dt, body)
    return strang_step(w, q, W1 * dt, body)


@njit(cache=True, error_model="numpy")
def step_driven(w, q, t, dt, body):
    """``step`` of a driven body from time t (s): the same composition, each Strang substep from the
    time the previous one reached (the weights' partial sums)."""
    w, q = strang_driven(w, q, t, W1 * dt, body)
    w, q = strang_driven(w, q, t + W1 * dt, W0 * dt, body)
    return strang_driven(w, q, t + (W1 + W0) * dt, W1 * dt, body)
