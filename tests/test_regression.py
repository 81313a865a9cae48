"""Regression: re-run every regression config for every registered method with the real ``gyrolab``
command and compare each fresh file with its stored dataset
(tests/data/regression/<config>/<method>.pack.xz, read by regenerate.read_pack), using
gyrolab-compare's own ``compare_datasets``.  A method or config without stored data fails with
the one command that adds it (``python tests/data/regenerate.py --add``).

Tolerance (tests/data/README.md explains the numbers): a value passes when
|fresh − stored| <= 1e-10 × the largest |value| of that variable in the stored
file; status and n_steps exactly.  Last-bit changes (what another CPU's libm
or another numba could bring) move these datasets by at most ~5e-13 of that
scale; a 6e-5 relative change in one coefficient of lie_poisson4 moves them by
~1e-8 (test_coefficient_change_fails_with_a_readable_message).
"""

import importlib.resources
import importlib.util
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr
import yaml

import gyrolab
from gyrolab.analysis.files.compare import compare_datasets, compare_files
from gyrolab.kernels.batch import sample_schedule
from gyrolab.kernels.registry import METHODS
from gyrolab.kernels.scenes import SCENES, build_scene
from gyrolab.results.layout import sample_variables
from gyrolab.results.migrate import current

from helpers import CONTROL_FAILURES

_spec = importlib.util.spec_from_file_location("regenerate", Path(__file__).parent / "data" / "regenerate.py")
regen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(regen)

# One pack per (config, method), ~5-19 kB each (tests/data/README.md): a method's data over all the
# datasets must stay within MAX_METHOD_BYTES, so ~100 methods fit in MAX_TOTAL_BYTES.
MAX_METHOD_BYTES = 100 * 1024
MAX_TOTAL_BYTES = 12 * 2**20


def one_method(path, method):
    """Method ``method``'s runs of a results file that holds several, with the config attr it would
    have had as a run of that method alone (sweep.method = [method]): a run's results do not depend
    on the other runs of its sweep (tests/test_block.py, tests/test_runner_cli.py)."""
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        ds = ds.load()
    part = ds.sel({"integrator": [method]})
    config = yaml.safe_load(ds.attrs["config"])
    config["sweep"]["method"] = [method]
    return part.assign_attrs(config=yaml.safe_dump(config, sort_keys=False))


def check_against_stored(fresh, name, method, stored=None):
    """Fail with the comparison table (and how to regenerate) unless ``fresh`` (a path, or a Dataset
    from ``one_method``) matches the stored dataset of regression config ``name`` for ``method`` (or
    the file ``stored``) and was made by the same config."""
    stored = Path(stored or regen.stored_path(name, method))
    if not stored.exists():
        pytest.fail(
            f"no stored regression data for method {method} on {name}; add it with:\n    {regen.ADD_COMMAND}",
            pytrace=False,
        )
    if isinstance(fresh, xr.Dataset):
        report = compare_datasets(fresh, regen.read_pack(stored), scaled=regen.SCALED_TOL)
        report.a, report.b = "fresh run", str(stored)
    else:
        report = regen.compare_with_stored(fresh, stored)
    hint = (
        f"If the change is intended, regenerate on purpose and commit the new file:\n"
        f"    python tests/data/regenerate.py --write {name}:{method}"
    )
    text = f"A = fresh run, B = {stored.name}\n{report.text()}\n{hint}"
    if report.configs:
        pytest.fail(
            f"{stored.name} was made with a different config than "
            f"conf/experiment/regression_{name}.yaml now holds\n{text}",
            pytrace=False,
        )
    if report.versions:
        warnings.warn(f"{stored.name}: {'; '.join(report.versions)} (compared within tolerance anyway)")
    if not report.ok:
        pytest.fail(f"regression {name}/{method}: fresh run differs from the stored dataset\n{text}", pytrace=False)
    return report


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """``fresh(name, method)``: path of a fresh run of regression config ``name`` for ``method``
    (each run once per module)."""
    work = tmp_path_factory.mktemp("regression")
    done = {}

    def get(name, method):
        if (name, method) not in done:
            done[name, method] = regen.run_config(name, method, work / f"{name}_{method}.h5", work)
        return done[name, method]

    return get


