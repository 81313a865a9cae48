"""output.variables: the per-sample variables a results file holds, and every reader of such a file."""

import numpy as np
import pytest
import xarray as xr
from hydra import compose, initialize_config_module

from gyrolab.results.layout import RUN_VARIABLES, SAMPLE_VARIABLES, VARIABLES_ATTR, held_variables, stored_per_sample
from gyrolab.runner.config import ConfigError, register_configs
from gyrolab.runner.grid import build_grid

from helpers import TINY, assert_ok, gyrolab

register_configs()
SMALL = [a for a in TINY if not a.startswith("sweep.method")] + ["sweep.method=[seed_next]"]


def grid_of(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        return build_grid(compose("config", overrides=[*SMALL, *overrides]))


def test_default_stores_every_variable_and_the_estimates_follow_a_choice():
    full, chosen = grid_of(), grid_of("output.variables=[energy,theta,axis]")
    assert full.variables == tuple(SAMPLE_VARIABLES)
    assert chosen.variables == ("axis", "theta", "energy")  # the layout's order
    assert full.bytes_stored() == full.n_runs * full.n_samples * stored_per_sample() * 8
    assert chosen.bytes_stored() * stored_per_sample() == full.bytes_stored() * 5  # axis 3 + theta + energy
    assert chosen.bytes_per_run() < full.bytes_per_run()


@pytest.mark.parametrize(
    "value, message",
    [
        ("[theta,thta]", "output.variables=[theta,thta]: unknown variable 'thta'; choose from axis, theta, phi"),
        ("[theta,theta]", "output.variables=[theta,theta]: variable 'theta' appears twice"),
    ],
)
def test_unknown_or_repeated_names_are_refused(value, message):
    with pytest.raises(ConfigError) as err:
        grid_of(f"output.variables={value}")
    assert str(err.value).startswith(message)


@pytest.mark.slow
def test_a_bad_name_on_the_command_line_is_one_line_before_any_work(tmp_path):
    result = gyrolab(*SMALL, "output.variables=[energy,Energy]", f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("gyrolab: error: output.variables=[energy,Energy]: unknown variable 'Energy'")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("variables")
    for name, extra in (("chosen", ["output.variables=[theta,energy]"]), ("full", [])):
        assert_ok(gyrolab(*SMALL, *extra, f"hydra.run.dir={root / name}", cwd=root))
    return root / "chosen" / "results.h5", root / "full" / "results.h5"


@pytest.mark.slow
def test_the_file_holds_the_chosen_variables_and_the_per_run_ones(files):
    chosen, full = files
    with xr.open_dataset(chosen, engine="h5netcdf") as a, xr.open_dataset(full, engine="h5netcdf") as b:
        assert set(a.data_vars) == {"theta", "energy", *RUN_VARIABLES, "body", "omega0", "q0"}
        assert a.attrs[VARIABLES_ATTR] == "theta energy" and VARIABLES_ATTR not in b.attrs
        assert held_variables(a) == ("theta", "energy") and held_variables(b) == tuple(SAMPLE_VARIABLES)
        for name in ("theta", "energy", "status", "n_steps"):
            np.testing.assert_array_equal(a[name].values, b[name].values)
    assert chosen.stat().st_size < full.stat().st_size / 2


@pytest.mark.slow
def test_a_figure_that_needs_a_missing_variable_is_one_line(files, tmp_path):
    from gyrolab.analysis.figures.registry import FIGURES, standard_figures
    from gyrolab.analysis.io import MissingVariableError
    from gyrolab.results import open_results

    chosen, _ = files
    ds = open_results(chosen)
    with pytest.raises(MissingVariableError, match="figure tip needs variable axis, which this file does not hold"):
        FIGURES["tip"].write(ds, tmp_path / "tip.png")
    result = gyrolab_plot("tip", str(chosen), "-o", str(tmp_path / "tip.png"), cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("gyrolab-plot: error: figure tip needs variable axis")
    with pytest.raises(MissingVariableError, match="figure energy needs variable Lz, which this file does not hold"):
        FIGURES["energy"].write(ds, tmp_path / "lz.png", quantity="Lz")  # conserved, but not stored
    drawn = standard_figures(str(chosen), str(tmp_path / "std"), ["nutation", "energy"], log=None)
    assert [p.name for p in drawn] == ["nutation_theta.png", "energy_drift.png"]


def gyrolab_plot(*args, cwd):
    import subprocess

    from helpers import command, environment

    return subprocess.run(
        command("gyrolab-plot", "gyrolab.analysis.figures.cli") + list(args),
        cwd=cwd,
        capture_output=True,
        text=True,
        env=environment(),
    )


@pytest.mark.slow
def test_compare_compares_the_variables_both_hold_and_says_which_it_left_out(files):
    from gyrolab.analysis.files.compare import compare_files

    chosen, full = files
    report = compare_files(chosen, full)
    per_run = {"status", "n_steps", "solver_iterations", "solver_iterations_max"}  # compared exactly
    assert {v.name for v in report.variables} == {"theta", "energy"} | per_run
    assert any("variable omega (not stored in" in d for d in report.dropped)


def test_combine_refuses_files_of_different_variables(files):
    from gyrolab.analysis.files.combine import CombineError, combine

    chosen, full = files
    with pytest.raises(CombineError, match="combine files of the same output.variables"):
        combine([chosen, full])
    assert set(combine([chosen]).data_vars) >= {"theta", "energy"}
