"""Compensated (error-free) accumulation of the state in the Lie–Poisson splittings (issue 22, item 4).

A plain splitting overwrites ω and q with each flow's result: every flow rounds the whole state, and
where a flow's rounding goes the same way step after step (a nearly constant turn, a product of nearly
constant unit quaternions) the invariants drift linearly at round-off level.  Here the state is a sum
``hi + lo`` of two doubles per component (``lo`` within half an ulp of ``hi``), and each flow is written
as an increment to it, added error-free (two-sum, Knuth TAOCP vol. 2 §4.2.2; the compensated sums of
IAS15, Rein & Spiegel, MNRAS 446 (2015) 1424, §2.3, and WHFast, Rein & Tamayo, MNRAS 452 (2015) 376):

- a kick adds h τ/I to ω;
- a turn of the body by a small rotation dq = 1 + (α, u) (α = cos(φ/2) − 1 = −sin²(φ/2)/(1 + cos(φ/2)),
  computed without cancellation; u = sin(φ/2) n̂) adds the Hamilton product q ⊗ (α, u) to q, so the
  rounding is that of the increment, ~φ/2 times smaller than of q ⊗ dq.  A symmetric body's flow adds
  the increment of the whole q, (q + ql) ⊗ (α, u), the product's rounding error and ql's own turn passed
  to the low part (``_turn_whole``), and turns ω⊥ by the angle of its turn about e3 as a rotation whose
  constants and products are exact to ~eps² (``_turn_matched``): on a top, whose turn constants are the same
  every step, the rounded product of q's high part drifted the energy the same way on every run (~5e-19 /s
  at dt = 5e-4 s on the 50 Hz top), and the shears' rounded products each run its own way (as much);
  benchmarks/double_double_top.py found which piece;
- a turn of L_b in a plane by −φ is three shears (x += t y; y −= s x; x += t y with t = tan(φ/2),
  s = sin φ; Paeth 1986): each shear has determinant 1 whatever its rounded coefficient, where the
  matrix (cos, sin; −sin, cos) of rounded entries scales |L⊥| by a factor that rounds the same way
  every step — the bias benchmarks/roundoff_bias.py found in lie_poisson4 (variant 3 there).  The three
  are a rotation only if s (1 + t²) = 2t, which the rounded pair misses by ~eps (and ω's shears by the
  rounding of I_y/I_x · I_x/I_y besides); where the pair is the same every step (a symmetric body's ω3
  is conserved) that miss drifts the energy linearly, ~6.6e-9 of it per step on the 50 Hz top
  (benchmarks/compensated_bias.py ``shear_pair``), so s and I_x/I_y carry low parts that close both
  conditions to ~eps²;
- q is projected back to |q| = 1 by the increment −q (|q|² − 1)/2, |q|² from hi and lo;
- the elliptic flow of an asymmetric body (kernels/euler_poinsot.py) adds ω(h) − ω, formed from the
  increments of sn, cn, dn without cancellation (``free_flow_increment``); its attitude is not an
  increment and is taken as it is.

What is left per step is the rounding of the increments themselves, ~|increment|·eps.  The flows are
those of kernels/free_flow.py (the exact symmetric free flow, or the axis splitting in a given order)
and of kernels/euler_poinsot.py, with gravity's kicks of an undriven body; ``strang_composition`` and
``kick_composition`` compose them as kernels/compose.py does (the same maps to rounding), for the
``accumulate=compensated`` variants of lie_poisson4 and split6_exact.  Those variants carry the low
parts (ωl, ql) from step to step (kernels/variants.py ``carried``).  benchmarks/brouwer.py measures
what it buys: the energy error against t over 1e8 steps, and its cost.
"""

from numba import njit, types
from numba.extending import intrinsic

from .compose import merged_kicks
from .euler_poinsot import free_flow_increment
from .free_flow import resolve_axes
from .rigid_body import gravity_torque
from .rotation import half_angle, quat_from_rotvec, quat_mul


