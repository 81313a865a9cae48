"""``gyrolab-compile [METHOD ...] [--jobs N]``: fill numba's cache with methods' kernels, in parallel.

numba compiles on one thread, and a method's kernels (its run kernel; its block kernel unless it declares
``BLOCKS = False``, seven lane passes or, for a step without rotation series, three (kernels/block.py);
its driven kernel if it sees time) take 3-35 s of CPU a method cold (``benchmarks/bench_compile.py``
times them; docs/benchmarks.md).  A sweep or a test session that compiles them one after another in its
own process uses one core and keeps every compiler's memory
(the suite's process grew to 8.7 GB compiling 27 methods; loading the same kernels from the cache
takes 0.43 GB).  Here each method compiles in a worker process of its own (``spawn``; a fresh worker
per method, so its memory goes back when it ends), ``--jobs`` at a time, into the same keyed cache
directories (kernels/__init__.py) the sweep and the tests load from.  Only kernels the cache does not
hold compile (``kernel_cached``); the real engines (kernels/real/) compile nothing.
``tests/conftest.py`` calls ``compile_methods`` for the methods a test session selects, and a sweep's
warm-up (runner/execute.py ``warm_up``) ``compile_kernels`` for the two or more cold kernels it runs.

Callers that overlap (the workers of ``pytest -n 2``, two ``gyrolab-compile`` started together) take
turns on a lock file in the cache root: the first compiles, the next then finds the kernels cached and compiles
nothing, instead of both compiling everything at once on the same cores.
"""

import argparse
import contextlib
import os
import signal
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context, resource_tracker

from ..pipes import quiet_on_broken_pipe

PATHS = ("runs", "blocks", "driven")
KERNEL_ENTRIES = {"runs": "run_batch", "driven": "run_batch_driven", "blocks": "run_blocks"}


def kernel_cached(method, path):
    """True when numba's cache for this source tree holds ``method``'s kernel of ``path`` (its index
    file exists and matches the source file: what numba checks before loading instead of compiling)."""
    from ..kernels.registry import get_method

    dispatcher = getattr(get_method(method), KERNEL_ENTRIES[path], None)
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # no dispatcher, no cache locator, an unreadable index: numba would compile
        return False


def compile_jobs():
    """Worker processes a cold warm-up (or gyrolab-compile by default) compiles in: the cores this process
    may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def die_with_parent():
    """Linux: ask the kernel to SIGKILL this process when its parent dies (prctl PR_SET_PDEATHSIG),
    so a ``kill -9`` of the runner never leaves a worker writing behind it."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def cold_kernels(names):
    """{method: [path, ...]} of the kernels of ``names`` (method names) that numba's cache lacks."""
    from ..kernels.real import is_real
    from ..kernels.registry import get_method, sees_time, uses_blocks

    out = {}
    for name in names:
        if is_real(name):
            continue
        module = get_method(name)
        paths = ["runs"] + (["blocks"] if uses_blocks(module) else []) + (["driven"] if sees_time(module) else [])
        cold = [path for path in paths if not kernel_cached(name, path)]
        if cold:
            out[name] = cold
    return out


def compile_one(name, paths):
    """(name, seconds): compile (or load) ``name``'s kernels of ``paths`` by integrating two steps of
    tiny runs through kernels.batch.integrate, with the argument types a sweep passes."""
    import numpy as np

    from ..kernels.batch import MIN_BLOCK_RUNS, integrate
    from ..kernels.scenes import build_scene

    start = time.perf_counter()
    for path in paths:
        scene = build_scene("forced_body" if path == "driven" else "heavy_top", 50.0, 45.0)
        n = MIN_BLOCK_RUNS if path == "blocks" else 1
        rows = [np.tile(np.asarray(x, dtype=float), (n, 1)) for x in (scene.body, scene.omega0, scene.q0)]
        ones = np.ones(n, dtype=np.int64)
        integrate(name, *rows, np.full(n, 1e-3), ones, 2, path="runs" if path == "driven" else path)
    return name, time.perf_counter() - start


