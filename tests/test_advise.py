"""gyrolab-advise (analysis/advice/advisor.py, cli.py, model.py, errors.py): bad input, the error
metrics against closed forms, the advice on three bodies that are not pinned scenes, and the error
model on held-out random bodies the calibration never saw (calibrate.py draws seed 1; these seed 2025)."""

import json
import math

import numpy as np
import pytest

from gyrolab.analysis.advice import advise, cli
from gyrolab.analysis.advice import calibrate as C
from gyrolab.analysis.advice import errors as E
from gyrolab.analysis.advice import model as M
from gyrolab.kernels.euler_poinsot import free_body

HELD_OUT_SEED = 2025


def test_attitude_is_rebuilt_from_the_samples():
    """R from (axis, γ, L) by Kabsch equals the quaternion's R along an exact free motion."""
    I, w = np.array([1.0, 2.0, 3.0]), np.array([0.3, 1.0, -0.4])
    t = np.linspace(0, 20, 50)
    ref, _ = E.reference_samples(E.body_row(I), w, E.Q0, t)
    _, q = free_body(I, w, E.Q0, t)
    R = E.attitude_from_samples(ref, I)
    assert np.max(np.abs(R - E.rotation_matrices(q))) < 1e-13


def test_errors_are_the_known_perturbation():
    """A run whose attitude is the exact one turned by 1e-4 rad about lab x reads 1e-4 rad; its ω, E, |L| unchanged."""
    I, w = np.array([1.0, 2.0, 3.0]), np.array([0.3, 1.0, -0.4])
    t = np.linspace(0, 10, 30)
    body = E.body_row(I)
    wt, q = free_body(I, w, E.Q0, t)
    a = 1e-4
    turn = np.array([math.cos(a / 2), math.sin(a / 2), 0.0, 0.0])
    a0, b0, c0, d0 = turn
    a1, b1, c1, d1 = np.moveaxis(q, -1, 0)
    q_turned = np.stack(  # turn * q (lab-frame rotation after the body's)
        [
            a0 * a1 - b0 * b1 - c0 * c1 - d0 * d1,
            a0 * b1 + b0 * a1 + c0 * d1 - d0 * c1,
            a0 * c1 - b0 * d1 + c0 * a1 + d0 * b1,
            a0 * d1 + b0 * c1 - c0 * b1 + d0 * a1,
        ],
        -1,
    )
    from gyrolab.kernels.reference import samples_from_states

    ref = samples_from_states(tuple(body), wt, E.rotation_matrices(q))
    run = samples_from_states(tuple(body), wt, E.rotation_matrices(q_turned))[None]
    assert E.run_errors(run, ref, body, w, "orientation")[0] == pytest.approx(a, rel=1e-6)
    assert E.run_errors(run, ref, body, w, "omega")[0] == 0.0
    assert E.run_errors(run, ref, body, w, "L_norm")[0] < 1e-15
    assert 0 < E.run_errors(run, ref, body, w, "L")[0] <= a * (1 + 1e-6)  # |ΔL| <= a |L|


