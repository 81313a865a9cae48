"""The axis order of the free-body splitting (issue 24, item 2): kernels.free_flow.axis_splitting in all
six orders, and the study of analysis/reports/splitting_order.py."""

import itertools
import math

import numpy as np
import pytest

from gyrolab.analysis.reports import splitting_order as so
from gyrolab.kernels.body import Body
from gyrolab.kernels.euler_poinsot import free_body
from gyrolab.kernels.free_flow import axis_splitting, free_flow

BODY = Body(1.0, 0.7, 0.4, 0.0)  # sorted: axes 0, 1, 2 are L, M, S
W0 = (0.4, -0.9, 1.3)  # rad/s


def _orientation_error(order, h, t_end=4.0):
    steps = int(round(t_end / h))
    _, w, q = so._run(W0, (1.0, 0.0, 0.0, 0.0), h, steps, 1, BODY, order)
    _, q_exact = free_body(np.array(BODY[:3]), np.array(W0), np.array([1.0, 0, 0, 0]), np.array([t_end]))
    return so._angle(q_exact[0], np.array(q))


@pytest.mark.parametrize("order", so.ORDERS, ids=so.order_name)
def test_every_axis_order_is_second_order_against_the_exact_flow(order):
    """Halving h divides the orientation error at 4 s by 4 (measured 3.9998–4.0002); the errors differ
    between orders (checked in the next test), the order does not."""
    e1, e2 = _orientation_error(order, 0.02), _orientation_error(order, 0.01)
    assert 3.8 < e1 / e2 < 4.2, (e1, e2)


def test_the_orders_are_different_maps_and_free_flow_is_1_2_3_2_1():
    """free_flow on an asymmetric body is the (0, 1, 2) order bit for bit; the six orders give six
    different states after one step (so the study compares six maps, not one)."""
    q0 = (1.0, 0.0, 0.0, 0.0)
    assert free_flow(W0, q0, 0.05, BODY) == axis_splitting(W0, q0, 0.05, BODY, (0, 1, 2))
    states = {axis_splitting(W0, q0, 0.05, BODY, order) for order in so.ORDERS}
    assert len(states) == 6


@pytest.mark.parametrize("order", so.ORDERS, ids=so.order_name)
def test_every_order_keeps_the_body_angular_momentum_norm_and_bounds_the_energy(order):
    """Each axis rotation turns L_b rigidly, so |L| is kept to rounding (≤ 1e-13 over 5000 steps); the
    energy error stays small and bounded (symplectic: no drift between the two halves of the run)."""
    w, q = W0, (1.0, 0.0, 0.0, 0.0)
    L0 = np.linalg.norm(np.array(BODY[:3]) * W0)
    e_first, _, _ = so._run(w, q, 0.02, 2500, 1, BODY, order)
    _, w, q = so._run(w, q, 0.02, 2500, 1, BODY, order)
    e_second, w, _ = so._run(w, q, 0.02, 2500, 1, BODY, order)
    assert abs(np.linalg.norm(np.array(BODY[:3]) * w) - L0) <= 1e-13 * L0
    assert 0 < e_first < 1e-3
    # measured against the new start: the same size, no growth (measured second/first 0.97–1.46)
    assert e_second < 3 * e_first


def test_water_is_a_planar_body_on_the_triangle_edge():
    """SPC/E water: I_L = I_M + I_S (planar), I_M/I_L = 0.6925, I_S/I_L = 0.3075 from its geometry."""
    il, im, i_s = so.water_moments()
    assert il == 1.0 and il >= im >= i_s
    assert abs(im + i_s - 1.0) < 1e-12
    assert abs(im - 0.6925) < 5e-4 and abs(i_s - 0.3075) < 5e-4


def test_substeps_are_the_same_order_at_a_tenth_of_the_step():
    """NO_SQUISH's m rotor substeps on a free body: the error of a second-order map at h/m, 100× smaller
    for m = 10 (measured 99.8–100.1× in both errors at water)."""
    e1, o1 = so.body_errors(so.water_moments(), substeps=1, n_motions=4)
    e10, o10 = so.body_errors(so.water_moments(), substeps=10, n_motions=4)
    assert np.all((e1 / e10 > 90) & (e1 / e10 < 110)), e1 / e10
    assert np.all((o1 / o10 > 90) & (o1 / o10 < 110)), o1 / o10


