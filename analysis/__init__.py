"""Post-hoc analysis: figures and comparisons read from stored results files.

The public entry points other packages use (the runner's figure step):
``standard_figures(results_path, out_dir, names=None)``, ``figure_names(setting)``
and ``FIGURES`` (analysis/figures/registry.py).
"""


def standard_figures(results_path, out_dir, names=None):
    """Write the named figures (default: those the file's config asks for); see analysis/figures/registry.py."""
    from .figures.registry import standard_figures as draw

    return draw(results_path, out_dir, names)


def figure_names(setting):
    """The figure names an ``output.figures`` setting asks for; ValueError on an unknown one."""
    from .figures.registry import figure_names as names

    return names(setting)
