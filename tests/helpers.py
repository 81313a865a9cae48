"""Helpers every test module may import (``from helpers import ...``); fixtures live in conftest.py.

- the CLI in subprocesses: ``gyrolab(...)``, ``start(...)``, the tiny grid
  ``TINY`` and chunking ``SLOW``, ``data(path)`` (a file without its volatile
  attrs), ``tiny_reference(root)``;
- ``build_dataset(path, grid, scene, ...)``: a small results file made
  through the batch kernels and gyrolab/results/layout.py, without the runner;
- one method's steps: ``DRIVEN_BODY``, ``random_states(n, seed)``, ``step_run(name, ...)``;
- the order tests' final states: ``final_samples``, ``state_error``, ``final_with_error``.
"""

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr

from gyrolab.kernels.batch import integrate, sample_schedule
from gyrolab.kernels.body import Body
from gyrolab.kernels.reference import dop853_with_error
from gyrolab.kernels.registry import get_method, stepper
from gyrolab.kernels.scenes import build_scene, get_scene
from gyrolab.results.identity import VOLATILE_ATTRS
from gyrolab.results.layout import GRID_DIMS, scene_attrs, solver_variables, to_dataset

BIN = Path(sys.executable).parent
TINY = [
    "sweep.method=[seed_next,lie_poisson]",
    "sweep.f=[10,50]",
    "sweep.theta0=[30,45]",
    "sweep.dt=[1e-3,1e-4]",
    "sweep.t_end=0.1",
    "output.every=1e-3",
    "output.figures=false",
]
SLOW = ["runner.chunk_seconds=1e-6"]  # chunks of `threads` runs: many chunks to interrupt


def command(name, module):
    exe = BIN / name
    return [str(exe)] if exe.exists() else [sys.executable, "-m", module]


def environment(**extra):
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "GYROLAB_TEST_CHUNK_DELAY")}
    env.update({k: str(v) for k, v in extra.items()})
    return env


def gyrolab(*args, cwd, env=None, timeout=300):
    return subprocess.run(
        command("gyrolab", "gyrolab.runner.app") + list(args),
        cwd=cwd,
        capture_output=True,
        text=True,
        env=env or environment(),
        timeout=timeout,
    )


def _default_signals():
    """In the child: default SIGINT, so the tests that send it see Python's KeyboardInterrupt even when
    the test run itself was started with SIGINT ignored (a background job of a shell without job
    control); Python installs its handler only for a signal not ignored at startup."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(*args, cwd, **env):
    return subprocess.Popen(
        command("gyrolab", "gyrolab.runner.app") + list(args),
        cwd=cwd,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=environment(**env),
        preexec_fn=_default_signals,
    )


def wait_for(predicate, proc, timeout=120):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert proc.poll() is None, f"finished before the test could interrupt it: {proc.communicate()}"
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def chunk_count(run_dir):
    return len(list((Path(run_dir) / "results.h5.partial").glob("chunk-*.npz")))


def data(path):
    """The file's data without what legitimately differs between runs (timings, provenance)."""
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        ds = ds.load()
    return (
        ds.drop_vars("wall_time")
        .drop_attrs(deep=False)
        .assign_attrs({k: v for k, v in ds.attrs.items() if k not in VOLATILE_ATTRS})
    )


def assert_ok(result):
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr


def tiny_reference(root):
    """Run TINY (+ SLOW chunking) uninterrupted on the local backend, all threads, in ``root``;
    returns the results file."""
    result = gyrolab(*TINY, *SLOW, f"hydra.run.dir={root / 'run'}", cwd=root)
    assert_ok(result)
    return root / "run" / "results.h5"


def method_params(known_failures=None):
    """Every registered method as a pytest param; those in ``known_failures`` ({name: reason}) marked
    strict xfail, so the recorded failure must keep failing (a method that starts passing is news)."""
    import pytest

    from gyrolab.kernels.registry import METHODS

    known_failures = dict(known_failures or {})
    return [
        pytest.param(m, marks=pytest.mark.xfail(strict=True, reason=known_failures[m])) if m in known_failures else m
        for m in METHODS
    ]


