"""lie_genalpha: Kynema's Lie-group generalized-α (Brüls–Cardona–Arnold), ρ∞ = 0.9, the body one node at its pivot.

The Lie-group generalized-α method of Brüls, Cardona & Arnold, "Lie group generalized-α time
integration of constrained flexible multibody systems", Mech. Mach. Theory 48 (2012) 121–137, as
Kynema (formerly Exawind/OpenTurbine) ships it: repository kynema/kynema at commit d3b403dc
(2026-05-04), src/step/step_parameters.hpp (the coefficients from ρ∞), src/state/
calculate_next_state.hpp (predictor), src/state/calculate_displacement.hpp (q = exp(h Δ) ⊗ q_n,
the increment on the LEFT), src/system/masses/*.hpp (residual, gyroscopic and inertia-stiffness
matrices), src/system/calculate_tangent_operator.hpp (its transpose since commit ebd716ad),
src/step/step.hpp and calculate_convergence_error.hpp (Newton loop and test).  tests/
kynema_genalpha.py transcribes the same files in numpy for Kynema's own 6-DOF heavy top.

The body is Kynema's rigid body modelled as one node at the pivot carrying the mass element with
the centre of mass offset (inertia about the pivot, gravity's moment about it), its translation
held: the translational unknowns then stay zero, and what remains is the rotational block below,
everything in the lab (inertial) frame as Kynema has it.  Kynema's own heavy-top test puts the
node at the centre of mass and pins it by a rigid joint to a ground node; that is the same
continuous problem but a different discretisation (the translational accelerations enter the
generalized-α recursion), and on that top the difference is large: at h = 2e-3 s the centre of
mass at 0.8 s is off DOP853 by 0.33 m with the node at the pivot (0.084 m at 1e-3 s, second
order) and by 4.6e-3 m with the node at the centre of mass, so this method is 0.34 m from Kynema's
published heavy-top state.  That model needs the mass apart from M g c, which the body record does
not carry: the parameter ``mass`` gives it (below), and ``lie_genalpha(mass=15)`` on gyrolab's
pinned experiment gives Kynema's published state at 0.8 s to 2.4e-12 m (centre of mass) and
1.1e-11 (quaternion), rounding: with Newton's test at 1e-8 (``atol``, ``rtol``, below) 4.4e-14 m and
6.8e-13.  On a free body it is Kynema's step itself: Kynema's precession test to
5.2e-13, and the numpy model of the pivot node to 1.7e-12 on the heavy top
(tests/test_lie_genalpha.py).

Per step of h from (Ω, q) with carried lab accelerations (Ω̇, a) (a the algorithmic one):
  coefficients  α_m = (2ρ∞ − 1)/(ρ∞ + 1), α_f = ρ∞/(ρ∞ + 1), γ = ½ + α_f − α_m, β = (γ + ½)²/4,
                γ' = γ/(h β), β' = (1 − α_m)/(h² β (1 − α_f));
  predictor     Ω̇₁ = 0, a₁ = (α_f Ω̇ − α_m a)/(1 − α_m), Ω₁ = Ω + h((1 − γ) a + γ a₁),
                Δ = Ω + h((½ − β) a + β a₁), q₁ = exp(h Δ) ⊗ q;
  Newton        r = ρ Ω̇₁ + Ω₁ × ρ Ω₁ − τ (ρ = R J Rᵀ, τ gravity's moment, lab), the iteration matrix
                S = β' ρ + γ' (Ω̃₁ρ − (ρΩ₁)~) + K Tᵀ with K = ρ Ω̇̃₁ − (ρΩ̇₁)~ + Ω̃₁(ρΩ̃₁ − (ρΩ₁)~)
                (no gravity stiffness, as Kynema) and T the tangent operator of h Δ; x = −S⁻¹ r
                (rows scaled by β h² first, as Kynema conditions them); Δ += x/h, Ω₁ += γ' x,
                Ω̇₁ += β' x, q₁ = exp(h Δ) ⊗ q;
  corrector     a₁ += (1 − α_f)/(1 − α_m) Ω̇₁.
**Tolerance and iteration cap** (Kynema's defaults in its heavy-top test): stop after the iteration
whose increment has RMS(x_i / (atol + rtol |h Δ_i|)) ≤ 1, atol = 1e-5, rtol = 1e-3, the mean taken
over a Kynema node's six unknowns (its three translational ones zero here), at most 10 iterations;
a step that has not converged returns NaN, so the run ends with the non-finite status.  The
absolute atol makes a floor: at h ≲ 1e-6 s on the 50 Hz top the first iteration already passes
the test short of the generalized-α solution, and the error grows again as h falls (1.7e-7 at
1.2e-6 s, 5.0e-5 at 1.5e-7 s: tests/test_engines.py, ORDER_SMALLEST_DT).  q is never
renormalised (Kynema does not); exp is Kynema's (the vector part zeroed below 1e-12 rad).

The run starts from consistent accelerations, Ω̇ = a = R I⁻¹(τ − ω × Iω), as Kynema's heavy top
does (its precession test starts from zero ones: ``step_carried_with`` takes any).  Second order; with
ρ∞ < 1 it damps the highest frequencies (numerical dissipation), so it keeps no invariant exactly
and is not symplectic.  ``step``, the contract's one-step function, is a run's first step (from the
consistent start); a run threads the accelerations from step to step through ``step_carried``
(driver.make_advance_carried, registry.stepper).

Parameters (kernels/parameters.py): ``rho_inf`` (default 0.9, Kynema's heavy top):
``lie_genalpha(rho_inf=1)`` has no numerical damping, ``lie_genalpha(rho_inf=0)`` the most.
``mass`` (kg, default 0: the node at the pivot, as above) and ``g`` (m/s², default 9.81): with a mass,
the body as Kynema's heavy-top test models it, the node at the centre of mass c = M g c / (mass g)
with the inertia about it, J = I − mass (|c|² 1 − c cᵀ), pinned to the pivot (the origin) by a rigid
joint and a massless ground node (``step_com_with``; the scene's M and g, or the continuous top is
the same but J may not be an inertia).  The joint's multipliers are eliminated exactly, so a Newton
iteration is one 3×3 solve; Kynema's convergence measure runs over its 15 unknowns; the carried
state adds the centre of mass's position, velocity and accelerations.
"""

