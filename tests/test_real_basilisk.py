"""Basilisk's spacecraft hub as a sweep method (kernels/real/basilisk_engine.py: real_basilisk_rk4).

- it is rk4_mrp: RK4 on (σ, ω) with the MRP shadow switch after the full step agrees with Basilisk's
  svIntegratorRK4 and HubEffector::modifyStates to rounding on a free asymmetric body, through shadow
  switches (σ_BN's convention: the MRP of gyrolab's body → lab q);
- refusals in one line: a heavy body (a hub has no pivot) and a dt that is not a whole number of
  nanoseconds (Basilisk's clock), both before any work at the grid check;
- end to end: a sweep of real_basilisk_rk4 beside rk4_mrp writes one results file that opens.

Skipped with a reason where Basilisk does not import (``pip install '.[engines]'``: bsk).
"""

import math

import numpy as np
import pytest

from gyrolab.kernels import real
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import STATUS_OK
from gyrolab.kernels.scenes import build_scene

from helpers import free_body_sweep

NAME = "real_basilisk_rk4"
pytestmark = pytest.mark.engine(NAME)
# The tumbling box of kernels/real/conformance.py: e3 the intermediate axis, |ω| ~ 140 rad/s
BOX = Body(1e-4, 3e-4, 2e-4, 0.0)
BOX_W0 = (0.5 * 2 * math.pi * 20, 0.3 * 2 * math.pi * 20, 2 * math.pi * 20)
TILT30 = (math.cos(math.radians(15.0)), math.sin(math.radians(15.0)), 0.0, 0.0)


def grid_of(*overrides):
    from hydra import compose, initialize_config_module

    from gyrolab.runner.config import register_configs
    from gyrolab.runner.grid import build_grid

    register_configs()
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=list(overrides)))


def test_registered_with_its_import_name():
    assert NAME in real.NAMES and real.PACKAGES[NAME] == "bsk" and real.IMPORT_NAMES["bsk"] == "Basilisk"
    assert real.package_missing(NAME) is None
    assert real.engine_version(NAME).startswith("bsk 2.")


def test_sigma_bn_is_the_mrp_of_q():
    """σ_BN maps N → B and q maps body → lab: the same attitude, so σ_BN is the MRP of q (|σ| ≤ 1 either sign of
    q), and the map back returns q (scalar ≥ 0)."""
    from gyrolab.kernels.real.basilisk_engine import mrp_from_quat, quat_from_mrp

    q = np.array([0.3, -0.5, 0.7, 0.4])
    q /= np.linalg.norm(q)
    for s in (1.0, -1.0):
        sigma = np.array(mrp_from_quat(s * q))
        assert np.linalg.norm(sigma) <= 1.0
        np.testing.assert_allclose(quat_from_mrp(sigma), q, rtol=0, atol=1e-15)


def test_matches_rk4_mrp_step_by_step_through_shadow_switches():
    """500 steps of dt = 1e-3 s on the tumbling box (|ω| ~ 140 rad/s: the attitude passes 180° about ten times, so
    Basilisk switches σ to its shadow set as often): ω and the orientation agree with rk4_mrp to 1e-12
    (measured 4.7e-13 / 5.7e-13 at 2000 steps; the conformance target is 1e-9)."""
    from gyrolab.kernels.real import conformance

    W, Q = conformance.engine_trajectory(NAME, BOX, BOX_W0, TILT30, 1e-3, 500, None)
    Wr, Qr = conformance.reproduction_trajectory("rk4_mrp", BOX, BOX_W0, TILT30, 1e-3, 500)
    dw, dq, k = conformance.disagreement(W, Q, Wr, Qr, BOX_W0)
    assert k == 500 and dw.max() < 1e-12 and dq.max() < 1e-12, (dw.max(), dq.max())
    # the run did pass through shadow switches: Basilisk's stored σ (read back, |σ| ≤ 1) jumped across the unit
    # sphere (|Δσ| ~ 2, where a step moves it at most ¼ (1 + σ²) |ω| dt ~ 0.07)
    sigma = Q[:, 1:] / (1.0 + Q[:, :1])
    assert np.abs(np.diff(sigma, axis=0)).max() > 0.5