@pytest.mark.parametrize(
    "argv, word",
    [
        (["1", "2", "-3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1"], "inertia"),
        (["1", "1", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1"], "triangle"),
        (["1", "2", "3", "--omega", "0", "0", "0", "--dt", "1e-3", "--T", "1"], "omega"),
        (["1", "2", "3", "--dt", "1e-3", "--T", "1"], "--omega"),
        (["1", "2", "3", "--omega-max", "-1", "--dt", "1e-3", "--T", "1"], "--omega-max"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "2", "--T", "1"], "dt"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt-range", "1e-2", "1e-3", "--T", "1"], "dt"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "nan"], "T="),
        (["1", "2", "3", "--omega", "1", "2", "3", "--budget", "0", "--T", "1"], "budget"),
        # a budget that buys less than one step: it advised dt = 601 s for T = 10 s
        (["1", "2", "3", "--omega", "1", "2", "3", "--budget", "1e-9", "--T", "10"], "less than one step"),
        # ω·Iω under- or overflows: SVD did not converge (a traceback), or inf
        (["1", "2", "3", "--omega", "1e-300", "0", "0", "--dt", "1e-2", "--T", "10"], "underflows"),
        (["1", "2", "3", "--omega", "1e200", "1", "1", "--dt", "1e-2", "--T", "10"], "overflows"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--metric", "spin"], "metric"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--tol", "0"], "tol"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--methods", "rk5"], "rk5"),
        (
            [
                "1",
                "2",
                "3",
                "--omega",
                "1",
                "2",
                "3",
                "--dt",
                "1e-3",
                "--T",
                "1",
                "--methods",
                "lie_poisson(axes=1-1-2)",
            ],
            "axis order",
        ),
        (
            ["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--methods", "no_squish(substeps=2)"],
            "no error constants",
        ),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--engines", "rk4"], "engine"),
        (["1", "2", "3", "--omega", "1", "2", "3", "--dt", "1e-3", "--T", "1", "--json", "/no/such/dir/a.json"], "dir"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_before_any_work(argv, word, capsys, monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("a run started on bad input")

    monkeypatch.setattr("gyrolab.kernels.batch.integrate", refuse)
    monkeypatch.setattr(M, "probe", refuse)
    monkeypatch.setattr(M, "growth_law", refuse)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and word in err, err


# The three bodies of issue 25 (none a pinned scene), each with the question its user would ask.
BODIES = {
    # a quadrotor's airframe at 30 rad/s (mostly yaw, with roll and pitch), a 1 kHz loop, 10 s
    "drone": dict(
        inertia=(0.0082, 0.0082, 0.0149),
        omega0=30 * np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0]),
        T=10.0,
        dt=1e-3,
        metric="orientation",
        tol=1e-6,
    ),
    # a satellite tumbling at 0.9 rad/s, propagated 1 h at a step of 1 ms to 0.1 s, attitude to 1e-4 rad
    "satellite": dict(
        inertia=(500.0, 200.0, 300.0),
        omega0=0.9 * np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8]),
        T=3600.0,
        dt_range=(1e-3, 0.1),
        metric="orientation",
        tol=1e-4,
    ),
    # water-like moments (1.0, 0.66, 0.34) x 1.9e-47 kg m² (H2O is ~ (1.0, 0.66, 0.34) x 1.9e-47), at
    # |ω| = 1e13 rad/s and dt = 5 fs (|ω| dt = 0.05), 20 ps, the energy to 1e-6
    "molecule": dict(
        inertia=tuple(1.9e-47 * np.array([1.0, 0.66, 0.34])),
        omega0=1e13 * np.array([0.4, 0.7, 0.6]) / np.linalg.norm([0.4, 0.7, 0.6]),
        T=2e-11,
        dt=5e-15,
        metric="energy",
        tol=1e-6,
    ),
}


# Whether the advice's measured error is within 2x of its prediction, as measured once (not tuned):
# measured/predicted 0.97 (drone, rk4), 0.98 (satellite, rk4 over 3240 rad), 0.99 (molecule).  See
# the README.
WITHIN_2X = {"drone": True, "satellite": True, "molecule": True}


@pytest.fixture(scope="module")
def compiled():
    """The advisor's kernels compiled (a short advice on the molecule), so that the prediction's time
    below is the prediction's, not numba's first compile (75 s on a cold cache)."""
    advise(**{**BODIES["molecule"], "T": 1e-12}, engines=())


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BODIES))
def test_advice_on_three_bodies(name, compiled):
    """The advice for each body: a method is recommended; the measured error of the recommendation (at
    the dt it advises) is within 2x of its prediction where the model holds (WITHIN_2X), and the
    advice after measuring meets the tolerance by measurement."""
    a = advise(**BODIES[name], engines=())
    print(f"\n{name}:\n" + "\n".join(cli.table(a)))
    assert a.recommended, "no method recommended"
    ratio = a.recommended_measured / a.recommended_predicted
    assert (0.5 <= ratio <= 2.0) == WITHIN_2X[name], ratio
    assert a.measured_advice and a.measured_advice_error <= a.tol
    assert a.seconds_predict < 30.0  # instant on an idle machine (~0.1 s per method once compiled)
    json.dumps(a.to_dict(), default=float)  # serialisable


def held_out(n=120):
    """Held-out free bodies (not the calibration's seed), each with one (h, τ) and one method."""
    I, w = C.draw_bodies(HELD_OUT_SEED, n)
    rng = np.random.default_rng(HELD_OUT_SEED + 1)
    h = 10 ** rng.uniform(-2, -1, n)
    tau = 10 ** rng.uniform(1, 2, n)
    methods = np.array(C.DEFAULT_METHODS)[np.arange(n) % len(C.DEFAULT_METHODS)]
    return I, w, h, tau, methods


