"""Where does compensated lie_poisson4's residual energy bias on the heavy top come from? (issue 22, item 4)

    python benchmarks/compensated_bias.py curve [--runs 32] [--steps 1e8] [--seed 1]
    python benchmarks/compensated_bias.py probe [--runs 8] [--steps 1e6] [--seed 1] [--variant NAME --amplitude A]
    python benchmarks/compensated_bias.py trend [--runs 32] [--dt 5e-4] [--t-end 2500] [--method lie_poisson4]
        [--gravity 1] [--perturbation 1e-9] [--dither A] [--variant NAME --amplitude A | --long-double]
    python benchmarks/compensated_bias.py response [--runs 2] [--dts 2.5e-4,5e-4,1e-3,2e-3] [--t-end 20]
        [--variant turn_mismatch --amplitude 1e-13]

``lie_poisson4(accumulate=compensated)`` on benchmarks/brouwer.py's heavy-top ensemble (50 Hz, 45°,
released, dt = 2.5e-5 s, ω0 perturbed by 1e-9 relative) walks as Brouwer's √t, but the mean over the
runs of E/E0 − 1 moves away from zero in proportion to t: a rounding bias common to the runs.

``curve`` runs the registered variant (brouwer.py ``run_compensated``, checked bit for bit against
integrate()) and prints that mean, its standard error and the RMS at 25 times, then the line fitted
through the mean: a bias grows as a t, a walk keeps the mean within its error.

``trend`` sees the same drift where it is cheap: at dt = 5e-4 s it is ~20 times faster per second (the
drift per step goes as dt²) and the truncation's oscillation, common to the runs, averages out of a line
fitted over 2500 s, so an ensemble takes a minute or two instead of half an hour.  It fits each run's slope
of E/E0 − 1 and of Lz/Lz0 − 1 (the vertical angular momentum, which every substep conserves exactly),
and prints the ensemble mean over ten blocks of time and how the runs spread about it; ``--gravity``
scales m g l, ``--perturbation`` the runs' initial difference, ``--method split6_exact`` runs that method's
variant, ``--variant`` runs the copy with one variant (lie_poisson4 only).  Each run's own drift (its slope less
the ensemble's) is fitted in each quarter of the run too: a rate the run keeps correlates from quarter to
quarter, a walk's does not.

``response`` asks how the drift a fixed error makes depends on the step: at each step of ``--dts`` it runs the
copy (below) and one variant at one amplitude on the same runs for ``--t-end`` seconds, and prints the slope of
the difference of their E/E0 − 1 and Lz/Lz0 − 1 (the runs' mean), per second and per substep.  A turn of ω⊥
about e3 that misses the body's by A rad in every substep (``turn_mismatch``, the default) changes neither T
nor V where it is made, yet the energy drifts, by the same amount per second at every step: an error of the
turns that grows as the substep's angle, ~eps φ ∝ dt, drifts the energy per second as dt, as the top's bias
does.

``probe`` finds which rounding it is not.  It runs a copy of the variant's step as it was registered until
2026-12-07 (kernels/compensated.py: Yoshida's triple jump of kick(h/2), the symmetric body's exact free flow,
kick(h/2); the body's turn added as q ⊗ (α, u) from q's high part, rounded, and ω⊥ turned by t = sh/ch), with
one suspected rounding amplified at a time; the variant ``turn_exact_rotation`` is the registered step since,
checked bit for bit against it.  A rounding that
makes a bias b per step, amplified A times, moves the mean by about A b per step: at 1e6 steps the bias
itself (~6e-19) is below the walk's spread (~3e-18), amplified 1e3 or more it would stand out.  Every
variant but norm_coarse, turn_matched and norm_exact is checked to be the copy bit for bit at amplitude 0
(1000 steps) before it runs.
Variants (name: what is amplified):

- ``copy``: nothing (the registered variant's map before 2026-12-07, bit for bit);
- ``axis_ratio``: the rounding of I3/I1 in the first turn's axis (ω1 h, ω2 h, (I3/I1) ω3 h), which is
  the same on every step since ω3 is conserved: the ratio scaled by 1 + 1e-8 (~1e8 times its rounding);
- ``turn_rate``: likewise the rate c = (1 − I3/I1) ω3 of the turn of L about e3 (and the body's second
  turn): scaled by 1 + 1e-8;
- ``kick_low_parts``: the kick's torque is taken from q's high part only; here from q + A ql (first
  order in ql), A = ±1000 (A = 1 would be the torque of the whole q);
- ``norm_coarse``: the projection to |q| = 1 computes |q|² − 1 in double; here from q rounded to
  multiples of 1e-12 (its error ~1e4 times larger);
- ``turn_low_parts``: the body's turn adds q ⊗ (α, u) from q's high part only; here plus A ql ⊗ (α, u),
  A = ±1000 (A = 1: the low part turned with the body, the increment of the whole q).

- ``shear_pair``: the shears' s = sin φ (with its low part, which closes (s + sl)(1 + t²) = 2t) given a
  relative error A = ±1e-10, the same on every step: the map is then no rotation of L by that much;
- ``shear_unclosed``: that low part times 1 − A: A = 1 is the rounded pair alone (the kernel before
  _sin_low), A = 10 ten times its miss;
- ``kick_rounding``: the kick's increment h τ/I (a product and a division, rounded twice) plus A times
  its rounding error e (the fma's exact product of h τ and the division's exact remainder), so that the
  increment's error is (1 − A) e: A = ±1000 amplifies that rounding;
- ``torque_rounding``: the same for the whole chain from q to the increment, the torque's own rounding
  included (γ1, γ2 from q's products and sums, m3 γ: each rounding's error from exact products and
  two-sums);
- ``turn_product``: the symmetric flow's increment of q, the Hamilton product q ⊗ (α, u), plus A times its
  rounding error (sixteen exact products and twelve two-sums);
- ``rate_low_parts``: the body's turn and the rate c take ω's high part only; here ω + A ωl (A = 1: the
  rates of the whole ω, up to the rounding of the sum);
- ``rotvec_rounding``: the turn's rotation vector and its quaternion's vector part, u = s (ω1 h, ω2 h,
  (I3/I1) ω3 h) with s = sin(φ/2)/φ: the rounding of each product (fma), so of u's direction and length
  for a given s, plus A times that error (s's own rounding, common to the three components, is a turn by
  a slightly wrong angle about the same axis);
- ``shear_rounding``: the increments of the three shears that turn ω⊥ (t y, −(s x) − sl x: products and a
  sum, each error exact) plus A times their rounding error: the roundings that change |ω⊥|, so T, directly;
- ``norm_rounding``: the projection's increment k q (k = −(|q|² − 1)/2) plus A times its products' error;
- ``turn_sums``: the turn's quaternion (α, v), composed from the two turns' (α1, u) and (α2, sh e3) by four
  products' and sums' formulas, plus A times their rounding error;
- ``all_roundings``: torque_rounding, rotvec_rounding, turn_sums, turn_product, norm_rounding and
  shear_rounding at once: if the bias is the sum of those roundings' it moves the mean (1 − A) times;
- ``sinc_rounding``: the turn's s = sin(φ/2)/φ (kernels/rotation._cos_sinc_half's series, the top's turns
  being far below SMALL_ANGLE) plus A times its rounding error, against the series to h^10 whose last
  sum 0.5 + y is kept exact: a turn by a slightly wrong angle about the turn's own axis;
- ``shear_low_parts``: the shears' increments t y and −(s + sl) x are formed from the high parts of ω⊥
  only, so its low parts are not turned; here plus A times the low parts' own increments (A = 1: the
  whole ω⊥ turned, to the rounding of those small increments);
- ``add_rounding``: the compensated sum itself (kernels/compensated._add: s = hi + y, y = d + lo, and the
  error of s as the new low part) is exact but for y's rounding, ~eps of the increment d; here plus A
  times that error in each of the step's seventeen sums a substep (kicks, turn, projection, shears).

For the rounding errors (kick_rounding to add_rounding, rate_low_parts and shear_low_parts excepted), A = 1
is not the exact increment: the increment plus its error is rounded again where it is added to the state
(~eps of the increment, the size of the error removed), so A = 1 is another rounding of the same size; only
the amplified runs tell, a bias b per step moving the mean by (1 − A) b per step.  (rate_low_parts at A = 1 is
the registered map itself: ω + ωl rounds back to ω.)

Variants that change the map rather than amplify a rounding:

- ``turn_mismatch``: the shears' angle 2 atan t moved by A rad in every substep (s closed to the new t),
  so that ω⊥ turns about e3 by A more than the body does: the response of the drift to such a mismatch;
- ``turn_matched``: the shears' t + tl = sh/(1 + α2) to ~eps², the tangent of the body's own turn about
  e3, with s closed to it and ω⊥'s low parts sheared too (no amplitude gives the registered bits: A is
  ignored); the registered t = sh/ch turns ω⊥ by ~1e-17 rad more or less than the body;
- ``norm_exact``: the projection from |q + ql|² − 1 to ~eps² (A ignored), where the registered one leaves
  |q + ql|² − 1 ≈ +1.4e-17;
- ``dither_rate``: the rate c of the turns about e3 times 1 + A d, d in [−0.5, 0.5) taken from ω1's low bits,
  so new on every substep: both turns keep using one c (the map stays a Poisson map up to rounding), but the
  turn constants (ch, sh, t, s) and their roundings, the same on every substep of a run otherwise, change from
  substep to substep.  A drift that is the fixed roundings' goes; one that a biased rounding of the constants
  at every argument makes stays.  A ≥ 1e-12: ch = cos(c h/2), near 1, changes by one ulp only every ~80 ulps
  of its argument, so a dither of a few ulps (4e-15) leaves its rounding as it was (``trend --dither A`` is
  the same dither on the copy or on any variant);
- ``dither_spin``: ω3 as the two turns take it (the first turn's axis (ω1 h, ω2 h, (I3/I1) ω3 h) and the rate c)
  moved the same way, the state's ω3 kept: nothing computed from ω3, the one rate the top's steps never change,
  is then the same from one substep to the next.

Variants that are the fix (A ignored):

- ``turn_exact``: the body's turn adds the increment of the whole q, (q + ql) ⊗ (α, u), with the product's
  rounding error and ql's own turn passed to the low part (kernels/compensated._turn_whole);
- ``turn_exact_matched``: that and ``turn_matched``'s shears (benchmarks/double_double_top._shear_turn_matched):
  the registered step earlier on 2026-12-07;
- ``turn_exact_rotation``: ``turn_exact`` and ω⊥ turned by the same angle as a rotation whose constants and
  products are exact to ~eps² (kernels/compensated._turn_matched): the registered step since.

``--variant NAME --amplitude A`` runs that one variant (e.g. ``turn_low_parts`` at A = 1, over 1e8 steps,
to see whether the bias is left when that rounding is corrected rather than amplified); a negative amplitude
in exponent form goes as ``--amplitude=-1e-13``.  ``trend --long-double`` runs lie_poisson4's step written
plainly in numpy's long double instead (run_long_double; ~2.3 ms a step for all the runs together, so 4 runs of
the default 5e6 steps take ~25 min of one core): the same map rounded 2048 times finer.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit, prange

sys.path.insert(0, str(Path(__file__).resolve().parent))
from brouwer import energy_extended, ensemble, run_compensated, up_in_body_extended  # noqa: E402
from double_double_top import PIECES, _shear_turn_matched, dither_number, pieces_mask, run_series  # noqa: E402

from gyrolab.kernels.compensated import (  # noqa: E402
    _add,
    _add3,
    _add4,
    _fma,
    _minus_one,
    _normalize,
    _shear_turn,
    _sin_low,
    _turn_matched,
    _turn_whole,
    _two_prod,
    kick,
    quat_mul_low,
    then_e3_turn,
)
from gyrolab.kernels.methods.lie_poisson4 import WEIGHTS  # noqa: E402
from gyrolab.kernels.rigid_body import gravity_torque  # noqa: E402
from gyrolab.kernels.rotation import (  # noqa: E402
    SMALL_ANGLE,
    WIDE_ANGLE,
    _cos_sinc_half,
    _cos_sinc_half_wide,
    half_angle,
    quat_from_rotvec,
    quat_mul,
)

# name: (code, amplitudes): each amplitude is one run of the ensemble
VARIANTS = {
    "copy": (0, (0.0,)),
    "axis_ratio": (1, (1e-8,)),
    "turn_rate": (2, (1e-8,)),
    "kick_low_parts": (3, (1000.0, -1000.0)),
    "norm_coarse": (4, (1e12,)),
    "turn_low_parts": (5, (1000.0, -1000.0)),
    "shear_pair": (6, (1e-10, -1e-10)),
    "shear_unclosed": (7, (1.0, 10.0)),
    "kick_rounding": (8, (1000.0, -1000.0)),
    "torque_rounding": (9, (1000.0, -1000.0)),
    "turn_product": (10, (1000.0, -1000.0)),
    "rate_low_parts": (11, (1000.0, -1000.0)),
    "rotvec_rounding": (12, (1000.0, -1000.0)),
    "shear_rounding": (13, (1000.0, -1000.0)),
    "norm_rounding": (14, (1000.0, -1000.0)),
    "turn_sums": (15, (1000.0, -1000.0)),
    "all_roundings": (16, (1000.0, -1000.0)),
    "sinc_rounding": (17, (1000.0, -1000.0)),
    "shear_low_parts": (18, (1000.0, -1000.0)),
    "add_rounding": (19, (1000.0, -1000.0)),
    "turn_mismatch": (20, (1e-13, -1e-13)),
    "turn_matched": (21, (1.0,)),
    "norm_exact": (22, (1.0,)),
    "dither_rate": (23, (1e-12,)),
    "dither_spin": (24, (1e-12,)),
    "turn_exact": (25, (1.0,)),
    "turn_exact_matched": (26, (1.0,)),
    "turn_exact_rotation": (27, (1.0,)),
}
NO_IDENTITY = (0, 4, 21, 22, 25, 26, 27)  # the copy itself, and the variants that have no amplitude giving its bits
W1, W0 = WEIGHTS[0], WEIGHTS[1]


@njit(error_model="numpy")
def _kick(w, wl, q, ql, h, body, code, amp):
    """kernels/compensated.kick; with code 3 the torque from q + amp ql (first order in ql; the top's
    torque m3 (γ2, −γ1, 0) with γ = Rᵀ ẑ, kernels/rotation.lab_up_in_body)."""
    if code == 8:
        return _kick_rounding(w, wl, q, h, body, amp)
    if code == 9 or code == 16:
        return _torque_rounding(w, wl, q, h, body, amp)
    if code == 19:
        return _kick_add_rounding(w, wl, q, h, body, amp)
    if code != 3:
        return kick(w, wl, q, h, body)
    a, b, c, d = q
    al, bl, cl, dl = amp * ql[0], amp * ql[1], amp * ql[2], amp * ql[3]
    g1 = 2.0 * (b * d - a * c) + 2.0 * ((bl * d + b * dl) - (al * c + a * cl))
    g2 = 2.0 * (c * d + a * b) + 2.0 * ((cl * d + c * dl) + (al * b + a * bl))
    m3 = body[3]
    return _add3(w, wl, h * (m3 * g2) / body[0], h * (-m3 * g1) / body[1], 0.0)


@njit(error_model="numpy")
def _increment_and_error(h, t, inertia):
    """(d, e): d = h t / I rounded as kernels/compensated.kick rounds it ((h t) rounded, then divided), and
    e = h t / I − d to ~eps² (the product's error exact by fma, the quotient's from its exact remainder)."""
    p, pe = _two_prod(h, t)
    d = p / inertia
    remainder = _fma(-d, inertia, p)  # p − d I, exact
    return d, (remainder + pe) / inertia


@njit(error_model="numpy")
def _kick_rounding(w, wl, q, h, body, amp):
    """kernels/compensated.kick with amp times its increment's rounding error added to the low parts (amp = 0:
    the same bits)."""
    t0, t1, t2 = gravity_torque(q, body)
    d0, e0 = _increment_and_error(h, t0, body[0])
    d1, e1 = _increment_and_error(h, t1, body[1])
    d2, e2 = _increment_and_error(h, t2, body[2])
    a0, l0 = _add(w[0], wl[0] + amp * e0, d0)
    a1, l1 = _add(w[1], wl[1] + amp * e1, d1)
    a2, l2 = _add(w[2], wl[2] + amp * e2, d2)
    return (a0, a1, a2), (l0, l1, l2)


@njit(error_model="numpy")
def _torque_rounding(w, wl, q, h, body, amp):
    """kernels/compensated.kick on the top (centre of mass on e3) with amp times the rounding error of its whole
    increment, from q to h τ/I: γ1 = 2(b d − a c) and γ2 = 2(c d + a b) (kernels/rotation.lab_up_in_body), the
    torque (m3 γ2, −m3 γ1, 0), then the increment (amp = 0: the same bits)."""
    a, b, c, d = q
    p, pe = _two_prod(b, d)
    r, re = _two_prod(a, c)
    s1, se1 = _add(p, 0.0, -r)
    g1, g1e = 2.0 * s1, 2.0 * (se1 + pe - re)
    p, pe = _two_prod(c, d)
    r, re = _two_prod(a, b)
    s2, se2 = _add(p, 0.0, r)
    g2, g2e = 2.0 * s2, 2.0 * (se2 + pe + re)
    m3 = body[3]
    t0, t0e = _two_prod(m3, g2)
    t1, t1e = _two_prod(-m3, g1)
    d0, e0 = _increment_and_error(h, t0, body[0])
    d1, e1 = _increment_and_error(h, t1, body[1])
    e0 += h * (t0e + m3 * g2e) / body[0]
    e1 += h * (t1e - m3 * g1e) / body[1]
    a0, l0 = _add(w[0], wl[0] + amp * e0, d0)
    a1, l1 = _add(w[1], wl[1] + amp * e1, d1)
    return (a0, a1, w[2]), (l0, l1, wl[2])


@njit(error_model="numpy")
def _rotvec_amplified(w0, w1, w2, k, h, amp):
    """kernels/rotation.quat_from_rotvec(w0 h, w1 h, k w2 h) with amp times the rounding error of its vector
    part for the computed s = sin(φ/2)/φ: the products w h (and k w2, then h) and s v, each error exact (fma).
    amp = 0: the same bits."""
    v0, v1 = w0 * h, w1 * h
    p = k * w2
    v2 = p * h
    e0, e1 = _fma(w0, h, -v0), _fma(w1, h, -v1)
    e2 = _fma(p, h, -v2) + _fma(k, w2, -p) * h
    angle2 = v0 * v0 + v1 * v1 + v2 * v2
    if angle2 < SMALL_ANGLE * SMALL_ANGLE:
        a, s = _cos_sinc_half(angle2)
    elif angle2 < WIDE_ANGLE * WIDE_ANGLE:
        a, s = _cos_sinc_half_wide(angle2)
    else:
        angle = np.sqrt(angle2)
        a, s = np.cos(0.5 * angle), np.sin(0.5 * angle) / angle
    u0, u1, u2 = s * v0, s * v1, s * v2
    u0 += amp * (s * e0 + _fma(s, v0, -u0))
    u1 += amp * (s * e1 + _fma(s, v1, -u1))
    u2 += amp * (s * e2 + _fma(s, v2, -u2))
    return a, u0, u1, u2


@njit(error_model="numpy")
def _shear_turn_amplified(x, xl, y, yl, t, s, c2, amp):
    """kernels/compensated._shear_turn of a symmetric body (kx = ky = 1, kyl = 0) with amp times each
    increment's rounding error added to the low parts (amp = 0: the same bits)."""
    sl = _sin_low(t, s, c2)
    d = t * y
    x, xl = _add(x, xl + amp * _fma(t, y, -d), d)
    p1, p2 = s * x, sl * x
    d = -p1 - p2
    _, f = _add(-p1, 0.0, -p2)
    y, yl = _add(y, yl + amp * (f - _fma(s, x, -p1) - _fma(sl, x, -p2)), d)
    d = t * y
    x, xl = _add(x, xl + amp * _fma(t, y, -d), d)
    return x, xl, y, yl


