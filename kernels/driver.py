"""Advance one run of a batch and record its samples; shared by every method.

Each method module defines ``step(w, q, dt, body) -> (w, q)``; entry.py builds
``advance_run = make_advance(step_counted, counting)`` for it (the step and its solver's iterations,
0 for a method without one: entry.counted) and a ``run_batch`` that calls it inside one ``prange`` over runs.
Each run's solver iterations (in all, most in one step) land in ``iterations`` (n, 2); a step whose
solver did not converge ends its run with STATUS_UNCONVERGED.  The step is bound by a closure, not passed as an
argument: numba lowers a dispatcher passed by value to a raw pointer, which
makes the calling kernel uncacheable.  Every kernel function is compiled with
``error_model="numpy"``: a division by zero (a blown-up run) gives inf/NaN and
the run is flagged non-finite, where the default would raise an exception that
a ``prange`` loses, leaving the run unwritten with status ok.

The parallel kernels are cached with the method (entry.py); the cache
directory is keyed by what each file compiles (kernels/__init__.py,
COMPILE_KEYS), so an edit of this file or of any helper never runs stale
machine code.

Sample layout, last axis of ``out`` (n_runs, n_samples, N_FIELDS):
axis_x, axis_y, axis_z (R e3, lab), omega_1..3 (body, rad/s),
energy (J), L_x, L_y, L_z (lab angular momentum, kg m²/s), L3 (kg m²/s),
gamma_1..3 (γ = Rᵀ ẑ, the lab vertical in body coordinates).
A new per-sample quantity is one more field here and in ``_record``, its
formula in reference.py's ``samples_from_states``, and one entry in the
results layout (gyrolab/results/layout.py; the recipe in docs/design.md).
"""

import math

import numpy as np
from numba import njit

from .body import Body, body_row
from .rigid_body import axis_lab, divergence_scale, energy, lab_momentum
from .rotation import lab_up_in_body

FIELDS = (
    "axis_x",
    "axis_y",
    "axis_z",
    "omega_1",
    "omega_2",
    "omega_3",
    "energy",
    "L_x",
    "L_y",
    "L_z",
    "L3",
    "gamma_1",
    "gamma_2",
    "gamma_3",
)
ENERGY = FIELDS.index("energy")
N_FIELDS = len(FIELDS)

STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_ENERGY = 2
STATUS_UNCONVERGED = 3
STATUS_LEGEND = {
    STATUS_OK: "ok",
    STATUS_NONFINITE: "state became NaN/inf",
    STATUS_ENERGY: "|E - E0| exceeded divergence_threshold x (T0 + |M g c|)",
    STATUS_UNCONVERGED: "a step's implicit solver did not converge within its iteration cap",
}


@njit(cache=True, error_model="numpy")
def _record(out, i, k, w, q, body):
    ax = axis_lab(q)
    L = lab_momentum(w, q, body)
    out[i, k, 0] = ax[0]
    out[i, k, 1] = ax[1]
    out[i, k, 2] = ax[2]
    out[i, k, 3] = w[0]
    out[i, k, 4] = w[1]
    out[i, k, 5] = w[2]
    out[i, k, 6] = energy(w, q, body)
    out[i, k, 7] = L[0]
    out[i, k, 8] = L[1]
    out[i, k, 9] = L[2]
    out[i, k, 10] = body[2] * w[2]
    g = lab_up_in_body(q)
    out[i, k, 11] = g[0]
    out[i, k, 12] = g[1]
    out[i, k, 13] = g[2]


@njit(cache=True, error_model="numpy")
def _start(i, w0, q0, bodies, threshold, out, status):
    """Run i's body, initial state and energy tolerance; records sample 0 and marks the run ok."""
    body = body_row(bodies, i)
    w = (w0[i, 0], w0[i, 1], w0[i, 2])
    q = (q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3])
    _record(out, i, 0, w, q, body)
    status[i] = STATUS_OK
    return body, w, q, threshold * divergence_scale(w, body)


