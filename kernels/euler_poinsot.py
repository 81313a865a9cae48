"""The exact torque-free rigid-body motion (Euler–Poinsot) in Jacobi elliptic functions.

``free_flow_exact(w, q, h, body) -> (w, q)`` is the flow of the free rigid body
over h seconds (the gravity fields of the body are ignored) for any positive principal moments in any
order, any ω and any orientation: three distinct moments on either side of
the separatrix and on it, two equal (the symmetric top, in closed form), all
equal (the sphere); ``free_flow_increment`` is the same flow with ω's change
as an increment formed without cancellation, for compensated sums.
``free_body(I, omega0, q0, t)`` evaluates it on an array
of times (and of bodies); ``flip_period(I, omega0)`` is the closed-form time
between two flips, 2K(m)/λ, ``elliptic_rate(I, omega0)`` the rate λ.

Formulation: Celledoni, Fassò, Säfström & Zanna, "The exact computation of
the free rigid body motion and its use in splitting methods", SIAM J. Sci.
Comput. 30 (2008) 2084–2112 [CFSZ], with the corrections of Principia's
``EulerSolver`` (mockingbirdnest/Principia, physics/euler_solver_body.hpp and
documentation/Celledoni.tex: the sign of λ in case (i), a separatrix case
(iii) that lets m1 and m3 have opposite signs, the sign of the arctangent in
ψ, Δ's computed without cancellation, and sign flips of the axes so that
the pole component is positive).  The body angular
momentum m = Iω, |m| = G, is in the three formulas of CFSZ
(i) 2T I2 > G²: m = (B13 dn, −B21 sn, B31 cn)(λt − ν), around e1;
(ii) 2T I2 < G²: m = (B13 cn, −B23 sn, B31 dn)(λt − ν), around e3;
(iii) on the separatrix: m = (B13 sech, G tanh, B31 sech)(λt − ν),
in the frame of the sorted moments I1 < I2 < I3 with signs chosen so that
the pole component is positive.  The attitude is R(t) = R0 P0ᵀ Y(ψ(t)) P(t):
P(t) is the shortest-arc rotation taking m(t)/G to the pole e (e1 or e3 with
a sign), well conditioned because m·e ≥ 0 throughout, Y(ψ) the rotation by
ψ about e, and ψ = G t / I_k + c_Π [Π − F](am u) + c_θ atan2(S sn, C cn)
with an elliptic integral of the third kind Π(φ, n|m), n ≤ 0.

Why CFSZ/Principia rather than van Zon & Schofield (J. Comput. Phys. 225,
2007): the same elliptic functions underlie both, but CFSZ gives the attitude
as one explicit rotation per instant with a single third-kind integral of a
parameter n ≤ 0 that depends on the inertia only, so it needs no theta-series
truncation, is real on both sides of the separatrix and has a separate
closed form on it; Principia has tested it to the ULP and published its
corrections.  Our own choices on top of it:

- the state at time t is built from the state at 0 by the addition theorems
  of sn, cn, dn (of tanh, sech on the separatrix), not by inverting the
  initial condition to an argument and evaluating there: at h = 0 the flow
  returns its input to a few roundings (no F⁻¹∘F round trip), and a step of
  a splitting method needs no absolute argument;
- Π − F = (n/3) sin³φ R_J is used instead of Π, since F(φ1) − F(φ0) = λh is
  known: no cancellation between R_F and R_J when |n| is large (near-
  symmetric bodies), and one Carlson R_F less;
- am u and the arctangent are continued across half periods by counting
  half periods J, so that ψ is continuous in t and the quaternion returned is
  continuous (no sign flips);
- P(t) m(t) = G e exactly up to rounding, so the lab angular momentum
  R m = G R0 P0ᵀ e is conserved to rounding whatever the error of ψ;
- a short step (|λh| < SHORT_STEP = 2, every step of a splitting at a sensible dt)
  needs neither K nor F nor a half-period count: by the addition theorem
  of the third-kind integral (DLMF 19.26.9, Legendre form), the increment
  of Π − F from am u0 to am(u0 + λh) is (Π − F)(am λh) minus an R_C of sn
  at u0, λh and u0 + λh, and (Π − F)(am λh) comes with sn, cn, dn(λh) from
  halving λh to ≤ 0.03 (Maclaurin series there) and doubling back, one R_C
  per doubling: no R_J of the endpoints, whose difference cancels; a longer
  step that spans more than K drops its whole half periods 2K (each adds the
  complete Π − F and π to θ) and takes the rest, at most K, the same way, and
  one of at most K (up to SHORT_PIECES times SHORT_STEP) goes in equal pieces;
  Against mpmath at 30 digits (tests/test_euler_poinsot.py
  ::test_short_step_third_kind_increment) it is within 4 eps of the
  increment; the two R_J and the 5-point Gauss–Legendre rule it replaced
  (for |λh| < 0.01) lost up to 320 and 860 eps, and it is faster than both
  (docs/benchmarks.md, "The exact free flow's short step");
- m(h) is rescaled to |m(0)| (a scaling keeps the orbit's shape, so no
  phase accuracy is lost) to remove a 0.3 eps/step drift of |L| and E that
  the per-step recomputation of the B's would otherwise leave.

Elliptic functions: kernels/elliptic.py (our own AGM/Landen sn, cn, dn and
Carlson R_F, R_J).  Conventions: q scalar first, R(q) body → lab, ω body
frame (rad/s), body = kernels/body.py's Body (only I1, I2, I3 are read).
"""

import math

import numpy as np
from numba import njit, prange

from .elliptic import (
    ellipk,
    ellipk_and_pi_minus_k,
    one_minus_cndn_series,
    rc1,
    rf,
    rj,
    rj_series,
    series_coefficients,
    sncndn,
    sncndn_series,
)
from .rotation import half_angle, quat_mul, quat_normalize, rotate_body_step

_PI = math.pi


@njit(cache=True, error_model="numpy")
def _sort3(I1, I2, I3):
    """(p0, p1, p2, parity): indices with I[p0] ≤ I[p1] ≤ I[p2]; parity +1 (even) or −1 (odd)."""
    if I1 <= I2:
        if I2 <= I3:
            return 0, 1, 2, 1.0
        if I1 <= I3:
            return 0, 2, 1, -1.0
        return 2, 0, 1, 1.0
    if I1 <= I3:
        return 1, 0, 2, -1.0
    if I2 <= I3:
        return 1, 2, 0, 1.0
    return 2, 1, 0, -1.0


