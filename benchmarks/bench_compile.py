"""Cold compile time of methods' kernels, for A/B runs across versions.

Each (method, round) compiles in a fresh interpreter with an empty ``NUMBA_CACHE_DIR`` (a temporary
directory), one after the other, so nothing is shared between measurements: the seconds are what a
user's first run of that method costs (the run, block and driven kernels the method has, through
runner/compile.py's ``compile_one``; the first kernel of a process also compiles the helpers every
method shares).  Compiling is one thread: run it on a quiet machine, or read the CPU seconds.

    python benchmarks/bench_compile.py --methods strang_exact,rk4 --rounds 3
    python benchmarks/bench_compile.py --methods rk4 --paths runs            # one kernel (runs, blocks, driven)

A/B: put each version's package on ``PYTHONPATH`` and alternate the runs (docs/benchmarks.md).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

_ONE = """
import json, resource, sys, time
from gyrolab.runner.compile import cold_kernels, compile_one
name = sys.argv[1]
paths = sys.argv[2].split(",") if len(sys.argv) > 2 else cold_kernels([name]).get(name, [])
_, seconds = compile_one(name, paths)
cpu = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"paths": paths, "wall": seconds, "cpu": cpu.ru_utime + cpu.ru_stime}))
"""


def compile_cold(method, paths=()):
    """{"paths", "wall", "cpu"}: one cold compile of ``method``'s kernels (those of ``paths``, e.g.
    ["runs", "blocks"]; default: all it has) in a fresh process and cache."""
    with tempfile.TemporaryDirectory(prefix="gyrolab-bench-compile-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        done = subprocess.run(
            [sys.executable, "-c", _ONE, method, *([",".join(paths)] if paths else [])],
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode:
            raise SystemExit(f"bench_compile: {method} failed: {done.stderr.strip().splitlines()[-1]}")
        return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default="strang_exact,rk4")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--paths", default="", help="only these kernels, e.g. runs,blocks (default: all)")
    args = parser.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    paths_wanted = [p for p in args.paths.split(",") if p]
    wall = {m: [] for m in methods}
    cpu = {m: [] for m in methods}
    paths = {}
    for _ in range(args.rounds):
        for method in methods:
            one = compile_cold(method, paths_wanted)
            paths[method] = one["paths"]
            wall[method].append(one["wall"])
            cpu[method].append(one["cpu"])
            print(
                f"{method:20s} {'+'.join(one['paths']):20s} {one['wall']:7.1f} s wall {one['cpu']:7.1f} s CPU",
                flush=True,
            )
    print(f"median of {args.rounds}:")
    for method in methods:
        print(
            f"{method:20s} {'+'.join(paths[method]):20s} {statistics.median(wall[method]):7.1f} s wall "
            f"{statistics.median(cpu[method]):7.1f} s CPU"
        )


if __name__ == "__main__":
    main()
