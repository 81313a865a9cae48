"""no_squish: NO_SQUISH, the molecular-dynamics rigid-rotor step (quaternion and its conjugate momentum).

Miller, Eleftheriou, Pattnaik, Ndirango, Newns & Martyna, J. Chem. Phys. 116, 8649 (2002), as LAMMPS
ships it in ``fix rigid/nve`` and ``rigid/nve/small`` (Source: lammps/lammps src/math_extra.cpp
``MathExtra::no_squish_rotate`` at commit bb720626, src/RIGID/fix_rigid_nh_small.cpp
``initial_integrate`` and ``final_integrate`` at commit 46265e36; jax-md's jax_md/rigid_body.py
``free_rotor`` turns about the same axes in the same order).
The variables are the unit quaternion q and its conjugate momentum p = 2 q ⊗ (0, L), L = Iω the body
angular momentum (LAMMPS ``quatvec``, ``invquatvec``).  One step of dt:

- half kick: p += dt · q ⊗ (0, τ_b) (LAMMPS ``conjqm += dtf2 * fquat``, dtf2 = 2 · dt/2), τ_b the
  body torque at time t;
- the free rotor as five exact rotations about single body axes, in the fixed order
  **3-2-1-2-3** (dt/2 about e3, dt/2 about e2, dt about e1, dt/2 about e2, dt/2 about e3), each
  ``no_squish_rotate``: φ = p·P_k q / (4 I_k), (p, q) ← cos(φ h) (p, q) + sin(φ h) (P_k p, P_k q),
  with libm cos/sin as LAMMPS; P_k q = q ⊗ (0, e_k), and φ h = ω_k h / 2, so q turns by ω_k h about
  body axis k: the exact flow of L_k²/(2 I_k);
- half kick with the torque at the new orientation and time t + dt (``final_integrate``).

The axes are the body's principal axes as given (e1, e2, e3 of the body record).  LAMMPS takes them
from ``MathEigen::jacobi3(..., 1)`` in ``setup_bodies_static``, which sorts them by ascending moment, so
its 3-2-1-2-3 turns about the *largest* moment first: on a body whose moments are not in ascending
order LAMMPS runs another splitting of the same kind (O(dt³) per step apart; measured against the
engine itself in docs/engines/conformance.md, ``real_lammps_rigid_nve``).  This method is LAMMPS's
step on a body relabelled so that I1 ≤ I2 ≤ I3.

Between steps gyrolab carries (ω, q), as every method does (kernels/methods/README.md): p is built
from ω at the start of the step and L = ½ vec(q* ⊗ p)/|q|² (``invquatvec``) read back at its end.
The two conversions are exact inverses in exact arithmetic (q* ⊗ p = 2 |q|² (0, L)); in floating
point each costs a few ulp, so a run differs from LAMMPS's (which carries p) by rounding only.  q is
renormalised at the end of the step, which LAMMPS does not do (its |q| moves by rounding alone, each
rotation being an orthogonal map of R⁴; gyrolab's methods keep |q| = 1 for the 1e6-step bars).
The rounding of the (q, p) form is larger than lie_poisson's (ω, q) form: |L| moves by 6e-14 in
4000 free steps (lie_poisson 1e-14) and the sleeping top's ω3 by 6e-13 in 5e4 steps (tests/helpers.py
lists both as known failures of rounding-level bars).  The map equals the axis splitting 3-2-1-2-3
of lie_poisson's kind in (ω, q) to a few ulp per step (tests/test_md_methods.py).  Symplectic and
second order; the free body's lab L and |L| are kept to rounding, and Lz under gravity.  Unlike
lie_poisson's exact symmetric flow, the rotations about e1 and e2 change L3, so L3 is not kept on the
symmetric top.

Parameters (kernels/parameters.py): ``axes`` (default 3-2-1, as shipped) the rotor's axis order, in body
labels or by moment (S-M-L turns about the smallest moment first, the order Fassò recommends;
docs/splitting_order.md); ``substeps`` (default 1) rotors of dt/substeps between the two kicks, as
DL_POLY 4 (10 by default) and jax-md's optional substeps run it.  ``no_squish(axes=X)`` is
``lie_poisson(axes=X)`` in (q, p) on an asymmetric body, to a few ulp per step (tested).
"""

import math

from numba import njit

from ..body import without_drive
from ..free_flow import resolve_axes
from ..parameters import axis_order, count
from ..rigid_body import torque_at
from ..rotation import quat_normalize
from ..variants import undriven

ORDER = 2
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz")
SHIPPED_AXES = (2, 1, 0)  # 3-2-1-2-3 in the body's labels, as LAMMPS, HOOMD-blue, DL_POLY and jax-md turn
PARAMETERS = {
    "axes": axis_order("3-2-1", "the rotor's axis order: a-b-c is a(h/2) b(h/2) c(h) b(h/2) a(h/2)"),
    "substeps": count("1", "rotors of dt/substeps between the kicks (DL_POLY's default is 10)"),
}


@njit(cache=True, error_model="numpy")
def _quat_vec(q, v):
    """q ⊗ (0, v): LAMMPS ``MathExtra::quatvec``."""
    return (
        -q[1] * v[0] - q[2] * v[1] - q[3] * v[2],
        q[0] * v[0] + q[2] * v[2] - q[3] * v[1],
        q[0] * v[1] + q[3] * v[0] - q[1] * v[2],
        q[0] * v[2] + q[1] * v[1] - q[2] * v[0],
    )


