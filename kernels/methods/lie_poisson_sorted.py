"""lie_poisson_sorted: lie_poisson with its free-body axis splitting in the moment-sorted order S-M-L-M-S.

The same Strang splitting as lie_poisson (half kick, free flow for dt, half kick; the exact free flow
when I1 = I2), but on an asymmetric body the five axis rotations run smallest moment outermost,
largest innermost: S(dt/2) M(dt/2) L(dt) M(dt/2) S(dt/2), whatever the scene's axis labels
(free_flow.moment_sorted_order).  lie_poisson turns 1-2-3-2-1 in the labels, so its rank order, and its
error, depend on how a scene numbers its axes: on the free_asymmetric scene (I = 1, 3, 2 × 1e-4)
it is S-L-M.  Over the inertia triangle S-M-L has the smallest orientation error at 77 % of the bodies
and is within 2.64× of the best order's energy error everywhere, where the label order can lose 27×
(Fassò, J. Comput. Phys. 189, 527, 2003; docs/splitting_order.md, analysis/reports/splitting_order.py).
Symplectic, second order; keeps what lie_poisson keeps.
"""

from numba import njit

from ..body import without_drive
from ..free_flow import free_flow_sorted, kick_at

ORDER = 2
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz", "L3")


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): lie_poisson's splitting made autonomous (the kicks at t
    and t + dt), the free flow in the sorted axis order."""
    w = kick_at(w, q, 0.5 * dt, t, body)
    w, q = free_flow_sorted(w, q, dt, body)
    return kick_at(w, q, 0.5 * dt, t + dt, body), q


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
