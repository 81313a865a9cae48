"""The real engines as sweep methods (kernels/real/: real_mujoco_*, real_pybullet*).

- names: accepted by the selector and the grid check, refused in one line naming the extra when the
  engine's package is missing, refused for a driven body;
- ``integrate`` returns what kernels/batch.py's does, with gyrolab's own per-sample fields: against
  the reproductions the engine isolates bit for bit (MuJoCo; PyBullet's btRigidBody) the whole
  sample array agrees to rounding;
- the divergence rule: MuJoCo's reset after mjWARN_BADQACC is status 1 at the step MuJoCo took it;
  energy past the threshold is status 2, at the same sample as the reproduction;
- provenance: the engine and its version in the file;
- end to end (slow): the issue's command writes one file that gyrolab-verdict and gyrolab-plot read.

Skipped with a reason where the engine package does not import (``pip install '.[engines]'``).
"""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

from gyrolab.kernels import real
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import FIELDS, STATUS_ENERGY, STATUS_NONFINITE, STATUS_OK
from gyrolab.kernels.registry import METHODS, get_method, select_methods
from gyrolab.kernels.scenes import build_scene

from helpers import command, environment, gyrolab

needs_mujoco = pytest.mark.engine("real_mujoco_euler")
needs_pybullet = pytest.mark.engine("real_pybullet")
REPRODUCTION = {
    "real_mujoco_euler": "mujoco_euler",
    "real_mujoco_implicitfast": "mujoco_implicitfast",
    "real_mujoco_implicit": "mujoco_implicit",
    "real_mujoco_rk4": "mujoco_rk4",
    "real_pybullet_maximal": "bullet_implicit_body",
}


def grid_of(*overrides):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=list(overrides)))


def scene_inputs(name, f=5.0, theta0=30.0, **options):
    sc = build_scene(name, f, theta0, **options)
    return np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0])


# ---------------------------------------------------------------- names


def test_real_names_are_not_registered_methods():
    """Every registry-parametrised test assumes a numba step: the real engines stay out of METHODS."""
    assert not set(real.NAMES) & set(METHODS)
    assert all(name.startswith(real.PREFIX) for name in real.NAMES)


def test_selector_real_is_the_engines_that_import_here(monkeypatch):
    """'real' selects the engines package_missing passes, in kernels/real's order.  package_missing is faked
    here: the real one imports every engine package (~0.1 GB held by this test worker afterwards); the
    sweep tests below select real engines through the real one."""
    loads = set(real.NAMES[::2])
    monkeypatch.setattr(real, "package_missing", lambda name: None if name in loads else f"{name} does not load")
    assert real.available() == [name for name in real.NAMES if name in loads] != []
    assert select_methods(["real"]) == real.available()
    assert select_methods(["real", "rk4"]) == real.available() + ["rk4"]


def test_unknown_real_name_is_one_line():
    with pytest.raises(ValueError, match="unknown real engine 'real_nope'") as err:
        select_methods(["real_nope"])
    assert "\n" not in str(err.value)


def test_missing_engine_package_is_refused_naming_the_extra(monkeypatch):
    """A name whose package does not import is refused at the selector (the grid check, before any work),
    by get_method and by integrate, in one line that names the extra."""
    monkeypatch.setitem(real.PACKAGES, "real_pybullet", "no_such_engine_package_here")
    monkeypatch.delitem(real._LOADED, "real_pybullet", raising=False)
    asks = real.package_missing  # the others load (not asked: that imports every engine into this worker)
    monkeypatch.setattr(real, "package_missing", lambda name: asks(name) if name == "real_pybullet" else None)
    for call in (
        lambda: select_methods(["real_pybullet"]),
        lambda: get_method("real_pybullet"),
        lambda: integrate("real_pybullet", *scene_inputs("free_asymmetric"), 1e-3, 1, 2),
    ):
        with pytest.raises(ValueError, match=r"pip install '\.\[engines\]'") as err:
            call()
        assert "\n" not in str(err.value) and "real_pybullet" in str(err.value)
    assert "real_pybullet" not in select_methods(["real"])


