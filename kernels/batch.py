"""Python entry to the batch kernels: run many independent runs of one method.

Every run has its own body, initial state, dt and sample stride; all runs share
the number of samples.  The work happens in the method's ``run_blocks``
(block.py: runs in blocks, the loop over runs vectorised, one prange over
threads, each with a balanced queue of blocks) or, for a handful of runs, in
its ``run_batch`` (driver.py: one run after another, one prange over runs).
Both give bit-identical results, independent of the thread count and of the
blocking.
"""

import math

import numba
import numpy as np

from . import real
from .block import plan_blocks
from .body import N_FIELDS as N_BODY
from .body import is_driven
from .driver import N_FIELDS
from .registry import DRIVEN_REFUSAL, driven_methods, get_method, sees_time, uses_blocks

DEFAULT_DIVERGENCE_THRESHOLD = 10.0
# Most runs per block: state, body and scratch of 64 lanes take ~8 kB of L1;
# 32 .. 128 lanes run equally fast (see MIN_BLOCK_RUNS for fewer).
BLOCK_LANES = 64
# Fewer runs than this go one by one.  LLVM vectorises the lane loop 8 wide and
# interleaved 4 times, so a block of fewer than 32 lanes runs its scalar
# remainder loop: measured (seed_next, heavy top, 2 threads, ns/step aggregate)
# 8 runs: blocks 35.7 vs one by one 23.7; 32 runs: 17.8 (two blocks of 16);
# 48 runs: 2.9; 64 runs: 2.2.  From 64 runs every thread's block vectorises.
MIN_BLOCK_RUNS = 64
PATHS = ("auto", "blocks", "runs")


def sample_schedule(dt, every, t_end):
    """(stride, n_samples): steps per stored sample and samples including t = 0.

    ValueError when dt does not divide ``every`` (to 1e-9 relative) or the
    times are not positive, or t_end < every.
    """
    for key, value in (("dt", dt), ("output.every", every), ("t_end", t_end)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{key}={value}: must be a finite number > 0")
    stride = round(every / dt)
    if stride < 1 or abs(stride * dt - every) > 1e-9 * every:
        raise ValueError(f"dt={dt}: must divide output.every={every} (every/dt = {every / dt:.6g})")
    if t_end < every:
        raise ValueError(f"t_end={t_end}: must be >= output.every={every}")
    n_samples = int(math.floor(t_end / every * (1 + 1e-12))) + 1
    return stride, n_samples


def integrate(
    method,
    bodies,
    omega0,
    q0,
    dt,
    stride,
    n_samples,
    threshold=DEFAULT_DIVERGENCE_THRESHOLD,
    *,
    path="auto",
    final_state=False,
    iterations=None,
):
    """Integrate a batch of runs with one method, in parallel over runs.

    bodies (n, body.N_FIELDS): rows of body.Body (fields and units in kernels/body.py); omega0 (n, 3) body rates
    (rad/s); q0 (n, 4) quaternions; dt (n,) step (s); stride (n,) steps per
    sample.  Returns (samples (n, n_samples, driver.N_FIELDS) float64 in the field order of
    ``driver.FIELDS``, status (n,) int8, n_steps (n,) int64).  ``path``
    "blocks" or "runs" forces a kernel ("auto": blocks from MIN_BLOCK_RUNS
    runs up, for methods that allow it: ``BLOCKS``); the results are the same bits.
    ``iterations``: None, or an (n, 2) int64 array filled with each run's solver iterations (in all,
    most in one step; methods/README.md, "Solvers"): 0 for a method without a solver, −1 for an
    engine package (kernels/real: not counted).
    """
    if path not in PATHS:
        raise ValueError(f"path={path!r}: choose from {', '.join(PATHS)}")
    if iterations is not None and not (
        isinstance(iterations, np.ndarray)
        and iterations.dtype == np.int64
        and iterations.flags.c_contiguous
        and iterations.flags.writeable
    ):
        raise ValueError("iterations: a writable C-contiguous int64 array of shape (n, 2), or None")
    if real.is_real(method):  # the engine package itself, run by run (kernels/real/); same returns
        if iterations is not None:
            iterations[...] = -1  # the engine's own solver, if any, is not visible: not counted
        return real.integrate(method, bodies, omega0, q0, dt, stride, n_samples, threshold)
    module = get_method(method)
    bodies = np.ascontiguousarray(bodies, dtype=np.float64).reshape(-1, N_BODY)
    n = bodies.shape[0]
    omega0 = np.ascontiguousarray(omega0, dtype=np.float64).reshape(n, 3)
    q0 = np.ascontiguousarray(q0, dtype=np.float64).reshape(n, 4)
    # Writable copies: numba compiles a separate kernel for read-only arrays.
    dt = np.require(np.broadcast_to(dt, (n,)), np.float64, ["C", "W"])
    stride = np.require(np.broadcast_to(stride, (n,)), np.int64, ["C", "W"])
    out = np.empty((n, int(n_samples), N_FIELDS))
    status = np.zeros(n, dtype=np.int8)
    n_steps = np.zeros(n, dtype=np.int64)
    if iterations is None:
        iterations = np.zeros((n, 2), dtype=np.int64)
    elif iterations.shape != (n, 2):
        raise ValueError(f"iterations: shape {iterations.shape}, not ({n}, 2)")
    else:
        iterations[...] = 0  # the block path (methods without a solver) leaves them so
    if final_state and is_driven(bodies):
        raise ValueError("final_state: a driven body runs one by one, not in blocks")
    if is_driven(bodies):
        # A torque that depends on time: only a step that sees time integrates it (never the blocks).
        if not sees_time(module):
            raise ValueError(f"method {method!r} {DRIVEN_REFUSAL}; methods that do: {', '.join(driven_methods())}")
        module.run_batch_driven(omega0, q0, bodies, dt, stride, float(threshold), out, status, n_steps, iterations)
    elif not final_state and (path == "runs" or not uses_blocks(module) or (path == "auto" and n < MIN_BLOCK_RUNS)):
        module.run_batch(omega0, q0, bodies, dt, stride, float(threshold), out, status, n_steps, iterations)
    else:
        plan = plan_blocks(stride, numba.get_num_threads(), BLOCK_LANES)
        state = np.empty((n, 7))
        module.run_blocks(omega0, q0, bodies, dt, stride, float(threshold), out, status, n_steps, *plan, state)
        if final_state:
            return out, status, n_steps, state
    return out, status, n_steps
