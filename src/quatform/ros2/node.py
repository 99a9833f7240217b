"""The ROS 2 node of the bridge: rclpy imported only here, only when a node is built.

ROS 2 bridge layer. :class:`BridgeNode` wraps a :class:`~quatform.ros2.bridge.FormationBridge`
in an ``rclpy`` node: one subscription per robot's pose topic (sensor-data QoS; PX4's
best-effort, transient-local profile for ``/fmu`` topics), the command publishers, the e-stop
(a ``std_msgs/Bool`` topic: true engages, false releases; and a ``std_srvs/SetBool`` service
doing the same; latched: zero commands until released) and a timer at the control rate.

Messages are built as ``rosbags`` classes (:mod:`quatform.messages`) and converted field by
field to the ROS installation's classes (:func:`to_ros`); incoming ROS messages are read by
field name, which both share. rclpy is never a pip dependency: a machine without it gets one
line saying to source ROS 2 (:func:`import_rclpy`).

Shutdown: rclpy's own SIGINT/SIGTERM handlers (Humble and later) shut the context down before
``KeyboardInterrupt`` reaches the node, after which a publish raises (``publisher's context is
invalid``). The node therefore initialises rclpy without them
(``SignalHandlerOptions.NO``): Ctrl-C raises ``KeyboardInterrupt`` in the spin with the
context still valid, and :meth:`BridgeNode.close` publishes the zero command to every robot
first, then destroys the node and shuts rclpy down.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import signal
import threading

import numpy as np

from .. import messages
from ..errors import InvalidInputError, MissingDependencyError
from .bridge import FormationBridge

__all__ = ["import_rclpy", "ros_class", "to_ros", "BridgeNode", "ROS_MISSING"]

#: The line a machine without rclpy gets.
ROS_MISSING = ("quatform ros2 needs ROS 2's rclpy, which is not installed here: source your ROS 2 installation "
               "(e.g. source /opt/ros/humble/setup.bash) and run it again; rclpy is not a pip dependency")


def import_rclpy():
    """``rclpy`` with its ``node`` and ``qos`` modules, or :class:`MissingDependencyError` (one line)."""
    try:
        rclpy = importlib.import_module("rclpy")
        importlib.import_module("rclpy.node")
        importlib.import_module("rclpy.qos")
        importlib.import_module("rclpy.signals")
    except ImportError:
        raise MissingDependencyError(ROS_MISSING) from None
    return rclpy


def ros_class(name: str):
    """The ROS installation's class of ``pkg/msg/Type`` (or ``pkg/srv/Type``): ``pkg.msg.Type``."""
    pkg, kind, typ = name.split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.{kind}"), typ)
    except (ImportError, AttributeError):
        raise MissingDependencyError(f"the ROS 2 message {name} is not installed here: install its package "
                                     f"(e.g. apt install ros-$ROS_DISTRO-{pkg.replace('_', '-')}, or build "
                                     f"{pkg} in your workspace) and source it") from None


def to_ros(msg):
    """The ROS installation's message equal to the ``rosbags`` message ``msg`` (itself when
    its class is the installation's, as with a fake rclpy on rosbags classes). Fields the
    installation's class lacks (another PX4 version) are left out."""
    cls = ros_class(msg.__msgtype__)
    if isinstance(msg, cls):
        return msg
    out = cls()
    own = cls.get_fields_and_field_types()
    for f in dataclasses.fields(msg):
        if f.name not in own:
            continue
        v = getattr(msg, f.name)
        if dataclasses.is_dataclass(v):
            v = to_ros(v)
        elif isinstance(v, np.ndarray):
            v = v.tolist()
        setattr(out, f.name, v)
    return out


def qos_profile(rclpy, which: str):
    """The rclpy QoS of the robots file's ``qos`` name: ``sensor`` rclpy's sensor-data profile,
    ``px4`` best effort and transient local (px4_ros_com's), else a reliable queue of 10."""
    q = importlib.import_module("rclpy.qos")
    if which == "sensor":
        return q.qos_profile_sensor_data
    if which == "px4":  # px4_ros_com's offboard example
        return q.QoSProfile(reliability=q.ReliabilityPolicy.BEST_EFFORT, durability=q.DurabilityPolicy.TRANSIENT_LOCAL,
                            history=q.HistoryPolicy.KEEP_LAST, depth=1)
    return 10


