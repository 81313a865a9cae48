"""Kynema's heavy top, re-run by an independent numpy transcription of its Lie-group
generalized-alpha step (tests/kynema_genalpha.py, read from kynema/kynema at commit d3b403dc).

Measured agreement (this machine, numpy float64):

* Kynema's published state.q at t = 0.8 s (tests/regression_tests/regression/test_heavy_top.cpp,
  asserted there to 1e-10): max abs difference 2.1e-11 over the 3 displacement and 4 quaternion
  components (quaternion w component; the rest <= 4.3e-12), every step converging in 3 Newton
  iterations.  Asserted here to 3e-11.
* The published numbers are the fully converged generalized-alpha solution: forcing >= 4 Newton
  iterations a step gives 8e-14.  Why Kynema's own run (3 iterations by the code as read) lands
  there is not resolved; the 2e-11 is not roundoff (float64 vs 80-bit: 1.6e-14).
* With the tangent operator untransposed (Kynema before commit ebd716ad, 2025-03-20) the
  transcription reproduces the heavy-top numbers published before that commit to 2.6e-13 -- a
  path-sensitive check (6-10 loosely converged Newton iterations a step; converging them fully
  moves the result by 6e-5).
* Kynema's precession test (free body, no constraint): 6.7e-16.
* Against an accurate solution of the pivoted rigid body (DOP853, rtol = atol = 1e-12): centre
  of mass off by 4.62e-3 m at h = 2e-3 and 1.15e-3 m at h = 1e-3 (order 2.00).

The pivot constraint holds to 6.7e-16 at every step and |q| = 1 to 2.1e-15.
"""

import numpy as np
import pytest
from kynema_genalpha import (
    GRAVITY,
    J_COM,
    MASS,
    OMEGA0,
    PRECESSION_PUBLISHED_QUAT,
    PUBLISHED_Q,
    X_COM0,
    pivot_residual,
    quat_compose,
    quat_to_matrix,
    run,
    run_precession,
)
from scipy.integrate import solve_ivp

# Kynema's heavy-top numbers before commit ebd716ad ("Transpose tangent matrix in
# CalculateTangentOperator{}"), set in commit 38aae826 (2025-01-17).
PUBLISHED_Q_BEFORE_EBD716AD = np.array(
    [
        -0.42217588230602943,
        -0.094581314972310801,
        -0.044548054997683689,
        -0.17925889552379232,
        0.21677585003948013,
        -0.95946635439403072,
        -0.017285658826872257,
    ]
)


@pytest.fixture(scope="module")
def heavy_top_run():
    """The published configuration, with per-step records."""
    record = {"phi": [], "qnorm": [], "iterations": []}

    def callback(step, s, iterations):
        record["phi"].append(np.abs(pivot_residual(s)).max())
        record["qnorm"].append(np.linalg.norm(s["q"][0, 3:]))
        record["iterations"].append(iterations)

    s = run(h=0.002, n_steps=400, rho_inf=0.9, callback=callback)
    return s, record


def test_reproduces_kynemas_published_state_at_0p8s(heavy_top_run):
    s, record = heavy_top_run
    diff = s["q"][0] - PUBLISHED_Q
    assert np.abs(diff).max() < 3e-11, diff
    assert set(record["iterations"]) == {3}


def test_pivot_holds_and_quaternion_stays_unit_at_every_step(heavy_top_run):
    """The index-3 pivot constraint is solved to roundoff at every step (not merely at the end),
    so the centre of mass stays on the unit sphere about the pivot; the rotation stays a unit
    quaternion although Kynema never renormalises."""
    s, record = heavy_top_run
    assert len(record["phi"]) == 400
    assert max(record["phi"]) < 1e-14
    assert np.abs(np.array(record["qnorm"]) - 1.0).max() < 1e-13
    assert abs(np.linalg.norm(X_COM0 + s["q"][0, :3]) - 1.0) < 1e-13
    assert np.abs(s["q"][1, :3]).max() < 1e-14  # the ground node stays at the origin


def test_published_state_is_the_fully_converged_solution():
    """Diagnostic: more Newton iterations close the 2e-11 gap to roundoff."""
    q = run(min_iter=4)["q"][0]
    assert np.abs(q - PUBLISHED_Q).max() < 3e-13


def test_untransposed_tangent_reproduces_the_numbers_published_before_ebd716ad():
    q = run(transpose_tangent=False)["q"][0]
    assert np.abs(q - PUBLISHED_Q_BEFORE_EBD716AD).max() < 2e-12
    assert np.abs(q - PUBLISHED_Q).max() > 1e-5  # the two published states do differ


def test_reproduces_kynemas_precession_test():
    s = run_precession()
    assert np.abs(s["q"][0, :3]).max() == 0.0
    assert np.abs(s["q"][0, 3:] - PRECESSION_PUBLISHED_QUAT).max() < 1e-13


def _reference_com_at(t_end):
    """Pivoted rigid body, body frame: I_p W' = c x (R^T m g) - W x I_p W, q' = q (x) (0, W) / 2,
    I_p = J + m (|c|^2 1 - c c^T); centre of mass at R c."""
    c = X_COM0
    ip = np.diag(J_COM) + MASS * ((c @ c) * np.eye(3) - np.outer(c, c))
    ip_inv = np.linalg.inv(ip)

    def rhs(t, y):
        q, w = y[:4], y[4:]
        torque = np.cross(c, quat_to_matrix(q).T @ (MASS * GRAVITY))
        return np.concatenate([0.5 * quat_compose(q, np.array([0.0, *w])), ip_inv @ (torque - np.cross(w, ip @ w))])

    y0 = np.concatenate([[1.0, 0.0, 0.0, 0.0], OMEGA0])
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    q = sol.y[:4, -1] / np.linalg.norm(sol.y[:4, -1])
    return quat_to_matrix(q) @ c


@pytest.mark.slow
def test_second_order_against_an_accurate_solution():
    x_ref = _reference_com_at(0.8)
    errors = []
    for h, n in [(2e-3, 400), (1e-3, 800)]:
        x = X_COM0 + run(h=h, n_steps=n)["q"][0, :3]
        errors.append(np.linalg.norm(x - x_ref))
    assert 4.4e-3 < errors[0] < 4.8e-3  # measured 4.62e-3 m
    order = np.log2(errors[0] / errors[1])
    assert 1.95 < order < 2.05  # measured 2.002
