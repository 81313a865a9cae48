"""solfec_imp: Solfec's RIG_IMP rigid rotation update (Koziara's "NEW3"): half-step, torque at t + h/2, Newton.

The scheme of T. Koziara and N. Bićanić, "Simple and efficient integration of rigid rotations suitable
for constraint solvers", IJNME 81 (2009) 1073–1092, as Solfec ships it: parmes/solfec-1.0 (the
repository tkoziara/solfec) at commit 287fba1d3f120529a01354b9d5457c77f0e1cbc2, file bod.c, functions
BODY_Dynamic_Step_Begin and BODY_Dynamic_Step_End (case RIG, bod->scheme == SCH_RIG_IMP) and the Newton
solver SOLVE; the exponential map and its partial derivatives are alg.h's EXPMAP and EXPMAP123.  With
J = diag(I1, I2, I3) the referential inertia, W the referential (body) angular velocity, Λ the rotation
(body → lab), T the referential torque and one step of h = dt from time t:

    Λ_{1/2} = Λ_n exp(h/2 Ŵ_n)                                      (Step_Begin: EXPMAP, NNMUL),
    T = T(Λ_{1/2}, t + h/2)                       (rig_force at time + half: reftorq + Λ_{1/2}ᵀ spatorq),
    A = exp(−h/2 Ŵ_n) J W_n + h T                                    (RIG_AUXILIARY: TVMUL, ADDMUL),
    W_{1/2} = J⁻¹ [exp(−h/2 Ŵ_n) J W_n + h/2 T],
    W⁰ = W_n + h J⁻¹ (T − W_{1/2} × J W_{1/2})                          (the explicit NEW1 velocity),
    solve exp(h/2 Ŵ) J W = A for W_{n+1} by Newton from W⁰                (Step_End: SOLVE (half, ...)),
    Λ_{n+1} = Λ_{1/2} exp(h/2 Ŵ_{n+1}).

Newton, as SOLVE has it: residual r(W) = exp(h/2 Ŵ) J W − A, tangent
Z = h/2 [∂exp/∂O_1 JW | ∂exp/∂O_2 JW | ∂exp/∂O_3 JW] + exp(h/2 Ŵ) J (O = h/2 W, ∂exp/∂O_k from
EXPMAP123), W ← W − Z⁻¹ r (LAPACK dgesv: LU with partial pivoting, written out here as dgetf2/dgetrs
do it, the multipliers by the pivot's reciprocal).  **Tolerance**: stop when max_i |r_i| ≤ 1e-12 · (h/2)
(SOLVE's `level = 1E-12 * h` with its argument h = half the step; absolute, in N m s).  **Iteration
cap**: SOLVE's `ASSERT (++i < 50, ERR_BOD_NEW3_NEWTON_DIVERGENCE)` follows every update, so at most 49
Newton updates succeed and the 50th aborts Solfec; here a step that has not met the tolerance within
49 updates (or whose LU meets a zero pivot, Solfec's ERR_BOD_NEW3_SINGULAR_JACOBIAN, or whose residual
turns NaN) returns NaN for ω and q, so the run ends with the status "unconverged".  A state that
already meets the tolerance with W⁰ takes no update (0 iterations counted).

Mapping.  Solfec stores Λ as a column-major 3×3 matrix (bod->conf[0..8]) and W = RIG_ANGVEL in the body
frame; here Λ = R(q), the quaternion's body → lab matrix, and W = ω.  The products Λ exp(Ô) are
quat_mul(q, quat_from_rotvec(O)) (exactly the same rotations; the matrices and quaternions round
differently, to a few ulp), and q is renormalised once per step (Solfec's Λ is never re-orthogonalised;
both drift by rounding only).  Everything acting on W is Solfec's own arithmetic in its order: EXPMAP's
matrix (Taylor below 10° as shipped), J⁻¹ as the reciprocals dgetri gives for the diagonal J, the
torque from gyrolab's torque_at at Λ_{1/2} (Solfec's validation top passes its spatial torque
−20 (Λ e3) × e3 through a FORCE callback; a drive, fixed in the body, is a CONVECTED torque, reftorq).
Only the rotation is reproduced: the body's centre is fixed (the pivot), no constraints (their impulse
would enter A and W at Step_End as zero here).

Order and invariants (tests/test_solfec_imp.py).  Second order (measured slope 2.00 on the 50 Hz top,
tests/test_engines.py; error ratios 4.00 per halving).  Torque-free, the lab momentum is kept up to the
Newton residual: Λ_{n+1} J W_{n+1} = Λ_{1/2} (A + r) = Λ_n J W_n + Λ_{1/2} r (exp(h/2 Ŵ_n) fixes W_n),
and Newton's last update leaves |r| far below its level in practice; so L, |L|, and under gravity L_z
(the spatial torque is horizontal) stay within 6e-13 of |L| over 2000 steps on every scene that conserves
them.  They are kept to the Newton residual, not to rounding: over the verdict's 1e6 steps of 1e-3 s they
drift linearly (L by 3.5e-14 /s on the free asymmetric body, above the verdict's 0.1 eps a step), so
PRESERVES declares none of them.  Not symplectic; the energy is not kept (Solfec: "no energy drift", a
bounded error: max |ΔH|/H 1.2e-7 on Solfec's top at h = 9e-3).

Finding: SOLVE's level 1e-12 · h/2 is absolute, while the residual rounds at ~eps |J W|; when
h < ~1e-3 |J W| / (N m s) Newton can stall at the rounding floor and trip the ASSERT, i.e. Solfec stops
the run; here the run turns NaN (gyrolab's 50 Hz heavy top, |J W| = 0.39 N m s, at h ≤ 1e-4 s).
"""

