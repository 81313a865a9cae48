"""heavy_body: a rigid body on a fixed pivot with its centre of mass anywhere (the asymmetric heavy top).

Body (SI): principal moments ``I1, I2, I3`` about the pivot (kg m², body
axes e1, e2, e3), mass ``M``, gravity ``g`` and the centre of mass ``com`` =
[c1, c2, c3] in body coordinates (m); the kernels get M g c (kernels/body.py)
and the torque γ × M g c.  com = [0, 0, l] with I1 = I2 is the symmetric top
of ``heavy_top``; anything else is in general chaotic (the Euler, Lagrange and
Kovalevskaya cases are the integrable exceptions).

Initial state: body rates (``omega1``, ``omega2``, 2πf) in rad/s and the
tilt θ0 of e3 from the vertical (φ0 = ψ0 = 0, as every scene).  The exact
motion keeps E and L_z (gravity exerts no torque about the vertical through
the pivot); L3 only when the body is symmetric about e3 with com on e3.

The moments must belong to a body of mass M with that centre of mass (the
moments about the centre of mass, by the parallel-axis theorem, positive and
obeying the triangle inequality); ``allow_unphysical: true`` runs published
normalised bodies that do not.
"""

from ..body import Body
from .common import Scene, check_pivot_inertia, check_positive, check_vector, tilt_quaternion

OPTIONS = {
    "I1": 0.02,
    "I2": 0.025,
    "I3": 0.008,
    "com": [0.03, 0.01, 0.1],
    "M": 1.0,
    "g": 9.81,
    "omega1": 0.0,
    "omega2": 0.0,
    "allow_unphysical": False,
}
CONSERVED = ("energy", "Lz")
CLOSED_FORM = None


def weight_body(I1, I2, I3, M, g, com):
    """Body (kernels/body.py) of principal moments I (kg m²) and weight M g (N) at ``com`` (m, body)."""
    c1, c2, c3 = com
    return Body(I1, I2, I3, M * g * c3, M * g * c1, M * g * c2)


def build(f, theta0, I1, I2, I3, com, M, g, omega1, omega2, allow_unphysical):
    check_positive({"I1": I1, "I2": I2, "I3": I3, "M": M, "g": g})
    com = check_vector("com", com)
    if not allow_unphysical:
        check_pivot_inertia(I1, I2, I3, M, com)
    omega0 = (float(omega1), float(omega2), 2.0 * 3.141592653589793 * f)
    return Scene("heavy_body", weight_body(I1, I2, I3, M, g, com), omega0, tilt_quaternion(theta0))
