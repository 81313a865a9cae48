"""MuJoCo itself (``pip install mujoco``): each run an MJCF model stepped by ``mujoco.mj_step``.

The model is the one tests/test_engines.py checks the reproductions with: only
rigid-body dynamics (contact, constraints, springs, dampers and actuation
disabled; no geoms), the integrator the name gives (``Euler``,
``implicitfast``, ``implicit``, ``RK4``; MuJoCo 4.0 reproduced by
kernels/methods/mujoco_*):

- free body: ``<freejoint/>``, gravity 0, mass 1 kg at the body origin, the
  principal moments as ``diaginertia`` (qpos[3:7] = q, qvel[3:6] = body ω);
- heavy body: a ``ball`` joint at the pivot, gravity −g ẑ with g = 9.81 m/s²,
  mass M at c = M g c / (M g) with the inertia about the centre of mass
  I_pivot − M (|c|² 1 − c cᵀ) as ``fullinertia`` (M = 1 kg, or larger when
  that tensor would not be a physical inertia: only M g c and I_pivot enter
  the motion).  qpos[0:4] = q, qvel[0:3] = body ω.

MuJoCo's defaults as shipped: no joint damping or armature; a step whose
acceleration is NaN or exceeds 1e10 (``mj_checkAcc``) raises
mjWARN_BADQACC and resets the state: the run is marked diverged (status 1,
kernels/real/__init__.py) at the sample that holds that step, and n_steps
counts the steps MuJoCo completed before it.
"""

import numpy as np

GRAVITY = 9.81  # m/s², the heavy body's g in the engine (only M g c enters the motion)
FLAGS = 'contact="disable" constraint="disable" spring="disable" damper="disable" actuation="disable"'


def free_xml(body, dt, integrator):
    """MJCF of a standalone free body with principal moments body[:3] (kg m²), no gravity."""
    return f"""<mujoco>
  <option timestep="{dt!r}" gravity="0 0 0" integrator="{integrator}"><flag {FLAGS}/></option>
  <worldbody>
    <body name="body">
      <freejoint/>
      <inertial pos="0 0 0" mass="1" diaginertia="{body[0]!r} {body[1]!r} {body[2]!r}"/>
    </body>
  </worldbody>
</mujoco>"""


def heavy_mass_and_com(body, g=GRAVITY):
    """(M kg, c (3,) m, inertia about the centre of mass (3, 3) kg m²) for a body record with M g c ≠ 0:
    M = 1 kg doubled until I_pivot − M (|c|² 1 − c cᵀ) has positive eigenvalues obeying the triangle
    inequality (what MuJoCo's compiler accepts)."""
    mgc = np.array([body.mgc1, body.mgc2, body.mgl])
    pivot = np.diag(np.asarray(body[:3], dtype=float))
    mass = 1.0
    for _ in range(200):
        c = mgc / (mass * g)
        about_com = pivot - mass * (c @ c * np.eye(3) - np.outer(c, c))
        e = np.sort(np.linalg.eigvalsh(about_com))
        if e[0] > 0 and e[0] + e[1] >= e[2] * (1 + 1e-12):
            return mass, c, about_com
        mass *= 2.0
    raise ValueError(f"no mass makes a physical inertia about the centre of mass of body {tuple(body[:6])}")


def heavy_xml(body, dt, integrator, g=GRAVITY):
    """MJCF of the body on a ball joint at the pivot under gravity −g ẑ (centre of mass at c)."""
    mass, c, about_com = heavy_mass_and_com(body, g)
    full = " ".join(repr(float(about_com[i, j])) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)))
    pos = " ".join(repr(float(x)) for x in c)
    return f"""<mujoco>
  <option timestep="{dt!r}" gravity="0 0 {-g!r}" integrator="{integrator}"><flag {FLAGS}/></option>
  <worldbody>
    <body name="body">
      <joint type="ball" damping="0" armature="0" frictionloss="0"/>
      <inertial pos="{pos}" mass="{mass!r}" fullinertia="{full}"/>
    </body>
  </worldbody>
</mujoco>"""


def is_free(body):
    return body.mgl == 0.0 and body.mgc1 == 0.0 and body.mgc2 == 0.0


class Backend:
    """One MuJoCo integrator (``mode``: the MJCF ``integrator`` attribute)."""

    PACKAGE = "mujoco"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)
    DEFAULTS = "MuJoCo as shipped: no damping, armature 0; mjWARN_BADQACC (|qacc| > 1e10 or NaN) resets the state"

    def __init__(self, name, mode):
        import mujoco

        self.name, self.mode, self.mujoco = name, mode, mujoco

    def check(self, body):
        """ValueError (one line) when this backend does not build ``body``: a heavy body needs a mass that
        makes a physical inertia about the centre of mass (``heavy_mass_and_com``)."""
        if not is_free(body):
            heavy_mass_and_com(body)

    def xml(self, body, dt):
        return free_xml(body, dt, self.mode) if is_free(body) else heavy_xml(body, dt, self.mode)

    def start(self, body, w0, q0, dt):
        """A run of ``body`` (kernels.body.Body) from ω0 (body, rad/s) and q0 (scalar first) with step dt (s)."""
        return _Run(self.mujoco, self.xml(body, dt), is_free(body), w0, q0)


class _Run:
    def __init__(self, mujoco, xml, free, w0, q0):
        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self.o = 3 if free else 0  # the free joint's position comes first, then its quaternion
        self.data.qpos[self.o : self.o + 4] = q0
        self.data.qvel[self.o : self.o + 3] = w0
        self.bad = mujoco.mjtWarning.mjWARN_BADQACC
        self.spec = mujoco.mjtState.mjSTATE_INTEGRATION
        # MuJoCo prints each warning ("Nan, Inf or huge value in QACC ..."); the run's status says it, so a
        # sweep of diverging runs does not flood the terminal.  Restored when the run closes.
        self.handler = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(_silent)

    def _warnings(self):
        return self.data.warning[self.bad].number

    def advance(self, n):
        """n steps of mj_step: (steps completed, ω body, q), or (steps before the reset, None, None)."""
        mj, m, d = self.mujoco, self.model, self.data
        before = self._warnings()
        saved = np.empty(mj.mj_stateSize(m, self.spec))
        mj.mj_getState(m, d, saved, self.spec)
        mj.mj_step(m, d, n)
        if self._warnings() == before:
            return n, d.qvel[self.o : self.o + 3].copy(), d.qpos[self.o : self.o + 4].copy()
        # MuJoCo reset the state inside these n steps: replay them one by one (deterministic) for the step
        mj.mj_setState(m, d, saved, self.spec)
        d.warning[self.bad].number = before
        for k in range(n):
            mj.mj_step(m, d)
            if self._warnings() != before:
                return k, None, None
        raise RuntimeError("MuJoCo's reset did not recur on replay")  # determinism broken: never seen

    def close(self):
        self.mujoco.set_mju_user_warning(self.handler)
        self.model = self.data = None


def _silent(message):
    """A MuJoCo warning handler that drops the message (the warning counters still count it)."""