@njit(cache=True, error_model="numpy")
def _add(hi, lo, d):
    """(hi, lo) + d, error-free: the sum s = hi + (d + lo) and its rounding error (two-sum)."""
    y = d + lo
    s = hi + y
    b = s - hi
    return s, (hi - (s - b)) + (y - b)


@njit(cache=True, error_model="numpy")
def _add3(w, wl, d0, d1, d2):
    a0, l0 = _add(w[0], wl[0], d0)
    a1, l1 = _add(w[1], wl[1], d1)
    a2, l2 = _add(w[2], wl[2], d2)
    return (a0, a1, a2), (l0, l1, l2)


@njit(cache=True, error_model="numpy")
def _add4(q, ql, d):
    a0, l0 = _add(q[0], ql[0], d[0])
    a1, l1 = _add(q[1], ql[1], d[1])
    a2, l2 = _add(q[2], ql[2], d[2])
    a3, l3 = _add(q[3], ql[3], d[3])
    return (a0, a1, a2, a3), (l0, l1, l2, l3)


@njit(cache=True, error_model="numpy")
def _minus_one(a, u0, u1, u2):
    """α = a − 1 of a unit quaternion (a, u) with a > 0, without cancellation: −|u|²/(1 + a)."""
    return -(u0 * u0 + u1 * u1 + u2 * u2) / (1.0 + a)


@njit(cache=True, error_model="numpy")
def _normalize(q, ql):
    """(q, ql) projected to |q| = 1: the increment −q (|q|² − 1)/2 (first order; |q|² − 1 ~ eps)."""
    n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0
    n2 += 2.0 * (q[0] * ql[0] + q[1] * ql[1] + q[2] * ql[2] + q[3] * ql[3])
    k = -0.5 * n2
    return _add4(q, ql, (k * q[0], k * q[1], k * q[2], k * q[3]))


@njit(cache=True, error_model="numpy")
def kick(w, wl, q, h, body):
    """(ω, ωl) after gravity's torque at q acted for h seconds (orientation frozen)."""
    t0, t1, t2 = gravity_torque(q, body)
    return _add3(w, wl, h * t0 / body[0], h * t1 / body[1], h * t2 / body[2])


@intrinsic
def _fma(typingctx, a, b, c):
    """a b + c rounded once (LLVM's llvm.fma.f64: one vfmadd on a CPU with FMA, as numba compiles for the
    host; libm's fma elsewhere).  numba has no math.fma."""
    if not all(isinstance(x, types.Float) for x in (a, b, c)):
        return None

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@njit(cache=True, error_model="numpy")
def _two_prod(a, b):
    """(p, e): p = a b rounded and its rounding error, a b = p + e exactly (the fma's single rounding of
    a b − p, which is representable; the same e as Dekker 1971's splitting, in two operations instead of
    seventeen).  Exact unless e underflows (|a b| below ~1e-292)."""
    p = a * b
    return p, _fma(a, b, -p)


@njit(cache=True, error_model="numpy")
def _reciprocal_low(k):
    """(r, rl): 1/k rounded and its low part, k (r + rl) = 1 to ~eps²."""
    r = 1.0 / k
    p, e = _two_prod(k, r)
    return r, ((1.0 - p) - e) * r  # 1 − p exact (p within an ulp of 1); r for 1/k: rl needs eps, not eps²


@njit(cache=True, error_model="numpy")
def _sin_low(t, s, c2):
    """sl with (s + sl)(1 + t²) = 2t to ~eps²: with it the shears (t, s + sl, t) are a rotation (by
    2 atan t) to ~eps², whatever the rounding of t and s.  c2 = cos²(φ/2) stands for 1/(1 + t²): it is
    that to a few eps, and sl (~eps s) needs no more."""
    t2, t2e = _two_prod(t, t)
    dh = 1.0 + t2
    b = dh - t2
    dl = ((1.0 - b) + (t2 - (dh - b))) + t2e  # 1 + t² = dh + dl (two-sum)
    p, pe = _two_prod(s, dh)
    return -(((p - 2.0 * t) + pe) + s * dl) * c2  # p − 2t exact: p is within 2x of 2t


