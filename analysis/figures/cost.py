"""What the figure step costs: seconds of wall time per figure kind on the 2-core development machine when
quiet, from the grid's shape, for the dry run (the figure step draws after the results file is written).

Each kind reads and draws a selection of the grid's runs (analysis/figures/record.py ``choose``: every
method, at most ``max_dt`` dt values and ``max_panels`` f × θ0 panels; methods past MAX_METHODS a panel
take more panels out of MAX_CELLS).  Its time is modelled as

    seconds = base + per_run × runs drawn + per_sample × runs drawn × samples per run

(base: the figure, its layout and PNG; per_run: a slab read and a curve; per_sample: reading, deriving
and drawing one sample).  One ``Cost`` per kind of registry.FIGURES, in COSTS.  The coefficients are
fitted by benchmarks/bench_post_steps.py figures: CPU time of the drawing process (the figures are one
thread; the machine was loaded, so CPU time stands for a quiet machine's wall time), files of 2 to 500
runs and 1001 to 10001 samples (docs/benchmarks.md "The post-steps' time").  IMPORT_SECONDS is paid once
per figure step: importing the figure modules and matplotlib.
"""

import math
from dataclasses import dataclass

from .record import MAX_CELLS, MAX_DT, MAX_METHODS, MAX_PANELS

IMPORT_SECONDS = 2.6


@dataclass(frozen=True)
class Cost:
    """How one figure kind selects runs and what each costs (s).  methods: 'all' or 'one'
    (tip: one method and dt); max_dt / max_panels: as the kind passes them to ``choose`` (None: all);
    rows_each: panels per f × θ0 (invariants: one per quantity); f_dt_all: draws every f and dt
    of one θ0 (the stability map)."""

    base: float
    per_run: float
    per_sample: float
    methods: str = "all"
    max_dt: int = MAX_DT
    max_panels: int = MAX_PANELS
    rows_each: int = 1
    f_dt_all: bool = False


COSTS = {
    "nutation": Cost(0.95, 0.023, 2.4e-6, max_dt=2, max_panels=6),
    "tip": Cost(0.3, 0.29, 0.0, methods="one", max_dt=1),  # a panel per run: its annulus, its trace
    "energy": Cost(0.76, 0.038, 0.0),
    "invariants": Cost(1.48, 0.078, 1.9e-6, max_panels=5, rows_each=3),
    # work-precision: 2.2 s and 18.7 s on 2 and 45 runs drawn (each run timed again against a DOP853 reference)
    "work-precision": Cost(1.43, 0.38, 0.0, max_dt=None, max_panels=4),
    # sciml: 68.8 s and 67.4 s on 2 and 45 runs (it integrates its own references: the grid hardly matters)
    "sciml": Cost(68.0, 0.0, 0.0, max_dt=None, max_panels=1),
    # stability: 1.17, 1.46, 2.83 s modelled on 2, 45, 250 runs; 0.68, 2.0, 2.7 s measured
    "stability": Cost(1.16, 0.0067, 0.0, f_dt_all=True),
    # animation: 24.3 s and 22.5 s on 2 and 45 runs (one run drawn, at most 120 frames)
    "animation": Cost(23.4, 0.0, 0.0, methods="one", max_dt=1, max_panels=1),
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
    return cost.base + runs * (cost.per_run + cost.per_sample * n_samples)


def figure_step_seconds(names, shape, n_samples):
    """({kind: seconds}, total seconds) of the figure step drawing ``names`` (total: IMPORT_SECONDS
    once, when there is a figure)."""
    each = {name: figure_seconds(name, shape, n_samples) for name in names}
    return each, (IMPORT_SECONDS + sum(each.values())) if each else 0.0
