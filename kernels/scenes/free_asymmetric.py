"""free_asymmetric: a torque-free box spun near its intermediate axis (tennis racket).

Principal moments I1 < I3 < I2 by default, so e3, the spin axis set by f, is
the intermediate axis: the spin is unstable and the body flips by 180°
periodically (Dzhanibekov effect).  Initial body rate ω = (eps ω3, 0, ω3)
with ω3 = 2πf; the flips come every ~ ln(1/eps) / (ω3 √(...)) seconds.
This is where methods fail differently: the flip times are exponentially
sensitive to errors.  Its exact solution is the Euler–Poinsot flow
(kernels/euler_poinsot.py, ``gyrolab.free_body``).

The moments of a real body obey the triangle inequality, and the scene checks
it.  Published test bodies do not always (Principia's I = (3, 5, 9),
Hairer–Lubich–Wanner's I = (2, 1, 2/3)): ``allow_unphysical: true`` runs them,
an explicit opt-in that is stored with the other scene options in the results
file.
"""

from ..body import Body
from .common import Scene, check_positive, check_triangle, tilt_quaternion

OPTIONS = {"I1": 1.0e-4, "I2": 3.0e-4, "I3": 2.0e-4, "eps": 1.0e-3, "allow_unphysical": False}
CONSERVED = ("energy", "L", "L_norm", "Lz")
CLOSED_FORM = "euler_poinsot"


def build(f, theta0, I1, I2, I3, eps, allow_unphysical):
    check_positive({"I1": I1, "I2": I2, "I3": I3})
    if not allow_unphysical:
        check_triangle(I1, I2, I3)
    omega3 = 2.0 * 3.141592653589793 * f
    return Scene("free_asymmetric", Body(I1, I2, I3, 0.0), (eps * omega3, 0.0, omega3), tilt_quaternion(theta0))
