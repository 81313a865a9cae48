"""The batch entry points of a method: three functions written once, here, compiled for each method.

A method module defines ``step`` (and its declarations, see methods/README.md);
``add_entry_points(module)`` gives it its own compiled copy of

- ``run_batch(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations)``:
  one ``prange`` over runs, each run by driver.make_advance's ``advance_run`` (for a method that
  carries state beyond (ω, q), ``step_carried``: driver.make_advance_carried's), around the method's
  counted step (``counted`` below: its solver's iterations, or none);
- ``run_blocks(..., runs, starts, queues, state)``: one ``prange`` over threads, each
  running its queue of vectorised blocks (block.py), and each run's final (ω, q) in
  ``state`` (n, 7) to continue it from (the runner's time segments); not made for a method that
  declares ``BLOCKS = False`` (its steps do not vectorise: ``uses_blocks`` below);
- for a method that sees time (``step_driven``), ``run_batch_driven`` with
  ``run_batch``'s arguments: driven bodies, one run after another
  (driver.make_advance_driven).  Compiled only when a driven scene runs.

So the path from the runner into a method's step reads statically: kernels/batch.py calls
``module.run_batch`` (``run_blocks``, ``run_batch_driven``), which is the function of that name
below; its ``_advance_run`` (``_advance_block``, ``_advance_driven``) is the loop that
driver.make_advance (block.make_advance_block, driver.make_advance_driven) builds around the
method's ``step``.

The copies must be cached (the block kernel takes seconds to compile), and numba
caches a function by its source file and qualified name, keyed by its
bytecode.  A closure made by a factory here would be cached under this
file for every method alike, and its key (the pickled cell contents,
dispatchers with per-process ids) would never match again.  So each copy is
the function below with its code object re-homed in the method's file
(``co_filename``) and its three loop names bound in globals of its own whose
``__name__`` is the method's module: numba then caches ``<method>.run_batch`` next
to that method's other functions, with the method's ``step`` inlined, exactly as a
hand-written copy in the method file would be, under every cache locator.  Staleness is
handled by the cache directory, which is keyed by the hash of every kernel source file
(kernels/__init__.py).  (A compile error of a copy names the method's file with the line
numbers of this one.)
"""

import types

import numpy as np
from numba import njit, prange

from .block import make_advance_block
from .driver import make_advance, make_advance_carried, make_advance_driven


def _bound_per_method(factory):
    """What the functions below call here: each method's copy binds the name to ``factory``'s loop
    around its own step instead; called on the template itself, one clear error."""

    def unbound(*args):
        raise TypeError(f"kernels/entry.py holds templates: call a method's own copy (loop: {factory})")

    return unbound


_advance_run = _bound_per_method("driver.make_advance(step)")
_advance_block = _bound_per_method("block.make_advance_block(step)")
_advance_driven = _bound_per_method("driver.make_advance_driven(step_driven)")

# The line numbers of these defs become part of the cache file names (numba's index is named
# <method>.<function>-<line>); an edit here changes the core key, so no stale copy can load.
# A loop is called with np.int64 of the prange index: numba types the loop signed before it
# becomes a parfor, whose gufunc's index is unsigned, and compiled the whole loop once for each
# (about a second of every kernel's cold compile).  The block queue is looped here, not in a
# function of its own: each numba function optimises and emits again the code of all it calls.


def run_batch(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations):
    """Integrate every run one by one, in parallel over runs (driver.make_advance)."""
    for i in prange(w0.shape[0]):
        _advance_run(np.int64(i), w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations)


def run_blocks(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, runs, starts, queues, state):
    """Integrate the runs in vectorised blocks, one queue of blocks per thread (block.py plan_blocks)."""
    for t in prange(queues.size - 1):
        for b in range(queues[t], queues[t + 1]):
            _advance_block(
                runs[starts[b] : starts[b + 1]], w0, q0, bodies, dts, strides, threshold, out, status, n_steps, state
            )


def run_batch_driven(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations):
    """Integrate driven bodies (a torque that depends on time), in parallel over runs."""
    for i in prange(w0.shape[0]):
        _advance_driven(np.int64(i), w0, q0, bodies, dts, strides, threshold, out, status, n_steps, iterations)


def uses_blocks(module):
    """Whether the method runs on the vectorised block path (``BLOCKS``, default True): whether it has
    ``run_blocks``.  Callers go through kernels.registry, which re-exports it."""
    return getattr(module, "BLOCKS", True)


# A method with an iterative solver defines the counted form of each step it has (methods/README.md,
# "Solvers"); the registry checks that it defines all of them.
COUNTED_STEPS = {"step": "step_counted", "step_driven": "step_driven_counted", "step_carried": "step_carried_counted"}


