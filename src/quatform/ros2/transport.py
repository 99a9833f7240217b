"""What a ROS 2 node of the bridge needs from its middleware: the transport interface (ROS 2 bridge layer).

:class:`~quatform.ros2.node.BridgeNode` and :class:`~quatform.ros2.local_node.LocalNode` hold
the node logic (subscriptions, the control timer, the e-stop, the zero command on exit) once;
a :class:`Transport` carries it on a middleware:

* :class:`~quatform.ros2.rclpy_transport.RclpyTransport` - rclpy, on a sourced ROS 2
  installation (any RMW);
* :class:`~quatform.ros2.dds.DdsTransport` - Cyclone DDS's Python binding speaking ROS 2's
  topics on the wire (RTPS), no ROS installation (``pip install -e ".[dds]"``).

Messages handed to and from a transport are ``rosbags`` classes (:mod:`quatform.messages`),
type names ROS 2's (``geometry_msgs/msg/Twist``), topic names absolute ROS 2 names
(``/r1/cmd_vel``), QoS one of the names of :data:`QOS`.
"""

from __future__ import annotations

import os
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import InvalidInputError

__all__ = ["QosProfile", "QOS", "Transport", "TRANSPORTS", "ros_domain_id"]


@dataclass(frozen=True)
class QosProfile:
    """A QoS: ``reliable`` (else best effort), ``transient_local`` (else volatile), keep last
    ``depth`` samples, or with ``keep_all`` every sample not yet taken (``depth`` then unused)."""

    reliable: bool
    transient_local: bool
    depth: int
    keep_all: bool = False


#: ROS 2's profiles by the names the endpoints give (:mod:`quatform.ros2.endpoints`):
#: ``sensor`` rmw_qos_profile_sensor_data (best effort, volatile, 5), ``default``
#: rmw_qos_profile_default (reliable, volatile, 10: commands), ``px4`` px4_ros_com's offboard
#: profile (best effort, transient local, 1), ``latched`` a latched topic such as ``/tf_static``
#: (reliable, transient local, 1), ``estop`` the node's reader of the latched e-stop (reliable,
#: transient local: a node started later still sees an e-stop published before it; keep all,
#: so an engage followed by a release before the node reads them is read, engage first),
#: ``clock`` rclcpp's ClockQoS (best effort, volatile, 1: ``/clock``), ``service``
#: rmw_qos_profile_services_default (reliable, volatile, 10: a service's requests and replies).
QOS = {
    "sensor": QosProfile(False, False, 5),
    "default": QosProfile(True, False, 10),
    "px4": QosProfile(False, True, 1),
    "latched": QosProfile(True, True, 1),
    "estop": QosProfile(True, True, 1, keep_all=True),
    "clock": QosProfile(False, False, 1),
    "service": QosProfile(True, False, 10),
}

#: The ``--transport`` names of the middlewares, in order of preference (``auto`` takes the
#: first importable one).
TRANSPORTS = ("rclpy", "dds")


def ros_domain_id(environ=os.environ) -> int:
    """``ROS_DOMAIN_ID`` (default 0); anything but an integer in 0..232 is one line."""
    text = environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:  # DDS's port mapping (7400 + 250 d + ...) fits in 16 bits up to 232
        raise InvalidInputError(f"ROS_DOMAIN_ID={text!r} must be an integer in 0..232")
    return value


class Transport(ABC):
    """A node on a middleware (see the module docstring). :meth:`open` makes the node; the rest
    act on it. Callbacks run inside :meth:`spin_once`, in the caller's thread."""

    #: Its ``--transport`` name.
    name: str = ""

    @abstractmethod
    def open(self, name: str, namespace: str | None = None) -> None:
        """Create the node ``name`` in ``namespace`` (its topics are absolute: it names the node only)."""

    @abstractmethod
    def subscribe(self, topic: str, msg_type: str, qos: str, callback: Callable, *, control: bool = False) -> None:
        """Call ``callback(msg)`` with every ``msg_type`` message on ``topic``. A ``control``
        topic (the e-stop) is handed on as soon as it is read, whatever the clock: a transport
        that paces data to ``/clock`` steps never holds it."""

    @abstractmethod
    def publisher(self, topic: str, msg_type: str, qos: str) -> Callable:
        """A function publishing a ``msg_type`` message on ``topic``."""

    @abstractmethod
    def service(self, name: str, srv_type: str, callback: Callable) -> None:
        """Serve ``name``: ``callback(request) -> {response field: value}``, called as soon as a
        request is read, whatever the clock (a control input, as a ``control`` topic)."""

    @abstractmethod
    def timer(self, period_s: float, callback: Callable) -> object:
        """Call ``callback()`` every ``period_s`` s of the node's clock."""

    @abstractmethod
    def now_ns(self) -> int:
        """The node's clock (ROS time), integer ns."""

    @abstractmethod
    def ok(self) -> bool:
        """The middleware can still carry a message."""

    @abstractmethod
    def spin_once(self, timeout_s: float) -> None:
        """Run the callbacks due (messages, then timers), waiting up to ``timeout_s`` for one."""

    @abstractmethod
    def log(self, level: str, text: str) -> None:
        """One line of the node's log (``info``, ``warning``, ``error``)."""

    @abstractmethod
    def close(self) -> None:
        """Destroy the node and shut the middleware down."""
