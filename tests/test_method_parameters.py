"""Methods with parameters (kernels/parameters.py, kernels/variants.py): names, the same bits at the
defaults, what each parameter changes, and a sweep that records the variant it ran."""

import numpy as np
import pytest

from gyrolab.kernels import variants
from gyrolab.kernels.body import Body
from gyrolab.kernels.euler_poinsot import free_body
from gyrolab.kernels.registry import METHODS, canonical_name, get_method, select_methods, stepper

from helpers import DRIVEN_BODY, free_body_sweep, random_states, step_run

EPS = np.finfo(float).eps
WITH_PARAMETERS = [name for name, mod in METHODS.items() if hasattr(mod, "PARAMETERS")]


def ulps(a, b):
    """max |a − b| in units of the double-precision spacing at the larger of the two vectors' norms."""
    a, b = np.asarray(a), np.asarray(b)
    return np.max(np.abs(a - b)) / (EPS * max(np.linalg.norm(a), np.linalg.norm(b)))


def test_the_methods_that_take_parameters():
    """The axis splittings and their composition, NO_SQUISH and generalized-α declare their choices."""
    assert {"lie_poisson", "lie_poisson4", "no_squish", "lie_genalpha"} <= set(WITH_PARAMETERS)
    assert set(get_method("no_squish").PARAMETERS) == {"axes", "substeps"}


@pytest.mark.parametrize(
    "given, expected",
    [
        ("lie_poisson(axes=1-2-3)", "lie_poisson"),  # every value the default: the plain name
        ("lie_poisson(axes=s-m-l)", "lie_poisson(axes=S-M-L)"),
        (" no_squish( substeps=10 , axes=1-2-3 ) ", "no_squish(axes=1-2-3,substeps=10)"),  # declared order
        ("no_squish(axes=3-2-1,substeps=4)", "no_squish(substeps=4)"),
        ("lie_genalpha(rho_inf=0.60)", "lie_genalpha(rho_inf=0.6)"),
        ("lie_genalpha(rho_inf=1)", "lie_genalpha(rho_inf=1.0)"),
        ("rk4", "rk4"),
    ],
)
def test_a_name_with_parameters_becomes_canonical(given, expected):
    assert canonical_name(given)[0] == expected
    assert select_methods([given]) == [expected]


def test_names_that_mean_the_same_variant_run_once():
    given = ["lie_poisson", "lie_poisson(axes=1-2-3)", "lie_poisson(axes=S-M-L)", "lie_poisson(axes=s-m-l)"]
    assert select_methods(given) == ["lie_poisson", "lie_poisson(axes=S-M-L)"]


@pytest.mark.parametrize(
    "bad, says",
    [
        ("rk4(axes=1-2-3)", "rk4 takes no parameters"),
        ("lie_poisson(order=1-2-3)", "unknown parameter; lie_poisson takes axes"),
        ("lie_poisson(axes=1-1-2)", "not an axis order"),
        ("lie_poisson(axes=1-2-M)", "not an axis order"),  # labels and ranks do not mix
        ("no_squish(substeps=0)", "not a count"),
        ("no_squish(substeps=2.5)", "not a count"),
        ("lie_genalpha(rho_inf=1.5)", "not a number from 0 to 1"),
        ("lie_genalpha(rho_inf=nan)", "not a number from 0 to 1"),
        ("lie_poisson(axes=1-2-3,axes=3-2-1)", "given twice"),
        ("lie_poisson(axes)", "method(name=value,...)"),
        ("lie_poisson(axes=1-2-3", "method(name=value,...)"),
        ("nosuch(a=1)", "unknown method"),
    ],
)
def test_a_bad_name_is_one_line_naming_what_is_wrong(bad, says):
    with pytest.raises(ValueError) as err:
        select_methods([bad])
    assert says in str(err.value) and "\n" not in str(err.value)