def own_methods(known_failures=None):
    """``method_params`` of gyrolab's own schemes: every registered method but the reproductions of
    engine updates (``REPRODUCES``), which test_engines.py judges by conformance with the engine."""
    from gyrolab.kernels.registry import METHODS

    return [
        p
        for p in method_params(known_failures)
        if not getattr(METHODS[p if isinstance(p, str) else p.values[0]], "REPRODUCES", "")
    ]


# The explicit Euler control is in the registry to give the verdicts a known "growing" answer; every
# accuracy bound fails for it by design (energy e-folds at c^2 dt, c = (1 - I3/I1) w3).
CONTROL_FAILURES = {"explicit_euler": "control method: explicit Euler's energy grows exponentially (rate c^2 dt)"}


# Second-order methods whose error constant on the free disc (f = 10 Hz, θ0 = 30°) is above 1, so they miss
# the (ω3 dt)^2 bar (lie_poisson has the exact symmetric free flow): measured error / (ω3 dt)^2 at dt = 1e-3,
# 5e-4, 2.5e-4, constant, so second order.
FREE_DISC_FAILURES = {
    "no_squish": "NO_SQUISH splits the symmetric free rotor too: error 2.1 (ω3 dt)^2, above the (ω3 dt)^2 bar",
    "lgvi": "LGVI's error on the free disc is 1.06 (ω3 dt)^2 (4.2e-3 at dt = 1e-3): 6 % above the bar",
}
# Its (q, p) form rounds more than the (ω, q) splittings: a rounding-level bar, missed by a little.
NO_SQUISH_ROUNDING = {
    "no_squish": "the (q, p) rotations and the p <-> ω conversions round more than lie_poisson's (ω, q) "
    "form: |L| moves 6e-14 in 4000 free steps (bar 5e-14), the sleeping top's ω3 6e-13 in 5e4 steps "
    "(bar 1e-14; LAMMPS's own p-carrying loop, without renormalising, 1.1e-13)"
}

# The steady-precession bar (θ within 1e-6 rad for 2 s at dt = 1e-4) is met by the second-order splittings
# because their free flow is exact for the symmetric top; these second-order methods integrate the fast
# spin itself and miss it (measured θ deviations for f = 23 fast, 50 slow, 50 fast).
STEADY_PRECESSION_FAILURES = {
    "lgvi": "LGVI integrates the 23-50 Hz spin with its own O(dt^2) error: θ off by 5.9e-6, 3.5e-6, 1.8e-6",
    "implicit_midpoint": "the midpoint rule's O(dt^2) error on the 23-50 Hz spin: θ off by 2.6e-4, 5.9e-5, 5.2e-4",
    "simo_wong": "Simo-Wong's midpoint rotation vector integrates the 23-50 Hz spin with its own O(dt^2) error: "
    "θ off by 2.9e-5, 2.0e-5, 7.8e-6",
}


GRID = {"integrator": ["seed_next", "seed_prev", "rk4"], "f": [10.0, 50.0], "theta0": [45.0], "dt": [1e-3, 5e-4]}


def final_samples(name, scene, dts, t_end):
    """(final samples (n, driver.N_FIELDS), status (n,)) of one scene integrated by method ``name`` to
    t_end (s) at each of the n steps ``dts``, in one batch, with the energy check off (threshold 1e9)."""
    n = len(dts)
    samples, status, _ = integrate(
        name,
        np.tile(scene.body, (n, 1)),
        np.tile(scene.omega0, (n, 1)),
        np.tile(scene.q0, (n, 1)),
        np.asarray(dts),
        np.rint(t_end / np.asarray(dts)).astype(np.int64),
        2,
        1e9,
    )
    return samples[:, -1, :], status


def state_error(final, reference, scene):
    """The order tests' error of final samples (..., driver.N_FIELDS) against a reference sample: the larger
    of the axis's largest component error and ω's (rad/s) over the scene's ω3, so relative."""
    final, reference = np.asarray(final), np.asarray(reference)
    return np.maximum(
        np.max(np.abs(final[..., :3] - reference[:3]), axis=-1),
        np.max(np.abs(final[..., 3:6] - reference[3:6]), axis=-1) / scene.omega0[2],
    )


