"""The package's structure holds: data flows one way, nothing imports in a circle.

Counted by tests/import_graph.py over every import, those inside functions
too: no edge from a lower layer to a higher one (kernels, results, analysis,
runner, the package's façade), no cycle between modules.  In particular the
analysis (figures, verdicts, file tools, reports) never imports the runner, and
the runner reaches the analysis only through its public figure step.
"""

import pytest

import import_graph


def test_no_back_edge_between_layers():
    edges = import_graph.edges()
    assert len(edges) > 150  # the graph was read
    assert import_graph.back_edges(edges) == []


@pytest.mark.slow
def test_no_import_cycle():
    assert import_graph.cycles(import_graph.edges()) == []


@pytest.mark.slow
def test_the_runner_reaches_the_analysis_only_through_its_public_figure_step():
    reached = {b for a, b, _ in import_graph.edges() if a.startswith("runner") and b.startswith("analysis")}
    assert reached <= {"analysis"}, reached


def test_the_counter_sees_a_cycle_and_a_back_edge(tmp_path):
    """The rules can fail: a scratch package with a cycle and an upward import is caught."""
    for folder in ("kernels", "runner", "analysis", "gyrolab"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "__init__.py").write_text("")
    (tmp_path / "analysis" / "a.py").write_text("from . import b\n")
    (tmp_path / "analysis" / "b.py").write_text("def f():\n    from .a import x\n")
    (tmp_path / "kernels" / "k.py").write_text("from ..runner import app\n")
    (tmp_path / "runner" / "app.py").write_text("")
    edges = import_graph.edges(tmp_path)
    assert import_graph.cycles(edges) == [["analysis.a", "analysis.b"]]
    assert [(a, b) for a, b, _ in import_graph.back_edges(edges)] == [("kernels.k", "runner.app")]


def test_results_files_are_opened_only_by_the_one_reader():
    """No module of the package outside gyrolab/results opens a file with xarray or netCDF directly: every
    command reads results files through gyrolab/results/reader.py (one check, one ResultsError)."""
    openers = ("open_dataset", "open_mfdataset", "open_datatree", "load_dataset")
    found = [
        f"{name}: {opener}"
        for name, path in import_graph.module_files().items()
        if not name.startswith("results")
        for opener in openers
        if f"{opener}(" in path.read_text()
    ]
    assert found == []
