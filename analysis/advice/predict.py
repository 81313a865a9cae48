"""Stability and drift of the engine updates on a torque-free body, predicted without running them.

The updates that fail (the explicit gyroscopic step of MuJoCo's Euler, Bullet's explicit term and
forward Euler; the |L|-rescaled step of Jolt and Rapier; the linearly implicit step of MuJoCo's
implicit) are first order, so one step is the exact flow plus a defect of order h², and the
defect's secular part moves the body slowly from one Euler–Poinsot orbit to the next.  An orbit of
the free body is fixed by two invariants: G² = |L|² and the distance of the energy from the pole
axis's, δ = |2 T I_p − G²| (I_p the moment of the axis the orbit turns about, e1 or e3 of the
sorted moments).  δ is written as a sum of positive terms, δ = Σ_{i≠p} m_i² |I_p − I_i| / I_i
(m = Iω, body frame), so it keeps its relative precision for a spin 1e-8 rad off a principal axis,
where 2T I_p − G² would be all rounding.

The predictor (first-order averaging, e.g. Sanders, Verhulst & Murdock, *Averaging Methods in
Nonlinear Dynamical Systems*, 2007, ch. 2): the change per step of G² and δ, averaged over the
orbit in time (n points uniform in the elliptic argument, Jacobi sn, cn, dn of the closed form,
Landau & Lifshitz, *Mechanics*, §37), is the rate of a slow ODE in the step count; that ODE is
integrated (Heun, each stage moving G² and δ by at most ``frac``) until the body blows up or
``n_max`` steps have passed.  The step applied is the method's own compiled ``step`` (one step of
``kernels.batch.integrate`` on all orbit points at once), so the clamps and caps the engines ship
are in it.  Valid while an orbit takes many steps to traverse compared with the drift (|ω| h ≲ 0.3).

Blow-up, precisely: the first step at which |E − E0| > ``BLOWUP_ENERGY`` E0 (kinetic energy up a
millionfold, |ω| up about 1e3, the driver's divergence flag with that threshold), or, with
``criterion="qacc"``, at which an orbit reaches |I⁻¹(ω × Iω)|_∞ > 1e10 rad/s² (MuJoCo's mjMAXVAL,
the test behind mjWARN_BADQACC).

``amplification`` is the linearisation the brief of issue 25 asks for: the finite-difference
Jacobian of the one-step ω map at the spin about the pole axis with the body's |L|, and its
eigenvalues; near an axis the averaged δ grows by |λ|² per step, and a test checks the two agree.

Units: I in kg m², ω in rad/s (body frame), dt in s; rates are per step unless named per second.
"""

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ...kernels import elliptic
from ...kernels.batch import integrate
from ...kernels.body import N_FIELDS as N_BODY
from ...kernels.driver import FIELDS

BLOWUP_ENERGY = 1e6  # |E − E0| / E0 that counts as blown up (|ω| up ~1e3)
MJ_MAXVAL = 1e10  # MuJoCo's mjMAXVAL: |qacc| above it raises mjWARN_BADQACC (engine_forward.c mj_checkAcc)
N_ORBIT = 32  # points per orbit for the average
OMEGA = slice(FIELDS.index("omega_1"), FIELDS.index("omega_3") + 1)

# The updates the predictor is for: those that blow up (explicit gyroscopic term), those that keep
# |L| and move the energy (rescale), those that damp (linearly implicit).  no_gyro keeps ω constant
# (nothing drifts, it is simply wrong); jolt_rescale's 47 rad/s clamp acts on the first step.
KINDS = {
    "mujoco_euler": "explicit gyroscopic",
    "bullet_explicit": "explicit gyroscopic",
    "explicit_euler": "explicit gyroscopic",
    "jolt_rescale_bare": "|L| rescale",
    "jolt_rescale": "|L| rescale",
    "rapier_rescale": "|L| rescale",
    "mujoco_implicit": "linearly implicit",
    "mujoco_implicitfast": "linearly implicit",  # a free body takes MuJoCo's implicit branch
    "bullet_implicit_body": "linearly implicit",
    "no_gyro": "no gyroscopic term",
}


def _sorted(I, w):
    """Moments sorted ascending per row, the permutation, and ω in that order (B, 3)."""
    perm = np.argsort(I, axis=1, kind="stable")
    return np.take_along_axis(I, perm, 1), perm, np.take_along_axis(w, perm, 1)


