"""The two arms of seed 003's teleoperator as robot models (robots layer).

Robots layer: the kinematics and inertias of :mod:`quatform.teleop` (the Kraft master of
Fig. 1, the 7-DOF Panda slave with its mass matrix) with their own motion under joint
torques, for :mod:`quatform.sim.plants.teleop`. Each is a
:class:`~quatform.robots.model.RobotModel`:

* ``point_kind`` ``"pose"``: the tool pose, position (m) and unit quaternion ``(w, x, y, z)``
  in the arm's base frame, ``(..., 7)``;
* state ``(q, qd)`` (rad, rad/s); commands the joint torques (N m);
* ``step(x, u, dt)``: one semi-implicit Euler step under the net torque ``u`` (the
  actuators' plus whatever the environment applies through the Jacobian): the master's
  joints are decoupled constant inertias with viscous friction and the static and Coulomb
  friction that makes each actuated joint need a share of full scale to move (seed 003 §6's
  "dead region"); the slave's motion is ``M(q) qdd = u - C(q, qd) qd - damping qd``. Both
  arms are gravity compensated (``tau_grav`` of seed 003 (11)-(12)), so gravity is left out.

The arms are torque-commanded by :class:`~quatform.teleop.TeleopController`, which maps a
task-space error to torques itself (eqs. (14a)/(14b)); a point *rate* does not determine a
torque, so :meth:`KraftMaster.actuate` / :meth:`PandaSlave.actuate` refuse (see
``docs/derivations.md``, "Teleoperation runs (seed 003)").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace
from ..errors import InvalidInputError
from ..teleop.arm import SerialArm
from ..teleop.kraft import KRAFT_DEADBAND, KRAFT_FULL_SCALE, KRAFT_MASTER
from ..teleop.slave import PANDA_SLAVE, PANDA_TORQUE_LIMITS, RigidArm
from .model import RobotModel

__all__ = ["KraftMaster", "PandaSlave", "friction_step"]


def _joint_columns(prefix: str, n: int) -> tuple:
    return tuple(f"q_{prefix}{i + 1}" for i in range(n)) + tuple(f"qd_{prefix}{i + 1}" for i in range(n))


def _joint_units(columns) -> dict:
    """Units of an arm's columns: joint angles rad, joint rates rad/s, torques N m."""
    return {c: "rad/s" if c.startswith("qd_") else "rad" if c.startswith("q_") else "N m" for c in columns}


def _pose(arm: SerialArm, q) -> np.ndarray:
    p, r = arm.forward(q)
    return np.concatenate([p, r], axis=-1)


def _saturate(u, limits) -> np.ndarray:
    u = np.asarray(u, dtype=float)
    u = np.where(np.isfinite(u), u, 0.0)
    return np.minimum(np.maximum(u, -limits), limits)


def _no_rate_map(name: str):
    raise InvalidInputError(f"{name} is torque-commanded: a tool-pose rate does not determine its joint torques; "
                            "drive it with quatform.teleop.TeleopController (seed 003 eqs. (14a)/(14b))")


def friction_step(qd, inertia, tau, static, dt) -> np.ndarray:
    """Joint velocities after ``dt`` s of net torque ``tau`` with static and Coulomb friction.

    Per joint: at rest it stays at rest while ``|tau| <= static``; moving, it feels
    ``-static sign(qd)`` (seed 003 §6's dead region), and friction alone never reverses its
    velocity within a step. ``qd``, ``tau`` ``(..., n)``; ``inertia``, ``static`` ``(n,)``.
    Selections only (no branch on the values), so it runs on NumPy and JAX arrays alike.
    """
    xp = array_namespace(qd)
    if xp is np:
        qd, tau = np.asarray(qd, dtype=float), np.asarray(tau, dtype=float)
    qd_new = qd + dt * tau / inertia
    if not np.any(static > 0):
        return qd_new
    stuck = (qd == 0.0) & (xp.abs(tau) <= static)
    direction = xp.where(qd != 0.0, xp.copysign(1.0, qd), xp.copysign(1.0, tau))
    v = qd + dt * (tau - static * direction) / inertia
    v = xp.where(v * direction < 0, 0.0, v)  # friction stops the joint within this step
    return xp.where(static > 0, xp.where(stuck, 0.0, v), qd_new)


