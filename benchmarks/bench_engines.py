"""ns per step of the engine schemes next to gyrolab's rk4 and lie_poisson, and MuJoCo's own cost.

    python benchmarks/bench_engines.py [--runs 512] [--steps 2000] [--repeat 5]

Every method's ``step`` runs in the same batched harness: one njit ``prange``
over runs, each run a register-resident loop of ``steps`` steps of the
write-up's heavy top (f = 50 Hz, θ0 = 45°, dt = 1e-4 s, spread over
slightly different tilts so no two runs are identical), on 1 and 2 numba
threads.  The figure is the best of ``repeat`` timed calls (on a shared
machine the minimum is the least disturbed) of the aggregate wall time /
(runs × steps), i.e. the cost of one step of one run when the batch is
shared over the threads.

MuJoCo's row is ``mujoco.rollout`` (C, its own thread pool) on the same top
as an MJCF ball joint, per integrator, with 1 and 2 ``MjData`` (threads);
it is skipped when ``mujoco`` does not import.  MuJoCo's step does far more
than the rotation update (kinematics, CRB, RNE, factorisation, the constraint
pipeline, sensors, energy bookkeeping off), so the ratio measures what using
the engine as a rigid-body integrator costs, not its integrator alone.

Quote ratios from one run only: the machine may be shared.
"""

import argparse
import importlib
import math
import os
import sys
import time

import numpy as np
from numba import get_num_threads, njit, prange, set_num_threads

from gyrolab.kernels.body import Body, body_row
from gyrolab.kernels.registry import METHODS, stepper

# every registered reproduction of an engine scheme (kernels/methods README: REPRODUCES)
ENGINE_METHODS = tuple(name for name, module in METHODS.items() if getattr(module, "REPRODUCES", ""))
OWN_METHODS = ("rk4", "lie_poisson")

M, R_DISC, ARM, G = 1.0, 0.05, 0.1, 10.0
I1 = M * (R_DISC**2 / 4 + ARM**2)
TOP = tuple(Body(I1, I1, M * R_DISC**2 / 2, M * G * ARM))
F_HZ, THETA0, DT = 50.0, 45.0, 1e-4


def load(name):
    """A method module: kernels/methods/<name>.py (or kernels/<name>.py before the methods/ move)."""
    for path in (f"gyrolab.kernels.methods.{name}", f"gyrolab.kernels.{name}"):
        try:
            return importlib.import_module(path)
        except ImportError:
            continue
    raise ImportError(name)


def make_batch(module):
    start, step_carried = stepper(module)  # a method's carried state threads through

    @njit(parallel=True, error_model="numpy")
    def run(W, Q, bodies, dt, n_steps):
        for i in prange(W.shape[0]):
            w = (W[i, 0], W[i, 1], W[i, 2])
            q = (Q[i, 0], Q[i, 1], Q[i, 2], Q[i, 3])
            body = body_row(bodies, i)
            c = start(w, q, body)
            for _ in range(n_steps):
                w, q, c = step_carried(w, q, c, dt, body)
            W[i, 0], W[i, 1], W[i, 2] = w
            Q[i, 0], Q[i, 1], Q[i, 2], Q[i, 3] = q

    return run


def initial_states(n_runs):
    theta = np.radians(THETA0 + np.linspace(-1.0, 1.0, n_runs))
    W = np.zeros((n_runs, 3))
    W[:, 2] = 2 * math.pi * F_HZ
    Q = np.zeros((n_runs, 4))
    Q[:, 0], Q[:, 1] = np.cos(theta / 2), np.sin(theta / 2)
    return W, Q, np.tile(TOP, (n_runs, 1))


def bench_numba(name, n_runs, steps, repeat, threads):
    run = make_batch(load(name))
    W0, Q0, bodies = initial_states(n_runs)
    run(W0.copy(), Q0.copy(), bodies, DT, 2)  # compile
    out = {}
    for t in threads:
        set_num_threads(t)
        times = []
        for _ in range(repeat):
            W, Q = W0.copy(), Q0.copy()
            start = time.perf_counter()
            run(W, Q, bodies, DT, steps)
            times.append(time.perf_counter() - start)
        assert np.all(np.isfinite(W)), name
        out[t] = float(np.min(times)) / (n_runs * steps) * 1e9
    return out


def top_xml(integrator):
    ixx, izz = M * R_DISC**2 / 4, M * R_DISC**2 / 2
    return f"""<mujoco>
  <option timestep="{DT!r}" gravity="0 0 {-G!r}" integrator="{integrator}">
    <flag contact="disable" constraint="disable" spring="disable" damper="disable" actuation="disable"/>
  </option>
  <worldbody>
    <body name="top">
      <joint type="ball"/>
      <inertial pos="0 0 {ARM!r}" mass="{M!r}" diaginertia="{ixx!r} {ixx!r} {izz!r}"/>
    </body>
  </worldbody>
</mujoco>"""


def bench_mujoco(integrator, n_runs, steps, repeat, threads):
    import mujoco
    from mujoco import rollout

    model = mujoco.MjModel.from_xml_string(top_xml(integrator))
    W0, Q0, _ = initial_states(n_runs)
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    states = np.empty((n_runs, mujoco.mj_stateSize(model, spec)))
    for i in range(n_runs):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = Q0[i]
        data.qvel[:] = W0[i]
        mujoco.mj_getState(model, data, states[i], spec)
    out = {}
    for t in threads:
        datas = [mujoco.MjData(model) for _ in range(t)]
        rollout.rollout(model, datas, states, nstep=2)
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            rollout.rollout(model, datas, states, nstep=steps)
            times.append(time.perf_counter() - start)
        out[t] = float(np.min(times)) / (n_runs * steps) * 1e9
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=512)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    threads = [t for t in (1, 2) if t <= get_num_threads()]
    rows = []
    for name in OWN_METHODS + ENGINE_METHODS:
        rows.append((name, bench_numba(name, args.runs, args.steps, args.repeat, threads)))
    try:
        import mujoco
        from mujoco import rollout  # noqa: F401

        version = mujoco.__version__
        for integrator in ("Euler", "implicitfast", "implicit", "RK4"):
            rows.append(
                (
                    f"MuJoCo {version} rollout {integrator}",
                    bench_mujoco(integrator, args.runs, args.steps, args.repeat, threads),
                )
            )
    except ImportError:
        print("(mujoco not installed: no MuJoCo rows)")
    base = dict(rows)["rk4"]
    print(
        f"heavy top f = {F_HZ:g} Hz, θ0 = {THETA0:g}°, dt = {DT:g} s; {args.runs} runs × {args.steps} steps, "
        f"best of {args.repeat}; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs"
    )
    head = "".join(f"  ns/step {t} thr  / rk4" for t in threads)
    print(f"{'method':<34}{head}")
    for name, cost in rows:
        cells = "".join(f"  {cost[t]:12.1f}  {cost[t] / base[t]:5.2f}" for t in threads)
        print(f"{name:<34}{cells}")
    set_num_threads(max(threads))
    return 0


if __name__ == "__main__":
    sys.exit(main())
