"""Post-hoc analysis: figures and comparisons read from stored results files.

The public entry points other packages use (the runner's figure step):
``standard_figures(results_path, out_dir, names=None)``, ``figure_names(setting)``
and ``FIGURES`` (analysis/figures/registry.py); for the dry run, ``figure_step_seconds`` and
``verdict_seconds`` (analysis/figures/cost.py, analysis/verdicts/cost.py).
"""


def standard_figures(results_path, out_dir, names=None):
    """Write the named figures (default: those the file's config asks for); see analysis/figures/registry.py."""
    from .figures.registry import standard_figures as draw

    return draw(results_path, out_dir, names)


def figure_names(setting):
    """The figure names an ``output.figures`` setting asks for; ValueError on an unknown one."""
    from .figures.registry import figure_names as names

    return names(setting)


def figure_step_seconds(names, shape, n_samples):
    """({kind: s}, total s): estimated wall time of the figure step; see analysis/figures/cost.py."""
    from .figures.cost import figure_step_seconds as seconds

    return seconds(names, shape, n_samples)


def verdict_seconds(grids, stability, rate, threads=2):
    """{part: s}: estimated wall time of the verdict study's post-step; see analysis/verdicts/cost.py."""
    from .verdicts.cost import verdict_seconds as seconds

    return seconds(grids, stability, rate, threads)