def final_with_error(scene, t_end):
    """(the scene's sample at t_end (s) by DOP853 at rtol = atol = 1e-13, read-only; that sample's own error
    in state_error's measure, dop853_with_error's estimate |y(1e-13) − y(1e-12)|): an order fit leaves out
    the errors below it (classify.fit_order ``reference_error``), which measure the reference."""
    samples, estimate = dop853_with_error(scene, t_end, t_end, tol=1e-13)
    final = samples[-1]
    final.flags.writeable = False
    return final, float(state_error(estimate[-1], np.zeros_like(final), scene))


def build_dataset(path, grid=None, scene="heavy_top", t_end=1.0, every=1e-3, threshold=10.0, **options):
    """Write a results file of ``grid`` (dict of lists over GRID_DIMS) to ``path`` and return its Dataset."""
    out = make_dataset(grid, scene, t_end, every, threshold, **options)
    out.to_netcdf(path, engine="h5netcdf")
    return out


def make_dataset(grid=None, scene="heavy_top", t_end=1.0, every=1e-3, threshold=10.0, **options):
    """The results Dataset of ``grid`` (dict of lists over GRID_DIMS, defaults GRID) in memory: every
    run through the batch kernels, the Dataset through layout.to_dataset (what the runner stores)."""
    grid = {**GRID, **(grid or {})}
    shape = [len(grid[k]) for k in GRID_DIMS]
    scenes = [[build_scene(scene, f, th, **options) for th in grid["theta0"]] for f in grid["f"]]
    n_samples = sample_schedule(grid["dt"][0], every, t_end)[1]
    raw, status, n_steps = None, np.zeros(shape, np.int8), np.zeros(shape, np.int64)
    iterations = np.zeros(shape + [2], np.int64)
    for index in np.ndindex(*shape):
        m, jf, kt, ld = index
        sc, dt = scenes[jf][kt], grid["dt"][ld]
        stride = sample_schedule(dt, every, t_end)[0]
        counts = np.zeros((1, 2), np.int64)  # the kernel's: [total solver iterations, most in one step]
        samples, st, ns = integrate(
            grid["integrator"][m],
            np.array([sc.body]),
            np.array([sc.omega0]),
            np.array([sc.q0]),
            dt,
            stride,
            n_samples,
            threshold,
            iterations=counts,
        )
        if raw is None:
            raw = np.empty(shape + list(samples.shape[1:]))
        raw[index], status[index], n_steps[index], iterations[index] = samples[0], st[0], ns[0], counts[0]
    declared = get_scene(scene)
    attrs = scene_attrs(scene, {**declared.OPTIONS, **options}, declared.CONSERVED, declared.CLOSED_FORM)
    attrs.update(t_end=t_end, every=every, divergence_threshold=threshold, config="built by tests/helpers.py")
    inputs = {
        "body": [[s.body for s in row] for row in scenes],
        "omega0": [[s.omega0 for s in row] for row in scenes],
        "q0": [[s.q0 for s in row] for row in scenes],
    }
    coords = {k: np.array(grid[k]) for k in GRID_DIMS} | {"time": np.arange(n_samples) * every}
    # ~2 ns per step, as the batched kernels take: a positive wall time, so the cost axes have points to draw
    per_run = {"status": status, "n_steps": n_steps, "wall_time": n_steps * 2e-9, **solver_variables(iterations)}
    return to_dataset(raw, per_run, coords, inputs, attrs)