import math

from numba import njit

from ..parameters import count, nonnegative, unit_interval
from ..rigid_body import euler_rhs, gravity_torque
from ..rotation import body_to_lab, quat_mul
from ..variants import carried_counted

ORDER = 2
SYMPLECTIC = False
PRESERVES = ()
REPRODUCES = "Kynema d3b403dc Lie-group generalized-α (rho_inf 0.9, atol 1e-5, rtol 1e-3, 10 iterations)"
BLOCKS = False  # a Newton loop per step: nothing for the lanes to vectorise

RHO_INF = 0.9  # spectral radius at infinity, Kynema's heavy top (1 is no numerical damping)
ATOL = 1e-5  # Newton test: absolute tolerance on each component of the increment h Δ (rad), Kynema's
RTOL = 1e-3  # Newton test: tolerance relative to |h Δ_i|, Kynema's heavy top
MAX_ITERATIONS = 10  # Newton iterations before a step is declared not converged (status 3), Kynema's
NODE_UNKNOWNS = 6.0  # the mean of the convergence test is over a Kynema node's six unknowns
PARAMETERS = {
    "rho_inf": unit_interval(repr(RHO_INF), "spectral radius at infinity: 1 no numerical damping, 0 the most"),
    "mass": nonnegative(
        "0.0", "kg; > 0: the node at the centre of mass of this mass, pinned at the pivot (Kynema's heavy top)"
    ),
    "g": nonnegative("9.81", "m/s², with mass > 0: the centre of mass is M g c / (mass g)"),
    "atol": nonnegative(repr(ATOL), "Newton test: absolute tolerance on the increment h Δ (rad, m)"),
    "rtol": nonnegative(repr(RTOL), "Newton test: tolerance relative to |h Δ_i|"),
    "iterations": count(
        str(MAX_ITERATIONS), "Newton iterations before a step fails (the run ends: status unconverged)"
    ),
}


@njit(cache=True, error_model="numpy")
def _rot(q):
    """R(q) row by row as a 9-tuple (Kynema's quadratic form, not renormalised)."""
    a, b, c, d = q
    return (
        a * a + b * b - c * c - d * d,
        2.0 * (b * c - a * d),
        2.0 * (b * d + a * c),
        2.0 * (b * c + a * d),
        a * a + c * c - b * b - d * d,
        2.0 * (c * d - a * b),
        2.0 * (b * d - a * c),
        2.0 * (c * d + a * b),
        a * a + d * d - b * b - c * c,
    )