@njit(error_model="numpy")
def _shear_turn_low_parts(x, xl, y, yl, t, s, c2, amp):
    """kernels/compensated._shear_turn of a symmetric body with amp times the low parts' own increments
    added to the low parts (amp = 0: the same bits; amp = 1: the low parts turned too)."""
    sl = _sin_low(t, s, c2)
    x, xl = _add(x, xl + amp * (t * yl), t * y)
    y, yl = _add(y, yl - amp * ((s + sl) * xl), -(s * x) - sl * x)
    x, xl = _add(x, xl + amp * (t * yl), t * y)
    return x, xl, y, yl


@njit(error_model="numpy")
def _normalize_amplified(q, ql, amp):
    """kernels/compensated._normalize with amp times its increment's product errors (amp = 0: the same bits)."""
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0
    n2 += 2.0 * (q[0] * ql[0] + q[1] * ql[1] + q[2] * ql[2] + q[3] * ql[3])
    k = -0.5 * n2
    d = (k * q[0], k * q[1], k * q[2], k * q[3])
    e = (_fma(k, q[0], -d[0]), _fma(k, q[1], -d[1]), _fma(k, q[2], -d[2]), _fma(k, q[3], -d[3]))
    return _add4(q, (ql[0] + amp * e[0], ql[1] + amp * e[1], ql[2] + amp * e[2], ql[3] + amp * e[3]), d)


