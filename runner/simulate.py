"""gyrolab.simulate: one run through the same batch engine, as an xarray Dataset."""
import time

import numpy as np
import xarray as xr

from ..kernels.batch import DEFAULT_DIVERGENCE_THRESHOLD, integrate, sample_schedule
from ..kernels.registry import get_method
from ..kernels.scenes import build_scene
from .dataset import COORD_ATTRS, VARIABLE_ATTRS, sample_variables


def simulate(
    scene="heavy_top",
    method="seed_next",
    f=10.0,
    theta0=45.0,
    dt=1e-4,
    t_end=10.0,
    every=1e-3,
    divergence_threshold=DEFAULT_DIVERGENCE_THRESHOLD,
    **scene_options,
):
    """Integrate one run and return its samples as a Dataset with dims (time, xyz).

    f in Hz (ω3 = 2πf), theta0 in degrees, dt, t_end and every (sample
    interval, a multiple of dt) in seconds.  ``scene_options`` are the scene's
    options (for heavy_top: M, r, l, g, init, phidot0).  Variables: axis (lab),
    theta, phi (rad), energy (J), Lz, L3, omega (body, rad/s); status,
    n_steps, wall_time (s).
    """
    get_method(method)
    sc = build_scene(scene, f, theta0, **scene_options)
    stride, n_samples = sample_schedule(dt, every, t_end)
    start = time.perf_counter()
    samples, status, n_steps = integrate(
        method, np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0]), dt, stride, n_samples,
        divergence_threshold,
    )
    wall = time.perf_counter() - start
    data = {}
    for name, values in sample_variables(samples[0]).items():
        dims = ("time", "xyz") if values.ndim == 2 else ("time",)
        data[name] = (dims, values, VARIABLE_ATTRS[name])
    data["status"] = ((), status[0], VARIABLE_ATTRS["status"])
    data["n_steps"] = ((), n_steps[0], VARIABLE_ATTRS["n_steps"])
    data["wall_time"] = ((), wall, VARIABLE_ATTRS["wall_time"])
    coords = {
        "time": ("time", np.arange(n_samples) * every, COORD_ATTRS["time"]),
        "xyz": ("xyz", np.array(["x", "y", "z"]), COORD_ATTRS["xyz"]),
    }
    attrs = {"scene": scene, "method": method, "f": f, "theta0": theta0, "dt": dt,
             **{f"scene_{k}": v for k, v in scene_options.items()}}
    return xr.Dataset(data, coords=coords, attrs=attrs)
