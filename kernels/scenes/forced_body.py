"""forced_body: a free rigid body driven by a body-fixed torque that depends on time (Hairer–Nørsett–Wanner's EULR).

Euler's equations with a body-frame torque τ(t) = ``torque`` sin²(``drive_rate`` t)
(N m, rad/s) while t lies in ``window`` = [t_on, t_off] (s), zero outside;
principal moments ``I1, I2, I3`` (kg m²) about the centre of mass; no gravity.
The defaults are the EULR problem of Hairer, Nørsett & Wanner (Solving ODEs I,
2nd ed., Springer 1993, Sect. II.10, p. 244): ω̇1 = −2 ω2 ω3,
ω̇2 = 1.25 ω3 ω1, ω̇3 = −0.5 ω1 ω2 + k(t), k(t) = 0.25 sin² t on [3π, 4π],
ω(0) = (1, 0, 0.9), t ∈ [0, 20] — the body I = (0.5, 2, 3) (I1 ω̇1 =
(I2 − I3) ω2 ω3 gives −2, and so on) with τ3 = I3 k(t) = 0.75 sin² t N m.
SciMLBenchmarks' rigid body (NonStiffODE/RigidBody_wpd) applies k(t) on all
of [0, 10]: ``window: [0, 10]`` (``experiment=sciml_rigid_body``).

Initial state: body rates (``omega1``, ``omega2``, 2πf) rad/s (EULR's
ω3 = 0.9 rad/s is f = 0.9/(2π) Hz) and the tilt θ0 of e3 (the orientation
only turns the output axis: nothing here depends on it).  The torque does
work and turns L, so nothing is conserved while it acts (CONSERVED is empty);
only methods that see time integrate the scene (``step_driven``,
kernels/methods/README.md), the others are refused before any run.  The
runner's divergence check compares |E − E0| with ``runner.divergence_threshold``
× (T0 + the most kinetic energy the drive can give, (|L0| + |τ| (t_off − t_on))²/(2 I_min):
kernels/rigid_body.py divergence_scale), so a run is stopped for energy no
drive could have put in, never for what the drive did (the SciML problem takes E
from 1.47 J to 6.5 J; a body at rest spun up by the drive starts at T0 = 0).

I = (0.5, 2, 3) violates the triangle inequality (0.5 + 2 < 3): no rigid body
has it, and the published problem uses it anyway, so ``allow_unphysical``
defaults to true here.
"""

import math

from ..body import Body
from .common import Scene, check_positive, check_triangle, check_vector, tilt_quaternion

OPTIONS = {
    "I1": 0.5,
    "I2": 2.0,
    "I3": 3.0,
    "omega1": 1.0,
    "omega2": 0.0,
    "torque": [0.0, 0.0, 0.75],
    "drive_rate": 1.0,
    "window": [3.0 * math.pi, 4.0 * math.pi],
    "allow_unphysical": True,
}
CONSERVED = ()
CLOSED_FORM = None


def check_window(window):
    """[t_on, t_off] (s), 0 <= t_on <= t_off, as a tuple; ValueError otherwise."""
    try:
        on, off = (float(v) for v in window)
    except (TypeError, ValueError):
        raise ValueError(f"scene.window={window}: must be a list of two times [t_on, t_off] in s") from None
    if not (math.isfinite(on) and math.isfinite(off) and 0.0 <= on <= off):
        raise ValueError(f"scene.window={[on, off]}: need 0 <= t_on <= t_off, finite (s)")
    return on, off


def build(f, theta0, I1, I2, I3, omega1, omega2, torque, drive_rate, window, allow_unphysical):
    check_positive({"I1": I1, "I2": I2, "I3": I3})
    if not allow_unphysical:
        check_triangle(I1, I2, I3)
    tau = check_vector("torque", torque)
    on, off = check_window(window)
    body = Body(I1, I2, I3, 0.0, 0.0, 0.0, tau[0], tau[1], tau[2], float(drive_rate), on, off)
    omega0 = (float(omega1), float(omega2), 2.0 * math.pi * f)
    return Scene("forced_body", body, omega0, tilt_quaternion(theta0))
