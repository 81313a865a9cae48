"""Problems others publish, pinned as experiments: their data as published, checked here.

- Hairer, Lubich & Wanner's free rigid body (conf/experiment/hlw_free_body.yaml);
- the heavy top of Brüls, Cardona & Arnold (2012), the benchmark multibody codes reproduce
  (conf/experiment/bruls_heavy_top.yaml; values as in Kynema's heavy_top example);
- SciMLBenchmarks' rigid body (conf/experiment/sciml_rigid_body.yaml, analysis/figures/sciml.py).
"""

import math

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from gyrolab.kernels.driver import FIELDS
from gyrolab.kernels.reference import dop853, rhs
from gyrolab.kernels.rotation import ck_matrix
from gyrolab.runner.config import register_configs

from helpers import experiment_scene

register_configs()


def test_hlw_free_body_is_their_body_and_initial_momentum():
    """I = (2, 1, 2/3), L0 = (cos 1.1, 0, sin 1.1) in the body frame, body axes on the lab's (GNI IV.1)."""
    sc = experiment_scene("hlw_free_body")
    np.testing.assert_allclose(sc.body[:3], (2.0, 1.0, 2.0 / 3.0), rtol=1e-15)
    assert tuple(sc.body[3:]) == (0.0,) * 9  # no weight, no drive
    L0 = np.asarray(sc.body[:3]) * np.asarray(sc.omega0)
    np.testing.assert_allclose(L0, (math.cos(1.1), 0.0, math.sin(1.1)), rtol=1e-15, atol=1e-16)
    np.testing.assert_allclose(ck_matrix(sc.q0), np.eye(3), atol=1e-16)


# Kynema's heavy_top example (the Brüls-Cardona-Arnold top), lab = body frame at t = 0:
BRULS_OMEGA = np.array([0.0, 150.0, -4.61538])  # rad/s
BRULS_OMEGA_DOT = np.array([661.3461692307691919, 0.0, 0.0])  # rad/s^2
BRULS_X = np.array([0.0, 1.0, 0.0])  # centre of mass, m
BRULS_X_DDOT = np.array([0.0, -21.3017325444000001, -30.9608307692308244])  # m/s^2
# Kynema's generalized-alpha run (dt = 2e-3 s, rho_inf = 0.9, 400 steps): centre-of-mass displacement
# along z at t = 0.8 s.  A second-order scheme at |omega| dt = 0.3: a few per cent off the exact motion.
KYNEMA_UZ_08 = -0.04455460488952848


def test_bruls_heavy_top_is_their_top():
    """The relabelled body (axes e1, −e2, −e3, tilt 180°) is the published one: the lab angular velocity,
    centre of mass, and the initial angular and centre-of-mass accelerations that Kynema lists."""
    sc = experiment_scene("bruls_heavy_top")
    R0 = ck_matrix(sc.q0)
    omega_lab = R0 @ np.asarray(sc.omega0)
    np.testing.assert_allclose(omega_lab, BRULS_OMEGA, rtol=0, atol=1e-13)
    com_body = np.array([sc.body.mgc1, sc.body.mgc2, sc.body.mgl]) / (15.0 * 9.81)
    np.testing.assert_allclose(R0 @ com_body, BRULS_X, atol=1e-15)
    y0 = np.concatenate((sc.omega0, R0.ravel()))
    omega_dot = R0 @ np.asarray(rhs(0.0, y0, *sc.body)[:3])
    np.testing.assert_allclose(omega_dot, BRULS_OMEGA_DOT, rtol=1e-12, atol=1e-9)
    x_ddot = np.cross(omega_dot, BRULS_X) + np.cross(BRULS_OMEGA, np.cross(BRULS_OMEGA, BRULS_X))
    np.testing.assert_allclose(x_ddot, BRULS_X_DDOT, rtol=1e-12)


def test_bruls_heavy_top_reference_is_near_kynemas_run():
    """DOP853 (rtol = atol = 1e-12) on the top: the centre of mass drops by 0.0460 m in 0.8 s; Kynema's
    generalized-alpha run at dt = 2e-3 s has 0.0446 (3 % off: its second-order error at |ω| dt = 0.3),
    and E, L_z stay to 1e-9."""
    sc = experiment_scene("bruls_heavy_top")
    ref = dop853(sc, 0.8, 2e-3)
    gamma = ref[:, FIELDS.index("gamma_1") : FIELDS.index("gamma_3") + 1]
    com_body = np.array([sc.body.mgc1, sc.body.mgc2, sc.body.mgl]) / (15.0 * 9.81)
    uz = gamma @ com_body  # the centre of mass's height, c·γ
    assert uz[0] == pytest.approx(0.0, abs=1e-15)
    assert uz[-1] == pytest.approx(KYNEMA_UZ_08, rel=0.05)
    assert uz[-1] == pytest.approx(-0.045977, abs=2e-6)
    energy = ref[:, FIELDS.index("energy")]
    assert np.ptp(energy) <= 1e-9 * abs(energy[0])


