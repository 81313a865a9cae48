"""``gyrolab-plot KIND FILE [KEY=VALUE ...]``: figures from a stored results file.

Usage examples: README.md, "Using it"; ``gyrolab-plot KIND --help`` for each kind.

A selection is KEY=VALUE[,VALUE...] with KEY in integrator (``method`` is read
as integrator, the name of the dim before layout 3), f (Hz), theta0 (deg),
dt (s).

A combined file (gyrolab-combine: its members stacked along a leading ``scene``
or ``job`` dim) takes one more key, ``scene=NAME`` or ``job=K`` (K from 0),
which draws that member with its own scene options and declarations.  Without
one, every member is drawn, each into its own file with the member in the
name (``energy_heavy_top.png``, ``energy_job1.png``; ``standard`` into
``figures/<member>/``): the user asked for the file's figure, and one figure
per member is what the separate files would have given (members differ in
scene, options and invariants, so no figure could share their panels).

Output: -o PATH (default ``<kind>.png`` next to FILE; ``-o energy.pdf`` writes a PDF); --format png
svg pdf for several.  Only ``work-precision`` and ``sciml`` run anything (their
scipy peers at several tolerances; sciml times four solvers, best of 7, and
re-times each method: minutes on a fast spin, one progress line per solver,
``--no-peers`` or ``--repeats 1`` to shorten); every other kind reads the stored
samples.
When a figure cannot draw every value of the grid it says which it drew, in
the figure and on a ``gyrolab-plot: note:`` line, with the command that draws
the others.  -o into a directory that does not exist is refused unless
--parents.  Bad input: one line on stderr naming the key and value, exit
status 2, no file written (of a combined file drawn member by member, the
members before the one that fails are written; the line names that member).
"""

import argparse
import sys
from pathlib import Path

from ...pipes import quiet_on_broken_pipe


def _common(p, many=False):
    if many:
        p.add_argument("file", metavar="FILE_OR_DIR", nargs="+", help="results files or a multirun directory")
    else:
        p.add_argument("file", metavar="FILE", help="results file (HDF5, gyrolab/results/layout.py)")
        p.add_argument(
            "selection",
            nargs="*",
            metavar="KEY=VALUE",
            help="grid values to draw: integrator=..., f=... (Hz), theta0=... (deg), dt=... (s); "
            "a combined file's scene=NAME or job=K",
        )
    p.add_argument(
        "-o",
        "--output",
        help="output path (suffix replaced per --format; a .png, .svg or .pdf suffix is the format when --format "
        "is not given); default next to FILE",
    )
    p.add_argument("--parents", action="store_true", help="create -o's missing parent directories")
    p.add_argument(
        "--format",
        nargs="+",
        default=None,
        choices=["png", "svg", "pdf"],
        help="file formats to write (default: -o's suffix if it is one of these, else png)",
    )


def build_parser():
    from .registry import FIGURES

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
    p.add_argument(
        "selection", nargs="*", metavar="scene=NAME|job=K", help="the member of a combined file (default: each)"
    )
    p.add_argument("-o", "--output", help="output directory (default: figures/ next to FILE)")
    p.add_argument("--parents", action="store_true", help="create -o's missing parent directories")
    return parser


def _fail(message):
    from ...results import EXIT_BAD_INPUT  # imported when needed: --help stays free of xarray

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


def _member_tag(ds, index=0, used=None):
    """The member of a combined file's slice as output names carry it: heavy_top, job1.  The label
    is text from the file: made a safe basename (gyrolab/safe_files.py), else ``member<index>``;
    a tag already in ``used`` (two labels made the same, e.g. ``x`` and ``../x``) gets ``_<index>``."""
    from ...safe_files import safe_name

    dim, _, label = ds.attrs["combined_member"].partition("=")
    tag = safe_name(label if dim == "scene" else f"{dim}{label}", f"member{index}")
    if used is not None:
        tag = f"{tag}_{index}" if tag in used else tag
        used.add(tag)
    return tag


