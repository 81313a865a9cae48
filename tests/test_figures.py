"""Every figure kind (analysis/figures/registry.py FIGURES) on every scene and a few grid shapes, checked without eyes:
the figure's size is bounded, no two text boxes overlap (matplotlib's tight bounding boxes), every swept value
is drawn or named in the figure's note, and no closed form or invariant is drawn that the scene lacks."""

import re

import matplotlib.pyplot as plt
import numpy as np
import pytest

from gyrolab.analysis.figures import cli
from gyrolab.analysis.figures.registry import FIGURES, standard_figures
from gyrolab.kernels.scenes import SCENES
from gyrolab.results import open_results

from helpers import build_dataset

SHAPES = {  # name: grid (method, f, theta0, dt)
    "1x1": {"integrator": ["rk4"], "f": [10.0], "theta0": [45.0], "dt": [1e-3]},
    "theta0x3": {"integrator": ["seed_next", "rk4"], "f": [10.0], "theta0": [30.0, 45.0, 60.0], "dt": [1e-3]},
    "fx6": {
        "integrator": ["seed_next", "lie_poisson"],
        "f": [2.0, 5.0, 10.0, 20.0, 50.0, 80.0],
        "theta0": [45.0],
        "dt": [1e-3, 5e-4],
    },
}
MAX_PX = 2400  # pixels per side at the PNG's 110 dpi
OPTIONS = {"work-precision": {"no_retime": True, "no_peers": True}, "sciml": {"no_retime": True, "no_peers": True}}


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("figures")
    out = {}
    for scene in SCENES:
        for shape, grid in SHAPES.items():
            path = root / f"{scene}_{shape}.h5"
            build_dataset(path, grid, scene=scene, t_end=0.4, every=1e-2)
            out[(scene, shape)] = path
    return out


def _drawn_ticks(axis):
    """Tick label texts matplotlib actually draws (ticks inside the view; the others keep stale positions)."""
    return [t for tick in axis._update_ticks() for t in (tick.label1, tick.label2) if t.get_visible()]


def texts(fig):
    """(artist, window extent, owner) of every visible, non-empty text of ``fig``; owner tags tick labels
    ("x" or "y" and their axes) so that the corner where an x and a y tick label meet is not an overlap."""
    renderer = fig.canvas.get_renderer()
    found = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        found += [(t, ("x", ax)) for t in _drawn_ticks(ax.xaxis)] + [(t, ("y", ax)) for t in _drawn_ticks(ax.yaxis)]
        found += [(t, None) for t in (ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label)]
        found += [(t, None) for t in ax.texts]
        if ax.get_legend() is not None:
            found += [(t, None) for t in ax.get_legend().get_texts()]
    found += [(t, None) for t in fig.texts]  # the suptitle is one of them
    for legend in fig.legends:
        found += [(t, None) for t in legend.get_texts()]
    out = []
    for t, owner in found:
        if t.get_visible() and t.get_text().strip():
            box = t.get_window_extent(renderer)
            if box.width > 0 and box.height > 0:
                out.append((t, box, owner))
    return out


def overlaps(fig):
    """Pairs of text boxes that overlap by more than 1 px each way (an x and a y tick label of the same
    axes meeting at its corner excepted)."""
    found = []
    boxes = texts(fig)
    for i, (a, ba, oa) in enumerate(boxes):
        for b, bb, ob in boxes[i + 1 :]:
            if oa and ob and oa[1] is ob[1] and oa[0] != ob[0]:
                continue
            w = min(ba.x1, bb.x1) - max(ba.x0, bb.x0)
            h = min(ba.y1, bb.y1) - max(ba.y0, bb.y0)
            if w > 1 and h > 1:
                found.append((a.get_text()[:40], b.get_text()[:40]))
    return found


def all_text(fig):
    """Every text of ``fig`` and its notes, whitespace collapsed (a title wrapped to its figure reads the same)."""
    text = " ".join(t.get_text() for t, _, _ in texts(fig)) + " " + " ".join(getattr(fig, "gyrolab_notes", []))
    return " ".join(text.split())


