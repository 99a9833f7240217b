"""Measured poses to a robot model's state, and its commands to twists (ROS 2 bridge layer).

The bridge drives the robots of a scenario's kinematic plant; each robot model has one
:class:`RobotIO` in :data:`ROBOT_IO` (a registry by model class) that says

* how a measured pose (position, orientation ``(w, x, y, z)`` body FLU to world ENU, and for
  the Bebop its body twist) becomes the model's state: the yaw read from the quaternion
  (z-y-x, :func:`quatform.formations.geometry.yaw_of`) and unwound next to the previous one,
  the Pioneer's control point a distance ``a`` ahead of the wheel axis (seed 001 §3.1.1,
  Fig. 10), a free body's unit quaternion on the previous one's side;
* which frame its commands live in (:attr:`RobotIO.natural_frame`): world-frame velocities for
  the 4-DOF, planar and free-body robots (seed 000 §4.1); the Pioneer's ``(v, omega)``
  (seed 001 eq. (3.1)) and the Bebop's command fractions ``(u_x, u_y, u_z, u_psi)`` (eq. (3.6),
  body frame through eq. (3.10); bebop_autonomy's ``cmd_vel``) in the body frame;
* how its command becomes a twist ``(linear (3,), angular (3,))`` in the world frame or its
  body frame (the 4-DOF and planar robots' body frame is their heading frame, eq. (3.8)'s yaw
  rotation: they have no attitude of their own), and whether it has the world velocity and
  yaw rate a PX4 or MAVROS velocity setpoint takes.

:data:`PLANT_ROBOTS` maps a plant class to its robots (models and the slices of the plant
state and command each owns): the kinematic team of the pair and team kinds, the Pioneer and
Bebop of the UGV-UAV kind.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..formations import geometry as g
from ..robots import Bebop, FreeBodyRobot, HolonomicRobot, Pioneer, PlanarHolonomicRobot
from ..sim.plants import KinematicTeam
from ..sim.plants.ugv_uav import PioneerBebopPlant

__all__ = ["PoseSample", "RobotIO", "ROBOT_IO", "PLANT_ROBOTS", "PlantRobots", "robot_io", "plant_robots",
           "heading_rotate"]


@dataclass(frozen=True)
class PoseSample:
    """One measured pose.

    Attributes
    ----------
    t : float
        Its time stamp, s.
    position : ndarray, shape (3,)
        m, world (ENU).
    quaternion : ndarray, shape (4,)
        ``(w, x, y, z)``, body (FLU) to world, unit.
    twist : tuple of two ndarrays (3,) or None
        Body-frame (FLU) linear, m/s, and angular, rad/s, velocity (``nav_msgs/Odometry``'s
        twist is in its ``child_frame_id``, the body, REP-105), or None.
    """

    t: float
    position: np.ndarray
    quaternion: np.ndarray
    twist: tuple | None = None


def heading_rotate(yaw, v, inverse: bool = False) -> np.ndarray:
    """``R_z(yaw) v`` (``inverse``: ``R_z(-yaw) v``, seed 001 eq. (3.8)) of ``(..., 3)`` vectors."""
    yaw = -np.asarray(yaw, dtype=float) if inverse else np.asarray(yaw, dtype=float)
    return g.rotate(g.q_yaw(yaw), np.asarray(v, dtype=float))


def _yaw(pose: PoseSample, previous):
    yaw = g.yaw_of(pose.quaternion)
    return float(yaw if previous is None else g.unwrap_near(yaw, previous))


@dataclass(frozen=True)
class RobotIO:
    """A robot model's measurement and command conversions (see the module docstring).

    Attributes
    ----------
    kind : str
        The model in words (messages, docs).
    natural_frame : str
        ``world`` or ``body``: the frame its commands are in.
    needs_twist : bool
        Its state holds velocities (the Bebop): its pose must come with a twist (odometry).
    setpoint : bool
        Its commands are a world velocity and a yaw rate (a PX4 / MAVROS velocity setpoint).
    state : callable ``(model, PoseSample, previous state or None) -> ndarray (k,)``
    world_twist : callable ``(model, u, state) -> (linear, angular)`` or None
        The command as world-frame velocities (None: it has none); ``u (..., k_u)``,
        ``state (..., k_x)``, results ``(..., 3)``: any number of robots of one model at once.
    body_twist : callable ``(model, u, state, quaternion) -> (linear, angular)``
        The command in the body frame (the same shapes, ``quaternion (..., 4)``).
    """

    kind: str
    natural_frame: str
    state: Callable
    body_twist: Callable
    world_twist: Callable | None = None
    needs_twist: bool = False
    setpoint: bool = False

    def twist(self, model, u, state, quaternion, frame: str):
        """``(linear (..., 3), angular (..., 3))`` of the commands ``u`` in ``frame`` (``world``/``body``)."""
        if frame == "world":
            return self.world_twist(model, u, state)
        return self.body_twist(model, u, state, quaternion)


def _z(w) -> np.ndarray:
    """``(0, 0, w)`` of ``(...)`` values: ``(..., 3)``."""
    w = np.asarray(w, dtype=float)
    return np.stack([np.zeros_like(w), np.zeros_like(w), w], axis=-1)


def _xy(x, y) -> np.ndarray:
    """``(x, y, 0)``: ``(..., 3)``."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return np.stack([x, y, np.zeros_like(x)], axis=-1)


