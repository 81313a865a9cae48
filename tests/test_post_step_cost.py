"""The dry run's time models of the post-steps: the figure step (analysis/figures/cost.py) and the verdict
study's callback (analysis/verdicts/cost.py).  Their coefficients are fitted by
benchmarks/bench_post_steps.py; here, what they count."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrolab.analysis.figures.cost import COSTS, figure_seconds, figure_step_seconds, runs_drawn
from gyrolab.analysis.figures.registry import DEFAULT, FIGURES
from gyrolab.analysis.verdicts.cost import bisection_seconds, bisection_trials, verdict_seconds


def test_every_figure_kind_has_one_cost():
    assert set(COSTS) == set(FIGURES)


def test_runs_drawn_follow_the_figures_selection():
    assert runs_drawn("tip", (5, 3, 1, 3)) == 3  # one method and dt, a panel per f
    assert runs_drawn("energy", (20, 1, 1, 1)) == 20  # every method drawn
    assert runs_drawn("energy", (5, 100, 5, 4)) == 5 * 3 * 9  # at most 3 dt and 9 f x theta0 panels
    assert runs_drawn("stability", (4, 100, 5, 4)) == 4 * 100 * 4  # every f and dt of one theta0


def test_figure_time_grows_with_the_samples_and_the_step_sums_its_figures():
    small, big = figure_seconds("nutation", (5, 3, 1, 3), 1001), figure_seconds("nutation", (5, 3, 1, 3), 10001)
    assert 0 < small < big
    each, total = figure_step_seconds(DEFAULT, (5, 3, 1, 3), 10001)
    assert set(each) == set(DEFAULT) and total > sum(each.values())  # + importing matplotlib once
    assert figure_step_seconds((), (5, 3, 1, 3), 10001) == ({}, 0.0)


def test_the_bisection_replayed_tries_the_ends_then_closes_on_the_threshold():
    omega, t_end = 314.0, 10.0
    calls = bisection_trials(omega, t_end, crit=1.0)
    lo_steps = 64 * np.ceil(t_end / 64 / (1e-3 / omega))
    assert list(calls[0]) == [lo_steps, 64 * np.ceil(t_end / 64 / (10.0 / omega))]  # the bracket's ends
    assert all(len(c) == 4 for c in calls[1:])  # batches of 4 trial steps (2 threads)
    # the last trials sit at the threshold, |w| dt = 1 rad: t_end * omega steps, within the sampling stride
    assert calls[-1] == pytest.approx(t_end * omega, rel=0.03)


def _grid(scene, methods, omega=314.0, driven=False):
    return SimpleNamespace(
        scene=scene,
        methods=tuple(methods),
        n_runs=len(methods),
        n_samples=2,
        driven=driven,
        inputs=lambda runs: (None, np.array([[0.0, 0.0, omega]])),
    )


def test_the_verdict_bisects_once_per_scene_and_method_at_the_given_rate():
    def rate(method, n_runs, driven):
        return 1e7

    ladder, long = _grid("heavy_top", ["rk4", "seed_next"]), _grid("heavy_top", ["rk4", "seed_next"])
    one = bisection_seconds("rk4", 314.0, 10.0, rate)
    both = verdict_seconds([ladder, long], 10.0, rate)["bisection"]
    assert both == pytest.approx(2 * one)  # the long run's methods were bisected with the ladder's
    assert verdict_seconds([ladder], 10.0, lambda m, n, d: 5e6)["bisection"] == pytest.approx(4 * one)
    assert verdict_seconds([ladder], None, rate)["bisection"] == 0.0  # no stability: no bisection
    other = _grid("free_asymmetric", ["rk4"])
    assert verdict_seconds([ladder, other], 10.0, rate)["bisection"] == pytest.approx(3 * one)
