"""The small-angle polynomial of rotation.py against exact rational arithmetic: an error bound, not a sample.

``_cos_sinc_half(angle2)`` returns c ≈ cos h and s ≈ sin(h)/(2h) with h² = angle2/4 ≤ 0.01 (angle < SMALL_ANGLE
= 0.2 rad), by Horner's rule on the Taylor series through h⁸.  Both series are power series in h², so for a
double angle2 the exact values are rationals we can sum with ``fractions.Fraction`` to any precision.

The bound, in units of the last place (ulp) of the result:
- truncation: both series alternate with terms decreasing in size (checked below), so the dropped tail is at
  most the first dropped term, h¹⁰/10! = 2.8e-17 for c (0.25 ulp of c ≥ 0.995) and h¹⁰/(2·11!) = 1.3e-18 for s
  (0.03 ulp of s ≥ 0.4995);
- rounding: the last operation, 1 + t (resp. 0.5 + t), rounds once (≤ 0.5 ulp); t = h²·p(h²) itself is off by
  a few of its own ulps, and |t| ≤ 0.005 (resp. 0.00084), i.e. ≤ 0.03 ulp of the result (measured below).
So |error| < 0.25 + 0.5 + 0.03 < 1 ulp: the polynomial is faithfully rounded (one of the two doubles around
the exact value) over the whole range; the test checks each part of that budget and the sum on 4000 angles,
including both ends.  It is not always the correctly rounded double (nor is libm's cos): that is what
test_rotation's "≤ 2 ulp of libm" allows for.
"""

from fractions import Fraction
from math import factorial

import numpy as np
import pytest

from gyrolab.kernels.rotation import SMALL_ANGLE, WIDE_ANGLE, _cos_sinc_half, _cos_sinc_half_wide

TERMS = 12  # the tail after 12 terms is < 1e-60 for h² ≤ 0.01


def exact(angle2, terms=TERMS):
    """(cos h, sin(h)/(2h)) as Fractions, h² = angle2/4, to < 1e-60 (h² ≤ 0.01 with TERMS terms)."""
    h2 = Fraction(angle2) / 4
    c = sum(Fraction((-1) ** k, factorial(2 * k)) * h2**k for k in range(terms))
    s = sum(Fraction((-1) ** k, 2 * factorial(2 * k + 1)) * h2**k for k in range(terms))
    return c, s


def ulps(value, reference):
    """|value − reference| in ulps of the double nearest the reference."""
    return float(abs(Fraction(value) - reference) / Fraction(float(np.spacing(float(reference)))))


def angles2():
    rng = np.random.default_rng(11)
    edge = SMALL_ANGLE * SMALL_ANGLE
    a2 = np.concatenate(
        [
            rng.uniform(0.0, edge, 2000),
            edge * 10.0 ** rng.uniform(-20, 0, 1000),
            np.nextafter(edge, 0.0) - np.arange(1000) * np.spacing(edge),  # the top end, ulp by ulp
        ]
    )
    return np.concatenate([[0.0, 5e-324, 1e-300], a2])


def test_series_alternate_with_decreasing_terms_and_small_tail():
    """At the largest h² = 0.01 each term is smaller than the one before (so the tail after h⁸ is below the
    first dropped term), and that term is 0.25 ulp of cos h and 0.03 ulp of sin(h)/(2h)."""
    h2 = Fraction(SMALL_ANGLE) ** 2 / 4
    cos_terms = [h2**k / factorial(2 * k) for k in range(8)]
    sinc_terms = [h2**k / (2 * factorial(2 * k + 1)) for k in range(8)]
    assert all(b < a for a, b in zip(cos_terms, cos_terms[1:]))
    assert all(b < a for a, b in zip(sinc_terms, sinc_terms[1:]))
    c, s = exact(np.nextafter(SMALL_ANGLE**2, 0.0))
    assert ulps(float(c), c - cos_terms[5]) < 0.75  # the nearest double is within 0.5 ulp of c
    assert float(cos_terms[5] / Fraction(float(np.spacing(float(c))))) < 0.26
    assert float(sinc_terms[5] / Fraction(float(np.spacing(float(s))))) < 0.03


