"""Heavy bodies with the centre of mass anywhere: the heavy_body and kovalevskaya scenes, their
reference solution and invariants, and that the general body reduces to the symmetric top exactly."""

import numpy as np
import pytest
import xarray as xr

from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import FIELDS
from gyrolab.kernels.invariants import kovalevskaya_integral
from gyrolab.kernels.reference import dop853
from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.scenes import build_scene

from helpers import assert_ok, gyrolab

OMEGA = slice(FIELDS.index("omega_1"), FIELDS.index("omega_3") + 1)
GAMMA = slice(FIELDS.index("gamma_1"), FIELDS.index("gamma_3") + 1)
ENERGY, LZ = FIELDS.index("energy"), FIELDS.index("L_z")


def kovalevskaya_of(samples, body):
    """K per sample of raw samples (n, FIELDS), through the layout's formula."""
    omega = xr.DataArray(samples[:, OMEGA], dims=("time", "xyz"), coords={"xyz": ["x", "y", "z"]})
    gamma = xr.DataArray(samples[:, GAMMA], dims=("time", "xyz"), coords={"xyz": ["x", "y", "z"]})
    stored = xr.DataArray(np.asarray(body), dims="body_param", coords={"body_param": list(body._fields)})
    return kovalevskaya_integral(omega, gamma, stored).values


def test_heavy_body_with_centre_of_mass_on_e3_is_the_heavy_top(run_scene):
    """heavy_body with the heavy top's moments and com = [0, 0, l] builds the heavy top's body and state
    to the bit, so every method runs it identically (the stored heavy-top regression data, written
    before the body had a centre-of-mass vector, check the kernels themselves bit for bit)."""
    M, r, l, g = 1.0, 0.05, 0.1, 10.0
    top = build_scene("heavy_top", 10.0, 45.0, M=M, r=r, l=l, g=g)
    I1, I2, I3 = top.body[:3]
    body = build_scene("heavy_body", 10.0, 45.0, I1=I1, I2=I2, I3=I3, com=[0.0, 0.0, l], M=M, g=g)
    assert tuple(body.body) == tuple(top.body) and body.omega0 == top.omega0 and body.q0 == top.q0
    for name in ("seed_next", "lie_poisson4"):
        np.testing.assert_array_equal(run_scene(name, body, 1e-3, 0.2, 1e-2), run_scene(name, top, 1e-3, 0.2, 1e-2))


@pytest.mark.parametrize(
    ("scene", "options"),
    [
        ("heavy_body", {"omega1": 4.0, "omega2": -3.0}),
        ("heavy_body", {"I3": 0.015, "com": [-0.05, 0.04, -0.02], "omega1": 1.0}),
        ("kovalevskaya", {"omega1": 2.0, "omega2": 1.0}),
    ],
)
def test_reference_keeps_every_declared_invariant(scene, options):
    """DOP853 at rtol = atol = 1e-12 on an off-axis centre of mass keeps E, L_z (and Kovalevskaya's K)
    to 1e-9 relative over 2 s: the general torque γ × M g c, the energy M g c·γ and K's formula (its
    sign of ν) agree with each other; a wrong sign of any of them breaks one of these by > 1e-3."""
    sc = build_scene(scene, 3.0, 40.0, **options)
    ref = dop853(sc, 2.0, 1e-2)
    scale = abs(ref[0, ENERGY]) + abs(sc.body.mgl) + abs(sc.body.mgc1) + abs(sc.body.mgc2)
    assert np.max(np.abs(ref[:, ENERGY] - ref[0, ENERGY])) <= 1e-9 * scale
    L = np.linalg.norm(ref[0, FIELDS.index("L_x") : FIELDS.index("L_z") + 1])
    assert np.max(np.abs(ref[:, LZ] - ref[0, LZ])) <= 1e-9 * L
    # the motion is not trivial: the axis moves and the body rates change by order one
    assert np.ptp(ref[:, FIELDS.index("axis_z")]) > 0.05
    if scene == "kovalevskaya":
        K = kovalevskaya_of(ref, sc.body)
        assert np.max(np.abs(K - K[0])) <= 1e-9 * K[0]
        # and K is not conserved by a body that is not Kovalevskaya's (the check can fail)
        other = build_scene("heavy_body", 3.0, 40.0, I1=0.02, I2=0.02, I3=0.01, com=[0.05, 0.0, 0.0], **options)
        off = build_scene("heavy_body", 3.0, 40.0, I1=0.02, I2=0.025, I3=0.01, com=[0.05, 0.0, 0.0], **options)
        assert tuple(other.body) == tuple(sc.body)
        K_off = kovalevskaya_of(dop853(off, 2.0, 1e-2), off.body)
        assert np.max(np.abs(K_off - K_off[0])) > 1e-3 * K_off[0]


