"""Captions for the README's figures, every number computed from the data the figure is drawn from.

    python -m gyrolab.analysis.reports.captions --default outputs/<run>/results.h5 --seed multirun/<seed run> \\
        --work-precision outputs/<wp run>/work_precision.h5 --stability multirun/<stability run> \\
        -o docs/figure_captions.md

Each caption names the command that made its data and quotes only values read
from that file (worst relative errors over the run, closed-form bounds,
counts of diverged runs); nothing is typed in by hand, so a caption cannot
disagree with its figure.  A section whose input is not given is left out.
"""

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from ...results import open_results
from ...safe_files import UnsafePathError, check_output, write_text
from ..figures import yardstick
from ..io import invariant_error


def worst_error(ds, quantity, **at):
    """max_t relative error of ``quantity`` of one run (inf when it diverged)."""
    run = ds.sel(at)
    err = invariant_error(run, quantity)
    finite = err[np.isfinite(err)]
    return float(finite.max()) if finite.size and int(run.status) == 0 else math.inf


def fmt_error(x, digits=2):
    return "diverged" if not math.isfinite(x) else f"{x:.{digits}g}"


def _run_at(ds):
    return {"theta0": float(ds.theta0.values[0])}


def nutation_caption(path):
    ds = open_results(path)
    dt = float(ds.dt.values.min())
    parts = []
    for f in ds.f.values:
        nut = yardstick.nutation(ds, f, ds.theta0.values[0])
        if nut is None:
            continue
        th = (
            np.degrees(ds.theta.sel({"integrator": "seed_prev", "f": f, "dt": dt, **_run_at(ds)}).values)
            if "seed_prev" in ds.integrator.values
            else None
        )
        out = "" if th is None else (f"; seed_prev spans {np.nanmin(th):.1f}°–{np.nanmax(th):.1f}° over the run")
        parts.append(
            f"f = {f:g} Hz: θ ∈ [{math.degrees(nut.theta_min):.2f}°, {math.degrees(nut.theta_max):.2f}°], "
            + (f"nutation period {nut.period * 1e3:.1f} ms" if math.isfinite(nut.period) else "an unstable vertical")
            + out
        )
    return (
        f"`gyrolab` (default study), `gyrolab-plot nutation {Path(path).name}`. θ(t) at the finest "
        f"dt = {dt:g} s (the others: `dt=...`), first and last three nutation periods, with the closed-form "
        "θ_min, θ_max dashed; a note names the methods whose curves lie on top of each other. " + "; ".join(parts) + "."
    )


def tip_caption(path):
    ds = open_results(path)
    dt = float(ds.dt.values.min())
    parts = []
    for f in ds.f.values:
        nut = yardstick.nutation(ds, f, ds.theta0.values[0])
        if nut is None:
            continue
        tmax = math.degrees(nut.theta_max)
        parts.append(
            f"{f:g} Hz: θ_max = {tmax:.1f}°"
            + (" (annulus drawn)" if tmax <= 90 else " (past the horizon: no bounding circles)")
        )
    return (
        f"`gyrolab-plot tip {Path(path).name}` (seed_next, dt = {dt:g} s, one turn of precession). The "
        "closed-form circles sin θ_min, sin θ_max are drawn only where they bound the trace (θ_max ≤ 90°); "
        "start, pivot and circles are in the legend. " + "; ".join(parts) + "."
    )


def energy_caption(path):
    ds = open_results(path)
    dt = float(ds.dt.values.max())
    lines = []
    for f in ds.f.values:
        vals = ", ".join(
            f"{m} {fmt_error(worst_error(ds, 'energy', integrator=m, f=f, dt=dt, **_run_at(ds)))}"
            for m in ds.integrator.values
        )
        lines.append(f"f = {f:g} Hz: {vals}")
    return (
        f"`gyrolab-plot energy {Path(path).name}` ({ds.integrator.size} methods × f = "
        f"{', '.join(f'{v:g}' for v in ds.f.values)} Hz × dt = {', '.join(f'{v:g}' for v in ds.dt.values)} s, "
        f"{float(ds.time[-1]):g} s). Running maximum of |E(t) − E0|/|E0|; worst values at dt = {dt:g} s: "
        + "; ".join(lines)
        + "."
    )


