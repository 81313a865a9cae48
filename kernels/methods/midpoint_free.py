"""midpoint_free: MuJoCo 3.7–3.10's implicit-midpoint rotation of a standalone free body (Newton-solved, torque held).

Followed: google-deepmind/mujoco at tag 3.10.0 (commit 28009f9105cd, 22 Jun
2026), src/engine/engine_forward.c ``midpointNewton``, ``mj_midpoint`` (its
aligned branch: centre of mass at the joint origin), ``midpoint`` and
``mj_implicitSkip`` (qvel_mid, then ``mj_advance`` → src/engine/engine_support.c
``mj_integratePosInd`` → src/engine/engine_util_spatial.c ``mju_quatIntegrate``);
src/engine/engine_util_solve.c ``mju_solve3``.  History (doc/changelog.rst):
added in 3.7.0 for the implicit and implicitfast integrators (commit 0c337799,
13 Apr 2026), restricted in 3.8.1 to implicitfast without fluid forces
(commit 910b3336: "Midpoint integration treats external forces as zero-order-hold
constants, which causes energy gain in the presence of contacts and in fluid
media"), replaced in 3.11.0 by the free-body gyroscopic derivatives (commit
f0fa3d82).  ``midpointNewton`` and ``mj_midpoint`` are the same in 3.7.0 and
3.10.0.  Per step, in the principal body frame (MuJoCo's inertial frame; the
body's iquat is the identity here, and ``mji_rotVecQuat`` copies exactly then):

    τ  = τ(q)  at the start of the step, held over it        (qfrc + qfrc_bias: the applied torque)
    solve (2/h) I (ω_m − ω) + ω_m × Iω_m − τ = 0 for ω_m     (Newton from ω_m = ω, below)
    ω' = 2 ω_m − ω
    q' = mju_quatIntegrate(q, ½(ω' + ω), h) = normalise₄(q) ⊗ axisAngle(ω̂_m, h|ω_m|)

Newton (``midpointNewton``): at most MAX_NEWTON_ITERATIONS iterations; stop when
|f| < NEWTON_TOLERANCE (1 + (2/h)|Iω_m|); J = (2/h) I + ∂(ω × Iω)/∂ω, solved by
``mju_solve3`` (Gauss–Jordan, no pivoting); backtracking line search, at most
MAX_LINE_SEARCH halvings, a step taken only if it lowers |f| (none: ω_m stays).
The products are written in MuJoCo's order (``mji_cross``, ``mju_norm3``).  The
tolerance's absolute part (1e-13 N m) dominates for gyrolab's 1e-4 kg m² bodies
at large h: ω' is then off the exact midpoint solution by up to ~3e-13
relative (tests/test_presets.py), which bounds how well |Iω| is kept.

MuJoCo applies it only to a free joint of a childless body that is awake and in
no constraint; gyrolab's gravity torque enters here as that body's applied
torque (``xfrc_applied``), evaluated at the start of the step as MuJoCo's
zero-order hold does.  A ball-jointed top is not eligible in MuJoCo (it takes
implicitfast's update, mujoco_implicitfast); this method integrates it with
the free-body formula.  The midpoint rule keeps the quadratic invariants of
the torque-free ω equation (|Iω|², and ½ ω·Iω: "conserving kinetic energy to
machine precision in the absence of external torques", 3.7.0's changelog) to
the Newton tolerance; with a torque held at its start value the energy is
not kept.  The orientation step is the exponential, not the Cayley map that
would match the midpoint ω update, so the lab L drifts.  Not a Poisson map
(see implicit_midpoint).  Order 2 on a free body, 1 with a torque that
depends on q (held over the step).  Conformance: the mujoco wheel of the
engines extra (4.0) no longer has the scheme; against mujoco 3.10.0 installed
in a second venv, python -m gyrolab.analysis.reports.mujoco_versions
(docs/engines/mujoco_versions.md, tests/test_mujoco_versions.py with
GYROLAB_MUJOCO_OTHER_PYTHON) compares it with implicitfast step by step.
"""

import math

from numba import njit

from ..engine_common import mj_normalize4, mj_quat_integrate
from ..rigid_body import gravity_torque

ORDER = 1  # the torque is held at its start-of-step value (zero-order hold)
FREE_ORDER = 2  # torque-free: the implicit midpoint rule
SYMPLECTIC = False
# judged by conformance with the engine (tests/test_engines.py)
REPRODUCES = "MuJoCo 3.10 implicitfast midpoint rule for free bodies"
# |Iω|² is a quadratic invariant of the torque-free ω equation, which the midpoint rule keeps, but only to
# the Newton tolerance: over the verdict's 1e6 steps of 1e-3 s on the free asymmetric body |L| drifts
# 5.6e-14 /s, above its 0.1 eps a step (docs/verdict.md), so L_norm is not declared (nor the energy: the
# heavy top's is not kept, and PRESERVES must hold on every scene conserving the invariant).
# For I1 = I2 with τ3 = 0 the third row of the Newton system is (0, 0, 2 I3 / h | −f3), f3 a rounding-level
# difference of ω1 (I ω2) and ω2 (I ω1): ω3 stays (measured: bit-identical over 5000 steps of the heavy top).
PRESERVES = ("L3",)

