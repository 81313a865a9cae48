"""gyrolab-verdict (analysis/verdicts/verdict.py) on small results files with known answers.

Files are built through the kernels and the layout (helpers.make_dataset): a dt ladder of the heavy
top (50 Hz, θ0 = 45°, released; final state at 1 s, dt = 1e-2/2^k) for the orders, long runs for
the drift classes; the CLI's JSON schema and its one-line refusals of bad input.
"""

import json
import math
import subprocess

import numpy as np
import pytest
import xarray as xr

from gyrolab.analysis.verdicts import classify
from gyrolab.analysis.verdicts import verdict as V
from gyrolab.analysis.verdicts.classify import DRIFT_CLASSES

from helpers import command, make_dataset

TRUE_ORDER = {"seed_next": 1, "rk4": 4, "lie_poisson": 2, "lie_poisson4": 4}
LADDER = [1e-2 / 2**k for k in range(13)]


def write(ds, path):
    ds.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.fixture(scope="module")
def ladder_file(tmp_path_factory):
    grid = {"integrator": list(TRUE_ORDER), "f": [50.0], "theta0": [45.0], "dt": LADDER}
    return write(make_dataset(grid, t_end=1.0, every=1.0), tmp_path_factory.mktemp("v") / "ladder.h5")


@pytest.fixture(scope="module")
def drift_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("d")
    a = make_dataset(
        {"integrator": ["lie_poisson", "rk4"], "f": [50.0], "theta0": [45.0], "dt": [1e-3]}, t_end=100.0, every=1e-2
    )
    b = make_dataset(
        {"integrator": ["explicit_euler"], "f": [50.0], "theta0": [45.0], "dt": [1e-5]}, t_end=5.0, every=1e-3
    )
    return write(a, root / "long.h5"), write(b, root / "euler.h5")


