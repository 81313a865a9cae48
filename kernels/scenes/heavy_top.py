"""heavy_top: the write-up's top, a thin disc on an arm, pivot fixed at the origin.

Body (SI): mass M, disc radius r, arm l from pivot to the disc's centre, gravity
g.  Inertia about the pivot: I1 = I2 = M (r²/4 + l²), I3 = M r²/2; the kernel
gets M g l for the torque.  Initial states (docs/design.md, "Scenes"), all with body spin
ω3 = 2πf and θ̇0 = 0 at φ0 = ψ0 = 0:

- release: ω = (0, 0, 2πf): the tip starts at rest and traces cusps;
- precession: a given precession rate ``phidot0`` (rad/s): loops or waves;
- steady_slow / steady_fast: φ̇0 on the slow or fast root of
  M g l = φ̇ (I3 ω3 − I1 φ̇ cos θ0) (Goldstein 5.77), so θ stays at θ0;
- sleeping: release at θ0 = 0 (upright).
"""

import math

from ..body import Body
from .common import Scene, body_rates, check_positive, tilt_quaternion

OPTIONS = {"M": 1.0, "r": 0.05, "l": 0.1, "g": 10.0, "init": "release", "phidot0": 0.0}
CONSERVED = ("energy", "Lz", "L3")
CLOSED_FORM = "heavy_top_nutation"
INITS = ("release", "precession", "steady_slow", "steady_fast", "sleeping")


def inertia(M, r, l):
    """(I1, I2, I3) about the pivot (kg m²) of a thin disc of radius r at distance l."""
    I1 = M * (r * r / 4.0 + l * l)
    return I1, I1, M * r * r / 2.0


def steady_precession_rates(I1, I3, mgl, omega3, theta0):
    """(slow, fast) roots φ̇ (rad/s) of M g l = φ̇ (I3 ω3 − I1 φ̇ cos θ0).

    ValueError when the roots are complex (I3² ω3² < 4 I1 M g l cos θ0),
    naming the smallest spin f that would do.
    """
    a = I1 * math.cos(theta0)
    L3 = I3 * omega3
    if abs(a) < 1e-15 * I1:  # θ0 = 90°: the equation is linear, one root
        rate = mgl / L3
        return rate, rate
    disc = L3 * L3 - 4.0 * a * mgl
    if disc < 0.0:
        f_min = math.sqrt(4.0 * a * mgl) / I3 / (2.0 * math.pi)
        raise ValueError(
            f"f={omega3 / (2 * math.pi):g}: steady precession at theta0={math.degrees(theta0):g} deg "
            f"has complex roots (I3^2 w3^2 < 4 I1 M g l cos theta0); it needs f >= {f_min:.2f} Hz"
        )
    root = math.sqrt(disc)
    # Written to avoid cancellation in the slow root.
    slow = 2.0 * mgl / (L3 + root)
    fast = (L3 + root) / (2.0 * a)
    return slow, fast


def build(f, theta0, M, r, l, g, init, phidot0):
    check_positive({"M": M, "r": r, "l": l, "g": g})
    if init not in INITS:
        raise ValueError(f"scene.init={init!r}: choose from {', '.join(INITS)}")
    I1, I2, I3 = inertia(M, r, l)
    mgl = M * g * l
    theta = math.radians(theta0)
    omega3 = 2.0 * math.pi * f
    if init == "release":
        phidot = 0.0
    elif init == "sleeping":
        if theta0 != 0.0:
            raise ValueError(f"theta0={theta0}: a sleeping top starts upright, theta0 must be 0")
        phidot = 0.0
    elif init == "precession":
        phidot = phidot0
    else:
        if omega3 == 0.0:
            raise ValueError("f=0: steady precession needs a spinning top (f > 0)")
        slow, fast = steady_precession_rates(I1, I3, mgl, omega3, theta)
        phidot = slow if init == "steady_slow" else fast
    # ψ̇ is fixed by ω3 = φ̇ cos θ + ψ̇ = 2πf.
    psidot = omega3 - phidot * math.cos(theta)
    omega0 = body_rates(phidot, 0.0, psidot, theta)
    return Scene("heavy_top", Body(I1, I2, I3, mgl), omega0, tilt_quaternion(theta0))