@njit(cache=True, error_model="numpy")
def _shear_turn(x, xl, y, yl, t, s, c2, kx, ky, kyl):
    """Turn (x, y) by −φ as three shears, x += t y; y −= s x; x += t y (t = tan(φ/2), s = sin φ,
    c2 = cos²(φ/2)), with x and y the components of ω whose L = I ω turn: kx = I_y/I_x and ky + kyl = 1/kx
    (``shear_ratios``) carry L's shear to ω.  s is closed to 2t/(1 + t²) (``_sin_low``) and ky to 1/kx, so
    that the map is a rotation of L to ~eps² and what is left is the rounding of the increments, different
    on every step."""
    sl = _sin_low(t, s, c2)
    x, xl = _add(x, xl, t * kx * y)
    y, yl = _add(y, yl, -(s * ky * x) - (s * kyl + sl * ky) * x)
    x, xl = _add(x, xl, t * kx * y)
    return x, xl, y, yl


@njit(cache=True, error_model="numpy")
def _signed_sum_low(a1, b1, a2, b2, g2, a3, b3, g3, a4, b4, g4):
    """The rounding error of a1 b1 + g2 a2 b2 + g3 a3 b3 + g4 a4 b4 (g = ±1) evaluated left to right as
    rotation.quat_mul does: the four products' errors (exact, fma) and the three sums' (two-sum)."""
    p1, e1 = _two_prod(a1, b1)
    p2, e2 = _two_prod(a2, b2)
    p3, e3 = _two_prod(a3, b3)
    p4, e4 = _two_prod(a4, b4)
    s, f2 = _add(p1, 0.0, g2 * p2)
    s, f3 = _add(s, 0.0, g3 * p3)
    s, f4 = _add(s, 0.0, g4 * p4)
    return e1 + g2 * e2 + g3 * e3 + g4 * e4 + f2 + f3 + f4


@njit(cache=True, error_model="numpy")
def quat_mul_low(p, q):
    """The exact p ⊗ q minus rotation.quat_mul(p, q), to ~eps² of the product."""
    pa, pb, pc, pd = p
    qa, qb, qc, qd = q
    return (
        _signed_sum_low(pa, qa, pb, qb, -1.0, pc, qc, -1.0, pd, qd, -1.0),
        _signed_sum_low(pa, qb, pb, qa, 1.0, pc, qd, 1.0, pd, qc, -1.0),
        _signed_sum_low(pa, qc, pb, qd, -1.0, pc, qa, 1.0, pd, qb, 1.0),
        _signed_sum_low(pa, qd, pb, qc, 1.0, pc, qb, -1.0, pd, qa, 1.0),
    )


@njit(cache=True, error_model="numpy")
def _turn_whole(q, ql, p):
    """(q, ql) + (q + ql) ⊗ p: q ⊗ p rounded is the increment, its rounding error and ql's own turn ql ⊗ p go
    to the low part first, so what is left is the compensated sum's one rounding (~eps of the increment, of a
    sum whose low part is new every step).  Turning q's high part alone and rounding the product drifted the
    top's energy linearly, the same way on every run, though each error is ~eps of the increment and of
    either sign (benchmarks/compensated_bias.py ``turn_exact``; the bisection in double-double,
    benchmarks/double_double_top.py)."""
    d = quat_mul(q, p)
    e = quat_mul_low(q, p)
    r = quat_mul(ql, p)
    return _add4(q, (ql[0] + (e[0] + r[0]), ql[1] + (e[1] + r[1]), ql[2] + (e[2] + r[2]), ql[3] + (e[3] + r[3])), d)


