"""gyrolab.simulate: one run through the same batch engine, as an xarray Dataset."""

import time

import numpy as np

from ..kernels.batch import DEFAULT_DIVERGENCE_THRESHOLD, integrate, sample_schedule
from ..kernels.registry import get_method
from ..kernels.scenes import build_scene, get_scene
from ..results.layout import scene_attrs, solver_variables, to_dataset


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
    options (for heavy_top: M, r, l, g, init, phidot0).  Variables as in a
    results file (gyrolab/results/layout.py): axis (lab), theta, phi (rad), energy (J),
    L (lab), Lz, L3 (kg m²/s), omega (body, rad/s); status, n_steps,
    wall_time (s), solver_iterations, solver_iterations_max; the run's body, omega0 and q0.
    """
    get_method(method)
    sc = build_scene(scene, f, theta0, **scene_options)
    stride, n_samples = sample_schedule(dt, every, t_end)
    iterations = np.zeros((1, 2), dtype=np.int64)
    start = time.perf_counter()
    samples, status, n_steps = integrate(
        method,
        np.array([sc.body]),
        np.array([sc.omega0]),
        np.array([sc.q0]),
        dt,
        stride,
        n_samples,
        divergence_threshold,
        iterations=iterations,
    )
    wall = time.perf_counter() - start
    declared = get_scene(scene)
    attrs = scene_attrs(scene, scene_options, declared.CONSERVED, declared.CLOSED_FORM)
    attrs.update(method=method, f=f, theta0=theta0, dt=dt)
    return to_dataset(
        samples[0],
        {"status": status[0], "n_steps": n_steps[0], "wall_time": wall, **solver_variables(iterations[0])},
        {"time": np.arange(n_samples) * every},
        inputs={"body": sc.body, "omega0": sc.omega0, "q0": sc.q0},
        attrs=attrs,
    )
