"""Analysis figures: content checks (lines per method, units, log scales, reference lines), CLI behaviour."""

import math
import warnings

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest

from gyrolab.analysis.figures import cli
from gyrolab.analysis.figures.energy import drift_figure, drift_table, invariants_figure
from gyrolab.analysis.figures.nutation import closed_form_nutation, theta_figure, tip_locus_figure
from gyrolab.analysis.figures.record import choose, facet, limit
from gyrolab.analysis.figures.registry import standard_figures
from gyrolab.analysis.io import METHOD_COLORS, SelectionError, parse_selection, relative_error, select
from gyrolab.kernels.closed_form import heavy_top_nutation
from gyrolab.kernels.scenes import build_scene
from gyrolab.results import open_results


def lines_of(ax, method):
    """Data lines (more than 2 points) drawn in ``method``'s colour."""
    want = matplotlib.colors.to_rgba(METHOD_COLORS[method])
    return [
        ln for ln in ax.get_lines() if len(ln.get_xdata()) > 2 and matplotlib.colors.to_rgba(ln.get_color()) == want
    ]


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def test_selection_parsing_and_matching(results_file):
    ds = open_results(results_file)
    sel = parse_selection(["method=seed_next,rk4", "dt=5e-4"])
    assert sel == {"integrator": ["seed_next", "rk4"], "dt": [5e-4]}
    sub = select(ds, sel)
    assert list(sub.integrator.values) == ["seed_next", "rk4"] and sub.dt.size == 1
    with pytest.raises(SelectionError, match="f=7"):
        select(ds, {"f": [7.0]})
    with pytest.raises(SelectionError, match="KEY=VALUE"):
        parse_selection(["speed=3"])
    # a key given twice selects both (the second replaced the first); a member is one at a time
    assert parse_selection(["f=10", "f=50,10"]) == {"f": [10.0, 50.0]}
    with pytest.raises(SelectionError, match="one scene at a time"):
        parse_selection(["scene=heavy_top", "scene=free_symmetric"], members=True)


def test_theta_figure_lines_and_closed_form_bounds(results_file):
    ds = open_results(results_file)
    fig = theta_figure(ds, {"dt": [1e-3]})  # every method at dt = 1e-3, one row per f
    axes = np.array(fig.axes).reshape(2, -1)
    for row, f in zip(axes, (10.0, 50.0)):
        ax = row[0]
        assert "(deg)" in ax.get_ylabel() and "(s)" in ax.get_xlabel()
        for m in ds.integrator.values:
            assert len(lines_of(ax, str(m))) == 1, m  # one line per method at the single dt drawn
        nut = heavy_top_nutation(build_scene("heavy_top", f, 45.0))
        levels = sorted(ln.get_ydata()[0] for ln in ax.get_lines() if len(ln.get_ydata()) == 2)
        assert levels == pytest.approx([math.degrees(nut.theta_min), math.degrees(nut.theta_max)], abs=1e-9)
        # rk4 at dt = 1e-3 stays inside the closed-form band to a tenth of a degree over the window drawn
        (rk4,) = lines_of(ax, "rk4")
        y = rk4.get_ydata()
        assert y.min() > levels[0] - 0.1 and y.max() < levels[1] + 0.1


def test_theta_figure_draws_each_dt_when_asked(results_file):
    fig = theta_figure(open_results(results_file), {"dt": [1e-3, 5e-4], "f": [50.0]})
    ax = fig.axes[0]
    assert len(lines_of(ax, "seed_prev")) == 2
    assert {ln.get_linestyle() for ln in lines_of(ax, "seed_prev")} == {"-", "--"}


