"""Verdicts measured from runs: order of convergence, drift class, stability threshold.

Pure numpy/scipy on arrays (no files, no plotting); the CLI and the pinned
study call these on what a results file holds.  Units: times and steps in
seconds; errors are whatever the caller passes (the verdict uses *relative*
errors, dimensionless), so rates come out in "relative error per second" etc.

- ``fit_order(dt, err)`` → ``OrderFit``: the measured order p of err ≈ C dt^p
  with a confidence interval, over the asymptotic range of the dt ladder.
- ``classify_drift(t, rel_err)`` → ``Drift``: ``bounded`` | ``linear`` |
  ``slowing`` | ``wander`` | ``growing`` | ``collapse`` | ``diverged`` |
  ``undetermined``, with a fitted rate, its unit, the time scales of a
  collapse or a slowing trend, and whether the series is
  ``preserved_to_rounding``.
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

DRIFT_CLASSES = (
    "bounded",
    "linear",
    "slow_oscillation",
    "slowing",
    "wander",
    "growing",
    "collapse",
    "diverged",
    "undetermined",
)


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
    not ("nonfinite", "diverged", "floor", "reference", "flat", "pre_asymptotic", "slopes_disagree",
    "not_falling", "too_few", or "").
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
    dt,
    err,
    *,
    scale=1.0,
    floor_ulps=1e3,
    reference_error=0.0,
    diverged_err=1.0,
    min_slope=0.3,
    slope_tol=0.1,
    min_points=3,
    confidence=0.95,
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
       1e3 eps ≈ 2.2e-13 by default); ``reference``: err ≤ ``reference_error``
       (in err's units), the reference's own error estimate, below which the
       error measures the reference, not the method;
    4. the asymptotic range: the local slopes between neighbouring steps are
       grouped into runs, each grown from a fine end towards coarser steps for
       as long as the next slope is within ``slope_tol`` (0.1) of the run's
       median; the finest run with at least ``min_points`` − 1 slopes and a
       median ≥ ``min_slope`` (0.3: the error still falls) is the fit range.
       Finer points are ``flat`` (a rounding or reference floor above the eps
       threshold, where the error no longer falls or scatters); coarser ones
       ``pre_asymptotic`` (a higher-order term still dominates, e.g.
       seed_next's dt² term at dt ≥ 2e-4 s on the 50 Hz top).  Without such a
       run every point left is ``slopes_disagree`` (no ``min_points`` − 1
       neighbouring slopes agree) or ``not_falling`` (they agree, but below
       ``min_slope``), and the reason lists the local slopes.

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
        elif err[i] <= reference_error:
            excluded[i] = "reference"
    # Coarse → fine order of the points still in; local slopes between neighbours.
    order = [i for i in np.argsort(-dt, kind="stable") if not excluded[i]]
    slopes = _local_slopes(np.log(dt[order]), np.log(err[order])) if len(order) >= 2 else np.array([])
    need = max(2, min_points) - 1  # slopes in a run
    chosen, long_enough = None, False
    for end in range(len(slopes) - 1, -1, -1):  # the run's finest slope, finest first
        run = [slopes[end]]
        start = end
        while start > 0 and abs(slopes[start - 1] - np.median(run)) <= slope_tol:
            start -= 1
            run.append(slopes[start])
        long_enough = long_enough or len(run) >= need
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
    elif slopes.size:
        # points enough for slopes, but no asymptotic range among them: say which rule left them out
        for i in order:
            excluded[i] = "not_falling" if long_enough else "slopes_disagree"
        order = []
    fit = OrderFit(confidence=confidence, excluded=excluded, used=[not e for e in excluded])
    if len(order) < max(2, min_points):
        fit.used = [False] * n
        fit.excluded = [e or "too_few" for e in excluded]
        listed = ", ".join(f"{slope:.3g}" for slope in slopes)
        words = {
            # no ``need`` neighbouring local slopes agree within slope_tol: no asymptotic range to fit
            "slopes_disagree": (
                f"whose local slopes disagree ({listed}: no {need} neighbours within {slope_tol:g} of each other)"
            ),
            # agreeing slopes, but below min_slope: the error does not fall with dt
            "not_falling": f"where err does not fall with dt (local slopes {listed}; need >= {min_slope:g})",
        }
        fit.reason = (
            f"{len(order)} usable point(s) after excluding "
            + (
                ", ".join(
                    f"{excluded.count(k)} {words.get(k, k)}"
                    for k in (
                        "nonfinite",
                        "diverged",
                        "floor",
                        "reference",
                        "flat",
                        "pre_asymptotic",
                        "slopes_disagree",
                        "not_falling",
                    )
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

    drift_class: one of DRIFT_CLASSES (see ``classify_drift``).  rate and
    rate_unit: "1/s" (linear: e ≈ intercept + rate·t over [fit_t0, fit_t1] s: from the first window's
    centre, where the fit has data, to the record's end),
    "1/sqrt(s)" (wander: σ of e(t) ~ σ √t), "1/s e-folding" (λ of |e| ~ e^{λt})
    or "power" (p of |e| ~ t^p) for growing, "" (NaN rate) otherwise;
    rate_stderr: its standard error where there is one.  period (s): a fitted
    oscillation of the window means (bounded or linear under it), NaN if none.
    collapse: collapse_size (e reached, signed) and collapse_time (s, the first
    time |e| reached 90 % of its late level), then_class / then_rate /
    then_rate_unit / then_intercept: the class of the rest of the record
    (t ≥ collapse_time).  slowing: t_turn (s), where the fitted trend would
    stop; run_longer (s), how long a record would decide bounded or saturating.
    preserved_to_rounding: max |e| ≤ preserved_ulps · eps.  amplitude: max |e|
    (finite part); mean: mean of e; late_mean: mean of e over the last window;
    t_diverged (s): when the run stopped, ``t_stop`` when the caller knows it (n_steps · dt of a
    stopped run: its last finite sample, where the kernel's divergence test fired), else the first
    time e is non-finite (or past ``blowup`` when given; NaN otherwise).  Diagnostics of the rule:
    n_windows, window (s), z_trend, accel, eta, zeta, oscillation, wander; reason: why, in words.
    """

    drift_class: str
    rate: float = math.nan
    rate_unit: str = ""
    rate_stderr: float = math.nan
    intercept: float = math.nan
    fit_t0: float = math.nan
    fit_t1: float = math.nan
    period: float = math.nan
    collapse_size: float = math.nan
    collapse_time: float = math.nan
    then_class: str = ""
    then_rate: float = math.nan
    then_rate_unit: str = ""
    then_intercept: float = math.nan
    t_turn: float = math.nan
    run_longer: float = math.nan
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

    def fitted(self, t):
        """The fitted line e ≈ intercept + rate·t at times t (s) of a linear class (or a collapse's
        linear tail), NaN outside [fit_t0, fit_t1] and for the other classes: what a figure draws."""
        t = np.asarray(t, dtype=float)
        if self.drift_class == "linear":
            a, b = self.intercept, self.rate
        elif self.drift_class == "collapse" and self.then_class == "linear":
            a, b = self.then_intercept, self.then_rate
        else:
            return np.full(t.shape, math.nan)
        return np.where((t >= self.fit_t0) & (t <= self.fit_t1), a + b * t, math.nan)


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


