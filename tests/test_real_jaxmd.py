"""jax-md's rigid-body NVE in the loop (kernels/real/jaxmd_engine.py: real_jaxmd_nve).

- ``integrate`` gives no_squish's samples to rounding on free asymmetric bodies at a dt exact in float32
  (jax-md steps NO_SQUISH in (q, p), gyrolab's no_squish in (ω, q): tests/test_jaxmd.py checks the step);
- at a dt not exact in float32 it runs float32(dt), as jax-md's velocity_verlet casts it: no_squish's
  samples at float32(dt) to rounding, a phase drift against no_squish at dt;
- one compilation serves every run and every stride;
- a heavy body and a zero moment are refused in one line, the grid check refusing the heavy scene before any
  work; the engine and its version go into a sweep's file next to no_squish's runs.

Skipped with a reason where jax-md does not import (``pip install '.[engines]'``).
"""

import numpy as np
import pytest

from gyrolab.kernels import real
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.body import Body
from gyrolab.kernels.driver import STATUS_OK
from gyrolab.kernels.real.jaxmd_engine import engine_dt
from gyrolab.kernels.scenes import build_scene

pytestmark = pytest.mark.engine("real_jaxmd_nve")
NAME = "real_jaxmd_nve"


def relative(a, b):
    """max |a − b| over each field's scale in b (a field identically 0 compared absolutely)."""
    scale = np.abs(b).max(axis=1, keepdims=True)
    return np.max(np.abs(a - b) / np.where(scale > 0, scale, 1.0))


def random_inputs(moments, n, seed):
    """n runs of one body: ω ~ 3 rad/s per component (body frame), q uniform on S³."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    return np.array([Body(*moments, 0.0)] * n), rng.normal(scale=3.0, size=(n, 3)), q


@pytest.mark.parametrize("moments", [(1.0, 0.7, 0.4), (0.4, 1.0, 0.7)], ids=["decreasing", "unsorted"])
def test_jaxmd_nve_gives_no_squish_samples(moments):
    """4 runs, 100 samples of 4 steps of 2⁻⁸ s (jax-md's float32 cast leaves it unchanged): the kernels' shapes,
    status and step counts, sample 0 identical, every field within 1e-12 of its scale of no_squish's
    (measured ≤ 7.4e-14: jax-md carries (q, p), no_squish (ω, q) renormalising q)."""
    args = (*random_inputs(moments, 4, 2404), 2.0**-8, 4, 101)
    got, want = integrate(NAME, *args), integrate("no_squish", *args)
    assert got[0].shape == want[0].shape and (got[1] == STATUS_OK).all()
    assert np.array_equal(got[1], want[1]) and np.array_equal(got[2], want[2])
    assert np.array_equal(got[0][:, 0], want[0][:, 0])
    assert relative(got[0], want[0]) < 1e-12


def test_tennis_racket_agrees_to_no_squishs_own_spread():
    """The tennis-racket box (free_asymmetric, 10 Hz), 1 s at dt = 2⁻¹⁰ s: before the first flip (t ≤ 0.2 s)
    within 1e-11 of no_squish (measured 1.1e-12); over the flips within 1e-8, the size of no_squish's own change
    when ω3 moves by one ulp (measured 2.4e-9 against its 1.3e-9: the flips amplify rounding, as for MuJoCo)."""
    sc = build_scene("free_asymmetric", 10.0, 30.0)
    B, W, Q = (np.array([x]) for x in (sc.body, sc.omega0, sc.q0))
    args = (2.0**-10, 10, 101)
    got, want = integrate(NAME, B, W, Q, *args)[0], integrate("no_squish", B, W, Q, *args)[0]
    assert relative(got[:, :21], want[:, :21]) < 1e-11
    assert relative(got, want) < 1e-8


def test_a_dt_not_exact_in_float32_runs_as_float32_dt():
    """dt = 1e-3 s is run as float32(1e-3) = 1.00000005e-3 s (jax-md's velocity_verlet cast): 100 samples of
    10 steps agree with no_squish at float32(dt) within 1e-12 of each field's scale (measured 1.4e-13), and
    differ from no_squish at dt by more than 1e-9 (measured 3.8e-7 by t = 1 s: the engine is 4.7e-8 s
    ahead of the time its sample is labelled with)."""
    assert engine_dt(1e-3) == float(np.float32(1e-3)) != 1e-3
    assert engine_dt(2.0**-10) == 2.0**-10
    args = (*random_inputs((1.0, 0.7, 0.4), 1, 2405), 1e-3, 10, 101)
    got = integrate(NAME, *args)[0]
    at_float32 = integrate("no_squish", *args[:3], engine_dt(1e-3), *args[4:])[0]
    assert relative(got, at_float32) < 1e-12
    assert relative(got, integrate("no_squish", *args)[0]) > 1e-9


def test_one_compilation_serves_every_run_and_stride():
    """The jitted loop takes dt, the moments, the state and the step count as data: runs of two bodies at two dt
    and three strides reuse one compilation."""
    backend = real.get_backend(NAME)
    for moments, dt in (((1.0, 0.7, 0.4), 2.0**-8), ((0.3, 0.2, 0.25), 1e-4)):
        for stride in (1, 3, 7):
            integrate(NAME, *random_inputs(moments, 1, 2406), dt, stride, 3)
    assert backend.steps._cache_size() == 1


def test_refusals_are_one_line():
    """A heavy body (jax-md has no joint) and a zero moment are refused in one line, by the backend and by the
    grid check before any work; a driven body by integrate."""
    from helpers import check_free_body_refusals

    check_free_body_refusals(NAME, "no_squish", Body(1.0, 0.0, 0.5, 0.0))


def test_version_and_defaults_are_declared():
    """The provenance names the package and its version; the backend states its hidden defaults."""
    assert real.PACKAGES[NAME] == "jax-md" and real.IMPORT_NAMES["jax-md"] == "jax_md"
    assert real.engine_version(NAME).startswith("jax-md 0.")
    defaults = real.get_backend(NAME).DEFAULTS
    assert "x64" in defaults and "float32(dt)" in defaults


@pytest.mark.slow
def test_sweep_with_jaxmd_writes_one_file_that_opens(tmp_path):
    """real_jaxmd_nve next to no_squish on the tennis-racket box at a float32-exact dt: one results file, jax-md's
    version in its attrs, status 0, the two integrators' ω within 1e-12 of the spin (measured 8.8e-15).
    Slow: the subprocess imports jax-md, whose rigid_body module builds its example shapes with eager JAX
    calls at import (35 s on the loaded 2-core machine, of which ~18 s the import)."""
    from helpers import free_body_sweep

    ds = free_body_sweep([NAME, "no_squish"], tmp_path, f="[5]", dt=f"[{2.0**-10!r}]", t_end=0.25, every=0.015625)
    assert ds.attrs["engine_versions"].startswith("jax-md ")
    assert (ds.status == 0).all() and ds.sizes["time"] == 17
    a, b = ds.omega.sel(integrator=NAME), ds.omega.sel(integrator="no_squish")
    assert float(abs(a - b).max()) < 1e-12 * 2 * np.pi * 5
