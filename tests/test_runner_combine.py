"""gyrolab-combine: tiles of one grid join along its axes; different scenes/options stack."""

import numpy as np
import pytest
import xarray as xr

from gyrolab.analysis.files.combine import CombineError, combine, main, write
from gyrolab.results import open_members
from gyrolab.results.layout import LAYOUT_VERSION
from gyrolab.results.migrate import SOLVER_COUNTS

from helpers import make_file, synthetic_dataset


def strip(ds):
    return ds.drop_vars([v for v in ds.variables if str(v).startswith("source_")] + ["wall_time"])


@pytest.mark.slow
def test_tiles_of_one_grid_join_along_its_axes(tmp_path):
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[50]")
    both = make_file(tmp_path / "both.h5", "sweep.f=[10,50]")
    out = combine([a, b])
    with xr.open_dataset(both, engine="h5netcdf") as ref:
        xr.testing.assert_equal(strip(out), ref.drop_vars("wall_time"))
    assert list(out["source_path"].values) == [str(a), str(b)]


def test_overlapping_files_are_refused(tmp_path):
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[10]")
    with pytest.raises(CombineError, match="overlaps .*a.h5"):
        combine([a, b])


def test_same_scene_with_other_options_stacks_along_job(tmp_path):
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[10]", "scene.M=2")
    out = combine([a, b])
    assert out["energy"].dims[0] == "job"
    assert list(out["scene_M"].values) == [1.0, 2.0] and "scene_M" not in out.attrs
    assert out.attrs["scene"] == "heavy_top"
    # energy scales with M at equal rates: E(M=2) = 2 E(M=1) at t = 0
    e0 = out["energy"].isel(time=0).squeeze()
    assert float(e0[1]) == pytest.approx(2 * float(e0[0]), rel=1e-12)


def test_different_grids_fill_the_gaps_with_status_minus_one(tmp_path):
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[50]", "scene=free_symmetric")
    out = combine([a, b])
    assert list(out["scene"].values) == ["heavy_top", "free_symmetric"] and list(out["f"].values) == [10, 50]
    status = out["status"].squeeze()
    assert status.dtype == np.int8
    assert int(status.sel(scene="heavy_top", f=50)) == -1 and int(status.sel(scene="heavy_top", f=10)) == 0
    assert np.isnan(out["energy"].sel(scene="heavy_top", f=50)).all()
    assert "-1: not in this scene's grid" in out["status"].attrs["legend"]


def test_names_longer_than_the_first_files_are_written_whole(tmp_path):
    """The first file's string coordinate carries its on-disk width (encoding dtype <U3 for "rk4"):
    the combined file must not write lie_poisson4 cut to that width (it read back as "lie")."""
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]", "sweep.method=[rk4]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[10]", "sweep.method=[lie_poisson4]", "scene=free_symmetric")
    write(combine([a, b]), tmp_path / "c.h5")
    with xr.open_dataset(tmp_path / "c.h5", engine="h5netcdf") as out:
        assert sorted(out["integrator"].values) == ["lie_poisson4", "rk4"]
        assert list(out["scene"].values) == ["heavy_top", "free_symmetric"]
        # each input's code is on record, not only its commit
        assert all(len(str(h)) == 16 for h in out["source_kernel_source_hash"].values)
        assert set(out["source_git_dirty"].values) <= {"0", "1"}


def test_cli_writes_the_file_and_refuses_bad_arguments(tmp_path, capsys):
    make_file(tmp_path / "a.h5", "sweep.f=[10]")
    make_file(tmp_path / "b.h5", "sweep.f=[50]")
    assert main([str(tmp_path)]) == 0
    with xr.open_dataset(tmp_path / "combined.h5", engine="h5netcdf") as ds:
        assert list(ds["f"].values) == [10, 50]
    assert main([str(tmp_path)]) == 2  # exists
    assert main([str(tmp_path / "nope")]) == 2
    assert main([str(tmp_path / "a.h5")]) == 2  # a file needs -o
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and all(e.startswith("gyrolab-combine: error: ") for e in errors)
    assert "exists" in errors[0] and "no such file" in errors[1] and "-o/--output" in errors[2]


@pytest.mark.slow
def test_files_of_an_older_layout_combine_into_todays(tmp_path):
    """A layout-2 file (dim ``method``, no solver counts) joins a current tile: the combined file is
    today's layout, dim ``integrator``, the old tile's solver counts -1 (not counted)."""
    from gyrolab.results.layout import LAYOUT_VERSION

    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[50]")
    with xr.open_dataset(b, engine="h5netcdf") as ds:
        old = ds.load().drop_vars(SOLVER_COUNTS).rename(integrator="method").assign_attrs(layout_version=2)
    old.to_netcdf(tmp_path / "b2.h5", engine="h5netcdf")
    out = combine([a, tmp_path / "b2.h5"])
    assert out.attrs["layout_version"] == LAYOUT_VERSION and "method" not in out.dims
    assert out["energy"].dims[:2] == ("integrator", "f") and list(out["f"].values) == [10, 50]
    for name in SOLVER_COUNTS:
        assert out[name].sel(f=50).values.item() == -1 and out[name].sel(f=10).values.item() >= 0
    xr.testing.assert_equal(strip(out).drop_vars(SOLVER_COUNTS), strip(combine([a, b])).drop_vars(SOLVER_COUNTS))


