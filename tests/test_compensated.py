"""Compensated accumulation (kernels/compensated.py): ``accumulate=compensated`` variants of lie_poisson4 and
split6_exact are the same maps to rounding, lose the plain state's linear round-off drift, and are
carried methods in everything (no blocks, no driven bodies)."""

import numpy as np
import pytest

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.driver import ENERGY, FIELDS
from gyrolab.kernels.registry import canonical_name, get_method
from gyrolab.kernels.scenes import build_scene

COMPENSATED = "(accumulate=compensated)"
OMEGA = slice(FIELDS.index("omega_1"), FIELDS.index("omega_1") + 3)
GAMMA = slice(FIELDS.index("gamma_1"), FIELDS.index("gamma_1") + 3)


def _run(method, scene, f, theta0, dt, stride, n_samples):
    sc = build_scene(scene, f, theta0)
    out, status, n_steps = integrate(
        method, np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0]), np.full(1, dt), np.full(1, stride),
        n_samples, 1e9,
    )  # fmt: skip
    assert status[0] == 0 and n_steps[0] == stride * (n_samples - 1)
    return out[0]


@pytest.mark.parametrize(
    "method, scene, f, theta0, dt",
    [
        ("lie_poisson4", "heavy_top", 50.0, 45.0, 1e-3),  # symmetric: the exact free flow, wide half angles
        ("lie_poisson4", "free_asymmetric", 1.0, 0.0, 1e-2),  # the axis splitting 1-2-3-2-1
        ("lie_poisson4(axes=S-M-L)", "heavy_body", 5.0, 30.0, 1e-3),  # another axis order, gravity off axis
        ("split6_exact", "heavy_top", 50.0, 45.0, 1e-3),
        ("split6_exact", "free_asymmetric", 1.0, 0.0, 1e-2),  # the elliptic flow's ω as increments
    ],
)
def test_the_compensated_variant_is_the_method_to_rounding(method, scene, f, theta0, dt):
    """200 steps of each: the compensated state is the plain one to rounding (the two round differently,
    and nothing else differs), far below either's truncation error."""
    name = method[:-1] + ",accumulate=compensated)" if method.endswith(")") else method + COMPENSATED
    plain = _run(method, scene, f, theta0, dt, 20, 11)
    comp = _run(name, scene, f, theta0, dt, 20, 11)
    scale = np.abs(plain[:, OMEGA]).max()
    assert np.abs(comp[:, OMEGA] - plain[:, OMEGA]).max() <= 1e-12 * scale
    assert np.abs(comp[:, GAMMA] - plain[:, GAMMA]).max() <= 1e-12
    assert not np.array_equal(comp[-1, OMEGA], plain[-1, OMEGA])  # the compensated path ran


@pytest.mark.parametrize(
    "method, scene, f, theta0, stride, drift",
    [
        ("lie_poisson4", "heavy_top", 50.0, 45.0, 4000, 1e-14),
        ("split6_exact", "free_asymmetric", 1.0, 0.0, 16000, 1e-13),  # seven elliptic flows a step, no kicks
    ],
)
def test_compensation_removes_the_linear_round_off_drift_of_the_energy(method, scene, f, theta0, stride, drift):
    """dt = 2.5e-5 s (lie_poisson4's energy oscillation on the top is below rounding; split6_exact's flows
    are exact on the free racket), 100 samples of `stride` steps: the plain state's energy error grows along
    the run (benchmarks/roundoff_bias.py: a rounding bias in lie_poisson4's turn of ω⊥, to ~3e-14 in 4e5
    steps; the elliptic flow's ω rebuilt from sn, cn, dn at every flow, to ~7e-13 in 1.6e6 steps: since
    2026-12-06 it drifts ~8x slower than the 1.2e-11 in 4e6 steps it had, and 4e5 steps no longer show it
    above its wander); compensated it stays at the rounding of evaluating E (~1e-16; benchmarks/brouwer.py
    resolves it below that, growing as √t)."""
    plain = _run(method, scene, f, theta0, 2.5e-5, stride, 101)
    comp = _run(method + COMPENSATED, scene, f, theta0, 2.5e-5, stride, 101)
    e_plain = np.abs(plain[:, ENERGY] / plain[0, ENERGY] - 1)
    e_comp = np.abs(comp[:, ENERGY] / comp[0, ENERGY] - 1)
    assert e_plain[-1] > drift  # the drift is there to remove ...
    assert e_plain[-1] > 5 * e_plain[10]  # ... and grows along the run (10x for a linear drift)
    assert e_comp.max() < 1e-15 and e_comp.max() < e_plain[-1] / 20


