"""Sweep axes as ranges (runner/ranges.py): the resolvers, in a config file and on the command line."""

import re

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

from gyrolab.runner.config import ConfigError, check_values, register_configs
from gyrolab.runner.ranges import RangeError, int_range, linspace, logspace

from helpers import assert_ok, gyrolab

register_configs()


def test_linspace_includes_both_ends():
    assert linspace(1, 100, 100) == [float(v) for v in range(1, 101)]
    assert linspace(15, 75, 5) == [15.0, 30.0, 45.0, 60.0, 75.0]
    assert linspace(2.5, 2.5, 1) == [2.5]


def test_logspace_takes_the_end_values_and_rounds_to_exact_decades():
    assert logspace(1e-5, 1e-3, 3) == [1e-5, 1e-4, 1e-3]  # not 1.0000000000000002e-4
    assert logspace(1e-3, 1e-6, 4) == [1e-3, 1e-4, 1e-5, 1e-6]
    np.testing.assert_allclose(logspace(1, 100, 5), np.geomspace(1, 100, 5), rtol=1e-12)


def test_range_is_pythons_with_the_stop_excluded():
    assert int_range(1, 101) == [float(v) for v in range(1, 101)]
    assert int_range(15, 90, 15) == [15.0, 30.0, 45.0, 60.0, 75.0]
    assert int_range(90, 0, -30) == [90.0, 60.0, 30.0]


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: linspace(1, 2), "linspace: takes start,stop,num, got 2"),
        (lambda: linspace(1, 2, 0), "num must lie in 1..1000000, got 0"),
        (lambda: linspace(1, 2, 2.5), "num must be an integer, got 2.5"),
        (lambda: linspace("a", 2, 3), "start must be a number, got 'a'"),
        (lambda: logspace(-5, -3, 3), "logspace: start and stop are the end values, not exponents"),
        (lambda: logspace(1e-5, 1e-3, 10**7), "num must lie in 1..1000000"),
        (lambda: int_range(1, 10, 0), "range: step must not be 0"),
        (lambda: int_range(10, 1), "range: range(10, 1, 1) is empty"),
        (lambda: int_range(1.5, 10), "start must be an integer, got 1.5"),
        (lambda: int_range(1), "range: takes start,stop[,step], got 1"),
    ],
)
def test_bad_arguments_say_what_is_wrong(call, message):
    with pytest.raises(RangeError, match=re.escape(message)):
        call()


def compose_with(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return compose("config", overrides=list(overrides))


def test_ranges_fill_the_sweep_axes_through_hydra_overrides():
    cfg = compose_with(
        "sweep.f=${linspace:1,100,100}", "sweep.theta0=${range:15,90,15}", "sweep.dt=${logspace:1e-5,1e-3,3}"
    )
    check_values(cfg)
    assert list(cfg.sweep.f) == [float(v) for v in range(1, 101)]
    assert list(cfg.sweep.theta0) == [15.0, 30.0, 45.0, 60.0, 75.0]
    assert list(cfg.sweep.dt) == [1e-5, 1e-4, 1e-3]


@pytest.mark.parametrize(
    "override, message",
    [
        ("sweep.f=${linspace:1,5,x}", "sweep.f=${linspace:1,5,x}: linspace: num must be a number, got 'x'"),
        ("sweep.dt=${logspace:-5,-3,3}", "sweep.dt=${logspace:-5,-3,3}: logspace: start and stop are the end values"),
        ("sweep.f=${lnspace:1,5,5}", "sweep.f=${lnspace:1,5,5}: Unsupported interpolation type lnspace (sweep ranges"),
        ("sweep.t_end=${range:1,3}", "sweep.t_end=${range:1,3}: Value '[1.0, 2.0]' of type 'list'"),
    ],
)
def test_a_bad_range_is_a_config_error_naming_key_and_expression(override, message):
    with pytest.raises(ConfigError) as err:
        check_values(compose_with(override))
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


@pytest.mark.slow
def test_ranges_on_the_command_line_and_in_a_config_file(tmp_path):
    (tmp_path / "conf" / "experiment").mkdir(parents=True)
    (tmp_path / "conf" / "experiment" / "ranged.yaml").write_text(
        "# @package _global_\nsweep:\n  f: ${linspace:10,50,2}\n  theta0: ${range:30,60,15}\n"
        "  dt: ${logspace:1e-4,1e-3,2}\n  method: [seed_next]\n  t_end: 0.01\n"
    )
    run = tmp_path / "run"
    result = gyrolab(
        f"--config-dir={tmp_path / 'conf'}",
        "experiment=ranged",
        "output.figures=false",
        f"hydra.run.dir={run}",
        cwd=tmp_path,
    )
    assert_ok(result)
    with xr.open_dataset(run / "results.h5", engine="h5netcdf") as ds:
        assert list(ds.f.values) == [10.0, 50.0] and list(ds.theta0.values) == [30.0, 45.0]
        assert list(ds.dt.values) == [1e-4, 1e-3]
    dry = gyrolab("sweep.f=${range:1,101}", "sweep.method=[seed_next]", "runner.dry_run=true", cwd=tmp_path)
    assert_ok(dry)
    assert "1 method x 100 f x 1 theta0 x 3 dt = 300 runs" in dry.stdout
    bad = gyrolab(
        "sweep.f=${range:1,101,0}", "sweep.method=[seed_next]", f"hydra.run.dir={tmp_path / 'bad'}", cwd=tmp_path
    )
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == ["gyrolab: error: sweep.f=${range:1,101,0}: range: step must not be 0"]
    assert not (tmp_path / "bad").exists()


@pytest.mark.slow
def test_help_shows_the_ranges(tmp_path):
    result = gyrolab("--help", cwd=tmp_path)
    assert_ok(result)
    for text in ("${linspace:1,100,100}", "${logspace:1e-5,1e-3,3}", "${range:15,90,15}"):
        assert text in result.stdout