@njit(cache=True, error_model="numpy")
def _sign(x):
    return -1.0 if x < 0.0 else 1.0


@njit(cache=True, error_model="numpy")
def _unsort(v0, v1, v2, p0, p1, p2):
    """Original-order tuple of a sorted-order one: out[p_k] = v_k."""
    a = v0 if p0 == 0 else (v1 if p1 == 0 else v2)
    b = v0 if p0 == 1 else (v1 if p1 == 1 else v2)
    c = v0 if p0 == 2 else (v1 if p1 == 2 else v2)
    return a, b, c


@njit(cache=True, error_model="numpy")
def _arc(m0, m1, m2, axis, sign):
    """The shortest-arc rotation taking m/|m| to sign·e_axis (m·e ≥ 0) as an unnormalised quaternion,
    (G + sign m_axis, m × sign e_axis) with G = |m|: its norm √(2G(G + sign m_axis)) ≥ √2 G, and G + sign m_axis
    ≥ G has no cancellation.  _flow's product of two of them is normalised once at the end (quat_normalize),
    which leaves the rotation they describe; the unit form, (1 + u·e, u × e)/√(2(1 + u·e)) with u = m/G,
    cost one square root and four divisions more per arc."""
    G = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if axis == 0:
        return G + sign * m0, 0.0, sign * m2, -sign * m1
    if axis == 1:
        return G + sign * m1, -sign * m2, 0.0, sign * m0
    return G + sign * m2, sign * m1, -sign * m0, 0.0


@njit(cache=True, error_model="numpy")
def _symmetric(w, q, h, axis, I_perp, I_axis):
    """Closed form for I_b = I_c = I_perp (b, c the other two axes, right-handed after axis); as
    free_flow.free_flow: R(h) = R0 Rot(m h / I_perp) Rot(e_axis c h), c = (1/I_axis − 1/I_perp) m_axis,
    while m turns by −c h about e_axis."""
    ratio = I_axis / I_perp
    c = (1.0 - ratio) * w[axis]
    if axis == 2:
        q = rotate_body_step(q, w[0] * h, w[1] * h, ratio * w[2] * h)
    elif axis == 0:
        q = rotate_body_step(q, ratio * w[0] * h, w[1] * h, w[2] * h)
    else:
        q = rotate_body_step(q, w[0] * h, ratio * w[1] * h, w[2] * h)
    ch, sh = half_angle(c * h)
    cp = 1.0 - 2.0 * sh * sh
    sp = 2.0 * sh * ch
    if axis == 2:
        q = quat_mul(q, (ch, 0.0, 0.0, sh))
        w = (cp * w[0] + sp * w[1], -sp * w[0] + cp * w[1], w[2])
    elif axis == 0:
        q = quat_mul(q, (ch, sh, 0.0, 0.0))
        w = (w[0], cp * w[1] + sp * w[2], -sp * w[1] + cp * w[2])
    else:
        q = quat_mul(q, (ch, 0.0, sh, 0.0))
        w = (cp * w[0] - sp * w[2], w[1], sp * w[0] + cp * w[2])
    return w, quat_normalize(q)


@njit(cache=True, error_model="numpy")
def _addition_denominator(s0, c0, s2, d2, m):
    """(x, D) = (m s0² s2², 1 − x): the addition theorems' denominator at u + v from sn, cn at u and sn, dn
    at v; for x ≥ 0.5 D = c0² + s0² d2², the same without cancellation."""
    x = m * s0 * s0 * s2 * s2
    if x < 0.5:
        return x, 1.0 - x
    return x, c0 * c0 + s0 * s0 * d2 * d2


@njit(cache=True, error_model="numpy")
def _add_sncndn(s0, c0, d0, s2, c2, d2, m):
    """(sn, cn, dn)(u + v) from the values at u and at v (addition theorems)."""
    den = _addition_denominator(s0, c0, s2, d2, m)[1]
    return (
        (s0 * c2 * d2 + s2 * c0 * d0) / den,
        (c0 * c2 - s0 * s2 * d0 * d2) / den,
        (d0 * d2 - m * s0 * s2 * c0 * c2) / den,
    )


@njit(cache=True, error_model="numpy")
def _add_sncndn_increment(s0, c0, d0, s2, c2, d2, e2, f2, mc):
    """(sn, cn, dn)(u + v) − (sn, cn, dn)(u) from the values at u, those at v and e2 = 1 − cn v, f2 = 1 − dn v,
    without the cancellation of the difference of _add_sncndn's results.  With x = m s0² s2² and the
    denominator D = 1 − x:
    sn(u + v) − s0 = (s0 T + s2 c0 d0)/D with T = m s0² s2² − 1 + c2 d2 = −d2 (d2 − c2) − m c0² s2²,
    d2 − c2 = mc s2²/(d2 + c2) (both terms of T ≤ 0: T's parts, ~v² each, cancel to ~mc v² near the
    separatrix where sn is near ±1, and the direct form lost 1e-13 there);
    cn(u + v) − c0 = (c0 (x − e2) − s0 s2 d0 d2)/D and dn(u + v) − d0 = (d0 (x − f2) − m s0 s2 c0 c2)/D.
    Each increment is within a few eps of the largest of the three (tests/test_euler_poinsot.py
    ::test_short_step_third_kind_increment), not of sn, cn, dn."""
    m = 1.0 - mc
    ss2 = s2 * s2
    x, den = _addition_denominator(s0, c0, s2, d2, m)
    gap = mc * ss2 / (d2 + c2) if c2 >= 0.0 else d2 - c2  # dn − cn ≥ 0; d2 + c2 ≥ d2 > 0 there
    t = -d2 * gap - m * c0 * c0 * ss2
    r = 1.0 / den
    return (
        (s0 * t + s2 * c0 * d0) * r,
        (c0 * (x - e2) - s0 * s2 * d0 * d2) * r,
        (d0 * (x - f2) - m * s0 * s2 * c0 * c2) * r,
    )


