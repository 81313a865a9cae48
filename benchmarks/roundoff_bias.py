"""Which rounding makes lie_poisson4's energy drift linearly at round-off level (issue 11)?

    python benchmarks/roundoff_bias.py [--t-end 200] [--dt 1e-4] [--f 50]

lie_poisson4 on the heavy top (θ0 = 45°, released, f = 50 Hz, dt = 1e-4 s) has
a truncation error far below rounding, yet E/E0 − 1 falls linearly
(−1.5e-15 /s).  This script copies the kernel (kernels/free_flow.py: kick and
the symmetric-body free_flow; kernels/methods/lie_poisson.py,
lie_poisson4.py; the rotation helpers) and changes one operation at a time;
variant 0 is the copy itself and is checked bit for bit against the
registered lie_poisson4.  Each variant's energy series is classified by
analysis/verdicts/classify.py.  Variants:

0  the copy, unchanged
1  free_flow: no quat_normalize at the end
2  libm cos/sin for every half angle instead of the Taylor polynomial
3  free_flow: ω⊥ turned by −c h with three shears (x += t y; y −= s x; x += t y,
   t = tan(ch/2), s = sin(ch)) instead of (cos, sin): each shear has
   determinant 1 whatever its rounded coefficient, so the map keeps a
   quadratic form within O(eps) of |ω⊥|² exactly — no per-step bias in |ω⊥|
4  free_flow: the (cos, sin) turn of ω⊥, then ω⊥ rescaled to its |ω⊥| before the turn
5  kick on L = Iω (L += h τ, ω = L/I) instead of ω += h τ/I
6  free_flow: cos(ch) = ch² − sh² instead of 1 − 2 sh²
7  free_flow: cos(ch), sin(ch) of the ω⊥ turn from libm at the full angle (c h)
8  variants 2 and 3 together
9  variant 3, and quat_normalize by one Newton step, q (3 − |q|²)/2, instead of q/√|q|²
10 variant 3, and the two small turns multiplied first: q ⊗ (q_v ⊗ q_e3) instead of (q ⊗ q_v) ⊗ q_e3
11 variant 3, and the kick on L = Iω (variant 5)

The table's σ is the wander left about the fitted drift (from the detrended
increments of the window means, 1/√s) and σ√T its size at the end of the
run: a drift whose rate·T is below σ√T no longer dominates the error.
"""

import argparse
import math
import time

import numpy as np
from numba import njit, prange

from gyrolab.analysis.verdicts.classify import classify_drift
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.rigid_body import energy, gravity_torque
from gyrolab.kernels.rotation import SMALL_ANGLE, _cos_sinc_half, quat_mul, quat_normalize
from gyrolab.kernels.scenes import build_scene

W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = 1.0 - 2.0 * W1
N_VARIANTS = 12
LABELS = (
    "copy of lie_poisson4",
    "no quat_normalize in free_flow",
    "libm half angles",
    "three-shear turn of ω⊥",
    "ω⊥ rescaled after its turn",
    "kick on L = Iω",
    "cos = ch² − sh²",
    "libm cos/sin(c h) for ω⊥",
    "libm half angles + shears",
    "shears + Newton normalise",
    "shears + small turns first",
    "shears + kick on L",
)


@njit(cache=True, error_model="numpy")
def _half_angle(phi, libm):
    if libm or not abs(phi) < SMALL_ANGLE:
        return math.cos(0.5 * phi), math.sin(0.5 * phi)
    c, s = _cos_sinc_half(phi * phi)
    return c, s * phi


@njit(cache=True, error_model="numpy")
def _quat_from_rotvec(v0, v1, v2, libm):
    angle2 = v0 * v0 + v1 * v1 + v2 * v2
    if not libm and angle2 < SMALL_ANGLE * SMALL_ANGLE:
        a, s = _cos_sinc_half(angle2)
    else:
        angle = math.sqrt(angle2)
        a = math.cos(0.5 * angle)
        s = math.sin(0.5 * angle) / angle if angle > 0.0 else 0.5
    return a, s * v0, s * v1, s * v2


@njit(cache=True, error_model="numpy")
def _kick(w, q, h, body, v):
    t1, t2, t3 = gravity_torque(q, body)
    if v == 5 or v == 11:
        L1, L2, L3 = body[0] * w[0] + h * t1, body[1] * w[1] + h * t2, body[2] * w[2] + h * t3
        return L1 / body[0], L2 / body[1], L3 / body[2]
    return w[0] + h * t1 * (1.0 / body[0]), w[1] + h * t2 * (1.0 / body[1]), w[2] + h * t3 * (1.0 / body[2])