@pytest.mark.slow
def test_polynomial_is_faithfully_rounded_over_the_whole_range():
    """Every angle² in [0, SMALL_ANGLE²): |c − cos h| and |s − sin(h)/(2h)| < 1 ulp, measured against the exact
    rationals.  Measured: max 0.75 ulp (c) and 0.52 ulp (s); both correctly rounded at 92 % of the angles.
    The part of the error that is not the final rounding (truncation + the rounding inside Horner) stays
    below 0.3 ulp (measured 0.25), as the budget in the module docstring says."""
    worst_c = worst_s = 0.0
    worst_inner = 0.0
    rounded = 0
    samples = angles2()
    for a2 in samples:
        c, s = _cos_sinc_half(float(a2))
        c_exact, s_exact = exact(float(a2))
        ec, es = ulps(c, c_exact), ulps(s, s_exact)
        worst_c, worst_s = max(worst_c, ec), max(worst_s, es)
        rounded += ec <= 0.5 and es <= 0.5
        # Error before the final rounding: the exact sum of the double 1 (or 0.5) and the double t.
        h2 = 0.25 * float(a2)
        t_c = h2 * (-1.0 / 2 + h2 * (1.0 / 24 + h2 * (-1.0 / 720 + h2 * (1.0 / 40320))))
        t_s = h2 * (-1.0 / 12 + h2 * (1.0 / 240 + h2 * (-1.0 / 10080 + h2 * (1.0 / 725760))))
        assert c == 1.0 + t_c and s == 0.5 + t_s  # the same expression as rotation.py
        inner = max(ulps(1 + Fraction(t_c), c_exact), ulps(Fraction(1, 2) + Fraction(t_s), s_exact))
        worst_inner = max(worst_inner, inner)
    print(
        f"max {worst_c:.3f} ulp (c), {worst_s:.3f} ulp (s), before the last rounding {worst_inner:.3f} ulp; "
        f"correctly rounded {rounded / len(samples):.1%}"
    )
    assert worst_c < 1.0 and worst_s < 1.0
    assert worst_inner < 0.3


@pytest.mark.parametrize("angle2", [0.0, 1e-30, 1e-8])
def test_tiny_angles_are_exact(angle2):
    """For tiny angles the results are the correctly rounded cos h and sin(h)/(2h) (1 and 0.5 below 1e-16)."""
    c, s = _cos_sinc_half(angle2)
    c_exact, s_exact = exact(angle2)
    assert c == float(c_exact) and s == float(s_exact)


def test_longer_series_is_faithfully_rounded_up_to_the_wide_angle():
    """From SMALL_ANGLE to WIDE_ANGLE (0.2 to 0.8 rad, h² < 0.16) rotation.py takes the series through h¹⁴ (c) and
    h¹² (s): |c − cos h| and |s − sin(h)/(2h)| < 1 ulp against the exact rationals, both edges included and the
    top end ulp by ulp.  Measured (printed with -s): max 0.58 ulp (c) and 0.55 ulp (s).  The first dropped terms
    are 2e-4 ulp (c ≥ 0.92) and 0.02 ulp (s ≥ 0.487) at the top end; the doubled series this replaced was
    within 0.71 and 2.3 ulp."""
    h2 = Fraction(WIDE_ANGLE) ** 2 / 4
    c_top, s_top = exact(np.nextafter(WIDE_ANGLE**2, 0.0), terms=24)
    assert float(h2**8 / factorial(16) / Fraction(float(np.spacing(float(c_top))))) < 0.001
    assert float(h2**7 / (2 * factorial(15)) / Fraction(float(np.spacing(float(s_top))))) < 0.03
    rng = np.random.default_rng(12)
    lo, hi = SMALL_ANGLE * SMALL_ANGLE, WIDE_ANGLE * WIDE_ANGLE
    samples = np.concatenate(
        [
            rng.uniform(lo, hi, 1500),
            [lo, np.nextafter(lo, 1.0)],
            np.nextafter(hi, 0.0) - np.arange(300) * np.spacing(hi),  # the top end, ulp by ulp
        ]
    )
    worst_c = worst_s = 0.0
    for a2 in samples:
        c, s = _cos_sinc_half_wide(float(a2))
        c_exact, s_exact = exact(float(a2), terms=24)  # h² ≤ 0.16: the tail after 24 terms is < 1e-60
        worst_c, worst_s = max(worst_c, ulps(c, c_exact)), max(worst_s, ulps(s, s_exact))
    print(f"max {worst_c:.3f} ulp (c), {worst_s:.3f} ulp (s)")
    assert worst_c < 1.0 and worst_s < 1.0
