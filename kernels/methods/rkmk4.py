"""rkmk4: Runge–Kutta–Munthe-Kaas of order 4 on SO(3) × R³ (the classic RK4 tableau, dexp⁻¹ corrected).

Iserles, Munthe-Kaas, Nørsett & Zanna, "Lie-group methods", Acta Numerica 9 (2000) 215–365, Sect. 5.3
(RKMK); the same algorithm as ManifoldDiffEq.jl src/lie_solvers.jl ``RKMK4``.  The orientation is
written q = q0 ⊗ exp(u) and the ODE of u, u̇ = dexp⁻¹_u(ω), is integrated in the Lie algebra R³
beside I ω̇ = τ − ω × Iω, each by the classic RK4 tableau (c = 0, ½, ½, 1; b = 1/6, 1/3, 1/3, 1/6):

    stage i: u_i = h Σ_j a_ij K_j,  Ω_i = ω + h Σ_j a_ij W_j,  Q_i = q ⊗ exp(u_i),
             K_i = dexp⁻¹_{u_i}(Ω_i),  W_i = I⁻¹ (τ(Q_i, t + c_i h) − Ω_i × I Ω_i)
    q ← q ⊗ exp(h Σ b_i K_i),  ω ← ω + h Σ b_i W_i

with the exact closed-form dexp⁻¹ of kernels/engine_common.py (``dexp_inv``; for order 4 the
truncation after the [u, [u, ·]] term would do; exact costs no more).  q stays on the unit sphere by
construction: the update is a product of unit quaternions (renormalised once per step against
rounding).  Each stage sees the torque at its own time, so a drive keeps the fourth order.  Not
symplectic; ω3 of the symmetric top with its centre of mass on e3 is carried exactly (its ω̇3 is 0
at every stage), so L3 is kept.  The same map as mujoco_rk4 (MuJoCo 4.0 applies dexp⁻¹ to its stage
velocities), written here in gyrolab's own helpers and with time: tests/test_md_methods.py checks
that the two agree to rounding.
"""

from numba import njit

from ..body import without_drive
from ..engine_common import dexp_inv
from ..rigid_body import euler_rhs, torque_at
from ..rotation import quat_from_rotvec, quat_mul, quat_normalize

ORDER = 4
SYMPLECTIC = False
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def _exp_right(q, u):
    """q ⊗ exp(u): the body turned by the rotation vector u (rad, body frame)."""
    return quat_mul(q, quat_from_rotvec(u[0], u[1], u[2]))


@njit(cache=True, error_model="numpy")
def _axpy(x, h, k):
    """x + h k on 3-tuples."""
    return x[0] + h * k[0], x[1] + h * k[1], x[2] + h * k[2]


@njit(cache=True, error_model="numpy")
def _slopes(u, w_stage, q, t, body):
    """(K, W) of a stage: the Lie-algebra velocity dexp⁻¹_u(Ω) and ω̇ at the stage orientation q ⊗ exp(u)."""
    k = dexp_inv(u, w_stage)
    wd = euler_rhs(w_stage, torque_at(_exp_right(q, u), t, body), body)
    return k, wd


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One RKMK4 step of dt seconds from time t (s); the stages at t, t + dt/2, t + dt/2, t + dt."""
    h = dt
    half = 0.5 * h
    zero = (0.0, 0.0, 0.0)
    k1, w1 = _slopes(zero, w, q, t, body)
    k2, w2 = _slopes(_axpy(zero, half, k1), _axpy(w, half, w1), q, t + half, body)
    k3, w3 = _slopes(_axpy(zero, half, k2), _axpy(w, half, w2), q, t + half, body)
    k4, w4 = _slopes(_axpy(zero, h, k3), _axpy(w, h, w3), q, t + h, body)
    s = h / 6.0
    u = (
        s * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
        s * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
        s * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]),
    )
    w_next = (
        w[0] + s * (w1[0] + 2.0 * (w2[0] + w3[0]) + w4[0]),
        w[1] + s * (w1[1] + 2.0 * (w2[1] + w3[1]) + w4[1]),
        w[2] + s * (w1[2] + 2.0 * (w2[2] + w3[2]) + w4[2]),
    )
    return w_next, quat_normalize(_exp_right(q, u))


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
