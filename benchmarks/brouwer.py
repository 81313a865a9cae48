"""Brouwer's law for rotation: the energy error of a splitting over 1e8 steps, plain and compensated (issue 22, item 4).

    python benchmarks/brouwer.py [--steps 1e8] [--runs 16] [--seed 1] [--figure docs/brouwer.png]
    python benchmarks/brouwer.py --forms plain    # the plain runs only: minutes, not the better part of an hour
    python benchmarks/brouwer.py --scenes heavy_top --methods split6_exact --forms compensated --runs 32 --seed 2 \
        --save runs/                              # each ensemble's errors to runs/<scene>_<method>_<form>_seed2.npz
    python benchmarks/brouwer.py --combine runs/heavy_top_split6_exact_compensated_seed*.npz   # one fit of them all

Round-off in a symplectic integrator whose truncation error is below rounding grows as a random walk,
|ΔE| ∝ √t (Brouwer 1937), when every rounding is unbiased; a rounding that goes the same way step
after step makes it grow as t.  The best N-body codes reach √t by accumulating the state with
error-free (compensated) sums (IAS15: Rein & Spiegel, MNRAS 446 (2015) 1424, §2.3; WHFast: Rein &
Tamayo, MNRAS 452 (2015) 376, §3.3).  This script runs a seeded ensemble of runs (initial body rates
perturbed by 1e-9 relative, so that each run rounds differently) of

- the registered methods ``lie_poisson4`` and ``split6_exact`` (kernels/methods), plain: ω and q
  overwritten by each flow;
- the same methods with the state compensated (kernels/compensated.py: ω and q kept as a sum hi + lo,
  each flow applied as an increment added error-free, rotations as a product with q in the form
  1 + (α, u), turns of ω by three shears (a symmetric body's by one rotation exact to ~eps²) and the
  elliptic flow's change of ω from the increments of sn, cn, dn),

on the 50 Hz heavy top (θ0 = 45°, released) and on the tennis-racket box (free_asymmetric, f = 1 Hz,
spun near its intermediate axis), both at dt = 2.5e-5 s, where the energy oscillation of the
truncation error is below the round-off being measured (at 1e-4 s lie_poisson4's is ~1e-15 on the top,
which hides the walk for the first 1e8 steps).  The energy of a compensated state is evaluated from
hi + lo in numpy's long double (a 64-bit significand here), since evaluating E in double rounds at
~1e-16, above the walk; the plain runs' errors are far above that and come from integrate() itself.
Each compensated method's loop here is checked bit for bit against the same variant run by
integrate() (the registered kernels).

It fits the ensemble's root-mean-square |E/E0 − 1| against t on a log-log scale from 1 % of the run
to its end: Brouwer's law is a slope 0.5, a rounding bias 1.  The slope's interval is the 95 % range
over bootstrap resamples of the ensemble's runs.  Prints one line per (scene, method, form) with the
slope, the RMS at the end and the CPU time per step (wall × threads / steps; both forms through the
one-by-one path), and draws the RMS curves.  On the racket split6_exact has no kicks: its step is seven
exact elliptic free flows, compensated as the increments of ω they make (kernels/euler_poinsot.py
``free_flow_increment``).

An ensemble of a few dozen runs leaves the slope uncertain by ~0.1 and takes the better part of an hour;
``--save DIR`` keeps each ensemble's per-run errors (|E/E0 − 1| at every sample, the sample times, the
scene, method, form, dt, steps and seed), and ``--combine FILE ...`` fits the union of ensembles saved with
different seeds (the same scene, method, form, dt and steps) without running anything: ensembles grow across
sessions.  Two files of one seed share their first runs (the seed's draws in order), so the union refuses them,
and ``--save`` refuses to replace a saved ensemble (before it runs anything).
"""

import argparse
import itertools
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

from gyrolab.kernels.batch import integrate
from gyrolab.kernels.driver import ENERGY, FIELDS
from gyrolab.kernels.registry import get_method
from gyrolab.kernels.scenes import build_scene
from gyrolab.safe_files import atomic_write

SCENES = {  # scene: (f Hz, θ0 deg, dt s)
    "heavy_top": (50.0, 45.0, 2.5e-5),
    "free_asymmetric": (1.0, 0.0, 2.5e-5),
}
METHODS = ("lie_poisson4", "split6_exact")
OMEGA = FIELDS.index("omega_1")


COMPENSATED = "(accumulate=compensated)"  # the variant of each method (kernels/compensated.py)


