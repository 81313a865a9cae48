"""A pure-numpy transcription of Kynema's Lie-group generalized-alpha step, for its heavy top.

Source read
-----------
Repository ``kynema/kynema`` (formerly Exawind/OpenTurbine), commit
d3b403dc6ea49a641f3eb16afbda7d0461644328 (2026-05-04).  Files:

* problem: ``tests/regression_tests/regression/test_heavy_top.cpp`` (also
  ``tests/documentation_tests/heavy_top/heavy_top.cpp``, same numbers);
* parameters: ``src/step/step_parameters.hpp``;
* step and Newton loop: ``src/step/step.hpp``, ``predict_next_state.hpp``,
  ``update_tangent_operator.hpp``, ``solve_system.hpp``, ``calculate_convergence_error.hpp``,
  ``update_state_prediction.hpp``, ``update_constraint_prediction.hpp``, ``reset_constraints.hpp``;
* state kernels: ``src/state/calculate_next_state.hpp``, ``calculate_displacement.hpp``,
  ``update_dynamic_prediction.hpp``, ``update_algorithmic_acceleration.hpp``,
  ``src/model/copy_nodes_to_state.hpp`` (initial algorithmic acceleration = acceleration);
* tangent operator: ``src/system/calculate_tangent_operator.hpp``;
* mass element: ``src/system/masses/*.hpp`` (quadrature-point values, inertial and gravity forces,
  gyroscopic and inertia-stiffness matrices, section-matrix rotation);
* constraints: ``src/constraints/calculate_rigid_joint_3DOF_constraint.hpp``,
  ``calculate_prescribed_bc_3DOF_constraint.hpp``, ``calculate_constraint_residual_gradient.hpp``,
  ``constraints.hpp`` (X0, row ranges), ``src/solver/condition_system.hpp``,
  ``src/solver/calculate_error_sum_squares.hpp``;
* conventions: ``src/math/quaternion_operations.hpp``, ``src/math/vector_operations.hpp``.

Conventions (as Kynema has them)
--------------------------------
* Quaternions are scalar first, (w, x, y, z).  A node's state ``q`` is a *displacement*: three
  translation components from the initial position ``x0`` and a rotation quaternion composed on the
  left of the initial orientation (here the identity).  Kynema's test asserts ``state.q``, so its
  "position" numbers are the centre-of-mass displacement from (0, 1, 0), not the position.
* Velocities, accelerations and the rotation increment are in the inertial (lab) frame: a step's
  rotation is ``q_new = exp(h * q_delta_rot) (x) q_prev`` (increment composed on the LEFT), and the
  inertia is rotated into the lab frame, rho = R J R^T.
* generalized-alpha (Chung-Hulbert form, as in Bruls, Cardona & Arnold 2012) from rho_inf:
  alpha_m = (2 rho_inf - 1) / (rho_inf + 1), alpha_f = rho_inf / (rho_inf + 1),
  gamma = 1/2 + alpha_f - alpha_m, beta = (gamma + 1/2)^2 / 4,
  gamma' = gamma / (h beta), beta' = (1 - alpha_m) / (h^2 beta (1 - alpha_f)).
  With rho_inf = 0.9: alpha_m = 0.8/1.9 = 0.42105, alpha_f = 0.9/1.9 = 0.47368,
  gamma = 0.55263, beta = 0.27701; at h = 2e-3, gamma' = 997.5 and beta' = 992750.
  The predictor (CalculateNextState) sets the physical acceleration vd to 0, the algorithmic one
  to a = (alpha_f vd_n - alpha_m a_n) / (1 - alpha_m), v = v_n + h ((1 - gamma) a_n + gamma a),
  q_delta = v_n + h ((1/2 - beta) a_n + beta a); after Newton, a += (1 - alpha_f)/(1 - alpha_m) vd.
* Newton unknowns: per node the 6-vector increment dx of the step's increment h*q_delta
  (translation, rotation vector), and per constraint row the multiplier increment;
  q_delta += dx / h, v += gamma' dx, vd += beta' dx.  The iteration matrix of the mass is
  beta' M + gamma' G + K T with T the (transposed) tangent operator of h*q_delta_rot.
  Converged when sqrt(mean over all 15 unknowns of (dx_i / (atol + rtol |x_i|))^2) <= 1, with
  x_i = h*q_delta_i for node DOFs and lambda_i for multipliers, atol = 1e-5, rtol = 1e-3, at most
  10 iterations; the increment of the converging iteration is still applied.
* Index-3 constraint (positions), scaled: the system rows of the residual and of the iteration
  matrix are multiplied by the conditioner beta h^2; the constraint gradient blocks are not, so the
  solved multiplier increments are divided by beta h^2 afterwards.  Multipliers restart at zero
  every step.  The derivative of B^T lambda (the constraint's geometric stiffness) is not in the
  iteration matrix, so Newton converges only linearly (rate ~3e-4) after its second iteration.

Model: node 0 carries the mass element (m = 15 kg, J = diag(0.234375, 0.46875, 0.234375) kg m^2
about the centre of mass, node at the centre of mass (0, 1, 0)), node 1 is a ground node at the
origin with 3 translational DOFs.  Constraint 0 (RigidJoint6DOFsTo3DOFs, base = node 0, target =
node 1, X0 = x0_target - x0_base = (0, -1, 0)): Phi = u1 + X0 - u0 - R0 X0.  Constraint 1
(PrescribedBC3DOFs on node 1): Phi = u1.  Gravity (0, 0, -9.81).  Initial state: omega =
(0, 150, -4.61538), xdot = omega x (0, 1, 0), and the consistent initial accelerations that the
Kynema test hard-codes.  h = 0.002 s, rho_inf = 0.9, 400 steps.

Agreement (see tests/test_kynema_heavy_top.py): Kynema's published t = 0.8 s state to 2.1e-11
(3 Newton iterations every step).  The published numbers are, to 8e-14, the *fully converged*
generalized-alpha solution (min_iter=4, or adding the geometric stiffness), which this literal
transcription is not after 3 iterations; the 2e-11 gap is not roundoff (float64 and 80-bit runs
differ by 1.6e-14) and its source is not resolved.  The same code with the tangent untransposed
(Kynema before commit ebd716ad, where the published numbers were set) reproduces the heavy-top
numbers published before that commit to 2.6e-13, through 6-10 loosely converged Newton
iterations a step, and Kynema's precession test to 6.7e-16.
"""

