"""Verdicts measured from runs: order of convergence, drift class, stability threshold.

Pure numpy/scipy on arrays (no files, no plotting); the CLI and the pinned
study call these on what a results file holds.  Units: times and steps in
seconds; errors are whatever the caller passes (the verdict uses *relative*
errors, dimensionless), so rates come out in "relative error per second" etc.

- ``fit_order(dt, err)`` → ``OrderFit``: the measured order p of err ≈ C dt^p
  with a confidence interval, over the asymptotic range of the dt ladder.
- ``classify_drift(t, rel_err)`` → ``Drift``: ``bounded`` | ``linear`` |
  ``random_walk`` | ``growing`` | ``diverged``, with a fitted rate, its unit,
  and whether the series is ``preserved_to_rounding``.
- ``stability_threshold(run_ok, lo, hi)`` → ``Threshold``: bisection in dt of
  a user predicate; ``method_stability_threshold(method, scene, t_end)`` runs
  the predicate "status ok over t_end" through ``gyrolab.kernels.batch.integrate``,
  several trial steps per batch.

Every record has ``as_dict()`` (JSON-ready: NaN → None) for ``verdict.json``.
"""

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import stats

EPS = float(np.finfo(np.float64).eps)  # 2.22e-16, one ulp of 1.0

DRIFT_CLASSES = ("bounded", "linear", "random_walk", "growing", "diverged")


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (np.floating, np.integer)):
        return _jsonable(value.item())
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


class _Record:
    def as_dict(self):
        """The record as a dict of plain Python values (NaN/inf → None), for JSON."""
        return _jsonable(asdict(self))


# ---------------------------------------------------------------- order of convergence


@dataclass
class OrderFit(_Record):
    """Measured order of convergence, err ≈ C dt^order.

    order: least-squares slope of log err against log dt over the asymptotic
    range (NaN when no fit is possible, see ``reason``); ci_low, ci_high: its
    ``confidence`` interval (t-distribution, n_points − 2 degrees of freedom;
    NaN with 2 points); stderr: the slope's standard error; dt_min, dt_max (s):
    the range of steps used; n_points: how many; used: per input point (in the
    caller's order) whether it entered the fit; excluded: per input point why
    not ("nonfinite", "diverged", "floor", "flat", "pre_asymptotic", or "").
    reason: "" for a fit, else why there is none.
    """

    order: float = math.nan
    ci_low: float = math.nan
    ci_high: float = math.nan
    stderr: float = math.nan
    confidence: float = 0.95
    dt_min: float = math.nan
    dt_max: float = math.nan
    n_points: int = 0
    used: list = field(default_factory=list)
    excluded: list = field(default_factory=list)
    reason: str = ""

    @property
    def ci(self):
        return self.ci_low, self.ci_high


def _local_slopes(ldt, lerr):
    return np.diff(lerr) / np.diff(ldt)


