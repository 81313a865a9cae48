"""Cost of a step and cost of an accuracy: gyrolab's kernels against scipy's DOP853 and MuJoCo's RK4.

Run:  python benchmarks/bench_kernels.py [--runs 256] [--repeat 7] [--quick] [--sections kernels,nutation,energy]

Prints, from one process (so that every ratio is taken under the same machine load):
1. ns per step of every method on the heavy top and the two free bodies: one run alone (the scalar
   single-trajectory kernel, run_batch), 256 runs one by one on 2 threads (run_batch), and 256 runs in
   blocks (run_blocks, the default of integrate) on 1 and 2 threads; aggregate over all runs;
2. the cost (CPU time per simulated second) of reaching 1e-6, 1e-8 and 1e-9 relative error in the
   nutation bounds θ_min, θ_max of the heavy top (50 Hz, 45°, released, 1 s, against the closed form),
   each method at the dt that reaches it, against scipy DOP853 at the tolerance that reaches it;
3. the same at 1e-6 and 1e-9 relative energy error (max over 1 s), against MuJoCo's RK4 through
   mujoco.rollout when mujoco is installed (an optional peer, never a dependency).
Times are medians of --repeat repeats after a warm-up call (JIT compile or cache load).
"""

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time

import llvmlite.binding as llvm
import numba
import numpy as np

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.scenes import build_scene

import mujoco_peer
import precision

SCENES = {
    "heavy_top": ("heavy_top", 50.0, 45.0),
    "free_symmetric": ("free_symmetric", 50.0, 45.0),
    "free_asymmetric": ("free_asymmetric", 5.0, 0.0),
}
DT = 1e-4
NUTATION_TARGETS = (1e-6, 1e-8, 1e-9)
ENERGY_TARGETS = (1e-6, 1e-9)
T_ACCURACY = 1.0  # simulated seconds of the accuracy runs
MAX_SCAN_STEPS = 20_000_000


def batch_inputs(scene_name, f, theta0, n_runs):
    """n runs of a scene with spins spread over f ± 5 % (distinct runs, same cost)."""
    spins = f * (1.0 + 0.1 * (np.arange(n_runs) / max(n_runs - 1, 1) - 0.5))
    scenes = [build_scene(scene_name, s, theta0) for s in spins]
    return (np.array([s.body for s in scenes]), np.array([s.omega0 for s in scenes]), np.array([s.q0 for s in scenes]))


