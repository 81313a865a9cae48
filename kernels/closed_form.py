"""Closed-form yardsticks: the heavy symmetric top's nutation, the free symmetric top.

Plain numpy/scipy, written independently of the numba kernels so that the tests
compare two derivations, not one code path with itself.

Heavy symmetric top (Goldstein §5.7).  With u = cos θ the motion obeys
u̇² = f(u) = (α − βu)(1 − u²) − (b − au)², α = 2(E − ½ I3 ω3²)/I1,
β = 2 M g l / I1, a = L3/I1, b = Lz/I1, and φ̇ = (b − au)/(1 − u²).
f is a cubic with leading coefficient β > 0 and f(±1) = −(b ∓ a)² ≤ 0, so
its roots are u1 ≤ u2 in [−1, 1] and u3 > 1; θ nutates between arccos u2
and arccos u1 with period T = 4 K(m) / √(β (u3 − u1)),
m = (u2 − u1)/(u3 − u1).
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.spatial.transform import Rotation
from scipy.special import ellipk


@dataclass(frozen=True)
class Nutation:
    """Nutation of a heavy symmetric top: θ range (rad), period (s), mean φ̇ (rad/s)."""

    theta_min: float
    theta_max: float
    period: float
    precession_rate: float


def scene_rotation(scene):
    """scipy Rotation of the scene's initial orientation (q0 = (a, b, c, d), scalar first)."""
    a, b, c, d = scene.q0
    return Rotation.from_quat([b, c, d, a])


def _axial(scene):
    """ValueError unless the centre of mass lies on e3 (mgc1 = mgc2 = 0) and nothing drives the body:
    these closed forms are the top's."""
    if any(float(v) != 0.0 for v in tuple(scene.body)[4:]):
        raise ValueError(
            f"body={tuple(scene.body)}: the closed form needs the centre of mass on e3 (mgc1 = mgc2 = 0) "
            "and no driving torque"
        )


def top_invariants(scene):
    """(E (J), Lz, L3 (kg m²/s)) of the scene's initial state, from rotation matrices."""
    I1, I2, I3, mgl = scene.body[:4]
    _axial(scene)
    w = np.asarray(scene.omega0, dtype=float)
    R = scene_rotation(scene).as_matrix()
    Iw = np.array([I1, I2, I3]) * w
    E = 0.5 * float(w @ Iw) + mgl * R[2, 2]
    Lz = float((R @ Iw)[2])
    return E, Lz, I3 * w[2]


def _cubic(scene):
    """Coefficients (α, β, a, b) of f(u) for the scene's initial state."""
    I1, I2, I3, mgl = scene.body[:4]
    _axial(scene)
    if I1 != I2:
        raise ValueError(f"body={scene.body}: the closed form needs a symmetric top (I1 = I2)")
    if not mgl > 0:
        raise ValueError(f"mgl={mgl}: the heavy-top closed form needs M g l > 0")
    _, Lz, L3 = top_invariants(scene)
    w1, w2, _ = scene.omega0
    # E − ½ I3 ω3² summed without the cancellation: α to full precision.
    u0 = scene_rotation(scene).as_matrix()[2, 2]
    alpha = (w1 * w1 + w2 * w2) + 2.0 * mgl * u0 / I1
    return alpha, 2.0 * mgl / I1, L3 / I1, Lz / I1


def _f(u, alpha, beta, a, b):
    return (alpha - beta * u) * (1.0 - u * u) - (b - a * u) ** 2


def _df(u, alpha, beta, a, b):
    return -beta * (1.0 - u * u) - 2.0 * u * (alpha - beta * u) + 2.0 * a * (b - a * u)


def _newton(u, coeffs, lo=-np.inf, hi=np.inf):
    """Polish a simple root of f; stops when the step no longer shrinks."""
    step = np.inf
    for _ in range(50):
        d = _df(u, *coeffs)
        if d == 0.0:
            break
        new_step = _f(u, *coeffs) / d
        if not abs(new_step) < step:
            break
        step = abs(new_step)
        u = min(max(u - new_step, lo), hi)
        if step <= 1e-17:
            break
    return u


def nutation_roots(scene):
    """(u1, u2, u3): roots of f(u) with −1 ≤ u1 ≤ u2 ≤ 1 < u3, polished to ~1e-15.

    A double root (steady precession) is returned as u1 = u2 = the local
    maximum of f in [−1, 1] when f there is zero to rounding.
    """
    alpha, beta, a, b = coeffs = _cubic(scene)
    # f(u) = β u³ − (α + a²) u² + (2ab − β) u + (α − b²)
    poly = np.array([beta, -(alpha + a * a), 2.0 * a * b - beta, alpha - b * b])
    # The local maximum of f lies in [−1, 1]: f' = 3β u² − 2(α + a²) u + (2ab − β).
    crit = np.roots(np.polyder(poly))
    crit = np.sort(crit[np.isreal(crit)].real)
    u3 = _newton(max(np.roots(poly).real.max(), 1.0), coeffs, lo=1.0)
    if crit.size == 2 and -1.0 <= crit[0] <= 1.0:
        u_c = crit[0]
        # Polish the critical point with Newton on f'.
        for _ in range(5):
            d2 = 6.0 * beta * u_c - 2.0 * (alpha + a * a)
            u_c -= _df(u_c, *coeffs) / d2
        fc = _f(u_c, *coeffs)
        # Rounding error of f(u_c): below it, the two roots are one double root.
        rounding = (
            16
            * np.finfo(float).eps
            * ((abs(alpha) + beta * abs(u_c)) * (1.0 - u_c * u_c) + 2.0 * abs(b - a * u_c) * (abs(b) + abs(a * u_c)))
        )
        if fc <= rounding:
            return u_c, u_c, u3
        u1 = _newton(_bisect(coeffs, -1.0, u_c), coeffs, -1.0, u_c)
        u2 = _newton(_bisect(coeffs, u_c, 1.0), coeffs, u_c, 1.0)
        return u1, u2, u3
    raise ValueError(f"no nutation interval in [-1, 1] for body={scene.body}, omega0={scene.omega0}")