def _remove_fast_oscillations(t, e, n_peaks=3, min_cycles=16.0, prominence=100.0):
    """e minus its ``n_peaks`` strongest sinusoids with at least ``min_cycles`` cycles in the record,
    each a line of the spectrum (``prominence`` times the median power of its neighbourhood).

    Window means average a fast oscillation away only when the window holds whole periods; a
    7.3 s sine in 6.25 s windows aliases into a slow beat that hides a trend or looks like a
    wander.  Each peak of the periodogram of the linearly detrended series (zero-padded 4x,
    refined by a parabola through log power) is fitted by least squares together with a line
    and removed; the slow part (< ``min_cycles`` cycles), which is what is judged, is kept.
    Needs uniform sampling (else e is returned as it is).
    """
    n = e.size
    dt = np.diff(t)
    if n < 64 or np.ptp(dt) > 1e-6 * np.mean(dt):
        return e
    span = t[-1] - t[0]
    x = (t - t[0]) / span
    resid = e - np.polyval(np.polyfit(x, e, 1), x)
    pad = 4 * n
    power = np.abs(np.fft.rfft(resid, pad)) ** 2
    freqs = np.fft.rfftfreq(pad, d=float(np.mean(dt)))
    fast = freqs * span >= min_cycles
    cols = [np.ones(n), x]
    taken = []
    order = np.argsort(np.where(fast, power, -1.0))[::-1]
    for i in order:
        if len(taken) == n_peaks or not fast[i] or i + 1 >= power.size:
            break
        if power[i] < power[i - 1] or power[i] < power[i + 1]:
            continue  # not a local maximum
        near = power[max(i - 64, 0) : i + 65]
        if power[i] < prominence * np.median(near):
            continue  # leakage of the slow part or noise, not a line of the spectrum
        if any(abs(i - j) < 8 for j in taken):
            continue  # the same peak again
        lp = np.log(power[i - 1 : i + 2] + 1e-300)
        shift = 0.5 * (lp[0] - lp[2]) / (lp[0] - 2 * lp[1] + lp[2]) if lp[0] - 2 * lp[1] + lp[2] < 0 else 0.0
        f = freqs[i] + shift * (freqs[1] - freqs[0])
        taken.append(i)
        cols += [np.cos(2 * np.pi * f * (t - t[0])), np.sin(2 * np.pi * f * (t - t[0]))]
    if not taken:
        return e
    A = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(A, e, rcond=None)
    return e - A[:, 2:] @ coef[2:]