import math

from numba import njit

from ..body import without_drive
from ..rigid_body import torque_at
from ..rotation import quat_from_rotvec, quat_mul, quat_normalize

ORDER = 2
SYMPLECTIC = False
PRESERVES = ()  # L, |L|, L_z: to the Newton residual (above), not to rounding
REPRODUCES = "Solfec RIG_IMP (NEW3), parmes/solfec-1.0 287fba1"

BLOCKS = False  # a Newton loop per step: the lanes do not vectorise it, and its iterations are counted
MAX_ITERATIONS = 50  # SOLVE's ASSERT (++i < 50): the 50th update aborts, so 49 can succeed
TOLERANCE = 1e-12  # SOLVE's level = 1E-12 * h, h its argument (half the step): max |r_i| <= 1e-12 * dt / 2

DEG_10_SQ = 3.0461741978671e-02  # alg.h: ten degrees squared in radians, EXPMAP's Taylor threshold


@njit(cache=True, error_model="numpy")
def _sinc_taylor(x):
    """sin|o|/|o| as alg.h's Horner polynomial in x = |o|², the Taylor series EXPMAP and EXPMAP123 share
    below ten degrees."""
    return (
        1.0
        + (
            -1.666666666666667e-1
            + (
                8.333333333333333e-3
                + (
                    -1.984126984126984e-4
                    + (2.755731922398589e-6 + (-2.505210838544172e-8 + 1.605904383682161e-10 * x) * x) * x
                )
                * x
            )
            * x
        )
        * x
    )


@njit(cache=True, error_model="numpy")
def _expmap(o0, o1, o2):
    """alg.h EXPMAP: exp(Ô) = I + sin|o|/|o| Ô + (1 − cos|o|)/|o|² Ô², as the 9-tuple of Solfec's
    column-major matrix (element (i, j) at 3 j + i), in its arithmetic (Taylor below 10°)."""
    x = o0 * o0 + o1 * o1 + o2 * o2
    if x < DEG_10_SQ:
        s = _sinc_taylor(x)
        c = (
            0.5
            + (
                -4.166666666666667e-2
                + (
                    1.388888888888889e-3
                    + (
                        -2.480158730158730e-5
                        + (2.755731922398589e-7 + (-2.087675698786810e-9 + 1.147074559772972e-11 * x) * x) * x
                    )
                    * x
                )
                * x
            )
            * x
        )
    else:
        a = math.sqrt(x)
        s = math.sin(a) / a
        c = (1.0 - math.cos(a)) / x
    p0, p1, p2 = o0 * o0, o1 * o1, o2 * o2
    p01, p02, p12 = o0 * o1, o0 * o2, o1 * o2
    s0, s1, s2 = s * o0, s * o1, s * o2
    r1 = c * p01
    r2 = c * p02
    r5 = c * p12
    return (
        -c * (p2 + p1) + 1.0,
        r1 + s2,
        r2 - s1,
        r1 - s2,
        -c * (p2 + p0) + 1.0,
        r5 + s0,
        r2 + s1,
        r5 - s0,
        -c * (p1 + p0) + 1.0,
    )


