"""The record of one figure kind (the registry is analysis/figures.py)."""
from dataclasses import dataclass, field
from typing import Callable

from .io import save_figure


@dataclass(frozen=True)
class Figure:
    """One figure kind.

    name: the CLI kind and the name in ``output.figures``; help: one line for
    ``--help``; draw(ds, sel, **options) -> matplotlib Figure, from a results
    Dataset and a selection dict; options: {flag: argparse kwargs} of its own
    CLI options (their ``dest`` names are the keyword arguments of draw);
    file_name: the PNG written by the figure step; thinned: draw the thinned
    grid (``thin``) in the figure step; render: optional
    render(ds, out, sel, **options) -> path for figures that are not a single
    matplotlib Figure (the animation writes a GIF).
    """

    name: str
    help: str
    draw: Callable = None
    options: dict = field(default_factory=dict)
    file_name: str = None
    thinned: bool = True
    render: Callable = None

    def write(self, ds, out, sel=None, formats=("png",), **options):
        """Draw into ``out`` (suffix replaced per format); the written path."""
        if self.render is not None:
            return self.render(ds, out, sel=sel, **options)
        return save_figure(self.draw(ds, sel, **options), out, formats=formats)
