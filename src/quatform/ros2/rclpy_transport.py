"""The rclpy transport: the bridge's node on a sourced ROS 2 installation (ROS 2 bridge layer).

rclpy is imported only here, only when a transport is built, and is never a pip dependency: a
machine without it gets one line saying to source ROS 2 (:func:`import_rclpy`) or to use the
``dds`` transport. Messages are built as ``rosbags`` classes (:mod:`quatform.messages`) and
converted field by field to the ROS installation's classes (:func:`to_ros`); incoming ROS
messages are read by field name, which both share.

Shutdown: rclpy's own SIGINT/SIGTERM handlers (Humble and later) shut the context down before
``KeyboardInterrupt`` reaches the node, after which a publish raises (``publisher's context is
invalid``). The transport therefore initialises rclpy without them
(``SignalHandlerOptions.NO``): Ctrl-C raises ``KeyboardInterrupt`` in the spin with the
context still valid, so the node's zero command still goes out.
"""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np

from ..errors import MissingDependencyError
from .transport import QOS, Transport

__all__ = ["import_rclpy", "ros_class", "to_ros", "qos_profile", "RclpyTransport", "ROS_MISSING"]

#: The line a machine without rclpy gets.
ROS_MISSING = ("quatform ros2 needs ROS 2's rclpy, which is not installed here: source your ROS 2 installation "
               "(e.g. source /opt/ros/humble/setup.bash) and run it again (rclpy is not a pip dependency), or speak "
               "ROS 2 on the wire without ROS with --transport dds (pip install -e \".[dds]\")")


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
    """The rclpy ``QoSProfile`` of the :data:`~quatform.ros2.transport.QOS` name ``which``."""
    q = importlib.import_module("rclpy.qos")
    p = QOS[which]
    return q.QoSProfile(
        reliability=q.ReliabilityPolicy.RELIABLE if p.reliable else q.ReliabilityPolicy.BEST_EFFORT,
        durability=q.DurabilityPolicy.TRANSIENT_LOCAL if p.transient_local else q.DurabilityPolicy.VOLATILE,
        history=q.HistoryPolicy.KEEP_ALL if p.keep_all else q.HistoryPolicy.KEEP_LAST, depth=p.depth)


class RclpyTransport(Transport):
    """A :class:`~quatform.ros2.transport.Transport` on rclpy.

    Parameters
    ----------
    rclpy : module, optional
        The ``rclpy`` to use (default: :func:`import_rclpy`; tests pass a fake one).
    use_sim_time : bool
        Set the node's ``use_sim_time`` parameter (its clock and timers follow ``/clock``).
    """

    name = "rclpy"

    def __init__(self, rclpy=None, use_sim_time: bool = False):
        self.rclpy = import_rclpy() if rclpy is None else rclpy
        self.use_sim_time = bool(use_sim_time)
        self.node = None

    def open(self, name, namespace=None):
        if not self.rclpy.ok():  # without rclpy's signal handlers: the zero command on Ctrl-C still goes out
            no_handlers = importlib.import_module("rclpy.signals").SignalHandlerOptions.NO
            self.rclpy.init(signal_handler_options=no_handlers)
        extra = {}
        if self.use_sim_time:
            param = importlib.import_module("rclpy.parameter").Parameter
            extra["parameter_overrides"] = [param("use_sim_time", value=True)]
        self.node = importlib.import_module("rclpy.node").Node(name, namespace=namespace, **extra)

    def subscribe(self, topic, msg_type, qos, callback, *, control=False):
        # rclpy's executor hands every message on as it is taken: a control topic needs nothing more
        self.node.create_subscription(ros_class(msg_type), topic, callback, qos_profile(self.rclpy, qos))

    def publisher(self, topic, msg_type, qos):
        pub = self.node.create_publisher(ros_class(msg_type), topic, qos_profile(self.rclpy, qos))
        return lambda msg: pub.publish(to_ros(msg))

    def service(self, name, srv_type, callback):
        def serve(request, response):
            for k, v in callback(request).items():
                setattr(response, k, v)
            return response

        self.node.create_service(ros_class(srv_type), name, serve)

    def timer(self, period_s, callback):
        return self.node.create_timer(period_s, callback)

    def now_ns(self):
        return int(self.node.get_clock().now().nanoseconds)

    def ok(self):
        return bool(self.rclpy.ok())

    def spin_once(self, timeout_s):
        self.rclpy.spin_once(self.node, timeout_sec=timeout_s)

    def log(self, level, text):
        getattr(self.node.get_logger(), level)(text)

    def close(self):
        if self.node is not None:
            self.node.destroy_node()
        if self.rclpy.ok():
            self.rclpy.shutdown()
