"""Every config group composes under the schema; wrong types and unknown keys fail at composition."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_module
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

from gyrolab.kernels.scenes import SCENES
from gyrolab.runner.config import ConfigError, check_values, config_hash, register_configs
from gyrolab.runner.grid import build_grid

CONF = Path(__file__).resolve().parents[1] / "conf"
register_configs()


def composed(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return compose("config", overrides=list(overrides))


def options(group):
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def test_default_config_is_the_main_study():
    cfg = composed()
    assert cfg.scene.name == "heavy_top"
    assert list(cfg.sweep.f) == [1.0, 10.0, 50.0] and list(cfg.sweep.theta0) == [45.0]
    assert {"seed_next", "seed_prev"} <= set(cfg.sweep.method) and len(cfg.sweep.method) >= 4
    grid = build_grid(cfg)
    assert grid.n_runs == len(cfg.sweep.method) * 3 * len(cfg.sweep.dt)


def test_one_scene_config_per_scene_module_with_its_options():
    assert options("scene") == sorted(SCENES)
    for name, module in SCENES.items():
        cfg = composed(f"scene={name}")
        keys = OmegaConf.to_container(cfg.scene)
        assert keys.pop("name") == name
        assert keys == module.OPTIONS, f"conf/scene/{name}.yaml must hold exactly {name}.OPTIONS"


@pytest.mark.parametrize("group", ["sweep", "output", "runner"])
def test_every_group_option_composes_and_builds(group):
    for option in options(group):
        build_grid(composed(f"{group}={option}"))


@pytest.mark.slow
@pytest.mark.parametrize("experiment", options("experiment"))
def test_every_experiment_composes_and_builds(experiment):
    cfg = composed(f"experiment={experiment}")
    grid = build_grid(cfg)
    assert grid.n_runs >= 1


@pytest.mark.parametrize(
    "override, key",
    [
        ("sweep.t_end=abc", "sweep.t_end"),
        ("sweep.f=[1,x]", "sweep.f"),
        ("sweep.f=10", "sweep.f"),  # axes are lists
        ("scene.M=heavy", "scene.M"),
        ("runner.dry_run=maybe", "runner.dry_run"),
        ("runner.threads=1.5", "runner.threads"),
        ("sweep.tend=3", "sweep.tend"),  # unknown key
        ("output.pth=x.h5", "output.pth"),
    ],
)
def test_schema_rejects_wrong_type_or_unknown_key(override, key):
    with pytest.raises(ConfigCompositionException) as info:
        composed(override)
    assert key.split(".")[-1] in str(info.value) + str(info.value.__cause__)


def test_keys_appended_with_plus_are_refused_too():
    for override, key in (("+sweep.foo=1", "sweep.foo=1"), ("+bar=2", "bar=2")):
        with pytest.raises(ConfigError, match=key):
            check_values(composed(override))
    with pytest.raises(ValueError, match="scene.foo"):
        build_grid(composed("+scene.foo=1"))


def test_scene_options_are_typed_per_scene():
    with pytest.raises(ConfigCompositionException):
        composed("scene=free_asymmetric", "scene.M=1")  # M is a heavy_top option
    assert composed("scene=free_asymmetric", "scene.I1=2e-4").scene.I1 == 2e-4


def test_hash_ignores_how_a_sweep_is_run_but_not_what_it_computes():
    base = config_hash(composed())
    assert (
        config_hash(
            composed(
                "runner.threads=1",
                "runner.chunk_seconds=0.1",
                "output.overwrite=true",
                "runner.resume=true",
                "output.figures=false",
            )
        )
        == base
    )
    assert config_hash(composed("output.every=2e-3")) != base
    assert config_hash(composed("scene.M=2")) != base
    assert config_hash(composed("runner.divergence_threshold=5")) != base


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["sweep.t_end=1e20"], "sweep.t_end=1e+20"),
        (["sweep.dt=[1e-300]"], "sweep.dt=1e-300"),
        (["sweep.f=[1e200]"], "sweep.f=1e+200: too fast"),
        (["output.figures=2"], "output.figures=2"),
        (["scene.phidot0=3"], "scene.phidot0=3.0: only used with scene.init=precession"),
        (["scene.init=steady_slow", "scene.phidot0=1"], "scene.phidot0=1.0"),
    ],
)
def test_values_a_type_cannot_rule_out_are_one_line_errors(overrides, message):
    with pytest.raises(ConfigError) as info:
        check_values(composed(*overrides))
    assert message in str(info.value) and "\n" not in str(info.value)


def test_phidot0_with_precession_is_accepted():
    check_values(composed("scene.init=precession", "scene.phidot0=3"))