def selected_methods(session, name):
    """The methods whose rerun test of dataset ``name`` this session runs (after -k and the like)."""
    return [
        item.callspec.params["method"]
        for item in session.items
        if getattr(item, "originalname", None) == "test_rerun_matches_stored_dataset"
        and item.callspec.params["name"] == name
    ]


@pytest.fixture(scope="module")
def fresh_all(request, tmp_path_factory):
    """``fresh_all(name)``: path of one fresh run of regression config ``name`` with every method
    whose rerun test is selected (one gyrolab process per config instead of one per method, and
    ``pytest -k METHOD`` compiles and runs only the methods it selects)."""
    work = tmp_path_factory.mktemp("regression_all")
    done = {}

    def get(name):
        if name not in done:
            methods = selected_methods(request.session, name)
            done[name] = regen.run_config(name, methods, work / f"{name}.h5", work)
        return done[name]

    return get


PAIRS = [(name, method) for name in regen.DATASETS for method in regen.dataset_methods(name)]


@pytest.mark.slow
@pytest.mark.parametrize("name,method", PAIRS, ids=[f"{n}-{m}" for n, m in PAIRS])
def test_rerun_matches_stored_dataset(fresh_all, name, method):
    check_against_stored(one_method(fresh_all(name), method), name, method)


@pytest.mark.slow
def test_same_machine_rerun_is_bit_identical(fresh, tmp_path):
    """The most sensitive dataset (tennis-racket flip) twice, with 1 thread and with all: identical bits."""
    first = fresh("free_asymmetric", "lie_poisson4")
    again = regen.run_config("free_asymmetric", "lie_poisson4", tmp_path / "again.h5", tmp_path, ["runner.threads=1"])
    report = compare_files(again, first)  # zero tolerance
    assert report.ok, report.text()


@pytest.mark.slow
def test_stored_dataset_from_another_config_or_version_is_named_up_front(fresh, tmp_path):
    """A stored file whose recorded config (g) and gyrolab version differ: the check fails on the
    config, and the first lines of its message say what differs."""
    copy = tmp_path / f"old{regen.PACK_SUFFIX}"
    ds = regen.read_pack(regen.stored_path("heavy_top_release", "rk4"))
    config = yaml.safe_load(ds.attrs["config"])
    config["scene"]["g"] = 9.81
    ds.attrs["config"] = yaml.safe_dump(config, sort_keys=False)
    ds.attrs["gyrolab_version"] = "0.0.9"
    regen.write_pack(ds, copy)
    with pytest.raises(pytest.fail.Exception) as failure:
        check_against_stored(fresh("heavy_top_release", "rk4"), "heavy_top_release", "rk4", stored=copy)
    lines = str(failure.value).splitlines()
    assert lines[0] == (
        f"old{regen.PACK_SUFFIX} was made with a different config than "
        "conf/experiment/regression_heavy_top_release.yaml now holds"
    )
    assert lines[4] == f"PROVENANCE: gyrolab_version differs: A {gyrolab.__version__}, B 0.0.9"
    assert lines[5] == "PROVENANCE: config differs: scene.g: A 10.0, B 9.81"


def test_every_regression_config_and_method_has_a_stored_dataset():
    """Coverage: every regression config has a stored file per registered method, and nothing else is
    stored; the failure names the command that adds what is missing."""
    experiments = importlib.resources.files("gyrolab.conf") / "experiment"
    configs = sorted(
        p.name[len("regression_") : -len(".yaml")]
        for p in experiments.iterdir()
        if p.name.startswith("regression_") and p.name.endswith(".yaml")
    )
    assert configs == sorted(regen.PINNED)
    assert {regen.pinned_scene(n) for n in regen.PINNED} | {
        d[len("scene_") :] for d in regen.DATASETS if d.startswith("scene_")
    } == set(SCENES)
    missing = [f"{n}/{m}" for n, m in PAIRS if not regen.stored_path(n, m).exists()]
    assert not missing, f"no stored regression data for {', '.join(missing)}; add it with: {regen.ADD_COMMAND}"
    expected = {regen.stored_path(n, m) for n, m in PAIRS}
    stray = sorted(
        str(p.relative_to(regen.DATA_DIR))
        for p in regen.STORE.rglob("*")
        if p.is_file() and p not in expected and not p.name.startswith(".")
    )
    assert not stray, f"stored files of no registered (config, method): {', '.join(stray)}"


