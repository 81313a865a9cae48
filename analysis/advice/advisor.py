"""gyrolab-advise: which update, at which step, at what cost, for the user's own body — predicted, then measured.

``advise(...)`` (and the command ``gyrolab-advise``) takes a body (moments, optionally the weight's
moment M g c; or a pinned scene), its initial spin, a time step (one dt, a range, or a wall-clock
budget), the horizon T and what must be right to what tolerance.  It

1. predicts, instantly: each method's error on this body from its declared order and the constants
   measured once by calibrate.py (model.py), the largest dt that keeps it within the tolerance and
   the cost (the steps times the method's measured ns per step); and, from predict.py, what each
   engine update does to this body (blow-up step, energy drift per second, flips lost);
2. measures, in a short run of each method on this body at the user's dt and at the dt it advises,
   against the exact free flow (or DOP853 for a heavy body);
3. answers: the cheapest method that meets the tolerance, the prediction beside the measurement.

Units: I kg m², ω rad/s (body frame), M g c N m (body frame), dt and T s.
"""

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from . import errors as E
from . import model
from .calibrate import DEFAULT_METHODS

ENGINES = ("mujoco_euler", "bullet_explicit", "mujoco_implicit", "jolt_rescale_bare", "rapier_rescale")
N_SAMPLES = 201  # samples per measured run
MAX_STEPS = 2_000_000  # steps per measured run; a longer horizon is measured over its start
MAX_H = 0.5  # largest Ω dt the advisor considers (the asymptotic model is for small steps)
# A free body whose orbit is closer than this to the separatrix (relative, predict.separatrix_distance)
# flips after a time that hangs on the distance; model.py's orientation and ω errors are within ~2x of
# the measured down to 1e-4 and drift off closer in, by 10x-1e4x either way at 1e-8 to 1e-12 (measured:
# tests/test_advise.py::test_near_the_separatrix_the_orientation_error_is_predicted and
# ::test_on_the_separatrix_the_advice_says_so_and_measures): the advice says so and rests on the measurement
NEAR_SEPARATRIX = 1e-4
ENGINE_STEPS = 200_000  # engine runs measured up to this many steps
ENGINE_SAMPLES = 20_001  # samples of a measured engine run (its flips are counted on them)


class AdviceError(ValueError):
    """Bad input to the advisor (one line, said before any work)."""


@dataclass
class MethodRow:
    """One method on the user's body: errors (the metric's units, dimensionless) and costs."""

    method: str
    order: int
    symplectic: bool
    ns_per_step: float
    dt_user: float  # s: the user's dt (the range's upper end; for a budget, the dt it affords)
    predicted_at_user: float
    measured_at_user: float = math.nan
    dt_largest: float = 0.0  # s: the largest dt within [lo, hi] predicted to meet the tolerance (0: none)
    predicted_at_largest: float = math.nan
    measured_at_largest: float = math.nan
    cost_s: float = math.inf  # predicted wall time (s) of the horizon at dt_largest
    meets: bool = False  # predicted (or, failing that, measured at dt_user) to meet the tolerance within the dt bounds
    met_by_measurement: bool = False  # predicted to miss at dt_user, measured to meet there
    measured_over_s: float = math.nan  # the measured runs' horizon (s; < T when T needs > MAX_STEPS steps)
    dt_corrected: float = math.nan  # s: the dt from the measured error when the advised dt missed
    measured_at_corrected: float = math.nan
    growth: float = 0.0  # κ g: the predicted error over T at Ω dt = model.H_PROBE, before rounding
    exponent: float = 0.0  # q: the predicted error goes as (Ω dt)^q (model.growth_law)
    free_exact: bool = False  # the method's step is the exact free flow (error: rounding)
    constants_of: str = ""  # a variant (kernels/parameters.py): the method whose calibrated constants it uses