def drawn_or_listed(text, key, value, ds=None):
    """``value`` of grid axis ``key`` appears in a figure whose ``all_text`` is ``text``: in a title/label as
    'f = 10 Hz', in a note, or (with the file ``ds``) as the title of a grid point with that value in the
    problem's own terms (figure.run_title: a peer problem's initial body rates)."""
    from gyrolab.analysis.figures.record import run_title

    v = f"{value:g}"
    pattern = {
        "f": rf"f = {v} Hz|f=[\d.,]*\b{v}\b|f = [\d., ]*\b{v}\b",
        "theta0": rf"θ0 = {v}°|theta0=[\d.,]*\b{v}\b|θ0 = [\d., ]*\b{v}\b",
    }[key]
    if re.search(pattern, text) is not None:
        return True
    if ds is None:
        return False
    points = [(f, th) for f in ds.f.values for th in ds.theta0.values if float({"f": f, "theta0": th}[key]) == value]
    return any(run_title(ds, f, th) in text for f, th in points)


@pytest.mark.slow
@pytest.mark.parametrize("kind", [k for k in FIGURES if FIGURES[k].render is None])
@pytest.mark.parametrize("shape", list(SHAPES))
@pytest.mark.parametrize("scene", list(SCENES))
def test_figure_renders_truthfully(kind, shape, scene, files):
    ds = open_results(files[(scene, shape)])
    if kind in ("energy", "invariants") and not SCENES[scene].CONSERVED:
        with pytest.raises(ValueError, match=f"the scene {scene} declares no conserved quantity"):
            FIGURES[kind].draw(ds, None)
        return
    fig = FIGURES[kind].draw(ds, None, **OPTIONS.get(kind, {}))
    fig.canvas.draw()
    box = fig.get_tightbbox(fig.canvas.get_renderer())
    assert box.width * 110 / fig.dpi <= MAX_PX and box.height * 110 / fig.dpi <= MAX_PX, (box.width, box.height)
    assert not overlaps(fig), overlaps(fig)
    text = all_text(fig)  # every text's extent is measured once: the figure no longer changes
    for key in ("f", "theta0"):
        for value in ds[key].values:
            if kind in ("stability",) and key == "f":
                continue  # the f axis of the map holds every f
            assert drawn_or_listed(text, key, float(value), ds), (key, value, text[:400])
    if scene == "free_asymmetric":
        assert "L_3" not in text  # not conserved by an asymmetric free body
    if scene != "heavy_top":
        assert "θ_min" not in text  # the heavy top's bounds only where the scene declares them
    if scene == "free_asymmetric" and kind in ("nutation", "tip"):
        assert "Euler–Poinsot" in text


@pytest.mark.slow
def test_animation_renders_for_every_scene(files, tmp_path):
    from PIL import Image

    for scene in SCENES:
        out = FIGURES["animation"].write(
            open_results(files[(scene, "1x1")]), tmp_path / f"{scene}.gif", seconds=0.2, fps=5
        )
        with Image.open(out) as im:
            assert im.n_frames >= 2 and max(im.size) <= MAX_PX


def test_nutation_defaults_to_finest_dt_and_says_so(files):
    ds = open_results(files[("heavy_top", "fx6")])
    fig = FIGURES["nutation"].draw(ds, None)
    assert "dt = 5e-4 s" in fig._suptitle.get_text()
    assert any("dt=0.001" in n for n in fig.gyrolab_notes)


def test_free_bodies_draw_their_exact_motion(files):
    from gyrolab.analysis.figures import yardstick

    for scene, label in (("free_symmetric", "free symmetric"), ("free_asymmetric", "Euler–Poinsot")):
        ds = open_results(files[(scene, "1x1")])
        fig = FIGURES["nutation"].draw(ds, None)
        exact = [ln for ax in fig.axes for ln in ax.get_lines() if label in str(ln.get_label())]
        assert exact, scene
        axis = yardstick.exact_axis(ds, 10.0, 45.0, ds.time.values)
        np.testing.assert_allclose(exact[0].get_ydata(), np.degrees(np.arccos(np.clip(axis[:, 2], -1, 1))))
    # the exact flow reproduces the stored initial axis
    ds = open_results(files[("free_asymmetric", "1x1")])
    axis = yardstick.exact_axis(ds, 10.0, 45.0, ds.time.values[:1])
    np.testing.assert_allclose(axis[0], ds.axis.values[0, 0, 0, 0, 0], atol=1e-12)


def test_coinciding_methods_are_named(files):
    # seed_next and rk4 advance ω alike on a free body: their energy curves coincide, and the figure says so
    ds = open_results(files[("free_asymmetric", "theta0x3")])
    fig = FIGURES["energy"].draw(ds, None)
    assert "same curve: seed_next = rk4" in all_text(fig)


