"""``gyrolab-verdict FILE...``: measured verdicts from stored results files.

Usage examples: README.md, "Using it".

Per (scene, method) it reports, from whatever the files hold:

- the **order** of convergence p (err ≈ C dt^p, ``classify.fit_order``) of every
  (method, f, θ0) with at least 3 step sizes: err = the final sample's state
  error, max(‖axis − axis_ref‖∞, ‖ω − ω_ref‖∞ / |ω0|) (dimensionless), against
  the finest reference available, in this order: the scene's closed form when
  it gives the state (``free_symmetric``; ``euler_poinsot``, the exact free
  body of gyrolab.free_body); else the finest ok run of a
  yardstick method in the same file (``YARDSTICKS``: lie_poisson4 or
  split6_exact, whichever finest run differs least from its own next finest
  run; its reference point is left out of its own fit); else DOP853
  (kernels/reference.py, rtol = atol = 1e-13, with its own error |y(tol) − y(10 tol)|) computed once
  per (scene, f, θ0).
  The record says which (``reference``);
- the **drift class** (``classify.classify_drift``) of every invariant the
  scene declares (layout.conserved; layout.invariant gives each series) for
  every run with at least ``MIN_DRIFT_SAMPLES`` samples: e(t) = (X(t) − X0)/|X0|,
  for L the norm of L(t) − L0 over |L0|; rate in 1/s (linear), 1/√s (random
  walk), 1/s e-folding or power (growing);
- **preserved**: max |e| at rounding level, ≤ max(500, 5 √N) eps for a run of
  N steps (a Brouwer walk of a few ulps per step's worth; 1.1e-12 at N = 1e6),
  and whether the method declares it (``PRESERVES``); ``rounding_drift``: not
  that, but a trend (linear, √t, or a slow oscillation or slowing trend the
  window cannot close) totalling ≤ 0.1 eps per step (a rounding bias);
- the **stability threshold** (|ω| dt)_crit, only with ``--stability T``:
  bisection in dt (``classify.method_stability_threshold``) of "the run stays
  bounded over T seconds" from the file's stored initial state.

Summary records (``kind: "summary"``, one per scene, method and invariant)
take the order from the ladder and the drift from the method's run with the
most steps; per-run records (``kind: "run"``) and order records (``kind:
"order"``) carry f (Hz), θ0 (deg) and dt (s).  Bad input (missing,
unreadable or foreign file, no runs, or nothing to judge: no dt ladder and
too few samples for a drift class): one line on stderr, exit 2, nothing
written.  A file named twice (or as itself and through its directory) is
judged once, with a note on stderr.
"""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from ...pipes import quiet_on_broken_pipe
from ...results import EXIT_BAD_INPUT
from ...safe_files import UnsafePathError, check_replaceable, write_text
from .cells import fmt_drift, fmt_number, fmt_order, fmt_preserved, fmt_threshold
from .classify import MIN_LADDER, classify_drift, fit_order, is_rounding_drift, signed_error

YARDSTICKS = ("lie_poisson4", "split6_exact")
MIN_DRIFT_SAMPLES = 16
# What a drift record carries beyond class and rate (classify.Drift): the fitted line, a period,
# a collapse's size, time and what follows, a slowing trend's turning point, and the reason in words.
DRIFT_DETAILS = (
    "intercept",
    "fit_t0",
    "fit_t1",
    "period",
    "collapse_size",
    "collapse_time",
    "then_class",
    "then_rate",
    "then_rate_unit",
    "then_intercept",
    "t_turn",
    "run_longer",
    "drift_reason",
)
DOP853_TOL = 1e-13
RECORD_KEYS = (
    "kind",
    "scene",
    "method",
    "quantity",
    "order",
    "order_ci",
    "drift_class",
    "drift_rate",
    "drift_rate_unit",
    "omega_dt_crit",
    "preserved",
    "declared_preserved",
    "f",
    "theta0",
    "dt",
)


class VerdictError(ValueError):
    """Bad input: a one-line message."""


# ---------------------------------------------------------------- reading


def load(paths):
    """[(path, Dataset)] of gyrolab results files (layout_version ≥ 1); VerdictError otherwise."""
    from ...results import ResultsError, find_results
    from ...results.reader import members_of, open_file

    out = []
    try:
        found = find_results(paths)
    except ResultsError as err:
        raise VerdictError(str(err)) from None
    found = _once(found)
    for path in found:
        try:
            whole, version = open_file(path)
            members = members_of(path, whole, version)  # a combined file: each scene (or job) on its own
        except ResultsError as err:
            raise VerdictError(str(err)) from None
        if members[0][0] is not None and _inputs_found(whole, found):
            continue  # gyrolab-combine's <dir>/combined.h5 next to its job files: judge those once
        for label, ds in members:
            name = path if label is None else f"{path} {ds.attrs['combined_member']}"
            if int(ds.attrs.get("layout_version", 0)) < 1 or "status" not in ds:
                raise VerdictError(f"FILE={name}: not a gyrolab results file (no layout_version >= 1)")
            if ds.sizes.get("integrator", 0) == 0 or int((ds["status"] >= 0).sum()) == 0:
                raise VerdictError(f"FILE={name}: holds no runs")
            out.append((name, ds))
    return out


