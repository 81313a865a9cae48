"""Pieces every scene uses: the Scene record and the initial tilt."""

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scene:
    """A body and its initial state.

    body: a kernels.body.Body (I1, I2, I3 in kg m², M g l in N m), moments
    about the pivot (about the centre of mass for a free body); omega0: body angular
    velocity (rad/s); q0: orientation quaternion (a, b, c, d), R(q0) maps body
    to lab coordinates.
    """

    name: str
    body: tuple
    omega0: tuple
    q0: tuple

    @property
    def symmetric(self):
        return self.body[0] == self.body[1]


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
