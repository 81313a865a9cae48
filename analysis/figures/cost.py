"""What the figure step costs: seconds of wall time per figure kind on the 2-core development machine when
quiet, from the grid's shape, for the dry run (the figure step draws after the results file is written).

Each kind reads and draws a selection of the grid's runs (analysis/figures/record.py ``choose``: every
method, at most ``max_dt`` dt values and ``max_panels`` f × θ0 panels; methods past MAX_METHODS a panel
take more panels out of MAX_CELLS).  Its time is modelled as

    seconds = base + own_per_sample × samples per run + runs drawn × (per_run + per_sample × samples per run)

(base: the figure, its layout and PNG; per_run: a slab read and a curve; per_sample: reading, deriving
and drawing one sample, or for work-precision timing the run again, which the samples stand for; own_per_sample:
what a kind integrates of its own over a run's span, once: sciml's references).  One ``Cost`` per kind of
registry.FIGURES, in COSTS.  The coefficients are a non-negative least-squares fit to ``python
benchmarks/bench_post_steps.py figures`` on the quiet 2-core machine (load average < 1; CPU time of the
drawing process, one thread), files of 2 to 500 runs and 1001 to 10001 samples (docs/benchmarks.md "The
post-steps' time").  IMPORT_SECONDS is paid once per figure step: importing the figure modules and
matplotlib.  An earlier fit, taken on a machine at load average 14–30, was 3–5× these: CPU time is not
load-free either.
"""

import math
from dataclasses import dataclass

from .record import MAX_CELLS, MAX_DT, MAX_METHODS, MAX_PANELS

IMPORT_SECONDS = 0.95


@dataclass(frozen=True)
class Cost:
    """How one figure kind selects runs and what each costs (s).  methods: 'all' or 'one'
    (tip: one method and dt); max_dt / max_panels: as the kind passes them to ``choose`` (None: all);
    rows_each: panels per f × θ0 (invariants: one per quantity); f_dt_all: draws every f and dt
    of one θ0 (the stability map)."""

    base: float
    per_run: float
    per_sample: float
    own_per_sample: float = 0.0
    methods: str = "all"
    max_dt: int = MAX_DT
    max_panels: int = MAX_PANELS
    rows_each: int = 1
    f_dt_all: bool = False


# Measured (s) on files of 2, 45, 45 (10x the samples) and 500 runs in the comments; nutation, energy,
# invariants and stability refitted on 2026-12-05 after they stopped selecting each run from the whole
# file (energy.py run_errors) and making log ticks outside the view (io.ticks_in_view).
COSTS = {
    "nutation": Cost(0.22, 0.0040, 6.0e-7, max_dt=2, max_panels=6),  # 0.21, 0.40, 0.52, 0.48
    "tip": Cost(0.0, 0.096, 0.0, methods="one", max_dt=1),  # a panel per run: 0.12, 0.26, 0.26, 0.88
    "energy": Cost(0.095, 0.0073, 0.0),  # 0.18, 0.33, 0.38, 0.82
    "invariants": Cost(0.20, 0.0072, 7.0e-7, max_panels=5, rows_each=3),  # 0.22, 0.56, 0.83, 0.60
    # work-precision times each run again against a DOP853 reference: 0.62, 4.66, 35.4, 5.78
    "work-precision": Cost(0.50, 0.036, 7.4e-5, max_dt=None, max_panels=4),
    # sciml integrates references of its own over the run's span, whatever the grid: 17.1, 17.2, 149, 17.1
    "sciml": Cost(2.4, 0.0, 0.0, own_per_sample=0.0147, max_dt=None, max_panels=1),
    "stability": Cost(0.29, 0.0011, 2.0e-7, f_dt_all=True),  # 0.14, 0.53, 0.41, 0.58
    "animation": Cost(5.1, 0.0, 0.0, methods="one", max_dt=1, max_panels=1),  # one run, ≤ 120 frames: 5.1–5.4
}


def runs_drawn(kind, shape):
    """Runs a figure of ``kind`` reads from a grid of ``shape`` (methods, f, θ0, dt)."""
    cost = COSTS[kind]
    n_m, n_f, n_t, n_d = shape
    if cost.f_dt_all:
        return n_m * n_f * n_d
    methods = 1 if cost.methods == "one" else n_m
    groups = 1 if cost.methods == "one" else math.ceil(n_m / MAX_METHODS)
    dts = n_d if cost.max_dt is None else min(n_d, cost.max_dt)
    panels = max(1, min(cost.max_panels, MAX_CELLS // (groups * cost.rows_each)))
    return methods * dts * min(n_f * n_t, panels)


def figure_seconds(kind, shape, n_samples):
    """Estimated wall time (s) of drawing one figure of ``kind`` (a name of registry.FIGURES) from a
    results file of grid ``shape`` (methods, f, θ0, dt) with ``n_samples`` samples a run."""
    cost = COSTS[kind]
    runs = runs_drawn(kind, shape)
    return cost.base + cost.own_per_sample * n_samples + runs * (cost.per_run + cost.per_sample * n_samples)


def figure_step_seconds(names, shape, n_samples):
    """({kind: seconds}, total seconds) of the figure step drawing ``names`` (total: IMPORT_SECONDS
    once, when there is a figure)."""
    each = {name: figure_seconds(name, shape, n_samples) for name in names}
    return each, (IMPORT_SECONDS + sum(each.values())) if each else 0.0