@njit(cache=True, error_model="numpy")
def tolerances(w0, bodies, threshold):
    """Each run's bound on |E − E0| (J): ``threshold`` × rigid_body.divergence_scale (T0 + |M g c|,
    plus a drive's reach), as ``_start`` computes it (the same bits), for a check of samples integrated
    on from a saved state (runner/segments.py)."""
    out = np.empty(w0.shape[0])
    for i in range(w0.shape[0]):
        out[i] = threshold * divergence_scale((w0[i, 0], w0[i, 1], w0[i, 2]), body_row(bodies, i))
    return out


def _run_around(steps_and_samples):
    """``advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations)``
    around a method's loop ``steps_and_samples(i, w, q, dt, stride, body, tolerance, out, status) ->
    (steps done, solver iterations in all, most in one step)``."""

    @njit(error_model="numpy")
    def advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations):
        body, w, q, tolerance = _start(i, w0, q0, bodies, threshold, out, status)
        # Two inlined copies of the loop: in the first the centre of mass is on e3 as a constant, so
        # the general branch of gravity_torque is folded away (a loop-invariant branch costs rk4's
        # four torque evaluations a step about 10 ns otherwise).  Same bits either way.
        if body[4] == 0.0 and body[5] == 0.0:
            axial = Body(body[0], body[1], body[2], body[3], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            done, total, most = steps_and_samples(i, w, q, dts[i], strides[i], axial, tolerance, out, status)
        else:
            done, total, most = steps_and_samples(i, w, q, dts[i], strides[i], body, tolerance, out, status)
        n_steps[i] = done
        iterations[i, 0] = total
        iterations[i, 1] = most

    return advance_run


def make_advance(step_counted, counting):
    """``advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations)``
    specialised to one method's counted step ``step_counted(w, q, dt, body) -> (w, q, n)``: the
    method's ``step`` and the iterations n its solver took (n < 0: not converged after −n, the state
    NaN; methods/README.md, "Solvers").  ``counting`` False (a method without a solver, whose n is 0:
    entry.py's ``counted``) compiles the tally out of the loop: a test per step, even of a constant,
    cost rk4 5–7 % one by one (measured).

    Integrates run i for ``strides[i]`` steps of ``dts[i]`` (s) per sample.
    Stops early, fills the remaining samples with NaN and sets ``status[i]``
    when a step's solver did not converge, the state goes non-finite or |E − E0| passes
    ``threshold`` times the energy scale T0 + |M g c| (so a top released at θ0 = 90°, E0 = T0,
    is fine).  ``iterations[i]`` = (the solver's iterations over the run, most in one step).
    """

    @njit(error_model="numpy", forceinline=True)
    def steps_and_samples(i, w, q, dt, stride, body, tolerance, out, status):
        done, total, most, failed = 0, 0, 0, False
        for k in range(1, out.shape[1]):
            for _ in range(stride):
                w, q, n = step_counted(w, q, dt, body)
                if counting:
                    total, most, failed = _count(total, most, failed, n)
                    if failed:
                        break
            done += stride
            _record(out, i, k, w, q, body)
            if _stopped(out, i, k, tolerance, status, failed):
                break
        return done, total, most

    return _run_around(steps_and_samples)


def make_advance_carried(start, step_carried_counted, counting):
    """``advance_run`` of ``make_advance`` for a method that carries state beyond (ω, q) from one step
    to the next (methods/README.md, "carried state": a multistep or generalized-α history such as
    lie_genalpha's accelerations): ``c = start(w, q, body)`` once from the run's initial state, then
    ``w, q, c, n = step_carried_counted(w, q, c, dt, body)`` each step (n and ``counting`` as in
    ``make_advance``).
    The carried state lives in the loop only: such a method runs one run after another (BLOCKS
    False), so a run is never cut into time segments and its carried state never needs to be saved;
    a resumed sweep runs it again whole."""

    @njit(error_model="numpy", forceinline=True)
    def steps_and_samples(i, w, q, dt, stride, body, tolerance, out, status):
        c = start(w, q, body)
        done, total, most, failed = 0, 0, 0, False
        for k in range(1, out.shape[1]):
            for _ in range(stride):
                w, q, c, n = step_carried_counted(w, q, c, dt, body)
                if counting:
                    total, most, failed = _count(total, most, failed, n)
                    if failed:
                        break
            done += stride
            _record(out, i, k, w, q, body)
            if _stopped(out, i, k, tolerance, status, failed):
                break
        return done, total, most

    return _run_around(steps_and_samples)


def make_advance_driven(step_driven_counted, counting):
    """``advance_run`` of ``make_advance`` for driven bodies (a torque that depends on time,
    body.py): each step is ``step_driven_counted(w, q, t, dt, body) -> (w, q, n)`` (n and
    ``counting`` as in ``make_advance``) from t = n dt, n the steps taken, so that t carries no rounding accumulated
    over the run.  The drive's window acts per step: a step whose midpoint t + dt/2 lies in
    [drive_on, drive_off] gets the body with its drive, any other the body with the drive's
    amplitude zeroed.  A window whose ends are multiples of dt is then exact; elsewhere the switch
    lands on the nearest step boundary."""

    @njit(error_model="numpy")
    def advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations):
        body, w, q, tolerance = _start(i, w0, q0, bodies, threshold, out, status)
        dt, stride = dts[i], strides[i]
        idle = Body(body[0], body[1], body[2], body[3], body[4], body[5], 0.0, 0.0, 0.0, body[9], body[10], body[11])
        done, total, most, failed = 0, 0, 0, False
        for k in range(1, out.shape[1]):
            for _ in range(stride):
                t = done * dt
                if body[10] <= t + 0.5 * dt <= body[11]:
                    w, q, n = step_driven_counted(w, q, t, dt, body)
                else:
                    w, q, n = step_driven_counted(w, q, t, dt, idle)
                done += 1
                if counting:
                    total, most, failed = _count(total, most, failed, n)
                    if failed:
                        break
            _record(out, i, k, w, q, body)
            if _stopped(out, i, k, tolerance, status, failed):
                break
        n_steps[i] = done
        iterations[i, 0] = total
        iterations[i, 1] = most

    return advance_run