def _once(found):
    """``found`` with each file once (a file named twice, or as itself and through its directory, would
    count every run twice); one line on stderr names what was left out."""
    first, out, again = {}, [], []
    for path in found:
        key = Path(path).resolve()
        if key in first:
            again.append(f"{path} (= {first[key]})" if str(path) != str(first[key]) else str(path))
            continue
        first[key] = path
        out.append(path)
    if again:
        sys.stderr.write(f"gyrolab-verdict: note: judged once, named more than once: {', '.join(again)}\n")
    return out


def _inputs_found(ds, found):
    """Whether every file the combined file ``ds`` (opened whole) was made from (its ``source_path``) is
    among ``found`` too (a directory searched with it), so its runs are judged there."""
    sources = [str(v) for v in ds["source_path"].values] if "source_path" in ds else []
    mine = {str(Path(p).resolve()) for p in found}
    return bool(sources) and all(s in mine for s in sources)


def _text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def scene_key(ds):
    """(scene name, 'k=v ...' of its options): files with the same key describe the same physics."""
    from ..io import scene_name, scene_options

    opts = " ".join(f"{k}={_text(v)}" for k, v in sorted(scene_options(ds).items()))
    return scene_name(ds), opts


def declared_preserves(method):
    """The invariants a registered method (or variant) declares it preserves, or None if it is not registered."""
    from ...kernels.registry import registered

    mod = registered(method)
    return None if mod is None else tuple(mod.PRESERVES)


def declared_order(method):
    """The order a registered method (or variant) declares, or None if it is not registered."""
    from ...kernels.registry import registered

    mod = registered(method)
    return None if mod is None else int(mod.ORDER)


# ---------------------------------------------------------------- order


def state_error(axis, omega, ref_axis, ref_omega, omega0):
    """max(‖axis − ref‖∞, ‖ω − ref‖∞ / |ω0|): the dimensionless state error of one sample."""
    axis, omega = np.asarray(axis, float), np.asarray(omega, float)
    return float(max(np.max(np.abs(axis - ref_axis)), np.max(np.abs(omega - ref_omega)) / omega0))


class References:
    """Reference final states (axis, ω) per (scene, f, θ0, t), each computed once."""

    def __init__(self, how="auto"):
        self.how = how
        self.cache = {}

    def get(self, ds, f, theta0):
        """(axis (3,), ω (3,) rad/s, label, yardstick (method, dt) or None, own error) at the file's last
        sample time.  ``own error`` is the reference's own error estimate in ``state_error``'s measure (0 for
        a closed form or the exact flow): an error below it measures the reference, not the method."""
        from ...results.layout import closed_form
        from ..io import build_run_scene

        t = float(ds.time.values[-1])
        scene = build_run_scene(ds, f, theta0)
        form = closed_form(ds)
        if self.how in ("auto", "closed_form") and form == "free_symmetric":
            from ...kernels.closed_form import free_symmetric_solution

            axis, omega = free_symmetric_solution(scene, [t])
            return axis[0], omega[0], f"closed form ({form})", None, 0.0
        if self.how in ("auto", "closed_form") and form == "euler_poinsot":
            from ...kernels.euler_poinsot import free_body

            omega, q = free_body(scene.body[:3], scene.omega0, scene.q0, np.array([t]))
            a, b, c, d = q[0]
            axis = np.array([2 * (b * d + a * c), 2 * (c * d - a * b), a * a + d * d - b * b - c * c])
            return axis, omega[0], "exact flow (euler_poinsot: gyrolab.free_body)", None, 0.0
        if self.how == "closed_form":
            raise VerdictError(f"--reference closed_form: scene {scene.name} has no closed-form state")
        if self.how in ("auto", "yardstick"):
            best = None
            for name in YARDSTICKS:
                if name not in ds.integrator.values:
                    continue
                runs = ds.sel({"integrator": name, "f": f, "theta0": theta0}).isel(time=-1)
                ok = sorted(float(dt) for dt in runs.dt.values if int(runs.status.sel(dt=dt)) == 0)
                if len(ok) < 2:
                    continue
                fine, next_ = runs.sel(dt=ok[0]), runs.sel(dt=ok[1])
                omega0 = float(np.linalg.norm(ds["omega0"].sel(f=f, theta0=theta0).values))
                # Self-consistency: the finest run against the next finest, an upper estimate of its error.
                spread = state_error(fine.axis.values, fine.omega.values, next_.axis.values, next_.omega.values, omega0)
                if best is None or spread < best[0]:
                    best = (spread, name, ok[0], fine)
            if best is not None:
                spread, name, dt, run = best
                return (
                    run.axis.values,
                    run.omega.values,
                    f"finest {name} run (dt = {dt:.3g} s; differs from its next finest by {spread:.1e})",
                    (name, dt),
                    spread,  # an upper estimate of its own error (the next finest is the worse of the two)
                )
        if self.how == "yardstick":
            raise VerdictError(f"--reference yardstick: no ok run of {' or '.join(YARDSTICKS)} in the file")
        key = (scene.body, scene.omega0, scene.q0, t)
        if key not in self.cache:
            from ...kernels.reference import dop853_with_error

            y, err = dop853_with_error(scene, t, t, tol=DOP853_TOL)
            s, e = y[-1], err[-1]
            # its own error in the state_error measure: |y(tol) − y(10 tol)|
            own = float(max(np.max(e[0:3]), np.max(e[3:6]) / float(np.linalg.norm(scene.omega0))))
            self.cache[key] = (s[0:3], s[3:6], own)
        axis, omega, own = self.cache[key]
        return axis, omega, f"DOP853 (rtol = atol = {DOP853_TOL:g}; its error ≤ {own:.1e})", None, own


