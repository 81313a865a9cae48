"""The README's methods table is generated from docs/verdict.json, never typed: it must match."""

import json
from pathlib import Path

from gyrolab.analysis.reports import readme_verdict
from gyrolab.kernels.registry import METHODS

ROOT = Path(__file__).resolve().parents[1]


def test_readme_methods_table_is_the_generated_one():
    assert (
        readme_verdict.main(
            ["--check", "--readme", str(ROOT / "README.md"), "--verdicts", str(ROOT / "docs" / "verdict.json")]
        )
        == 0
    )


def test_generated_table_lists_every_method_with_its_measured_order():
    records = json.loads((ROOT / "docs" / "verdict.json").read_text())
    text = readme_verdict.table(records)
    for name in METHODS:
        assert f"| `{name}` |" in text, name
    lie = next(
        r
        for r in records
        if r.get("kind") == "summary"
        and r["scene"] == "heavy_top"
        and r["method"] == "lie_poisson"
        and r["quantity"] == "energy"
    )
    assert f"{lie['order']:.2f} [" in text