@njit(cache=True, error_model="numpy")
def _mv(m, v):
    return (
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    )


@njit(cache=True, error_model="numpy")
def _transposed(m):
    """mᵀ of a 3×3 m (9-tuple, row-major)."""
    return (m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8])


@njit(cache=True, error_model="numpy")
def _mm(a, b):
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@njit(cache=True, error_model="numpy")
def _tilde(v):
    """The skew matrix of v: tilde(v) u = v × u."""
    return (0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0)


@njit(cache=True, error_model="numpy")
def _solve(m, b):
    """m⁻¹ b for a 3×3 m (9-tuple, row-major) by its adjugate (Cramer)."""
    c00 = m[4] * m[8] - m[5] * m[7]
    c01 = m[5] * m[6] - m[3] * m[8]
    c02 = m[3] * m[7] - m[4] * m[6]
    det = m[0] * c00 + m[1] * c01 + m[2] * c02
    inv = 1.0 / det
    return (
        (c00 * b[0] + (m[2] * m[7] - m[1] * m[8]) * b[1] + (m[1] * m[5] - m[2] * m[4]) * b[2]) * inv,
        (c01 * b[0] + (m[0] * m[8] - m[2] * m[6]) * b[1] + (m[2] * m[3] - m[0] * m[5]) * b[2]) * inv,
        (c02 * b[0] + (m[1] * m[6] - m[0] * m[7]) * b[1] + (m[0] * m[4] - m[1] * m[3]) * b[2]) * inv,
    )


@njit(cache=True, error_model="numpy")
def _exp(r):
    """Kynema's RotationVectorToQuaternion: the unit quaternion of the rotation vector r (rad)."""
    angle = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    factor = 0.0 if abs(angle) < 1.0e-12 else math.sin(angle / 2.0) / angle
    return math.cos(angle / 2.0), r[0] * factor, r[1] * factor, r[2] * factor


@njit(cache=True, error_model="numpy")
def _tangent_transposed(r):
    """Tᵀ of Kynema's CalculateTangentOperator for the rotation vector r = h Δ (rad):
    T = 1 + (cos φ − 1)/φ² r̃ + (1 − sin φ/φ)/φ² r̃², φ = |r| (formed, then transposed, as Kynema)."""
    phi = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    t1 = (math.cos(phi) - 1.0) / (phi * phi) if phi > 1.0e-16 else 0.0
    t2 = (1.0 - math.sin(phi) / phi) / (phi * phi) if phi > 1.0e-16 else 0.0
    rt = _tilde(r)
    rt2 = _mm(rt, rt)
    t = (
        1.0 + t1 * rt[0] + t2 * rt2[0],
        t1 * rt[1] + t2 * rt2[1],
        t1 * rt[2] + t2 * rt2[2],
        t1 * rt[3] + t2 * rt2[3],
        1.0 + t1 * rt[4] + t2 * rt2[4],
        t1 * rt[5] + t2 * rt2[5],
        t1 * rt[6] + t2 * rt2[6],
        t1 * rt[7] + t2 * rt2[7],
        1.0 + t1 * rt[8] + t2 * rt2[8],
    )
    return _transposed(t)


