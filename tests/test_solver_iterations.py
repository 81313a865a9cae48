"""Implicit methods count their solver's iterations per run, and a step whose solver does not converge
ends its run with its own status (kernels/methods/README.md, "Solvers"; kernels/driver.py)."""

import types

import numpy as np
import pytest
from numba import njit

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.driver import STATUS_OK, STATUS_UNCONVERGED
from gyrolab.kernels.registry import METHODS, counts_iterations, get_method, register, uses_blocks
from gyrolab.kernels.scenes import build_scene

SOLVER_METHODS = sorted(name for name, module in METHODS.items() if counts_iterations(module))
# Each method's cap on iterations in one step (its declared constant) and where it converges quickly
CAPS = {
    "dlpoly_fiqa": None,  # two loops: q_update's (MXQUAT) and the synchronisation's
    "implicit_midpoint": "MAX_ITERATIONS",
    "lgvi": "MAX_ITERATIONS",
    "lie_genalpha": "MAX_ITERATIONS",
    "midpoint_free": "MAX_NEWTON_ITERATIONS",
    "simo_wong": "MAX_ITERATIONS",
    "solfec_imp": "MAX_ITERATIONS",
}


def top_batch(n=2, f=10.0, scene="heavy_top"):
    sc = build_scene(scene, f, 45.0)
    return np.array([sc.body] * n), np.array([sc.omega0] * n), np.array([sc.q0] * n)


def run(method, dt, n_samples=40, stride=10, scene="heavy_top"):
    bodies, omega0, q0 = top_batch(scene=scene)
    iterations = np.full((len(bodies), 2), -7, np.int64)
    out, status, n_steps = integrate(method, bodies, omega0, q0, dt, stride, n_samples, iterations=iterations)
    return out, status, n_steps, iterations


def test_the_implicit_methods_are_the_ones_that_count():
    """Every method with a solver loop per step counts (and runs one by one); the explicit ones do not."""
    assert SOLVER_METHODS == sorted(CAPS)
    for name in SOLVER_METHODS:
        assert not uses_blocks(METHODS[name]), name
    for name in ("rk4", "lie_poisson", "seed_next", "chrono_euler", "no_squish"):
        assert not counts_iterations(METHODS[name]), name


@pytest.mark.parametrize("method", SOLVER_METHODS)
def test_a_converging_run_counts_its_iterations(method):
    """At a small step every step converges: status ok, at least one iteration a step on average (the
    state moves, so the first guess is never the solution), none over the cap; the counted step is the
    plain step's bits (same samples as stepping ``step`` by hand)."""
    out, status, n_steps, iterations = run(method, 2e-4)
    assert (status == STATUS_OK).all()
    total, most = iterations[0]
    assert np.array_equal(iterations[0], iterations[1])  # same inputs, same counts
    assert n_steps[0] <= total <= n_steps[0] * most
    cap = CAPS[method]
    assert 1 <= most <= (getattr(METHODS[method], cap) if cap else 160)
    module = get_method(method)
    bodies, omega0, q0 = top_batch(n=1)
    from gyrolab.kernels.registry import stepper

    start, step_carried = stepper(module)
    w, q = tuple(omega0[0]), tuple(q0[0])
    c = start(w, q, bodies[0])
    for _ in range(10):
        w, q, c = step_carried(w, q, c, 2e-4, bodies[0])
    assert np.array_equal(out[0, 1, 3:6], np.array(w))


@pytest.mark.parametrize("method", SOLVER_METHODS)
def test_a_step_that_does_not_converge_ends_the_run_unconverged(method):
    """Too large a step for the iteration to contract: the run stops at the sample after the failed
    step with status unconverged (not "non-finite"), NaN from there on, and the iterations it spent counted."""
    if method == "midpoint_free":
        pytest.skip("MuJoCo's midpoint Newton goes on from its last iterate at the cap; so does its reproduction")
    if method == "lie_genalpha":
        method = "lie_genalpha(iterations=1)"  # Newton at its default converges at any dt here
    out, status, n_steps, iterations = run(method, 0.1, n_samples=20, stride=5)
    assert (status == STATUS_UNCONVERGED).all(), status
    stopped = int(np.argmax(np.isnan(out[0, :, 6])))
    assert stopped >= 1 and np.isnan(out[0, stopped:]).all() and np.isfinite(out[0, :stopped]).all()
    assert n_steps[0] == stopped * 5
    assert iterations[0, 1] >= 1 and iterations[0, 0] >= iterations[0, 1]


def test_explicit_methods_count_zero_and_the_driven_path_counts_too():
    """rk4 has no solver (0, 0) on both paths; a driven body (run_batch_driven) counts as the free one."""
    for path in ("runs", "blocks"):
        bodies, omega0, q0 = top_batch(n=64)
        iterations = np.full((64, 2), -7, np.int64)
        integrate("rk4", bodies, omega0, q0, 1e-3, 5, 4, path=path, iterations=iterations)
        assert not iterations.any(), path
    out, status, n_steps, iterations = run("implicit_midpoint", 1e-3, scene="forced_body")
    assert (status == STATUS_OK).all() and (iterations[:, 0] >= n_steps).all() and (iterations[:, 1] >= 1).all()


def test_iterations_must_be_a_writable_int64_pair_per_run():
    bodies, omega0, q0 = top_batch()
    for bad in (np.zeros((2, 2)), np.zeros((3, 2), np.int64), np.zeros((2, 2), np.int64)[:, ::-1]):
        with pytest.raises(ValueError, match="iterations"):
            integrate("rk4", bodies, omega0, q0, 1e-3, 5, 4, iterations=bad)


def test_the_registry_refuses_a_counted_solver_that_is_incomplete():
    """A method with step_counted must run one by one and count every step it has."""

    @njit
    def step(w, q, dt, body):
        return w, q

    @njit
    def step_counted(w, q, dt, body):
        return w, q, 1

    module = types.ModuleType("gyrolab.kernels.methods.broken_solver")
    module.ORDER, module.SYMPLECTIC, module.PRESERVES = 1, False, ()
    module.step, module.step_counted, module.step_driven = step, step_counted, step
    with pytest.raises(TypeError) as err:
        register("broken_solver", module)
    assert "step_driven_counted" in str(err.value) and "BLOCKS = False" in str(err.value)
