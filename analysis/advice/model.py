"""The advisor's error model: a method's error on a free body, from its declared order, a one-step
probe on the body's own orbit and one constant per (method, metric) measured once (calibrate.py,
error_constants.json).

Dimensionless groups (Ω = |ω0|, the body's spin rate): h = Ω dt, the angle turned per step, and
τ = Ω T, the angle turned over the horizon.  A p-th order method's local error is ∝ h^(p+1), so
after N = T/dt steps its secular (phase) part is ∝ N h^(p+1) = h^p τ.  How large the constant is
depends on the body's shape and on where on its orbit it is (a spin about a principal axis has
nothing to get wrong but its kinematics, and a splitting method is then exact; near the separatrix
a small error of the period moves the body far).  No single constant per method covers that (nor
one fitted with shape groups such as ``shape``'s: tried while building this, it missed the
calibration bodies' errors by more than 2× about half the time), so the shape enters through the
method itself:

``probe`` takes one step of the method at h = H_PROBE from N_PROBE = 128 points of the body's orbit
(uniform in time from ω0, the Euler–Poinsot closed form) and compares it with the exact flow.  The
state after k steps is the exact one at k + σ steps turned about L by α (the free flow commutes with
turns about L), so the attitude error is |α m̂ + σ ω| (body frame): the per-step defects are the
time shift s along the orbit and the turn a about L beyond the shift's own.  Each accumulates from
the start, its orbit mean k times (secular) plus the running sum of its periodic part (which comes
and goes: a symplectic method's bounded energy error), both together, at the horizon's last orbit.
A change of the orbit's invariants G² and δ changes the period and the turn about L per period: a
drift of them (a non-symplectic method's energy) makes σ and α grow as k², and their periodic
wander from the start's values (zero at the start, not on average) as k, through how much faster a
body moved to the nearby orbit runs, and turns about L, at each point of it (near the separatrix
that sensitivity sits at the slow passage by the intermediate axis; weighting the wander by its orbit
mean missed the orientation error there by 10x-1e4x, mostly over).  The energy and |L|
errors are the accumulated per-step changes.  Each metric's exponent q in h is measured between
probes at H_PROBE and H_LOW (rk4's secular energy error goes as h^5 at a given τ, not h^4); then
error(h) = κ g (h / H_PROBE)^q, κ the calibrated constant of the (method, metric), plus a rounding
floor: the exact-flow method's measured error per step times T/dt.  With the structure right, κ is
0.98–1.00 for every default method and metric (it was 0.39–0.96 when secular and periodic parts were
summed as separate bounds and the turn's k² growth was missing; the local wander moved none of them
by more than 1 %, so the stored constants stand).  What the model reaches: on the calibration bodies
(120, seed 1, 4 (h, τ) each) 100 / 93 / 97 % of the orientation errors within 2× for rk4 /
lie_poisson / lie_poisson4 and 98–100 % of the energy errors; on held-out bodies (tests/test_advise.py,
seed 2025) 96 % (orientation) and 99 % (energy); on the three users' bodies of issue 25
measured/predicted 0.97–0.99 (README); near the separatrix within 2× down to 1e-4 of it (relative) and
off closer in (advisor.NEAR_SEPARATRIX).  The misses left (5 of 119 held-out runs, 2–3.7× either way)
are why the advisor measures after predicting.

``shape`` gives two descriptive groups the advisor reports: ε = |ω × Iω| / (|ω| |Iω|), the sine of
the angle between ω and L, and ρ = Ω P / 2π, spin turns per period P of ω(t) in the body.
"""

import json
import math
from importlib import resources

import numpy as np

from .predict import _delta, amplitudes, orbit_points, orbit_state, phase_rates, separatrix_delta

CONSTANTS_FILE = "error_constants.json"
EPS_FLOOR = 1e-9  # ε below this is a spin about a principal axis to rounding
RHO_RANGE = (1e-3, 1e6)
SATURATED = 0.1  # errors above this are outside the asymptotic regime (the model is for small errors)
ROUNDING = 1e-16  # per step: the rounding floor when the constants do not give one