import numpy as np

from transcribe import qmul as quat_compose  # the Hamilton product, scalar first
from transcribe import rot as quat_to_matrix  # R(q), Kynema's quadratic form too (not renormalised)

# ---------------------------------------------------------------------------------------------
# Problem data of Kynema's heavy-top test
# ---------------------------------------------------------------------------------------------
MASS = 15.0
J_COM = np.array([0.234375, 0.46875, 0.234375])
X_COM0 = np.array([0.0, 1.0, 0.0])
OMEGA0 = np.array([0.0, 150.0, -4.61538])
OMEGA_DOT0 = np.array([661.3461692307691919, 0.0, 0.0])
X_DDOT0 = np.array([0.0, -21.3017325444000001, -30.9608307692308244])
GRAVITY = np.array([0.0, 0.0, -9.81])

# Kynema's published state.q of the mass node after 400 steps (t = 0.8 s): displacement of the
# centre of mass from X_COM0, then the rotation quaternion (w, x, y, z).
PUBLISHED_Q = np.array(
    [
        -0.42217802273894345,
        -0.09458263530050703,
        -0.04455460488952848,
        -0.17919607435565366,
        0.21677896640311572,
        -0.95947769608535960,
        -0.017268392381761217,
    ]
)


def step_parameters(h, rho_inf):
    """StepParameters(is_dynamic_solve=true, ...) of src/step/step_parameters.hpp."""
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    beta = 0.25 * (gamma + 0.5) * (gamma + 0.5)
    return {
        "h": h,
        "alpha_m": alpha_m,
        "alpha_f": alpha_f,
        "gamma": gamma,
        "beta": beta,
        "gamma_prime": gamma / (h * beta),
        "beta_prime": (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f)),
        "conditioner": beta * h * h,
    }


