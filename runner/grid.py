"""The sweep grid: every run's inputs, checked up front, and its split into chunks.

A run is one point (method, f, theta0, dt) of the Cartesian grid, numbered in
C order of the results' dims (integrator, f, theta0, dt: the sweep's methods are the
file's integrator dim).  ``build_grid`` builds
every scene and every sample schedule before any work, so bad input fails
first.  A chunk is a set of runs of ONE method (``plan_chunks``): runs of one dt
fill chunks of equal runs, so the batch kernel's prange hands every thread the
same work, and each dt's leftovers are pooled into chunks of mixed dt.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from omegaconf import OmegaConf

from ..kernels.batch import MIN_BLOCK_RUNS, sample_schedule
from ..kernels.body import N_FIELDS as N_BODY
from ..kernels.body import is_driven
from ..kernels.real import STEP_RATES as REAL_STEP_RATES
from ..kernels.real import check_bodies, check_steps, is_real
from ..kernels.registry import DRIVEN_REFUSAL, driven_methods, get_method, sees_time, select_methods
from ..kernels.scenes import SCENES, build_scene
from ..results.layout import (
    FIXED_COORDS,
    INPUT_VARIABLES,
    RAW_PER_SAMPLE,
    RUN_VARIABLES,
    SAMPLE_VARIABLES,
    chosen_variables,
    stored_per_sample,
)
from .config import ConfigError, check_values

# Rough steps per second per thread of each method on the development machine
# (heavy top, warm JIT cache); only used to size chunks and for dry-run estimates.
STEP_RATE = {"seed_next": 1.2e7, "seed_prev": 1.2e7, "rk4": 1.2e7, "lie_poisson": 1.2e7, "lie_poisson4": 5e6}
DEFAULT_STEP_RATE = 5e6
# The real engines (kernels/real/: the engine package itself, one run after another): their own rates.
STEP_RATE.update(REAL_STEP_RATES)
# Speed of the vectorised block path (kernels/block.py; chunks of >= MIN_BLOCK_RUNS runs) over the
# one-by-one path, per method: ns/step one by one / in blocks, heavy top, 256 runs, 2 threads, the
# "after" columns of docs/benchmarks.md's centre-of-mass table (bench_methods.py, quiet machine).
# seed_prev is seed_next's arithmetic.  Any other method: the lowest measured speed-up of a method the
# blocks do help (mujoco_implicit's).  The exact-free-flow methods (strang_exact, ...) are off the block
# path (BLOCKS = False: their libm-bound elliptic functions ran 0.8-1.2x one by one's time in blocks).
BLOCK_SPEEDUP = {
    "seed_next": 6.9,
    "seed_prev": 6.9,
    "rk4": 5.7,
    "lie_poisson": 6.0,
    "lie_poisson4": 5.8,
    "mujoco_implicit": 2.7,
}
DEFAULT_BLOCK_SPEEDUP = 2.7
MAX_CHUNK_BYTES = 256 * 2**20
# The most runs one sweep holds: the runner keeps per-run arrays (inputs, status, steps, wall time,
# chunk plan, assembly's owner/row maps: ~PER_RUN_BYTES a run) and plans chunks run by run, so a
# bigger grid is refused up front, in O(axes), rather than after minutes of planning.
MAX_RUNS = 10**7
PER_RUN_BYTES = 200
# Effective rates of the pipeline around the kernels on the development machine (docs/benchmarks.md,
# benchmarks/bench_pipeline.py): journal bytes (raw samples) per second, results bytes per second
# of assembly (journal read, variables derived, file written), and seconds per run of assembly.
JOURNAL_RATE = 5.0e8
ASSEMBLY_RATE = 3.5e8
ASSEMBLY_PER_RUN = 2e-5
# What a results file holds besides its variables' values and coordinates: the attrs (the resolved
# config as YAML, the provenance: ~20 kB) and HDF5's object headers, FILE_METADATA_BYTES, plus each
# per-sample variable's header and chunk index (a chunked dataset), SAMPLE_METADATA_BYTES.  Measured
# (file size less the datasets' storage): 35 kB for a 2000-run file of theta alone, 78 kB for a 2-run
# file of all nine, 49 kB for a 100000-run file of theta alone (its four chunks).
FILE_METADATA_BYTES = 30e3
SAMPLE_METADATA_BYTES = 5.5e3
# Bytes a string coordinate's value takes in the file (a variable-length string: its 16-byte
# reference; the characters themselves go to the global heap, inside FILE_METADATA_BYTES).
STRING_BYTES = 16
# Bytes per run of the per-run variables (status, n_steps, wall_time, the solver counts), as the file
# and each journal chunk store them; a journal chunk adds each run's number (int64).
RUN_BYTES = sum(np.dtype(dtype).itemsize for dtype, _ in RUN_VARIABLES.values())


@dataclass(frozen=True)
class Grid:
    """All runs of a sweep.  Axes: methods (str), f (Hz), theta0 (deg), dt (s);
    t_end and every (s); strides[l] steps per sample at dt[l]; bodies/omega0/q0
    of each (f, theta0) as arrays (nf, nt, N_BODY|3|4); variables: the per-sample variables
    the results file holds."""

    scene: str
    options: dict
    methods: tuple
    f: tuple
    theta0: tuple
    dt: tuple
    t_end: float
    every: float
    threshold: float
    strides: tuple
    n_samples: int
    bodies: np.ndarray = field(repr=False)
    omega0: np.ndarray = field(repr=False)
    q0: np.ndarray = field(repr=False)
    variables: tuple = tuple(SAMPLE_VARIABLES)  # the per-sample variables stored (output.variables)

    @property
    def shape(self):
        return (len(self.methods), len(self.f), len(self.theta0), len(self.dt))

    @property
    def n_runs(self):
        return int(np.prod(self.shape))

    def index(self, runs):
        """(method, f, theta0, dt) indices of flat run numbers."""
        return np.unravel_index(np.asarray(runs), self.shape)

    def steps(self, runs):
        """Planned steps of each run (the kernel stops early only when a run diverges)."""
        ld = self.index(runs)[3]
        return (self.n_samples - 1) * np.asarray(self.strides, dtype=np.int64)[ld]

    @property
    def total_steps(self):
        return int(self.steps(np.arange(self.n_runs)).sum())

    def inputs(self, runs):
        """Kernel inputs of the given runs: bodies, omega0, q0, dt (s), stride (fresh C arrays)."""
        _, jf, kt, ld = self.index(runs)
        return (
            np.ascontiguousarray(self.bodies[jf, kt]),
            np.ascontiguousarray(self.omega0[jf, kt]),
            np.ascontiguousarray(self.q0[jf, kt]),
            np.asarray(self.dt, dtype=np.float64)[ld].copy(),
            np.asarray(self.strides, dtype=np.int64)[ld].copy(),
        )

    def bytes_stored(self):
        """Size of the per-sample data in the results file (bytes); ``file_bytes`` is the whole file."""
        return self.n_runs * self.n_samples * stored_per_sample(self.variables) * 8

    def file_bytes(self):
        """Size of the whole results file (bytes), from its layout (gyrolab/results/layout.py): the
        per-sample variables, the per-run ones (RUN_VARIABLES), the runs' inputs over (f, theta0)
        (INPUT_VARIABLES), the coordinates, the attrs and HDF5's headers (FILE_METADATA_BYTES,
        SAMPLE_METADATA_BYTES)."""
        inputs = len(self.f) * len(self.theta0) * sum(len(FIXED_COORDS[own]) for own, _ in INPUT_VARIABLES.values())
        numeric = len(self.f) + len(self.theta0) + len(self.dt) + self.n_samples  # float64 coordinates
        strings = len(self.methods) + sum(len(v) for v in FIXED_COORDS.values())
        return (
            self.bytes_stored()
            + self.n_runs * RUN_BYTES
            + (inputs + numeric) * 8
            + strings * STRING_BYTES
            + FILE_METADATA_BYTES
            + SAMPLE_METADATA_BYTES * len(self.variables)
        )

    def journal_bytes(self):
        """Size of the journal of every run (bytes): the raw samples, the run numbers and per-run
        variables of each chunk (runner/store.py CHUNK_KEYS)."""
        return self.n_runs * (self.n_samples * RAW_PER_SAMPLE * 8 + 8 + RUN_BYTES)

    @property
    def driven(self):
        """Whether the scene drives its bodies (a torque that depends on time: no block path)."""
        return is_driven(self.bodies)

    def bytes_per_run(self):
        """Memory of one run's samples while a chunk is integrated and stored (bytes)."""
        return self.n_samples * (RAW_PER_SAMPLE + stored_per_sample(self.variables)) * 8


