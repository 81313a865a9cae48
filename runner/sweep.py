"""The sweep: check everything, run the grid's missing runs on a backend (runner/local_backend.py or
runner/dask_backend.py) with a progress bar, assemble the results file and draw its figures."""

import errno
import os
import shlex
import shutil
import sys
import time
from contextlib import ExitStack
from pathlib import Path

import h5py
import numpy as np
from hydra.core.hydra_config import HydraConfig
from omegaconf import OmegaConf

from ..kernels.driver import STATUS_UNCONVERGED
from ..results.layout import scene_attrs
from ..safe_files import OutputLock, remove_stale_temporaries
from .config import ConfigError, config_hash
from .execute import BackendError
from .grid import build_grid
from .local_backend import LocalBackend
from .preflight import (
    _size,
    check_fits,
    check_output_paths,
    check_writable,
    describe,
    dry_run,
    nearest_dir,
    output_state,
    resolve_output,
    resolve_threads,
    stored_hash,
)
from .signals import EXIT_FAILED, exit_status, ignore_signals, raise_pending, signal_name
from .store import Journal, assemble


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


def open_backend(runner, threads):
    """The backend of ``runner.backend``: this process's ``threads`` numba threads, or the Dask cluster
    of runner.backend=dask (runner/dask_backend.py; a dry run starts none of its own, only plans it).
    A context manager; ConfigError on bad input."""
    if runner.backend != "dask":
        return LocalBackend(threads)
    try:
        from .dask_backend import open_cluster
    except ImportError as err:
        if (err.name or "").split(".")[0] in ("dask", "distributed"):
            raise ConfigError("runner.backend=dask: needs dask.distributed (pip install 'gyrolab[dask]')") from None
        raise
    return open_cluster(runner, bool(runner.dry_run))


def run_sweep(cfg, run_dir):
    """Check everything, then run the grid (or only its missing runs) and write the results."""
    with ExitStack() as stack:
        return sweep(cfg, run_dir, stack)


def sweep(cfg, run_dir, stack):
    """``run_sweep``; a Dask cluster it connects to is closed by ``stack``."""
    grid = build_grid(cfg)
    threads = 1 if cfg.runner.backend == "dask" else resolve_threads(cfg.runner.threads)
    out = resolve_output(cfg.output.path, run_dir)
    check_writable(out)
    check_output_paths(out)
    OutputLock(out).check_free()
    chash = config_hash(cfg)
    overwrite, resume = bool(cfg.output.overwrite), bool(cfg.runner.resume)
    state = output_state(out, chash, overwrite, resume)
    if state == "done" and not cfg.runner.dry_run:
        backend = LocalBackend(threads)  # nothing to run: no cluster to connect to
    else:  # an unreachable cluster: ConfigError, before any work; a dry run plans runner.address=local
        backend = stack.enter_context(open_backend(cfg.runner, threads))
    chunks = backend.plan(grid, np.arange(grid.n_runs), cfg.runner.chunk_seconds)
    peak = check_fits(grid, out, chunks)
    if cfg.runner.dry_run:
        figures = cfg.output.figures
        dry_run(
            grid,
            out,
            chunks,
            backend,
            peak,
            state,
            OmegaConf.to_container(figures) if OmegaConf.is_list(figures) else figures,
            cfg.runner.chunk_seconds,
        )
        return None
    if state == "done":
        with OutputLock(out):
            remove_stale_temporaries(out)
            Journal(out).discard()  # killed between the rename and the clean-up
        print(f"gyrolab: {out} is already complete (same config); nothing to do")
        return str(out)

    out.parent.mkdir(parents=True, exist_ok=True)
    backend.start()
    started = time.perf_counter()
    with OutputLock(out):
        state = output_state(out, chash, overwrite, resume)  # again, now that we hold the lock
        remove_stale_temporaries(out)  # a killed assembly's half-written results file
        try:
            timing = execute(cfg, grid, out, backend, chash, resume=state == "resume", run_dir=run_dir)
        except KeyboardInterrupt as err:
            ignore_signals()
            sys.exit(exit_status(err))
        except (BackendError, OSError):
            ignore_signals()
            sys.exit(EXIT_FAILED)
    try:
        elapsed = time.perf_counter() - started
        with h5py.File(out, "r") as fh:
            status = fh["status"][...]
        unconverged = int((status == STATUS_UNCONVERGED).sum())
        failed = f"{int((status != 0).sum()) - unconverged} diverged"
        if unconverged:
            failed += f", {unconverged} with a solver that did not converge"
        print(
            f"gyrolab: results: {out} ({_size(out.stat().st_size)}, {grid.n_runs} runs, "
            f"{failed}) in {elapsed:.1f} s ({timing['integrating']:.1f} s integrating, "
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


def execute(cfg, grid, out, backend, chash, resume, run_dir):
    """Run the missing runs on ``backend`` (runner/local_backend.py's interface) with a progress bar,
    then assemble the results file (we hold the lock).

    Returns the wall time (s) of the phases: {"integrating" (JIT warm-up and journal writes
    excluded), "journal" (writing the journal's chunks), "assembly" (writing the results file)}."""
    from tqdm import tqdm

    journal = Journal(out)
    if resume:
        journal.clean_temporaries()
        journal.report_set_aside(journal.verify(grid.n_runs, grid.n_samples))
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
    if backend.remote:
        print(f"gyrolab: running on {backend.describe()}")
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
            backend.warm_up(grid)
        start = time.perf_counter()
        if todo.size:
            backend.run_missing(grid, journal, todo, cfg.runner.chunk_seconds, number, progress)
        computing = time.perf_counter() - start - journal.write_seconds
        bar.close()
        raise_pending()  # a signal swallowed during integration
        start = time.perf_counter()
        assemble(out, grid, journal, file_attrs(cfg, grid, backend.threads, chash), before_replace=raise_pending)
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
