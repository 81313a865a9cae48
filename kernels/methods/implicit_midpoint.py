"""implicit_midpoint: the implicit midpoint rule on (ω, q), solved by fixed-point iteration.

y_{n+1} = y_n + h f(t + h/2, (y_n + y_{n+1})/2) for y = (ω, q) ∈ R⁷ with I ω̇ = τ(q, t) − ω × Iω and
q̇ = ½ q ⊗ (0, ω) (Hairer, Lubich & Wanner, Geometric Numerical Integration, 2nd ed. 2006, Sects.
II.1 and IV.2; for the rigid body Austin, Krishnaprasad & Wang, J. Comput. Phys. 107 (1993) 105–117).
It is solved for the midpoint Y = (y_n + y_{n+1})/2 = y_n + h/2 f(t + h/2, Y) by fixed-point
iteration from Y = y_n (the form DL_POLY's FIQA uses for its quaternion): the map contracts by about
h |ω| / 2 per sweep.  **Tolerance**: stop when the largest change of Y's components, ω relative to
|ω|, q absolute, is ≤ 1e-15 (then y_{n+1} = 2Y − y_n); **iteration cap** 60.  A step that has not
converged (h |ω| too large for the iteration to contract) returns NaN for ω and q, so the run ends
with the status "unconverged" instead of continuing from a wrong step; each run counts its sweeps
(methods/README.md, "Solvers").

The midpoint rule keeps every quadratic invariant of the ODE exactly (to the solver's tolerance):
|q|² (q·q̇ = 0), the energy ½ ω·Iω + M g c·γ(q) (γ is quadratic in q), |Iω|² of a free body, and the
linear I3 ω3 of the symmetric top.  Its lab angular momentum is cubic (R(q) I ω) and is not kept.
Second order, symmetric; not a Poisson map of the rigid body's bracket (AKW 1993: "almost Poisson"),
so SYMPLECTIC is False.  |q| = 1 is one of the kept quadratic invariants, but only to the solver's
tolerance (6e-14 after 4000 steps of the 50 Hz top), so q is renormalised once per step.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import euler_rhs, torque_at
from ..rotation import quat_mul, quat_normalize

ORDER = 2
SYMPLECTIC = False
PRESERVES = ("energy", "L_norm", "L3")

BLOCKS = False  # a fixed-point loop per step: the lanes do not vectorise it, and its sweeps are counted
MAX_ITERATIONS = 60
TOLERANCE = 1e-15


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven_counted(w, q, t, dt, body):
    """One implicit-midpoint step of dt seconds from time t (s), the torque at t + dt/2, and the
    fixed-point sweeps it took (−MAX_ITERATIONS: not converged, the state NaN)."""
    half = 0.5 * dt
    tm = t + half
    wm, qm = w, q
    scale = max(abs(w[0]), abs(w[1]), abs(w[2]))
    for n in range(1, MAX_ITERATIONS + 1):
        a = euler_rhs(wm, torque_at(qm, tm, body), body)
        qd = quat_mul(qm, (0.0, wm[0], wm[1], wm[2]))  # 2 q̇
        w_new = (w[0] + half * a[0], w[1] + half * a[1], w[2] + half * a[2])
        h4 = 0.5 * half
        q_new = (q[0] + h4 * qd[0], q[1] + h4 * qd[1], q[2] + h4 * qd[2], q[3] + h4 * qd[3])
        dw = max(abs(w_new[0] - wm[0]), abs(w_new[1] - wm[1]), abs(w_new[2] - wm[2]))
        dq = max(abs(q_new[0] - qm[0]), abs(q_new[1] - qm[1]), abs(q_new[2] - qm[2]), abs(q_new[3] - qm[3]))
        wm, qm = w_new, q_new
        scale = max(scale, abs(wm[0]), abs(wm[1]), abs(wm[2]))
        if dw <= TOLERANCE * scale and dq <= TOLERANCE:
            return (
                (2.0 * wm[0] - w[0], 2.0 * wm[1] - w[1], 2.0 * wm[2] - w[2]),
                quat_normalize((2.0 * qm[0] - q[0], 2.0 * qm[1] - q[1], 2.0 * qm[2] - q[2], 2.0 * qm[3] - q[3])),
                n,
            )
    nan = float("nan")
    return (nan, nan, nan), (nan, nan, nan, nan), -MAX_ITERATIONS


@njit(cache=True, error_model="numpy")
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): step_driven_counted without its count."""
    w1, q1, _ = step_driven_counted(w, q, t, dt, body)
    return w1, q1


@njit(cache=True, error_model="numpy")
def step_counted(w, q, dt, body):
    """step_driven_counted of an undriven body, from t = 0 with its drive folded away."""
    return step_driven_counted(w, q, 0.0, dt, without_drive(body))


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
