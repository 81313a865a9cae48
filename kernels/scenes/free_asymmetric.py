"""free_asymmetric: a torque-free box spun near its intermediate axis (tennis racket).

Principal moments I1 < I3 < I2 by default, so e3, the spin axis set by f, is
the intermediate axis: the spin is unstable and the body flips by 180°
periodically (Dzhanibekov effect).  Initial body rate ω = (eps ω3, 0, ω3)
with ω3 = 2πf; the flips come every ~ ln(1/eps) / (ω3 √(...)) seconds.
This is where methods fail differently: the flip times are exponentially
sensitive to errors.
"""

from ..body import Body
from .common import Scene, check_positive, check_triangle, tilt_quaternion

OPTIONS = {"I1": 1.0e-4, "I2": 3.0e-4, "I3": 2.0e-4, "eps": 1.0e-3}
CONSERVED = ("energy", "L", "L_norm", "Lz")
CLOSED_FORM = "euler_poinsot"


def build(f, theta0, I1, I2, I3, eps):
    check_positive({"I1": I1, "I2": I2, "I3": I3})
    check_triangle(I1, I2, I3)
    omega3 = 2.0 * 3.141592653589793 * f
    return Scene("free_asymmetric", Body(I1, I2, I3, 0.0), (eps * omega3, 0.0, omega3), tilt_quaternion(theta0))
