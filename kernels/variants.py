"""A method with parameter values bound: a module of its own, with its own cached entry points.

``build(module, name, values)`` calls the method's ``variant(**values)`` (kernels/methods/README.md,
"Parameters") for the step functions with the values bound as compile-time constants (numba freezes a
closure's free variables), and makes a module that is the method's in everything else (ORDER, PRESERVES,
REPRODUCES, its helpers) with those steps and entry points compiled around them (entry.py).

The entry points are cached like the plain method's, in the method's file, under qualified names that
carry a tag: ``run_batch__v<hash>``.  numba names a cache file by the function's qualified name and
keys it by its bytecode and closure contents only, so two variants' copies of ``run_batch`` (same
bytecode, no closure, the steps reached through globals) would otherwise load each other's machine
code.  The tag hashes the canonical name and the kernel values, so a change in how a value parses
(kernels/parameters.py, which keys no cache) also selects a fresh file.

The helpers below make the steps every variant needs from the one it defines, as each method file
writes its own ``step``: the undriven step from the time-aware one, a carried method's first step, and
the uncounted steps of a method whose solver counts its iterations.
"""

import hashlib
import types

from numba import njit

from .body import without_drive
from .entry import ENTRY_POINTS, add_entry_points


def undriven(step_driven):
    """``{"step_driven", "step"}``: ``step_driven(w, q, t, dt, body)`` and the step of an undriven body,
    ``step_driven`` from t = 0 with the drive folded away (as every method file writes ``step``)."""

    @njit(error_model="numpy")
    def step(w, q, dt, body):
        return step_driven(w, q, 0.0, dt, without_drive(body))

    return {"step_driven": step_driven, "step": step}


def carried(start, step_carried):
    """``{"start", "step_carried", "step"}`` of a method that carries state: ``step`` is a run's first
    step, from ``start``'s state."""

    @njit(error_model="numpy")
    def step(w, q, dt, body):
        w1, q1, _ = step_carried(w, q, start(w, q, body), dt, body)
        return w1, q1

    return {"start": start, "step_carried": step_carried, "step": step}


def carried_counted(start, step_carried_counted):
    """``carried`` for a method whose steps count their solver's iterations (methods/README.md,
    "Solvers"): ``{"start", "step_carried_counted", "step_carried", "step_counted", "step"}`` from
    ``step_carried_counted(w, q, c, dt, body) -> (w, q, c, n)``."""

    @njit(error_model="numpy")
    def step_carried(w, q, c, dt, body):
        w1, q1, c1, _ = step_carried_counted(w, q, c, dt, body)
        return w1, q1, c1

    @njit(error_model="numpy")
    def step_counted(w, q, dt, body):
        w1, q1, _, n = step_carried_counted(w, q, start(w, q, body), dt, body)
        return w1, q1, n

    steps = carried(start, step_carried)
    steps.update(step_carried_counted=step_carried_counted, step_counted=step_counted)
    return steps


STEP_FUNCTIONS = ("step_driven", "start", "step_carried", "step_counted", "step_driven_counted", "step_carried_counted")
CARRIED_STEPS = {"step", "start", "step_carried"}  # what ``carried`` returns


def steps_of(module):
    """The step functions a variant of ``module`` must define: ``step``, and those of ``STEP_FUNCTIONS``
    (``step_driven``, ``start``, ``step_carried`` and their counted forms) the method has."""
    return {"step"} | {fn for fn in STEP_FUNCTIONS if hasattr(module, fn)}


def build(module, name, values):
    """The method ``module`` as ``name`` (its canonical name, kernels/parameters.py) with ``values``
    ({parameter: kernel value}) bound: a module with the variant's steps and its own entry points."""
    steps = module.variant(**values)
    needed = steps_of(module)
    # A variant may carry state where the method does not (lie_poisson4(accumulate=compensated) carries
    # the low parts of ω and q): it then defines a carried method's steps, and it is one in everything
    # else too: no step_driven (the driven loop carries (ω, q) only), one run after another (BLOCKS).
    carries = "step_carried" in steps and "step_carried" not in needed
    if set(steps) != (CARRIED_STEPS if carries else needed):
        raise TypeError(
            f"{module.__name__}.variant returned {sorted(steps)}; a variant of it defines {sorted(needed)}"
            + (f" or, carrying state, {sorted(CARRIED_STEPS)}" if "step_carried" not in needed else "")
        )
    variant = types.ModuleType(module.__name__, module.__doc__)
    variant.__dict__.update(
        {k: v for k, v in vars(module).items() if k not in ENTRY_POINTS and k not in STEP_FUNCTIONS and k != "__spec__"}
    )
    variant.__dict__.update(steps)
    if carries:
        variant.BLOCKS = False
    variant.METHOD, variant.NAME, variant.VALUES = module, name, dict(values)
    tag = hashlib.sha256(f"{name}\0{sorted(values.items())!r}".encode()).hexdigest()[:12]
    return add_entry_points(variant, tag=f"__v{tag}")