# Seconds numba takes to compile one method's kernel of each path on a cold cache, in a compile worker
# (a fresh interpreter per method, where warm_up sends two or more cold kernels), from
# the workers' own lines on a fresh NUMBA_CACHE_DIR on the quiet 2-core machine, 2026-12-04: the verdict
# study's 36 plain run and 19 driven kernels 2-3 s each; a 500-run sweep's run + block kernels 16-28 s a
# method (rk4 22, lie_poisson4 28, seed_next 16); strang_exact, whose step inlines the exact
# Euler-Poinsot flow, run and driven kernels 6 s each.  The model: COMPILE_SECONDS[path], plus
# EXACT_FLOW_SECONDS[path] for a method whose step has the exact flow (FREE_EXACT).  The compositions of it
# (strang_exact4, suzuki4_exact, split6_exact) call the flow at one place in a loop over their weights
# (kernels/compose.py) and compile as strang_exact does (13.4-13.6 s each for the run kernel in a fresh
# process, benchmarks/bench_compile.py); while they inlined one flow per substep they took 17, 29 and 43 s
# (run) and 25, 34 and 59 s (driven), ~n^1.5 for n flows.  (Compiled one after another in the sweep's own
# process, as before the compile workers, the same kernels took 1.5-3x these: numba keeps every module it
# compiled.)  A block kernel whose step has no rotation series compiles its fast lane passes alone
# (kernels/lanes.py has_series): BLOCK_ONE_PASS_SECONDS, from bench_compile.py --paths blocks on 2026-12-05
# (the faster Intel machine, quiet): rk4 12.2 s and no_squish 13.1 s against seed_next 18.3 s and
# lie_poisson4 30.4 s, each ~2 s of it the fresh interpreter's own start.  Since each loop compiles once
# and the block kernel's helpers are inlined into it (kernels/entry.py, kernels/block.py; 2026-12-05), the
# workers' lines of gyrolab-compile on an empty cache: a method without a block kernel 2-4 s for its run
# and driven kernels; run + block kernels 7-9 s where the step has no rotation series; run, block and
# driven kernels 18-20 s for seed_next, rkmk4 and lie_poisson, 25-27 s for cg4 and lie_poisson4.
COMPILE_SECONDS = {"runs": 2.0, "driven": 2.0, "blocks": 15.0}
BLOCK_ONE_PASS_SECONDS = 6.0
EXACT_FLOW_SECONDS = {"runs": 2.5, "driven": 3.3, "blocks": 2.5}


def compile_seconds(method, path):
    """Estimated seconds to compile ``method``'s kernel of ``path`` on a cold cache (the model above)."""
    from ..kernels.lanes import has_series
    from ..kernels.registry import get_method

    module = get_method(method)
    seconds = COMPILE_SECONDS[path]
    if path == "blocks" and not has_series(module.step):
        seconds = BLOCK_ONE_PASS_SECONDS
    return seconds + (EXACT_FLOW_SECONDS[path] if getattr(module, "FREE_EXACT", False) else 0.0)


def compile_weight(name, paths):
    """A sort key that ranks methods by their cold compile time: the model above summed over the kernels
    ``paths`` (e.g. ["runs", "blocks", "driven"]), so the methods with block kernels go first."""
    return sum(compile_seconds(name, path) for path in paths)


@contextlib.contextmanager
def _cache_lock():
    """Hold an exclusive lock on ``<cache root>/compile.lock`` (blocking) for the duration; nothing where
    there is no cache root or no ``fcntl`` (then overlapping callers both compile, as before)."""
    from ..kernels import CACHE_ROOT

    try:
        import fcntl
    except ImportError:  # Windows
        fcntl = None
    handle = None
    if CACHE_ROOT and fcntl:
        flags = os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW  # never a file a symlink points at
        try:
            handle = os.fdopen(os.open(os.path.join(CACHE_ROOT, "compile.lock"), flags, 0o600), "w")
        except OSError:  # unwritable, or a symlink planted in its place: compile without the lock
            handle = None
    if handle is None:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes, or when the process dies
        yield


def compile_methods(names, jobs=None, report=print):
    """Compile the cold kernels of ``names`` (every path each method has) in ``jobs`` worker processes
    (default: the cores this process may use); ``report`` gets one line per method.  Returns {method: seconds}; a worker
    that fails is reported and skipped (whoever runs the method compiles it then).  Overlapping callers
    take turns (the lock above), so each kernel compiles once."""
    with _cache_lock():
        return _compile(cold_kernels(names), jobs, report, "gyrolab-compile")


