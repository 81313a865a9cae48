"""The figure registry, and the figures a sweep writes after it finishes.

A figure kind is a ``Figure`` record (analysis/figures/record.py) defined in its own module and listed
once in ``ENTRIES`` (``FIGURES`` maps each name to its record, importing the modules on first use);
``gyrolab-plot KIND`` (analysis/figures/cli.py), the runner's figure step and the tests all iterate over
this registry.  A study names the figures it wants in its config (``output.figures: [stability,
energy]``; ``true`` means ``DEFAULT``, ``false`` none); the resolved config is stored in the results
file, so ``gyrolab-plot standard FILE`` draws the same set.

Any grid shape: each figure facets its panels (analysis/figures/record.py: rows of at
most 3, bounded size) and draws every method it is given (past 8 curves a panel,
the methods are split over more panels); when a grid has more f, θ0 or dt values
than it can draw, it draws a selection and says which, in the figure and on the
command line, with the ``gyrolab-plot KIND FILE key=...`` that draws the others.
The figure step reads the file lazily (results.open_results(lazy=True)): its memory
follows what is drawn, not the file's size.  A figure that fails
is reported on stderr and skipped, so a sweep's results are never lost to a
plotting problem; each figure drawn is reported on one progress line.
"""

import functools
import sys
import time
from pathlib import Path

from .record import Figure  # noqa: F401 (the record each figure module defines)

# One line per figure kind: its name, and "<module of analysis/figures>.<its Figure record>".  The names
# are known without importing the figure modules (matplotlib, xarray): a dry run checks ``output.figures``
# and costs the figure step from them alone.
ENTRIES = {
    "nutation": "nutation.THETA",
    "tip": "nutation.TIP",
    "energy": "energy.DRIFT",
    "invariants": "energy.INVARIANTS",
    "work-precision": "work_precision.FIGURE",
    "sciml": "sciml.FIGURE",
    "stability": "stability.FIGURE",
    "animation": "animation.FIGURE",
}
# What a sweep draws when its config says ``output.figures: true``.
DEFAULT = ("nutation", "tip", "energy", "invariants")


@functools.cache
def _registry():
    """{name: Figure} of every entry, importing the figure modules (once)."""
    import importlib

    figures = {}
    for name, entry in ENTRIES.items():
        module, _, record = entry.partition(".")
        figure = getattr(importlib.import_module(f".{module}", __package__), record)
        if figure.name != name:
            raise RuntimeError(f"figure registry: {entry} is named {figure.name!r}, listed as {name!r}")
        figures[name] = figure
    return figures


def __getattr__(attr):
    """``FIGURES`` ({name: Figure}), imported on first use: the figure modules bring matplotlib."""
    if attr == "FIGURES":
        return _registry()
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


def figure_names(setting):
    """The figure names a config's ``output.figures`` asks for (True: DEFAULT, False/None: none);
    ValueError naming the first unknown one."""
    if setting is None or setting is False:
        return ()
    if setting is True:
        return DEFAULT
    names = [setting] if isinstance(setting, str) else list(setting)
    for name in names:
        if name not in ENTRIES:
            raise ValueError(
                f"output.figures={name}: unknown figure; choose from {', '.join(ENTRIES)} "
                "(or true for the default set, false for none)"
            )
    return tuple(names)


def requested_figures(ds):
    """The figures the file's own config asked for (its ``config`` attr), else DEFAULT."""
    import yaml

    from ...limits import safe_yaml

    try:
        config = safe_yaml(ds.attrs.get("config", "")) or {}
        setting = (config.get("output") or {}).get("figures", True)
        return figure_names(setting) or DEFAULT
    except (yaml.YAMLError, AttributeError, ValueError):  # ValueError: limits.LimitError too
        return DEFAULT


def standard_figures(results_path, out_dir, names=None, log=print, ds=None, label=None):
    """Write the figures ``names`` (default: those the file's config asks for) of ``results_path``
    (or of its opened Dataset ``ds``: one member of a combined file) into ``out_dir`` (created);
    return the written paths.  One progress line per figure through ``log`` (and each figure's
    selection note, with ``label``, default the file's path, in its command)."""
    from ...results import open_results
    from ..io import MissingVariableError

    if ds is None:  # read lazily: each figure reads the slabs it draws, never the whole file
        ds = open_results(results_path, lazy=True)
        try:
            return standard_figures(results_path, out_dir, names, log, ds, label)
        finally:
            ds.close()
    which = "" if label is None else f" ({label})"
    label = str(results_path) if label is None else label
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = requested_figures(ds) if names is None else figure_names(names)
    paths = []
    for k, name in enumerate(names, 1):
        figure = _registry()[name]
        started = time.perf_counter()
        notes = []
        try:
            path = figure.write(ds, out_dir / (figure.file_name or f"{name.replace('-', '_')}.png"), notes=notes)
        except MissingVariableError as err:
            print(f"gyrolab: figure {name} skipped{which}: {err}", file=sys.stderr)
            continue
        except Exception as err:  # a figure must never cost the user the results
            print(f"gyrolab: figure {name} skipped{which}: {type(err).__name__}: {err}", file=sys.stderr)
            continue
        paths.append(path)
        if log is not None:
            log(f"gyrolab: figure {k}/{len(names)} {name}: {path} ({time.perf_counter() - started:.1f} s)")
            for note in notes:
                log(f"gyrolab:   {name}: {note.replace('FILE', label)}")
    return paths
