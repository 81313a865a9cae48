"""lie_poisson4 on the symmetric heavy top in double-double arithmetic, whole or piece by piece (issue 22, item 4).

    python benchmarks/compensated_bias.py trend --double-double [PIECES] [--dither A]

The map of ``lie_poisson4(accumulate=compensated)`` on the heavy top (Yoshida's triple jump of kick(h/2), the
symmetric body's exact free flow, kick(h/2)) with every number a double-double, an unevaluated sum hi + lo of
two doubles (~1e-32 relative; Dekker 1971, the QD library's arithmetic of Hida, Li & Bailey 2001): the same map
as the double kernel, rounded ~1e16 times finer, so its energy error is the map's own (the truncation's
oscillation), with no rounding bias.  ``PIECES`` (comma-separated) computes some pieces of the step as the
double kernel did before 2026-12-07 instead, on the double-double state's high and low parts:

- ``kicks``: kernels/compensated.kick (the torque from q's high part, h τ/I rounded, added error-free);
- ``turn``: the body's turn about the rotation vector (ω1 h, ω2 h, (I3/I1) ω3 h) and about e3 by c h, both
  parts below;
- ``turn_quaternion``: that turn's quaternion (α, u) in double (rotation.quat_from_rotvec, rotation.half_angle,
  the composition's formulas), applied in double-double;
- ``turn_application``: the double-double turn quaternion rounded to double and added as the kernel did, q's
  high part times it, rounded (rotation.quat_mul), then compensated._add4;
- ``projection``: compensated._normalize (|q|² − 1 from q's high part in double);
- ``shears``: ω⊥ turned by compensated._shear_turn with t = sh/ch of the double half_angle(c h);
- ``shears_matched``: ω⊥ turned by ``_shear_turn_matched`` below, Paeth's three shears by the angle of the
  double constants' turn about e3 (the kernel earlier on 2026-12-07:
  ``kicks,projection,turn_quaternion,application_whole_exact,shears_matched``);
- ``turn_matched``: ω⊥ turned by compensated._turn_matched, a rotation by that angle with its constants and
  products exact to ~eps² (the kernel since, ``kicks,projection,turn_quaternion,application_whole_exact,
  turn_matched``).

and ``application_high_exact``, ``application_whole_rounded``, ``application_whole_exact`` (with
``turn_quaternion``) apply the double quaternion as q's high part times it exactly (its rounding error to the
low part, ql not turned), as the whole q times it rounded (ql ⊗ (α, u) added to the rounded product) and as
the whole q times it with the product's rounding error and ql's turn passed to the low part
(kernels/compensated._turn_whole, the kernel since 2026-12-07; the compensated sum's one rounding is left).

Every piece uses the same h = fl(w dt) and ratio fl(I3/I1), so the pieces are parts of one map (with the exact
product w dt instead, a double piece's h would differ from the others' by the same rounding on every run, a
common error of its own).  The turn's rate c = (1 − I3/I1) ω3 (times the dither) is a double-double; double
pieces take its high part.
"""

import math
from fractions import Fraction

import numpy as np
from numba import njit, prange

from gyrolab.kernels.compensated import (
    _add,
    _add4,
    _fma,
    _minus_one,
    _normalize,
    _shear_turn,
    _sin_low,
    _turn_matched,
    _turn_whole,
    kick,
    then_e3_turn,
)
from gyrolab.kernels.methods.lie_poisson4 import WEIGHTS
from gyrolab.kernels.rotation import half_angle, quat_from_rotvec, quat_mul

W1, W0 = WEIGHTS[0], WEIGHTS[1]
PIECES = {
    "kicks": 1,
    "turn": 2,
    "projection": 4,
    "shears": 8,
    "turn_quaternion": 16,
    "turn_application": 32,
    "application_high_exact": 64,
    "application_whole_rounded": 128,
    "application_whole_exact": 256,
    "shears_matched": 512,
    "turn_matched": 1024,
}


def pieces_mask(names):
    """The bit mask of comma-separated PIECES names ('' for none); one line and exit on an unknown one."""
    mask = 0
    for name in filter(None, (n.strip() for n in names.split(","))):
        if name not in PIECES:
            raise SystemExit(f"--double-double: unknown piece {name!r}; one of {', '.join(PIECES)}")
        mask |= PIECES[name]
    return mask