# ---------------------------------------------------------------------------------------------
# Small math (src/math)
# ---------------------------------------------------------------------------------------------
def tilde(v):
    """Skew matrix: tilde(a) @ b = a x b."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotvec_to_quat(phi):
    """Exponential map of a rotation vector (Kynema zeroes the vector part below 1e-12 rad)."""
    angle = np.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    factor = 0.0 if abs(angle) < 1.0e-12 else np.sin(angle / 2.0) / angle
    return np.array([np.cos(angle / 2.0), phi[0] * factor, phi[1] * factor, phi[2] * factor])


def tangent_operator(h, q_delta):
    """CalculateTangentOperator: T = I + (cos p - 1)/p^2 tilde(r) + (1 - sin p / p)/p^2 tilde(r)^2 on the
    rotation block, r = h * q_delta_rot, p = |r|; Kynema stores and uses its transpose."""
    T = np.eye(6)
    rv = h * q_delta[3:6]
    phi = np.sqrt(rv @ rv)
    tmp1 = (np.cos(phi) - 1.0) / (phi * phi) if phi > 1.0e-16 else 0.0
    tmp2 = (1.0 - np.sin(phi) / phi) / (phi * phi) if phi > 1.0e-16 else 0.0
    rt = tilde(rv)
    T[3:6, 3:6] += tmp1 * rt + tmp2 * (rt @ rt)
    return T.T


# ---------------------------------------------------------------------------------------------
# The mass element (src/system/masses)
# ---------------------------------------------------------------------------------------------
def mass_element(p, q, v, vd, T, mass=MASS, inertia=J_COM, gravity=GRAVITY, mstar=None):
    """masses::CalculateQuadraturePointValues: residual (inertial minus gravity force) and the
    element's iteration matrix beta' M + gamma' G + K T, everything in the lab frame.  The 6x6
    material mass matrix is diag(mass, mass, mass, *inertia) (no offset of the centre of mass), or
    ``mstar`` when given (a node off the centre of mass: see pivot_mass_matrix)."""
    R = quat_to_matrix(q[3:])  # q (x) x0 with x0 the identity
    RR = np.zeros((6, 6))
    RR[:3, :3] = R
    RR[3:, 3:] = R
    Mstar = np.diag([mass, mass, mass, *inertia]) if mstar is None else mstar
    Muu = RR @ Mstar @ RR.T
    m = Muu[0, 0]
    eta = np.array([Muu[5, 1], -Muu[5, 0], Muu[4, 0]]) / m  # CoM offset from the node (zero here)
    rho = Muu[3:, 3:].copy()
    u_ddot, omega, omega_dot = vd[:3], v[3:], vd[3:]
    wt, wdt, et = tilde(omega), tilde(omega_dot), tilde(eta)

    # Inertial force FI = [m u'' + (w'~ + w~ w~) m eta ; m eta~ u'' + rho w' + w~ rho w]
    Fi = np.empty(6)
    Fi[:3] = (m * (wt @ wt) + m * wdt) @ eta + m * u_ddot
    Fi[3:] = et @ (m * u_ddot) + rho @ omega_dot + (wt @ rho) @ omega
    # Gravity FG = [m g ; eta~ m g]
    Fg = np.empty(6)
    Fg[:3] = m * gravity
    Fg[3:] = et @ Fg[:3]
    residual = Fi - Fg

    # Gyroscopic matrix G (derivative of FI w.r.t. velocity)
    G = np.zeros((6, 6))
    meta = m * eta
    G[:3, 3:] = tilde(wt @ meta).T + wt @ tilde(meta).T
    G[3:, 3:] = wt @ rho - tilde(rho @ omega)
    # Inertia stiffness matrix K (derivative of FI w.r.t. the rotation)
    K = np.zeros((6, 6))
    K[:3, 3:] = (wdt + wt @ wt) @ tilde(meta).T
    K22 = rho @ wdt + tilde(u_ddot) @ tilde(meta) - tilde(rho @ omega_dot)
    K22 = K22 + wt @ (rho @ wt - tilde(rho @ omega))
    K[3:, 3:] = K22

    matrix = p["beta_prime"] * Muu + p["gamma_prime"] * G + K @ T
    return residual, matrix


# ---------------------------------------------------------------------------------------------
# State and the generalized-alpha predictor / corrector (src/state, src/step)
# ---------------------------------------------------------------------------------------------
IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def make_state(v, vd):
    """State of n nodes from their velocities and accelerations (n x 6), displacement zero."""
    n = len(v)
    return {
        "q": np.tile(IDENTITY_Q, (n, 1)),
        "q_prev": np.tile(IDENTITY_Q, (n, 1)),
        "q_delta": np.zeros((n, 6)),
        "v": np.array(v, dtype=float),
        "vd": np.array(vd, dtype=float),
        "a": np.array(vd, dtype=float),  # CopyNodesToState: algorithmic acceleration = acceleration
    }


def calculate_displacement(s, h):
    """q = q_prev (+) h q_delta: translation added, rotation exp(h w) composed on the LEFT."""
    for n in range(len(s["q"])):
        s["q"][n, :3] = s["q_prev"][n, :3] + h * s["q_delta"][n, :3]
        s["q"][n, 3:] = quat_compose(rotvec_to_quat(h * s["q_delta"][n, 3:]), s["q_prev"][n, 3:])


def predict_next_state(p, s):
    """PredictNextState: CalculateNextState on every component of every node, then the
    displacement.  vd (the physical acceleration) restarts at zero, a is the algorithmic one."""
    h, am, af, be, ga = p["h"], p["alpha_m"], p["alpha_f"], p["beta"], p["gamma"]
    s["q_prev"][:] = s["q"]
    v_p, vd_p, a_p = s["v"].copy(), s["vd"].copy(), s["a"].copy()
    s["vd"][:] = 0.0
    s["a"][:] = (af * vd_p - am * a_p) / (1.0 - am)
    s["v"][:] = v_p + h * (1.0 - ga) * a_p + ga * h * s["a"]
    s["q_delta"][:] = v_p + (0.5 - be) * h * a_p + be * h * s["a"]
    calculate_displacement(s, h)


def update_dynamic_prediction(p, s, node, dx):
    """UpdateDynamicPrediction for one node's active DOFs, dx = the Newton increment."""
    k = len(dx)
    s["q_delta"][node, :k] += dx / p["h"]
    s["v"][node, :k] += p["gamma_prime"] * dx
    s["vd"][node, :k] += p["beta_prime"] * dx


