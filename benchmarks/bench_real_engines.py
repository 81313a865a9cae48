"""Cost per step of a real-engine run (kernels/real/) next to its reproduction's, both through
kernels.batch.integrate as a sweep runs them.

    python benchmarks/bench_real_engines.py [--steps 100000] [--stride 100] [--repeat 3] [--only real_newton]

One run of the tennis-racket box (free_asymmetric, f = 10 Hz) and one of the write-up's heavy top
(f = 10 Hz, θ0 = 45°) at dt = 1e-4 s, a sample every ``stride`` steps, the best of ``repeat`` timed
calls after one warm-up call (numba compile, engine import), in µs per step.  A real engine runs its
runs one after another in this process (MuJoCo: ``mj_step`` with nstep = stride; PyBullet:
``stepSimulation`` called from Python; Basilisk: one ``ExecuteSimulation`` per sample, ~0.2 ms a call;
Newton: ``solver.step`` from Python, a few Warp CPU kernel launches a step; jax-md: a jitted
``lax.fori_loop`` of ``stride`` NVE steps per sample), so its cost per step includes building the model
and reading the state back each sample; a reproduction runs numba's kernel (one run: ``run_batch``).
Quote ratios from one run only: the machine may be shared.
"""

import argparse
import time

import numpy as np

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.real import engine_versions, package_missing
from gyrolab.kernels.scenes import build_scene

PAIRS = (
    ("real_mujoco_euler", "mujoco_euler"),
    ("real_mujoco_implicitfast", "mujoco_implicitfast"),
    ("real_mujoco_implicit", "mujoco_implicit"),
    ("real_mujoco_rk4", "mujoco_rk4"),
    ("real_pybullet", "bullet_explicit"),
    ("real_pybullet_maximal", "bullet_implicit_body"),
    ("real_basilisk_rk4", "rk4_mrp"),  # free bodies only: the heavy top row says "not run"
    ("real_newton_semi", "newton_semi"),
    ("real_newton_xpbd", "newton_semi"),  # XPBD's damping is 0 as shipped: the closest reproduction, not its update
    ("real_jaxmd_nve", "no_squish"),  # free bodies only: the heavy top is "not run"
)


def cost(method, scene, steps, stride, repeat):
    """Best µs per step over ``repeat`` calls of one run of ``steps`` steps."""
    B, W, Q = (np.array([x]) for x in (scene.body, scene.omega0, scene.q0))
    n_samples = steps // stride + 1
    integrate(method, B, W, Q, 1e-4, stride, 2)  # warm up: compile or import
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        _, status, n_steps = integrate(method, B, W, Q, 1e-4, stride, n_samples)
        best = min(best, (time.perf_counter() - start) / max(int(n_steps[0]), 1))
    return best * 1e6, int(status[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=100_000)
    ap.add_argument("--stride", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", default="", help="only the real engines whose name starts with this")
    args = ap.parse_args()
    scenes = {
        "tennis racket": build_scene("free_asymmetric", 10.0, 30.0),
        "heavy top": build_scene("heavy_top", 10.0, 45.0),
    }
    names = [real for real, _ in PAIRS if real.startswith(args.only) and package_missing(real) is None]
    print(f"{engine_versions(names)}; {args.steps} steps of dt = 1e-4 s, a sample every {args.stride}")
    print("| scene | real engine | µs/step | reproduction | µs/step | ratio |")
    print("|---|---|---|---|---|---|")
    for label, scene in scenes.items():
        for real, reproduction in PAIRS:
            if real not in names:
                continue
            try:
                engine_us, _ = cost(real, scene, args.steps, args.stride, args.repeat)
            except ValueError as err:  # a body that backend does not build
                print(f"| {label} | {real} | not run: {str(err).split(';')[0]} ||||")
                continue
            ours_us, _ = cost(reproduction, scene, args.steps, args.stride, args.repeat)
            print(
                f"| {label} | {real} | {engine_us:.3g} | {reproduction} | {ours_us:.3g} | {engine_us / ours_us:.0f}x |"
            )


if __name__ == "__main__":
    main()
