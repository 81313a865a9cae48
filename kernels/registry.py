"""The registered integration methods: one line each.

A method is one module in kernels/methods/ written to the contract in
kernels/methods/README.md (``step`` and its declarations); ``register``
checks that contract and gives the module its batch entry points
(entry.py), so nothing else needs to change for a new method.
"""

import importlib
from collections.abc import MutableMapping

from numba.core.dispatcher import Dispatcher

from . import real, variants
from .entry import (  # noqa: F401 - the registry's view of a method
    COUNTED_STEPS,
    add_entry_points,
    carries_state,
    counts_iterations,
    stepper,
    uses_blocks,
)
from .invariants import check_names
from .parameters import Parameter, canonical, split_name


def register(name, module):
    """Check ``module`` against the method contract and add its entry points; TypeError if it breaks it."""
    doc = (module.__doc__ or "").strip()
    problems = []
    if not doc.startswith(f"{name}:"):
        problems.append(f'its docstring must start with "{name}: <one-line summary>"')
    if not (isinstance(getattr(module, "ORDER", None), int) and module.ORDER >= 1):
        problems.append("ORDER must be an int >= 1")
    if not isinstance(getattr(module, "SYMPLECTIC", None), bool):
        problems.append("SYMPLECTIC must be a bool")
    preserves = getattr(module, "PRESERVES", None)
    if not isinstance(preserves, tuple):
        problems.append("PRESERVES must be a tuple of invariant names (kernels/invariants.py)")
    else:
        try:
            check_names(preserves, f"{name}.PRESERVES")
        except ValueError as err:
            problems.append(str(err))
    if not isinstance(getattr(module, "step", None), Dispatcher):
        problems.append("step(w, q, dt, body) -> (w, q) must be a numba @njit function")
    if not isinstance(getattr(module, "FREE_EXACT", False), bool):
        problems.append("FREE_EXACT, when given, must be a bool")
    if not isinstance(getattr(module, "REPRODUCES", ""), str):
        problems.append("REPRODUCES, when given, must name the engine scheme reproduced (a str)")
    if hasattr(module, "step_driven") and not isinstance(module.step_driven, Dispatcher):
        problems.append("step_driven(w, q, t, dt, body) -> (w, q), when given, must be a numba @njit function")
    if not isinstance(getattr(module, "BLOCKS", True), bool):
        problems.append("BLOCKS, when given, must be a bool")
    if carries_state(module):
        for fn in ("start", "step_carried"):
            if not isinstance(getattr(module, fn, None), Dispatcher):
                problems.append(f"a method that carries state must define {fn} as a numba @njit function")
        if getattr(module, "BLOCKS", True):
            problems.append(
                "a method that carries state must declare BLOCKS = False (the block path carries (ω, q) only)"
            )
        if hasattr(module, "step_driven"):
            problems.append(
                "a method that carries state cannot define step_driven yet (the driven loop carries (ω, q) only)"
            )
    if counts_iterations(module):
        for plain, counted in COUNTED_STEPS.items():
            if hasattr(module, plain) and not isinstance(getattr(module, counted, None), Dispatcher):
                problems.append(f"a method with a counted solver (step_counted) must define {counted} as well")
        if getattr(module, "BLOCKS", True):
            problems.append(
                "a method with a counted solver must declare BLOCKS = False (the block path counts no iterations)"
            )
    parameters = getattr(module, "PARAMETERS", None)
    if parameters is not None:
        declared = parameters.values() if isinstance(parameters, dict) else ()
        if not (declared and all(isinstance(p, Parameter) for p in declared)):
            problems.append("PARAMETERS, when given, must map parameter names to kernels.parameters.Parameter")
        elif not callable(getattr(module, "variant", None)):
            problems.append("a method with PARAMETERS must define variant(**values) -> its steps (kernels/variants.py)")
        else:
            try:  # the defaults must parse, and the variant must define the steps the method has (cheap: no compiling)
                values = canonical(name, parameters, {})[1]
                got, needed = sorted(module.variant(**values)), sorted(variants.steps_of(module))
                if got != needed:
                    problems.append(f"variant() returned {got}; it must define {needed}")
            except (TypeError, ValueError) as err:
                problems.append(f"its PARAMETERS defaults and variant() do not fit: {err}")
    if problems:
        raise TypeError(f"method {name!r} ({module.__name__}): " + "; ".join(problems))
    return add_entry_points(module)