@njit(cache=True, error_model="numpy", forceinline=True)
def _rotational(rho, v, vd, t_r, beta_p, gamma_p):
    """The rotational block of Kynema's mass element with the centre of mass at the node's rotation centre
    (no offset term): the inertial moment ρ Ω̇ + (Ω̃ ρ) Ω (N m, lab) and the unscaled iteration matrix
    β' ρ + γ' (Ω̃ ρ − (ρΩ)~) + K t_r with K = ρ Ω̇̃ − (ρΩ̇)~ + Ω̃ (ρ Ω̃ − (ρΩ)~) (9-tuple, row-major)."""
    rho_v = _mv(rho, v)
    rho_vd = _mv(rho, vd)
    wt = _tilde(v)
    g_mat = _mm(wt, rho)
    gyro = _mv(g_mat, v)  # Ω × ρΩ as Kynema forms it, (Ω̃ ρ) Ω
    inertial = (rho_vd[0] + gyro[0], rho_vd[1] + gyro[1], rho_vd[2] + gyro[2])
    rvt = _tilde(rho_v)
    k_mat = _mm(rho, _tilde(vd))
    rvdt = _tilde(rho_vd)
    inner = _mm(rho, wt)
    k2 = _mm(wt, (inner[0] - rvt[0], inner[1] - rvt[1], inner[2] - rvt[2], inner[3] - rvt[3],
                  inner[4] - rvt[4], inner[5] - rvt[5], inner[6] - rvt[6], inner[7] - rvt[7],
                  inner[8] - rvt[8]))  # fmt: skip
    kt = _mm(
        (
            k_mat[0] - rvdt[0] + k2[0],
            k_mat[1] - rvdt[1] + k2[1],
            k_mat[2] - rvdt[2] + k2[2],
            k_mat[3] - rvdt[3] + k2[3],
            k_mat[4] - rvdt[4] + k2[4],
            k_mat[5] - rvdt[5] + k2[5],
            k_mat[6] - rvdt[6] + k2[6],
            k_mat[7] - rvdt[7] + k2[7],
            k_mat[8] - rvdt[8] + k2[8],
        ),
        t_r,
    )
    m_rot = (
        beta_p * rho[0] + gamma_p * (g_mat[0] - rvt[0]) + kt[0],
        beta_p * rho[1] + gamma_p * (g_mat[1] - rvt[1]) + kt[1],
        beta_p * rho[2] + gamma_p * (g_mat[2] - rvt[2]) + kt[2],
        beta_p * rho[3] + gamma_p * (g_mat[3] - rvt[3]) + kt[3],
        beta_p * rho[4] + gamma_p * (g_mat[4] - rvt[4]) + kt[4],
        beta_p * rho[5] + gamma_p * (g_mat[5] - rvt[5]) + kt[5],
        beta_p * rho[6] + gamma_p * (g_mat[6] - rvt[6]) + kt[6],
        beta_p * rho[7] + gamma_p * (g_mat[7] - rvt[7]) + kt[7],
        beta_p * rho[8] + gamma_p * (g_mat[8] - rvt[8]) + kt[8],
    )
    return inertial, m_rot


@njit(cache=True, error_model="numpy")
def start(w, q, body):
    """The carried state of a run's start: the consistent lab accelerations (Ω̇, a) with a = Ω̇ =
    R I⁻¹(τ − ω × Iω) (rad/s²; the lab derivative of Ω = R ω is R ω̇)."""
    wd = euler_rhs(w, gravity_torque(q, body), body)
    vd = body_to_lab(q, wd[0], wd[1], wd[2])
    return vd[0], vd[1], vd[2], vd[0], vd[1], vd[2]


@njit(cache=True, error_model="numpy", forceinline=True)
def _coefficients(dt, rho_inf):
    """StepParameters: (α_m, α_f, γ, β, γ', β', β h²) of a step of dt seconds at spectral radius ρ∞."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) * (gamma + 0.5)
    return am, af, gamma, beta, gamma / (dt * beta), (1.0 - am) / (dt * dt * beta * (1.0 - af)), beta * dt * dt


@njit(cache=True, error_model="numpy", forceinline=True)
def _predict(v_n, vd_n, a_n, dt, am, af, gamma, beta):
    """CalculateNextState on three components: (a₁, v₁, Δ) from (v, v̇, a) at the step's start (the
    physical acceleration v̇₁ restarts at zero)."""
    a1 = (
        (af * vd_n[0] - am * a_n[0]) / (1.0 - am),
        (af * vd_n[1] - am * a_n[1]) / (1.0 - am),
        (af * vd_n[2] - am * a_n[2]) / (1.0 - am),
    )
    v = (
        v_n[0] + dt * (1.0 - gamma) * a_n[0] + gamma * dt * a1[0],
        v_n[1] + dt * (1.0 - gamma) * a_n[1] + gamma * dt * a1[1],
        v_n[2] + dt * (1.0 - gamma) * a_n[2] + gamma * dt * a1[2],
    )
    dl = (
        v_n[0] + (0.5 - beta) * dt * a_n[0] + beta * dt * a1[0],
        v_n[1] + (0.5 - beta) * dt * a_n[1] + beta * dt * a1[1],
        v_n[2] + (0.5 - beta) * dt * a_n[2] + beta * dt * a1[2],
    )
    return a1, v, dl


@njit(cache=True, error_model="numpy", forceinline=True)
def _error_squares(x, dl, dt, atol, rtol):
    """Σ (x_i / (atol + rtol |h Δ_i|))² over three unknowns: Kynema's convergence measure, taken before
    the update, against the increment h Δ."""
    e0 = x[0] / (atol + rtol * abs(dl[0] * dt))
    e1 = x[1] / (atol + rtol * abs(dl[1] * dt))
    e2 = x[2] / (atol + rtol * abs(dl[2] * dt))
    return e0 * e0 + e1 * e1 + e2 * e2


@njit(cache=True, error_model="numpy", forceinline=True)
def _update(dl, v, vd, x, dt, gamma_p, beta_p):
    """UpdateDynamicPrediction on three components: Δ += x/h, v += γ' x, v̇ += β' x."""
    return (
        (dl[0] + x[0] / dt, dl[1] + x[1] / dt, dl[2] + x[2] / dt),
        (v[0] + gamma_p * x[0], v[1] + gamma_p * x[1], v[2] + gamma_p * x[2]),
        (vd[0] + beta_p * x[0], vd[1] + beta_p * x[1], vd[2] + beta_p * x[2]),
    )


@njit(cache=True, error_model="numpy", forceinline=True)
def _body_rates(q, v):
    """ω = Rᵀ Ω (rad/s, body) with Kynema's R(q)."""
    rm = _rot(q)
    return (
        rm[0] * v[0] + rm[3] * v[1] + rm[6] * v[2],
        rm[1] * v[0] + rm[4] * v[1] + rm[7] * v[2],
        rm[2] * v[0] + rm[5] * v[1] + rm[8] * v[2],
    )