@njit(cache=True, error_model="numpy")
def _expmap_column(d, o, a, cb, k, j):
    """Element (i, k) of EXPMAP123's R_j for i = 0, 1, 2 (column k), given aux's column k ``d``: the
    shipped formulas, one column of one partial derivative ∂exp(Ô)/∂O_j (column-major, 3 k + i)."""
    oj = o[j]
    r0, r1, r2 = d[0] * oj, d[1] * oj, d[2] * oj
    # the additive terms of alg.h's R0, R1, R2, element by element (tmp = c_b O, a)
    if j == 0:
        if k == 0:
            return r0 + 2.0 * cb[0], r1 + cb[1], r2 + cb[2]
        if k == 1:
            return r0 + cb[1], r1, r2 + a
        return r0 + cb[2], r1 - a, r2
    if j == 1:
        if k == 0:
            return r0, r1 + cb[0], r2 - a
        if k == 1:
            return r0 + cb[0], r1 + 2.0 * cb[1], r2 + cb[2]
        return r0 + a, r1 + cb[2], r2
    if k == 0:
        return r0, r1 + a, r2 + cb[0]
    if k == 1:
        return r0 - a, r1, r2 + cb[1]
    return r0 + cb[0], r1 + cb[1], r2 + 2.0 * cb[2]


@njit(cache=True, error_model="numpy")
def _tangent_column(o0, o1, o2, jw0, jw1, jw2, j):
    """Column j of SOLVE's Z before scaling: (∂exp(Ô)/∂O_j) J W (alg.h EXPMAP123, then NVMUL)."""
    x = o0 * o0 + o1 * o1 + o2 * o2
    if x < 1e-16 * DEG_10_SQ:  # the derivatives at O = 0: ∂exp/∂O_j = ê_j
        if j == 0:
            return (
                0.0 * jw0 + 0.0 * jw1 + 0.0 * jw2,
                0.0 * jw0 + 0.0 * jw1 - 1.0 * jw2,
                0.0 * jw0 + 1.0 * jw1 + 0.0 * jw2,
            )
        if j == 1:
            return (
                0.0 * jw0 + 0.0 * jw1 + 1.0 * jw2,
                0.0 * jw0 + 0.0 * jw1 + 0.0 * jw2,
                -1.0 * jw0 + 0.0 * jw1 + 0.0 * jw2,
            )
        return 0.0 * jw0 - 1.0 * jw1 + 0.0 * jw2, 1.0 * jw0 + 0.0 * jw1 + 0.0 * jw2, 0.0 * jw0 + 0.0 * jw1 + 0.0 * jw2
    c = 1.0 / x
    if x < DEG_10_SQ:
        a = _sinc_taylor(x)
        b = (
            c
            - 0.5
            + (
                4.166666666666667e-2
                + (
                    -1.388888888888889e-3
                    + (
                        2.480158730158730e-5
                        + (-2.755731922398589e-7 + (2.087675698786810e-9 - 1.147074559772972e-11 * x) * x) * x
                    )
                    * x
                )
                * x
            )
            * x
        )
    else:
        x = math.sqrt(x)
        a = math.sin(x) / x
        b = c * math.cos(x)
    b_ac = b - a * c
    ac_2cc_2bc = (a - 2.0 * (c - b)) * c
    c_b = c - b
    t0, t1, t2 = o0 * b_ac, o1 * b_ac, o2 * b_ac
    # aux = ac_2cc_2bc O Oᵀ − a I + b_ac Ô (column-major, DIADIC then SCALE9 then the additions)
    a0 = o0 * o0 * ac_2cc_2bc - a
    a1 = o1 * o0 * ac_2cc_2bc + t2
    a2 = o2 * o0 * ac_2cc_2bc - t1
    a3 = o0 * o1 * ac_2cc_2bc - t2
    a4 = o1 * o1 * ac_2cc_2bc - a
    a5 = o2 * o1 * ac_2cc_2bc + t0
    a6 = o0 * o2 * ac_2cc_2bc + t1
    a7 = o1 * o2 * ac_2cc_2bc - t0
    a8 = o2 * o2 * ac_2cc_2bc - a
    o = (o0, o1, o2)
    cb = (o0 * c_b, o1 * c_b, o2 * c_b)
    k0 = _expmap_column((a0, a1, a2), o, a, cb, 0, j)
    k1 = _expmap_column((a3, a4, a5), o, a, cb, 1, j)
    k2 = _expmap_column((a6, a7, a8), o, a, cb, 2, j)
    # NVMUL (R_j, JW): (R_j JW)_i = R_j(i, 0) JW_0 + R_j(i, 1) JW_1 + R_j(i, 2) JW_2
    return (
        k0[0] * jw0 + k1[0] * jw1 + k2[0] * jw2,
        k0[1] * jw0 + k1[1] * jw1 + k2[1] * jw2,
        k0[2] * jw0 + k1[2] * jw1 + k2[2] * jw2,
    )


