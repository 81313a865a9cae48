"""Our numba Jacobi sn, cn, dn, K(m) and Carlson R_F, R_J, R_D, R_C against scipy.special.

Parameter convention of kernels/elliptic.py: the complementary parameter mc = 1 − m (m = k²).
Errors are in units of eps = 2^-52: absolute for sn, cn, dn (|values| ≤ 1), relative otherwise.
Measured (python -m pytest tests/test_elliptic.py -s): printed by each test.
"""

import math

import numpy as np
import pytest
import scipy.special as sp
from numba import njit
from scipy.integrate import quad

from gyrolab.kernels import elliptic as E

EPS = np.finfo(float).eps


@njit(cache=False)
def _sncndn_many(u, mc):
    out = np.empty((u.size, 3))
    for i in range(u.size):
        out[i, 0], out[i, 1], out[i, 2] = E.sncndn(u[i], mc[i])
    return out


@njit(cache=False)
def _carlson_many(x, y, z, p):
    out = np.empty((x.size, 3))
    for i in range(x.size):
        out[i, 0] = E.rf(x[i], y[i], z[i])
        out[i, 1] = E.rj(x[i], y[i], z[i], p[i])
        out[i, 2] = E.rd(x[i], y[i], p[i])
    return out


@njit(cache=False)
def _k_many(mc):
    out = np.empty(mc.size)
    for i in range(mc.size):
        out[i] = E.ellipk(mc[i])
    return out


@njit(cache=False)
def _f_pi_many(phi, n, mc):
    out = np.empty((phi.size, 2))
    for i in range(phi.size):
        out[i, 0] = E.ellipf(phi[i], mc[i])
        out[i, 1] = E.ellippi(phi[i], n[i], mc[i])
    return out


def test_sncndn_within_a_quarter_period():
    """|u| ≤ K(m), 0 ≤ m ≤ 0.999 (2e5 points): max |ours − scipy.ellipj| ≤ 32 eps (measured 18.5 eps;
    scipy's own AGM/asin algorithm is not exact either)."""
    rng = np.random.default_rng(0)
    m = rng.uniform(0.0, 0.999, 200_000)
    u = rng.uniform(-1.0, 1.0, m.size) * sp.ellipk(m)
    mc = 1.0 - m
    ours = _sncndn_many(u, mc)
    ref = np.array(sp.ellipj(u, 1.0 - mc)[:3]).T
    err = np.max(np.abs(ours - ref)) / EPS
    print(f"sncndn |u| <= K: {err:.1f} eps")
    assert err <= 32


def test_sncndn_large_arguments():
    """|u| ≤ 20 (several periods): the argument itself carries |u| eps, so the bound is
    8 (1 + |u|) eps (measured max error / (1 + |u|) = 7.2 eps)."""
    rng = np.random.default_rng(1)
    m = rng.uniform(0.0, 0.99, 200_000)
    u = rng.uniform(-20.0, 20.0, m.size)
    mc = 1.0 - m
    ours = _sncndn_many(u, mc)
    ref = np.array(sp.ellipj(u, 1.0 - mc)[:3]).T
    err = np.max(np.max(np.abs(ours - ref), axis=1) / (1.0 + np.abs(u))) / EPS
    print(f"sncndn |u| <= 20: {err:.1f} eps (1 + |u|)")
    assert err <= 8


def test_sncndn_identities_and_limits():
    """sn² + cn² = 1 to 4 eps and dn² + m sn² = 1 to 16 eps (measured 2 and 11 eps; the exact flow
    restores both to rounding itself); m = 0: (sin, cos, 1); m = 1 (mc = 0): (tanh, sech, sech);
    tiny mc (1e-300) and tiny u are handled."""
    rng = np.random.default_rng(2)
    mc = 10.0 ** rng.uniform(-300, 0, 100_000)
    u = rng.uniform(-50, 50, mc.size)
    s, c, d = _sncndn_many(u, mc).T
    m = 1.0 - mc
    assert np.max(np.abs(s * s + c * c - 1)) <= 4 * EPS
    assert np.max(np.abs(d * d + m * s * s - 1)) <= 16 * EPS
    for x in (1e-12, 0.3, 2.0, -7.0):
        np.testing.assert_allclose(E.sncndn(x, 1.0), (math.sin(x), math.cos(x), 1.0), rtol=0, atol=2 * EPS)
        np.testing.assert_allclose(
            E.sncndn(x, 0.0), (math.tanh(x), 1 / math.cosh(x), 1 / math.cosh(x)), rtol=0, atol=2 * EPS
        )
    # near m = 1 against scipy's own separatrix-side values (m = 1 − 1e-12 is exact enough in scipy)
    ref = sp.ellipj(3.0, 1.0 - 2.0**-40)[:3]
    np.testing.assert_allclose(E.sncndn(3.0, 2.0**-40), ref, rtol=0, atol=1e-14)


