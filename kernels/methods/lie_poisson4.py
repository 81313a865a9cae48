"""lie_poisson4: fourth-order composition of lie_poisson (Yoshida's triple jump).

S(w1 dt) S(w0 dt) S(w1 dt) with w1 = 1/(2 − 2^(1/3)), w0 = 1 − 2 w1, where S is
the symmetric second-order lie_poisson step.  Symplectic; the middle substep
runs backwards in time.  Source: Yoshida (1990), Suzuki (1990).

Parameter ``axes`` (default 1-2-3): the axis order of every substep's free flow, as lie_poisson's.
"""

from numba import njit

from ..body import without_drive
from ..compose import compose_steps
from ..variants import undriven
from .lie_poisson import PARAMETERS as STRANG_PARAMETERS
from .lie_poisson import step_driven as strang_driven
from .lie_poisson import variant as strang_variant

ORDER = 4
SYMPLECTIC = True
PRESERVES = ("L", "L_norm", "Lz", "L3")
PARAMETERS = STRANG_PARAMETERS  # the axis order of lie_poisson's free flow

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


def variant(axes):
    """The composition of lie_poisson's variant with the free flow's axis order ``axes``."""
    return undriven(compose_steps(strang_variant(axes)["step_driven"], WEIGHTS))