def _runner(step_carried, start):
    """run(w0, q0, body, dt, stride, n_samples, out): out[i, k] = (ω, ωl, q, ql) after k·stride steps of
    run i by the carried step of a compensated variant; the low parts are what integrate() cannot store."""

    @njit(parallel=True, error_model="numpy")
    def run(w0, q0, body, dt, stride, n_samples, out):
        for i in prange(w0.shape[0]):
            w = (w0[i, 0], w0[i, 1], w0[i, 2])
            q = (q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3])
            c = start(w, q, body)
            for k in range(n_samples):
                if k:
                    for _ in range(stride):
                        w, q, c = step_carried(w, q, c, dt, body)
                wl, ql = c
                for j in range(3):
                    out[i, k, j] = w[j]
                    out[i, k, 3 + j] = wl[j]
                for j in range(4):
                    out[i, k, 6 + j] = q[j]
                    out[i, k, 10 + j] = ql[j]

    return run


_RUNNERS = {}


def run_compensated(method, w0, q0, body, dt, stride, n_samples):
    """(runs, n_samples, 14) states (ω, ωl, q, ql) of the method's compensated variant; its ω is checked
    bit for bit against the same variant run by integrate() (the registered kernels) at the first sample."""
    module = get_method(method + COMPENSATED)
    if method not in _RUNNERS:
        _RUNNERS[method] = _runner(module.step_carried, module.start)
    out = np.empty((w0.shape[0], n_samples, 14))
    _RUNNERS[method](w0, q0, body, dt, stride, n_samples, out)
    ref, status, _ = integrate(
        method + COMPENSATED, body[None], w0[:1], q0[:1], np.full(1, dt), np.full(1, stride), 2, 1e9
    )
    first = ref[0, 1, OMEGA : OMEGA + 3]
    if not np.array_equal(first, out[0, 1, 0:3]):
        raise SystemExit(f"{method}{COMPENSATED}: this script's loop and integrate() differ: {first} {out[0, 1, 0:3]}")
    return out


def _warm_up(method, form, body, w0, q0, dt):
    """Load (or compile) the kernels before the timed run, so that ns/step is the integration alone."""
    if form == "plain":
        integrate(method, body[None], w0[:1], q0[:1], np.full(1, dt), np.ones(1, np.int64), 2, 1e9, path="runs")
    else:
        run_compensated(method, w0[:1], q0[:1], body, dt, 1, 2)


def up_in_body_extended(q):
    """γ = Rᵀ ẑ, the lab vertical in body coordinates, as (γ1, γ2, γ3) of quaternions q (..., 4) in numpy's
    long double, q normalised first."""
    q = q.astype(np.longdouble)
    q = q / np.sqrt(np.sum(q * q, axis=-1))[..., None]
    a, b, c, d = np.moveaxis(q, -1, 0)
    return 2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - b * b - c * c


def energy_extended(w, q, body):
    """E (J) of states ω (..., 3) and q (..., 4) in numpy's long double (64-bit significand here), q
    normalised first: the energy of the state itself, below the double rounding of evaluating it."""
    w = w.astype(np.longdouble)
    g1, g2, g3 = up_in_body_extended(q)
    I = body.astype(np.longdouble)
    kinetic = (I[0] * w[..., 0] ** 2 + I[1] * w[..., 1] ** 2 + I[2] * w[..., 2] ** 2) / 2
    return kinetic + I[3] * g3 + I[4] * g1 + I[5] * g2


def ensemble(scene, runs, seed, perturbation=1e-9):
    """(body, ω0 (runs, 3), q0 (runs, 4), dt): the scene's initial state, ω perturbed by ``perturbation`` relative
    (normal, per component)."""
    f, theta0, dt = SCENES[scene]
    sc = build_scene(scene, f, theta0)
    rng = np.random.default_rng(seed)
    w0 = np.array(sc.omega0) * (1.0 + perturbation * rng.standard_normal((runs, 3)))
    q0 = np.tile(np.array(sc.q0), (runs, 1))
    return np.array(sc.body, dtype=np.float64), w0, q0, dt


