"""Combined files (gyrolab-combine) are first-class: gyrolab-plot draws a member (scene=NAME, job=K)
or each member, gyrolab-compare compares them member by member or one member with a one-scene
file, gyrolab-verdict judges each member, and a member carries its own scene attrs."""

import subprocess

import numpy as np
import pytest

from gyrolab.analysis.figures import cli
from gyrolab.analysis.files.combine import main as combine_main
from gyrolab.analysis.files.compare import compare_files
from gyrolab.analysis.files.compare import main as compare_main
from gyrolab.results import ResultsError, open_members, open_results

from helpers import BIN, make_file


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two one-scene files of different scenes and grids, their combination (twice, in both orders)
    and a combination along ``job`` (one scene, two masses)."""
    root = tmp_path_factory.mktemp("combined")
    for d in ("top", "free", "heavy"):
        (root / d).mkdir()
    top = make_file(root / "top" / "results.h5", "sweep.f=[10]")
    free = make_file(root / "free" / "results.h5", "sweep.f=[5,20]", "scene=free_symmetric")
    heavy = make_file(root / "heavy" / "results.h5", "sweep.f=[10]", "scene.M=2")
    assert combine_main([str(top), str(free), "-o", str(root / "combined.h5")]) == 0
    assert combine_main([str(free), str(top), "-o", str(root / "again.h5")]) == 0
    assert combine_main([str(top), str(heavy), "-o", str(root / "jobs.h5")]) == 0
    return {"top": top, "free": free, "heavy": heavy, "root": root} | {
        k: root / f"{k}.h5" for k in ("combined", "again", "jobs")
    }


def plot(*args):
    """(exit status, stderr lines) of gyrolab-plot, in this process."""
    try:
        return cli.main([str(a) for a in args]), []
    except SystemExit as done:
        return done.code, []


@pytest.mark.slow
def test_a_member_carries_the_attrs_of_its_scene(runs):
    """The slice of a combined file is the one-scene file it came from: the scene, its options, the
    invariants it conserves and its closed form (the attrs that differ between the scenes, which
    gyrolab-combine stores along ``scene``), and only its own grid values (the others, status -1)."""
    for name, scene in (("top", "heavy_top"), ("free", "free_symmetric")):
        one = open_results(runs[name])
        member = open_results(runs["combined"], {"scene": scene})
        for key in ("scene", "conserved", "closed_form", "t_end", "every"):
            assert member.attrs[key] == one.attrs[key], key
        assert {k: v for k, v in member.attrs.items() if k.startswith("scene_")} == {
            k: v for k, v in one.attrs.items() if k.startswith("scene_")
        }
        assert member["f"].values.tolist() == one["f"].values.tolist()
        assert (member["status"].values == 0).all() and member["status"].dtype == np.int8
        np.testing.assert_array_equal(member["energy"].values, one["energy"].values)
        np.testing.assert_array_equal(member["body"].values, one["body"].values)
    conserved = {label: ds.attrs["conserved"] for label, ds in open_members(runs["combined"])}
    assert conserved["heavy_top"] != conserved["free_symmetric"]


@pytest.mark.slow
def test_plot_a_scene_of_a_combined_file(runs, tmp_path):
    out = tmp_path / "top.png"
    assert plot("energy", runs["combined"], "scene=heavy_top", "-o", out)[0] == 0
    assert out.stat().st_size > 0
    assert plot("invariants", runs["combined"], "scene=free_symmetric", "f=20", "-o", tmp_path / "inv.png")[0] == 0
    assert (tmp_path / "inv.png").stat().st_size > 0


def test_plot_a_combined_file_draws_each_scene_with_the_scene_in_the_name(runs, capsys):
    assert plot("energy", runs["combined"])[0] == 0
    wrote = [line for line in capsys.readouterr().out.splitlines() if line.startswith("gyrolab-plot: wrote")]
    assert [line.rsplit("/", 1)[1] for line in wrote] == ["energy_heavy_top.png", "energy_free_symmetric.png"]
    assert all(
        (runs["root"] / name).stat().st_size > 0 for name in ("energy_heavy_top.png", "energy_free_symmetric.png")
    )


def test_plot_a_job_of_a_combined_file(runs, tmp_path):
    member = open_results(runs["jobs"], {"job": 1})
    assert member.attrs["scene_M"] == 2.0 and member.attrs["scene"] == "heavy_top"
    assert open_results(runs["jobs"], {"job": 0}).attrs["scene_M"] == 1.0
    assert plot("nutation", runs["jobs"], "job=1", "-o", tmp_path / "n.png")[0] == 0
    assert (tmp_path / "n.png").stat().st_size > 0


@pytest.mark.parametrize(
    "words, message",
    [
        (["scene=nope"], "scene=nope: not in FILE="),
        (["job=0"], "combined along scene (scene has heavy_top, free_symmetric)"),
        (["scene=heavy_top,free_symmetric"], "one scene at a time"),
    ],
)
def test_a_bad_member_is_one_line_and_exit_2(runs, words, message, capsys):
    assert plot("energy", runs["combined"], *words)[0] == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gyrolab-plot: error: ") and message in err[0], err


def test_a_scene_selection_on_a_one_scene_file(runs, tmp_path, capsys):
    """scene= naming the file's own scene is harmless; another scene is one line and exit 2."""
    assert plot("energy", runs["top"], "scene=heavy_top", "-o", tmp_path / "e.png")[0] == 0
    assert plot("energy", runs["top"], "scene=free_symmetric")[0] == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a combined file (one scene, heavy_top)" in err[0]


