"""Pieces every scene uses: the Scene record and the initial tilt."""

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scene:
    """A body and its initial state.

    body: a kernels.body.Body (its fields and units in kernels/body.py), moments
    about the pivot (about the centre of mass for a free body); omega0: body angular
    velocity (rad/s); q0: orientation quaternion (a, b, c, d), R(q0) maps body
    to lab coordinates.
    """

    name: str
    body: tuple
    omega0: tuple
    q0: tuple


def tilt_quaternion(theta0_deg):
    """q0 for R0 = Rx(θ0): Goldstein z-x-z angles with φ0 = ψ0 = 0.

    The axis tip R0 e3 starts at (0, −sin θ0, cos θ0).
    """
    h = 0.5 * math.radians(theta0_deg)
    return (math.cos(h), math.sin(h), 0.0, 0.0)


def body_rates(phidot, thetadot, psidot, theta):
    """Body angular velocity from Euler-angle rates at ψ = 0 (Goldstein 4.125), rad/s."""
    return (thetadot, phidot * math.sin(theta), phidot * math.cos(theta) + psidot)


def check_finite(values):
    """ValueError naming the first option that is NaN or ±inf."""
    for key, value in values.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool) and not np.isfinite(value):
            raise ValueError(f"{key}={value}: must be a finite number")


def check_positive(values):
    """ValueError naming the first option that is not > 0."""
    for key, value in values.items():
        if not value > 0:
            raise ValueError(f"scene.{key}={value}: must be > 0")


def check_triangle(I1, I2, I3):
    """Principal moments of a real body obey I_i + I_j >= I_k."""
    for (a, b, c), name in (((I1, I2, I3), "I3"), ((I2, I3, I1), "I1"), ((I3, I1, I2), "I2")):
        if a + b < c:
            raise ValueError(
                f"scene.{name}={c}: violates the triangle inequality of principal moments "
                f"({a} + {b} < {c}); no rigid body has these moments (scene.allow_unphysical=true runs them anyway)"
            )


def check_pivot_inertia(I1, I2, I3, M, com):
    """Principal moments about a pivot that some rigid body of mass M (kg) with its centre of mass
    at ``com`` (m, body coordinates) can have: the inertia about the centre of mass,
    diag(I) − M (|c|² 1 − c cᵀ) (parallel-axis theorem), must be a real body's (positive
    eigenvalues that obey the triangle inequality).  ValueError naming what fails."""
    c = np.asarray(com, dtype=float)
    about_com = np.diag([I1, I2, I3]) - M * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    moments = np.linalg.eigvalsh(about_com)
    if not moments[0] > 0.0 or moments[0] + moments[1] < moments[2] * (1.0 - 1e-12):
        raise ValueError(
            f"scene.I1, I2, I3 = {I1}, {I2}, {I3} about the pivot, M = {M}, com = {[float(x) for x in c]}: the moments "
            f"about the centre of mass would be {', '.join(f'{m:.4g}' for m in moments)} (kg m2), which no "
            "rigid body has (scene.allow_unphysical=true runs them anyway)"
        )


def check_vector(key, value):
    """A list of three finite floats (a body-frame vector option) as a tuple; ValueError otherwise."""
    try:
        vector = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"scene.{key}={value}: must be a list of three numbers [x, y, z]") from None
    if len(vector) != 3 or not all(np.isfinite(vector)):
        raise ValueError(f"scene.{key}={list(value)}: must be a list of three finite numbers [x, y, z]")
    return vector
