"""bepu_conserve_momentum: BEPUphysics v2's ConserveMomentum mode: exact rotation by ω, then ω ← I_new⁻¹ L_prev.

Followed: bepu/bepuphysics2 at commit 956a679f817d (v2.5.0-beta.28, 1 Mar
2026): BepuPhysics/PoseIntegrator.cs ``AngularIntegrationMode`` (the enum),
``PoseIntegration.Integrate`` (the orientation), ``PoseIntegration.
IntegrateAngularVelocityConserveMomentum`` and the loop of
``PoseIntegrator.IntegrateBundlesAfterSubstepping`` for an unconstrained body
("velocity -> pose"): the user's ``IPoseIntegratorCallbacks.IntegrateVelocity``
(gravity, torques, damping: written by the user, the engine applies none),
then, with ``AngularIntegrationMode.ConserveMomentum``:

    previousOrientation = orientation
    orientation ← normalise(Rot(|ω| dt about ω̂) ∘ orientation)   (skipped when |ω| ≤ 1e-15)
    L = R_prev I R_prevᵀ ω;  ω ← R I⁻¹ Rᵀ L                       (world frame, R = R(orientation))

so the world angular momentum the step started from is re-projected onto
the new orientation's inertia.  The enum's own comment: "Approximately
conserves angular momentum by updating the angular velocity according to
the change in orientation. Does a decent job for gyroscopes, but angular
velocities will tend to drift towards a minimal inertia axis."  In the body
frame (q ⊗ Rot(ω h) is Bepu's world-frame concatenation):

    ω ← ω + h I⁻¹ τ(q);  ω ← ω · (1 − ANGULAR_DAMPING)^h          (the callback)
    q' ← normalise(q ⊗ Rot(ω h))
    ω ← I⁻¹ R(q')ᵀ R(q) I ω                                        (= I⁻¹ Rot(−ω h) I ω)

Defaults: the mode is a property of the user's callbacks; the enum's zero
value and the demos' choice (Demos/DemoCallbacks.cs
``DemoPoseIntegratorCallbacks.AngularIntegrationMode`` =>
``Nonconserving``) is Nonconserving, which is no_gyro with an exact rotation
(ω never changes torque-free), so this mode is opt-in.  The engine has no
damping or velocity cap of its own; the demos' callbacks damp ω by
Pow(Clamp(1 − 0.03, 0, 1), dt) per step (angularDamping = .03f); this preset
keeps the engine's 0 (ANGULAR_DAMPING, in the demos' form).  Bepu keeps the
local inverse inertia and takes the local inertia by cofactors
(engine_common ``bepu_conserve_momentum``).  Found: torque-free, the world L
is kept up to a rounding drift (~2.5e-16 relative per step in double,
growing linearly: not declared in PRESERVES), while the kinetic
energy ½ L·I⁻¹L grows step by step toward L²/(2 I_min): ω drifts toward the
axis of least inertia, as the comment says (tests/test_presets2.py).  With
the weight, L changes by h τ per step, so the vertical Lz of a top is kept
to the same drift.
Bepu computes in single precision; this is double.  The pivot of the heavy
top is a gravity torque here (the unconstrained-body path), not a Bepu ball
socket (constrained bodies take the same calls inside the solver's substeps,
Constraints/TypeProcessor.cs).  Order 1 (for the rigid body itself, ω × Iω
included through the re-projection: measured slope 0.999 on the 50 Hz top,
tests/test_engines.py).
"""

from numba import njit

from ..engine_common import bepu_conserve_momentum, exp_rotate, torque_kick

ORDER = 1
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = "BEPUphysics 2.5 AngularIntegrationMode.ConserveMomentum (opt-in; the default is Nonconserving)"
# Torque-free the world L is re-projected, not kept exactly: the two rotation matrices per step leave a
# rounding drift growing ~linearly (measured 1.4e-12 relative in 5000 steps of the 10 Hz top, Lz; 5e-12
# in 2e4 steps of a free body), over tests/test_engines.py's 1e-12 bar, so nothing is declared.
PRESERVES = ()

ANGULAR_DAMPING = 0.0  # fraction of ω removed per second, the user's callback (the demos' .03f); engine: none
MIN_SPEED = 1e-15  # rad/s, PoseIntegration.Integrate: no rotation when |ω| <= 1e-15


@njit(cache=True, error_model="numpy")
def bepu_step(w, q, dt, body, angular_damping):
    """One unconstrained-body step of Bepu's ConserveMomentum mode with the demos' damping form."""
    w = torque_kick(w, q, dt, body)
    damp = min(max(1.0 - angular_damping, 0.0), 1.0) ** dt
    w = (w[0] * damp, w[1] * damp, w[2] * damp)
    q_new = exp_rotate(q, w, dt, MIN_SPEED * abs(dt))
    return bepu_conserve_momentum(w, q, q_new, body), q_new


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    return bepu_step(w, q, dt, body, ANGULAR_DAMPING)
