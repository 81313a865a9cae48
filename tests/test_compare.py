"""gyrolab-compare: the comparison rules, the table, the exit status and the provenance notes.

The files here are built by helpers.make_dataset in the results layout
(gyrolab/results/layout.py) and written with h5netcdf,
so these tests do not depend on the runner; tests/test_regression.py runs
the same code on files the ``gyrolab`` command wrote.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from gyrolab.analysis.files.compare import CompareError, compare_files, main, parse_tolerances
from gyrolab.results.layout import SAMPLE_VARIABLES, VARIABLES_ATTR

from helpers import make_dataset, synthetic_dataset

METHODS = ("seed_next", "lie_poisson")
F = (10.0, 20.0)
DT = (1e-3, 5e-4)


def config_text(scene="heavy_top", t_end=0.1, path="results.h5", **scene_options):
    """A resolved config like the runner stores in the ``config`` attr."""
    return yaml.safe_dump(
        {
            "scene": {"name": scene, **scene_options},
            "sweep": {"method": list(METHODS), "f": list(F), "theta0": [45.0], "dt": list(DT), "t_end": t_end},
            "output": {"every": 0.01, "path": path, "overwrite": False, "figures": False},
            "runner": {
                "resume": False,
                "dry_run": False,
                "threads": None,
                "chunk_seconds": 1.0,
                "divergence_threshold": 10.0,
                "backend": "local",
            },
        },
        sort_keys=False,
    )


def assemble(scene="heavy_top", t_end=0.1, every=0.01, **scene_options):
    """Results Dataset (gyrolab/results/layout.py) of METHODS x F x [45 deg] x DT, built by helpers.make_dataset."""
    ds = make_dataset(
        {"integrator": list(METHODS), "f": list(F), "theta0": [45.0], "dt": list(DT)},
        scene,
        t_end,
        every,
        **scene_options,
    )
    ds.attrs.update(
        {
            "config": config_text(scene, t_end, **scene_options),
            "gyrolab_version": "0.1.0",
            "git_commit": "0" * 40,
            "git_dirty": 0,
            "numba_version": "0.68.1",
            "numpy_version": "2.4.6",
            "threads": 2,
            "created": "2026-01-01T00:00:00+00:00",
        }
    )
    return ds


def write(ds, path):
    ds.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.fixture(scope="module")
def base():
    return assemble().load()


@pytest.fixture
def pair(base, tmp_path):
    """(path A, path B, function that writes a modified copy of the base as B)."""
    a = write(base, tmp_path / "a.h5")

    def variant(modify, name="b.h5"):
        ds = base.copy(deep=True)
        ds = modify(ds) or ds
        return write(ds, tmp_path / name)

    return a, variant


def test_assembled_file_has_the_results_layout(pair):
    a, _ = pair
    with xr.open_dataset(a, engine="h5netcdf") as ds:
        assert ds["axis"].dims == ("integrator", "f", "theta0", "dt", "time", "xyz")
        assert ds["status"].dims == ("integrator", "f", "theta0", "dt")
        assert list(ds["integrator"].values) == list(METHODS)
        assert ds.sizes["time"] == 11


def test_identical_files_pass_with_zero_tolerance(pair):
    a, variant = pair
    b = variant(lambda ds: None)
    report = compare_files(a, b)
    assert report.ok and report.exit_status == 0
    assert all(v.max_abs == 0 and v.n_bad == 0 for v in report.variables)
    assert report.worst_run is None
    assert {v.name for v in report.variables} == set(SAMPLE_VARIABLES) | {
        "status",
        "n_steps",
        "solver_iterations",
        "solver_iterations_max",
    }
    assert "ignored: wall_time (timing, not physics)" in report.text()


def _bump_energy(ds, rel=1e-6):
    """Energy of run (lie_poisson, f=20, dt=5e-4) at t = 0.05 s times (1 + rel)."""
    sel = {"integrator": "lie_poisson", "f": 20.0, "dt": 5e-4, "time": 0.05}
    ds["energy"].loc[sel] = ds["energy"].loc[sel] * (1 + rel)
    return ds


def test_one_changed_value_is_found_with_its_run_and_time(base, pair):
    a, variant = pair
    b = variant(_bump_energy)
    report = compare_files(a, b)
    assert not report.ok and report.exit_status == 1
    energy = next(v for v in report.variables if v.name == "energy")
    assert energy.n_bad == 1
    assert energy.max_rel == pytest.approx(1e-6 / (1 + 1e-6), rel=1e-9)  # |a-b| / max(|a|, |b|)
    e = float(base["energy"].loc[{"integrator": "lie_poisson", "f": 20.0, "dt": 5e-4, "time": 0.05}].squeeze())
    assert energy.max_abs == pytest.approx(abs(e) * 1e-6, rel=1e-6)
    assert energy.worst == {"integrator": "lie_poisson", "f": 20.0, "theta0": 45.0, "dt": 5e-4, "time": 0.05}
    assert report.failed() == ["energy"] and report.bad_runs == 1
    assert report.worst_run == {"integrator": "lie_poisson", "f": 20.0, "theta0": 45.0, "dt": 5e-4}
    text = report.text()
    assert "run differing most: integrator=lie_poisson f=20 theta0=45 dt=0.0005 (energy" in text
    assert text.splitlines()[-1] == "RESULT: DIFFERENT, energy out of tolerance in 1 of 8 runs"


@pytest.mark.slow
def test_tolerances_default_and_per_variable(pair):
    a, variant = pair
    b = variant(_bump_energy)
    assert compare_files(a, b, rtol=2e-6).ok
    assert not compare_files(a, b, rtol=5e-7).ok
    assert compare_files(a, b, rtol={"energy": 2e-6}).ok  # other variables are equal: 0 suffices
    assert not compare_files(a, b, rtol={"energy": 5e-7, "*": 1.0}).ok  # the named value wins
    energy = float(xr.open_dataset(a, engine="h5netcdf")["energy"].max())
    assert compare_files(a, b, atol={"energy": 2e-6 * energy}).ok
    assert compare_files(a, b, scaled=2e-6).ok  # atol = 2e-6 x largest |energy| in B
    assert not compare_files(a, b, scaled=2e-6, atol={"energy": 0.0}).ok  # named atol beats --scaled


def test_comparison_is_symmetric(pair):
    a, variant = pair
    b = variant(_bump_energy)
    ab, ba = compare_files(a, b, rtol=1e-9), compare_files(b, a, rtol=1e-9)
    for x, y in zip(ab.variables, ba.variables):
        assert (x.max_abs, x.max_rel, x.n_bad) == (y.max_abs, y.max_rel, y.n_bad)


def test_nan_in_both_is_equal_nan_against_number_is_not(pair):
    a, variant = pair
    at = {"integrator": "seed_next", "f": 10.0, "dt": 1e-3}

    def diverge(ds):  # a run that diverged at t = 0.07 s: NaN afterwards
        ds["theta"].loc[at] = np.where(ds["time"] >= 0.07, np.nan, ds["theta"].loc[at])
        return ds

    both = variant(diverge, "both.h5")
    assert compare_files(both, variant(diverge, "both2.h5")).ok
    report = compare_files(a, both, rtol=1.0, atol=1.0)  # NaN vs number fails whatever the tolerance
    theta = next(v for v in report.variables if v.name == "theta")
    assert not report.ok and theta.n_bad == theta.n_nan == 4
    assert theta.worst == {**at, "theta0": 45.0, "time": 0.07}  # where the divergence starts
    assert "NaN in one file, a number in the other" in report.text()
    assert "4/88 (4 NaN)" in report.text()


@pytest.mark.slow
def test_status_and_n_steps_are_exact_wall_time_ignored(pair):
    a, variant = pair

    def fail_one(ds):
        ds["status"].loc[{"integrator": "seed_next", "f": 10.0, "dt": 1e-3}] = 2
        return ds

    report = compare_files(a, variant(fail_one), rtol=10.0, atol=10.0)
    assert report.failed() == ["status"]
    with pytest.raises(CompareError, match="status is compared exactly"):
        compare_files(a, a, rtol={"status": 1.0})
    slow = variant(lambda ds: ds.assign(wall_time=ds["wall_time"] * 100 + 1), "slow.h5")
    assert compare_files(a, slow).ok
    with pytest.raises(CompareError, match="no variable wall_time"):
        compare_files(a, slow, rtol={"wall_time": 1.0})


def test_runs_match_by_label_not_position(pair):
    a, variant = pair
    b = variant(lambda ds: ds.isel(integrator=[1, 0], dt=[1, 0]))
    assert compare_files(a, b).ok


@pytest.mark.slow
def test_different_grids_cannot_be_compared(pair):
    a, variant = pair
    fewer = variant(lambda ds: ds.isel(f=[0]), "fewer.h5")
    with pytest.raises(CompareError, match=r"different grids: f is \[10, 20\] in A and \[10\] in B"):
        compare_files(a, fewer)
    report = compare_files(a, fewer, shared_runs=True)
    assert report.ok and report.n_runs == 4
    assert "not compared (only in one file): f [20] only in A, [] only in B" in report.text()
    # a shorter sweep (t_end 0.05 s): its attrs and step counts say so too, else the reader refuses it
    shorter = variant(
        lambda ds: ds.isel(time=slice(0, 6)).assign_attrs(t_end=0.05).assign(n_steps=ds["n_steps"] // 2), "shorter.h5"
    )
    with pytest.raises(CompareError, match="time has 11 samples to 0.1 s in A and 6 samples to 0.05 s in B"):
        compare_files(a, shorter)
    # A file whose writer chose to leave Lz out (output.variables) is compared on what both hold ...
    held = " ".join(n for n in SAMPLE_VARIABLES if n != "Lz")
    no_lz = variant(lambda ds: ds.drop_vars("Lz").assign_attrs({VARIABLES_ATTR: held}), "nolz.h5")
    report = compare_files(a, no_lz)
    assert report.ok and "Lz" in report.text()
    # ... one that lost it (damaged: no variables attr says so) is refused by the reader, as by every command.
    damaged = variant(lambda ds: ds.drop_vars("Lz"), "damaged.h5")
    with pytest.raises(
        CompareError, match="B: FILE=.*damaged.h5: not a complete gyrolab results file .no variable 'Lz'"
    ):
        compare_files(a, damaged)
    other = variant(lambda ds: ds.assign_attrs(scene="free_symmetric"), "other.h5")
    with pytest.raises(CompareError, match="different scenes"):
        compare_files(a, other)


def test_provenance_differences_come_first(pair):
    a, variant = pair

    def newer(ds):
        ds.attrs.update(
            gyrolab_version="0.2.0", numba_version="0.70.0", config=config_text(path="/elsewhere/x.h5", M=2.0)
        )
        return ds

    report = compare_files(a, variant(newer))
    assert report.ok  # provenance is reported, the numbers decide the verdict
    assert report.versions == ["gyrolab_version differs: A 0.1.0, B 0.2.0", "numba_version differs: A 0.68.1, B 0.70.0"]
    assert report.configs == ["config differs: scene.M: A (absent), B 2.0"]  # output.path is not data
    lines = report.text().splitlines()
    assert lines[2].startswith("PROVENANCE: gyrolab_version differs") and lines[4].startswith("PROVENANCE: config")
    same = compare_files(a, variant(lambda ds: ds.assign_attrs(config=config_text(path="/x.h5")), "c.h5"))
    assert same.versions == [] and same.configs == []


def test_parse_tolerances():
    assert parse_tolerances(["energy=1e-9", "1e-12"], "--rtol") == {"energy": 1e-9, "*": 1e-12}
    assert parse_tolerances(None, "--rtol") == {}
    with pytest.raises(CompareError, match="--atol energy=abc: not a number"):
        parse_tolerances(["energy=abc"], "--atol")
    with pytest.raises(CompareError, match="--rtol -1: must be a finite number >= 0"):
        parse_tolerances(["-1"], "--rtol")
    # '=1' was the default for every variable; a name given twice kept only its last value
    with pytest.raises(CompareError, match="--atol =1: no variable before '='"):
        parse_tolerances(["=1"], "--atol")
    with pytest.raises(CompareError, match="--rtol energy=1e-3: energy is given twice"):
        parse_tolerances(["energy=1e-9", "energy=1e-3"], "--rtol")
    with pytest.raises(CompareError, match="--rtol 1e-3: the default is given twice"):
        parse_tolerances(["1e-9", "1e-3"], "--rtol")


@pytest.mark.slow
def test_main_exit_status_and_one_line_errors(pair, tmp_path, capsys):
    a, variant = pair
    b = variant(_bump_energy)
    assert main([str(a), str(a)]) == 0
    assert main([str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "energy" in out and "RESULT: DIFFERENT" in out
    assert main([str(a), str(b), "--rtol", "energy=2e-6"]) == 0
    capsys.readouterr()
    for argv, message in [
        ([str(a), str(tmp_path / "missing.h5")], "cannot compare: B: "),
        ([str(a), __file__], "not a readable results file"),
        ([str(a), str(variant(lambda ds: ds.isel(dt=[0]), "dt.h5"))], "different grids: dt"),
        ([str(a), str(b), "--rtol", "enrgy=1e-9"], "error: --rtol enrgy=1e-09: no variable enrgy"),
        ([str(a), str(b), "--ignore", "enrgy"], "error: --ignore enrgy: no variable enrgy in either file"),
        ([str(a), str(b), "--atol", "x=y"], "error: --atol x=y: not a number"),
    ]:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, err
    with pytest.raises(SystemExit) as exit_info:
        main([str(a)])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.slow
def test_console_script(pair):
    """The installed command: exit 0 / 1 / 2 as documented."""
    a, variant = pair
    exe = Path(sys.executable).parent / "gyrolab-compare"
    b = variant(_bump_energy)
    codes = [
        subprocess.run([str(exe), str(a), str(x)], capture_output=True, text=True).returncode
        for x in (a, b, Path(a).with_name("nothing.h5"))
    ]
    assert codes == [0, 1, 2]


@pytest.mark.slow
def test_a_config_attr_that_is_not_a_gyrolab_config_is_compared_as_text(tmp_path):
    """A file whose ``config`` attr is not a YAML mapping (hand-made, foreign) compares without a
    traceback; two such texts that differ are named as a config difference, not an error."""
    ds = make_dataset(t_end=0.05, every=1e-2)
    a, b, c = tmp_path / "a.h5", tmp_path / "b.h5", tmp_path / "c.h5"
    for path, text in ((a, "built by hand"), (b, "built by hand"), (c, "sweep: [unclosed")):
        ds.attrs["config"] = text
        ds.to_netcdf(path, engine="h5netcdf")
    assert compare_files(a, b).ok and not compare_files(a, b).configs
    report = compare_files(a, c)
    assert report.ok and any("config" in note for note in report.configs), report.text()


@pytest.mark.slow
def test_a_combined_members_provenance_comes_from_its_source_variables(base, tmp_path):
    from gyrolab.analysis.files.combine import main as combine_main

    a = write(base, tmp_path / "top.h5")
    other = assemble("free_symmetric")
    other.attrs.update(gyrolab_version="0.3.0", git_commit="1" * 40)
    b = write(other, tmp_path / "free.h5")
    combined = tmp_path / "combined.h5"
    assert combine_main([str(a), str(b), "-o", str(combined)]) in (0, None)
    report = compare_files(combined, a, members=({"scene": "heavy_top"}, None))
    assert report.ok
    assert report.headers[0].startswith("gyrolab 0.1.0, git 0000000000")  # the heavy top's source, not "?"
    assert "created 2026-01-01T00:00:00+00:00" in report.headers[0]
    assert not [v for v in report.versions if v.startswith("gyrolab_version")], report.versions
    assert "numba_version recorded only in B" in report.versions  # combine keeps no library versions
    assert not [c for c in report.configs if "recorded only" in c], report.configs
    free = compare_files(combined, b, members=({"scene": "free_symmetric"}, None))
    assert free.headers[0].startswith("gyrolab 0.3.0, git 1111111111")  # each member its own source


@pytest.mark.slow
def test_solver_counts_are_compared_exactly(tmp_path):
    """One run's solver count differs: out of tolerance whatever the tolerances (and none can be
    given for it); the run and the variable are named."""
    counts = np.array([[[[[40, 6], [0, 0]]], [[[-1, -1], [12, 5]]]]])
    grid = {"f": [10.0, 20.0], "dt": [1e-3, 5e-4]}
    a = write(synthetic_dataset(grid, counts=counts), tmp_path / "a.h5")
    assert compare_files(a, a).ok
    changed = counts.copy()
    changed[0, 1, 0, 1, 0] = 13
    b = write(synthetic_dataset(grid, counts=changed), tmp_path / "b.h5")
    report = compare_files(a, b, rtol=10.0, atol=10.0)
    assert report.failed() == ["solver_iterations"] and report.bad_runs == 1
    (diff,) = [v for v in report.variables if v.name == "solver_iterations"]
    assert diff.exact and diff.n_bad == 1 and diff.max_abs == 1.0
    assert diff.worst == {"integrator": "m1", "f": 20.0, "theta0": 45.0, "dt": 5e-4}
    assert "RESULT: DIFFERENT, solver_iterations out of tolerance in 1 of 4 runs" in report.text()
    for name in ("solver_iterations", "solver_iterations_max"):
        with pytest.raises(CompareError, match=f"{name} is compared exactly"):
            compare_files(a, b, atol={name: 1.0})
    most = counts.copy()
    most[0, 0, 0, 0, 1] = 7
    assert compare_files(a, write(synthetic_dataset(grid, counts=most), tmp_path / "c.h5")).failed() == [
        "solver_iterations_max"
    ]


def test_a_file_of_layout_3_compares_without_the_solver_counts_and_says_so(tmp_path):
    """The stored data of layout 3 (as tests/data's regression packs) lack the solver counts: a fresh
    file compares with it on everything else, in either order, and the report names what it left out."""
    fresh = write(synthetic_dataset(), tmp_path / "fresh.h5")
    stored = write(synthetic_dataset(version=3), tmp_path / "stored.h5")
    for a, b in ((fresh, stored), (stored, fresh)):
        report = compare_files(a, b, scaled=1e-10)
        assert report.ok, report.text()
        assert {v.name for v in report.variables} == set(SAMPLE_VARIABLES) | {"status", "n_steps"}
        assert report.dropped == [
            "variable solver_iterations (not in the older layout of one file)",
            "variable solver_iterations_max (not in the older layout of one file)",
        ]
        assert "not compared (only in one file): variable solver_iterations " in report.text()
    diverged = synthetic_dataset(version=3)
    diverged["status"][...] = 2  # what the older layout holds is still compared
    assert compare_files(fresh, write(diverged, tmp_path / "diverged.h5")).failed() == ["status"]