def invariants_caption(path):
    from ..io import drawable_invariants

    ds = open_results(path)
    dt = float(ds.dt.values.max())
    qs = drawable_invariants(ds)
    exact = [
        q
        for q in qs
        if all(
            worst_error(ds, q, integrator=m, f=f, dt=d, **_run_at(ds)) == 0
            for m in ds.integrator.values
            for f in ds.f.values
            for d in ds.dt.values
        )
    ]
    f = 10.0 if 10.0 in ds.f.values else float(ds.f.values[0])
    lz = (
        ", ".join(
            f"{m} {fmt_error(worst_error(ds, 'Lz', integrator=m, f=f, dt=dt, **_run_at(ds)))}"
            for m in ds.integrator.values
        )
        if "Lz" in qs
        else ""
    )
    return (
        f"`gyrolab-plot invariants {Path(path).name}`. One row per invariant the scene declares "
        f"({', '.join(qs)})"
        + (f"; {', '.join(exact)} kept exactly by every run, so no row (the figure says so)" if exact else "")
        + (f". Worst relative L_z error at f = {f:g} Hz, dt = {dt:g} s: {lz}." if lz else ".")
    )


def work_precision_caption(path):
    from ..figures.work_precision import reference_name, work_precision_data

    ds = open_results(path)
    data = work_precision_data(ds, retime=False, peers=False)
    key = max(data)
    dts = sorted({p[0] for pts in data[key]["methods"].values() for p in pts})
    dt = min(dts, key=lambda d: abs(math.log10(d / 1e-4)))
    errs = ", ".join(
        f"{m} {fmt_error(next(p[3] for p in pts if p[0] == dt))} rad" for m, pts in data[key]["methods"].items()
    )
    return (
        f"`gyrolab experiment=work_precision` ({ds.integrator.size} methods, f = "
        f"{', '.join(f'{v:g}' for v in ds.f.values)} Hz, dt = {dts[0]:g} … {dts[-1]:g} s, "
        f"{float(ds.time[-1]):g} s). Error = max deviation of the axis from {reference_name(ds)}; cost "
        "re-timed on one thread after JIT warm-up; scipy DOP853 and RK45 as peers. Right panels: method steps "
        "per simulated second, which are not equal work (a DOP853 step is 12 RHS evaluations, rk4 4 stages; "
        f"the figure says so). At f = {key[0]:g} Hz, dt = {dt:g} s: {errs}."
    )


def stability_caption(paths):
    from ..figures.stability import _logerr, default_measure

    out = []
    for path in paths:
        ds = open_results(path)
        th = float(ds.theta0.values[0])
        measure = default_measure(ds)
        bad = {str(m): int((ds.status.sel({"integrator": m, "theta0": th}) != 0).sum()) for m in ds.integrator.values}
        maps = {
            str(m): _logerr(ds.sel({"integrator": m, "theta0": th}).sortby("f").sortby("dt"), th, measure, ds)
            for m in ds.integrator.values
        }
        same = sorted(
            {
                tuple(sorted(k for k in maps if np.allclose(maps[k], v, atol=0.01, equal_nan=True)))
                for v in maps.values()
            }
        )
        same = [g for g in same if len(g) > 1]
        what = (
            "log10 worst relative energy error"
            if measure == "energy"
            else "log10 worst axis deviation (rad) from the exact Euler–Poinsot flow"
        )
        out.append(
            f"{ds.attrs.get('scene')}: {what}; diverged runs of {ds.f.size * ds.dt.size}: "
            + ", ".join(f"{m} {n}" for m, n in bad.items())
            + (f"; identical maps: {'; '.join(' = '.join(g) for g in same)}" if same else "")
        )
    return (
        "`gyrolab experiment=stability` (every pinned method over f × dt, 10 s each; "
        "grey cells with a red ×: diverged). " + ". ".join(out) + "."
    )


