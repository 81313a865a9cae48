"""Cost of a step: ns/step per method and scene, single trajectory and batched.

Run:  python benchmarks/bench_kernels.py [--runs 256] [--repeat 7]

Prints one table from one run, so ratios (2 threads vs 1, numba vs scipy) are
taken under the same machine load.  Times are medians over --repeat repeats,
after a warm-up call that compiles (or loads) the numba kernels.
"""
import argparse
import platform
import time

import numba
import numpy as np

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.scenes import build_scene

SCENES = {
    "heavy_top": dict(name="heavy_top", f=50.0, theta0=45.0),
    "free_symmetric": dict(name="free_symmetric", f=50.0, theta0=45.0),
    "free_asymmetric": dict(name="free_asymmetric", f=5.0, theta0=0.0),
}
DT = 1e-4


def median_ns_per_step(method, scene, n_runs, steps_per_run, repeat):
    """Median wall time per integration step (ns), aggregated over the batch."""
    bodies = np.tile(scene.body, (n_runs, 1))
    omega0 = np.tile(scene.omega0, (n_runs, 1))
    q0 = np.tile(scene.q0, (n_runs, 1))
    stride = steps_per_run // 10
    integrate(method, bodies, omega0, q0, DT, 1, 2)  # warm-up: compile or load cache
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        _, status, n_steps = integrate(method, bodies, omega0, q0, DT, stride, 11)
        times.append(time.perf_counter() - start)
        assert (status == 0).all()
    return np.median(times) / n_steps.sum() * 1e9


def dop853_cost(scene, t_end, rtol):
    """scipy DOP853 on the same equations: (µs per accepted step, ms per simulated second)."""
    from scipy.integrate import solve_ivp

    I = np.array(scene.body[:3])
    mgl = scene.body[3]

    def rhs(t, y):
        w, R = y[:3], y[3:].reshape(3, 3)
        gamma = R[2]
        tau = mgl * np.array([gamma[1], -gamma[0], 0.0])
        wdot = (tau - np.cross(w, I * w)) / I
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([wdot, (R @ W).ravel()])

    a, b, c, d = scene.q0
    R0 = np.array([
        [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
        [2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)],
        [2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - b * b - c * c],
    ])
    y0 = np.concatenate([scene.omega0, R0.ravel()])
    start = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=rtol)
    wall = time.perf_counter() - start
    return wall / (sol.t.size - 1) * 1e6, wall / t_end * 1e3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=256, help="runs in the batched measurement")
    parser.add_argument("--steps", type=int, default=200_000, help="steps of the single-trajectory measurement")
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()

    max_threads = numba.config.NUMBA_NUM_THREADS
    print(f"# gyrolab kernel benchmark: {platform.processor() or platform.machine()}, "
          f"{max_threads} numba threads available, numba {numba.__version__}, numpy {np.__version__}")
    print(f"# dt = {DT} s; single: 1 run x {args.steps} steps; batch: {args.runs} runs x "
          f"{args.steps // 20} steps; medians of {args.repeat}\n")
    print(f"| scene | method | single ns/step | batch 1 thread ns/step | batch 2 threads ns/step | 2-thread speed-up |")
    print("|---|---|---:|---:|---:|---:|")
    for scene_name, spec in SCENES.items():
        scene = build_scene(spec["name"], spec["f"], spec["theta0"])
        for method in METHODS:
            numba.set_num_threads(1)
            single = median_ns_per_step(method, scene, 1, args.steps, args.repeat)
            batch1 = median_ns_per_step(method, scene, args.runs, args.steps // 20, args.repeat)
            numba.set_num_threads(min(2, max_threads))
            batch2 = median_ns_per_step(method, scene, args.runs, args.steps // 20, args.repeat)
            print(f"| {scene_name} | {method} | {single:.1f} | {batch1:.1f} | {batch2:.1f} | {batch1 / batch2:.2f}x |")

    scene = build_scene("heavy_top", 50.0, 45.0)
    print("\n| reference | rtol | µs per accepted step | ms per simulated second |")
    print("|---|---:|---:|---:|")
    for rtol in (1e-6, 1e-9, 1e-12):
        per_step, per_second = dop853_cost(scene, 2.0, rtol)
        print(f"| scipy DOP853, heavy top 50 Hz | {rtol:g} | {per_step:.1f} | {per_second:.1f} |")


if __name__ == "__main__":
    main()