@njit(cache=True, error_model="numpy")
def _reduced(s, c, S, C):
    """(sin φr, cos² φr, φr, θr) with am = Jπ + φr, |φr| ≤ π/2, and θr = atan2(S sin φr, C cos φr)."""
    sr = s if c >= 0.0 else -s
    ac = abs(c)
    return sr, c * c, math.atan2(sr, ac), math.atan2(S * sr, C * ac)


@njit(cache=True, error_model="numpy")
def _addition_defect(su, sv, suv, a, m):
    """G(u) + G(v) − G(u + v) for G(u) = (Π − F)(am u, n|m), n = −a ≤ 0, from su, sv, suv = sn at u, v, u + v.

    The addition theorem of the third-kind integral (DLMF 19.26.9 in Legendre form): with S = su sv suv,
    P = Π_k (1 + a sn_k²) and δ = a(1 + a)(a + m), the defect is a S R_C(P − δS², P).  P − δS² =
    1 + a(Σ sn² − m S²) + a²(Σ sn_i² sn_j² − (1 + m) S²) ≥ 1 is formed without the cancellation of its a³
    terms (near-symmetric bodies have a ≫ 1).  With x = P − δS² and δ > 0 (a > 0, m ≥ 0), R_C(x, x + δS²) =
    atan(z)/(√δ |S|), z = √δ |S|/√x, so the defect is (a/√δ) atan(√δ S/√x) (z² = δS²/x below 1e-3: a S/√x
    times rc1's series of atan(z)/z).  What depends on the sn's is one square root, one division and the
    atan; R_C(1, 1 + δS²/x)/√x in rc1's form took two square roots and three divisions in a row
    (docs/benchmarks.md, "The exact free flow's short step")."""
    s2u = su * su
    s2v = sv * sv
    s2uv = suv * suv
    S = su * sv * suv
    SS = S * S
    x = 1.0 + a * (s2u + s2v + s2uv - m * SS) + a * a * (s2u * s2v + s2u * s2uv + s2v * s2uv - (1.0 + m) * SS)
    r = 1.0 / math.sqrt(x)
    delta = a * (1.0 + a) * (a + m)
    z2 = delta * SS * (r * r)
    if z2 < 1.0e-3:  # atan(z)/z = 1 − z²/3 + z⁴/5 − ...: to z¹² the error is < 1e-21
        return a * S * r * rc1(z2)
    k = math.sqrt(delta)
    return (a / k) * math.atan(k * S * r)


@njit(cache=True, error_model="numpy")
def _rj_close(x, y, z, p):
    """Carlson's R_J(x, y, z, p) for arguments close together (the short step's base): the series about
    their mean A, A^(-3/2) times elliptic.rj_series (the same series rj ends with), without elliptic.rj's
    set-up of a duplication loop that would not run, and with one division; elliptic.rj when they are
    farther apart than its bound for no duplication (900 max|A − arg| < A)."""
    A = (x + y + z + p + p) * 0.2
    if 900.0 * max(abs(A - x), abs(A - y), abs(A - z), abs(A - p)) >= A:
        return rj(x, y, z, p)
    inv = 1.0 / A
    return rj_series((A - x) * inv, (A - y) * inv, (A - z) * inv) * inv * math.sqrt(inv)


# |w| at or below which the short step takes sn, cn, dn from their Maclaurin series and G from one R_J
# of close arguments: sncndn_series is within 0.7 eps (sn, relative) and 0.3 eps (cn, dn) of mpmath for
# |w| ≤ 0.03, every m in [0, 1] (the first dropped terms are < 0.05 eps there).
SERIES_BASE = 0.03

# |λh| below which a step takes the short branch (no K, no F, no R_J of the endpoints).  Its three parts
# hold beyond it; the bound is the doublings' conditioning.  The defect's R_C has x = P − δS² ≥ 1 for every
# real u0, λh (_addition_defect), so its atan form holds everywhere; |λh| < 2 < π ≤ 2K keeps the change of
# am, hence of θ, below π, where the atan2 of θ's increment is unambiguous; a doubling's input (|w| < 1)
# has sn ≤ 0.85, so D = 1 − m sn⁴ ≥ 0.66 and cn, dn ≥ 0.54.  Measured against mpmath (300 random m, n, u0
# each): sn, cn, dn at u0 + λh within 1.4e-15 for 1 ≤ |λh| < 2 by this branch, 1.5e-15 by the long one
# (Bulirsch's sncndn); for 2 ≤ |λh| < π this branch lost up to 2.5e-14 against the long one's 2.8e-15.
# Raised from 1 (2026-12-05): a step past the bound (K, one R_F, two or three R_J, four atan2) costs
# ~2.1x a short one of 1 ≤ |λh| < 2 (benchmarks/bench_free_body.py, table 1c).
SHORT_STEP = 2.0

# A step of SHORT_STEP ≤ |λh| < SHORT_STEP·SHORT_PIECES that spans at most K (else whole half periods go first:
# _elliptic_case) goes in k ≤ SHORT_PIECES equal pieces of the short
# branch (one _short_step, then the addition theorems once per piece) instead of the long branch: 0.45-0.49x
# its cost for 2 ≤ |λh| < 6 and 0.55-0.58x at 7.5 (table 1c of benchmarks/bench_free_body.py, 2026-12-06 after
# the on-the-curve rescaling went additive; each piece past the first ~30-50 ns on the AMD EPYC VM, the long
# branch ~830-910 ns there), and more accurate (tests/test_euler_poinsot.py::test_a_long_step_in_short_pieces).
# Eight pieces (|λh| < 16) were tried and not kept: sn, cn, dn lost up to 6.2e-14 and θ's increment 8.3e-14
# against mpmath (the long branch: 3.4e-14-7.6e-14 and 6e-15).
SHORT_PIECES = 4