def seed_captions(directory):
    from ..figures.seed import load_jobs

    jobs = load_jobs([directory])
    lines = []
    for name, (ds, f) in jobs.items():
        at = {"f": f, "theta0": float(ds.theta0.values[0])}
        vals = ", ".join(
            f"dt = {d:g} s: seed_next {fmt_error(worst_error(ds, 'energy', integrator='seed_next', dt=d, **at))}, "
            f"seed_prev {fmt_error(worst_error(ds, 'energy', integrator='seed_prev', dt=d, **at))}"
            for d in ds.dt.values
        )
        lines.append(f"{name} ({f:g} Hz): {vals}")
    cusp = jobs.get("cusp")
    remark = ""
    if cusp is not None:
        ds = cusp[0]
        body = ds["body"].sel({"theta0": ds.theta0.values[0]})
        parts = []
        for f in (1.0, 10.0, 50.0):
            if f not in ds.f.values:
                continue
            I1, I2, I3, mgl = (float(v) for v in body.sel({"f": f}).values[:4])
            ratio = I3 * 2 * math.pi * f * f / (mgl * math.sin(math.radians(float(ds.theta0.values[0]))))
            nut = yardstick.nutation(ds, f, ds.theta0.values[0])
            parts.append(
                f"{f:g} Hz: L/ΔL = {ratio:.3g}, θ ∈ [{math.degrees(nut.theta_min):.1f}°, "
                f"{math.degrees(nut.theta_max):.1f}°]"
            )
        remark = "Remark 1 (`seed_remark1.png`), released at 45°: " + "; ".join(parts) + "."
    return (
        "`gyrolab experiment=seed_figures` (the seed_* PNGs; `gyrolab-plot seed <dir>` redraws them). "
        "Worst relative energy error over the run in the figure's panels (`seed_next_vs_prev.png`): "
        + "; ".join(lines)
        + ".",
        remark,
    )


def build(default=None, seed=None, work_precision=None, stability=()):
    """The markdown text of docs/figure_captions.md from the given inputs."""
    sections = []
    if seed:
        next_prev, remark = seed_captions(seed)
        sections += [("seed_next_vs_prev.png, seed_regimes.png", next_prev), ("seed_remark1.png", remark)]
    if default:
        sections += [
            ("nutation_theta.png", nutation_caption(default)),
            ("tip_locus.png", tip_caption(default)),
            ("energy_drift.png", energy_caption(default)),
            ("invariants.png", invariants_caption(default)),
        ]
    if work_precision:
        sections.append(("work_precision.png", work_precision_caption(work_precision)))
    if stability:
        sections.append(("stability_heavy_top.png, stability_free_asymmetric.png", stability_caption(stability)))
    body = "\n\n".join(f"### {name}\n\n{text}" for name, text in sections if text)
    return (
        "# Figure captions (generated)\n\nWritten by `python -m gyrolab.analysis.reports.captions`; every number is "
        "read from the results file the figure is drawn from.\n\n" + body + "\n"
    )


def _stability_files(paths):
    files = []
    for p in map(Path, paths):
        files += sorted(p.rglob("stability.h5")) if p.is_dir() else [p]
    return files


def main(argv=None):
    """``python -m gyrolab.analysis.reports.captions``: write the captions file."""
    p = argparse.ArgumentParser(
        prog="python -m gyrolab.analysis.reports.captions",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--default", help="results.h5 of the default study (`gyrolab`)")
    p.add_argument("--seed", help="multirun directory of experiment=seed_figures")
    p.add_argument("--work-precision", help="work_precision.h5 of experiment=work_precision")
    p.add_argument("--stability", nargs="*", default=[], help="stability.h5 files or the multirun directory")
    p.add_argument("-o", "--output", default="docs/figure_captions.md")
    args = p.parse_args(argv)
    try:
        check_output(args.output)
    except UnsafePathError as err:
        sys.stderr.write(f"captions: error: {err}\n")
        return 2
    text = build(args.default, args.seed, args.work_precision, _stability_files(args.stability))
    write_text(Path(args.output), text)
    print(f"captions: wrote {args.output}")
    return 0


if __name__ == "__main__":
    main()
