"""lammps_richardson: LAMMPS fix rigid's velocity-Verlet step with the Richardson-extrapolated quaternion update.

Source: lammps/lammps src/math_extra.cpp ``MathExtra::richardson``, ``mq_to_omega``,
``angmom_to_omega``, ``q_to_exyz``, ``quat_to_mat`` (commit 012003c6; the same text at bb720626),
src/math_extra.h ``vecquat``, ``qnormalize``, ``matvec``, ``transpose_matvec`` (commit 02dd3c39), as
called from src/RIGID/fix_rigid.cpp ``FixRigid::initial_integrate`` and ``final_integrate`` (commit
00b92cd9; ``rigid/small`` calls the same ``richardson``).  LAMMPS carries the space-frame angular
momentum m (``angmom``), the principal-axis quaternion q (body → space, as gyrolab's) and its
columns ex, ey, ez (``q_to_exyz``).  One step of dt, with dtf = dtq = dt/2 (``init``: ``dtf = 0.5 * dt
* ftm2v``, ``dtq = 0.5 * dt``):

- ``initial_integrate``: m += dtf · τ (space-frame torque at t); ω = ``angmom_to_omega``(m, ex, ey, ez,
  I) (space-frame ω from the half-step m and the *old* axes); ``richardson``(q, m, ω, I, dtq):
  q_full = qnormalize(q + dtq (0, ω) ⊗ q) (one Euler step of q̇ = ½ ω q over dt),
  q_half = qnormalize(q + ½dtq (0, ω) ⊗ q); ω ← ``mq_to_omega``(m, q_half) (recomputed from the same m
  at the half-step orientation, through ``quat_to_mat``); q_half ← qnormalize(q_half + ½dtq (0, ω) ⊗
  q_half); q = qnormalize(2 q_half − q_full) (the Richardson extrapolation of the two Euler
  estimates); then ex, ey, ez = ``q_to_exyz``(q);
- ``final_integrate``: m += dtf · τ (torque at the new orientation, t + dt); ω = ``angmom_to_omega``.

Between steps gyrolab carries the body ω, so the step builds m = I ω on the axes of q
(``omega_to_angmom``'s sum with the body ω, mbody = I ω) and returns the body ω that
``angmom_to_omega`` forms on its way (wbody_k = m · e_k / I_k), both divided by |q|² (the columns
of ``q_to_exyz`` are |q|² times unit vectors: without it the ω ↔ m round trip, which LAMMPS never
makes, scales ω by (1 + 4δ) for |q| = 1 + δ each step, and the rounding of ``qnormalize`` drifted
the 50 Hz top's axis by 2e-9 over 6.5e6 steps, a floor in the order measurement); the body torque τ_b (``torque_at``)
enters LAMMPS's space-frame kicks as ex τ1 + ey τ2 + ez τ3 (``matvec`` on the columns), the frame
LAMMPS sums its atoms' torques in.  In exact arithmetic the conversions are inverse to each other, so
a run differs from LAMMPS's (which carries m) by rounding only (tests/test_md_lammps_dlpoly.py checks
the step against a numpy transcription of the LAMMPS routines in their own variables).  Zero moments
are handled as LAMMPS does (that component of the body ω is set to 0).

Second order (the extrapolation cancels the two Euler estimates' O(dt²) errors; measured 2.0 on a
heavy asymmetric top).  Not symplectic: the quaternion update is not the exact flow of the half-step
m, and on a free asymmetric body its energy creeps up monotonically (LAMMPS's examples/rigid logs,
and tests/test_md_lammps_dlpoly.py), where NO_SQUISH's oscillates without trend.  Kept: the space
angular momentum is untouched by the rotation (the kicks change it by the torque alone), so in LAMMPS,
which carries m, the free body's lab L and |L|, and Lz under gravity (the torque's z-component is zero),
hold to rounding.  Here the step rebuilds m from the carried ω and q and back each step, and that round
trip drifts by more than rounding: over the verdict's 1e6 steps of 1e-3 s, Lz by 4.6–4.8e-14 /s on the heavy
bodies and L by a slowing trend on the free ones (docs/verdict.md), above its 0.1 eps a step; so PRESERVES
declares none of them.
"""

import math

from numba import njit

from ..body import without_drive
from ..rigid_body import torque_at

ORDER = 2
SYMPLECTIC = False
PRESERVES = ()  # kept in LAMMPS (it carries m); drifts here through the ω ↔ m round trip
REPRODUCES = "LAMMPS fix rigid (MathExtra::richardson), commit 012003c6 / fix_rigid.cpp 00b92cd9"


@njit(cache=True, error_model="numpy")
def _qnormalize(q):
    """``MathExtra::qnormalize``: q · (1/√|q|²)."""
    norm = 1.0 / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q[0] * norm, q[1] * norm, q[2] * norm, q[3] * norm


@njit(cache=True, error_model="numpy")
def _vecquat(a, b):
    """``MathExtra::vecquat``: (0, a) ⊗ b."""
    return (
        -a[0] * b[1] - a[1] * b[2] - a[2] * b[3],
        b[0] * a[0] + a[1] * b[3] - a[2] * b[2],
        b[0] * a[1] + a[2] * b[1] - a[0] * b[3],
        b[0] * a[2] + a[0] * b[2] - a[1] * b[1],
    )


