"""lie_trotter: Lie–Trotter splitting, full gravity kick then the free-body flow; symplectic Euler on T*SO(3).

Per step: ω ← kick(ω, q, dt) (the exact flow of the potential M g l cos θ for
dt: q frozen, I ω += τ(q) dt), then (ω, q) ← free_flow(ω, q, dt) (exact for a
symmetric body, the Poisson axis sub-splitting otherwise; kernels/free_flow.py).
A composition of two exact (Poisson) flows, so it is a Poisson map: first
order, symplectic, the energy error bounded with no secular drift (backward
error analysis: it is the exact flow of a modified Hamiltonian H + dt H1 + …).
It is the kick–drift order of ``seed_next`` with the drift made exact, the
control that shows what seed_next's RK4 ω update costs.
Source: Trotter (1959), Proc. AMS 10, 545; McLachlan (1993), Phys. Rev. Lett.
71, 3043; Dullweber, Leimkuhler & McLachlan (1997), J. Chem. Phys. 107, 5840.
"""

from numba import njit

from ..body import without_drive
from ..free_flow import free_flow, kick_at

ORDER = 1
# On a torque-free body the kick vanishes and the step is free_flow alone: exact for a symmetric
# body, the second-order axis sub-splitting otherwise.
FREE_ORDER = 2
SYMPLECTIC = True
# Both flows turn the body by exact rotations and change L_b only by the kick τ dt with
# τ ⟂ e3 and τ_lab ⟂ ẑ: the lab L (free bodies), |L|, Lz and L3 (symmetric top) are kept to
# rounding.  The energy is not (bounded O(dt) error) unless the free flow is the whole step.
PRESERVES = ("L", "L_norm", "Lz", "L3")


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the kick holds t, the free flow advances it."""
    w = kick_at(w, q, dt, t, body)
    return free_flow(w, q, dt, body)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