@njit(cache=True, error_model="numpy")
def _solve3(z, r0, r1, r2):
    """x with Z x = r for the column-major 3×3 ``z``: LAPACK dgesv's LU with partial pivoting (dgetf2:
    the first largest |pivot|, multipliers by its reciprocal; dgetrs: row swaps, unit-lower forward and
    upper back substitution by columns).  A zero pivot (dgesv's info > 0) gives NaN."""
    a00, a10, a20, a01, a11, a21, a02, a12, a22 = z
    b0, b1, b2 = r0, r1, r2
    # column 0: pivot row (idamax: the first of the largest)
    m = abs(a00)
    p = 0
    if abs(a10) > m:
        m = abs(a10)
        p = 1
    if abs(a20) > m:
        p = 2
    if p == 1:
        a00, a10 = a10, a00
        a01, a11 = a11, a01
        a02, a12 = a12, a02
        b0, b1 = b1, b0
    elif p == 2:
        a00, a20 = a20, a00
        a01, a21 = a21, a01
        a02, a22 = a22, a02
        b0, b2 = b2, b0
    if a00 == 0.0:
        nan = math.nan
        return nan, nan, nan
    inv = 1.0 / a00
    l10 = a10 * inv
    l20 = a20 * inv
    a11 = a11 - l10 * a01
    a21 = a21 - l20 * a01
    a12 = a12 - l10 * a02
    a22 = a22 - l20 * a02
    # column 1
    if abs(a21) > abs(a11):
        a11, a21 = a21, a11
        a12, a22 = a22, a12
        l10, l20 = l20, l10
        b1, b2 = b2, b1
    if a11 == 0.0:
        nan = math.nan
        return nan, nan, nan
    l21 = a21 * (1.0 / a11)
    a22 = a22 - l21 * a12
    if a22 == 0.0:
        nan = math.nan
        return nan, nan, nan
    # forward (unit lower), then back substitution (upper), column by column as dtrsm does
    b1 = b1 - b0 * l10
    b2 = b2 - b0 * l20
    b2 = b2 - b1 * l21
    b2 = b2 / a22
    b0 = b0 - b2 * a02
    b1 = b1 - b2 * a12
    b1 = b1 / a11
    b0 = b0 - b1 * a01
    b0 = b0 / a00
    return b0, b1, b2


@njit(cache=True, error_model="numpy")
def _residual(w0, w1, w2, half, I1, I2, I3, g0, g1, g2):
    """SOLVE's residual r = exp(h/2 Ŵ) J W − G with its exp(h/2 Ŵ) (EXPMAP) and B = exp(h/2 Ŵ) J."""
    e = _expmap(w0 * half, w1 * half, w2 * half)
    # NNMUL (A, J, B) with J diagonal: B(i, j) = A(i, j) J_j (the off-diagonal zeros add nothing)
    b = (e[0] * I1, e[1] * I1, e[2] * I1, e[3] * I2, e[4] * I2, e[5] * I2, e[6] * I3, e[7] * I3, e[8] * I3)
    r0 = b[0] * w0 + b[3] * w1 + b[6] * w2 - g0
    r1 = b[1] * w0 + b[4] * w1 + b[7] * w2 - g1
    r2 = b[2] * w0 + b[5] * w1 + b[8] * w2 - g2
    return b, r0, r1, r2


