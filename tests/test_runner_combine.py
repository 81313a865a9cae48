"""gyrolab-combine: tiles of one grid join along its axes; different scenes/options stack."""

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

from gyrolab.runner.app import file_attrs
from gyrolab.runner.combine import CombineError, combine, main
from gyrolab.runner.config import config_hash, register_configs
from gyrolab.runner.execute import run_chunk
from gyrolab.runner.grid import build_grid
from gyrolab.runner.store import write_results

register_configs()
BASE = ["sweep.method=[seed_next]", "sweep.theta0=[45]", "sweep.dt=[1e-3]", "sweep.t_end=0.02", "output.every=1e-3"]


def make_file(path, *overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[*BASE, *overrides])
    grid = build_grid(cfg)
    write_results(path, grid, [run_chunk(grid, np.arange(grid.n_runs), 1)], file_attrs(cfg, grid, 1, config_hash(cfg)))
    return path


def strip(ds):
    return ds.drop_vars([v for v in ds.variables if str(v).startswith("source_")] + ["wall_time"])


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