def test_tip_circles_only_where_they_bound(files):
    ds = open_results(files[("heavy_top", "fx6")])
    fig = FIGURES["tip"].draw(ds, {"f": [2.0, 50.0]})
    low, high = fig.axes[:2]
    assert "no bounding circles" in " ".join(t.get_text() for t in low.texts)  # 2 Hz falls past 90°
    assert sum(len(ln.get_xdata()) == 361 for ln in high.get_lines()) == 2  # 50 Hz: the annulus
    labels = fig.legends[0].get_texts()
    assert {"start (t = 0)", "pivot (lab z axis)"} <= {t.get_text() for t in labels}


def test_energy_refuses_an_invariant_the_scene_lacks(files):
    with pytest.raises(ValueError, match="does not conserve"):
        FIGURES["energy"].draw(open_results(files[("free_asymmetric", "1x1")]), None, quantity="L3")


@pytest.mark.slow
def test_cli_output_dir_rule_and_notes(files, tmp_path, capsys):
    path = files[("heavy_top", "fx6")]
    missing = tmp_path / "nope" / "e.png"
    with pytest.raises(SystemExit) as exc:
        cli.main(["energy", str(path), "-o", str(missing)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist" in err[0] and not missing.parent.exists()
    assert cli.main(["nutation", str(path), "-o", str(missing), "--parents"]) == 0
    out = capsys.readouterr().out
    assert missing.exists() and f"gyrolab-plot nutation {path} dt=0.001" in out
    # -o's suffix is the format when --format is not given (-o e.pdf wrote e.png); --format still rules
    assert cli.main(["energy", str(path), "-o", str(tmp_path / "e.pdf")]) == 0
    assert (tmp_path / "e.pdf").read_bytes().startswith(b"%PDF") and not (tmp_path / "e.png").exists()
    assert cli.main(["energy", str(path), "-o", str(tmp_path / "g.pdf"), "--format", "svg"]) == 0
    assert (tmp_path / "g.svg").exists() and not (tmp_path / "g.pdf").exists()


@pytest.mark.slow
def test_figure_step_prints_progress(files, tmp_path):
    lines = []
    paths = standard_figures(files[("heavy_top", "1x1")], tmp_path / "figs", log=lines.append)
    assert len(paths) == 4 and len([ln for ln in lines if "figure " in ln]) == 4
    assert lines[0].startswith("gyrolab: figure 1/4 nutation")


def test_many_methods_are_all_drawn_in_groups():
    import xarray as xr

    from gyrolab.analysis.figures.record import MAX_METHODS, choose, method_groups
    from gyrolab.kernels.registry import METHODS

    ds = xr.Dataset(coords={"integrator": list(METHODS), "f": [10.0], "theta0": [45.0], "dt": [1e-3]})
    sub, note = choose(ds, "energy")
    assert [str(m) for m in sub.integrator.values] == list(METHODS) and note is None  # no method dropped
    groups = method_groups(sub.integrator.values)
    assert [m for g in groups for m in g] == list(METHODS)
    assert len(groups) == -(-len(METHODS) // MAX_METHODS) and max(map(len, groups)) - min(map(len, groups)) <= 1


def test_log_ticks_outside_the_view_are_never_made_and_the_figure_is_the_same():
    """io.ticks_in_view (save_figure): a log axis's locators stop at the view, and the PNG is the one
    matplotlib's own locators give, byte for byte, with a tick at a view limit still drawn."""
    import io as bytes_io

    from gyrolab.analysis.io import ticks_in_view

    def png(in_view):
        fig, axes = plt.subplots(1, 2)
        axes[0].plot([3e-5, 3e-2], [0.4, 80.0])
        axes[1].plot([1e-4, 1e-2], [1.0, 100.0])  # limits on decades: those ticks are drawn
        for ax in axes:
            ax.set_xscale("log")
            ax.set_yscale("log")
        axes[1].set_xlim(1e-4, 1e-2)
        if in_view:
            ticks_in_view(fig)
            fig.canvas.draw()
            locs = axes[0].xaxis.get_minorticklocs()
            lo, hi = axes[0].get_xlim()
            assert len(locs) and all(lo <= t <= hi for t in locs)
            assert {1e-4, 1e-2} <= set(axes[1].xaxis.get_majorticklocs())
        out = bytes_io.BytesIO()
        fig.savefig(out, format="png", dpi=60)
        plt.close(fig)
        return out.getvalue()

    assert png(True) == png(False)
