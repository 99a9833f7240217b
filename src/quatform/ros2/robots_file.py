"""The robots file of the ROS 2 bridge: which topics carry each robot's pose and commands.

ROS 2 bridge layer (top, beside :mod:`quatform.runs`). ``robots.toml`` holds an optional
``[bridge]`` table (the world frame, the start timeout, the e-stop topic) and one ``[[robots]]``
table per robot of the scenario, in the scenario's robot order (``docs/ros2.md``)::

    [bridge]
    world_frame = "world"
    start_timeout_s = 5.0
    estop_topic = "/quatform/estop"

    [[robots]]
    name = "cf1"
    namespace = "/cf1"                  # default: "/" + name; "" for none
    pose_topic = "/vrpn_client_node/cf1/pose"
    pose_type = "pose"                  # pose | odometry | px4
    command_topic = "cmd_vel"           # relative: under the namespace
    command_type = "twist-stamped"      # twist | twist-stamped | mavros | px4
    command_frame = "world"             # world | body (default: the robot model's own)
    timeout_s = 0.2

Every key is read strictly with :mod:`quatform.checks` (an unknown key names the nearest
valid one); a topic named twice (two robots on one pose topic, a command topic that is also
a pose topic ...) is one line naming it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..checks import MISSING, check_keys, number, records, table, text
from ..errors import InvalidInputError
from ..tomlio import read_toml

__all__ = ["RobotLink", "BridgeSettings", "RobotsFile", "read_robots_file", "robots_from_dict", "resolve_topic",
           "COMMAND_FRAMES"]

#: ``command_frame`` values: world-frame velocities (ENU), or the robot's own FLU frame.
COMMAND_FRAMES = ("world", "body")

_HINT = "see docs/ros2.md"
_BRIDGE_KEYS = ("world_frame", "start_timeout_s", "estop_topic", "estop_service")
_ROBOT_KEYS = ("name", "namespace", "pose_topic", "pose_type", "command_topic", "command_type", "command_frame",
               "timeout_s", "frame_id")


def resolve_topic(namespace: str, topic: str) -> str:
    """The absolute name of ``topic`` (``/ns/topic`` for a relative one, ``topic`` if absolute)."""
    if topic.startswith("/"):
        return topic
    ns = namespace.rstrip("/")
    return f"{ns}/{topic}" if ns else f"/{topic}"


@dataclass(frozen=True)
class RobotLink:
    """One robot's topics.

    Attributes
    ----------
    name : str
        The robot's name (messages, files, the replay's columns).
    namespace : str
        Prefix of its relative topic names (default ``/<name>``; ``""``: none).
    pose_topic, command_topic : str
        Absolute topic names (:func:`resolve_topic`).
    pose_type : str
        ``pose`` (``geometry_msgs/PoseStamped``, ENU/FLU), ``odometry`` (``nav_msgs/Odometry``:
        pose ENU/FLU, twist in the body frame) or ``px4`` (``px4_msgs/VehicleOdometry``, NED/FRD).
    command_type : str
        ``twist`` (``geometry_msgs/Twist``), ``twist-stamped`` (``TwistStamped``), ``mavros``
        (``TwistStamped`` in the world frame, ENU, for ``/mavros/setpoint_velocity/cmd_vel``) or
        ``px4`` (``px4_msgs/TrajectorySetpoint`` velocity setpoints, NED, and
        ``OffboardControlMode`` on ``<namespace>/fmu/in/offboard_control_mode``).
    command_frame : str or None
        ``world`` or ``body``: the frame of a ``twist``/``twist-stamped`` command's velocities;
        None (left out): the robot model's own (world velocities for the 4-DOF, planar and
        free-body robots; body for the Pioneer's ``(v, omega)`` and the Bebop's fractions);
        ``mavros`` and ``px4`` are ``world``.
    timeout_s : float
        A pose older than this (since it arrived) is stale: every command is zeroed and held.
    frame_id : str
        ``header.frame_id`` of its body-frame commands (default ``<name>/base_link``).
    """

    name: str
    namespace: str
    pose_topic: str
    pose_type: str
    command_topic: str
    command_type: str
    command_frame: str | None
    timeout_s: float
    frame_id: str

    @property
    def offboard_topic(self) -> str:
        """A PX4 robot's ``OffboardControlMode`` topic."""
        return resolve_topic(self.namespace, "fmu/in/offboard_control_mode")


@dataclass(frozen=True)
class BridgeSettings:
    """The ``[bridge]`` table: ``world_frame`` (frame_id of world-frame commands),
    ``start_timeout_s`` (how long the node waits for every robot's first pose),
    ``estop_topic`` (the ``std_msgs/Bool`` e-stop: true engages, false releases) and
    ``estop_service`` (a ``std_srvs/SetBool`` service doing the same)."""

    world_frame: str = "world"
    start_timeout_s: float = 5.0
    estop_topic: str = "/quatform/estop"
    estop_service: str = "/quatform/set_estop"


