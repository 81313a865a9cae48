"""split6_exact: sixth-order symmetric composition (Yoshida's solution A) of the exact-free-flow Strang splitting.

S(w3 dt) S(w2 dt) S(w1 dt) S(w0 dt) S(w1 dt) S(w2 dt) S(w3 dt), S = strang_exact's
step (half kick, exact Euler–Poinsot flow, half kick), with Yoshida's
7-stage coefficients of solution A, w1 = −1.17767998417887,
w2 = 0.235573213359357, w3 = 0.784513610477560, w0 = 1 − 2(w1 + w2 + w3);
the adjacent half kicks are merged (8 kicks, 7 exact free flows).
Symplectic; on a free body it is the exact solution to rounding at any dt.
Source: H. Yoshida, "Construction of higher order symplectic integrators",
Phys. Lett. A 150 (1990) 262, Table 1 (solution A); the exact free flow as in
Celledoni, Fassò, Säfström & Zanna, SIAM J. Sci. Comput. 30 (2008) 2084.
"""

from numba import njit

from ..euler_poinsot import free_flow_exact
from ..free_flow import kick, kick_at

ORDER = 6
SYMPLECTIC = True
FREE_EXACT = True  # on a torque-free body the step is the exact flow: error at rounding for any dt
PRESERVES = ("L", "L_norm", "Lz", "L3")

W1 = -1.17767998417887
W2 = 0.235573213359357
W3 = 0.784513610477560
W0 = 1.0 - 2.0 * (W1 + W2 + W3)
K3 = 0.5 * W3
K32 = 0.5 * (W3 + W2)
K21 = 0.5 * (W2 + W1)
K10 = 0.5 * (W1 + W0)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w = kick(w, q, K3 * dt, body)
    w, q = free_flow_exact(w, q, W3 * dt, body)
    w = kick(w, q, K32 * dt, body)
    w, q = free_flow_exact(w, q, W2 * dt, body)
    w = kick(w, q, K21 * dt, body)
    w, q = free_flow_exact(w, q, W1 * dt, body)
    w = kick(w, q, K10 * dt, body)
    w, q = free_flow_exact(w, q, W0 * dt, body)
    w = kick(w, q, K10 * dt, body)
    w, q = free_flow_exact(w, q, W1 * dt, body)
    w = kick(w, q, K21 * dt, body)
    w, q = free_flow_exact(w, q, W2 * dt, body)
    w = kick(w, q, K32 * dt, body)
    w, q = free_flow_exact(w, q, W3 * dt, body)
    return kick(w, q, K3 * dt, body), q


@njit(cache=True, error_model="numpy")
def step_driven(w, q, t, dt, body):
    """``step`` of a driven body from time t (s): each kick at the time the free flows before it
    reached (the partial sums of the weights W3, W2, W1, W0, W1, W2, W3)."""
    t1 = t + W3 * dt
    t2 = t1 + W2 * dt
    t3 = t2 + W1 * dt
    t4 = t3 + W0 * dt
    t5 = t4 + W1 * dt
    t6 = t5 + W2 * dt
    w = kick_at(w, q, K3 * dt, t, body)
    w, q = free_flow_exact(w, q, W3 * dt, body)
    w = kick_at(w, q, K32 * dt, t1, body)
    w, q = free_flow_exact(w, q, W2 * dt, body)
    w = kick_at(w, q, K21 * dt, t2, body)
    w, q = free_flow_exact(w, q, W1 * dt, body)
    w = kick_at(w, q, K10 * dt, t3, body)
    w, q = free_flow_exact(w, q, W0 * dt, body)
    w = kick_at(w, q, K10 * dt, t4, body)
    w, q = free_flow_exact(w, q, W1 * dt, body)
    w = kick_at(w, q, K21 * dt, t5, body)
    w, q = free_flow_exact(w, q, W2 * dt, body)
    w = kick_at(w, q, K32 * dt, t6, body)
    w, q = free_flow_exact(w, q, W3 * dt, body)
    return kick_at(w, q, K3 * dt, t + dt, body), q