@pytest.mark.slow
@pytest.mark.parametrize("metric", ["orientation", "energy"])
def test_predicted_error_on_held_out_bodies(metric):
    """120 held-out random bodies, one method each (the 3 default methods in turn), h = |ω|dt in
    [0.01, 0.1], τ = |ω|T in [10, 100]: the predicted error within 2x of the measured one.  Counted
    over the runs whose measured error is in the model's range (1e-12 .. 0.1: above rounding, below
    saturation).  Issue 25 asks for >= 90 %, which the model reaches (asserted, and printed)."""
    I, w, h, tau, methods = held_out()
    constants = M.load_constants()["methods"]
    wn = np.linalg.norm(w, axis=1)
    measured = np.full(len(wn), np.nan)
    predicted = np.full(len(wn), np.nan)
    for m in C.DEFAULT_METHODS:
        k = np.flatnonzero(methods == m)
        dt, stride, T = C.schedule(h[k], tau[k], wn[k])
        err, _ = C.measure(m, I[k], w[k], dt, stride, (metric,))
        c = constants[m]
        g, q = M.growth_law(m, I[k], w[k], T, c["order"])[metric]
        measured[k] = err[:, 0]
        rounding = M.rounding_floor(M.load_constants(), metric)
        predicted[k] = M.predicted_error(c["kappa"][metric], g, q, h[k], wn[k] * T, rounding)
    use = (measured > 1e-12) & (measured < M.SATURATED)
    ratio = predicted[use] / measured[use]
    within = np.mean((ratio >= 0.5) & (ratio <= 2.0))
    print(f"\n{metric}: {within:.0%} of {use.sum()} held-out runs within 2x")
    assert use.sum() >= 80
    assert within >= HELD_OUT_FLOOR[metric], f"{within:.0%} within 2x; ratios {np.sort(ratio)}"


# what the model reaches on the held-out set (measured after each of three model changes, never tuned
# on it: orientation 96 % of 119 since the wander is weighted point by point, 92 % before; energy 99 %
# of 118), issue 25's 90 %
HELD_OUT_FLOOR = {"orientation": 0.90, "energy": 0.90}


def test_a_budget_gives_each_method_the_dt_it_affords(tmp_path):
    """--budget: each method's smallest dt is the one its ns/step affords over T; the advice fits the
    budget; the figure is written (predicted curves only: no measurement here)."""
    I, w, T, budget = (1.0, 2.0, 3.0), (0.3, 1.0, -0.4), 100.0, 2e-3
    a = advise(I, w, T, budget=budget, tol=1e-6, measure=False, engines=())
    for r in a.rows:
        assert r.dt_user == pytest.approx(T * r.ns_per_step * 1e-9 / budget)
    assert a.recommended
    best = next(r for r in a.rows if r.method == a.recommended)
    assert best.cost_s <= budget * (1 + 1e-9) and best.predicted_at_largest <= a.tol
    cli.figure(a, tmp_path / "advice.png")
    assert (tmp_path / "advice.png").stat().st_size > 10_000


def test_constants_file_names_how_it_was_measured():
    data = M.load_constants()
    assert "calibrate" in data["how"]
    for m in C.DEFAULT_METHODS:
        entry = data["methods"][m]
        assert entry["ns_per_step"] > 0 and entry["order"] >= 1
        assert set(entry["kappa"]) >= {"orientation", "omega", "energy"}
        assert all(0 < k < 1e6 for k in entry["kappa"].values())


def test_the_methods_option_keeps_a_variants_commas():
    from gyrolab.kernels.parameters import split_names

    assert split_names("rk4, no_squish(axes=S-M-L,substeps=10),lie_poisson(axes=3-2-1)") == [
        "rk4",
        "no_squish(axes=S-M-L,substeps=10)",
        "lie_poisson(axes=3-2-1)",
    ]
    assert split_names("rk4,no_squish(substeps=0") == ["rk4", "no_squish(substeps=0"]


def test_a_variant_is_predicted_by_its_own_steps_on_the_users_body():
    """A calibrated method's variant (kernels/parameters.py) is advised like the method: predicted by its
    own steps on this body (model.probe) with the method's calibrated constants, then measured.  On
    SPC/E-like water labelled with the moments decreasing, lie_poisson turns L-M-S; the order S-M-L is
    predicted and measured ~40x better in energy (measured 1.38e-06 against 5.42e-05 at dt = 0.02 s over
    100 s, each within 2 % of its prediction), and is the advice."""
    a = advise(
        (1.0, 0.6925, 0.3075),
        (1.2, -0.7, 0.9),
        100.0,
        dt=0.02,
        metric="energy",
        tol=1e-5,
        methods=["lie_poisson", "lie_poisson(axes=s-m-l)"],
        engines=(),
    )
    rows = {r.method: r for r in a.rows}
    assert set(rows) == {"lie_poisson", "lie_poisson(axes=S-M-L)"}  # canonical names
    plain, sorted_ = rows["lie_poisson"], rows["lie_poisson(axes=S-M-L)"]
    assert sorted_.constants_of == "lie_poisson" and plain.constants_of == ""
    assert sorted_.measured_at_user < plain.measured_at_user / 10
    for r in (plain, sorted_):
        assert abs(r.measured_at_user / r.predicted_at_user - 1) < 0.1, r
    assert a.recommended == "lie_poisson(axes=S-M-L)" and not plain.meets