def drive_window(ds, f, th):
    """[on, off] (s) of the time-dependent torque of the body at (f, θ0) (kernels/body.py's drive), or
    None when its amplitude is zero or the file stores no body."""
    if "body" not in ds:
        return None
    body = ds["body"].sel(f=f, theta0=th).to_series()
    if not any(body.get(k, 0.0) for k in ("tau1", "tau2", "tau3")):
        return None
    return [float(body["drive_on"]), float(body["drive_off"])]


def order_records(ds, refs):
    """Order records of every (method, f, θ0) of ``ds`` with ≥ MIN_LADDER step sizes."""
    from ..io import scene_name

    if ds.sizes["dt"] < MIN_LADDER or ds.sizes["time"] < 2:
        return []
    out = []
    for f in ds.f.values:
        for th in ds.theta0.values:
            ref_axis, ref_omega, label, own, ref_error = refs.get(ds, f, th)
            omega0 = float(np.linalg.norm(ds["omega0"].sel(f=f, theta0=th).values))
            for m in ds.integrator.values:
                runs = ds.sel({"integrator": m, "f": f, "theta0": th}).isel(time=-1)
                dts, errs = [], []
                for dt in runs.dt.values:
                    if own == (str(m), float(dt)):
                        continue  # the reference itself
                    run = runs.sel(dt=dt)
                    bad = int(run.status) != 0
                    dts.append(float(dt))
                    errs.append(
                        math.inf if bad else state_error(run.axis.values, run.omega.values, ref_axis, ref_omega, omega0)
                    )
                fit = fit_order(dts, errs, reference_error=ref_error)
                out.append(
                    dict(
                        kind="order",
                        scene=scene_name(ds),
                        method=str(m),
                        quantity="state",
                        f=float(f),
                        theta0=float(th),
                        dt=None,
                        t_end=float(ds.time.values[-1]),
                        reference=label,
                        reference_error=ref_error,
                        order=fit.order,
                        order_ci=[fit.ci_low, fit.ci_high],
                        order_dt_range=[fit.dt_min, fit.dt_max],
                        order_points=fit.n_points,
                        order_reason=fit.reason,
                        declared_order=declared_order(m),
                        ladder_dt=dts,
                        ladder_err=errs,
                        ladder_used=fit.used,
                        ladder_excluded=fit.excluded,
                        drive_window=drive_window(ds, f, th),
                    )
                )
    return out


# ---------------------------------------------------------------- drift


def preserved_ulps(n_steps):
    """The rounding level of a run of n_steps steps, in ulps: max(500, 5 √N)."""
    return max(500.0, 5.0 * math.sqrt(max(n_steps, 0)))


def drift_records(ds):
    """Run records (one per run and declared invariant) of every run with ≥ MIN_DRIFT_SAMPLES samples."""
    from ...kernels.invariants import has_invariant, invariant
    from ...results.layout import conserved
    from ..io import scene_name

    if ds.sizes["time"] < MIN_DRIFT_SAMPLES:
        return []
    t = np.asarray(ds.time.values, dtype=float)
    out = []
    names = [q for q in conserved(ds) if has_invariant(ds, q)]
    for m in ds.integrator.values:
        declared = declared_preserves(m)
        for f in ds.f.values:
            for th in ds.theta0.values:
                for dt in ds.dt.values:
                    run = ds.sel({"integrator": m, "f": f, "theta0": th, "dt": dt})
                    n_steps = int(run.n_steps)
                    solver = solver_counts(run)
                    # a stopped run stopped after its n_steps steps; its samples after that are NaN
                    t_stop = n_steps * float(dt) if int(run.status) > 0 else None
                    for q in names:
                        e = signed_error(invariant(run, q).values)
                        d = classify_drift(t, e, preserved_ulps=preserved_ulps(n_steps), t_stop=t_stop)
                        d.drift_reason = d.reason
                        # A drift whose total stays below 0.1 ulp per step is a rounding bias, not truncation.
                        rounding_drift = is_rounding_drift(
                            d.drift_class, d.amplitude, n_steps, d.preserved_to_rounding, d.rate_unit
                        )
                        out.append(
                            dict(
                                kind="run",
                                scene=scene_name(ds),
                                method=str(m),
                                quantity=q,
                                f=float(f),
                                theta0=float(th),
                                dt=float(dt),
                                t_end=float(t[-1]),
                                n_steps=n_steps,
                                status=int(run.status),
                                **solver,
                                drift_class=d.drift_class,
                                drift_rate=d.rate,
                                drift_rate_unit=d.rate_unit,
                                drift_rate_stderr=d.rate_stderr,
                                amplitude=d.amplitude,
                                late_mean=d.late_mean,
                                t_diverged=d.t_diverged,
                                preserved=d.preserved_to_rounding,
                                rounding_drift=bool(rounding_drift),
                                **{k: getattr(d, k) for k in DRIFT_DETAILS},
                                declared_preserved=None if declared is None else q in declared,
                                order=None,
                                order_ci=None,
                                omega_dt_crit=None,
                            )
                        )
    return out


