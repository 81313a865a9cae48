"""Cost of the exact free rigid-body flow (kernels/euler_poinsot.py) and of the exact Strang splitting.

Run:  python benchmarks/bench_free_body.py [--runs 256] [--steps 2000] [--repeat 5] [--no-lanes] [--baseline REV]

Prints, from one process (ratios are taken under the same machine load):
1. ns per step of one exact free-flow step (free_flow_exact as a step) against one rk4 step, both in the
   same batched njit prange harness (runs × steps, each run its own (ω, q), aggregate wall time / steps),
   1 and 2 threads, on generic asymmetric bodies (random moments and rates);
   then the same at ‖ω‖dt from 0.005 to 1.5 rad (|ω| = 10 rad/s, dt scaled), where the step's |λh| goes
   from the very short to the longest the short-step branch takes (|λh| < SHORT_STEP, a few bodies past it
   at 1.5 rad before SHORT_STEP was raised to 2); with --baseline REV, the exact flow of
   kernels/euler_poinsot.py at git revision REV timed in the same process, alternating with today's, and
   today's file loaded the same way ("exact, copied"): compare REV with that column.  A copy (the file
   re-imported from a scratch directory, its relative imports pointed at the installed package) measured
   12-16 % slower than the same source installed (2026-12-05, cause not found), so the installed column
   flatters today's code against REV; for an A/B of installed packages, ``pip install --target DIR`` the
   other revision and run this script with ``PYTHONPATH=DIR``;
1c. the exact flow at a fixed |λh| (each body's ω scaled so that its elliptic argument advances by λh per
   step: the cost of the short branch's doublings, of its pieces from SHORT_STEP to SHORT_STEP·SHORT_PIECES,
   and of a step past them: since 2026-12-06 (later) its whole half periods 2K dropped (K and Π − K from one
   AGM) and the rest by the short branch or its pieces, before that K, R_F and two or three R_J);
2. the exact Strang splitting (strang_exact) against lie_poisson (axis sub-splitting) on the asymmetric
   box of the free_asymmetric scene, I = (1e-4, 3e-4, 2e-4), ω = (1e-3 ω3, 0, ω3), f = 10 Hz ± 5 %,
   dt = 1e-4, in the same harness;
3. (unless --no-lanes) the compile time of ``lanes.lane_step(step)`` (the forceinline recompilation of the
   vectorised block path) for strang_exact, called in a loop over a small array, and its ns/step there.
Times are medians of --repeat repeats after a warm-up call.  On the 2-core Xeon of 2026-12-05 a change of
euler_poinsot.py's line numbers alone (one comment line) moved every row of the exact flow by 5-8 %, the
same in every run of a build: compare a change with a control build of the old code so shifted, not only
with the old build (docs/benchmarks.md, "the short branch up to |λh| = 2").  Found on 2026-12-06 (AMD EPYC
VM): the exact flow's rows depended by ~20 % on how its code was compiled: with a fresh cache this script
compiled the flow together with its harness (the slower case); if a method that uses the flow (strang_exact,
whose step_driven is forceinline) ran first with the same NUMBA_CACHE_DIR, the faster.  Since
free_flow_exact is forceinline too, every caller gets the faster case; for a build before that, compare in
the same case (docs/benchmarks.md, "2026-12-06: the exact flow's chain").
"""

import argparse
import importlib.util
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

from gyrolab.kernels.body import N_FIELDS, body_row
from gyrolab.kernels.euler_poinsot import SERIES_BASE, SHORT_STEP, elliptic_rate, free_flow_exact

try:
    from gyrolab.kernels.euler_poinsot import SHORT_PIECES
except ImportError:  # before the short branch went in pieces (2026-12-06)
    SHORT_PIECES = 1
from gyrolab.kernels.methods import lie_poisson, strang_exact

try:
    from gyrolab.kernels.methods import rk4
except ImportError:  # before the methods/ refactor
    from gyrolab.kernels import rk4


@njit(cache=True, error_model="numpy")
def exact_free_step(w, q, dt, body):
    return free_flow_exact(w, q, dt, body)


def make_harness(step):
    @njit(parallel=True, error_model="numpy")
    def harness(W, Q, B, dt, n_steps):
        for i in prange(W.shape[0]):
            w = (W[i, 0], W[i, 1], W[i, 2])
            q = (Q[i, 0], Q[i, 1], Q[i, 2], Q[i, 3])
            body = body_row(B, i)
            for _ in range(n_steps):
                w, q = step(w, q, dt, body)
            W[i, 0], W[i, 1], W[i, 2] = w
            Q[i, 0], Q[i, 1], Q[i, 2], Q[i, 3] = q

    return harness


def ns_per_step(harness, inputs, dt, steps, threads, repeat):
    W0, Q0, B = inputs
    numba.set_num_threads(threads)
    harness(W0.copy(), Q0.copy(), B, dt, 1)
    times = []
    for _ in range(repeat):
        W, Q = W0.copy(), Q0.copy()
        start = time.perf_counter()
        harness(W, Q, B, dt, steps)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / (steps * W0.shape[0]) * 1e9