@njit(cache=True, error_model="numpy")
def _short_step(v, mc, n):
    """(sn, cn, dn)(v), G(v) = (Π − F)(am v, n|m), 1 − cn(v) and 1 − dn(v) for |v| < SHORT_STEP, by halving v
    to |w| ≤ SERIES_BASE and doubling back.

    At w: sn, cn, dn from their Maclaurin series (exact to rounding) and G(w) from one R_J whose arguments
    differ by a w² at most (``_rj_close``: its series alone, unless a ≳ 1 calls for a duplication or two).
    Each doubling: sn(2w) = 2 s c d/D, 1 − cn(2w) = 2 s² d²/D, 1 − dn(2w) = 2 m s² c²/D with D = 1 − m s⁴
    (1 − cn and 1 − dn carried instead of cn and dn, which near 1 keep few of w's digits), and
    G(2w) = 2 G(w) − defect(w, w).  The half-
    and double-argument transformations T. Fukushima uses for incomplete elliptic integrals, applied to the
    step: ~1.5x faster than Bulirsch's sncndn and an R_J of v (docs/benchmarks.md), to a few eps
    (tests/test_euler_poinsot.py::test_short_step_third_kind_increment).  |v| < SHORT_STEP keeps every
    doubling well conditioned (its input has sn ≤ sn(1) < 0.85: D ≥ 0.66, cn and dn ≥ 0.54); run up to K it
    lost 1e-9 in sn near the separatrix, where D = 1 − m s⁴ cancels as sn → 1."""
    m = 1.0 - mc
    a = -n
    w = abs(v)
    k = 0
    while w > SERIES_BASE:
        w *= 0.5  # exact
        k += 1
    coefficients = series_coefficients(m)
    s, c, d = sncndn_series(w, coefficients)
    ss = s * s
    g = -(a / 3.0) * ss * s * _rj_close(c * c, c * c + mc * ss, 1.0, 1.0 + a * ss)
    e = 1.0 - c
    f = 1.0 - d
    # the 1 − cn, 1 − dn returned for free_flow_increment: without a doubling, from their own series (1 − c keeps
    # c's rounding); a doubling forms them afresh from s, c, d without cancellation.  e and f stay 1 − c and
    # 1 − d, so that the doublings and free_flow_exact keep their bits.
    e_out, f_out = one_minus_cndn_series(w, coefficients)
    for _ in range(k):
        r = 1.0 / (1.0 - m * ss * ss)
        c = 1.0 - e
        d = 1.0 - f
        s2 = 2.0 * s * c * d * r
        e = 2.0 * ss * d * d * r
        f = 2.0 * m * ss * c * c * r
        g = 2.0 * g - _addition_defect(s, s, s2, a, m)
        s = s2
        ss = s * s
        e_out = e
        f_out = f
    if v < 0.0:  # sn and G are odd, cn and dn even
        return -s, 1.0 - e, 1.0 - f, -g, e_out, f_out
    return s, 1.0 - e, 1.0 - f, g, e_out, f_out


@njit(cache=True, error_model="numpy")
def _on_the_curve(s, c, mc):
    """(sn, cn, dn) from the addition theorems' sn, cn rescaled to sn² + cn² = 1 and dn from dn² + m sn² = 1,
    to rounding (energy and |L| to a few ULP).

    The addition theorems leave s² + c² = 1 + δ with |δ| a few eps (their denominator is formed without
    cancellation), so 1/√(1 + δ) = 1 − δ/2 + O(δ²) to rounding: one Newton step of the inverse square root
    from 1, instead of a square root and a division on the chain of dependent operations that carries ω from
    one step to the next, whose latency sets the step's cost (docs/benchmarks.md, "2026-12-06: the exact
    flow's chain")."""
    e = 0.5 * (1.0 - (s * s + c * c))  # −δ/2; 1 − (s² + c²) is exact (Sterbenz)
    s += s * e  # s (1 − δ/2) as s + s·e, not as a factor 1 − δ/2 rounded to the uneven grid around 1
    c += c * e
    return s, c, math.sqrt(c * c + mc * s * s)


@njit(cache=True, error_model="numpy", inline="always")
def _short_piece(s0, c0, d0, s2, c2, d2, g_v, e2, f2, m, mc, n, S, C):
    """One piece of the short branch: (sn, cn, dn) at u0 + v from those at u0 and at v (e2, f2 = 1 − cn v,
    1 − dn v), G(u0 + v) − G(u0) = G(v) − defect(u0, v) with g_v = G(v), θ(am(u0 + v)) − θ(am u0) (|v| < 2
    keeps the change of am below π, where the atan2 is unambiguous) and the increments of sn, cn, dn."""
    s1, c1, d1 = _add_sncndn(s0, c0, d0, s2, c2, d2, m)
    ds, dc, dd = _add_sncndn_increment(s0, c0, d0, s2, c2, d2, e2, f2, mc)
    if s2 != 0.0:
        s1, c1, d1 = _on_the_curve(s1, c1, mc)
    d_theta = math.atan2(C * S * (c0 * s1 - s0 * c1), C * C * c0 * c1 + S * S * s0 * s1)
    return s1, c1, d1, g_v - _addition_defect(s0, s2, s1, -n, m), d_theta, ds, dc, dd


@njit(cache=True, error_model="numpy")
def _short_pieces(s0, c0, d0, v, m, mc, n, S, C, cpi):
    """_elliptic_case's results for SHORT_STEP ≤ |v| < SHORT_STEP·SHORT_PIECES: k = ⌊|v|/SHORT_STEP⌋ + 1 equal
    pieces v/k of the short branch, sn, cn, dn and G = Π − F of v/k once (_short_step), then k times the
    addition theorems from the state reached, G's increment and θ's atan2 each time (G decreases
    monotonically for n < 0, so the pieces' increments of G add without cancellation).  0.45-0.58x the cost
    of _long_step up to |v| = 8 (benchmarks/bench_free_body.py, table 1c)."""
    k = int(abs(v) / SHORT_STEP) + 1
    s2, c2, d2, g_v, e2, f2 = _short_step(v / k, mc, n)
    s1, c1, d1, g, d_theta, ds, dc, dd = _short_piece(s0, c0, d0, s2, c2, d2, g_v, e2, f2, m, mc, n, S, C)
    for _ in range(k - 1):
        s1, c1, d1, gi, thi, dsi, dci, ddi = _short_piece(s1, c1, d1, s2, c2, d2, g_v, e2, f2, m, mc, n, S, C)
        g += gi
        d_theta += thi
        ds += dsi
        dc += dci
        dd += ddi
    return s1, c1, d1, cpi * g, d_theta, ds, dc, dd


