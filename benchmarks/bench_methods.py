"""ns per step of chosen methods through the public batch entry, for A/B runs across versions.

    python benchmarks/bench_methods.py --methods seed_next,rk4,lie_poisson --repeat 7

Only ``gyrolab.kernels.batch.integrate`` and ``gyrolab.kernels.scenes.build_scene`` are used, so the
same script times any gyrolab version (run it with each version's interpreter, alternately, and
compare medians taken under the same load).  Rows: scene x method x path (256 runs in blocks on all
numba threads; 256 runs one by one); heavy top f = 10 Hz, free asymmetric box f = 10 Hz (``--scenes``:
any registered scene, e.g. heavy_body, whose centre of mass off e3 takes the general path; ``--f``),
θ0 = 45°, dt = 1e-4 s (``--dt``), 2000 steps per run, aggregate ns per step over all runs (median of --repeat after a
warm-up call that compiles or loads the kernels).
"""

import argparse
import statistics
import time

import numba
import numpy as np

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.scenes import build_scene


def time_path(method, scene, path, runs, steps, repeat, f=10.0, dt=1e-4):
    sc = build_scene(scene, f, 45.0)
    args = (
        np.tile(sc.body, (runs, 1)),
        np.tile(sc.omega0, (runs, 1)) * np.linspace(0.9, 1.1, runs)[:, None],
        np.tile(sc.q0, (runs, 1)),
        dt,
        steps // 4,
        5,
        1e9,
    )
    integrate(method, *args, path=path)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        integrate(method, *args, path=path)
        times.append(time.perf_counter() - start)
    return statistics.median(times) / (runs * steps) * 1e9


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default="seed_next,seed_prev,rk4,lie_poisson,lie_poisson4")
    parser.add_argument("--runs", type=int, default=256)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--scenes", default="heavy_top,free_asymmetric")
    parser.add_argument("--paths", default="blocks,runs", help="blocks and/or runs (one by one)")
    parser.add_argument("--f", type=float, default=10.0, help="spin (Hz)")
    parser.add_argument("--dt", type=float, default=1e-4, help="step (s)")
    args = parser.parse_args()
    paths = args.paths.split(",")
    what = f"f = {args.f:g} Hz, dt = {args.dt:g} s; ns/step aggregate, median of {args.repeat}"
    print(f"threads {numba.get_num_threads()}; {what}")
    for scene in args.scenes.split(","):
        for method in args.methods.split(","):
            row = {
                path: time_path(method, scene, path, args.runs, args.steps, args.repeat, args.f, args.dt)
                for path in paths
            }
            print(f"{scene:16s} {method:36s} " + "  ".join(f"{p} {t:7.2f}" for p, t in row.items()), flush=True)


if __name__ == "__main__":
    main()