@njit(cache=True, error_model="numpy", forceinline=True)
def step_begin(w, q, t, dt, body):
    """Solfec's BODY_Dynamic_Step_Begin and RIG_AUXILIARY, shared by RIG_IMP and RIG_NEG: (Λ_{1/2} as a
    quaternion, A = exp(−h/2 Ŵ_n) J W_n + h T (N m s, body frame), the explicit velocity W⁰ (rad/s, body))."""
    I1, I2, I3 = body[0], body[1], body[2]
    half = 0.5 * dt
    W0, W1, W2 = w
    # Step_Begin: DR = exp(h/2 Ŵ_n), Λ_{1/2} = Λ_n DR, the torque at Λ_{1/2} and t + h/2
    o0, o1, o2 = W0 * half, W1 * half, W2 * half
    dr = _expmap(o0, o1, o2)
    q_half = quat_mul(q, quat_from_rotvec(o0, o1, o2))
    f0, f1, f2 = torque_at(q_half, t + half, body)
    jw0, jw1, jw2 = I1 * W0, I2 * W1, I3 * W2
    # TVMUL (DR, JW): DRᵀ J W_n = exp(−h/2 Ŵ_n) J W_n
    e0 = dr[0] * jw0 + dr[1] * jw1 + dr[2] * jw2
    e1 = dr[3] * jw0 + dr[4] * jw1 + dr[5] * jw2
    e2 = dr[6] * jw0 + dr[7] * jw1 + dr[8] * jw2
    g0, g1, g2 = e0 + dt * f0, e1 + dt * f1, e2 + dt * f2  # A = exp(−h/2 Ŵ_n) J W_n + h T
    # W_{1/2} = J⁻¹ [(h/2) T + DRᵀ J W_n] (TVADDMUL, then NVMUL by J⁻¹'s reciprocals)
    inv1, inv2, inv3 = 1.0 / I1, 1.0 / I2, 1.0 / I3
    v0 = inv1 * (f0 * half + e0)
    v1 = inv2 * (f1 * half + e1)
    v2 = inv3 * (f2 * half + e2)
    u0, u1, u2 = I1 * v0, I2 * v1, I3 * v2
    # force = T − W_{1/2} × J W_{1/2} (PRODUCTSUB); W⁰ = W_n + (h force) J⁻¹ (dgemv, alpha = h, beta = 1)
    f0 = f0 - (v1 * u2 - v2 * u1)
    f1 = f1 - (v2 * u0 - v0 * u2)
    f2 = f2 - (v0 * u1 - v1 * u0)
    W0 = W0 + dt * f0 * inv1
    W1 = W1 + dt * f1 * inv2
    W2 = W2 + dt * f2 * inv3
    return q_half, (g0, g1, g2), (W0, W1, W2)


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven_counted(w, q, t, dt, body):
    """One Solfec RIG_IMP step of dt seconds from time t (s), the torque at t + dt/2, and SOLVE's
    Newton iterations (< 0: not converged, the state NaN)."""
    I1, I2, I3 = body[0], body[1], body[2]
    half = 0.5 * dt
    q_half, (g0, g1, g2), (W0, W1, W2) = step_begin(w, q, t, dt, body)
    # Step_End: SOLVE (half, J, W, A, DR), Newton from W⁰
    level = TOLERANCE * half
    b, r0, r1, r2 = _residual(W0, W1, W2, half, I1, I2, I3, g0, g1, g2)
    error = max(abs(r0), abs(r1), abs(r2))
    n = 0
    while error > level:
        jw0, jw1, jw2 = I1 * W0, I2 * W1, I3 * W2
        o0, o1, o2 = W0 * half, W1 * half, W2 * half
        z0 = _tangent_column(o0, o1, o2, jw0, jw1, jw2, 0)
        z1 = _tangent_column(o0, o1, o2, jw0, jw1, jw2, 1)
        z2 = _tangent_column(o0, o1, o2, jw0, jw1, jw2, 2)
        # SCALE9 (Z, h/2), NNADD (Z, B, Z): the tangent dexp h/2 JW + exp J, column-major
        z = (
            z0[0] * half + b[0],
            z0[1] * half + b[1],
            z0[2] * half + b[2],
            z1[0] * half + b[3],
            z1[1] * half + b[4],
            z1[2] * half + b[5],
            z2[0] * half + b[6],
            z2[1] * half + b[7],
            z2[2] * half + b[8],
        )
        x0, x1, x2 = _solve3(z, r0, r1, r2)
        W0, W1, W2 = W0 - x0, W1 - x1, W2 - x2
        b, r0, r1, r2 = _residual(W0, W1, W2, half, I1, I2, I3, g0, g1, g2)
        error = max(abs(r0), abs(r1), abs(r2))
        n += 1
        if n >= MAX_ITERATIONS:  # ASSERT (++i < 50, ERR_BOD_NEW3_NEWTON_DIVERGENCE)
            break
    if not error <= level or n >= MAX_ITERATIONS:  # not converged, a zero pivot, or NaN
        nan = math.nan
        return (nan, nan, nan), (nan, nan, nan, nan), -max(n, 1)
    # Λ_{n+1} = Λ_{1/2} exp(h/2 Ŵ_{n+1})
    q_next = quat_mul(q_half, quat_from_rotvec(W0 * half, W1 * half, W2 * half))
    return (W0, W1, W2), quat_normalize(q_next), n


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