def error_sum_squares(pi, xi, atol, rtol):
    """CalculateSystemErrorSumSquares / CalculateConstraintsErrorSumSquares (Table 1 of
    doi:10.1115/1.4033441): sum of (increment / (atol + rtol |current value|))^2."""
    e = pi / (atol + rtol * np.abs(xi))
    return float(np.sum(e * e))


def update_algorithmic_acceleration(p, s):
    s["a"] += (1.0 - p["alpha_f"]) / (1.0 - p["alpha_m"]) * s["vd"]


# ---------------------------------------------------------------------------------------------
# The heavy top: node 0 = the mass, node 1 = the ground node (3 active DOFs)
# ---------------------------------------------------------------------------------------------
ACTIVE = (6, 3)  # active DOFs per node
FIRST = (0, 6)  # first system DOF of each node
N_SYSTEM = 9
N_CONSTRAINT_ROWS = 6  # rows 0..2: rigid joint; rows 3..5: prescribed BC on the ground node
N_DOFS = N_SYSTEM + N_CONSTRAINT_ROWS
X0_JOINT = np.zeros(3) - X_COM0  # target (ground) minus base (mass) initial position


def initial_state():
    v = np.zeros((2, 6))
    v[0, :3] = np.cross(OMEGA0, X_COM0)  # (4.61538, 0, 0)
    v[0, 3:] = OMEGA0
    vd = np.zeros((2, 6))
    vd[0, :3] = X_DDOT0
    vd[0, 3:] = OMEGA_DOT0
    s = make_state(v, vd)
    s["lam"] = np.zeros(N_CONSTRAINT_ROWS)
    return s


def pivot_residual(s):
    """Phi of the rigid joint: u_ground + X0 - u_mass - R X0 (zero when the pivot holds)."""
    return s["q"][1, :3] + X0_JOINT - s["q"][0, :3] - quat_to_matrix(s["q"][0, 3:]) @ X0_JOINT


