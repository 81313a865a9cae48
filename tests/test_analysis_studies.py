"""Study figures (stability map, seed figures, work-precision, animation) on small simulate-built files."""

import warnings

import matplotlib.pyplot as plt
import numpy as np
import pytest

from gyrolab.analysis.figures.animation import animate
from gyrolab.analysis.figures.registry import standard_figures
from gyrolab.analysis.figures.seed import load_jobs, next_vs_prev_figure, regimes_figure, seed_figures
from gyrolab.analysis.figures.stability import stability_figure
from gyrolab.analysis.figures.work_precision import work_precision_data, work_precision_figure
from gyrolab.results import open_results

from helpers import build_dataset


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.mark.slow
def test_stability_map_cells_and_diverged_marks(tmp_path):
    # With a tight divergence threshold (|E − E0| > 0.2 (T0 + Mgl)) seed_prev's energy gain at the 10 Hz
    # top stops its runs within 3 s; rk4 stays far below it.
    path = tmp_path / "stability.h5"
    ds = build_dataset(
        path,
        {"integrator": ["rk4", "seed_prev"], "f": [2.0, 10.0], "dt": [1e-3, 2e-3]},
        t_end=3.0,
        every=1e-2,
        threshold=0.2,
    )
    assert int(ds.status.sel({"integrator": "rk4"}).max()) == 0
    assert int(ds.status.sel({"integrator": "seed_prev", "f": 10.0}).max()) != 0
    fig = stability_figure(open_results(path))
    ax_rk4, ax_prev = fig.axes[:2]
    assert ax_rk4.get_xscale() == "log" and ax_rk4.get_yscale() == "log"
    assert ax_rk4.get_xlabel() == "time step dt (s)" and ax_rk4.get_ylabel() == "spin f (Hz)"
    mesh = ax_rk4.collections[0]
    values = np.asarray(mesh.get_array()).reshape(2, 2)  # rows f, columns dt
    e = ds.energy.sel({"integrator": "rk4", "theta0": 45.0}).values  # (f, dt, time)
    expected = np.log10(np.abs(e - e[..., :1]).max(axis=-1) / np.abs(e[..., 0]))
    np.testing.assert_allclose(values, expected, rtol=1e-12)
    # diverged cells are marked with a red x, ok cells carry their number
    n_bad = int((ds.status.sel({"integrator": "seed_prev"}) != 0).sum())
    crosses = [ln for ln in ax_prev.get_lines() if ln.get_marker() == "x"]
    assert len(crosses) == n_bad and f"{n_bad} diverged" in ax_prev.get_title()
    # ... and take no colour of the scale: the error before the stop is no measure of the run
    prev = np.ma.asarray(ax_prev.collections[0].get_array()).reshape(2, 2)
    bad = ds.status.sel({"integrator": "seed_prev", "theta0": 45.0}).transpose("f", "dt").values != 0
    assert np.array_equal(np.ma.getmaskarray(prev), bad)
    grey = ax_prev.collections[0].get_cmap().get_bad()
    assert grey[0] == grey[1] == grey[2] and grey[3] == 1.0  # an opaque grey, outside viridis
    assert "log10" in fig.axes[-1].get_ylabel()  # the colour bar says what the colour is
    # the figure step draws what the study's config names (output.figures), whatever the file is called
    other = tmp_path / "renamed.h5"
    ds.assign_attrs(config="output:\n  figures: [stability, energy]\n").to_netcdf(other, engine="h5netcdf")
    names = [p.name for p in standard_figures(other, tmp_path / "figs")]
    assert names == ["stability_map.png", "energy_drift.png"]
    assert [p.name for p in standard_figures(path, tmp_path / "default")] == [
        "nutation_theta.png",
        "tip_locus.png",
        "energy_drift.png",
        "invariants.png",
    ]