@needs_mujoco
def test_grid_check_refuses_a_missing_engine_before_any_work(monkeypatch):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import ConfigError, register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    monkeypatch.setitem(real.PACKAGES, "real_mujoco_rk4", "no_such_engine_package_here")
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=["sweep.method=[rk4,real_mujoco_rk4]", "scene=free_asymmetric"])
    with pytest.raises(ConfigError, match=r"sweep\.method=real_mujoco_rk4: .*pip install '\.\[engines\]'"):
        build_grid(cfg)


@pytest.mark.slow
@needs_mujoco
def test_grid_takes_real_engines_and_the_selector():
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs
    from gyrolab.runner.execute import warm_up_paths
    from gyrolab.runner.grid import build_grid

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=["sweep.method=[real,rk4]", "scene=free_asymmetric"])
    grid = build_grid(cfg)
    assert list(grid.methods) == real.available() + ["rk4"]
    assert warm_up_paths(grid) == [("rk4", "runs")]  # nothing for numba to compile for an engine


@needs_pybullet
def test_grid_check_refuses_a_body_the_engine_does_not_build():
    """PyBullet's rigid body on a pivot is not built: refused at the grid check in one line, before any work."""
    from gyrolab.runner.config import ConfigError

    with pytest.raises(ConfigError, match=r"sweep\.method=real_pybullet_maximal: .*free bodies only") as err:
        grid_of("sweep.method=[rk4,real_pybullet_maximal]", "scene=heavy_top")
    assert "\n" not in str(err.value)
    assert grid_of("sweep.method=[real_pybullet]", "scene=heavy_top").methods[0] == "real_pybullet"


@needs_mujoco
def test_driven_body_is_refused():
    body = np.array([Body(1e-4, 3e-4, 2e-4, 0.0, 0.0, 0.0, 1e-3, 0.0, 0.0, 1.0, 0.0, 1.0)])
    with pytest.raises(ValueError, match="driven body"):
        integrate("real_mujoco_rk4", body, np.array([[1.0, 0.0, 0.0]]), np.array([[1.0, 0, 0, 0]]), 1e-3, 1, 3)


# ---------------------------------------------------------------- integrate: the kernels' returns and fields


@needs_mujoco
@pytest.mark.parametrize("scene", ["free_asymmetric", "heavy_top", "heavy_body"])
@pytest.mark.parametrize("name", [n for n in REPRODUCTION if n.startswith("real_mujoco")])
def test_mujoco_backend_gives_the_reproductions_samples(name, scene):
    """Two runs (dt 1e-3 and 5e-4, strides 5 and 10) of 200 samples: same shapes and dtypes as the kernels,
    sample 0 the same bits, every field within 1e-10 of its scale (MuJoCo computes in the world frame,
    gyrolab in the body frame: rounding only).  Measured max ~2e-15."""
    options = {"omega1": 4.0, "omega2": -3.0} if scene == "heavy_body" else {}
    B, W, Q = scene_inputs(scene, **options)
    B, W, Q = np.repeat(B, 2, 0), np.repeat(W, 2, 0), np.repeat(Q, 2, 0)
    dt, stride = np.array([1e-3, 5e-4]), np.array([5, 10])
    got = integrate(name, B, W, Q, dt, stride, 200)
    want = integrate(REPRODUCTION[name], B, W, Q, dt, stride, 200)
    for g, w in zip(got, want):
        assert g.shape == w.shape and g.dtype == w.dtype
    out, status, n_steps = got
    assert np.array_equal(out[:, 0], want[0][:, 0])
    assert np.array_equal(status, want[1]) and np.array_equal(n_steps, want[2]) and (status == STATUS_OK).all()
    scale = np.abs(want[0]).reshape(2, -1, len(FIELDS)).max(axis=1, keepdims=True)
    assert np.max(np.abs(out - want[0]) / scale) < 1e-10


