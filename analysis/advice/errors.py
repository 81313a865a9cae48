"""What "right" means for the advisor, measured: a run's error against an independent reference.

The metrics (all dimensionless, the largest value over the run's samples):

- ``orientation``: the angle (rad) of R_refᵀ R, the rotation between the computed and the reference
  attitude.  The samples do not store the quaternion, so R is rebuilt from three body vectors whose
  lab images they do store: R e3 = axis, R γ = ẑ (γ = Rᵀ ẑ), R Iω = L (Kabsch's least-squares
  rotation; exact for a run's own samples, which are consistent to rounding, whenever the three do
  not all point the same way: the runs start from a generic attitude, ``Q0``).
- ``omega``: |ω − ω_ref| / |ω0| (body rates).
- ``energy``: |E − E_ref| / (T0 + |M g c|), the energy error relative to the body's energy scale.
- an invariant of kernels/invariants.py (``L``, ``L_norm``, ``Lz``, ``L3``, ``kovalevskaya``):
  |X − X_ref| / scale, with the scale |L0| for the momenta and K0 for Kovalevskaya's integral.

The reference: the exact Euler–Poinsot flow (``free_body``, closed form at every sample time) for a
body without gravity, DOP853 on (ω, R) at rtol = atol = 1e-12 (kernels/reference.py) for a heavy one.
"""

import math
from types import SimpleNamespace

import numpy as np

from ...kernels.body import N_FIELDS as N_BODY
from ...kernels.driver import FIELDS
from ...kernels.euler_poinsot import free_body
from ...kernels.invariants import INVARIANTS
from ...kernels.reference import dop853, samples_from_states

METRICS = ("orientation", "omega", "energy") + tuple(k for k in INVARIANTS if k != "energy")
# A generic initial attitude (unit quaternion, scalar first): no body axis vertical, so the three
# vectors that rebuild R never coincide.  Free bodies' errors do not depend on it (both attitudes
# are multiplied on the left by it).
Q0 = np.array([0.9, 0.3, -0.2, 0.25]) / np.linalg.norm([0.9, 0.3, -0.2, 0.25])
AXIS, OMEGA, ENERGY = slice(0, 3), slice(3, 6), FIELDS.index("energy")
L_LAB, L3, GAMMA = slice(7, 10), FIELDS.index("L3"), slice(11, 14)


def is_free(body):
    """Whether a body row (kernels/body.py FIELDS) has no weight and no drive."""
    return not any(float(v) for v in tuple(body)[3:])


def reference_samples(body, omega0, q0, times):
    """Reference samples (n, driver.N_FIELDS) of one body at ``times`` (s, uniform from 0): the exact
    free flow for a body without gravity, DOP853 (rtol = atol = 1e-12) otherwise; and its name."""
    body = np.asarray(body, float)
    if is_free(body):
        w, q = free_body(body[:3], np.asarray(omega0, float), np.asarray(q0, float), np.asarray(times, float))
        return samples_from_states(tuple(body), w, rotation_matrices(q)), "exact free flow (Euler–Poinsot)"
    every = float(times[1] - times[0])
    scene = SimpleNamespace(body=tuple(body), omega0=tuple(omega0), q0=tuple(q0))
    return dop853(scene, float(times[-1]), every)[: len(times)], "DOP853 at rtol = atol = 1e-12"


def rotation_matrices(q):
    """R (..., 3, 3) of unit quaternions q (..., 4), scalar first, body → lab."""
    a, b, c, d = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack(
        [
            np.stack([a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)], -1),
            np.stack([2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)], -1),
            np.stack([2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d], -1),
        ],
        -2,
    )


