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

import os
from pathlib import Path

# numba runs a parallel kernel on its OpenMP layer (libgomp), whose idle threads keep spinning after each
# parallel region for GOMP_SPINCOUNT iterations (300,000 unless set: about a millisecond) before they sleep.
# Where another process wants the cores (the test suite's second worker, two sweeps, Dask workers on one
# machine) the spinning threads take them from it: the advisor's 6000 small batches (mujoco_implicit, 200
# bodies) took 20.5 s with libgomp's spin beside a second process doing the same, 5.6 s with this one, and
# 3.8 s against 4.5 alone (benchmarks/bench_contention.py, docs/benchmarks.md).  So a short spin, unless the
# user chose a wait policy or a spin count.
# libgomp reads them when it loads, at numba's first parallel call (after this import).
if "OMP_WAIT_POLICY" not in os.environ:
    os.environ.setdefault("GOMP_SPINCOUNT", "10000")

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