@needs_pybullet
def test_pybullet_rigid_body_gives_bullet_implicit_body():
    """PyBullet's btRigidBody (useMaximalCoordinates) runs BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY, damping 0:
    the reproduction's samples to 1e-9 over 2000 steps of the tennis racket (measured 7.5e-14)."""
    B, W, Q = scene_inputs("free_asymmetric")
    out, status, n_steps = integrate("real_pybullet_maximal", B, W, Q, 1e-4, 10, 201)
    want, _, _ = integrate("bullet_implicit_body", B, W, Q, 1e-4, 10, 201)
    assert status[0] == STATUS_OK and n_steps[0] == 2000
    assert np.max(np.abs(out[0, :, 3:6] - want[0, :, 3:6])) / np.abs(W).max() < 1e-9


@needs_pybullet
def test_pybullet_default_damps_a_free_body():
    """PyBullet's default body (btMultiBody) damps ω by −(k + k|ω|) ω with k = 0.04 as shipped: the energy of
    a free body falls (real_pybullet), where the rigid body (no damping) keeps it to 1e-6."""
    B, W, Q = scene_inputs("free_asymmetric", f=1.0)
    out, status, _ = integrate("real_pybullet", B, W, Q, 1e-3, 100, 11)
    kept, _, _ = integrate("real_pybullet_maximal", B, W, Q, 1e-3, 100, 11)
    e = out[0, :, FIELDS.index("energy")]
    assert status[0] == STATUS_OK and e[-1] < 0.95 * e[0]
    k = kept[0, :, FIELDS.index("energy")]
    assert abs(k[-1] - k[0]) < 1e-6 * k[0]


@needs_pybullet
def test_pybullet_default_caps_each_lab_component_of_omega_at_100():
    """btMultiBody's m_maxCoordinateVelocity = 100 (as shipped): a symmetric body spun at 150 rad/s about its
    axis (upright, so lab and body components agree) comes out of the first step at exactly 100 rad/s; the
    rigid body (maximal coordinates) keeps 150."""
    B = np.array([Body(1e-4, 1e-4, 2e-4, 0.0)])
    W, Q = np.array([[0.0, 0.0, 150.0]]), np.array([[1.0, 0.0, 0.0, 0.0]])
    out, status, _ = integrate("real_pybullet", B, W, Q, 1e-4, 1, 2)
    assert status[0] == STATUS_OK and out[0, 1, FIELDS.index("omega_3")] == 100.0
    kept, _, _ = integrate("real_pybullet_maximal", B, W, Q, 1e-4, 1, 2)
    assert kept[0, 1, FIELDS.index("omega_3")] == 150.0


@needs_pybullet
def test_pybullet_refusals_are_one_line():
    """A pivot on the rigid-body type and a centre of mass off the principal axes are not built: one line."""
    for name, scene, options in (
        ("real_pybullet_maximal", "heavy_top", {}),
        ("real_pybullet", "heavy_body", {"omega1": 4.0, "omega2": -3.0}),
    ):
        with pytest.raises(ValueError) as err:
            integrate(name, *scene_inputs(scene, **options), 1e-3, 1, 3)
        assert "\n" not in str(err.value) and name in str(err.value)


# ---------------------------------------------------------------- divergence


@needs_mujoco
def test_mujoco_reset_is_status_1_at_the_step_mujoco_took_it():
    """The write-up's 50 Hz top with MuJoCo's Euler at dt = 1e-3 (tests/test_engines.py: MuJoCo resets at
    step 467): with the energy rule out of the way (threshold 1e30) the run is status 1, n_steps = 467 (the
    steps completed before the reset), the sample holding the reset and every later one NaN."""
    B, W, Q = scene_inputs("heavy_top", f=50.0, theta0=45.0, M=1.0, r=0.05, l=0.1, g=10.0)
    out, status, n_steps = integrate("real_mujoco_euler", B, W, Q, 1e-3, 10, 101, threshold=1e30)
    assert status[0] == STATUS_NONFINITE and n_steps[0] == 467
    assert np.isfinite(out[0, :47]).all() and np.isnan(out[0, 47:]).all()


