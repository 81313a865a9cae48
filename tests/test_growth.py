"""Adding a per-sample variable by the recipe (docs/design.md) keeps every older file readable.

The recipe is applied to a scratch copy of the package: one raw field in kernels/driver.py
(``FIELDS`` and ``_record``) and its formula in kernels/reference.py (``samples_from_states``), and
one ``SAMPLE_VARIABLES`` entry in gyrolab/results/layout.py, nothing else (no layout bump, no
``ABSENT_BEFORE`` entry).  With that copy a tiny sweep runs, and the one reader opens a file written
before (by this gyrolab) and every stored regression pack: the new variable is absent in those, the
others are read as before, and a reader that needs it says why in one line.
"""

import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from helpers import TINY, assert_ok, environment, gyrolab

ROOT = Path(__file__).resolve().parents[1]
SMALL = [a for a in TINY if not a.startswith(("sweep.method", "sweep.f", "sweep.theta0", "sweep.dt"))] + [
    "sweep.method=[seed_next]",
    "sweep.f=[10]",
    "sweep.theta0=[30]",
    "sweep.dt=[1e-3]",
]


def scratch_package(dest):
    """A copy of the package's sources at ``dest``/gyrolab, laid out as pyproject installs them."""
    section = (ROOT / "pyproject.toml").read_text().split("[tool.setuptools.package-dir]")[1].split("\n[")[0]
    layout = dict(re.findall(r'^"([\w.]+)" = "([\w/]+)"$', section, re.MULTILINE))  # tomllib: Python >= 3.11
    assert "gyrolab.kernels" in layout and "gyrolab.conf" in layout, section
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "_build_info.py")
    for package, source in sorted(layout.items(), key=lambda item: item[0].count(".")):
        target = dest.joinpath(*package.split("."))
        shutil.copytree(ROOT / source, target, ignore=ignore, dirs_exist_ok=True)
    return dest / "gyrolab"


def edit(path, old, new):
    text = path.read_text()
    assert text.count(old) == 1, f"{path}: the recipe's anchor {old!r} is not there once"
    path.write_text(text.replace(old, new))


def apply_recipe(package):
    """The documented recipe: ``omega_norm`` (|ω|, rad/s) as a raw field (driver and reference) and one
    layout entry."""
    driver = package / "kernels" / "driver.py"
    edit(driver, '    "gamma_3",\n)', '    "gamma_3",\n    "omega_norm",\n)')
    edit(
        driver,
        "    out[i, k, 13] = g[2]\n",
        "    out[i, k, 13] = g[2]\n    out[i, k, 14] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])\n",
    )
    edit(
        package / "kernels" / "reference.py",
        '        "gamma_3": gamma[:, 2],\n    }',
        '        "gamma_3": gamma[:, 2],\n        "omega_norm": np.linalg.norm(omega, axis=1),\n    }',
    )
    edit(
        package / "results" / "layout.py",
        "\n}\nRUN_VARIABLES = {",
        '\n    "omega_norm": SampleVariable("rad s-1", "|w|", lambda r: r[..., RAW_FIELDS.index("omega_norm")]),'
        "\n}\nRUN_VARIABLES = {",
    )


CHECK = textwrap.dedent(
    """
    import sys
    from pathlib import Path

    import numpy as np

    import gyrolab
    from gyrolab.analysis.files.compare import compare_datasets
    from gyrolab.analysis.io import missing_variable_error
    from gyrolab.results import open_results
    from gyrolab.results.layout import SAMPLE_VARIABLES, held_variables
    from gyrolab.results.migrate import current, file_layout_version
    from gyrolab.results.reader import check

    sys.path.insert(0, sys.argv[3])
    import regenerate

    assert Path(gyrolab.__file__).resolve().is_relative_to(Path(sys.argv[4]).resolve()), gyrolab.__file__
    assert "omega_norm" in SAMPLE_VARIABLES
    old, new = open_results(sys.argv[1]), open_results(sys.argv[2])
    assert "omega_norm" not in held_variables(old) and "omega_norm" not in old
    assert held_variables(old) == tuple(n for n in SAMPLE_VARIABLES if n != "omega_norm")
    assert held_variables(new) == tuple(SAMPLE_VARIABLES)
    w = new["omega"].values
    assert np.array_equal(new["omega_norm"].values, np.sqrt(w[..., 0] ** 2 + w[..., 1] ** 2 + w[..., 2] ** 2))
    report = compare_datasets(new, old)
    assert report.ok, report.text()
    assert any("omega_norm" in d and "written before gyrolab stored omega_norm" in d for d in report.dropped)
    from gyrolab.kernels.reference import samples_from_states

    raw = samples_from_states((1.0, 2.0, 3.0, 0.0), np.array([[3.0, 4.0, 12.0]]), np.eye(3)[None])
    assert raw[0, -1] == 13.0  # the reference gives the new field too
    print(missing_variable_error(old, "omega_norm", "omega_norm_plot"))
    packs = sorted(Path(regenerate.STORE).rglob("*" + regenerate.PACK_SUFFIX))
    assert len(packs) > 100, len(packs)
    for path in packs:
        ds = current(regenerate.read_pack(path))
        check(path, ds, file_layout_version(ds))
        assert "omega_norm" not in held_variables(ds)
    print(f"{len(packs)} stored packs read")
    """
)


@pytest.mark.slow
def test_a_variable_added_by_the_recipe_keeps_older_files_readable(tmp_path):
    old_run = tmp_path / "old"
    assert_ok(gyrolab(*SMALL, f"hydra.run.dir={old_run}", cwd=tmp_path))
    package = scratch_package(tmp_path / "scratch")
    apply_recipe(package)
    env = environment(PYTHONPATH=tmp_path / "scratch", NUMBA_CACHE_DIR=tmp_path / "numba")
    new_run = tmp_path / "new"
    result = subprocess.run(
        [sys.executable, "-m", "gyrolab.runner.app", *SMALL, f"hydra.run.dir={new_run}"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert_ok(result)
    (tmp_path / "check.py").write_text(CHECK)
    result = subprocess.run(
        [
            sys.executable,
            str(tmp_path / "check.py"),
            str(old_run / "results.h5"),
            str(new_run / "results.h5"),
            str(ROOT / "tests" / "data"),
            str(package),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    line, count = result.stdout.strip().splitlines()
    assert line == (
        "figure omega_norm_plot needs variable omega_norm, which this file does not hold (it holds axis, theta, "
        "phi, energy, L, Lz, L3, omega, gamma: it was written before gyrolab stored omega_norm)"
    )
    assert count.endswith("stored packs read")
