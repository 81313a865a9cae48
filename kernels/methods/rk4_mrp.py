"""rk4_mrp: classic RK4 on modified Rodrigues parameters σ and ω, with the shadow-set switch (Basilisk).

The spacecraft hub of Basilisk (Source: AVSLab/basilisk
src/simulation/dynamics/_GeneralModuleFiles/hubEffector.cpp at commit 04b930dc, ``computeDerivatives``
and ``modifyStates``; its default integrator is svIntegratorRK4): the attitude state is σ_BN, the MRP
of the body relative to the inertial frame, with σ̇ = ¼ B(σ) ω, B(σ) = (1 − σ²) 1 + 2 [σ×] + 2 σσᵀ,
beside Euler's equations I ω̇ = τ − ω × Iω; both are advanced by one classic RK4 step, each stage
seeing the torque of its own orientation and time (t, t + dt/2, t + dt/2, t + dt).  After the whole
step (never at a stage) Basilisk's ``modifyStates`` switches to the shadow set when |σ| > 1:
σ ← −σ/|σ|², the same attitude with |σ| < 1.

gyrolab carries (ω, q) between steps: σ = (b, c, d)/(1 + a) for q = (a, b, c, d) with a ≥ 0 (−q
otherwise: the same rotation), so |σ| ≤ 1 as Basilisk's state after its switch, and back
q = ((1 − σ²), 2σ)/(1 + σ²).  The two are exact inverses in exact arithmetic (Schaub & Junkins,
Analytical Mechanics of Space Systems, 3.7); in floating point they cost a few ulp per step.  The
MRP σ_BN of Basilisk (N → B) is the MRP of gyrolab's q (body → lab), as both describe the same
attitude.  q is a unit quaternion by construction (no renormalisation is needed).  Not symplectic;
fourth order; ω3 of a symmetric top with its centre of mass on e3 stays constant exactly (ω̇3 = 0
at every stage), so L3 is kept.
"""

from numba import njit

from ..body import without_drive
from ..rigid_body import euler_rhs, torque_at

ORDER = 4
SYMPLECTIC = False
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def mrp_from_quat(q):
    """σ with |σ| ≤ 1 of the unit quaternion q (scalar first)."""
    a, b, c, d = q
    if a >= 0.0:
        s = 1.0 / (1.0 + a)
    else:
        s = -1.0 / (1.0 - a)
    return b * s, c * s, d * s


@njit(cache=True, error_model="numpy")
def quat_from_mrp(sigma):
    """The unit quaternion ((1 − σ²), 2σ)/(1 + σ²) of σ (scalar ≥ 0 when |σ| ≤ 1)."""
    s1, s2, s3 = sigma
    n2 = s1 * s1 + s2 * s2 + s3 * s3
    inv = 1.0 / (1.0 + n2)
    return (1.0 - n2) * inv, 2.0 * s1 * inv, 2.0 * s2 * inv, 2.0 * s3 * inv


@njit(cache=True, error_model="numpy")
def _rates(w, sigma, t, body):
    """(ω̇, σ̇) at time t (s): Euler's equations with the torque at the orientation of σ, and ¼ B(σ) ω."""
    wd = euler_rhs(w, torque_at(quat_from_mrp(sigma), t, body), body)
    s1, s2, s3 = sigma
    w1, w2, w3 = w
    n2 = s1 * s1 + s2 * s2 + s3 * s3
    sw = s1 * w1 + s2 * w2 + s3 * w3
    c = 1.0 - n2
    return wd, (
        0.25 * (c * w1 + 2.0 * (s2 * w3 - s3 * w2) + 2.0 * s1 * sw),
        0.25 * (c * w2 + 2.0 * (s3 * w1 - s1 * w3) + 2.0 * s2 * sw),
        0.25 * (c * w3 + 2.0 * (s1 * w2 - s2 * w1) + 2.0 * s3 * sw),
    )


@njit(cache=True, error_model="numpy")
def _stage(w, sigma, h, k):
    kw, ks = k
    return (
        (w[0] + h * kw[0], w[1] + h * kw[1], w[2] + h * kw[2]),
        (sigma[0] + h * ks[0], sigma[1] + h * ks[1], sigma[2] + h * ks[2]),
    )


@njit(cache=True, error_model="numpy")
def _combine(x, s, a, b, c, d):
    """x + s (a + 2 (b + c) + d), componentwise on 3-tuples."""
    return (
        x[0] + s * (a[0] + 2.0 * (b[0] + c[0]) + d[0]),
        x[1] + s * (a[1] + 2.0 * (b[1] + c[1]) + d[1]),
        x[2] + s * (a[2] + 2.0 * (b[2] + c[2]) + d[2]),
    )


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One RK4 step of dt seconds on (σ, ω) from time t (s), then Basilisk's shadow-set switch."""
    sigma = mrp_from_quat(q)
    h = 0.5 * dt
    k1 = _rates(w, sigma, t, body)
    w2, s2 = _stage(w, sigma, h, k1)
    k2 = _rates(w2, s2, t + h, body)
    w3, s3 = _stage(w, sigma, h, k2)
    k3 = _rates(w3, s3, t + h, body)
    w4, s4 = _stage(w, sigma, dt, k3)
    k4 = _rates(w4, s4, t + dt, body)
    s = dt / 6.0
    w_next = _combine(w, s, k1[0], k2[0], k3[0], k4[0])
    sigma = _combine(sigma, s, k1[1], k2[1], k3[1], k4[1])
    n2 = sigma[0] * sigma[0] + sigma[1] * sigma[1] + sigma[2] * sigma[2]
    if n2 > 1.0:  # hubEffector::modifyStates: |σ| > 1 → the shadow set −σ/|σ|²
        inv = -1.0 / n2
        sigma = (sigma[0] * inv, sigma[1] * inv, sigma[2] * inv)
    return w_next, quat_from_mrp(sigma)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