def test_a_sweep_with_a_bad_parameter_fails_before_any_work(tmp_path):
    from helpers import gyrolab

    res = gyrolab('sweep.method=["no_squish(substeps=0)"]', "output.figures=false", cwd=tmp_path)
    assert res.returncode != 0
    assert "sweep.method=no_squish(substeps=0)" in res.stderr and "not a count" in res.stderr
    assert not list(tmp_path.rglob("*.h5"))


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_PARAMETERS)
def test_a_variant_at_the_defaults_is_the_method_bit_for_bit(name):
    """``variant(**defaults)`` (built here directly: the registry never builds it, the canonical name of
    the defaults being the plain name) steps exactly as the method, driven and undriven, and its runs
    (carried state threaded) too."""
    module = METHODS[name]
    values = canonical_name(name)[1]
    same = variants.build(module, f"{name}(defaults)", values)
    for w, q, t, dt in random_states(20, 7):
        assert same.step(w, q, dt, DRIVEN_BODY) == module.step(w, q, dt, DRIVEN_BODY)
        if hasattr(module, "step_driven"):
            assert same.step_driven(w, q, t, dt, DRIVEN_BODY) == module.step_driven(w, q, t, dt, DRIVEN_BODY)
    body = Body(0.02, 0.025, 0.008, 0.98, 0.29, 0.1, 0.3, -0.2, 0.75, 0.0, 0.0, 0.0)
    runs = []
    for mod in (module, same):
        start, step_carried = stepper(mod)
        w, q = (3.0, -20.0, 40.0), (1.0, 0.0, 0.0, 0.0)
        c = start(w, q, body)
        for _ in range(50):
            w, q, c = step_carried(w, q, c, 2e-3, body)
        runs.append((w, q))
    assert runs[0] == runs[1]


def test_lie_poisson_sorted_is_lie_poisson_with_the_axes_sorted_by_moment():
    """The registered lie_poisson_sorted and lie_poisson(axes=S-M-L) are one map, on every labelling of
    an asymmetric heavy body (its moments in any order of the labels)."""
    sorted_, by_name = METHODS["lie_poisson_sorted"], get_method("lie_poisson(axes=S-M-L)")
    for labels in ((0.02, 0.025, 0.008), (0.008, 0.02, 0.025), (0.025, 0.008, 0.02)):
        body = Body(*labels, 0.98, 0.29, 0.1, 0.3, -0.2, 0.75, 3.0, 0.0, 100.0)
        for w, q, t, dt in random_states(20, 3):
            assert by_name.step_driven(w, q, t, dt, body) == sorted_.step_driven(w, q, t, dt, body)


@pytest.mark.parametrize("axes", ["1-2-3", "2-3-1", "S-M-L"])
def test_no_squish_in_an_axis_order_is_lie_poisson_in_that_order(axes):
    """NO_SQUISH in (q, p) and lie_poisson in (ω, q), both turning about the axes in the order ``axes``,
    are one map to ≤ 10 ulp a step on a driven asymmetric heavy body (the shipped 3-2-1 is checked in
    test_md_methods.py); a different order is a different map (more than 1e-8 apart, relative, somewhere)."""
    ns, lp = get_method(f"no_squish(axes={axes})"), get_method(f"lie_poisson(axes={axes})")
    shipped = METHODS["no_squish"]
    worst = apart = 0.0
    for w, q, t, dt in random_states(200, 11):
        a, b = ns.step_driven(w, q, t, dt, DRIVEN_BODY), lp.step_driven(w, q, t, dt, DRIVEN_BODY)
        worst = max(worst, ulps(a[0], b[0]), ulps(a[1], b[1]))
        apart = max(apart, ulps(a[0], shipped.step_driven(w, q, t, dt, DRIVEN_BODY)[0]) * EPS)
    assert worst <= 10, worst
    assert apart > 1e-8, apart


