"""Basilisk itself (``pip install bsk``, imports as ``Basilisk``): each run one ``spacecraft.Spacecraft`` hub.

The run is a free rigid hub: ``hub.mHub`` = 1 kg, ``hub.IHubPntBc_B`` = diag(I1, I2, I3) about the centre
of mass (``r_BcB_B`` = 0), no gravity body, no effectors; ``hub.sigma_BNInit`` = the MRP of the run's q
and ``hub.omega_BN_BInit`` = ω (body frame).  σ_BN is the attitude of B relative to N, [BN] = C(σ_BN)
maps N components to B components; gyrolab's q (scalar first) maps body to lab, R(q) = [NB] = [BN]ᵀ, so
σ_BN is the MRP of q itself: σ = (b, c, d)/(1 + a) (a ≥ 0; −q otherwise), and back
q = ((1 − σ²), 2σ)/(1 + σ²) (kernels/methods/rk4_mrp.py uses the same two maps).  Every sample the
state is read from ``scStateOutMsg`` (sigma_BN, omega_BN_B), written after the step's MRP switch.
A heavy body (a pivot, gravity about it) is not what a spacecraft hub models: refused in one line.

- ``real_basilisk_rk4`` (``mode="RK4"``, the Spacecraft's default integrator): free bodies only;
  kernels/methods/rk4_mrp reproduces its update (RK4 on σ and ω, the shadow switch after the full
  step) to rounding where the motion does not amplify it (kernels/real/conformance.py); the step is
  dt as whole nanoseconds.

Basilisk's choices, as shipped (AVSLab/basilisk at babdff7a60ae, the 2.12 line; the wheel bsk 2.12.1
holds the hub-only fast path, commit a2e9a7a1e, by its symbol ``computeHubOnlyDerivatives``):

- integrator: ``svIntegratorRK4``, the Spacecraft's default (src/simulation/dynamics/
  _GeneralModuleFiles/svIntegratorRK4.cpp, svIntegratorRungeKutta.h): classic RK4 (a = ½, ½, 1;
  b = ⅙, ⅓, ⅓, ⅙) on the stacked states (σ, ω, r, v, ...), each stage state y0 + dt Σ a k and the
  final y0 + dt Σ b k built by ``StateData::propagateState`` (state += deriv dt, no switching);
- derivatives: with no state effector and the centre of mass at B (``Spacecraft::useHubOnlyFastPath``)
  ``HubEffector::computeHubOnlyDerivatives``: σ̇ = ¼ B(σ) ω, ω̇ = I.ldlt().solve(τ − ω × Iω)
  (Eigen); otherwise the back-substitution of ``HubEffector::computeDerivatives``, the same ω̇
  for this hub but through matrix inverses;
- MRP shadow switching (``HubEffector::modifyStates``, called from ``Spacecraft::postIntegration``):
  after the whole RK4 step, never inside a stage, |σ| > 1 → σ ← −σ/|σ|², so the stored σ has
  |σ| ≤ 1 (rk4_mrp reproduces exactly this);
- time: integer nanoseconds.  The task rate is dt in ns and the integrator's step is
  ``diffNanoToSec`` = ns · 1e-9 (NANO2SEC, src/architecture/utilities/macroDefinitions.h), each step
  from the integer clock (no drift): a dt that is not a whole number of ns (to 1e-12 relative) is
  refused in one line (``Backend.check_dt``); 1e-3 and 1e-4 s are exact (ns · 1e-9 == dt bit for bit);
- the task also runs at t = 0 (``ExecuteSimulation`` runs every task time up to and including the stop
  time): that call integrates a zero step (state += 0) and is no step.

One ``ConfigureStopTime`` + ``ExecuteSimulation`` per sample (``advance(n)``), never per step: measured
on the development machine (2 shared cores) ~0.2 ms a call (~0.12 ms of it in ``TotalSim.StepUntilStop``
itself, the rest SimBaseClass's Python event and progress-bar loop) besides ~10 µs a step, so one step
per call costs ~200 µs and a stride of 100 ~15 µs a step; building a run (SimBaseClass, Spacecraft,
InitializeSimulation) ~5 ms.  Basilisk never throws a state away: a
non-finite ω or σ reaches gyrolab's own divergence rule.
"""

import numpy as np