def test_stability_map_with_a_top_that_does_not_spin_puts_f_on_a_linear_axis(tmp_path):
    # f = 0 (a top released from rest) has no place on a log axis: matplotlib warned and dropped the limits
    path = tmp_path / "f0.h5"
    build_dataset(path, {"integrator": ["rk4"], "f": [0.0, 5.0], "dt": [1e-3, 2e-3]}, t_end=0.2, every=1e-2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = stability_figure(open_results(path))
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    assert ax.get_ylim() == pytest.approx((-2.5, 7.5))  # cells centred on f = 0 and 5 Hz
    assert np.all(np.isfinite(np.asarray(ax.collections[0].get_array())))


@pytest.fixture(scope="module")
def seed_dir(tmp_path_factory):
    """Four short jobs like experiment=seed_figures (cusp, loop, wave, steady at 22.1 Hz)."""
    root = tmp_path_factory.mktemp("seed")
    grid = {"integrator": ["seed_next", "seed_prev", "lie_poisson4"], "f": [1.0, 10.0, 20.0, 22.1, 50.0], "dt": [1e-3]}
    for i, phidot0 in enumerate((0.0, -3.0, 3.0, 10.973050677702307)):
        (root / str(i)).mkdir()
        build_dataset(root / str(i) / "seed.h5", grid, t_end=0.6, init="precession", phidot0=phidot0)
    return root


@pytest.mark.slow
def test_seed_jobs_are_classified_by_regime(seed_dir):
    jobs = load_jobs([seed_dir])
    assert sorted(jobs) == ["cusp", "loop", "steady", "wave"]
    assert jobs["steady"][1] == pytest.approx(22.1) and jobs["loop"][1] == 20.0


@pytest.mark.slow
def test_seed_figures_content(seed_dir, tmp_path):
    jobs = load_jobs([seed_dir])
    fig = regimes_figure(jobs)
    titles = [ax.get_title() for ax in fig.axes]
    assert any("cusps" in t for t in titles) and any("steady" in t and "22.1 Hz" in t for t in titles)
    steady_ax = fig.axes[3]
    assert any("22.07 Hz" in t.get_text() for t in steady_ax.texts)  # says why 20 Hz is not drawn
    fig = next_vs_prev_figure(jobs)
    top = fig.axes[:4]
    assert all(ax.get_yscale() == "log" for ax in top)
    for ax in top:  # seed_prev (ω(t)) ends above seed_next (ω(t+dt)) in every regime
        ends = {ln.get_label().split(",")[0]: ln.get_ydata()[-1] for ln in ax.get_lines()}
        assert ends["seed_prev"] > 10 * ends["seed_next"]
    paths = seed_figures([seed_dir], tmp_path)
    assert [p.name for p in paths] == ["seed_regimes.png", "seed_remark1.png", "seed_next_vs_prev.png"]


@pytest.mark.slow
def test_work_precision_lines_and_peers(tmp_path):
    path = tmp_path / "work_precision.h5"
    build_dataset(
        path, {"integrator": ["rk4", "lie_poisson"], "f": [10.0], "dt": [1e-3, 5e-4, 2.5e-4]}, t_end=0.2, every=1e-2
    )
    ds = open_results(path)
    data = work_precision_data(ds, retime=False)
    pts = data[(10.0, 45.0)]["methods"]
    # the error falls with dt at about the declared order (rk4: 4, lie_poisson: 2)
    for m, order in (("rk4", 4), ("lie_poisson", 2)):
        dts = np.array([p[0] for p in pts[m]])
        errs = np.array([p[3] for p in pts[m]])
        slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
        assert slope == pytest.approx(order, abs=0.5), (m, slope)
    assert {"DOP853", "RK45"} <= set(data[(10.0, 45.0)]["peers"])
    fig = work_precision_figure(ds, data=data)
    left, right = fig.axes[:2]
    for ax in (left, right):
        assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
        assert "(rad)" in ax.get_ylabel()
    assert "(s/s)" in left.get_xlabel() and "(1/s)" in right.get_xlabel()
    labels = [ln.get_label() for ln in left.get_lines()]
    assert "rk4" in labels and "lie_poisson" in labels and any(lab.startswith("scipy DOP853") for lab in labels)


def test_animation_writes_gif_frames(results_file, tmp_path):
    from PIL import Image

    out = animate(
        open_results(results_file),
        tmp_path / "top.gif",
        {"integrator": ["rk4"], "f": [50.0]},
        seconds=0.2,
        fps=10,
        max_frames=12,
    )
    with Image.open(out) as im:
        assert 5 <= im.n_frames <= 12


@pytest.mark.slow
def test_stability_map_rings_the_runs_whose_solver_gave_up(tmp_path):
    """implicit_midpoint's fixed point does not converge at the 100 Hz top at dt = 1e-2 s: the cell is
    ringed (not crossed), the panel counts it as a solver failure and the title says what a ring is."""
    from gyrolab.kernels.driver import STATUS_UNCONVERGED

    path = tmp_path / "stability.h5"
    ds = build_dataset(
        path, {"integrator": ["implicit_midpoint"], "f": [2.0, 100.0], "dt": [1e-3, 1e-2]}, t_end=0.2, every=1e-2
    )
    failed = ds.status.sel({"integrator": "implicit_midpoint", "theta0": 45.0}).values == STATUS_UNCONVERGED
    assert failed.sum() >= 1 and (ds.status.values != 0).sum() == failed.sum()
    fig = stability_figure(open_results(path))
    ax = fig.axes[0]
    rings = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
    assert len(rings) == failed.sum() and not [ln for ln in ax.get_lines() if ln.get_marker() == "x"]
    assert f"{failed.sum()} solver failed (o)" in ax.get_title() and "diverged (x)" not in ax.get_title()
    assert "○: solver did not converge" in " ".join(fig._suptitle.get_text().split())  # wrapped to the width