def shape(I, omega0):
    """(ε, ρ) of bodies I (B, 3) kg m² from body rates ω0 (B, 3) rad/s (see the module docstring)."""
    I = np.atleast_2d(np.asarray(I, float))
    w = np.atleast_2d(np.asarray(omega0, float))
    m = I * w
    wn = np.linalg.norm(w, axis=1)
    eps = np.linalg.norm(np.cross(w, m), axis=1) / (wn * np.linalg.norm(m, axis=1))
    Is, _, G2, delta, pole, sign = orbit_state(I, w)
    _, period = orbit_points(Is, G2, delta, pole, sign, n=1)
    rho = wn * period / (2 * math.pi)
    return np.maximum(eps, EPS_FLOOR), np.clip(np.nan_to_num(rho, nan=RHO_RANGE[1], posinf=RHO_RANGE[1]), *RHO_RANGE)


def load_constants():
    """The stored constants: {"methods": {name: {"order", "ns_per_step", "kappa": {metric: κ}, ...}}, "how": ...}."""
    text = resources.files(__package__).joinpath(CONSTANTS_FILE).read_text()
    return json.loads(text)


def rounding_floor(constants, metric):
    """The exact flow's measured error per step in ``metric`` (calibrate.py, on the FREE_EXACT method),
    ROUNDING if not calibrated."""
    for entry in constants["methods"].values():
        if metric in entry.get("rounding_per_step", {}):
            return float(entry["rounding_per_step"][metric])
    return ROUNDING


def predicted_error(kappa, growth, order, h, tau, rounding=ROUNDING):
    """Predicted error (errors.py's metric) at h = Ω dt over τ = Ω T from the calibrated factor κ and the
    probe's growth at H_PROBE over the same T: κ g (h / H_PROBE)^p (every term of the growth is a
    defect ∝ h^(p+1) times a step count ∝ 1/h), plus the rounding floor ``rounding`` × T/dt (the
    exact flow's error per step, calibrate.py)."""
    h = np.asarray(h, float)
    return kappa * growth * (h / H_PROBE) ** order + rounding * np.asarray(tau, float) / h


def largest_h(kappa, growth, order, tol, tau, rounding=ROUNDING):
    """The largest h = Ω dt whose predicted error is ≤ tol (0 if the rounding floor alone exceeds it):
    the truncation term's root, then bisection in log h when the rounding floor pushes it over."""

    def ok(h):
        return float(predicted_error(kappa, growth, order, h, tau, rounding)) <= tol

    hi = (
        MAX_H_SEARCH
        if not kappa * growth > 0
        else min(H_PROBE * (tol / (kappa * growth)) ** (1.0 / order), MAX_H_SEARCH)
    )
    if ok(hi):
        return hi
    lo = hi
    for _ in range(200):  # down until the floor allows it
        lo *= 0.5
        if ok(lo):
            break
    else:
        return 0.0
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


MAX_H_SEARCH = 10.0
H_PROBE = 0.1  # Ω dt of the probe step (asymptotic for every calibrated method, far above rounding)
# points of the orbit the probe steps from: 32 under-resolve the defects of an orbit near the
# separatrix, peaked over its short flip (lie_poisson's orientation there: 76 % of the calibration
# points within 2x at 32, 85-90 % at 128)
N_PROBE = 128
H_LOW = 0.025  # the second probe step: the growth's exponent in h is measured between the two


def growth_law(method, I, omega0, T, order, n=None):
    """{metric: (g, q)}: ``probe``'s growth g (B,) at H_PROBE and its exponent q (B,) in h, measured
    between the probes at H_PROBE and H_LOW, so that the error at h is κ g (h / H_PROBE)^q.

    The declared order p is the exponent of a defect ∝ h^(p+1) summed over N ∝ 1/h steps, but not
    every metric's: rk4's per-step energy change has a vanishing mean at h^5 (its secular energy error
    goes as h^5 at a given τ, not h^4), and a drift of the orbit's invariants turns into a phase error
    ∝ N², one power of h less.  q is measured, not declared, and kept within [p − 1, p + 1] (a probe
    at rounding gives no exponent: p then)."""
    n = N_PROBE if n is None else n
    hi = probe(method, I, omega0, T, n)
    lo = probe(method, I, omega0, T, n, h=H_LOW)
    out = {}
    for metric, g in hi.items():
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.log(g / lo[metric]) / math.log(H_PROBE / H_LOW)
        q = np.where(np.isfinite(q), np.clip(q, order - 1, order + 1), order)
        out[metric] = (g, q)
    return out


def _rotvec(R):
    """Rotation vectors (..., 3) of rotation matrices R (..., 3, 3) (small angles: the skew part)."""
    from scipy.spatial.transform import Rotation

    shape = R.shape[:-2]
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(shape + (3,))