def rms_slope(t, e, rng, lo=0.01, n_boot=200):
    """Slope of log RMS_runs|e| against log t over t ≥ lo·t_end, and its 95 % bootstrap interval over runs."""
    keep = t >= lo * t[-1]
    lt = np.log(t[keep])

    def slope(rows):
        r = np.sqrt(np.mean(e[rows][:, keep] ** 2, axis=0))
        ok = r > 0
        return np.polyfit(lt[ok], np.log(r[ok]), 1)[0]

    s = slope(np.arange(e.shape[0]))
    boot = [slope(rng.integers(0, e.shape[0], e.shape[0])) for _ in range(n_boot)]
    return s, np.percentile(boot, [2.5, 97.5])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=float, default=1e8, help="steps per run (default 1e8)")
    ap.add_argument("--runs", type=int, default=16, help="runs in each compensated ensemble (default 16)")
    ap.add_argument(
        "--plain-runs", type=int, default=4, help="runs of each plain one (default 4: its slope 1 is plain)"
    )
    ap.add_argument("--samples", type=int, default=1000, help="energy samples per run (default 1000)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--dt", type=float, default=None, help="step (s) for every scene instead of its own")
    ap.add_argument("--verbose", action="store_true", help="print each RMS curve at nine times")
    ap.add_argument("--figure", default=None, help="PNG of the RMS curves (default: none)")
    ap.add_argument(
        "--forms", default="plain,compensated", help="plain and/or compensated (default both; plain alone is minutes)"
    )
    ap.add_argument("--save", default=None, help="directory for each ensemble's per-run errors (.npz)")
    ap.add_argument("--combine", nargs="+", default=None, help="fit the union of ensembles saved by --save; no runs")
    args = ap.parse_args(argv)
    if args.figure and not args.figure.endswith(".png"):
        ap.error("--figure: a .png path")
    if args.combine:
        curve, args.dt = combine(args.combine, np.random.default_rng(args.seed), args.verbose)
        if args.figure:
            _figure([curve], args)
        return
    if min(args.runs, args.plain_runs) < 2 or args.samples < 10 or args.steps < args.samples:
        ap.error("--runs and --plain-runs take at least 2 runs, --samples at least 10, --steps at least --samples")
    for given, known in ((args.scenes, SCENES), (args.methods, METHODS)):
        unknown = [x for x in given.split(",") if x not in known]
        if unknown:
            ap.error(f"{unknown[0]!r}: choose from {', '.join(known)}")
    forms = args.forms.split(",")
    if not forms or any(f not in ("plain", "compensated") for f in forms):
        ap.error(f"--forms {args.forms!r}: plain and/or compensated, comma-separated")
    if args.save:  # before an hour of runs: a directory we can write and no ensemble of this seed to replace
        where = Path(args.save)
        try:
            where.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            ap.error(f"--save {args.save}: {err.strerror}")
        for scene, method, form in itertools.product(args.scenes.split(","), args.methods.split(","), forms):
            if ensemble_path(where, scene, method, form, args.seed).exists():
                ap.error(f"--save: {ensemble_path(where, scene, method, form, args.seed)} exists: another --seed")
    n = args.samples + 1
    stride = max(1, round(args.steps / args.samples))
    rng = np.random.default_rng(args.seed)
    curves = []
    steps = stride * args.samples
    print(
        f"{args.runs} runs compensated, {args.plain_runs} plain, {steps:.3g} steps each; "
        "RMS over the runs of |E/E0 − 1|, fitted from 1 % of t_end"
    )
    head = f"{'scene':<16} {'method':<13} {'state':<12} {'runs':>4} {'slope':>6} {'95 %':>15}"
    print(f"{head} {'RMS at end':>11} {'mean at end ± s.e.':>21} {'CPU ns/step':>11}")
    for scene in args.scenes.split(","):
        body, w0, q0, dt = ensemble(scene, max(args.runs, args.plain_runs), args.seed)
        dt = args.dt or dt
        t = np.arange(n) * stride * dt
        for method in args.methods.split(","):
            for form in forms:
                _warm_up(method, form, body, w0, q0, dt)
                t0 = time.perf_counter()
                runs = args.plain_runs if form == "plain" else args.runs
                if form == "plain":
                    out, status, _ = integrate(
                        method, np.tile(body, (runs, 1)), w0[:runs], q0[:runs], np.full(runs, dt),
                        np.full(runs, stride), n, 1e9, path="runs",
                    )  # fmt: skip
                    assert (status == 0).all(), status
                    E = out[:, :, ENERGY].astype(np.longdouble)  # the plain error is far above double rounding
                else:
                    states = run_compensated(method, w0[:runs], q0[:runs], body, dt, stride, n)
                    w = states[..., 0:3].astype(np.longdouble) + states[..., 3:6]
                    q = states[..., 6:10].astype(np.longdouble) + states[..., 10:14]
                    E = energy_extended(w, q, body)
                wall = time.perf_counter() - t0
                e = np.asarray(E[:, 1:] / E[:, :1] - 1, dtype=np.float64)
                cost = wall * 1e9 * min(numba.get_num_threads(), runs) / (runs * steps)
                curves.append(report(scene, method, form, t[1:], e, rng, args.verbose, cost))
                if args.save:
                    key = {"scene": scene, "method": method, "form": form, "dt": dt, "steps": steps}
                    save_ensemble(Path(args.save), key, args.seed, t[1:], e)
    if args.figure:
        _figure(curves, args)