def calibrated_name(method):
    """The name whose calibrated constants (calibrate.py) predict ``method``: the method itself, or for a
    variant with parameters (``lie_poisson(axes=S-M-L)``) the method it is a variant of.  The prediction
    then runs the variant's own steps (model.probe: its defects on this body) and takes only the
    calibrated factor κ, the ns per step and the order from the method; the measurement decides."""
    from ...kernels.parameters import split_name

    return split_name(method)[0]


@dataclass
class EngineRow:
    """What an engine update does to this free body at the user's dt (predict.py; measured where run)."""

    method: str
    kind: str
    blow_up_step: float
    blow_up_step_measured: float
    energy_drift_per_s: float  # (dE/dt) / E0 at the start (1/s)
    relaxation: str
    flips_exact: float  # flips of the exact motion in T
    flips_lost: float  # exact flips minus the engine's predicted flips in T
    flips_lost_measured: float = math.nan  # exact flips minus the engine's measured flips in T (NaN: not measured)


@dataclass
class Advice:
    """The advisor's answer; ``rows`` per method, ``engines`` per engine update, ``recommended``."""

    inertia: list
    mgc: list
    omega0: list
    T: float
    metric: str
    tol: float
    dt_bounds: list  # [lo, hi] s
    h: float  # |ω0| dt at the upper bound
    tau: float  # |ω0| T
    shape: dict
    reference: str
    prediction_note: str
    rows: list = field(default_factory=list)
    engines: list = field(default_factory=list)
    recommended: str = ""
    recommended_dt: float = math.nan
    recommended_predicted: float = math.nan
    recommended_measured: float = math.nan
    rounding_per_step: float = 0.0  # the rounding floor's error per step in the metric
    measured_advice: str = ""  # the cheapest method whose measured error meets the tolerance
    measured_advice_dt: float = math.nan
    measured_advice_error: float = math.nan
    seconds_predict: float = 0.0
    seconds_measure: float = 0.0
    separatrix_distance: float = math.nan  # free body: predict.separatrix_distance (NaN: heavy or symmetric body)
    intermediate_axis_rate: float = math.nan  # 1/s: e-folding rate of a perturbation of a spin about the middle axis

    def to_dict(self):
        return asdict(self)


def _omega_scale(body, omega0):
    """Ω (rad/s): |ω0|, plus the pendulum rate √(|M g c| / I_min) of a heavy body's weight."""
    return float(np.linalg.norm(omega0)) + math.sqrt(float(np.linalg.norm(body[3:6])) / float(min(body[:3])))


