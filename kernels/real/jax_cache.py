"""JAX's persistent compilation cache for the JAX engines (MJX, jax-md).

XLA compiles an engine's jitted step loop once per model structure and integrator (MJX's ``mjx.step``
loop ~1-2 s, on the 2-core machine), and a process without a persistent cache compiles it again: every
sweep, every worker, every conformance table (``python -m gyrolab.kernels.real.conformance --steps 200``
31 s on an empty cache, 19 s on a full one).  ``use_compilation_cache(jax)`` points JAX at a cache in
gyrolab's cache directory beside numba's (``$XDG_CACHE_HOME/gyrolab/jax``, default
``~/.cache/gyrolab/jax``) unless the user chose one (``JAX_COMPILATION_CACHE_DIR`` or
``jax.config``).  Every compile is kept (JAX keeps only those over 1 s by default: the small ones add
up), and the cache is bounded in size, which makes JAX take a file lock (the ``filelock`` package, in
the ``engines`` extra) around each read and write, so that concurrent processes never read an entry
half-written.  An entry is keyed by the program, JAX's version and the backend: it gives the same
executable, so the same bits.
"""

import os

MAX_BYTES = 1 << 30  # JAX evicts the least recently used entries beyond this


def cache_dir():
    """gyrolab's directory for JAX's compilation cache (``$XDG_CACHE_HOME/gyrolab/jax``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "gyrolab", "jax")


def use_compilation_cache(jax):
    """Turn on JAX's persistent compilation cache in ``cache_dir()`` for this process, before its first
    compile; a cache directory the user set is kept as it is."""
    if jax.config.jax_compilation_cache_dir:
        return
    path = cache_dir()
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return  # no place to keep it: JAX compiles in every process, as it does by default
    if not os.access(path, os.W_OK):
        return
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
