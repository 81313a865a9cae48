"""The conserved quantities: what scenes declare, what methods claim to preserve, how a file gives them.

A scene's ``CONSERVED`` and a method's ``PRESERVES`` are tuples of the names of
``INVARIANTS``.  Each invariant is one declaration: what it is, its symbol and
unit for figures and tables, and either a stored per-sample variable of the
same name (the results layout, gyrolab/results/layout.py) or a formula over
stored variables (``needs`` and ``derive``).

Adding a derived invariant (recipe, also in docs/design.md): one entry here
with ``needs`` (the stored variables or run inputs it reads) and ``derive``
(a function of the opened Dataset, numpy/xarray only, returning one value per
sample), then name it in the scenes' ``CONSERVED`` that keep it.  Figures,
verdicts and tables find it by name; a file that lacks one of ``needs`` has no
such invariant (``has_invariant``), and the figures say so.

Pure Python: numba compiles nothing here (kernels/__init__.py NOT_COMPILED).
"""

from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Invariant:
    """A conserved quantity: ``description`` (with its formula), ``label`` (symbol in figures), ``units``;
    ``derive(ds)`` and the variables it ``needs`` when it is not stored itself under its name."""

    description: str
    label: str
    units: str
    needs: tuple = ()
    derive: Callable = None


def kovalevskaya_integral(omega, gamma, body):
    """K = (ω1² − ω2² − ν γ1)² + (2 ω1 ω2 − ν γ2)² (rad⁴ s⁻⁴), ν = M g c1 / I3.

    Conserved by the exact motion of Kovalevskaya's top: I1 = I2 = 2 I3 about
    the pivot, centre of mass on body e1 (c = (c1, 0, 0)); γ = Rᵀ ẑ the lab
    vertical in body coordinates.  ``omega``/``gamma``: DataArrays with an
    ``xyz`` dim; ``body``: the stored body (dim ``body_param``).  The sign of ν
    follows from V = M g c·γ (checked by tests/test_heavy_body.py).
    """
    nu = body.sel(body_param="mgc1") / body.sel(body_param="I3")
    w1, w2 = omega.sel(xyz="x"), omega.sel(xyz="y")
    g1, g2 = gamma.sel(xyz="x"), gamma.sel(xyz="y")
    return (w1 * w1 - w2 * w2 - nu * g1) ** 2 + (2.0 * w1 * w2 - nu * g2) ** 2


INVARIANTS = {
    "energy": Invariant("total energy E = 1/2 w.Iw + M g c.gamma (J); M g l cos(theta) for c = l e3", "E", "J"),
    "L": Invariant("angular momentum about the pivot in the lab frame, R I w (kg m2/s, vector)", "L", "kg m2 s-1"),
    "L_norm": Invariant(
        "magnitude |L| = |I w| of the angular momentum (kg m2/s)",
        "|L|",
        "kg m2 s-1",
        needs=("L",),
        # skipna=False: a diverged run's NaN samples stay NaN (xarray's default sum would read them as |L| = 0)
        derive=lambda ds: np.sqrt((ds["L"] ** 2).sum("xyz", skipna=False)),
    ),
    "Lz": Invariant("lab vertical angular momentum (R I w).z (kg m2/s)", "L_z", "kg m2 s-1"),
    "L3": Invariant("angular momentum along the symmetry axis, I3 w3 (kg m2/s)", "L_3", "kg m2 s-1"),
    "kovalevskaya": Invariant(
        "Kovalevskaya's quartic integral (w1^2 - w2^2 - nu g1)^2 + (2 w1 w2 - nu g2)^2, nu = M g c1 / I3",
        "K",
        "rad4 s-4",
        needs=("omega", "gamma", "body"),
        derive=lambda ds: kovalevskaya_integral(ds["omega"], ds["gamma"], ds["body"]),
    ),
}


def check_names(names, owner):
    """ValueError naming the first entry of ``names`` that is not an invariant."""
    for name in names:
        if name not in INVARIANTS:
            raise ValueError(f"{owner}: {name!r} is not an invariant; choose from {', '.join(INVARIANTS)}")


def needed_variables(name):
    """The variables of a results file that invariant ``name`` is read from (itself when stored)."""
    declared = INVARIANTS.get(name)
    return declared.needs if declared is not None and declared.needs else (name,)


def has_invariant(ds, name):
    """True when ``invariant(ds, name)`` can be computed from what the Dataset ``ds`` holds."""
    return all(v in ds.data_vars for v in needed_variables(name))


def invariant(ds, name):
    """Invariant ``name`` per sample of the results Dataset ``ds`` (a stored variable or its formula)."""
    declared = INVARIANTS.get(name)
    return declared.derive(ds) if declared is not None and declared.derive is not None else ds[name]
