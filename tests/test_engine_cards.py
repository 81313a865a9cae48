"""The per-method cards (docs/engines/<name>.md) and their index are generated from files, never typed."""

import json
import math
import shutil
from pathlib import Path

import pytest

from gyrolab.analysis.reports import engine_cards
from gyrolab.analysis.verdicts.verdict import fmt_order
from gyrolab.kernels import real
from gyrolab.kernels.registry import METHODS

ROOT = Path(__file__).resolve().parents[1]
ENGINES = ROOT / "docs" / "engines"
VERDICTS = ROOT / "docs" / "verdict.json"
CONFORMANCE = ENGINES / "conformance.json"


def _args(readme=ROOT / "README.md", verdicts=VERDICTS, conformance=CONFORMANCE, out_dir=ENGINES):
    return ["--readme", str(readme), "--verdicts", str(verdicts), "--conformance", str(conformance),
            "--out-dir", str(out_dir)]  # fmt: skip


def _card(name):
    return (ENGINES / f"{name}.md").read_text()


def test_cards_and_both_indexes_on_disk_are_the_generated_ones():
    assert engine_cards.main(["--check", *_args()]) == 0


def test_every_method_and_every_real_backend_has_a_card_listed_in_both_indexes():
    readme, index = (ROOT / "README.md").read_text(), (ENGINES / "README.md").read_text()
    block = readme.split(engine_cards.BEGIN)[1].split(engine_cards.END)[0]
    names = [*METHODS, *real.NAMES]
    assert len(set(names)) == len(names) > 0  # a name twice would hide a missing card
    for name in names:
        assert _card(name).startswith(f"# `{name}`\n"), name
        assert engine_cards.FOOTER in _card(name)
        assert f"| [`{name}`](docs/engines/{name}.md) |" in block, name
        assert f"| [`{name}`]({name}.md) |" in index, name