@dataclass(frozen=True)
class RobotsFile:
    """A read robots file: the bridge settings and the robots in the scenario's order."""

    robots: tuple
    settings: BridgeSettings
    where: str = "robots.toml"

    @property
    def names(self) -> tuple:
        return tuple(r.name for r in self.robots)


def _name_text(d, key, where, default=MISSING):
    v = text(d, key, where, default, place="[[robots]]")
    if not v or any(c.isspace() for c in v):
        raise InvalidInputError(f"{where}: [[robots]] {key} = {v!r} must be a non-empty name without spaces")
    return v


def _topic(d, key, where, namespace, default=MISSING):
    raw = _name_text(d, key, where, default)
    topic = resolve_topic(namespace, raw)
    if "//" in topic or topic.endswith("/"):
        raise InvalidInputError(f"{where}: [[robots]] {key} = {raw!r} gives the topic {topic!r}, not a valid ROS 2 "
                                "name; write it as /a/b or a relative a/b")
    return topic


def robots_from_dict(data: dict, where: str) -> RobotsFile:
    """The :class:`RobotsFile` of parsed TOML ``data`` (``where``: the file, for messages)."""
    check_keys(data, ("bridge", "robots"), where, hint=_HINT)
    b = table(data, "bridge", where, default={})
    check_keys(b, _BRIDGE_KEYS, where, "[bridge]", _HINT)
    settings = BridgeSettings(
        world_frame=text(b, "world_frame", where, "world", place="[bridge]"),
        start_timeout_s=number(b, "start_timeout_s", where, 5.0, place="[bridge]", low=0.0, low_open=True),
        estop_topic=resolve_topic("", text(b, "estop_topic", where, "/quatform/estop", place="[bridge]")),
        estop_service=resolve_topic("", text(b, "estop_service", where, "/quatform/set_estop", place="[bridge]")))
    robots = []
    from .endpoints import COMMAND_WRITERS, POSE_READERS  # the message types: registries

    for r, w in records(data, "robots", _ROBOT_KEYS, where, "robots", _HINT):
        name = _name_text(r, "name", w)
        ns = text(r, "namespace", w, f"/{name}", place="[[robots]]")
        if ns and (not ns.startswith("/") or any(c.isspace() for c in ns)):
            raise InvalidInputError(f"{w}: [[robots]] namespace = {ns!r} must be absolute (start with /) without "
                                    "spaces, or be left out")
        pose_type = text(r, "pose_type", w, "pose", place="[[robots]]", choices=tuple(POSE_READERS))
        command_type = text(r, "command_type", w, "twist-stamped", place="[[robots]]", choices=tuple(COMMAND_WRITERS))
        frame = text(r, "command_frame", w, None, place="[[robots]]", choices=COMMAND_FRAMES)
        if COMMAND_WRITERS[command_type].setpoint and frame not in (None, "world"):
            raise InvalidInputError(f"{w}: [[robots]] command_frame = {frame!r}: {command_type} velocity setpoints "
                                    "are world-frame; leave command_frame out or set it to 'world'")
        robots.append(RobotLink(
            name=name, namespace=ns, pose_topic=_topic(r, "pose_topic", w, ns),
            pose_type=pose_type,
            command_topic=_topic(r, "command_topic", w, ns, COMMAND_WRITERS[command_type].default_topic),
            command_type=command_type, command_frame=frame,
            timeout_s=number(r, "timeout_s", w, 0.5, place="[[robots]]", low=0.0, low_open=True),
            frame_id=text(r, "frame_id", w, f"{name}/base_link", place="[[robots]]")))
    if not robots:
        raise InvalidInputError(f"{where}: no [[robots]] tables; give one per robot of the scenario, in its order "
                                f"({_HINT})")
    _check_unique(robots, settings, where)
    return RobotsFile(tuple(robots), settings, where)


def _check_unique(robots, settings, where) -> None:
    """Refuse a name or topic given twice (one line naming it and both users)."""
    seen: dict[str, str] = {}
    for r in robots:
        if r.name in [x.name for x in robots[:robots.index(r)]]:
            raise InvalidInputError(f"{where}: two [[robots]] are named {r.name!r}; give each robot its own name")
    uses = [(settings.estop_topic, "[bridge] estop_topic")]
    for r in robots:
        uses.append((r.pose_topic, f"robot {r.name!r} pose_topic"))
        uses.append((r.command_topic, f"robot {r.name!r} command_topic"))
        if r.command_type == "px4":
            uses.append((r.offboard_topic, f"robot {r.name!r} offboard_control_mode (px4)"))
    for topic, user in uses:
        if topic in seen:
            raise InvalidInputError(f"{where}: the topic {topic} is named twice ({seen[topic]} and {user}); give "
                                    "each robot its own pose and command topics")
        seen[topic] = user


def read_robots_file(path) -> RobotsFile:
    """Read ``robots.toml`` at ``path`` (strictly; one line for any bad key or value)."""
    data, p = read_toml(path, {}, "robots")
    return robots_from_dict(data, str(p))
