"""Every pinned experiment (conf/experiment/*.yaml) composes and plans as a user would start it.

``gyrolab experiment=NAME runner.dry_run=true`` for each: Hydra composes it
(multirun studies too), every job's grid is built and checked (methods and
selectors resolved from the registry, scene options, sizes), and the plan is
printed; nothing is integrated.  A study whose config no longer composes, names
a method that is gone or a scene option that changed fails here, not in a
user's first run (lightning-hydra-template's test_sweeps does the same).
"""

import importlib.resources

import pytest

from helpers import gyrolab

EXPERIMENTS = sorted(
    p.name.removesuffix(".yaml")
    for p in (importlib.resources.files("gyrolab.conf") / "experiment").iterdir()
    if p.name.endswith(".yaml") and not p.name.startswith("regression_")  # those: tests/test_regression.py
)


def test_every_experiment_is_listed():
    assert {"default", "verdict", "verdict_ladder", "verdict_long", "engines", "sciml_rigid_body"} <= set(EXPERIMENTS)


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_pinned_experiment_plans_without_error(tmp_path, name):
    result = gyrolab(f"experiment={name}", "runner.dry_run=true", cwd=tmp_path, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "gyrolab dry run:" in result.stdout
    assert "Traceback" not in result.stderr + result.stdout
    assert not list(tmp_path.rglob("*.h5")), "a dry run wrote a results file"


def test_the_verdict_study_plans_every_job_and_its_post_step(tmp_path):
    """A multirun's sweeper params (experiment=verdict: scene=glob(*) x ladder, long) are planned job by job,
    the verdict after them is estimated (analysis/verdicts/cost.py), and nothing reads as a failed step."""
    scenes = [p for p in (importlib.resources.files("gyrolab.conf") / "scene").iterdir() if p.name.endswith(".yaml")]
    result = gyrolab("experiment=verdict", "runner.dry_run=true", cwd=tmp_path, timeout=600)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("gyrolab dry run: ") == 2 * len(scenes) + 1  # every job, then the verdict
    assert "gyrolab dry run: the verdict after the jobs: estimated" in result.stdout
    assert "bisection" in result.stdout and "skipped" not in result.stderr
    assert list(tmp_path.iterdir()) == []
