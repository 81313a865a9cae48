"""MuJoCo 3.10 → 4.0 (analysis/reports/mujoco_versions.py): the free body's drift class changed, and
midpoint_free is MuJoCo 3.10's implicitfast.

- always: the report's tables and findings from a tiny fake input (no MuJoCo needed);
- with ``GYROLAB_MUJOCO_OTHER_PYTHON`` set to an interpreter whose mujoco is 3.x < 3.11 (e.g.
  ``python3 -m venv /tmp/venv-mj310 && /tmp/venv-mj310/bin/pip install mujoco==3.10.0 numpy``) and a
  mujoco ≥ 3.11 in this one: on the tennis racket and the tumbling box at dt = 1e-3 s, implicitfast keeps
  the energy in 3.10 and loses it in this version, in different drift classes; midpoint_free agrees with
  3.10's implicitfast to ≤ 1e-9 step by step.  Skipped with the reason otherwise.
"""

import os
import subprocess

import pytest

from gyrolab.analysis.reports import mujoco_versions as mv
from gyrolab.kernels.real.conformance import THRESHOLD

OTHER = os.environ.get("GYROLAB_MUJOCO_OTHER_PYTHON")
CASES = ("tennis racket", "tumbling box")


def _drift_row(version, integrator, final, drift_class, max_abs):
    d = dict(
        drift_class=drift_class, rate=float("nan"), rate_unit="", max_abs=max_abs, at={"1": final / 4}, final=final
    )
    return dict(
        label=version,
        version=version,
        case="tennis racket",
        integrator=integrator,
        dt=1e-3,
        n_steps=2000,
        t_end=2.0,
        reset=None,
        energy=d,
        L_norm=dict(d),
    )


def test_report_formats_fake_rows():
    drift = [
        _drift_row("3.10.0", "implicitfast", 1e-12, "bounded", 2e-12),
        _drift_row("4.0.1", "implicitfast", -0.5, "slowing", 0.5),
        _drift_row("4.0.1", "implicit", -0.5, "slowing", 0.5),
    ]
    conformance = [
        dict(
            case="tennis racket",
            dt=1e-3,
            version="3.10.0",
            steps=100,
            engine_steps=100,
            compared=100,
            dw=0.0,
            dq=0.0,
            self_dw=1e-9,
            self_dq=2e-9,
            first_over=None,
        )
    ]
    infos = {
        "other": dict(version="3.10.0", version_string="3.10.0"),
        "this": dict(version="4.0.1", version_string="4.0.1"),
    }
    text = mv.report(infos, drift, conformance)
    assert "mujoco 3.10.0" in text and "mujoco 4.0.1" in text
    assert (
        "| tennis racket | implicitfast | 0.001 | 3.10.0 | 2.5e-13 | — | 1e-12 | 2e-12 | bounded | bounded | none |"
        in text
    )
    assert "| tennis racket | 0.001 | 3.10.0 | 100 (100) | 0 | 0 | 1e-09 / 2e-09 | never |" in text
    assert "max abs(e) over 2 s ≤ 2e-12" in text and "e(2 s) = -0.5" in text
    assert "(bit for bit)" in text
    # every table row has as many cells as its header
    for block in text.split("\n\n"):
        lines = [line for line in block.splitlines() if line.startswith("|")]
        if lines:
            assert {line.count("|") for line in lines} == {lines[0].count("|")}, block


def test_a_missing_other_interpreter_is_refused_in_one_line(tmp_path, capsys):
    out = tmp_path / "mujoco_versions.md"
    assert mv.main(["--other-python", str(tmp_path / "no-python"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mujoco_versions: error:") and err.count("\n") == 1 and "no-python" in err
    assert not out.exists()


def _other_version():
    if not OTHER:
        return None, "GYROLAB_MUJOCO_OTHER_PYTHON is not set (an interpreter with mujoco 3.x < 3.11)"
    try:
        out = subprocess.run(
            [OTHER, "-c", "import mujoco; print(mujoco.__version__)"], capture_output=True, text=True, timeout=60
        )
    except OSError as err:
        return None, f"GYROLAB_MUJOCO_OTHER_PYTHON={OTHER}: {err}"
    if out.returncode != 0:
        return None, f"GYROLAB_MUJOCO_OTHER_PYTHON={OTHER} does not import mujoco"
    version = out.stdout.strip()
    major, minor = mv._version_key(version)[:2]
    if not (major == 3 and minor < 11):
        return None, f"GYROLAB_MUJOCO_OTHER_PYTHON={OTHER} has mujoco {version}, not 3.x < 3.11"
    return version, ""


def _this_version():
    try:
        import mujoco
    except ImportError:
        return None, "needs mujoco >= 3.11 in this interpreter (pip install '.[engines]')"
    if mv._version_key(mujoco.__version__)[:2] < (3, 11):
        return None, f"this interpreter's mujoco is {mujoco.__version__}, not >= 3.11"
    return mujoco.__version__, ""


OTHER_VERSION, OTHER_REASON = _other_version()
THIS_VERSION, THIS_REASON = _this_version()
needs_other = pytest.mark.skipif(OTHER_VERSION is None, reason=OTHER_REASON)
needs_both = pytest.mark.skipif(OTHER_VERSION is None or THIS_VERSION is None, reason=OTHER_REASON or THIS_REASON)


@needs_both
def test_implicitfast_drift_class_changed():
    import sys

    _, old = mv.drift_rows(OTHER, "other", cases=CASES, dts=(1e-3,), t_end=5.0)
    _, new = mv.drift_rows(sys.executable, "this", cases=CASES, dts=(1e-3,), t_end=5.0)
    assert {r["version"] for r in old} == {OTHER_VERSION} and {r["version"] for r in new} == {THIS_VERSION}
    for o, n in zip(old, new, strict=True):
        assert (o["case"], o["integrator"]) == (n["case"], n["integrator"])
        if o["integrator"] != "implicitfast":
            # implicit: the same update in both versions
            assert o["energy"]["drift_class"] == n["energy"]["drift_class"]
            assert abs(o["energy"]["final"] - n["energy"]["final"]) < 1e-9
            continue
        assert o["energy"]["max_abs"] < 1e-9, o  # 3.10: the midpoint rule keeps the energy
        assert n["energy"]["final"] < -0.05, n  # ≥ 3.11: the gyroscopic derivative damps it
        assert o["energy"]["drift_class"] != n["energy"]["drift_class"], (o, n)
        assert n["energy"]["drift_class"] in ("linear", "slowing", "collapse"), n


@needs_other
def test_midpoint_free_is_mujoco_3_10_implicitfast():
    _, rows = mv.conformance_rows(OTHER, cases=CASES, dts=(1e-3, 1e-4), steps=2000)
    for r in rows:
        assert r["compared"] == 2000, r
        assert r["dw"] <= THRESHOLD and r["dq"] <= THRESHOLD, r
