"""The README's methods table, generated from the stored verdicts (docs/verdict.json).

    python -m gyrolab.analysis.reports.readme_verdict            # rewrite the block in README.md
    python -m gyrolab.analysis.reports.readme_verdict --check    # exit 1 if README.md is not what it would write

The block between ``<!-- verdict-table:begin -->`` and ``<!-- verdict-table:end -->``
is written from the verdict records (gyrolab-verdict --json; `gyrolab
experiment=verdict` regenerates docs/verdict.json) and the method registry:
nobody types a measured number into it.  tests/test_verdict_readme.py runs
``--check``, so the README cannot drift from the verdicts it quotes.
"""

import argparse
import json
import sys
from pathlib import Path

from ...safe_files import check_output, write_text

BEGIN, END = "<!-- verdict-table:begin -->", "<!-- verdict-table:end -->"


def _drift(rec):
    """The energy drift cell: the verdict's own wording (analysis/verdicts/verdict.py fmt_drift)."""
    from ..verdicts.verdict import fmt_drift

    return fmt_drift(rec) if rec.get("drift_class") else "—"


def table(records, scene="heavy_top"):
    """Markdown rows: one per registered method, from its ``summary`` records on ``scene``."""
    from ...kernels.registry import METHODS
    from ..verdicts.verdict import fmt_threshold, ladder_words

    summary = {
        (r["method"], r["quantity"]): r for r in records if r.get("kind") == "summary" and r.get("scene") == scene
    }
    first = next(r for r in summary.values())
    lines = [
        f"Measured on `{scene}` (f = {first['order_f']:g} Hz, θ0 = {first['order_theta0']:g}°): order from the final "
        f"state at t = {first['order_t_end']:g} s over a dt ladder of {ladder_words(first.get('ladder_dt') or [])} "
        "(95 % interval; reference: "
        f"{first['reference']}); energy drift over {first['t_end']:g} s at dt = {first['dt']:g} s "
        f"({first['n_steps']:.0e} steps); (‖ω‖dt)_crit bounded over {first['stability_t_end']:g} s "
        "(`> 10`: bounded at the top of the bracket). All scenes: [docs/verdict.md](docs/verdict.md).",
        "",
        "| method | declared order | measured order | symplectic | energy drift | (‖ω‖dt)_crit | what it is |",
        "|---|---:|---|:---:|---|---:|---|",
    ]
    for name, module in METHODS.items():
        rec = summary.get((name, "energy"))
        if rec is None:
            lines.append(
                f"| `{name}` | {module.ORDER} | (no verdict yet) | {'yes' if module.SYMPLECTIC else 'no'} "
                f"| | | {module.__doc__.strip().splitlines()[0].split(': ', 1)[1]} |"
            )
            continue
        order = rec.get("order")
        measured = (
            f"{order:.2f} [{rec['order_ci'][0]:.2f}, {rec['order_ci'][1]:.2f}]"
            if order is not None
            else f"— ({rec.get('order_reason') or 'no fit'})"
        )
        crit_text = fmt_threshold(rec)  # the verdict table's own cell ("; fails at ≤ y" included)
        doc = module.__doc__.strip().splitlines()[0].split(": ", 1)[1]
        lines.append(
            f"| `{name}` | {module.ORDER} | {measured} | {'yes' if module.SYMPLECTIC else 'no'} | "
            f"{_drift(rec)} | {crit_text} | {doc} |"
        )
    return "\n".join(lines)


def render(readme_text, records):
    """README text with the block between the markers regenerated."""
    head, _, rest = readme_text.partition(BEGIN)
    _, _, tail = rest.partition(END)
    if not rest or END not in rest:
        raise ValueError(f"README.md has no {BEGIN} ... {END} block")
    return f"{head}{BEGIN}\n{table(records)}\n{END}{tail}"


def main(argv=None):
    root = Path(__file__).resolve().parents[2]  # the checkout: analysis/reports/ is two levels down
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--readme", default=str(root / "README.md"))
    parser.add_argument("--verdicts", default=str(root / "docs" / "verdict.json"))
    parser.add_argument("--check", action="store_true", help="exit 1 when README.md differs from the generation")
    args = parser.parse_args(argv)
    try:
        records = json.loads(Path(args.verdicts).read_text())
        text = Path(args.readme).read_text()
        new = render(text, records)
        if not args.check:
            check_output(args.readme)
    except (OSError, ValueError, KeyError, StopIteration) as err:
        sys.stderr.write(f"readme_verdict: error: {err}\n")
        return 2
    if args.check:
        if new != text:
            sys.stderr.write(
                "readme_verdict: README.md's methods table is stale; "
                "run python -m gyrolab.analysis.reports.readme_verdict\n"
            )
            return 1
        return 0
    write_text(Path(args.readme), new)
    print(f"readme_verdict: wrote the methods table of {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
