"""lie_poisson: second-order symplectic Lie–Poisson splitting (Strang).

Half kick by the gravity torque, free-body flow for dt (closed form for a
symmetric body, axis sub-splitting otherwise; see free_flow.py), half kick.
Symplectic on T*SO(3), so the energy error stays bounded with no drift.
Source: McLachlan (1993), Dullweber, Leimkuhler & McLachlan (1997).

Parameter ``axes`` (default 1-2-3): the order of the axis sub-splitting, a(h/2) b(h/2) c(h) b(h/2)
a(h/2), in body labels or by moment (S-M-L is lie_poisson_sorted; kernels/parameters.py).  Which order
is best depends on the moments (Fassò 2003; docs/splitting_order.md); a symmetric body (I1 = I2) takes
the exact flow in every order.
"""

from numba import njit

from ..body import without_drive
from ..free_flow import free_flow, free_flow_axes, kick_at
from ..parameters import axis_order
from ..variants import undriven

ORDER = 2
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz", "L3")
PARAMETERS = {
    "axes": axis_order("1-2-3", "order of the free flow's axis splitting: a-b-c is a(h/2) b(h/2) c(h) b(h/2) a(h/2)"),
}


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the splitting of the system made autonomous with t
    as a coordinate, the free flow advancing t, the kicks holding it (the first at t, the last at
    t + dt).  Still second order and symmetric."""
    w = kick_at(w, q, 0.5 * dt, t, body)
    w, q = free_flow(w, q, dt, body)
    return kick_at(w, q, 0.5 * dt, t + dt, body), q


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))


def variant(axes):
    """The steps with the free flow's axis splitting in the order ``axes`` (kernels/parameters.py codes).
    The plain ``step_driven`` above keeps free_flow's literal axes: through axis_splitting the one-by-one
    path ran 13-20 % slower (free_flow.py), and the two are the same map bit for bit at 1-2-3."""

    @njit(error_model="numpy", forceinline=True)
    def step_driven(w, q, t, dt, body):
        w = kick_at(w, q, 0.5 * dt, t, body)
        w, q = free_flow_axes(w, q, dt, body, axes)
        return kick_at(w, q, 0.5 * dt, t + dt, body), q

    return undriven(step_driven)
