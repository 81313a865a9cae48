"""mujoco_rk4: MuJoCo 4.0's "RK4" integrator: the classic RK4 tableau, the quaternion by Runge–Kutta–Munthe-Kaas.

Followed: google-deepmind/mujoco at commit a7255075b003 (3.12.0-31-g, 22 Aug
2026), src/engine/engine_forward.c ``mj_RungeKutta`` (N = 4, RK4_A, RK4_B,
stage states X[i] = X[0] "+" h Σ a_ij F_j through ``mj_integratePos``, final
update through ``mj_advance``), and the behaviour of the ``mujoco`` 4.0.0
wheel (6 Nov 2026), whose source is not in the fetched snapshot.  The
3.12 source sums the stage *velocities* and exponentiates them; 4.0.0 does
not (its one-step orientation error is O(h⁵), 3.12's is O(h³)): one step of
4.0.0 is reproduced to 1e-16 only when each stage velocity first goes
through the exact dexp⁻¹ of the stage's accumulated rotation (RKMK), which is
what this file does (tests/test_engines.py checks 10⁴ steps against the wheel).
With f(q, ω) = M⁻¹ (τ(q) − ω × Iω), E(q, s) = mju_quatIntegrate(q, s, h):

    ω1 = ω0,             k1 = ω1,                         q1 = q0,         a1 = f(q1, ω1)
    ω2 = ω0 + h a1/2,    s2 = k1/2,  q2 = E(q0, s2),  k2 = dexp⁻¹(h s2, ω2),  a2 = f(q2, ω2)
    ω3 = ω0 + h a2/2,    s3 = k2/2,  q3 = E(q0, s3),  k3 = dexp⁻¹(h s3, ω3),  a3 = f(q3, ω3)
    ω4 = ω0 + h a3,      s4 = k3,    q4 = E(q0, s4),  k4 = dexp⁻¹(h s4, ω4),  a4 = f(q4, ω4)
    ω ← ω0 + h Σ bᵢ aᵢ,  q ← E(q0, Σ bᵢ kᵢ),  b = (1/6, 1/3, 1/3, 1/6)

summed in MuJoCo's order (dX = 0; dX += xᵢ bᵢ).  No hidden limits.  Order 4.
The 3.12 variant (no dexp⁻¹) is second order on a body whose ω turns: its
dropped commutator is h³ [ω, ω̇]/6 per step.
"""

from numba import njit

from ..engine_common import dexp_inv, mj_quat_integrate
from .mujoco_euler import qacc

ORDER = 4
SYMPLECTIC = False
REPRODUCES = "MuJoCo 4.0 RK4"  # judged by conformance with the engine (tests/test_engines.py)
# For I1 = I2 every stage acceleration has a3 = 0 exactly, so ω3 is carried unchanged.
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    h = dt
    a1 = qacc(w, q, body)
    k1 = w
    s2 = (k1[0] * 0.5, k1[1] * 0.5, k1[2] * 0.5)
    q2 = mj_quat_integrate(q, s2, h)
    w2 = (w[0] + (a1[0] * 0.5) * h, w[1] + (a1[1] * 0.5) * h, w[2] + (a1[2] * 0.5) * h)
    k2 = dexp_inv((h * s2[0], h * s2[1], h * s2[2]), w2)
    a2 = qacc(w2, q2, body)
    s3 = (k2[0] * 0.5, k2[1] * 0.5, k2[2] * 0.5)
    q3 = mj_quat_integrate(q, s3, h)
    w3 = (w[0] + (a2[0] * 0.5) * h, w[1] + (a2[1] * 0.5) * h, w[2] + (a2[2] * 0.5) * h)
    k3 = dexp_inv((h * s3[0], h * s3[1], h * s3[2]), w3)
    a3 = qacc(w3, q3, body)
    s4 = k3
    q4 = mj_quat_integrate(q, s4, h)
    w4 = (w[0] + a3[0] * h, w[1] + a3[1] * h, w[2] + a3[2] * h)
    k4 = dexp_inv((h * s4[0], h * s4[1], h * s4[2]), w4)
    a4 = qacc(w4, q4, body)
    b1 = 1.0 / 6.0
    b2 = 1.0 / 3.0
    s = (
        0.0 + k1[0] * b1 + k2[0] * b2 + k3[0] * b2 + k4[0] * b1,
        0.0 + k1[1] * b1 + k2[1] * b2 + k3[1] * b2 + k4[1] * b1,
        0.0 + k1[2] * b1 + k2[2] * b2 + k3[2] * b2 + k4[2] * b1,
    )
    a = (
        0.0 + a1[0] * b1 + a2[0] * b2 + a3[0] * b2 + a4[0] * b1,
        0.0 + a1[1] * b1 + a2[1] * b2 + a3[1] * b2 + a4[1] * b1,
        0.0 + a1[2] * b1 + a2[2] * b2 + a3[2] * b2 + a4[2] * b1,
    )
    w_next = (w[0] + a[0] * h, w[1] + a[1] * h, w[2] + a[2] * h)
    return w_next, mj_quat_integrate(q, s, h)
