"""The ``gyrolab`` command (a Hydra app): config → grid → chunks → one results file.

    gyrolab                                   # the write-up's main study (conf/sweep/default.yaml)
    gyrolab sweep.f=[1,10,50] sweep.dt=[1e-3,1e-4] sweep.method=[seed_next,lie_poisson] sweep.t_end=10
    gyrolab experiment=<name>                 # a pinned study, conf/experiment/<name>.yaml
    gyrolab runner.dry_run=true ...           # sizes and estimates, no work
    gyrolab -m scene=heavy_top,free_asymmetric ...   # one results file per job; see gyrolab-combine

The results go to ``output.path`` (default ``results.h5``) in Hydra's output
directory (``outputs/<date>/<time>/``), figures to ``figures/`` next to it.
An interrupted sweep is finished, computing only its missing runs, with the
same overrides plus ``runner.resume=true hydra.run.dir=<that directory>``
(the command is printed when it is interrupted).

Bad input (any key) exits with status 2 and one line on stderr naming the
key and the value, before any work and without leaving files behind.

Faults: Ctrl-C, SIGTERM and SIGHUP (what Slurm, ``timeout`` and ``docker
stop`` send) keep the journal, remove the lock, print the resume command and
exit 128 + the signal number; further signals while cleaning up are ignored.
A full disk or another I/O error while running prints one line (what failed,
where, the free space, the resume command) and exits 1 with the journal
intact.  A resume verifies the journal's chunks and recomputes bad ones.
Test hook: the environment variable GYROLAB_TEST_CHUNK_DELAY (seconds)
sleeps after each stored chunk.
"""

import errno
import os
import re
import shlex
import shutil
import signal
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import h5py
import hydra
import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.errors import HydraException
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from ..results.layout import RAW_PER_SAMPLE, scene_attrs
from ..safe_files import OutputBusyError, OutputLock, UnsafePathError, check_replaceable, remove_stale_temporaries
from .config import ConfigError, config_hash, register_configs
from .execute import BackendError, compile_estimate
from .grid import build_grid, estimate_seconds, estimate_writing_seconds, plan_chunks
from .store import Journal, assemble, partial_dir

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT; SIGTERM gives 143, SIGHUP 129
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# Loading one method's kernels from a warm numba cache, the checks and the file's open and close
# (the "rest" of benchmarks/bench_pipeline.py: 0.5-0.9 s with 2 to 4 methods).
LOAD_SECONDS = 0.2
# The figure step (analysis/figures/registry.py standard_figures, in this process after the sweep) reads the
# results file lazily (gyrolab/results/reader.py open_results(lazy=True): the per-run variables in memory, the
# samples slab by slab as each figure selects them), so its memory hardly follows the file: the
# process's peak RSS is ~ FIGURE_BASE_BYTES + FIGURE_PER_BYTE x the file's size.  Measured
# (docs/benchmarks.md): the 8000-run sweep writing a 1.09 GB file, figures included, 501 MB (it was
# 1673 MB when the figures loaded the whole file), the 40000-run one writing 5.45 GB 518 MB;
# gyrolab-plot standard alone 293 MB on the first file and 296 MB on the second.
FIGURE_BASE_BYTES = 500e6
FIGURE_PER_BYTE = 0.001


def fail(message):
    """Print one line and exit with the bad-input status."""
    sys.stderr.write(f"gyrolab: error: {' '.join(str(message).split())}\n")
    sys.stderr.flush()
    sys.exit(EXIT_BAD_INPUT)


# --------------------------------------------------------------------------- signals


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread like Ctrl-C's KeyboardInterrupt."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


# Signals received, in order.  The exception a handler raises can land inside a finalizer (a weakref
# callback), where Python prints "Exception ignored" and carries on: the sweep would then finish as if
# never signalled.  raise_pending() raises it again at the points where a sweep commits work.
_PENDING = []


def _raise_interrupted(signum, frame):
    _PENDING.append(signum)
    raise Interrupted(signum)


def _raise_keyboard_interrupt(signum, frame):
    _PENDING.append(signum)
    raise KeyboardInterrupt


def raise_pending():
    """Raise the interrupt of a signal whose exception was swallowed; nothing when none came."""
    if _PENDING:
        raise KeyboardInterrupt if _PENDING[0] == signal.SIGINT else Interrupted(_PENDING[0])


