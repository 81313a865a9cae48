"""Fixtures for the physics tests: one run of a scene, and a bare step loop.

Tests that sweep methods parametrise over ``registry.METHODS``, so a newly
registered method inherits every one of them.
"""
import numpy as np
import pytest
from numba import njit

from gyrolab.kernels.batch import integrate, sample_schedule
from gyrolab.kernels.registry import METHODS


def _run_scene(method, scene, dt, t_end, every, threshold=1e9):
    """Samples (n_samples, 9) of one run through the batch engine; asserts status ok.

    The default divergence threshold is huge so that runs which gain or lose
    energy on purpose (seed_prev) are recorded rather than cut off.
    """
    stride, n_samples = sample_schedule(dt, every, t_end)
    samples, status, _ = integrate(
        method, np.array([scene.body]), np.array([scene.omega0]), np.array([scene.q0]), dt, stride, n_samples,
        threshold,
    )
    assert status[0] == 0, f"{method}: run status {status[0]}"
    return samples[0]


_LOOPS = {}


def _step_loop(method):
    """njit function (w, q, dt, body, n) -> (w, q) applying the method's ``step`` n times.

    The batch driver stores only axis and ω; tests that need the whole
    orientation (the quaternion) call the step directly.
    """
    if method not in _LOOPS:
        step = METHODS[method].step

        @njit
        def loop(w, q, dt, body, n):
            for _ in range(n):
                w, q = step(w, q, dt, body)
            return w, q

        _LOOPS[method] = loop
    return _LOOPS[method]


@pytest.fixture(scope="session")
def run_scene():
    """``run_scene(method, scene, dt, t_end, every, threshold=1e9) -> samples (n_samples, 9)``."""
    return _run_scene


@pytest.fixture(scope="session")
def step_loop():
    """``step_loop(method)(w, q, dt, body, n) -> (w, q)``: n bare steps, compiled once per method."""
    return _step_loop
