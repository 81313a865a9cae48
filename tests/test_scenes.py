"""Scenes: bodies, initial states (docs/design.md) and clear errors for bad options."""

import math

import numpy as np
import pytest

from gyrolab.kernels.body import Body
from gyrolab.kernels.rotation import ck_matrix
from gyrolab.kernels.scenes import SCENES, build_scene
from gyrolab.kernels.scenes.heavy_top import steady_precession_rates


def test_heavy_top_seed_body():
    """M = 1 kg, r = 0.05 m, l = 0.1 m, g = 10: I1 = I2 = M(r²/4 + l²), I3 = M r²/2, M g l = 1."""
    sc = build_scene("heavy_top", 10.0, 45.0)
    np.testing.assert_allclose(sc.body, Body(0.010625, 0.010625, 0.00125, 1.0), rtol=1e-15)
    sc = build_scene("heavy_top", 10.0, 45.0, M=2.0, r=0.1, l=0.3, g=9.81)
    np.testing.assert_allclose(
        sc.body, Body(2 * (0.01 / 4 + 0.09), 2 * (0.01 / 4 + 0.09), 2 * 0.01 / 2, 2 * 9.81 * 0.3), rtol=1e-15
    )


@pytest.mark.parametrize("scene", sorted(SCENES))
@pytest.mark.parametrize("theta0", [0.0, 30.0, 45.0, 90.0, 180.0])
def test_initial_axis(scene, theta0):
    """R0 = Rx(θ0): the axis tip starts at (0, −sin θ0, cos θ0) and R0 is a rotation."""
    sc = build_scene(scene, 10.0, theta0)
    R = ck_matrix(sc.q0)
    th = math.radians(theta0)
    np.testing.assert_allclose(R[:, 2], [0.0, -math.sin(th), math.cos(th)], atol=2e-16)
    np.testing.assert_allclose(R[:, 0], [1.0, 0.0, 0.0], atol=2e-16)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=2e-16)


@pytest.mark.parametrize("f", [0.0, 1.0, 50.0])
def test_release_spins_only(f):
    assert build_scene("heavy_top", f, 45.0).omega0 == (0.0, 0.0, 2 * math.pi * f)


def goldstein_body_rates(phidot, thetadot, psidot, theta, psi=0.0):
    """docs/design.md, conventions (Goldstein 4.125), written out independently of the scene code."""
    return (
        phidot * math.sin(theta) * math.sin(psi) + thetadot * math.cos(psi),
        phidot * math.sin(theta) * math.cos(psi) - thetadot * math.sin(psi),
        phidot * math.cos(theta) + psidot,
    )


@pytest.mark.parametrize("phidot0", [-3.0, 0.5, 2.0])
def test_precession_body_rates(phidot0):
    """init=precession: θ̇0 = 0, given φ̇0, and the spin f sets the body ω3 = 2πf."""
    f, theta0 = 20.0, 60.0
    sc = build_scene("heavy_top", f, theta0, init="precession", phidot0=phidot0)
    th = math.radians(theta0)
    psidot = 2 * math.pi * f - phidot0 * math.cos(th)
    np.testing.assert_allclose(sc.omega0, goldstein_body_rates(phidot0, 0.0, psidot, th), rtol=1e-15, atol=1e-15)
    assert sc.omega0[2] == pytest.approx(2 * math.pi * f, rel=1e-15)


@pytest.mark.parametrize("f, theta0", [(23.0, 45.0), (50.0, 30.0), (50.0, 45.0), (25.0, 80.0), (10.0, 120.0)])
def test_steady_rates_solve_the_precession_condition(f, theta0):
    """Both steady inits put φ̇ on a root of M g l = φ̇ (I3 ω3 − I1 φ̇ cos θ0), |slow| < |fast|."""
    rates = []
    for init in ("steady_slow", "steady_fast"):
        sc = build_scene("heavy_top", f, theta0, init=init)
        I1, _, I3, mgl = sc.body[:4]
        th = math.radians(theta0)
        phidot = sc.omega0[1] / math.sin(th)  # ω2 = φ̇ sin θ at ψ = 0
        assert sc.omega0[0] == 0.0  # θ̇0 = 0
        assert sc.omega0[2] == pytest.approx(2 * math.pi * f, rel=1e-15)
        assert phidot * (I3 * sc.omega0[2] - I1 * phidot * math.cos(th)) == pytest.approx(mgl, rel=1e-12)
        rates.append(phidot)
    # Above the horizontal both roots are prograde; hanging below it (θ0 > 90°) the fast one is retrograde.
    assert 0 < rates[0] < abs(rates[1])
    assert (rates[1] > 0) == (theta0 < 90.0)


