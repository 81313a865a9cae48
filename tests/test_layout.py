"""The results layout: files of the current layout (4: the per-run solver counts), of layout 3 (the
grid dim ``integrator``, no solver counts), of layout 2 (the dim called ``method``), of layout 1
(before heavy bodies: no gamma, a four-field body) and of layout 0 (before layout_version) open with
every reader, as today's names; foreign files are refused."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

from gyrolab.analysis.files.compare import compare_files
from gyrolab.results import ResultsError, open_results
from gyrolab.results.layout import (
    LAYOUT_VERSION,
    RAW_FIELDS,
    RUN_VARIABLES,
    SAMPLE_VARIABLES,
    required_variables,
)
from gyrolab.results.migrate import SOLVER_COUNTS, file_layout_version

from helpers import BIN, make_dataset, synthetic_dataset

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture
def stored_rk4(tmp_path):
    """The stored regression dataset heavy_top_release/rk4 (layout 1) as a results file."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("regenerate", DATA / "regenerate.py")
    regen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(regen)
    out = tmp_path / "stored_rk4.h5"
    regen.export_results(regen.stored_path("heavy_top_release", "rk4"), out)
    return out


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """(current, layout 0) files of the same runs: layout 0 is gyrolab at c0ed527 (no layout_version,
    no L, no stored run inputs)."""
    root = tmp_path_factory.mktemp("layout")
    ds = make_dataset({"integrator": ["rk4", "lie_poisson"], "f": [10.0], "dt": [1e-3]}, t_end=0.2, every=1e-2)
    ds.attrs.update(gyrolab_version="0.1.0", config="sweep:\n  t_end: 0.2\n")
    new, old = root / "new.h5", root / "old.h5"
    ds.to_netcdf(new, engine="h5netcdf")
    legacy = ds.drop_vars(["L", "gamma", "body", "omega0", "q0", *SOLVER_COUNTS]).rename(integrator="method")
    legacy.attrs = {k: v for k, v in ds.attrs.items() if k not in ("layout_version", "conserved", "closed_form")}
    legacy.to_netcdf(old, engine="h5netcdf")
    return new, old


@pytest.fixture(scope="module")
def layout_1(files, tmp_path_factory):
    """The current file as layout 1 wrote it: no gamma, body_param = (I1, I2, I3, mgl)."""
    import xarray as xr

    ds = xr.open_dataset(files[0], engine="h5netcdf").load()
    one = ds.drop_vars(["gamma", *SOLVER_COUNTS]).isel(body_param=slice(0, 4)).rename(integrator="method")
    one.attrs["layout_version"] = 1
    path = tmp_path_factory.mktemp("layout1") / "v1.h5"
    one.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.fixture(scope="module")