@njit(error_model="numpy")
def _shear_turn_matched(x, xl, y, yl, sh, al2, s, c2):
    """The symmetric body's turn of ω⊥ in kernels/compensated.py earlier on 2026-12-07, kept to compare: by the
    angle of the body's turn about e3, (1 + α2, sh e3), as Paeth's three shears with t + tl = sh/(1 + α2) (the
    tangent of that turn's half angle) and s + sl closed to it, ω⊥'s low parts sheared too: a rotation to ~eps²,
    but each shear's rounded product t y, s x (and the rounding of it plus the low part) loses ~eps of it."""
    dh, dl = _add(1.0, 0.0, al2)  # 1 + α2 = dh + dl exactly
    t = sh / dh
    tl = (_fma(-t, dh, sh) - t * dl) / dh
    sl = _sin_low(t, s, c2) + tl * 2.0 * (1.0 - t * t) * c2 * c2  # d(2t/(1 + t²))/dt = 2(1 − t²)/(1 + t²)²
    x, xl = _add(x, xl + (tl * y + t * yl), t * y)
    y, yl = _add(y, yl - (s + sl) * xl, -(s * x) - sl * x)
    x, xl = _add(x, xl + (tl * y + t * yl), t * y)
    return x, xl, y, yl


# --- double-double arithmetic: (hi, lo) with |lo| ≤ ulp(hi)/2 ---


@njit(error_model="numpy")
def _two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@njit(error_model="numpy")
def _fast_two_sum(a, b):  # |a| ≥ |b|
    s = a + b
    return s, b - (s - a)


@njit(error_model="numpy")
def add(x, y):
    s, e = _two_sum(x[0], y[0])
    t, f = _two_sum(x[1], y[1])
    s, e = _fast_two_sum(s, e + t)
    return _fast_two_sum(s, e + f)


@njit(error_model="numpy")
def sub(x, y):
    return add(x, (-y[0], -y[1]))


@njit(error_model="numpy")
def mul(x, y):
    p = x[0] * y[0]
    return _fast_two_sum(p, _fma(x[0], y[0], -p) + (x[0] * y[1] + x[1] * y[0]))


@njit(error_model="numpy")
def mul_double(x, d):
    p = x[0] * d
    return _fast_two_sum(p, _fma(x[0], d, -p) + x[1] * d)


@njit(error_model="numpy")
def div(x, y):
    q1 = x[0] / y[0]
    r = sub(x, mul_double(y, q1))
    q2 = r[0] / y[0]
    r = sub(r, mul_double(y, q2))
    return add(_fast_two_sum(q1, q2), (r[0] / y[0], 0.0))


def _inverse_factorials(n):
    """1/k! as double-doubles, k = 0 … n."""
    out = np.zeros((n + 1, 2))
    for k in range(n + 1):
        f = Fraction(1, math.factorial(k))
        out[k, 0] = float(f)
        out[k, 1] = float(f - Fraction(out[k, 0]))
    return out


INVERSE_FACTORIALS = _inverse_factorials(35)


@njit(error_model="numpy")
def cos_sinc(y, inv):
    """(cos x, sin(x)/x) from y = x² (double-double), Taylor to x^32 and x^33: below 1e-32 for |x| < 0.5."""
    c = (0.0, 0.0)
    s = (0.0, 0.0)
    for k in range(16, -1, -1):
        sign = 1.0 if k % 2 == 0 else -1.0
        c = add((sign * inv[2 * k, 0], sign * inv[2 * k, 1]), mul(y, c))
        s = add((sign * inv[2 * k + 1, 0], sign * inv[2 * k + 1, 1]), mul(y, s))
    return c, s


# --- the step ---


@njit(error_model="numpy")
def _kick(w0, w1, q, h, body, double):
    """ω⊥ after gravity's torque at q for h seconds (the top: τ = m3 (γ2, −γ1, 0), γ = Rᵀ ẑ)."""
    a, b, c, d = q
    if double:
        w, wl = kick((w0[0], w1[0], 0.0), (w0[1], w1[1], 0.0), (a[0], b[0], c[0], d[0]), h[0], body)
        return (w[0], wl[0]), (w[1], wl[1])
    g1 = mul_double(sub(mul(b, d), mul(a, c)), 2.0)
    g2 = mul_double(add(mul(c, d), mul(a, b)), 2.0)
    w0 = add(w0, div(mul(h, mul_double(g2, body[3])), (body[0], 0.0)))
    w1 = sub(w1, div(mul(h, mul_double(g1, body[3])), (body[1], 0.0)))
    return w0, w1


