"""dlpoly_fiqa: DL_POLY 4's leap-frog rigid-body rotation with Fincham's implicit quaternion algorithm (FIQA).

Fincham, Mol. Simul. 8, 165 (1992), as DL_POLY 4 ships it for its leap-frog (LFV) integrators.
Source: DL_POLY 4 ``quaternions_container.f90`` ``q_update`` (t. forester 1993, adapted i.t. todorov
October 2010), the rigid-body block of the LFV integrators (``nvt_g1_lfv.f90``; ``nve_1_lfv.f90`` has
the same block without the thermostat terms) and ``read_control.f90``'s defaults ``mxquat = 100``,
``quattol = 1.0e-8``; the same algorithm as DL_POLY Classic's ``lf_rotation1_module.f``
``update_quaternions`` / ``nveq_1`` (w. smith 2005, t. forester 1993).  These texts were read from the
public code index, which names neither repository nor commit for the DL_POLY 4 files; DL_POLY 4 itself
is distributed by CCP5 / STFC Daresbury (no public GitHub repository).

DL_POLY's leap-frog state is (ω^{n-½}, q^n), ω the body-frame angular velocity, q body → lab (its
``getrotmat`` is gyrolab's R(q)).  One LFV step of dt with the body torque τ^n = Rᵀ τ_lab at q^n:

1. ω^n: five fixed-point sweeps (the "e. yezdimer" iteration, a fixed count, no test) of
   ω ← ω^{n-½} + dt/2 · f(ω), f(ω) = I⁻¹(τ^n + (I2 − I3) ω2 ω3, ...) (Euler's equations), from ω =
   ω^{n-½}; the last f is kept: ω^{n+½} = ω^{n-½} + dt f;
2. ω^{n+1} estimate: 2 ω^{n+½} − ω^n;
3. ``q_update``: the trapezoidal rule q^{n+1} = q^n + dt/2 (½ q^n ⊗ ω^n + ½ q^{n+1} ⊗ ω^{n+1}) solved
   by fixed-point iteration from the Euler estimate q^n + dt/2 q^n ⊗ ω^n, q^{n+1} renormalised after
   every sweep.  **Tolerance** ``quattol`` = 1e-8 on eps = dt |ẏ_k − ẏ_{k-1}| (the change of the
   trapezoid's slope sum between sweeps, times dt); **iteration cap** ``mxquat`` = 100.  DL_POLY
   stops the run (``error(321)``) when a step reaches the cap; here that step returns NaN for ω and
   q, so the run ends with the non-finite status and never continues from a wrong step.

**Mapping the leap-frog half-step velocity onto step(w, q, dt, body).**  gyrolab carries ω and q at
the same time, so the method carries the synchronised ω^n, the fixed point of step 1's equation
ω^n = ω^{n-½} + dt/2 f(ω^n) (DL_POLY's five sweeps approximate it; it is the full-step velocity DL_POLY
reports its rotational energy from).  The step begins by recovering the leap-frog state exactly from
that relation, ω^{n-½} = ω^n − dt/2 f(ω^n) (explicit), runs DL_POLY's step 1-3 as shipped, and ends
by solving ω^{n+1} = ω^{n+½} + dt/2 f(ω^{n+1}) with the torque at q^{n+1} (the next step's step 1),
iterated to convergence (change ≤ 1e-15 |ω|, cap 60, NaN and the status "unconverged" past it)
rather than five times, so that the next step's recovery returns this step's ω^{n+½} to rounding.
The (ω^{n+½}, q) sequence is then DL_POLY's own to rounding; only the ω gyrolab reports (and
computes the energy from) is the synchronised one.  Carrying ω^{n-½} itself instead would put every
diagnostic half a step out of phase with q (an O(dt) error in ω at time t).

Second order (trapezoidal quaternion update with a second-order ω^{n+1} extrapolation; measured 2.0).
Not symplectic, and |q| = 1 only through the renormalisation.  It keeps no invariant to rounding:
the free body's L moves by the trapezoid's and the tolerance's errors.  Explicit about time: the
torque is taken at t (step 1) and t + dt (the synchronisation), as DL_POLY's forces at step n and
n + 1.  DL_POLY sums the torque in the lab frame and turns it to the body with ``getrotmat``'s Rᵀ;
gyrolab's ``torque_at`` gives the body torque directly (a rounding-level difference).
"""

import math

from numba import njit

from ..body import without_drive
from ..rigid_body import torque_at

ORDER = 2
SYMPLECTIC = False
PRESERVES = ()
REPRODUCES = "DL_POLY 4 LFV FIQA (q_update, quattol 1e-8, mxquat 100)"

BLOCKS = False  # fixed-point loops per step: the lanes do not vectorise them, and their iterations are counted
MXQUAT = 100  # DL_POLY 4 read_control.f90 default
QUATTOL = 1.0e-8  # DL_POLY 4 read_control.f90 default
OMEGA_SWEEPS = 5  # DL_POLY's fixed count for ω^n
SYNC_TOLERANCE = 1e-15  # the synchronised ω's fixed point: relative change per sweep
SYNC_MAX_ITERATIONS = 60


@njit(cache=True, error_model="numpy")
def _f(w, tau, body):
    """DL_POLY's ω̇: rgdri(2) · (τ + (I2 − I3) ω2 ω3, ...), rgdri(2) = 1/I."""
    return (
        (1.0 / body[0]) * (tau[0] + (body[1] - body[2]) * w[1] * w[2]),
        (1.0 / body[1]) * (tau[1] + (body[2] - body[0]) * w[2] * w[0]),
        (1.0 / body[2]) * (tau[2] + (body[0] - body[1]) * w[0] * w[1]),
    )