def layout_2(files, tmp_path_factory):
    """The current file as layout 2 wrote it: the grid dim called ``method``."""
    import xarray as xr

    ds = xr.open_dataset(files[0], engine="h5netcdf").load().drop_vars(SOLVER_COUNTS).rename(integrator="method")
    ds.attrs["layout_version"] = 2
    path = tmp_path_factory.mktemp("layout2") / "v2.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A results file written by the runner (runner/store.py) of two integrators."""
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import config_hash, register_configs
    from gyrolab.runner.execute import run_chunk
    from gyrolab.runner.grid import build_grid
    from gyrolab.runner.store import write_results
    from gyrolab.runner.sweep import file_attrs

    register_configs()
    overrides = ["sweep.method=[rk4,lie_poisson]", "sweep.f=[10]", "sweep.theta0=[45]", "sweep.dt=[1e-3]"]
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[*overrides, "sweep.t_end=0.02", "output.every=1e-3"])
    grid = build_grid(cfg)
    chunks = [run_chunk(grid, np.arange(m * grid.n_runs // 2, (m + 1) * grid.n_runs // 2), 1) for m in range(2)]
    path = tmp_path_factory.mktemp("fresh") / "results.h5"
    write_results(path, grid, chunks, file_attrs(cfg, grid, 1, config_hash(cfg)))
    return path


def test_theta_is_the_tilt_of_the_axis_direction_accurate_on_the_vertical():
    # an axis (0, 0, 1 − 2e-12), a quaternion's norm drift on a top sleeping exactly upright, is tilt 0, not
    # arccos(1 − 2e-12) = 2e-6 rad; hanging likewise π; elsewhere the angle of the axis however long it is
    tilts = np.radians([0.0, 1e-7, 30.0, 45.0, 90.0, 135.0, 180.0])
    raw = np.zeros((len(tilts) + 2, len(RAW_FIELDS)))
    ax, ay, az = (RAW_FIELDS.index(n) for n in ("axis_x", "axis_y", "axis_z"))
    raw[: len(tilts), ax] = np.sin(tilts) * np.cos(0.3)
    raw[: len(tilts), ay] = np.sin(tilts) * np.sin(0.3)
    raw[: len(tilts), az] = np.cos(tilts)
    raw[-2, az], raw[-1, az] = 1.0 - 2e-12, -(1.0 - 2e-12)
    raw[2] *= 1.0 + 1e-9  # a longer vector, the same direction
    theta = SAMPLE_VARIABLES["theta"].derive(raw)
    np.testing.assert_allclose(theta[: len(tilts)], tilts, rtol=1e-15, atol=1e-22)
    assert theta[-2] == 0.0 and theta[-1] == np.pi


def test_a_fresh_file_selects_one_integrator_with_sel_and_opens_with_netcdf_c(fresh):
    """Layout 3: ``ds.sel(integrator="rk4")`` selects exactly rk4 (with the dim called ``method``,
    ``ds.sel(method="rk4")`` was .sel's own keyword and silently kept every method); netCDF-C reads
    the same file with the same dims."""
    import xarray as xr

    with xr.open_dataset(fresh, engine="h5netcdf") as ds:
        assert ds.attrs["layout_version"] == LAYOUT_VERSION == 4
        for name in SOLVER_COUNTS:  # rk4 and lie_poisson have no iterative solver
            assert ds[name].dtype == np.int64 and (ds[name].values == 0).all(), name
        assert list(ds["integrator"].values) == ["rk4", "lie_poisson"] and "method" not in ds.dims
        rk4 = ds.sel(integrator="rk4")
        assert "integrator" not in rk4.dims and str(rk4["integrator"].values) == "rk4"
        assert rk4["energy"].dims == ("f", "theta0", "dt", "time")
        both = ds.sel(integrator=["rk4", "lie_poisson"])
        assert not np.array_equal(both["omega"].values[0], both["omega"].values[1])
        h5 = ds.load()
    with xr.open_dataset(fresh, engine="netcdf4") as c:
        assert c["energy"].dims == ("integrator", "f", "theta0", "dt", "time")
        assert list(c["integrator"].values) == ["rk4", "lie_poisson"]
        np.testing.assert_array_equal(
            c.sel(integrator="lie_poisson")["energy"].values, h5.sel(integrator="lie_poisson")["energy"].values
        )


@pytest.mark.parametrize("lazy", [False, True])
def test_the_reader_gives_what_xarray_opens(fresh, files, layout_1, lazy):
    """The reader opens through a file that keeps its lookups (gyrolab/results/reader.py ``_LookupsKept``):
    the Dataset is the one ``xr.open_dataset(engine="h5netcdf")`` gives, values, attrs and encodings."""
    import xarray as xr

    from gyrolab.results.migrate import current
    from gyrolab.results.reader import open_file

    for path in (fresh, *files, layout_1):
        with xr.open_dataset(path, engine="h5netcdf", phony_dims="access") as ds:
            expected = current(ds.load())
        got, version = open_file(path, lazy=lazy)
        with got:
            got.load()
            xr.testing.assert_identical(got, expected)
            assert version == file_layout_version(expected)
            for name in expected.variables:  # repr: a NaN _FillValue is never == itself
                assert repr(got[name].encoding) == repr(expected[name].encoding), (path, name)


def test_a_lazily_opened_file_is_closed_with_its_dataset(fresh, tmp_path):
    """``ds.close()`` of a lazy Dataset closes its file (it stayed open, read-only, until the Dataset was
    collected: HDF5 then refused to open it for writing in the same process)."""
    import shutil

    import h5py

    from gyrolab.results.reader import open_file

    path = shutil.copy(fresh, tmp_path / "results.h5")
    ds, _ = open_file(path, lazy=True)
    with pytest.raises(OSError, match="already open"):
        h5py.File(path, "r+")
    assert float(ds["energy"].isel(time=-1).max()) > 0  # read lazily, from the open file
    ds.close()
    with h5py.File(path, "r+") as h5:  # closed: HDF5 lets it open for writing
        assert "energy" in h5


@pytest.mark.slow
def test_older_layouts_open_with_integrator_not_method(files, layout_1, layout_2, stored_rk4):
    """Every older layout (0, 1, 2 and the stored regression data) reads with the dim ``integrator``:
    the rename happens once, when the file is opened (layout.current)."""
    import xarray as xr

    from gyrolab.results.migrate import current

    stored = stored_rk4
    for path in (files[1], layout_1, layout_2, stored):
        with xr.open_dataset(path, engine="h5netcdf") as raw:
            assert "method" in raw.dims and file_layout_version(raw) < 3
            assert "integrator" in current(raw).dims and "method" not in current(raw).dims
        ds = open_results(path)
        assert "integrator" in ds.dims and "method" not in ds.dims and "method" not in ds.variables
        assert ds["energy"].dims[0] == "integrator"
    assert list(open_results(layout_2)["integrator"].values) == ["rk4", "lie_poisson"]
    assert open_results(stored)["integrator"].values.tolist() == ["rk4"]


@pytest.mark.slow
def test_compare_a_layout_2_file_with_a_current_file(files, layout_2):
    report = compare_files(layout_2, files[0])
    assert report.ok, report.text()
    assert report.dropped == [f"variable {name} (not in the older layout of one file)" for name in SOLVER_COUNTS]
    assert report.n_runs == 2
    done = subprocess.run([str(BIN / "gyrolab-compare"), str(layout_2), str(files[0])], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "RESULT: OK" in done.stdout and "2 integrator" in done.stdout


@pytest.mark.slow
def test_selection_by_the_old_name_method_still_works(layout_2, tmp_path):
    done = subprocess.run(
        [str(BIN / "gyrolab-plot"), "energy", str(layout_2), "method=rk4", "-o", str(tmp_path / "e.png")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "e.png").stat().st_size > 0


def test_layout_1_file_opens_with_the_body_it_meant(files, layout_1):
    """A layout-1 body (centre of mass on e3) reads as today's Body with mgc1 = mgc2 = 0; compare with a
    current file of the same runs passes and says that gamma is not in the older layout."""
    from gyrolab.analysis.io import build_run_scene
    from gyrolab.kernels.body import FIELDS

    ds = open_results(layout_1)
    assert file_layout_version(ds) == 1 and "gamma" not in ds
    assert list(ds["body_param"].values) == list(FIELDS)
    np.testing.assert_array_equal(ds["body"].values[..., 4:], 0.0)
    current = open_results(files[0])
    np.testing.assert_array_equal(ds["body"].values, current["body"].values)
    assert build_run_scene(ds, 10.0, 45.0) == build_run_scene(current, 10.0, 45.0)
    report = compare_files(layout_1, files[0])
    assert report.ok and not report.versions, report.text()
    assert any("variable gamma" in note for note in report.dropped)


def test_stored_regression_data_of_layout_1_open_with_the_current_body(stored_rk4):
    from gyrolab.kernels.body import FIELDS

    ds = open_results(stored_rk4)
    assert file_layout_version(ds) == 1 and list(ds["body_param"].values) == list(FIELDS)
    assert float(ds["body"].sel(body_param="mgl").values.max()) > 0.0


def test_current_and_layout_0_files_open(files):
    new, old = files
    assert file_layout_version(open_results(new)) == LAYOUT_VERSION
    legacy = open_results(old)
    assert file_layout_version(legacy) == 0 and "L" not in legacy
    assert set(SAMPLE_VARIABLES) - {"L", "gamma"} <= set(legacy)


def test_compare_across_layouts_compares_the_shared_variables(files):
    report = compare_files(*files)
    assert report.ok
    assert any("variable L" in note for note in report.dropped)


@pytest.mark.slow
def test_every_figure_of_a_layout_0_file(files, tmp_path):
    """The standard figures draw from a layout-0 file (invariants it lacks are left out)."""
    done = subprocess.run(
        [str(BIN / "gyrolab-plot"), "standard", str(files[1]), "-o", str(tmp_path / "figs")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert len(list((tmp_path / "figs").glob("*.png"))) == 4


def test_a_newer_layout_is_refused_in_one_line(files, tmp_path):
    import xarray as xr

    ds = xr.open_dataset(files[0], engine="h5netcdf").load()
    ds.attrs["layout_version"] = LAYOUT_VERSION + 1
    path = tmp_path / "future.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    with pytest.raises(ResultsError, match="newer than this gyrolab reads"):
        open_results(path)


def test_plot_standard_that_draws_nothing_exits_2(files, tmp_path, monkeypatch, capsys):
    """`gyrolab-plot standard` whose every figure fails is not a success: one line, exit 2."""
    from gyrolab.analysis.figures import cli
    from gyrolab.analysis.figures import registry as figures

    monkeypatch.setattr(figures, "standard_figures", lambda *args, **kwargs: [])
    with pytest.raises(SystemExit) as done:
        cli.main(["standard", str(files[0]), "-o", str(tmp_path / "figs")])
    assert done.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no figure could be drawn" in err[0]


def test_a_file_of_today_holds_the_solver_counts_with_their_dtype_and_attrs(tmp_path):
    """Layout 4: solver_iterations and solver_iterations_max, int64 per run, with units, long names and
    what 0 and -1 mean; written and read back as stored."""
    counts = np.array([[[[[7, 3], [0, 0]]], [[[-1, -1], [12, 5]]]]])  # (integrator, f, theta0, dt, 2)
    synthetic_dataset({"f": [10.0, 20.0], "dt": [1e-3, 5e-4]}, counts=counts).to_netcdf(tmp_path / "r.h5")
    ds = open_results(tmp_path / "r.h5")
    assert file_layout_version(ds) == LAYOUT_VERSION == 4
    assert list(RUN_VARIABLES)[-2:] == list(SOLVER_COUNTS) == ["solver_iterations", "solver_iterations_max"]
    for k, name in enumerate(SOLVER_COUNTS):
        assert ds[name].dtype == np.int64 and ds[name].dims == ("integrator", "f", "theta0", "dt")
        np.testing.assert_array_equal(ds[name].values, counts[..., k])
        assert ds[name].attrs["units"] == "1"
        assert "0: the method has no iterative solver" in ds[name].attrs["description"]
        assert "-1: not counted (an engine package" in ds[name].attrs["description"]
    assert ds["solver_iterations"].attrs["long_name"] == "implicit solver iterations over the run"
    assert ds["solver_iterations_max"].attrs["long_name"] == "most solver iterations in one step"
    assert "summed over the run's steps" in ds["solver_iterations"].attrs["description"]
    assert "3: a step's implicit solver did not converge" in ds["status"].attrs["legend"]


def test_a_layout_3_file_without_the_solver_counts_opens_and_validates(tmp_path):
    """Layouts 0 to 3 lack the solver counts: such a file opens, checked, without them (never filled
    in); a layout-4 file without them is incomplete."""
    for version in (3, 2):
        assert not set(SOLVER_COUNTS) & set(required_variables(version))
    assert set(SOLVER_COUNTS) <= set(required_variables(4))
    old = synthetic_dataset(version=3)
    assert not set(SOLVER_COUNTS) & set(old.data_vars)
    old.to_netcdf(tmp_path / "v3.h5")
    ds = open_results(tmp_path / "v3.h5")
    assert file_layout_version(ds) == 3 and not set(SOLVER_COUNTS) & set(ds.data_vars)
    assert int(ds["n_steps"].values.ravel()[0]) == 20
    old.assign_attrs(layout_version=4).to_netcdf(tmp_path / "v4.h5")
    with pytest.raises(ResultsError, match="no variable 'solver_iterations'"):
        open_results(tmp_path / "v4.h5")


@pytest.mark.parametrize(
    "counts, message",
    [
        ([[-2, 0]], "solver_iterations=-2 is below -1"),
        ([[-1, 4]], "solver_iterations=-1 with solver_iterations_max=4: -1 .not counted. must be in both"),
        ([[5, 6]], "solver_iterations_max=6 exceeds the run's total solver_iterations=5"),
    ],
)
def test_solver_counts_that_cannot_be_are_refused_in_one_line(tmp_path, counts, message):
    synthetic_dataset(counts=np.array(counts).reshape(1, 1, 1, 1, 2)).to_netcdf(tmp_path / "r.h5")
    with pytest.raises(ResultsError, match=message):
        open_results(tmp_path / "r.h5")


def test_one_solver_count_without_the_other_is_refused(tmp_path):
    synthetic_dataset(version=3).assign(solver_iterations=synthetic_dataset()["solver_iterations"]).to_netcdf(
        tmp_path / "r.h5"
    )
    with pytest.raises(ResultsError, match="variable solver_iterations without solver_iterations_max"):
        open_results(tmp_path / "r.h5")