@njit(error_model="numpy")
def _split(q):
    return (q[0][0], q[1][0], q[2][0], q[3][0]), (q[0][1], q[1][1], q[2][1], q[3][1])


@njit(error_model="numpy")
def _join(hi, lo):
    return (hi[0], lo[0]), (hi[1], lo[1]), (hi[2], lo[2]), (hi[3], lo[3])


@njit(error_model="numpy")
def _product(q, p):
    """q ⊗ p of double-double quaternions."""
    a, b, c, d = q
    pa, pb, pc, pd = p
    return (
        sub(sub(sub(mul(a, pa), mul(b, pb)), mul(c, pc)), mul(d, pd)),
        sub(add(add(mul(a, pb), mul(b, pa)), mul(c, pd)), mul(d, pc)),
        add(add(sub(mul(a, pc), mul(b, pd)), mul(c, pa)), mul(d, pb)),
        add(sub(add(mul(a, pd), mul(b, pc)), mul(c, pb)), mul(d, pa)),
    )


@njit(error_model="numpy")
def _flow(w0, w1, w2, q, h, rate, k, inv, mask):
    """The symmetric body's exact free flow for h seconds: the body turns by Rot((ω1 h, ω2 h, k ω3 h)) Rot(c h e3),
    ω⊥ by −c h about e3 (k = I3/I1, c = ``rate``)."""
    half = (0.5 * h[0], 0.0)
    ch_d, sh_d = half_angle(rate[0] * h[0])  # the double pieces' constants
    x = mul(rate, half)
    ch, sinc = cos_sinc(mul(x, x), inv)
    sh = mul(sinc, x)
    double_quaternion = mask & (2 | 16)
    if double_quaternion:
        a1, u0, u1, u2 = quat_from_rotvec(w0[0] * h[0], w1[0] * h[0], k * w2[0] * h[0])
        al1 = _minus_one(a1, u0, u1, u2)
        al2 = _minus_one(ch_d, 0.0, 0.0, sh_d)
        pa, pb, pc, pd = then_e3_turn(al1, u0, u1, u2, al2, sh_d)
        p = ((pa, 0.0), (pb, 0.0), (pc, 0.0), (pd, 0.0))
    else:
        v0, v1, v2 = mul(w0, h), mul(w1, h), mul_double(mul(w2, h), k)
        a1, s = cos_sinc(mul_double(add(add(mul(v0, v0), mul(v1, v1)), mul(v2, v2)), 0.25), inv)
        s = mul_double(s, 0.5)
        u0, u1, u2 = mul(s, v0), mul(s, v1), mul(s, v2)
        p = (
            sub(sub(mul(a1, ch), mul(u2, sh)), (1.0, 0.0)),  # α = p_a − 1
            add(mul(u0, ch), mul(u1, sh)),
            sub(mul(u1, ch), mul(u0, sh)),
            add(mul(a1, sh), mul(u2, ch)),
        )
    hi, lo = _split(q)
    ph = (p[0][0], p[1][0], p[2][0], p[3][0])
    if mask & (2 | 32):  # as the kernel before 2026-12-07
        q = _join(*_add4(hi, lo, quat_mul(hi, ph)))
    elif mask & 64:  # q's high part times p exactly, ql not turned
        e = _product(((hi[0], 0.0), (hi[1], 0.0), (hi[2], 0.0), (hi[3], 0.0)), p)
        d = (e[0][0], e[1][0], e[2][0], e[3][0])
        q = _join(*_add4(hi, (lo[0] + e[0][1], lo[1] + e[1][1], lo[2] + e[2][1], lo[3] + e[3][1]), d))
    elif mask & 128:  # the whole q times p, rounded
        d, r = quat_mul(hi, ph), quat_mul(lo, ph)
        q = _join(*_add4(hi, lo, (d[0] + r[0], d[1] + r[1], d[2] + r[2], d[3] + r[3])))
    elif mask & 256:
        q = _join(*_turn_whole(hi, lo, ph))
    else:
        e = _product(q, p)
        q = (add(q[0], e[0]), add(q[1], e[1]), add(q[2], e[2]), add(q[3], e[3]))
    if mask & 4:
        q = _join(*_normalize(*_split(q)))
    else:
        a, b, c, d = q
        n = sub(add(add(add(mul(a, a), mul(b, b)), mul(c, c)), mul(d, d)), (1.0, 0.0))
        f = add(sub((1.0, 0.0), mul_double(n, 0.5)), mul_double(mul(n, n), 0.375))  # 1/√(1 + n) to O(n³)
        q = (mul(a, f), mul(b, f), mul(c, f), mul(d, f))
    if mask & 8:
        t, s2, c2 = sh_d / ch_d, 2.0 * sh_d * ch_d, ch_d * ch_d
        xh, xl, yh, yl = _shear_turn(w0[0], w0[1], w1[0], w1[1], t, s2, c2, 1.0, 1.0, 0.0)
        w0, w1 = (xh, xl), (yh, yl)
    elif mask & 1024:
        al2 = _minus_one(ch_d, 0.0, 0.0, sh_d)
        xh, xl, yh, yl = _turn_matched(w0[0], w0[1], w1[0], w1[1], sh_d, al2)
        w0, w1 = (xh, xl), (yh, yl)
    elif mask & 512:
        al2 = _minus_one(ch_d, 0.0, 0.0, sh_d)
        xh, xl, yh, yl = _shear_turn_matched(w0[0], w0[1], w1[0], w1[1], sh_d, al2, 2.0 * sh_d * ch_d, ch_d * ch_d)
        w0, w1 = (xh, xl), (yh, yl)
    else:
        co, si = sub(mul(ch, ch), mul(sh, sh)), mul_double(mul(sh, ch), 2.0)
        w0, w1 = add(mul(co, w0), mul(si, w1)), sub(mul(co, w1), mul(si, w0))
    return w0, w1, q


