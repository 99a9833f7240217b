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
import re
from functools import lru_cache

import numpy as np

from .errors import InvalidInputError, MissingDependencyError

__all__ = ["typestore", "msg_type", "stamp", "stamp_ns", "nanoseconds", "seconds", "pose_stamped", "pose_from_msg",
           "twist", "twist_from_msg", "twist_stamped", "odometry_pose", "transform_stamped", "tf_message", "line_list",
           "marker_array", "pose_array", "joint_state", "wrench_stamped", "path", "string", "named_type", "named_message"]


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
    """``builtin_interfaces/msg/Time`` of ``t`` s (rounded to the nanosecond; ``t`` >= 0 and finite).

    ``t`` may also be a ``Time`` already (:func:`stamp_ns`'s): it is returned as it is, so a
    stamp given in integer nanoseconds (a ROS clock's, a bag's) reaches a message without a
    round trip through float seconds (which at an epoch time of 1.7e9 s resolves 238 ns)."""
    if _is_time(t):
        return t
    t = float(t)
    if not math.isfinite(t) or t < 0:
        raise InvalidInputError(f"a ROS 2 time stamp must be finite and >= 0 s, got {t!r}")
    ns = round(t * 1e9)
    return msg_type("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_ns(ns: int):
    """``builtin_interfaces/msg/Time`` of ``ns`` integer nanoseconds (>= 0), exactly."""
    ns = int(ns)
    if ns < 0:
        raise InvalidInputError(f"a ROS 2 time stamp must be >= 0 ns, got {ns}")
    return msg_type("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def nanoseconds(time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/msg/Time`` (exact)."""
    return int(time.sec) * 1_000_000_000 + int(time.nanosec)


def _is_time(t) -> bool:
    return hasattr(t, "sec") and hasattr(t, "nanosec")


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


def odometry(t: float, position, quaternion, linear, angular, frame_id: str = "world", child_frame_id: str = ""):
    """``nav_msgs/msg/Odometry`` at ``t`` s: the pose of ``child_frame_id`` in ``frame_id``
    (``position`` (3,) m, ``quaternion`` ``(w, x, y, z)`` (4,)) and its twist in ``child_frame_id``
    (REP-105: ``linear`` m/s, ``angular`` rad/s, each (3,)); covariances zero (unknown)."""
    cov = np.zeros(36)
    return msg_type("nav_msgs/msg/Odometry")(
        header=_header(t, frame_id), child_frame_id=str(child_frame_id),
        pose=msg_type("geometry_msgs/msg/PoseWithCovariance")(pose=_pose(position, quaternion), covariance=cov),
        twist=msg_type("geometry_msgs/msg/TwistWithCovariance")(twist=twist(linear, angular), covariance=cov.copy()))


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


def _vector3(v, what: str):
    v = np.asarray(v, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{what} must be a finite (3,) vector, got {v.tolist()}")
    return msg_type("geometry_msgs/msg/Vector3")(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def transform_stamped(t: float, parent: str, child: str, position, quaternion):
    """``geometry_msgs/msg/TransformStamped``: the pose of frame ``child`` in ``parent`` at ``t`` s
    (``position`` m (3,), ``quaternion`` ``(w, x, y, z)`` (4,), child to parent)."""
    pose = _pose(position, quaternion)
    p = pose.position
    tr = msg_type("geometry_msgs/msg/Transform")(
        translation=msg_type("geometry_msgs/msg/Vector3")(x=p.x, y=p.y, z=p.z), rotation=pose.orientation)
    return msg_type("geometry_msgs/msg/TransformStamped")(header=_header(t, parent), child_frame_id=str(child),
                                                           transform=tr)


def tf_message(transforms):
    """``tf2_msgs/msg/TFMessage`` of a sequence of :func:`transform_stamped`."""
    return msg_type("tf2_msgs/msg/TFMessage")(transforms=list(transforms))


def line_list(t: float, points, *, frame_id: str = "world", ns: str = "", marker_id: int = 0,
              width: float = 0.02, rgba=(0.2, 0.4, 1.0, 1.0)):
    """``visualization_msgs/msg/Marker`` of type ``LINE_LIST``: segments between the points
    ``(2 E, 3)`` (m, in ``frame_id``; points ``2 k`` and ``2 k + 1`` are segment ``k``),
    ``width`` m wide, colour ``rgba`` (each in [0, 1])."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] % 2 or not np.all(np.isfinite(pts)):
        raise InvalidInputError(f"a line list is finite points of shape (2 E, 3), got shape {pts.shape}")
    point = msg_type("geometry_msgs/msg/Point")
    marker = msg_type("visualization_msgs/msg/Marker")
    color = msg_type("std_msgs/msg/ColorRGBA")(**dict(zip("rgba", (float(c) for c in rgba))))
    defaults = {f: _default(f, marker) for f in ("texture_resource", "texture", "uv_coordinates", "mesh_file")
                if f in marker.__dataclass_fields__}
    return marker(header=_header(t, frame_id), ns=str(ns), id=int(marker_id), type=marker.LINE_LIST,
                  action=marker.ADD, pose=_pose([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
                  scale=msg_type("geometry_msgs/msg/Vector3")(x=float(width), y=0.0, z=0.0), color=color,
                  lifetime=msg_type("builtin_interfaces/msg/Duration")(sec=0, nanosec=0), frame_locked=False,
                  points=[point(x=float(a), y=float(b), z=float(c)) for a, b, c in pts], colors=[], text="",
                  mesh_resource="", mesh_use_embedded_materials=False, **defaults)


def _default(field: str, marker):
    """Empty value of the Marker fields newer than ROS 2 Humble's first release (texture, mesh file)."""
    if field == "texture":
        return msg_type("sensor_msgs/msg/CompressedImage")(header=_header(0.0, ""), format="",
                                                          data=np.zeros(0, dtype=np.uint8))
    if field == "mesh_file":
        return msg_type("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, dtype=np.uint8))
    return [] if field == "uv_coordinates" else ""


def marker_array(markers):
    """``visualization_msgs/msg/MarkerArray`` of a sequence of markers."""
    return msg_type("visualization_msgs/msg/MarkerArray")(markers=list(markers))


def pose_array(t: float, positions, quaternions, frame_id: str = "world"):
    """``geometry_msgs/msg/PoseArray`` at ``t`` s: ``positions`` (N, 3) m and ``quaternions`` ``(w, x, y, z)`` (N, 4)."""
    p = np.asarray(positions, dtype=float)
    q = np.asarray(quaternions, dtype=float)
    if p.ndim != 2 or p.shape[1:] != (3,) or q.shape != (p.shape[0], 4):
        raise InvalidInputError(f"a pose array is positions (N, 3) and quaternions (N, 4), got shapes {p.shape} "
                                f"and {q.shape}")
    return msg_type("geometry_msgs/msg/PoseArray")(header=_header(t, frame_id),
                                                   poses=[_pose(a, b) for a, b in zip(p, q)])


def joint_state(t: float, names, position, velocity=None, effort=None, frame_id: str = ""):
    """``sensor_msgs/msg/JointState`` at ``t`` s: joint ``names`` (J,), ``position`` rad (J,),
    ``velocity`` rad/s and ``effort`` N m (J,) each (empty when None)."""
    names = [str(n) for n in names]
    arrays = []
    for what, a in (("position", position), ("velocity", velocity), ("effort", effort)):
        a = np.zeros(0) if a is None else np.asarray(a, dtype=float)
        if a.shape not in ((len(names),), (0,)) or not np.all(np.isfinite(a)):
            raise InvalidInputError(f"joint state {what}: finite ({len(names)},) values for joints {names}, got "
                                    f"shape {a.shape}")
        arrays.append(a)
    return msg_type("sensor_msgs/msg/JointState")(header=_header(t, frame_id), name=names, position=arrays[0],
                                                  velocity=arrays[1], effort=arrays[2])


def wrench_stamped(t: float, force, torque, frame_id: str):
    """``geometry_msgs/msg/WrenchStamped`` at ``t`` s: ``force`` N (3,), ``torque`` N m (3,) in ``frame_id``."""
    wrench = msg_type("geometry_msgs/msg/Wrench")(force=_vector3(force, "a force"), torque=_vector3(torque, "a torque"))
    return msg_type("geometry_msgs/msg/WrenchStamped")(header=_header(t, frame_id), wrench=wrench)


def path(t: float, times, positions, quaternions, frame_id: str = "world"):
    """``nav_msgs/msg/Path`` stamped ``t`` s of the poses at ``times`` (P,) s: ``positions`` (P, 3) m,
    ``quaternions`` ``(w, x, y, z)`` (P, 4)."""
    p = np.asarray(positions, dtype=float)
    q = np.asarray(quaternions, dtype=float)
    times = np.asarray(times, dtype=float)
    if p.shape != (times.size, 3) or q.shape != (times.size, 4):
        raise InvalidInputError(f"a path is times (P,), positions (P, 3) and quaternions (P, 4), got shapes "
                                f"{times.shape}, {p.shape} and {q.shape}")
    return msg_type("nav_msgs/msg/Path")(header=_header(t, frame_id),
                                         poses=[pose_stamped(s, a, b, frame_id) for s, a, b in zip(times, p, q)])


def string(text: str):
    """``std_msgs/msg/String``."""
    return msg_type("std_msgs/msg/String")(data=str(text))


#: A ROS 2 field name (rosidl): a lower-case letter, then lower-case letters, digits and single underscores.
_FIELD = re.compile(r"^[a-z](?:[a-z0-9]|_(?!_))*(?<!_)$")


def named_type(fields) -> tuple:
    """The definition of a message of named numbers, as a ``rosbags`` type-store entry
    ``(constants, fields)`` (``Typestore.register({name: named_type(...)})``): a ``std_msgs/Header``
    and one ``float64`` per name of ``fields`` (each a valid ROS 2 field name: lower case, digits,
    single underscores). Its ``.msg`` text (``std_msgs/Header header``, ``float64 x_c`` ...) is
    what a bag embeds.

    Foxglove and PlotJuggler read the definition from the bag and plot each field by its name
    (``/quatform/cluster.x_c``), which an unnamed ``std_msgs/Float64MultiArray`` cannot offer.
    """
    from rosbags.interfaces import Nodetype

    fields = [str(f) for f in fields]
    bad = [f for f in fields if not _FIELD.match(f) or f == "header"]
    if bad or len(set(fields)) != len(fields):
        raise InvalidInputError(f"named message fields must be distinct ROS 2 field names (lower case, digits, "
                                f"single underscores, not 'header'), got {bad or fields}")
    return [], [("header", (Nodetype.NAME, "std_msgs/msg/Header"))] + [(f, (Nodetype.BASE, ("float64", 0)))
                                                                       for f in fields]


def named_message(cls, t: float, fields, values):
    """A message of the class ``cls`` (registered from :func:`named_type`) at ``t`` s: ``values`` (k,)
    for the ``fields`` (k,)."""
    values = np.asarray(values, dtype=float)
    if values.shape != (len(fields),):
        raise InvalidInputError(f"{len(fields)} fields take {len(fields)} values, got shape {values.shape}")
    return cls(header=_header(t, ""), **{f: float(v) for f, v in zip(fields, values)})