def counts_iterations(module):
    """Whether the method has an iterative solver whose iterations its runs count (``step_counted``,
    methods/README.md, "Solvers"); such a method runs one run after another (BLOCKS False)."""
    return hasattr(module, "step_counted")


def carries_state(module):
    """Whether the method carries state beyond (ω, q) from step to step (``step_carried`` and
    ``start``, methods/README.md); its ``run_batch`` then threads that state through each run."""
    return hasattr(module, "step_carried")


_STEPPERS = {}


def stepper(module):
    """``(start, step_carried)`` of a method, njit functions for loops that step a run outside the
    drivers (tests, reports, benchmarks): ``c = start(w, q, body)`` once, then
    ``w, q, c = step_carried(w, q, c, dt, body)`` per step.  For a method that carries state beyond
    (ω, q) these are its own; for every other one ``c`` is a placeholder and ``step_carried`` is its
    ``step`` (the same bits).  A loop written this way steps every method as its run does: calling
    ``step`` again and again would restart a carried method's history every step."""
    if carries_state(module):
        return module.start, module.step_carried
    if module not in _STEPPERS:
        step = module.step

        @njit(error_model="numpy", forceinline=True)
        def start(w, q, body):
            return 0.0

        @njit(error_model="numpy", forceinline=True)
        def step_carried(w, q, c, dt, body):
            w, q = step(w, q, dt, body)
            return w, q, c

        _STEPPERS[module] = start, step_carried
    return _STEPPERS[module]


ENTRY_POINTS = ("run_batch", "run_blocks", "run_batch_driven")


def _compiled_copy(function, module, tag, **loops):
    """``function`` re-homed in ``module`` (its file and module name) with ``loops`` as its globals,
    compiled, cached and parallel like every entry point; ``tag`` appended to its qualified name (a
    variant's, kernels/variants.py) names its own cache file."""
    namespace = {"__name__": module.__name__, "__file__": module.__file__, "np": np, "prange": prange, **loops}
    code = function.__code__.replace(co_filename=module.__file__)
    copy = types.FunctionType(code, namespace, function.__name__)
    copy.__qualname__, copy.__doc__ = function.__qualname__ + tag, function.__doc__
    return njit(cache=True, parallel=True, error_model="numpy")(copy)


def counted(module):
    """The method's step with its solver's iterations, ``(w, q, n)``, for the drivers: its own
    ``step_counted`` (n < 0: not converged after −n) or, for a method without a solver, its
    ``step`` with n = 0 (the loop around it does not count: ``counts_iterations``)."""
    if counts_iterations(module):
        return module.step_counted
    step = module.step

    @njit(error_model="numpy", forceinline=True)
    def step_counted(w, q, dt, body):
        w, q = step(w, q, dt, body)
        return w, q, 0

    return step_counted


def counted_driven(module):
    """``counted`` for ``step_driven``: ``step_driven_counted(w, q, t, dt, body) -> (w, q, n)``."""
    if hasattr(module, "step_driven_counted"):
        return module.step_driven_counted
    step_driven = module.step_driven

    @njit(error_model="numpy", forceinline=True)
    def step_driven_counted(w, q, t, dt, body):
        w, q = step_driven(w, q, t, dt, body)
        return w, q, 0

    return step_driven_counted


def counted_carried(module):
    """``counted`` for ``step_carried``: ``step_carried_counted(w, q, c, dt, body) -> (w, q, c, n)``."""
    if hasattr(module, "step_carried_counted"):
        return module.step_carried_counted
    step_carried = module.step_carried

    @njit(error_model="numpy", forceinline=True)
    def step_carried_counted(w, q, c, dt, body):
        w, q, c = step_carried(w, q, c, dt, body)
        return w, q, c, 0

    return step_carried_counted


def add_entry_points(module, tag=""):
    """Define ``run_batch``, ``run_blocks`` (unless the module says ``BLOCKS = False``) and
    ``run_batch_driven`` (if it has ``step_driven``) in ``module`` (a method module with ``step``);
    ``tag``: see ``_compiled_copy``."""
    if carries_state(module):
        advance = make_advance_carried(module.start, counted_carried(module), counts_iterations(module))
    else:
        advance = make_advance(counted(module), counts_iterations(module))
    module.run_batch = _compiled_copy(run_batch, module, tag, _advance_run=advance)
    if uses_blocks(module):
        module.run_blocks = _compiled_copy(run_blocks, module, tag, _advance_block=make_advance_block(module.step))
    if hasattr(module, "step_driven"):
        module.run_batch_driven = _compiled_copy(
            run_batch_driven,
            module,
            tag,
            _advance_driven=make_advance_driven(counted_driven(module), counts_iterations(module)),
        )
    return module