def synthetic_dataset(grid=None, scene="heavy_top", t_end=0.02, every=1e-3, counts=None, version=None, seed=0):
    """A results Dataset of ``grid`` (dict of lists over GRID_DIMS) that passes the reader's checks, with
    made-up samples and no kernel run (a test of the file layer compiles nothing): every run finished
    (status 0, its steps spanning t_end), solver counts ``counts`` (an array (*grid shape, 2) of
    [total, most in one step]; default distinct values per run).  ``version`` < 4: as that layout
    wrote it, without the solver counts (the grid dim stays ``integrator``: what readers see)."""
    from gyrolab.results.layout import RAW_PER_SAMPLE
    from gyrolab.results.migrate import SOLVER_COUNTS

    grid = {"integrator": ["m1"], "f": [10.0], "theta0": [45.0], "dt": [1e-3], **(grid or {})}
    shape = [len(grid[k]) for k in GRID_DIMS]
    n_samples = round(t_end / every) + 1
    raw = np.random.default_rng(seed).uniform(-1.0, 1.0, (*shape, n_samples, RAW_PER_SAMPLE))
    n_steps = np.broadcast_to(np.array([round(t_end / dt) for dt in grid["dt"]], np.int64), shape).copy()
    if counts is None:
        total = 1 + np.arange(np.prod(shape), dtype=np.int64).reshape(shape) * 10
        counts = np.stack([total, 1 + total // 10], axis=-1)
    per_run = {"status": np.zeros(shape, np.int8), "n_steps": n_steps, "wall_time": np.ones(shape)}
    per_run |= solver_variables(counts)
    scenes = [[build_scene(scene, f, th) for th in grid["theta0"]] for f in grid["f"]]
    inputs = {k: [[getattr(s, k) for s in row] for row in scenes] for k in ("body", "omega0", "q0")}
    declared = get_scene(scene)
    attrs = scene_attrs(scene, declared.OPTIONS, declared.CONSERVED, declared.CLOSED_FORM)
    attrs.update(t_end=t_end, every=every, divergence_threshold=10.0, config=f"scene:\n  name: {scene}\n")
    coords = {k: np.array(grid[k]) for k in GRID_DIMS} | {"time": np.arange(n_samples) * every}
    ds = to_dataset(raw, per_run, coords, inputs, attrs)
    if version is not None:
        ds = ds.drop_vars(SOLVER_COUNTS if version < 4 else []).assign_attrs(layout_version=version)
    return ds


# A small sweep (one method, one theta0 and dt, 20 samples) for make_file's overrides to extend.
FILE_BASE = [
    "sweep.method=[seed_next]",
    "sweep.theta0=[45]",
    "sweep.dt=[1e-3]",
    "sweep.t_end=0.02",
    "output.every=1e-3",
]


def make_file(path, *overrides):
    """Write the results file of FILE_BASE + ``overrides`` (Hydra overrides) to ``path`` through the
    runner's own grid, chunk and store (no subprocess); return ``path``."""
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import config_hash, register_configs
    from gyrolab.runner.execute import run_chunk
    from gyrolab.runner.grid import build_grid
    from gyrolab.runner.store import write_results
    from gyrolab.runner.sweep import file_attrs

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[*FILE_BASE, *overrides])
    grid = build_grid(cfg)
    write_results(path, grid, [run_chunk(grid, np.arange(grid.n_runs), 1)], file_attrs(cfg, grid, 1, config_hash(cfg)))
    return path


def experiment_scene(name):
    """The Scene the pinned experiment ``name`` runs (its single f and theta0, its scene options)."""
    from hydra import compose, initialize_config_module
    from omegaconf import OmegaConf

    from gyrolab.runner.config import register_configs

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[f"experiment={name}"])
    options = OmegaConf.to_container(cfg.scene, resolve=True)
    scene = options.pop("name")
    (f,), (theta0,) = cfg.sweep.f, cfg.sweep.theta0
    return build_scene(scene, float(f), float(theta0), **options)


# a heavy asymmetric body with its centre of mass off every axis and a drive: every torque path
DRIVEN_BODY = Body(0.02, 0.025, 0.008, 0.98, 0.29, 0.1, 0.3, -0.2, 0.75, 3.0, 0.0, 100.0)