def attitude_from_samples(samples, inertia):
    """R (..., 3, 3) rebuilt from samples (..., N_FIELDS) of a body with moments ``inertia`` (3,):
    the rotation taking e3, γ, Iω/|Iω| (body) onto axis, ẑ, L/|L| (lab), by Kabsch's SVD."""
    s = np.asarray(samples, float)
    m = s[..., OMEGA] * np.asarray(inertia, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        m_hat = m / np.linalg.norm(m, axis=-1, keepdims=True)
        L_hat = s[..., L_LAB] / np.linalg.norm(s[..., L_LAB], axis=-1, keepdims=True)
    e3 = np.broadcast_to([0.0, 0.0, 1.0], s[..., AXIS].shape)
    body = np.stack([e3, s[..., GAMMA], np.nan_to_num(m_hat)], -1)  # columns: body vectors
    lab = np.stack([s[..., AXIS], e3, np.nan_to_num(L_hat)], -1)
    H = lab @ np.swapaxes(body, -1, -2)
    bad = ~np.all(np.isfinite(H), axis=(-2, -1))
    H = np.where(bad[..., None, None], np.eye(3), H)
    U, _, Vt = np.linalg.svd(H)
    D = np.ones(U.shape[:-1])
    D[..., -1] = np.sign(np.linalg.det(U @ Vt))
    R = (U * D[..., None, :]) @ Vt
    R[bad] = np.nan
    return R


def energy_scale(body, omega0):
    """T0 + |M g c| (J): the energy against which energy errors are relative."""
    body = np.asarray(body, float)
    w = np.asarray(omega0, float)
    return 0.5 * float(np.sum(body[:3] * w * w)) + float(np.linalg.norm(body[3:6]))


def kovalevskaya(samples, body):
    """Kovalevskaya's integral K (rad⁴ s⁻⁴) per sample; ν = M g c1 / I3 (kernels/invariants.py)."""
    nu = body[4] / body[2]
    w1, w2 = samples[..., 3], samples[..., 4]
    g1, g2 = samples[..., 11], samples[..., 12]
    return (w1 * w1 - w2 * w2 - nu * g1) ** 2 + (2.0 * w1 * w2 - nu * g2) ** 2


def run_errors(samples, ref, body, omega0, metric):
    """Largest error over the samples (n_runs, n, N_FIELDS) of runs of one body against its reference
    samples (n, N_FIELDS) in ``metric`` (METRICS); inf for a run that blew up (a non-finite sample)."""
    body = np.asarray(body, float)
    s = np.asarray(samples, float)
    L0 = float(np.linalg.norm(body[:3] * np.asarray(omega0, float)))
    if metric == "orientation":
        R, R_ref = attitude_from_samples(s, body[:3]), attitude_from_samples(ref, body[:3])
        # |R − R_ref|_F = 2√2 sin(θ/2): the angle without the cancellation of arccos near 0
        chord = np.linalg.norm(R - R_ref[None], axis=(-2, -1)) / (2 * math.sqrt(2))
        e = 2 * np.arcsin(np.clip(chord, 0.0, 1.0))
    elif metric == "omega":
        e = np.linalg.norm(s[..., OMEGA] - ref[None, :, OMEGA], axis=-1) / np.linalg.norm(omega0)
    elif metric == "energy":
        e = np.abs(s[..., ENERGY] - ref[None, :, ENERGY]) / energy_scale(body, omega0)
    elif metric in ("L", "L_norm"):
        if metric == "L":
            e = np.linalg.norm(s[..., L_LAB] - ref[None, :, L_LAB], axis=-1)
        else:
            e = np.abs(np.linalg.norm(s[..., L_LAB], axis=-1) - np.linalg.norm(ref[:, L_LAB], axis=-1)[None])
        e = e / L0
    elif metric == "Lz":
        e = np.abs(s[..., L_LAB.stop - 1] - ref[None, :, L_LAB.stop - 1]) / L0
    elif metric == "L3":
        e = np.abs(s[..., L3] - ref[None, :, L3]) / L0
    elif metric == "kovalevskaya":
        K_ref = kovalevskaya(ref, body)
        e = np.abs(kovalevskaya(s, body) - K_ref[None]) / max(abs(float(K_ref[0])), 1e-300)
    else:
        raise ValueError(f"metric {metric!r}: choose from {', '.join(METRICS)}")
    e = np.where(np.isfinite(e), e, np.inf)
    return e.max(axis=-1)


def body_row(inertia, mgc=(0.0, 0.0, 0.0)):
    """A body row (kernels/body.py FIELDS) from moments (3,) kg m² and M g c (3,) N m, body frame."""
    row = np.zeros(N_BODY)
    row[:3] = inertia
    row[3], row[4], row[5] = mgc[2], mgc[0], mgc[1]  # (mgl, mgc1, mgc2) = M g (c3, c1, c2)
    return row