@njit(cache=True, error_model="numpy", forceinline=True)
def step_carried_with(w, q, c, dt, body, rho_inf, atol, rtol, iterations):
    """One generalized-α step of dt seconds with spectral radius ``rho_inf``: body rates w (rad/s),
    q (body → lab) and the carried lab accelerations c = (Ω̇, a) (rad/s²) to the new (w, q, c); Newton
    stops at RMS(x_i / (atol + rtol |h Δ_i|)) ≤ 1 or fails after ``iterations``."""
    am, af, gamma, beta, gamma_p, beta_p, cond = _coefficients(dt, rho_inf)
    jj = (body[0], body[1], body[2])
    a1, v, dl = _predict(
        body_to_lab(q, w[0], w[1], w[2]), (c[0], c[1], c[2]), (c[3], c[4], c[5]), dt, am, af, gamma, beta
    )
    vd = (0.0, 0.0, 0.0)
    q1 = quat_mul(_exp((dt * dl[0], dt * dl[1], dt * dl[2])), q)

    converged, n = False, 0
    for n in range(1, iterations + 1):  # noqa: B007 - n, the iterations taken, is returned
        rm = _rot(q1)
        # rho = R J R^T
        rho = (
            rm[0] * jj[0] * rm[0] + rm[1] * jj[1] * rm[1] + rm[2] * jj[2] * rm[2],
            rm[0] * jj[0] * rm[3] + rm[1] * jj[1] * rm[4] + rm[2] * jj[2] * rm[5],
            rm[0] * jj[0] * rm[6] + rm[1] * jj[1] * rm[7] + rm[2] * jj[2] * rm[8],
            rm[3] * jj[0] * rm[0] + rm[4] * jj[1] * rm[1] + rm[5] * jj[2] * rm[2],
            rm[3] * jj[0] * rm[3] + rm[4] * jj[1] * rm[4] + rm[5] * jj[2] * rm[5],
            rm[3] * jj[0] * rm[6] + rm[4] * jj[1] * rm[7] + rm[5] * jj[2] * rm[8],
            rm[6] * jj[0] * rm[0] + rm[7] * jj[1] * rm[1] + rm[8] * jj[2] * rm[2],
            rm[6] * jj[0] * rm[3] + rm[7] * jj[1] * rm[4] + rm[8] * jj[2] * rm[5],
            rm[6] * jj[0] * rm[6] + rm[7] * jj[1] * rm[7] + rm[8] * jj[2] * rm[8],
        )
        tb = gravity_torque(q1, body)
        tau = _mv(rm, tb)
        inertial, m_rot = _rotational(
            rho, v, vd, _tangent_transposed((dt * dl[0], dt * dl[1], dt * dl[2])), beta_p, gamma_p
        )
        res = (inertial[0] - tau[0], inertial[1] - tau[1], inertial[2] - tau[2])
        s_mat = (
            cond * m_rot[0], cond * m_rot[1], cond * m_rot[2],
            cond * m_rot[3], cond * m_rot[4], cond * m_rot[5],
            cond * m_rot[6], cond * m_rot[7], cond * m_rot[8],
        )  # fmt: skip
        x = _solve(s_mat, (-cond * res[0], -cond * res[1], -cond * res[2]))
        err = math.sqrt(_error_squares(x, dl, dt, atol, rtol) / NODE_UNKNOWNS)
        dl, v, vd = _update(dl, v, vd, x, dt, gamma_p, beta_p)
        q1 = quat_mul(_exp((dt * dl[0], dt * dl[1], dt * dl[2])), q)
        if err <= 1.0:
            converged = True
            break

    if not converged:  # also a NaN err: the step is no solution, and the run says so
        nan = math.nan
        return (nan, nan, nan), (nan, nan, nan, nan), (nan, nan, nan, nan, nan, nan), -max(n, 1)
    f = (1.0 - af) / (1.0 - am)
    a1 = (a1[0] + f * vd[0], a1[1] + f * vd[1], a1[2] + f * vd[2])
    return _body_rates(q1, v), q1, (vd[0], vd[1], vd[2], a1[0], a1[1], a1[2]), n


