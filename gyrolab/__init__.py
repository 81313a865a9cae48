"""gyrolab: batch experiments with rigid-body rotation schemes.

``simulate(...)`` runs one trajectory, ``methods()`` lists the integrators;
the ``gyrolab`` command runs whole sweeps (see README).
"""
from importlib.metadata import PackageNotFoundError, version

from .kernels.registry import methods
from .runner.simulate import simulate

try:
    __version__ = version("gyrolab")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0+unknown"

__all__ = ["simulate", "methods", "__version__"]
