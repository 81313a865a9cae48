"""The exact yardstick of a stored run, from what its scene declares (layout.closed_form).

- ``heavy_top_nutation``: the heavy symmetric top's θ_min, θ_max, nutation
  period and mean precession rate (kernels/closed_form.heavy_top_nutation);
  no trajectory, only bounds.
- ``free_symmetric``: the torque-free symmetric body's exact axis
  (kernels/closed_form.free_symmetric_solution); characteristic period: one
  precession turn of the axis about L, 2π I1 / |L|.
- ``euler_poinsot``: the exact free rigid body of any inertia (gyrolab.free_body,
  Jacobi elliptic functions); characteristic period: the closed-form time
  between two flips, 2 K(m) / λ (kernels/euler_poinsot.flip_period).

Every function returns None when the file's scene declares no such closed
form, so a figure never draws a yardstick the scene does not have.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..io import build_run_scene


@dataclass(frozen=True)
class Period:
    """A characteristic time of the exact motion: ``seconds`` (s) and what it is (``label``)."""

    seconds: float
    label: str


def kind(ds):
    """The file's closed form name (layout.closed_form), or None."""
    from ...results.layout import closed_form

    return closed_form(ds)


def nutation(ds, f, theta0):
    """Closed-form Nutation (kernels/closed_form.py) of grid point (f Hz, θ0 deg), or None."""
    if kind(ds) != "heavy_top_nutation":
        return None
    from ...kernels.closed_form import heavy_top_nutation

    try:
        return heavy_top_nutation(build_run_scene(ds, f, theta0))
    except ValueError:
        return None


def axis_from_quaternion(q):
    """Lab symmetry axis R(q) e3 (n, 3) of quaternions q (n, 4), scalar first, body -> lab."""
    a, b, c, d = (q[..., k] for k in range(4))
    return np.stack((2 * (b * d + a * c), 2 * (c * d - a * b), a * a - b * b - c * c + d * d), axis=-1)


def exact_motion(ds, f, theta0, times):
    """(axis (n, 3) lab, omega (n, 3) body rad/s) of the exact motion at ``times`` (s), or None when the
    scene's closed form gives no trajectory (heavy top: bounds only)."""
    name = kind(ds)
    times = np.asarray(times, dtype=float)
    if name == "free_symmetric":
        from ...kernels.closed_form import free_symmetric_solution

        try:
            return free_symmetric_solution(build_run_scene(ds, f, theta0), times)
        except ValueError:
            return None
    if name == "euler_poinsot":
        from ...kernels.euler_poinsot import free_body

        scene = build_run_scene(ds, f, theta0)
        omega, q = free_body(np.asarray(scene.body[:3]), np.asarray(scene.omega0), np.asarray(scene.q0), times)
        return axis_from_quaternion(q), omega
    return None


def exact_axis(ds, f, theta0, times):
    """The exact lab axis (n, 3) at ``times`` (s), or None (see exact_motion)."""
    motion = exact_motion(ds, f, theta0, times)
    return None if motion is None else motion[0]


def flip_period(ds, f, theta0):
    """Closed-form time between flips (s) of the free asymmetric body, or None (other scenes)."""
    if kind(ds) != "euler_poinsot":
        return None
    from ...kernels.euler_poinsot import flip_period as period

    scene = build_run_scene(ds, f, theta0)
    value = float(period(np.asarray(scene.body[:3]), np.asarray(scene.omega0)))
    return value if math.isfinite(value) else None


def flip_times(ds, f, theta0, times):
    """Times (s) within ``times`` where the exact motion flips: the exact ω component along the
    intermediate axis' partner that starts largest (the spin axis) changes sign; [] when no flip."""
    motion = exact_motion(ds, f, theta0, times)
    if motion is None or kind(ds) != "euler_poinsot":
        return []
    omega = motion[1]
    spin = int(np.argmax(np.abs(omega[0])))
    w = omega[:, spin]
    crossing = np.flatnonzero(np.sign(w[1:]) != np.sign(w[:-1]))
    t = np.asarray(times, dtype=float)
    # linear interpolation between the samples around each sign change
    return [float(t[i] - w[i] * (t[i + 1] - t[i]) / (w[i + 1] - w[i])) for i in crossing]


def period(ds, f, theta0):
    """The characteristic Period of grid point (f, θ0) under the scene's closed form, or None."""
    name = kind(ds)
    if name == "heavy_top_nutation":
        nut = nutation(ds, f, theta0)
        return None if nut is None or not nut.period > 0 else Period(nut.period, "nutation period")
    if name == "free_symmetric":
        scene = build_run_scene(ds, f, theta0)
        I1 = scene.body[0]
        L = np.linalg.norm(np.asarray(scene.body[:3]) * np.asarray(scene.omega0))
        return Period(2 * math.pi * I1 / L, "precession period 2π I1/|L|") if L > 0 else None
    if name == "euler_poinsot":
        value = flip_period(ds, f, theta0)
        return None if value is None else Period(value, "flip period 2K(m)/λ")
    return None


def label(ds):
    """What the yardstick is, for legends: e.g. 'exact (Euler–Poinsot flow)'; None without one."""
    return {
        "heavy_top_nutation": "closed-form θ_min, θ_max",
        "free_symmetric": "exact (free symmetric top)",
        "euler_poinsot": "exact (Euler–Poinsot flow)",
    }.get(kind(ds))
