"""mujoco_implicitfast: MuJoCo's "implicitfast" (RNE derivatives dropped; kept for a free body).

Followed: google-deepmind/mujoco at commit a7255075b003 (3.12.0-31-g, 22 Aug
2026), src/engine/engine_forward.c ``mj_implicitSkip`` (integrator
mjINT_IMPLICITFAST), src/engine/engine_derivative.c ``mjd_smooth_vel`` with
flg_bias = 0 and ``mjd_freeMhat`` / ``freeBias_vel_blocks`` (the 6×6 local
unsymmetric solve for free joints whose body has no children), and
doc/computation/index.rst "Gyroscopic derivatives for free bodies"; checked
against the ``mujoco`` 4.0.0 wheel by tests/test_engines.py.

- Ball joint (a heavy body, M g c ≠ 0): D holds only damping and
  actuator derivatives, zero for the rigid body, so M − h D = M and the update
  is exactly MuJoCo's semi-implicit Euler (mujoco_euler): the gyroscopic force
  is explicit.
- Free body (M g c = 0, read as a standalone free joint): the bias
  derivative is put back, so the update is mujoco_implicit's.

Both then integrate q with the new ω (``mju_quatIntegrate``).  A free body
that is part of a larger tree, or a ball-jointed body without gravity, would
take the first branch in MuJoCo; gyrolab's body tuple cannot express those.
No hidden limits.  Order 1.
"""

from numba import njit

from ..engine_common import mj_quat_integrate
from ..rigid_body import potential_scale
from .mujoco_euler import qacc
from .mujoco_implicit import implicit_qacc

ORDER = 1
SYMPLECTIC = False
REPRODUCES = "MuJoCo 4.0 implicitfast"  # judged by conformance with the engine (tests/test_engines.py)
PRESERVES = ("L3",)


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    if potential_scale(body) == 0.0:
        a = implicit_qacc(w, q, dt, body)
    else:
        a = qacc(w, q, body)
    w_next = (w[0] + a[0] * dt, w[1] + a[1] * dt, w[2] + a[2] * dt)
    return w_next, mj_quat_integrate(q, w_next, dt)