def quiet_swallowed_interrupts(previous):
    """A sys.unraisablehook that drops an interrupt swallowed by a finalizer and passes anything else
    to ``previous``: the interrupt is recorded in _PENDING and raised again by raise_pending, so
    Python's "Exception ignored ... Traceback" would only break the sweep's one-line message."""

    def hook(unraisable):
        if not (isinstance(unraisable.exc_value, KeyboardInterrupt) and _PENDING):
            previous(unraisable)

    hook.quiets_interrupts = True
    return hook


def handle_signals():
    """SIGTERM and SIGHUP interrupt like Ctrl-C (KeyboardInterrupt); every one is also recorded for
    raise_pending.  SIGINT keeps Python's meaning, and stays ignored where it was ignored at start."""
    if not getattr(sys.unraisablehook, "quiets_interrupts", False):
        sys.unraisablehook = quiet_swallowed_interrupts(sys.unraisablehook)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_interrupted)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _raise_keyboard_interrupt)


def ignore_signals():
    """While cleaning up after the first signal: a second one must not cut the clean-up short."""
    for sig in HANDLED_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)


def exit_status(interrupt):
    """128 + the signal number of a KeyboardInterrupt (SIGINT) or Interrupted."""
    return 128 + getattr(interrupt, "signum", signal.SIGINT)


def signal_name(interrupt):
    return signal.Signals(getattr(interrupt, "signum", signal.SIGINT)).name


# --------------------------------------------------------------------------- output checks


def check_run_dir(key, value):
    """ConfigError unless ``hydra.run.dir``/``hydra.sweep.dir`` is, or can be made, a writable directory."""
    path = Path(os.path.expanduser(value))
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{key}={value}: exists and is not a directory")
    ancestor = path
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ConfigError(f"{key}={value}: {ancestor} is not a directory")
    try:
        with tempfile.TemporaryDirectory(dir=ancestor, prefix=".gyrolab-probe-"):
            pass
    except OSError as err:
        raise ConfigError(f"{key}={value}: cannot write in {ancestor} ({err.strerror})") from None


def check_run_dirs(argv):
    """``check_run_dir`` of the run/sweep directories given on the command line."""
    for arg in argv:
        key, eq, value = arg.lstrip("+~").partition("=")
        if eq and key in ("hydra.run.dir", "hydra.sweep.dir") and "${" not in value:
            check_run_dir(key, value)


def resolve_output(path, run_dir):
    """The results file: ``output.path`` relative to Hydra's output directory."""
    out = Path(os.path.expanduser(str(path)))
    out = out if out.is_absolute() else Path(run_dir) / out
    return out.parent.resolve() / out.name  # the name itself not resolved: a link there is refused, not followed


def check_writable(out):
    """ConfigError unless the results' directory exists as a writable directory or can be made one."""
    if out.is_dir():
        raise ConfigError(f"output.path={out}: is a directory, not a file name")
    ancestor = out.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ConfigError(f"output.path={out}: {ancestor} is not a directory")
    try:
        with tempfile.NamedTemporaryFile(dir=ancestor, prefix=".gyrolab-probe-"):
            pass
    except OSError as err:
        raise ConfigError(f"output.path={out}: cannot write in {ancestor} ({err.strerror})") from None


def check_output_paths(out):
    """UnsafePathError when a link or special file sits where the results file or its journal
    directory will be: gyrolab never writes through one (gyrolab/safe_files.py)."""
    check_replaceable(out)
    journal = partial_dir(out)
    if journal.is_symlink() or (journal.exists() and not journal.is_dir()):
        raise UnsafePathError(f"{journal}: not a directory (a link or a file); remove it to run this sweep")


def stored_hash(path):
    """The config_hash attr of an existing results file (None if unreadable)."""
    try:
        with h5py.File(path, "r") as fh:
            value = fh.attrs.get("config_hash")
    except OSError:
        return None
    return value.decode() if isinstance(value, bytes) else value


