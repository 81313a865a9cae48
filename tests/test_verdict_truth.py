"""gyrolab-verdict says what the files hold: figures of groups that differ in θ0 only, one drift row per
(f, θ0) group, a refusal when nothing can be judged, the time a run stopped, a file named twice judged once,
why an order fit has no points, and the ladder of each method.

Every file is helpers.synthetic_dataset (made-up samples, no kernel run): fast, and the wording is what is
tested, not the numbers.
"""

import json

import numpy as np
import pytest

from gyrolab.analysis.verdicts import classify, figures
from gyrolab.analysis.verdicts import verdict as V

from helpers import synthetic_dataset


def write(ds, path):
    ds.to_netcdf(path, engine="h5netcdf")
    return path


def test_the_figure_draws_files_that_differ_in_theta0_only(tmp_path):
    """Two files at the same f and dt, θ0 = 45° and 30°: the drift panel looked a θ0 = 30° run up in the
    θ0 = 45° file (KeyError: not all values found in index 'theta0')."""
    a = write(synthetic_dataset({"theta0": [45.0]}), tmp_path / "a.h5")
    b = write(synthetic_dataset({"theta0": [30.0]}), tmp_path / "b.h5")
    assert V.main([str(a), str(b), "--figures", str(tmp_path / "fig")]) == 0
    assert (tmp_path / "fig" / "verdict_heavy_top.png").stat().st_size > 0


def test_each_drift_panel_shows_one_group_and_says_which(tmp_path):
    """A file of two f: panel (c) drew the runs of both groups under the first group's title.  Now one row
    of drift panels per (f, θ0) group, each titled with its own group and holding its own runs only."""
    path = write(synthetic_dataset({"f": [10.0, 50.0], "integrator": ["m1", "m2"]}), tmp_path / "two.h5")
    datasets = V.load([path])
    records = V.verdict([path])
    fig = figures.scene_figure("heavy_top", records, [ds for _, ds in datasets])
    drift = [ax for ax in fig.axes if ax.get_title().startswith("(c)")]
    assert len(drift) == 2 * 3  # two groups × heavy_top's energy, Lz, L3
    for ax in drift:
        f = 10 if "f = 10 Hz" in ax.get_title() else 50
        assert f"f = {f} Hz, θ0 = 45°, dt = 0.001 s" in ax.get_title(), ax.get_title()
        assert len(ax.get_lines()) >= 2  # m1 and m2 of this group ...
    energy = [ax for ax in drift if "of energy" in ax.get_title()]
    curves = [tuple(np.round(line.get_ydata()[:3], 12)) for ax in energy for line in ax.get_lines()[:2]]
    assert len(set(curves)) == 4  # ... and not the other group's
    assert "f = 10 Hz" in energy[0].get_title() and "f = 50 Hz" in energy[1].get_title()


def test_many_groups_draw_at_most_four_drift_rows_and_say_so(tmp_path):
    """A sweep of 6 f: six rows of drift panels would make a figure 34 inches tall; four are drawn and the
    title says which share of the groups they are."""
    path = write(synthetic_dataset({"f": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]}), tmp_path / "six.h5")
    datasets = V.load([path])
    fig = figures.scene_figure("heavy_top", V.verdict([path]), [ds for _, ds in datasets])
    drift = [ax for ax in fig.axes if ax.get_title().startswith("(c)")]
    assert len(drift) == figures.MAX_DRIFT_ROWS * 3 == 12
    assert "the first 4 of 6 (f, θ0) groups" in fig._suptitle.get_text()


def test_nothing_to_judge_is_refused_in_one_line_saying_why(tmp_path, capsys):
    """One dt and 6 samples per run: no order (no dt ladder) and no drift class (< 16 samples).  It printed
    a blank line, exited 0 and wrote '[]'."""
    path = write(synthetic_dataset(t_end=0.005), tmp_path / "few.h5")
    out = tmp_path / "v.json"
    with pytest.raises(SystemExit) as stop:
        V.main([str(path), "--json", str(out), "--markdown", str(tmp_path / "v.md"), "--figures", str(tmp_path / "d")])
    assert stop.value.code == 2
    err = capsys.readouterr()
    assert err.out == "" and err.err.count("\n") == 1
    assert "nothing to judge" in err.err and "no dt ladder" in err.err
    assert f"6 samples per run (a drift class needs >= {V.MIN_DRIFT_SAMPLES})" in err.err
    assert not out.exists() and not (tmp_path / "v.md").exists() and not (tmp_path / "d").exists()


