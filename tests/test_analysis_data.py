"""Small stored results files for the analysis tests, built without the runner.

``build_dataset`` calls ``gyrolab.simulate`` once per grid point and stacks the
runs into a Dataset with the SPEC §4 dims (method, f, theta0, dt, time, xyz)
and file attrs (scene, scene_<option>), then writes it with h5netcdf, so the
analysis reads exactly what it reads from the runner's files.
"""
import numpy as np
import pytest
import xarray as xr

import gyrolab
from gyrolab.runner.dataset import COORD_ATTRS

GRID = {"method": ["seed_next", "seed_prev", "rk4"], "f": [10.0, 50.0], "theta0": [45.0], "dt": [1e-3, 5e-4]}


def build_dataset(path, grid=None, scene="heavy_top", t_end=1.0, every=1e-3, threshold=10.0, **options):
    """Write a results file of ``grid`` (dict of lists) to ``path``; return the Dataset."""
    grid = {**GRID, **(grid or {})}
    runs = []
    for m in grid["method"]:
        for f in grid["f"]:
            for th in grid["theta0"]:
                for dt in grid["dt"]:
                    ds = gyrolab.simulate(scene=scene, method=m, f=f, theta0=th, dt=dt, t_end=t_end, every=every,
                                          divergence_threshold=threshold, **options)
                    runs.append(ds.drop_attrs() if hasattr(ds, "drop_attrs") else ds.assign_attrs({}))
    shape = [len(grid[k]) for k in ("method", "f", "theta0", "dt")]
    stacked = xr.concat(runs, dim="run")
    data = {}
    for name, var in stacked.data_vars.items():
        values = var.values.reshape(shape + list(var.shape[1:]))
        data[name] = (("method", "f", "theta0", "dt") + var.dims[1:], values, var.attrs)
    coords = {k: (k, np.array(grid[k]), COORD_ATTRS[k]) for k in ("method", "f", "theta0", "dt")}
    coords["time"] = ("time", stacked.time.values, COORD_ATTRS["time"])
    coords["xyz"] = ("xyz", np.array(["x", "y", "z"]), COORD_ATTRS["xyz"])
    from gyrolab.kernels.scenes import get_scene

    opts = {**get_scene(scene).OPTIONS, **options}
    attrs = {"scene": scene, **{f"scene_{k}": v for k, v in opts.items()}, "t_end": t_end, "every": every,
             "divergence_threshold": threshold, "config": "built by tests/test_analysis_data.py"}
    out = xr.Dataset(data, coords=coords, attrs=attrs)
    out.to_netcdf(path, engine="h5netcdf")
    return out


@pytest.fixture(scope="session")
def results_file(tmp_path_factory):
    """3 methods x f 10, 50 Hz x θ0 45° x dt 1e-3, 5e-4 s, heavy top released, 1 s."""
    path = tmp_path_factory.mktemp("analysis") / "results.h5"
    build_dataset(path)
    return path


@pytest.fixture(scope="session")
def single_run_file(tmp_path_factory):
    """One method, one f, one dt: the smallest grid a figure must survive."""
    path = tmp_path_factory.mktemp("analysis1") / "results.h5"
    build_dataset(path, {"method": ["lie_poisson"], "f": [20.0], "dt": [1e-3]}, t_end=0.5)
    return path