def test_a_compensated_variant_is_a_carried_method():
    """It carries the low parts from step to step: one run after another (no block kernels), no step_driven
    (the driven loop carries (ω, q) only), so a driven body is refused by name; the plain method keeps both."""
    for method in ("lie_poisson4", "split6_exact"):
        module = get_method(method + COMPENSATED)
        assert module.BLOCKS is False and not hasattr(module, "run_blocks")
        assert not hasattr(module, "step_driven") and hasattr(module, "step_carried")
        assert hasattr(get_method(method), "step_driven")
        sc = build_scene("forced_body", 1.0, 0.0)
        with pytest.raises(ValueError, match="does not see time"):
            integrate(
                method + COMPENSATED, np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0]),
                np.full(1, 1e-3), np.full(1, 1), 2, 1e9,
            )  # fmt: skip


def test_the_parameter_names_its_choice_canonically():
    assert canonical_name("lie_poisson4(accumulate=COMPENSATED)")[0] == "lie_poisson4(accumulate=compensated)"
    assert canonical_name("split6_exact(accumulate=plain)") == ("split6_exact", {"accumulate": 0})
    assert canonical_name("lie_poisson4(axes=S-M-L,accumulate=compensated)")[1] == {
        "axes": (3, 4, 5),
        "accumulate": 1,
    }
    with pytest.raises(ValueError, match="not one of plain, compensated"):
        canonical_name("lie_poisson4(accumulate=kahan)")


def test_the_shears_are_a_rotation_to_eps_squared():
    """The three shears (t, s + sl, t) turn L exactly when (s + sl)(1 + t²) = 2t, and the ω shears when
    kx (ky + kyl) = 1: with the rounded pair alone each misses by ~eps, the same on every step where the
    pair is (a symmetric body's ω3 is conserved), which drifts the energy linearly
    (benchmarks/compensated_bias.py shear_pair).  Checked in exact rationals on random angles and ratios."""
    from fractions import Fraction

    from gyrolab.kernels.compensated import _reciprocal_low, _sin_low, _two_prod
    from gyrolab.kernels.rotation import half_angle

    rng = np.random.default_rng(3)
    for a, b in (rng.standard_normal((300, 2)) * 10 ** rng.uniform(-100, 100, (300, 2))).tolist():
        p, e = _two_prod(a, b)  # the low parts' exact products
        assert p == a * b and Fraction(a) * Fraction(b) == Fraction(p) + Fraction(e)
    worst_pair = worst_closed = worst_k = worst_k_closed = 0.0
    for phi in np.concatenate([rng.uniform(-3, 3, 300), 10 ** rng.uniform(-9, 0, 300)]):
        ch, sh = half_angle(phi)
        t, s = sh / ch, 2.0 * sh * ch
        two_t = 2 * Fraction(t)
        sl = _sin_low(t, s, ch * ch)
        worst_pair = max(worst_pair, abs(float((Fraction(s) * (1 + Fraction(t) ** 2) - two_t) / two_t)))
        miss = ((Fraction(s) + Fraction(sl)) * (1 + Fraction(t) ** 2) - two_t) / two_t
        worst_closed = max(worst_closed, abs(float(miss)))
    for kx in 10 ** rng.uniform(-3, 3, 300):
        ky, kyl = _reciprocal_low(kx)
        assert ky == 1.0 / kx
        worst_k = max(worst_k, abs(float(Fraction(kx) * Fraction(ky) - 1)))
        worst_k_closed = max(worst_k_closed, abs(float(Fraction(kx) * (Fraction(ky) + Fraction(kyl)) - 1)))
    assert 1e-17 < worst_pair < 1e-15 and 1e-17 < worst_k < 1e-15  # the misses the low parts close
    assert worst_closed < 1e-30 and worst_k_closed < 1e-30, (worst_closed, worst_k_closed)


