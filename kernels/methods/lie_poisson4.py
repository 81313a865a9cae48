"""lie_poisson4: fourth-order composition of lie_poisson (Yoshida's triple jump).

S(w1 dt) S(w0 dt) S(w1 dt) with w1 = 1/(2 − 2^(1/3)), w0 = 1 − 2 w1, where S is
the symmetric second-order lie_poisson step.  Symplectic; the middle substep
runs backwards in time.  Source: Yoshida (1990), Suzuki (1990).

Parameters: ``axes`` (default 1-2-3), the axis order of every substep's free flow, as lie_poisson's;
``accumulate`` (default plain): ``compensated`` keeps ω and q as hi + lo and adds every flow as an
error-free increment (kernels/compensated.py), so that a run's round-off no longer drifts linearly
(benchmarks/brouwer.py: about √t, 4–7 orders lower after 1e8 steps); that variant carries the low parts
from step to step, runs one run after another, and integrates undriven bodies only.
"""

from numba import njit

from .. import compensated
from ..body import without_drive
from ..compose import compose_steps
from ..parameters import ACCUMULATE
from ..variants import carried, undriven
from .lie_poisson import PARAMETERS as STRANG_PARAMETERS
from .lie_poisson import step_driven as strang_driven
from .lie_poisson import variant as strang_variant

ORDER = 4
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz", "L3")
PARAMETERS = {**STRANG_PARAMETERS, "accumulate": ACCUMULATE}  # lie_poisson's axis order; plain or compensated

W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
W0 = 1.0 - 2.0 * W1
WEIGHTS = (W1, W0, W1)
_composed = compose_steps(strang_driven, WEIGHTS)  # whole Strang steps, substep k from t + (w_0 + … + w_{k−1}) dt


@njit(cache=True, error_model="numpy", forceinline=True)  # inlined into step: its drive folds away
def step_driven(w, q, t, dt, body):
    """One step of dt seconds from time t (s): the composition, each Strang substep from the time the
    previous ones reached (kernels/compose.py)."""
    return _composed(w, q, t, dt, body)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    """One step of dt seconds of the body without its drive: step_driven from t = 0."""
    return step_driven(w, q, 0.0, dt, without_drive(body))


def variant(axes, accumulate):
    """The composition of lie_poisson's variant with the free flow's axis order ``axes``; with
    ``accumulate`` 1 (compensated) the same map compensated (kernels/compensated.py), a carried method."""
    if accumulate:
        return carried(compensated.start, compensated.strang_composition(WEIGHTS, axes))
    return undriven(compose_steps(strang_variant(axes)["step_driven"], WEIGHTS))
