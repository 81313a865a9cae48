"""no_gyro: velocity update without the ω × Iω term (PhysX's default, Godot), then an exact rotation.

The engines integrate the world-frame angular velocity with the applied
torque only, ω_lab ← ω_lab + h I_lab⁻¹ τ_lab, and turn the body by ω_lab h.
Written in the body frame this is

    ω ← ω + h I⁻¹ τ(q);   q ← normalise(q ⊗ Rot(ω h))

(a rotation about ω leaves ω's body components unchanged, so the body and
lab forms are the same map).  Followed: godotengine/godot at commit
09b30be86dd3 (the stored snapshot), servers/physics_3d/godot_body_3d.cpp
``GodotBody3D::integrate_forces`` (ω ← ω · max(0, 1 − h c) + I_lab⁻¹ τ h, no
gyroscopic term) and ``GodotBody3D::integrate_velocities`` (exact rotation
Basis(ω̂, |ω| h) · basis, orthonormalised); Godot issue #80703 reports the
consequence tested in tests/test_engines.py: a torque-free body spun off its
principal axes keeps a constant ω.  PhysX: the gyroscopic term is behind
PxRigidBodyFlag::eENABLE_GYROSCOPIC_FORCES, off by default (read in PhysX
5.6.1's source for physx_default, which is this update with PhysX's shipped
damping and cap).  The bare scheme: no damping.  The engines' defaults would
damp (Godot's project setting physics/3d/default_angular_damp = 0.1 /s,
combined with the body's; PhysX's 0.05 /s, with |ω| capped at 100 rad/s:
physx_default); set ANGULAR_DAMPING to reproduce one.  It cannot show the precession of a free asymmetric body
or the tennis-racket flip; with gravity it is first order for a different
equation (I ω̇ = τ) unless I1 = I2 = I3.  No velocity caps.  Order 1 (for
that equation).
"""

from numba import njit

from ..engine_common import exp_rotate, torque_kick

ORDER = 1
SYMPLECTIC = False
REPRODUCES = (
    "PhysX / Godot default: no gyroscopic term"  # judged by conformance with the engine (tests/test_engines.py)
)
# Torque-free, ω is constant: |L| = |Iω| and L3 are kept exactly (the scene's lab L is not);
# with gravity, τ3 = 0 keeps ω3 for any body.
PRESERVES = ("L_norm", "L3")

ANGULAR_DAMPING = 0.0  # 1/s; Godot's default is 0.1, PhysX's 0.05 (see above)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    if ANGULAR_DAMPING != 0.0:
        damp = max(0.0, 1.0 - ANGULAR_DAMPING * dt)
        w = (w[0] * damp, w[1] * damp, w[2] * damp)
    w = torque_kick(w, q, dt, body)
    return w, exp_rotate(q, w, dt, 0.0)