def test_steady_rates_at_horizontal_have_one_root():
    slow, fast = steady_precession_rates(0.010625, 0.00125, 1.0, 2 * math.pi * 10, math.pi / 2)
    assert slow == fast == pytest.approx(1.0 / (0.00125 * 2 * math.pi * 10), rel=1e-15)


def test_sleeping_top_is_upright_and_spinning():
    sc = build_scene("heavy_top", 50.0, 0.0, init="sleeping")
    assert sc.omega0 == (0.0, 0.0, 2 * math.pi * 50.0)
    np.testing.assert_allclose(ck_matrix(sc.q0), np.eye(3), atol=0)


def test_free_symmetric_body_and_rates():
    """Disc about its centre: I1 = I2 = M r²/4, I3 = M r²/2, no gravity; ω = (0, wobble ω3, ω3)."""
    sc = build_scene("free_symmetric", 10.0, 30.0, M=2.0, r=0.1, wobble=0.25)
    np.testing.assert_allclose(sc.body, Body(0.005, 0.005, 0.01, 0.0), rtol=1e-15)
    w3 = 2 * math.pi * 10.0
    np.testing.assert_allclose(sc.omega0, (0.0, 0.25 * w3, w3), rtol=1e-15)


def test_free_asymmetric_body_and_rates():
    """Spin about e3, the intermediate axis by default (I1 < I3 < I2), with a small ω1 = eps ω3."""
    sc = build_scene("free_asymmetric", 5.0, 0.0)
    I1, I2, I3, mgl = sc.body[:4]
    assert I1 < I3 < I2 and mgl == 0.0
    w3 = 2 * math.pi * 5.0
    np.testing.assert_allclose(sc.omega0, (1e-3 * w3, 0.0, w3), rtol=1e-15)


@pytest.mark.parametrize(
    "scene, kwargs, key",
    [
        ("heavy_top", {"init": "spinning"}, "scene.init"),
        ("heavy_top", {"M": -1.0}, "scene.M"),
        ("heavy_top", {"r": 0.0}, "scene.r"),
        ("heavy_top", {"l": -0.1}, "scene.l"),
        ("heavy_top", {"g": 0.0}, "scene.g"),
        ("heavy_top", {"mass": 1.0}, "scene.mass"),
        ("heavy_top", {"phidot0": float("nan")}, "phidot0"),
        ("heavy_top", {"init": "sleeping"}, "theta0"),  # sleeping needs θ0 = 0
        ("free_symmetric", {"wobble_rate": 1.0}, "scene.wobble_rate"),
        ("free_symmetric", {"M": 0.0}, "scene.M"),
        ("free_asymmetric", {"I3": 5e-4}, "scene.I3"),  # triangle inequality
        ("free_asymmetric", {"I1": -1.0}, "scene.I1"),
    ],
)
def test_bad_options_name_the_key(scene, kwargs, key):
    with pytest.raises(ValueError) as err:
        build_scene(scene, 10.0, 45.0, **kwargs)
    message = str(err.value)
    assert key in message and "\n" not in message


@pytest.mark.parametrize(
    "f, theta0, key",
    [(-1.0, 45.0, "f=-1"), (10.0, 181.0, "theta0=181"), (10.0, -5.0, "theta0=-5"), (float("inf"), 45.0, "f=inf")],
)
def test_bad_spin_or_tilt_name_the_key(f, theta0, key):
    with pytest.raises(ValueError, match=key):
        build_scene("heavy_top", f, theta0)


def test_unknown_scene_names_the_choices():
    with pytest.raises(ValueError, match="unknown scene 'spinning_plate'.*heavy_top"):
        build_scene("spinning_plate", 10.0, 45.0)


def test_steady_without_spin_is_refused():
    with pytest.raises(ValueError, match="f=0"):
        build_scene("heavy_top", 0.0, 45.0, init="steady_slow")


def test_published_unphysical_bodies_need_the_recorded_opt_in():
    """Principia's Dzhanibekov body I = (3, 5, 9) breaks the triangle inequality: refused by default,
    built with allow_unphysical=True (an option, so the runner stores it in the file attrs)."""
    with pytest.raises(ValueError, match="triangle inequality.*allow_unphysical=true"):
        build_scene("free_asymmetric", 1.0, 20.0, I1=3.0, I2=5.0, I3=9.0)
    sc = build_scene("free_asymmetric", 1.0, 20.0, I1=3.0, I2=5.0, I3=9.0, allow_unphysical=True)
    assert tuple(sc.body[:3]) == (3.0, 5.0, 9.0)
    assert "allow_unphysical" in SCENES["free_asymmetric"].OPTIONS
