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

from ..body import without_drive
from ..compose import compose_kicks
from ..euler_poinsot import free_flow_exact
from ..free_flow import kick_at

ORDER = 4
SYMPLECTIC = True
FREE_EXACT = True  # on a torque-free body the step is the exact flow: error at rounding for any dt
BLOCKS = False  # its libm-bound elliptic free flow does not vectorise: docs/benchmarks.md, "Off the block path"
PRESERVES = ("L", "L_norm", "Lz", "L3")

G1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
G0 = 1.0 - 2.0 * G1
WEIGHTS = (G1, G0, G1)
_composed = compose_kicks(kick_at, free_flow_exact, WEIGHTS)  # 4 kicks (2 merged), 3 exact free flows


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): each kick at the time the free flows before it reached
    (t, t + γ1 dt, then + γ0 dt, and t + dt; kernels/compose.py)."""
    return _composed(w, q, t, dt, body)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
