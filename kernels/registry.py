"""The registered integration methods: one line each.

A method is a module with ``ORDER``, ``SYMPLECTIC``, a docstring, a numba
``step(w, q, dt, body) -> (w, q)`` and a parallel ``run_batch``.
"""
from . import lie_poisson, lie_poisson4, rk4, seed_next, seed_prev

METHODS = {
    "seed_next": seed_next,
    "seed_prev": seed_prev,
    "rk4": rk4,
    "lie_poisson": lie_poisson,
    "lie_poisson4": lie_poisson4,
}


def get_method(name):
    """The method module registered as ``name``; ValueError naming the choices."""
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}") from None


def methods():
    """{name: {"order", "symplectic", "doc"}} for every registered method."""
    return {
        name: {
            "order": mod.ORDER,
            "symplectic": mod.SYMPLECTIC,
            "doc": (mod.__doc__ or "").strip().splitlines()[0],
        }
        for name, mod in METHODS.items()
    }