# A spin near the intermediate axis (the Dzhanibekov flip): I = (2, 3, 5) kg m², ω0 = (f, 10, f) rad/s,
# dt = 2 ms over 20 s.  f = 0.3, 0.03, 0.01 put the orbit 2.0e-3, 2.0e-5, 2.2e-6 (relative) from the
# separatrix.  Measured/predicted orientation error at these before the wander was weighted point by
# point: lie_poisson 11, 0.033, 0.0048; lie_poisson4 0.10, 0.0039, 0.00063.
NEAR_SEPARATRIX_BODY = dict(inertia=(2.0, 3.0, 5.0), T=20.0, dt=2e-3, engines=())


@pytest.mark.parametrize(
    "f, methods", [(0.3, C.DEFAULT_METHODS), (0.03, C.DEFAULT_METHODS), (0.01, ("lie_poisson", "lie_poisson4"))]
)
def test_near_the_separatrix_the_orientation_error_is_predicted(f, methods):
    """The symplectic methods' bounded energy error moves the body to a nearby orbit by an amount that
    comes and goes; near the separatrix it matters only during the slow passage by the intermediate
    axis, where the period's sensitivity lives (model.probe's local rates).  Within 2x down to 2e-6 of
    the separatrix for them, to 2e-5 for rk4 (whose energy drifts: measured/predicted 0.18 at 2.2e-6)."""
    a = advise(omega0=(f, 10.0, f), methods=methods, **NEAR_SEPARATRIX_BODY)
    assert a.separatrix_distance < 3e-3
    for r in a.rows:
        assert 0.5 <= r.measured_at_user / r.predicted_at_user <= 2.0, (f, r.method, r)


def test_on_the_separatrix_the_advice_says_so_and_measures():
    """Closer than advisor.NEAR_SEPARATRIX the prediction is off (here 2e-10: lie_poisson predicted ~1e3x
    its measured error, rk4 ~1/50) and the table says that the measurement decides, with the axis's
    instability rate; a method predicted to miss that is measured to meet is advised on the measurement."""
    a = advise(omega0=(1e-4, 10.0, 1e-4), tol=1e-2, **NEAR_SEPARATRIX_BODY)
    assert 0 < a.separatrix_distance < 1e-9
    # λ = Ω √((I2 − I1)(I3 − I2) / (I1 I3)) at Ω = |L| / I2 = 10 rad/s: √(2/10) · 10
    assert a.intermediate_axis_rate == pytest.approx(10 * math.sqrt(0.2), rel=1e-6)
    text = "\n".join(cli.table(a))
    assert "from the separatrix" in text and "the measurement decides" in text and "e-fold every 0.224 s" in text
    lp = next(r for r in a.rows if r.method == "lie_poisson")
    assert lp.predicted_at_user > 10 * lp.measured_at_user  # the model's miss this close in
    assert a.measured_advice and a.measured_advice_error <= a.tol
    for r in a.rows:
        if r.met_by_measurement:
            assert r.measured_at_user <= a.tol and not r.predicted_at_user <= a.tol and "yes*" in text


def test_a_spin_exactly_about_the_intermediate_axis_is_a_steady_spin():
    """ω0 along the intermediate axis: every method and the exact flow keep it (ω × Iω = 0), so the
    errors are the attitude kinematics' alone, and no engine update moves the energy.  The orbit's closed
    form would be the separatrix (k² = 1); it used to be taken as the flipping orbit at k² = 1 − 1e-15,
    whose points (scipy's ellipj past u = K) reached |m| = 1e15 |L|: predicted errors of 1e9 rad and a
    MuJoCo blow-up at step 1e-60."""
    a = advise((1.0, 2.0, 3.0), (0.0, 5.0, 0.0), 10.0, dt=0.01)
    assert a.separatrix_distance == 0.0
    for r in a.rows:
        assert r.measured_at_user < 1e-6 and r.predicted_at_user < 1e-6, r
    rk4 = next(r for r in a.rows if r.method == "rk4")
    assert rk4.measured_at_user / rk4.predicted_at_user == pytest.approx(1.0, rel=0.1)
    for e in a.engines:
        assert math.isinf(e.blow_up_step) and e.energy_drift_per_s == 0.0, e
    text = "\n".join(cli.table(a))
    assert "on the separatrix: a spin about the intermediate axis" in text and "e-fold every 0.346 s" in text
