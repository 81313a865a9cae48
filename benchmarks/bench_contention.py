"""numba's OpenMP threads spinning while another process wants the cores (gyrolab/__init__.py GOMP_SPINCOUNT).

    python benchmarks/bench_contention.py [--spins default,libgomp,passive] [--rounds 2]

numba runs every parallel kernel on its OpenMP layer; after a parallel region libgomp's threads spin for
GOMP_SPINCOUNT iterations before they sleep (300,000 unless set).  A run of many small batches (the
advisor's prediction: thousands of ``integrate`` calls of a few hundred one-step runs) is timed in a fresh
process for each setting (libgomp reads it when it loads), alone and beside a neighbour: a second process
doing the same in a loop with the same setting, as the test suite's two workers, two sweeps or two Dask
workers on one machine do.  ``default``: neither variable in the children's environment, so gyrolab sets
its own (the shipped setting); ``libgomp``: GOMP_SPINCOUNT=300000, libgomp's own default (gyrolab keeps a
count that is set); a number: that GOMP_SPINCOUNT; ``passive``: OMP_WAIT_POLICY=PASSIVE.
Prints the seconds of each (setting, alone/beside) as the median over the rounds.  Run it on an otherwise
quiet machine: the neighbour is the load.
"""

import argparse
import os
import statistics
import subprocess
import sys
import time

_PREDICT = """
import sys, time
import numpy as np
from gyrolab.analysis.advice.predict import predict_many
rng = np.random.default_rng(26)
n = 200
scale = 10 ** rng.uniform(-5, 3, n)
I = 10 ** rng.uniform(-1, 0, (n, 3)) * scale[:, None]
d = rng.normal(size=(n, 3))
d /= np.linalg.norm(d, axis=1)[:, None]
wn = 10 ** rng.uniform(-1, 3, n)
dt = 10 ** rng.uniform(-3, np.log10(0.3), n) / wn
w = d * wn[:, None]
predict_many("mujoco_implicit", I[:4], w[:4], dt[:4], n_max=20_000)  # load the kernels
loop = sys.argv[1] == "loop"
while True:
    start = time.perf_counter()
    predict_many("mujoco_implicit", I, w, dt, n_max=20_000)
    if not loop:
        print(time.perf_counter() - start)
        break
"""


def environment(spin):
    """The child's environment for a setting (see the module docstring)."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    if spin == "passive":
        env["OMP_WAIT_POLICY"] = "PASSIVE"
    elif spin == "libgomp":
        env["GOMP_SPINCOUNT"] = "300000"
    elif spin != "default":
        env["GOMP_SPINCOUNT"] = str(int(spin))
    return env


def timed(spin, beside):
    """Seconds of one prediction in a fresh process, with a neighbour doing the same if ``beside``."""
    env = environment(spin)
    neighbour = None
    if beside:
        neighbour = subprocess.Popen([sys.executable, "-c", _PREDICT, "loop"], env=env)
        time.sleep(3.0)  # past its imports and kernel loading: busy
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PREDICT, "once"], env=env, capture_output=True, text=True, check=True
        )
    finally:
        if neighbour is not None:
            neighbour.kill()
            neighbour.wait()
    return float(done.stdout.split()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spins", default="default,libgomp,passive")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    spins = [s for s in args.spins.split(",") if s]
    seconds = {(s, b): [] for s in spins for b in (False, True)}
    print(f"# load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} CPUs")
    for _ in range(args.rounds):
        for spin in spins:
            for beside in (False, True):
                seconds[spin, beside].append(timed(spin, beside))
    print(f"{'setting':>10} {'alone (s)':>10} {'beside a neighbour (s)':>24}")
    for spin in spins:
        alone, beside = (statistics.median(seconds[spin, b]) for b in (False, True))
        print(f"{spin:>10} {alone:10.2f} {beside:24.2f}")


if __name__ == "__main__":
    main()
