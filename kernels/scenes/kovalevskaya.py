"""kovalevskaya: Kovalevskaya's top, I1 = I2 = 2 I3 about the pivot and the centre of mass on body e1.

The third integrable heavy top (after Euler's and Lagrange's; Kovalevskaya
1889): besides E and L_z it keeps the quartic integral
K = (ω1² − ω2² − ν γ1)² + (2 ω1 ω2 − ν γ2)², ν = M g c / I3, with γ = Rᵀ ẑ
(gyrolab/results/layout.py ``kovalevskaya_integral``, from the stored ω, γ and body).
A scheme that keeps E and L_z can still drift in K, so K judges it on a
fourth, non-trivial invariant.

Body (SI): ``I3`` (kg m²) sets I1 = I2 = 2 I3; mass ``M``, gravity ``g``,
the centre of mass at ``c`` e1 (m).  Such a body is a real one only when
M c² ≤ I3 / 2 (the moments about the centre of mass obey the triangle
inequality); ``allow_unphysical: true`` runs the normalised textbook body
(I3 = 1, M g c = 1) when c is chosen so.  Initial state: body rates
(``omega1``, ``omega2``, 2πf) (rad/s) and the tilt θ0 of e3, as heavy_body.
"""

from .common import Scene, check_pivot_inertia, check_positive, tilt_quaternion
from .heavy_body import weight_body

OPTIONS = {"I3": 0.01, "c": 0.05, "M": 1.0, "g": 9.81, "omega1": 0.0, "omega2": 0.0, "allow_unphysical": False}
CONSERVED = ("energy", "Lz", "kovalevskaya")
CLOSED_FORM = None


def build(f, theta0, I3, c, M, g, omega1, omega2, allow_unphysical):
    check_positive({"I3": I3, "c": c, "M": M, "g": g})
    com = (c, 0.0, 0.0)
    if not allow_unphysical:
        check_pivot_inertia(2.0 * I3, 2.0 * I3, I3, M, com)
    omega0 = (float(omega1), float(omega2), 2.0 * 3.141592653589793 * f)
    body = weight_body(2.0 * I3, 2.0 * I3, I3, M, g, com)
    return Scene("kovalevskaya", body, omega0, tilt_quaternion(theta0))
