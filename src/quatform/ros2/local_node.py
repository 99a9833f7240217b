"""One robot's ROS 2 node of a decentralised formation, on any transport (rclpy or DDS).

ROS 2 bridge layer. :class:`LocalNode` wraps a :class:`~quatform.ros2.local_bridge.LocalBridge`
in a node of a :class:`~quatform.ros2.transport.Transport`, one per robot (``quatform ros2
--scenario NET --robots robots.toml --robot I [--transport dds]`` on each robot, or each in one
launch file):

* its own pose topic (the robots file's, sensor-data QoS; PX4's profile for ``/fmu`` topics);
* each in-neighbour's message, ``/<neighbour namespace>/quatform/message``
  (:data:`~quatform.ros2.local_bridge.MESSAGE_TYPE`, best-effort sensor-data QoS: a lost
  message only ages the one held, as on the simulated links);
* its command (the robots file's ``command_topic`` and ``command_type``) and its message,
  ``/<its namespace>/quatform/message``, published at each tick of a timer at the control rate
  (the scenario's by default).

The node is in the robot's namespace. E-stop (the robots file's topic, shared by every robot's
node; its service in the robot's namespace), Ctrl-C, SIGTERM and shutdown behave as
:class:`~quatform.ros2.node.BridgeNode`'s: latched zero command until released, and the zero
command published before the transport is closed.
"""

from __future__ import annotations

from .local_bridge import LocalBridge
from .node import BridgeNode
from .robots_file import resolve_topic

__all__ = ["LocalNode"]


class LocalNode(BridgeNode):
    """A node running one robot's :class:`LocalBridge` at ``rate_hz``.

    Parameters
    ----------
    bridge : LocalBridge
    rate_hz : float
        Control rate, Hz.
    transport : Transport, optional
        Its middleware (default: rclpy, :class:`~quatform.ros2.rclpy_transport.RclpyTransport`).
    name : str, optional
        The node's name (default ``quatform_<robot name>``).
    """

    def __init__(self, bridge: LocalBridge, rate_hz: float, transport=None, name: str | None = None):
        link = bridge.link
        super().__init__(bridge, rate_hz, transport, name or f"quatform_{link.name.replace('-', '_')}",
                         namespace=link.namespace or None)

    def estop_service(self) -> str:
        """Its e-stop service, in its namespace (``/<namespace>/quatform/set_estop`` by default): one
        service per robot's node, where one name served by several nodes answers unpredictably.
        The e-stop topic stays the robots file's: one message stops every robot."""
        return resolve_topic(self.bridge.link.namespace, self.bridge.robots.settings.estop_service.lstrip("/"))

    def _subscribe(self) -> None:
        """Its own pose, and each in-neighbour's message."""
        b = self.bridge
        for topic, typ, qos in b.pose_topics():
            self.transport.subscribe(topic, typ, qos, self._pose_callback(b.robot))
        for j, topic, typ, qos in b.neighbour_topics():
            self.transport.subscribe(topic, typ, qos, self._message_callback(j))

    def _message_callback(self, j):
        said = []

        def callback(msg):
            names = tuple(msg.name)
            if not self.bridge.on_message(j, msg) and names != self.bridge.columns and not said:
                said.append(True)  # one line per neighbour, not one per message
                self.transport.log(
                    "warning", f"robot {self.bridge.names[j]!r} sends {', '.join(names)} on "
                    f"{self.bridge.message_topics[j]}, not {', '.join(self.bridge.columns)}: its messages are not "
                    "used (another law or scenario?)")
        return callback