def test_sciml_rigid_body_is_their_problem():
    """The pinned experiment is SciML's: ω(0) = (1, 0, 0.9), I = (0.5, 2, 3), the drive 0.25 sin² t in ω̇3
    on all of [0, 10] (not EULR's [3π, 4π]), t_end = 10."""
    from gyrolab.kernels.rigid_body import drive_torque

    sc = experiment_scene("sciml_rigid_body")
    np.testing.assert_allclose(sc.omega0, (1.0, 0.0, 0.9), rtol=1e-15)
    assert tuple(sc.body[:3]) == (0.5, 2.0, 3.0) and (sc.body.drive_on, sc.body.drive_off) == (0.0, 10.0)
    for t in (0.3, 5.0, 9.9):
        assert drive_torque(t, sc.body)[2] / sc.body.I3 == pytest.approx(0.25 * math.sin(t) ** 2, rel=1e-15)
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        cfg = compose("config", overrides=["experiment=sciml_rigid_body"])
    assert cfg.sweep.t_end == 10.0 and "sciml" in cfg.output.figures


@pytest.mark.slow
def test_sciml_diagram_from_a_small_run(tmp_path):
    """A reduced run of the pinned experiment (rk4 and lie_poisson4 at three dt): the diagram's data has
    each method's error falling ~16x per halving, the peers' errors falling with their tolerance, the
    figure draws, and the table command writes every point and refuses a missing file in one line; on a
    body with gravity the peers solve (ω, R) and the figure says which (f, θ0) it drew."""
    from gyrolab.analysis.figures import sciml
    from gyrolab.results import open_results

    from helpers import gyrolab

    out = tmp_path / "sciml.h5"
    done = gyrolab(
        "experiment=sciml_rigid_body",
        "sweep.method=[rk4,lie_poisson4]",
        "sweep.dt=[0.02,0.01,0.005]",
        "output.figures=false",
        f"output.path={out}",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    ds = open_results(out)
    data = sciml.sciml_data(ds, retime=False, repeats=1, tolerances=sciml.TOLERANCES[::3])
    for m in ("rk4", "lie_poisson4"):
        errors = [p[3] for p in data["methods"][m]]  # dt ascending
        assert 10 < errors[1] / errors[0] < 22 and 10 < errors[2] / errors[1] < 22, errors
    for name in sciml.PEERS:
        errors = [p[4] for p in data["peers"][name]]
        assert len(errors) == 3 and errors[-1] < errors[0], (name, errors)
    fig = sciml.sciml_figure(ds, data=data)
    assert len(fig.axes[0].get_lines()) >= 6
    table = tmp_path / "table.md"
    assert sciml.main([str(out), "-o", str(table), "--repeats", "1"]) == 0
    text = table.read_text()
    assert text.count("| `rk4` |") == 3 and "scipy Radau" in text and "abstol 1e-13" in text
    heavy = tmp_path / "heavy.h5"  # a body with gravity: the peers solve (ω, R)
    done = gyrolab(
        "sweep.method=[rk4]",
        "sweep.t_end=0.1",
        "output.every=0.01",
        "output.figures=false",
        f"output.path={heavy}",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    data = sciml.sciml_data(
        open_results(heavy), retime=False, repeats=1, peers=("DOP853",), tolerances=sciml.TOLERANCES[:1]
    )
    assert data["equations"] == "(ω, R)" and data["peers"]["DOP853"][0][4] < 1e-3
    assert data["note"].endswith("gyrolab-plot sciml FILE f=10,50"), data["note"]  # the default study: f = 1, 10, 50
    import subprocess
    import sys

    refused = subprocess.run(
        [
            sys.executable,
            "-m",
            "gyrolab.analysis.figures.sciml",
            str(tmp_path / "none.h5"),
            "-o",
            str(tmp_path / "x.md"),
        ],
        capture_output=True,
        text=True,
    )
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1, refused.stderr
    assert "none.h5" in refused.stderr and not (tmp_path / "x.md").exists()