@njit(cache=True, error_model="numpy")
def _add_pair(hi, lo, d, dl):
    """(hi, lo) + (d, dl) to ~eps² of the sum: the high parts' two-sum, its error and both low parts added to
    it.  ``_add`` rounds d + lo first, which loses ~eps of d: an increment's own rounding."""
    s, e = _add(hi, 0.0, d)
    return _add(s, 0.0, e + (lo + dl))


@njit(cache=True, error_model="numpy")
def _turn_matched(x, xl, y, yl, sh, al2):
    """A symmetric body's turn of ω⊥ = (x, y) by −B about e3, B the angle of the body's own turn about e3, the
    quaternion (1 + α2, sh e3) (α2 = −sh²/(1 + ch)), to ~eps² of ω⊥: x += (co − 1) x + si y and
    y += (co − 1) y − si x, with T = sh/(1 + α2) = tan(B/2), co − 1 = −2T²/(1 + T²) and si = 2T/(1 + T²) each
    to ~eps², the products' rounding errors (fma) and the sums' passed to the low parts.  Paeth's three shears
    with t + tl = T and s closed to it (the registered step earlier on 2026-12-07) were a rotation to ~eps²
    too, but each shear's rounded product t y, s x lost ~eps of it, and on the top, whose T is the same every
    step, those losses drifted each run's energy its own way (~5e-19 /s at dt = 5e-4 s, correlated from
    quarter to quarter of a run; benchmarks/double_double_top.py ``shears_matched`` against
    ``turn_matched``)."""
    # each quotient from a reciprocal, within an ulp or two; its residual (exact by the fma) over the
    # denominator is its low part, so that the pair is the quotient to ~eps² whatever the rounding of the first
    dh, dl = _add(1.0, 0.0, al2)  # 1 + α2 = dh + dl exactly
    rd = 1.0 / dh
    t = sh * rd
    tl = (_fma(-t, dh, sh) - t * dl) * rd  # T = t + tl
    t2, t2e = _two_prod(t, t)
    t2l = t2e + 2.0 * t * tl  # T² = t2 + t2l
    nh, nl = _add(1.0, 0.0, t2)
    nl += t2l  # 1 + T² = nh + nl
    rn = 1.0 / nh
    si = 2.0 * t * rn
    sil = (_fma(-si, nh, 2.0 * t) + 2.0 * tl - si * nl) * rn  # 2T − si (1 + T²), over 1 + T²
    ac = -2.0 * t2 * rn
    acl = -(_fma(ac, nh, 2.0 * t2) + 2.0 * t2l + ac * nl) * rn  # −(2T² + ac (1 + T²)), over 1 + T²
    p1, e1 = _two_prod(ac, x)
    p2, e2 = _two_prod(si, y)
    dx, f = _add(p1, 0.0, p2)
    dxl = f + e1 + e2 + (acl * x + sil * y) + (ac * xl + si * yl)
    p1, e1 = _two_prod(ac, y)
    p2, e2 = _two_prod(si, x)
    dy, f = _add(p1, 0.0, -p2)
    dyl = f + e1 - e2 + (acl * y - sil * x) + (ac * yl - si * xl)
    x, xl = _add_pair(x, xl, dx, dxl)
    y, yl = _add_pair(y, yl, dy, dyl)
    return x, xl, y, yl


@njit(cache=True, error_model="numpy")
def shear_ratios(body):
    """Per axis k, (kx, ky, kyl): kx = I_j/I_i and ky + kyl = 1/kx to ~eps², i, j = k + 1, k + 2 (mod 3),
    the body constants of ``_axis_turn``'s shears; computed once per step, not on each of its turns."""
    k0, k1, k2 = body[2] / body[1], body[0] / body[2], body[1] / body[0]
    r0, rl0 = _reciprocal_low(k0)
    r1, rl1 = _reciprocal_low(k1)
    r2, rl2 = _reciprocal_low(k2)
    return (k0, r0, rl0), (k1, r1, rl1), (k2, r2, rl2)