# ---------------------------------------------------------------- stability threshold


def threshold_records(datasets, t_end, rtol=1e-3):
    """One record per (scene, method) of the files: (|ω| dt)_crit over t_end s at the first (f, θ0)."""
    from ..io import build_run_scene, scene_name
    from .classify import method_stability_threshold

    done, out = set(), []
    for _, ds in datasets:
        for m in ds.integrator.values:
            key = (scene_key(ds), str(m))
            if key in done or declared_order(m) is None:
                continue
            done.add(key)
            f, th = float(ds.f.values[0]), float(ds.theta0.values[0])
            thr = method_stability_threshold(str(m), build_run_scene(ds, f, th), t_end, rtol=rtol)
            out.append(
                dict(
                    kind="threshold",
                    scene=scene_name(ds),
                    method=str(m),
                    quantity="stability",
                    f=f,
                    theta0=th,
                    dt=None,
                    stability_t_end=float(t_end),
                    omega_dt_crit=thr.omega_dt_crit,
                    omega_dt_bracket=[thr.omega_dt_lo, thr.omega_dt_hi],
                    omega_dt_small_fail=thr.omega_dt_small_fail,
                    omega=thr.omega,
                    threshold_reason=thr.reason,
                    order=None,
                    order_ci=None,
                    drift_class=None,
                    drift_rate=None,
                    preserved=None,
                )
            )
    return out


# ---------------------------------------------------------------- the verdict


SOLVER_KEYS = ("solver_iterations", "solver_iterations_max")


def solver_counts(run):
    """{solver_iterations, solver_iterations_max} of one run of a file (None where its layout has none,
    kernels/methods/README.md "Solvers": 0 no solver, −1 not counted)."""
    return {k: int(run[k]) if k in run else None for k in SOLVER_KEYS}


def solver_words(rows):
    """ "method 3.1 (5), ..." for the rows (summaries of one scene and (f, θ0)) of methods whose solver
    counted iterations in their drift run: the mean a step and the most in one step; "" if none."""
    seen = {}
    for r in rows:
        total, most, steps = r.get("solver_iterations"), r.get("solver_iterations_max"), r.get("n_steps")
        if r["method"] not in seen and total and total > 0 and steps:
            seen[r["method"]] = f"{r['method']} {total / steps:.3g} ({most})"
    return ", ".join(seen.values())


def _blank(**kw):
    rec = {k: None for k in RECORD_KEYS}
    rec.update(kw)
    return rec


def summaries(datasets, orders, runs, thresholds):
    """Summary records: per (scene, method, declared invariant) the order, drift, preserved and threshold."""
    from ...results.layout import conserved
    from ..io import scene_name

    scenes = {}
    for _, ds in datasets:
        scenes.setdefault(scene_name(ds), [])
        for q in conserved(ds):
            if q not in scenes[scene_name(ds)]:
                scenes[scene_name(ds)].append(q)
        for m in ds.integrator.values:
            scenes.setdefault(("methods", scene_name(ds)), [])
            if str(m) not in scenes[("methods", scene_name(ds))]:
                scenes[("methods", scene_name(ds))].append(str(m))
    out = []
    for scene in [k for k in scenes if isinstance(k, str)]:
        # One verdict per (method, f, θ0) group the files hold: a ladder's order and the longest run's drift.
        groups = list(
            dict.fromkeys(
                (r["f"], r["theta0"]) for r in orders + runs + thresholds if r["scene"] == scene and r["f"] is not None
            )
        )
        for m in scenes[("methods", scene)]:
            thr = next((r for r in thresholds if r["scene"] == scene and r["method"] == m), None)
            for f, th in groups:
                mine_o = [o for o in orders if (o["scene"], o["method"], o["f"], o["theta0"]) == (scene, m, f, th)]
                order = next((o for o in mine_o if not o["order_reason"]), mine_o[0] if mine_o else None)
                mine_r = [r for r in runs if (r["scene"], r["method"], r["f"], r["theta0"]) == (scene, m, f, th)]
                if order is None and not mine_r and not (thr and (thr["f"], thr["theta0"]) == (f, th)):
                    continue
                out += _group_summaries(scene, m, f, th, order, mine_r, thr, scenes[scene])
    return out