@njit(cache=True, error_model="numpy")
def _long_step(s0, c0, d0, lam, h, mc, n, S, C, cpi, K, pi_minus_k):
    """_elliptic_case's results for |λh| ≥ SHORT_STEP·SHORT_PIECES when a half period 2K is longer than the pieces
    reach (K ≥ HALF_PERIODS_BELOW, m within ~2e-6 of the separatrix), given K and the complete Π − K: sn, cn,
    dn of λh (Bulirsch), the addition theorems, and Π − F and θ at both endpoints (R_F, two R_J, four atan2)
    continued over the half periods counted from the endpoints' arguments.  The difference of the endpoints'
    R_J cancels: measured against mpmath for 2 ≤ |λh| < 8, its increment of Π − F lost up to 2.5e4 eps where
    the pieces lost 9 eps."""
    m = 1.0 - mc
    v = lam * h
    s2, c2, d2 = sncndn(v, mc)
    s1, c1, d1 = _add_sncndn(s0, c0, d0, s2, c2, d2, m)
    ds, dc, dd = _add_sncndn_increment(s0, c0, d0, s2, c2, d2, 1.0 - c2, 1.0 - d2, mc)
    if s2 != 0.0:
        s1, c1, d1 = _on_the_curve(s1, c1, mc)
    sr0, cc0, phr0, thr0 = _reduced(s0, c0, S, C)
    sr1, cc1, phr1, thr1 = _reduced(s1, c1, S, C)
    # half periods: J0 from the quadrant, J1 from u1 = u0 + λh (|am u − πu/2K| < π/2)
    j0 = 0.0
    if c0 < 0.0:
        j0 = 1.0 if s0 >= 0.0 else -1.0
    u0 = 2.0 * j0 * K + sr0 * rf(cc0, cc0 + mc * sr0 * sr0, 1.0)
    u1 = u0 + lam * h
    j1 = math.floor(u1 / (2.0 * K) - phr1 / _PI + 0.5)
    dj = j1 - j0
    pf1 = sr1 * sr1 * sr1 * rj(cc1, cc1 + mc * sr1 * sr1, 1.0, 1.0 - n * sr1 * sr1)
    pf0 = sr0 * sr0 * sr0 * rj(cc0, cc0 + mc * sr0 * sr0, 1.0, 1.0 - n * sr0 * sr0)
    d_pf = (n / 3.0) * (pf1 - pf0)
    d_theta = thr1 - thr0
    if dj != 0.0:
        d_pf += 2.0 * dj * pi_minus_k
        d_theta += dj * _PI
    return s1, c1, d1, cpi * d_pf, d_theta, ds, dc, dd


# A step of |λh| ≥ SHORT_STEP that spans more than K drops its whole half periods 2K when K is below this: what
# remains, |r| ≤ K, goes by the short branch or its pieces, and the half periods add their complete Π − F and π
# each.  Above it (mc ≲ 2e-6, the separatrix's neighbourhood, where K = ln(4/√mc) + ... grows without bound)
# the remainder could exceed the pieces' reach: the step goes in pieces below SHORT_STEP·SHORT_PIECES and by
# _long_step above.
HALF_PERIODS_BELOW = SHORT_STEP * SHORT_PIECES


@njit(cache=True, error_model="numpy")
def _elliptic_case(s0, c0, d0, lam, h, mc, n, S, C, cpi):
    """(sn, cn, dn) at u1 = u0 + λh, the non-linear part of ψ,
    cpi·[(Π − F)(am u1) − (Π − F)(am u0)] + (θ(am u1) − θ(am u0)) (θ continuous), and the increments
    (sn, cn, dn)(u1) − (s0, c0, d0) without cancellation (_add_sncndn_increment; past a whole number of
    half periods the plain differences, see below).

    Branches by |λh|: the short one below SHORT_STEP.  Past it, a step longer than K (and K <
    HALF_PERIODS_BELOW) is λh = 2K·N + r with |r| ≤ K, N ≠ 0: sn and cn change sign over each half period 2K
    and dn does not, Π − F grows by its complete value 2(Π − K)(n|m) and θ by π, so the step is r by the
    short branch or its pieces, then N half periods added (K and Π − K from one AGM,
    elliptic.ellipk_and_pi_minus_k).  Any other step goes in equal pieces of the short branch below
    SHORT_STEP·SHORT_PIECES (_short_pieces) and by _long_step above (only where K ≥ HALF_PERIODS_BELOW).
    Against mpmath for 8 ≤ |λh| ≤ 500 (tests/test_euler_poinsot.py::test_a_long_step_in_whole_half_periods)
    the increment of Π − F is within 2.4 eps (_long_step's 4.1 eps on the same draws); sn, cn and dn at u1
    carry the rounding of r = λh − 2K·N, ~eps·|λh|, as Bulirsch's sncndn of λh in _long_step does."""
    m = 1.0 - mc
    v = lam * h
    if abs(v) < SHORT_STEP:
        # Short step (|v| < 2 < 2K: no half-period count, no K, no F): G(u1) − G(u0) = G(v) − defect(u0, v).
        s2, c2, d2, g_v, e2, f2 = _short_step(v, mc, n)
        s1, c1, d1, g, d_theta, ds, dc, dd = _short_piece(s0, c0, d0, s2, c2, d2, g_v, e2, f2, m, mc, n, S, C)
        return s1, c1, d1, cpi * g, d_theta, ds, dc, dd
    K, pi_minus_k = ellipk_and_pi_minus_k(mc, n)
    if abs(v) <= K or K >= HALF_PERIODS_BELOW:
        if abs(v) < SHORT_STEP * SHORT_PIECES:
            return _short_pieces(s0, c0, d0, v, m, mc, n, S, C, cpi)
        return _long_step(s0, c0, d0, lam, h, mc, n, S, C, cpi, K, pi_minus_k)
    half_periods = math.floor(v / (2.0 * K) + 0.5)
    r = v - 2.0 * K * half_periods  # |r| ≤ K (to rounding) < HALF_PERIODS_BELOW = SHORT_STEP·SHORT_PIECES
    if abs(r) < SHORT_STEP:
        s2, c2, d2, g_v, e2, f2 = _short_step(r, mc, n)
        s1, c1, d1, g, d_theta, ds, dc, dd = _short_piece(s0, c0, d0, s2, c2, d2, g_v, e2, f2, m, mc, n, S, C)
        g *= cpi
    else:
        s1, c1, d1, g, d_theta, ds, dc, dd = _short_pieces(s0, c0, d0, r, m, mc, n, S, C, cpi)
    g += cpi * (2.0 * half_periods) * pi_minus_k
    d_theta += half_periods * _PI
    if half_periods % 2.0 != 0.0:
        # an odd count turns sn and cn over: the increments from u0 are then the plain differences (the state
        # has come half a period or more away, so there is no small difference to keep)
        s1 = -s1
        c1 = -c1
        ds = s1 - s0
        dc = c1 - c0
    return s1, c1, d1, g, d_theta, ds, dc, dd