def test_integrate_matches_rk4_mrp_on_free_asymmetric():
    """kernels.batch.integrate (what a sweep calls): the tennis racket at f = 10 Hz, dt = 1e-4 s, 0.1 s (before its
    first flip amplifies rounding): every sample field agrees with rk4_mrp to 1e-12 of its scale."""
    sc = build_scene("free_asymmetric", 10.0, 30.0)
    B, W, Q = np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0])
    out, status, n_steps = integrate(NAME, B, W, Q, 1e-4, 10, 101)
    want, w_status, w_steps = integrate("rk4_mrp", B, W, Q, 1e-4, 10, 101)
    assert status[0] == w_status[0] == STATUS_OK and n_steps[0] == w_steps[0] == 1000
    scale = np.maximum(np.abs(want).max(axis=1, keepdims=True), 1e-300)
    assert np.all(np.abs(out - want) <= 1e-12 * scale + 1e-15)


def test_heavy_body_is_refused_in_one_line():
    sc = build_scene("heavy_top", 5.0, 30.0)
    B, W, Q = np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0])
    with pytest.raises(ValueError, match="free bodies only") as err:
        integrate(NAME, B, W, Q, 1e-3, 1, 3)
    assert "\n" not in str(err.value) and NAME in str(err.value)


def test_dt_not_whole_nanoseconds_is_refused_in_one_line():
    """Basilisk's clock counts integer nanoseconds: 1e-3 and 1e-4 s are exact, 1e-3 / 3 s is refused naming the
    nearest whole number."""
    from gyrolab.kernels.real.basilisk_engine import step_nanos

    assert step_nanos(1e-3) == 1_000_000 and step_nanos(1e-4) == 100_000
    assert step_nanos(1e-3) * 1e-9 == 1e-3 and step_nanos(1e-4) * 1e-9 == 1e-4  # Basilisk's step is dt exactly
    for dt in (1e-3 / 3, 1e-10, 0.0):
        with pytest.raises(ValueError, match="whole number of nanoseconds") as err:
            integrate(NAME, np.array([BOX]), np.array([BOX_W0]), np.array([TILT30]), dt, 1, 2)
        assert "\n" not in str(err.value)


def test_grid_refuses_before_any_work():
    from gyrolab.runner.config import ConfigError

    with pytest.raises(ConfigError, match=rf"sweep\.method={NAME}: .*free bodies only") as err:
        grid_of(f"sweep.method=[rk4_mrp,{NAME}]", "scene=heavy_top")
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=rf"sweep\.method={NAME}: .*whole number of nanoseconds") as err:
        grid_of(f"sweep.method=[rk4_mrp,{NAME}]", "scene=free_asymmetric", "sweep.dt=[2.5e-10]")
    assert "\n" not in str(err.value)


def test_conformance_rows_for_basilisk(monkeypatch):
    """The conformance pair at 300 steps (the other engines' pairs left out): agreement to rounding on the free
    cases, the heavy cases not run (a note)."""
    from gyrolab.kernels.real import conformance

    pair = ("rk4_mrp", NAME, None)
    assert pair in conformance.PAIRS
    monkeypatch.setattr(conformance, "PAIRS", (pair,))
    conformance_rows = conformance.rows(300)
    assert len(conformance_rows) == len(conformance.cases()) * len(conformance.DTS)
    for r in conformance_rows:
        if r["case"] in ("tennis racket", "tumbling box"):
            assert r["dw"] < 1e-12 and r["dq"] < 1e-12 and r["first_over"] is None, r
        else:
            assert "free bodies only" in r["note"], r


@pytest.mark.slow  # the gyrolab command alone starts in ~9 s on a loaded 2-core machine (rk4_mrp only: 9.3 s)
def test_sweep_beside_rk4_mrp_writes_one_file(tmp_path):
    """gyrolab 'sweep.method=[real_basilisk_rk4,rk4_mrp]' scene=free_asymmetric at a small size: one results file
    that opens, the engine's version in its attrs, the two methods agreeing to rounding before the first flip
    (Basilisk adds ~2 s to the command: its import and 20 ExecuteSimulation calls)."""
    ds = free_body_sweep([NAME, "rk4_mrp"], tmp_path)
    assert ds.attrs["engine_versions"].startswith("bsk ")
    assert (ds.status == 0).all()
    a, b = ds.omega.sel(integrator=NAME), ds.omega.sel(integrator="rk4_mrp")
    assert float(abs(a - b).max()) < 1e-10 * 2 * math.pi * 10
