"""Error against dt for the cost tables of bench_kernels.py: nutation bounds and energy.

``scan(method, scene, dt, t_end)`` steps one run with the method's own step
and returns (relative error of the θ extrema against the closed-form nutation
bounds, max |E − E0| / E0).  Each extremum of u = cos θ between two steps is
located by re-stepping from the step before it with 16 fractions of the step
(one step of size τ each) and a parabola through the best three: the
location error is ~(Ω dt/8)⁴ of the nutation amplitude, far below the
method's own error, so the scan measures the method, not the sampling.

``dt_for(ladder, target)``: the dt (or tolerance) at which an error reaches a
target, interpolated log-log between the ladder points that bracket it.
"""

import math
import time

import numpy as np
from numba import njit

from gyrolab.kernels.closed_form import heavy_top_nutation, scene_rotation
from gyrolab.kernels.lanes import ieee_step
from gyrolab.kernels.reference import rhs
from gyrolab.kernels.registry import METHODS, stepper
from gyrolab.kernels.rigid_body import energy

MAX_EXTREMA = 4096
_SCANS = {}


def _make_scan(start, step_carried, step):
    @njit
    def u_after(w, q, tau, body):
        _, q = step(w, q, tau, body)
        return q[0] * q[0] + q[3] * q[3] - q[1] * q[1] - q[2] * q[2]

    @njit
    def scan(w, q, dt, body, n, u_ext, sign):
        e0 = energy(w, q, body)
        worst = 0.0
        c = start(w, q, body)
        w2, q2 = w, q  # state at step k − 2
        u2 = q[0] * q[0] + q[3] * q[3] - q[1] * q[1] - q[2] * q[2]
        w, q, c = step_carried(w, q, c, dt, body)
        u1 = q[0] * q[0] + q[3] * q[3] - q[1] * q[1] - q[2] * q[2]
        found = 0
        for _ in range(n - 1):
            w1, q1 = w, q
            w, q, c = step_carried(w, q, c, dt, body)
            worst = max(worst, abs(energy(w, q, body) - e0))
            u0 = q[0] * q[0] + q[3] * q[3] - q[1] * q[1] - q[2] * q[2]
            s = 1.0 if u1 > u2 else -1.0
            if (u1 - u2) * (u0 - u1) < 0.0 and found < u_ext.size:
                # extremum of u in (t_{k-2}, t_k): 17 values at τ = j·2dt/16 from state k − 2
                best, jbest = s * u2, 0
                vals = np.empty(17)
                for j in range(17):
                    vals[j] = u_after(w2, q2, j * dt / 8.0, body) if j else u2  # τ = 0: no step to take
                    if s * vals[j] > best:
                        best, jbest = s * vals[j], j
                jbest = min(max(jbest, 1), 15)
                a, b, c = vals[jbest - 1], vals[jbest], vals[jbest + 1]
                den = a - 2.0 * b + c
                d = 0.5 * (a - c) / den if den != 0.0 else 0.0
                u_ext[found] = b - 0.25 * (a - c) * d
                sign[found] = s
                found += 1
            if not math.isfinite(u0):
                return found, math.inf
            w2, q2, u2, u1 = w1, q1, u1, u0
        return found, worst / abs(e0)

    return scan


def scan(method, scene, dt, t_end):
    """(max relative error of θ_min and θ_max, max |E − E0|/E0) of one run of ``t_end`` s."""
    if method not in _SCANS:
        module = METHODS[method]
        # The run threads a method's carried state (registry.stepper); the re-steps that locate an
        # extremum start afresh from the saved (ω, q) with the method's ``step`` (for a method that
        # carries state, its first step from a consistent start: an interpolant whose error is one
        # step's local error, still below the run's own).  IEEE division: a blow-up gives NaN.
        _SCANS[method] = _make_scan(*stepper(module), ieee_step(module.step))
    u_ext, sign = np.empty(MAX_EXTREMA), np.empty(MAX_EXTREMA)
    n = int(round(t_end / dt))
    found, e_err = _SCANS[method](tuple(scene.omega0), tuple(scene.q0), dt, tuple(scene.body), n, u_ext, sign)
    return _bound_error(u_ext[:found], sign[:found], heavy_top_nutation(scene)), e_err


def _bound_error(u_ext, sign, nut):
    """Worst relative error of the θ extrema: maxima of u = cos θ are θ_min, minima θ_max."""
    theta = np.arccos(np.clip(u_ext, -1.0, 1.0))
    tops, bottoms = theta[sign > 0], theta[sign < 0]
    if tops.size < 2 or bottoms.size < 2 or not np.all(np.isfinite(theta)):
        return math.inf
    return float(max(np.max(np.abs(tops / nut.theta_min - 1)), np.max(np.abs(bottoms / nut.theta_max - 1))))


def dop853_point(scene, t_end, rtol):
    """scipy DOP853 on (ω, R) at rtol = atol: (wall s per simulated s, nutation bound error, steps).

    Timed: the solve with dense output; not timed: evaluating it every 1e-4 s and
    locating the θ extrema (parabola through 3 samples: ~1e-12 relative).
    """
    from scipy.integrate import solve_ivp

    y0 = np.concatenate((np.asarray(scene.omega0, float), scene_rotation(scene).as_matrix().ravel()))
    args = tuple(float(v) for v in scene.body)
    start = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=rtol, dense_output=True, args=args)
    wall = time.perf_counter() - start
    h = 1e-4
    u = sol.sol(np.arange(int(t_end / h) + 1) * h)[11]  # R[2, 2] = cos θ
    k = np.nonzero((u[1:-1] - u[:-2]) * (u[2:] - u[1:-1]) < 0)[0] + 1
    a, b, c = u[k - 1], u[k], u[k + 1]
    d = 0.5 * (a - c) / (a - 2 * b + c)
    u_ext = b - 0.25 * (a - c) * d
    sign = np.where(b > a, 1.0, -1.0)
    return wall / t_end, _bound_error(u_ext, sign, heavy_top_nutation(scene)), sol.t.size - 1


def dt_for(ladder, target):
    """(x, flag): the x (dt or tolerance) where the error reaches ``target``.

    ``ladder`` = [(x, error)] from coarse to fine.  Bracketed by the finest point
    still above target and the next finer one, interpolated log-log (flag "");
    below the ladder's finest point, extrapolated with the slope of its last two
    finite points (flag "~"); None if the errors never fall.
    """
    pts = [(x, e) for x, e in ladder if math.isfinite(e) and e > 0]
    if not pts:
        return None, ""
    above = [i for i, (_, e) in enumerate(pts) if e > target]
    if not above:
        return pts[0][0], "<="  # already at the coarsest point
    i = above[-1]
    if i + 1 < len(pts):
        (x0, e0), (x1, e1) = pts[i], pts[i + 1]
        flag = ""
    elif len(pts) >= 2:
        (x0, e0), (x1, e1) = pts[-2], pts[-1]
        flag = "~"
    else:
        return None, ""
    if not (e1 < e0 and x1 != x0):
        return None, ""
    slope = math.log(e1 / e0) / math.log(x1 / x0)
    return x0 * (target / e0) ** (1.0 / slope), flag