# One line per method: the module kernels/methods/<name>.py.
NAMES = (
    "seed_next",
    "seed_prev",
    "rk4",
    "lie_poisson",
    "lie_poisson4",
    "lie_poisson_sorted",
    "explicit_euler",
    "lie_trotter",
    # splittings around the exact Euler-Poinsot free flow (kernels/euler_poinsot.py)
    "strang_exact",
    "strang_exact4",
    "split6_exact",
    "suzuki4_exact",
    # the rotation updates physics engines ship (each file names the engine source it follows)
    "mujoco_euler",
    "mujoco_implicitfast",
    "mujoco_implicit",
    "mujoco_rk4",
    "bullet_explicit",
    "bullet_implicit_body",
    "jolt_rescale",
    "jolt_rescale_bare",
    "rapier_rescale",
    "no_gyro",
    # the engines' presets with their hidden defaults (issue 23): PhysX's, Newton's, MuJoCo 3.7-3.10's midpoint
    "physx_default",
    "newton_semi",
    "midpoint_free",
    # issue 23 item 3: PhysX with its gyroscopic flag set, Brax's spring pipeline, Bepu's ConserveMomentum
    "physx_gyro",
    "brax_spring",
    "bepu_conserve_momentum",
    # the rotation updates of molecular dynamics, spacecraft and geometric-integration codes (issue 24)
    "no_squish",
    "rk4_mrp",
    "rkmk4",
    "cg4",
    "lgvi",
    "implicit_midpoint",
    # Simo & Wong's energy-momentum update (issue 24; the Solfec heavy top, conf/experiment/solfec_heavy_top.yaml)
    "simo_wong",
    "lammps_richardson",
    "dlpoly_fiqa",
    # Project Chrono's default timestepper for a rigid body (issue 24)
    "chrono_euler",
    # Kynema's Lie-group generalized-α (issue 24): carries its accelerations from step to step
    "lie_genalpha",
    # Solfec's rigid rotation updates RIG_IMP (NEW3) and its default RIG_NEG (NEW2) (issue 24, the Solfec heavy top)
    "solfec_imp",
    "solfec_neg",
)


class Registry(MutableMapping):
    """``METHODS``: name -> method module, in ``NAMES``' order; each module imported and ``register``-ed on
    first use, so that a process pays for the methods it runs: importing all 41 and building their entry
    points took ~0.25 s of every ``gyrolab`` process's start, most of which run one to five.  Iterating
    names costs nothing; ``items()`` and ``values()`` import every method.  A module set here
    (``METHODS[name] = register(name, module)``, a user's method outside the package) is taken as it is."""

    def __init__(self, names):
        self._names = list(names)
        self._modules = {}

    def __getitem__(self, name):
        module = self._modules.get(name)
        if module is None:
            if name not in self._names:
                raise KeyError(name)
            module = register(name, importlib.import_module(f".methods.{name}", __package__))
            self._modules[name] = module
        return module

    def __setitem__(self, name, module):
        if name not in self._names:
            self._names.append(name)
        self._modules[name] = module

    def __delitem__(self, name):
        self._names.remove(name)
        self._modules.pop(name, None)

    def __contains__(self, name):
        return name in self._names

    def __iter__(self):
        return iter(list(self._names))

    def __len__(self):
        return len(self._names)

    def __repr__(self):
        return f"Registry({self._names!r})"


METHODS = Registry(NAMES)


_VARIANTS = {}  # canonical name -> the variant module built for it in this process


def canonical_name(name):
    """``(canonical name, values)`` of a registered method's ``name``, plain or with parameters
    (``no_squish(substeps=10)``, kernels/parameters.py): ``values`` is {parameter: kernel value} ({} for a
    method without parameters); ValueError (one line) for an unknown method, parameter or value."""
    base, given = split_name(name)
    if base not in METHODS:
        raise ValueError(f"unknown method {base!r}; choose from {', '.join(METHODS)}")
    declared = getattr(METHODS[base], "PARAMETERS", {})
    if given and not declared:
        with_parameters = ", ".join(m for m, mod in METHODS.items() if hasattr(mod, "PARAMETERS"))
        raise ValueError(f"{name!r}: {base} takes no parameters (methods that do: {with_parameters})")
    return canonical(base, declared, given)