@njit(error_model="numpy")
def _sum_error(a, b, c, d, g, e, f):
    """(a + b) + (c d + g e f) as the turn's formulas round it (g = ±1), and its rounding error: the two
    products' (fma) and the three sums' (two-sum)."""
    p1, p2 = c * d, e * f
    s1, f1 = _add(p1, 0.0, g * p2)
    s0, f0 = _add(a, 0.0, b)
    r, f2 = _add(s0, 0.0, s1)
    return r, _fma(c, d, -p1) + g * _fma(e, f, -p2) + f1 + f0 + f2


@njit(error_model="numpy")
def _sinc_error(angle2, s):
    """sin(h)/(2h) − s, h = √angle2/2 < SMALL_ANGLE/2, with s kernels/rotation._cos_sinc_half's value: 0.5 + y,
    y the series' other terms to h^10 (its rounding ~eps |y|, |y| < h²/12), summed with 0.5 exactly."""
    h2 = 0.25 * angle2
    y = h2 * (-1.0 / 12 + h2 * (1.0 / 240 + h2 * (-1.0 / 10080 + h2 * (1.0 / 725760 + h2 * (-1.0 / 79833600)))))
    hi, lo = _add(0.5, 0.0, y)
    return (hi - s) + lo


@njit(error_model="numpy")
def _add_amp(hi, lo, d, amp):
    """kernels/compensated._add with amp times the rounding error of its y = d + lo added to the low part
    (amp = 0: the same bits)."""
    y = d + lo
    b = y - d
    ey = (d - (y - b)) + (lo - b)  # d + lo − y, exact (two-sum)
    s = hi + y
    b = s - hi
    return s, (hi - (s - b)) + (y - b) + amp * ey


