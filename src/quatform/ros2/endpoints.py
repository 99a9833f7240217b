"""The message types the ROS 2 bridge reads poses from and writes commands to (ROS 2 bridge layer).

:data:`POSE_READERS` (a robots file's ``pose_type``) and :data:`COMMAND_WRITERS`
(``command_type``) are registries: each reader turns one message into a
:class:`~quatform.ros2.robot_io.PoseSample` (REP-103: ENU world, FLU body), each writer turns a
robot's twist into the messages it publishes, topic by topic. Messages are ``rosbags`` classes
(:mod:`quatform.messages`); the node converts them to the ROS installation's own classes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import messages
from ..errors import InvalidInputError
from ..registry import Registry
from . import px4
from .robot_io import PoseSample

__all__ = ["PoseReader", "CommandWriter", "POSE_READERS", "COMMAND_WRITERS", "pose_sample"]

#: How far a measured quaternion's norm may be from 1 before the pose is refused (a mocap
#: driver sends unit quaternions in float32 or float64; renormalised within this).
UNIT_SLACK = 1e-3


def _header_ns(msg) -> int:
    return messages.nanoseconds(msg.header.stamp)


def _px4_ns(msg) -> int:
    return int(msg.timestamp) * 1000  # PX4's timestamp is integer microseconds


@dataclass(frozen=True)
class PoseReader:
    """``msg_type`` (the ROS 2 type name), ``read(msg) -> (t, position, quaternion, twist)`` and
    ``stamp_ns(msg) -> int`` (the message's time in integer nanoseconds, exactly: a bag's
    epoch stamps keep every nanosecond, which ``t`` in float seconds does not)."""

    msg_type: str
    read: Callable
    qos: str = "sensor"
    stamp_ns: Callable = _header_ns


def _pose(msg):
    t, p, q, _ = messages.pose_from_msg(msg)
    return t, p, q, None


def _odometry(msg):
    t, p, q, _ = messages.odometry_pose(msg)
    return t, p, q, messages.twist_from_msg(msg.twist)


#: Pose message types by ``pose_type`` (``POSE_READERS.add(name, PoseReader(...))`` beside a reader).
POSE_READERS = Registry("pose type")
POSE_READERS.add("pose", PoseReader("geometry_msgs/msg/PoseStamped", _pose))
POSE_READERS.add("odometry", PoseReader("nav_msgs/msg/Odometry", _odometry))
POSE_READERS.add("px4", PoseReader("px4_msgs/msg/VehicleOdometry", px4.vehicle_odometry_pose, qos="px4",
                                   stamp_ns=_px4_ns))


def pose_sample(pose_type: str, msg) -> PoseSample | None:
    """The :class:`PoseSample` of a pose message, or None for a lost frame (a NaN, or a
    quaternion whose norm is not 1 to :data:`UNIT_SLACK`): a lost frame never reaches a command."""
    t, p, q, twist = POSE_READERS[pose_type].read(msg)
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    with np.errstate(over="ignore"):  # a damaged entry (1e200): an infinite norm, a lost frame, no warning
        n = float(np.linalg.norm(q))
    if not (np.all(np.isfinite(p)) and np.isfinite(n) and abs(n - 1.0) <= UNIT_SLACK):
        return None
    if twist is not None:
        twist = tuple(np.asarray(a, dtype=float) for a in twist)
        if not all(np.all(np.isfinite(a)) for a in twist):
            return None
    return PoseSample(float(t), p, q / n, twist)


@dataclass(frozen=True)
class CommandWriter:
    """How a robot's twist is published.

    Attributes
    ----------
    topics : callable ``link -> ((topic, msg_type, qos), ...)``
    build : callable ``(link, t, linear, angular, world_frame, frame) -> ((topic, msg), ...)``
    setpoint : bool
        It takes a world velocity and a yaw rate only (PX4, MAVROS).
    default_topic : str
        The command topic of a robot whose robots file names none (relative: under its namespace).
    """

    topics: Callable
    build: Callable
    setpoint: bool = False
    default_topic: str = "cmd_vel"


def _frame_id(link, world_frame, frame):
    return world_frame if frame == "world" else link.frame_id


def _twist_build(link, t, lin, ang, world_frame, frame):
    return ((link.command_topic, messages.twist(lin, ang)),)


def _twist_stamped_build(link, t, lin, ang, world_frame, frame):
    return ((link.command_topic, messages.twist_stamped(t, lin, ang, _frame_id(link, world_frame, frame))),)


def _px4_topics(link):
    return ((link.offboard_topic, "px4_msgs/msg/OffboardControlMode", "px4"),
            (link.command_topic, "px4_msgs/msg/TrajectorySetpoint", "px4"))


def _px4_build(link, t, lin, ang, world_frame, frame):
    if abs(ang[0]) > 0 or abs(ang[1]) > 0:
        raise InvalidInputError(f"robot {link.name!r}: a PX4 velocity setpoint has a yaw rate only; its command "
                                f"asks for roll/pitch rates {ang[:2].tolist()}")
    return ((link.offboard_topic, px4.offboard_control_mode(t)),
            (link.command_topic, px4.trajectory_setpoint(t, lin, float(ang[2]))))


#: Command message types by ``command_type`` (``COMMAND_WRITERS.add(name, CommandWriter(...))``
#: beside a writer).
COMMAND_WRITERS = Registry("command type")
COMMAND_WRITERS.add("twist", CommandWriter(lambda link: ((link.command_topic, "geometry_msgs/msg/Twist", "default"),),
                                           _twist_build))
COMMAND_WRITERS.add("twist-stamped", CommandWriter(
    lambda link: ((link.command_topic, "geometry_msgs/msg/TwistStamped", "default"),), _twist_stamped_build))
# MAVROS setpoint_velocity/cmd_vel: a TwistStamped in the local ENU frame (MAVROS converts to NED)
COMMAND_WRITERS.add("mavros", CommandWriter(
    lambda link: ((link.command_topic, "geometry_msgs/msg/TwistStamped", "default"),), _twist_stamped_build,
    setpoint=True, default_topic="mavros/setpoint_velocity/cmd_vel"))
COMMAND_WRITERS.add("px4", CommandWriter(_px4_topics, _px4_build, setpoint=True,
                                         default_topic="fmu/in/trajectory_setpoint"))
