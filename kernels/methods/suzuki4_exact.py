"""suzuki4_exact: fourth-order 5-stage composition (Suzuki's fractal) of the exact-free-flow Strang splitting.

S(p dt) S(p dt) S((1 − 4p) dt) S(p dt) S(p dt), p = 1/(4 − 4^(1/3)) ≈ 0.4145,
1 − 4p ≈ −0.6580, where S is strang_exact's step (half kick, exact
Euler–Poinsot flow, half kick); the adjacent half kicks are merged (6 kicks,
5 exact free flows).  Two more substeps than strang_exact4's triple jump buy
a smaller backward substep and a smaller error constant.  Symplectic; on a
free body it is the exact solution to rounding at any dt.  The whole method
is its table of weights (kernels/compose.py).  Source: M. Suzuki, "Fractal
decomposition of exponential operators with applications to many-body
theories and Monte Carlo simulations", Phys. Lett. A 146 (1990) 319;
Hairer, Lubich & Wanner, Geometric Numerical Integration (2006), §II.4;
the exact free flow as in Celledoni, Fassò, Säfström & Zanna, SIAM J. Sci.
Comput. 30 (2008) 2084.
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

P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
WEIGHTS = (P, P, 1.0 - 4.0 * P, P, P)
_composed = compose_kicks(kick_at, free_flow_exact, WEIGHTS)  # 6 kicks (4 merged), 5 exact free flows


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): each kick at the time the free flows before it reached
    (the partial sums of the weights, then t + dt; kernels/compose.py)."""
    return _composed(w, q, t, dt, body)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
