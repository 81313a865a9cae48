"""Measure the advisor's error constants once per method: ``python -m gyrolab.analysis.advice.calibrate``.

On CALIBRATION_BODIES free bodies drawn with seed CALIBRATION_SEED (``draw_bodies``: moments within
a factor 10 of each other, the body's scale over 5 decades, ω0 in a random direction, |ω0| over
3 decades; none of them the held-out bodies of tests/test_advise.py, which use another seed), each
method runs at the (h = Ω dt, τ = Ω T) of GRID; its errors (errors.py's metrics, against the exact
free flow) divided by model.py's probe prediction give κ (their median, in log space), using only
errors between FIT_RANGE (below: rounding; above: outside the asymptotic regime).  It also times each method's
step (ns per step of one run, on the block kernels; the machine's load average is stored with it).
Writes analysis/advice/error_constants.json (atomically).
"""

import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from ...kernels.batch import integrate
from ...kernels.body import N_FIELDS as N_BODY
from ...kernels.euler_poinsot import free_body
from ...kernels.reference import samples_from_states
from ...kernels.registry import METHODS
from . import errors as E
from .model import CONSTANTS_FILE, H_PROBE, SATURATED, growth_law

CALIBRATION_SEED = 1
CALIBRATION_BODIES = 120
GRID = ((0.1, 100.0), (0.03, 100.0), (0.1, 10.0), (0.01, 10.0))  # (h, τ)
FIT_RANGE = (1e-12, SATURATED)
N_SAMPLES = 101
# gyrolab's own schemes the advisor chooses among by default, and the other methods it can calibrate
DEFAULT_METHODS = ("rk4", "lie_poisson", "lie_poisson4")
# methods whose step is the exact free flow (FREE_EXACT): calibrated for their cost only
FREE_EXACT_METHODS = ("strang_exact",)
FITTED_METRICS = ("orientation", "omega", "energy", "L_norm")


def draw_bodies(seed, n):
    """n free bodies (I (n, 3) kg m², ω0 (n, 3) rad/s): moments within a factor 10 of each other,
    scale 1e-3 … 1e2 kg m², ω0 in a uniformly random direction, |ω0| 0.1 … 100 rad/s."""
    rng = np.random.default_rng(seed)
    scale = 10 ** rng.uniform(-3, 2, n)
    I = 10 ** rng.uniform(-1, 0, (n, 3)) * scale[:, None]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return I, d * 10 ** rng.uniform(-1, 2, n)[:, None]


