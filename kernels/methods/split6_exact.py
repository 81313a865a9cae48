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

Parameter ``accumulate`` (default plain): ``compensated`` keeps ω and q as hi + lo and adds the kicks,
the closed-form free flow of a body with I1 = I2 and an asymmetric body's elliptic change of ω (from the
increments of sn, cn, dn) as error-free increments (kernels/compensated.py); an asymmetric body's
attitude is computed afresh each substep and stays uncompensated.  That variant carries the low parts
from step to step, runs one run after another, and integrates undriven bodies only.
"""

from numba import njit

from .. import compensated
from ..body import without_drive
from ..compose import compose_kicks
from ..euler_poinsot import free_flow_exact
from ..free_flow import kick_at
from ..parameters import ACCUMULATE
from ..variants import carried

ORDER = 6
SYMPLECTIC = True
FREE_EXACT = True  # on a torque-free body the step is the exact flow: error at rounding for any dt
BLOCKS = False  # its libm-bound elliptic free flow does not vectorise: docs/benchmarks.md, "Off the block path"
PRESERVES = ("L", "L_norm", "Lz", "L3")
PARAMETERS = {"accumulate": ACCUMULATE}

W1 = -1.17767998417887
W2 = 0.235573213359357
W3 = 0.784513610477560
W0 = 1.0 - 2.0 * (W1 + W2 + W3)
WEIGHTS = (W3, W2, W1, W0, W1, W2, W3)
_composed = compose_kicks(kick_at, free_flow_exact, WEIGHTS)  # 8 kicks (6 merged), 7 exact free flows


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): each kick at the time the free flows before it reached
    (the partial sums of the weights, then t + dt; kernels/compose.py)."""
    return _composed(w, q, t, dt, body)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))


def variant(accumulate):
    """The method itself (``accumulate`` 0, plain), or with ``accumulate`` 1 the same map compensated
    (kernels/compensated.py), a carried method."""
    if accumulate:
        return carried(compensated.start, compensated.kick_composition(WEIGHTS))
    return {"step_driven": step_driven, "step": step}