@pytest.mark.slow
def test_plot_standard_of_a_combined_file_draws_every_scene(runs, tmp_path):
    done = subprocess.run(
        [str(BIN / "gyrolab-plot"), "standard", str(runs["combined"]), "-o", str(tmp_path / "figs")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    for scene in ("heavy_top", "free_symmetric"):
        assert len(list((tmp_path / "figs" / scene).glob("*.png"))) == 4, scene
    assert "Traceback" not in done.stderr


def test_plot_standard_of_a_combined_file_that_draws_nothing_exits_2(runs, tmp_path, monkeypatch, capsys):
    from gyrolab.analysis.figures import registry as figures

    monkeypatch.setattr(figures, "standard_figures", lambda *args, **kwargs: [])
    assert plot("standard", runs["combined"], "-o", tmp_path / "figs")[0] == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no figure could be drawn" in err[0], err


def test_compare_combined_files_of_the_same_scenes(runs):
    """Member by member, matched by label (the two files stack the scenes in opposite orders)."""
    report = compare_files(runs["combined"], runs["again"])
    assert report.ok, report.text()
    assert report.n_runs == 2 * 1 * 3 * 1 * 1  # scene x integrator x f (union) x theta0 x dt
    assert "2 scene x 1 integrator x 3 f" in report.grid
    assert compare_files(runs["combined"], runs["combined"]).ok


def test_compare_a_member_with_a_one_scene_file(runs, capsys):
    assert compare_main([str(runs["combined"]), "scene=free_symmetric", str(runs["free"])]) == 0
    out = capsys.readouterr().out
    assert "RESULT: OK" in out and "scene=free_symmetric" in out
    assert compare_main([str(runs["top"]), str(runs["combined"]), "scene=heavy_top"]) == 0
    capsys.readouterr()
    assert compare_main([str(runs["combined"]), "scene=heavy_top", str(runs["free"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "different scenes: heavy_top in A and free_symmetric in B" in err[0], err


def test_compare_a_combined_file_with_a_one_scene_file_names_the_selection(runs, capsys):
    assert compare_main([str(runs["combined"]), str(runs["top"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "combined file of scenes heavy_top, free_symmetric" in err[0], err
    assert f"gyrolab-compare {runs['combined']} scene=heavy_top {runs['top']}" in err[0]


def test_verdict_judges_each_member(runs):
    from gyrolab.analysis.verdicts.verdict import load

    loaded = load([runs["combined"]])
    assert [name.rsplit(" ", 1)[1] for name, _ in loaded] == ["scene=heavy_top", "scene=free_symmetric"]
    with pytest.raises(ResultsError, match="combined file of 2 scenes .*choose one with scene=heavy_top"):
        open_results(runs["combined"])


def test_verdict_of_a_directory_judges_a_combined_file_once(runs):
    """gyrolab-combine DIR writes DIR/combined.h5 next to the job files: a verdict of DIR judges the
    job files, not their runs twice."""
    from gyrolab.analysis.verdicts.verdict import load

    names = [str(name) for name, _ in load([runs["root"] / "top", runs["root"] / "free", runs["combined"]])]
    assert names == [str(runs["top"]), str(runs["free"])]
    assert len(load([runs["combined"]])) == 2  # alone, its members
