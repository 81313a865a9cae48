"""Every pinned experiment (conf/experiment/*.yaml) composes and plans as a user would start it.

``gyrolab experiment=NAME runner.dry_run=true`` for each: Hydra composes it
(multirun studies too), every job's grid is built and checked (methods and
selectors resolved from the registry, scene options, sizes), and the plan is
printed; nothing is integrated.  A study whose config no longer composes, names
a method that is gone or a scene option that changed fails here, not in a
user's first run (lightning-hydra-template's test_sweeps does the same).
"""

import importlib.resources
import re

import pytest

from helpers import environment, gyrolab

EXPERIMENTS = sorted(
    p.name.removesuffix(".yaml")
    for p in (importlib.resources.files("gyrolab.conf") / "experiment").iterdir()
    if p.name.endswith(".yaml") and not p.name.startswith("regression_")  # those: tests/test_regression.py
)


def test_every_experiment_is_listed():
    assert {"default", "verdict", "verdict_ladder", "verdict_long", "engines", "sciml_rigid_body"} <= set(EXPERIMENTS)


@pytest.mark.slow
@pytest.mark.parametrize("name", EXPERIMENTS)
def test_pinned_experiment_plans_without_error(tmp_path, name):
    result = gyrolab(f"experiment={name}", "runner.dry_run=true", cwd=tmp_path, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "gyrolab dry run:" in result.stdout
    assert "Traceback" not in result.stderr + result.stdout
    assert not list(tmp_path.rglob("*.h5")), "a dry run wrote a results file"
    if name == "verdict":  # every registered method on every scene (that it can integrate), none typed in conf/
        import numpy as np

        from gyrolab.kernels.body import is_driven
        from gyrolab.kernels.registry import METHODS, driven_methods
        from gyrolab.kernels.scenes import SCENES, build_scene

        def can_run(scene):
            driven = is_driven(np.array([build_scene(scene, 50.0, 45.0).body], dtype=float))
            return len(driven_methods()) if driven else len(METHODS)

        plans = re.findall(r"gyrolab dry run: (\w+): (\d+) method x", result.stdout)
        assert sorted(plans) == sorted((s, str(can_run(s))) for s in SCENES for _ in range(2)), plans


def tiny_axes():
    """Overrides that shrink any experiment's sweep axes to conf/sweep/tiny.yaml's (its methods kept)."""
    import yaml

    tiny = yaml.safe_load((importlib.resources.files("gyrolab.conf") / "sweep" / "tiny.yaml").read_text())
    axes = [f"sweep.{key}=[{','.join(str(v) for v in tiny[key])}]" for key in ("f", "theta0", "dt")]
    return [*axes, f"sweep.t_end={tiny['t_end']}", f"output.every={max(tiny['dt'])}"]


def expected_figure_files(ds):
    """{figure: file name} the figure step writes for the figures a results file's config names."""
    import yaml

    from gyrolab.analysis.figures.registry import FIGURES, figure_names

    setting = yaml.safe_load(ds.attrs["config"])["output"]["figures"]
    return {n: FIGURES[n].file_name or f"{n.replace('-', '_')}.png" for n in figure_names(setting)}


# The verdict study runs every registered method on every scene (12 jobs); its coverage is what
# test_pinned_experiment_plans_without_error plans, and here two methods run through all its jobs and its
# callback (its stability bisection over 1 s, not 10), so the smoke run stays within seconds per job.
FEWER_METHODS = {"verdict": ["sweep.method=[rk4,lie_poisson]", "hydra.callbacks.verdict.stability=1.0"]}


@pytest.mark.slow
@pytest.mark.parametrize("name", EXPERIMENTS)
def test_pinned_experiment_runs_at_tiny_size(tmp_path, name):
    """``gyrolab experiment=NAME`` really runs, on conf/sweep/tiny.yaml's axes with the experiment's own
    methods, scenes, jobs, figures and callbacks: every results file opens with the one reader and
    every figure its config names is drawn (lightning-hydra-template's test_sweeps)."""
    from gyrolab.results import find_results, open_results

    result = gyrolab(
        f"experiment={name}",
        *tiny_axes(),
        *FEWER_METHODS.get(name, []),
        f"hydra.run.dir={tmp_path / 'run'}",
        f"hydra.sweep.dir={tmp_path / 'multirun'}",
        cwd=tmp_path,
        timeout=1800,  # seconds when the kernels are cached; a cold numba cache compiles the methods first
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert "Traceback" not in result.stderr + result.stdout
    assert "skipped" not in result.stderr, result.stderr[-3000:]
    files = find_results([tmp_path])
    assert files
    for path in files:
        ds = open_results(path)
        assert int((ds["status"] == 0).sum()) > 0, f"{path}: no run finished"
        for figure, file_name in expected_figure_files(ds).items():
            drawn = list((path.parent / "figures").glob(f"{file_name.rsplit('.', 1)[0]}.*"))
            assert drawn, f"{path}: figure {figure} ({file_name}) was not drawn"


@pytest.mark.slow
def test_the_verdict_study_plans_every_job_and_its_post_step(tmp_path):
    """A multirun's sweeper params (experiment=verdict: scene=glob(*) x ladder, long) are planned job by job,
    the verdict after them is estimated (analysis/verdicts/cost.py), and nothing reads as a failed step."""
    scenes = [p for p in (importlib.resources.files("gyrolab.conf") / "scene").iterdir() if p.name.endswith(".yaml")]
    cache = tmp_path.parent / f"{tmp_path.name}-cache"  # empty: every kernel cold
    run = tmp_path / "run"
    run.mkdir()
    result = gyrolab(
        "experiment=verdict", "runner.dry_run=true", cwd=run, env=environment(NUMBA_CACHE_DIR=cache), timeout=600
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("gyrolab dry run: ") == 2 * len(scenes) + 1  # every job, then the verdict
    # the jobs run in one process: a kernel cold for several jobs is compiled (and counted) by the first only
    named = re.findall(r"compiling: \d+ kernels not in the numba cache: (.*)", result.stdout)
    kernels = [kernel for line in named for kernel in line.split(", ")]
    assert kernels and len(kernels) == len(set(kernels)), kernels
    assert "compiled by an earlier job of this multirun" in result.stdout
    assert not list(cache.rglob("*.nbi"))  # estimated, not compiled
    assert "gyrolab dry run: the verdict after the jobs: estimated" in result.stdout
    assert "bisection" in result.stdout and "skipped" not in result.stderr
    assert list(run.iterdir()) == []