def _von_neumann(r):
    """⟨(Δr)²⟩ / var(r): ≈ 2 for independent values, ≪ 1 for a smooth or wandering series."""
    var = float(np.var(r))
    return float(np.mean(np.diff(r) ** 2)) / var if var > 0 else 2.0


def _sine_fit(tw, m, periods):
    """Best fit of m ≈ a + b t + c cos(2πt/P) + s sin(2πt/P) over P (s): the best of the trial
    ``periods``, refined between its neighbours; (P, coefficients, residuals, their covariance)."""
    from scipy.optimize import minimize_scalar

    x = tw - tw[0]

    def design(P):
        return np.column_stack([np.ones_like(x), x, np.cos(2 * np.pi * x / P), np.sin(2 * np.pi * x / P)])

    def ss(P):
        A = design(P)
        coef, *_ = np.linalg.lstsq(A, m, rcond=None)
        r = m - A @ coef
        return float(r @ r)

    trial = [ss(P) for P in periods]
    i = int(np.argmin(trial))
    lo, hi = periods[max(i - 1, 0)], periods[min(i + 1, len(periods) - 1)]
    P = float(minimize_scalar(ss, bounds=(lo, hi), method="bounded").x) if hi > lo else float(periods[i])
    A = design(P)
    coef, *_ = np.linalg.lstsq(A, m, rcond=None)
    r = m - A @ coef
    cov = np.linalg.pinv(A.T @ A) * float(r @ r) / max(m.size - 5, 1)
    return P, coef, r, cov


def _on_its_data(t, e, intercept, rate, frac=0.125):
    """Whether the fitted line intercept + rate·t at the record's end lies within a factor 2 of
    the envelope of |e| over the last ``frac`` of the record: [min |e| / 2, 2 max |e|]."""
    tail = np.abs(e[t >= t[-1] - frac * (t[-1] - t[0])])
    v = abs(intercept + rate * t[-1])
    return 0.5 * float(tail.min()) <= v <= 2.0 * float(tail.max())


def collapse_words(size):
    """How a collapse of relative size ``size`` (e at its end: X/X0 − 1) reads: 'collapses by 87 %',
    'jumps by 45 %'; past a sign change 'falls through zero to -1.2 x its start', and a jump of ten times
    or more 'jumps 4.6e+05-fold' (a percentage of millions reads as noise)."""
    if size < -1:
        return f"falls through zero to {1 + size:.2g} x its start"
    if size >= 9:
        return f"jumps {1 + size:.2g}-fold"
    return f"{'collapses' if size < 0 else 'jumps'} by {abs(size):.0%}"