def fit_order(
    dt, err, *, scale=1.0, floor_ulps=1e3, diverged_err=1.0, min_slope=0.3, slope_tol=0.1, min_points=3, confidence=0.95
):
    """Order of convergence of a dt ladder, fitted over its asymptotic range.

    dt (s), err: one error per step size (any positive measure, e.g. the final
    state's max-norm error against a reference), ``scale`` the size of the
    quantity the error is measured on (so err/scale is relative; 1 when err
    already is).  Points are excluded, in this order:

    1. ``nonfinite``: err is NaN/inf (the run blew up) or ≤ 0;
    2. ``diverged``: err/scale ≥ ``diverged_err`` (an O(1) error is no
       convergence data);
    3. ``floor``: err/scale < ``floor_ulps`` · eps (round-off floor,
       1e3 eps ≈ 2.2e-13 by default);
    4. the asymptotic range: the local slopes between neighbouring steps are
       grouped into runs, each grown from a fine end towards coarser steps for
       as long as the next slope is within ``slope_tol`` (0.1) of the run's
       median; the finest run with at least ``min_points`` − 1 slopes and a
       median ≥ ``min_slope`` (0.3: the error still falls) is the fit range.
       Finer points are ``flat`` (a rounding or reference floor above the eps
       threshold, where the error no longer falls or scatters); coarser ones
       ``pre_asymptotic`` (a higher-order term still dominates, e.g.
       seed_next's dt² term at dt ≥ 2e-4 s on the 50 Hz top).

    The fit needs ``min_points`` (≥ 2) points; with 2 the CI is NaN.  Returns an
    ``OrderFit``.
    """
    dt = np.asarray(dt, dtype=float).ravel()
    err = np.asarray(err, dtype=float).ravel()
    if dt.shape != err.shape:
        raise ValueError(f"dt and err differ in length: {dt.size} vs {err.size}")
    if not np.all(np.isfinite(dt) & (dt > 0)):
        raise ValueError("dt must be finite and > 0")
    n = dt.size
    excluded = [""] * n
    rel = err / scale
    for i in range(n):
        if not (math.isfinite(err[i]) and err[i] > 0):
            excluded[i] = "nonfinite"
        elif rel[i] >= diverged_err:
            excluded[i] = "diverged"
        elif rel[i] < floor_ulps * EPS:
            excluded[i] = "floor"
    # Coarse → fine order of the points still in; local slopes between neighbours.
    order = [i for i in np.argsort(-dt, kind="stable") if not excluded[i]]
    slopes = _local_slopes(np.log(dt[order]), np.log(err[order])) if len(order) >= 2 else np.array([])
    need = max(2, min_points) - 1  # slopes in a run
    chosen = None
    for end in range(len(slopes) - 1, -1, -1):  # the run's finest slope, finest first
        run = [slopes[end]]
        start = end
        while start > 0 and abs(slopes[start - 1] - np.median(run)) <= slope_tol:
            start -= 1
            run.append(slopes[start])
        if len(run) >= need and np.median(run) >= min_slope:
            chosen = (start, end)
            break
    if chosen is not None:
        start, end = chosen
        for i in order[end + 2 :]:
            excluded[i] = "flat"
        for i in order[:start]:
            excluded[i] = "pre_asymptotic"
        order = order[start : end + 2]
    else:
        order = []
    fit = OrderFit(confidence=confidence, excluded=excluded, used=[not e for e in excluded])
    if len(order) < max(2, min_points):
        fit.used = [False] * n
        fit.excluded = [e or "too_few" for e in excluded]
        fit.reason = (
            f"{len(order)} usable point(s) after excluding "
            + (
                ", ".join(
                    f"{excluded.count(k)} {k}"
                    for k in ("nonfinite", "diverged", "floor", "flat", "pre_asymptotic")
                    if excluded.count(k)
                )
                or "none"
            )
            + f"; need {max(2, min_points)}"
        )
        return fit
    x, y = np.log(dt[order]), np.log(err[order])
    res = stats.linregress(x, y)
    fit.order = float(res.slope)
    fit.n_points = len(order)
    fit.dt_min, fit.dt_max = float(dt[order].min()), float(dt[order].max())
    if len(order) > 2:
        fit.stderr = float(res.stderr)
        half = stats.t.ppf(0.5 + 0.5 * confidence, len(order) - 2) * fit.stderr
        fit.ci_low, fit.ci_high = fit.order - half, fit.order + half
    return fit


# ---------------------------------------------------------------- drift class


@dataclass
class Drift(_Record):
    """Drift class of an invariant's relative error series e(t).

    drift_class: one of DRIFT_CLASSES; rate and rate_unit: the fitted rate,
    "1/s" (slope of e, linear), "1/sqrt(s)" (σ of e(t) ~ σ √t, random walk),
    "1/s e-folding" (λ of |e| ~ e^{λt}) or "power" (p of |e| ~ t^p) for
    growing, "" (NaN rate) for bounded and diverged; rate_stderr: its standard
    error where there is one.  preserved_to_rounding: max |e| ≤
    preserved_ulps · eps.  amplitude: max |e| (finite part); mean: mean of e;
    late_mean: mean of e over the last window; t_diverged (s): first time e is
    non-finite or past ``blowup`` (NaN otherwise).  Diagnostics of the rule
    (see ``classify_drift``): n_windows, window (s), z_trend, accel, eta, zeta,
    oscillation, wander.
    """

    drift_class: str
    rate: float = math.nan
    rate_unit: str = ""
    rate_stderr: float = math.nan
    preserved_to_rounding: bool = False
    amplitude: float = math.nan
    mean: float = math.nan
    late_mean: float = math.nan
    t_diverged: float = math.nan
    n_windows: int = 0
    window: float = math.nan
    z_trend: float = math.nan
    accel: float = math.nan
    eta: float = math.nan
    zeta: float = math.nan
    oscillation: float = math.nan
    wander: float = math.nan
    reason: str = ""


