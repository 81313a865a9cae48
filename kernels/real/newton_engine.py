"""Newton itself (``pip install newton warp-lang``) on Warp's CPU device: each run one body stepped by a solver.

One name per solver (newton 1.8.0, warp-lang 1.19.0; source read from the installed wheel,
newton/_src/solvers/; its ``integrate_rigid_body`` and the damping and iteration defaults below are
identical, diffed, to newton-physics/newton at 41a5392c13b9, the commit kernels/methods/newton_semi follows):

- ``real_newton_semi`` (``mode="semi"``): ``SolverSemiImplicit``.  Its body update is
  solver.py ``integrate_rigid_body``: explicit ω × Iω in the body frame, ω₁ = R(wb + I⁻¹ tb h), the
  first-order quaternion step r₁ = normalize(r₀ + ½h (ω₁, 0) ⊗ r₀), then ω₁ ← ω₁ (1 − c h) with
  c = ``angular_damping`` = 0.05 /s as shipped (solver_semi_implicit.py ``__init__``), applied after
  the rotation and not clamped at 0; no angular-velocity cap.  Joints would be penalty springs
  (``joint_attach_ke`` = 1e4, ``joint_attach_kd`` = 1e2): none is built (a free body's FREE joint
  adds no force, kernels_body.py ``eval_body_joints`` returns for it).
- ``real_newton_xpbd`` (``mode="xpbd"``): ``SolverXPBD``, ``iterations`` = 2, ``angular_damping`` =
  0.0 as shipped (solver_xpbd.py ``__init__``).  With no contact and only the FREE joint (whose
  constraint solve returns at once, xpbd/kernels.py ``solve_body_joints``) its step is
  ``integrate_rigid_body`` with damping 0, followed per iteration by ``apply_body_deltas`` with zero
  deltas: the quaternion renormalised again (a float32 rounding, no change in exact arithmetic) and
  **ω (and v) set to exactly 0 when |ω| < 1e-4 rad/s** ("XXX this improves gradient stability",
  xpbd/kernels.py ``apply_body_deltas``), a snap no spinning body here reaches.

The body: ``ModelBuilder(gravity=(0, 0, 0))``, ``add_body`` (the stand-alone free body: a link with a
FREE joint) of mass 1 kg at the origin with the principal moments as a diagonal inertia, no shape,
``finalize(device="cpu")``; ``solver.step(state_in, state_out, None, None, dt)`` with the two states
swapped each step.  Newton stores ``body_q`` as (px, py, pz, qx, qy, qz, qw) (body → world) and
``body_qd`` as (v, ω) with ω the **angular half, second, in the world frame** (``integrate_rigid_body``
returns ``wp.spatial_vector(v1, w1)`` with w1 = quat_rotate(r0, ...)): ω_body = Rᵀ ω_world, computed
here in float64 from the read-back quaternion.

**float32**: the Model and State arrays are wp.transform / wp.spatial_vector / wp.mat33, Warp's float32
types, and the kernels compute in float32; Newton 1.8 has no float64 switch (Warp has float64 types,
Newton's solvers are not written for them).  So the initial state is rounded to float32 (~6e-8
relative) and every step rounds at ~1e-7: the engine is not comparable with the float64 reproduction
below ~1e-7 per step.  Nor is the rounding only noise: ω is turned into the body frame and back each step
by a quaternion normalised in float32 (|r|² = 1 + ~half an ulp), which raises |ω| by ~2e-7 a step
(measured: 5 -> 5.0011 rad/s in 1000 steps of an undamped principal-axis spin; the energy of the tumbling
box +1.7e-3 in 1e4 steps at dt = 1e-4 against newton_semi), per step, so more per second at a smaller dt
(kernels/real/conformance.py READING, tests/test_real_newton.py).

Heavy bodies are refused: a pivot is a Newton joint (a ball joint to the world) that SolverSemiImplicit
holds with penalty springs and SolverXPBD by relaxed position projection; not built here.
Warp compiles each solver's kernel modules on first use (about 5 s for the semi-implicit update, a
minute or more for the XPBD module on 2 cores) into its kernel cache (~/.cache/warp), reused afterwards.
"""

import numpy as np