@njit(cache=True, error_model="numpy")
def _q_to_exyz(q):
    """``MathExtra::q_to_exyz``: the space-frame principal axes (the columns of R(q))."""
    ex = (
        q[0] * q[0] + q[1] * q[1] - q[2] * q[2] - q[3] * q[3],
        2.0 * (q[1] * q[2] + q[0] * q[3]),
        2.0 * (q[1] * q[3] - q[0] * q[2]),
    )
    ey = (
        2.0 * (q[1] * q[2] - q[0] * q[3]),
        q[0] * q[0] - q[1] * q[1] + q[2] * q[2] - q[3] * q[3],
        2.0 * (q[2] * q[3] + q[0] * q[1]),
    )
    ez = (
        2.0 * (q[1] * q[3] + q[0] * q[2]),
        2.0 * (q[2] * q[3] - q[0] * q[1]),
        q[0] * q[0] - q[1] * q[1] - q[2] * q[2] + q[3] * q[3],
    )
    return ex, ey, ez


@njit(cache=True, error_model="numpy")
def _on_axes(ex, ey, ez, v):
    """``MathExtra::matvec(ex, ey, ez, v)``: ex v1 + ey v2 + ez v3 (body components to space)."""
    return (
        ex[0] * v[0] + ey[0] * v[1] + ez[0] * v[2],
        ex[1] * v[0] + ey[1] * v[1] + ez[1] * v[2],
        ex[2] * v[0] + ey[2] * v[1] + ez[2] * v[2],
    )


@njit(cache=True, error_model="numpy")
def _wbody(m, ex, ey, ez, body):
    """The body ω of ``angmom_to_omega``: m · e_k / I_k, 0 where I_k = 0."""
    w1 = 0.0 if body[0] == 0.0 else (m[0] * ex[0] + m[1] * ex[1] + m[2] * ex[2]) / body[0]
    w2 = 0.0 if body[1] == 0.0 else (m[0] * ey[0] + m[1] * ey[1] + m[2] * ey[2]) / body[1]
    w3 = 0.0 if body[2] == 0.0 else (m[0] * ez[0] + m[1] * ez[1] + m[2] * ez[2]) / body[2]
    return w1, w2, w3


@njit(cache=True, error_model="numpy")
def _mq_to_omega(m, q, body):
    """``MathExtra::mq_to_omega``: the space ω from the space m at orientation q (via ``quat_to_mat``)."""
    w2 = q[0] * q[0]
    i2 = q[1] * q[1]
    j2 = q[2] * q[2]
    k2 = q[3] * q[3]
    twoij = 2.0 * q[1] * q[2]
    twoik = 2.0 * q[1] * q[3]
    twojk = 2.0 * q[2] * q[3]
    twoiw = 2.0 * q[1] * q[0]
    twojw = 2.0 * q[2] * q[0]
    twokw = 2.0 * q[3] * q[0]
    r00, r01, r02 = w2 + i2 - j2 - k2, twoij - twokw, twojw + twoik
    r10, r11, r12 = twoij + twokw, w2 - i2 + j2 - k2, twojk - twoiw
    r20, r21, r22 = twoik - twojw, twojk + twoiw, w2 - i2 - j2 + k2
    b0 = r00 * m[0] + r10 * m[1] + r20 * m[2]  # transpose_matvec
    b1 = r01 * m[0] + r11 * m[1] + r21 * m[2]
    b2 = r02 * m[0] + r12 * m[1] + r22 * m[2]
    b0 = 0.0 if body[0] == 0.0 else b0 / body[0]
    b1 = 0.0 if body[1] == 0.0 else b1 / body[1]
    b2 = 0.0 if body[2] == 0.0 else b2 / body[2]
    return (
        r00 * b0 + r01 * b1 + r02 * b2,  # matvec
        r10 * b0 + r11 * b1 + r12 * b2,
        r20 * b0 + r21 * b1 + r22 * b2,
    )


@njit(cache=True, error_model="numpy")
def _richardson(q, m, w, body, dtq):
    """``MathExtra::richardson(q, m, w, moments, dtq)``: the new normalised q (space-frame m and ω)."""
    wq = _vecquat(w, q)
    qfull = _qnormalize(
        (q[0] + dtq * wq[0], q[1] + dtq * wq[1], q[2] + dtq * wq[2], q[3] + dtq * wq[3]),
    )
    h = 0.5 * dtq
    qhalf = _qnormalize((q[0] + h * wq[0], q[1] + h * wq[1], q[2] + h * wq[2], q[3] + h * wq[3]))
    w = _mq_to_omega(m, qhalf, body)
    wq = _vecquat(w, qhalf)
    qhalf = _qnormalize(
        (qhalf[0] + h * wq[0], qhalf[1] + h * wq[1], qhalf[2] + h * wq[2], qhalf[3] + h * wq[3]),
    )
    return _qnormalize(
        (
            2.0 * qhalf[0] - qfull[0],
            2.0 * qhalf[1] - qfull[1],
            2.0 * qhalf[2] - qfull[2],
            2.0 * qhalf[3] - qfull[3],
        )
    )


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One fix-rigid step of dt seconds from time t (s): kicks with the torque at t and at t + dt."""
    dtf = 0.5 * dt
    ex, ey, ez = _q_to_exyz(q)
    s = 1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])  # R(q) = |q|² · rotation
    m = _on_axes(ex, ey, ez, (s * body[0] * w[0], s * body[1] * w[1], s * body[2] * w[2]))
    tau = _on_axes(ex, ey, ez, torque_at(q, t, body))
    m = (m[0] + dtf * tau[0], m[1] + dtf * tau[1], m[2] + dtf * tau[2])
    ws = _on_axes(ex, ey, ez, _wbody(m, ex, ey, ez, body))  # angmom_to_omega
    q = _richardson(q, m, ws, body, dtf)
    ex, ey, ez = _q_to_exyz(q)
    tau = _on_axes(ex, ey, ez, torque_at(q, t + dt, body))
    m = (m[0] + dtf * tau[0], m[1] + dtf * tau[1], m[2] + dtf * tau[2])
    wb = _wbody(m, ex, ey, ez, body)
    s = 1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (s * wb[0], s * wb[1], s * wb[2]), q


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