def check_inputs(inertia, omega0, mgc, T, dt_bounds, budget, metric, tol, methods, engines):
    """AdviceError (one line) for the first bad input; nothing is run."""
    from ...kernels.registry import canonical_name
    from .predict import KINDS

    I = np.asarray(inertia, float)
    if I.shape != (3,) or not np.all(np.isfinite(I)) or np.any(I <= 0):
        raise AdviceError(f"inertia={np.ravel(inertia).tolist()}: three finite moments > 0 (kg m^2)")
    if np.any(2 * I > I.sum() * (1 + 1e-12)):  # I_i <= I_j + I_k
        raise AdviceError(f"inertia={I.tolist()}: violates the triangle inequality (no rigid body has these moments)")
    w = np.asarray(omega0, float)
    if w.shape != (3,) or not np.all(np.isfinite(w)) or not np.any(w):
        raise AdviceError(f"omega={np.ravel(omega0).tolist()}: three finite body rates, not all zero (rad/s)")
    with np.errstate(over="ignore", under="ignore"):
        kinetic = 0.5 * float(np.dot(I * w, w))
    if not (0 < kinetic < math.inf):  # 1e-300 rad/s: ω·Iω underflows to 0 and the orbit's constants are 0/0
        where = "underflows to 0" if kinetic == 0 else "overflows"
        raise AdviceError(f"omega={w.tolist()}: ½ ω·Iω {where} in double precision (J); rescale the body's units")
    c = np.asarray(mgc, float)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise AdviceError(f"mgc={np.ravel(mgc).tolist()}: three finite values (N m)")
    if not (math.isfinite(T) and T > 0):
        raise AdviceError(f"T={T}: the horizon must be finite and > 0 s")
    if budget is not None:
        if not (math.isfinite(budget) and budget > 0):
            raise AdviceError(f"budget={budget}: the wall-clock budget must be finite and > 0 s")
    else:
        lo, hi = dt_bounds
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
            if lo == hi:
                raise AdviceError(f"dt={lo}: the time step must be finite and > 0 s")
            raise AdviceError(f"dt-range=({lo}, {hi}): need 0 < LO <= HI, finite (s)")
        if hi > T:
            raise AdviceError(f"dt={hi}: larger than the horizon T={T} s")
    if metric not in E.METRICS:
        raise AdviceError(f"metric={metric!r}: choose from {', '.join(E.METRICS)}")
    if metric == "kovalevskaya" and c[0] == 0:
        raise AdviceError("metric=kovalevskaya: needs a weight off the symmetry axis (M g c1 != 0)")
    if not (math.isfinite(tol) and 0 < tol < 1):
        raise AdviceError(f"tol={tol}: the tolerance must lie in (0, 1) (relative; rad for orientation)")
    constants = model.load_constants()["methods"]
    for m in methods:
        try:
            canonical_name(m)
        except ValueError as err:
            raise AdviceError(f"method {m!r}: {err}; calibrated: {', '.join(constants)}") from None
        base = calibrated_name(m)
        if base not in constants or not (metric in constants[base]["kappa"] or constants[base].get("free_exact")):
            raise AdviceError(
                f"method {m!r}: no error constants for {metric!r}; calibrated: {', '.join(constants)} "
                "(and their variants, e.g. lie_poisson(axes=S-M-L))"
            )
    for m in engines:
        if m not in KINDS:
            raise AdviceError(f"engine {m!r}: not predicted; choose from {', '.join(KINDS)}")
    if not methods:
        raise AdviceError("methods: give at least one")
    if budget is not None:  # the budget must buy one step of each method: its dt at most T
        ns, costly = max((float(constants[calibrated_name(m)]["ns_per_step"]), m) for m in methods)
        if budget < ns * 1e-9:
            raise AdviceError(
                f"budget={budget:g} s: buys less than one step of {costly} ({ns:.3g} ns a step); "
                f"give at least {ns * 1e-9:.3g} s"
            )


