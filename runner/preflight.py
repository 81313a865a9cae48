"""Checks before any work (paths, an existing results file or journal, memory, disk, threads) and
the dry run's plan; each problem is one ConfigError naming the key and value."""

import os
import shutil
import tempfile
from pathlib import Path

import h5py
import numpy as np

from ..safe_files import UnsafePathError, check_replaceable
from .config import ConfigError
from .execute import compile_estimate, compile_memory
from .grid import estimate_writing_seconds
from .store import START_OVER, Journal, JournalError, partial_dir

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
    """The results file: ``output.path`` relative to Hydra's output directory.  ConfigError when the
    path names a directory (it ends in a separator, or in . or ..): the file would take the
    directory's name."""
    text = str(path)
    if text.endswith(("/", os.sep)) or os.path.basename(text) in (".", ".."):
        raise ConfigError(
            f"output.path={text}: names a directory, not a file; give the file's name too "
            f"(e.g. output.path={os.path.join(text, 'results.h5')})"
        )
    out = Path(os.path.expanduser(text))
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
            try:
                manifest = journal.manifest()
            except JournalError as err:  # its advice, output.overwrite=true, also needs runner.resume=true left out
                reason = str(err).removesuffix(f"; {START_OVER}")
                raise JournalError(f"{reason}; {start_over(overwrite, 'the journal')}") from None
            if manifest.get("config_hash") != chash:
                raise ConfigError(
                    f"runner.resume=true: {journal.dir} holds runs of a different config, so this sweep has "
                    f"nothing to resume; {start_over(overwrite)}"
                )
            check_same_code(journal, manifest, overwrite)
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


def start_over(overwrite, what="them"):
    """What to do to discard a journal that runner.resume=true cannot resume, and start over.  A
    resume never discards a journal, output.overwrite=true or not: it asks for those runs, and a
    journal can hold hours of them (a config typo must not lose them)."""
    if overwrite:
        return f"to discard {what} and start over, leave out runner.resume=true (output.overwrite=true is set)"
    return f"to discard {what} and start over, leave out runner.resume=true and set output.overwrite=true"


def check_same_code(journal, manifest, overwrite=False):
    """ConfigError when the journal's runs were computed by other kernel code than this gyrolab's:
    one results file must not hold runs of two kernel versions.  ``overwrite``: output.overwrite."""
    from ..kernels import SOURCE_HASH

    recorded = manifest.get("kernel_source_hash")
    if recorded != SOURCE_HASH:
        made = f"kernel_source_hash {recorded[:12]}" if isinstance(recorded, str) else "no kernel_source_hash"
        raise ConfigError(
            f"runner.resume=true: {journal.dir} was computed by other kernel code ({made}, this gyrolab's is "
            f"{SOURCE_HASH[:12]}: kernels/ changed); resume with the code that made it, or {start_over(overwrite)}"
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
    """Peak disk use (bytes): the journal (raw samples and per-run variables) plus the results file
    being assembled (all it holds: ``Grid.file_bytes``)."""
    return grid.journal_bytes() + grid.file_bytes()


def _size(n):
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000


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
    return FIGURE_BASE_BYTES + FIGURE_PER_BYTE * grid.file_bytes()


def dry_run(grid, out, chunks, backend, peak, state, figures=True, chunk_seconds=1.0):
    """Print the plan of the sweep of ``grid`` into ``out`` on ``backend`` (runner/local_backend.py's
    interface): sizes, time and memory estimates (the figure step's from analysis/figures/cost.py), what
    would compile; nothing runs.  ``figures``: the config's output.figures setting; ``chunk_seconds``:
    runner.chunk_seconds (the length of the segments of chunks cut in time)."""
    from ..analysis import figure_names, figure_step_seconds

    steps = grid.steps(np.arange(grid.n_runs))
    seconds, where = backend.estimate_seconds(grid, chunks), backend.describe()
    print(f"gyrolab dry run: {describe(grid)}")
    print(f"  steps per run: {steps.min():.3g} to {steps.max():.3g}; {len(chunks)} chunks on {where}")
    segments = backend.segment_files_seconds(grid, chunks, chunk_seconds)  # long chunks' samples so far, rewritten
    writing, loading = estimate_writing_seconds(grid) + segments, LOAD_SECONDS * len(grid.methods)
    compiling, cold, before = compile_estimate(grid)  # from numba's cache as it is now, per method and path
    print(
        f"  estimated time: {seconds + writing + loading + compiling:.3g} s to the results file "
        f"({seconds:.3g} s integration, {writing:.3g} s journal and assembly"
        + (f" ({segments:.2g} s of it the segment files of chunks cut in time)" if segments else "")
        + f", {loading:.2g} s loading kernels, "
        f"{compiling:.0f} s compiling)"
    )
    each, drawing = figure_step_seconds(figure_names(figures), grid.shape, grid.n_samples)
    if each:
        kinds = ", ".join(f"{name} {sec:.2g} s" for name, sec in each.items())
        print(f"  + {drawing:.2g} s figures ({kinds}; on a quiet 2-core machine)")
    if cold:
        names = ", ".join(f"{m} ({p})" for m, p in cold)
        print(f"  compiling: {len(cold)} kernels not in the numba cache: {names}")
    elif not before:
        print("  compiling: none (every kernel is in the numba cache)")
    if before:
        print(f"  compiling: {len(before)} more not in the cache, compiled by an earlier job of this multirun")
    extra, where = compile_memory(cold)
    compiling_note = f"; + ~{_size(extra)} while numba compiles {len(cold)} kernel(s) {where}" if cold else ""
    print(f"  peak memory: ~{_size(peak)} of samples per chunk (+ ~0.3 GB for Python, numba, xarray{compiling_note})")
    if each:
        need, memory = figure_memory(grid), available_memory()
        print(
            f"  figure step: peak memory ~{_size(need)} (the figures read the results file slab by slab: "
            f"~{_size(FIGURE_BASE_BYTES)} + {FIGURE_PER_BYTE:g} x its {_size(grid.file_bytes())})"
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
        f"  output: {out} ~ {_size(grid.file_bytes())} (peak disk {_size(disk_needed(grid))} with the partial chunks)"
    )
    if state != "fresh":
        print(f"  note: runner.resume=true would {'skip: the file is complete' if state == 'done' else 'resume it'}")
