"""Jacobi elliptic functions and Carlson's symmetric integrals in numba, allocation-free.

Parameter convention: the *parameter* m = k² (k the modulus) as in scipy and
Abramowitz & Stegun; every function here takes the *complementary* parameter
mc = 1 − m = k'² instead (and m itself where the formula needs it), because
near the separatrix of the free rigid body m → 1 and all the information is
in mc, which the caller computes without cancellation.  For 0 ≤ m ≤ 1:

- ``sncndn(u, mc)`` -> (sn, cn, dn) of u at parameter m = 1 − mc: Bulirsch's
  descending Gauss/Landen transformation (AGM; Bulirsch, Numer. Math. 7, 1965,
  "sncndn"; also Numerical Recipes §6.12).  The AGM ladder is walked back
  without storing it: a_{n-1} = a_n + c_n, b_{n-1} = b_n² / a_{n-1}, both
  relatively accurate (c_n is carried by c_{n+1} = c_n² / (4 a_{n+1})), so no
  array is needed.  mc = 0 gives (tanh, sech, sech).
- ``ellipk(mc)``: K(m) = π / (2 AGM(1, √mc)); ``ellipk_and_pi_minus_k(mc, n)``: K and the complete
  Π(n|m) − K from the same AGM (DLMF 19.8.6).
- ``rf(x, y, z)``, ``rj(x, y, z, p)`` (p > 0), ``rd(x, y, z)``,
  ``rc1(e)`` = R_C(1, 1 + e): Carlson's duplication algorithms (Carlson,
  Numer. Algorithms 10, 1995; DLMF §19.36), relative error ≤ 8 eps measured
  (R_J loses digits when p is far below x, y, z spread over many decades,
  where R_C(1, 1 + e) with e → −1 cancels; the flow always has p ≥ 1 ≥ x, y, z).
- ``ellipf_red(s, c2, d2)`` = F(φ|m) and ``ellippi_red(s, c2, d2, n)`` =
  Π(φ, n|m) = ∫₀^φ dθ / ((1 − n sin²θ) √(1 − m sin²θ)) for |φ| ≤ π/2, given
  s = sin φ, c2 = cos²φ, d2 = 1 − m sin²φ (no angle, no cancellation: the
  flow has sn, cn, dn at hand).  ``ellipf(phi, mc)``, ``ellippi(phi, n, mc)``
  are the same for any real φ (quasi-periodic continuation F(φ + jπ) =
  F(φ) + 2jK, Π likewise with the complete Π), and ``ellippi_complete(n, mc)``.
  n < 1 (the rigid body only needs n ≤ 0).
"""

import math

from numba import njit

_PI = math.pi
# Bulirsch's AGM stops when |a − b| ≤ CA a; the top-level error is O(CA²).
_CA = 1.0e-9
_MAX_AGM = 40
# Below this |u| sncndn uses the Maclaurin series (no AGM, no libm), exact to rounding.
_SERIES_U = 0.01


@njit(cache=True, error_model="numpy")
def series_coefficients(m):
    """Maclaurin coefficients of sn, cn, dn in u² (DLMF 22.10.1-3) at parameter m, for sncndn_series."""
    m2 = m * m
    m3 = m2 * m
    return (
        -(1.0 + m) * (1.0 / 6.0),
        (1.0 + 14.0 * m + m2) * (1.0 / 120.0),
        -(1.0 + 135.0 * m + 135.0 * m2 + m3) * (1.0 / 5040.0),
        (1.0 + 1228.0 * m + 5478.0 * m2 + 1228.0 * m3 + m2 * m2) * (1.0 / 362880.0),
        (1.0 + 4.0 * m) * (1.0 / 24.0),
        -(1.0 + 44.0 * m + 16.0 * m2) * (1.0 / 720.0),
        (1.0 + 408.0 * m + 912.0 * m2 + 64.0 * m3) * (1.0 / 40320.0),
        m * (4.0 + m) * (1.0 / 24.0),
        -m * (16.0 + 44.0 * m + m2) * (1.0 / 720.0),
        m * (64.0 + 912.0 * m + 408.0 * m2 + m3) * (1.0 / 40320.0),
        m,
    )