def solve_step(p, s, max_iter=10, atol=1.0e-5, rtol=1.0e-3, min_iter=0, transpose_tangent=True, log=None):
    """One SolveStep of src/step/step.hpp for the heavy top.  Returns (converged, iterations).

    min_iter > 0 forces at least that many Newton iterations (not Kynema; a diagnostic).
    transpose_tangent=False uses the tangent operator as Kynema had it before commit ebd716ad
    (2025-03-20), which reproduces the heavy-top numbers Kynema published before that commit."""
    h = p["h"]
    cond = p["conditioner"]

    predict_next_state(p, s)
    s["lam"][:] = 0.0  # ResetConstraints

    err = 1000.0
    it = 0
    while err > 1.0 or it < min_iter:
        if it >= max_iter:
            return False, it
        T = [tangent_operator(h, s["q_delta"][n]) for n in range(2)]
        if not transpose_tangent:
            T = [t.T for t in T]

        A = np.zeros((N_DOFS, N_DOFS))
        b = np.zeros(N_DOFS)

        # Mass element on node 0 (no external forces)
        r_mass, k_mass = mass_element(p, s["q"][0], s["v"][0], s["vd"][0], T[0])
        b[0:6] += r_mass
        A[0:6, 0:6] += cond * k_mass  # ContributeMassesToSparseMatrix scales by the conditioner

        # Constraint 0: rigid joint, base = node 0 (6 DOFs), target = node 1 (3 DOFs).
        # Gradient B = [[-I, tilde(R X0)]] on the base and [I] on the target; the constraint rows
        # hold B T (T = the node's tangent), the system columns hold B^T (no tangent, and no
        # derivative of B^T lambda: Kynema has no constraint geometric stiffness).
        R0X0 = quat_to_matrix(s["q"][0, 3:]) @ X0_JOINT
        B_base = np.hstack([-np.eye(3), tilde(R0X0)])
        B_tgt = np.eye(3)
        lam0 = s["lam"][0:3]
        rows0 = slice(N_SYSTEM, N_SYSTEM + 3)
        A[rows0, 0:6] = B_base @ T[0]
        A[rows0, 6:9] = B_tgt @ T[1][:3, :3]
        A[0:6, rows0] = B_base.T
        A[6:9, rows0] = B_tgt.T
        b[0:6] += B_base.T @ lam0
        b[6:9] += B_tgt.T @ lam0
        b[rows0] = pivot_residual(s)

        # Constraint 1: prescribed zero displacement of the ground node (X0 = 0): Phi = u_ground
        lam1 = s["lam"][3:6]
        rows1 = slice(N_SYSTEM + 3, N_SYSTEM + 6)
        A[rows1, 6:9] = B_tgt @ T[1][:3, :3]
        A[6:9, rows1] = B_tgt.T
        b[6:9] += B_tgt.T @ lam1
        b[rows1] = s["q"][1, :3]

        # SolveSystem: condition the system rows of R (times beta h^2), negate, solve, and divide
        # the multiplier part of the solution by the conditioner.
        b[:N_SYSTEM] *= cond
        x = np.linalg.solve(A, -b)
        x[N_SYSTEM:] /= cond

        # CalculateConvergenceError: RMS over all 15 unknowns, before the state is updated
        ssq = 0.0
        for n in range(2):
            pi = x[FIRST[n] : FIRST[n] + ACTIVE[n]]
            ssq += error_sum_squares(pi, s["q_delta"][n, : ACTIVE[n]] * h, atol, rtol)
        ssq += error_sum_squares(x[N_SYSTEM:], s["lam"], atol, rtol)
        err = np.sqrt(ssq / N_DOFS)
        if log is not None:
            log.append(err)

        # UpdateStatePrediction and UpdateConstraintPrediction (also after the converging solve)
        for n in range(2):
            update_dynamic_prediction(p, s, n, x[FIRST[n] : FIRST[n] + ACTIVE[n]])
        calculate_displacement(s, h)
        s["lam"] += x[N_SYSTEM:]
        it += 1

    update_algorithmic_acceleration(p, s)
    return not np.isnan(err), it


def run(h=0.002, n_steps=400, rho_inf=0.9, callback=None, **step_options):
    """Run the heavy top and return the final state; callback(step, state, iterations) after each
    step.  step_options go to solve_step."""
    p = step_parameters(h, rho_inf)
    s = initial_state()
    for k in range(n_steps):
        ok, it = solve_step(p, s, **step_options)
        if not ok:
            raise RuntimeError(f"Newton did not converge at step {k + 1}")
        if callback is not None:
            callback(k + 1, s, it)
    return s


# ---------------------------------------------------------------------------------------------
# Kynema's precession test (tests/regression_tests/regression/test_precession.cpp): one free
# node with a mass element, no gravity, no constraints -- a check of the mass element, tangent
# operator, predictor and convergence test without the pivot.
# ---------------------------------------------------------------------------------------------
PRECESSION_PUBLISHED_QUAT = np.array(
    [-0.63053045128590757, 0.60556039120583116, -0.30157681970585326, -0.38049886257377241]
)