def test_ellipk():
    """K(m) over mc = 1e-300 .. 1 against scipy.special.ellipkm1: ≤ 4 eps relative (measured 3.5)."""
    mc = 10.0 ** np.random.default_rng(3).uniform(-300, 0, 100_000)
    err = np.max(np.abs(_k_many(mc) / sp.ellipkm1(mc) - 1)) / EPS
    print(f"K: {err:.1f} eps")
    assert err <= 4
    assert abs(E.ellipk(1.0) - math.pi / 2) <= EPS


@pytest.mark.slow
def test_ellipk_and_pi_minus_k():
    """K(m) and the complete Π(n|m) − K(m) = (n/3) R_J(0, mc, 1, 1 − n) from one AGM (DLMF 19.8.6): K against
    scipy.special.ellipkm1 over 20,000 mc from 1e-300 to 1 (≤ 4 eps, measured 3.0), Π − K against mpmath's
    R_J at 30 digits over 600 draws, mc = 1e-300 .. 1 and n = −1e6 .. −1e-6 (the free body's n ≤ 0) or
    0 < n ≤ 0.99: ≤ 4 eps relative (measured 2.7; scipy.special.elliprj itself is 22 eps off at some
    mc ~ 4e-14, which is why the reference is mpmath); n = 0 gives 0."""
    mp = pytest.importorskip("mpmath", reason="mpmath is in the test extra: pip install '.[test]'")
    mp.mp.dps = 30
    rng = np.random.default_rng(11)
    mc = 10.0 ** rng.uniform(-300, 0, 20_000)
    k = np.array([E.ellipk_and_pi_minus_k(a, -1.0)[0] for a in mc])
    k_err = np.max(np.abs(k / sp.ellipkm1(mc) - 1)) / EPS
    mc, n = mc[:600], np.concatenate([-(10.0 ** rng.uniform(-6, 6, 300)), rng.uniform(0.0, 0.99, 300)])
    pi_err = max(
        abs(E.ellipk_and_pi_minus_k(a, b)[1] / (b / mp.mpf(3) * mp.elliprj(0, a, 1, 1 - mp.mpf(b))) - 1)
        for a, b in zip(mc, n)
    )
    pi_err = float(pi_err) / EPS
    print(f"K from the third kind's AGM: {k_err:.1f} eps; Pi - K: {pi_err:.1f} eps")
    assert k_err <= 4
    assert pi_err <= 4
    assert E.ellipk_and_pi_minus_k(0.5, 0.0)[1] == 0.0


def test_carlson_against_scipy():
    """R_F, R_J, R_D on x, y, z ∈ [0, 5], p ∈ [0.01, 5] and on the flow's arguments (x = cos²φ,
    y = x + mc sin²φ, z = 1, p = 1 − n sin²φ ≥ 1, n from 0 to −1e6): ≤ 8 eps relative (measured 4, 6, 4).
    (R_J loses accuracy when p is far below x, y, z and they span many decades: 7e4 eps at
    x ~ 1e9, y, z ~ 1e-18, p = 0.01; the flow never goes there.)"""
    rng = np.random.default_rng(4)
    n_pts = 200_000
    x, y, z = rng.uniform(0, 5, (3, n_pts))
    p = rng.uniform(0.01, 5, n_pts)
    ours = _carlson_many(x, y, z, p)
    for k, ref in enumerate((sp.elliprf(x, y, z), sp.elliprj(x, y, z, p), sp.elliprd(x, y, p))):
        err = np.max(np.abs(ours[:, k] / ref - 1)) / EPS
        print(f"carlson {('RF', 'RJ', 'RD')[k]}: {err:.1f} eps")
        assert err <= 8
    phi = rng.uniform(0, math.pi / 2, n_pts)
    mc = 10.0 ** rng.uniform(-16, 0, n_pts)
    n = -(10.0 ** rng.uniform(-3, 6, n_pts))
    s2 = np.sin(phi) ** 2
    x = np.cos(phi) ** 2
    y = x + mc * s2
    ours = _carlson_many(x, y, np.ones(n_pts), 1 - n * s2)
    for k, ref in enumerate((sp.elliprf(x, y, 1.0), sp.elliprj(x, y, 1.0, 1 - n * s2))):
        err = np.max(np.abs(ours[:, k] / ref - 1)) / EPS
        print(f"carlson on the flow's range {('RF', 'RJ')[k]}: {err:.1f} eps")
        assert err <= 8
    for e in (-0.9, -1e-4, 0.0, 1e-4, 3.0):
        assert abs(E.rc1(e) / sp.elliprc(1.0, 1.0 + e) - 1) <= 4 * EPS