@pytest.mark.parametrize("name", ["rk4", "lie_poisson4", "strang_exact4"])
def test_kovalevskaya_integral_error_falls_at_the_declared_order(name, run_scene):
    """max |K − K0| over 2 s for dt = 4e-3 … 5e-4 falls like dt^ORDER (log-log slope ORDER ± 0.4):
    the fourth-order methods keep Kovalevskaya's integral to their order, none exactly."""
    sc = build_scene("kovalevskaya", 3.0, 40.0, omega1=2.0, omega2=1.0)
    dts = np.array([4e-3, 2e-3, 1e-3, 5e-4])
    errors = []
    for dt in dts:
        K = kovalevskaya_of(run_scene(name, sc, dt, 2.0, 2e-2), sc.body)
        errors.append(np.max(np.abs(K - K[0])) / K[0])
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert errors[-1] > 1e-14  # above rounding: the slope measures truncation
    assert abs(slope - METHODS[name].ORDER) <= 0.4, (slope, errors)


def test_unphysical_moments_are_refused_unless_allowed():
    with pytest.raises(ValueError, match="no rigid body has"):
        build_scene("heavy_body", 5.0, 30.0, I1=0.005, I2=0.005, I3=0.002, com=[0.0, 0.0, 0.1])
    with pytest.raises(ValueError, match="no rigid body has"):
        build_scene("kovalevskaya", 5.0, 30.0, I3=1.0, c=1.0, M=1.0)
    sc = build_scene("kovalevskaya", 5.0, 30.0, I3=1.0, c=1.0, M=1.0, g=1.0, allow_unphysical=True)
    assert sc.body == Body(2.0, 2.0, 1.0, 0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match=r"scene.com=.*three"):
        build_scene("heavy_body", 5.0, 30.0, com=[0.1, 0.2])


@pytest.mark.slow
def test_heavy_body_from_the_command_line_stores_its_com_and_reads_back(tmp_path):
    """``scene=heavy_body scene.com=[...]`` runs, the file stores the vector option and the body,
    and the analysis rebuilds the run's scene from the file."""
    from gyrolab.analysis.io import build_run_scene, scene_options
    from gyrolab.results import open_results

    out = tmp_path / "run"
    proc = gyrolab(
        "scene=heavy_body",
        "scene.com=[0.02,-0.01,0.08]",
        "sweep.method=[lie_poisson]",
        "sweep.f=[5]",
        "sweep.theta0=[30]",
        "sweep.dt=[1e-3]",
        "sweep.t_end=0.1",
        "output.every=1e-2",
        "output.figures=false",
        f"hydra.run.dir={out}",
        cwd=tmp_path,
    )
    assert_ok(proc)
    ds = open_results(out / "results.h5")
    assert scene_options(ds)["com"] == pytest.approx([0.02, -0.01, 0.08])
    sc = build_run_scene(ds, 5.0, 30.0)
    assert sc.body.mgc1 == pytest.approx(9.81 * 0.02) and sc.body.mgc2 == pytest.approx(-9.81 * 0.01)
    assert "gamma" in ds and ds.attrs["conserved"] == "energy Lz"
    np.testing.assert_allclose((ds.gamma**2).sum("xyz"), 1.0, rtol=1e-12)
    assert bool(np.isfinite(ds.energy).all()) and int(ds.status.max()) == 0


def test_peer_table_reads_every_declared_invariant_from_the_file(tmp_path):
    """``python -m gyrolab.analysis.reports.peer_table``: per file an axis-error table and one table per declared
    invariant (Kovalevskaya's K included), a row per method and a column per dt, numbers from the file."""
    from gyrolab.analysis.io import invariant_error
    from gyrolab.analysis.reports import peer_table
    from gyrolab.results import open_results

    from helpers import build_dataset

    path = tmp_path / "kov.h5"
    grid = {"integrator": ["rk4", "lie_poisson4"], "f": [3.0], "theta0": [40.0], "dt": [2e-3, 1e-3]}
    build_dataset(path, grid, scene="kovalevskaya", t_end=0.4, every=2e-2, omega1=2.0, omega2=1.0)
    out = tmp_path / "peer.md"
    assert peer_table.main([str(path), "-o", str(out)]) == 0
    text = out.read_text()
    for q in ("energy", "Lz", "kovalevskaya"):
        assert f"Worst relative error of {q} over the run:" in text
    ds = open_results(path)
    run = ds.sel({"integrator": "rk4", "f": 3.0, "theta0": 40.0, "dt": 1e-3})
    worst = float(np.nanmax(invariant_error(run, "kovalevskaya")))
    k_table = text.split("Worst relative error of kovalevskaya over the run:")[1]
    rk4_row = next(line for line in k_table.splitlines() if line.startswith("| `rk4`"))
    assert rk4_row.split("|")[2].strip() == f"{worst:.2g}"  # the dt = 1e-3 column


def test_peer_table_refuses_a_missing_file_in_one_line_and_writes_nothing(tmp_path, capsys):
    from gyrolab.analysis.reports import peer_table

    out = tmp_path / "peer.md"
    assert peer_table.main([str(tmp_path / "absent.h5"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no such results file" in err and not out.exists()