# ---------------------------------------------------------------- the node at the centre of mass
# Kynema's own heavy top (tests/regression_tests/regression/test_heavy_top.cpp): the mass element on a
# node at the centre of mass (6 unknowns), a massless ground node at the pivot held by a prescribed
# BC, and a rigid joint between them.  The ground node's unknowns are zero and its multipliers the
# joint's negated (its rows say λ_joint + λ_BC = 0, from zero every step), so the 15 unknowns of
# Kynema's system reduce exactly to the node's 6 and the joint's 3 multipliers, solved here by
# eliminating the translation (its block is β' m 1) and the multipliers: a 3×3 solve a Newton
# iteration.  Kynema's convergence measure still runs over all 15 (the BC multipliers count as the
# joint's again, the ground node's zero increments add nothing).  Carried state, lab frame:
# (x, ẋ, ẍ, Ω̇, a_x, a_Ω): the centre of mass (m), its velocity and acceleration, the angular
# acceleration and the six algorithmic accelerations.
SYSTEM_UNKNOWNS = 15.0  # Kynema's heavy top: node (6) + ground node (3) + joint (3) + BC (3) rows


@njit(cache=True, error_model="numpy")
def _centre_of_mass(body, mass, g):
    """(c, J): the centre of mass c = M g c / (m g) (m, body) and the inertia about it,
    J = I_pivot − m (|c|² 1 − c cᵀ) (kg m², body, 9-tuple), for a body of ``mass`` kg under ``g`` m/s²."""
    s = 1.0 / (mass * g)
    c = (body[4] * s, body[5] * s, body[3] * s)
    cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2]
    return c, (
        body[0] - mass * (cc - c[0] * c[0]), mass * c[0] * c[1], mass * c[0] * c[2],
        mass * c[1] * c[0], body[1] - mass * (cc - c[1] * c[1]), mass * c[1] * c[2],
        mass * c[2] * c[0], mass * c[2] * c[1], body[2] - mass * (cc - c[2] * c[2]),
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def start_com(w, q, body, mass, g):
    """The carried state of a run's start with the node at the centre of mass: x = R c, ẋ = Ω × x,
    ẍ = Ω̇ × x + Ω × (Ω × x), Ω̇ = R I⁻¹(τ − ω × Iω) (the pivot's consistent accelerations), a = the
    accelerations (Kynema's CopyNodesToState)."""
    c, _ = _centre_of_mass(body, mass, g)
    x = body_to_lab(q, c[0], c[1], c[2])
    om = body_to_lab(q, w[0], w[1], w[2])
    wd = euler_rhs(w, gravity_torque(q, body), body)
    od = body_to_lab(q, wd[0], wd[1], wd[2])
    xv = _cross(om, x)
    xa = _cross(od, x)
    xc = _cross(om, xv)
    xd = (xa[0] + xc[0], xa[1] + xc[1], xa[2] + xc[2])
    return x + xv + xd + od + xd + od


@njit(cache=True, error_model="numpy")
def _cross(a, b):
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy", forceinline=True)
def step_com_with(w, q, c, dt, body, rho_inf, mass, g, atol, rtol, iterations):
    """One generalized-α step of dt seconds of the body as Kynema models its heavy top: the node at the
    centre of mass (``mass`` kg, ``g`` m/s² along −z), pinned to the pivot at the origin by a rigid
    joint; c = (x, ẋ, ẍ, Ω̇, a_x, a_Ω) (lab) to the new (w, q, c)."""
    am, af, gamma, beta, gamma_p, beta_p, cond = _coefficients(dt, rho_inf)
    cb, jc = _centre_of_mass(body, mass, g)
    x_n = (c[0], c[1], c[2])
    at1, vt, dlt = _predict((c[3], c[4], c[5]), (c[6], c[7], c[8]), (c[12], c[13], c[14]), dt, am, af, gamma, beta)
    ar1, v, dl = _predict(
        body_to_lab(q, w[0], w[1], w[2]), (c[9], c[10], c[11]), (c[15], c[16], c[17]), dt, am, af, gamma, beta
    )
    vdt = (0.0, 0.0, 0.0)
    vd = (0.0, 0.0, 0.0)
    x1 = (x_n[0] + dt * dlt[0], x_n[1] + dt * dlt[1], x_n[2] + dt * dlt[2])
    q1 = quat_mul(_exp((dt * dl[0], dt * dl[1], dt * dl[2])), q)
    lam = (0.0, 0.0, 0.0)  # the joint's multipliers (N), from zero every step (ResetConstraints)
    a_t = cond * beta_p * mass  # the translational block of the scaled iteration matrix, times 1

    converged, n = False, 0
    for n in range(1, iterations + 1):  # noqa: B007 - n, the iterations taken, is returned
        rm = _rot(q1)
        rho = _mm(_mm(rm, jc), _transposed(rm))
        t_r = _tangent_transposed((dt * dl[0], dt * dl[1], dt * dl[2]))
        inertial, m_rot = _rotational(rho, v, vd, t_r, beta_p, gamma_p)
        rc = _mv(rm, cb)  # R c: the centre of mass from the pivot
        phi = (rc[0] - x1[0], rc[1] - x1[1], rc[2] - x1[2])  # the joint's residual (pivot held at 0)
        sm = _tilde((-rc[0], -rc[1], -rc[2]))  # the joint's gradient on the node: [−1, (R X0)~], X0 = −R c
        smt = _transposed(sm)
        sl = _mv(smt, lam)  # Sᵀ λ
        # scaled residual rows: translation m ẍ − m g_vec + (−λ), rotation inertial + Sᵀ λ
        r_t = (
            cond * (mass * vdt[0] - lam[0]),
            cond * (mass * vdt[1] - lam[1]),
            cond * (mass * vdt[2] + mass * g - lam[2]),
        )
        r_r = (cond * (inertial[0] + sl[0]), cond * (inertial[1] + sl[1]), cond * (inertial[2] + sl[2]))
        # eliminate: x_t = (y − r_t)/a_t, y = r_t + a_t (S T x_r + Φ), (K_r + a_t Sᵀ S T) x_r = −r_r − Sᵀ(r_t + a_t Φ)
        st = _mm(sm, t_r)
        sts = _mm(smt, st)
        k = (
            cond * m_rot[0] + a_t * sts[0], cond * m_rot[1] + a_t * sts[1], cond * m_rot[2] + a_t * sts[2],
            cond * m_rot[3] + a_t * sts[3], cond * m_rot[4] + a_t * sts[4], cond * m_rot[5] + a_t * sts[5],
            cond * m_rot[6] + a_t * sts[6], cond * m_rot[7] + a_t * sts[7], cond * m_rot[8] + a_t * sts[8],
        )  # fmt: skip
        rhs_t = (r_t[0] + a_t * phi[0], r_t[1] + a_t * phi[1], r_t[2] + a_t * phi[2])
        sr = _mv(smt, rhs_t)
        xr = _solve(k, (-r_r[0] - sr[0], -r_r[1] - sr[1], -r_r[2] - sr[2]))
        stx = _mv(st, xr)
        y = (rhs_t[0] + a_t * stx[0], rhs_t[1] + a_t * stx[1], rhs_t[2] + a_t * stx[2])
        xt = ((y[0] - r_t[0]) / a_t, (y[1] - r_t[1]) / a_t, (y[2] - r_t[2]) / a_t)
        dlam = (y[0] / cond, y[1] / cond, y[2] / cond)

        e_l0 = dlam[0] / (atol + rtol * abs(lam[0]))
        e_l1 = dlam[1] / (atol + rtol * abs(lam[1]))
        e_l2 = dlam[2] / (atol + rtol * abs(lam[2]))
        ssq = _error_squares(xt, dlt, dt, atol, rtol) + _error_squares(xr, dl, dt, atol, rtol)
        ssq += 2.0 * (e_l0 * e_l0 + e_l1 * e_l1 + e_l2 * e_l2)
        err = math.sqrt(ssq / SYSTEM_UNKNOWNS)

        dlt, vt, vdt = _update(dlt, vt, vdt, xt, dt, gamma_p, beta_p)
        dl, v, vd = _update(dl, v, vd, xr, dt, gamma_p, beta_p)
        x1 = (x_n[0] + dt * dlt[0], x_n[1] + dt * dlt[1], x_n[2] + dt * dlt[2])
        q1 = quat_mul(_exp((dt * dl[0], dt * dl[1], dt * dl[2])), q)
        lam = (lam[0] + dlam[0], lam[1] + dlam[1], lam[2] + dlam[2])
        if err <= 1.0:
            converged = True
            break

    if not converged:  # also a NaN err: the step is no solution, and the run says so
        n3 = (math.nan, math.nan, math.nan)
        return n3, (math.nan,) + n3, n3 + n3 + n3 + n3 + n3 + n3, -max(n, 1)
    f = (1.0 - af) / (1.0 - am)
    at1 = (at1[0] + f * vdt[0], at1[1] + f * vdt[1], at1[2] + f * vdt[2])
    ar1 = (ar1[0] + f * vd[0], ar1[1] + f * vd[1], ar1[2] + f * vd[2])
    return _body_rates(q1, v), q1, x1 + vt + vdt + vd + at1 + ar1, n


@njit(cache=True, error_model="numpy")
def step_carried_counted(w, q, c, dt, body):
    """One step of dt seconds (s) at ρ∞ = RHO_INF, carrying c = (Ω̇, a), the lab accelerations, and
    its Newton iterations (< 0: not converged, the state NaN)."""
    return step_carried_with(w, q, c, dt, body, RHO_INF, ATOL, RTOL, MAX_ITERATIONS)


@njit(cache=True, error_model="numpy")
def step_carried(w, q, c, dt, body):
    """step_carried_counted without its count."""
    w1, q1, c1, _ = step_carried_counted(w, q, c, dt, body)
    return w1, q1, c1


@njit(cache=True, error_model="numpy")
def step_counted(w, q, dt, body):
    """A run's first step of dt seconds from (w, q) at rest in its history (the consistent start),
    and its Newton iterations."""
    w1, q1, _, n = step_carried_counted(w, q, start(w, q, body), dt, body)
    return w1, q1, n


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """A run's first step of dt seconds from (w, q) at rest in its history (the consistent start)."""
    w1, q1, _ = step_carried(w, q, start(w, q, body), dt, body)
    return w1, q1


def variant(rho_inf, mass, g, atol, rtol, iterations):
    """The steps at spectral radius ``rho_inf`` (0 ≤ ρ∞ ≤ 1), one node at the pivot (``mass`` 0) or the
    node at the centre of mass of a body of ``mass`` kg under ``g`` m/s², pinned at the pivot; Newton's
    test ``atol``, ``rtol`` and its cap of ``iterations``."""
    if mass == 0.0:

        @njit(error_model="numpy")
        def step_carried_counted(w, q, c, dt, body):
            return step_carried_with(w, q, c, dt, body, rho_inf, atol, rtol, iterations)

        return carried_counted(start, step_carried_counted)

    @njit(error_model="numpy")
    def start_at_com(w, q, body):
        return start_com(w, q, body, mass, g)

    @njit(error_model="numpy")
    def step_at_com(w, q, c, dt, body):
        return step_com_with(w, q, c, dt, body, rho_inf, mass, g, atol, rtol, iterations)

    return carried_counted(start_at_com, step_at_com)
