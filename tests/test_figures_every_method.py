"""The engines study (`experiment=engines`, at a tiny size) through the runner's own figure step: every
figure it writes draws every method it was given (in its legend or panel titles), and no two of its text
boxes overlap; the colour-and-marker scheme tells every registered method (40 and more) apart."""

import matplotlib.pyplot as plt
import pytest
import yaml

from gyrolab.analysis.figures.registry import FIGURES
from gyrolab.results import open_results

from helpers import assert_ok, gyrolab
from test_figures import overlaps, texts

ENGINES = "conf/experiment/engines.yaml"


@pytest.fixture(scope="module")
def engines_files(tmp_path_factory):
    """{scene: results path} of the engines study at 0.1 s (every method, f and dt of the study); the
    tests draw its figures themselves (the runner's figure step is tests/test_experiments.py's)."""
    root = tmp_path_factory.mktemp("engines")
    result = gyrolab(
        "experiment=engines",
        "sweep.t_end=0.1",
        "output.every=0.01",
        "output.figures=false",
        f"hydra.sweep.dir={root}",
        cwd=root,
        timeout=900,
    )
    assert_ok(result)
    files = {}
    for path in sorted(root.glob("*/engines.h5")):
        ds = open_results(path)
        files[str(ds.attrs["scene"])] = path
    assert set(files) == {"heavy_top", "free_asymmetric"}, (files, result.stdout[-2000:])
    return files


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def _study_methods():
    """The study's methods as the runner resolves them (its config names them by selector, all_engines)."""
    from pathlib import Path

    from gyrolab.kernels.registry import select_methods

    here = Path(__file__).resolve().parents[1]
    return select_methods(yaml.safe_load((here / ENGINES).read_text())["sweep"]["method"])


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["stability", "energy", "invariants"])
@pytest.mark.parametrize("scene", ["heavy_top", "free_asymmetric"])
def test_engines_figures_draw_every_method_without_overlap(kind, scene, engines_files):
    ds = open_results(engines_files[scene])
    methods = [str(m) for m in ds.integrator.values]
    assert methods == _study_methods()
    fig = FIGURES[kind].draw(ds, None)
    fig.canvas.draw()
    shown = {t.get_text() for t, _, _ in texts(fig)}
    # a legend entry is "name" or "name (diverged at ...)"; a map's title is "name" or "name\n..."
    named = {w.split(" (")[0].split("\n")[0] for w in shown}
    missing = [m for m in methods if m not in named]
    assert not missing, (kind, scene, missing)
    assert not overlaps(fig), overlaps(fig)
    if kind != "stability":  # every f of the study in a panel title, none left to a note
        for f in ds.f.values:
            assert any(t.startswith(f"f = {float(f):g} Hz") for t in shown), (kind, f)


def test_every_method_and_forty_at_least_have_their_own_colour_marker_pair(monkeypatch):
    from gyrolab.analysis import io
    from gyrolab.kernels import registry

    names = list(registry.METHODS) + [f"method_{k}" for k in range(40 - len(registry.METHODS))]
    monkeypatch.setattr(registry, "METHODS", {name: None for name in names})
    pairs = {(io.color(m), io.marker(m)) for m in names}
    assert len(names) >= 40 and len(pairs) == len(names)
    fixed = set(io.METHOD_COLORS.values())
    assert not [m for m in names if m not in io.METHOD_COLORS and io.color(m) in fixed]  # fixed colours stay unique


def test_a_figure_of_many_rows_puts_more_methods_in_a_panel_instead_of_shrinking_every_panel():
    """Four invariants × four groups of 7 (25 methods) made 16 rows, each panel shrunk to a third of its
    height until notes and tick labels collided; a panel takes 9 then, and the figure keeps 12 rows."""
    from gyrolab.analysis.figures.record import MAX_METHODS, MAX_ROWS, method_groups, methods_per_panel

    assert methods_per_panel(24, 4) == MAX_METHODS  # 3 groups of 8: 12 rows, as before
    assert methods_per_panel(25, 4) == 9
    assert methods_per_panel(25, 3) == MAX_METHODS  # 4 groups × 3 rows fit
    for n in range(1, 80):
        for rows_each in (1, 2, 3, 4, 5):
            groups = method_groups([f"m{k}" for k in range(n)], methods_per_panel(n, rows_each))
            assert sum(map(len, groups)) == n
            assert len(groups) * rows_each <= max(MAX_ROWS, rows_each)