def test_rk4_measured_order_on_heavy_top_is_the_verdict_value():
    records = json.loads(VERDICTS.read_text())
    rec = next(
        r
        for r in records
        if r.get("kind") == "summary"
        and r["method"] == "rk4"
        and r["scene"] == "heavy_top"
        and r["quantity"] == "energy"
    )
    row = next(line for line in _card("rk4").splitlines() if line.startswith("| heavy_top |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == fmt_order(rec)
    assert cells[2].startswith(f"{rec['order']:.2f} [{rec['order_ci'][0]:.2f}, {rec['order_ci'][1]:.2f}]")
    # every scene the json holds for rk4 has its row
    scenes = {r["scene"] for r in records if r.get("kind") == "summary" and r["method"] == "rk4"}
    assert {line.split("|")[1].strip() for line in _card("rk4").splitlines() if line.startswith("| ")} >= scenes


def test_hidden_defaults_are_read_from_the_module_with_their_values_and_comments():
    jolt = METHODS["jolt_rescale"]
    assert jolt.ANGULAR_DAMPING == 0.05
    card = _card("jolt_rescale")
    assert "| `ANGULAR_DAMPING` | 0.05 | 1/s, BodyCreationSettings::mAngularDamping |" in card
    assert f"= {jolt.MAX_ANGULAR_VELOCITY:.6g} |" in card  # 0.25 π · 60, computed by the module
    defaults, coefficients = engine_cards.hidden_defaults(jolt)
    assert [d[0] for d in defaults] == ["MAX_ANGULAR_VELOCITY", "ANGULAR_DAMPING", "MIN_ROTATION"] and not coefficients
    # a default imported from a sibling method file is shown with where it comes from
    (threshold,) = engine_cards.hidden_defaults(METHODS["bullet_implicit_body"])[0]
    assert threshold[0] == "ANGULAR_MOTION_THRESHOLD" and threshold[2] == pytest.approx(math.pi / 4)
    assert threshold[4] == "bullet_explicit" and "(from `bullet_explicit`)" in _card("bullet_implicit_body")
    # composition weights are coefficients, not defaults
    defaults, coefficients = engine_cards.hidden_defaults(METHODS["lie_poisson4"])
    assert not defaults and [c[0] for c in coefficients] == ["W1", "W0"]


def test_conformance_comes_from_the_json_or_says_why_not():
    doc = json.loads(CONFORMANCE.read_text())
    euler = [r for r in doc["rows"] if r["reproduction"] == "mujoco_euler" and r["engine"] == "real_mujoco_euler"]
    euler = [r for r in euler if "note" not in r]  # the card's verdict is against its own engine, the first pair
    worst = max(euler, key=lambda r: r["dw"])
    card = _card("mujoco_euler")
    assert f"worst {worst['dw']:.2g} vs `real_mujoco_euler` ({worst['case']}, dt = {worst['dt']:g} s" in card
    assert "Not checked: no Jolt Python package is installed here" in _card("jolt_rescale")
    assert f"mujoco {doc['engines']['mujoco']}" in _card("real_mujoco_euler")
    for name, module in METHODS.items():  # every reproduction's engine is known to ENGINE_PACKAGES
        if getattr(module, "REPRODUCES", None):
            engine_cards.engine_of(module.REPRODUCES)


def test_conformance_json_has_the_rows_nan_as_null(monkeypatch):
    """The JSON's format; every engine counted as not loading, since asking would import them all (~0.7 GB
    held by this test worker): test_real_engines runs the command itself and checks the versions."""
    from gyrolab.kernels.real import conformance

    monkeypatch.setattr(conformance, "package_missing", lambda name: f"{name} not asked here")

    rows = [{"case": "c", "dt": 1e-3, "reproduction": "mujoco_euler", "engine": "real_mujoco_euler", "dw": math.nan}]
    doc = json.loads(conformance.as_json(rows, 7))
    assert doc["steps"] == 7 and doc["rows"][0]["dw"] is None and doc["threshold"] == conformance.THRESHOLD
    from gyrolab.kernels.real import PACKAGES

    paired = {PACKAGES[engine] for _, engine, _ in conformance.PAIRS}  # every engine of the pairs, each once
    assert paired >= {"mujoco", "mujoco-mjx", "pybullet", "bsk", "newton", "jax-md"}
    assert set(doc["engines"]) == paired and len(doc["pairs"]) == len(conformance.PAIRS)
    assert set(doc["engines"].values()) == {None}


@pytest.mark.slow
def test_write_then_check_in_a_scratch_copy(tmp_path):
    readme = tmp_path / "README.md"
    shutil.copy(ROOT / "README.md", readme)
    out = tmp_path / "engines"
    out.mkdir()
    assert engine_cards.main(["--check", *_args(readme=readme, out_dir=out)]) == 1  # no cards yet
    assert engine_cards.main(_args(readme=readme, out_dir=out)) == 0
    assert len(list(out.glob("*.md"))) == len(METHODS) + len(real.NAMES) + 1  # a card each and the index
    assert readme.read_text() == (ROOT / "README.md").read_text()
    assert engine_cards.main(["--check", *_args(readme=readme, out_dir=out)]) == 0
    (out / "rk4.md").write_text("edited by hand\n")
    assert engine_cards.main(["--check", *_args(readme=readme, out_dir=out)]) == 1


@pytest.mark.parametrize(
    "content",
    [None, "{not json", "[1, 2]", '{"kind": "summary"}', '[{"kind": "summary", "method": "rk4"}]', "[]"],
    ids=["missing", "corrupt", "not-records", "not-a-list", "incomplete-record", "empty"],
)
def test_bad_verdicts_exit_2_with_one_line(tmp_path, capsys, content):
    path = tmp_path / "verdict.json"
    if content is not None:
        path.write_text(content)
    assert engine_cards.main(["--check", *_args(verdicts=path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("engine_cards: error: ") and err.count("\n") == 1, err


@pytest.mark.parametrize("content", [None, "{", '{"rows": []}'], ids=["missing", "corrupt", "incomplete"])
def test_bad_conformance_exits_2_with_one_line(tmp_path, capsys, content):
    path = tmp_path / "conformance.json"
    if content is not None:
        path.write_text(content)
    assert engine_cards.main(["--check", *_args(conformance=path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("engine_cards: error: ") and err.count("\n") == 1, err