@njit(error_model="numpy")
def _add4_amp(q, ql, d, amp):
    a0, l0 = _add_amp(q[0], ql[0], d[0], amp)
    a1, l1 = _add_amp(q[1], ql[1], d[1], amp)
    a2, l2 = _add_amp(q[2], ql[2], d[2], amp)
    a3, l3 = _add_amp(q[3], ql[3], d[3], amp)
    return (a0, a1, a2, a3), (l0, l1, l2, l3)


@njit(error_model="numpy")
def _kick_add_rounding(w, wl, q, h, body, amp):
    """kernels/compensated.kick with _add_amp for its sums."""
    t0, t1, t2 = gravity_torque(q, body)
    a0, l0 = _add_amp(w[0], wl[0], h * t0 / body[0], amp)
    a1, l1 = _add_amp(w[1], wl[1], h * t1 / body[1], amp)
    a2, l2 = _add_amp(w[2], wl[2], h * t2 / body[2], amp)
    return (a0, a1, a2), (l0, l1, l2)


@njit(error_model="numpy")
def _normalize_exact(q, ql):
    """kernels/compensated._normalize with |q + ql|² − 1 to ~eps² (exact squares, two-sums), where the
    registered projection leaves |q + ql|² − 1 ≈ +1.4e-17 on the top's runs."""
    s = 0.0
    sl = 0.0
    for i in range(4):
        p, e = _two_prod(q[i], q[i])
        s, f = _add(s, 0.0, p)
        sl += f + e + 2.0 * q[i] * ql[i]
    k = -0.5 * ((s - 1.0) + sl)  # s − 1 exact: s is within a few eps of 1
    return _add4(q, ql, (k * q[0], k * q[1], k * q[2], k * q[3]))


@njit(error_model="numpy")
def _normalize_coarse(q, ql, scale):
    """kernels/compensated._normalize with |q|² − 1 from q rounded to multiples of 1/scale."""
    r0, r1 = round(q[0] * scale) / scale, round(q[1] * scale) / scale
    r2, r3 = round(q[2] * scale) / scale, round(q[3] * scale) / scale
    k = -0.5 * (r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3 - 1.0)
    return _add4(q, ql, (k * q[0], k * q[1], k * q[2], k * q[3]))


@njit(error_model="numpy")
def _flow(w, wl, q, ql, h, body, code, amp, dither=0.0):
    """kernels/compensated._symmetric_flow, with the variant ``code``'s rounding amplified by ``amp``, and the rate
    c of the turns about e3 times 1 + dither d, d in [−0.5, 0.5) from ω1's low bits (new on every substep)."""
    I1, I3 = body[0], body[2]
    ratio = I3 / I1
    k = ratio * (1.0 + amp) if code == 1 else ratio
    c = (1.0 - ratio) * (1.0 + amp) * w[2] if code == 2 else (1.0 - ratio) * w[2]
    if code == 23:  # dither_rate: the dither's amplitude is the variant's
        dither = amp
    if dither != 0.0:
        c *= 1.0 + dither * dither_number(w[0])
    r = w  # the rates of the turns; code 11: of ω + amp ωl (amp = 1: of the whole ω)
    if code == 11:
        r = (w[0] + amp * wl[0], w[1] + amp * wl[1], w[2] + amp * wl[2])
        c = (1.0 - ratio) * r[2]
    if code == 24:  # ω3 as both turns take it (not the state's) moved the same way as dither_rate's rate
        r = (w[0], w[1], w[2] * (1.0 + amp * dither_number(w[0])))
        c = (1.0 - ratio) * r[2]
    if code == 12 or code == 16:
        a1, u0, u1, u2 = _rotvec_amplified(w[0], w[1], w[2], k, h, amp)
    elif code == 17:
        v0, v1, v2 = w[0] * h, w[1] * h, k * w[2] * h
        angle2 = v0 * v0 + v1 * v1 + v2 * v2
        if angle2 >= SMALL_ANGLE * SMALL_ANGLE:
            raise ValueError("sinc_rounding: a turn beyond SMALL_ANGLE")
        a1, sinc = _cos_sinc_half(angle2)
        sinc += amp * _sinc_error(angle2, sinc)
        u0, u1, u2 = sinc * v0, sinc * v1, sinc * v2
    else:
        a1, u0, u1, u2 = quat_from_rotvec(r[0] * h, r[1] * h, k * r[2] * h)
    al1 = _minus_one(a1, u0, u1, u2)
    ch, sh = half_angle(c * h)
    al2 = _minus_one(ch, 0.0, 0.0, sh)
    alpha, v0, v1, v2 = then_e3_turn(al1, u0, u1, u2, al2, sh)
    if code == 15 or code == 16:
        # each formula as (a + b) + (c d ± e f); a one-term first sum (v0, v1) adds 0.0, the same bits
        alpha, ea = _sum_error(al1, al2, al1, al2, -1.0, u2, sh)
        v0, e0 = _sum_error(u0, 0.0, al2, u0, 1.0, u1, sh)
        v1, e1 = _sum_error(u1, 0.0, al2, u1, -1.0, u0, sh)
        v2, e2 = _sum_error(sh, u2, al1, sh, 1.0, al2, u2)
        alpha, v0, v1, v2 = alpha + amp * ea, v0 + amp * e0, v1 + amp * e1, v2 + amp * e2
    dq = quat_mul(q, (alpha, v0, v1, v2))
    if code == 10 or code == 16:
        e = quat_mul_low(q, (alpha, v0, v1, v2))
        dq = (dq[0] + amp * e[0], dq[1] + amp * e[1], dq[2] + amp * e[2], dq[3] + amp * e[3])
    if code == 5:
        e = quat_mul(ql, (alpha, v0, v1, v2))
        dq = (dq[0] + amp * e[0], dq[1] + amp * e[1], dq[2] + amp * e[2], dq[3] + amp * e[3])
    if code == 19:
        q, ql = _add4_amp(q, ql, dq, amp)
    elif code == 25 or code == 26 or code == 27:  # the increment of the whole q (the kernel since 2026-12-07)
        q, ql = _turn_whole(q, ql, (alpha, v0, v1, v2))
    else:
        q, ql = _add4(q, ql, dq)
    if code == 4:
        q, ql = _normalize_coarse(q, ql, amp)
    elif code == 22:
        q, ql = _normalize_exact(q, ql)
    elif code == 14 or code == 16:
        q, ql = _normalize_amplified(q, ql, amp)
    elif code == 19:
        n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0  # kernels/compensated._normalize's
        n2 += 2.0 * (q[0] * ql[0] + q[1] * ql[1] + q[2] * ql[2] + q[3] * ql[3])
        k = -0.5 * n2
        q, ql = _add4_amp(q, ql, (k * q[0], k * q[1], k * q[2], k * q[3]), amp)
    else:
        q, ql = _normalize(q, ql)
    t, sp = sh / ch, 2.0 * sh * ch
    # _shear_turn's s is s + s kyl + sl (ky = 1); kyl carries the variant: a relative error amp of s, or
    # −amp sl/s, which takes amp times _sin_low's low part off again (0 for the other variants)
    kyl = amp if code == 6 else (-amp * _sin_low(t, sp, ch * ch) / sp if code == 7 else 0.0)
    if code == 20 and amp != 0.0:  # the shears' angle 2 atan t moved by amp (rad), s closed to the new t
        t = t + amp * 0.5 * (1.0 + t * t)
        c2 = 1.0 / (1.0 + t * t)
        x, xl, y, yl = _shear_turn(w[0], wl[0], w[1], wl[1], t, 2.0 * t * c2, c2, 1.0, 1.0, 0.0)
    elif code == 21 or code == 26:
        x, xl, y, yl = _shear_turn_matched(w[0], wl[0], w[1], wl[1], sh, al2, sp, ch * ch)
    elif code == 27:
        x, xl, y, yl = _turn_matched(w[0], wl[0], w[1], wl[1], sh, al2)
    elif code == 13 or code == 16:
        x, xl, y, yl = _shear_turn_amplified(w[0], wl[0], w[1], wl[1], t, sp, ch * ch, amp)
    elif code == 18:
        x, xl, y, yl = _shear_turn_low_parts(w[0], wl[0], w[1], wl[1], t, sp, ch * ch, amp)
    elif code == 19:
        sl = _sin_low(t, sp, ch * ch)
        x, xl = _add_amp(w[0], wl[0], t * w[1], amp)
        y, yl = _add_amp(w[1], wl[1], -(sp * x) - sl * x, amp)
        x, xl = _add_amp(x, xl, t * y, amp)
    else:
        x, xl, y, yl = _shear_turn(w[0], wl[0], w[1], wl[1], t, sp, ch * ch, 1.0, 1.0, kyl)
    return (x, y, w[2]), (xl, yl, wl[2]), q, ql


