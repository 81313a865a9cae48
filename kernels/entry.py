"""The batch entry points of a method, made from one template for every method.

A method module defines ``step`` (and its declarations, see
methods/README.md); ``add_entry_points(module)`` gives it

- ``run_batch(w0, q0, bodies, dts, strides, threshold, out, status, n_steps)``:
  one ``prange`` over runs, each run by driver.make_advance's ``advance_run``;
- ``run_blocks(..., runs, starts, queues, state)``: one ``prange`` over threads, each
  running its queue of vectorised blocks (block.py), and each run's final (ω, q) in
  ``state`` (n, 7) to continue it from (the runner's time segments); not made for a method that
  declares ``BLOCKS = False`` (its steps do not vectorise: ``uses_blocks`` below);
- for a method that sees time (``step_driven``), ``run_batch_driven`` with
  ``run_batch``'s arguments: driven bodies, one run after another
  (driver.make_advance_driven).  Compiled only when a driven scene runs.

Both must be cached (the block kernel takes seconds to compile), and numba
caches a function by its source file and qualified name, keyed by its
bytecode.  A closure made by a factory here would be cached under this
file for every method alike, and its key (the pickled cell contents,
dispatchers with per-process ids) would never match again.  So the template
below is compiled once per method *as if it were written in the method's
own file* (``compile(..., module.__file__)``) and run in the method's
namespace: numba then caches ``<method>.run_batch`` next to that method's
other functions, with the method's ``step`` bound as a global, exactly as a
hand-written copy would be.  Staleness is handled by the cache directory,
which is keyed by the hash of every kernel source file (kernels/__init__.py).
"""

from .block import make_advance_queue
from .driver import make_advance, make_advance_driven

# The line numbers of these defs become part of the cache file names: keep them fixed.
_TEMPLATE = """
@_njit(cache=True, parallel=True, error_model="numpy")
def run_batch(w0, q0, bodies, dts, strides, threshold, out, status, n_steps):
    for i in _prange(w0.shape[0]):
        _advance_run(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps)
"""
_BLOCKS_TEMPLATE = """
@_njit(cache=True, parallel=True, error_model="numpy")
def run_blocks(w0, q0, bodies, dts, strides, threshold, out, status, n_steps, runs, starts, queues, state):
    for t in _prange(queues.size - 1):
        _advance_queue(t, runs, starts, queues, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, state)
"""
_DRIVEN_TEMPLATE = """
@_njit(cache=True, parallel=True, error_model="numpy")
def run_batch_driven(w0, q0, bodies, dts, strides, threshold, out, status, n_steps):
    for i in _prange(w0.shape[0]):
        _advance_driven(i, w0, q0, bodies, dts, strides, threshold, out, status, n_steps)
"""


def uses_blocks(module):
    """Whether the method runs on the vectorised block path (``BLOCKS``, default True): whether it has
    ``run_blocks``.  Callers go through kernels.registry, which re-exports it."""
    return getattr(module, "BLOCKS", True)


def add_entry_points(module):
    """Define ``run_batch``, ``run_blocks`` (unless the module says ``BLOCKS = False``) and
    ``run_batch_driven`` (if it has ``step_driven``) in ``module`` (a method module with ``step``)."""
    from numba import njit, prange

    namespace = vars(module)
    namespace["_njit"], namespace["_prange"] = njit, prange
    namespace["_advance_run"] = make_advance(module.step)
    exec(compile(_TEMPLATE, module.__file__, "exec"), namespace)
    if uses_blocks(module):
        namespace["_advance_queue"] = make_advance_queue(module.step)
        exec(compile(_BLOCKS_TEMPLATE, module.__file__, "exec"), namespace)
    if hasattr(module, "step_driven"):
        namespace["_advance_driven"] = make_advance_driven(module.step_driven)
        exec(compile(_DRIVEN_TEMPLATE, module.__file__, "exec"), namespace)
    return module
