"""strang_exact4: fourth-order triple-jump composition of the exact-free-flow Strang splitting.

S(γ1 dt) S(γ0 dt) S(γ1 dt), γ1 = 1/(2 − 2^(1/3)), γ0 = 1 − 2γ1 < 0, where S is
strang_exact's step (half kick, exact Euler–Poinsot flow, half kick); the
adjacent half kicks are merged.  Symplectic; the middle substep runs
backwards in time (the exact flow takes any sign of dt).  On a free body it
is the exact solution to rounding at any dt.  Source: Yoshida, Phys. Lett. A
150 (1990) 262; Suzuki (1990); with the exact free flow as in Celledoni,
Fassò, Säfström & Zanna, SIAM J. Sci. Comput. 30 (2008) 2084.
"""

from numba import njit

from ..euler_poinsot import free_flow_exact
from ..free_flow import kick, kick_at

ORDER = 4
SYMPLECTIC = True
FREE_EXACT = True  # on a torque-free body the step is the exact flow: error at rounding for any dt
PRESERVES = ("L", "L_norm", "Lz", "L3")

G1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
G0 = 1.0 - 2.0 * G1
K_OUT = 0.5 * G1  # first and last half kick
K_IN = 0.5 * (G1 + G0)  # merged kicks between substeps


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w = kick(w, q, K_OUT * dt, body)
    w, q = free_flow_exact(w, q, G1 * dt, body)
    w = kick(w, q, K_IN * dt, body)
    w, q = free_flow_exact(w, q, G0 * dt, body)
    w = kick(w, q, K_IN * dt, body)
    w, q = free_flow_exact(w, q, G1 * dt, body)
    return kick(w, q, K_OUT * dt, body), q


@njit(cache=True, error_model="numpy")
def step_driven(w, q, t, dt, body):
    """``step`` of a driven body from time t (s): each kick at the time the free flows before it
    reached (t, t + G1 dt, t + (G1 + G0) dt, t + dt)."""
    t1 = t + G1 * dt
    t2 = t1 + G0 * dt
    w = kick_at(w, q, K_OUT * dt, t, body)
    w, q = free_flow_exact(w, q, G1 * dt, body)
    w = kick_at(w, q, K_IN * dt, t1, body)
    w, q = free_flow_exact(w, q, G0 * dt, body)
    w = kick_at(w, q, K_IN * dt, t2, body)
    w, q = free_flow_exact(w, q, G1 * dt, body)
    return kick_at(w, q, K_OUT * dt, t + dt, body), q