def _group_summaries(scene, m, f, th, order, group_runs, thr, quantities):
    """Summary records of one (scene, method, f, θ0): one per declared invariant; a scene that declares
    none (forced_body: the drive does work) still has its order and threshold, in one record with
    quantity None."""
    out = []
    for q in quantities or [None]:
        mine = [r for r in group_runs if r["quantity"] == q]
        run = max(mine, key=lambda r: (r["n_steps"], r["t_end"], -r["dt"])) if mine else None
        rec = _blank(
            kind="summary", scene=scene, method=m, quantity=q, declared_order=declared_order(m), f=f, theta0=th
        )
        if order:
            rec.update(
                {
                    k: order[k]
                    for k in (
                        "order",
                        "order_ci",
                        "order_dt_range",
                        "order_points",
                        "order_reason",
                        "reference",
                        "reference_error",
                        "ladder_excluded",
                        "ladder_err",
                        "ladder_dt",
                    )
                }
            )
            rec.update(order_f=order["f"], order_theta0=order["theta0"], order_t_end=order["t_end"])
        if run:
            rec.update(
                {
                    k: run[k]
                    for k in (
                        "drift_class",
                        "drift_rate",
                        "drift_rate_unit",
                        "drift_rate_stderr",
                        "amplitude",
                        "late_mean",
                        "t_diverged",
                        "preserved",
                        "rounding_drift",
                        *DRIFT_DETAILS,
                        "declared_preserved",
                        "f",
                        "theta0",
                        "dt",
                        "t_end",
                        "n_steps",
                        "status",
                        *SOLVER_KEYS,
                    )
                }
            )
        if thr and (thr["f"], thr["theta0"]) == (f, th):  # bisected at one (f, θ0) per scene
            rec.update(
                omega_dt_crit=thr["omega_dt_crit"],
                omega_dt_bracket=thr["omega_dt_bracket"],
                omega_dt_small_fail=thr.get("omega_dt_small_fail"),
                stability_t_end=thr["stability_t_end"],
                threshold_reason=thr["threshold_reason"],
                stability_f=thr["f"],
                stability_theta0=thr["theta0"],
            )
        out.append(rec)
    return out


def verdict(paths, stability=None, reference="auto", at=None):
    """All records (summary, order, run, threshold) from the results files ``paths``; ``stability``: T (s)
    of the threshold bisection, None to skip it; ``at``: {'f': Hz, 'theta0': deg} to judge only that
    group (default: every (method, f, θ0) group of the files)."""
    return judge(select_at(load(paths), at), stability=stability, reference=reference)


def judge(datasets, stability=None, reference="auto"):
    """All records of ``verdict`` from loaded ``datasets`` ([(name, Dataset)], ``load``); VerdictError
    when none of them holds anything to judge (``nothing_to_judge`` says why)."""
    refs = References(reference)
    orders, runs = [], []
    for _, ds in datasets:
        orders += order_records(ds, refs)
        runs += drift_records(ds)
    thresholds = threshold_records(datasets, stability) if stability else []
    out = summaries(datasets, orders, runs, thresholds) + orders + runs + thresholds
    if not out:
        raise VerdictError(nothing_to_judge(datasets))
    for rec in out:  # every record carries every key of RECORD_KEYS (None where it does not apply)
        for key in RECORD_KEYS:
            rec.setdefault(key, None)
    return out


def nothing_to_judge(datasets):
    """Why ``datasets`` give no record, in one line: per file, what ``order_records`` and ``drift_records``
    need that it lacks."""
    from ...kernels.invariants import has_invariant
    from ...results.layout import conserved

    whys = {}
    for name, ds in datasets:
        n_dt, n_t = ds.sizes["dt"], ds.sizes["time"]
        lacks = []
        if n_dt < MIN_LADDER:
            lacks.append(f"{n_dt} step size{'s' * (n_dt != 1)}, no dt ladder (an order needs >= {MIN_LADDER})")
        elif n_t < 2:
            lacks.append(f"{n_t} sample per run (an order needs a final state after the start)")
        if not [q for q in conserved(ds) if has_invariant(ds, q)]:
            lacks.append("no conserved quantity (a drift class needs one)")
        elif n_t < MIN_DRIFT_SAMPLES:
            lacks.append(f"{n_t} samples per run (a drift class needs >= {MIN_DRIFT_SAMPLES})")
        whys.setdefault(" and ".join(lacks), []).append(str(name))
    files = "; ".join(f"{', '.join(names)}: {why}" for why, names in whys.items())
    return (
        f"nothing to judge: {files}; add dt values (sweep.dt), more samples (output.every, sweep.t_end), "
        "or pass --stability T"
    )


def jsonable(value):
    """Plain JSON values: NaN/inf → None, numpy scalars → Python."""
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# ---------------------------------------------------------------- text