from ..methods import rk4_mrp
from .pybullet_engine import is_free

NANO2SEC = 1e-9  # Basilisk's macroDefinitions.h


def mrp_from_quat(q):
    """σ_BN (|σ| ≤ 1) of gyrolab's q (scalar first, body → lab): rk4_mrp's own conversion."""
    return list(rk4_mrp.mrp_from_quat(tuple(map(float, q))))


def quat_from_mrp(sigma):
    """gyrolab's q (scalar first, scalar ≥ 0 when |σ| ≤ 1) of σ_BN: rk4_mrp's own conversion."""
    return np.array(rk4_mrp.quat_from_mrp(tuple(map(float, sigma))))


def step_nanos(dt, name="real_basilisk_rk4"):
    """dt (s) as Basilisk's integer nanoseconds; ValueError (one line) when it is not a whole number of them."""
    dt = float(dt)
    ns = int(round(dt * 1e9)) if np.isfinite(dt) and dt > 0 else 0
    if ns < 1 or abs(ns * NANO2SEC - dt) > 1e-12 * dt:
        raise ValueError(
            f"method {name!r} steps Basilisk's integer-nanosecond clock: dt = {dt!r} s is not a whole number "
            f"of nanoseconds (nearest {max(ns, 1)} ns = {max(ns, 1) * NANO2SEC!r} s); choose a dt that is"
        )
    return ns


class Backend:
    """Basilisk's Spacecraft hub with its default integrator, svIntegratorRK4 (``mode`` "RK4")."""

    PACKAGE = "bsk"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)
    DEFAULTS = (
        "Basilisk Spacecraft hub, svIntegratorRK4; MRP shadow switch |sigma| > 1 after each full step "
        "(HubEffector::modifyStates); integer-ns clock, step = ns * 1e-9 s"
    )

    def __init__(self, name, mode):
        from Basilisk.simulation import spacecraft
        from Basilisk.utilities import SimulationBaseClass

        self.name, self.mode = name, mode
        self.spacecraft, self.sim_base = spacecraft, SimulationBaseClass

    def check(self, body):
        """ValueError (one line) when this backend does not build ``body``: a heavy body (pivot, M g c ≠ 0)."""
        if not is_free(body):
            raise ValueError(
                f"method {self.name!r} runs free bodies only (a Basilisk spacecraft hub has no pivot: "
                f"M g c = {(body.mgc1, body.mgc2, body.mgl)} N m is not modelled); use a free-body scene"
            )

    def check_dt(self, dt):
        """ValueError (one line) when ``dt`` (s) is not a whole number of nanoseconds."""
        step_nanos(dt, self.name)

    def start(self, body, w0, q0, dt):
        """A run of ``body`` (kernels.body.Body) from ω0 (body, rad/s) and q0 (scalar first) with step dt (s)."""
        self.check(body)
        ns = step_nanos(dt, self.name)
        return _Run(self, body, w0, q0, ns)


class _Run:
    def __init__(self, backend, body, w0, q0, ns):
        sim = backend.sim_base.SimBaseClass()
        process = sim.CreateNewProcess("gyrolab")
        process.addTask(sim.CreateNewTask("dynamics", ns))
        sc = backend.spacecraft.Spacecraft()
        sc.ModelTag = "body"
        sc.hub.mHub = 1.0
        sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
        sc.hub.IHubPntBc_B = [[float(body.I1), 0.0, 0.0], [0.0, float(body.I2), 0.0], [0.0, 0.0, float(body.I3)]]
        sc.hub.sigma_BNInit = [[x] for x in mrp_from_quat(q0)]
        sc.hub.omega_BN_BInit = [[float(x)] for x in w0]
        sim.AddModelToTask("dynamics", sc)
        sim.InitializeSimulation()
        self.sim, self.sc, self.ns, self.now = sim, sc, ns, 0

    def advance(self, n):
        """n steps of dt in one ExecuteSimulation: (n, ω body (rad/s), q scalar first)."""
        self.now += int(n) * self.ns
        self.sim.ConfigureStopTime(self.now)
        self.sim.ExecuteSimulation()
        state = self.sc.scStateOutMsg.read()
        return n, np.array(state.omega_BN_B, dtype=float), quat_from_mrp(state.sigma_BN)

    def close(self):
        self.sim = self.sc = None