def run_one_node(p, s, n_steps, element, held=False, max_iter=6, atol=1.0e-5, rtol=1.0e-3):
    """``n_steps`` steps of one node (state ``s``) whose mass element is ``element(q, v, vd, T) ->
    (residual, matrix)``: Kynema's predictor, Newton loop and convergence test (the RMS over the node's
    six unknowns).  ``held``: the node's translation is held (its unknowns stay zero) and only the
    rotational block is solved.  Returns ``s``."""
    h = p["h"]
    for k in range(n_steps):
        predict_next_state(p, s)
        err, it = 1000.0, 0
        while err > 1.0:
            if it >= max_iter:
                raise RuntimeError(f"Newton did not converge at step {k + 1}")
            T = tangent_operator(h, s["q_delta"][0])
            r, m = element(s["q"][0], s["v"][0], s["vd"][0], T)
            if held:
                x = np.zeros(6)
                x[3:] = np.linalg.solve(p["conditioner"] * m[3:, 3:], -p["conditioner"] * r[3:])
            else:
                x = np.linalg.solve(p["conditioner"] * m, -p["conditioner"] * r)
            err = np.sqrt(error_sum_squares(x, s["q_delta"][0] * h, atol, rtol) / 6)
            update_dynamic_prediction(p, s, 0, x)
            calculate_displacement(s, h)
            it += 1
        update_algorithmic_acceleration(p, s)
    return s


def run_precession(n_steps=500, h=0.01, rho_inf=1.0, max_iter=6, atol=1.0e-5, rtol=1.0e-3):
    p = step_parameters(h, rho_inf)
    s = make_state([[0.0, 0.0, 0.0, 0.5, 0.5, 1.0]], np.zeros((1, 6)))
    body = {"mass": 1.0, "inertia": np.array([1.0, 1.0, 0.5]), "gravity": np.zeros(3)}

    def element(q, v, vd, T):
        return mass_element(p, q, v, vd, T, **body)

    return run_one_node(p, s, n_steps, element, max_iter=max_iter, atol=atol, rtol=rtol)


# ---------------------------------------------------------------------------------------------
# The same body as one node at the pivot (gyrolab's lie_genalpha): Kynema's mass element with the
# centre of mass off the node, the node's translation held (a prescribed BC), so only the
# rotational block of the Newton system remains and the translational unknowns stay zero.
# ---------------------------------------------------------------------------------------------
def pivot_mass_matrix(mass, j_com, com):
    """Kynema's 6x6 material mass matrix of a rigid body at a node off its centre of mass by ``com``
    (body frame): [[m 1, (m com~)^T], [m com~, J_com + m (|com|^2 1 - com com^T)]] (the mass
    element reads the offset back from the lower-left block)."""
    c = np.asarray(com, dtype=float)
    mc = mass * tilde(c)
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[3:, :3] = mc
    out[:3, 3:] = mc.T
    out[3:, 3:] = np.diag(j_com) + mass * ((c @ c) * np.eye(3) - np.outer(c, c))
    return out


def run_pivot_node(h=0.002, n_steps=400, rho_inf=0.9, mass=MASS, j_com=J_COM, com=X_COM0, gravity=GRAVITY,
                   omega0=OMEGA0, max_iter=10, atol=1.0e-5, rtol=1.0e-3):  # fmt: skip
    """The body as one node at the pivot (orientation identity, lab angular velocity ``omega0``),
    from the consistent accelerations; Kynema's predictor, mass element, tangent and convergence
    test (the RMS over the node's six unknowns).  Returns the node's state dict."""
    p = step_parameters(h, rho_inf)
    mstar = pivot_mass_matrix(mass, j_com, com)
    jp = mstar[3:, 3:]
    w = np.asarray(omega0, dtype=float)
    wd = np.linalg.solve(jp, np.cross(com, mass * gravity) - np.cross(w, jp @ w))
    s = make_state([[0.0, 0.0, 0.0, *w]], [[0.0, 0.0, 0.0, *wd]])

    def element(q, v, vd, T):
        return mass_element(p, q, v, vd, T, gravity=gravity, mstar=mstar)

    return run_one_node(p, s, n_steps, element, held=True, max_iter=max_iter, atol=atol, rtol=rtol)


if __name__ == "__main__":  # python tests/kynema_genalpha.py: the agreement the README states
    state = run()
    print(f"max |state.q - Kynema's published| at t = 0.8 s: {np.abs(state['q'][0] - PUBLISHED_Q).max():.2g}")