def output_state(out, chash, overwrite, resume):
    """What to do with ``out``: "fresh", "resume" or "done"; ConfigError when it is not allowed."""
    journal = Journal(out)
    if out.exists():
        if resume and not overwrite:
            if stored_hash(out) == chash:
                return "done"
            raise ConfigError(
                f"output.path={out}: exists and was made with a different config; "
                "set output.overwrite=true to replace it"
            )
        if not overwrite:
            raise ConfigError(
                f"output.path={out}: exists; set output.overwrite=true to replace it "
                "(or runner.resume=true to finish an interrupted sweep)"
            )
    if journal.exists():
        if resume:
            manifest = journal.manifest()
            if manifest.get("config_hash") != chash:
                raise ConfigError(
                    f"runner.resume=true: {journal.dir} holds runs of a different config; "
                    "set output.overwrite=true to discard them"
                )
            check_same_code(journal, manifest)
            return "resume"
        if not overwrite:
            raise ConfigError(
                f"output.path={out}: an interrupted sweep left {journal.dir}; finish it with "
                "runner.resume=true or start over with output.overwrite=true"
            )
    elif partial_dir(out).exists() and not overwrite:
        raise ConfigError(f"output.path={out}: {partial_dir(out)} exists and is not a gyrolab journal")
    elif resume and not overwrite:
        raise ConfigError(
            f"runner.resume=true: nothing to resume at {out} (no results file, no journal "
            f"{journal.dir}); leave out runner.resume=true to start this sweep"
        )
    return "fresh"


def check_same_code(journal, manifest):
    """ConfigError when the journal's runs were computed by other kernel code than this gyrolab's:
    one results file must not hold runs of two kernel versions."""
    from ..kernels import SOURCE_HASH

    recorded = manifest.get("kernel_source_hash")
    if recorded != SOURCE_HASH:
        made = f"kernel_source_hash {recorded[:12]}" if isinstance(recorded, str) else "no kernel_source_hash"
        raise ConfigError(
            f"runner.resume=true: {journal.dir} was computed by other kernel code ({made}, this gyrolab's is "
            f"{SOURCE_HASH[:12]}: kernels/ changed); resume with the code that made it, or start over with "
            "output.overwrite=true"
        )