def test_tip_locus_is_the_stored_axis(results_file):
    ds = open_results(results_file)
    fig = tip_locus_figure(ds, method="rk4", f=50.0, dt=5e-4)
    (ax,) = fig.axes
    (trace,) = lines_of(ax, "rk4")
    run = ds.sel({"integrator": "rk4", "f": 50.0, "theta0": 45.0, "dt": 5e-4})
    n = len(trace.get_xdata())
    np.testing.assert_array_equal(trace.get_xdata(), run.axis.values[:n, 0])
    np.testing.assert_array_equal(trace.get_ydata(), run.axis.values[:n, 1])
    assert ax.get_aspect() == 1.0
    # the closed-form annulus: two dashed circles of radius sin θ_min, sin θ_max
    nut = closed_form_nutation(ds, 50.0, 45.0)
    radii = sorted(
        np.hypot(ln.get_xdata(), ln.get_ydata()).mean() for ln in ax.get_lines() if len(ln.get_xdata()) == 361
    )
    assert radii == pytest.approx(sorted([math.sin(nut.theta_min), math.sin(nut.theta_max)]), rel=1e-6)
    assert "rk4" in fig._suptitle.get_text() and "f = 50 Hz" in ax.get_title()


def test_energy_drift_log_scale_lines_per_method_and_dt(results_file):
    ds = open_results(results_file)
    fig = drift_figure(ds, "energy")
    assert len(fig.axes) == 2  # one panel per f
    for ax in fig.axes:
        assert ax.get_yscale() == "log"
        assert ax.get_xlabel() == "time t (s)"
        for m in ds.integrator.values:
            assert len(lines_of(ax, str(m))) == ds.dt.size
    # The write-up's claim as the figure shows it: seed_prev's curve ends far above seed_next's.
    ax = fig.axes[0]
    end = {m: max(ln.get_ydata()[-1] for ln in lines_of(ax, m)) for m in ("seed_next", "seed_prev")}
    assert end["seed_prev"] > 10 * end["seed_next"]


def test_drift_table_matches_stored_energy(results_file):
    ds = open_results(results_file)
    table = drift_table(ds, "energy")
    e = ds.energy.sel({"integrator": "rk4", "f": 10.0, "theta0": 45.0, "dt": 1e-3}).values
    worst, final = table[("rk4", 10.0, 45.0, 1e-3)]
    assert worst == pytest.approx(np.abs(e - e[0]).max() / abs(e[0]), rel=1e-12)
    assert final == pytest.approx(abs(e[-1] - e[0]) / abs(e[0]), rel=1e-12)


def test_invariants_figure_drops_exact_rows_and_says_so(results_file):
    fig = invariants_figure(open_results(results_file))
    axes = np.array(fig.axes).reshape(2, 2)  # rows E, L_z; L_3 is exact for every run: no row, a note
    assert all(ax.get_yscale() == "log" for ax in axes.ravel())
    assert "E" in axes[0, 0].get_ylabel() and "L_z" in axes[1, 0].get_ylabel()
    assert any("L_3: kept exactly (error 0) by every run drawn" in n for n in fig.gyrolab_notes)


def test_relative_error_of_a_quantity_zero_throughout_is_zero_without_a_warning():
    # L_z and L_3 of a top released from rest (f = 0) are 0 at every sample: 0/0 was NaN and a RuntimeWarning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(relative_error(np.zeros((2, 5))), np.zeros((2, 5)))
        assert relative_error(np.array([0.0, 1e-3, -2e-3]))[2] == pytest.approx(1.0)  # scaled by max |x|
    assert np.isnan(relative_error(np.array([1.0, np.nan]))[1])  # a diverged sample stays NaN


def test_a_run_that_stopped_at_its_first_step_is_not_called_exact(results_file):
    # its only finite sample is t = 0, where every error is 0: that says nothing about conservation
    ds = open_results(results_file).load()
    run = {"integrator": str(ds.integrator.values[0]), "f": ds.f.values[0], "theta0": ds.theta0.values[0]}
    run["dt"] = ds.dt.values[0]
    ds["status"].loc[run] = 1
    for name in ("energy", "Lz", "L3", "L", "omega", "axis"):
        if name in ds:
            ds[name].loc[{**run, "time": ds.time.values[1:]}] = np.nan
    fig = invariants_figure(ds)
    assert len(fig.axes) == 3 * 2  # L_3 now has its row: the stopped run did not keep it
    assert not any("kept exactly" in n for n in getattr(fig, "gyrolab_notes", []))
    assert not any("exactly conserved" in t.get_text() for ax in drift_figure(ds).axes for t in ax.texts)


