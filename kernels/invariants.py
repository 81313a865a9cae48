"""The names of the conserved quantities that scenes declare and methods claim to preserve.

A scene's ``CONSERVED`` and a method's ``PRESERVES`` are tuples of these
names; the results layout (gyrolab/layout.py) stores or derives each of them
per sample, so figures and verdicts read them by name.
"""

INVARIANTS = {
    "energy": "total energy E = 1/2 w.Iw + M g c.gamma (J); M g l cos(theta) for c = l e3",
    "L": "angular momentum about the pivot in the lab frame, R I w (kg m2/s, vector)",
    "L_norm": "magnitude |L| = |I w| of the angular momentum (kg m2/s)",
    "Lz": "lab vertical angular momentum (R I w).z (kg m2/s)",
    "L3": "angular momentum along the symmetry axis, I3 w3 (kg m2/s)",
    "kovalevskaya": "Kovalevskaya's quartic integral (w1^2 - w2^2 - nu g1)^2 + (2 w1 w2 - nu g2)^2, nu = M g c1 / I3",
}


def check_names(names, owner):
    """ValueError naming the first entry of ``names`` that is not an invariant."""
    for name in names:
        if name not in INVARIANTS:
            raise ValueError(f"{owner}: {name!r} is not an invariant; choose from {', '.join(INVARIANTS)}")