def check_grid_size(shape, given=None, at_least=False):
    """ConfigError when the grid of ``shape`` (methods, f, theta0, dt) has more than MAX_RUNS runs;
    O(axes): nothing per run is built before this.  ``given``: sweep.method as written, named in the
    message when its selectors (``all``, ...) stand for more methods (``at_least``: a lower bound)."""
    n = math.prod(shape)
    if n > MAX_RUNS:
        m, f, t, d = shape
        methods = f"{m} method"
        if given is not None and len(given) != m:
            methods += f" (sweep.method=[{','.join(map(str, given))}] selects {'at least ' if at_least else ''}{m})"
        raise ConfigError(
            f"sweep: {methods} x {f} f x {t} theta0 x {d} dt = {n:.3g} runs, more than the {MAX_RUNS:.0e} one "
            "sweep may hold (its per-run bookkeeping alone would need ~{:.3g} GB); split it into jobs "
            "(gyrolab -m ...) and join them with gyrolab-combine".format(n * PER_RUN_BYTES / 1e9)
        )


def build_grid(cfg):
    """Check the whole config and build every run's inputs; ConfigError on bad input."""
    # The grid's size first, before any check that costs time (check_values imports the figure
    # modules) and before anything is built per (f, theta0) or per run.  With selectors expanded
    # (sweep.method=[all] is 41 methods): on a driven scene ``all`` means fewer methods, and whether
    # the scene drives its body is known once the scenes are built, so this counts the fewer and
    # the exact count is checked again below, when the scenes are built and the selectors expanded.
    try:
        given = list(cfg.sweep.method)
        fewest = len(select_methods(given, driven_scene=True))
        shape = (fewest,) + tuple(len(cfg.sweep[axis]) for axis in ("f", "theta0", "dt"))
    except Exception:  # an axis that is not a list or does not resolve, a bad name: the checks below say which
        shape = None
    if shape is not None:
        check_grid_size(shape, given, at_least=fewest != len(select_methods(given)))
    check_values(cfg)
    sweep, scene_cfg = cfg.sweep, OmegaConf.to_container(cfg.scene, resolve=True)
    for m in sweep.method:
        try:
            select_methods([m])
        except ValueError as err:
            raise ConfigError(f"sweep.method={m}: {err}") from None
    name = scene_cfg.pop("name", None)
    if name not in SCENES:
        raise ConfigError(f"scene.name={name}: unknown scene; choose from {', '.join(SCENES)}")
    every, t_end = float(cfg.output.every), float(sweep.t_end)
    strides = []
    for dt in sweep.dt:
        try:
            stride, n_samples = sample_schedule(float(dt), every, t_end)
        except ValueError as err:
            raise ConfigError(_prefix_sweep(str(err))) from None
        strides.append(stride)
    nf, nt = len(sweep.f), len(sweep.theta0)
    bodies, omega0, q0 = np.empty((nf, nt, N_BODY)), np.empty((nf, nt, 3)), np.empty((nf, nt, 4))
    for j, f in enumerate(sweep.f):
        for k, theta0 in enumerate(sweep.theta0):
            try:
                sc = build_scene(name, float(f), float(theta0), **scene_cfg)
            except ValueError as err:
                raise ConfigError(_prefix_sweep(str(err))) from None
            bodies[j, k], omega0[j, k], q0[j, k] = sc.body, sc.omega0, sc.q0
    # Selectors (sweep.method=[all], ...) become the methods they select, in the config too, so the
    # stored config, the journal's config hash and the figures name the methods that ran.
    chosen = select_methods(list(sweep.method), driven_scene=is_driven(bodies))
    check_grid_size((len(chosen), nf, nt, len(sweep.dt)), list(sweep.method))  # before anything per run is built
    if chosen != list(sweep.method):
        sweep.method = chosen
    with np.errstate(over="ignore", invalid="ignore"):
        rates = np.square(omega0).sum(axis=-1)
    if not (np.isfinite(rates).all() and np.isfinite(bodies).all() and np.isfinite(q0).all()):
        j, k = np.argwhere(~np.isfinite(rates) | ~np.isfinite(bodies).all(-1) | ~np.isfinite(q0).all(-1))[0]
        raise ConfigError(
            f"scene: the initial state at f={sweep.f[int(j)]}, theta0={sweep.theta0[int(k)]} overflows float64 "
            f"(|omega0|^2 = {rates[j, k]:.3g} rad^2/s^2: a scene option such as scene.omega1 is too large); "
            "every run would be infinite from t = 0"
        )
    for m in sweep.method:  # a real engine builds the body in its own terms (kernels/real/): can it?
        if is_real(m):
            try:
                check_bodies(m, bodies)
                check_steps(m, sweep.dt)
            except ValueError as err:
                raise ConfigError(f"sweep.method={m}: {err} (scene {name})") from None
    if is_driven(bodies):
        blind = [m for m in sweep.method if not sees_time(get_method(m))]
        if blind:
            raise ConfigError(
                f"sweep.method={blind[0]}: {DRIVEN_REFUSAL} (scene {name} drives the body); "
                f"methods that do: {', '.join(driven_methods())}"
            )
    return Grid(
        scene=name,
        options=scene_cfg,
        methods=tuple(sweep.method),
        f=tuple(map(float, sweep.f)),
        theta0=tuple(map(float, sweep.theta0)),
        dt=tuple(map(float, sweep.dt)),
        t_end=t_end,
        every=every,
        threshold=float(cfg.runner.divergence_threshold),
        strides=tuple(strides),
        n_samples=n_samples,
        bodies=bodies,
        omega0=omega0,
        q0=q0,
        variables=chosen_variables(_list_or_none(cfg.output.variables)),
    )


