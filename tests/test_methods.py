"""Every registered method: its contract, the free top's exact solution, conservation laws,
the measured order of convergence and (symplectic ones) bounded energy.

Each test is parametrised over ``registry.METHODS``; a new method inherits all of them.
Accuracy bounds use the same convention as test_heavy_top: relative error
(ω3 dt)^ORDER, the step's spin phase raised to the declared order.
"""
import math

import numpy as np
import pytest

import gyrolab
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.closed_form import free_symmetric_solution
from gyrolab.kernels.reference import dop853
from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.rotation import ck_matrix
from gyrolab.kernels.scenes import build_scene

from helpers import method_params

# Error level below which a run is at its rounding floor, not its truncation error
# (measured floors: 1e-13 .. 4e-11 over up to 2e5 steps).
ROUNDING_FLOOR = 1e-11


def order_tolerance(name, omega3, dt):
    return (omega3 * dt) ** METHODS[name].ORDER


def test_registry_contract():
    """Each method declares ORDER (int ≥ 1), SYMPLECTIC (bool), a docstring, step and run_batch;
    gyrolab.methods() lists exactly the registered ones with these declarations."""
    listed = gyrolab.methods()
    assert set(listed) == set(METHODS)
    for name, module in METHODS.items():
        assert isinstance(module.ORDER, int) and module.ORDER >= 1
        assert isinstance(module.SYMPLECTIC, bool)
        assert module.__doc__ and module.__doc__.strip()
        assert callable(module.step) and callable(module.run_batch)
        assert listed[name]["order"] == module.ORDER
        assert listed[name]["symplectic"] == module.SYMPLECTIC


# ---------------------------------------------------------------- free symmetric top


def test_free_closed_form_matches_dop853():
    """The exact free-top solution and DOP853 agree (measured 1e-12 at 10 Hz, 4e-12 at 50 Hz)."""
    for f in (10.0, 50.0):
        sc = build_scene("free_symmetric", f, 30.0)
        times = np.arange(101) * 1e-2
        axis, omega = free_symmetric_solution(sc, times)
        ref = dop853(sc, 1.0, 1e-2)
        assert np.max(np.abs(ref[:, :3] - axis)) < 1e-10
        assert np.max(np.abs(ref[:, 3:6] - omega)) / sc.omega0[2] < 1e-10
        # The closed form starts where the scene does.
        np.testing.assert_allclose(axis[0], [0.0, -0.5, math.sqrt(3) / 2], atol=1e-16)
        np.testing.assert_allclose(omega[0], sc.omega0, atol=0)


@pytest.mark.parametrize("name", method_params())
def test_free_top_matches_closed_form(name, run_scene):
    """Free disc, f = 10 Hz, θ0 = 30°, wobble 0.1, 1 s, dt = 1e-3, 5e-4, 2.5e-4: axis and ω/ω3 within
    (ω3 dt)^ORDER + 1e-11 of the exact solution, and the error shrinks by 2^ORDER per halving (30 % slack)
    until it reaches rounding.  Measured at 2.5e-4: seeds 7.4e-4, rk4 3.2e-9, lie_poisson(4) ≤ 8e-13
    (their free flow is exact)."""
    sc = build_scene("free_symmetric", 10.0, 30.0)
    every = 1e-2
    axis, omega = free_symmetric_solution(sc, np.arange(101) * every)
    errors = []
    for dt in (1e-3, 5e-4, 2.5e-4):
        s = run_scene(name, sc, dt, 1.0, every)
        err = max(np.max(np.abs(s[:, :3] - axis)), np.max(np.abs(s[:, 3:6] - omega)) / sc.omega0[2])
        assert err <= order_tolerance(name, sc.omega0[2], dt) + ROUNDING_FLOOR
        errors.append(err)
    for coarse, fine in zip(errors, errors[1:]):
        if coarse > 10 * ROUNDING_FLOOR:
            assert fine <= 1.3 * coarse / 2 ** METHODS[name].ORDER


@pytest.mark.parametrize("scene, f, options, name", [
    pytest.param(scene, f, options, *p.values, marks=p.marks) if scene == "free_asymmetric" else (scene, f, options, m)
    for scene, f, options in (("free_symmetric", 10.0, {}), ("free_asymmetric", 5.0, {"eps": 0.1}))
    # explicit Euler keeps L of the symmetric top (ω3 fixed, ω⊥ turning slowly) within the bound,
    # not that of the asymmetric box
    for m, p in zip(METHODS, (q if hasattr(q, "values") else pytest.param(q) for q in method_params()))
])
def test_free_body_conserves_lab_angular_momentum(name, scene, f, options, step_loop):
    """1 s at dt = 2.5e-4: the lab vector L = R I ω is conserved to (ω3 dt)^ORDER + 1e-11 relative
    (measured: seeds 6e-5 / 2.4e-3, rk4 4.5e-12 / 4.2e-11).  Symplectic methods turn the body by exact
    rotations, so they conserve the lab L to rounding (≤ 1e-11; measured ≤ 9.3e-13) and |L| to
    5e-14 (measured ≤ 9.5e-15); for the symmetric body their free flow is exact, so E too (1e-14;
    measured ≤ 6.7e-16)."""
    sc = build_scene(scene, f, 30.0, **options)
    dt = 2.5e-4
    inertia = np.array(sc.body[:3])
    L0 = ck_matrix(sc.q0) @ (inertia * sc.omega0)
    w, q = step_loop(name)(sc.omega0, sc.q0, dt, sc.body, 4000)
    Lb = inertia * np.array(w)
    drift = np.linalg.norm(ck_matrix(q) @ Lb - L0) / np.linalg.norm(L0)
    assert drift <= order_tolerance(name, sc.omega0[2], dt) + ROUNDING_FLOOR
    if METHODS[name].SYMPLECTIC:
        assert drift <= ROUNDING_FLOOR
        assert abs(np.linalg.norm(Lb) / np.linalg.norm(L0) - 1) <= 5e-14
        if scene == "free_symmetric":
            E0 = 0.5 * np.sum(inertia * np.square(sc.omega0))
            assert abs(0.5 * np.sum(Lb * w) / E0 - 1) <= 1e-14


