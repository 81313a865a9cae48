"""PyBullet itself (``pip install pybullet``): each run one body in a DIRECT client, ``stepSimulation``.

PyBullet exposes no switch for Bullet's gyroscopic modes (btRigidBody's
BT_ENABLE_GYROSCOPIC_FORCE_* flags appear nowhere in its API:
bulletphysics/bullet3 at 6c888f4abd7b, examples/SharedMemory/
PhysicsServerCommandProcessor.cpp); what decides the update is the body type
``createMultiBody`` builds, so there is one name per type:

- ``real_pybullet`` (``mode="multibody"``, PyBullet's default,
  useMaximalCoordinates=0): a Featherstone btMultiBody.  Its articulated-body
  algorithm adds ω × Iω explicitly (``m_useGyroTerm`` true) with the angular
  damping torque −I ω (k + k |ω|), k = m_angularDamping = 0.04 as shipped
  (src/BulletDynamics/Featherstone/btMultiBody.cpp: constructor and
  ``computeAccelerationsArticulatedBodyAlgorithmMultiDof``), every
  velocity component (the base's ω in lab components) clamped to
  m_maxCoordinateVelocity = 100 rad/s (btMultiBody.h
  ``applyDeltaVeeMultiDof``; measured: a body spun at 150 rad/s leaves the
  first step at 100, tests/test_real_engines.py),
  the quaternion by ``stepPositionsMultiDof``'s exponential map capped at
  π/4 rad per step.  Heavy body: a fixed base and one link on a spherical
  joint at the pivot (joint state: q and the body-frame ω), the joint's
  default motor (PyBullet gives every spherical joint one that holds it
  still) switched off with force 0, as PyBullet's guide says; the centre of
  mass on a principal axis of the pivot inertia (a rotated inertial frame is
  not built).
- ``real_pybullet_maximal`` (``mode="maximal"``, useMaximalCoordinates=1): a
  btRigidBody, whose constructor sets BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY
  (kernels/methods/bullet_implicit_body reproduces it), damping 0; PyBullet sets
  sleeping thresholds 0.2236 (rad/s, m/s: MyMultiBodyCreator.cpp), reached by
  no spinning body here.  Free bodies only (a pivot would be a point-to-point
  constraint solved by impulses: not built).

The body has no collision shape; its mass (1 kg for a free body) and principal
moments are set by ``changeDynamics``.  Defaults are kept as shipped (not
readable through PyBullet's API; values from the source above).  Bullet stores
the base's angular velocity in the lab frame: ω_body = Rᵀ ω_lab.
"""

import numpy as np

GRAVITY = 9.81  # m/s², the heavy body's g in the engine (only M g c enters the motion)


def quat_matrix(q):
    """R (3, 3) of a unit quaternion q = (a, b, c, d), scalar first, body → lab."""
    a, b, c, d = q
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - b * b - c * c],
        ]
    )


def to_bullet(q):
    """Bullet's (x, y, z, w) of gyrolab's (a, b, c, d)."""
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


def from_bullet(xyzw):
    return np.array([xyzw[3], xyzw[0], xyzw[1], xyzw[2]])


def is_free(body):
    return body.mgl == 0.0 and body.mgc1 == 0.0 and body.mgc2 == 0.0


class Backend:
    """PyBullet with one body type (``mode``: "multibody", PyBullet's default, or "maximal")."""

    PACKAGE = "pybullet"
    BLOCKS = False  # never the numba block path (kernels/entry.py uses_blocks)

    def __init__(self, name, mode):
        import pybullet

        self.name, self.mode, self.pb = name, mode, pybullet
        self.DEFAULTS = (
            "btMultiBody: explicit gyroscopic term, angular damping 0.04 (k + k|w|), |w_i| <= 100 rad/s clamp"
            if mode == "multibody"
            else "btRigidBody: implicit body-frame gyroscopic impulse, damping 0"
        )

    def check(self, body):
        """ValueError (one line) when this backend does not build ``body`` (kernels.body.Body)."""
        if is_free(body):
            return
        if self.mode == "maximal":
            raise ValueError(
                f"method {self.name!r} runs free bodies only (a pivot needs a point-to-point constraint: "
                "not built); use real_pybullet for a heavy body"
            )
        from .mujoco_engine import heavy_mass_and_com

        _, com, about_com = heavy_mass_and_com(body, GRAVITY)
        moments = np.diag(about_com)
        if np.abs(about_com - np.diag(moments)).max() > 1e-12 * moments.max():
            # a rotated inertial frame reaches the multibody's joint frame, which this backend does not model
            raise ValueError(
                f"method {self.name!r} runs a heavy body whose centre of mass lies on a principal axis "
                f"(its inertia about the centre of mass diagonal in the body frame); c = {tuple(com)} m is not"
            )

    def start(self, body, w0, q0, dt, angular_damping=None):
        """A run of ``body`` from ω0 (body, rad/s) and q0 (scalar first) with step dt (s).
        ``angular_damping`` replaces the shipped damping (conformance runs only; None: as shipped)."""
        self.check(body)
        return _Run(self.pb, self.mode, body, np.asarray(w0, float), np.asarray(q0, float), dt, angular_damping)