# Command converters take the commands u (..., k_u), the states (..., k_x) and quaternions (..., 4)
# of any number of robots of one model at once.

# -- the 4-DOF robot (seed 000 §4.1): (x, y, z, theta); commands world (v_x, v_y, v_z, omega_z)
def _holonomic_state(model, pose, prev):
    return np.r_[pose.position, _yaw(pose, None if prev is None else prev[3])]


def _holonomic_world(model, u, state):
    return np.asarray(u[..., 0:3], dtype=float), _z(u[..., 3])


def _holonomic_body(model, u, state, q):
    return heading_rotate(state[..., 3], u[..., 0:3], inverse=True), _z(u[..., 3])


# -- the planar holonomic robot: (x, y, theta); commands world (v_x, v_y, omega_z)
def _planar_state(model, pose, prev):
    return np.r_[pose.position[0:2], _yaw(pose, None if prev is None else prev[2])]


def _planar_world(model, u, state):
    return _xy(u[..., 0], u[..., 1]), _z(u[..., 2])


def _planar_body(model, u, state, q):
    return heading_rotate(state[..., 2], _xy(u[..., 0], u[..., 1]), inverse=True), _z(u[..., 2])


# -- the Pioneer 3-DX (seed 001 §3.1.1): the control point (x, y, psi); commands (v, omega), eq. (3.1)
def _pioneer_state(model, pose, prev):
    psi = _yaw(pose, None if prev is None else prev[2])
    # the control point, a ahead of the middle of the wheel axis (the pose's origin), Fig. 10
    return np.array([pose.position[0] + model.a * np.cos(psi), pose.position[1] + model.a * np.sin(psi), psi])


def _pioneer_body(model, u, state, q):
    return _xy(u[..., 0], 0.0), _z(u[..., 1])


# -- the free body: (x, y, z, q_w, q_x, q_y, q_z); commands world (v, w)
def _free_body_state(model, pose, prev):
    q = np.asarray(pose.quaternion, dtype=float)
    q = q / np.linalg.norm(q)
    if prev is not None:
        q = g.closest_sign(q, prev[3:7])  # q and -q are one orientation: stay on the previous side
    return np.r_[pose.position, q]


def _free_body_world(model, u, state):
    return np.asarray(u[..., 0:3], dtype=float), np.asarray(u[..., 3:6], dtype=float)


def _free_body_body(model, u, state, q):
    qc = g.conj(np.asarray(state[..., 3:7], dtype=float))
    return g.rotate(qc, np.asarray(u[..., 0:3], dtype=float)), g.rotate(qc, np.asarray(u[..., 3:6], dtype=float))


