"""MuJoCo's RK4 on the seed's heavy top, through mujoco.rollout (optional: only if mujoco imports).

The top is one body on a ball joint at the origin, mass M with its centre at
l e3 and inertia (M r²/4, M r²/4, M r²/2) about the centre (so about the pivot
I1 = I2 = M(r²/4 + l²), I3 = M r²/2, as in gyrolab), gravity −g ẑ, no
contacts, constraints or damping.  A ball joint's qpos is the body's
quaternion (w, x, y, z), the same convention as gyrolab's q, and its qvel the
body-frame angular velocity, gyrolab's ω.
"""

import time

import numpy as np


def available():
    try:
        import mujoco  # noqa: F401
        from mujoco import rollout  # noqa: F401
    except ImportError:
        return False
    return True


def top_xml(dt, M=1.0, r=0.05, l=0.1, g=10.0):
    ixx, izz = M * r * r / 4, M * r * r / 2
    return f"""<mujoco>
  <option timestep="{dt!r}" gravity="0 0 {-g!r}" integrator="RK4">
    <flag contact="disable" constraint="disable" energy="enable"/>
  </option>
  <worldbody>
    <body name="top">
      <joint type="ball" damping="0" armature="0"/>
      <inertial pos="0 0 {l!r}" mass="{M!r}" diaginertia="{ixx!r} {ixx!r} {izz!r}"/>
    </body>
  </worldbody>
</mujoco>"""


def _model(scene, dt):
    import mujoco

    model = mujoco.MjModel.from_xml_string(top_xml(dt))
    data = mujoco.MjData(model)
    data.qpos[:] = scene.q0
    data.qvel[:] = scene.omega0
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return model, data, state


def energy_error(scene, dt, t_end):
    """(max |E − E0|/E0 over every step of t_end s, ns per step of that rollout on one thread)."""
    from mujoco import rollout

    model, data, s0 = _model(scene, dt)
    e0 = float(data.energy.sum())
    n = int(round(t_end / dt))
    start = time.perf_counter()
    states, _ = rollout.rollout(model, data, s0[None], nstep=n)
    wall = time.perf_counter() - start
    a, b, c, d = states[0, :, 1:5].T
    w = states[0, :, 5:8]
    E = 0.5 * (w * w * np.asarray(scene.body[:3])).sum(axis=1) + scene.body[3] * (a * a + d * d - b * b - c * c)
    return float(np.max(np.abs(E - e0)) / abs(e0)), wall / n * 1e9


def ns_per_step(scene, dt, n_runs, threads, steps, repeat):
    """Median aggregate ns per step of ``n_runs`` rollouts of ``steps`` steps on ``threads`` threads."""
    import mujoco
    from mujoco import rollout

    model, _, s0 = _model(scene, dt)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    initial = np.tile(s0, (n_runs, 1))
    rollout.rollout(model, datas, initial, nstep=2)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        rollout.rollout(model, datas, initial, nstep=steps)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / (n_runs * steps) * 1e9
