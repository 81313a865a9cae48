"""What the verdict study's post-step costs: seconds of wall time on the 2-core development machine when
quiet, for the dry run of ``gyrolab experiment=verdict`` (analysis/verdicts/study.py's callback).

The callback (after every job has written its file) reads the files, fits the orders and classifies the
drifts (``verdict`` without ``stability``), bisects (|ω| dt)_crit once per (scene, method with a declared
order) at the first (f, θ0) of its files (``threshold_records``), and writes verdict.md, verdict.json and
one figure per scene.  The bisection is counted step by step: ``classify.stability_threshold`` itself is
replayed with a predicate that knows the threshold (NOMINAL_CRIT), so the trial steps are exactly the
ones it would try; each trial integrates t_end s at the method's steps per second ``rate(method, n_runs,
driven)``, which the caller passes: runner/grid.py's ``step_rate`` (the analysis does not import the
runner; a bisection batch is a handful of runs, so the one-by-one or driven path).  The lowest
trial, |ω| dt = 1e-3, is most of the steps whatever the threshold is, so the nominal threshold costs
little accuracy.  The other coefficients are fitted by benchmarks/bench_post_steps.py verdict (CPU time of
the one process on the quiet machine, load average < 1; a first fit on a machine at load 14-30 was 2.4-3x
these).
"""

import numpy as np

NOMINAL_CRIT = 1.0  # rad: (|ω| dt)_crit assumed for counting the trials (measured ones: 0.1 to 3, docs/verdict.md)
BISECTION_SAMPLES = 65  # method_stability_threshold's n_samples: steps = 64 × its stride
# Fitted by benchmarks/bench_post_steps.py (see docs/benchmarks.md "The post-steps' time"):
BISECTION_RATE_FACTOR = 1.0  # measured steps/s of the bisection over runner/grid.py's step_rate
BISECTION_CALL_SECONDS = 0.0  # per integrate call of the bisection (dispatch, tiling, status check)
# reading and classifying, 2 scenes x (ladder, long run) of 5 methods: 2.95 s measured
READ_SECONDS_PER_FILE = 0.38  # opening a results file, its per-run variables, a ladder's reference (DOP853)
SECONDS_PER_SAMPLE = 1.4e-5  # reading and classifying one stored sample of one run (the long runs' drifts)
FIGURE_SECONDS_PER_SCENE = 1.15  # verdict_<scene>.png (2.29 s for two scenes of 5 methods)
WRITE_SECONDS = 0.02  # verdict.md, verdict.json (0.01 s measured)


def bisection_trials(omega, t_end, crit=NOMINAL_CRIT, rtol=1e-3, batch=4):
    """The integrate calls of one ``method_stability_threshold`` (default bracket |ω| dt from 1e-3 to 10
    rad) whose (|ω| dt)_crit is ``crit``: a list of arrays, each the steps of the runs of one call.
    omega: |ω0| (rad/s); t_end (s)."""
    from .classify import stability_threshold

    calls = []
    dt_crit = crit / omega

    def run_ok(dts):
        dts = np.asarray(dts, dtype=float)
        stride = np.maximum(1, np.ceil(t_end / (BISECTION_SAMPLES - 1) / dts))
        calls.append((BISECTION_SAMPLES - 1) * stride)
        return dts < dt_crit

    stability_threshold(run_ok, 1e-3 / omega, 10.0 / omega, omega=omega, rtol=rtol, batch=batch, max_evals=200)
    return calls


def bisection_seconds(method, omega, t_end, rate, threads=2, driven=False):
    """Estimated wall time (s) of bisecting ``method``'s (|ω| dt)_crit over ``t_end`` s from a state
    rotating at ``omega`` rad/s, on ``threads`` numba threads (a call's runs are shared among them; a
    call lasts at least its longest run); ``rate(method, n_runs, driven)``: steps/s per thread.  Runs
    above the threshold are counted in full (they stop when they diverge, which near the threshold is
    late)."""
    batch = max(4, 2 * threads)
    total = 0.0
    for steps in bisection_trials(omega, t_end, batch=batch):
        speed = rate(method, len(steps), driven) * BISECTION_RATE_FACTOR
        total += max(steps.sum() / min(threads, len(steps)), steps.max()) / speed + BISECTION_CALL_SECONDS
    return total


def verdict_seconds(grids, stability, rate, threads=2):
    """Estimated wall time (s) of the verdict study's post-step over the job grids ``grids`` (each a
    runner/grid.py Grid, one per results file of the multirun): {'reading': ..., 'bisection': ...,
    'figures': ..., 'writing': ...}.  ``stability``: T (s) of the bisection, None or 0 for none;
    ``rate``: as for ``bisection_seconds``."""
    from .verdict import declared_order

    reading = sum(READ_SECONDS_PER_FILE + g.n_runs * g.n_samples * SECONDS_PER_SAMPLE for g in grids)
    bisection, done = 0.0, set()
    for g in grids:
        if not stability:
            break
        omega = float(np.linalg.norm(g.inputs(np.zeros(1, dtype=np.int64))[1][0]))  # the first (f, θ0)
        for m in g.methods:
            if (g.scene, m) in done or declared_order(m) is None or omega == 0.0:
                continue
            done.add((g.scene, m))
            bisection += bisection_seconds(m, omega, float(stability), rate, threads, g.driven)
    scenes = {g.scene for g in grids}
    return {
        "reading": reading,
        "bisection": bisection,
        "figures": FIGURE_SECONDS_PER_SCENE * len(scenes),
        "writing": WRITE_SECONDS,
    }