def markdown(records, title="Verdicts measured by gyrolab"):
    """The verdict as a Markdown document: per scene, one table row per method, with the conditions."""
    from ...kernels.scenes import scenes as scene_table

    summ = [r for r in records if r["kind"] == "summary"]
    lines = [
        f"# {title}",
        "",
        "Generated by `gyrolab-verdict` (analysis/verdicts/verdict.py) from stored results; do not edit by hand.  "
        "Regenerate docs/: `gyrolab experiment=verdict hydra.callbacks.verdict.docs_dir=$PWD/docs`.",
        "Order: fitted p of err ≈ C dtᵖ over the asymptotic range of the dt ladder [95 % CI], err = the final "
        "state's error max(‖axis − ref‖∞, ‖ω − ref‖∞/|ω0|).  Drift: class of e(t) = (X(t) − X0)/|X0| of each "
        "declared invariant (|L(t) − L0|/|L0| for L) with its fitted rate; bounded shows max |e|; a collapse "
        "its size, the time it took and what follows; a trend that bends, how long a run would decide; "
        "'wander' (σ√t) claims no randomness; 'diverged (t = …)': the run stopped there, after its "
        "n_steps steps (NaN, or its energy past runner.divergence_threshold × (T0 + |Mgl|)), while an "
        "invariant of a run that goes on is classed by its shape however far it moves.  "
        "Preserved: max |e| ≤ max(500, 5√N) eps over N steps; 'rounding drift': a trend (linear, √t, slowing "
        "or the start of a slow oscillation) whose total stays below 0.1 eps per step; '!' = declared in "
        "PRESERVES but not kept.  '≤ reference': the errors lie below the reference's own error estimate, "
        "so they measure the reference, not the method (such points are left out of every fit).  "
        "(‖ω‖dt)_crit: largest step, by bisection, whose run stays bounded (|E − E0| ≤ T0 + |Mgl|) over the "
        "stated time; '< x' = not bounded even at the smallest step tried (nor at any of 8 larger ones), "
        "'> x' = bounded at the largest; '; fails at ≤ y': steps up to y failed too (a solver that stalls "
        "at small steps), the bisection ran above them.",
        "",
    ]
    for scene in dict.fromkeys(r["scene"] for r in summ):
        rows = [r for r in summ if r["scene"] == scene]
        quantities = [q for q in dict.fromkeys(r["quantity"] for r in rows) if q is not None]
        info = scene_table().get(scene, {})
        lines += [f"## {scene}", "", f"{info.get('doc', '')}", ""]
        conds = _conditions(records, scene)
        lines += [f"- {c}" for c in conds] + [""]
        groups = list(dict.fromkeys((r["f"], r["theta0"]) for r in rows))
        several = len(groups) > 1  # then every row says which (f, θ0) it is
        head = (
            ["method"]
            + (["f (Hz)", "θ0 (°)"] if several else [])
            + ["declared order", "measured order"]
            + [f"{q} drift" for q in quantities]
            + ["preserved to rounding", "(‖ω‖dt)_crit"]
        )
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for key in dict.fromkeys((r["method"], r["f"], r["theta0"]) for r in rows):
            mine = [r for r in rows if (r["method"], r["f"], r["theta0"]) == key]
            first = mine[0]
            cells = [f"`{key[0]}`"] + ([fmt_number(key[1]), fmt_number(key[2])] if several else [])
            cells += [str(first.get("declared_order") or "—"), fmt_order(first)]
            cells += [fmt_drift(next((r for r in mine if r["quantity"] == q), {})) for q in quantities]
            cells += [fmt_preserved(mine), fmt_threshold(first)]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def ladder_words(dts):
    """'13 steps, halving' / '3 steps, decades' / '4 steps, ratio 3' / '5 steps, uneven': the dt ladder as it is."""
    d = np.sort(np.asarray([x for x in dts if x is not None], float))[::-1]
    if d.size < 2:
        return f"{d.size} step"
    r = d[:-1] / d[1:]
    if np.ptp(r) > 0.01 * r.mean():
        return f"{d.size} steps, uneven (ratios {r.min():.3g} … {r.max():.3g})"
    ratio = float(r.mean())
    word = (
        {2: "halving", 10: "decades"}.get(round(ratio), f"ratio {ratio:.3g}")
        if abs(ratio - round(ratio)) < 0.01
        else f"ratio {ratio:.3g}"
    )
    return f"{d.size} steps, {word}"


_LADDER_KEY = ("f", "theta0", "t_end", "reference", "ladder_dt")