def _list_or_none(node):
    return None if node is None else list(node)


def _prefix_sweep(message):
    """Name sweep keys in full: the kernels say ``f=…``, the config says ``sweep.f=…``."""
    for key in ("f=", "theta0=", "dt=", "t_end="):
        if message.startswith(key):
            return "sweep." + message
    return message


def chunk_size(
    steps_per_run, rate, threads, chunk_seconds, bytes_per_run, max_bytes=MAX_CHUNK_BYTES, speedup=1.0, in_time=False
):
    """Runs per chunk: about ``chunk_seconds`` of work at ``rate`` steps/s per thread,
    a multiple of ``threads`` (so every thread gets equal work), within ``max_bytes``.

    Raised to the batch kernels' MIN_BLOCK_RUNS when that many runs would take at
    most ``chunk_seconds`` in vectorised blocks (``speedup`` times faster per
    run than one by one: the method's BLOCK_SPEEDUP); the measured rate then sizes the next chunks.
    ``in_time``: the runner cuts a longer chunk in time (runner/segments.py), so a method with blocks
    (``speedup`` > 1) gets MIN_BLOCK_RUNS runs however long they are."""
    by_time = chunk_seconds * rate * threads / max(int(steps_per_run), 1)
    k = max(threads, int(by_time // threads) * threads)
    if by_time * speedup >= MIN_BLOCK_RUNS or (in_time and speedup > 1):
        k = max(k, MIN_BLOCK_RUNS)
    by_memory = max(1, int(max_bytes // max(bytes_per_run, 1)))
    if k > by_memory:
        k = max(threads, by_memory // threads * threads) if by_memory >= threads else by_memory
    return k


def plan_chunks(grid, runs, threads, chunk_seconds, rates=None, max_bytes=MAX_CHUNK_BYTES, in_time=True):
    """Split ``runs`` (flat numbers) into chunks of one method each, in method order.

    Runs of one dt fill chunks of ``chunk_size`` equal runs (every thread gets
    the same work); what is left of each dt, less than a chunk, is pooled with
    the other dts' leftovers of that method into chunks of about
    ``chunk_seconds``, so a grid of many small dt groups does not become many
    tiny chunks.  ``in_time`` (both backends): a dt group of MIN_BLOCK_RUNS runs or more keeps
    MIN_BLOCK_RUNS runs a chunk on the block path however long they are, and the backend cuts a
    long chunk in time (runner/segments.py); ``in_time=False``: the rule before (benchmarks).
    """
    rates = rates or {}
    runs = np.sort(np.asarray(runs, dtype=np.int64))
    im, _, _, ld = grid.index(runs)
    chunks = []
    for m in range(len(grid.methods)):
        rate = rates.get(grid.methods[m], STEP_RATE.get(grid.methods[m], DEFAULT_STEP_RATE))
        speedup = step_rate(grid.methods[m], MIN_BLOCK_RUNS, grid.driven) / STEP_RATE.get(
            grid.methods[m], DEFAULT_STEP_RATE
        )
        leftovers = []
        for l in range(len(grid.dt)):
            group = runs[(im == m) & (ld == l)]
            if group.size == 0:
                continue
            steps = int(grid.steps(group[:1])[0])
            long_block = in_time and group.size >= MIN_BLOCK_RUNS
            k = chunk_size(steps, rate, threads, chunk_seconds, grid.bytes_per_run(), max_bytes, speedup, long_block)
            full = group.size // k * k
            chunks.extend(group[i : i + k] for i in range(0, full, k))
            leftovers.append(group[full:])
        chunks.extend(
            _pool(grid, np.concatenate(leftovers) if leftovers else runs[:0], rate, threads, chunk_seconds, max_bytes)
        )
    return chunks


def _pool(grid, runs, rate, threads, chunk_seconds, max_bytes):
    """Pack runs of mixed step counts into chunks of at most ~chunk_seconds and max_bytes."""
    budget_steps = chunk_seconds * rate * threads
    max_runs = max(1, int(max_bytes // max(grid.bytes_per_run(), 1)))
    chunks, start, steps = [], 0, 0
    per_run = grid.steps(runs)
    for i, n in enumerate(per_run):
        if i > start and (steps + n > budget_steps or i - start >= max_runs):
            chunks.append(runs[start:i])
            start, steps = i, 0
        steps += int(n)
    if start < len(runs):
        chunks.append(runs[start:])
    return chunks


def step_rate(method, n_runs, driven=False):
    """Estimated steps per second per thread of ``method`` in a chunk of ``n_runs`` runs: STEP_RATE,
    times its BLOCK_SPEEDUP when the batch kernels run the chunk in vectorised blocks."""
    rate = STEP_RATE.get(method, DEFAULT_STEP_RATE)
    if runs_in_blocks(method, n_runs, driven):
        rate *= BLOCK_SPEEDUP.get(method, DEFAULT_BLOCK_SPEEDUP)
    return rate


def runs_in_blocks(method, n_runs, driven=False):
    """Whether kernels/batch.py's ``integrate`` runs a chunk of ``n_runs`` runs of ``method`` on the
    block path (its "auto" rule: the method allows it and there are MIN_BLOCK_RUNS runs or more; a
    driven body, ``driven``, never: it runs one by one through step_driven)."""
    from ..kernels.registry import get_method, uses_blocks

    return not driven and n_runs >= MIN_BLOCK_RUNS and uses_blocks(get_method(method))


def estimate_seconds(grid, chunks, threads):
    """Estimated integration wall time (s) of the chunks, JIT compile not included: each chunk's
    runs' steps (every run counted, at its own dt) at ``step_rate``, shared among ``threads``, and
    never less than its longest run."""
    total = 0.0
    for chunk in chunks:
        method = grid.methods[int(grid.index(chunk[:1])[0][0])]
        steps = grid.steps(chunk)
        rate = step_rate(method, len(chunk), grid.driven)
        total += max(float(steps.sum()) / min(threads, len(chunk)), float(steps.max())) / rate
    return total


def estimate_writing_seconds(grid):
    """Estimated wall time (s) of writing the journal (raw samples, checksummed, fsync) and assembling
    the results file, at the effective rates JOURNAL_RATE and ASSEMBLY_RATE (bytes/s) measured by
    benchmarks/bench_pipeline.py, plus ASSEMBLY_PER_RUN seconds per run."""
    raw = grid.n_runs * grid.n_samples * RAW_PER_SAMPLE * 8
    return raw / JOURNAL_RATE + grid.bytes_stored() / ASSEMBLY_RATE + grid.n_runs * ASSEMBLY_PER_RUN
