"""The figure registry, and the figures a sweep writes after it finishes.

A figure kind is a ``Figure`` record (analysis/figure.py) defined in its own module and listed
once in ``FIGURES``; ``gyrolab-plot KIND`` (analysis/cli.py), the runner's
figure step and the tests all iterate over this registry.  A study names the
figures it wants in its config (``output.figures: [stability, energy]``;
``true`` means ``DEFAULT``, ``false`` none); the resolved config is stored in
the results file, so ``gyrolab-plot standard FILE`` draws the same set.

The line figures read well from any grid shape because large grids are
thinned (at most 4 values of f, 3 of dt, 2 of θ0; ``thin``).  A figure that
fails is reported on stderr and skipped, so a sweep's results are never lost
to a plotting problem.
"""
import sys
import time
from pathlib import Path

import numpy as np

from .figure import Figure  # noqa: F401 (the record each figure module defines)
from .io import open_results


def _registry():
    from . import animation, energy, nutation, stability, work_precision

    figures = (
        nutation.THETA,
        nutation.TIP,
        energy.DRIFT,
        energy.INVARIANTS,
        work_precision.FIGURE,
        stability.FIGURE,
        animation.FIGURE,
    )
    return {f.name: f for f in figures}


FIGURES = _registry()
# What a sweep draws when its config says ``output.figures: true``.
DEFAULT = ("nutation", "tip", "energy", "invariants")


def figure_names(setting):
    """The figure names a config's ``output.figures`` asks for (True: DEFAULT, False/None: none);
    ValueError naming the first unknown one."""
    if setting is None or setting is False:
        return ()
    if setting is True:
        return DEFAULT
    names = [setting] if isinstance(setting, str) else list(setting)
    for name in names:
        if name not in FIGURES:
            raise ValueError(f"output.figures={name}: unknown figure; choose from {', '.join(FIGURES)} "
                             "(or true for the default set, false for none)")
    return tuple(names)


def thin(ds, max_f=4, max_dt=3, max_theta0=2):
    """Selection dict keeping at most max_* evenly spread values of f, dt, θ0 (ends included)."""
    sel = {}
    for key, n in (("f", max_f), ("dt", max_dt), ("theta0", max_theta0)):
        values = ds[key].values
        if values.size > n:
            idx = np.unique(np.round(np.linspace(0, values.size - 1, n)).astype(int))
            sel[key] = [float(v) for v in values[idx]]
    return sel


def requested_figures(ds):
    """The figures the file's own config asked for (its ``config`` attr), else DEFAULT."""
    import yaml

    try:
        config = yaml.safe_load(ds.attrs.get("config", "")) or {}
        setting = (config.get("output") or {}).get("figures", True)
        return figure_names(setting) or DEFAULT
    except (yaml.YAMLError, AttributeError, ValueError):
        return DEFAULT


def standard_figures(results_path, out_dir, names=None):
    """Write the figures ``names`` (default: those the file's config asks for) of ``results_path``
    into ``out_dir``; return the written paths."""
    ds = open_results(results_path)
    out_dir = Path(out_dir)
    names = requested_figures(ds) if names is None else figure_names(names)
    sel = thin(ds)
    small = ds.sel(sel) if sel else ds
    paths = []
    for name in names:
        figure = FIGURES[name]
        started = time.perf_counter()
        try:
            paths.append(figure.write(small if figure.thinned else ds,
                                      out_dir / (figure.file_name or f"{name.replace('-', '_')}.png")))
        except Exception as err:  # a figure must never cost the user the results
            print(f"gyrolab: figure {name} skipped: {type(err).__name__}: {err}", file=sys.stderr)
        else:
            if time.perf_counter() - started > 30:
                print(f"gyrolab: figure {name} took {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return paths