def _conditions(records, scene):
    """Sentences stating f, θ0, dt and t_end behind the numbers of ``scene``."""
    out = []
    orders = [r for r in records if r["kind"] == "order" and r["scene"] == scene]
    # one sentence per ladder: the methods of one (f, θ0) may differ in ladder (a yardstick's own reference
    # run is left out of it) or reference; then each sentence names its methods
    ladders = _methods_by(orders, *_LADDER_KEY)
    for key, methods in ladders.items():
        o = next(x for x in orders if _row_key(x, _LADDER_KEY) == key)
        dts = o["ladder_dt"]
        shared = sum(k[:2] == key[:2] for k in ladders) > 1
        who = f" ({', '.join(f'`{m}`' for m in methods)})" if shared else ""
        drive = o.get("drive_window")
        if drive and drive[0] >= o["t_end"]:  # the drive never acted on these runs: say so
            drive = f"; the drive acts on [{drive[0]:.4g}, {drive[1]:.4g}] s, after t = {o['t_end']:g} s: undriven here"
        elif drive:
            drive = f"; the drive acts on [{drive[0]:.4g}, {drive[1]:.4g}] s"
        out.append(
            f"order{who}: f = {o['f']:g} Hz, θ0 = {o['theta0']:g}°, final state at t = {o['t_end']:g} s, "
            f"dt = {max(dts):.3g} … {min(dts):.3g} s ({ladder_words(dts)}); reference: {o['reference']}{drive or ''}"
        )
    runs = [r for r in records if r["kind"] == "summary" and r["scene"] == scene and r.get("drift_class")]
    drifts = _methods_by([r for r in runs if r.get("status") == 0], "f", "theta0", "dt", "t_end", "n_steps")
    for key, methods in drifts.items():
        f, th, dt, t_end, n = key
        mine = [r for r in runs if (r["f"], r["theta0"], r["dt"], r["t_end"], r["n_steps"]) == key]
        solved = solver_words(mine)
        solved = f"; solver iterations a step (most in one step): {solved}" if solved else ""
        shared = sum(k[:2] == key[:2] for k in drifts) > 1
        who = f" ({', '.join(f'`{m}`' for m in methods)})" if shared else ""
        out.append(
            f"drift{who}: f = {f:g} Hz, θ0 = {th:g}°, dt = {dt:g} s, t_end = {t_end:g} s ({n:.3g} steps){solved}"
        )
    thr = [r for r in records if r["kind"] == "threshold" and r["scene"] == scene]
    for key in dict.fromkeys((r["f"], r["theta0"], r["stability_t_end"], r["omega"]) for r in thr):
        f, th, t_end, omega = key
        out.append(
            f"(‖ω‖dt)_crit: f = {f:g} Hz, θ0 = {th:g}°, ‖ω0‖ = {omega:.4g} rad/s, bounded over "
            f"{t_end:g} s, bisection to 0.1 % in dt"
        )
    return out


TABLE_WIDTH = 120


def _cell(text, width):
    """text padded to ``width`` columns, or cut with '…' (the full text is in --json / --markdown)."""
    text = str(text)
    return text.ljust(width) if len(text) <= width else text[: width - 1] + "…"


def _row_key(r, keys):
    return tuple(tuple(r[k]) if isinstance(r[k], list) else r[k] for k in keys)


def _methods_by(rows, *keys):
    """{(the rows' values of ``keys``, lists as tuples): [methods]} in the rows' order."""
    out = {}
    for r in rows:
        key = _row_key(r, keys)
        out.setdefault(key, [])
        if r["method"] not in out[key]:
            out[key].append(r["method"])
    return out


def table(records, width=TABLE_WIDTH):
    """Plain-text verdict, ``width`` columns at most: per (scene, f, θ0) group the lines stating it, then
    per method its measured order (on its first row) and one row per invariant: drift, (‖ω‖dt)_crit."""
    summ = [r for r in records if r["kind"] == "summary"]
    cols = (21, 10, 34)  # method, invariant, order; the drift takes the rest but the crit column
    crit_w = 7
    drift_w = width - sum(cols) - crit_w - 4
    lines = []
    for key in dict.fromkeys((r["scene"], r["f"], r["theta0"]) for r in summ):
        rows = [r for r in summ if (r["scene"], r["f"], r["theta0"]) == key]
        scene, f, th = key
        lines += ["", f"{scene}: f = {fmt_number(f)} Hz, θ0 = {fmt_number(th)}°"]
        # Methods of one group may differ in ladder (a yardstick's own reference run is left out of it;
        # files of other sweeps), reference and drift run: one line per each, naming its methods when
        # there are several.
        ladders = _methods_by([r for r in rows if r.get("ladder_dt")], "order_t_end", "ladder_dt")
        for (t_end, dts), methods in ladders.items():
            who = f" of {', '.join(methods)}" if len(ladders) > 1 else ""
            lines.append(
                _cell(
                    f"  order{who}: final state at t = {fmt_number(t_end)} s, dt = {max(dts):.3g} … "
                    f"{min(dts):.3g} s ({ladder_words(dts)})",
                    width,
                ).rstrip()
            )
        references = _methods_by([r for r in rows if r.get("ladder_dt")], "reference")
        for (reference,), methods in references.items():
            who = f" of {', '.join(methods)}" if len(references) > 1 else ""
            lines.append(_cell(f"  reference{who}: {reference}", width).rstrip())
        drifts = _methods_by([r for r in rows if r.get("dt") is not None], "dt", "t_end")
        for (dt, t_end), methods in drifts.items():
            mine = [r for r in rows if r["method"] in methods and (r.get("dt"), r.get("t_end")) == (dt, t_end)]
            steps = max((r["n_steps"] for r in mine if r.get("status") == 0), default=round(t_end / dt))
            who = f" of {', '.join(methods)}" if len(drifts) > 1 else ""
            lines.append(
                _cell(
                    f"  drift{who}: dt = {fmt_number(dt)} s over {fmt_number(t_end)} s ({steps:.3g} steps)", width
                ).rstrip()
            )
        if drifts:
            solved = solver_words(rows)
            if solved:
                lines.append(_cell(f"  implicit solvers, iterations a step (most in one): {solved}", width).rstrip())
        head = [_cell("method", cols[0]), _cell("invariant", cols[1]), _cell("measured order", cols[2])]
        lines.append(" ".join(head + [_cell("drift", drift_w), "crit"]))
        shown = set()
        for r in rows:
            new_method = r["method"] not in shown
            shown.add(r["method"])
            cells = [
                _cell(r["method"] if new_method else "", cols[0]),
                _cell(r["quantity"] or "—", cols[1]),
                _cell(fmt_order(r, short=True) if new_method else "", cols[2]),
                _cell(fmt_drift(r, short=True), drift_w),
                _cell(fmt_threshold(r) if new_method else "", crit_w),
            ]
            lines.append(" ".join(cells).rstrip())
    return "\n".join(lines).lstrip("\n")