@needs_mujoco
def test_energy_rule_matches_the_reproduction():
    """With the default threshold the same run stops on energy (status 2) at the same sample as mujoco_euler."""
    B, W, Q = scene_inputs("heavy_top", f=50.0, theta0=45.0, M=1.0, r=0.05, l=0.1, g=10.0)
    out, status, n_steps = integrate("real_mujoco_euler", B, W, Q, 1e-3, 10, 101)
    want, w_status, w_steps = integrate("mujoco_euler", B, W, Q, 1e-3, 10, 101)
    assert status[0] == w_status[0] == STATUS_ENERGY and n_steps[0] == w_steps[0] < 467
    k = n_steps[0] // 10
    assert np.isnan(out[0, k + 1 :]).all() and np.isfinite(out[0, : k + 1]).all()


# ---------------------------------------------------------------- provenance


@needs_mujoco
def test_engine_versions_in_provenance():
    from importlib.metadata import version

    from gyrolab.runner.provenance import engine_versions

    assert engine_versions("sweep:\n  method: [rk4, lie_poisson]\n") == {}
    got = engine_versions("sweep:\n  method: [real_mujoco_rk4, rk4, real_mujoco_euler]\n")
    assert got == {"engine_versions": f"mujoco {version('mujoco')}"}


# ---------------------------------------------------------------- end to end