from .pybullet_engine import is_free, quat_matrix


class Backend:
    """One Newton solver on Warp's CPU device (``mode``: "semi" SolverSemiImplicit, "xpbd" SolverXPBD)."""

    PACKAGE = "newton"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)
    MODES = ("semi", "xpbd")
    PRECISION = np.float32  # the engine's state (conformance.py perturbs ω3 by one ulp of this type)

    def __init__(self, name, mode):
        if mode not in self.MODES:
            raise ValueError(f"Newton backend mode {mode!r}: choose from {', '.join(self.MODES)}")
        import warp

        warp.config.quiet = True  # no "Warp initialized" banner (if Warp is not initialised yet)
        warp.config.log_level = warp.LOG_WARNING  # no "Module ... load on device 'cpu' took" line per kernel module
        import newton

        self.name, self.mode, self.wp, self.newton = name, mode, warp, newton
        self.DEFAULTS = (
            "SolverSemiImplicit: explicit gyroscopic term, first-order quaternion, angular damping 0.05/s "
            "(w *= 1 - 0.05 h after the rotation), no cap; float32"
            if mode == "semi"
            else "SolverXPBD: explicit gyroscopic term, first-order quaternion, angular damping 0, 2 iterations "
            "renormalising q, |w| < 1e-4 rad/s snapped to 0; float32"
        )

    def check(self, body):
        """ValueError (one line) when this backend does not build ``body`` (kernels.body.Body): heavy bodies."""
        if not is_free(body):
            raise ValueError(
                f"method {self.name!r} runs free bodies only (a pivot is a Newton ball joint, held by "
                "penalty springs in SolverSemiImplicit and by position projection in SolverXPBD: not built); "
                "use real_mujoco_* for a heavy body"
            )

    def start(self, body, w0, q0, dt, angular_damping=None):
        """A run of ``body`` from ω0 (body, rad/s) and q0 (scalar first) with step dt (s).
        ``angular_damping`` (1/s) replaces the solver's shipped damping (conformance runs only; None: as shipped)."""
        self.check(body)
        return _Run(self, body, np.asarray(w0, float), np.asarray(q0, float), float(dt), angular_damping)


class _Run:
    def __init__(self, backend, body, w0, q0, dt, angular_damping):
        wp, newton = backend.wp, backend.newton
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
        i1, i2, i3 = (float(x) for x in body[:3])
        builder.add_body(mass=1.0, inertia=wp.mat33(i1, 0.0, 0.0, 0.0, i2, 0.0, 0.0, 0.0, i3))
        self.model = builder.finalize(device="cpu")
        options = {} if angular_damping is None else {"angular_damping": float(angular_damping)}
        solver = newton.solvers.SolverSemiImplicit if backend.mode == "semi" else newton.solvers.SolverXPBD
        self.solver = solver(self.model, **options)
        self.state, self.next = self.model.state(), self.model.state()
        self.control = self.model.control()  # empty (no joint drive); step() would build one per call for None
        a, b, c, d = q0 / np.linalg.norm(q0)
        self.state.body_q.assign(np.array([[0.0, 0.0, 0.0, b, c, d, a]], dtype=np.float32))
        qd = np.zeros((1, 6), dtype=np.float32)
        qd[0, 3:] = quat_matrix((a, b, c, d)) @ w0  # the angular half, world frame
        self.state.body_qd.assign(qd)
        self.dt = dt

    def advance(self, n):
        """n solver steps: (n, ω body (rad/s), q scalar first); float32 values read back as float64."""
        step, dt, control = self.solver.step, self.dt, self.control
        for _ in range(n):
            step(self.state, self.next, control, None, dt)
            self.state, self.next = self.next, self.state
        pose = self.state.body_q.numpy()[0].astype(np.float64)
        q = np.array([pose[6], pose[3], pose[4], pose[5]])
        w_world = self.state.body_qd.numpy()[0, 3:].astype(np.float64)
        with np.errstate(all="ignore"):  # an exploding run reads back inf/NaN: gyrolab's rule marks it
            return n, quat_matrix(q / np.linalg.norm(q)).T @ w_world, q

    def close(self):
        self.model = self.solver = self.state = self.next = self.control = None