# -- the Bebop 2 (seed 001 §3.1.2): (x, y, z, psi, v_x, v_y, z_dot, psi_dot), body (v_x, v_y) by eq. (3.8)
def _bebop_state(model, pose, prev):
    if pose.twist is None:
        raise InvalidInputError("a Bebop's measured state holds its velocity: give it pose_type = 'odometry' "
                                "(nav_msgs/Odometry, e.g. bebop_autonomy's odom) or 'px4'")
    q = np.asarray(pose.quaternion, dtype=float)
    psi = _yaw(pose, None if prev is None else prev[3])
    lin, ang = (np.asarray(a, dtype=float) for a in pose.twist)
    v_world = g.rotate(q, lin)
    v_heading = heading_rotate(psi, v_world, inverse=True)  # eq. (3.8): world to the Bebop frame
    w, x, y, z = q
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    # the z-y-x yaw rate of body rates (p, q, r): (q sin(roll) + r cos(roll)) / cos(pitch)
    # (Beard & McLain 2012, Small Unmanned Aircraft, §3.2); seed 001 §3.1.2 keeps roll and pitch
    # within 5 deg, where it is r to within 0.4 %
    psi_dot = (ang[1] * np.sin(roll) + ang[2] * np.cos(roll)) / np.cos(pitch)
    return np.r_[pose.position, psi, v_heading[0], v_heading[1], v_world[2], psi_dot]


def _bebop_body(model, u, state, q):
    # bebop_autonomy's cmd_vel: linear.x forward, linear.y left, linear.z up, angular.z yaw, fractions of [-1, 1]
    return np.asarray(u[..., 0:3], dtype=float), _z(u[..., 3])


#: The conversions of each robot model class.
ROBOT_IO = {
    HolonomicRobot: RobotIO("4-DOF holonomic robot", "world", _holonomic_state, _holonomic_body, _holonomic_world,
                            setpoint=True),
    PlanarHolonomicRobot: RobotIO("planar holonomic robot", "world", _planar_state, _planar_body, _planar_world,
                                  setpoint=True),
    Pioneer: RobotIO("Pioneer 3-DX (v, omega)", "body", _pioneer_state, _pioneer_body),
    FreeBodyRobot: RobotIO("free body", "world", _free_body_state, _free_body_body, _free_body_world),
    Bebop: RobotIO("Bebop 2 (command fractions)", "body", _bebop_state, _bebop_body, needs_twist=True),
}


def robot_io(model) -> RobotIO:
    """The :class:`RobotIO` of a robot model (its class in :data:`ROBOT_IO`); another is one line."""
    io = ROBOT_IO.get(type(model))
    if io is None:
        raise InvalidInputError(f"the ROS 2 bridge has no conversions for a {type(model).__name__} robot; it drives "
                                f"{', '.join(c.__name__ for c in ROBOT_IO)}")
    return io


@dataclass(frozen=True)
class PlantRobots:
    """A plant's robots: their models and the slices of the plant state and command each owns."""

    models: tuple
    state_slices: tuple
    command_slices: tuple


def _team_robots(plant: KinematicTeam) -> PlantRobots:
    t = plant.team
    return PlantRobots(tuple(t.robots), tuple(t.state_slices), tuple(t.command_slices))


def _ugv_uav_robots(plant: PioneerBebopPlant) -> PlantRobots:
    return PlantRobots((plant.pioneer, plant.bebop), (slice(0, 3), slice(3, 11)), (slice(0, 2), slice(2, 6)))


#: The robots of each plant class the bridge drives (the kinematic plants of the scenario kinds).
PLANT_ROBOTS = {KinematicTeam: _team_robots, PioneerBebopPlant: _ugv_uav_robots}


def plant_robots(plant, where: str) -> PlantRobots:
    """The :class:`PlantRobots` of ``plant`` (``where``: the scenario, for the message)."""
    make = PLANT_ROBOTS.get(type(plant))
    if make is None:
        raise InvalidInputError(f"{where}: the ROS 2 bridge drives the robots of a kinematic plant (pair, team and "
                                f"ugv-uav scenarios); this scenario's plant is a {type(plant).__name__}")
    return make(plant)