@njit(parallel=True, error_model="numpy")
def _run_series(w0, q0, body, dt, stride, code, amp, out, dither=0.0):
    """out[i, k] = (ω, ωl, q, ql) of run i after k·stride steps, k = 0 … out.shape[1] − 1."""
    for i in prange(w0.shape[0]):
        w = (w0[i, 0], w0[i, 1], w0[i, 2])
        q = (q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3])
        wl = (0.0, 0.0, 0.0)
        ql = (0.0, 0.0, 0.0, 0.0)
        for k in range(out.shape[1]):
            if k > 0:
                for _ in range(stride):
                    for h in (W1 * dt, W0 * dt, W1 * dt):
                        w, wl = _kick(w, wl, q, ql, 0.5 * h, body, code, amp)
                        w, wl, q, ql = _flow(w, wl, q, ql, h, body, code, amp, dither)
                        w, wl = _kick(w, wl, q, ql, 0.5 * h, body, code, amp)
            for j in range(3):
                out[i, k, j], out[i, k, 3 + j] = w[j], wl[j]
            for j in range(4):
                out[i, k, 6 + j], out[i, k, 10 + j] = q[j], ql[j]


def _run(w0, q0, body, dt, n, code, amp, out):
    """out[i] = (ω, ωl, q, ql) after n steps of run i."""
    series = np.empty((w0.shape[0], 2, 14))
    _run_series(w0, q0, body, dt, n, code, amp, series)
    out[:] = series[:, 1]


def relative_energy_error(states, body, w0, q0):
    """E/E0 − 1 of states (..., 14) = (ω, ωl, q, ql), evaluated from hi + lo in long double."""
    w = states[..., 0:3].astype(np.longdouble) + states[..., 3:6]
    q = states[..., 6:10].astype(np.longdouble) + states[..., 10:14]
    E = energy_extended(w, q, body)
    E0 = energy_extended(w0, q0, body)
    return np.asarray(E / (E0 if E.ndim == 1 else E0[:, None]) - 1, dtype=np.float64)


def energy_evaluation_error(states, body, w0, q0):
    """max over the runs of |relative_energy_error − the same at 50 digits| (mpmath, from the exact hi + lo;
    brouwer.energy_extended's formula): how far the long-double evaluation of E/E0 − 1 itself is off."""
    try:
        import mpmath
    except ImportError:
        raise SystemExit("--exact-energy needs mpmath (in the test extra: pip install '.[test]')") from None

    mp = mpmath.mp.clone()
    mp.dps = 50

    def energy(w, q):
        w = [mp.mpf(float(x)) for x in w]
        q = [mp.mpf(float(x)) for x in q]
        n = mp.sqrt(sum(x * x for x in q))
        a, b, c, d = (x / n for x in q)
        g1, g2, g3 = 2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - b * b - c * c
        I = [mp.mpf(float(x)) for x in body]
        return (I[0] * w[0] ** 2 + I[1] * w[1] ** 2 + I[2] * w[2] ** 2) / 2 + I[3] * g3 + I[4] * g1 + I[5] * g2

    worst = 0.0
    e = relative_energy_error(states, body, w0, q0)
    for i, st in enumerate(states):
        w = [mp.mpf(float(st[j])) + mp.mpf(float(st[3 + j])) for j in range(3)]
        q = [mp.mpf(float(st[6 + j])) + mp.mpf(float(st[10 + j])) for j in range(4)]
        exact = energy(w, q) / energy(w0[i], q0[i]) - 1
        worst = max(worst, abs(float(exact - mp.mpf(float(e[i])))))
    return worst