def random_states(n, seed, dt_max=1e-2):
    """n (ω, q, t, dt): ω ~ 20 rad/s, q uniform on S³, t in [0, 10] s, dt in [1e-4, dt_max] s."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q = rng.normal(size=4)
        yield (
            tuple(rng.normal(scale=20.0, size=3)),
            tuple(q / np.linalg.norm(q)),
            float(rng.uniform(0.0, 10.0)),
            float(rng.uniform(1e-4, dt_max)),
        )


def step_run(name, w, q, dt, body, n):
    """Arrays (n + 1, 3) of ω (rad/s, body) and (n + 1, 4) of q of n steps of dt seconds of ``name``."""
    start, step_carried = stepper(get_method(name))  # a method's carried state threads through (a variant too)
    W, Q = [w], [q]
    c = start(w, q, body)
    for _ in range(n):
        w, q, c = step_carried(w, q, c, dt, body)
        W.append(w)
        Q.append(q)
    return np.array(W), np.array(Q)


def free_body_sweep(methods, tmp_path, f="[10]", dt="[1e-3]", t_end=0.2, every=1e-2):
    """``gyrolab`` on the tumbling box (scene free_asymmetric) with ``methods`` (a list of names), the
    Hydra lists ``f`` (Hz) and ``dt`` (s), ``t_end`` and ``every`` (s), no figures, run in ``tmp_path``
    (results.h5 there): what the real engines' tests sweep beside their reproductions.  Asserts that it
    exits 0 and stores the methods by their canonical names (a name with parameters given in double
    quotes, kernels/parameters.py), and returns the results Dataset, loaded."""
    import xarray as xr

    from gyrolab.kernels.registry import select_methods

    res = gyrolab(
        f"sweep.method=[{','.join(methods)}]",
        "scene=free_asymmetric",
        f"sweep.f={f}",
        f"sweep.dt={dt}",
        f"sweep.t_end={t_end}",
        f"output.every={every}",
        "output.figures=false",
        f"hydra.run.dir={tmp_path}",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    with xr.open_dataset(tmp_path / "results.h5", engine="h5netcdf") as ds:
        out = ds.load()
    assert list(out.integrator.values) == select_methods([m.strip('"') for m in methods])
    return out


def check_free_body_refusals(name, partner, degenerate, also=None):
    """What a free-body-only real engine ``name`` refuses, each in one line: a heavy body (no joint) and the
    ``degenerate`` body (kernels.body.Body: a moment the engine cannot take), by its backend, by ``integrate``
    (through ``also`` too, another mode of the same backend, when given) and by the grid check before any work
    (a sweep of ``partner`` and ``name`` on the heavy top); a driven body by ``integrate``."""
    import numpy as np
    import pytest
    from hydra import compose, initialize_config_module

    from gyrolab.kernels import real
    from gyrolab.kernels.batch import integrate
    from gyrolab.kernels.scenes import build_scene
    from gyrolab.runner.config import ConfigError, register_configs
    from gyrolab.runner.grid import build_grid

    top = build_scene("heavy_top", 5.0, 30.0)
    for body, match in ((top.body, "free bodies only"), (degenerate, "positive principal moments")):
        with pytest.raises(ValueError, match=match) as err:
            real.check_bodies(name, np.array([body]))
        assert "\n" not in str(err.value) and name in str(err.value)
        with pytest.raises(ValueError, match=match):
            integrate(also or name, np.array([body]), np.array([top.omega0]), np.array([top.q0]), 1e-3, 1, 2)
    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=[f"sweep.method=[{partner},{name}]", "scene=heavy_top"])
    with pytest.raises(ConfigError, match="free bodies only") as err:
        build_grid(cfg)
    assert "\n" not in str(err.value)
    driven = build_scene("free_asymmetric", 5.0, 30.0)
    body = np.array([driven.body])
    body[0, 6], body[0, 10], body[0, 11] = 1e-3, 0.0, 1.0  # tau1 on from t = 0 to 1 s
    with pytest.raises(ValueError, match="driving torque") as err:
        integrate(name, body, np.array([driven.omega0]), np.array([driven.q0]), 1e-3, 1, 2)
    assert "\n" not in str(err.value)


def block_path_args(sc):
    """integrate()'s arguments after the method for MIN_BLOCK_RUNS runs of Scene ``sc`` (ω0 scaled 0.5-1.5×
    across them), dt 1e-3 s, 11 samples 5 steps apart, threshold 10: the smallest batch on the block path."""
    from gyrolab.kernels.batch import MIN_BLOCK_RUNS

    n = MIN_BLOCK_RUNS
    omega0 = np.tile(sc.omega0, (n, 1)) * np.linspace(0.5, 1.5, n)[:, None]
    return np.tile(sc.body, (n, 1)), omega0, np.tile(sc.q0, (n, 1)), 1e-3, 5, 11, 10.0