def compile_kernels(kernels, jobs=None, report=print, prefix="gyrolab"):
    """Compile the kernels ``kernels`` ([(method, path)], e.g. the cold ones a sweep warms up: only the
    paths it runs) in worker processes, as ``compile_methods`` does; lines start with ``prefix``."""
    with _cache_lock():
        todo = {}
        for method, path in kernels:
            if not kernel_cached(method, path):  # an overlapping caller may have compiled it meanwhile
                todo.setdefault(method, []).append(path)
        return _compile(todo, jobs, report, prefix)


def _worker_init():
    """A compile worker: Ctrl-C is its caller's to answer (which then terminates the pool), and it dies
    with its caller (Linux), so an interrupted or killed sweep leaves no compiler running behind it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()


def _compile_task(job):
    """(name, seconds, error): compile_one in a worker; an exception comes back as its one-line text."""
    name, paths = job
    try:
        return compile_one(name, paths) + ("",)
    except Exception as err:  # noqa: BLE001 - one method's failure must not stop the others
        return name, 0.0, f"{type(err).__name__}: {err}"


def _compile(todo, jobs, report, prefix):
    if not todo:
        return {}
    jobs = max(1, min(jobs or compile_jobs(), len(todo)))
    n_kernels = sum(map(len, todo.values()))
    report(f"{prefix}: compiling {n_kernels} kernels of {len(todo)} methods, {jobs} at a time ...")
    done = {}
    context = get_context("spawn")  # a fresh interpreter: no numba state or memory inherited
    fresh = {"max_tasks_per_child": 1} if sys.version_info >= (3, 11) else {}  # 3.10: workers are reused
    # A Ctrl-C reaches the terminal's whole process group, the compile workers too.  _worker_init ignores
    # it, but only once a worker has started, and a spawned worker spends a second importing first: a
    # Ctrl-C then printed its KeyboardInterrupt traceback under our one line.  So the workers start with
    # SIGINT blocked (a mask is inherited through fork and exec): the pool's first workers are spawned here
    # by submit, the later ones (one per method) by its manager thread, which submit starts and which
    # inherits this thread's mask.  This thread unblocks it after submitting; a Ctrl-C that came in the
    # meantime was held pending, not lost, and is raised then.  multiprocessing's resource tracker unblocks
    # SIGINT in the calling thread after starting itself, so it is started first.
    masked = hasattr(signal, "pthread_sigmask")
    if masked:
        resource_tracker.ensure_running()
        before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    pool = ProcessPoolExecutor(jobs, mp_context=context, initializer=_worker_init, **fresh)
    try:
        # longest first, so that no worker is left alone with a long method at the end (LPT scheduling)
        order = sorted(todo, key=lambda name: compile_weight(name, todo[name]), reverse=True)
        try:
            futures = {pool.submit(_compile_task, (name, todo[name])): name for name in order}
        finally:
            if masked:
                signal.pthread_sigmask(signal.SIG_SETMASK, before)
        for k, future in enumerate(as_completed(futures), 1):
            name, seconds, error = future.result()
            if error:
                report(f"{prefix}: {name}: failed ({error})")
                continue
            done[name] = seconds
            report(f"{prefix}: compiled {name} ({', '.join(todo[name])}) in {seconds:.0f} s ({k}/{len(todo)})")
    except BaseException:  # an interrupt: stop the compilers now rather than wait minutes for them
        # the executor has no terminate(): kill its worker processes (its own map of them), then shut down
        for process in list(getattr(pool, "_processes", {}).values()):
            process.kill()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return done


@quiet_on_broken_pipe
def main(argv=None):
    from ..kernels.registry import METHODS, select_methods
    from ..results import EXIT_BAD_INPUT

    parser = argparse.ArgumentParser(prog="gyrolab-compile", description=__doc__.splitlines()[0])
    parser.add_argument("methods", nargs="*", help="method names or selectors (default: all)")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: the CPU count)")
    args = parser.parse_args(argv)
    try:
        names = select_methods(args.methods) if args.methods else list(METHODS)
    except ValueError as err:
        print(f"gyrolab-compile: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.jobs is not None and args.jobs < 1:
        print(f"gyrolab-compile: --jobs={args.jobs}: must be >= 1", file=sys.stderr)
        return EXIT_BAD_INPUT
    start = time.perf_counter()
    done = compile_methods(names, args.jobs)
    seconds = time.perf_counter() - start
    print(f"gyrolab-compile: {len(done)} methods in {seconds:.0f} s" if done else "gyrolab-compile: all cached")
    return 0


if __name__ == "__main__":
    sys.exit(main())
