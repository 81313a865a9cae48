"""rapier_rescale: Rapier's gyroscopic correction (|L|-rescaled explicit step) and linearised rotation.

Followed: dimforge/rapier at commit ccd01cd294e8 (v0.35.2-1-g, 16 Aug 2026):
src/dynamics/rigid_body.rs ``gyroscopic_corrected_angvel`` (called by
src/dynamics/solver/staged_island_solver/worker.rs after the substep's
force increment ω += h I⁻¹ τ), and src/dynamics/rigid_body_components.rs
``RigidBodyVelocity::integrate_linearized`` (3D: q ← normalise((1, ω h/2) ⊗ q),
world frame).  Per (sub)step, with the torque first, then the correction:

    ω ← ω + h I⁻¹ τ(q);   L = I ω;  L' = L − h ω × L;  ω ← I⁻¹ L' |L|/|L'|
    q ← normalise(q ⊗ (1, ω h/2))

Rapier has no angular-velocity cap for a free body
(``max_corrective_velocity`` only limits contact position correction) and
no default angular damping, so there is no hidden limit to switch.  The
gyroscopic correction is opt-in (``enable_gyroscopic_forces``).  Rapier's
f32 build is the default; this is double.  avian (Bevy) does the same
correction (its PR #993 reports the drift toward L²/(2 I2)).  Order 1.
"""

import math

from numba import njit

from ..engine_common import rescale_momentum_step, torque_kick
from ..rotation import quat_mul

ORDER = 1
SYMPLECTIC = False
REPRODUCES = "Rapier 0.35 gyroscopic correction"  # judged by conformance with the engine (tests/test_engines.py)
PRESERVES = ("L_norm",)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    w = rescale_momentum_step(torque_kick(w, q, dt, body), dt, body)
    h = 0.5 * dt
    a, b, c, d = quat_mul(q, (1.0, w[0] * h, w[1] * h, w[2] * h))
    inv = 1.0 / math.sqrt(a * a + b * b + c * c + d * d)
    return w, (a * inv, b * inv, c * inv, d * inv)