@dataclass(frozen=True)
class KraftMaster(RobotModel):
    """The Kraft master as a robot model (see the module docstring).

    Parameters
    ----------
    inertia : tuple of float, shape (6,)
        Joint inertias, kg m^2 (a light, counterbalanced desk arm: decoupled, constant).
    viscous : float
        Viscous friction of every joint, N m s/rad.
    deadband : tuple of float, shape (6,)
        Static and Coulomb friction as a fraction of each joint's full-scale torque.
    arm : SerialArm
    full_scale : tuple of float
        Actuator torque limits, N m (0: joint 6 has no actuator).
    """

    inertia: tuple = (0.02, 0.02, 0.015, 0.004, 0.004, 0.002)
    viscous: float = 0.05
    deadband: tuple = KRAFT_DEADBAND
    arm: SerialArm = KRAFT_MASTER
    full_scale: tuple = KRAFT_FULL_SCALE

    name = "kraft-master"
    point_kind = "pose"
    #: Torque-commanded: its commands are not its point's rates and do not scale together.
    passthrough = False
    holonomic = False

    @property
    def state_columns(self) -> tuple:
        return _joint_columns("m", self.arm.n)

    @property
    def command_columns(self) -> tuple:
        return tuple(f"tau_m{i + 1}" for i in range(self.arm.n))

    @property
    def column_units(self) -> dict:
        """The unit of each state and command column (rad, rad/s, N m)."""
        return _joint_units((*self.state_columns, *self.command_columns))

    @property
    def static_friction(self) -> np.ndarray:
        """Each joint's static and Coulomb friction torque, N m (``deadband * full_scale``)."""
        return np.asarray(self.deadband, float) * np.asarray(self.full_scale)

    def point(self, x) -> np.ndarray:
        """Tool position and orientation ``(..., 7)`` of the state ``x = (q, qd)``."""
        return _pose(self.arm, np.asarray(x, float)[..., :self.arm.n])

    def actuate(self, x, rate, t, memory):
        _no_rate_map(self.name)

    def saturate(self, u) -> np.ndarray:
        return _saturate(u, np.asarray(self.full_scale, float))

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` s of the net joint torque ``u`` (actuators + hand): the viscous
        and dead-region friction, then ``q += dt qd`` (semi-implicit Euler)."""
        n = self.arm.n
        q, qd = x[..., :n], x[..., n:]
        qd = friction_step(qd, np.asarray(self.inertia, float), u - self.viscous * qd, self.static_friction, dt)
        return array_namespace(qd).concatenate([q + dt * qd, qd], axis=-1)


@dataclass(frozen=True)
class PandaSlave(RobotModel):
    """The 7-DOF slave as a robot model (see the module docstring).

    Parameters
    ----------
    damping : float
        Joint damping, N m s/rad.
    arm : RigidArm
        Kinematics and mass matrix.
    torque_limits : tuple of float, shape (7,)
        N m.
    """

    damping: float = 2.0
    arm: RigidArm = PANDA_SLAVE
    torque_limits: tuple = PANDA_TORQUE_LIMITS

    name = "panda-slave"
    point_kind = "pose"
    #: Torque-commanded: its commands are not its point's rates and do not scale together.
    passthrough = False
    holonomic = False

    @property
    def state_columns(self) -> tuple:
        return _joint_columns("s", self.arm.arm.n)

    @property
    def command_columns(self) -> tuple:
        return tuple(f"tau_s{i + 1}" for i in range(self.arm.arm.n))

    @property
    def column_units(self) -> dict:
        """The unit of each state and command column (rad, rad/s, N m)."""
        return _joint_units((*self.state_columns, *self.command_columns))

    def point(self, x) -> np.ndarray:
        """Tool position and orientation ``(..., 7)`` of the state ``x = (q, qd)``."""
        return _pose(self.arm.arm, np.asarray(x, float)[..., :self.arm.arm.n])

    def actuate(self, x, rate, t, memory):
        _no_rate_map(self.name)

    def saturate(self, u) -> np.ndarray:
        return _saturate(u, np.asarray(self.torque_limits, float))

    def step(self, x, u, dt: float, M=None) -> np.ndarray:
        """State after ``dt`` s of the net joint torque ``u`` (actuators + environment):
        ``qd += dt M^-1 (u - damping qd - C qd)``, then ``q += dt qd`` (one configuration;
        ``M``: the mass matrix at ``q`` if already computed)."""
        xp = array_namespace(x)
        n = self.arm.arm.n
        q, qd = x[:n], x[n:]
        M = self.arm.mass_matrix(q) if M is None else M
        coriolis = self.arm.coriolis(q, qd, M)
        qd = qd + dt * xp.linalg.solve(M, u - self.damping * qd - coriolis)
        return xp.concatenate([q + dt * qd, qd])