@njit(cache=True, error_model="numpy")
def q_update(tstep, op, oq, q):
    """DL_POLY 4 ``q_update``: (q^{n+1}, iterations); op = ω^n, oq = ω^{n+1}, body frame."""
    q0, q1, q2, q3 = q
    oxp, oyp, ozp = op
    oxq, oyq, ozq = oq
    qn0 = q0 + (-q1 * oxp - q2 * oyp - q3 * ozp) * tstep * 0.5
    qn1 = q1 + (q0 * oxp - q3 * oyp + q2 * ozp) * tstep * 0.5
    qn2 = q2 + (q3 * oxp + q0 * oyp - q1 * ozp) * tstep * 0.5
    qn3 = q3 + (-q2 * oxp + q1 * oyp + q0 * ozp) * tstep * 0.5
    qn0b = qn1b = qn2b = qn3b = 0.0
    itq = 0
    eps = 2.0 * QUATTOL
    while itq < MXQUAT and eps > QUATTOL:
        qn0a = 0.5 * (-q1 * oxp - q2 * oyp - q3 * ozp) + 0.5 * (-qn1 * oxq - qn2 * oyq - qn3 * ozq)
        qn1a = 0.5 * (q0 * oxp - q3 * oyp + q2 * ozp) + 0.5 * (qn0 * oxq - qn3 * oyq + qn2 * ozq)
        qn2a = 0.5 * (q3 * oxp + q0 * oyp - q1 * ozp) + 0.5 * (qn3 * oxq + qn0 * oyq - qn1 * ozq)
        qn3a = 0.5 * (-q2 * oxp + q1 * oyp + q0 * ozp) + 0.5 * (-qn2 * oxq + qn1 * oyq + qn0 * ozq)
        qn0 = q0 + 0.5 * qn0a * tstep
        qn1 = q1 + 0.5 * qn1a * tstep
        qn2 = q2 + 0.5 * qn2a * tstep
        qn3 = q3 + 0.5 * qn3a * tstep
        rnorm = 1.0 / math.sqrt(qn0**2 + qn1**2 + qn2**2 + qn3**2)
        qn0 = qn0 * rnorm
        qn1 = qn1 * rnorm
        qn2 = qn2 * rnorm
        qn3 = qn3 * rnorm
        eps = math.sqrt(((qn0a - qn0b) ** 2 + (qn1a - qn1b) ** 2 + (qn2a - qn2b) ** 2 + (qn3a - qn3b) ** 2) * tstep**2)
        qn0b, qn1b, qn2b, qn3b = qn0a, qn1a, qn2a, qn3a
        itq += 1
    return (qn0, qn1, qn2, qn3), itq


@njit(cache=True, error_model="numpy")
def lfv_rotation(w_half, q, tau, dt, body):
    """DL_POLY's LFV rotation from the leap-frog state (ω^{n-½}, q^n) and the body torque τ^n:
    (ω^n, ω^{n+½}, q^{n+1}, q_update's iteration count)."""
    hstep = 0.5 * dt
    oxp, oyp, ozp = w_half
    opx = opy = opz = 0.0
    for _ in range(OMEGA_SWEEPS):
        opx, opy, opz = _f((oxp, oyp, ozp), tau, body)
        oxp = w_half[0] + hstep * opx
        oyp = w_half[1] + hstep * opy
        ozp = w_half[2] + hstep * opz
    w_next_half = (w_half[0] + dt * opx, w_half[1] + dt * opy, w_half[2] + dt * opz)
    oq = (2.0 * w_next_half[0] - oxp, 2.0 * w_next_half[1] - oyp, 2.0 * w_next_half[2] - ozp)
    q_new, itq = q_update(dt, (oxp, oyp, ozp), oq, q)
    return (oxp, oyp, ozp), w_next_half, q_new, itq


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven_counted(w, q, t, dt, body):
    """One DL_POLY LFV step of dt seconds from time t (s), synchronised ω in and out (module doc), and
    the fixed-point iterations it took: q_update's and the synchronisation's (< 0: not converged,
    the state NaN)."""
    nan = float("nan")
    half = 0.5 * dt
    tau = torque_at(q, t, body)
    a = _f(w, tau, body)
    w_half = (w[0] - half * a[0], w[1] - half * a[1], w[2] - half * a[2])
    _, w_next_half, q_new, itq = lfv_rotation(w_half, q, tau, dt, body)
    if itq >= MXQUAT:
        return (nan, nan, nan), (nan, nan, nan, nan), -itq
    tau = torque_at(q_new, t + dt, body)
    wn = w_next_half
    scale = max(abs(wn[0]), abs(wn[1]), abs(wn[2]))
    for n in range(1, SYNC_MAX_ITERATIONS + 1):
        a = _f(wn, tau, body)
        w_new = (w_next_half[0] + half * a[0], w_next_half[1] + half * a[1], w_next_half[2] + half * a[2])
        dw = max(abs(w_new[0] - wn[0]), abs(w_new[1] - wn[1]), abs(w_new[2] - wn[2]))
        wn = w_new
        scale = max(scale, abs(wn[0]), abs(wn[1]), abs(wn[2]))
        if dw <= SYNC_TOLERANCE * scale:
            return wn, q_new, itq + n
    return (nan, nan, nan), (nan, nan, nan, nan), -(itq + SYNC_MAX_ITERATIONS)


@njit(cache=True, error_model="numpy")
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): step_driven_counted without its count."""
    w1, q1, _ = step_driven_counted(w, q, t, dt, body)
    return w1, q1


@njit(cache=True, error_model="numpy")
def step_counted(w, q, dt, body):
    """step_driven_counted of an undriven body, from t = 0 with its drive folded away."""
    return step_driven_counted(w, q, 0.0, dt, without_drive(body))


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))