def ns_per_step(method, inputs, dt, steps, threads, path, repeat):
    """Median wall time per step (ns) of integrate(), aggregate over all runs of the batch."""
    bodies, omega0, q0 = inputs
    numba.set_num_threads(threads)
    integrate(method, bodies, omega0, q0, dt, 1, 2, path=path)  # warm-up: compile or load the cache
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        _, status, n_steps = integrate(method, bodies, omega0, q0, dt, max(steps // 10, 1), 11, path=path)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / int(n_steps.sum()) * 1e9


def header(args):
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    commit = subprocess.run(
        ["git", "describe", "--always", "--dirty"],
        capture_output=True,
        text=True,
        cwd=os.path.dirname(os.path.abspath(__file__)),
    ).stdout.strip()
    print(f"# gyrolab kernel benchmark, {datetime.datetime.now().isoformat(timespec='seconds')}, commit {commit}")
    print(f"# command: python benchmarks/{os.path.basename(sys.argv[0])} {' '.join(sys.argv[1:])}".rstrip())
    print(
        f"# machine: {cpu}, {os.cpu_count()} CPUs, {numba.config.NUMBA_NUM_THREADS} numba threads, "
        f"LLVM target {llvm.get_host_cpu_name()}"
    )
    versions = f"numba {numba.__version__}, numpy {np.__version__}"
    try:
        import scipy

        versions += f", scipy {scipy.__version__}"
    except ImportError:
        pass
    if mujoco_peer.available():
        import mujoco

        versions += f", mujoco {mujoco.__version__}"
    else:
        versions += ", mujoco not installed"
    print(f"# {versions}")
    print(f"# load average at start (1, 5, 15 min): {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def kernel_table(args):
    print(
        f"\n## 1. ns per step (dt = {DT} s; aggregate wall time / steps of all runs; {args.runs} runs in a "
        f"batch, spins f ± 5 %)\n"
    )
    print(
        "| scene | method | single run | runs one by one, 2 threads | blocks, 1 thread | blocks, 2 threads "
        "| 2-thread speed-up | blocks 2 thr vs single |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    single_steps, batch_steps = args.steps, max(args.steps * 40 // args.runs, 100)
    threads = min(2, numba.config.NUMBA_NUM_THREADS)
    for scene_name, (name, f, theta0) in SCENES.items():
        one, many = batch_inputs(name, f, theta0, 1), batch_inputs(name, f, theta0, args.runs)
        for method in METHODS:
            single = ns_per_step(method, one, DT, single_steps, 1, "runs", args.repeat)
            runs2 = ns_per_step(method, many, DT, batch_steps, threads, "runs", args.repeat)
            block1 = ns_per_step(method, many, DT, batch_steps, 1, "blocks", args.repeat)
            block2 = ns_per_step(method, many, DT, batch_steps, threads, "blocks", args.repeat)
            print(
                f"| {scene_name} | {method} | {single:.1f} | {runs2:.1f} | {block1:.2f} | {block2:.2f} | "
                f"{block1 / block2:.2f}x | {single / block2:.0f}x |",
                flush=True,
            )


def balance_table(args):
    """Mixed step counts and diverging runs: the blocks' load balance on 2 threads."""
    name, f, theta0 = SCENES["heavy_top"]
    bodies, omega0, q0 = batch_inputs(name, f, theta0, args.runs)
    threads = min(2, numba.config.NUMBA_NUM_THREADS)
    every, t_end = 2e-2, 2.0 if not args.quick else 0.2
    n_samples = int(round(t_end / every)) + 1

    def wall(dt, nthreads, threshold):
        stride = np.rint(every / dt).astype(np.int64)
        numba.set_num_threads(nthreads)
        integrate("seed_next", bodies, omega0, q0, dt, stride, 2)
        times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            _, status, n_steps = integrate("seed_next", bodies, omega0, q0, dt, stride, n_samples, threshold)
            times.append(time.perf_counter() - start)
        return float(np.median(times)), status, int(n_steps.sum())

    print(f"\n## 1b. Load balance: seed_next, heavy top, {args.runs} runs, {t_end:g} s, samples every {every:g} s\n")
    print("| batch | steps done | ns/step, 1 thread | ns/step, 2 threads | speed-up |")
    print("|---|---:|---:|---:|---:|")
    mixed = np.resize([1e-4, 2e-4, 2.5e-4, 5e-4], args.runs)
    half_bad = np.where(np.arange(args.runs) % 2 == 0, 1e-4, 2e-2)  # dt = 2e-2: ω dt = 6 rad, blows up
    for label, dt, threshold in [
        ("all dt = 1e-4 s", np.full(args.runs, 1e-4), 10.0),
        ("dt 1e-4, 2e-4, 2.5e-4, 5e-4 s mixed", mixed, 10.0),
        ("every other run at dt = 2e-2 s", half_bad, 10.0),
    ]:
        w1, status, steps = wall(dt, 1, threshold)
        w2, _, _ = wall(dt, threads, threshold)
        extra = f" ({int((status != 0).sum())} diverged)" if (status != 0).any() else ""
        print(
            f"| {label}{extra} | {steps} | {w1 / steps * 1e9:.2f} | {w2 / steps * 1e9:.2f} | {w1 / w2:.2f}x |",
            flush=True,
        )


def ladders(args):
    """{method: [(dt, nutation bound error, energy error)]} on the heavy top, dt halving from 3.2e-2 s."""
    scene = build_scene(*SCENES["heavy_top"])
    out = {}
    for method in METHODS:
        rows, dt = [], 3.2e-2
        while T_ACCURACY / dt <= (MAX_SCAN_STEPS if not args.quick else MAX_SCAN_STEPS // 20):
            nut, en = precision.scan(method, scene, dt, T_ACCURACY)
            rows.append((dt, nut, en))
            if nut < 1e-10 and en < 1e-10:
                break
            dt /= 2
        out[method] = rows
    return out


def cost_at(method, dt, args, cache={}):
    """(single-run ns/step, blocks-on-1-thread ns/step) at step dt on the heavy top."""
    key = (method, dt)
    if key not in cache:
        name, f, theta0 = SCENES["heavy_top"]
        single = ns_per_step(method, batch_inputs(name, f, theta0, 1), dt, args.steps // 2, 1, "runs", args.repeat)
        block = ns_per_step(method, batch_inputs(name, f, theta0, 64), dt, args.steps // 20, 1, "blocks", args.repeat)
        cache[key] = (single, block)
    return cache[key]


def _fmt_dt(dt, flag):
    return "—" if dt is None else f"{flag}{dt:.3g}"


def accuracy_tables(args, sections):
    lad = ladders(args)
    scene = build_scene(*SCENES["heavy_top"])
    if "nutation" in sections:
        print(
            f"\n## 2. Cost of an accuracy: relative error of the nutation bounds θ_min, θ_max (heavy top 50 Hz, "
            f"45°, released, {T_ACCURACY:g} s, against the closed form)\n"
        )
        print(
            "dt: the step that reaches the error, log-log interpolated between the two dt of the ladder "
            "(halving from 3.2e-2 s) that bracket it; `~`: extrapolated beyond the finest dt with the last "
            "slope; `<=`: already reached at the coarsest. Cost in ms of CPU per simulated second: "
            "single run (run_batch), and per run in a batch of 64 (blocks, 1 thread).\n"
        )
        dop = [(rtol,) + precision.dop853_point(scene, T_ACCURACY, rtol) for rtol in 10.0 ** -np.arange(4, 14.0)]
        print(
            "| error | method | dt (s) | ns/step single | ns/step batched | ms/sim-s single | "
            "ms/sim-s batched | DOP853 / single | DOP853 / batched |"
        )
        print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
        for target in NUTATION_TARGETS:
            tol, tflag = precision.dt_for([(r, e) for r, _, e, _ in dop], target)
            dop_cost = _interp_cost([(r, c) for r, c, _, _ in dop], tol)
            for method in METHODS:
                dt, flag = precision.dt_for([(d, n) for d, n, _ in lad[method]], target)
                _row(target, method, dt, flag, dop_cost * 1e3, args)
            print(
                f"| {target:g} | scipy DOP853 | rtol {_fmt_dt(tol, tflag)} | | | {dop_cost * 1e3:.3g} | | | |",
                flush=True,
            )
    if "energy" in sections:
        print(
            f"\n## 3. Cost of an accuracy: max relative energy error over {T_ACCURACY:g} s (heavy top 50 Hz, "
            f"45°, released)\n"
        )
        mj = []
        if mujoco_peer.available():
            dt = 4e-3
            while dt >= 1e-5:
                err, ns = mujoco_peer.energy_error(scene, dt, T_ACCURACY)
                mj.append((dt, err, ns))
                if err < 1e-10:
                    break
                dt /= 2
        else:
            print("mujoco is not installed (`pip install mujoco` for MuJoCo's RK4 as a peer).\n")
        print(
            "| energy error | method | dt (s) | ns/step single | ns/step batched | ms/sim-s single | "
            "ms/sim-s batched | MuJoCo / single | MuJoCo / batched |"
        )
        print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
        for target in ENERGY_TARGETS:
            mj_cost, mj_row = None, ""
            if mj:
                dt, flag = precision.dt_for([(d, e) for d, e, _ in mj], target)
                if dt is not None:
                    scene_ = build_scene(*SCENES["heavy_top"])
                    single = mujoco_peer.ns_per_step(scene_, dt, 1, 1, args.steps // 20, args.repeat)
                    batched = mujoco_peer.ns_per_step(scene_, dt, 64, 1, args.steps // 200, args.repeat)
                    mj_cost = single / dt * 1e-6
                    mj_row = (
                        f"| {target:g} | MuJoCo RK4 (mujoco.rollout) | {_fmt_dt(dt, flag)} | {single:.0f} | "
                        f"{batched:.0f} | {mj_cost:.3g} | {batched / dt * 1e-6:.3g} | | |"
                    )
            for method in METHODS:
                dt, flag = precision.dt_for([(d, e) for d, _, e in lad[method]], target)
                _row(target, method, dt, flag, mj_cost, args)
            if mj_row:
                print(mj_row, flush=True)
    print("\n### dt ladders (heavy top, 1 s): dt, nutation bound error, energy error\n")
    for method, rows in lad.items():
        print(f"- {method}: " + "; ".join(f"{d:.3g}: {n:.2g}, {e:.2g}" for d, n, e in rows))
    if "nutation" in sections:
        print(
            "- scipy DOP853 (rtol = atol: ms per sim-s, nutation bound error, steps): "
            + "; ".join(f"{r:.0e}: {c * 1e3:.3g}, {e:.2g}, {n}" for r, c, e, n in dop)
        )
    if "energy" in sections and mj:
        print(
            "- MuJoCo RK4 (dt: energy error, ns/step): " + "; ".join(f"{d:.3g}: {e:.2g}, {ns:.0f}" for d, e, ns in mj)
        )


def _interp_cost(points, x):
    """Cost at tolerance x, log-log interpolated in the (tolerance, cost) points."""
    if x is None:
        return float("nan")
    xs, cs = np.log([p[0] for p in points])[::-1], np.log([p[1] for p in points])[::-1]
    return float(np.exp(np.interp(np.log(x), xs, cs)))


def _row(target, method, dt, flag, peer_ms, args):
    if dt is None:
        print(f"| {target:g} | {method} | not reached | | | | | | |", flush=True)
        return
    single, block = cost_at(method, float(f"{dt:.3g}"), args)
    ms_single, ms_block = single / dt * 1e-6, block / dt * 1e-6
    ratios = f"{_ratio(peer_ms / ms_single)} | {_ratio(peer_ms / ms_block)}" if peer_ms else " | "
    print(
        f"| {target:g} | {method} | {_fmt_dt(dt, flag)} | {single:.1f} | {block:.2f} | {ms_single:.3g} | "
        f"{ms_block:.3g} | {ratios} |",
        flush=True,
    )


def _ratio(r):
    return f"{r:.0f}x" if r >= 10 else f"{r:.2g}x"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=256, help="runs in the batched measurements of table 1")
    parser.add_argument("--steps", type=int, default=200_000, help="steps of a single-run measurement")
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--quick", action="store_true", help="few repeats and short ladders (a smoke run)")
    parser.add_argument("--sections", default="kernels,nutation,energy")
    args = parser.parse_args()
    if args.quick:
        args.repeat, args.steps = 3, 20_000
    sections = set(args.sections.split(","))
    header(args)
    if "kernels" in sections:
        kernel_table(args)
        balance_table(args)
    if sections & {"nutation", "energy"}:
        accuracy_tables(args, sections)
    print(f"\n# load average at end (1, 5, 15 min): {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