def _delta(Is, m, pole):
    """δ = Σ_{i≠p} m_i² |I_p − I_i| / I_i for rows of sorted moments Is and momenta m (..., 3)."""
    Ip = np.take_along_axis(Is, pole[:, None], 1)
    shape = (Is.shape[0],) + (1,) * (m.ndim - 2) + (3,)
    weight = (np.abs(Ip - Is) / Is).reshape(shape)
    return np.sum(m * m * weight, axis=-1)


def orbit_state(I, w):
    """(Is, perm, G², δ, pole, sign) of the orbits through body rates w (B, 3) of bodies I (B, 3).

    pole is 0 (the smallest moment: 2T I2 > G²) or 2 (the largest), sign the sign of the pole
    component of m; Is the sorted moments and perm their order."""
    Is, perm, ws = _sorted(I, w)
    m = Is * ws
    G2 = np.sum(m * m, axis=1)
    s = np.sum(m * m * (Is[:, 1:2] - Is) / Is, axis=1)  # 2T I2 − G², term by term
    pole = np.where(s > 0, 0, 2)
    sign = np.where(np.take_along_axis(m, pole[:, None], 1)[:, 0] < 0, -1.0, 1.0)
    return Is, perm, G2, _delta(Is, m, pole), pole, sign


def two_T(Is, G2, delta, pole):
    """Twice the kinetic energy (J) from the orbit's invariants (sorted moments, G², δ, pole)."""
    Ip = np.take_along_axis(Is, pole[:, None], 1)[:, 0]
    return np.where(pole == 2, G2 + delta, G2 - delta) / Ip


def separatrix_delta(Is, G2, pole):
    """δ of the separatrix (2T = G²/I2) for orbits about ``pole``."""
    Ip = np.take_along_axis(Is, pole[:, None], 1)[:, 0]
    return G2 * np.abs(Ip / Is[:, 1] - 1.0)