@pytest.mark.slow
def test_standard_figures_default_and_single_run(results_file, single_run_file, tmp_path):
    paths = standard_figures(results_file, tmp_path / "a")
    assert [p.name for p in paths] == ["nutation_theta.png", "tip_locus.png", "energy_drift.png", "invariants.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
    one = standard_figures(single_run_file, tmp_path / "b")
    assert len(one) == 4


def test_limit_keeps_ends_and_choose_says_what_it_drew():
    import xarray as xr

    ds = xr.Dataset(coords={"integrator": ["rk4"], "f": np.arange(1.0, 13.0), "dt": [1e-3], "theta0": [45.0]})
    assert [float(v) for v in limit(ds, "f", 4)[0]] == [1.0, 5.0, 8.0, 12.0]
    sub, note = choose(ds, "energy")
    assert sub.f.size == 9 and "gyrolab-plot energy FILE f=" in note
    assert facet(7) == (3, 3) and facet(2) == (1, 2)


def test_cli_writes_and_refuses(results_file, tmp_path, capsys):
    out = tmp_path / "e.png"
    assert cli.main(["energy", str(results_file), "method=rk4", "--quantity", "Lz", "-o", str(out)]) == 0
    assert out.stat().st_size > 10_000
    bad = tmp_path / "bad.png"
    with pytest.raises(SystemExit) as exc:
        cli.main(["nutation", str(results_file), "f=7", "-o", str(bad)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "f=7" in err[0]
    assert not bad.exists()
    with pytest.raises(SystemExit) as exc:
        cli.main(["energy", str(tmp_path / "missing.h5")])
    assert exc.value.code == 2


@pytest.mark.parametrize(
    "kind", ["nutation", "tip", "energy", "invariants", "work-precision", "stability", "animation", "seed", "standard"]
)
def test_cli_help(kind, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([kind, "--help"])
    assert exc.value.code == 0
    assert "usage: gyrolab-plot" in capsys.readouterr().out


def test_a_selection_names_a_method_with_parameters_as_the_file_does():
    """A variant's name keeps its commas and is made canonical (the runner stores it so), so a plot can
    select ``lie_poisson(axes=s-m-l)``; a name the registry does not know stays as given."""
    from gyrolab.analysis.io import parse_selection

    sel = parse_selection(["integrator=lie_poisson(axes=s-m-l),no_squish(substeps=10,axes=1-2-3),DOP853", "f=10,50"])
    assert sel == {
        "integrator": ["lie_poisson(axes=S-M-L)", "no_squish(axes=1-2-3,substeps=10)", "DOP853"],
        "f": [10.0, 50.0],
    }


def test_a_top_released_level_from_rest_has_its_energy_error_against_mgl():
    """θ0 = 90°, f = 0: E0 = M g l cos 90° ≈ 2e-16 J while the top swaps M g l = 1 J between V and T.
    Its energy error was |ΔE| / 2e-16 (lie_poisson: 1.8e8) or, below 1e-9 of the run's largest |E|,
    that largest |E|, which is the error itself (seed_next: exactly 1).  Measured against T0 + |M g c|
    instead, and said so in the figure; at f = 10 Hz the energy is T0 + 0 and nothing changes.  L_z at
    f = 10 Hz starts at 0 (the spin axis is level) and is measured against |L|."""
    from gyrolab.analysis.io import invariant_error, invariant_scale

    from helpers import make_dataset

    ds = make_dataset({"integrator": ["seed_next", "lie_poisson"], "f": [0.0, 10.0], "theta0": [90.0], "dt": [1e-4]})
    mgl = float(ds.body.sel(body_param="mgl").isel(f=0, theta0=0))
    assert float(invariant_scale(ds, "energy").sel(f=0.0, theta0=90.0)) == pytest.approx(mgl, rel=1e-15)
    for m in ("seed_next", "lie_poisson"):
        run = ds.sel(integrator=m, f=0.0, theta0=90.0, dt=1e-4)
        e = run.energy.values
        assert abs(e[0]) < 1e-15 * mgl
        assert invariant_error(run, "energy") == pytest.approx(np.abs(e - e[0]) / mgl, rel=1e-12)
        assert invariant_error(run, "energy").max() < 1e-2  # was 1 (seed_next) and 1.8e8 (lie_poisson)
        spun = ds.sel(integrator=m, f=10.0, theta0=90.0, dt=1e-4)
        e = spun.energy.values
        assert invariant_error(spun, "energy") == pytest.approx(np.abs(e - e[0]) / abs(e[0]), rel=1e-12)
        L = np.linalg.norm(spun.L.values[0])
        assert invariant_error(spun, "Lz") == pytest.approx(np.abs(spun.Lz.values - spun.Lz.values[0]) / L)
    table = drift_table(ds, "energy")
    assert table[("lie_poisson", 0.0, 90.0, 1e-4)][0] < 1e-6
    fig = drift_figure(ds)
    notes = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert any("E(0) ≈ 0: relative to T0 + |M g c| = 1 J" in n for n in notes), notes


def test_the_nutation_figure_draws_a_run_that_diverged_before_its_end_window():
    """MuJoCo's Euler at 50 Hz, dt = 1 ms diverges at 0.15 s of 2 s: its θ in the figure's end window is
    all NaN, and matplotlib's fractional markevery raised IndexError when the figure was saved."""
    import io as bytes_io

    from helpers import make_dataset

    ds = make_dataset({"integrator": ["mujoco_euler", "lie_poisson"], "f": [50.0], "dt": [1e-3]}, t_end=2.0)
    assert int(ds.status.sel(integrator="mujoco_euler").max()) != 0
    fig = theta_figure(ds)
    assert len(fig.axes) >= 2  # a start and an end window
    fig.savefig(bytes_io.BytesIO(), format="png")
    assert any("diverged" in t.get_text() for t in fig.legends[0].get_texts())


def test_the_energy_figure_ends_a_stopped_runs_curve_where_it_stopped():
    """MuJoCo's Euler at 50 Hz, dt = 1 ms stops at ~0.15 s of 2 s: its running-max curve ran on flat to
    2 s (np.fmax.accumulate carries values over the NaN samples), and its × sat at t_end."""
    from helpers import make_dataset

    ds = make_dataset({"integrator": ["mujoco_euler", "lie_poisson"], "f": [50.0], "dt": [1e-3]}, t_end=2.0)
    run = ds.sel(integrator="mujoco_euler").squeeze()
    stopped = int(run.n_steps) * 1e-3
    assert int(run.status) != 0 and stopped < 1.0
    fig = drift_figure(ds)
    ax = fig.axes[0]
    line = next(ln for ln in ax.get_lines() if ln.get_label().startswith("mujoco_euler"))
    t, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    assert np.nanmax(t[np.isfinite(y)]) <= stopped + 1e-12  # the curve ends where the run stopped
    cross = next(ln for ln in ax.get_lines() if ln.get_marker() == "x")
    assert float(cross.get_xdata()[0]) <= stopped + 1e-12  # and so does its ×


def test_dt_labels_tell_every_step_apart():
    """One significant digit called 2.5e-4 '3e-4' and both 1.25e-4 and 1e-4 '1e-4'."""
    from gyrolab.analysis.io import fmt_dt

    dts = [1e-3, 5e-4, 2.5e-4, 2e-4, 1.5e-4, 1.25e-4, 1e-4, 1.0000000001e-3]
    labels = [fmt_dt(d) for d in dts]
    assert len(set(labels)) == len(dts), labels
    assert labels[:3] == ["dt = 1e-3 s", "dt = 5e-4 s", "dt = 2.5e-4 s"]
    assert all(float(label[5:-2]) == d for label, d in zip(labels, dts))
