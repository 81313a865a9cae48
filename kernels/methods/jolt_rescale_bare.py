"""jolt_rescale_bare: Jolt's gyroscopic |L|-rescale step without its velocity cap and damping.

Followed: jrouwe/JoltPhysics at commit 3b47ec390cb9 (v5.5.0-182-g), the same
lines as jolt_rescale (Jolt/Physics/Body/MotionProperties.inl
``ApplyGyroscopicForceInternal``, Jolt/Physics/Body/Body.inl
``AddRotationStep``), with MAX_ANGULAR_VELOCITY = ∞ and ANGULAR_DAMPING = 0:

    L  = I ω;  L' = L − h ω × L;  L' ← L' |L|/|L'|;  ω ← I⁻¹ L' + h I⁻¹ τ(q)
    q ← normalise(q ⊗ Rot(ω h))

Torque-free, |L| is kept to rounding, but the explicit step does not keep
the energy: it drifts toward L²/(2 I2), the intermediate axis (avian PR
#993; measured in tests/test_engines.py).  Order 1.
"""

import math

from numba import njit

from .jolt_rescale import jolt_step

ORDER = 1
SYMPLECTIC = False
REPRODUCES = (
    "Jolt 5.5 gyroscopic |L|-rescale, no limits"  # judged by conformance with the engine (tests/test_engines.py)
)
PRESERVES = ("L_norm",)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return jolt_step(w, q, dt, body, math.inf, 0.0)