def report(scene, method, form, t, e, rng, verbose=False, cost=None):
    """Print the ensemble's row (slope and its 95 % interval, RMS and mean ± s.e. at the end, CPU ns per
    step) and, ``verbose``, its RMS curve at nine times; return the figure's curve."""
    runs = e.shape[0]
    s, (a, b) = rms_slope(t, e, rng)
    rms = np.sqrt(np.mean(e**2, axis=0))
    fit = f"{s:6.3f} [{a:6.3f}, {b:6.3f}]"
    # a rounding bias moves every run the same way: the mean over the runs, against its standard error
    mean = f"{e[:, -1].mean():10.2e} ± {e[:, -1].std(ddof=1) / np.sqrt(runs):8.1e}"
    cost = "—" if cost is None else f"{cost:.1f}"  # a union of saved ensembles ran nothing here
    print(f"{scene:<16} {method:<13} {form:<12} {runs:4d} {fit} {rms[-1]:11.3e} {mean} {cost:>11}", flush=True)
    if verbose:
        marks = np.unique(np.geomspace(1, rms.size, 9).astype(int)) - 1
        print("    RMS at t =", ", ".join(f"{t[m]:.3g} s: {rms[m]:.2e}" for m in marks))
    return scene, method, form, t, rms, s


ENSEMBLE_KEY = ("scene", "method", "form", "dt", "steps")  # what ensembles must share to be fitted as one


def ensemble_path(where, scene, method, form, seed):
    return where / f"{scene}_{method}_{form}_seed{seed}.npz"


def save_ensemble(where, key, seed, t, e):
    """Write one ensemble's errors e (runs, samples) at times t (s) to ``ensemble_path``, whole or not at all
    (gyrolab.safe_files)."""
    path = ensemble_path(where, key["scene"], key["method"], key["form"], seed)
    atomic_write(path, lambda fh: np.savez(fh, t=t, e=e, seed=seed, **key))
    print(f"    saved {e.shape[0]} runs to {path}")


def combine(paths, rng, verbose):
    """Fit the union of saved ensembles (``--save``): one row, as a run of all their runs would print it.  Returns
    the figure's curve and the ensembles' dt (s)."""
    key, seeds, t, errors = None, [], None, []
    for path in paths:
        try:
            with np.load(path) as f:
                this = {k: f[k].item() for k in ENSEMBLE_KEY}
                seed, tt, e = int(f["seed"]), f["t"], f["e"]
        except (OSError, KeyError, ValueError) as err:
            raise SystemExit(f"brouwer: {path}: not an ensemble saved by --save ({err})") from None
        if key is None:
            key, t = this, tt
        elif this != key or not np.array_equal(tt, t):
            raise SystemExit(f"brouwer: {path}: {this} is not the ensemble of {paths[0]}: {key}")
        if seed in seeds:
            raise SystemExit(f"brouwer: {path}: seed {seed} twice; its runs would count twice")
        seeds.append(seed)
        errors.append(e)
    e = np.concatenate(errors)
    seeds = ", ".join(map(str, seeds))
    print(f"{e.shape[0]} runs of seeds {seeds}, {key['steps']:.3g} steps each at dt = {key['dt']:g} s")
    return report(key["scene"], key["method"], key["form"], t, e, rng, verbose), key["dt"]


def _figure(curves, args):
    """One panel per scene: the RMS curves (plain dotted, compensated solid) and guides ∝ t and ∝ √t
    through the end of the highest plain and compensated curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gyrolab.analysis.io import save_figure

    scenes = list(dict.fromkeys(c[0] for c in curves))
    fig, axes = plt.subplots(1, len(scenes), figsize=(6.2 * len(scenes), 4.8), squeeze=False)
    colours = {"lie_poisson4": "tab:blue", "split6_exact": "tab:red"}
    for ax, scene in zip(axes[0], scenes):
        mine = [c for c in curves if c[0] == scene]
        for _, method, form, t, rms, s in mine:
            style = "-" if form == "compensated" else ":"
            ax.loglog(t, rms, style, color=colours.get(method, "k"), lw=1.4, label=f"{method}, {form}: slope {s:.2f}")
        t = mine[0][3]
        guides = (("plain", 1.0, "k-.", "∝ t (a rounding bias)"), ("compensated", 0.5, "k--", "∝ √t (Brouwer's law)"))
        for form, power, style, label in guides:
            ends = [c[4][-1] for c in mine if c[2] == form]
            if ends:
                ax.loglog(t, max(ends) * 1.6 * (t / t[-1]) ** power, style, lw=0.8, label=label)
        f, theta0, dt = SCENES[scene]
        ax.set_title(f"{scene}, f = {f:g} Hz, dt = {args.dt or dt:g} s")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("RMS over the runs of |E/E0 − 1|")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle("Energy round-off: state overwritten by each flow (dotted) or accumulated error-free (solid)")
    fig.tight_layout()
    print(f"figure: {save_figure(fig, args.figure)}")  # through a private temporary, never through a link


if __name__ == "__main__":
    main()
