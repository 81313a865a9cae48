"""kernels/compose.py: a composition is its table of weights; the composers compute the substeps.

What is checked: the substep sizes, start times and merged kicks the composers hand to the base
step are exactly (bit for bit) the partial sums of the weights they replace in hand-unrolled code;
a one-weight kick composition is the Strang step (lie_poisson's); a kick composition of zero length is
the identity bit for bit, and runs the whole table at any other dt; weights that do not sum to 1 are refused.
The composed methods' bits against the stored data are tests/test_regression.py's, their order
tests/test_methods.py's and tests/test_forced_body.py's.
"""

import numpy as np
import pytest
from numba import njit

from gyrolab.kernels.body import Body
from gyrolab.kernels.compose import compose_kicks, compose_steps
from gyrolab.kernels.free_flow import free_flow, kick_at
from gyrolab.kernels.methods import lie_poisson, split6_exact, suzuki4_exact

W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = 1.0 - 2.0 * W1


@njit(error_model="numpy")
def _record_start(w, q, t, h, body):
    """A 'step' that shifts its start time t and size h into the state (w keeps the last three t)."""
    return (w[1], w[2], t), (q[1], q[2], q[3], h)


@njit(error_model="numpy")
def _record_kick(w, q, h, t, body):
    """A 'kick' that shifts the kick's time into w and its size into q."""
    return w[1], w[2], t


@njit(error_model="numpy")
def _record_flow(w, q, h, body):
    return w, (q[1], q[2], q[3], h)


# a heavy body with a drive (a torque that depends on time)
DRIVEN_BODY = Body(0.02, 0.025, 0.008, 0.98, 0.29, 0.1, 0.1, -0.2, 0.3, 2.0, 0.0, 10.0)


def _random_states(seed, n=20):
    """n random (ω (rad/s), unit q, t (s), dt (s)), body frame."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        w = tuple(rng.normal(scale=20.0, size=3))
        q = rng.normal(size=4)
        yield w, tuple(q / np.linalg.norm(q)), float(rng.uniform(0, 10)), float(rng.uniform(1e-4, 1e-2))


def test_whole_substeps_start_at_the_partial_sums():
    """compose_steps over (w1, w0, w1): substeps of w1 dt, w0 dt, w1 dt from t, t + w1 dt,
    t + (w1 + w0) dt, the times lie_poisson4 computed by hand."""
    composed = compose_steps(_record_start, (W1, W0, W1))
    t, dt = 0.37, 1e-3
    w, q = composed((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), t, dt, Body(1.0, 1.0, 1.0, 0.0))
    assert w == (t, t + W1 * dt, t + (W1 + W0) * dt)
    assert q[1:] == (W1 * dt, W0 * dt, W1 * dt)


def test_merged_kicks_hold_the_time_the_flows_reached():
    """compose_kicks over (w1, w0, w1): kicks at t, t1 = t + w1 dt, t1 + w0 dt and t + dt (the last
    three kept), flows of w1 dt, w0 dt, w1 dt: the times strang_exact4 computed by hand."""
    composed = compose_kicks(_record_kick, _record_flow, (W1, W0, W1))
    t, dt = 0.37, 1e-3
    w, q = composed((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), t, dt, Body(1.0, 1.0, 1.0, 0.0))
    t1 = t + W1 * dt
    assert w == (t1, t1 + W0 * dt, t + dt)
    assert q[1:] == (W1 * dt, W0 * dt, W1 * dt)


def test_one_weight_is_the_strang_step():
    """compose_kicks(kick_at, free_flow, (1.0,)) is lie_poisson's step_driven (kick, flow, kick) bit
    for bit, on a driven heavy body at random states."""
    composed = compose_kicks(kick_at, free_flow, (1.0,))
    for w, q, t, dt in _random_states(5):
        assert composed(w, q, t, dt, DRIVEN_BODY) == lie_poisson.step_driven(w, q, t, dt, DRIVEN_BODY)


def test_a_kick_composition_of_zero_length_is_the_identity_and_any_other_runs_every_substep():
    """dt = 0: (ω, q) back bit for bit through split6_exact's table and the exact flow, whose own h = 0
    returns its input only to a few roundings; dt = ±1e-300 (the smallest steps): every flow runs."""
    for w, q, t, _ in _random_states(11):
        assert split6_exact.step_driven(w, q, t, 0.0, DRIVEN_BODY) == (w, q)
        assert split6_exact.step(w, q, 0.0, DRIVEN_BODY) == (w, q)
    recorded = compose_kicks(_record_kick, _record_flow, split6_exact.WEIGHTS)
    for dt in (1e-300, -1e-300, 1e-3):
        _, q = recorded((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.0, dt, Body(1.0, 1.0, 1.0, 0.0))
        assert q[1:] == tuple(x * dt for x in split6_exact.WEIGHTS[-3:])  # the last three flows ran


def test_suzuki_weights_are_the_fractal_table():
    """p = 1/(4 − 4^(1/3)): five symmetric weights summing to 1, the middle one 1 − 4p < 0."""
    p = suzuki4_exact.P
    assert suzuki4_exact.WEIGHTS == (p, p, 1.0 - 4.0 * p, p, p)
    assert p == pytest.approx(0.4144907717943757, rel=1e-15)
    assert sum(suzuki4_exact.WEIGHTS) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize("weights", [(), (0.5, 0.4), (W1, W1, W1)])
def test_weights_that_do_not_sum_to_one_are_refused(weights):
    with pytest.raises(ValueError, match="must sum to 1"):
        compose_kicks(_record_kick, _record_flow, weights)
    with pytest.raises(ValueError, match="must sum to 1"):
        compose_steps(_record_start, weights)