def test_incomplete_integrals():
    """F(φ|m) against scipy.ellipkinc for any real φ (|φ| ≤ 20, m ≤ 0.999): ≤ 8 eps relative (measured 4.3);
    Π(φ, n|m) (n ≤ 0, as the flow needs) against its Carlson form with scipy's elliprf/elliprj (reduced
    to |φ| ≤ π/2 and continued by Π(φ + jπ) = Π(φ) + 2jΠ(n|m)): ≤ 8 eps of the magnitude of the terms
    s R_F, (n/3) s³ R_J, 2j R_F(0, mc, 1), 2j (n/3) R_J(0, mc, 1, 1 − n) (measured 6.8, 4.5 when the complete
    Π was Carlson's form too, before it came from ellipk_and_pi_minus_k's AGM, which is closer to mpmath than
    scipy's elliprj: test_ellipk_and_pi_minus_k; relative to Π itself 333 eps, as the R_F and R_J terms cancel
    for n ≪ −1, which is why the flow uses Π − F = (n/3) s³ R_J);
    and against adaptive quadrature of the defining integral at a few points (1e-13)."""
    rng = np.random.default_rng(5)
    n_pts = 100_000
    phi = rng.uniform(-20, 20, n_pts)
    m = rng.uniform(0, 0.999, n_pts)
    n = -(10.0 ** rng.uniform(-3, 3, n_pts))
    ours = _f_pi_many(phi, n, 1 - m)
    ref_f = sp.ellipkinc(phi, m)
    err_f = np.max(np.abs(ours[:, 0] - ref_f) / np.abs(ref_f)) / EPS
    j = np.floor(phi / np.pi + 0.5)
    r = phi - j * np.pi
    s, c2 = np.sin(r), np.cos(r) ** 2
    d2 = 1 - m * s * s
    pi_red = s * sp.elliprf(c2, d2, 1) + n / 3 * s**3 * sp.elliprj(c2, d2, 1, 1 - n * s * s)
    pi_c = sp.elliprf(0, 1 - m, 1) + n / 3 * sp.elliprj(0, 1 - m, 1, 1 - n)
    ref_pi = pi_red + 2 * j * pi_c
    scale = (
        np.abs(s * sp.elliprf(c2, d2, 1))
        + np.abs(n / 3 * s**3 * sp.elliprj(c2, d2, 1, 1 - n * s * s))
        + 2 * np.abs(j) * (sp.elliprf(0, 1 - m, 1) + np.abs(n / 3 * sp.elliprj(0, 1 - m, 1, 1 - n)))
    )
    err_pi = np.max(np.abs(ours[:, 1] - ref_pi) / scale) / EPS
    err_rel = np.max(np.abs(ours[:, 1] - ref_pi) / np.abs(ref_pi)) / EPS
    print(f"F: {err_f:.1f} eps, Pi: {err_pi:.1f} eps of the terms ({err_rel:.0f} eps relative)")
    assert err_f <= 8
    assert err_pi <= 8
    for ph, nn, mm in ((0.7, -0.5, 0.3), (1.5, -30.0, 0.9), (4.0, -2.0, 0.99), (-2.5, 0.5, 0.2)):
        val = quad(
            lambda t: 1 / ((1 - nn * math.sin(t) ** 2) * math.sqrt(1 - mm * math.sin(t) ** 2)),
            0,
            ph,
            epsabs=0,
            epsrel=5e-14,
            limit=200,
        )[0]
        assert abs(E.ellippi(ph, nn, 1 - mm) / val - 1) <= 1e-13