@njit(cache=True, error_model="numpy")
def _separatrix(t0, s0, v):
    """(tanh, sech)(a + v) from (tanh a, sech a), without cancellation in 1 + tanh a tanh v."""
    if s0 == 0.0 or v == 0.0:
        return t0, s0
    tv = math.tanh(v)
    sv = 1.0 / math.cosh(v)
    if t0 * tv >= 0.0:
        den = 1.0 + t0 * tv
    else:
        a0 = abs(t0)
        av = abs(tv)
        den = s0 * s0 / (1.0 + a0) + a0 * (sv * sv / (1.0 + av))
    t1 = (t0 + tv) / den
    s1 = s0 * sv / den
    r = 1.0 / math.sqrt(t1 * t1 + s1 * s1)  # tanh² + sech² = 1 to rounding
    return t1 * r, s1 * r


@njit(cache=True, error_model="numpy")
def _sorted_flow(x, y, z, J1, J2, J3, par, h, D1, D3):
    """Flow of the body momentum in the sorted frame J1 < J2 < J3 (par = parity of the sort); D1 = G² − 2T J1
    and D3 = 2T J3 − G² (both > 0) as _flow formed them for its test of a steady rotation.

    Returns (x0, y0, z0, x1, y1, z1, psi, pole, pole_sign, sx, sy, sz, dx, dy, dz): the sign-adjusted
    momentum at 0 (rebuilt from the elliptic parametrisation) and at h, ψ(h) − ψ(0), the sorted pole index
    (0 or 2), the signs σ with m'_k = σ_k m_k (det = +1) and the increment m'(h) − m'(0) (before
    free_flow_exact's rescaling; from the increments of sn, cn, dn, without the cancellation of the
    difference; on the separatrix the plain difference)."""
    J32 = J3 - J2
    J31 = J3 - J1
    J21 = J2 - J1
    G2 = x * x + y * y + z * z
    G = math.sqrt(G2)
    D3 = -D3  # G² − 2T J3 < 0
    D2 = z * z * J32 / J3 - x * x * J21 / J1  # G² − 2T J2
    B13 = math.sqrt(J1 * -D3 / J31)
    B31 = math.sqrt(J3 * D1 / J31)
    if D2 < 0.0:
        # (i): around e1
        sx = _sign(x)
        sy = 1.0
        sz = par * sx
        x *= sx
        z *= sz
        B21 = math.sqrt(J2 * D1 / J21)
        mc = min(D2 * J31 / (D3 * J21), 1.0)
        lam = -math.sqrt(-D3 * J21 / (J1 * J2 * J3))
        s0 = -y / B21
        c0 = z / B31
        d0 = x / B13
        n = -J1 * J32 / (J3 * J21)
        cpi = -G * J31 / (lam * J1 * J3)
        s1, c1, d1, p_pi, d_th, ds, dc, dd = _elliptic_case(
            s0, c0, d0, lam, h, mc, n, math.sqrt(J2 * J31), math.sqrt(J3 * J21), cpi
        )
        psi = G / J3 * h + p_pi - d_th
        d_m = (B13 * dd, -B21 * ds, B31 * dc)
        return (B13 * d0, -B21 * s0, B31 * c0, B13 * d1, -B21 * s1, B31 * c1, psi, 0, 1.0, sx, sy, sz) + d_m
    if D2 > 0.0:
        # (ii): around e3
        sz = _sign(z)
        sy = 1.0
        sx = par * sz
        x *= sx
        z *= sz
        B23 = math.sqrt(J2 * -D3 / J32)
        mc = min(D2 * J31 / (D1 * J32), 1.0)
        lam = -math.sqrt(D1 * J32 / (J1 * J2 * J3))
        s0 = -y / B23
        c0 = x / B13
        d0 = z / B31
        n = -J3 * J21 / (J1 * J32)
        cpi = G * J31 / (lam * J1 * J3)
        s1, c1, d1, p_pi, d_th, ds, dc, dd = _elliptic_case(
            s0, c0, d0, lam, h, mc, n, math.sqrt(J2 * J31), math.sqrt(J1 * J32), cpi
        )
        psi = G / J1 * h + p_pi + d_th
        d_m = (B13 * dc, -B23 * ds, B31 * dd)
        return (B13 * c0, -B23 * s0, B31 * d0, B13 * c1, -B23 * s1, B31 * d1, psi, 2, 1.0, sx, sy, sz) + d_m
    # (iii): on the separatrix, m = (B13 sech, G tanh, B31 sech)(λ2 t − ν)
    sx = _sign(x)
    sz = _sign(z)
    sy = par * sx * sz
    x *= sx
    y *= sy
    z *= sz
    lam2 = math.sqrt(-D1 * D3 / (J1 * J3)) / G
    t0 = y / G
    s0 = x / B13 if B13 >= B31 else z / B31
    t1, s1 = _separatrix(t0, s0, lam2 * h)
    tau0 = t0 / (1.0 + s0)  # tanh(a/2)
    tau1 = t1 / (1.0 + s1)
    if B13 < B31:
        psi = G / J2 * h - 2.0 * (math.atan2((B13 - G) * tau1, B31) - math.atan2((B13 - G) * tau0, B31))
        pole = 0
    else:
        psi = G / J2 * h + 2.0 * (math.atan2((B31 - G) * tau1, B13) - math.atan2((B31 - G) * tau0, B13))
        pole = 2
    d_m = (B13 * (s1 - s0), G * (t1 - t0), B31 * (s1 - s0))
    return (B13 * s0, G * t0, B31 * s0, B13 * s1, G * t1, B31 * s1, psi, pole, 1.0, sx, sy, sz) + d_m


