"""Independent reference solution: scipy's DOP853 on (ω, R) with rotation matrices.

A different formulation from every registered method (no quaternions, no
splitting, adaptive 8th-order steps): state y = (ω body (3), R row-major (9)),
I ω̇ = τ_b − ω × Iω, Ṙ = R [ω]×, τ_b = γ × (M g c) + τ_d(t), γ = Rᵀ ẑ (the
body's (mgl, mgc1, mgc2) = M g (c3, c1, c2); c = l e3 is the symmetric heavy
top; τ_d the driving torque of kernels/body.py, zero for every scene but
forced_body).  Where the drive switches on or off, the integration restarts,
so no adaptive step straddles the kink in τ_d's second derivative.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from .body import N_FIELDS as N_BODY
from .body import Body
from .closed_form import scene_rotation
from .driver import N_FIELDS


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
    """Samples (n, driver.N_FIELDS) in driver.FIELDS order from ω (n, 3) and R (n, 3, 3)."""
    I = np.asarray(body[:3], dtype=float)
    body = tuple(body) + (0.0,) * (N_BODY - len(body))
    weight_moment = np.array([body[4], body[5], body[3]])  # M g c in body coordinates
    Iw = omega * I
    L = np.einsum("nij,nj->ni", R, Iw)
    out = np.empty((omega.shape[0], N_FIELDS))
    out[:, 0:3] = R[:, :, 2]
    out[:, 3:6] = omega
    out[:, 6] = 0.5 * np.sum(omega * Iw, axis=1) + R[:, 2, :] @ weight_moment
    out[:, 7:10] = L
    out[:, 10] = Iw[:, 2]
    out[:, 11:14] = R[:, 2, :]
    return out


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