def parse_at(items):
    """{'f': Hz, 'theta0': deg} from ``--at f=50 theta0=45`` (also 'f=50,theta0=45'); VerdictError if bad."""
    out = {}
    for item in (x for arg in items or [] for x in arg.split(",") if x):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in ("f", "theta0"):
            raise VerdictError(f"--at {item}: expected f=<Hz> or theta0=<deg>")
        try:
            out[key] = float(value)
        except ValueError:
            raise VerdictError(f"--at {item}: {value!r} is not a number") from None
    return out


def select_at(datasets, at):
    """The datasets restricted to the (f, θ0) of ``at`` (values within 1e-9 relative); VerdictError when
    no file holds it."""
    if not at:
        return datasets
    out = []
    for name, ds in datasets:
        sel = {}
        for key, value in at.items():
            hits = [v for v in ds[key].values if math.isclose(float(v), value, rel_tol=1e-9, abs_tol=1e-12)]
            if not hits:
                break
            sel[key] = hits
        else:
            out.append((name, ds.sel(sel)))
    if not out:
        have = sorted({(float(f), float(t)) for _, ds in datasets for f in ds.f.values for t in ds.theta0.values})
        raise VerdictError(
            f"--at {' '.join(f'{k}={v:g}' for k, v in at.items())}: no file holds it; (f, theta0) held: "
            + ", ".join(f"({f:g}, {t:g})" for f, t in have[:12])
        )
    return out


# ---------------------------------------------------------------- CLI


def build_parser():
    p = argparse.ArgumentParser(
        prog="gyrolab-verdict", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("file", nargs="+", metavar="FILE", help="results files (or directories of them)")
    p.add_argument("--json", metavar="PATH", help="write the records as a JSON list")
    p.add_argument("--markdown", metavar="PATH", help="write the verdict tables as Markdown")
    p.add_argument(
        "--stability",
        metavar="T",
        type=float,
        help="also bisect the stability threshold over T seconds per (scene, method)",
    )
    p.add_argument(
        "--reference",
        choices=("auto", "closed_form", "yardstick", "dop853"),
        default="auto",
        help="reference of the order fits (default auto: closed form, yardstick run, DOP853)",
    )
    p.add_argument("--figures", metavar="DIR", help="draw verdict_<scene>.png into DIR")
    p.add_argument(
        "--at",
        nargs="+",
        metavar="K=V",
        help="judge only this group, e.g. --at f=50 theta0=45 (default: one verdict per (method, f, θ0) group)",
    )
    return p


def fail(message):
    sys.stderr.write(f"gyrolab-verdict: error: {' '.join(str(message).split())}\n")
    sys.exit(EXIT_BAD_INPUT)


def write_outputs(records, json_path=None, markdown_path=None, figures_dir=None, datasets=None):
    """Write the JSON list, the Markdown and the figures asked for; returns the paths written."""
    written = []
    if json_path:
        write_text(Path(json_path), json.dumps(jsonable(records), indent=1) + "\n")
        written.append(Path(json_path))
    if markdown_path:
        write_text(Path(markdown_path), markdown(records) + "\n")
        written.append(Path(markdown_path))
    if figures_dir:
        from .figures import draw_figures

        written += draw_figures(records, datasets or [], figures_dir)
    return written


@quiet_on_broken_pipe
def main(argv=None):
    args = build_parser().parse_args(argv)
    if args.stability is not None and not (math.isfinite(args.stability) and args.stability > 0):
        fail(f"--stability={args.stability}: must be a time > 0 s")
    for flag in ("json", "markdown"):
        path = getattr(args, flag)
        if path and not Path(path).resolve().parent.is_dir():
            fail(f"--{flag}={path}: no such directory {Path(path).resolve().parent}")
        if path:
            try:
                check_replaceable(path)
            except UnsafePathError as err:
                fail(err)
    try:
        at = parse_at(args.at)
        datasets = select_at(load(args.file), at)
        records = judge(datasets, stability=args.stability, reference=args.reference)
    except VerdictError as err:
        fail(err)
    print(table(records))
    try:
        written = write_outputs(records, args.json, args.markdown, args.figures, datasets)
    except UnsafePathError as err:
        fail(err)
    for path in written:
        print(f"gyrolab-verdict: wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