def _member_path(path, ds, index=0, used=None):
    """``path`` with the member in its name: energy.png -> energy_heavy_top.png / energy_job1.png,
    checked to stay in ``path``'s directory."""
    from ...safe_files import inside

    path = Path(path)
    return inside(path.parent, path.with_name(f"{path.stem}_{_member_tag(ds, index, used)}{path.suffix}"))


def _split_member(words):
    """(member selection {scene|job: value}, grid selection) of the KEY=VALUE words."""
    from ..io import MEMBER_DIMS, parse_selection

    sel = parse_selection(words, members=True)
    member = {k: sel.pop(k)[0] for k in MEMBER_DIMS if k in sel}
    return member, sel


def run(args, notes=None):
    """Make the figure ``args.kind``; return the written path(s).  ``notes`` (a list) receives the
    figure's selection notes, with FILE replaced by the file's path (and member selection)."""
    from ...results import open_members
    from ..io import SelectionError
    from .registry import FIGURES

    kind = args.kind
    _check_output(args)
    if kind == "standard":
        from ...safe_files import inside
        from .registry import standard_figures

        member, grid = _split_member(args.selection)
        if grid:
            raise SelectionError(f"{' '.join(args.selection)}: standard takes only scene=NAME or job=K")
        out = Path(args.output or Path(args.file).parent / "figures")
        # a clear error before anything is written; read lazily: memory follows what is drawn, not the file
        members = open_members(args.file, member, lazy=True)
        paths, used = [], set()
        log = lambda line: print(line.replace("gyrolab:", "gyrolab-plot:", 1))  # noqa: E731
        try:
            for k, (label, ds) in enumerate(members):
                where = out if label is None or len(members) == 1 else inside(out, out / _member_tag(ds, k, used))
                source = args.file if label is None else f"{args.file} {ds.attrs['combined_member']}"
                paths += standard_figures(args.file, where, log=log, ds=ds, label=source)
        finally:
            for _, ds in members:
                ds.close()
        if not paths:  # every figure failed (each said why on stderr): not a success
            raise SelectionError(f"FILE={args.file}: no figure could be drawn from it")
        return paths
    if kind == "seed":
        from .seed import seed_figures

        first = Path(args.file[0])
        # next to a results file given as FILE, inside a multirun directory given as DIR
        out = Path(args.output or (first.parent if first.is_file() else first) / "seed_figures.png")
        return seed_figures(args.file, out, formats=args.format)
    figure = FIGURES[kind]  # argparse has already refused anything else
    member, sel = _split_member(args.selection)
    members = open_members(args.file, member, lazy=True)
    default = Path(args.file).with_name(f"{kind.replace('-', '_')}.png")
    out = Path(args.output) if args.output else default
    options = {
        flag.lstrip("-").replace("-", "_"): getattr(args, flag.lstrip("-").replace("-", "_")) for flag in figure.options
    }
    try:
        return _write_members(figure, members, args, out, sel, options, notes)
    finally:
        for _, ds in members:
            ds.close()


def _write_members(figure, members, args, out, sel, options, notes):
    """``figure`` of each (label, Dataset) of ``members`` written; the paths (see ``run``)."""
    from ..io import SelectionError

    paths, used = [], set()
    for k, (label, ds) in enumerate(members):
        drawn = []
        if label is None:
            where, source = out, str(args.file)
        else:
            where = out if args.output and len(members) == 1 else _member_path(out, ds, k, used)
            source = f"{args.file} {ds.attrs['combined_member']}"
        try:
            paths.append(figure.write(ds, where, sel, formats=args.format, notes=drawn, **options))
        except (SelectionError, ValueError) as err:
            raise type(err)(f"{source}: {err}" if label is not None else str(err)) from None
        if notes is not None:
            notes.extend(n.replace("FILE", source) for n in drawn)
    return paths


@quiet_on_broken_pipe
def main(argv=None):
    """Console entry point ``gyrolab-plot``."""
    from ..io import SelectionError

    args = build_parser().parse_args(argv)
    if getattr(args, "format", "") is None:  # -o energy.pdf writes a PDF (it wrote energy.png)
        suffix = Path(args.output).suffix.lstrip(".").lower() if args.output else ""
        args.format = [suffix] if suffix in ("png", "svg", "pdf") else ["png"]
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