def available_memory():
    """Bytes of memory available to a new allocation (MemAvailable), None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def nearest_dir(path):
    while not path.exists():
        path = path.parent
    return path


def check_fits(grid, out, chunks):
    """ConfigError when a chunk would not fit in memory or the results not on disk."""
    memory = available_memory()
    peak = max(len(c) for c in chunks) * grid.bytes_per_run()
    if memory is not None and peak > memory:
        raise ConfigError(
            f"output.every={grid.every}: a run stores {grid.n_samples} samples and needs "
            f"{_size(grid.bytes_per_run())}; "
            f"more than the {_size(memory)} of memory available (raise output.every or lower sweep.t_end)"
        )
    need = disk_needed(grid)
    free = shutil.disk_usage(nearest_dir(out.parent)).free
    if need > free:
        raise ConfigError(
            f"output.path={out}: the results need {_size(need)} on disk (file and partial chunks) "
            f"but only {_size(free)} is free (raise output.every or shrink the sweep)"
        )
    return peak


def disk_needed(grid):
    """Peak disk use (bytes): the journal of raw samples plus the results file being assembled."""
    journal = grid.n_runs * grid.n_samples * RAW_PER_SAMPLE * 8
    return journal + grid.bytes_stored()


def _size(n):
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000


# --------------------------------------------------------------------------- the sweep


def resolve_threads(requested):
    """numba threads to use (runner.threads, else all of NUMBA_NUM_THREADS)."""
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    if requested is None:
        return numba.get_num_threads()
    if requested > top:
        raise ConfigError(
            f"runner.threads={requested}: more than NUMBA_NUM_THREADS={top} (set that variable to allow more)"
        )
    return int(requested)


def describe(grid):
    m, f, t, d = grid.shape
    return (
        f"{grid.scene}: {m} method x {f} f x {t} theta0 x {d} dt = {grid.n_runs} runs, "
        f"{grid.total_steps:.3g} steps, {grid.n_samples} samples each"
    )


def figure_memory(grid):
    """Estimated peak memory (bytes) of the sweep's process while it draws the figures of ``grid``'s
    results file (FIGURE_BASE_BYTES, FIGURE_PER_BYTE)."""
    return FIGURE_BASE_BYTES + FIGURE_PER_BYTE * grid.bytes_stored()


def dry_run(grid, out, chunks, threads, peak, state, cluster=None, figures=True):
    steps = grid.steps(np.arange(grid.n_runs))
    if cluster is not None:
        seconds, where = cluster.estimate_seconds(grid, chunks), cluster.describe()
    else:
        seconds, where = estimate_seconds(grid, chunks, threads), f"{threads} threads"
    print(f"gyrolab dry run: {describe(grid)}")
    print(f"  steps per run: {steps.min():.3g} to {steps.max():.3g}; {len(chunks)} chunks on {where}")
    writing, loading = estimate_writing_seconds(grid), LOAD_SECONDS * len(grid.methods)
    compiling, cold = compile_estimate(grid)  # from numba's cache as it is now, per method and path
    print(
        f"  estimated time: {seconds + writing + loading + compiling:.3g} s to the results file "
        f"({seconds:.3g} s integration, {writing:.3g} s journal and assembly, {loading:.2g} s loading kernels, "
        f"{compiling:.0f} s compiling; figures extra)"
    )
    if cold:
        names = ", ".join(f"{m} ({p})" for m, p in cold)
        print(f"  compiling: {len(cold)} kernels not in the numba cache: {names}")
    else:
        print("  compiling: none (every kernel is in the numba cache)")
    print(f"  peak memory: ~{_size(peak)} of samples per chunk (+ ~0.3 GB for Python, numba, xarray)")
    if figures:
        need, memory = figure_memory(grid), available_memory()
        print(
            f"  figure step: peak memory ~{_size(need)} (the figures read the results file slab by slab: "
            f"~{_size(FIGURE_BASE_BYTES)} + {FIGURE_PER_BYTE:g} x its {_size(grid.bytes_stored())})"
            + (
                f"; more than the {_size(memory)} available: set output.figures=false and draw a selection "
                "with gyrolab-plot KIND FILE key=..."
                if memory is not None and need > memory
                else ""
            )
        )
    else:
        print("  figure step: none (output.figures=false)")
    print(
        f"  output: {out} ~ {_size(grid.bytes_stored())} (peak disk {_size(disk_needed(grid))} with the partial chunks)"
    )
    if state != "fresh":
        print(f"  note: runner.resume=true would {'skip: the file is complete' if state == 'done' else 'resume it'}")


def resume_command(run_dir):
    overrides = [o for o in HydraConfig.get().overrides.task if not o.startswith(("runner.resume=", "hydra.run.dir="))]
    words = ["gyrolab", *overrides, "runner.resume=true", f"hydra.run.dir={run_dir}"]
    return " ".join(shlex.quote(w) for w in words)


def file_attrs(cfg, grid, threads, chash):
    from ..kernels.scenes import get_scene
    from .provenance import provenance

    declared = get_scene(grid.scene)
    attrs = scene_attrs(grid.scene, grid.options, declared.CONSERVED, declared.CLOSED_FORM)
    attrs.update(t_end=grid.t_end, every=grid.every, divergence_threshold=grid.threshold, config_hash=chash)
    attrs.update(provenance(OmegaConf.to_yaml(cfg, resolve=True), threads))
    return attrs


def open_cluster(runner, dry_run=False):
    """The Dask cluster of runner.backend=dask (runner/dask_backend.py; a dry run starts none of its
    own, only plans it); ConfigError on bad input."""
    try:
        from .dask_backend import open_cluster
    except ImportError as err:
        if (err.name or "").split(".")[0] in ("dask", "distributed"):
            raise ConfigError("runner.backend=dask: needs dask.distributed (pip install 'gyrolab[dask]')") from None
        raise
    return open_cluster(runner, dry_run)


def run_sweep(cfg, run_dir):
    """Check everything, then run the grid (or only its missing runs) and write the results."""
    with ExitStack() as stack:
        return sweep(cfg, run_dir, stack)


def sweep(cfg, run_dir, stack):
    """``run_sweep``; a Dask cluster it connects to is closed by ``stack``."""
    import numba

    grid = build_grid(cfg)
    cluster = None
    threads = 1 if cfg.runner.backend == "dask" else resolve_threads(cfg.runner.threads)
    out = resolve_output(cfg.output.path, run_dir)
    check_writable(out)
    check_output_paths(out)
    OutputLock(out).check_free()
    chash = config_hash(cfg)
    overwrite, resume = bool(cfg.output.overwrite), bool(cfg.runner.resume)
    state = output_state(out, chash, overwrite, resume)
    if cfg.runner.backend == "dask" and (state != "done" or cfg.runner.dry_run):
        # unreachable: ConfigError, before any work; a dry run plans runner.address=local, starts nothing
        cluster = stack.enter_context(open_cluster(cfg.runner, dry_run=bool(cfg.runner.dry_run)))
        threads = cluster.threads
        chunks = cluster.plan(grid, np.arange(grid.n_runs), cfg.runner.chunk_seconds)
    else:
        chunks = plan_chunks(grid, np.arange(grid.n_runs), threads, cfg.runner.chunk_seconds)
    peak = check_fits(grid, out, chunks)
    if cfg.runner.dry_run:
        dry_run(grid, out, chunks, threads, peak, state, cluster, figures=bool(cfg.output.figures))
        return None
    if state == "done":
        with OutputLock(out):
            remove_stale_temporaries(out)
            Journal(out).discard()  # killed between the rename and the clean-up
        print(f"gyrolab: {out} is already complete (same config); nothing to do")
        return str(out)

    out.parent.mkdir(parents=True, exist_ok=True)
    if cluster is None:
        numba.set_num_threads(threads)
    started = time.perf_counter()
    with OutputLock(out):
        state = output_state(out, chash, overwrite, resume)  # again, now that we hold the lock
        remove_stale_temporaries(out)  # a killed assembly's half-written results file
        try:
            timing = execute(cfg, grid, out, threads, chash, resume=state == "resume", run_dir=run_dir, cluster=cluster)
        except KeyboardInterrupt as err:
            ignore_signals()
            sys.exit(exit_status(err))
        except (BackendError, OSError):
            ignore_signals()
            sys.exit(EXIT_FAILED)
    try:
        elapsed = time.perf_counter() - started
        with h5py.File(out, "r") as fh:
            failed = int((fh["status"][...] != 0).sum())
        print(
            f"gyrolab: results: {out} ({_size(out.stat().st_size)}, {grid.n_runs} runs, "
            f"{failed} diverged) in {elapsed:.1f} s ({timing['integrating']:.1f} s integrating, "
            f"{timing['journal']:.1f} s journal, {timing['assembly']:.1f} s assembly)"
        )
        figures = cfg.output.figures
        if figures:
            make_figures(out, OmegaConf.to_container(figures) if OmegaConf.is_list(figures) else figures)
    except KeyboardInterrupt as err:  # the results are complete: say so, not "nothing was saved"
        ignore_signals()
        sys.stderr.write(
            f"\ngyrolab: interrupted ({signal_name(err)}) after the results were complete: {out}; "
            f"draw the figures with gyrolab-plot standard {out}\n"
        )
        sys.exit(exit_status(err))
    return str(out)


def execute(cfg, grid, out, threads, chash, resume, run_dir, cluster=None):
    """Run the missing runs with a progress bar (on ``cluster`` if given, else here), then
    assemble the results file (we hold the lock).

    Returns the wall time (s) of the phases: {"integrating" (JIT warm-up and journal writes
    excluded), "journal" (writing the journal's chunks), "assembly" (writing the results file)}."""
    from tqdm import tqdm

    from .execute import run_missing, warm_up

    journal = Journal(out)
    if resume:
        journal.clean_temporaries()
        for name, reason in journal.verify(grid.n_runs, grid.n_samples):
            print(
                f"gyrolab: journal: {name} moved aside to {journal.rejected_dir}: {reason}; "
                "its runs are computed again",
                file=sys.stderr,
            )
        done, number = journal.done_runs()
    else:
        try:
            journal.create(
                {"config_hash": chash, "n_runs": grid.n_runs, "shape": list(grid.shape), "n_samples": grid.n_samples}
            )  # and this code's kernel_source_hash
        except OSError as err:
            print(f"gyrolab: error: {io_error(err, journal.dir)}; nothing was computed", file=sys.stderr)
            journal.discard()  # a half-made journal would block both the rerun and a resume
            raise
        done, number = np.empty(0, dtype=np.int64), 0
    todo = np.setdiff1d(np.arange(grid.n_runs), done)
    print(f"gyrolab: {describe(grid)}")
    if done.size:
        print(f"gyrolab: resuming: {done.size} runs already done, {todo.size} to go")
    if cluster is not None:
        print(f"gyrolab: running on {cluster.describe()}")
    print(f"gyrolab: writing {out}", flush=True)
    counter = {"runs": int(done.size)}
    bar = tqdm(
        total=int(grid.steps(todo).sum()) if todo.size else 0,
        unit="step",
        unit_scale=True,
        disable=None,
        dynamic_ncols=True,
        desc="gyrolab",
        postfix=f"runs {done.size}/{grid.n_runs}",
    )

    def progress(runs, steps):
        counter["runs"] += runs
        bar.set_postfix_str(f"runs {counter['runs']}/{grid.n_runs}", refresh=False)
        bar.update(steps)

    previous = _inode(out)  # an old file being replaced; a new inode after an interrupt is ours, complete
    try:
        if todo.size:
            (cluster.warm_up if cluster is not None else warm_up)(grid)
        start = time.perf_counter()
        if todo.size and cluster is not None:
            cluster.run_missing(grid, journal, todo, cfg.runner.chunk_seconds, number, progress)
        elif todo.size:
            run_missing(grid, journal, todo, threads, cfg.runner.chunk_seconds, number, progress)
        computing = time.perf_counter() - start - journal.write_seconds
        bar.close()
        raise_pending()  # a signal swallowed during integration
        start = time.perf_counter()
        assemble(out, grid, journal, file_attrs(cfg, grid, threads, chash), before_replace=raise_pending)
        assembly = time.perf_counter() - start
    except KeyboardInterrupt as err:
        ignore_signals()
        bar.close()
        why = "interrupted" if type(err) is KeyboardInterrupt else f"interrupted by {signal_name(err)}"
        if _inode(out) not in (None, previous) and stored_hash(out) == chash:  # just after our rename: whole
            print(f"\ngyrolab: {why} after the results were complete: {out}", file=sys.stderr)
            journal.discard()
            raise
        print(
            f"\ngyrolab: {why}; {counter['runs']} of {grid.n_runs} runs are saved in {journal.dir}.\n"
            f"Finish with: {resume_command(run_dir)}",
            file=sys.stderr,
        )
        raise
    except BackendError as err:
        ignore_signals()
        bar.close()
        print(
            f"\ngyrolab: error: {' '.join(str(err).split())}; {counter['runs']} of {grid.n_runs} runs are "
            f"saved in {journal.dir}.\nFinish with: {resume_command(run_dir)}",
            file=sys.stderr,
        )
        raise
    except OSError as err:  # a full disk, a lost mount, a read-only file system ...
        ignore_signals()
        bar.close()
        print(
            f"gyrolab: error: {io_error(err, out)}; {counter['runs']} of {grid.n_runs} runs are saved in "
            f"{journal.dir}; fix that, then finish with: {resume_command(run_dir)}",
            file=sys.stderr,
        )
        raise
    journal.discard()
    return {"integrating": computing, "journal": journal.write_seconds, "assembly": assembly}


def _inode(path):
    try:
        return os.lstat(path).st_ino
    except OSError:
        return None


def io_error(err, where):
    """One line on an OSError while writing near ``where``: what failed and, for a full disk,
    the free space there.  h5py reports ENOSPC inside its message, without errno."""
    text = " ".join(str(err).split())
    full = err.errno in (errno.ENOSPC, errno.EDQUOT) or "No space left" in text or "errno = 28" in text
    target = err.filename or where
    if full:
        try:
            free = _size(shutil.disk_usage(nearest_dir(Path(target).parent)).free)
        except OSError:
            free = "?"
        return f"no space left on the device of {target} ({free} free)"
    reason = err.strerror or (text[:160] if text else type(err).__name__)
    return f"I/O error writing {target}: {reason}"


def make_figures(out, names):
    """The figures ``names`` (output.figures) into ``figures/`` next to the results file."""
    from ..analysis import figure_names, standard_figures

    print(f"gyrolab: drawing {len(figure_names(names))} figures ...", flush=True)
    paths = standard_figures(str(out), str(out.parent / "figures"), names)
    print(f"gyrolab: figures: {out.parent / 'figures'} ({len(paths)} PNG)")
    return paths


def remove_empty_dirs(directory, stop):
    """Remove ``directory`` and its parents while they are empty, up to ``stop`` (excluded)."""
    directory, stop = Path(directory).resolve(), Path(stop).resolve()
    while directory != stop and stop in directory.parents:
        try:
            directory.rmdir()
        except OSError:
            return
        directory = directory.parent


@hydra.main(version_base=None, config_path="pkg://gyrolab.conf", config_name="config")
def hydra_main(cfg):
    run_dir = HydraConfig.get().runtime.output_dir
    try:
        return run_sweep(cfg, run_dir)
    except (ConfigError, OutputBusyError, UnsafePathError) as err:
        remove_empty_dirs(run_dir, os.getcwd())
        fail(err)
    finally:
        if cfg.runner.dry_run:
            remove_empty_dirs(run_dir, os.getcwd())


# --------------------------------------------------------------------------- errors from Hydra itself


def describe_hydra_error(err, argv):
    """One line naming the key and value of a composition error from Hydra/OmegaConf."""
    cause = err.__cause__ if isinstance(err.__cause__, OmegaConfBaseException) else None
    text = str(err)
    missing = re.search(r"Could not find '([^']+)/([^']+)'", text)
    if missing:
        group, name = missing.groups()
        options = re.search(rf"Available options in '{re.escape(group)}':\n((?:\t.*\n?)*)", text)
        choices = ", ".join(o.strip() for o in options.group(1).splitlines()) if options else ""
        return f"{group}={name}: unknown {group}" + (f"; choose from {choices}" if choices else "")
    key = getattr(cause or err, "full_key", None)
    override = re.search(r"override '([^']+)'", text) or re.search(r"override (\S+)", text)
    token = getattr(err, "override", None) or (override.group(1) if override else None)
    if token and "=" not in token:
        token = next((a for a in argv if a.lstrip("+~").startswith(token + "=")), token)
    if token is None and key:
        token = next((a for a in argv if a.lstrip("+~").startswith(f"{key}=")), key)
    reason = str(cause) if cause is not None else text
    if cause is None and override and "\n" in text:
        reason = text.split("\n", 1)[1]
    lines = [line.strip() for line in reason.strip().splitlines() if line.strip()]
    if lines and lines[0].endswith("raised while composing config:") and len(lines) > 1:
        lines = lines[1:]  # Hydra's heading; the reason is on the next line
    reason = lines[0] if lines else type(err).__name__
    if key is None:
        key = next(
            (line.split(":", 1)[1].strip() for line in text.splitlines() if line.strip().startswith("full_key:")), None
        )
        if key and token is None:
            token = next((a for a in argv if a.lstrip("+~").startswith(f"{key}=")), None)
            in_file = re.search(r"In '([^']+)'", text)
            token = token or (f"{key} (in {in_file.group(1)}.yaml)" if in_file else key)
    if "is not a ListConfig" in reason:
        reason += " (sweep axes are lists, e.g. sweep.f=[10])"
    return f"{token}: {reason}" if token else reason


def describe_yaml_error(err):
    """One line naming the file, line and problem of a YAML syntax error in a config file."""
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    where = f"{mark.name}, line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "a config file"
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    return f"{where}: YAML syntax error: {problem}"


def main():
    """Console entry point ``gyrolab``."""
    import yaml

    register_configs()
    if os.environ.get("HYDRA_FULL_ERROR"):  # the user asked for Hydra's own tracebacks
        return hydra_main()
    os.environ["HYDRA_FULL_ERROR"] = "1"  # let composition errors reach us instead of a printed trace
    handle_signals()
    try:
        check_run_dirs(sys.argv[1:])
        hydra_main()
    except (ConfigError, OutputBusyError, UnsafePathError) as err:
        fail(err)
    except (HydraException, OmegaConfBaseException) as err:
        fail(describe_hydra_error(err, sys.argv[1:]))
    except yaml.YAMLError as err:
        fail(describe_yaml_error(err))
    except (FileExistsError, FileNotFoundError, NotADirectoryError, PermissionError) as err:  # Hydra's mkdir
        fail(f"hydra.run.dir: cannot make {err.filename}: {err.strerror}")
    except KeyboardInterrupt as err:  # before the sweep started (imports, composition, checks)
        ignore_signals()
        sys.stderr.write(f"gyrolab: interrupted ({signal_name(err)}) before any run started; nothing was saved\n")
        sys.exit(exit_status(err))


if __name__ == "__main__":
    main()