def generic_inputs(n, seed=0):
    rng = np.random.default_rng(seed)
    B = np.zeros((n, N_FIELDS))
    B[:, :3] = rng.uniform(1.0, 3.0, (n, 3))
    W = rng.normal(size=(n, 3)) * 10.0
    Q = rng.normal(size=(n, 4))
    return W, Q / np.linalg.norm(Q, axis=1, keepdims=True), B


def baseline_free_flow(rev, workdir):
    """free_flow_exact of kernels/euler_poinsot.py at git revision rev, its relative imports pointed at
    today's installed package (they must still exist there), as a step function; the file goes in workdir.
    Raises ValueError with one line when the revision or its file cannot be read or imported."""
    if rev.startswith("-"):  # git would read it as an option (--output=FILE writes a file)
        raise ValueError(f"--baseline {rev}: not a revision")
    repo = Path(__file__).resolve().parent.parent
    shown = subprocess.run(
        ["git", "-C", str(repo), "show", f"{rev}:kernels/euler_poinsot.py"], capture_output=True, text=True
    )
    if shown.returncode != 0:
        raise ValueError(
            f"--baseline {rev}: {shown.stderr.strip().splitlines()[-1] if shown.stderr else 'git show failed'}"
        )
    try:
        flow = copied_free_flow(shown.stdout, "baseline_euler_poinsot", workdir)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"--baseline {rev}: its euler_poinsot.py does not load against today's package: {exc}")
    return _as_step(flow)


def copied_free_flow(source, name, workdir):
    """free_flow_exact of the euler_poinsot.py text ``source``, imported as module ``name`` from workdir with
    its relative imports pointed at the installed package."""
    path = Path(workdir) / f"{name}.py"
    path.write_text(source.replace("from .", "from gyrolab.kernels."))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.free_flow_exact


def _as_step(flow):
    """A step function (w, q, dt, body) -> (w, q) of the exact flow ``flow``."""

    @njit(error_model="numpy")
    def step(w, q, dt, body):
        return flow(w, q, dt, body)

    return step


def box_inputs(n):
    spins = 10.0 * (1.0 + 0.1 * (np.arange(n) / max(n - 1, 1) - 0.5))
    om3 = 2 * math.pi * spins
    W = np.stack([1e-3 * om3, np.zeros(n), om3], axis=1)
    Q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    B = np.tile([1e-4, 3e-4, 2e-4, 0.0, 0.0, 0.0], (n, 1))
    return W, Q, B