def test_diverged_says_when_the_run_stopped(tmp_path):
    """A run its kernel stopped after 10 steps of 1 ms keeps its sample at 0.01 s and NaN-fills the rest:
    the verdict said 'diverged (t = 0.011 s)', the first NaN, one sample after the stop."""
    ds = synthetic_dataset({"dt": [1e-3]}, t_end=0.02, every=1e-3)
    timed = [v for v in ds.data_vars if "time" in ds[v].dims]
    ds = ds.assign({v: ds[v].where(ds.time <= 0.01) for v in timed})
    ds["status"][:] = 2  # energy past the divergence threshold at the sample of 0.01 s
    ds["n_steps"][:] = 10
    recs = [r for r in V.drift_records(ds) if r["drift_class"] == "diverged"]
    assert recs and all(r["t_diverged"] == pytest.approx(0.01) for r in recs)
    assert V.fmt_drift(recs[0]) == "diverged (t = 0.01 s)"
    assert "stopped at t = 0.01 s" in recs[0]["drift_reason"]
    # without the stop time (a bare series), the first non-finite sample's time as before
    t = ds.time.values
    e = np.where(t <= 0.01, 1e-3 * t, np.nan)
    assert classify.classify_drift(t, e).t_diverged == pytest.approx(0.011)


def test_a_file_named_twice_is_judged_once(tmp_path, capsys):
    """`gyrolab-verdict s1 s1/results.h5` (a directory means its results.h5) counted every run twice."""
    run = tmp_path / "s1"
    run.mkdir()
    path = write(synthetic_dataset(), run / "results.h5")
    once = tmp_path / "once.json"
    twice = tmp_path / "twice.json"
    V.main([str(path), "--json", str(once)])
    capsys.readouterr()
    V.main([str(run), str(path), "--json", str(twice)])
    assert json.loads(twice.read_text()) == json.loads(once.read_text())
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "judged once" in err and "results.h5" in err


def test_an_order_fit_without_points_says_what_left_them_out():
    """rk4 at 10 Hz (3 steps): local slopes 4.45 and 4.29 differ by more than slope_tol, so no asymptotic
    range; the reason read '0 usable point(s) after excluding none'."""
    dt = [1e-3, 5e-4, 2.5e-4]
    fit = classify.fit_order(dt, [3.157e-06, 1.444e-07, 7.374e-09])
    assert fit.excluded == ["slopes_disagree"] * 3
    assert "excluding none" not in fit.reason and "3 whose local slopes disagree (4.45, 4.29" in fit.reason
    rec = {"order": None, "order_reason": fit.reason, "ladder_excluded": fit.excluded, "ladder_err": [3e-6, 1e-7, 7e-9]}
    assert V.fmt_order(rec, short=True) == "— (local slopes disagree)"
    # slopes that agree but do not fall
    fit = classify.fit_order(dt, [1e-4, 0.98e-4, 0.97e-4])
    assert fit.excluded == ["not_falling"] * 3 and "where err does not fall with dt" in fit.reason
    # one point left (the other is below the reference's error): it is usable, just alone
    fit = classify.fit_order(dt[:2], [1e-6, 1e-12], reference_error=1e-10)
    assert fit.reason == "1 usable point(s) after excluding 1 reference; need 3"


def test_the_ladder_header_states_each_methods_ladder(tmp_path):
    """A yardstick's own reference run leaves its ladder, and another file's methods have other runs: the
    header stated the first method's ladder and drift run for all of them."""
    ladder = synthetic_dataset({"integrator": ["rk4", "lie_poisson4"], "dt": [1e-3, 5e-4, 2.5e-4]})
    long = synthetic_dataset({"integrator": ["seed_prev"], "dt": [5e-3]}, t_end=0.1, every=5e-3)
    paths = [write(ladder, tmp_path / "ladder.h5"), write(long, tmp_path / "long.h5")]
    records = V.verdict(paths)
    text = V.table(records)
    assert "order of rk4: final state at t = 0.02 s, dt = 0.001 … 0.00025 s (3 steps, halving)" in text
    assert "order of lie_poisson4: final state at t = 0.02 s, dt = 0.001 … 0.0005 s (2 steps, halving)" in text
    assert "drift of rk4, lie_poisson4: dt = 0.00025 s over 0.02 s" in text
    assert "drift of seed_prev: dt = 0.005 s over 0.1 s" in text
    md = V.markdown(records)
    assert "order (`rk4`): f = 10 Hz, θ0 = 45°, final state at t = 0.02 s, dt = 0.001 … 0.00025 s (3 steps" in md
    assert "order (`lie_poisson4`): f = 10 Hz" in md and "(2 steps, halving)" in md
    # one ladder for every method: no names, as before
    single = V.table(V.verdict([write(synthetic_dataset({"dt": [1e-3, 5e-4, 2.5e-4]}), tmp_path / "one.h5")]))
    assert "  order: final state at t = 0.02 s" in single and "  drift: dt = 0.00025 s" in single
