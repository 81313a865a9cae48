"""Where a method's cold compile goes: seconds per numba function, and how often each was compiled.

numba compiles every function a kernel calls as a library of its own (typed, lowered, optimised and
emitted as machine code), and a caller then optimises and emits again the code of all it calls.  This
script listens to numba's compile events while one method's kernels compile on an empty cache and
prints each function's exclusive seconds (its own compile, less the compiles it triggered) and its
number of compiles; a count above one with the same arguments is a function compiled twice for types
that differ only in literal-ness or signedness (kernels/entry.py, kernels/block.py).

    python benchmarks/profile_compile.py seed_next blocks
    python benchmarks/profile_compile.py strang_exact runs,driven --top 20 --signatures

The paths not asked for but compiled first (``runs``, unless asked) are outside the profile: they fill
the shared helpers, as in a compile worker.  One thread; run it on a quiet machine.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

_IN_EMPTY_CACHE = "GYROLAB_PROFILE_COMPILE_CHILD"


def profile(method, paths):
    """{function: [exclusive seconds, compiles, [argument types]]} and the total seconds of compiling
    ``method``'s kernels of ``paths`` (after its run kernel, unless ``paths`` has it)."""
    from numba.core import event

    from gyrolab.runner.compile import compile_one

    if "runs" not in paths:
        compile_one(method, ["runs"])
    stack, table = [], {}

    class Listener(event.Listener):
        def on_start(self, ev):
            func = ev.data["dispatcher"].py_func
            stack.append([f"{func.__module__.rsplit('.', 1)[-1]}.{func.__qualname__}", time.perf_counter(), 0.0])

        def on_end(self, ev):
            name, start, children = stack.pop()
            seconds = time.perf_counter() - start
            row = table.setdefault(name, [0.0, 0, []])
            row[0] += seconds - children
            row[1] += 1
            row[2].append(str(ev.data["args"]))
            if stack:
                stack[-1][2] += seconds

    start = time.perf_counter()
    with event.install_listener("numba:compile", Listener()):
        compile_one(method, paths)
    return table, time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("method")
    parser.add_argument("paths", help="kernels to profile, e.g. blocks or runs,driven")
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--signatures", action="store_true", help="the argument types of each repeated compile")
    args = parser.parse_args(argv)
    from gyrolab.kernels.registry import METHODS
    from gyrolab.runner.compile import PATHS

    if args.method not in METHODS:
        parser.error(f"unknown method {args.method!r} (one of: {', '.join(METHODS)})")
    if not set(args.paths.split(",")) <= set(PATHS):
        parser.error(f"paths {args.paths!r}: a comma-separated list of {', '.join(PATHS)}")
    if os.environ.get(_IN_EMPTY_CACHE) is None:  # numba reads its cache folder at import: a child of our own
        with tempfile.TemporaryDirectory(prefix="gyrolab-profile-compile-") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, **{_IN_EMPTY_CACHE: "1"})
            raise SystemExit(subprocess.call([sys.executable, *sys.argv], env=env))
    table, total = profile(args.method, args.paths.split(","))
    compiles = sum(row[1] for row in table.values())
    print(f"{args.method} {args.paths}: {total:.2f} s, {len(table)} functions, {compiles} compiles")
    print(f"{'s':>6} {'n':>3}  function")
    for name, (seconds, n, signatures) in sorted(table.items(), key=lambda item: -item[1][0])[: args.top]:
        print(f"{seconds:6.2f} {n:3d}  {name}")
        if args.signatures and n > 1:
            for signature in signatures:
                print(f"{'':11}{signature[:160]}")


if __name__ == "__main__":
    main()