def probe(method, I, omega0, T, n=None, h=None):
    """Error growth terms of ``method`` on free bodies I (B, 3) from ω0 (B, 3) over T (B,) s, at
    h = H_PROBE, or at ``h`` (dimensionless, per errors.py metric, before the calibrated factor).

    One step of the method from n points of the orbit through ω0 (uniform in time from ω0, forward,
    predict.py's closed form), against the exact flow over the same step: the defects, in units where
    the step is 1 (the free body's equations are homogeneous: ω(t) from ω0 is c ω(ct) from c ω0):
    - time shift s along the orbit (d_ω · ω̇ / |ω̇|²): the body ahead of or behind the exact one,
    - turn a about L (the rotation R_exᵀ R_num's component along Iω/|Iω|, less the shift's turn ω s),
    - energy and |L| changes per step, and those of G² and δ, which move the period and the turn
      about L per period (their elasticities by finite differences of the closed form).
    Each is accumulated from the start (orbit mean × steps + running sum of its periodic part) at
    n + 1 times over the horizon's last orbit (or over T < P), and the largest error over them is
    the growth (module docstring).
    Returns {metric: growth (B,)} at h = H_PROBE (or ``h``)."""
    from ...kernels.batch import integrate
    from ...kernels.body import N_FIELDS as N_BODY
    from ...kernels.euler_poinsot import free_body
    from . import errors as E

    n = N_PROBE if n is None else n
    I = np.atleast_2d(np.asarray(I, float))
    w0 = np.atleast_2d(np.asarray(omega0, float))
    B = I.shape[0]
    Om = np.linalg.norm(w0, axis=1)
    dt = (H_PROBE if h is None else h) / Om
    Is, perm, G2, delta, pole, sign = orbit_state(I, w0)
    # the orbit's points from ω0 forward in time: a periodic part's excursion is from the start
    start = np.take_along_axis(I * w0, perm, 1)
    m, period = orbit_points(
        Is, G2, delta, pole, sign, n, start=start, start_rate=np.take_along_axis(np.cross(I * w0, w0), perm, 1)
    )
    w = _unsort(m / Is[:, None, :], perm)  # (B, n, 3) rad/s, the body's own axes
    wu = (w * dt[:, None, None]).reshape(B * n, 3)  # rates in units of 1/dt: one step of length 1
    Ir = np.repeat(I, n, axis=0)
    bodies = np.zeros((B * n, N_BODY))
    bodies[:, :3] = Ir
    q0 = np.tile(E.Q0, (B * n, 1))
    out, _, _ = integrate(method, bodies, wu, q0, np.ones(B * n), 1, 2, threshold=1e300, path="blocks")
    num = out[:, 1]
    w_ex, q_ex = free_body(Ir, wu, q0, np.array([1.0]))  # every row's step is 1 in these units
    w_ex, q_ex = w_ex[:, 0], q_ex[:, 0]
    R_num = E.attitude_from_samples(num, Ir)
    R_ex = E.rotation_matrices(q_ex)
    r = _rotvec(np.swapaxes(R_ex, -1, -2) @ R_num)  # R_num = R_ex exp([r]): r in the body frame
    m_ex = Ir * w_ex
    m_hat = m_ex / np.linalg.norm(m_ex, axis=1)[:, None]
    f = np.cross(m_ex, w_ex) / Ir  # ω̇ (units 1/dt²)
    d = num[:, 3:6] - w_ex
    ff = np.sum(f * f, axis=1)
    s = np.where(ff > 1e-30 * np.sum(w_ex**2, axis=1) ** 2, np.sum(d * f, axis=1) / np.maximum(ff, 1e-300), 0.0)
    # the attitude drift about L beyond the turn of the time shift (R(t + s) = R(t) exp(ω s)), which
    # the shift s already accounts for below: counting it in a as well counted it twice (by up to 2×
    # when ω is nearly along L)
    a = np.sum((r - s[:, None] * w_ex) * m_hat, axis=1)
    dE = 0.5 * np.sum(Ir * num[:, 3:6] ** 2, axis=1) - 0.5 * np.sum(Ir * w_ex**2, axis=1)
    dL = np.linalg.norm(Ir * num[:, 3:6], axis=1) - np.linalg.norm(m_ex, axis=1)
    # A drift of the orbit's invariants (G² = |L|², δ; a non-symplectic method's energy) changes the
    # period P step by step, so the time shift grows as ½ k² dlnP/step after k steps
    m_num_s = np.take_along_axis(Ir * num[:, 3:6], np.repeat(perm, n, axis=0), 1).reshape(B, n, 3)
    m_ex_s = np.take_along_axis(m_ex, np.repeat(perm, n, axis=0), 1).reshape(B, n, 3)
    dlnG2_k = np.sum(m_num_s**2, axis=2) / np.sum(m_ex_s**2, axis=2) - 1
    dlnG2 = dlnG2_k.mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        dlnd_k = np.nan_to_num(_delta(Is, m_num_s, pole) / _delta(Is, m_ex_s, pole) - 1)
        dlnd = dlnd_k.mean(axis=1)
        # elasticities of the period (closed form, finite differences; dt units cancel in them), each
        # difference taken away from the separatrix (G² up, δ down) by a fraction of the distance to it
        # (so that an orbit near it is not moved across it), but far enough above rounding to be a difference
        eta = np.clip(1e-2 * (separatrix_delta(Is, G2, pole) - delta) / delta, 1e-12, 1e-6)
        _, P_G = orbit_points(Is, G2 * (1 + eta), delta, pole, sign, 1)
        _, P_d = orbit_points(Is, G2, delta * (1 - eta), pole, sign, 1)
        eP_G, eP_d = np.log(P_G / period) / eta, -np.log(P_d / period) / eta
        dlnP = eP_G * dlnG2 + eP_d * dlnd
        # and the turn about L per period Δφ changes too: the turn α grows as ½ k² (dt/P) dΔφ/step
        phi0 = _turn_per_period(Is, G2, delta, pole, sign)
        ephi_G = (_turn_per_period(Is, G2 * (1 + eta), delta, pole, sign) - phi0) / eta * dt / period
        ephi_d = -(_turn_per_period(Is, G2, delta * (1 - eta), pole, sign) - phi0) / eta * dt / period
        dalpha = ephi_G * dlnG2 + ephi_d * dlnd  # per step², rad
        # The invariants' periodic wander (zero at the start, so not zero on average: a symplectic method's
        # bounded energy error) acts where the body is: a body moved to a nearby orbit runs faster or slower
        # there, and turns about L more or less per unit of its amplitude φ, by the local sensitivities (at
        # fixed φ, predict.phase_rates).  Their orbit means are the period's and the turn's elasticities
        # above, but near the separatrix they peak at the slow passage by the intermediate axis, where a
        # wander that is zero at the start is small again: weighting the wander by the mean instead missed
        # the orientation error there by 10x-1e4x, mostly over (tests/test_advise.py
        # ::test_near_the_separatrix_the_orientation_error_is_predicted)
        sphi, cphi = amplitudes(Is, G2, delta, pole, m)
        f0, p0 = phase_rates(Is, G2, delta, pole, sphi, cphi)
        fG, pG = phase_rates(Is, G2 * (1 + eta), delta, pole, sphi, cphi)
        fd, pd = phase_rates(Is, G2, delta * (1 - eta), pole, sphi, cphi)
        e = eta[:, None]
        c_G, c_d = np.nan_to_num(np.log(fG / f0) / e), np.nan_to_num(-np.log(fd / f0) / e)  # ∂ ln φ̇ / ∂ ln (G², δ)
        # ∂ (ψ̇/φ̇) / ∂ ln (G², δ) times the φ of a step: rad per step
        t_G = np.nan_to_num((pG / fG - p0 / f0) / e * f0 * dt[:, None])
        t_d = np.nan_to_num(-(pd / fd - p0 / f0) / e * f0 * dt[:, None])
    dlnP = np.where(np.isfinite(dlnP), dlnP, 0.0)
    dalpha = np.where(np.isfinite(dalpha), dalpha, 0.0)
    finite = np.isfinite(period) & (period > 0)
    per_point = np.where(finite, period, 1.0) / (n * dt)  # steps per orbit point
    T_arr = np.broadcast_to(np.asarray(T, float), (B,))
    covered = np.where(finite, T_arr / np.where(finite, period, 1.0) * n, n)  # points over T

    # The times the errors are evaluated at: the last orbit of the horizon (n + 1 points, T ≥ P), or
    # the points it covers and T itself (T < P); their steps from the start and orbit points
    j = np.arange(n + 1)[None, :] / n
    Pf = np.where(finite, period, 1.0)[:, None]
    t = np.where(covered[:, None] >= n, T_arr[:, None] - Pf * (1 - j), np.minimum(j * Pf, T_arr[:, None]))
    t = np.where(finite[:, None], t, T_arr[:, None] * j)  # no period (a spin about an axis): uniform
    steps = t / dt[:, None]
    pos = np.where(finite[:, None], np.mod(t, Pf) / Pf * n, 0.0)
    idx = np.minimum(np.floor(pos), n - 1).astype(int)
    frac = pos - idx
    rows = np.arange(B)[:, None]

    def accumulated(x):
        """Sum of the per-step defect x (B·n) from the start at the evaluation times (B, n + 1):
        mean × steps + the running sum of its periodic part from ω0 (it comes and goes)."""
        x = x.reshape(B, n)
        mean = x.mean(axis=1)
        dev = (x - mean[:, None]) * per_point[:, None]
        run = np.concatenate([np.zeros((B, 1)), np.cumsum(dev, axis=1)], axis=1)  # at k P / n
        return mean[:, None] * steps + run[rows, idx] + dev[rows, idx] * frac

    def growth(x):
        return np.abs(accumulated(x)).max(axis=1)

    def wander(x):
        """The running sum of the periodic part of the per-step change x (B·n), over each point (B, n): how far
        the invariant has wandered from its start's value there (its mean drift is dlnP's and dalpha's)."""
        x = x.reshape(B, n)
        dev = (x - x.mean(axis=1)[:, None]) * per_point[:, None]
        run = np.concatenate([np.zeros((B, 1)), np.cumsum(dev, axis=1)], axis=1)
        return 0.5 * (run[:, :-1] + run[:, 1:])

    # The state after k steps is the exact one at k + σ steps turned about L by α (both a solution:
    # the free flow commutes with turns about L), so the attitude error is |α m̂ + σ ω| (body frame,
    # ω in rad per step), α and σ the accumulated a and s, secular and periodic parts together (in
    # phase, as they are: a and s's periodic parts nearly cancel when ω is nearly along L).  A drift
    # of the orbit's invariants adds −½ k² dlnP to σ; their wander adds the local rates' sums.
    W_G, W_d = wander(dlnG2_k), wander(dlnd_k)
    z_sigma = np.where(finite[:, None], c_G * W_G + c_d * W_d, 0.0)  # steps gained per step
    z_alpha = np.where(finite[:, None], t_G * W_G + t_d * W_d, 0.0)  # rad turned per step
    sigma = accumulated(s) - 0.5 * steps**2 * dlnP[:, None] + accumulated(z_sigma)
    alpha = accumulated(a) + 0.5 * steps**2 * dalpha[:, None] + accumulated(z_alpha)
    w_step = wu.reshape(B, n, 3)[rows, idx]  # rad per step, (B, n + 1, 3)
    mh = m_hat.reshape(B, n, 3)[rows, idx]
    A = np.linalg.norm(alpha[..., None] * mh + sigma[..., None] * w_step, axis=2).max(axis=1)
    S = np.abs(sigma).max(axis=1)
    fmax = np.sqrt(ff.reshape(B, n).max(axis=1))  # |ω̇| in units 1/dt²
    E0 = 0.5 * np.sum(I * w0 * w0, axis=1) * dt**2
    L0 = np.linalg.norm(I * w0, axis=1) * dt
    return {
        "orientation": A,
        "omega": fmax * S / (Om * dt),
        "energy": growth(dE) / E0,
        "L_norm": growth(dL) / L0,
    }


def _turn_per_period(Is, G2, delta, pole, sign, n=64):
    """Δφ (rad): the turn about L over one period of the orbit (sorted moments Is, invariants G², δ),
    the period times the mean of φ̇ = G (2T − m_p²/I_p) / (G² − m_p²) (Landau & Lifshitz §37, with the
    pole axis p as the third: R(t + P) = Rot_L(Δφ) R(t)); φ̇ is predict.phase_rates' ψ̇."""
    m, period = orbit_points(Is, G2, delta, pole, sign, n)
    _, rate = phase_rates(Is, G2, delta, pole, *amplitudes(Is, G2, delta, pole, m))
    return period * rate.mean(axis=1)


def _unsort(v, perm):
    out = np.empty_like(v)
    np.put_along_axis(out, np.broadcast_to(perm[:, None, :], v.shape), v, -1)
    return out