def _window_means(t, e, k):
    """Centres (s) and means of e over k windows of equal sample count."""
    n = (e.size // k) * k
    start = e.size - n  # drop the first few samples, never the last ones
    tw = t[start:].reshape(k, -1).mean(axis=1)
    mw = e[start:].reshape(k, -1).mean(axis=1)
    return tw, mw


def _growth_rate(t, y):
    """(rate, unit, stderr) of |y| growing: e-folding rate or power-law exponent, the better fit."""
    ok = (y > 0) & (t > 0)
    t, y = t[ok], y[ok]
    if t.size < 3:
        return math.nan, "", math.nan
    ly = np.log(y)
    exp_fit = stats.linregress(t, ly)
    pow_fit = stats.linregress(np.log(t), ly)
    if exp_fit.rvalue**2 >= pow_fit.rvalue**2:
        return float(exp_fit.slope), "1/s e-folding", float(exp_fit.stderr)
    return float(pow_fit.slope), "power", float(pow_fit.stderr)


def classify_drift(
    t,
    rel_err,
    *,
    n_windows=None,
    blowup=1.0,
    preserved_ulps=500.0,
    z_crit=4.0,
    accel_crit=1.5,
    eta_crit=1.0,
    zeta_crit=0.15,
    min_wander=0.05,
):
    """Drift class of a relative error series e(t) = X(t)/X(0) − 1 of an invariant X.

    t (s), increasing; rel_err: e at those times (dimensionless).  The series
    is cut into K windows of equal length τ (K = ``n_windows``, default
    clip(n/16, 8, 64)); m_k is e averaged over window k, which averages the
    oscillations of a bounded error away but keeps a trend or a wander.  With
    the increments d_k = m_{k+1} − m_k:

    1. ``diverged``: e is non-finite anywhere, or |e| > ``blowup`` (default 1:
       the invariant is off by 100 %).
    1b. ``bounded`` when the window means move (their range, ``wander``) by
       less than ``min_wander`` (0.05) times the ``oscillation`` they average
       away (√2 × the rms of e about its window mean: a sine's amplitude).
       This keeps an oscillation whose period is close to the window length,
       whose means then alias into a slow smooth swing (≲ 3 % of its
       amplitude), from passing for a trend or a wander; a real drift 10×
       below the oscillation still counts.
    2. Trend test: z = mean(d) / (std(d)/√(K−1)), a t-statistic of the mean
       increment.  A deterministic trend makes every increment the same sign,
       |z| ≫ 1; for a random walk z ~ N(0, 1); for a stationary (bounded)
       series z → 0 like 1/√K.  |z| > ``z_crit`` (4) means a trend; so does a
       sign test on the increments as significant as that (two-sided binomial
       p < 6e-5 for z_crit = 4: e.g. ≥ 50 of 63 of the same sign), which
       catches a monotone trend whose increments vary too much for the
       t-statistic (an exponential over many e-foldings).
    3. With a trend, ``growing`` when it accelerates: the mean increment over
       the later half of the windows is ≥ ``accel_crit`` (1.5) times that of
       the earlier half, same sign, and the difference is itself significant
       at ``z_crit``.  For e ∝ t^p that ratio is 2^p − 1: linear 1, quadratic
       3, and 1.5 means p ≥ 1.32; an exponential e^{λt} over a run of length T
       gives ≈ e^{λT/2}.  Rate: λ of |m_k − e(0)| ~ e^{λt} or p of ~ t^p, whichever
       fits log|m| better (over the later 3/4 of the windows).  Else
       ``linear``, rate: least-squares slope of m_k against t (1/s), stderr
       from the regression.
       Without a significant z, the trend may still hide under oscillations
       whose window means jitter more than one window's drift: the
       least-squares slope b of m_k against t with |b|/stderr(b) > ``z_crit``
       and residuals that look stationary (their von Neumann ratio, see 4,
       ≥ ``eta_crit``) is ``linear`` too.  (A random walk gives spuriously
       significant slopes too, but its residuals still wander: small ratio.)
    4. Otherwise: von Neumann's ratio η = ⟨d²⟩ / var(m), the mean
       square successive difference over the variance of the window means.
       Window means of a bounded (stationary) error are nearly independent,
       η ≈ 2; a random walk's wander makes var(m) ≈ K τ σ²/6 ≫ ⟨d²⟩ = τ σ², η ≈
       6/K (0.1 for K = 64).  A slow deterministic oscillation (period of a few
       windows) also has small η, so the wander must also grow with the lag:
       ζ, the log–log slope of the structure function S(ℓ) = ⟨(m_{k+ℓ} −
       m_k)²⟩ over ℓ = 1 … K/2 (≈ 0 bounded, 1 random walk, 2 trend; an
       oscillation's S(ℓ) rises then falls back), must exceed ``zeta_crit``
       (0.15; measured on 300 seeded walks of 4e4 steps the 1st percentile of
       ζ is 0.20, and on amplitude-modulated sines with η < 1 its maximum
       0.11).  Both: ``random_walk``, rate σ = √(1.5 ⟨d²⟩/τ) (1/√s, e(t) ~
       σ √t: means of a Brownian path over adjacent windows differ by
       var = (2/3) σ² τ; relative stderr 1/√(2(K−1))).  Else ``bounded`` (no
       rate; see amplitude).  An oscillation slower than ~1/3 of the run is
       indistinguishable from a trend or a wander over that run.

    preserved_to_rounding: max |e| ≤ ``preserved_ulps`` eps (500 eps ≈
    1.1e-13), independent of the class (a rounding-level linear drift is still
    ``linear``).  A series shorter than 16 samples gets the class "bounded" or
    "diverged" only from steps 1 and the amplitude, with ``reason`` set.
    """
    t = np.asarray(t, dtype=float).ravel()
    e = np.asarray(rel_err, dtype=float).ravel()
    if t.shape != e.shape:
        raise ValueError(f"t and rel_err differ in length: {t.size} vs {e.size}")
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("t must hold at least 2 strictly increasing times")
    finite = np.isfinite(e)
    bad = ~finite | (np.abs(np.where(finite, e, 0.0)) > blowup)
    amplitude = float(np.max(np.abs(e[finite]))) if finite.any() else math.nan
    base = dict(
        amplitude=amplitude,
        preserved_to_rounding=bool(finite.all() and amplitude <= preserved_ulps * EPS),
        mean=float(np.mean(e[finite])) if finite.any() else math.nan,
    )
    if bad.any():
        first = int(np.argmax(bad))
        why = "non-finite" if not finite[first] else f"|e| > {blowup:g}"
        return Drift("diverged", t_diverged=float(t[first]), reason=f"{why} at t = {t[first]:g} s", **base)
    k = n_windows or int(np.clip(e.size // 16, 8, 64))
    if e.size < 2 * k or k < 4:
        return Drift("bounded", reason=f"{e.size} samples: too short to classify a trend", **base)
    tw, m = _window_means(t, e, k)
    tau = float(np.mean(np.diff(tw)))
    n_used = (e.size // k) * k
    within = e[e.size - n_used :].reshape(k, -1) - m[:, None]
    oscillation = math.sqrt(2.0) * float(np.std(within))  # a sine's amplitude from its rms
    wander = float(np.ptp(m))
    d = np.diff(m)
    scale_floor = EPS * max(amplitude, EPS)  # increments below this are rounding of the means
    se = max(float(np.std(d, ddof=1)) / math.sqrt(d.size), scale_floor)
    z = float(np.mean(d)) / se
    rec = Drift(
        "bounded",
        late_mean=float(m[-1]),
        n_windows=k,
        window=tau,
        z_trend=z,
        oscillation=oscillation,
        wander=wander,
        **base,
    )
    if wander < min_wander * oscillation:
        rec.reason = f"window means move by {wander:.3g} < {min_wander:g} x the oscillation {oscillation:.3g}"
        return rec
    n_up = int(np.count_nonzero(d > 0))
    n_signed = n_up + int(np.count_nonzero(d < 0))
    p_sign = stats.binomtest(n_up, n_signed).pvalue if n_signed else 1.0
    if abs(z) > z_crit or p_sign < 2.0 * stats.norm.sf(z_crit):
        h = d.size // 2
        early, late = d[:h], d[-h:]
        me, ml = float(np.mean(early)), float(np.mean(late))
        se_e = float(np.std(early, ddof=1)) / math.sqrt(h) if h > 1 else 0.0
        se_l = float(np.std(late, ddof=1)) / math.sqrt(h) if h > 1 else 0.0
        accel = ml / me if me != 0.0 else math.copysign(math.inf, ml)
        rec.accel = float(accel)
        significant = abs(ml - me) > z_crit * max(math.hypot(se_e, se_l), scale_floor)
        if accel >= accel_crit and significant:
            rec.drift_class = "growing"
            q = k // 4
            rec.rate, rec.rate_unit, rec.rate_stderr = _growth_rate(tw[q:], np.abs(m[q:] - e[0]))
            return rec
        fit = stats.linregress(tw, m)
        rec.drift_class = "linear"
        rec.rate, rec.rate_unit, rec.rate_stderr = float(fit.slope), "1/s", float(fit.stderr)
        return rec
    # A trend hidden under oscillations whose window means still jitter more than one window's
    # drift: the regression on the means sees it, and then its residuals are stationary.
    fit = stats.linregress(tw, m)
    resid = m - (fit.intercept + fit.slope * tw)
    var_r = float(np.var(resid, ddof=2))
    eta_r = float(np.mean(np.diff(resid) ** 2)) / var_r if var_r > scale_floor**2 else 2.0
    if fit.stderr > 0 and abs(fit.slope) / fit.stderr > z_crit and eta_r >= eta_crit:
        rec.drift_class = "linear"
        rec.rate, rec.rate_unit, rec.rate_stderr = float(fit.slope), "1/s", float(fit.stderr)
        rec.eta = eta_r
        return rec
    lags = np.arange(1, k // 2 + 1)
    S = np.array([np.mean((m[l:] - m[:-l]) ** 2) for l in lags])
    rec.zeta = float(stats.linregress(np.log(lags), np.log(S)).slope) if np.all(S > 0) else 0.0
    var_m = float(np.var(m, ddof=1))
    rec.eta = float(np.mean(d * d)) / var_m if var_m > scale_floor**2 else 2.0
    if rec.eta < eta_crit and rec.zeta > zeta_crit:
        rec.drift_class = "random_walk"
        # Means of a Brownian path over adjacent windows of length τ differ by var = (2/3) σ² τ.
        rec.rate, rec.rate_unit = math.sqrt(1.5 * float(np.mean(d * d)) / tau), "1/sqrt(s)"
        # σ from K − 1 independent increments: relative standard error 1/√(2(K − 1)).
        rec.rate_stderr = rec.rate / math.sqrt(2.0 * d.size)
    return rec


def relative_error(series, reference=None):
    """(x − x_ref)/|x_ref| along the last axis, x_ref = the first sample unless given."""
    x = np.asarray(series, dtype=float)
    ref = x[..., :1] if reference is None else np.asarray(reference, dtype=float)
    return (x - ref) / np.abs(ref)


# ---------------------------------------------------------------- stability threshold


@dataclass
class Threshold(_Record):
    """Stability threshold found by bisection in dt.

    dt_lo (s): the largest step seen whose run stayed bounded below dt_hi, the
    smallest seen that did not; omega_dt_crit = |ω| · dt_lo (rad, the
    dimensionless step), with the bracket omega_dt_lo, omega_dt_hi = |ω| ·
    (dt_lo, dt_hi); omega (rad/s): the |ω| used (1 when none given, so the
    omega_dt values are then plain dt); n_evals: predicate calls (runs);
    reason: "" when the bracket converged, else why not.
    """

    omega_dt_crit: float = math.nan
    omega_dt_lo: float = math.nan
    omega_dt_hi: float = math.nan
    dt_lo: float = math.nan
    dt_hi: float = math.nan
    omega: float = 1.0
    n_evals: int = 0
    reason: str = ""


def _finish(rec, lo, hi, omega, evals, reason=""):
    rec.dt_lo, rec.dt_hi, rec.omega, rec.n_evals, rec.reason = lo, hi, omega, evals, reason
    rec.omega_dt_lo = omega * lo if lo is not None and math.isfinite(lo) else math.nan
    rec.omega_dt_hi = omega * hi if hi is not None and math.isfinite(hi) else math.nan
    rec.omega_dt_crit = rec.omega_dt_lo if not reason else math.nan
    return rec


def stability_threshold(run_ok, lo, hi, *, omega=1.0, rtol=1e-3, max_evals=60, batch=1):
    """Bisect the step dt (s) between ``lo`` (a stable step) and ``hi`` (an unstable one).

    ``run_ok(dts) -> sequence of bool``: for each trial step whether the run
    stays bounded over the study time (the caller's predicate; it is given a
    1-d array of ``batch`` steps at a time so it can run them in one batch).
    The ends are checked first.  Each round tries ``batch`` steps spaced
    geometrically inside the bracket and keeps [largest ok step below the
    smallest failing one, that failing step], until hi/lo − 1 ≤ ``rtol``.
    (A predicate that is not monotone in dt yields one of its crossings.)
    ``omega`` (rad/s) scales the result to |ω| dt.  Returns a ``Threshold``.
    """
    if not (0 < lo < hi):
        raise ValueError(f"need 0 < lo < hi, got lo={lo}, hi={hi}")
    rec = Threshold()
    ends = np.asarray(run_ok(np.array([lo, hi], dtype=float)), dtype=bool)
    evals = 2
    if not ends[0]:
        return _finish(rec, math.nan, lo, omega, evals, f"the run at lo = {lo:g} s is not bounded")
    if ends[1]:
        return _finish(rec, hi, math.nan, omega, evals, f"the run at hi = {hi:g} s stays bounded")
    while hi / lo - 1 > rtol:
        if evals >= max_evals:
            return _finish(rec, lo, hi, omega, evals, f"max_evals = {max_evals} reached")
        trial = np.geomspace(lo, hi, batch + 2)[1:-1]
        ok = np.asarray(run_ok(trial), dtype=bool)
        evals += trial.size
        failing = np.nonzero(~ok)[0]
        first_bad = failing[0] if failing.size else trial.size
        if first_bad < trial.size:
            hi = float(trial[first_bad])
        if first_bad > 0:
            lo = float(trial[first_bad - 1])
    return _finish(rec, lo, hi, omega, evals)


def method_stability_threshold(
    method,
    scene,
    t_end,
    *,
    lo=None,
    hi=None,
    threshold=1.0,
    rtol=1e-3,
    batch=None,
    n_samples=65,
    integrate=None,
    max_evals=200,
):
    """(|ω| dt)_crit of a registered method on a scene, by batched bisection over t_end seconds.

    method: a registered method name (or whatever ``integrate`` accepts as its
    first argument); scene: a ``Scene`` (body, omega0, q0), e.g. from
    ``kernels.scenes.build_scene``.  A run "stays bounded" when its status is
    ok: finite, and |E − E0| ≤ ``threshold`` · (T0 + |M g l|) at every one of
    the ``n_samples`` samples over t ≥ t_end (s).  The bracket defaults to
    |ω0| dt from 1e-3 to 10 rad (the ends are checked); ``batch`` trial steps
    per round (default 2 × numba threads, at least 4).  ``integrate`` defaults
    to ``gyrolab.kernels.batch.integrate`` (same signature).  Returns a
    ``Threshold`` with omega = |ω0| of the scene.
    """
    import numba

    if integrate is None:
        from ...kernels.batch import integrate
    omega = float(np.linalg.norm(scene.omega0))
    if omega == 0.0:
        raise ValueError("the scene does not rotate (|omega0| = 0): no |omega| dt to measure")
    lo = 1e-3 / omega if lo is None else lo
    hi = 10.0 / omega if hi is None else hi
    batch = batch or max(4, 2 * numba.get_num_threads())
    every_steps = n_samples - 1

    def run_ok(dts):
        dts = np.asarray(dts, dtype=float)
        n = dts.size
        strides = np.maximum(1, np.ceil(t_end / every_steps / dts)).astype(np.int64)
        _, status, _ = integrate(
            method,
            np.tile(scene.body, (n, 1)),
            np.tile(scene.omega0, (n, 1)),
            np.tile(scene.q0, (n, 1)),
            dts,
            strides,
            n_samples,
            threshold,
        )
        return status == 0

    return stability_threshold(run_ok, lo, hi, omega=omega, rtol=rtol, batch=batch, max_evals=max_evals)