@pytest.mark.slow
def test_stored_datasets_open_are_small_and_cover_every_scene_and_method():
    total, scenes, inits, per_method = 0, set(), set(), {}
    for name, method in PAIRS:
        path = regen.stored_path(name, method)
        total += path.stat().st_size
        per_method[method] = per_method.get(method, 0) + path.stat().st_size
        with regen.read_pack(path) as ds:
            config = yaml.safe_load(ds.attrs["config"])
            assert ds.attrs["scene"] == config["scene"]["name"]
            stored_dim = "integrator" if ds.attrs["layout_version"] >= 3 else "method"  # renamed at layout 3
            assert ds[stored_dim].values.tolist() == [method], path
            assert current(ds)["integrator"].values.tolist() == [method], path
            if not (getattr(METHODS[method], "REPRODUCES", "") or method in CONTROL_FAILURES):
                assert (ds["status"].values == 0).all(), f"{path}: a run diverged"
            assert ds.attrs["gyrolab_version"] and ds.attrs["numba_version"] and ds.attrs["git_commit"]
            assert ds.attrs["layout_version"] >= 1 and ds.attrs["kernel_source_hash"]
            scenes.add(ds.attrs["scene"])
            if ds.attrs["scene"] == "heavy_top":
                inits.add(ds.attrs["scene_init"])
    assert total < MAX_TOTAL_BYTES, f"stored datasets take {total / 2**20:.2f} MB"
    large = {m: f"{n / 1024:.0f} kB" for m, n in per_method.items() if n > MAX_METHOD_BYTES}
    assert not large, f"stored data of a method over {MAX_METHOD_BYTES // 1024} kB: {large}"
    assert scenes == set(SCENES)
    assert {"release", "steady_slow"} <= inits


# --------------------------------------------------------------------------- a deliberate coefficient change


def overwrite_method(path, method, run_batch):
    """Recompute every run of ``method`` in the results file ``path`` (in place) with ``run_batch``."""
    from gyrolab.kernels.driver import N_FIELDS

    with xr.open_dataset(path, engine="h5netcdf") as ds:
        config = yaml.safe_load(ds.attrs["config"])
        methods = current(ds)["integrator"].values.tolist()  # a stored file of layout 1 calls it method
        fs, thetas, dts = ds["f"].values, ds["theta0"].values, ds["dt"].values
    options = dict(config["scene"])
    name = options.pop("name")
    im = methods.index(method)
    with h5py.File(path, "r+") as fh:
        for jf, f in enumerate(fs):
            for kt, theta0 in enumerate(thetas):
                for ld, dt in enumerate(dts):
                    sc = build_scene(name, float(f), float(theta0), **options)
                    stride, n = sample_schedule(float(dt), config["output"]["every"], config["sweep"]["t_end"])
                    out = np.empty((1, n, N_FIELDS))
                    status, n_steps = np.zeros(1, np.int8), np.zeros(1, np.int64)
                    iterations = np.zeros((1, 2), np.int64)
                    run_batch(
                        np.array([sc.omega0]),
                        np.array([sc.q0]),
                        np.array([sc.body]),
                        np.array([float(dt)]),
                        np.array([stride]),
                        config["runner"]["divergence_threshold"],
                        out,
                        status,
                        n_steps,
                        iterations,
                    )
                    for var, values in sample_variables(out[0]).items():
                        if var in fh:  # a stored file of an older layout lacks the newer variables
                            fh[var][im, jf, kt, ld] = values
                    fh["status"][im, jf, kt, ld] = status[0]
                    fh["n_steps"][im, jf, kt, ld] = n_steps[0]
                    for column, var in enumerate(("solver_iterations", "solver_iterations_max")):
                        if var in fh:  # layout 4 on
                            fh[var][im, jf, kt, ld] = iterations[0, column]