class BridgeNode:
    """An rclpy node running a :class:`FormationBridge` at ``rate_hz``.

    Parameters
    ----------
    bridge : FormationBridge
    rate_hz : float
        Control rate, Hz.
    rclpy : module, optional
        The ``rclpy`` to use (default: :func:`import_rclpy`; tests pass a fake one).
    name : str
        The node's name.
    namespace : str, optional
        The node's namespace (its topics are absolute names: it names the node only).
    """

    def __init__(self, bridge: FormationBridge, rate_hz: float, rclpy=None, name: str = "quatform_bridge",
                 namespace: str | None = None):
        if not (isinstance(rate_hz, (int, float)) and np.isfinite(rate_hz) and rate_hz > 0):
            raise InvalidInputError(f"--rate {rate_hz!r} must be a positive number of Hz")
        self.rclpy = import_rclpy() if rclpy is None else rclpy
        self.bridge = bridge
        self.rate_hz = float(rate_hz)
        self.ticks: list = []
        self.timer = None
        self._said: tuple = ()
        if not self.rclpy.ok():  # without rclpy's signal handlers: the zero command on Ctrl-C still goes out
            no_handlers = importlib.import_module("rclpy.signals").SignalHandlerOptions.NO
            self.rclpy.init(signal_handler_options=no_handlers)
        self.node = importlib.import_module("rclpy.node").Node(name, namespace=namespace)
        s = bridge.robots.settings
        self._subscribe()
        self.publishers = {}
        for topic, typ, qos in bridge.command_topics():
            self.publishers[topic] = self.node.create_publisher(ros_class(typ), topic, qos_profile(self.rclpy, qos))
        self.node.create_subscription(ros_class("std_msgs/msg/Bool"), s.estop_topic, self._estop_topic, 10)
        self.node.create_service(ros_class("std_srvs/srv/SetBool"), self.estop_service(), self._estop_service)

    def estop_service(self) -> str:
        """The name of its e-stop service: the robots file's ``[bridge] estop_service``."""
        return self.bridge.robots.settings.estop_service

    def _subscribe(self) -> None:
        """Subscribe to every robot's pose topic (sensor-data QoS, PX4's for ``/fmu``)."""
        for i, (topic, typ, qos) in enumerate(self.bridge.pose_topics()):
            self.node.create_subscription(ros_class(typ), topic, self._pose_callback(i), qos_profile(self.rclpy, qos))

    # -- callbacks ----------------------------------------------------------------------------
    def now_ns(self) -> int:
        return int(self.node.get_clock().now().nanoseconds)

    def _pose_callback(self, i):
        def callback(msg):
            if not self.bridge.on_pose(i, msg, self.now_ns()):
                topic = self.bridge.robots.robots[i].pose_topic
                self.node.get_logger().warning(f"robot {self.bridge.names[i]!r}: lost frame on {topic} (NaN or "
                                               "non-unit quaternion)")
        return callback

    def _estop_topic(self, msg):
        self.set_estop(bool(msg.data))

    def _estop_service(self, request, response):
        self.set_estop(bool(request.data))
        response.success = True
        response.message = "e-stop engaged: zero commands until released" if request.data else "e-stop released"
        return response

    def set_estop(self, engaged: bool) -> None:
        """Engage (latched: zero commands from the next tick on, and at once) or release the e-stop."""
        if engaged:
            self.bridge.engage_estop()
            self.node.get_logger().warning("e-stop engaged: zero commands until released")
            self.publish_zero()
        else:
            self.bridge.release_estop()
            self.node.get_logger().info("e-stop released")

    def _on_timer(self):
        tick = self.bridge.tick(self.now_ns())
        self.ticks.append(tick)
        if tick.stale != self._said:
            if tick.stale:
                self.node.get_logger().warning(f"stale pose from {', '.join(tick.stale)}: commands zeroed and held")
            self._said = tick.stale
        self._publish(tick.messages)

    def _publish(self, msgs):
        for topic, msg in msgs:
            self.publishers[topic].publish(to_ros(msg))

    def publish_zero(self) -> None:
        """Zero commands to every robot the bridge drives, now."""
        self._publish(self.bridge.zero_messages(messages.stamp_ns(self.now_ns())))

    # -- running ------------------------------------------------------------------------------
    def wait_for_robots(self, timeout_s: float | None = None) -> None:
        """Spin until every robot has a pose; none within ``timeout_s`` (default the robots file's
        ``start_timeout_s``) is one line naming the robot and its topic."""
        timeout_s = self.bridge.robots.settings.start_timeout_s if timeout_s is None else timeout_s
        start = self.now_ns()
        while self.bridge.missing():
            if not self.rclpy.ok():
                raise InvalidInputError("ROS 2 was shut down while waiting for the robots' poses; not starting")
            if self.now_ns() - start > timeout_s * 1e9:
                i = self.bridge.missing()[0]
                link = self.bridge.robots.robots[i]
                more = len(self.bridge.missing()) - 1
                raise InvalidInputError(
                    f"robot {link.name!r}: no pose on {link.pose_topic} ({link.pose_type}) within {timeout_s:g} s"
                    + (f" (and {more} more robots)" if more else "")
                    + "; check the topic with 'ros2 topic echo' or raise [bridge] start_timeout_s; not starting")
            self.rclpy.spin_once(self.node, timeout_sec=0.05)

    def start(self) -> None:
        """Wait for every robot, then start the control timer."""
        self.wait_for_robots()
        self.timer = self.node.create_timer(1.0 / self.rate_hz, self._on_timer)

    def spin(self) -> None:
        """Run until ROS shuts down, Ctrl-C or SIGTERM (raised here as ``KeyboardInterrupt``);
        zero commands on the way out (:meth:`close`)."""
        with _sigterm_interrupts():
            try:
                while self.rclpy.ok():
                    self.rclpy.spin_once(self.node, timeout_sec=0.1)
            finally:
                self.close()

    def close(self) -> None:
        """Zero commands to every robot while the context is still valid, then destroy the node
        and shut rclpy down, in that order. A context someone else already shut down can carry
        no message: the node logs one error line saying so instead of raising."""
        try:
            if self.rclpy.ok():
                self.publish_zero()
            else:
                self.node.get_logger().error("ROS 2 was shut down before the zero command could be sent: the "
                                             "robots keep their last command until their own timeout")
        finally:
            self.node.destroy_node()
            if self.rclpy.ok():
                self.rclpy.shutdown()


@contextlib.contextmanager
def _sigterm_interrupts():
    """SIGTERM raises ``KeyboardInterrupt`` inside the block (main thread only; restored after),
    so a terminated bridge sends its zero command as on Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
