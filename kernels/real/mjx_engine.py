"""MuJoCo XLA (``pip install mujoco-mjx``, JAX on the CPU): each run stepped by ``mjx.step`` in a jitted loop.

Each run is the MJCF model of the C engine's backend, put on the device with ``mjx.put_model``
(mujoco_engine.free_xml / heavy_xml: rigid-body dynamics only, a free joint without gravity or a ball
joint at the pivot under −g ẑ), with the same state layout (qpos = q scalar first, qvel = ω body) and
the integrators MJX implements: ``Euler``, ``implicitfast`` and ``RK4`` (MJX has no ``implicit``).
What differs from the C engine, as shipped:

- **double precision only because this backend asks for it**: JAX computes in float32 unless
  ``jax_enable_x64`` is set, which ``Backend`` sets for the process (an MJX user who does not gets
  float32 trajectories; the conformance table is in float64);
- **no divergence test**: MJX has no mjWARN_BADQACC check and never resets the state, so an exploding
  run goes to inf/NaN and gyrolab's own rule (kernels/driver.py ``_diverged``) marks it, where the C
  engine resets at |qacc| > 1e10;
- the steps of one sample are one ``jax.lax.fori_loop`` of ``mjx.step`` (jitted once per model
  structure and integrator; dt, moments and state are array data, so a sweep recompiles nothing).
"""

import numpy as np

from . import mujoco_engine
from .mujoco_engine import is_free

MODES = ("Euler", "implicitfast", "RK4")


class Backend(mujoco_engine.Backend):
    """One MJX integrator (``mode``: the MJCF ``integrator`` attribute, one of ``MODES``); the C backend's
    models and body check (``xml``, ``check``), its own start."""

    PACKAGE = "mujoco-mjx"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)
    DEFAULTS = (
        "MJX as shipped but with jax_enable_x64 set (MJX computes in float32 otherwise); no damping, armature 0; "
        "no mjWARN_BADQACC check: a run that explodes goes to NaN, marked by gyrolab's rule"
    )

    def __init__(self, name, mode):
        if mode not in MODES:
            raise ValueError(f"MJX has no integrator {mode!r}; it has {', '.join(MODES)}")
        import jax

        from .jax_cache import use_compilation_cache

        jax.config.update("jax_enable_x64", True)
        use_compilation_cache(jax)
        import mujoco
        from mujoco import mjx

        self.name, self.mode, self.mujoco, self.mjx = name, mode, mujoco, mjx

        def steps(model, data, n):
            return jax.lax.fori_loop(0, n, lambda _, d: mjx.step(model, d), data)

        def each(model, data, n):
            """n steps, and (qvel, qpos) after each: one jitted scan instead of n calls (conformance.py)."""

            def body(d, _):
                d = mjx.step(model, d)
                return d, (d.qvel, d.qpos)

            return jax.lax.scan(body, data, None, length=n)

        self.steps = jax.jit(steps)
        self.each = jax.jit(each, static_argnums=2)

    def start(self, body, w0, q0, dt):
        """A run of ``body`` (kernels.body.Body) from ω0 (body, rad/s) and q0 (scalar first) with step dt (s)."""
        return _Run(self, self.xml(body, dt), is_free(body), w0, q0)


class _Run:
    def __init__(self, backend, xml, free, w0, q0):
        mjx = backend.mjx
        self.steps, self.each = backend.steps, backend.each
        self.model = mjx.put_model(backend.mujoco.MjModel.from_xml_string(xml))
        data = mjx.make_data(self.model)
        self.o = o = 3 if free else 0  # the free joint's position comes first, then its quaternion
        qpos = data.qpos.at[o : o + 4].set(np.asarray(q0, dtype=float))
        qvel = data.qvel.at[o : o + 3].set(np.asarray(w0, dtype=float))
        self.data = data.replace(qpos=qpos, qvel=qvel)

    def advance(self, n):
        """n steps of mjx.step: (n, ω body, q); a run that exploded returns its non-finite state."""
        self.data = self.steps(self.model, self.data, n)
        o = self.o
        return n, np.asarray(self.data.qvel[o : o + 3]), np.asarray(self.data.qpos[o : o + 4])

    def trajectory(self, n):
        """(W (n, 3) ω body, Q (n, 4) q) after each of the next n steps, in one call (NaN where it exploded)."""
        self.data, (qvel, qpos) = self.each(self.model, self.data, n)
        o = self.o
        return np.asarray(qvel[:, o : o + 3]), np.asarray(qpos[:, o : o + 4])

    def close(self):
        self.model = self.data = None
