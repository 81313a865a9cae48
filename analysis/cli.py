"""``gyrolab-plot KIND FILE [KEY=VALUE ...]``: figures from a stored results file.

    gyrolab-plot nutation results.h5 f=10,50 dt=1e-4       # θ(t) per method, closed-form bounds
    gyrolab-plot tip results.h5 method=seed_next f=50      # tip locus seen from above
    gyrolab-plot energy results.h5 --quantity Lz           # relative drift of E, Lz or L3
    gyrolab-plot invariants results.h5                     # E, Lz and L3 together
    gyrolab-plot work-precision work_precision.h5          # error vs cost, DOP853 as a peer
    gyrolab-plot stability stability.h5                    # log10 max energy error over dt x f
    gyrolab-plot animation results.h5 method=rk4 f=50      # GIF of the top
    gyrolab-plot seed multirun/<date>/<time>               # the write-up's figures from a seed_figures multirun
    gyrolab-plot standard results.h5                       # what the runner writes after a sweep

A selection is KEY=VALUE[,VALUE...] with KEY in method, f (Hz), theta0 (deg),
dt (s).  Output: -o PATH (default ``<kind>.png`` next to FILE); --format png
svg pdf for several.  Only ``work-precision`` runs anything (its DOP853 peer,
scipy, at several tolerances); every other kind reads the stored samples.
Bad input: one line on stderr naming the key and value, exit status 2,
no file written.
"""
import argparse
import sys
from pathlib import Path

EXIT_BAD_INPUT = 2


def _common(p, many=False):
    if many:
        p.add_argument("file", metavar="FILE_OR_DIR", nargs="+", help="results files or a multirun directory")
    else:
        p.add_argument("file", metavar="FILE", help="results file (HDF5, SPEC §4)")
        p.add_argument("selection", nargs="*", metavar="KEY=VALUE",
                       help="grid values to draw: method=..., f=... (Hz), theta0=... (deg), dt=... (s)")
    p.add_argument("-o", "--output", help="output path (suffix replaced per --format); default next to FILE")
    p.add_argument("--format", nargs="+", default=["png"], choices=["png", "svg", "pdf"],
                   help="file formats to write (default: png)")


def build_parser():
    parser = argparse.ArgumentParser(
        prog="gyrolab-plot", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Run `gyrolab-plot KIND --help` for each kind's options.")
    sub = parser.add_subparsers(dest="kind", metavar="KIND", required=True)
    p = sub.add_parser("nutation", help="θ(t) per method with the closed-form θ_min/θ_max",
                       description="θ(t) (deg) per method with the closed-form nutation bounds; "
                                   "first and last nutation periods of the run.")
    _common(p)
    p.add_argument("--periods", type=float, default=3.0, help="nutation periods per window (default 3)")
    p = sub.add_parser("tip", help="locus of the axis tip seen from above (write-up figs 6-9)",
                       description="Lab x, y of the unit symmetry axis for one method and dt, one panel per f.")
    _common(p)
    p.add_argument("--t-max", type=float, default=None, help="last time drawn (s); default one precession turn")
    p = sub.add_parser("energy", help="relative drift of E, L_z or L_3 vs time (log scale)",
                       description="|X(t) − X0|/|X0| per method (colour) and dt (line style), one panel per f.")
    _common(p)
    p.add_argument("--quantity", choices=["energy", "Lz", "L3"], default="energy")
    p.add_argument("--raw", action="store_true", help="raw error instead of its running maximum")
    p = sub.add_parser("invariants", help="E, L_z and L_3 drift in one figure")
    _common(p)
    p.add_argument("--raw", action="store_true", help="raw error instead of its running maximum")
    p = sub.add_parser("work-precision", help="error vs cost on log-log axes, DOP853 as a peer",
                       description="Error against the closed-form nutation (or DOP853) vs wall time per "
                                   "simulated second and steps; re-runs scipy DOP853/RK45 as peers.")
    _common(p)
    p.add_argument("--no-peers", action="store_true", help="do not run the scipy peers")
    p = sub.add_parser("stability", help="heatmap of log10 max energy error over dt x f per method")
    _common(p)
    p = sub.add_parser("animation", help="GIF of the top (disc, axis, tip trace) from a stored run")
    _common(p)
    p.add_argument("--seconds", type=float, default=None, help="simulated seconds shown (default: up to 2 s)")
    p.add_argument("--fps", type=int, default=20, help="frames per second of the GIF (default 20)")
    p = sub.add_parser("seed", help="the write-up's figures from a seed_figures multirun directory")
    _common(p, many=True)
    p = sub.add_parser("standard", help="the runner's standard figures into a directory")
    p.add_argument("file", metavar="FILE")
    p.add_argument("-o", "--output", help="output directory (default: figures/ next to FILE)")
    return parser


def _fail(message):
    sys.stderr.write(f"gyrolab-plot: error: {' '.join(str(message).split())}\n")
    sys.exit(EXIT_BAD_INPUT)


def run(args):
    """Make the figure ``args.kind``; return the written path(s)."""
    from .io import open_results, parse_selection, save_figure

    kind = args.kind
    if kind == "standard":
        from .figures import standard_figures

        out = args.output or Path(args.file).parent / "figures"
        open_results(args.file)  # a clear error before anything is written
        return standard_figures(args.file, out)
    if kind == "seed":
        from .seed_figures import seed_figures

        out = Path(args.output or Path(args.file[0]) / "seed_figures.png")
        return seed_figures(args.file, out, formats=args.format)
    ds = open_results(args.file)
    sel = parse_selection(args.selection)
    default = Path(args.file).with_name(f"{kind.replace('-', '_')}.png")
    out = Path(args.output) if args.output else default
    if kind == "animation":
        from .animation import animate

        return animate(ds, out.with_suffix(".gif") if out.suffix != ".gif" else out, sel=sel,
                       seconds=args.seconds, fps=args.fps)
    if kind == "nutation":
        from .nutation import theta_figure

        fig = theta_figure(ds, sel, n_periods=args.periods)
    elif kind == "tip":
        from .nutation import tip_locus_figure

        one = {k: v[0] for k, v in sel.items() if k in ("method", "dt")}
        fig = tip_locus_figure(ds, one.get("method"), sel.get("f", [None])[0] if len(sel.get("f", [])) == 1
                               else None, sel.get("theta0", [None])[0], one.get("dt"), t_max=args.t_max)
    elif kind == "energy":
        from .energy import drift_figure

        fig = drift_figure(ds, args.quantity, sel, envelope=not args.raw)
    elif kind == "invariants":
        from .energy import invariants_figure

        fig = invariants_figure(ds, sel, envelope=not args.raw)
    elif kind == "work-precision":
        from .work_precision import work_precision_figure

        fig = work_precision_figure(ds, sel, peers=not args.no_peers)
    elif kind == "stability":
        from .stability import stability_figure

        fig = stability_figure(ds, sel)
    else:  # argparse has already refused anything else
        raise AssertionError(kind)
    paths = [save_figure(fig, out, formats=args.format)]
    return paths


def main(argv=None):
    """Console entry point ``gyrolab-plot``."""
    from .io import SelectionError

    args = build_parser().parse_args(argv)
    try:
        result = run(args)
    except (SelectionError, ValueError) as err:
        _fail(err)
    paths = result if isinstance(result, (list, tuple)) else [result]
    for p in paths:
        print(f"gyrolab-plot: wrote {p}")
    return 0


if __name__ == "__main__":
    main()
