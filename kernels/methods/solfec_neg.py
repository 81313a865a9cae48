"""solfec_neg: Solfec's default rigid rotation update RIG_NEG (Koziara's "NEW2"): explicit, momentum-exact.

T. Koziara and N. Bićanić, "Simple and efficient integration of rigid rotations suitable for constraint
solvers", IJNME 81 (2009) 1073–1092, as Solfec ships it, its default for rigid bodies: parmes/solfec-1.0
(the repository tkoziara/solfec) at commit 287fba1d3f120529a01354b9d5457c77f0e1cbc2, file bod.c,
functions BODY_Dynamic_Step_Begin and BODY_Dynamic_Step_End (case RIG, bod->scheme == SCH_RIG_NEG);
the exponential map is alg.h's EXPMAP.  With J = diag(I1, I2, I3), W the referential (body) angular
velocity, Λ the rotation (body → lab), T the referential torque and one step of h = dt from time t:

    Λ_{1/2} = Λ_n exp(h/2 Ŵ_n),   T = T(Λ_{1/2}, t + h/2),
    A = exp(−h/2 Ŵ_n) J W_n + h T,
    W_{1/2} = J⁻¹ [exp(−h/2 Ŵ_n) J W_n + h/2 T],
    W¹ = W_n + h J⁻¹ (T − W_{1/2} × J W_{1/2})                    (Step_Begin: the NEW1 velocity),
    Λ_{n+1} = Λ_{1/2} exp(h/2 Ŵ¹),
    W_{n+1} = J⁻¹ exp(−h/2 Ŵ¹) A                                    (Step_End: TVMUL, NVMUL by J⁻¹).

Step_Begin is solfec_imp's (kernels/methods/solfec_imp.py, its helpers); RIG_NEG differs only in its
end: no Newton, the rotation advanced by the explicit W¹ and the momentum A pulled back by that same
rotation.  Mapping as in solfec_imp: Λ = R(q) and the products Λ exp(Ô) are quaternion products
(quat_mul(q, quat_from_rotvec(O))), q renormalised once per step; everything acting on W is Solfec's
arithmetic in its order (EXPMAP's matrix, J⁻¹ as reciprocals, dgemv's order).  Only the rotation is
reproduced (fixed centre, no constraints: their impulse would enter W and A as zero here).

Order and invariants (tests/test_solfec_imp.py).  Λ_{n+1} J W_{n+1} = Λ_{1/2} A = Λ_n J W_n + h Λ_{1/2} T
exactly in exact arithmetic (exp(h/2 Ŵ¹) cancels): torque-free, the lab momentum L and |L| are kept to
rounding (PRESERVES), and under gravity L_z (the spatial torque Λ_{1/2} T is horizontal): Solfec's "exact
momentum conservation".  L_z is kept only to a few ulp a step: the torque turns to the lab through the
quaternion Λ_{1/2} while A uses EXPMAP's matrix, and the two round differently; on the heavy top it stays
at rounding, with the centre of mass off the axis (heavy_body, kovalevskaya) it drifts 2.3–3.3e-14 /s at
dt = 1e-3 s (docs/verdict.md), above the verdict's 0.1 eps a step, so L_z is not declared.  Its energy
drifts (Solfec: "negative energy drift").  Explicit; second order (measured); not symplectic.
"""

from numba import njit

from ..body import without_drive
from ..rotation import quat_from_rotvec, quat_mul, quat_normalize
from .solfec_imp import _expmap, step_begin

ORDER = 2
SYMPLECTIC = False
PRESERVES = ("L", "L_norm")
REPRODUCES = "Solfec RIG_NEG (NEW2), parmes/solfec-1.0 287fba1"


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One Solfec RIG_NEG step of dt seconds from time t (s); the torque at t + dt/2."""
    I1, I2, I3 = body[0], body[1], body[2]
    half = 0.5 * dt
    q_half, (g0, g1, g2), (W0, W1, W2) = step_begin(w, q, t, dt, body)  # as solfec_imp
    inv1, inv2, inv3 = 1.0 / I1, 1.0 / I2, 1.0 / I3
    # Step_End (SCH_RIG_NEG): DR = exp(h/2 Ŵ¹), Λ_{n+1} = Λ_{1/2} DR, W_{n+1} = J⁻¹ DRᵀ A
    o0, o1, o2 = W0 * half, W1 * half, W2 * half
    dr = _expmap(o0, o1, o2)
    q_next = quat_mul(q_half, quat_from_rotvec(o0, o1, o2))
    a0 = dr[0] * g0 + dr[1] * g1 + dr[2] * g2
    a1 = dr[3] * g0 + dr[4] * g1 + dr[5] * g2
    a2 = dr[6] * g0 + dr[7] * g1 + dr[8] * g2
    return (inv1 * a0, inv2 * a1, inv3 * a2), quat_normalize(q_next)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