@njit(cache=True, error_model="numpy")
def _axis_turn(w, wl, q, ql, axis, h, ratios):
    """The flow of L_k²/(2 I_k) for h seconds, compensated: the body turns by φ = ω_k h about e_k, L_b by −φ.
    ``ratios`` is ``shear_ratios(body)``."""
    c, s = half_angle(w[axis] * h)
    u = (s if axis == 0 else 0.0, s if axis == 1 else 0.0, s if axis == 2 else 0.0)
    q, ql = _add4(q, ql, quat_mul(q, (_minus_one(c, 0.0, 0.0, s), u[0], u[1], u[2])))
    t, sp = s / c, 2.0 * s * c  # tan(φ/2), sin φ
    # L_b turns in the plane (e_i, e_j), i, j = axis + 1, axis + 2 (mod 3): x = L_i, y = L_j
    i, j = (axis + 1) % 3, (axis + 2) % 3
    kx, ky, kyl = ratios[axis]
    x, xl, y, yl = _shear_turn(w[i], wl[i], w[j], wl[j], t, sp, c * c, kx, ky, kyl)
    if axis == 0:
        return (w[0], x, y), (wl[0], xl, yl), q, ql
    if axis == 1:
        return (y, w[1], x), (yl, wl[1], xl), q, ql
    return (x, y, w[2]), (xl, yl, wl[2]), q, ql


@njit(cache=True, error_model="numpy")
def then_e3_turn(al1, u0, u1, u2, al2, sh):
    """(α, v) of the turn (1 + α1, u) followed by the turn (1 + α2, sh e3) about the body's e3, the product
    (1 + α1, u) ⊗ (1 + α2, sh e3) = 1 + (α, v) with α = α1 + α2 + α1 α2 − u3 sh and
    v = u + sh e3 + α1 sh e3 + α2 u + u × sh e3, formed without cancellation (α1, α2 = cos − 1 as
    ``_minus_one`` gives them).  A symmetric body's two turns in one increment (``_symmetric_flow``, and the
    copies of it in benchmarks/compensated_bias.py and benchmarks/double_double_top.py)."""
    alpha = al1 + al2 + (al1 * al2 - u2 * sh)
    v0 = u0 + (al2 * u0 + u1 * sh)
    v1 = u1 + (al2 * u1 - u0 * sh)
    v2 = sh + u2 + (al1 * sh + al2 * u2)
    return alpha, v0, v1, v2


@njit(cache=True, error_model="numpy")
def _symmetric_flow(w, wl, q, ql, h, body):
    """The exact torque-free flow of a body with I1 = I2 (kernels/free_flow.free_flow's), compensated:
    R(h) = R0 Rot(ω⊥ h + (I3/I1) ω3 h e3) Rot(c h e3), L_b turned by −c h about e3, c = (1 − I3/I1) ω3."""
    I1, I3 = body[0], body[2]
    c = (1.0 - I3 / I1) * w[2]
    a1, u0, u1, u2 = quat_from_rotvec(w[0] * h, w[1] * h, I3 / I1 * w[2] * h)
    al1 = _minus_one(a1, u0, u1, u2)
    ch, sh = half_angle(c * h)
    al2 = _minus_one(ch, 0.0, 0.0, sh)
    q, ql = _turn_whole(q, ql, then_e3_turn(al1, u0, u1, u2, al2, sh))
    q, ql = _normalize(q, ql)
    x, xl, y, yl = _turn_matched(w[0], wl[0], w[1], wl[1], sh, al2)
    return (x, y, w[2]), (xl, yl, wl[2]), q, ql