def check_copy(body, w0, q0, dt, variants):
    """Exit with one line unless ``turn_exact_rotation`` is the registered lie_poisson4(accumulate=compensated) bit
    for bit over 1000 steps of the first run, and each variant (but those in NO_IDENTITY) at amplitude 0 is the
    copy (the registered map before 2026-12-07)."""
    now = np.empty((1, 14))
    _run(w0[:1], q0[:1], body, dt, 1000, VARIANTS["turn_exact_rotation"][0], 1.0, now)
    registered = run_compensated("lie_poisson4", w0[:1], q0[:1], body, dt, 1000, 2)[0, 1]
    if not np.array_equal(now[0], registered):
        raise SystemExit(f"turn_exact_rotation and lie_poisson4(accumulate=compensated) differ: {now[0]} {registered}")
    check = np.empty((1, 14))
    _run(w0[:1], q0[:1], body, dt, 1000, 0, 0.0, check)
    for name, (code, _) in variants.items():
        if code in NO_IDENTITY:
            continue
        zero = np.empty((1, 14))
        _run(w0[:1], q0[:1], body, dt, 1000, code, 0.0, zero)
        if not np.array_equal(zero[0], check[0]):
            raise SystemExit(f"{name} at amplitude 0 differs from the registered variant")


def probe(runs, steps, seed, variants=VARIANTS, exact=False, dt=None):
    body, w0, q0, dt0 = ensemble("heavy_top", runs, seed)
    dt = dt or dt0
    check_copy(body, w0, q0, dt, variants)
    head = f"{runs} runs x {steps:.3g} steps, heavy top 50 Hz, dt = {dt:g} s"
    print(f"{head}; the copy equals the registered variant, and so does each variant at amplitude 0")
    print(f"{'variant':<16} {'amplitude':>10} {'mean of E/E0 - 1 ± s.e.':>24} {'per step':>10} {'s':>5}")
    for name, (code, amps) in variants.items():
        for amp in amps:
            out = np.empty((runs, 14))
            t0 = time.perf_counter()
            _run(w0, q0, body, dt, int(steps), code, amp, out)
            wall = time.perf_counter() - t0
            e = relative_energy_error(out, body, w0, q0)
            mean, se = e.mean(), e.std(ddof=1) / np.sqrt(runs)
            print(f"{name:<16} {amp:10.3g} {mean:12.3e} ± {se:8.1e} {mean / steps:10.2e} {wall:5.1f}", flush=True)
            if exact:
                print(f"  long double against 50 digits: {energy_evaluation_error(out, body, w0, q0):.1e} at most")


def curve(runs, steps, seed, samples=1000, dt=None):
    body, w0, q0, dt0 = ensemble("heavy_top", runs, seed)
    dt = dt or dt0
    stride = max(1, round(steps / samples))
    t0 = time.perf_counter()
    states = run_compensated("lie_poisson4", w0, q0, body, dt, stride, samples + 1)
    wall = time.perf_counter() - t0
    e = relative_energy_error(states[:, 1:], body, w0, q0)
    t = np.arange(1, samples + 1) * stride * dt
    mean, se, rms = e.mean(0), e.std(0, ddof=1) / np.sqrt(runs), np.sqrt((e**2).mean(0))
    head = f"lie_poisson4(accumulate=compensated), {runs} runs (seed {seed}) x {stride * samples:.3g} steps"
    print(f"{head}, {wall:.0f} s")
    print(f"{'t (s)':>9} {'mean of E/E0 - 1 ± s.e.':>24} {'RMS':>10}")
    for k in np.unique(np.geomspace(1, samples, 25).astype(int)) - 1:
        print(f"{t[k]:9.4g} {mean[k]:12.3e} ± {se[k]:8.1e} {rms[k]:10.3e}")
    a, b = np.polyfit(t, mean, 1)
    # no error for a: the means at different times share the walk up to the earlier one (judge the trend
    # by the end's mean against its standard error, and by another seed)
    print(f"mean = a t + b: a = {a:.3g} /s ({a * dt:.2g} per step), b = {b:.3g}")


def vertical_momentum(w, q, body):
    """L·ẑ (kg m²/s) of states ω (..., 3) and q (..., 4) in long double: L = I ω in the body frame dotted with
    γ = Rᵀ ẑ, q normalised first.  Every substep of the top's splitting conserves it exactly (the kick's
    torque m3 γ × e3 is horizontal, the free flow keeps L in space)."""
    w = w.astype(np.longdouble)
    g1, g2, g3 = up_in_body_extended(q)
    inertia = body.astype(np.longdouble)
    return inertia[0] * w[..., 0] * g1 + inertia[1] * w[..., 1] * g2 + inertia[2] * w[..., 2] * g3


def relative_vertical_momentum(states, body):
    """Lz/Lz0 − 1 of one run's states (samples, 14) = (ω, ωl, q, ql), from hi + lo in long double."""
    w = states[:, 0:3].astype(np.longdouble) + states[:, 3:6]
    q = states[:, 6:10].astype(np.longdouble) + states[:, 10:14]
    lz = vertical_momentum(w, q, body)
    return np.asarray(lz / lz[0] - 1, dtype=float)


# Seconds between the trend's samples (13 steps at 5e-4 s): many samples a nutation (~0.17 s) and no multiple of
# the spin's period (20 ms), so that the fits and block means average the common oscillation out; ~1.4 GB of
# states for 32 runs of 2500 s at any dt.
TREND_SPACING = 6.5e-3


def run_long_double(w0, q0, body, dt, stride, samples):
    """(E/E0 − 1, Lz/Lz0 − 1), each (runs, samples), of lie_poisson4's step on the top written plainly in numpy's
    long double (64-bit significand: 2048 times finer than double), every run at once: the same map as the
    compensated kernel (the same W1, W0 and body constants; the body's turns from cosl and sinl, the projection
    q/|q|), rounded differently.  Slow (~2.3 ms a step on this VM)."""
    ld = np.longdouble
    b = body.astype(ld)
    i1, i2, i3, m3 = b[0], b[1], b[2], b[3]
    ratio = i3 / i1
    w0_, w1_, w2 = (w0[:, j].astype(ld) for j in range(3))
    a, bq, c, d = (q0[:, j].astype(ld) for j in range(4))

    def invariants():
        w, q = np.stack((w0_, w1_, w2), axis=-1), np.stack((a, bq, c, d), axis=-1)
        return energy_extended(w, q, body), vertical_momentum(w, q, body)

    e = np.empty((samples, w0.shape[0]), dtype=ld)
    lz = np.empty_like(e)
    e[0], lz[0] = invariants()
    rate = (1 - ratio) * w2  # the turn of L about e3, constant on the top

    def kick(w0_, w1_, a, bq, c, d, h):
        g1, g2 = 2 * (bq * d - a * c), 2 * (c * d + a * bq)  # γ1, γ2 = (Rᵀ ẑ)1,2; τ = m3 (γ2, −γ1, 0)
        return w0_ + h * (m3 * g2) / i1, w1_ - h * (m3 * g1) / i2

    for k in range(1, samples):
        for _ in range(stride):
            for h in (ld(W1) * ld(dt), ld(W0) * ld(dt), ld(W1) * ld(dt)):
                w0_, w1_ = kick(w0_, w1_, a, bq, c, d, h / 2)
                # the free flow: R(h) = R Rot((ω⊥, (I3/I1) ω3) h) Rot(c h e3), ω⊥ turned by −c h
                v0, v1, v2 = w0_ * h, w1_ * h, ratio * w2 * h
                phi = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
                a1, s = np.cos(phi / 2), np.sin(phi / 2) / phi
                u0, u1, u2 = s * v0, s * v1, s * v2
                ch, sh = np.cos(rate * h / 2), np.sin(rate * h / 2)
                pa, pb, pc, pd = a1 * ch - u2 * sh, u0 * ch + u1 * sh, u1 * ch - u0 * sh, a1 * sh + u2 * ch
                a, bq, c, d = (
                    a * pa - bq * pb - c * pc - d * pd,
                    a * pb + bq * pa + c * pd - d * pc,
                    a * pc - bq * pd + c * pa + d * pb,
                    a * pd + bq * pc - c * pb + d * pa,
                )
                n = np.sqrt(a * a + bq * bq + c * c + d * d)
                a, bq, c, d = a / n, bq / n, c / n, d / n
                co, si = np.cos(rate * h), np.sin(rate * h)
                w0_, w1_ = co * w0_ + si * w1_, co * w1_ - si * w0_
                w0_, w1_ = kick(w0_, w1_, a, bq, c, d, h / 2)
        e[k], lz[k] = invariants()
    return np.asarray(e / e[0] - 1, float).T, np.asarray(lz / lz[0] - 1, float).T