@njit(cache=True, error_model="numpy")
def _free_flow(w, q, h, body, v):
    """kernels/free_flow.free_flow, symmetric branch (I1 = I2), with variant v."""
    I1, _, I3, _ = body[:4]
    libm = v == 2 or v == 8
    c = (1.0 - I3 / I1) * w[2]
    qv = _quat_from_rotvec(w[0] * h, w[1] * h, I3 / I1 * w[2] * h, libm)
    ch, sh = _half_angle(c * h, libm)
    if v == 10:
        q = quat_mul(q, quat_mul(qv, (ch, 0.0, 0.0, sh)))
    else:
        q = quat_mul(quat_mul(q, qv), (ch, 0.0, 0.0, sh))
    if v == 3 or v >= 8:
        t = sh / ch  # tan(c h / 2)
        s = 2.0 * sh * ch  # sin(c h)
        x, y = w[0], w[1]
        # rotate (x, y) by −c h: x' = cos x + sin y, y' = −sin x + cos y
        x = x + t * y
        y = y - s * x
        x = x + t * y
        wn = (x, y, w[2])
    else:
        if v == 6:
            cp = ch * ch - sh * sh
            sp = 2.0 * sh * ch
        elif v == 7:
            cp, sp = math.cos(c * h), math.sin(c * h)
        else:
            cp = 1.0 - 2.0 * sh * sh
            sp = 2.0 * sh * ch
        x, y = cp * w[0] + sp * w[1], -sp * w[0] + cp * w[1]
        if v == 4:
            r = math.sqrt((w[0] * w[0] + w[1] * w[1]) / (x * x + y * y))
            x, y = x * r, y * r
        wn = (x, y, w[2])
    if v == 1:
        return wn, q
    if v == 9:
        a, b, cq, d = q
        f = 1.5 - 0.5 * (a * a + b * b + cq * cq + d * d)
        return wn, (a * f, b * f, cq * f, d * f)
    return wn, quat_normalize(q)


@njit(cache=True, error_model="numpy")
def _strang(w, q, dt, body, v):
    w = _kick(w, q, 0.5 * dt, body, v)
    w, q = _free_flow(w, q, dt, body, v)
    return _kick(w, q, 0.5 * dt, body, v), q


@njit(cache=True, error_model="numpy")
def _step(w, q, dt, body, v):
    w, q = _strang(w, q, W1 * dt, body, v)
    w, q = _strang(w, q, W0 * dt, body, v)
    return _strang(w, q, W1 * dt, body, v)


@njit(cache=True, parallel=True, error_model="numpy")
def run_variants(variants, w0, q0, body, dt, stride, n, out, final):
    """out[i, k] = E after k·stride steps of variant variants[i]; final[i] = (ω, q) at the end."""
    for i in prange(variants.size):
        v = variants[i]
        w, q = (w0[0], w0[1], w0[2]), (q0[0], q0[1], q0[2], q0[3])
        out[i, 0] = energy(w, q, body)
        for k in range(1, n):
            for _ in range(stride):
                w, q = _step(w, q, dt, body, v)
            out[i, k] = energy(w, q, body)
        final[i, 0], final[i, 1], final[i, 2] = w
        final[i, 3], final[i, 4], final[i, 5], final[i, 6] = q


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=200.0)
    ap.add_argument("--dt", type=float, default=1e-4)
    ap.add_argument("--f", type=float, default=50.0)
    ap.add_argument("--variants", type=str, default=",".join(map(str, range(N_VARIANTS))))
    args = ap.parse_args(argv)
    sc = build_scene("heavy_top", args.f, 45.0)
    body = tuple(float(x) for x in sc.body)
    every = 1e-2
    stride = round(every / args.dt)
    n = int(round(args.t_end / every)) + 1
    variants = np.array([int(x) for x in args.variants.split(",")], dtype=np.int64)
    out = np.empty((variants.size, n))
    final = np.empty((variants.size, 7))
    t0 = time.perf_counter()
    run_variants(variants, np.array(sc.omega0), np.array(sc.q0), body, args.dt, stride, n, out, final)
    wall = time.perf_counter() - t0
    t = np.arange(n) * every
    print(
        f"lie_poisson4 variants, heavy top f = {args.f:g} Hz, θ0 = 45° released, dt = {args.dt:g} s, "
        f"{args.t_end:g} s ({n - 1} samples of {stride} steps); {wall:.1f} s"
    )
    if 0 in variants:
        ref, status, _ = integrate(
            "lie_poisson4", np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0]), args.dt, stride, n, 1e9
        )
        i0 = int(np.nonzero(variants == 0)[0][0])
        same = np.array_equal(ref[0, :, 6], out[i0])
        print(f"variant 0 bit-identical to the registered lie_poisson4's energy samples: {same}")
    marks = [T for T in (10.0, 50.0, 100.0, 200.0, 400.0, 1000.0) if T <= t[-1] + 1e-9]
    print(
        f"\n{'variant':<32} {'class':>11} {'rate':>11} {'unit':>10} {'±':>8} "
        + " ".join(f"{'<e> ' + format(T, 'g') + ' s':>11}" for T in marks)
        + f" {'z':>8} {'σ 1/√s':>9} {'σ√T':>9}"
    )
    for i, v in enumerate(variants):
        e = out[i] / out[i, 0] - 1
        d = classify_drift(t, e)
        means = " ".join(f"{np.mean(e[(t > T - 5) & (t <= T + 1e-9)]):11.3e}" for T in marks)
        # the wander about the drift: σ of the window means' increments, detrended (1/√s)
        m = e[-(t.size // d.n_windows) * d.n_windows :].reshape(d.n_windows, -1).mean(axis=1)
        inc = np.diff(m)
        sigma = math.sqrt(1.5 * np.var(inc) / d.window)
        print(
            f"{v:<2} {LABELS[v]:<30} {d.drift_class:>11} {d.rate:11.3e} {d.rate_unit:>10} {d.rate_stderr:8.1e} "
            f"{means} {d.z_trend:8.1f} {sigma:9.2e} {sigma * math.sqrt(t[-1]):9.2e}"
        )


if __name__ == "__main__":
    main()