def classify_drift(
    t,
    rel_err,
    *,
    n_windows=None,
    blowup=None,
    preserved_ulps=500.0,
    z_crit=4.0,
    accel_crit=1.5,
    eta_crit=1.0,
    zeta_crit=0.15,
    min_wander=0.05,
    collapse_min=0.01,
    collapse_early=0.1,
    slowing_min=0.5,
    df_crit=-3.5,
    min_samples=8,
    t_stop=None,
    _tail=False,
):
    """Drift class of a relative error series e(t) = X(t)/X(0) − 1 of an invariant X.

    t (s), increasing; rel_err: e at those times (dimensionless).  In the
    order tried:

    1. ``diverged``: e is non-finite anywhere: the run stopped (a runner
       NaN-fills a run's samples after its kernel's divergence test, the
       energy off by ``runner.divergence_threshold``; ``t_diverged`` is
       ``t_stop`` when given, the time the run stopped, else the first
       non-finite sample's, one sample later).  A finite invariant
       off by more than 100 % is not by itself a divergence: an |L|
       rescale that turns L, a damped energy that settles below zero, are
       bounded runs and are classed by their shape below (a collapse, a
       growth...).  A caller that wants a magnitude rule passes ``blowup``:
       then |e| > blowup is ``diverged`` too, tested after the collapse
       test.  ``undetermined``: fewer than ``min_samples`` (8) samples.
    2. ``collapse``: a fast relaxation or jump.  With x the largest |e| over
       the first ``collapse_early`` (10 %) of the record: x ≥ ``collapse_min``
       (1 %) and ≥ half the record's largest |e|; e reaches half of x within
       the first 1 % of the record (a tenth of ``collapse_early``) and stays
       there: its median over the ``collapse_early`` after the peak is ≥ 70 %
       of x.  ``collapse_time`` is when e first reaches 90 % of x,
       ``collapse_size`` e there.  The rest of the record (t ≥
       collapse_time) is classified by these same rules (``then_class``,
       ``then_rate``...): "collapses by 87 % within 1 s, then linear ...".
       Never a linear rate fitted through the drop.
    3. Fast oscillations removed (``_remove_fast_oscillations``: the three
       strongest sinusoids with ≥ 4 cycles in the record), the series is cut
       into K windows of equal length τ (K = ``n_windows``, default
       clip(n/16, 8, 64); K = n for a short record of < 2K samples); m_k is
       the (cleaned) e averaged over window k, d_k = m_{k+1} − m_k.
       ``bounded`` when the means move (``wander``, their range) by less than
       ``min_wander`` (0.05) times the ``oscillation`` they average away
       (√2 × the rms of the raw e about its window mean: a sine's amplitude).
    4. A slow oscillation seen whole: m fitted by a line plus one sinusoid of
       period P ∈ [4τ, 0.8 T] (T the record's length; a best P at the top of
       that range is no resolved period and is not taken).  When that fit leaves white residuals (von Neumann ratio
       ≥ ``eta_crit``; or all but 1e-4 of var(m)) and explains ≥ 98 % of var(m), the series is
       ``linear`` if the line's slope is significant (|b|/se > ``z_crit``)
       and its total |b| T is ≥ 10 % of the sine's amplitude, else
       ``bounded``; ``period`` = P either way.  (A two-cycle sine is bounded,
       not a wander.)
    5. Trend test: z = mean(d) / (std(d)/√(K−1)), a t-statistic of the mean
       increment (|z| ≫ 1 for a deterministic trend, z ~ N(0, 1) for a
       wander, → 0 for a stationary series); |z| > ``z_crit`` (4), or a sign
       test on the increments as significant (two-sided binomial p < 6e-5),
       means a trend.  With a trend:
       - ``growing`` when it accelerates: the mean increment over the later
         half of the windows is ≥ ``accel_crit`` (1.5) times that of the
         earlier half, same sign, the difference significant at ``z_crit``
         (e ∝ t^p gives 2^p − 1; e^{λt} over T about e^{λT/2}).  Rate: λ of
         |m − e(0)| ~ e^{λt} or p of ~ t^p, the better fit of log|m| over the
         later 3/4 of the windows;
       - ``slowing`` when it decelerates: a quadratic fit of m has a
         significant curvature (|c|/se > ``z_crit``) against the slope, and
         the slope falls by ≥ ``slowing_min`` (50 %) across the record.  A
         trend that slows may be a bounded oscillation longer than the window
         (Kovalevskaya's lie_poisson energy over 1000 s of a 58 000 s
         period) or a saturating relaxation: the record cannot tell.
         ``t_turn`` is where the fitted quadratic stops, ``run_longer`` =
         2 t_turn: a record that long shows which;
       - else ``linear``: least-squares line through m (rate 1/s, intercept,
         stderr), provided its value at the end lies within a factor 2 of
         the envelope of |e| there (``_on_its_data``).
       Without a significant z, a trend hidden under oscillations whose
       means jitter more than one window's drift is ``linear`` when the
       regression slope of m is significant (> ``z_crit`` standard errors)
       and its residuals look stationary (von Neumann ratio ≥ ``eta_crit``).
    6. ``wander`` (σ √t, unit 1/√s): von Neumann's ratio η = ⟨d²⟩ / var(m) <
       ``eta_crit`` (a stationary series gives ≈ 2, a Brownian path ≈ 6/K)
       and the structure function S(ℓ) = ⟨(m_{k+ℓ} − m_k)²⟩ still grows at
       large lags: its log–log slope ζ over ℓ = 1 … K/2 and over ℓ = K/8 …
       K/2 both > ``zeta_crit`` (0.15).  Stationary correlated noise (AR(1)
       with a correlation time of a few windows) saturates at large lags:
       ``bounded``.  The name claims no randomness: integrators are
       deterministic, and a wander reproducible under a tiny perturbation
       of the initial state is as much a wander as a rounding walk; σ =
       √(1.5 ⟨d²⟩/τ) (adjacent means of a Brownian path differ by var =
       (2/3) σ² τ; relative stderr 1/√(2(K−1))).
    7. Else ``bounded`` (no rate; see amplitude).

    preserved_to_rounding: max |e| ≤ ``preserved_ulps`` eps (500 eps ≈
    1.1e-13), independent of the class (a rounding-level linear drift is still
    ``linear``).  An oscillation slower than the record that shows no
    curvature (the record sits on its zero crossing) is indistinguishable from
    a linear trend over that record.
    """
    t = np.asarray(t, dtype=float).ravel()
    e = np.asarray(rel_err, dtype=float).ravel()
    if t.shape != e.shape:
        raise ValueError(f"t and rel_err differ in length: {t.size} vs {e.size}")
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("t must hold at least 2 strictly increasing times")
    finite = np.isfinite(e)
    amplitude = float(np.max(np.abs(e[finite]))) if finite.any() else math.nan
    base = dict(
        amplitude=amplitude,
        preserved_to_rounding=bool(finite.all() and amplitude <= preserved_ulps * EPS),
        mean=float(np.mean(e[finite])) if finite.any() else math.nan,
    )
    if not finite.all():
        first = int(np.argmax(~finite))
        if t_stop is not None and math.isfinite(t_stop):
            # the kernel stopped the run at t_stop (its divergence test fired on that sample, kept finite)
            # and NaN-filled the samples after it: the first NaN is one sample later than the stop
            why = f"stopped at t = {t_stop:g} s (non-finite from t = {t[first]:g} s)"
            return Drift("diverged", t_diverged=float(t_stop), reason=why, **base)
        return Drift("diverged", t_diverged=float(t[first]), reason=f"non-finite at t = {t[first]:g} s", **base)
    if e.size < min_samples:
        return Drift("undetermined", reason=f"{e.size} samples: too few to classify (need {min_samples})", **base)
    opts = dict(
        blowup=blowup,
        preserved_ulps=preserved_ulps,
        z_crit=z_crit,
        accel_crit=accel_crit,
        eta_crit=eta_crit,
        zeta_crit=zeta_crit,
        min_wander=min_wander,
        slowing_min=slowing_min,
        df_crit=df_crit,
        min_samples=min_samples,
    )
    span = float(t[-1] - t[0])
    if not _tail:
        early = t <= t[0] + collapse_early * span
        i_pk = int(np.argmax(np.abs(np.where(early, e, 0.0))))
        x = abs(float(e[i_pk]))
        s = math.copysign(1.0, e[i_pk])
        if x >= collapse_min and x >= 0.5 * amplitude:
            i50 = int(np.argmax(s * e >= 0.5 * x))
            i90 = int(np.argmax(s * e >= 0.9 * x))
            held = s * e[(t >= t[i_pk]) & (t <= t[i_pk] + collapse_early * span)]
            if t[i50] - t[0] <= 0.1 * collapse_early * span and np.median(held) >= 0.7 * x and e.size - i90 >= 2:
                rest = classify_drift(t[i90:], e[i90:], _tail=True, **opts)
                return Drift(
                    "collapse",
                    collapse_size=float(e[i90]),
                    collapse_time=float(t[i90]),
                    then_class=rest.drift_class,
                    then_rate=rest.rate,
                    then_rate_unit=rest.rate_unit,
                    then_intercept=rest.intercept,
                    fit_t0=rest.fit_t0,
                    fit_t1=rest.fit_t1,
                    period=rest.period,
                    t_turn=rest.t_turn,
                    run_longer=rest.run_longer,
                    late_mean=float(np.mean(e[t >= t[-1] - 0.05 * span])),
                    reason=(
                        f"{collapse_words(float(e[i90]))} within {t[i90] - t[0]:.3g} s (half of it within "
                        f"{t[i50] - t[0]:.3g} s), then {rest.drift_class}: {rest.reason}"
                    ),
                    **base,
                )
    if blowup is not None and amplitude > blowup:
        first = int(np.argmax(np.abs(e) > blowup))
        return Drift("diverged", t_diverged=float(t[first]), reason=f"|e| > {blowup:g} at t = {t[first]:g} s", **base)
    k = n_windows or int(np.clip(e.size // 16, 8, 64))
    clean = _remove_fast_oscillations(t, e)
    if e.size < 2 * k:
        k = e.size  # a short record: every sample is its own window
    tw, m = _window_means(t, clean, k)
    tau = float(np.mean(np.diff(tw)))
    n_used = (e.size // k) * k
    within = e[e.size - n_used :].reshape(k, -1) - _window_means(t, e, k)[1][:, None]
    oscillation = math.sqrt(2.0) * float(np.std(within))  # a sine's amplitude from its rms
    wander = float(np.ptp(m))
    d = np.diff(m)
    scale_floor = EPS * max(amplitude, EPS)  # increments below this are rounding of the means
    rec = Drift(
        "bounded",
        late_mean=float(m[-1]),
        n_windows=k,
        window=tau,
        oscillation=oscillation,
        wander=wander,
        **base,
    )
    if wander < min_wander * oscillation or wander <= scale_floor:
        rec.reason = f"window means move by {wander:.3g} < {min_wander:g} x the oscillation {oscillation:.3g}"
        return rec

    def linear(fit, why):
        rec.drift_class = "linear"
        rec.rate, rec.rate_unit, rec.rate_stderr = float(fit.slope), "1/s", float(fit.stderr)
        rec.intercept, rec.fit_t0, rec.fit_t1 = float(fit.intercept), float(tw[0]), float(t[-1])
        rec.reason = why
        return rec

    # 4. a slow oscillation seen whole, with or without a trend under it
    span_w = float(tw[-1] - tw[0])
    if k >= 12 and span_w > 0:
        periods = np.geomspace(4 * tau, 0.8 * span, 60)
        P, coef, r, cov = _sine_fit(tw, m, periods)
        var_m = float(np.var(m))
        amp = math.hypot(coef[2], coef[3])
        se_b = math.sqrt(max(cov[1, 1], 0.0))
        explained = 1.0 - float(np.var(r)) / var_m if var_m > 0 else 0.0
        resolved = P < 0.75 * span  # at the top of the trial range it only soaks up a curvature
        if resolved and (explained >= 1 - 1e-4 or _von_neumann(r) >= eta_crit) and explained >= 0.98 and amp > 0:
            rec.period = float(P)
            b = float(coef[1])
            if se_b > 0 and abs(b) / se_b > z_crit and abs(b) * span >= 0.1 * amp:
                rec.drift_class = "linear"
                rec.rate, rec.rate_unit, rec.rate_stderr = b, "1/s", se_b
                rec.intercept = float(coef[0] - b * tw[0])
                rec.fit_t0, rec.fit_t1 = float(tw[0]), float(t[-1])
                rec.reason = f"trend under an oscillation of period {P:.3g} s"
                return rec
            rec.reason = f"oscillation of period {P:.3g} s (amplitude {amp:.3g} of the window means)"
            return rec

    # 5. trend tests
    se = max(float(np.std(d, ddof=1)) / math.sqrt(d.size), scale_floor)
    z = float(np.mean(d)) / se
    rec.z_trend = z
    n_up = int(np.count_nonzero(d > 0))
    n_signed = n_up + int(np.count_nonzero(d < 0))
    p_sign = stats.binomtest(n_up, n_signed).pvalue if n_signed else 1.0
    fit = stats.linregress(tw, m)
    if abs(z) > z_crit or p_sign < 2.0 * stats.norm.sf(z_crit):
        h = d.size // 2
        early, late_d = d[:h], d[-h:]
        me, ml = float(np.mean(early)), float(np.mean(late_d))
        se_e = float(np.std(early, ddof=1)) / math.sqrt(h) if h > 1 else 0.0
        se_l = float(np.std(late_d, ddof=1)) / math.sqrt(h) if h > 1 else 0.0
        accel = ml / me if me != 0.0 else math.copysign(math.inf, ml)
        rec.accel = float(accel)
        significant = abs(ml - me) > z_crit * max(math.hypot(se_e, se_l), scale_floor)
        if accel >= accel_crit and significant:
            rec.drift_class = "growing"
            q = k // 4
            rec.rate, rec.rate_unit, rec.rate_stderr = _growth_rate(tw[q:], np.abs(m[q:] - e[0]))
            rec.reason = f"trend accelerating by {accel:.3g}x from the first half to the second"
            return rec
        # A trend that bends: a cubic through the means.  An oscillation obeys e''' = -w^2 e', so a
        # significant cubic term against the slope gives its period even from a record much shorter than
        # it (Kovalevskaya's lie_poisson energy: 60 000 s from 1000 s); a saturation (e''' with e') does
        # not; a significant curvature against the slope without that is a trend that slows.
        if k >= 8:
            x = tw - tw.mean()
            A = np.column_stack([np.ones_like(x), x, x * x, x**3])
            coef, *_ = np.linalg.lstsq(A, m, rcond=None)
            r = m - A @ coef
            cov = np.linalg.pinv(A.T @ A) * float(r @ r) / max(k - 4, 1)
            b, c, d3 = float(coef[1]), float(coef[2]), float(coef[3])
            se_c, se_d = math.sqrt(max(cov[2, 2], 0.0)), math.sqrt(max(cov[3, 3], 0.0))
            s0, s1 = b + 2 * c * x[0] + 3 * d3 * x[0] ** 2, b + 2 * c * x[-1] + 3 * d3 * x[-1] ** 2
            if se_d > 0 and abs(d3) / se_d > z_crit and b != 0 and -6 * d3 / b > 0:
                period = 2 * math.pi / math.sqrt(-6 * d3 / b)
                if period > span:
                    rec.drift_class = "slow_oscillation"
                    rec.period = period
                    rec.run_longer = float(t[0] + period)
                    rec.rate, rec.rate_unit, rec.rate_stderr = float(fit.slope), "1/s", float(fit.stderr)
                    rec.intercept, rec.fit_t0, rec.fit_t1 = float(fit.intercept), float(tw[0]), float(t[-1])
                    rec.reason = (
                        f"trend over a record shorter than its oscillation (period ~ {period:.2g} s from its "
                        f"curvature); run longer than {rec.run_longer:.2g} s to decide"
                    )
                    return rec
            if se_c > 0 and abs(c) / se_c > z_crit and s0 != 0 and 1.0 - s1 / s0 >= slowing_min:
                rec.drift_class = "slowing"
                rec.t_turn = float(tw.mean() - b / (2 * c))
                rec.run_longer = float(2.0 * (rec.t_turn - t[0]) + t[0])
                rec.reason = (
                    f"trend slowing by {1 - s1 / s0:.0%} over the record: a saturation or an oscillation longer "
                    f"than the record; run longer than {rec.run_longer:.3g} s to decide"
                )
                return rec
        if _on_its_data(t, e, fit.intercept, fit.slope):
            return linear(fit, f"trend: z = {z:.3g}")
        rec.reason = "a trend whose fitted line is off its data"
    # A trend hidden under oscillations whose window means still jitter more than one window's
    # drift: the regression on the means sees it, and then its residuals are stationary.
    resid = m - (fit.intercept + fit.slope * tw)
    eta_r = _von_neumann(resid) if float(np.var(resid)) > scale_floor**2 else 2.0
    if (
        fit.stderr > 0
        and abs(fit.slope) / fit.stderr > z_crit
        and eta_r >= eta_crit
        and _on_its_data(t, e, fit.intercept, fit.slope)
    ):
        rec.eta = eta_r
        return linear(fit, f"trend under the jitter of the window means (slope {abs(fit.slope) / fit.stderr:.3g} se)")
    # 6. wander or bounded
    lags = np.arange(1, k // 2 + 1)
    S = np.array([np.mean((m[l:] - m[:-l]) ** 2) for l in lags])
    rec.zeta = float(stats.linregress(np.log(lags), np.log(S)).slope) if np.all(S > 0) and lags.size >= 2 else 0.0
    # Dickey-Fuller: regress d_k on m_k; a stationary series pulls back (slope < 0, t well below 0),
    # a wander does not (t ~ -1.5 +- 1; the 1 % critical value with a constant is about -3.5).
    df = stats.linregress(m[:-1], d) if d.size >= 3 and np.ptp(m[:-1]) > 0 else None
    df_t = float(df.slope / df.stderr) if df is not None and df.stderr > 0 else 0.0
    var_m = float(np.var(m, ddof=1))
    rec.eta = float(np.mean(d * d)) / var_m if var_m > scale_floor**2 else 2.0
    if rec.eta < eta_crit and rec.zeta > zeta_crit and df_t > df_crit:
        rec.drift_class = "wander"
        # Means of a Brownian path over adjacent windows of length τ differ by var = (2/3) σ² τ.
        rec.rate, rec.rate_unit = math.sqrt(1.5 * float(np.mean(d * d)) / tau), "1/sqrt(s)"
        # σ from K − 1 independent increments: relative standard error 1/√(2(K − 1)).
        rec.rate_stderr = rec.rate / math.sqrt(2.0 * d.size)
        rec.reason = f"wanders: eta = {rec.eta:.2g}, structure-function slope {rec.zeta:.2g}"
        return rec
    rec.reason = (
        rec.reason or f"no trend, no wander: eta = {rec.eta:.2g}, zeta = {rec.zeta:.2g}, Dickey-Fuller t = {df_t:.2g}"
    )
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
    reason: "" when the bracket converged, else why not; omega_dt_small_fail:
    when the smallest step failed but a larger one stayed bounded (a solver
    whose absolute tolerance falls below rounding at small steps), |ω| times
    the largest step seen failing below the last bounded stretch of probes
    (the bisection then runs above it), else NaN.
    """

    omega_dt_crit: float = math.nan
    omega_dt_lo: float = math.nan
    omega_dt_hi: float = math.nan
    dt_lo: float = math.nan
    dt_hi: float = math.nan
    omega: float = 1.0
    n_evals: int = 0
    reason: str = ""
    omega_dt_small_fail: float = math.nan  # |ω| dt of the largest failing step below the bounded range


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
        # unstable at every step, or a failure only small steps meet (an implicit solver whose absolute
        # tolerance lies below the rounding of its residual): probe upward once before saying "unstable"
        probes = np.geomspace(lo, hi, max(batch, 8) + 2)[1:-1]
        ok = np.asarray(run_ok(probes), dtype=bool)
        evals += probes.size
        if not ok.any():
            return _finish(rec, math.nan, lo, omega, evals, f"the run at lo = {lo:g} s is not bounded")
        # the stability edge lies above the last bounded probe (failures below it may be sporadic: whether
        # a Newton solve meets its floor is luck); those below the last bounded stretch are reported
        last = int(np.nonzero(ok)[0][-1])
        below = np.nonzero(~ok[:last])[0]
        rec.omega_dt_small_fail = omega * float(probes[below[-1]] if below.size else lo)
        lo = float(probes[last])
        if last + 1 < probes.size:
            hi = float(probes[last + 1])
        elif ends[1]:
            return _finish(rec, hi, math.nan, omega, evals, f"the run at hi = {hi:g} s stays bounded")
    elif ends[1]:
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


def signed_error(values):
    """e(t) of an invariant series: (x − x0)/|x0| for a scalar (x0 → max |x| when |x0| is ~0 next to it),
    |X − X0|/|X0| for a vector (time, xyz)."""
    x = np.asarray(values, dtype=float)
    if x.ndim == 2:
        scale = np.linalg.norm(x[0]) or np.nanmax(np.linalg.norm(x, axis=-1))
        return np.linalg.norm(x - x[:1], axis=-1) / scale
    scale = abs(x[0])
    big = np.nanmax(np.abs(x)) if np.isfinite(x).any() else 0.0
    if not scale > 1e-9 * big:
        scale = big or 1.0
    return (x - x[0]) / scale


# The fewest steps of a dt ladder an order is fitted from (and worded from: cells.fmt_order).
MIN_LADDER = 3

# The drift classes that are a trend (a rate, however it bends); a bounded, collapsing or diverging
# invariant is not a rounding bias whatever its size.
TREND_CLASSES = ("linear", "wander", "slow_oscillation", "slowing")


def is_rounding_drift(drift_class, amplitude, n_steps, preserved, rate_unit=""):
    """A trend whose total stays below 0.1 ulp per step (``amplitude`` ≤ 0.1 eps N): a rounding bias,
    not truncation, whether the window shows it as a line, a √t wander, the start of a slow oscillation
    or a power-law growth (``rate_unit`` "power": split6_exact's L_z on Kovalevskaya's top, 4.3e-12 in
    1e6 steps, read "growing ∝ t^1.33" after an ulp-level change of its elliptic functions; the
    verdict still names that growth in its drift column).  An exponential growth is never one."""
    trend = drift_class in TREND_CLASSES or (drift_class == "growing" and rate_unit == "power")
    return (
        not preserved
        and trend
        and amplitude is not None
        and math.isfinite(amplitude)
        and amplitude <= 0.1 * EPS * n_steps
    )
