"""lie_genalpha (kernels/methods/lie_genalpha.py): Kynema's Lie-group generalized-α step with the body
as one node at its pivot, checked against Kynema's published precession test, against an independent
numpy transcription of the same node model (tests/kynema_genalpha.py ``run_pivot_node``, which reuses
the mass element that reproduces Kynema's published heavy top), against DOP853, and as a run: the
accelerations it carries from step to step go through the driver, and a step whose Newton loop does
not converge ends the run with the non-finite status.

Measured (this machine, float64):

* Kynema's precession test (tests/regression_tests/regression/test_precession.cpp: a free body
  J = diag(1, 1, 0.5), ω = (0.5, 0.5, 1) rad/s, h = 0.01 s, ρ∞ = 1, 500 steps from zero
  accelerations): the published quaternion to 5.2e-13.
* Kynema's heavy top with the node at the pivot (inertia about it, diag(15.234375, 0.46875,
  15.234375) kg m², M g c = 147.15 N m along body y, Ω0 = (0, 150, −4.61538) rad/s, h = 2e-3 s,
  ρ∞ = 0.9, 400 steps): the numpy transcription of that model to 1.7e-12 (quaternion; lab rates
  to 8e-11 rad/s of 150).
* Where the node sits changes the answer: against DOP853 the centre of mass at 0.8 s is off by
  0.332 m at h = 2e-3 s and 0.0839 m at h = 1e-3 s (order 1.98) with the node at the pivot, and
  by 4.62e-3 m with Kynema's own model (node at the centre of mass, pinned to a ground node by a
  rigid joint), the same continuous top: so the pivot node differs from Kynema's published heavy-top
  state by 0.336 m there.
* Kynema's own model is the variant ``lie_genalpha(mass=15)`` (the node at the centre of mass of the
  15 kg top, the joint's multipliers eliminated exactly): Kynema's published state at 0.8 s to 2.4e-12
  m (centre of mass) and 1.1e-11 (quaternion), from gyrolab's pinned experiment in its own frame
  (tests/kynema_genalpha.py, the 15-unknown numpy transcription, gets 2.1e-11).
"""

import math
import types

import numpy as np
import pytest
from kynema_genalpha import (
    MASS,
    OMEGA0,
    OMEGA_DOT0,
    PRECESSION_PUBLISHED_QUAT,
    PUBLISHED_Q,
    X_COM0,
    X_DDOT0,
    quat_to_matrix,
    run_pivot_node,
)
from numba import njit

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import FIELDS, STATUS_OK, STATUS_UNCONVERGED
from gyrolab.kernels.registry import METHODS, carries_state, get_method, register, stepper
from gyrolab.kernels.rotation import quat_mul
from gyrolab.runner.grid import runs_in_blocks

GENALPHA = METHODS["lie_genalpha"]
# Kynema's heavy top, node at the pivot: moments about it by the parallel-axis theorem, M g c along y.
PIVOT_BODY = Body(15.234375, 0.46875, 15.234375, 0.0, 0.0, MASS * 9.81 * 1.0)
W0 = tuple(float(v) for v in OMEGA0)  # body = lab at t = 0 (orientation the identity)
Q0 = (1.0, 0.0, 0.0, 0.0)


@njit
def _steps_with(w, q, c, dt, body, rho_inf, n):
    step_with = GENALPHA.step_carried_with
    for _ in range(n):
        w, q, c, _ = step_with(w, q, c, dt, body, rho_inf, 1e-5, 1e-3, 10)
    return w, q, c


def _run(h, n, body=PIVOT_BODY, w=W0, q=Q0):
    """(w, q) after n registered steps (ρ∞ = 0.9) from the consistent start."""
    start, step_carried = stepper(GENALPHA)
    c = start(w, q, body)
    for _ in range(n):
        w, q, c = step_carried(w, q, c, h, body)
    return np.array(w), np.array(q)


def test_reproduces_kynemas_precession_test():
    w, q, c = _steps_with((0.5, 0.5, 1.0), Q0, (0.0,) * 6, 0.01, Body(1.0, 1.0, 0.5, 0.0), 1.0, 500)
    assert np.abs(np.array(q) - PRECESSION_PUBLISHED_QUAT).max() < 2e-12  # measured 5.2e-13
    assert all(math.isfinite(v) for v in c)


def test_heavy_top_matches_the_numpy_transcription_of_the_pivot_node():
    w, q = _run(2e-3, 400)
    ref = run_pivot_node()
    ref_q, ref_v = ref["q"][0, 3:], ref["v"][0, 3:]
    assert np.abs(ref["q"][0, :3]).max() == 0.0  # the node's translation stays held
    assert np.abs(q - ref_q).max() < 1e-11  # measured 1.7e-12
    assert np.abs(quat_to_matrix(q) @ w - ref_v).max() < 1e-9 * np.abs(ref_v).max()  # lab rates