def test_the_study_table_is_read_off_its_numbers():
    """A small study (3 lattice rows, 20 s, 4 motions): every body's best order has factor 1, each row
    of the tables names one of the six orders, and the conclusions quote the factors in the tables."""
    res = so.study(n=3, t_end=20.0, n_motions=4)
    f = so.factors(res["energy"])
    assert np.all(f >= 1.0) and np.all(f.min(axis=1) == 1.0)
    text = so.markdown(res)
    for order in so.ORDERS:
        assert f"| {so.order_name(order)} |" in text
    fw = so.factors(res["water_energy"])[0]
    lms = fw[so.ORDERS.index((0, 1, 2))]
    assert f"loses {lms:.3g}× with moments sorted increasing" in text
    assert res["points"].shape == (len(res["energy"]), 2)
    assert np.all(res["points"][:, 0] + res["points"][:, 1] >= 1.0)


def test_report_refuses_a_missing_directory_in_one_line(tmp_path, capsys):
    assert so.main(["-o", str(tmp_path / "no" / "splitting_order.md")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("splitting_order: error:") and "\n" not in err


def test_orders_are_named_by_moment_rank():
    assert so.order_name((0, 1, 2)) == "L-M-S" and so.order_name((2, 1, 0)) == "S-M-L"
    assert math.factorial(3) == len(set(map(so.order_name, so.ORDERS)))


def _cyclic(body, k):
    """The body with its axis labels turned cyclically by k (a rotation of the frame, not a reflection)."""
    idx = [(i + k) % 3 for i in range(3)]
    return Body(*[body[i] for i in idx], 0.0), idx


def test_lie_poisson_sorted_does_not_depend_on_how_the_axes_are_labelled():
    """The same free body labelled three ways (cyclic relabellings): lie_poisson_sorted's energy error over
    2000 steps is the same to rounding for all three, lie_poisson's differs with the labels (it turns
    1-2-3-2-1 in them); on labels sorted increasing the two are the same map bit for bit."""
    from gyrolab.kernels.registry import METHODS

    base = Body(1.0, 0.7, 0.4, 0.0)
    w0 = (0.4, -0.9, 1.3)
    errors = {"lie_poisson": [], "lie_poisson_sorted": []}
    for k in range(3):
        body, idx = _cyclic(base, k)
        w = tuple(w0[i] for i in idx)
        for name in errors:
            ww, q = w, (1.0, 0.0, 0.0, 0.0)
            e0 = sum(body[i] * ww[i] ** 2 for i in range(3))
            worst = 0.0
            for _ in range(2000):
                ww, q = METHODS[name].step(ww, q, 0.02, body)
                worst = max(worst, abs(sum(body[i] * ww[i] ** 2 for i in range(3)) - e0) / e0)
            errors[name].append(worst)
    s, lp = np.array(errors["lie_poisson_sorted"]), np.array(errors["lie_poisson"])
    assert s.max() / s.min() < 1 + 1e-6, s
    assert lp.max() / lp.min() > 1.5, lp
    ascending = Body(0.4, 0.7, 1.0, 0.0)
    w, q = (1.3, -0.9, 0.4), (1.0, 0.0, 0.0, 0.0)
    sorted_step, label_step = METHODS["lie_poisson_sorted"].step, METHODS["lie_poisson"].step
    assert sorted_step(w, q, 0.02, ascending) == label_step(w, q, 0.02, ascending)


def test_moment_sorted_order_sorts_every_labelling():
    """For each of the six labellings of three distinct moments the order is (smallest, middle, largest)."""
    from gyrolab.kernels.free_flow import moment_sorted_order

    for labels in itertools.permutations((1.0, 2.0, 3.0)):
        order = moment_sorted_order(Body(*labels, 0.0))
        assert [labels[k] for k in order] == [1.0, 2.0, 3.0], (labels, order)


def test_report_that_cannot_write_says_so_in_one_line(tmp_path, capsys, monkeypatch):
    """A write that fails after the study (here: the figure's file system refuses) is one line, exit 1,
    and leaves no Markdown behind."""

    def refuse(*args, **kwargs):
        raise OSError(28, "No space left on device")

    small_study = so.study
    monkeypatch.setattr(so, "study", lambda: small_study(n=2, t_end=2.0, n_motions=2))
    monkeypatch.setattr(so, "figure", refuse)
    out = tmp_path / "splitting_order.md"
    assert so.main(["-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("splitting_order: error: could not write") and "\n" not in err
    assert not out.exists()