def test_attrs_that_differ_between_scenes_are_kept_along_scene(tmp_path):
    """conserved and closed_form differ between heavy_top and free_symmetric: kept per scene (the
    member a reader selects carries them), not dropped as conflicting."""
    a = make_file(tmp_path / "a.h5", "sweep.f=[10]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[10]", "scene=free_symmetric")
    out = combine([a, b])
    with xr.open_dataset(a, engine="h5netcdf") as one, xr.open_dataset(b, engine="h5netcdf") as two:
        assert list(out["conserved"].values) == [one.attrs["conserved"], two.attrs["conserved"]]
        assert list(out["closed_form"].values) == [one.attrs["closed_form"], two.attrs["closed_form"]]
    assert "conserved" not in out.attrs and out["conserved"].dims == ("scene",)


def test_a_vector_scene_option_that_differs_is_kept_as_json(tmp_path):
    import json

    from gyrolab.results.members import member

    a = make_file(tmp_path / "a.h5", "sweep.f=[3]", "scene=heavy_body", "scene.com=[0.02,0,0.1]")
    b = make_file(tmp_path / "b.h5", "sweep.f=[3]", "scene=heavy_body", "scene.com=[0,0.02,0.1]")
    out = combine([a, b])
    assert out["scene_com"].dims == ("job",) and out["scene_com"].attrs["encoding"] == "json"
    assert json.loads(out["scene_com"].values[1]) == [0.0, 0.02, 0.1]
    np.testing.assert_array_equal(member(out, "1").attrs["scene_com"], [0.0, 0.02, 0.1])


def _counts(ds):
    return [ds[name].values.ravel().tolist() for name in SOLVER_COUNTS]


def test_a_layout_3_tile_joins_a_layout_4_one_with_its_solver_counts_minus_one(tmp_path):
    """Tiles of one grid, one of layout 3 (no solver counts): the combined file is of today's layout,
    the old tile's runs not counted (-1), the new tile's counts as stored; it opens and validates."""
    new = synthetic_dataset({"f": [10.0]}, counts=np.array([[[[[40, 6]]]]]))
    old = synthetic_dataset({"f": [20.0]}, version=3)
    new.to_netcdf(tmp_path / "new.h5")
    old.to_netcdf(tmp_path / "old.h5")
    out = combine([tmp_path / "old.h5", tmp_path / "new.h5"])
    assert out.attrs["layout_version"] == LAYOUT_VERSION and list(out["f"].values) == [10.0, 20.0]
    assert _counts(out) == [[40, -1], [6, -1]]
    assert all(out[name].dtype == np.int64 for name in SOLVER_COUNTS)
    assert "not counted" in out["solver_iterations"].attrs["description"]
    write(out, tmp_path / "combined.h5")
    ((_, back),) = open_members(tmp_path / "combined.h5")
    assert _counts(back) == [[40, -1], [6, -1]]
    # only old tiles: the combined file is still of today's layout, every run not counted
    old.sel(f=[20.0]).to_netcdf(tmp_path / "old_only.h5")
    assert _counts(combine([tmp_path / "old_only.h5"])) == [[-1], [-1]]


def test_an_identical_overlap_across_layouts_keeps_the_counted_runs(tmp_path):
    """--allow-identical-overlap: the same runs in a layout-3 file (not counted) and a layout-4 one
    are identical; the combined file keeps the counts that were counted.  Counts that differ where both
    were counted are refused."""
    synthetic_dataset({"dt": [1e-3, 5e-4]}, version=3).to_netcdf(tmp_path / "old.h5")
    synthetic_dataset({"dt": [1e-3, 5e-4]}).to_netcdf(tmp_path / "new.h5")
    paths = [tmp_path / "old.h5", tmp_path / "new.h5"]
    counted = synthetic_dataset({"dt": [1e-3, 5e-4]}).sortby("dt")  # the union grid's dt ascend
    assert _counts(combine(paths, allow_identical_overlap=True)) == _counts(counted) == [[11, 1], [2, 1]]
    other = synthetic_dataset({"dt": [1e-3, 5e-4]}, counts=np.array([[[[[1, 1], [99, 9]]]]]))
    other.to_netcdf(tmp_path / "other.h5")
    with pytest.raises(CombineError, match="solver_iterations of the runs it shares with .*new.h5 differs"):
        combine([tmp_path / "new.h5", tmp_path / "other.h5"], allow_identical_overlap=True)


def test_members_of_different_layouts_and_grids_stack_with_counts_minus_one(tmp_path):
    """Stacked along scene: a layout-3 member (not counted) and a layout-4 member; grid points a member
    does not have are -1 too, and each member reads back with integer counts."""
    synthetic_dataset({"f": [10.0]}, version=3).to_netcdf(tmp_path / "top.h5")
    free = synthetic_dataset({"f": [10.0, 20.0]}, scene="free_symmetric", counts=np.array([[[[[5, 2]]], [[[7, 3]]]]]))
    free.to_netcdf(tmp_path / "free.h5")
    out = combine([tmp_path / "top.h5", tmp_path / "free.h5"])
    assert list(out["scene"].values) == ["heavy_top", "free_symmetric"]
    assert out["solver_iterations"].dims[0] == "scene" and out["solver_iterations"].dtype == np.int64
    assert out["solver_iterations"].squeeze().values.tolist() == [[-1, -1], [5, 7]]
    assert out["solver_iterations_max"].squeeze().values.tolist() == [[-1, -1], [2, 3]]
    assert out["status"].squeeze().values.tolist() == [[0, -1], [0, 0]]
    write(out, tmp_path / "combined.h5")
    members = dict(open_members(tmp_path / "combined.h5"))
    assert _counts(members["heavy_top"]) == [[-1], [-1]]
    assert _counts(members["free_symmetric"]) == [[5, 7], [2, 3]]
    assert all(m[name].dtype == np.int64 for m in members.values() for name in SOLVER_COUNTS)