@pytest.mark.slow
def test_the_node_at_the_pivot_is_second_order_and_not_kynemas_centre_of_mass_model():
    from test_kynema_heavy_top import _reference_com_at

    x_ref = _reference_com_at(0.8)
    errors = [np.linalg.norm(quat_to_matrix(_run(h, n)[1]) @ X_COM0 - x_ref) for h, n in ((2e-3, 400), (1e-3, 800))]
    assert 0.30 < errors[0] < 0.36  # measured 0.332 m
    assert 1.95 < math.log2(errors[0] / errors[1]) < 2.05  # measured 1.98
    kynema_com = X_COM0 + PUBLISHED_Q[:3]  # Kynema's model: its error is 4.62e-3 m (test_kynema_heavy_top)
    assert np.linalg.norm(kynema_com - x_ref) < 5e-3
    assert 0.25 < np.linalg.norm(quat_to_matrix(_run(2e-3, 400)[1]) @ X_COM0 - kynema_com) < 0.40  # 0.336


KYNEMA_MODEL = "lie_genalpha(mass=15.0)"  # the node at the centre of mass of the 15 kg top, g = 9.81


def _run_named(name, h, n, body, w, q):
    """(w, q, c) after n steps of the method or variant ``name`` from its start."""
    start, step_carried = stepper(get_method(name))
    c = start(w, q, body)
    for _ in range(n):
        w, q, c = step_carried(w, q, c, h, body)
    return np.array(w), np.array(q), np.array(c)


def test_the_node_at_the_centre_of_mass_is_kynemas_heavy_top():
    """``lie_genalpha(mass=15)`` models the top as Kynema's test does (the node at the centre of mass,
    pinned at the pivot by a rigid joint): from the consistent start (Kynema's hard-coded accelerations
    to 1e-12), 400 steps of 2e-3 s give Kynema's published state.q at 0.8 s, centre-of-mass
    displacement and quaternion (measured 2.4e-12 and 1.1e-11), here on gyrolab's own pinned experiment
    (conf/experiment/bruls_heavy_top.yaml: body axes (e1, −e2, −e3), q0 = Rx(180°)), so Kynema's frame
    is checked too: its quaternion is gyrolab's times (0, −1, 0, 0)."""
    from helpers import experiment_scene

    sc = experiment_scene("bruls_heavy_top")
    w0, q0 = tuple(sc.omega0), tuple(sc.q0)
    module = get_method(KYNEMA_MODEL)
    c0 = np.array(module.start(w0, q0, sc.body))
    assert np.allclose(c0[:3], X_COM0, rtol=0, atol=1e-15)  # the centre of mass, lab
    assert np.abs(c0[6:9] - X_DDOT0).max() < 1e-12 and np.abs(c0[9:12] - OMEGA_DOT0).max() < 1e-9
    w, q, c = _run_named(KYNEMA_MODEL, 2e-3, 400, sc.body, w0, q0)
    q_kynema = quat_mul(q, (0.0, -1.0, 0.0, 0.0))
    assert np.abs(c[:3] - X_COM0 - PUBLISHED_Q[:3]).max() < 1e-11  # measured 2.4e-12 m
    assert np.abs(np.array(q_kynema) - PUBLISHED_Q[3:]).max() < 1e-10  # measured 1.1e-11


def test_newtons_test_is_a_parameter():
    """Newton's tolerance and cap are parameters (Kynema's atol 1e-5, rtol 1e-3, 10 by default): with the
    test at 1e-8 the centre-of-mass model converges further every step and comes closer to Kynema's
    published state (centre of mass 4.4e-14 m and quaternion 6.8e-13, against 2.4e-12 and 1.1e-11 at the
    defaults: the published numbers are the converged solution, tests/kynema_genalpha.py; at 1e-11 the
    test sits on the rounding of the multipliers and a step fails to pass it); capped at 2 iterations
    (Kynema's top needs 3) a step fails and the state is NaN from then on, which a run reports as
    non-finite."""
    from helpers import experiment_scene

    sc = experiment_scene("bruls_heavy_top")
    w0, q0 = tuple(sc.omega0), tuple(sc.q0)
    _, q, c = _run_named("lie_genalpha(mass=15,atol=1e-8,rtol=1e-8)", 2e-3, 400, sc.body, w0, q0)
    q_kynema = quat_mul(q, (0.0, -1.0, 0.0, 0.0))
    assert np.abs(np.array(q_kynema) - PUBLISHED_Q[3:]).max() < 3e-12  # measured 6.8e-13
    assert np.abs(c[:3] - X_COM0 - PUBLISHED_Q[:3]).max() < 3e-13  # measured 4.4e-14 m
    w, q, _ = _run_named("lie_genalpha(mass=15,iterations=2)", 2e-3, 1, sc.body, w0, q0)
    assert np.isnan(w).all() and np.isnan(q).all()


