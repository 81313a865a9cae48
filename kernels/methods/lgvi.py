"""lgvi: the Lie-group variational integrator of Lee, Leok & McClamroch (implicit, Newton on the Cayley vector).

Lee, Leok & McClamroch, "A Lie group variational integrator for the attitude dynamics of a rigid body
with applications to the 3D pendulum", Proc. IEEE CCA 2005, 962–967, and "Lie group variational
integrators for the full body problem", Comput. Methods Appl. Mech. Engrg. 196 (2007) 2907–2924
(Sect. 4.3, the Cayley/Newton solve).  With Π = Iω the body angular momentum, M the body torque and
J_d = ½ tr(I) 1 − I, one step of h = dt from time t:

    (h Π_k + h²/2 M_k)^ = F J_d − J_d Fᵀ           solved for F ∈ SO(3),
    R_{k+1} = R_k F,
    Π_{k+1} = Fᵀ (Π_k + h/2 M_k) + h/2 M_{k+1},

M_k the torque at (R_k, t) and M_{k+1} at (R_{k+1}, t + h) (the trapezoidal discrete Lagrangian; a
drive enters as a torque at the same two times).  F = Cay(f) = (1 + f̂)(1 − f̂)⁻¹, whose quaternion is
(1, f)/√(1 + f·f), and the implicit equation becomes, with g = h Π_k + h²/2 M_k,

    G(f) = g + g × f + (g·f) f − 2 I f = 0,    ∇G = ĝ + (g·f) 1 + f gᵀ − 2 I,

solved by Newton from f = I⁻¹ g / 2 (the explicit first-order guess), with kernels/engine_common's
``solve33``.  **Tolerance**: stop when max |Δf| ≤ 1e-14 max |f| (Newton converges quadratically, so
the f returned after that update is at rounding; a bound of a few ε could sit below the rounding
noise of G on an elongated body); **iteration cap** 30.  A step whose
Newton iteration has not met the tolerance in 30 iterations returns NaN for ω and q, so the run ends
with the status "unconverged" instead of continuing from a wrong step.

Symplectic (a variational integrator) and second order.  For a free body Π_{k+1} = Fᵀ Π_k, so the
lab angular momentum R Π and |Π| are kept to rounding whatever the Newton residual; under gravity the
lab L_z too (the trapezoid's torques are horizontal in the lab).  On a free body it keeps the
kinetic energy to rounding as well (measured 3e-15 after 4000 steps of the tumbling box of
test_methods' L test, where no_squish's energy error is 7.6e-7).  q is renormalised once per step
against rounding.

This is also RATTLE (Andersen 1983) on the rotation matrix under QᵀQ = 1, i.e. the discrete
Moser–Veselov map between two half kicks (McLachlan & Scovel 1995; Hairer, Lubich & Wanner,
Geometric Numerical Integration, VII.5): tests/test_md_methods.py test_lgvi_is_rattle finds the same
step to 1e-15 from an independent matrix transcription, so gyrolab ships no separate ``rattle``.
"""

import math

from numba import njit

from ..body import without_drive
from ..engine_common import solve33
from ..rigid_body import torque_at
from ..rotation import quat_mul, quat_normalize

ORDER = 2
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz")

BLOCKS = False  # a Newton loop per step, its iterations counted (one by one it runs 1.25x the blocks' time)
MAX_ITERATIONS = 30
TOLERANCE = 1e-14  # on max |Δf|, relative to max |f|


@njit(cache=True, error_model="numpy")
def cayley_vector(g, body):
    """(f, iterations) with G(f) = 0 for g = h Π + h²/2 M (N m s), by Newton; NaNs and
    −MAX_ITERATIONS when it does not converge."""
    I1, I2, I3 = body[0], body[1], body[2]
    g0, g1, g2 = g
    f0, f1, f2 = 0.5 * g0 / I1, 0.5 * g1 / I2, 0.5 * g2 / I3
    for n in range(1, MAX_ITERATIONS + 1):
        gf = g0 * f0 + g1 * f1 + g2 * f2
        r0 = g0 + (g1 * f2 - g2 * f1) + gf * f0 - 2.0 * I1 * f0
        r1 = g1 + (g2 * f0 - g0 * f2) + gf * f1 - 2.0 * I2 * f1
        r2 = g2 + (g0 * f1 - g1 * f0) + gf * f2 - 2.0 * I3 * f2
        # ∇G = ĝ + (g·f) 1 + f gᵀ − 2 I, rows
        A = (
            (gf + f0 * g0 - 2.0 * I1, -g2 + f0 * g1, g1 + f0 * g2),
            (g2 + f1 * g0, gf + f1 * g1 - 2.0 * I2, -g0 + f1 * g2),
            (-g1 + f2 * g0, g0 + f2 * g1, gf + f2 * g2 - 2.0 * I3),
        )
        d0, d1, d2 = solve33(A, (r0, r1, r2))
        f0, f1, f2 = f0 - d0, f1 - d1, f2 - d2
        size = max(abs(f0), abs(f1), abs(f2))
        if max(abs(d0), abs(d1), abs(d2)) <= TOLERANCE * size or size == 0.0:
            return (f0, f1, f2), n
    nan = float("nan")
    return (nan, nan, nan), -MAX_ITERATIONS


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven_counted(w, q, t, dt, body):
    """One LGVI step of dt seconds from time t (s), the torques at t and t + dt, and the Newton
    iterations it took (< 0: not converged, the state NaN)."""
    I1, I2, I3 = body[0], body[1], body[2]
    h = dt
    m0, m1, m2 = torque_at(q, t, body)
    a0 = I1 * w[0] + 0.5 * h * m0  # Π_k + h/2 M_k
    a1 = I2 * w[1] + 0.5 * h * m1
    a2 = I3 * w[2] + 0.5 * h * m2
    (f0, f1, f2), n = cayley_vector((h * a0, h * a1, h * a2), body)
    inv = 1.0 / math.sqrt(1.0 + f0 * f0 + f1 * f1 + f2 * f2)
    qf = (inv, f0 * inv, f1 * inv, f2 * inv)  # Cay(f)
    q_next = quat_normalize(quat_mul(q, qf))
    # Fᵀ a = a + 2/(1 + f·f) (−f × a + f × (f × a)) (Cayley): a itself exact, rounding only in the small
    # correction (through the unit quaternion instead, |Π| drifted 6e-13 in 4000 steps)
    c = 2.0 / (1.0 + f0 * f0 + f1 * f1 + f2 * f2)
    x0, x1, x2 = f1 * a2 - f2 * a1, f2 * a0 - f0 * a2, f0 * a1 - f1 * a0  # f × a
    y0, y1, y2 = f1 * x2 - f2 * x1, f2 * x0 - f0 * x2, f0 * x1 - f1 * x0  # f × (f × a)
    b0, b1, b2 = a0 + c * (y0 - x0), a1 + c * (y1 - x1), a2 + c * (y2 - x2)
    n0, n1, n2 = torque_at(q_next, t + h, body)
    return (
        ((b0 + 0.5 * h * n0) / I1, (b1 + 0.5 * h * n1) / I2, (b2 + 0.5 * h * n2) / I3),
        q_next,
        n,
    )


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
