"""``gyrolab-advise``: the advisor on the command line (a table, ``--json PATH``, ``--figure PATH``).

    gyrolab-advise 0.0082 0.0082 0.0149 --omega 9 6 28 --dt 1e-3 --T 10 --metric orientation --tol 1e-3

Bad input: one line on stderr and exit status 2, before any work.
"""

import argparse
import json
import math
import sys
import time

import numpy as np

from ...kernels.parameters import split_names
from ...pipes import quiet_on_broken_pipe
from . import errors as E
from .advisor import ENGINES, NEAR_SEPARATRIX, AdviceError, advise
from .calibrate import DEFAULT_METHODS
from .model import EPS_FLOOR, RHO_RANGE

WIDTH = 120


def _g(x, fmt=".2e"):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else ("inf" if x == math.inf else f"{x:{fmt}}")


def _steps(n, dt):
    return "never" if not math.isfinite(n) else f"{n:.4g} ({n * dt:.3g} s)"


def _separatrix_lines(a):
    """The note for a free body near its separatrix: the intermediate axis's instability, and that the
    measurement decides (advisor.NEAR_SEPARATRIX)."""
    d, lam = a.separatrix_distance, a.intermediate_axis_rate
    if not (d < NEAR_SEPARATRIX):  # NaN: no separatrix
        return []
    last = ";" if a.metric in ("orientation", "omega") and d > 0 else ")"
    if d == 0:
        growth = lam * a.T
        factor = f"x{math.exp(growth):.2g}" if growth < 700 else "past any float"
        out = [
            "(omega0 is on the separatrix: a spin about the intermediate axis, which the updates keep (w x Iw = 0)",
            f" but any perturbation leaves: it grows e-fold every {1 / lam:.3g} s, {factor} over T{last}",
        ]
    else:
        out = [
            f"(omega0 is {d:.2g} from the separatrix, relative to its distance from the pole axis: the body flips,",
            f" lingering by the intermediate axis, where a perturbation grows e-fold every {1 / lam:.3g} s{last}",
        ]
    if last == ";":
        out += [
            " when it flips hangs on that distance, and the predicted orientation and omega errors this close",
            " can be off by 10x-1e4x either way: the measurement decides)",
        ]
    return out