class _Run:
    def __init__(self, pb, mode, body, w0, q0, dt, angular_damping):
        self.pb = pb
        self.client = c = pb.connect(pb.DIRECT)
        self.free = is_free(body)
        pb.setTimeStep(dt, physicsClientId=c)
        inertia = [float(x) for x in body[:3]]
        if self.free:
            pb.setGravity(0, 0, 0, physicsClientId=c)
            self.id = pb.createMultiBody(
                baseMass=1.0, baseCollisionShapeIndex=-1, useMaximalCoordinates=mode == "maximal", physicsClientId=c
            )
            pb.changeDynamics(self.id, -1, mass=1.0, localInertiaDiagonal=inertia, physicsClientId=c)
            if angular_damping is not None:
                pb.changeDynamics(self.id, -1, angularDamping=float(angular_damping), physicsClientId=c)
            pb.resetBasePositionAndOrientation(self.id, [0, 0, 0], to_bullet(q0), physicsClientId=c)
            pb.resetBaseVelocity(self.id, [0, 0, 0], list(quat_matrix(q0) @ w0), physicsClientId=c)
        else:
            from .mujoco_engine import heavy_mass_and_com

            mass, com, about_com = heavy_mass_and_com(body, GRAVITY)
            moments = np.diag(about_com)  # diagonal: Backend.check
            pb.setGravity(0, 0, -GRAVITY, physicsClientId=c)
            self.id = pb.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=-1,
                linkMasses=[mass],
                linkCollisionShapeIndices=[-1],
                linkVisualShapeIndices=[-1],
                linkPositions=[[0, 0, 0]],
                linkOrientations=[[0, 0, 0, 1]],
                linkInertialFramePositions=[list(map(float, com))],
                linkInertialFrameOrientations=[[0, 0, 0, 1]],
                linkParentIndices=[0],
                linkJointTypes=[pb.JOINT_SPHERICAL],
                linkJointAxis=[[0, 0, 1]],
                physicsClientId=c,
            )
            pb.changeDynamics(
                self.id, 0, mass=mass, localInertiaDiagonal=[float(x) for x in moments], physicsClientId=c
            )
            if angular_damping is not None:
                pb.changeDynamics(self.id, 0, angularDamping=float(angular_damping), physicsClientId=c)
            # PyBullet gives every spherical joint a motor (btMultiBodySphericalJointMotor, impulse up to 1000:
            # PhysicsServerCommandProcessor.cpp createJointMotors) that holds the joint still; a pivot is no
            # motor, so it is switched off the way PyBullet's docs say (force 0).
            pb.setJointMotorControlMultiDof(
                self.id,
                0,
                pb.POSITION_CONTROL,
                targetPosition=[0, 0, 0, 1],
                positionGain=0,
                velocityGain=0,
                force=[0, 0, 0],
                physicsClientId=c,
            )
            pb.resetJointStateMultiDof(
                self.id, 0, targetValue=to_bullet(q0), targetVelocity=list(map(float, w0)), physicsClientId=c
            )

    def advance(self, n):
        """n calls of stepSimulation: (n, ω body (rad/s), q scalar first)."""
        pb, c = self.pb, self.client
        for _ in range(n):
            pb.stepSimulation(physicsClientId=c)
        if self.free:
            _, xyzw = pb.getBasePositionAndOrientation(self.id, physicsClientId=c)
            q = from_bullet(xyzw)
            _, w_lab = pb.getBaseVelocity(self.id, physicsClientId=c)
            return n, quat_matrix(q).T @ np.asarray(w_lab), q
        position, velocity, _, _ = pb.getJointStateMultiDof(self.id, 0, physicsClientId=c)
        return n, np.asarray(velocity, float), from_bullet(position)

    def close(self):
        if self.client is not None:
            self.pb.disconnect(physicsClientId=self.client)
            self.client = None