def test_the_symmetric_turn_adds_the_whole_increment_and_turns_omega_by_the_same_angle():
    """A symmetric body's turn (kernels/compensated._turn_whole) adds (q + ql) ⊗ p with the product's rounding
    error: hi + lo after it is the exact sum to the compensated sum's one rounding (~eps of the increment),
    where q's high part times p, rounded, misses ql ⊗ p and the product's rounding; and _turn_matched turns
    ω⊥ + its low part by the angle of the body's turn about e3, (1 + α2, sh e3), to ~eps² of ω⊥, where
    t = sh/ch alone is another angle by ~eps.  Checked in exact rationals on random turns."""
    from fractions import Fraction

    from gyrolab.kernels.compensated import (
        _add4,
        _minus_one,
        _turn_matched,
        _turn_whole,
        quat_mul_low,
    )
    from gyrolab.kernels.rotation import half_angle, quat_from_rotvec, quat_mul

    def exact_mul(p, q):
        pa, pb, pc, pd = (Fraction(x) for x in p)
        qa, qb, qc, qd = (Fraction(x) for x in q)
        return (
            pa * qa - pb * qb - pc * qc - pd * qd,
            pa * qb + pb * qa + pc * qd - pd * qc,
            pa * qc - pb * qd + pc * qa + pd * qb,
            pa * qd + pb * qc - pc * qb + pd * qa,
        )

    rng = np.random.default_rng(5)
    worst_low = worst_whole = worst_old = 0.0
    for _ in range(200):
        q = rng.standard_normal(4)
        q = tuple(q / np.linalg.norm(q))
        ql = tuple(rng.uniform(-0.5, 0.5, 4) * np.spacing(np.abs(q)))
        a, u0, u1, u2 = quat_from_rotvec(*rng.uniform(-0.3, 0.3, 3))
        p = (_minus_one(a, u0, u1, u2), u0, u1, u2)
        exact = exact_mul(q, p)
        d, e = quat_mul(q, p), quat_mul_low(q, p)
        worst_low = max(worst_low, max(abs(float(x - Fraction(y) - Fraction(z))) for x, y, z in zip(exact, d, e)))
        whole = [Fraction(x) + Fraction(y) for x, y in zip(q, ql)]
        target = [w + x for w, x in zip(whole, exact_mul(whole, p))]
        new = _turn_whole(q, ql, p)
        old = _add4(q, ql, d)
        worst_whole = max(
            worst_whole, max(abs(float(Fraction(h) + Fraction(lo) - t)) for h, lo, t in zip(*new, target))
        )
        worst_old = max(worst_old, max(abs(float(Fraction(h) + Fraction(lo) - t)) for h, lo, t in zip(*old, target)))
    eps = np.finfo(float).eps
    assert worst_low < 1e-31  # quat_mul + quat_mul_low is the product to ~eps² (|q ⊗ p| < 0.2)
    assert worst_whole < eps * 0.2 and worst_old > 2 * worst_whole, (worst_whole, worst_old)

    worst_matched = worst_ratio = 0.0
    for phi in rng.uniform(-0.8, 0.8, 300):
        ch, sh = half_angle(phi)
        al2 = _minus_one(ch, 0.0, 0.0, sh)
        tangent = Fraction(sh) / (1 + Fraction(al2))  # tan of half the body's turn about e3
        x, y = rng.standard_normal(2)
        xl, yl = rng.uniform(-0.5, 0.5, 2) * np.spacing(np.abs((x, y)))
        xs, xsl, ys, ysl = _turn_matched(x, xl, y, yl, sh, al2)
        assert abs(xsl) <= 0.5 * np.spacing(abs(xs)) and abs(ysl) <= 0.5 * np.spacing(abs(ys))
        # the exact turn of (x + xl, y + yl) by −2 atan(tangent): cos and sin of it from the tangent, rationally
        c2 = 1 / (1 + tangent**2)
        co, si = (1 - tangent**2) * c2, 2 * tangent * c2
        x, y = Fraction(x) + Fraction(xl), Fraction(y) + Fraction(yl)
        rx, ry = co * x + si * y, co * y - si * x
        miss = max(abs(float(Fraction(xs) + Fraction(xsl) - rx)), abs(float(Fraction(ys) + Fraction(ysl) - ry)))
        worst_matched = max(worst_matched, miss / float(max(abs(x), abs(y))))
        worst_ratio = max(worst_ratio, abs(float((Fraction(sh) / Fraction(ch)) / tangent - 1)))
    assert worst_matched < 4 * eps**2, worst_matched  # no rounding of eps left, of the constants or the products
    assert 1e-17 < worst_ratio  # t = sh/ch turns by another angle, ~eps of it
