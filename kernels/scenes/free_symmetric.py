"""free_symmetric: a torque-free thin disc, the correctness yardstick.

Body: disc of mass M and radius r about its centre, I1 = I2 = M r²/4,
I3 = M r²/2; no gravity.  Initial state: spin ω3 = 2πf plus a transverse
body rate ω2 = wobble · ω3, so L is off the symmetry axis and the axis
precesses about L with the closed-form rate |L|/I1 (kernels/closed_form.py).
"""

from ..body import Body
from .common import Scene, check_positive, tilt_quaternion

OPTIONS = {"M": 1.0, "r": 0.05, "wobble": 0.1}
CONSERVED = ("energy", "L", "L_norm", "Lz", "L3")
CLOSED_FORM = "free_symmetric"


def build(f, theta0, M, r, wobble):
    check_positive({"M": M, "r": r})
    I1 = M * r * r / 4.0
    omega3 = 2.0 * 3.141592653589793 * f
    return Scene("free_symmetric", Body(I1, I1, 2.0 * I1, 0.0), (0.0, wobble * omega3, omega3), tilt_quaternion(theta0))