@njit(cache=True, error_model="numpy")
def sncndn_series(u, k):
    """(sn, cn, dn)(u) from the Maclaurin series through u⁹ (sn) and u⁸ (cn, dn), k =
    series_coefficients(m); exact to rounding for |u| < 0.01 (the first dropped terms are < 2e-22)."""
    u2 = u * u
    sn = u * (1.0 + u2 * (k[0] + u2 * (k[1] + u2 * (k[2] + u2 * k[3]))))
    cn = 1.0 + u2 * (-0.5 + u2 * (k[4] + u2 * (k[5] + u2 * k[6])))
    dn = 1.0 + u2 * (-0.5 * k[10] + u2 * (k[7] + u2 * (k[8] + u2 * k[9])))
    return sn, cn, dn


@njit(cache=True, error_model="numpy")
def one_minus_cndn_series(u, k):
    """(1 − cn u, 1 − dn u) from sncndn_series' series without their leading 1, each within a few eps of itself
    (1 − cn formed from sncndn_series' cn keeps cn's rounding, ~eps, against a value ~u²/2)."""
    u2 = u * u
    return (
        -u2 * (-0.5 + u2 * (k[4] + u2 * (k[5] + u2 * k[6]))),
        -u2 * (-0.5 * k[10] + u2 * (k[7] + u2 * (k[8] + u2 * k[9]))),
    )


@njit(cache=True, error_model="numpy")
def sncndn(u, mc):
    """(sn u, cn u, dn u) at parameter m = 1 − mc, 0 ≤ mc ≤ 1 (Bulirsch's algorithm)."""
    if mc <= 0.0:
        t = math.tanh(u)
        s = 1.0 / math.cosh(u)
        return t, s, s
    m = 1.0 - mc
    if abs(u) < _SERIES_U:
        return sncndn_series(u, series_coefficients(m))
    # Forward AGM: a_0 = 1, b_0 = √mc, c_0 = √m; keep only the last level.
    a = 1.0
    b = math.sqrt(mc)
    c = math.sqrt(m)
    levels = 0
    while levels < _MAX_AGM:
        if abs(a - b) <= _CA * a:
            break
        a_next = 0.5 * (a + b)
        b = math.sqrt(a * b)
        c = 0.25 * c * c / a_next  # c_{n+1} = c_n² / (4 a_{n+1})
        a = a_next
        levels += 1
    # Bulirsch iterates once more: top amplitude scale a_{N+1} = (a_N + b_N)/2.
    a_top = 0.5 * (a + b)
    x = a_top * u
    sn = math.sin(x)
    cn = math.cos(x)
    dn = 1.0
    if sn != 0.0:
        r = cn / sn
        cc = a_top * r
        # walk back the ladder: level n = levels .. 0 uses (a_n, b_n)
        an = a
        bn = b
        cnl = c
        for _ in range(levels + 1):
            r *= cc
            cc *= dn
            dn = (bn + r) / (an + r)
            r = cc / an
            # previous level
            a_prev = an + cnl
            b_prev = bn * bn / a_prev
            c_prev = 2.0 * math.sqrt(an * cnl)
            an, bn, cnl = a_prev, b_prev, c_prev
        if abs(cc) > 1.0e150:
            s = 1.0 / (abs(cc) * math.sqrt(1.0 + 1.0 / (cc * cc)))
        else:
            s = 1.0 / math.sqrt(cc * cc + 1.0)
        sn = s if sn >= 0.0 else -s
        cn = cc * sn
    return sn, cn, dn


@njit(cache=True, error_model="numpy")
def ellipk(mc):
    """Complete K(m), m = 1 − mc, 0 < mc ≤ 1: π / (2 AGM(1, √mc))."""
    a = 1.0
    b = math.sqrt(mc)
    for _ in range(_MAX_AGM):
        if abs(a - b) <= 1.0e-8 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return _PI / (a + b)