# ---------------------------------------------------------------- measured order


def final_state_errors(name, scene, reference, dts, t_end):
    """Error of the final state (max of |axis − ref| and |ω − ref|/ω3) for each dt, in one batch."""
    n = len(dts)
    strides = np.rint(t_end / np.asarray(dts)).astype(np.int64)
    samples, status, _ = integrate(
        name, np.tile(scene.body, (n, 1)), np.tile(scene.omega0, (n, 1)), np.tile(scene.q0, (n, 1)),
        np.asarray(dts), strides, 2, 1e9,
    )
    final = samples[:, -1, :]
    errors = np.maximum(np.max(np.abs(final[:, :3] - reference[:3]), axis=1),
                        np.max(np.abs(final[:, 3:6] - reference[3:6]), axis=1) / scene.omega0[2])
    return np.where(status == 0, errors, np.nan)  # a step too coarse to stay bounded has no error to fit


ORDER_CASES = {
    # heavy top, released: the gravity torque is what the seed schemes treat crudely
    "heavy_top_50Hz_45": ("heavy_top", 50.0, 45.0, {}),
    # torque-free box spun near its intermediate axis: the Lie-Poisson free flow is a splitting here
    "free_asymmetric_5Hz": ("free_asymmetric", 5.0, 20.0, {"eps": 0.1}),
}


@pytest.mark.parametrize("case", ORDER_CASES)
@pytest.mark.parametrize("name", METHODS)
def test_measured_order_matches_declared(name, case):
    """Final state at t = 1 s against DOP853 (rtol = atol = 1e-13) for dt = 1e-2 / 2^k, k = 0..11; the
    log-log slope over the four smallest dt whose error is above 1e-9 (clear of rounding) is ORDER ± 0.3.

    Measured slopes (heavy top / asymmetric box): seed_next 1.00 / 1.00 (at dt ≥ 2e-4 on the 50 Hz
    top it looks second order: a large dt² term hides the dt term), seed_prev 0.99 / 1.00,
    rk4 3.99 / 4.08, lie_poisson 2.00 / 2.00, lie_poisson4 4.00 / 4.00.
    """
    scene, f, theta0, options = ORDER_CASES[case]
    sc = build_scene(scene, f, theta0, **options)
    t_end = 1.0
    reference = dop853(sc, t_end, t_end, rtol=1e-13, atol=1e-13)[-1]
    dts = 1e-2 / 2.0 ** np.arange(14)
    errors = final_state_errors(name, sc, reference, dts, t_end)
    usable = np.nonzero(errors > 1e-9)[0][-4:]
    assert len(usable) == 4, errors
    slope = np.polyfit(np.log(dts[usable]), np.log(errors[usable]), 1)[0]
    assert abs(slope - expected_order(METHODS[name], sc)) <= 0.3, (slope, errors)


def expected_order(module, scene):
    """The declared order; on a torque-free body (M g l = 0) ``FREE_ORDER`` when the method declares one
    (a splitting whose kicks vanish there is its free flow alone: lie_trotter is then second order)."""
    return getattr(module, "FREE_ORDER", module.ORDER) if scene.body.mgl == 0.0 else module.ORDER


# ---------------------------------------------------------------- symplectic energy


@pytest.mark.parametrize("name", [m for m, mod in METHODS.items() if mod.SYMPLECTIC])
def test_symplectic_energy_is_bounded(name, run_scene):
    """Heavy top f = 10 Hz, θ0 = 45° release, dt = 1e-3, 100 s: |ΔE|/E0 stays ≤ (ω3 dt)^ORDER and the
    largest |ΔE| of the last 10 s is within 10 % of the first 10 s (no secular drift).
    Measured: lie_poisson 7.68e-6 / 7.68e-6, lie_poisson4 3.14e-10 / 3.13e-10 (rk4, for contrast,
    1.2e-6 → 1.2e-5)."""
    sc = build_scene("heavy_top", 10.0, 45.0)
    s = run_scene(name, sc, 1e-3, 100.0, 1e-2)
    rel = np.abs(s[:, 6] / s[0, 6] - 1)
    n = len(rel) // 10
    assert rel.max() <= order_tolerance(name, sc.omega0[2], 1e-3)
    assert rel[-n:].max() <= 1.1 * rel[:n].max()
