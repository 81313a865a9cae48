"""simo_wong: Simo & Wong's energy-momentum rotation update (implicit, fixed point on the body increment).

J.C. Simo and K.K. Wong, "Unconditionally stable algorithms for rigid body dynamics that exactly
preserve energy and momentum", Int. J. Numer. Meth. Engng 31 (1991) 19–52, in the material (body)
form that Krysl restates ("Explicit momentum-conserving integrator for dynamics of rigid bodies
approximating the midpoint Lie algorithm", IJNME 63 (2005) 2171–2193, Sect. 2) and that Bottasso &
Borri's trapezoidal Munthe-Kaas scheme reduces to (Krysl's IncrSO3 codes, "bb_rkmk_trap").  With
J = diag(I1, I2, I3), W the body angular velocity, Λ the rotation (body → lab), T = Λᵀ m the body
torque and one step of h = dt from time t:

    Θ = h/2 (W_n + W_{n+1})                                   (the midpoint body rotation vector),
    Λ_{n+1} = Λ_n exp(Θ̂),
    Λ_{n+1} J W_{n+1} = Λ_n J W_n + h/2 (m_n + m_{n+1}),        (spatial momentum balance), i.e.
    J W_{n+1} = exp(−Θ̂) (J W_n + h/2 T_n) + h/2 T_{n+1},

T_n the torque at (Λ_n, t) and T_{n+1} at (Λ_{n+1}, t + h): **the external torque enters by the
trapezoidal rule on the spatial impulse** (a drive, a torque fixed in the body, at the same two times).
Solved by fixed-point iteration on W_{n+1} from W_{n+1} = W_n: each sweep forms Θ from the last
iterate, exp(−Θ̂) and the torque at Λ_n exp(Θ̂), and the next iterate; the map contracts by roughly
h |ω| / 2 times the inertia ratio.  **Tolerance**: stop when max |ΔW_{n+1}| ≤ 1e-15 max |W|, and
return that sweep's W_{n+1} and Λ_n exp(Θ̂); **iteration cap** 60.  A step that has not met the
tolerance in 60 sweeps (h |ω| too large for the iteration to contract) returns NaN for ω and q, so
the run ends with the status "unconverged" instead of continuing from a wrong step.  The returned
W_{n+1} and Λ_{n+1} come from the same Θ, so the spatial momentum balance holds to rounding whatever
the residual; the midpoint relation Θ = h/2 (W_n + W_{n+1}) holds to the tolerance.

What it keeps.  Torque-free: the lab angular momentum Λ J W exactly (Λ_{n+1} J W_{n+1} = Λ_n J W_n
by construction) and so |L|; and the kinetic energy exactly, because exp(Θ̂) fixes Θ:
Θ·J W_n = Θ·exp(Θ̂) J W_{n+1} = Θ·J W_{n+1}, i.e. (W_n + W_{n+1})·J (W_{n+1} − W_n) = 0 (Simo &
Wong's energy-momentum property; measured to rounding, tests/test_methods.py).  Under gravity the
spatial torques m = −M g (Λ c) × e_z are horizontal, so the trapezoid keeps L_z exactly; the energy is
then kept only to O(h²) without drift (the work h/2 Θ·(T_n + T_{n+1}) is not the exact potential
drop: a discrete gradient would be needed), and L3 of the symmetric top is not kept (exp(−Θ̂) mixes
the components of J W).  Second order (the midpoint rotation vector, the trapezoidal impulse:
symmetric); not symplectic (Simo & Wong's scheme is energy-momentum, not a Poisson map; Lewis & Simo
1994 show which member of the family is).  q is renormalised once per step against rounding.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import torque_at
from ..rotation import body_to_lab, quat_from_rotvec, quat_mul, quat_normalize

ORDER = 2
SYMPLECTIC = False
PRESERVES = ("L", "L_norm", "Lz")

BLOCKS = False  # a fixed-point loop per step: the lanes do not vectorise it, and its sweeps are counted
MAX_ITERATIONS = 60
TOLERANCE = 1e-15  # on max |ΔW_{n+1}|, relative to max |W|


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven_counted(w, q, t, dt, body):
    """One Simo-Wong step of dt seconds from time t (s), the torques at t and t + dt (trapezoid), and
    the fixed-point sweeps it took (−MAX_ITERATIONS: not converged, the state NaN)."""
    I1, I2, I3 = body[0], body[1], body[2]
    half = 0.5 * dt
    m0, m1, m2 = torque_at(q, t, body)
    a0 = I1 * w[0] + half * m0  # J W_n + h/2 T_n
    a1 = I2 * w[1] + half * m1
    a2 = I3 * w[2] + half * m2
    v0, v1, v2 = w  # W_{n+1}, first guess W_n
    scale = max(abs(v0), abs(v1), abs(v2))
    for n in range(1, MAX_ITERATIONS + 1):
        qt = quat_from_rotvec(half * (w[0] + v0), half * (w[1] + v1), half * (w[2] + v2))  # exp(Θ̂)
        q_next = quat_mul(q, qt)
        b0, b1, b2 = body_to_lab((qt[0], -qt[1], -qt[2], -qt[3]), a0, a1, a2)  # exp(−Θ̂) a
        n0, n1, n2 = torque_at(q_next, t + dt, body)
        u0, u1, u2 = (b0 + half * n0) / I1, (b1 + half * n1) / I2, (b2 + half * n2) / I3
        change = max(abs(u0 - v0), abs(u1 - v1), abs(u2 - v2))
        v0, v1, v2 = u0, u1, u2
        scale = max(scale, abs(v0), abs(v1), abs(v2))
        if change <= TOLERANCE * scale:
            return (v0, v1, v2), quat_normalize(q_next), n  # W_{n+1} and Λ_{n+1} from the same Θ
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