def _aligned_schedule(dt, T):
    """(dt', stride, n_steps): a run of about T s at dt' ≤ dt, sampled N_SAMPLES times, at most MAX_STEPS steps."""
    steps = max(N_SAMPLES - 1, int(math.ceil(T / dt)))
    steps = min(steps, MAX_STEPS)
    stride = max(1, steps // (N_SAMPLES - 1))
    steps = stride * (N_SAMPLES - 1)
    return dt, stride, steps


def _measure(method, body, omega0, q0, dts, T, metric):
    """Measured errors of ``method`` at each dt of ``dts`` (one ``integrate`` call) and the horizon (s)."""
    from ...kernels.batch import integrate

    plans = [_aligned_schedule(dt, T) for dt in dts]
    n = len(dts)
    out, _, _ = integrate(
        method,
        np.tile(body, (n, 1)),
        np.tile(omega0, (n, 1)),
        np.tile(q0, (n, 1)),
        np.array([p[0] for p in plans]),
        np.array([p[1] for p in plans]),
        N_SAMPLES,
        threshold=1e300,
        path="blocks",
    )
    errs, horizon = [], []
    for k, (dt, stride, steps) in enumerate(plans):
        t = np.arange(N_SAMPLES) * stride * dt
        ref, name = E.reference_samples(body, omega0, q0, t)
        errs.append(float(E.run_errors(out[k : k + 1], ref, body, omega0, metric)[0]))
        horizon.append(steps * dt)
    return errs, horizon, name


def _flips(pred, I, dt, T):
    """Flips (sign changes of the intermediate momentum) in T along the predictor's slow trajectory."""
    from .predict import orbit_points, orbit_state  # noqa: F401 (orbit_state documents the invariants)

    I = np.asarray(I, float)
    Is = np.sort(I)
    t = pred.n_steps * dt
    stop = min(T, pred.blow_up_step * dt)
    G2, twoT = pred.G2, 2 * pred.energy
    s = twoT * Is[1] - G2  # > 0: orbit about the smallest moment
    pole = np.where(s > 0, 0, 2)
    delta = np.abs(twoT * Is[pole] - G2)
    B = len(t)
    _, period = orbit_points(np.tile(Is, (B, 1)), G2, delta, pole, np.ones(B), n=1)
    rate = np.where(np.isfinite(period) & (period > 0), 2.0 / period, 0.0)  # flips per s
    grid = np.linspace(0.0, stop, 400) if stop > 0 else np.zeros(1)
    return float(np.trapezoid(np.interp(grid, t, rate), grid)) if stop > 0 else 0.0


def _engine_rows(engines, body, omega0, dt, T, measure, progress):
    """EngineRow per engine update (predict.py), measured blow-up when ``measure``."""
    from ...kernels.euler_poinsot import flip_period
    from .predict import measure_blow_up, predict

    I = body[:3]
    steps = T / dt
    fp = float(flip_period(I, omega0))
    exact = T / fp if math.isfinite(fp) and fp > 0 else 0.0
    rows = []
    for k, m in enumerate(engines):
        if progress:
            progress(f"engine {m} ({k + 1}/{len(engines)})")
        p = predict(m, I, omega0, dt, n_max=max(steps, 1.0))
        blown = flips_measured = math.nan
        if measure:
            blown, _, run, flips_measured = measure_blow_up(
                m, I, omega0, dt, min(steps, ENGINE_STEPS), n_samples=ENGINE_SAMPLES
            )
            if run < 0.999 * steps:  # measured over the start of T only (ENGINE_STEPS): no count for T
                flips_measured = math.nan
        flips = _flips(p, I, dt, T) if exact >= 1 else 0.0
        relax = ""
        if p.relaxes_to:
            relax = f"{p.relaxation_time:.3g} s to {p.relaxes_to}" if math.isfinite(p.relaxation_time) else ""
        lost = exact - flips if exact >= 1 else 0.0
        row = EngineRow(m, p.kind, p.blow_up_step, blown, p.energy_rate_relative, relax, exact, lost)
        if exact >= 1:
            row.flips_lost_measured = exact - flips_measured
        rows.append(row)
    return rows


def advise(
    inertia,
    omega0,
    T,
    *,
    dt=None,
    dt_range=None,
    budget=None,
    metric="orientation",
    tol=1e-3,
    mgc=(0.0, 0.0, 0.0),
    q0=None,
    methods=DEFAULT_METHODS,
    engines=ENGINES,
    measure=True,
    progress=None,
):
    """Advice for a body with moments ``inertia`` (3,) kg m², weight moment ``mgc`` = M g c (3,) N m
    (body frame; zero: a free body), from body rates ``omega0`` (3,) rad/s and attitude ``q0`` (scalar
    first; default errors.Q0), over T s, keeping ``metric`` (errors.METRICS) within ``tol``.

    Exactly one of ``dt`` (s), ``dt_range`` (lo, hi) s or ``budget`` (wall-clock s for the horizon)
    bounds the step.  ``measure=False`` returns the prediction only.  ``progress(str)`` is called
    before each run.  AdviceError (one line) on bad input, before any work.  Returns ``Advice``."""
    given = [x is not None for x in (dt, dt_range, budget)]
    if sum(given) != 1:
        raise AdviceError("give exactly one of dt, dt_range, budget")
    if dt is not None:
        dt_bounds = (float(dt), float(dt))
    elif dt_range is not None:
        dt_bounds = tuple(float(v) for v in dt_range)
        if len(dt_bounds) != 2:
            raise AdviceError(f"dt_range={dt_range}: two values lo hi (s)")
    else:
        dt_bounds = (math.nan, math.nan)
    methods, engines = list(methods), list(engines)
    check_inputs(inertia, omega0, mgc, float(T), dt_bounds, budget, metric, float(tol), methods, engines)
    from ...kernels.registry import select_methods

    methods = select_methods(methods)  # canonical names, each once (a variant at its defaults is the method)
    t_start = time.perf_counter()
    body = E.body_row(inertia, mgc)
    omega0 = np.asarray(omega0, float)
    q0 = E.Q0 if q0 is None else np.asarray(q0, float) / np.linalg.norm(q0)
    free = E.is_free(body)
    Om = _omega_scale(body, omega0)
    tau = Om * T
    eps, rho = (float(v[0]) for v in model.shape(body[None, :3], omega0[None]))
    constants = model.load_constants()
    rounding = model.rounding_floor(constants, metric)
    constants = constants["methods"]
    rows = []
    for m in methods:
        c = constants[calibrated_name(m)]
        ns = float(c["ns_per_step"])
        p = c["order"]
        if c.get("free_exact"):
            if not free:
                continue  # its constants are for free bodies, where it is exact
            kappa, g, q = 1.0, 0.0, p  # the exact flow: rounding only
        else:
            kappa = c["kappa"][metric]
            g, q = model.growth_law(m, body[None, :3], omega0[None], np.array([T]), p)[metric]
            g, q = float(g[0]), float(q[0])
        if budget is not None:
            lo, hi = T * ns * 1e-9 / budget, MAX_H / Om
        else:
            lo, hi = dt_bounds
        dt_user = hi if budget is None else lo
        h_max = model.largest_h(kappa, g, q, tol, tau, rounding)
        dt_largest = min(h_max / Om, hi, MAX_H / Om)
        row = MethodRow(
            method=m,
            order=p,
            symplectic=c["symplectic"],
            ns_per_step=ns,
            dt_user=dt_user,
            predicted_at_user=float(model.predicted_error(kappa, g, q, Om * dt_user, tau, rounding)),
            growth=kappa * g,
            exponent=q,
            free_exact=bool(c.get("free_exact")),
            constants_of="" if calibrated_name(m) == m else calibrated_name(m),
        )
        if dt_largest >= lo and dt_largest > 0:
            row.dt_largest = dt_largest
            row.predicted_at_largest = float(model.predicted_error(kappa, g, q, Om * dt_largest, tau, rounding))
            row.cost_s = T / dt_largest * ns * 1e-9
            row.meets = True
        rows.append(row)
    ok = [r for r in rows if r.meets]
    best = min(ok, key=lambda r: r.cost_s) if ok else None
    lo_all, hi_all = dt_bounds if budget is None else (min(r.dt_user for r in rows), MAX_H / Om)
    advice = Advice(
        inertia=list(map(float, body[:3])),
        mgc=list(map(float, mgc)),
        omega0=list(map(float, omega0)),
        T=float(T),
        metric=metric,
        tol=float(tol),
        dt_bounds=[float(lo_all), float(hi_all)],
        h=Om * hi_all,
        tau=tau,
        shape={"eps": eps, "rho": rho},
        reference="exact free flow (Euler–Poinsot)" if free else "DOP853 at rtol = atol = 1e-12",
        prediction_note="" if free else "heavy body: free-body constants with Ω = |ω0| + √(|M g c|/I_min)",
    )
    advice.rows = rows
    advice.rounding_per_step = rounding
    if free:
        from .predict import intermediate_axis_rate, separatrix_distance

        advice.separatrix_distance = float(separatrix_distance(body[None, :3], omega0[None])[0])
        advice.intermediate_axis_rate = intermediate_axis_rate(body[:3], float(np.linalg.norm(body[:3] * omega0)))
    if best is not None:
        advice.recommended, advice.recommended_dt = best.method, best.dt_largest
        advice.recommended_predicted = best.predicted_at_largest
    advice.seconds_predict = time.perf_counter() - t_start
    engines = engines if free else []  # predict.py is for free bodies
    if not measure:
        advice.engines = _engine_rows(
            engines, body, omega0, dt_bounds[1] if budget is None else hi_all / 10, T, False, None
        )
        return advice
    t_meas = time.perf_counter()
    for k, r in enumerate(rows):
        if progress:
            progress(f"measuring {r.method} ({k + 1}/{len(rows)})")
        dts = [r.dt_user] if r.dt_user > 0 else []
        if r.meets and not math.isclose(r.dt_largest, r.dt_user, rel_tol=1e-9):
            dts.append(r.dt_largest)
        if not dts:
            continue
        errs, horizon, advice.reference = _measure(r.method, body, omega0, q0, dts, T, metric)
        r.measured_over_s = horizon[0]
        if r.dt_user > 0:
            r.measured_at_user = errs[0]
        if r.meets:
            r.measured_at_largest = errs[-1]
        if horizon[-1] < T * (1 - 1e-9):  # measured over the start: the prediction over the same span
            c = constants[calibrated_name(r.method)]
            p = c["order"]
            if c.get("free_exact"):
                kappa, g, q = 1.0, 0.0, p
            else:
                kappa = c["kappa"][metric]
                law = model.growth_law(r.method, body[None, :3], omega0[None], np.array([horizon[0]]), p)[metric]
                g, q = float(law[0][0]), float(law[1][0])
            r.predicted_at_user = float(model.predicted_error(kappa, g, q, Om * r.dt_user, Om * horizon[0], rounding))
            if r.meets:
                r.predicted_at_largest = float(
                    model.predicted_error(kappa, g, q, Om * r.dt_largest, Om * horizon[-1], rounding)
                )
    if best is not None:
        advice.recommended_measured = best.measured_at_largest
        advice.recommended_predicted = best.predicted_at_largest
    # The measurement has the last word: a method whose run at its advised dt misses the tolerance gets
    # a smaller dt from its measured error and the declared order, measured again (once); the advice is
    # then the cheapest method whose measured error meets the tolerance.
    for r in rows:
        if r.meets and r.measured_at_largest > tol and math.isfinite(r.measured_at_largest):
            dt_new = r.dt_largest * (0.8 * tol / r.measured_at_largest) ** (1.0 / r.order)
            if dt_new < (dt_bounds[0] if budget is None else r.dt_user):
                r.meets = False
                continue
            if progress:
                progress(f"measuring {r.method} again at dt = {dt_new:.3g} s")
            errs, _, _ = _measure(r.method, body, omega0, q0, [dt_new], T, metric)
            r.dt_corrected, r.measured_at_corrected = dt_new, errs[0]
            r.cost_s = T / dt_new * r.ns_per_step * 1e-9
            r.meets = errs[0] <= tol
    # and the other way: a method predicted to miss at the user's dt (the range's largest, the budget's
    # smallest) that was measured to meet there meets, at that dt
    for r in rows:
        if not r.meets and r.dt_user > 0 and r.measured_at_user <= tol:
            r.meets = r.met_by_measurement = True
            r.dt_corrected = r.measured_at_corrected = math.nan
            r.dt_largest, r.predicted_at_largest = r.dt_user, r.predicted_at_user
            r.measured_at_largest = r.measured_at_user
            r.cost_s = T / r.dt_user * r.ns_per_step * 1e-9
    passed = [r for r in rows if r.meets and (r.measured_at_largest <= tol or r.measured_at_corrected <= tol)]
    final = min(passed, key=lambda r: r.cost_s) if passed else None
    if final is not None:
        advice.measured_advice = final.method
        advice.measured_advice_dt = final.dt_corrected if math.isfinite(final.dt_corrected) else final.dt_largest
        advice.measured_advice_error = (
            final.measured_at_corrected if math.isfinite(final.dt_corrected) else final.measured_at_largest
        )
    dt_engine = dt_bounds[1] if budget is None else (best.dt_largest if best else hi_all / 10)
    advice.engines = _engine_rows(engines, body, omega0, dt_engine, T, True, progress)
    advice.seconds_measure = time.perf_counter() - t_meas
    return advice