def table(a):
    """The advice as lines of at most WIDTH characters."""
    out = []
    I = ", ".join(f"{v:.4g}" for v in a.inertia)
    w = ", ".join(f"{v:.4g}" for v in a.omega0)
    out.append(
        f"body I = ({I}) kg m^2" + (f", M g c = {tuple(a.mgc)} N m" if any(a.mgc) else "") + f"; omega0 = ({w}) rad/s"
    )
    eps = "0 (a principal axis)" if a.shape["eps"] <= EPS_FLOOR else f"{a.shape['eps']:.3g}"
    rho = "inf (omega constant)" if a.shape["rho"] >= RHO_RANGE[1] else f"{a.shape['rho']:.3g}"
    out.append(f"|omega| dt = {a.h:.3g} at dt = {a.dt_bounds[1]:.3g} s, |omega| T = {a.tau:.3g} over T = {a.T:g} s")
    out.append(f"sin(omega, L) = {eps}, spins per omega period = {rho}")
    out.append(f"must be right: {a.metric} <= {a.tol:g}; reference: {a.reference}")
    if a.prediction_note:
        out.append(f"({a.prediction_note})")
    out += _separatrix_lines(a)
    out.append("")
    wm = max([14] + [len(r.method) + 1 for r in a.rows])  # the method column fits a variant's name
    head = (
        f"{'method':<{wm}}{'p':>2} {'ns/step':>8} {'dt (s)':>9} {'predicted':>10} {'measured':>10}"
        f" {'largest dt':>11} {'predicted':>10} {'measured':>10} {'cost (s)':>9} {'meets':>6}"
    )
    out.append(head)
    for r in a.rows:
        mark = " <- advice" if r.method == a.recommended else ""
        out.append(
            f"{r.method:<{wm}}{r.order:>2} {r.ns_per_step:>8.0f} {r.dt_user:>9.3g} {_g(r.predicted_at_user):>10}"
            f" {_g(r.measured_at_user):>10} {(f'{r.dt_largest:.3g}' if r.meets else 'none'):>11}"
            f" {_g(r.predicted_at_largest):>10} {_g(r.measured_at_largest):>10} {_g(r.cost_s, '.3g'):>9}"
            f" {('yes' if r.meets and not r.met_by_measurement else 'yes*' if r.meets else 'no'):>6}{mark}"
        )
    if any(r.met_by_measurement for r in a.rows):
        out.append("(yes*: predicted to miss at the user's dt, measured to meet there)")
    bases = sorted({r.constants_of for r in a.rows if r.constants_of})
    if bases:
        names = ", ".join(bases)
        out.append(f"(variants: predicted by their own steps on this body, with the calibrated constants of {names})")
    exact = [r.method for r in a.rows if r.free_exact]
    if exact:
        out.append(f"({', '.join(exact)}: the exact free flow in each step, so the error is rounding at any dt)")
    short = [r for r in a.rows if math.isfinite(r.measured_over_s) and r.measured_over_s < a.T * (1 - 1e-9)]
    if short:
        out.append(
            f"(measured over the first {min(r.measured_over_s for r in short):.3g} s of T; predicted over the same)"
        )
    out.append("")
    if a.recommended:
        ratio = a.recommended_measured / a.recommended_predicted if a.recommended_predicted else math.nan
        out.append(
            f"advice: {a.recommended} at dt = {a.recommended_dt:.4g} s: {a.metric} error predicted "
            f"{a.recommended_predicted:.2e}, measured {_g(a.recommended_measured)} (measured/predicted {ratio:.2f})"
        )
        if a.measured_advice and (a.measured_advice != a.recommended or a.measured_advice_dt != a.recommended_dt):
            out.append(
                f"measured advice: {a.measured_advice} at dt = {a.measured_advice_dt:.4g} s "
                f"(measured {a.measured_advice_error:.2e}: the advised dt missed, so it was cut by the measured "
                "error and the order)"
            )
    else:
        best = min(a.rows, key=lambda r: r.predicted_at_user if not math.isnan(r.predicted_at_user) else math.inf)
        out.append(
            f"advice: no method is predicted to meet {a.tol:g} within the step bounds; the most accurate "
            f"at dt = {best.dt_user:.3g} s is {best.method} ({_g(best.predicted_at_user)} predicted)"
        )
        if a.measured_advice:
            out.append(
                f"measured advice: {a.measured_advice} at dt = {a.measured_advice_dt:.4g} s "
                f"(measured {a.measured_advice_error:.2e}: predicted to miss, measured to meet)"
            )
    out.append(f"time: prediction {a.seconds_predict:.2f} s, measurement {a.seconds_measure:.1f} s")
    if a.engines:
        dt = a.dt_bounds[1]
        out.append("")
        out.append(
            f"engine updates on this body at dt = {dt:.3g} s (predicted by analysis/advice/predict.py; measured to "
            f"{min(a.T / dt, 2e5):.3g} steps):"
        )
        out.append(
            f"{'engine update':<18} {'kind':<19} {'blow-up predicted':>20} {'measured':>18} "
            f"{'dE/dt/E0 (1/s)':>14} {'flips lost pred|meas':>25}"
        )
        for e in a.engines:
            flips = "-"
            if e.flips_exact >= 1:
                flips = f"{e.flips_lost:.3g}|{_g(e.flips_lost_measured, '.3g')} of {e.flips_exact:.3g}"
            measured = _steps(e.blow_up_step_measured, dt) if not math.isnan(e.blow_up_step_measured) else "-"
            out.append(
                f"{e.method:<18} {e.kind:<19} {_steps(e.blow_up_step, dt):>20} {measured:>18} "
                f"{e.energy_drift_per_s:>14.3e} {flips:>25}"
            )
            if e.relaxation:
                out.append(f"{'':<18} relaxes: {e.relaxation}")
    return [line[:WIDTH] for line in out]