@njit(cache=True, error_model="numpy")
def ellipk_and_pi_minus_k(mc, n):
    """(K(m), Π(n|m) − K(m)), m = 1 − mc, 0 < mc ≤ 1, n < 1, from one AGM (DLMF 19.8.6-7; the form of
    Π − K there, π n ΣQ / (4 M (1 − n)), has no difference of K and Π, so it keeps its relative accuracy as
    n → 0).  Each level: a_{j+1} = (a + g)/2, g_{j+1} = √(a g), p_{j+1} = (p² + a g)/(2p) (p₀² = 1 − n),
    Q_{j+1} = Q ε/2 with ε = (p² − a g)/(p² + a g): one square root and two divisions, against R_J(0, mc, 1,
    1 − n)'s four square roots, a division and an R_C per duplication.  The AGM converges quadratically, p
    to it by halving while p ≫ M, so 3-13 levels for −1e3 ≤ n ≤ −1e-3 and mc ≥ 1e-15.  Π − K within 2.7 eps
    of mpmath for mc ≥ 1e-300, −1e6 ≤ n ≤ 0.99, K within 3 eps (tests/test_elliptic.py
    ::test_ellipk_and_pi_minus_k)."""
    a = 1.0
    g = math.sqrt(mc)
    p2 = 1.0 - n
    p = math.sqrt(p2)
    q = 1.0
    total = 1.0
    for _ in range(_MAX_AGM + 60):  # Q at least halves per level: ≤ 60 levels after the AGM's own
        ag = a * g
        den = p2 + ag
        q *= 0.5 * (p2 - ag) / den
        p = 0.5 * den / p
        p2 = p * p
        a, g = 0.5 * (a + g), math.sqrt(ag)
        total += q
        if abs(q) <= 1.0e-17 * total and abs(a - g) <= 1.0e-8 * a:
            break
    mean = 0.5 * (a + g)
    return _PI / (2.0 * mean), _PI * n * total / (4.0 * mean * (1.0 - n))


@njit(cache=True, error_model="numpy")
def rf(x, y, z):
    """Carlson's R_F(x, y, z) = ½ ∫₀^∞ dt / √((t+x)(t+y)(t+z)); x, y, z ≥ 0, at most one zero."""
    A0 = (x + y + z) / 3.0
    dx = A0 - x
    dy = A0 - y
    Q = 600.0 * max(abs(dx), abs(dy), abs(A0 - z))  # (3r)^(-1/6) with r = 1e-17
    A = A0
    f = 1.0
    for _ in range(60):
        if f * Q < abs(A):
            break
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        A = 0.25 * (A + lam)
        f *= 0.25
    X = f * dx / A
    Y = f * dy / A
    Z = -X - Y
    E2 = X * Y - Z * Z
    E3 = X * Y * Z
    return (1.0 - E2 / 10.0 + E3 / 14.0 + E2 * E2 / 24.0 - 3.0 * E2 * E3 / 44.0) / math.sqrt(A)


@njit(cache=True, error_model="numpy")
def rc1(e):
    """R_C(1, 1 + e) for e > −1: atan(√e)/√e (e > 0), atanh(√−e)/√−e (e < 0)."""
    if abs(e) < 1.0e-3:
        # 1 − e/3 + e²/5 − e³/7 + ... (alternating, |term| < 1e-3^k); to e^6 error < 1e-21
        return 1.0 + e * (-1.0 / 3 + e * (1.0 / 5 + e * (-1.0 / 7 + e * (1.0 / 9 + e * (-1.0 / 11 + e / 13)))))
    if e > 0.0:
        s = math.sqrt(e)
        return math.atan(s) / s
    s = math.sqrt(-e)
    return math.atanh(s) / s


