"""Tables of pinned problems' results, every number read from their results files.

    python -m gyrolab.analysis.reports.peer_table outputs/<hlw run>/hlw_free_body.h5 \\
        outputs/<bruls run>/bruls_heavy_top.h5 -o docs/peer_problems.md

For each file: the scene, its options and grid, then per method the axis error at
every dt (max over the run of |R e3 − reference|, rad, against the scene's exact
motion or DOP853 at 1e-12, as in the work-precision figure) and, per invariant the
scene declares, its worst relative error at every dt (halving dt divides a p-th order
method's error by 2^p).
Diverged runs read "diverged".
"""

import argparse
import sys
from pathlib import Path

from ...results import ResultsError, open_results
from ...safe_files import UnsafePathError, check_output, write_text
from ..figures.record import run_title
from ..figures.work_precision import reference_name, work_precision_data
from ..io import drawable_invariants, scene_name, scene_options
from .captions import fmt_error, worst_error


def file_section(path):
    """Markdown section of one results file: its setting, the axis-error table and the invariants table."""
    ds = open_results(path)
    data = work_precision_data(ds, retime=False, peers=False)
    options = ", ".join(f"{k} = {v}" for k, v in scene_options(ds).items())
    dts = sorted(float(d) for d in ds.dt.values)
    lines = [f"## {Path(path).name}", "", f"Scene `{scene_name(ds)}` ({options}); t = 0 … {float(ds.time[-1]):g} s."]
    header = "| method | " + " | ".join(f"dt = {d:g} s" for d in dts) + " |"
    rule = "|---|" + "---|" * len(dts)
    for (f, th), entry in data.items():
        lines += [
            "",
            f"{run_title(ds, f, th)}. Max axis error (rad) against {reference_name(ds)}:",
            "",
            header,
            rule,
        ]
        for m, pts in entry["methods"].items():
            errs = {p[0]: p[3] for p in pts}
            status = {d: int(ds.status.sel({"integrator": m, "f": f, "theta0": th, "dt": d})) for d in dts}
            cells = [fmt_error(errs[d]) if status[d] == 0 else "diverged" for d in dts]
            lines.append(f"| `{m}` | " + " | ".join(cells) + " |")
        for q in drawable_invariants(ds):
            lines += ["", f"Worst relative error of {q} over the run:", "", header, rule]
            for m in entry["methods"]:
                at = {"integrator": m, "f": f, "theta0": th}
                lines.append(f"| `{m}` | " + " | ".join(fmt_error(worst_error(ds, q, dt=d, **at)) for d in dts) + " |")
    return "\n".join(lines)


def main(argv=None):
    """``python -m gyrolab.analysis.reports.peer_table FILE... -o OUT``: write the tables."""
    p = argparse.ArgumentParser(
        prog="python -m gyrolab.analysis.reports.peer_table",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("files", nargs="+", help="results files of pinned experiments")
    # required: a default would overwrite whatever docs/ the current directory has
    p.add_argument("-o", "--output", required=True, help="the Markdown file to write (docs/peer_problems.md)")
    args = p.parse_args(argv)
    try:
        check_output(args.output)  # before the work: a missing directory or a link there
        sections = [file_section(f) for f in args.files]  # every file read before anything is written
    except (ResultsError, UnsafePathError) as err:  # a bad file or selection (SelectionError is one)
        sys.stderr.write(f"peer_table: error: {' '.join(str(err).split())}\n")
        return 2
    text = (
        "# Peer problems (generated)\n\nWritten by `python -m gyrolab.analysis.reports.peer_table`; every number is "
        "read from the results file named in its heading.\n\n" + "\n\n".join(sections) + "\n"
    )
    write_text(Path(args.output), text)
    print(f"peer_table: wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
