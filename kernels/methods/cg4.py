"""cg4: Crouch–Grossman method of order 4 (five stages, frozen body velocities composed as exponentials).

Crouch & Grossman, J. Nonlinear Sci. 3 (1993) 1–33; the fourth-order coefficients are Example 1 of
Jackiewicz, Marthinsen & Owren, "Construction of Runge–Kutta methods of Crouch–Grossman type of high
order", Adv. Comput. Math. 13 (2000) 405–415, as ManifoldDiffEq.jl ships them (Source:
JuliaManifolds/ManifoldDiffEq.jl src/frozen_solvers.jl ``CG4a`` at commit 07c94fef, 16 digits).  A
Crouch–Grossman method freezes each stage's vector field and composes the exponentials of the frozen
fields instead of summing them in one exponential (RKMK): with the body velocity a left-invariant
field (q̇ = ½ q ⊗ (0, ω)),

    Q_i = q ⊗ exp(h a_i1 Ω_1) ⊗ exp(h a_i2 Ω_2) ⊗ … ⊗ exp(h a_i,i−1 Ω_i−1),  Ω_i = ω + h Σ_j a_ij W_j,
    W_i = I⁻¹ (τ(Q_i, t + c_i h) − Ω_i × I Ω_i),
    q ← q ⊗ exp(h b_1 Ω_1) ⊗ … ⊗ exp(h b_5 Ω_5),  ω ← ω + h Σ b_i W_i

(the first factor next to q, as ManifoldDiffEq.jl retracts X1 first).  No dexp⁻¹ is needed; the price
is five stages and the Crouch–Grossman order conditions, which these coefficients solve to 16 digits
(tests/test_md_methods.py checks the classical conditions through order 4 to 1e-15).  Unit q by
construction (renormalised once per step against rounding).  Each stage sees the torque at its own
time t + c_i h.  Not symplectic; ω3 of the symmetric top with its centre of mass on e3 is carried
exactly, so L3 is kept.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import euler_rhs, torque_at
from ..rotation import quat_from_rotvec, quat_mul, quat_normalize

ORDER = 4
SYMPLECTIC = False
PRESERVES = ("L3",)

# JMO (2000) Example 1, as ManifoldDiffEq.jl CG4a
A21 = 0.8177227988124852
A31, A32 = 0.3199876375476427, 0.0659864263556022
A41, A42, A43 = 0.9214417194464946, 0.4997857776773573, -1.0969984448371582
A51, A52, A53, A54 = 0.3552358559023322, 0.2390958372307326, 1.3918565724203246, -1.1092979392113465
B1, B2, B3 = 0.1370831520630755, -0.0183698531564020, 0.7397813985370780
B4, B5 = -0.1907142565505889, 0.3322195591068374
C2, C3, C4, C5 = 0.8177227988124852, 0.3859740639032449, 0.3242290522866937, 0.8768903263420429


@njit(cache=True, error_model="numpy")
def _turn(q, h, w):
    """q ⊗ exp(h ω): the body turned by the frozen body velocity ω for h seconds."""
    return quat_mul(q, quat_from_rotvec(h * w[0], h * w[1], h * w[2]))


@njit(cache=True, error_model="numpy")
def _velocity(w, h, a, b, c, d, wa, wb, wc, wd):
    """ω + h (a W_a + b W_b + c W_c + d W_d) on 3-tuples."""
    return (
        w[0] + h * (a * wa[0] + b * wb[0] + c * wc[0] + d * wd[0]),
        w[1] + h * (a * wa[1] + b * wb[1] + c * wc[1] + d * wd[1]),
        w[2] + h * (a * wa[2] + b * wb[2] + c * wc[2] + d * wd[2]),
    )


@njit(cache=True, error_model="numpy")
def _accel(w, q, t, body):
    return euler_rhs(w, torque_at(q, t, body), body)


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One CG4 step of dt seconds from time t (s); stage i at t + c_i dt."""
    h = dt
    zero = (0.0, 0.0, 0.0)
    o1 = w
    w1 = _accel(o1, q, t, body)
    q2 = _turn(q, A21 * h, o1)
    o2 = _velocity(w, h, A21, 0.0, 0.0, 0.0, w1, zero, zero, zero)
    w2 = _accel(o2, q2, t + C2 * h, body)
    q3 = _turn(_turn(q, A31 * h, o1), A32 * h, o2)
    o3 = _velocity(w, h, A31, A32, 0.0, 0.0, w1, w2, zero, zero)
    w3 = _accel(o3, q3, t + C3 * h, body)
    q4 = _turn(_turn(_turn(q, A41 * h, o1), A42 * h, o2), A43 * h, o3)
    o4 = _velocity(w, h, A41, A42, A43, 0.0, w1, w2, w3, zero)
    w4 = _accel(o4, q4, t + C4 * h, body)
    q5 = _turn(_turn(_turn(_turn(q, A51 * h, o1), A52 * h, o2), A53 * h, o3), A54 * h, o4)
    o5 = _velocity(w, h, A51, A52, A53, A54, w1, w2, w3, w4)
    w5 = _accel(o5, q5, t + C5 * h, body)
    q_next = _turn(_turn(_turn(_turn(_turn(q, B1 * h, o1), B2 * h, o2), B3 * h, o3), B4 * h, o4), B5 * h, o5)
    w_next = _velocity(w, h, B1, B2, B3, B4, w1, w2, w3, w4)
    w_next = (w_next[0] + h * B5 * w5[0], w_next[1] + h * B5 * w5[1], w_next[2] + h * B5 * w5[2])
    return w_next, quat_normalize(q_next)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