def trend_sampling(dt, t_end):
    """(steps, steps between samples, samples) of a trend run."""
    n = int(round(t_end / dt))
    stride = max(1, round(TREND_SPACING / dt))
    return n, stride, n // stride + 1


def trend(
    runs,
    seed,
    dt,
    t_end,
    method="lie_poisson4",
    gravity=1.0,
    variant=None,
    amplitude=None,
    long_double=False,
    perturbation=1e-9,
    dither=0.0,
    double_double=None,
):
    """The top's drift where it is cheap to see: at dt = 5e-4 s its truncation oscillation (~3e-13, common to
    the runs) averages out over 2500 s, and the drift, ~20x faster per second than at 2.5e-5 s, stands out
    in a minute or two.  Prints each run's fitted slope of E/E0 − 1 and of Lz/Lz0 − 1 (their mean ± s.e. and
    spread), the ensemble mean of E/E0 − 1 over ten blocks of time, and how far the runs depart from the
    ensemble mean at t/4, t/2 and t (∝ t: a drift of each run's own; ∝ √t: a walk).  ``dither`` runs the copy (or
    the variant) with the turns' rate c dithered by that relative amount on every substep.  ``double_double``
    (comma-separated PIECES, '' for none) runs the step in double-double with those pieces in double
    (benchmarks/double_double_top.py)."""
    body, w0, q0, _ = ensemble("heavy_top", runs, seed, perturbation)
    body = body.copy()
    body[3] *= gravity  # m g l
    n, stride, samples = trend_sampling(dt, t_end)
    t0 = time.perf_counter()
    states = None
    if long_double:
        e, lz = run_long_double(w0, q0, body, dt, stride, samples)
        what = f"{method}'s step in long double, plain"
    elif double_double is not None:
        states = run_series(w0, q0, body, dt, stride, samples, pieces_mask(double_double), dither)
        what = f"{method}'s step in double-double, in double: {double_double or 'nothing'}"
        if dither:
            what += f", the turns' rate dithered by {dither:g}"
    elif variant is None and dither == 0.0:
        states = run_compensated(method, w0, q0, body, dt, stride, samples)
        what = f"{method}(accumulate=compensated)"
    else:
        variant, amp = (variant, amplitude) if variant else ("copy", 0.0)
        code = VARIANTS[variant][0]
        check_copy(body, w0, q0, dt, {variant: VARIANTS[variant]})
        states = np.empty((runs, samples, 14))
        _run_series(w0, q0, body, dt, stride, code, amp, states, dither)
        what = f"the copy of lie_poisson4(accumulate=compensated), {variant} at {amp:g}"
        if dither:
            what += f", the turns' rate dithered by {dither:g}"
    wall = time.perf_counter() - t0
    if states is not None:
        e = np.array([relative_energy_error(st, body, w0[i], q0[i]) for i, st in enumerate(states)])
        lz = np.array([relative_vertical_momentum(st, body) for st in states])  # run by run: ~40 MB at a time
    t = np.arange(samples) * stride * dt
    keep = t >= 0.02 * t_end
    head = f"{what}, heavy top 50 Hz 45°, m g l x {gravity:g}; {runs} runs (seed {seed}, ω0 perturbed {perturbation:g})"
    print(f"{head} x {n:.3g} steps of {dt:g} s")
    print(f"({wall:.0f} s to integrate)")
    r = np.sqrt(runs)
    for name, x in (("E/E0 - 1", e), ("Lz/Lz0 - 1", lz)):
        slopes = np.polyfit(t[keep], x[:, keep].T, 1)[0]
        m, sd = slopes.mean(), slopes.std(ddof=1)
        print(f"{name:>10}: slope {m:10.3e} ± {sd / r:7.1e} /s ({m * dt:.2e} per step), runs' spread {sd:.2e} /s")
    mean = e.mean(0)
    edges = np.linspace(0.0, t_end, 11)
    blocks = [mean[(t >= lo) & (t < hi)].mean() for lo, hi in zip(edges[:-1], edges[1:])]
    print("ensemble mean of E/E0 - 1 over ten blocks of t_end/10:", " ".join(f"{b:.4e}" for b in blocks))
    departure = np.sqrt(((e - mean) ** 2).mean(0))
    quarters = [departure[(samples - 1) // 4], departure[(samples - 1) // 2], departure[-1]]
    print("RMS departure from the ensemble mean at t/4, t/2, t:", " ".join(f"{d:.2e}" for d in quarters))
    # each run's own drift, fitted in each quarter of the run (the first from 2 % of t_end): a rate the run keeps
    # correlates from quarter to quarter; a walk's slopes do not
    own = []
    for lo, hi in ((0.02, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0)):
        part = (t >= lo * t_end) & (t <= hi * t_end)
        own.append(np.polyfit(t[part], (e - mean)[:, part].T, 1)[0])
    corr = np.corrcoef(own)
    pairs = corr[np.triu_indices(4, 1)]
    spreads = " ".join(f"{s.std(ddof=1):.2e}" for s in own)
    print(f"each run's own slope by quarter: spread {spreads} /s;", end=" ")
    print(f"correlation between quarters {pairs.min():.2f} to {pairs.max():.2f}")


def response(runs, seed, dts, t_end, variant, amplitude, samples=41):
    """The drift a variant makes against the copy, at each step of ``dts``: the slope over ``t_end`` seconds
    (``samples`` samples) of each run's difference of E/E0 − 1 and of Lz/Lz0 − 1, variant less copy; their mean
    ± standard error over the runs, per second, and the energy's per substep."""
    body, w0, q0, _ = ensemble("heavy_top", runs, seed)
    code = VARIANTS[variant][0]
    print(f"{variant} at {amplitude:g} against the copy, heavy top 50 Hz 45°; {runs} runs (seed {seed}) x {t_end:g} s")
    print(f"{'dt (s)':>8} {'E slope ± s.e. (/s)':>22} {'per substep':>12} {'Lz slope ± s.e. (/s)':>22} {'s':>5}")
    for dt in dts:
        check_copy(body, w0, q0, dt, {variant: VARIANTS[variant]})
        stride = max(1, round(t_end / dt / (samples - 1)))
        t = np.arange(samples) * stride * dt
        t0 = time.perf_counter()
        series = []
        for amp in (0.0, amplitude):
            states = np.empty((runs, samples, 14))
            _run_series(w0, q0, body, dt, stride, code if amp else 0, amp, states)
            e = np.array([relative_energy_error(st, body, w0[i], q0[i]) for i, st in enumerate(states)])
            lz = np.array([relative_vertical_momentum(st, body) for st in states])
            series.append((e, lz))
        wall = time.perf_counter() - t0
        (e0, lz0), (e1, lz1) = series
        cells = []
        for d in (e1 - e0, lz1 - lz0):
            slopes = np.polyfit(t, d.T, 1)[0]
            cells.append((slopes.mean(), slopes.std(ddof=1) / np.sqrt(runs)))
        (e_slope, e_se), (lz_slope, lz_se) = cells
        substep = e_slope * dt / len(WEIGHTS)  # three substeps a step
        line = f"{dt:8.3g} {e_slope:11.4e} ± {e_se:8.1e} {substep:12.3e} {lz_slope:11.4e} ± {lz_se:8.1e}"
        print(f"{line} {wall:5.1f}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("curve", "probe", "trend", "response"))
    ap.add_argument("--runs", type=int, default=None, help="runs (default: curve 32, probe 8, trend 32, response 2)")
    ap.add_argument("--steps", type=float, default=None, help="steps a run (default: curve 1e8, probe 1e6)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dt", type=float, default=None, help="time step (s; default brouwer.py's 2.5e-5, trend 5e-4)")
    ap.add_argument("--t-end", type=float, default=None, help="trend, response: seconds a run (default 2500, 20)")
    ap.add_argument(
        "--dts", default="2.5e-4,5e-4,1e-3,2e-3", help="response: steps (s), comma-separated (default 2.5e-4 … 2e-3)"
    )
    ap.add_argument("--method", choices=("lie_poisson4", "split6_exact"), default="lie_poisson4", help="trend")
    ap.add_argument("--gravity", type=float, default=1.0, help="trend: m g l times this (default 1)")
    ap.add_argument(
        "--perturbation", type=float, default=1e-9, help="trend: relative perturbation of the runs' ω0 (default 1e-9)"
    )
    ap.add_argument(
        "--dither", type=float, default=0.0, help="trend: the turns' rate times 1 + A d on every substep (|d| < 0.5)"
    )
    ap.add_argument(
        "--long-double", action="store_true", help="trend: lie_poisson4's step plainly in long double (numpy; slow)"
    )
    ap.add_argument(
        "--double-double",
        nargs="?",
        const="",
        metavar="PIECES",
        help=f"trend: the step in double-double, PIECES of it in double (comma-separated: {', '.join(PIECES)})",
    )
    ap.add_argument("--variant", choices=list(VARIANTS), help="probe, trend: this variant only (with --amplitude)")
    ap.add_argument("--amplitude", type=float, default=None, help="probe, trend: the variant's amplitude")
    ap.add_argument(
        "--exact-energy", action="store_true", help="probe: also check each run's E/E0 − 1 at 50 digits (mpmath)"
    )
    args = ap.parse_args(argv)
    runs = args.runs or {"curve": 32, "probe": 8, "trend": 32, "response": 2}[args.what]
    steps = args.steps or (1e8 if args.what == "curve" else 1e6)
    if runs < 2 or steps < 1000:
        ap.error("--runs: at least 2; --steps: at least 1000")
    if args.dt is not None and not 0.0 < args.dt <= 1e-3:
        ap.error("--dt: in (0, 1e-3] s")
    trend_only = args.method != "lie_poisson4" or args.gravity != 1.0 or args.long_double or args.perturbation != 1e-9
    if args.what != "trend" and (trend_only or args.dither or args.double_double is not None):
        ap.error("--method, --gravity, --perturbation, --dither, --long-double, --double-double: trend only")
    if args.what not in ("trend", "response") and args.t_end is not None:
        ap.error("--t-end: trend and response only")
    if args.what != "response" and args.dts != ap.get_default("dts"):
        ap.error("--dts: response only (the others take --dt)")
    if (args.variant is None) != (args.amplitude is None) or (args.variant and args.what == "curve"):
        ap.error("--variant and --amplitude go together, with probe, trend or response")
    if args.what == "response":
        if args.steps is not None or args.exact_energy or args.dt is not None:
            ap.error("response: --runs, --dts, --t-end, --variant and --amplitude (and --seed) only")
        try:
            dts = [float(x) for x in args.dts.split(",")]
        except ValueError:
            ap.error(f"--dts {args.dts!r}: steps in seconds, comma-separated")
        t_end = args.t_end or 20.0
        if not all(0.0 < dt <= 1e-2 and 40 * dt <= t_end <= 1e6 * dt for dt in dts):
            ap.error("--dts: each in (0, 1e-2] s, with 40 to 1e6 steps in --t-end")
        variant, amplitude = args.variant or "turn_mismatch", args.amplitude or 1e-13
        if variant == "copy" or amplitude == 0.0:
            ap.error("--variant copy or --amplitude 0: no difference to measure")
        response(runs, args.seed, dts, t_end, variant, amplitude)
    elif args.what == "trend":
        if args.steps is not None or args.exact_energy:
            ap.error("--steps, --exact-energy: curve and probe (trend's length is --t-end)")
        if (args.variant or args.long_double or args.dither) and args.method != "lie_poisson4":
            ap.error("--variant, --dither, --long-double: lie_poisson4's step only")
        if args.dither and (args.long_double or not 0.0 < args.dither <= 1e-6):
            ap.error("--dither: in (0, 1e-6], not with --long-double")
        if sum((bool(args.variant), args.long_double, args.double_double is not None)) > 1:
            ap.error("--variant, --long-double and --double-double: one of them")
        if args.double_double is not None:
            pieces_mask(args.double_double)  # an unknown piece: one line, before any work
            if args.method != "lie_poisson4":
                ap.error("--double-double: lie_poisson4's step only")
        dt = args.dt or 5e-4
        t_end = args.t_end or 2500.0
        if not 100 * dt <= t_end <= 1e8 * dt or not 0.0 < args.gravity <= 100.0:
            ap.error("--t-end: 100 to 1e8 steps; --gravity: in (0, 100]")
        if not 0.0 < args.perturbation <= 1e-3:
            ap.error("--perturbation: in (0, 1e-3]")
        if runs * trend_sampling(dt, t_end)[2] * 14 * 8 > 8e9:  # the states held for the fits
            ap.error("--runs x --t-end: over 8 GB of samples (32 runs of 2500 s take 1.4 GB); fewer or shorter")
        variant = (args.variant, args.amplitude)
        more = {"long_double": args.long_double, "perturbation": args.perturbation, "dither": args.dither}
        more["double_double"] = args.double_double
        trend(runs, args.seed, dt, t_end, args.method, args.gravity, *variant, **more)
    elif args.what == "curve":
        curve(runs, steps, args.seed, dt=args.dt)
    elif args.variant:
        variant = {args.variant: (VARIANTS[args.variant][0], (args.amplitude,))}
        probe(runs, steps, args.seed, variant, args.exact_energy, args.dt)
    else:
        probe(runs, steps, args.seed, exact=args.exact_energy, dt=args.dt)


if __name__ == "__main__":
    main()
