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
When a figure cannot draw every value of the grid it says which it drew, in
the figure and on a ``gyrolab-plot: note:`` line, with the command that draws
the others.  -o into a directory that does not exist is refused unless
--parents.  Bad input: one line on stderr naming the key and value, exit
status 2, no file written.
"""

import argparse
import sys
from pathlib import Path

EXIT_BAD_INPUT = 2


def _common(p, many=False):
    if many:
        p.add_argument("file", metavar="FILE_OR_DIR", nargs="+", help="results files or a multirun directory")
    else:
        p.add_argument("file", metavar="FILE", help="results file (HDF5, gyrolab/layout.py)")
        p.add_argument(
            "selection",
            nargs="*",
            metavar="KEY=VALUE",
            help="grid values to draw: method=..., f=... (Hz), theta0=... (deg), dt=... (s)",
        )
    p.add_argument("-o", "--output", help="output path (suffix replaced per --format); default next to FILE")
    p.add_argument("--parents", action="store_true", help="create -o's missing parent directories")
    p.add_argument(
        "--format",
        nargs="+",
        default=["png"],
        choices=["png", "svg", "pdf"],
        help="file formats to write (default: png)",
    )


def build_parser():
    from .figures import FIGURES

    parser = argparse.ArgumentParser(
        prog="gyrolab-plot",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Run `gyrolab-plot KIND --help` for each kind's options.",
    )
    sub = parser.add_subparsers(dest="kind", metavar="KIND", required=True)
    for name, figure in FIGURES.items():
        p = sub.add_parser(name, help=figure.help, description=figure.help)
        _common(p)
        for flag, kwargs in figure.options.items():
            p.add_argument(flag, **kwargs)
    p = sub.add_parser("seed", help="the write-up's figures from a seed_figures multirun directory")
    _common(p, many=True)
    p = sub.add_parser("standard", help="the figures the file's study asks for (output.figures) into a directory")
    p.add_argument("file", metavar="FILE")
    p.add_argument("-o", "--output", help="output directory (default: figures/ next to FILE)")
    p.add_argument("--parents", action="store_true", help="create -o's missing parent directories")
    return parser


def _fail(message):
    sys.stderr.write(f"gyrolab-plot: error: {' '.join(str(message).split())}\n")
    sys.exit(EXIT_BAD_INPUT)


def _check_output(args):
    """ValueError (exit 2) when -o names a path whose parent directory does not exist (unless --parents)."""
    if not args.output:
        return
    parent = Path(args.output).parent
    if not parent.is_dir():
        if getattr(args, "parents", False):
            parent.mkdir(parents=True, exist_ok=True)
        else:
            raise ValueError(f"-o {args.output}: directory {parent} does not exist (create it, or pass --parents)")


def run(args, notes=None):
    """Make the figure ``args.kind``; return the written path(s).  ``notes`` (a list) receives the
    figure's selection notes, with FILE replaced by the file's path."""
    from .figures import FIGURES
    from .io import SelectionError, open_results, parse_selection

    kind = args.kind
    _check_output(args)
    if kind == "standard":
        from .figures import standard_figures

        out = args.output or Path(args.file).parent / "figures"
        open_results(args.file)  # a clear error before anything is written
        paths = standard_figures(args.file, out, log=lambda line: print(line.replace("gyrolab:", "gyrolab-plot:", 1)))
        if not paths:  # every figure failed (each said why on stderr): not a success
            raise SelectionError(f"FILE={args.file}: no figure could be drawn from it")
        return paths
    if kind == "seed":
        from .seed_figures import seed_figures

        first = Path(args.file[0])
        # next to a results file given as FILE, inside a multirun directory given as DIR
        out = Path(args.output or (first.parent if first.is_file() else first) / "seed_figures.png")
        return seed_figures(args.file, out, formats=args.format)
    figure = FIGURES[kind]  # argparse has already refused anything else
    ds = open_results(args.file)
    sel = parse_selection(args.selection)
    default = Path(args.file).with_name(f"{kind.replace('-', '_')}.png")
    out = Path(args.output) if args.output else default
    options = {
        flag.lstrip("-").replace("-", "_"): getattr(args, flag.lstrip("-").replace("-", "_")) for flag in figure.options
    }
    drawn = []
    path = figure.write(ds, out, sel, formats=args.format, notes=drawn, **options)
    if notes is not None:
        notes.extend(n.replace("FILE", str(args.file)) for n in drawn)
    return [path]


def main(argv=None):
    """Console entry point ``gyrolab-plot``."""
    from .io import SelectionError

    args = build_parser().parse_args(argv)
    notes = []
    try:
        result = run(args, notes)
    except (SelectionError, ValueError) as err:
        _fail(err)
    paths = result if isinstance(result, (list, tuple)) else [result]
    if args.kind != "standard":  # standard_figures reports each figure itself
        for p in paths:
            print(f"gyrolab-plot: wrote {p}")
    for note in notes:
        print(f"gyrolab-plot: note: {note}")
    return 0


if __name__ == "__main__":
    main()
