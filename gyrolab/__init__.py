"""gyrolab: batch experiments with rigid-body rotation schemes.

``simulate(...)`` runs one trajectory, ``methods()`` lists the integrators,
``scenes()`` the scenes, ``free_body(I, omega0, q0, t)`` is the exact
torque-free motion (Euler–Poinsot, any positive moments); the ``gyrolab`` command runs whole sweeps (see
README).

The source tree keeps the package's sub-packages at its top level
(kernels/, runner/, analysis/, conf/; pyproject.toml maps them under
gyrolab).  When Python finds this file in a checkout rather than in an
installation (``python -c "import gyrolab"`` from the checkout root puts the
checkout first on sys.path), the checkout's top level joins the package's
path, so ``gyrolab.kernels`` is the checkout's kernels/ and the checkout's
code runs, whole and consistent, instead of an ImportError.
"""

from pathlib import Path

_HERE = Path(__file__).resolve().parent
_CHECKOUT = _HERE.parent
if (
    not (_HERE / "kernels").is_dir()
    and (_CHECKOUT / "pyproject.toml").is_file()
    and (_CHECKOUT / "kernels" / "registry.py").is_file()
):
    __path__.append(str(_CHECKOUT))  # noqa: F821 (the package's own __path__)

from .kernels.euler_poinsot import free_body  # noqa: E402
from .kernels.registry import methods  # noqa: E402
from .kernels.scenes import scenes  # noqa: E402
from .runner.simulate import simulate  # noqa: E402
from .version import __version__  # noqa: E402

__all__ = ["simulate", "methods", "scenes", "free_body", "__version__"]