def run_cli(*args, tmp_path):
    return subprocess.run(
        command("gyrolab-verdict", "gyrolab.analysis.verdicts.verdict") + [str(a) for a in args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )


def records(paths, tmp_path, *extra):
    out = tmp_path / "v.json"
    V.main([str(p) for p in paths] + ["--json", str(out)] + list(extra))
    return json.loads(out.read_text())


def test_orders_of_the_ladder(ladder_file, tmp_path):
    recs = records([ladder_file], tmp_path)
    orders = {r["method"]: r for r in recs if r["kind"] == "order"}
    for name, p in TRUE_ORDER.items():
        r = orders[name]
        assert abs(r["order"] - p) <= 0.15, r
        assert r["order_ci"][0] <= r["order"] <= r["order_ci"][1]
        assert r["reference"].startswith("finest lie_poisson4 run")
    summ = [r for r in recs if r["kind"] == "summary" and r["method"] == "rk4"]
    assert {r["quantity"] for r in summ} == {"energy", "Lz", "L3"}  # heavy_top's CONSERVED
    assert all(abs(r["order"] - 4) <= 0.15 for r in summ)


@pytest.mark.slow
def test_dop853_reference_gives_the_same_orders(ladder_file, tmp_path):
    recs = records([ladder_file], tmp_path, "--reference", "dop853")
    for r in (r for r in recs if r["kind"] == "order"):
        assert r["reference"].startswith("DOP853")
        assert abs(r["order"] - TRUE_ORDER[r["method"]]) <= 0.15, r


def test_drift_classes(drift_files, tmp_path):
    recs = records(drift_files, tmp_path)
    runs = {(r["method"], r["quantity"]): r for r in recs if r["kind"] == "run"}
    assert runs["lie_poisson", "energy"]["drift_class"] == "bounded"
    assert runs["rk4", "energy"]["drift_class"] == "linear" and runs["rk4", "energy"]["drift_rate"] < 0
    assert runs["rk4", "energy"]["drift_rate_unit"] == "1/s"
    assert runs["explicit_euler", "energy"]["drift_class"] == "growing"
    # L3 = I3 w3 is kept exactly by every symmetric-top scheme; the declaration agrees
    assert runs["lie_poisson", "L3"]["preserved"] and runs["lie_poisson", "L3"]["declared_preserved"]
    assert not runs["rk4", "energy"]["preserved"]


def test_json_schema(ladder_file, drift_files, tmp_path):
    recs = records([ladder_file, *drift_files], tmp_path)
    assert {r["kind"] for r in recs} == {"summary", "order", "run"}
    for r in recs:
        assert set(V.RECORD_KEYS) <= set(r), r
    for r in recs:
        if r["kind"] == "run":
            assert all(isinstance(r[k], float) for k in ("f", "theta0", "dt"))
            assert r["drift_class"] in DRIFT_CLASSES
        if r["kind"] == "order":
            assert len(r["order_ci"]) == 2
    summ = [r for r in recs if r["kind"] == "summary" and r["method"] == "rk4" and r["quantity"] == "energy"]
    assert len(summ) == 1 and summ[0]["order"] is not None and summ[0]["drift_class"] == "linear"
    assert summ[0]["t_end"] == 100.0 and summ[0]["dt"] == 1e-3  # the drift comes from the long run


def test_markdown_states_the_conditions(ladder_file, drift_files, tmp_path):
    md = tmp_path / "v.md"
    V.main([str(ladder_file), *map(str, drift_files), "--markdown", str(md)])
    text = md.read_text()
    assert "## heavy_top" in text and "| `rk4` | 4 |" in text
    assert "f = 50 Hz, θ0 = 45°, final state at t = 1 s" in text
    assert "dt = 0.001 s, t_end = 100 s" in text


@pytest.mark.slow
def test_cli_prints_a_table(ladder_file, tmp_path):
    result = run_cli(ladder_file, tmp_path=tmp_path)
    assert result.returncode == 0, result.stderr
    row = next(line for line in result.stdout.splitlines() if line.startswith("seed_next"))
    assert row.split()[2].startswith("1.0"), row  # (method, invariant, measured order ...)


def _bad_inputs(tmp_path, ladder_file):
    (tmp_path / "notes.h5").write_text("not hdf5\n")
    foreign = tmp_path / "foreign.h5"
    xr.Dataset({"x": ("n", np.arange(3.0))}).to_netcdf(foreign, engine="h5netcdf")
    empty = tmp_path / "empty.h5"
    with xr.open_dataset(ladder_file, engine="h5netcdf") as ds:
        ds.load().isel(integrator=[]).to_netcdf(empty, engine="h5netcdf")
    return {
        "missing": [tmp_path / "nope.h5"],
        "unreadable": [tmp_path / "notes.h5"],
        "foreign": [foreign],
        "no runs": [empty],
        "empty dir": [tmp_path / "sub"],
    }


@pytest.mark.slow
def test_bad_input_exits_2_with_one_line(ladder_file, tmp_path):
    (tmp_path / "sub").mkdir()
    for name, files in _bad_inputs(tmp_path, ladder_file).items():
        out = tmp_path / f"{name}.json"
        result = run_cli(*files, "--json", out, tmp_path=tmp_path)
        assert result.returncode == 2, (name, result)
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr, (name, result)
        assert result.stderr.startswith("gyrolab-verdict: error:"), result.stderr
        assert not out.exists(), name


@pytest.mark.slow
def test_bad_flags_exit_2(ladder_file, tmp_path):
    for args in (["--stability", "-1"], ["--json", str(tmp_path / "no" / "dir" / "v.json")]):
        result = run_cli(ladder_file, *args, tmp_path=tmp_path)
        assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result


def test_stability_threshold_record(tmp_path):
    """rk4 on the free disc: |c| dt_crit = 2√2 on the imaginary axis (c = ω3 here)."""
    path = write(
        make_dataset(
            {"integrator": ["rk4"], "f": [10.0], "theta0": [30.0], "dt": [1e-3]},
            scene="free_symmetric",
            t_end=1.0,
            every=0.1,
        ),
        tmp_path / "disc.h5",
    )
    recs = records([path], tmp_path, "--stability", "10")
    thr = next(r for r in recs if r["kind"] == "threshold")
    omega = thr["omega"]
    c = 2 * math.pi * 10.0
    assert thr["omega_dt_crit"] * c / omega == pytest.approx(2 * math.sqrt(2), rel=5e-3)
    summ = next(r for r in recs if r["kind"] == "summary")
    assert summ["omega_dt_crit"] == thr["omega_dt_crit"] and summ["stability_t_end"] == 10.0


@pytest.mark.slow
def test_seed_next_drift_at_50_hz_is_linear_at_the_issue_rate(tmp_path):
    """Issue 11: heavy top, θ0 = 45°, released, 50 Hz, dt = 1e-3 s, 400 s: linear, −3.2e-6 /s ± 10 %."""
    path = write(
        make_dataset(
            {"integrator": ["seed_next"], "f": [50.0], "theta0": [45.0], "dt": [1e-3]}, t_end=400.0, every=0.1
        ),
        tmp_path / "seed.h5",
    )
    recs = records([path], tmp_path)
    e = next(r for r in recs if r["kind"] == "summary" and r["quantity"] == "energy")
    assert e["drift_class"] == "linear" and e["drift_rate_unit"] == "1/s"
    assert e["drift_rate"] == pytest.approx(-3.2e-6, rel=0.1), e


# ---------------------------------------------------------------- any file: one verdict per (method, f, θ0)


@pytest.fixture(scope="module")
def two_f_file(tmp_path_factory):
    """Like the default study: two f, one θ0, a ladder of decades, 0.5 s sampled every 10 ms."""
    grid = {"integrator": ["seed_next", "lie_poisson"], "f": [10.0, 50.0], "theta0": [45.0], "dt": [1e-3, 1e-4, 1e-5]}
    return write(make_dataset(grid, t_end=0.5, every=1e-2), tmp_path_factory.mktemp("two") / "results.h5")


@pytest.mark.slow
def test_one_verdict_per_method_f_and_theta0(two_f_file, tmp_path):
    """Issue 26: every (method, f, θ0) group with a ladder gets its own verdict, labelled; the terminal
    table fits 120 columns, names each group and words the ladder from its steps (decades, not halving)."""
    recs = records([two_f_file], tmp_path)
    summ = [r for r in recs if r["kind"] == "summary"]
    assert {(r["method"], r["f"], r["theta0"]) for r in summ} == {
        (m, f, 45.0) for m in ("seed_next", "lie_poisson") for f in (10.0, 50.0)
    }
    for r in summ:
        order = next(o for o in recs if o["kind"] == "order" and (o["method"], o["f"]) == (r["method"], r["f"]))
        assert r["order"] == order["order"] and r["order_f"] == r["f"]  # the order of its own f
    result = run_cli(two_f_file, tmp_path=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert max(map(len, lines)) <= 120
    assert "heavy_top: f = 10 Hz, θ0 = 45°" in lines and "heavy_top: f = 50 Hz, θ0 = 45°" in lines
    assert "decades" in result.stdout and "halving" not in result.stdout
    md = tmp_path / "v.md"
    V.main([str(two_f_file), "--markdown", str(md)])
    assert "| method | f (Hz) | θ0 (°) |" in md.read_text()


@pytest.mark.slow
def test_at_picks_one_group_and_refuses_one_not_held(two_f_file, tmp_path):
    recs = records([two_f_file], tmp_path, "--at", "f=50")
    assert {r["f"] for r in recs if r["kind"] in ("summary", "order", "run")} == {50.0}
    result = run_cli(two_f_file, "--at", "f=7", tmp_path=tmp_path)
    assert result.returncode == 2 and "f=7" in result.stderr and "(10, 45)" in result.stderr
    assert result.stderr.count("\n") == 1 and not result.stdout
    result = run_cli(two_f_file, "--at", "dt=1", tmp_path=tmp_path)
    assert result.returncode == 2 and "expected f=<Hz> or theta0=<deg>" in result.stderr


def test_wording_comes_from_the_data():
    assert V.ladder_words([1e-3, 1e-4, 1e-5]) == "3 steps, decades"
    assert V.ladder_words([1e-2 / 2**k for k in range(13)]) == "13 steps, halving"
    assert V.ladder_words([1e-3, 3e-4, 1e-4]).startswith("3 steps, uneven")
    rec = {"order": None, "order_reason": "0 usable point(s) after excluding 3 flat; need 3", "ladder_err": []}
    assert V.fmt_order(rec, short=True) == "— (0 usable point(s))"
    assert V.fmt_order(rec) == "— (0 usable point(s) after excluding 3 flat; need 3)"


def test_the_figures_fitted_line_lies_on_its_data(drift_files, tmp_path):
    """Issue 26: the dashed line panel (c) draws for a linear run (analysis/verdicts/figures.py fitted_line, from the
    record's own intercept and rate) is within a factor 2 of |e| over the run's last eighth."""
    from gyrolab.analysis.verdicts.figures import fitted_line
    from gyrolab.kernels.invariants import invariant

    recs = records(drift_files, tmp_path)
    ds = xr.open_dataset(drift_files[0], engine="h5netcdf")
    t = ds.time.values
    held = set(ds.integrator.values)
    linear = [r for r in recs if r["kind"] == "run" and r["drift_class"] == "linear" and r["method"] in held]
    assert linear
    for r in linear:
        run = ds.sel({"integrator": r["method"], "f": r["f"], "theta0": r["theta0"], "dt": r["dt"]})
        e = np.abs(V.signed_error(invariant(run, r["quantity"]).values))
        line = np.abs(fitted_line(r, t))
        tail = e[t >= t[-1] - t[-1] / 8]
        assert 0.5 * tail.min() <= line[-1] <= 2 * tail.max(), r
        assert np.isnan(line[t < r["fit_t0"]]).all()


def test_errors_below_the_references_own_error_leave_the_fit_and_say_so():
    # A second-order ladder err = 1e-2 dt²/dt0² measured against a reference good to 1e-7: the three finest
    # points (≤ 1e-7) measure the reference, so they leave the fit, which keeps order 2 on the others.
    dt = 1e-2 / 2.0 ** np.arange(10)
    err = 1e-2 * (dt / dt[0]) ** 2
    fit = V.fit_order(dt, err, reference_error=1e-7)
    assert [x for x in fit.excluded if x] == ["reference"] * int(np.sum(err <= 1e-7))
    assert abs(fit.order - 2.0) < 1e-9
    # all of them below it: no order, and the table says why instead of 'flat' or a bare reason
    fit = V.fit_order(dt, err * 1e-6, reference_error=1e-7)
    assert math.isnan(fit.order) and "reference" in fit.reason
    rec = dict(order=None, order_reason=fit.reason, ladder_excluded=fit.excluded, ladder_err=list(err * 1e-6))
    text = V.fmt_order(rec)
    assert text.startswith("— (≤ reference") and f"{err[0] * 1e-6:.0e}" in text


def test_a_rounding_level_trend_is_a_rounding_drift_whatever_the_window_calls_it():
    # lie_poisson4's |L − L0| on the free disc over 1e6 steps: 9.3e-12 in all, 0.04 ulp per step, which a
    # 1000 s window sees as the start of an oscillation of period ~7000 s (docs/verdict.md said
    # "!L declared, not kept").
    for cls in classify.TREND_CLASSES:
        assert classify.is_rounding_drift(cls, 9.3e-12, 1_000_000, False)
        assert not classify.is_rounding_drift(cls, 1e-9, 1_000_000, False)  # 4.5 ulp a step: truncation
    for cls in ("bounded", "collapse", "diverged", "growing"):
        assert not classify.is_rounding_drift(cls, 1e-15, 1_000_000, False)
    # A power-law growth at that size is one too (split6_exact's L_z on Kovalevskaya's top: 4.3e-12 over
    # 1e6 steps, "growing ∝ t^1.33"); an exponential growth never, however small.
    assert classify.is_rounding_drift("growing", 4.3e-12, 1_000_000, False, "power")
    assert not classify.is_rounding_drift("growing", 1e-9, 1_000_000, False, "power")
    assert not classify.is_rounding_drift("growing", 1e-15, 1_000_000, False, "1/s e-folding")
    assert not classify.is_rounding_drift("linear", 1e-15, 1_000_000, True)  # preserved is said as such
    assert not classify.is_rounding_drift("linear", None, 1_000_000, False)
    rec = dict(quantity="L", preserved=False, declared_preserved=True, drift_class="slow_oscillation")
    assert V.fmt_preserved([dict(rec, amplitude=9.3e-12, n_steps=1_000_000)]) == "L (rounding drift)"
    assert V.fmt_preserved([dict(rec, amplitude=1e-9, n_steps=1_000_000)]) == "!L declared, not kept"


def test_an_invariant_whose_bits_never_move_is_exact_not_bounded_by_zero():
    """Issue 26: an invariant kept to the last bit (L3 of the heavy top under every method) read
    'bounded (≤ 0)'; it says exact, and a bound above zero keeps its number."""
    from gyrolab.analysis.verdicts.cells import fmt_drift

    t = np.linspace(0.0, 10.0, 201)
    d = classify.classify_drift(t, np.zeros_like(t))
    assert d.drift_class == "bounded" and d.amplitude == 0
    assert fmt_drift({"drift_class": "bounded", "amplitude": 0.0}) == "exact (e = 0 at every sample)"
    assert fmt_drift({"drift_class": "bounded", "amplitude": 6.6e-16}) == "bounded (≤ 6.6e-16)"


def test_a_diverged_run_is_diverged_in_every_invariant_derived_or_stored():
    """Issue 26: |L| (derived from L) of a run its kernel stopped was read as 0 after the stop (xarray's sum
    skips NaN), so the verdict called explicit_euler's L_norm 'bounded (≤ 2.5)' beside its diverged
    energy.  Every invariant of a stopped run is NaN after the stop and classed diverged at one time."""
    from gyrolab.kernels.invariants import invariant

    ds = make_dataset(
        {"integrator": ["explicit_euler"], "f": [50.0], "theta0": [45.0], "dt": [1e-3]},
        scene="free_asymmetric",
        t_end=2.0,
        every=1e-2,
    )
    run = ds.isel(integrator=0, f=0, theta0=0, dt=0)
    assert int(run.status) != 0  # explicit Euler's energy gain stops it within 0.5 s (the verdict study's run)
    t = ds.time.values
    times = set()
    for q in ("energy", "L", "L_norm", "Lz"):
        x = invariant(run, q).values
        stop = int(np.argmax(~np.isfinite(x.reshape(len(t), -1)).any(axis=1)))
        assert 0 < stop and not np.isfinite(x[stop:]).any(), q
        d = classify.classify_drift(t, V.signed_error(x))
        assert d.drift_class == "diverged", (q, d.reason)
        times.add(d.t_diverged)
    assert len(times) == 1


def test_the_verdict_text_counts_the_implicit_solvers_of_its_drift_runs():
    """A summary whose drift run counted solver iterations shows their mean a step and the most in one
    step; methods without a solver (0), engines (−1) and files of older layouts (None) show nothing."""
    rows = [
        {"method": "implicit_midpoint", "solver_iterations": 3100, "solver_iterations_max": 5, "n_steps": 1000},
        {"method": "implicit_midpoint", "solver_iterations": 3100, "solver_iterations_max": 5, "n_steps": 1000},
        {"method": "rk4", "solver_iterations": 0, "solver_iterations_max": 0, "n_steps": 1000},
        {"method": "mujoco_engine", "solver_iterations": -1, "solver_iterations_max": -1, "n_steps": 1000},
        {"method": "lgvi", "solver_iterations": None, "solver_iterations_max": None, "n_steps": 1000},
    ]
    assert V.solver_words(rows) == "implicit_midpoint 3.1 (5)"
    assert V.solver_words(rows[2:]) == ""