@njit(cache=True, error_model="numpy")
def free_flow(w, wl, q, ql, h, body, axes, ratios):
    """kernels/free_flow.free_flow_axes compensated: the exact flow when I1 = I2, else the axis splitting
    a(h/2) b(h/2) c(h) b(h/2) a(h/2) in the order ``axes`` (kernels/parameters.py codes, resolve_axes);
    ``ratios`` is ``shear_ratios(body)``."""
    if body[0] == body[1]:
        return _symmetric_flow(w, wl, q, ql, h, body)
    a, b, c = resolve_axes(body, axes)
    half = 0.5 * h
    w, wl, q, ql = _axis_turn(w, wl, q, ql, a, half, ratios)
    w, wl, q, ql = _axis_turn(w, wl, q, ql, b, half, ratios)
    w, wl, q, ql = _axis_turn(w, wl, q, ql, c, h, ratios)
    w, wl, q, ql = _axis_turn(w, wl, q, ql, b, half, ratios)
    w, wl, q, ql = _axis_turn(w, wl, q, ql, a, half, ratios)
    q, ql = _normalize(q, ql)
    return w, wl, q, ql


@njit(cache=True, error_model="numpy")
def exact_flow(w, wl, q, ql, h, body):
    """kernels/euler_poinsot.free_flow_exact, compensated: a body with I1 = I2 by its closed form as
    increments (_symmetric_flow); any other body's elliptic flow by euler_poinsot.free_flow_increment, whose
    change of ω (from the increments of sn, cn, dn) is added error-free.  Its attitude q(h) = q P0ᵀ Y(ψ) P
    is computed afresh from the state, not as an increment: taken as it is (rounded by ~eps a step), q's
    low part dropped.  A free body's energy and |L| depend on ω alone; a heavy asymmetric body's kicks see
    q's rounding."""
    if body[0] == body[1]:
        return _symmetric_flow(w, wl, q, ql, h, body)
    dw, q = free_flow_increment(w, q, h, body)
    w, wl = _add3(w, wl, dw[0], dw[1], dw[2])
    return w, wl, q, (0.0, 0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def strang_step(w, wl, q, ql, h, body, axes, ratios):
    """lie_poisson's step of an undriven body compensated: kick(h/2) free_flow(h) kick(h/2)."""
    w, wl = kick(w, wl, q, 0.5 * h, body)
    w, wl, q, ql = free_flow(w, wl, q, ql, h, body, axes, ratios)
    w, wl = kick(w, wl, q, 0.5 * h, body)
    return w, wl, q, ql


@njit(cache=True, error_model="numpy")
def start(w, q, body):
    """A run's carried state: the low parts (ωl, ql) of ω and q, zero at the start."""
    return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)


def strang_composition(weights, axes):
    """``step_carried(w, q, c, dt, body) -> (w, q, c)``: the composition of compensated Strang steps of
    ``weights[k] * dt`` (kernels/compose.py compose_steps' map, undriven), c = (ωl, ql)."""
    weights = tuple(float(x) for x in weights)

    @njit(error_model="numpy")
    def step_carried(w, q, c, dt, body):
        wl, ql = c
        ratios = shear_ratios(body)
        for k in range(len(weights)):
            w, wl, q, ql = strang_step(w, wl, q, ql, weights[k] * dt, body, axes, ratios)
        return w, q, (wl, ql)

    return step_carried


def kick_composition(weights):
    """``step_carried`` of the composition with merged kicks and exact free flows (kernels/compose.py
    compose_kicks' map, undriven), compensated: n exact flows ``exact_flow`` and n + 1 kicks."""
    weights = tuple(float(x) for x in weights)
    kicks = merged_kicks(weights)

    @njit(error_model="numpy")
    def step_carried(w, q, c, dt, body):
        wl, ql = c
        for k in range(len(weights)):
            w, wl = kick(w, wl, q, kicks[k] * dt, body)
            w, wl, q, ql = exact_flow(w, wl, q, ql, weights[k] * dt, body)
        w, wl = kick(w, wl, q, kicks[-1] * dt, body)
        return w, q, (wl, ql)

    return step_carried
