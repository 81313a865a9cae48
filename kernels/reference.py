"""Independent reference solutions that state their own error: DOP853 on (ω, R), and for a body
without gravity a Taylor series in extended precision.

A different formulation from every registered method (no quaternions, no
splitting, adaptive 8th-order steps): state y = (ω body (3), R row-major (9)),
I ω̇ = τ_b − ω × Iω, Ṙ = R [ω]×, τ_b = γ × (M g c) + τ_d(t), γ = Rᵀ ẑ (the
body's (mgl, mgc1, mgc2) = M g (c3, c1, c2); c = l e3 is the symmetric heavy
top; τ_d the driving torque of kernels/body.py, zero for every scene but
forced_body).  Where the drive switches on or off, the integration restarts,
so no adaptive step straddles the kink in τ_d's second derivative.

A reference is only as good as its error: ``dop853_with_error`` also returns
|y(tol) − y(10 tol)|, an upper estimate of the error of the run at tol (DOP853's
global error tracks its tolerance: at 1e-13 on the SciML body it is 1.3e-13,
the estimate 1.4e-12).  ``taylor_free_omega`` integrates Euler's equations of a
body without gravity (ω alone: SciMLBenchmarks' rigid body) by a 30-term Taylor
series in numpy.longdouble (eps 1.1e-19 on x86-64); ``free_omega_reference``
runs it at two step sizes and states their difference, plus the float64
rounding of the result, as its error (2e-16 on the SciML body, whose ω(10)
it gives to 7e-19 of a 30-digit mpmath Taylor solution, issue 25).
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from .body import N_FIELDS as N_BODY
from .body import Body
from .closed_form import scene_rotation
from .driver import FIELDS


def rhs(t, y, I1, I2, I3, mgl, mgc1=0.0, mgc2=0.0, tau1=0.0, tau2=0.0, tau3=0.0, rate=0.0, on=0.0, off=0.0):
    """d/dt of y = (ω body (rad/s), R row-major) at time t (s): Euler's equations with the gravity
    torque and the drive, and Ṙ = R [ω]×; the scipy ``solve_ivp`` form, args = the body tuple."""
    w1, w2, w3 = y[0], y[1], y[2]
    R = y[3:].reshape(3, 3)
    gamma = R[2]  # γ = Rᵀ ẑ is the third row of R
    tau = np.cross(gamma, (mgc1, mgc2, mgl))
    if on <= t <= off:
        tau = tau + np.array([tau1, tau2, tau3]) * np.sin(rate * t) ** 2
    dw = (
        (tau[0] + (I2 - I3) * w2 * w3) / I1,
        (tau[1] + (I3 - I1) * w3 * w1) / I2,
        (tau[2] + (I1 - I2) * w1 * w2) / I3,
    )
    W = np.array([[0.0, -w3, w2], [w3, 0.0, -w1], [-w2, w1, 0.0]])
    return np.concatenate((dw, (R @ W).ravel()))


def samples_from_states(body, omega, R):
    """Samples (n, driver.N_FIELDS) in driver.FIELDS order from ω (n, 3) and R (n, 3, 3).

    Each column is looked up by its name in driver.FIELDS, the one raw-field map the kernels'
    ``_record`` writes too: a field added there without its formula here is a KeyError naming it,
    never an uninitialised column."""
    I = np.asarray(body[:3], dtype=float)
    body = tuple(body) + (0.0,) * (N_BODY - len(body))
    weight_moment = np.array([body[4], body[5], body[3]])  # M g c in body coordinates
    Iw = omega * I
    L = np.einsum("nij,nj->ni", R, Iw)
    gamma = R[:, 2, :]  # γ = Rᵀ ẑ, the third row of R
    columns = {
        "axis_x": R[:, 0, 2],
        "axis_y": R[:, 1, 2],
        "axis_z": R[:, 2, 2],
        "omega_1": omega[:, 0],
        "omega_2": omega[:, 1],
        "omega_3": omega[:, 2],
        "energy": 0.5 * np.sum(omega * Iw, axis=1) + gamma @ weight_moment,
        "L_x": L[:, 0],
        "L_y": L[:, 1],
        "L_z": L[:, 2],
        "L3": Iw[:, 2],
        "gamma_1": gamma[:, 0],
        "gamma_2": gamma[:, 1],
        "gamma_3": gamma[:, 2],
    }
    missing = [name for name in FIELDS if name not in columns]
    if missing:
        raise KeyError(f"kernels/reference.py samples_from_states: no formula for raw field {missing[0]!r}")
    return np.stack([columns[name] for name in FIELDS], axis=1)


def dop853(scene, t_end, every, rtol=1e-12, atol=1e-12):
    """Reference samples (n_samples, driver.N_FIELDS) at t = 0, every, 2 every, ... ≤ t_end (s).

    Fields in driver.FIELDS order: axis R e3 (lab), ω (body, rad/s), E (J),
    L (lab), L3 (kg m²/s), γ (body).  The samples come from DOP853's dense output, accurate
    to about the tolerances.
    """
    if not (every > 0 and t_end >= every):
        raise ValueError(f"every={every}, t_end={t_end}: need 0 < every <= t_end")
    n_samples = int(math.floor(t_end / every * (1 + 1e-12))) + 1
    times = np.arange(n_samples) * every
    y0 = np.concatenate((np.asarray(scene.omega0, dtype=float), scene_rotation(scene).as_matrix().ravel()))
    body = Body(*(float(v) for v in scene.body))
    y = np.empty((n_samples, y0.size))
    y[0] = y0
    start = 0.0
    for end in _pieces(body, times[-1]):
        inside = (times > start) & (times <= end)
        t_eval = np.union1d(times[inside], [end])
        # Within a piece the drive is either on throughout or off: say so, so that no stage at a
        # piece's end sees the other side of the switch.
        on = body.drive_on <= 0.5 * (start + end) <= body.drive_off
        if on:
            piece = body._replace(drive_on=-math.inf, drive_off=math.inf)
        else:
            piece = body._replace(tau1=0.0, tau2=0.0, tau3=0.0)
        sol = solve_ivp(rhs, (start, end), y0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol, args=piece)
        if not sol.success:
            raise RuntimeError(f"DOP853 failed: {sol.message}")
        y[inside] = sol.y.T[np.isin(t_eval, times[inside])]
        y0, start = sol.y[:, -1], end
    return samples_from_states(scene.body, y[:, :3], y[:, 3:].reshape(-1, 3, 3))


def _pieces(body, t_end):
    """End times (s) of the intervals of [0, t_end] on which the drive is smooth: split where it
    switches on or off."""
    cuts = [t for t in (body.drive_on, body.drive_off) if any(body[6:9]) and 0.0 < t < t_end]
    return sorted(set(cuts)) + [t_end]


def dop853_with_error(scene, t_end, every, tol=1e-13):
    """(samples as ``dop853`` at rtol = atol = ``tol``, error estimate (n_samples, N_FIELDS)): the
    estimate is |samples(tol) − samples(10 tol)|, an upper estimate of the error at ``tol``."""
    fine = dop853(scene, t_end, every, rtol=tol, atol=tol)
    coarse = dop853(scene, t_end, every, rtol=10 * tol, atol=10 * tol)
    return fine, np.abs(fine - coarse)


def taylor_free_omega(body, omega0, t_end, h=0.05, order=30):
    """ω(t_end) (rad/s, numpy.longdouble (3,)) of a body without gravity under the drive of
    kernels/body.py, by a Taylor series in extended precision.

    ω̇_i = ((I_j − I_k) ω_j ω_k + τ_i s(t)) / I_i (body frame, (i, j, k) cyclic), s = sin²(rate t)
    inside the drive window, is a quadratic field, so its Taylor coefficients follow from Cauchy
    products: (n+1) w_i[n+1] = ((I_j − I_k) Σ_m w_j[m] w_k[n−m] + τ_i s[n]) / I_i, with
    s = (1 − cos(A + B u))/2 about t0 (A = 2 rate t0, B = 2 rate): s[0] = (1 − cos A)/2,
    s[n] = −Bⁿ cos(A + nπ/2) / (2 n!).  Steps of ``h`` s (the last one shortened to land on t_end),
    ``order`` terms each, summed by Horner; restarts where the drive switches on or off.
    ``omega0`` may be given in longdouble (e.g. SciML's exact 0.9).
    """
    ld = np.longdouble
    body = Body(*(float(v) for v in body)) if not isinstance(body, Body) else body
    if body.mgl or body.mgc1 or body.mgc2:
        raise ValueError("taylor_free_omega: the body has gravity; its ω depends on the orientation")
    inertia = np.array(body[:3], dtype=ld)
    coupling = np.array([body.I2 - body.I3, body.I3 - body.I1, body.I1 - body.I2], dtype=ld) / inertia
    torque = np.array([body.tau1, body.tau2, body.tau3], dtype=ld) / inertia
    n_terms = order + 1
    k = np.arange(n_terms).astype(ld)
    factorial = np.cumprod(np.concatenate(([ld(1)], k[1:])))
    w = np.array(omega0, dtype=ld)
    t = ld(0)
    for end in _pieces(body, float(t_end)):
        end = ld(end)
        driven = any(body[6:9]) and body.drive_on <= 0.5 * float(t + end) <= body.drive_off
        while t < end:
            step = min(ld(h), end - t)
            c = np.zeros((3, n_terms), dtype=ld)
            c[:, 0] = w
            s = np.zeros(n_terms, dtype=ld)
            if driven:
                a, b = 2 * ld(body.drive_rate) * t, 2 * ld(body.drive_rate)
                s = -(b**k) / factorial * np.cos(a + k * ld(np.pi) / 2) / 2
                s[0] = (1 - np.cos(a)) / 2
            for n in range(order):
                products = np.array(
                    [
                        np.dot(c[1, : n + 1], c[2, n::-1]),
                        np.dot(c[2, : n + 1], c[0, n::-1]),
                        np.dot(c[0, : n + 1], c[1, n::-1]),
                    ],
                    dtype=ld,
                )
                c[:, n + 1] = (coupling * products + torque * s[n]) / (n + 1)
            w = c[:, order].copy()
            for n in range(order - 1, -1, -1):
                w = w * step + c[:, n]
            t = t + step
    return w


def free_omega_reference(body, omega0, t_end, h=0.05):
    """(ω(t_end) (rad/s, float64 (3,)), its error estimate (rad/s), label) of a body without gravity:
    ``taylor_free_omega`` at steps h and h/2; the estimate is their largest difference plus the
    float64 rounding of ω (half an ulp of its largest component)."""
    w = taylor_free_omega(body, omega0, t_end, h)
    w2 = taylor_free_omega(body, omega0, t_end, h / 2)
    out = w.astype(float)
    err = float(np.max(np.abs(w - w2))) + 0.5 * float(np.spacing(np.max(np.abs(out))))
    return out, err, f"Taylor series (30 terms, longdouble, h = {h:g} s; its error ≤ {err:.1e} rad/s)"