@needs_mujoco
@needs_pybullet
@pytest.mark.slow
def test_sweep_with_real_engines_reads_everywhere(tmp_path):
    """The issue's command at a small size: one file holding the real engines and their reproductions side by
    side (the engine versions in its attrs); gyrolab-verdict and gyrolab-plot standard read it."""

    methods = "real_mujoco_implicitfast,mujoco_implicitfast,real_pybullet,bullet_implicit_body,lie_poisson4"
    res = gyrolab(
        f"sweep.method=[{methods}]",
        "scene=free_asymmetric",
        "sweep.f=[1,10]",
        "sweep.dt=[1e-3,1e-4]",
        "sweep.t_end=0.5",
        "output.every=1e-2",
        "output.figures=false",
        f"hydra.run.dir={tmp_path}",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    path = tmp_path / "results.h5"
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        assert list(ds.integrator.values) == methods.split(",")
        assert ds.attrs["engine_versions"].startswith("mujoco ") and "pybullet " in ds.attrs["engine_versions"]
        assert (ds.status == 0).all()
        a = ds.omega.sel(integrator="real_mujoco_implicitfast")
        b = ds.omega.sel(integrator="mujoco_implicitfast")
        scale = 2 * math.pi * 10
        # the racket's flips amplify rounding (MuJoCo's world frame against gyrolab's body frame: 1e-17 a step)
        assert float(abs(a - b).isel(time=slice(0, 11)).max()) < 1e-12 * scale  # t <= 0.1 s, before any flip
        assert float(abs(a - b).max()) < 1e-5 * scale  # measured 1.9e-7 rad/s at dt = 1e-3, f = 10 Hz
    verdict = subprocess.run(
        command("gyrolab-verdict", "gyrolab.analysis.verdicts.verdict") + [str(path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=environment(),
    )
    assert verdict.returncode == 0, verdict.stderr
    assert "real_pybullet" in verdict.stdout and "bullet_implicit_body" in verdict.stdout
    plot = subprocess.run(
        command("gyrolab-plot", "gyrolab.analysis.figures.cli") + ["standard", str(path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=environment(),
    )
    assert plot.returncode == 0, plot.stderr
    assert len(list((tmp_path / "figures").glob("*.png"))) >= 3


# ---------------------------------------------------------------- the conformance table


@pytest.mark.slow
@needs_mujoco
@needs_pybullet
def test_conformance_rows_at_a_short_length(tmp_path):
    """python -m gyrolab.kernels.real.conformance at 200 steps: the isolated updates agree to 1e-12 on the
    tumbling box and the top (no amplification that early), PyBullet's default body is not
    bullet_implicit_body (it differs from step 1), and the table and its JSON have a row per (case, dt, pair)
    of every engine that loads; the rows not run are the free-body-only engines' (PyBullet's rigid body,
    jax-md, ...) on a pivot.  Run as the command, in a subprocess: it loads every engine package (~0.5 GB),
    which this test worker then does not hold for the rest of the suite."""
    from gyrolab.kernels.real import conformance  # the module only: it imports no engine

    out = tmp_path / "conformance.md"
    run = subprocess.run(
        [sys.executable, "-m", "gyrolab.kernels.real.conformance", "--steps", "200", "--out", str(out)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=environment(),
        timeout=900,  # 74 s in CI on a loaded machine
    )
    assert run.returncode == 0, run.stderr
    doc = json.loads(out.with_suffix(".json").read_text())
    assert doc["steps"] == 200
    loaded = {p["engine"] for p in doc["pairs"] if doc["engines"][real.PACKAGES[p["engine"]]] is not None}
    for package, found in doc["engines"].items():  # the installed version of every engine that loads
        assert found is None or found[0].isdigit(), (package, found)
    assert {"real_mujoco_euler", "real_pybullet"} <= loaded
    rows = doc["rows"]
    assert [p["engine"] for p in doc["pairs"]] == [engine for _, engine, _ in conformance.PAIRS]
    assert {r["case"] for r in rows} == set(conformance.cases())
    n_pairs = sum(p["engine"] in loaded for p in doc["pairs"])
    assert len(rows) == len(conformance.cases()) * len(conformance.DTS) * n_pairs
    for r in rows:
        if "note" in r:  # unbuilt pivots (PyBullet); Basilisk, Newton, jax-md, LAMMPS: free bodies only (their tests)
            engines = ("real_pybullet", "real_basilisk", "real_newton", "real_jaxmd", "real_lammps")
            assert r["engine"].startswith(engines) and r["case"] != "tumbling box"
            continue
        isolated = r["engine"].startswith("real_mujoco") or r["engine"] == "real_pybullet_maximal"
        if isolated and r["case"] in ("tumbling box", "50 Hz top", "heavy body, c off-axis"):
            assert r["dw"] < 1e-12 and r["dq"] < 1e-12, r
        if r["engine"] == "real_pybullet" and r["damping"] is None:
            assert r["dw"] > 1e-3 and r["first_over"] == 1, r
    table = [line for line in out.read_text().splitlines() if line.startswith("|")]
    assert len(table) == len(rows) + 2  # header, rule, a line per row


@needs_pybullet
@pytest.mark.parametrize("dt", [1e-3, 5e-4])
def test_pybullet_box_spun_about_its_intermediate_axis(dt):
    """The issue's PyBullet case: a 0.1 x 0.2 x 0.4 m box (1 kg) spun at 10 rad/s about its intermediate axis,
    here with ω1 = 1e-3 ω3 to seed the flip, 10 s.  With the angular damping set to 0 PyBullet's default body
    keeps flipping and is bullet_explicit's update (ω3 changes sign as often; ω within 1e-6 relative); as
    shipped (damping 0.04) |ω| decays (measured 10 -> 1.55 rad/s at dt = 1e-3) and the flips stop after
    the first.  The issue's "|ω| settles at 10.06 rad/s about the intermediate axis" is not reproduced by
    this set-up."""
    from gyrolab.kernels.real import conformance

    box = Body(*(np.array([0.2**2 + 0.4**2, 0.1**2 + 0.2**2, 0.1**2 + 0.4**2]) / 12), 0.0)  # e3 intermediate
    w0, q0 = (1e-2, 0.0, 10.0), (1.0, 0.0, 0.0, 0.0)
    n = int(round(10.0 / dt))
    undamped, _ = conformance.engine_trajectory("real_pybullet", box, w0, q0, dt, n, 0.0)
    explicit, _ = conformance.reproduction_trajectory("bullet_explicit", box, w0, q0, dt, n)

    def flips(W):
        return int(np.sum(np.diff(np.sign(W[:, 2])) != 0))

    assert flips(undamped) == flips(explicit) >= 3
    assert np.max(np.linalg.norm(undamped - explicit, axis=1)) < 1e-6 * 10.0
    shipped, _ = conformance.engine_trajectory("real_pybullet", box, w0, q0, dt, n, None)
    assert flips(shipped) <= 1 and np.linalg.norm(shipped[-1]) < 0.5 * 10.0