@njit(cache=True, error_model="numpy")
def _project(x, y, z, x0, y0, z0, inv_G2):
    """m = (x, y, z) scaled to |m| = |m0|; inv_G2 = 1/|m0|².

    The B's of the elliptic parametrisation are recomputed from the state at every step with the same
    few-ULP rounding, which scales m(h) (|L| and E together) by nearly the same factor 1 + O(eps) at every
    step of a splitting: without this, a drift of 0.3 eps/step in |L| and E (6e-11 over 1e6 steps on the
    box; with it 6e-14 for |L|, 3e-13 for E).  A scaling leaves the shape of the orbit (the distance
    (G² − 2T I2)/G² to the separatrix) unchanged, so it costs no phase accuracy; correcting E separately
    would (measured: 20x worse forward-back errors near the separatrix).
    """
    # x (1 + d) as x + d x: a factor g = 1 + d rounded to a double would round d (~ eps) to the uneven
    # grid of doubles around 1 and bias the scaling (measured: no better than not scaling at all).
    # |m0|² − |m|² as Σ (m0 − m)(m0 + m): its rounding error is eps times the (small) difference, not
    # eps |m|², which would be nearly the same at every step and drift coherently.
    # |m0|² for |m|² in the divisor: they differ by O(eps) and d is O(eps), so d changes by O(eps²); 1/|m0|²
    # is formed at the start of the step, off the chain from m(h) to the next step.
    d = 0.5 * ((x0 - x) * (x0 + x) + (y0 - y) * (y0 + y) + (z0 - z) * (z0 + z)) * inv_G2
    return x + d * x, y + d * y, z + d * z


# forceinline (free_flow_exact, free_flow_increment): a caller compiled with these thin wrappers inlined gets
# _flow's faster code, ~20 % a step, as the methods' forceinline step_driven always did; a plain njit caller
# compiled in the same process as _flow got the slower (docs/benchmarks.md, "2026-12-06: the exact flow's
# chain").  Same bits.
@njit(cache=True, error_model="numpy", forceinline=True)
def free_flow_exact(w, q, h, body):
    """(ω, q) after the torque-free motion for h seconds (any h, any sign); only I1, I2, I3 of the body are read."""
    w1, q1, _ = _flow(w, q, h, body)
    return w1, q1


@njit(cache=True, error_model="numpy", forceinline=True)
def free_flow_increment(w, q, h, body):
    """(ω(h) − ω, q(h)): free_flow_exact's flow with ω's change as an increment (rad/s, body frame) for a
    compensated sum (kernels/compensated.py).  For three distinct moments the increment comes from those
    of sn, cn, dn (_add_sncndn_increment, within ~2 eps of the largest of them), times the B's: adding it
    to ω rounds ω by ~eps |ω(h) − ω|, where free_flow_exact's ω(h), rebuilt from the elliptic functions,
    is rounded by ~eps |ω| at every step (and rescaled to |L(0)| against the drift that leaves; an
    increment needs no rescaling).  On the separatrix, and for a symmetric body (kernels/compensated.py
    has that flow as increments of its own), the increment is the plain difference."""
    w1, q1, dw = _flow(w, q, h, body)
    return dw, q1


@njit(cache=True, error_model="numpy")
def _flow(w, q, h, body):
    """(ω(h), q(h), ω(h) − ω): free_flow_exact and free_flow_increment, written once."""
    I1, I2, I3 = body[0], body[1], body[2]
    p0, p1, p2, par = _sort3(I1, I2, I3)
    I = (I1 + 0.0, I2 + 0.0, I3 + 0.0)
    J1 = I[p0]
    J2 = I[p1]
    J3 = I[p2]
    still = (0.0, 0.0, 0.0)
    if J1 == J3:
        # sphere: ω constant, R(h) = R0 Rot(ω h)
        return (w[0], w[1], w[2]), quat_normalize(rotate_body_step(q, w[0] * h, w[1] * h, w[2] * h)), still
    if J1 == J2 or J2 == J3:
        if J1 == J2:
            w1, q1 = _symmetric(w, q, h, p2, J1, J3)
        else:
            w1, q1 = _symmetric(w, q, h, p0, J2, J1)
        return w1, q1, (w1[0] - w[0], w1[1] - w[1], w1[2] - w[2])
    m = (I1 * w[0], I2 * w[1], I3 * w[2])
    x = m[p0]
    y = m[p1]
    z = m[p2]
    big = max(abs(x), abs(y), abs(z))
    if big == 0.0:
        return (w[0], w[1], w[2]), q, still
    scale = 1.0
    if big < 1e-60 or big > 1e60:
        # the flow of m/s over s h is the flow of m over h, scaled by 1/s; s a power of 2 (exact).  The bound
        # keeps the product of the two unnormalised arcs (_arc, norm ~ G² each) and its squared norm ~ G⁴ in
        # quat_normalize far from overflow and underflow.
        scale = math.ldexp(1.0, math.frexp(big)[1])
        x /= scale
        y /= scale
        z /= scale
    D1 = y * y * (J2 - J1) / J2 + z * z * (J3 - J1) / J3
    D3 = x * x * (J3 - J1) / J1 + y * y * (J3 - J2) / J2
    if D1 == 0.0 or D3 == 0.0:
        # steady rotation about the smallest or the largest axis: ω constant
        return (w[0], w[1], w[2]), quat_normalize(rotate_body_step(q, w[0] * h, w[1] * h, w[2] * h)), still
    flow = _sorted_flow(x, y, z, J1, J2, J3, par, h * scale, D1, D3)
    xa, ya, za, xb, yb, zb, psi, pole, _, sx, sy, sz, dx, dy, dz = flow
    dm = _unsort(sx * dx, sy * dy, sz * dz, p0, p1, p2)
    if h != 0.0:
        xb, yb, zb = _project(xb, yb, zb, x, y, z, 1.0 / (x * x + y * y + z * z))
    # back to the original axes: m[p_k] = σ_k m'_k (still divided by scale)
    ma = _unsort(sx * xa, sy * ya, sz * za, p0, p1, p2)
    mb = _unsort(sx * xb, sy * yb, sz * zb, p0, p1, p2)
    if pole == 0:
        axis = p0
        sign = sx
    else:
        axis = p2
        sign = sz
    pa = _arc(ma[0], ma[1], ma[2], axis, sign)
    pb = _arc(mb[0], mb[1], mb[2], axis, sign)
    cy, sy_ = half_angle(psi)
    sy_ *= sign
    if axis == 0:
        y_rot = (cy, sy_, 0.0, 0.0)
    elif axis == 1:
        y_rot = (cy, 0.0, sy_, 0.0)
    else:
        y_rot = (cy, 0.0, 0.0, sy_)
    pa_conj = (pa[0], -pa[1], -pa[2], -pa[3])
    q1 = quat_mul(quat_mul(q, pa_conj), quat_mul(y_rot, pb))
    # ω = m/I by division, not by a reciprocal 1/I: its rounding would scale ω by the same factor at every
    # step, a coherent drift of |L| and E (measured: 1.5e-11 in 2e5 steps, test_splitting_invariants_do_not_drift)
    w1 = (scale * mb[0] / I1, scale * mb[1] / I2, scale * mb[2] / I3)
    return w1, quat_normalize(q1), (scale * dm[0] / I1, scale * dm[1] / I2, scale * dm[2] / I3)