@njit(error_model="numpy")
def dither_number(x):
    """A number in [−0.5, 0.5) from x's bits below 2^-20 (x = ω1, which every kick changes by far more): new on
    every substep, the same for the same state (the dither of benchmarks/compensated_bias.py trend)."""
    bits = x * 1048576.0
    return bits - math.floor(bits) - 0.5


@njit(error_model="numpy")
def _one_run(i, w0in, q0in, body, dt, stride, dither, inv, mask, out):
    k = body[2] / body[0]
    w0, w1, w2 = (w0in[i, 0], 0.0), (w0in[i, 1], 0.0), (w0in[i, 2], 0.0)
    q = ((q0in[i, 0], 0.0), (q0in[i, 1], 0.0), (q0in[i, 2], 0.0), (q0in[i, 3], 0.0))
    rate0 = mul(_two_sum(1.0, -k), w2)  # (1 − k) ω3, 1 − k exact as a double-double
    for n in range(out.shape[1]):
        if n > 0:
            for _ in range(stride):
                for weight in (W1, W0, W1):
                    h = (weight * dt, 0.0)
                    half = (0.5 * h[0], 0.0)
                    rate = rate0
                    if dither != 0.0:
                        rate = mul_double(rate0, 1.0 + dither * dither_number(w0[0]))
                    w0, w1 = _kick(w0, w1, q, half, body, mask & 1)
                    w0, w1, q = _flow(w0, w1, w2, q, h, rate, k, inv, mask)
                    w0, w1 = _kick(w0, w1, q, half, body, mask & 1)
        out[i, n, 0], out[i, n, 1], out[i, n, 2] = w0[0], w1[0], w2[0]
        out[i, n, 3], out[i, n, 4], out[i, n, 5] = w0[1], w1[1], w2[1]
        for j in range(4):
            out[i, n, 6 + j], out[i, n, 10 + j] = q[j][0], q[j][1]


@njit(parallel=True, error_model="numpy")
def _run_all(w0, q0, body, dt, stride, dither, inv, mask, out):
    for i in prange(w0.shape[0]):
        _one_run(i, w0, q0, body, dt, stride, dither, inv, mask, out)


def run_series(w0, q0, body, dt, stride, samples, mask=0, dither=0.0):
    """(runs, samples, 14) states (ω, ωl, q, ql) of the top every ``stride`` steps, in double-double with the
    pieces of ``mask`` (PIECES) as the double kernel; the turns' rate times 1 + dither d on every substep."""
    if body[0] != body[1] or np.any(body[4:] != 0.0):
        raise SystemExit("--double-double: a symmetric top (I1 = I2, centre of mass on e3, no drive) only")
    out = np.empty((w0.shape[0], samples, 14))
    _run_all(w0, q0, body, dt, stride, dither, INVERSE_FACTORIALS, mask, out)
    return out