def schedule(h, tau, omega_norm, n_samples=N_SAMPLES):
    """(dt (s), stride, T (s)) of runs at h = Ω dt over about τ = Ω T, T a whole number of samples."""
    steps = np.maximum(np.round(np.asarray(tau) / np.asarray(h)), n_samples - 1).astype(np.int64)
    stride = np.maximum(steps // (n_samples - 1), 1)
    dt = np.asarray(h) / np.asarray(omega_norm)
    return dt, stride, stride * (n_samples - 1) * dt


def measure(method, I, omega0, dt, stride, metrics, n_samples=N_SAMPLES, bodies=None):
    """Errors (B, len(metrics)) of ``method`` on B bodies (free unless ``bodies`` rows are given)
    from ω0 (B, 3) at dt (B,) s, sampled every ``stride`` steps: one ``integrate`` call, then the
    reference (errors.reference_samples) per body.  Also returns the wall time (s) of the call."""
    I = np.atleast_2d(I)
    B = I.shape[0]
    if bodies is None:
        bodies = np.zeros((B, N_BODY))
        bodies[:, :3] = I
    start = time.perf_counter()
    out, _, _ = integrate(
        method, bodies, omega0, np.tile(E.Q0, (B, 1)), dt, stride, n_samples, threshold=1e300, path="blocks"
    )
    wall = time.perf_counter() - start
    err = np.empty((B, len(metrics)))
    refs = None
    if not np.any(bodies[:, 3:]):
        # free bodies: one closed-form call for all, in units where each run's sampled span is 1
        # (ω(t) from ω0 is c ω(ct) from c ω0)
        span = (n_samples - 1) * stride * dt
        w, q = free_body(I, omega0 * span[:, None], np.tile(E.Q0, (B, 1)), np.linspace(0.0, 1.0, n_samples))
        refs = [samples_from_states(tuple(bodies[b]), w[b] / span[b], E.rotation_matrices(q[b])) for b in range(B)]
    for b in range(B):
        if refs is not None:
            ref = refs[b]
        else:
            ref, _ = E.reference_samples(bodies[b], omega0[b], E.Q0, np.arange(n_samples) * stride[b] * dt[b])
        for k, metric in enumerate(metrics):
            err[b, k] = E.run_errors(out[b : b + 1], ref, bodies[b], omega0[b], metric)[0]
    return err, wall


def ns_per_step(method, n_runs=64, steps=20_000):
    """Wall time per step of one run (ns), on the block kernels, 64 runs of a generic free body."""
    bodies = np.zeros((n_runs, N_BODY))
    bodies[:, :3] = (1.0, 2.0, 3.0)
    w = np.tile([0.3, 1.0, 0.5], (n_runs, 1))
    q = np.tile(E.Q0, (n_runs, 1))
    integrate(method, bodies, w, q, np.full(n_runs, 1e-3), 10, 2, path="blocks")  # compile / load
    start = time.perf_counter()
    integrate(method, bodies, w, q, np.full(n_runs, 1e-3), steps, 2, threshold=1e300, path="blocks")
    return (time.perf_counter() - start) / (n_runs * steps) * 1e9


def fit(method, I, omega0, progress=None):
    """The constants of one method: κ per metric, the median of measured / probe-predicted error over
    the calibration grid (errors within FIT_RANGE), and the share of points that κ puts within 2×."""
    order = METHODS[method].ORDER
    wn = np.linalg.norm(omega0, axis=1)
    if getattr(METHODS[method], "FREE_EXACT", False):
        # the exact Euler–Poinsot flow: a free body's error is rounding at any dt; its median per step
        # is every method's rounding floor
        per_step = {metric: [] for metric in FITTED_METRICS}
        for h, tau in GRID:
            dt, stride, T = schedule(np.full(len(wn), h), tau, wn)
            err, _ = measure(method, I, omega0, dt, stride, FITTED_METRICS)
            for k, metric in enumerate(FITTED_METRICS):
                per_step[metric].append(err[:, k] / (T / dt))
        rounding = {metric: float(np.median(np.concatenate(v))) for metric, v in per_step.items()}
        return {
            "order": order,
            "symplectic": METHODS[method].SYMPLECTIC,
            "free_exact": True,
            "kappa": {},
            "rounding_per_step": rounding,
        }
    logs = {metric: [] for metric in FITTED_METRICS}
    for h, tau in GRID:
        dt, stride, T = schedule(np.full(len(wn), h), tau, wn)
        err, _ = measure(method, I, omega0, dt, stride, FITTED_METRICS)
        law = growth_law(method, I, omega0, T, order)
        for k, metric in enumerate(FITTED_METRICS):
            e = err[:, k]
            g, q = law[metric]
            pred = g * (h / H_PROBE) ** q
            use = (e > FIT_RANGE[0]) & (e < FIT_RANGE[1]) & (pred > 0)
            logs[metric].append(np.log(e[use] / pred[use]))
        if progress:
            progress(f"{method}: h = {h}, tau = {tau}")
    kappa, within, n_points = {}, {}, {}
    for metric, parts in logs.items():
        r = np.concatenate(parts)
        if r.size < 20:
            continue
        med = float(np.median(r))
        kappa[metric] = math.exp(med)
        within[metric] = round(float(np.mean(np.abs(r - med) <= math.log(2))), 3)
        n_points[metric] = int(r.size)
    return {
        "order": order,
        "symplectic": METHODS[method].SYMPLECTIC,
        "kappa": kappa,
        "within_2x_calibration": within,
        "n_points": n_points,
    }


def main(argv=None):
    """Calibrate ``argv`` methods (default DEFAULT_METHODS) and write error_constants.json next to this file."""
    import argparse

    from ...safe_files import write_text

    ap = argparse.ArgumentParser(prog="python -m gyrolab.analysis.advice.calibrate", description=__doc__.split("\n")[0])
    ap.add_argument("--methods", default=",".join(DEFAULT_METHODS + FREE_EXACT_METHODS), help="comma-separated methods")
    ap.add_argument("--out", default=str(Path(__file__).with_name(CONSTANTS_FILE)), help="output JSON")
    args = ap.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        print(f"error: --methods: unknown {', '.join(unknown)}", file=sys.stderr)
        return 2
    out = Path(args.out)
    old = json.loads(out.read_text()) if out.is_file() else {"methods": {}}
    I, omega0 = draw_bodies(CALIBRATION_SEED, CALIBRATION_BODIES)
    for method in methods:
        start = time.perf_counter()
        entry = fit(method, I, omega0, progress=lambda s: print(f"  {s}", file=sys.stderr, flush=True))
        entry["ns_per_step"] = round(ns_per_step(method), 1)
        entry["load_average"] = round(os.getloadavg()[0], 2)
        old["methods"][method] = entry
        print(f"{method}: {time.perf_counter() - start:.0f} s, " + json.dumps(entry["kappa"]), file=sys.stderr)
    old["how"] = (
        f"python -m gyrolab.analysis.advice.calibrate: {CALIBRATION_BODIES} free bodies of draw_bodies(seed="
        f"{CALIBRATION_SEED}), (h, tau) in {list(GRID)}, kappa = median of measured / probe over errors in "
        f"{list(FIT_RANGE)}; "
        "ns_per_step on 64 runs of the block kernels, at the load average stored with it (2 cores)"
    )
    write_text(out, json.dumps(old, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
