"""ROS 2 messages of quatform's poses, commands and times (I/O layer, beside the report).

The one conversion between quatform's arrays and the standard ROS 2 messages, shared by the
MCAP writer and reader (:mod:`quatform.bags`) and the ROS 2 bridge (:mod:`quatform.ros2`).
Messages are ``rosbags`` classes (pure Python; the ROS 2 Humble type store), so they
serialise to CDR without ROS installed and are the same types ``rclpy`` publishes.

Conventions (REP-103 and ``docs/conventions.md``): the world frame is ENU, a robot's body frame
FLU; quatform's quaternions are ``(w, x, y, z)`` and a ROS ``geometry_msgs/Quaternion`` is
``(x, y, z, w)`` by field name: :func:`pose_stamped` and :func:`pose_from_msg` do that
reordering and nothing else. Times are scenario seconds as ``builtin_interfaces/Time``
(``sec``, ``nanosec``), rounded to the nanosecond.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .errors import InvalidInputError, MissingDependencyError

__all__ = ["typestore", "msg_type", "stamp", "seconds", "pose_stamped", "pose_from_msg", "twist",
           "twist_from_msg", "twist_stamped", "odometry_pose"]


@lru_cache(maxsize=1)
def typestore():
    """The ROS 2 Humble type store of ``rosbags`` (its message classes and CDR serialiser)."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:  # pragma: no cover - rosbags is a core dependency
        raise MissingDependencyError('ROS 2 messages need rosbags: pip install -e .') from None
    return get_typestore(Stores.ROS2_HUMBLE)


def msg_type(name: str):
    """The message class ``name`` (``geometry_msgs/msg/PoseStamped``); an unknown name is one line."""
    types = typestore().types
    if name not in types:
        from .checks import nearest

        raise InvalidInputError(f"unknown ROS 2 message type {name!r}{nearest(name, types)}")
    return types[name]


def stamp(t: float):
    """``builtin_interfaces/msg/Time`` of ``t`` s (rounded to the nanosecond; ``t`` >= 0 and finite)."""
    t = float(t)
    if not math.isfinite(t) or t < 0:
        raise InvalidInputError(f"a ROS 2 time stamp must be finite and >= 0 s, got {t!r}")
    ns = round(t * 1e9)
    return msg_type("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def seconds(time) -> float:
    """Seconds of a ``builtin_interfaces/msg/Time``."""
    return time.sec + time.nanosec * 1e-9


def _header(t: float, frame_id: str):
    return msg_type("std_msgs/msg/Header")(stamp=stamp(t), frame_id=str(frame_id))


def _pose(position, quaternion):
    p = np.asarray(position, dtype=float)
    q = np.asarray(quaternion, dtype=float)
    if p.shape != (3,) or q.shape != (4,):
        raise InvalidInputError(f"a pose is a position (3,) and a quaternion (w, x, y, z) (4,), got shapes "
                                f"{p.shape} and {q.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise InvalidInputError(f"a pose must be finite, got position {p.tolist()} and quaternion {q.tolist()}")
    point = msg_type("geometry_msgs/msg/Point")(x=float(p[0]), y=float(p[1]), z=float(p[2]))
    quat = msg_type("geometry_msgs/msg/Quaternion")(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0]))
    return msg_type("geometry_msgs/msg/Pose")(position=point, orientation=quat)


def pose_stamped(t: float, position, quaternion, frame_id: str = "world"):
    """``geometry_msgs/msg/PoseStamped`` at ``t`` s.

    Parameters
    ----------
    t : float
        Time stamp, s.
    position : array_like, shape (3,)
        m, in ``frame_id`` (ENU).
    quaternion : array_like, shape (4,)
        ``(w, x, y, z)``, body (FLU) to ``frame_id``.
    frame_id : str
    """
    return msg_type("geometry_msgs/msg/PoseStamped")(header=_header(t, frame_id), pose=_pose(position, quaternion))


def _pose_arrays(pose):
    p = pose.position
    q = pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.w, q.x, q.y, q.z])


def pose_from_msg(msg):
    """``(t, position (3,), quaternion (w, x, y, z) (4,), frame_id)`` of a ``PoseStamped``."""
    p, q = _pose_arrays(msg.pose)
    return seconds(msg.header.stamp), p, q, msg.header.frame_id


def odometry_pose(msg):
    """``(t, position, quaternion (w, x, y, z), frame_id)`` of a ``nav_msgs/msg/Odometry``'s pose."""
    p, q = _pose_arrays(msg.pose.pose)
    return seconds(msg.header.stamp), p, q, msg.header.frame_id


def twist(linear, angular):
    """``geometry_msgs/msg/Twist``: ``linear`` m/s and ``angular`` rad/s, each (3,)."""
    v = np.asarray(linear, dtype=float)
    w = np.asarray(angular, dtype=float)
    if v.shape != (3,) or w.shape != (3,) or not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        raise InvalidInputError(f"a twist is finite linear (3,) and angular (3,) velocities, got "
                                f"{v.tolist()} and {w.tolist()}")
    vec = msg_type("geometry_msgs/msg/Vector3")
    return msg_type("geometry_msgs/msg/Twist")(linear=vec(x=float(v[0]), y=float(v[1]), z=float(v[2])),
                                               angular=vec(x=float(w[0]), y=float(w[1]), z=float(w[2])))


def twist_stamped(t: float, linear, angular, frame_id: str = "world"):
    """``geometry_msgs/msg/TwistStamped`` at ``t`` s."""
    return msg_type("geometry_msgs/msg/TwistStamped")(header=_header(t, frame_id), twist=twist(linear, angular))


def twist_from_msg(msg):
    """``(linear (3,), angular (3,))`` of a ``Twist`` (or the twist of a ``TwistStamped``)."""
    tw = getattr(msg, "twist", msg)
    return (np.array([tw.linear.x, tw.linear.y, tw.linear.z]),
            np.array([tw.angular.x, tw.angular.y, tw.angular.z]))