@njit(cache=True, error_model="numpy")
def _modulus_and_rate(I1, I2, I3, w1, w2, w3):
    """(m_c, λ): the complementary parameter 1 − m and the rate λ (1/s) of the elliptic argument u = λt − ν
    of the motion from ω = (w1, w2, w3) (_sorted_flow's formulas); λ = 0 for a symmetric body or on the
    separatrix (no elliptic motion)."""
    p0, p1, p2, par = _sort3(I1, I2, I3)
    I = (I1 + 0.0, I2 + 0.0, I3 + 0.0)
    J1 = I[p0]
    J2 = I[p1]
    J3 = I[p2]
    m = (I1 * w1, I2 * w2, I3 * w3)
    x = m[p0]
    y = m[p1]
    z = m[p2]
    if J1 == J2 or J2 == J3:
        return 1.0, 0.0
    J32 = J3 - J2
    J31 = J3 - J1
    J21 = J2 - J1
    D1 = y * y * J21 / J2 + z * z * J31 / J3
    D3 = -(x * x * J31 / J1 + y * y * J32 / J2)
    D2 = z * z * J32 / J3 - x * x * J21 / J1
    if D2 < 0.0:
        return min(D2 * J31 / (D3 * J21), 1.0), math.sqrt(-D3 * J21 / (J1 * J2 * J3))
    if D2 > 0.0:
        return min(D2 * J31 / (D1 * J32), 1.0), math.sqrt(D1 * J32 / (J1 * J2 * J3))
    return 0.0, 0.0


def flip_period(I, omega0):
    """Closed-form time (s) between two successive flips, 2 K(m) / λ: the half period of the body
    angular momentum m(t) (its intermediate component m2 ∝ sn changes sign every 2K/λ).  The full
    period of m(t) is twice this.  inf for a symmetric body or on the separatrix."""
    mc, lam = _modulus_and_rate(*np.asarray(I, dtype=float), *np.asarray(omega0, dtype=float))
    return math.inf if lam == 0.0 else 2.0 * ellipk(mc) / lam


def elliptic_rate(I, omega0):
    """λ (1/s): the rate of the elliptic argument u = λt − ν of the torque-free motion from the body rates
    omega0 (rad/s) of principal moments I (kg m², any order); a step of h seconds advances u by λh, which
    decides the branch it takes (SHORT_STEP) and its number of doublings.  0 for a symmetric body or on the
    separatrix."""
    return _modulus_and_rate(*np.asarray(I, dtype=float), *np.asarray(omega0, dtype=float))[1]


@njit(cache=True, parallel=True, error_model="numpy")
def _free_body(I, w0, q0, t, w_out, q_out):
    nb = I.shape[0]
    nt = t.shape[0]
    for k in prange(nb * nt):
        b = k // nt
        i = k - b * nt
        body = (I[b, 0], I[b, 1], I[b, 2], 0.0)
        w, q = free_flow_exact((w0[b, 0], w0[b, 1], w0[b, 2]), (q0[b, 0], q0[b, 1], q0[b, 2], q0[b, 3]), t[i], body)
        w_out[b, i, 0] = w[0]
        w_out[b, i, 1] = w[1]
        w_out[b, i, 2] = w[2]
        q_out[b, i, 0] = q[0]
        q_out[b, i, 1] = q[1]
        q_out[b, i, 2] = q[2]
        q_out[b, i, 3] = q[3]


def free_body(I, omega0, q0, t):
    """The exact torque-free motion from (ω0, q0) at each time of t (s, measured from the initial state).

    I (3,) principal moments (kg m², any order, any positive values), omega0 (3,) body angular velocity
    (rad/s), q0 (4,) orientation (scalar first, body → lab), t (n,) times.  Returns ω (n, 3) and q (n, 4).
    With batches I (B, 3), omega0 (B, 3), q0 (B, 4) (any of them may be a single one) it returns
    ω (B, n, 3), q (B, n, 4).  Each time is computed directly from the initial state, not by stepping.
    """
    I = np.asarray(I, dtype=float)
    omega0 = np.asarray(omega0, dtype=float)
    q0 = np.asarray(q0, dtype=float)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    single = I.ndim == 1 and omega0.ndim == 1 and q0.ndim == 1
    nb = max(np.atleast_2d(a).shape[0] for a in (I, omega0, q0))
    I2 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(I), (nb, 3)))
    w2 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(omega0), (nb, 3)))
    q2 = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(q0), (nb, 4)))
    if np.any(I2 <= 0):
        raise ValueError("principal moments must be positive")
    w_out = np.empty((nb, t.size, 3))
    q_out = np.empty((nb, t.size, 4))
    _free_body(I2, w2, q2, np.ascontiguousarray(t), w_out, q_out)
    if single:
        return w_out[0], q_out[0]
    return w_out, q_out