def lane_compile(step, n_lanes=8, steps=2000):
    """Seconds to compile lane_step(step) inside a loop over a small array, and its ns/step there."""
    from gyrolab.kernels.lanes import lane_step

    start = time.perf_counter()
    fast = lane_step(step)

    @njit(error_model="numpy")
    def loop(W, Q, B, dt, n_steps):
        for _ in range(n_steps):
            for j in range(W.shape[0]):
                w, q = fast(
                    (W[j, 0], W[j, 1], W[j, 2]),
                    (Q[j, 0], Q[j, 1], Q[j, 2], Q[j, 3]),
                    dt,
                    body_row(B, j),
                )
                W[j, 0], W[j, 1], W[j, 2] = w
                Q[j, 0], Q[j, 1], Q[j, 2], Q[j, 3] = q

    W, Q, B = box_inputs(n_lanes)
    loop(W, Q, B, 1e-4, 1)
    compile_s = time.perf_counter() - start
    W, Q, B = box_inputs(n_lanes)
    start = time.perf_counter()
    loop(W, Q, B, 1e-4, steps)
    ns = (time.perf_counter() - start) / (steps * n_lanes) * 1e9
    finite = bool(np.all(np.isfinite(W)) and np.all(np.isfinite(Q)))
    return compile_s, ns, finite


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=256)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-lanes", action="store_true")
    parser.add_argument("--baseline", metavar="REV", help="also time the exact flow of this git revision")
    args = parser.parse_args()
    workdir = tempfile.TemporaryDirectory(prefix="bench_free_body_")
    baseline = None
    if args.baseline:  # before any timing: a bad revision is one line, not a traceback after minutes
        try:
            baseline = baseline_free_flow(args.baseline, workdir.name)
        except ValueError as exc:
            parser.exit(2, f"bench_free_body: {exc}\n")
    threads = [1, 2] if numba.config.NUMBA_NUM_THREADS >= 2 else [1]
    print(
        f"# bench_free_body: {args.runs} runs x {args.steps} steps, medians of {args.repeat}; "
        f"{os.cpu_count()} CPUs; load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )

    print("\n## 1. one step, generic asymmetric bodies (dt = 1e-3)\n")
    print("| step | " + " | ".join(f"{t} thread(s) ns/step" for t in threads) + " |")
    print("|---|" + "---:|" * len(threads))
    inputs = generic_inputs(args.runs)
    table = {}
    for name, step in (("rk4", rk4.step), ("exact free flow", exact_free_step)):
        harness = make_harness(step)
        table[name] = [ns_per_step(harness, inputs, 1e-3, args.steps, t, args.repeat) for t in threads]
        print(f"| {name} | " + " | ".join(f"{v:.1f}" for v in table[name]) + " |", flush=True)
    print(
        "| ratio exact / rk4 | "
        + " | ".join(f"{a / b:.1f}x" for a, b in zip(table["exact free flow"], table["rk4"]))
        + " |"
    )

    print("\n## 1b. exact free flow / rk4 per step against ‖ω‖dt (|ω| = 10 rad/s, 1 thread)\n")
    W, Q, B = generic_inputs(args.runs)
    inputs = (10.0 * W / np.linalg.norm(W, axis=1, keepdims=True), Q, B)
    steps = {"rk4": rk4.step, "exact": exact_free_step}
    if baseline is not None:
        today = Path(importlib.util.find_spec("gyrolab.kernels.euler_poinsot").origin).read_text()
        steps["exact, copied"] = _as_step(copied_free_flow(today, "today_euler_poinsot", workdir.name))
        steps[f"exact at {args.baseline}"] = baseline
    harnesses = {name: make_harness(step) for name, step in steps.items()}
    names = list(steps)
    print(
        "| ‖ω‖dt (rad) | "
        + " | ".join(f"{name} ns/step" for name in names)
        + " | "
        + " | ".join(f"{name} / rk4" for name in names[1:])
        + " |"
    )
    print("|---:|" + "---:|" * (2 * len(names) - 1))
    for wdt in (0.005, 0.02, 0.05, 0.1, 0.15, 0.3, 0.6, 0.9, 1.5):
        ns = {name: ns_per_step(harnesses[name], inputs, wdt / 10.0, args.steps, 1, args.repeat) for name in names}
        print(
            f"| {wdt} | "
            + " | ".join(f"{ns[name]:.1f}" for name in names)
            + " | "
            + " | ".join(f"{ns[name] / ns['rk4']:.1f}x" for name in names[1:])
            + " |",
            flush=True,
        )

    print(
        f"\n## 1c. exact free flow against |λh| (SHORT_STEP = {SHORT_STEP:g}, SHORT_PIECES = {SHORT_PIECES}; "
        "dt = 1e-2, 1 thread)\n"
    )
    print("| \\|λh\\| | pieces × doublings | exact ns/step | exact / rk4 at 1b's 0.005 rad |")
    print("|---:|---:|---:|---:|")
    W, Q, B = generic_inputs(args.runs)
    rates = np.array([elliptic_rate(B[i, :3], W[i]) for i in range(args.runs)])
    harness = harnesses["exact"]
    rk4_ns = ns_per_step(harnesses["rk4"], inputs, 0.005 / 10.0, args.steps, 1, args.repeat)
    for lam_h in (0.02, 0.1, 0.5, 0.9, 1.1, 1.5, 1.9, 2.1, 3.0, 3.9, 5.0, 7.5, 8.5, 12.0, 30.0, 100.0):
        scaled = (W * (lam_h / (rates * 1e-2))[:, None], Q, B)
        ns = ns_per_step(harness, scaled, 1e-2, args.steps, 1, args.repeat)
        pieces = 1 if lam_h < SHORT_STEP else int(lam_h / SHORT_STEP) + 1
        doublings = max(math.ceil(math.log2(lam_h / pieces / SERIES_BASE)), 0)
        # past the pieces: whole half periods 2K dropped and the rest, |r| ≤ K (K differs from body to body), by the
        # short branch or its pieces (K ≥ HALF_PERIODS_BELOW, or a build before 2026-12-06: the long branch)
        doublings = f"{pieces} × {doublings}" if lam_h < SHORT_STEP * SHORT_PIECES else "2K·N + r"
        print(f"| {lam_h} | {doublings} | {ns:.1f} | {ns / rk4_ns:.1f}x |", flush=True)

    print("\n## 2. asymmetric box, f = 10 Hz, dt = 1e-4\n")
    print("| method | " + " | ".join(f"{t} thread(s) ns/step" for t in threads) + " |")
    print("|---|" + "---:|" * len(threads))
    inputs = box_inputs(args.runs)
    table = {}
    for name, step in (("lie_poisson", lie_poisson.step), ("strang_exact", strang_exact.step), ("rk4", rk4.step)):
        harness = make_harness(step)
        table[name] = [ns_per_step(harness, inputs, 1e-4, args.steps, t, args.repeat) for t in threads]
        print(f"| {name} | " + " | ".join(f"{v:.1f}" for v in table[name]) + " |", flush=True)
    print(
        "| ratio strang_exact / lie_poisson | "
        + " | ".join(f"{a / b:.1f}x" for a, b in zip(table["strang_exact"], table["lie_poisson"]))
        + " |"
    )

    if not args.no_lanes:
        print("\n## 3. lanes.lane_step (forceinline recompilation for the block path)\n")
        for name, step in (("lie_poisson", lie_poisson.step), ("strang_exact", strang_exact.step)):
            seconds, ns, finite = lane_compile(step)
            print(
                f"- {name}: compile {seconds:.1f} s, {ns:.1f} ns/step (8 lanes, scalar loop), finite: {finite}",
                flush=True,
            )


if __name__ == "__main__":
    main()
