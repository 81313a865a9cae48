"""The standard figures the runner writes after a sweep (``output.figures=true``).

``standard_figures(results_path, out_dir)`` reads one results file and writes
PNGs that read well from any grid shape: θ(t) against the closed-form bounds,
the tip locus seen from above, the energy drift and all three invariants.
Large grids are thinned for these line figures (at most 4 values of f, 3 of
dt, 2 of θ0).  A file named after a pinned study (``output.path`` =
``stability.h5`` or ``work_precision.h5``, as set by conf/experiment) also
gets that study's figure.  A figure that fails is reported on stderr and
skipped, so a sweep's results are never lost to a plotting problem.
"""
import sys
import time
from pathlib import Path

import numpy as np

from .io import open_results, save_figure


def thin(ds, max_f=4, max_dt=3, max_theta0=2):
    """Selection dict keeping at most max_* evenly spread values of f, dt, θ0 (ends included)."""
    sel = {}
    for key, n in (("f", max_f), ("dt", max_dt), ("theta0", max_theta0)):
        values = ds[key].values
        if values.size > n:
            idx = np.unique(np.round(np.linspace(0, values.size - 1, n)).astype(int))
            sel[key] = [float(v) for v in values[idx]]
    return sel


def study_of(path):
    """The pinned study a results file belongs to, from its file name (or None)."""
    stem = Path(path).stem
    for study in ("work_precision", "stability"):
        if stem.startswith(study):
            return study
    return None


def standard_figures(results_path, out_dir):
    """Write the standard PNGs of ``results_path`` into ``out_dir``; return their paths."""
    from .energy import drift_figure, invariants_figure
    from .nutation import theta_figure, tip_locus_figure

    ds = open_results(results_path)
    out_dir = Path(out_dir)
    sel = thin(ds)
    small = ds.sel(sel) if sel else ds
    jobs = [
        ("nutation_theta.png", lambda: theta_figure(small)),
        ("tip_locus.png", lambda: tip_locus_figure(small, method=_best_method(small))),
        ("energy_drift.png", lambda: drift_figure(small, "energy")),
        ("invariants.png", lambda: invariants_figure(small)),
    ]
    study = study_of(results_path)
    if study == "stability":
        from .stability import stability_figure

        jobs.insert(0, ("stability_map.png", lambda: stability_figure(ds)))
    elif study == "work_precision":
        from .work_precision import work_precision_figure

        jobs.insert(0, ("work_precision.png", lambda: work_precision_figure(ds)))
    paths = []
    for name, make in jobs:
        started = time.perf_counter()
        try:
            paths.append(save_figure(make(), out_dir / name))
        except Exception as err:  # a figure must never cost the user the results
            print(f"gyrolab: figure {name} skipped: {type(err).__name__}: {err}", file=sys.stderr)
        else:
            if time.perf_counter() - started > 30:
                print(f"gyrolab: figure {name} took {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return paths


def _best_method(ds):
    """The method drawn in the single-run figures: seed_next when present (the write-up's scheme)."""
    methods = [str(m) for m in ds.method.values]
    return "seed_next" if "seed_next" in methods else methods[0]
