"""Why seed_next's energy drifts (issue 11): a table of measured drift classes and rates.

    python benchmarks/seed_next_drift.py [--t-end 400]

Hypothesis: the RK4 update of ω with the torque frozen is not a Poisson map.
For a symmetric body (I1 = I2) with a frozen torque τ, Euler's equations are
linear: y = ω⊥ − ω*, ω* = (τ2, −τ1)/(I1 c), turns at the rate c = (1 − I3/I1) ω3,
and RK4 multiplies |y|² per step by g = |P(i c dt)|² = 1 − (c dt)⁶/72 + (c dt)⁸/576
(P the RK4 polynomial) instead of 1: the nutation part of ω is damped a little
every step, a secular loss of kinetic energy ½ I1 (g − 1) |y|² per step, on top of
the bounded kick–drift error.  Experiments:

1. seed_next as registered;
2. seed_next with the RK4 ω update replaced by the exact solution of the
   same frozen-torque linear ODE (rotation of y by −c dt), the body still
   rotated by CK(ω(t+dt) dt): isolates "RK4 is not Poisson";
3. lie_trotter: kick, then the exact free flow (kernels/methods/lie_trotter.py);
4. the prediction: the per-step loss ½ I1 (g − 1)|y|² summed along seed_next's
   own trajectory, divided by E0 and the run time;
5. the same on the torque-free disc (free_symmetric), where ω* = 0.

Rates are the classifier's (analysis/verdicts/classify.py): least-squares slope of the
windowed means of E/E0 − 1, in 1/s.  The issue's reference numbers: mean of the
last 5 s of 400 s = −1.30e-3 at 50 Hz, dt = 1e-3 s (−3.2e-6 /s).
"""

import argparse
import math
import time

import numpy as np
from numba import njit

from gyrolab.analysis.verdicts.classify import classify_drift
from gyrolab.kernels.methods import lie_trotter
from gyrolab.kernels.methods.seed_next import rk4_frozen_torque
from gyrolab.kernels.rigid_body import energy, gravity_torque
from gyrolab.kernels.rotation import rotate_body_step
from gyrolab.kernels.scenes import build_scene


@njit(cache=True, error_model="numpy")
def exact_frozen_torque(w, tau, dt, body):
    """ω(t+dt) of I ω̇ = τ − ω × Iω with τ frozen, exactly, for I1 = I2 (ω3 is constant)."""
    I1, _, I3, _ = body[:4]
    c = (1.0 - I3 / I1) * w[2]
    cc, sc = math.cos(c * dt), math.sin(c * dt)
    if c == 0.0:
        return w[0] + dt * tau[0] / I1, w[1] + dt * tau[1] / I1, w[2]
    s1, s2 = tau[1] / (I1 * c), -tau[0] / (I1 * c)  # ω* (steady state of the frozen system)
    y1, y2 = w[0] - s1, w[1] - s2
    return s1 + cc * y1 + sc * y2, s2 - sc * y1 + cc * y2, w[2]


@njit(cache=True, error_model="numpy")
def run(variant, w, q, dt, body, stride, n):
    """Energy samples (n,) every ``stride`` steps, and the predicted RK4 loss (J) summed over the run.

    variant 0: seed_next; 1: seed_next with the exact frozen-torque ω update; 2: lie_trotter.
    """
    out = np.empty(n)
    out[0] = energy(w, q, body)
    I1, I3 = body[0], body[2]
    loss = 0.0
    for k in range(1, n):
        for _ in range(stride):
            tau = gravity_torque(q, body)
            if variant == 2:
                w, q = lie_trotter.step(w, q, dt, body)
                continue
            c = (1.0 - I3 / I1) * w[2]
            th = c * dt
            g = 1.0 - th**6 / 72.0 + th**8 / 576.0
            if c != 0.0:
                y1, y2 = w[0] - tau[1] / (I1 * c), w[1] + tau[0] / (I1 * c)
                loss += 0.5 * I1 * (g - 1.0) * (y1 * y1 + y2 * y2)
            if variant == 0:
                w = rk4_frozen_torque(w, tau, dt, body)
            else:
                w = exact_frozen_torque(w, tau, dt, body)
            q = rotate_body_step(q, w[0] * dt, w[1] * dt, w[2] * dt)
        out[k] = energy(w, q, body)
    return out, loss


NAMES = {0: "seed_next", 1: "seed_next, exact ω", 2: "lie_trotter"}


def measure(scene, f, dt, t_end, variant, every=1e-2, **options):
    sc = build_scene(scene, f, 45.0 if scene == "heavy_top" else 30.0, **options)
    stride = round(every / dt)
    n = int(round(t_end / (stride * dt))) + 1
    e, loss = run(variant, sc.omega0, sc.q0, dt, sc.body, stride, n)
    t = np.arange(n) * stride * dt
    rel = e / e[0] - 1
    d = classify_drift(t, rel)
    last5 = float(np.mean(rel[t > t[-1] - 5.0]))
    return d, last5, loss / e[0] / t[-1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=400.0)
    args = ap.parse_args(argv)
    T = args.t_end
    rows = []
    # (label, scene, f, dt, variant)
    for variant in (0, 1, 2):
        rows.append(("A: the three schemes, 50 Hz, dt 1e-3", "heavy_top", 50.0, 1e-3, variant))
    for dt in (2e-3, 1e-3, 5e-4, 2.5e-4):
        rows.append(("B: dt scaling, 50 Hz", "heavy_top", 50.0, dt, 0))
    for f in (10.0, 20.0, 30.0, 50.0, 100.0):
        rows.append(("C: f scaling, dt 1e-3", "heavy_top", f, 1e-3, 0))
    for variant in (0, 1, 2):
        rows.append(("D: free disc, 50 Hz, wobble 0.1, dt 1e-3", "free_symmetric", 50.0, 1e-3, variant))
    t0 = time.perf_counter()
    section = None
    print(f"t_end = {T:g} s, θ0 = 45° released (free disc: θ0 = 30°), E sampled every 1e-2 s")
    hdr = (
        f"{'scheme':<20} {'f Hz':>5} {'dt s':>8} {'class':>11} {'rate 1/s':>11} {'±':>8} "
        f"{'predicted':>11} {'last 5 s':>10} {'max|e|':>9}"
    )
    fits = {"B": [], "C": []}
    for label, scene, f, dt, variant in rows:
        if label != section:
            section = label
            print(f"\n{label}\n{hdr}")
        d, last5, predicted = measure(scene, f, dt, T, variant)
        pred = f"{predicted:11.3e}" if variant == 0 else f"{'—':>11}"
        rate = f"{d.rate:11.3e}" if d.rate_unit == "1/s" else f"{'—':>11}"
        se = f"{d.rate_stderr:8.1e}" if d.rate_unit == "1/s" else f"{'':>8}"
        print(
            f"{NAMES[variant]:<20} {f:5g} {dt:8.2e} {d.drift_class:>11} {rate} {se} {pred} {last5:10.3e} "
            f"{d.amplitude:9.2e}"
        )
        if label[0] in fits and d.drift_class == "linear":
            fits[label[0]].append((dt if label[0] == "B" else f, abs(d.rate)))
    for key, what in (("B", "dt"), ("C", "f")):
        if len(fits[key]) >= 2:
            x, y = np.log([p[0] for p in fits[key]]), np.log([p[1] for p in fits[key]])
            print(f"\n|rate| ∝ {what}^{np.polyfit(x, y, 1)[0]:.2f} (log–log fit over the linear rows of {key})")
    print(f"\n{time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