def test_no_squish_substeps_cut_the_rotor_error_by_their_square():
    """On a free asymmetric body the kicks vanish, so ``no_squish(substeps=10)`` is ten rotors of dt/10:
    its orientation error against the exact Euler–Poinsot flow after 0.5 s is ~100× smaller than one
    rotor's (second order), and the run is the plain method's at dt/10 to rounding."""
    body = Body(0.025, 0.02, 0.008, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    w0, q0, dt, n = (3.0, -20.0, 40.0), (1.0, 0.0, 0.0, 0.0), 5e-3, 100
    _, q_exact = free_body(np.array(body[:3]), np.array(w0), np.array(q0), np.array([n * dt]))
    errors = {}
    for name in ("no_squish", "no_squish(substeps=10)"):
        _, Q = step_run(name, w0, q0, dt, body, n)
        errors[name] = 2 * np.arccos(min(1.0, abs(float(np.dot(Q[-1], q_exact[0])))))
    ratio = errors["no_squish"] / errors["no_squish(substeps=10)"]
    assert 80 < ratio < 120, (errors, ratio)
    _, Q_fine = step_run("no_squish", w0, q0, dt / 10, body, 10 * n)
    _, Q_sub = step_run("no_squish(substeps=10)", w0, q0, dt, body, n)
    assert np.max(np.abs(Q_fine[-1] - Q_sub[-1])) < 1e-11


def test_lie_genalpha_rho_inf_sets_the_numerical_damping():
    """ρ∞ = 1 is generalized-α without numerical damping: the free symmetric top's energy, which the
    damped variants bleed from the high frequencies, is kept best (the variant steps as
    ``step_carried_with`` at that ρ∞, bit for bit)."""
    module = METHODS["lie_genalpha"]
    body = Body(0.02, 0.02, 0.008, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    w0, q0 = (3.0, -2.0, 60.0), (1.0, 0.0, 0.0, 0.0)
    w_rho, q_rho = step_run("lie_genalpha(rho_inf=0.5)", w0, q0, 1e-3, body, 30)
    w, q, c = w0, q0, module.start(w0, q0, body)
    for _ in range(30):
        w, q, c, _ = module.step_carried_with(w, q, c, 1e-3, body, 0.5, module.ATOL, module.RTOL, module.MAX_ITERATIONS)
    assert tuple(w_rho[-1]) == w and tuple(q_rho[-1]) == q
    print()
    drift = {}
    for rho in ("0.0", "0.5", "1.0"):
        name = f"lie_genalpha(rho_inf={rho})"
        W, _ = step_run(name, w0, q0, 1e-2, body, 500)
        energy = 0.5 * np.sum(np.array(body[:3]) * W**2, axis=1)
        drift[rho] = np.max(np.abs(energy / energy[0] - 1))
        print(f"  {name}: max |ΔE|/E over 500 steps of 10 ms = {drift[rho]:.3g}")
    assert drift["1.0"] < drift["0.5"] < drift["0.0"], drift


@pytest.mark.slow
def test_a_sweep_records_each_variant_it_ran(tmp_path):
    """A sweep of a method and two variants (one named twice, in two spellings) runs each through its own
    cached entry points and stores it under its canonical name; each run's last sample is that variant
    stepped by hand from the scene's initial state."""
    from gyrolab.kernels.scenes import build_scene

    given = ['"no_squish(substeps=4)"', '"lie_poisson(axes=S-M-L)"', "no_squish", '"lie_poisson(axes=s-m-l)"']
    ds = free_body_sweep(given, tmp_path)  # 0.2 s at dt 1e-3
    names = ["no_squish(substeps=4)", "lie_poisson(axes=S-M-L)", "no_squish"]
    assert list(ds.integrator.values) == names
    sc = build_scene("free_asymmetric", float(ds.f[0]), float(ds.theta0[0]))
    last = {}
    for name in names:
        W, _ = step_run(name, tuple(sc.omega0), tuple(sc.q0), 1e-3, sc.body, 200)
        last[name] = ds.omega.sel(integrator=name).squeeze().isel(time=-1).values
        assert np.array_equal(last[name], W[-1]), name
    assert not np.array_equal(last["no_squish"], last["no_squish(substeps=4)"])  # the parameter reached the kernel


def test_variants_cache_under_their_own_names():
    """Each variant's entry points have their own qualified name (its cache file), different from the
    plain method's and from every other variant's."""
    names = {
        get_method(n).run_batch.py_func.__qualname__
        for n in ("no_squish", "no_squish(substeps=4)", "no_squish(substeps=5)", "no_squish(axes=S-M-L)")
    }
    assert len(names) == 4 and "run_batch" in names


@pytest.mark.slow
def test_the_splitting_order_experiment_on_water(tmp_path):
    """``experiment=splitting_order``: SPC/E water labelled with the moments increasing (as LAMMPS labels
    it), so the shipped NO_SQUISH is lie_poisson in the order L-M-S (to rounding over 5000 steps);
    S-M-L has the smallest energy error of the six orders and L-M-S loses more than 10× against it
    (measured 57×; 35× in docs/splitting_order.md's median over eight motions); DL_POLY's 10 rotor
    substeps cut NO_SQUISH's error ~100× (measured 5.6e-05, 5.6e-07, and 9.8e-07 → 9.9e-09 in S-M-L)."""
    import xarray as xr

    from gyrolab.analysis.reports.splitting_order import water_moments

    from helpers import experiment_scene, gyrolab

    sc = experiment_scene("splitting_order")
    assert np.allclose(sc.body[:3], sorted(water_moments()), rtol=1e-15, atol=0)
    res = gyrolab("experiment=splitting_order", "output.figures=false", f"hydra.run.dir={tmp_path}", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    with xr.open_dataset(tmp_path / "splitting_order.h5", engine="h5netcdf") as ds:
        energy = ds.energy.squeeze().load()
        omega = ds.omega.squeeze().load()
    drift = {
        str(m): float(np.max(np.abs(energy.sel(integrator=m) / energy.sel(integrator=m)[0] - 1)))
        for m in energy.integrator.values
    }
    orders = {m: e for m, e in drift.items() if m.startswith("lie_poisson")}
    assert len(orders) == 6 and min(orders, key=orders.get) == "lie_poisson(axes=S-M-L)", orders
    assert orders["lie_poisson(axes=L-M-S)"] > 10 * orders["lie_poisson(axes=S-M-L)"]
    shipped = omega.sel(integrator="no_squish") - omega.sel(integrator="lie_poisson(axes=L-M-S)")
    assert float(np.max(np.abs(shipped))) < 1e-10
    assert 50 < drift["no_squish"] / drift["no_squish(substeps=10)"] < 200
    assert 50 < drift["no_squish(axes=S-M-L)"] / drift["no_squish(axes=S-M-L,substeps=10)"] < 200


@pytest.mark.parametrize("name", ["lie_poisson(axes=S-M-L)", "no_squish(axes=2-3-1,substeps=3)"])
def test_a_variant_on_the_block_path_is_its_runs_bit_for_bit(name):
    """The block path recompiles a variant's step (closures and all, kernels/lanes.py) for the lanes: on an
    asymmetric heavy body its samples are the one-run-at-a-time path's, bit for bit, and the variant's
    own (not the plain method's)."""
    from gyrolab.kernels.batch import integrate
    from gyrolab.kernels.scenes import build_scene

    from helpers import block_path_args

    args = block_path_args(build_scene("heavy_body", 10.0, 45.0, I1=1.3, I2=1.0, I3=0.6))
    runs, blocks = integrate(name, *args, path="runs"), integrate(name, *args, path="blocks")
    for a, b in zip(runs, blocks):
        np.testing.assert_array_equal(a, b)
    plain = integrate(name.split("(")[0], *args, path="runs")
    assert not np.array_equal(plain[0], runs[0])