def test_a_pack_reads_back_as_the_results_file_it_stores(tmp_path):
    """export (a results file again) and pack once more: the same Dataset, bit for bit, and the
    same bytes; a pack that lost bytes is refused."""
    stored = regen.stored_path("scene_forced_body", "rk4")  # ndarray attrs, layout 3
    exported = tmp_path / "rk4.h5"
    regen.export_results(stored, exported)
    again = tmp_path / f"again{regen.PACK_SUFFIX}"
    regen.pack_results(exported, again)
    assert again.read_bytes() == stored.read_bytes()
    with xr.open_dataset(exported, engine="h5netcdf") as ds:
        assert ds.load().identical(regen.read_pack(stored))
    import lzma

    cut = tmp_path / f"cut{regen.PACK_SUFFIX}"
    cut.write_bytes(lzma.compress(lzma.decompress(stored.read_bytes())[:-8]))
    with pytest.raises(ValueError, match="bytes"):
        regen.read_pack(cut)


@pytest.mark.slow
def test_write_keeps_a_stored_pack_of_an_older_layout(capsys):
    """``--write`` on a pack of layout 1 (a fixture of tests/test_layout.py) refuses to move it to
    today's layout without ``--relayout``: the pack's bytes stay, the command says why and exits non-zero."""
    stored = regen.stored_path("heavy_top_release", "rk4")
    before = stored.read_bytes()
    assert regen._layout(regen.read_pack(stored)) == 1
    with pytest.raises(SystemExit, match="kept in their layout: heavy_top_release:rk4"):
        regen.main(["--write", "heavy_top_release:rk4"])
    out = capsys.readouterr().out
    assert "NOT WRITTEN tests/data/regression/heavy_top_release/rk4.pack.xz: stored in layout 1" in out
    assert "Pass --relayout" in out
    assert stored.read_bytes() == before
    with pytest.raises(SystemExit):  # --relayout alone is a usage error
        regen.main(["--relayout", "heavy_top_release:rk4"])


@pytest.mark.slow
def test_coefficient_change_fails_with_a_readable_message(tmp_path):
    """Yoshida's w1 = 1/(2 − 2^(1/3)) with 2^(1/3) written as 1.26 (a 6e-5 relative change):
    the regression check of a copy of the stored file must fail and name lie_poisson4."""
    copy = tmp_path / "perturbed.h5"
    stored = regen.stored_path("heavy_top_release", "lie_poisson4")
    regen.export_results(stored, copy)
    overwrite_method(copy, "lie_poisson4", regen.lie_poisson4_with(1.0 / (2.0 - 1.26)))
    with pytest.raises(pytest.fail.Exception) as failure:
        check_against_stored(copy, "heavy_top_release", "lie_poisson4")
    message = str(failure.value)
    print(message)  # what a developer sees (pytest -s)
    assert "regression heavy_top_release/lie_poisson4: fresh run differs from the stored dataset" in message
    assert "run differing most: integrator=lie_poisson4" in message
    assert "out of tolerance in 2 of 2 runs" in message  # both dt
    assert "python tests/data/regenerate.py --write heavy_top_release:lie_poisson4" in message
    report = regen.compare_with_stored(copy, stored)
    worst = max((v for v in report.variables if not v.ok), key=lambda v: v.max_abs / max(v.atol, 1e-300))
    assert worst.max_abs > 10 * worst.atol  # fails by a wide margin, not by a hair
    # the same copy with the true coefficient passes again: the check is about the coefficient
    overwrite_method(copy, "lie_poisson4", regen.lie_poisson4_with(1.0 / (2.0 - 2.0 ** (1.0 / 3.0))))
    check_against_stored(copy, "heavy_top_release", "lie_poisson4")
