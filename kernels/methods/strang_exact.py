"""strang_exact: second-order Strang splitting whose free flow is the exact Euler–Poinsot flow.

Half kick by the gravity torque (free_flow.kick), the exact torque-free motion
for dt (euler_poinsot.free_flow_exact: Jacobi elliptic functions and an
elliptic integral of the third kind, any inertia), half kick.  On a free body
(mgl = 0) the kicks vanish and the step is the exact solution to rounding at
any dt, energy included; with gravity it is a symmetric, symplectic
(Lie–Poisson) second-order splitting.  Source: Celledoni, Fassò, Säfström &
Zanna, SIAM J. Sci. Comput. 30 (2008) 2084, §4 (splitting with the exact free
rigid body flow); Strang (1968); Dullweber, Leimkuhler & McLachlan (1997).
"""

from numba import njit

from ..body import without_drive
from ..euler_poinsot import free_flow_exact
from ..free_flow import kick_at

ORDER = 2
SYMPLECTIC = True
FREE_EXACT = True  # on a torque-free body the step is the exact flow: error at rounding for any dt
BLOCKS = False  # its libm-bound elliptic free flow does not vectorise: docs/benchmarks.md, "Off the block path"
# energy is kept to rounding only when the scene is free (it is not in the list, because a heavy top
# conserves it and the splitting does not); the lab L and |L| of a free body, Lz (the gravity torque is
# horizontal) and L3 of a symmetric heavy top are.
PRESERVES = ("L", "L_norm", "Lz", "L3")


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the exact free flow advances t, the kicks hold it
    (at t and t + dt), as lie_poisson's."""
    w = kick_at(w, q, 0.5 * dt, t, body)
    w, q = free_flow_exact(w, q, dt, body)
    return kick_at(w, q, 0.5 * dt, t + dt, body), q


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