def get_method(name):
    """The method module registered as ``name``, the variant module of a name with parameters
    (kernels/variants.py), or for a real engine (``real_*``, kernels/real/) its backend (no numba
    step, ``BLOCKS`` False); ValueError naming the choices, or the missing extra."""
    if real.is_real(name):
        return real.get_backend(name)
    if name in METHODS:
        return METHODS[name]
    if name not in _VARIANTS:
        key, values = canonical_name(name)
        if key not in _VARIANTS:
            base = split_name(key)[0]
            _VARIANTS[key] = METHODS[base] if key == base else variants.build(METHODS[base], key, values)
        _VARIANTS[name] = _VARIANTS[key]
    return _VARIANTS[name]


def registered(name):
    """The module of a registered method or variant ``name``, or None (a real engine, a name not known here)."""
    try:
        return None if real.is_real(str(name)) else get_method(str(name))
    except ValueError:
        return None


# How batch.integrate and the grid check name a method that cannot integrate a driven body.
DRIVEN_REFUSAL = "does not see time (no step_driven), so it cannot integrate a torque that depends on time"


def sees_time(module):
    """Whether the method integrates driven bodies (a torque that depends on time): it defines
    ``step_driven``.  Every method integrates the free body and gravity with the centre of mass on
    e3 or anywhere (``gravity_torque``); only these also the drive."""
    return hasattr(module, "step_driven")


def force_models(module):
    """The force models the method integrates (kernels/body.py): the free body, the weight with the
    centre of mass on e3 or anywhere, and, for a method that sees time, the drive."""
    return ("free", "axial", "general") + (("driven",) if sees_time(module) else ())


def driven_methods():
    """Names of the registered methods that see time."""
    return [name for name, mod in METHODS.items() if sees_time(mod)]


# Names a sweep may give in sweep.method instead of (or beside) methods; each stands for the registered
# methods it selects, in registry order, so that a study covering "every method" lists none by hand.
SELECTORS = {
    "all": "every registered method that can integrate the scene (on a driven scene, those that see time)",
    "all_own": "gyrolab's own schemes (every method that does not reproduce an engine)",
    "all_engines": "the reproductions of engines' rotation updates (REPRODUCES)",
    "driven": "the methods that see time (step_driven)",
    "real": "the real engines whose package imports here (kernels/real/: real_mujoco_*, real_pybullet*)",
}


def select_methods(names, driven_scene=False):
    """``names`` (sweep.method: method names, names with parameters and SELECTORS) as method names, each
    once, in the order given (a selector's methods in registry order, a name with parameters in its
    canonical form); ValueError (one line) naming an unknown name or a bad parameter.
    ``driven_scene``: the scene drives its body, so ``all`` means the methods that see time."""
    out = []
    for name in names:
        if name == "all":
            chosen = driven_methods() if driven_scene else list(METHODS)
        elif name == "all_own":
            chosen = [m for m, mod in METHODS.items() if not getattr(mod, "REPRODUCES", "")]
        elif name == "all_engines":
            chosen = [m for m, mod in METHODS.items() if getattr(mod, "REPRODUCES", "")]
        elif name == "driven":
            chosen = driven_methods()
        elif name == "real":
            chosen = real.available()
        elif name in METHODS:
            chosen = [name]
        elif real.is_real(name):
            real.check_available(name)  # one line naming the extra when the engine's package is missing
            chosen = [name]
        elif split_name(name)[0] in METHODS:  # a method with parameters: its canonical name
            chosen = [canonical_name(name)[0]]
        else:
            raise ValueError(
                f"unknown method {name!r}; choose from {', '.join(METHODS)}, a real engine "
                f"({', '.join(real.NAMES)}), a selector ({', '.join(SELECTORS)}) or a method with "
                "parameters, e.g. no_squish(substeps=10)"
            )
        out.extend(m for m in chosen if m not in out)
    return out


def methods():
    """{name: {"order", "symplectic", "preserves", "force_models", "parameters", "doc"}} for every
    registered method; "parameters" is {parameter: (default, meaning)}."""
    return {
        name: {
            "order": mod.ORDER,
            "symplectic": mod.SYMPLECTIC,
            "preserves": mod.PRESERVES,
            "force_models": force_models(mod),
            "parameters": {k: (p.default, p.doc) for k, p in getattr(mod, "PARAMETERS", {}).items()},
            "doc": (mod.__doc__ or "").strip().splitlines()[0],
        }
        for name, mod in METHODS.items()
    }