@njit(cache=True, error_model="numpy")
def rj(x, y, z, p):
    """Carlson's R_J(x, y, z, p) = 3/2 ∫₀^∞ dt / ((t+p) √((t+x)(t+y)(t+z))); x, y, z ≥ 0 (at most one
    zero), p > 0."""
    A0 = (x + y + z + p + p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    dx = A0 - x
    dy = A0 - y
    dz = A0 - z
    Q = 900.0 * max(abs(dx), abs(dy), abs(dz), abs(A0 - p))  # (r/4)^(-1/6) with r = 1e-17
    A = A0
    f = 1.0  # 4^-k
    f3 = 1.0  # 4^-3k
    total = 0.0
    for _ in range(60):
        if f * Q < abs(A):
            break
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        sp = math.sqrt(p)
        lam = sx * sy + sx * sz + sy * sz
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = f3 * delta / (d * d)
        total += f * rc1(e) / d
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        p = 0.25 * (p + lam)
        A = 0.25 * (A + lam)
        f *= 0.25
        f3 *= 1.0 / 64.0
    series = rj_series(f * dx / A, f * dy / A, f * dz / A)
    return f * series / (A * math.sqrt(A)) + 6.0 * total


@njit(cache=True, error_model="numpy")
def rj_series(X, Y, Z):
    """The series of Carlson's R_J(x, y, z, p) about the mean A = (x + y + z + 2p)/5 of its arguments, times
    A^(3/2): 1 − 3E2/14 + E3/6 + 9E2²/88 − 3E4/22 − 9E2E3/52 + 3E5/26 in the scaled deviations X = (A − x)/A,
    Y, Z and P = (A − p)/A = −(X + Y + Z)/2 (Carlson, Numer. Algorithms 10 (1995) 13–26, eq. (2.7)); the
    tail of ``rj`` after its duplications, and the whole of an R_J of close arguments
    (euler_poinsot._rj_close)."""
    P = -0.5 * (X + Y + Z)
    E2 = X * Y + X * Z + Y * Z - 3.0 * P * P
    E3 = X * Y * Z + 2.0 * E2 * P + 4.0 * P * P * P
    E4 = (2.0 * X * Y * Z + E2 * P + 3.0 * P * P * P) * P
    E5 = X * Y * Z * P * P
    return 1.0 + (
        E2 * (-3.0 / 14.0 + E2 * (9.0 / 88.0) - E3 * (9.0 / 52.0))
        + E3 * (1.0 / 6.0)
        - E4 * (3.0 / 22.0)
        + E5 * (3.0 / 26.0)
    )


@njit(cache=True, error_model="numpy")
def rd(x, y, z):
    """Carlson's R_D(x, y, z) = R_J(x, y, z, z); x, y ≥ 0 (not both zero), z > 0."""
    return rj(x, y, z, z)


@njit(cache=True, error_model="numpy")
def ellipf_red(s, c2, d2):
    """F(φ|m) for |φ| ≤ π/2 from s = sin φ, c2 = cos² φ, d2 = 1 − m sin² φ."""
    return s * rf(c2, d2, 1.0)


@njit(cache=True, error_model="numpy")
def ellippi_red(s, c2, d2, n):
    """Π(φ, n|m) for |φ| ≤ π/2 and n < 1, from s = sin φ, c2 = cos² φ, d2 = 1 − m sin² φ."""
    s2 = s * s
    return s * rf(c2, d2, 1.0) + n / 3.0 * s * s2 * rj(c2, d2, 1.0, 1.0 - n * s2)


@njit(cache=True, error_model="numpy")
def ellippi_complete(n, mc):
    """Π(n|m) = Π(π/2, n|m), m = 1 − mc, n < 1, mc > 0: K + (Π − K) from one AGM (ellipk_and_pi_minus_k)."""
    k, pi_minus_k = ellipk_and_pi_minus_k(mc, n)
    return k + pi_minus_k


@njit(cache=True, error_model="numpy")
def _reduce(phi):
    """(j, sin ψ, cos² ψ) with φ = jπ + ψ, |ψ| ≤ π/2."""
    j = math.floor(phi / _PI + 0.5)
    r = phi - j * _PI
    s = math.sin(r)
    c = math.cos(r)
    return j, s, c * c


@njit(cache=True, error_model="numpy")
def ellipf(phi, mc):
    """Incomplete F(φ|m) = ∫₀^φ dθ / √(1 − m sin²θ), any real φ, m = 1 − mc, 0 < mc ≤ 1."""
    j, s, c2 = _reduce(phi)
    value = ellipf_red(s, c2, c2 + mc * s * s)
    if j != 0.0:
        value += 2.0 * j * ellipk(mc)
    return value


@njit(cache=True, error_model="numpy")
def ellippi(phi, n, mc):
    """Incomplete Π(φ, n|m) = ∫₀^φ dθ / ((1 − n sin²θ) √(1 − m sin²θ)), any real φ, n < 1, 0 < mc ≤ 1."""
    j, s, c2 = _reduce(phi)
    value = ellippi_red(s, c2, c2 + mc * s * s, n)
    if j != 0.0:
        value += 2.0 * j * ellippi_complete(n, mc)
    return value