@njit(cache=True, error_model="numpy")
def _inv_quat_vec(q, p):
    """vec(q* ⊗ p): LAMMPS ``MathExtra::invquatvec``."""
    return (
        -q[1] * p[0] + q[0] * p[1] + q[3] * p[2] - q[2] * p[3],
        -q[2] * p[0] - q[3] * p[1] + q[0] * p[2] + q[1] * p[3],
        -q[3] * p[0] + q[2] * p[1] - q[1] * p[2] + q[0] * p[3],
    )


@njit(cache=True, error_model="numpy")
def _kick(p, q, h2, tau):
    """p += h2 · q ⊗ (0, τ_b): a half kick with h2 = 2 · (dt/2) (N m s)."""
    f = _quat_vec(q, tau)
    return p[0] + h2 * f[0], p[1] + h2 * f[1], p[2] + h2 * f[2], p[3] + h2 * f[3]


@njit(cache=True, error_model="numpy")
def _rotate(k, p, q, inertia, h):
    """``MathExtra::no_squish_rotate(k, p, q, inertia, h)``: the exact flow of L_k²/(2 I_k) for h s."""
    if k == 1:
        kq = (-q[1], q[0], q[3], -q[2])
        kp = (-p[1], p[0], p[3], -p[2])
    elif k == 2:
        kq = (-q[2], -q[3], q[0], q[1])
        kp = (-p[2], -p[3], p[0], p[1])
    else:
        kq = (-q[3], q[2], -q[1], q[0])
        kp = (-p[3], p[2], -p[1], p[0])
    phi = p[0] * kq[0] + p[1] * kq[1] + p[2] * kq[2] + p[3] * kq[3]
    if inertia == 0.0:
        phi = 0.0
    else:
        phi /= 4.0 * inertia
    c = math.cos(h * phi)
    s = math.sin(h * phi)
    return (
        (c * p[0] + s * kp[0], c * p[1] + s * kp[1], c * p[2] + s * kp[2], c * p[3] + s * kp[3]),
        (c * q[0] + s * kq[0], c * q[1] + s * kq[1], c * q[2] + s * kq[2], c * q[3] + s * kq[3]),
    )


@njit(cache=True, error_model="numpy", forceinline=True)
def _rotor(p, q, h, body, axes):
    """The free rotor for h seconds: exact rotations a(h/2) b(h/2) c(h) b(h/2) a(h/2) about the body
    axes ``axes`` = (a, b, c) (0-based; LAMMPS numbers them from 1)."""
    half = 0.5 * h
    a, b, c = axes
    p, q = _rotate(a + 1, p, q, body[a], half)
    p, q = _rotate(b + 1, p, q, body[b], half)
    p, q = _rotate(c + 1, p, q, body[c], h)
    p, q = _rotate(b + 1, p, q, body[b], half)
    return _rotate(a + 1, p, q, body[a], half)


@njit(cache=True, error_model="numpy", forceinline=True)
def step_driven_with(w, q, t, dt, body, axes, substeps):
    """One NO_SQUISH step of dt seconds from time t (s), the rotor in the axis order ``axes``
    (kernels/parameters.py codes, free_flow.resolve_axes) as ``substeps`` rotors of dt/substeps
    between the kicks: the kicks see the torque at t and t + dt (the splitting made autonomous with t
    as a coordinate, the rotor advancing t)."""
    I1, I2, I3 = body[0], body[1], body[2]
    qv = _quat_vec(q, (I1 * w[0], I2 * w[1], I3 * w[2]))
    p = (2.0 * qv[0], 2.0 * qv[1], 2.0 * qv[2], 2.0 * qv[3])
    p = _kick(p, q, dt, torque_at(q, t, body))
    order = resolve_axes(body, axes)
    h = dt / substeps
    for _ in range(substeps):
        p, q = _rotor(p, q, h, body, order)
    p = _kick(p, q, dt, torque_at(q, t + dt, body))
    # L = ½ vec(q* ⊗ p) / |q|²: the exact inverse of p = 2 q ⊗ (0, L) for any q (LAMMPS omits 1/|q|²,
    # harmless where p is carried; here the conversion recurs every step, so |q| ≠ 1 would compound:
    # measured 3e-11 in |L| after 4000 steps without it, 6e-14 with it)
    L = _inv_quat_vec(q, p)
    s = 0.5 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (s * L[0] / I1, s * L[1] / I2, s * L[2] / I3), quat_normalize(q)


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One NO_SQUISH step of dt seconds from time t (s) as the MD codes ship it: the rotor 3-2-1-2-3,
    once per step."""
    return step_driven_with(w, q, t, dt, body, SHIPPED_AXES, 1)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of an undriven body: step_driven from t = 0, its drive folded away."""
    return step_driven(w, q, 0.0, dt, without_drive(body))


def variant(axes, substeps):
    """The steps with the rotor in the axis order ``axes`` as ``substeps`` rotors of dt/substeps."""

    @njit(error_model="numpy", forceinline=True)
    def step_driven(w, q, t, dt, body):
        return step_driven_with(w, q, t, dt, body, axes, substeps)

    return undriven(step_driven)