def figure(a, path):
    """Error against cost on the user's body: each method's predicted line over dt, its measured
    points, the tolerance, the advice; written atomically to ``path``."""
    import matplotlib.pyplot as plt

    from ...safe_files import atomic_replace
    from . import model

    Om = a.h / a.dt_bounds[1]
    fig, ax = plt.subplots(figsize=(8, 5.5), layout="constrained")
    for k, r in enumerate(a.rows):
        colour = f"C{k}"
        h_user = Om * r.dt_user
        h = np.geomspace(min(h_user, Om * r.dt_largest if r.meets else h_user) / 30, 0.5, 80)
        err = model.predicted_error(1.0, r.growth, r.exponent or r.order, h, a.tau, a.rounding_per_step)
        cost = a.T / (h / Om) * r.ns_per_step * 1e-9
        # solid where the model holds, dotted past its regime (model.SATURATED), none past the largest error
        # the metric can have (an attitude error is at most π rad)
        cap = math.pi if a.metric == "orientation" else math.inf
        inside = np.where(err <= model.SATURATED, err, np.nan)
        beyond = np.where((err >= model.SATURATED) & (err <= cap), err, np.nan)
        ax.loglog(cost, inside, "-", color=colour, lw=1.2, label=f"{r.method} (order {r.order}) predicted")
        ax.loglog(cost, beyond, ":", color=colour, lw=1.2)
        pts = [(r.dt_user, r.measured_at_user)] + ([(r.dt_largest, r.measured_at_largest)] if r.meets else [])
        for dt, e in pts:
            if math.isfinite(e) and e > 0:
                ax.loglog(a.T / dt * r.ns_per_step * 1e-9, e, "o", color=colour, ms=6, mfc="white", mew=1.5)
        if math.isfinite(r.measured_at_corrected):
            ax.loglog(r.cost_s, r.measured_at_corrected, "s", color=colour, ms=6, mfc="white", mew=1.5)
        if r.method == a.measured_advice and math.isfinite(a.measured_advice_error):
            ax.loglog(
                a.T / a.measured_advice_dt * r.ns_per_step * 1e-9,
                a.measured_advice_error,
                "*",
                color=colour,
                ms=16,
                mec="k",
                label=f"advice after measuring: {r.method}, dt = {a.measured_advice_dt:.3g} s",
            )
    if 0 < a.separatrix_distance < NEAR_SEPARATRIX and a.metric in ("orientation", "omega"):
        ax.text(
            0.02,
            0.02,
            f"{a.separatrix_distance:.2g} from the separatrix: the prediction can be off 10x-1e4x;"
            " the measurement decides",
            transform=ax.transAxes,
            fontsize=8,
            color="0.3",
        )
    ax.axhline(a.tol, color="k", ls="--", lw=1)
    ax.text(ax.get_xlim()[1], a.tol, f"tolerance {a.tol:g}  ", va="bottom", ha="right")
    ax.plot([], [], ":", color="gray", label=f"predicted past the model's regime (> {model.SATURATED:g})")
    ax.plot([], [], "o", color="gray", mfc="white", label="measured at the user's and the advised dt")
    if any(math.isfinite(r.measured_at_corrected) for r in a.rows):
        ax.plot([], [], "s", color="gray", mfc="white", label="measured again at a dt cut by the measured error")
    ax.set_xlabel(f"cost: wall time of the {a.T:g} s horizon (s, from ns/step measured in calibration)")
    unit = " (rad)" if a.metric == "orientation" else " (relative)"
    ax.set_ylabel(f"largest {a.metric} error over T{unit}")
    I = ", ".join(f"{v:.3g}" for v in a.inertia)
    ax.set_title(
        f"I = ({I}) kg m², |ω0| = {np.linalg.norm(a.omega0):.3g} rad/s, T = {a.T:g} s: error against cost", fontsize=10
    )
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    atomic_replace(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    plt.close(fig)


@quiet_on_broken_pipe
def main(argv=None):
    """The ``gyrolab-advise`` command."""
    ap = argparse.ArgumentParser(
        prog="gyrolab-advise",
        description="Which rotation update, at which step, at what cost, for your body: predicted, then measured.",
    )
    ap.add_argument("inertia", nargs=3, type=float, metavar="I", help="principal moments (kg m^2)")
    ap.add_argument("--omega", nargs=3, type=float, metavar="W", help="initial body rates (rad/s)")
    ap.add_argument("--omega-max", type=float, help="|omega| (rad/s), with --axis")
    ap.add_argument(
        "--axis",
        nargs=3,
        type=float,
        default=(1.0, 1.0, 1.0),
        metavar="A",
        help="direction of omega in the body with --omega-max (default 1 1 1)",
    )
    ap.add_argument(
        "--mgc",
        nargs=3,
        type=float,
        default=(0.0, 0.0, 0.0),
        metavar="C",
        help="M g times the centre of mass, body frame (N m; default 0: a free body)",
    )
    step = ap.add_mutually_exclusive_group(required=True)
    step.add_argument("--dt", type=float, help="the time step (s)")
    step.add_argument("--dt-range", nargs=2, type=float, metavar=("LO", "HI"), help="allowed time steps (s)")
    step.add_argument("--budget", type=float, help="wall-clock budget for the horizon (s)")
    ap.add_argument("--T", type=float, required=True, help="horizon (s)")
    ap.add_argument(
        "--metric", default="orientation", help=f"what must be right: {', '.join(E.METRICS)} (default orientation)"
    )
    ap.add_argument("--tol", type=float, default=1e-3, help="tolerance (rad for orientation, else relative)")
    ap.add_argument(
        "--methods",
        default=",".join(DEFAULT_METHODS),
        help="comma-separated methods to choose among; a calibrated method's variant too, e.g. lie_poisson(axes=S-M-L)",
    )
    ap.add_argument("--engines", default=",".join(ENGINES), help="comma-separated engine updates to report ('' none)")
    ap.add_argument("--predict-only", action="store_true", help="skip the measurement")
    ap.add_argument("--json", metavar="PATH", help="write the advice as JSON")
    ap.add_argument("--figure", metavar="PATH", help="write error against cost as PNG")
    args = ap.parse_args(argv)
    from ...safe_files import UnsafePathError, check_output

    try:
        if (args.omega is None) == (args.omega_max is None):
            raise AdviceError("give --omega W1 W2 W3 or --omega-max W (with --axis)")
        if args.omega is not None:
            omega0 = np.array(args.omega)
        else:
            axis = np.array(args.axis)
            if not (np.all(np.isfinite(axis)) and np.any(axis)) or not (
                math.isfinite(args.omega_max) and args.omega_max > 0
            ):
                raise AdviceError(
                    f"--omega-max {args.omega_max} --axis {axis.tolist()}: need |omega| > 0 and a non-zero axis"
                )
            omega0 = args.omega_max * axis / np.linalg.norm(axis)
        for path in (args.json, args.figure):
            if path:
                check_output(path)
        started = time.perf_counter()
        last = [0.0]

        def progress(text):
            print(f"\r[{time.perf_counter() - started:5.1f} s] {text:<60}", end="", file=sys.stderr, flush=True)
            last[0] = 1

        a = advise(
            args.inertia,
            omega0,
            args.T,
            dt=args.dt,
            dt_range=args.dt_range,
            budget=args.budget,
            metric=args.metric,
            tol=args.tol,
            mgc=args.mgc,
            methods=split_names(args.methods),
            engines=[m for m in args.engines.split(",") if m],
            measure=not args.predict_only,
            progress=progress,
        )
        if last[0]:
            print(file=sys.stderr)
    except (AdviceError, UnsafePathError) as err:
        print(f"gyrolab-advise: error: {err}", file=sys.stderr)
        return 2
    print("\n".join(table(a)))
    if args.json:
        from ...safe_files import write_text

        write_text(args.json, json.dumps(a.to_dict(), indent=1, default=float) + "\n")
    if args.figure:
        figure(a, args.figure)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