@njit(cache=True, error_model="numpy", forceinline=True)
def _count(total, most, failed, n):
    """The run's solver tally after a step that took n iterations (n < 0: −n, not converged)."""
    m = -n if n < 0 else n
    return total + m, max(most, m), failed or n < 0


@njit(cache=True, error_model="numpy")
def _stopped(out, i, k, tolerance, status, failed):
    """Whether run i ends at sample k: a step's solver failed on the way to it (status unconverged),
    or the sample is non-finite or off in energy (``_diverged``).  NaN-fills what follows."""
    if not failed:
        return _diverged(out, i, k, tolerance, status)
    status[i] = STATUS_UNCONVERGED
    _fill_after(out, i, k)
    return True


@njit(cache=True, error_model="numpy")
def _diverged(out, i, k, tolerance, status):
    """Flag run i if sample k is non-finite or off in energy; NaN-fill what follows."""
    if abs(out[i, k, ENERGY] - out[i, 0, ENERGY]) <= tolerance:  # False for NaN too
        return False
    finite = True
    for f in range(N_FIELDS):
        finite = finite and math.isfinite(out[i, k, f])
    status[i] = STATUS_ENERGY if finite else STATUS_NONFINITE
    _fill_after(out, i, k)
    return True


@njit(cache=True, error_model="numpy")
def _fill_after(out, i, k):
    """NaN in run i's samples after sample k."""
    for later in range(k + 1, out.shape[1]):
        for f in range(N_FIELDS):
            out[i, later, f] = np.nan