BLOCKS = False  # a Newton loop per step: the lanes do not vectorise it, and its iterations are counted
MAX_NEWTON_ITERATIONS = 100  # midpointNewton: for (niter=0; niter < 100; niter++)
MAX_LINE_SEARCH = 20  # backtracking halvings per Newton step, midpointNewton: for (ls=0; ls < 20; ls++)
NEWTON_TOLERANCE = 1e-13  # N m, midpointNewton: stop at |f| < tol (1 + (2/h)|Iω_m|) (1e-6 with mjUSESINGLE)


@njit(cache=True, error_model="numpy")
def mj_solve3(A, b):
    """``mju_solve3``: x with A x = b by Gauss–Jordan elimination without pivoting (A: 9 floats, row-major)."""
    m00, m01, m02, m03 = A[0], A[1], A[2], b[0]
    m10, m11, m12, m13 = A[3], A[4], A[5], b[1]
    m20, m21, m22, m23 = A[6], A[7], A[8], b[2]
    # i = 0
    p = m00
    m00, m01, m02, m03 = m00 / p, m01 / p, m02 / p, m03 / p
    f = m10
    m10, m11, m12, m13 = m10 - f * m00, m11 - f * m01, m12 - f * m02, m13 - f * m03
    f = m20
    m20, m21, m22, m23 = m20 - f * m00, m21 - f * m01, m22 - f * m02, m23 - f * m03
    # i = 1
    p = m11
    m11, m12, m13 = m11 / p, m12 / p, m13 / p
    f = m01
    m01, m02, m03 = m01 - f * m11, m02 - f * m12, m03 - f * m13
    f = m21
    m21, m22, m23 = m21 - f * m11, m22 - f * m12, m23 - f * m13
    # i = 2
    p = m22
    m22, m23 = m22 / p, m23 / p
    f = m02
    m02, m03 = m02 - f * m22, m03 - f * m23
    f = m12
    m12, m13 = m12 - f * m22, m13 - f * m23
    return m03, m13, m23


@njit(cache=True, error_model="numpy")
def mj_cross(a, b):
    """``mji_cross``: a × b in MuJoCo's order of operations."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy")
def mj_norm3(v):
    """``mju_norm3``."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True, error_model="numpy")
def midpoint_residual(wm, w, tau, i2h, body):
    """f = (2/h) I (ω_m − ω) + ω_m × Iω_m − τ and Iω_m, as midpointNewton forms them."""
    Iw = (body[0] * wm[0], body[1] * wm[1], body[2] * wm[2])
    c = mj_cross(wm, Iw)
    f = (
        i2h * body[0] * (wm[0] - w[0]) + c[0] - tau[0],
        i2h * body[1] * (wm[1] - w[1]) + c[1] - tau[1],
        i2h * body[2] * (wm[2] - w[2]) + c[2] - tau[2],
    )
    return f, Iw


@njit(cache=True, error_model="numpy")
def midpoint_newton(w, tau, h, body):
    """``midpointNewton``: the midpoint angular velocity ω_m (rad/s), body frame, and the Newton
    iterations taken (MAX_NEWTON_ITERATIONS: the cap reached, ω_m the last iterate, as MuJoCo keeps it)."""
    i2h = 2.0 / h
    dI0, dI1, dI2 = body[2] - body[1], body[0] - body[2], body[1] - body[0]
    # i2h_I[k] = i2h * inertia[k], precomputed in MuJoCo; (i2h * I) * x is what midpoint_residual does
    a0, a1, a2 = i2h * body[0], i2h * body[1], i2h * body[2]
    wm = w
    n = 0
    while n < MAX_NEWTON_ITERATIONS:
        f, Iw = midpoint_residual(wm, w, tau, i2h, body)
        fnorm = mj_norm3(f)
        if fnorm < NEWTON_TOLERANCE * (1.0 + i2h * mj_norm3(Iw)):
            break
        n += 1
        J = (
            a0, wm[2] * dI0, wm[1] * dI0,
            wm[2] * dI1, a1, wm[0] * dI1,
            wm[1] * dI2, wm[0] * dI2, a2,
        )  # fmt: skip
        delta = mj_solve3(J, (-f[0], -f[1], -f[2]))
        step = 1.0
        for _ls in range(MAX_LINE_SEARCH):
            w_try = (wm[0] + step * delta[0], wm[1] + step * delta[1], wm[2] + step * delta[2])
            f_try, _ = midpoint_residual(w_try, w, tau, i2h, body)
            if mj_norm3(f_try) < fnorm:
                wm = w_try
                break
            step *= 0.5
    return wm, n


@njit(cache=True, error_model="numpy", forceinline=True)
def step_counted(w, q, dt, body):
    """One step of dt seconds (s) and its Newton iterations (never < 0: at the cap MuJoCo goes on, and
    so does this reproduction; a run's ``solver_iterations_max`` of MAX_NEWTON_ITERATIONS shows it)."""
    # qfrc at the start of the step, from mj_forward's (normalised) orientation
    tau = gravity_torque(mj_normalize4(q), body)
    wm, n = midpoint_newton(w, tau, dt, body)
    w_new = (2.0 * wm[0] - w[0], 2.0 * wm[1] - w[1], 2.0 * wm[2] - w[2])
    # mj_implicitSkip: qvel_mid = 0.5 * (qvel_new + qvel_old), then mj_advance integrates q with it
    w_mid = (0.5 * (w_new[0] + w[0]), 0.5 * (w_new[1] + w[1]), 0.5 * (w_new[2] + w[2]))
    return w_new, mj_quat_integrate(q, w_mid, dt), n


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds (s): step_counted without its count."""
    w1, q1, _ = step_counted(w, q, dt, body)
    return w1, q1