def _bisect(coeffs, lo, hi):
    """A root of f between lo and hi, where f changes sign (or touches 0 at an end)."""
    flo = _f(lo, *coeffs)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        fm = _f(mid, *coeffs)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
        if hi - lo <= 1e-16:
            break
    return 0.5 * (lo + hi)


def heavy_top_nutation(scene):
    """Nutation of a heavy symmetric top from its initial state (docs/design.md, "The scheme and its rivals").

    theta_min, theta_max (rad): the turning points of θ; period (s): time from
    one θ minimum to the next; precession_rate (rad/s): the azimuth gained per
    nutation period divided by the period, i.e. the long-run mean φ̇.

    A top that starts on the vertical (u0 = cos θ0 = ±1) spinning about its axis alone stays there: θ_min =
    θ_max = θ0 and the precession rate is NaN (no azimuth on the vertical).  There α = β u0, b = a u0 and
    f(u) = (u − u0)² (β (u0 + u) − a²): small tilts nutate with the period 2π / √(a² − 2β u0) where that is
    real (always hanging; standing up, Maxwell's criterion I3² ω3² > 4 I1 M g l of the sleeping top), and
    the period is NaN where the vertical is unstable (the cubic's motion away from it is the Euler angles'
    singularity, not the top's).
    """
    alpha, beta, a, b = _cubic(scene)
    u0 = float(scene_rotation(scene).as_matrix()[2, 2])
    if abs(u0) == 1.0 and b == a * u0:
        theta0 = 0.0 if u0 > 0 else math.pi
        rate2 = a * a - 2.0 * beta * u0  # the squared angular frequency of small nutations about the vertical
        period = 2.0 * math.pi / math.sqrt(rate2) if rate2 > 0 else math.nan
        return Nutation(theta_min=theta0, theta_max=theta0, period=period, precession_rate=math.nan)
    u1, u2, u3 = nutation_roots(scene)
    m = (u2 - u1) / (u3 - u1)
    period = 4.0 * ellipk(m) / math.sqrt(beta * (u3 - u1))

    # u = u1 + (u2 − u1) sin² s turns du/√f into 2 ds / √(β (u3 − u)): smooth on [0, π/2].
    def phidot_weight(s):
        u = u1 + (u2 - u1) * math.sin(s) ** 2
        lz_off = b - a * u  # 0 at every u for a top without spin (a = b = 0): φ̇ = 0, also where u rounds to ±1
        return 0.0 if lz_off == 0.0 else lz_off / (1.0 - u * u) * 2.0 / math.sqrt(beta * (u3 - u))

    # full_output: near u = 1 rounding in b − au caps the accuracy (quad would warn).
    half = quad(phidot_weight, 0.0, 0.5 * math.pi, epsabs=0.0, epsrel=1e-13, limit=200, full_output=1)[0]
    dphi = 2.0 * half
    return Nutation(
        theta_min=math.acos(min(u2, 1.0)),
        theta_max=math.acos(max(u1, -1.0)),
        period=period,
        precession_rate=dphi / period,
    )


def free_symmetric_solution(scene, times):
    """Exact torque-free motion of a symmetric body (I1 = I2).

    Returns (axis (n, 3): R(t) e3 in the lab frame, omega (n, 3): body rates
    in rad/s) at ``times`` (s).  The lab angular momentum L is fixed; in the
    body, L_b turns by −c t about e3 with c = (1/I3 − 1/I1) L3, and
    R(t) = R0 · Rot(L_b0 t / I1) · Rot(e3 c t).
    """
    I1, I2, I3, mgl = scene.body[:4]
    _axial(scene)
    if I1 != I2 or mgl != 0.0:
        raise ValueError(f"body={scene.body}: needs a free symmetric body (I1 = I2, M g l = 0)")
    t = np.asarray(times, dtype=float).reshape(-1)
    w0 = np.asarray(scene.omega0, dtype=float)
    Lb0 = np.array([I1, I2, I3]) * w0
    c = (1.0 / I3 - 1.0 / I1) * Lb0[2]
    e3 = np.array([0.0, 0.0, 1.0])
    R = scene_rotation(scene) * Rotation.from_rotvec(np.outer(t, Lb0 / I1)) * Rotation.from_rotvec(np.outer(c * t, e3))
    axis = R.as_matrix()[:, :, 2]
    ct, st = np.cos(c * t), np.sin(c * t)
    omega = np.column_stack([ct * w0[0] + st * w0[1], -st * w0[0] + ct * w0[1], np.full_like(t, w0[2])])
    return axis, omega