def separatrix_distance(I, w):
    """(δ_sep − δ) / δ_sep (B,) of the orbits through body rates w (B, 3) rad/s of bodies I (B, 3) kg m²:
    how far the orbit is from the separatrix 2T = G²/I2, relative (1 on a pole spin, 0 on the
    separatrix: the spin about the intermediate axis); NaN unless the three moments differ."""
    Is, _, G2, delta, pole, _ = orbit_state(np.atleast_2d(I), np.atleast_2d(w))
    dsep = separatrix_delta(Is, G2, pole)
    distinct = (Is[:, 0] < Is[:, 1]) & (Is[:, 1] < Is[:, 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(distinct, np.maximum(dsep - delta, 0.0) / dsep, np.nan)


def intermediate_axis_rate(I, G):
    """λ (1/s): the e-folding rate of a small perturbation of the spin about the intermediate axis of
    moments I (3,) kg m² with |L| = G kg m²/s, Ω √((I2 − I1)(I3 − I2) / (I1 I3)), Ω = G / I2 (the
    linearised Euler equations at that spin; Landau & Lifshitz §37)."""
    I1, I2, I3 = np.sort(np.asarray(I, float))
    return G / I2 * math.sqrt(max((I2 - I1) * (I3 - I2), 0.0) / (I1 * I3))


# An orbit whose δ is within this many roundings of the separatrix's is on it: a spin about the
# intermediate axis (or a motion towards it), which the elliptic closed form cannot tell from a flip
SEPARATRIX_ROUNDINGS = 4
SEPARATRIX_MC = SEPARATRIX_ROUNDINGS * np.finfo(float).eps


@njit(cache=True, error_model="numpy")
def _jacobi(u, mc):
    """(sn, cn, dn) of u (B, n) at parameters m = 1 − mc (B,), 0 ≤ mc ≤ 1 (kernels/elliptic.py's
    sncndn: accurate as m → 1, where scipy's ellipj is not past u ≈ K for m > 1 − 1e-9)."""
    sn = np.empty_like(u)
    cn = np.empty_like(u)
    dn = np.empty_like(u)
    for b in range(u.shape[0]):
        for j in range(u.shape[1]):
            sn[b, j], cn[b, j], dn[b, j] = elliptic.sncndn(u[b, j], mc[b])
    return sn, cn, dn


@njit(cache=True, error_model="numpy")
def _quarter_period_and_start(mc, phi):
    """K(m) (B,) and the elliptic argument F(φ | m) (B,) of amplitudes φ, m = 1 − mc, 0 < mc ≤ 1."""
    K = np.empty_like(mc)
    u0 = np.empty_like(mc)
    for b in range(mc.shape[0]):
        K[b] = elliptic.ellipk(mc[b])
        u0[b] = elliptic.ellipf(phi[b], mc[b])
    return K, u0


def _orbit_constants(Is, G2, delta, pole):
    """(o, a_o², a_2², a_p², m_c, λ, on_separatrix) (B,) of the orbits (sorted moments Is, G², δ, pole p):
    o the opposite extreme axis, the squared amplitudes of m_o = a_o cn u, m_2 = a_2 sn u, m_p = ± a_p dn u,
    the complementary parameter m_c = 1 − k² (formed from the distance to the separatrix, not as a
    difference: an orbit 1e-14 of δ from it keeps its period, as scipy's ellipk(1 − 1e-15) would not),
    the rate λ (1/s) of u = λt, and whether δ is within SEPARATRIX_ROUNDINGS roundings of the separatrix's
    (m_c is then SEPARATRIX_MC: the nearest orbit the closed form tells from it)."""
    idx = np.arange(Is.shape[0])
    o = 2 - pole
    Ip, Io, Im = Is[idx, pole], Is[idx, o], Is[:, 1]
    dpo, dpm = np.abs(Ip - Io), np.abs(Ip - Im)
    dsep = separatrix_delta(Is, G2, pole)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_o2 = np.where(dpo > 0, delta * Io / dpo, 0.0)
        a_m2 = np.where(dpm > 0, delta * Im / dpm, 0.0)
        a_p2 = np.maximum(G2 - a_o2, 0.0)
        X = (G2 * dpo - delta * Io) / Ip  # |G² − 2T I_o| > 0
        elliptic_orbit = (dpm > 0) & (X > 0)
        # 1 − k² = (dpm X − dmo δ) / (dpm X), and dpm X − dmo δ = dpo Im (δ_sep − δ) / Ip
        mc = np.where(elliptic_orbit, dpo * Im * (dsep - delta) / (Ip * dpm * X), 1.0)
        mc = np.clip(np.nan_to_num(mc, nan=1.0), 0.0, 1.0)
        lam = np.sqrt(np.maximum(dpm * X, 0.0) / (Is[:, 0] * Is[:, 1] * Is[:, 2]))
    on_separatrix = elliptic_orbit & (dsep - delta <= SEPARATRIX_ROUNDINGS * np.finfo(float).eps * dsep)
    return o, a_o2, a_m2, a_p2, np.where(on_separatrix, SEPARATRIX_MC, mc), lam, on_separatrix


def amplitudes(Is, G2, delta, pole, m):
    """(sin φ, cos φ) (B, n) of the sorted momenta m (B, n, 3) on their orbits (sorted moments Is, G², δ,
    pole): sn u = m_2 / a_2, cn u = m_o / a_o, φ = am u; φ = 0 where the orbit is a point (a pole spin)."""
    o, a_o2, a_m2, _, _, _, _ = _orbit_constants(Is, G2, delta, pole)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = m[:, :, 1] / np.sqrt(a_m2)[:, None]
        c = np.take_along_axis(m, o[:, None, None], 2)[..., 0] / np.sqrt(a_o2)[:, None]
        r = np.hypot(s, c)
        ok = np.isfinite(r) & (r > 0)
        return np.where(ok, s / r, 0.0), np.where(ok, c / r, 1.0)


def phase_rates(Is, G2, delta, pole, sin_phi, cos_phi):
    """(φ̇, ψ̇) (B, n) rad/s at the amplitudes φ (sin φ, cos φ (B, n)) of the orbits (sorted moments Is,
    G², δ, pole): φ = am u, so φ̇ = λ dn u = λ √(m_c + k² cos² φ), and ψ̇ = G (2T − m_p²/I_p)/(G² − m_p²)
    the turn rate about L (Landau & Lifshitz §37; m_p² = a_p² dn² u).  At a fixed φ the point of a nearby
    orbit is the one across from it, so the derivatives in G² and δ at fixed φ are how a body moved to
    that orbit runs faster or slower there."""
    idx = np.arange(Is.shape[0])
    _, _, _, a_p2, mc, lam, _ = _orbit_constants(Is, G2, delta, pole)
    dn2 = mc[:, None] + (1.0 - mc)[:, None] * cos_phi**2
    mp2 = a_p2[:, None] * dn2
    Ip = Is[idx, pole][:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        psidot = np.sqrt(G2)[:, None] * (two_T(Is, G2, delta, pole)[:, None] - mp2 / Ip) / (G2[:, None] - mp2)
    return lam[:, None] * np.sqrt(dn2), psidot


def orbit_points(Is, G2, delta, pole, sign, n=N_ORBIT, start=None, start_rate=None):
    """Body momenta m (B, n, 3), sorted frame, uniform in time over one period of the orbit.

    Closed form (Landau & Lifshitz §37), written for either pole p with o the opposite extreme
    axis: m_o = a_o cn u, m_2 = a_2 sn u, m_p = ± a_p dn u, u = λ t, u over one period 4K(k²).
    Also returns the period in seconds (inf for a body with equal moments about the pole: no motion;
    inf on the separatrix, δ within SEPARATRIX_ROUNDINGS roundings of its: the spin about the
    intermediate axis, or a motion that nears it forever; its points are then all the start, or without
    a start those of the nearest orbit the closed form tells from it, 1 − k² = SEPARATRIX_MC, whose
    average over a period is the separatrix's limit).
    ``start`` (B, 3), sorted momenta on the orbits, and ``start_rate``, their dm/dt (sorted): the points
    begin there and follow the motion forward in time (else they begin at u = 2K / n, in the direction
    of increasing u, which is backward in time for about half the orbits: a sorted frame is left-handed
    for an odd permutation).  Near the separatrix (1 − k² → 0) see ``_orbit_constants`` and ``_jacobi``."""
    B = Is.shape[0]
    idx = np.arange(B)
    o, a_o2, a_m2, a_p2, mc, lam, on_separatrix = _orbit_constants(Is, G2, delta, pole)
    k2 = 1.0 - mc
    phi = np.zeros(B)
    if start is not None:  # the start's u: its amplitude φ (sn u = sin φ, cn u = cos φ), then F(φ | k²)
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.arctan2(np.nan_to_num(start[:, 1] / np.sqrt(a_m2)), np.nan_to_num(start[idx, o] / np.sqrt(a_o2)))
    K, u0 = _quarter_period_and_start(mc, phi)  # mc > 0: SEPARATRIX_MC on the separatrix
    u = 4.0 * K[:, None] * (np.arange(n) + (0.5 if start is None else 0.0))[None, :] / n
    if start is not None:
        sn0, cn0, dn0 = (v[:, 0] for v in _jacobi(u0[:, None], mc))
        tangent = np.zeros((B, 3))  # dm/du at the start
        tangent[idx, o] = -np.sqrt(a_o2) * sn0 * dn0
        tangent[:, 1] = np.sqrt(a_m2) * cn0 * dn0
        tangent[idx, pole] = -sign * np.sqrt(a_p2) * k2 * sn0 * cn0
        forward = np.where(np.sum(tangent * start_rate, axis=1) < 0, -1.0, 1.0)
        u = u0[:, None] + forward[:, None] * u
    sn, cn, dn = _jacobi(u, mc)
    m = np.empty((B, n, 3))
    m[idx, :, o] = np.sqrt(a_o2)[:, None] * cn
    m[:, :, 1] = np.sqrt(a_m2)[:, None] * sn
    m[idx, :, pole] = (sign * np.sqrt(a_p2))[:, None] * dn
    if start is not None and on_separatrix.any():  # the body stays at the spin (or nears it forever)
        m[on_separatrix] = start[on_separatrix][:, None, :]
    with np.errstate(divide="ignore"):
        period = np.where((lam > 0) & ~on_separatrix, 4.0 * K / lam, np.inf)
    return m, period


def _unsort(v, perm):
    """Undo ``_sorted`` on the last axis of v (B, ..., 3)."""
    out = np.empty_like(v)
    np.put_along_axis(out, np.broadcast_to(perm.reshape((perm.shape[0],) + (1,) * (v.ndim - 2) + (3,)), v.shape), v, -1)
    return out


def one_step(method, I, w, dt):
    """ω after one step of ``method`` from rates w (N, 3), bodies I (N, 3) free, dt (N,) s; identity q."""
    N = w.shape[0]
    bodies = np.zeros((N, N_BODY))
    bodies[:, :3] = I
    q0 = np.zeros((N, 4))
    q0[:, 0] = 1.0
    out, _, _ = integrate(method, bodies, w, q0, dt, 1, 2, threshold=1e300)
    return out[:, 1, OMEGA]


def averaged_rates(method, Is, perm, G2, delta, pole, sign, dt, n=N_ORBIT):
    """Orbit-averaged change per step of (G², δ) of ``method`` at step dt (B,), and the orbit points."""
    B = Is.shape[0]
    m, period = orbit_points(Is, G2, delta, pole, sign, n)
    w_sorted = m / Is[:, None, :]
    w = _unsort(w_sorted, perm).reshape(B * n, 3)
    I_rows = np.repeat(_unsort(Is, perm), n, axis=0)
    w1 = one_step(method, I_rows, w, np.repeat(dt, n)).reshape(B, n, 3)
    w1s = np.take_along_axis(w1, np.broadcast_to(perm[:, None, :], w1.shape), 2)
    m1 = Is[:, None, :] * w1s
    dG2 = np.sum(m1 * m1, axis=-1) - np.sum(m * m, axis=-1)
    dd = _delta(Is, m1, pole) - _delta(Is, m, pole)
    return dG2.mean(axis=1), dd.mean(axis=1), m, period


@dataclass
class Prediction:
    """What the predictor says about one (method, body, ω0, dt); steps and seconds from the start."""

    method: str
    kind: str
    dt: float
    blow_up_step: float  # inf: none within n_max steps
    energy_rate: float  # dE/dt at the start (J/s; per step: × dt)
    energy_rate_relative: float  # (dE/dt) / E0 (1/s)
    relaxation_time: float  # s for the distance to the energy it relaxes to to fall by e (inf: none seen)
    relaxes_to: str  # "pole axis", "separatrix L²/(2 I2)", "" (none)
    n_steps: np.ndarray  # the slow trajectory: step counts,
    energy: np.ndarray  # kinetic energy (J) and
    G2: np.ndarray  # |L|² (kg² m⁴/s²) at them


def _qacc_max(m, Is):
    """max over orbit points of |I⁻¹ (ω × Iω)|_∞ (rad/s²) in the sorted frame."""
    w = m / Is[:, None, :]
    c = np.cross(w, m) / Is[:, None, :]
    return np.abs(c).max(axis=(1, 2))


def predict_many(method, I, omega0, dt, n_max=1e5, criterion="energy", frac=0.1, max_stages=3000, n=N_ORBIT):
    """Predict each of B runs of ``method`` on free bodies I (B, 3) kg m² from ω0 (B, 3) rad/s at dt (B,) s.

    Returns a list of ``Prediction``.  ``criterion`` "energy" (|E − E0| > BLOWUP_ENERGY E0) or
    "qacc" (MuJoCo's |qacc| > 1e10)."""
    if criterion not in ("energy", "qacc"):
        raise ValueError(f"criterion={criterion!r}: choose energy or qacc")
    I = np.atleast_2d(np.asarray(I, dtype=float))
    omega0 = np.atleast_2d(np.asarray(omega0, dtype=float))
    B = max(I.shape[0], omega0.shape[0])
    I = np.ascontiguousarray(np.broadcast_to(I, (B, 3)))
    omega0 = np.ascontiguousarray(np.broadcast_to(omega0, (B, 3)))
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (B,)).copy()
    Is, perm, G2, delta, pole, sign = orbit_state(I, omega0)
    T0 = 0.5 * two_T(Is, G2, delta, pole)
    n_done = np.zeros(B)
    blow = np.full(B, np.inf)
    active = T0 > 0
    hist = [[(0.0, T0[b], G2[b])] for b in range(B)]
    rate0 = np.zeros(B)
    relax = np.full(B, np.inf)
    target = np.array([""] * B, dtype=object)
    d_start = np.full(B, np.nan)  # distance to the relaxation target at the start
    kind = KINDS.get(method, "")
    # a spin exactly about a principal axis stays (ω × Iω = 0 in every update): about the intermediate
    # axis too, where the orbit's closed form is the separatrix, whose limit would drift
    active &= np.count_nonzero(omega0, axis=1) > 1
    for stage in range(max_stages):
        if not active.any():
            break
        a = np.flatnonzero(active)
        rG, rd, m, _ = averaged_rates(method, Is[a], perm[a], G2[a], delta[a], pole[a], sign[a], dt[a], n)
        if stage == 0:
            rT = 0.5 * np.where(pole[a] == 2, rG + rd, rG - rd) / np.take_along_axis(Is[a], pole[a][:, None], 1)[:, 0]
            rate0[a] = rT / dt[a]
            dsep = separatrix_delta(Is[a], G2[a], pole[a])
            toward_pole = rd < 0
            target[a] = np.where(rd == 0, "", np.where(toward_pole, "pole axis", "separatrix L²/(2 I2)"))
            d_start[a] = np.where(toward_pole, delta[a], dsep - delta[a])
        # Heun in log G² and log δ (exact for the exponential growth of a nutation about an axis), each
        # stage moving either by at most frac; shortened while the corrector's rates say it went too far
        tiny = 1e-300
        gG, gd = rG / G2[a], rd / np.maximum(delta[a], tiny)
        scale = np.maximum(np.abs(gG), np.abs(gd))
        with np.errstate(divide="ignore"):
            dn = np.where(scale > 0, frac / scale, np.inf)
        dn = np.minimum(dn, n_max - n_done[a])
        if kind == "|L| rescale":
            # the separatrix attracts these: a stage moves δ by at most frac of the distance left to it, so the
            # slow trajectory nears it and settles instead of stepping across and back
            with np.errstate(divide="ignore", invalid="ignore"):
                gap = separatrix_delta(Is[a], G2[a], pole[a]) - delta[a]
                dn = np.where(rd > 0, np.minimum(dn, frac * gap / rd), dn)
        gG2, gd2 = gG.copy(), gd.copy()
        todo = np.isfinite(dn)
        for _ in range(10):
            f = np.flatnonzero(todo)
            if f.size == 0:
                break
            G2p = G2[a][f] * np.exp(dn[f] * gG[f])
            dp = np.maximum(delta[a][f], tiny) * np.exp(dn[f] * gd[f])
            rG2, rd2, _, _ = averaged_rates(method, Is[a][f], perm[a][f], G2p, dp, pole[a][f], sign[a][f], dt[a][f], n)
            gG2[f], gd2[f] = rG2 / G2p, rd2 / dp
            jump = dn[f] * np.maximum(np.abs(gG2[f]), np.abs(gd2[f]))
            too_far = ~(jump <= 3 * frac)  # NaN too
            dn[f[too_far]] *= 0.25
            todo[:] = False
            todo[f[too_far]] = True
        gG2[todo], gd2[todo] = gG[todo], gd[todo]  # still too far after the retries: an Euler stage
        with np.errstate(over="ignore", invalid="ignore"):
            G2_new = G2[a] * np.exp(0.5 * dn * (gG + gG2))
            d_new = np.where(delta[a] > 0, delta[a] * np.exp(0.5 * dn * (gd + gd2)), 0.0)
        d_new = np.nan_to_num(d_new, nan=0.0, posinf=np.inf)
        n_new = n_done[a] + dn
        T_new = 0.5 * two_T(Is[a], G2_new, d_new, pole[a])
        # blow-up test on the new orbit, interpolated in log energy between the stage's ends
        if criterion == "energy":
            x0, x1, lim = 0.5 * two_T(Is[a], G2[a], delta[a], pole[a]), T_new, (1 + BLOWUP_ENERGY) * T0[a]
        else:
            m_new, _ = orbit_points(Is[a], G2_new, d_new, pole[a], sign[a], n)
            x0, x1, lim = _qacc_max(m, Is[a]), _qacc_max(m_new, Is[a]), np.full(a.size, MJ_MAXVAL)
        with np.errstate(divide="ignore", invalid="ignore"):
            hit = ((x1 >= lim) | ~np.isfinite(x1)) & np.isfinite(dn)  # a non-finite orbit: past any limit
            t = np.clip(np.log(lim / x0) / np.log(x1 / x0), 0.0, 1.0)
        blow[a[hit]] = n_done[a][hit] + np.nan_to_num(t[hit], nan=0.5) * dn[hit]
        # relaxation: the step where the distance to the target has fallen by e
        dsep_new = separatrix_delta(Is[a], G2_new, pole[a])
        dist = np.where(target[a] == "pole axis", d_new, dsep_new - d_new)
        crossed = np.isinf(relax[a]) & (target[a] != "") & (dist <= d_start[a] / math.e)
        relax[a[crossed]] = n_new[crossed] * dt[a][crossed]
        # past the separatrix: the orbit turns about the other extreme axis
        sw = d_new > dsep_new
        if sw.any():
            tT = two_T(Is[a][sw], G2_new[sw], d_new[sw], pole[a][sw])
            newp = 2 - pole[a][sw]
            Ip = np.take_along_axis(Is[a][sw], newp[:, None], 1)[:, 0]
            d_new[sw] = np.abs(tT * Ip - G2_new[sw])
            pole[a[sw]] = newp
            sign[a[sw]] = 1.0
        G2[a], delta[a], n_done[a] = G2_new, d_new, n_new
        for j, b in enumerate(a):
            hist[b].append((n_new[j], T_new[j], G2_new[j]))
        # a rescale that has reached the separatrix stays there (the orbit's period diverges)
        settled = (
            (kind == "|L| rescale")
            & (target[a] == "separatrix L²/(2 I2)")
            & (np.abs(dsep_new - d_new) <= 1e-3 * dsep_new)
        )
        active[a] = ~hit & ~settled & (n_new < n_max) & np.isfinite(dn) & (T_new > 0)
    kind = KINDS.get(method, "")
    out = []
    for b in range(B):
        h = np.array(hist[b])
        out.append(
            Prediction(
                method=method,
                kind=kind,
                dt=float(dt[b]),
                blow_up_step=float(blow[b]),
                energy_rate=float(rate0[b]),
                energy_rate_relative=float(rate0[b] / T0[b]) if T0[b] > 0 else 0.0,
                relaxation_time=float(relax[b]),
                relaxes_to=str(target[b]) if kind == "|L| rescale" else "",
                n_steps=h[:, 0],
                energy=h[:, 1],
                G2=h[:, 2],
            )
        )
    return out


def predict(method, I, omega0, dt, **kw):
    """``predict_many`` for one body I (3,) kg m², ω0 (3,) rad/s (body frame), dt s: one ``Prediction``."""
    return predict_many(method, np.asarray(I, float)[None], np.asarray(omega0, float)[None], [dt], **kw)[0]


def energy_after(pred, n):
    """Predicted kinetic energy (J) after n steps, from the slow trajectory (log-linear between stages)."""
    ns, E = pred.n_steps, pred.energy
    if n >= ns[-1]:
        return float(E[-1]) if np.isinf(pred.blow_up_step) else math.inf
    return float(np.exp(np.interp(n, ns, np.log(np.maximum(E, 1e-300)))))


def amplification(method, I, omega0, dt, eps=1e-7):
    """Eigenvalues (3,) of the Jacobian of the one-step ω map at the spin about the pole axis of the
    orbit through ω0, with the body's |L| (central finite differences, relative step eps).

    For a first-order update about a stable axis, two are a complex pair of modulus |λ| = per-step
    amplification of a nutation (> 1: it grows, explicit gyroscopic; < 1: damped, implicit), the
    third ≈ 1 (the spin itself)."""
    I = np.asarray(I, float)[None]
    Is, perm, G2, _, pole, sign = orbit_state(I, np.asarray(omega0, float)[None])
    ws = np.zeros((1, 3))
    ws[0, pole[0]] = sign[0] * math.sqrt(G2[0]) / Is[0, pole[0]]
    w_star = _unsort(ws, perm)[0]
    h = eps * np.linalg.norm(w_star)
    pts = np.array([w_star + s * h * e for e in np.eye(3) for s in (1.0, -1.0)])
    w1 = one_step(method, np.repeat(I, 6, axis=0), pts, np.full(6, float(dt)))
    J = np.stack([(w1[2 * k] - w1[2 * k + 1]) / (2 * h) for k in range(3)], axis=1)
    return np.linalg.eigvals(J)


# --- command line: what each engine update does to one free body -------------------------------

DEFAULT_METHODS = ("mujoco_euler", "bullet_explicit", "mujoco_implicit", "jolt_rescale_bare", "rapier_rescale")


def measure_blow_up(method, I, omega0, dt, n_max, horizon_steps=None, n_samples=2001):
    """Measured blow-up step (|E − E0| > BLOWUP_ENERGY E0; inf: none in the horizon), the kinetic
    energy (J) after min(horizon, n_max) steps (NaN once blown up), the steps run, and the flips
    (sign changes of the intermediate axis's rate, counted on the samples up to the blow-up; NaN for a
    body without a distinct intermediate moment, or when the samples are too few to resolve them: more
    than one flip per 4 samples), sampled ``n_samples`` times over the horizon."""
    horizon = int(min(n_max, horizon_steps or n_max))
    stride = max(1, math.ceil(horizon / (n_samples - 1)))
    bodies = np.zeros((1, N_BODY))
    bodies[0, :3] = I
    q0 = np.array([[1.0, 0.0, 0.0, 0.0]])
    n_samples = horizon // stride + 1
    out, status, n_steps = integrate(
        method, bodies, np.asarray(omega0, float)[None], q0, [dt], stride, n_samples, threshold=BLOWUP_ENERGY
    )
    blown = float(n_steps[0]) if status[0] != 0 else math.inf
    flips = math.nan
    order = np.argsort(I)
    if I[order[0]] < I[order[1]] < I[order[2]]:
        w_mid = out[0, : int(min(n_steps[0], horizon)) // stride + 1, FIELDS.index("omega_1") + int(order[1])]
        signs = np.sign(w_mid[np.isfinite(w_mid) & (w_mid != 0)])
        counted = int(np.count_nonzero(signs[1:] != signs[:-1]))
        flips = float(counted) if 4 * counted <= len(signs) else math.nan
    return blown, float(out[0, -1, FIELDS.index("energy")]), (n_samples - 1) * stride, flips


def _fmt_steps(n, dt):
    return "never" if not math.isfinite(n) else f"{n:.4g} ({n * dt:.3g} s)"


def main(argv=None):
    """``python -m gyrolab.analysis.advice.predict I1 I2 I3 --omega W1 W2 W3 --dt DT [--check]``."""
    import argparse
    import sys
    import time

    from ...kernels.registry import METHODS

    ap = argparse.ArgumentParser(
        prog="python -m gyrolab.analysis.advice.predict",
        description="Predict what the engine rotation updates do to a torque-free body: per-step "
        "amplification of a nutation about its spin axis, blow-up step (|E - E0| > 1e6 E0), energy "
        "drift, relaxation of the |L|-rescaled updates.  --check runs each update to compare.",
    )
    ap.add_argument("inertia", nargs=3, type=float, metavar="I", help="principal moments (kg m^2)")
    ap.add_argument("--omega", nargs=3, type=float, required=True, metavar="W", help="body rates (rad/s)")
    ap.add_argument("--dt", type=float, required=True, help="time step (s)")
    ap.add_argument("--steps", type=float, default=1e5, help="horizon in steps (default 1e5)")
    ap.add_argument("--methods", default=",".join(DEFAULT_METHODS), help="comma-separated engine updates")
    ap.add_argument("--check", action="store_true", help="also run each update and show the measured values")
    args = ap.parse_args(argv)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    problems = []
    if not all(math.isfinite(v) and v > 0 for v in args.inertia):
        problems.append(f"inertia={args.inertia}: the moments must be finite and > 0")
    if not all(math.isfinite(v) for v in args.omega) or not any(args.omega):
        problems.append(f"--omega={args.omega}: must be finite and not all zero")
    if not (math.isfinite(args.dt) and args.dt > 0):
        problems.append(f"--dt={args.dt}: must be finite and > 0")
    if not (math.isfinite(args.steps) and 1 <= args.steps <= 1e8):
        problems.append(f"--steps={args.steps}: must be in [1, 1e8]")
    unknown = [m for m in methods if m not in KINDS or m not in METHODS]
    if unknown:
        problems.append(f"--methods: {', '.join(unknown)} not predicted; choose from {', '.join(KINDS)}")
    if problems:
        print("error: " + problems[0], file=sys.stderr)
        return 2
    I, w, dt = np.array(args.inertia), np.array(args.omega), args.dt
    wn = float(np.linalg.norm(w))
    print(
        f"body I = {tuple(args.inertia)} kg m^2, omega = {tuple(args.omega)} rad/s (|omega| dt = {wn * dt:.3g}), "
        f"dt = {dt:g} s, horizon {args.steps:.3g} steps"
    )
    head = f"{'method':<20} {'kind':<20} {'|lambda|/step':>13} {'blow-up step':>22} {'dE/dt / E0 (1/s)':>17}"
    head += f" {'relaxation':>28}" + (f" {'measured blow-up':>22} {'E(end)/E0 pred|meas':>20}" if args.check else "")
    print(head)
    for method in methods:
        t0 = time.perf_counter()
        p = predict(method, I, w, dt, n_max=args.steps)
        mods = np.abs(amplification(method, I, w, dt))
        lam = float(mods[np.argmax(np.abs(mods - 1.0))])  # the nutation's, not the spin's ≈ 1
        relax = (
            ""
            if not p.relaxes_to
            else (
                f"{p.relaxation_time:.3g} s to {p.relaxes_to}"
                if math.isfinite(p.relaxation_time)
                else f"to {p.relaxes_to}"
            )
        )
        row = f"{method:<20} {p.kind:<20} {lam:>13.6f} {_fmt_steps(p.blow_up_step, dt):>22} "
        row += f"{p.energy_rate_relative:>17.3e} {relax:>28}"
        if args.check:
            blown, E_end, n_run, _ = measure_blow_up(method, I, w, dt, args.steps)
            E0 = 0.5 * float(np.sum(I * w * w))
            pred_end = energy_after(p, n_run) / E0
            ends = f"{pred_end:>9.4g}|{E_end / E0:<10.4g}" if not math.isfinite(blown) else f"{'blown up':>20}"
            row += f" {_fmt_steps(blown, dt):>22} {ends}"
        print(row + f"   [{time.perf_counter() - t0:.1f} s]", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