def test_the_two_node_models_are_one_continuous_top():
    """Where the node sits is a choice of discretisation, not of physics (the continuous top is the same
    for any mass the record's M g c is split into): over 0.1 s both models converge as h² to the
    centre-of-mass node's run at h/4 (quaternion: 4.9e-6 and 1.2e-6 for the centre-of-mass node at
    h = 4e-4 and 2e-4 s, 4.3e-4 and 1.1e-4 for the node at the pivot: order 2.0 each)."""
    diffs = []
    for h in (4e-4, 2e-4):
        n = round(0.1 / h)
        _, q_pivot, _ = _run_named("lie_genalpha", h, n, PIVOT_BODY, W0, Q0)
        _, q_com, _ = _run_named(KYNEMA_MODEL, h, n, PIVOT_BODY, W0, Q0)
        _, q_fine, _ = _run_named(KYNEMA_MODEL, h / 4, 4 * n, PIVOT_BODY, W0, Q0)
        diffs.append((np.abs(q_com - q_fine).max(), np.abs(q_pivot - q_fine).max()))
    for model in (0, 1):
        assert 1.8 < math.log2(diffs[0][model] / diffs[1][model]) < 2.2, diffs
    assert diffs[1][0] < 2e-6 and diffs[1][1] < 2e-4, diffs


def test_a_run_threads_the_accelerations_through_the_driver():
    """The runner's path (batch.integrate, driver.make_advance_carried) gives the bits of the stepper
    loop, and differs from restarting the history every step (the contract's ``step`` repeated)."""
    assert carries_state(GENALPHA) and not getattr(GENALPHA, "BLOCKS", True)
    assert not runs_in_blocks("lie_genalpha", 10_000)  # so the runner never cuts its runs in time segments
    n, stride = 40, 10
    bodies = np.array([PIVOT_BODY, Body(2.0, 3.0, 4.0, 0.0)])
    w0, q0 = np.array([W0, (1.0, -2.0, 30.0)]), np.array([Q0, (0.6, 0.8, 0.0, 0.0)])
    out, status, steps = integrate("lie_genalpha", bodies, w0, q0, 1e-3, stride, n // stride + 1)
    assert list(status) == [STATUS_OK, STATUS_OK] and list(steps) == [n, n]
    omega = [FIELDS.index(f"omega_{k}") for k in (1, 2, 3)]
    for i in range(2):
        w, _ = _run(1e-3, n, Body(*bodies[i]), tuple(w0[i]), tuple(q0[i]))
        assert np.array_equal(out[i, -1, omega], w)
    w, q = W0, Q0
    for _ in range(n):
        w, q = GENALPHA.step(w, q, 1e-3, PIVOT_BODY)
    assert np.abs(np.array(w) - out[0, -1, omega]).max() > 1e-4  # the history matters (3.8e-4 rad/s)


def test_a_step_that_does_not_converge_ends_the_run_unconverged():
    """Ten Newton iterations cannot converge a step that turns the body by radians: the step returns
    NaN (not a wrong state), and the run's status says so: unconverged, not a blow-up."""
    body = Body(1.0, 2.0, 3.0, 0.0)
    w, q = GENALPHA.step((300.0, -200.0, 100.0), Q0, 0.2, body)
    assert all(math.isnan(v) for v in (*w, *q))
    out, status, _ = integrate("lie_genalpha", np.array([body]), np.array([(300.0, -200.0, 100.0)]), [Q0], 0.2, 1, 3)
    assert status[0] == STATUS_UNCONVERGED and np.isnan(out[0, 1:]).all()


def test_the_registry_checks_a_carried_methods_contract_in_one_line():
    """A method with ``step_carried`` must also have ``start``, both numba functions, and must stay off
    the block path and the driven loop (they carry (ω, q) only)."""
    broken = types.ModuleType("gyrolab.kernels.methods.carried")
    broken.__doc__ = "carried: a method that carries state, half written"
    broken.ORDER, broken.SYMPLECTIC, broken.PRESERVES = 2, False, ()
    broken.step, broken.step_driven = GENALPHA.step, GENALPHA.step
    broken.step_carried = lambda w, q, c, dt, body: (w, q, c)
    with pytest.raises(TypeError) as err:
        register("carried", broken)
    message = str(err.value)
    assert "\n" not in message
    for part in ("must define start", "must define step_carried", "BLOCKS = False", "cannot define step_driven"):
        assert part in message


def test_the_stepper_of_a_method_without_carried_state_is_its_step():
    start, step_carried = stepper(METHODS["rk4"])
    w, q, body = (1.0, -2.0, 30.0), (0.6, 0.8, 0.0, 0.0), Body(2.0, 3.0, 4.0, 1.5)
    c = start(w, q, body)
    assert step_carried(w, q, c, 1e-3, body) == (*METHODS["rk4"].step(w, q, 1e-3, body), c)
