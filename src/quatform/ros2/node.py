"""The bridge's ROS 2 node, on any transport: rclpy, or DDS without ROS (ROS 2 bridge layer).

:class:`BridgeNode` wraps a :class:`~quatform.ros2.bridge.FormationBridge` in a node of a
:class:`~quatform.ros2.transport.Transport`: one subscription per robot's pose topic
(sensor-data QoS; PX4's best-effort, transient-local profile for ``/fmu`` topics), the command
publishers, the e-stop (a ``std_msgs/Bool`` topic, latched: true engages, false releases; and
a ``std_srvs/SetBool`` service doing the same; zero
commands until released) and a timer at the control rate. The transport carries it:
:class:`~quatform.ros2.rclpy_transport.RclpyTransport` (default) or
:class:`~quatform.ros2.dds.DdsTransport`.

Shutdown: Ctrl-C (and SIGTERM, raised as :class:`~quatform.errors.Terminated`, a
``KeyboardInterrupt``, while spinning) reaches the spin with the transport still able to
publish; :meth:`BridgeNode.close` publishes the zero command to every robot first, then closes
the transport, with SIGINT and SIGTERM ignored meanwhile, so a second Ctrl-C cannot cut the zero
command short after some robots.
"""

from __future__ import annotations

import contextlib
import signal
import threading

import numpy as np

from .. import messages
from ..errors import InvalidInputError, Terminated
from .bridge import FormationBridge
from .transport import Transport

__all__ = ["BridgeNode"]


class BridgeNode:
    """A node running a :class:`FormationBridge` at ``rate_hz`` on a transport.

    Parameters
    ----------
    bridge : FormationBridge
    rate_hz : float
        Control rate, Hz (of the transport's clock).
    transport : Transport, optional
        Its middleware (default: rclpy, :class:`~quatform.ros2.rclpy_transport.RclpyTransport`).
    name : str
        The node's name.
    namespace : str, optional
        The node's namespace (its topics are absolute names: it names the node only).
    """

    def __init__(self, bridge: FormationBridge, rate_hz: float, transport: Transport | None = None,
                 name: str = "quatform_bridge", namespace: str | None = None):
        if not (isinstance(rate_hz, (int, float)) and np.isfinite(rate_hz) and rate_hz > 0):
            raise InvalidInputError(f"--rate {rate_hz!r} must be a positive number of Hz")
        if transport is None:
            from .rclpy_transport import RclpyTransport

            transport = RclpyTransport()
        self.transport = transport
        self.bridge = bridge
        self.rate_hz = float(rate_hz)
        self.ticks: list = []
        self.timer = None
        self._said: tuple = ()
        transport.open(name, namespace)
        s = bridge.robots.settings
        self._subscribe()
        self.publishers = {topic: transport.publisher(topic, typ, qos) for topic, typ, qos in bridge.command_topics()}
        transport.subscribe(s.estop_topic, "std_msgs/msg/Bool", "estop", self._estop_topic, control=True)
        transport.service(self.estop_service(), "std_srvs/srv/SetBool", self._estop_service)

    def estop_service(self) -> str:
        """The name of its e-stop service: the robots file's ``[bridge] estop_service``."""
        return self.bridge.robots.settings.estop_service

    def _subscribe(self) -> None:
        """Subscribe to every robot's pose topic (sensor-data QoS, PX4's for ``/fmu``)."""
        for i, (topic, typ, qos) in enumerate(self.bridge.pose_topics()):
            self.transport.subscribe(topic, typ, qos, self._pose_callback(i))

    # -- callbacks ----------------------------------------------------------------------------
    def now_ns(self) -> int:
        return self.transport.now_ns()

    def _pose_callback(self, i):
        def callback(msg):
            if not self.bridge.on_pose(i, msg, self.now_ns()):
                topic = self.bridge.robots.robots[i].pose_topic
                self.transport.log("warning", f"robot {self.bridge.names[i]!r}: lost frame on {topic} (NaN or "
                                   "non-unit quaternion)")
        return callback

    def _estop_topic(self, msg):
        self.set_estop(bool(msg.data))

    def _estop_service(self, request):
        self.set_estop(bool(request.data))
        return {"success": True,
                "message": "e-stop engaged: zero commands until released" if request.data else "e-stop released"}

    def set_estop(self, engaged: bool) -> None:
        """Engage (latched: zero commands from the next tick on, and at once) or release the e-stop."""
        if engaged:
            self.bridge.engage_estop()
            self.transport.log("warning", "e-stop engaged: zero commands until released")
            self.publish_zero()
        else:
            self.bridge.release_estop()
            self.transport.log("info", "e-stop released")

    def _on_timer(self):
        tick = self.bridge.tick(self.now_ns())
        self.ticks.append(tick)
        if tick.stale != self._said:
            if tick.stale:
                self.transport.log("warning", f"stale pose from {', '.join(tick.stale)}: commands zeroed and held")
            self._said = tick.stale
        self._publish(tick.messages)

    def _publish(self, msgs):
        for topic, msg in msgs:
            self.publishers[topic](msg)

    def publish_zero(self) -> None:
        """Zero commands to every robot the bridge drives, now."""
        self._publish(self.bridge.zero_messages(messages.stamp_ns(self.now_ns())))

    # -- running ------------------------------------------------------------------------------
    def wait_for_robots(self, timeout_s: float | None = None) -> None:
        """Spin until every robot has a pose; none within ``timeout_s`` (default the robots file's
        ``start_timeout_s``, of the transport's clock) is one line naming the robot and its topic."""
        timeout_s = self.bridge.robots.settings.start_timeout_s if timeout_s is None else timeout_s
        start = self.now_ns()
        while self.bridge.missing():
            if not self.transport.ok():
                raise InvalidInputError("ROS 2 was shut down while waiting for the robots' poses; not starting")
            if self.now_ns() - start > timeout_s * 1e9:
                i = self.bridge.missing()[0]
                link = self.bridge.robots.robots[i]
                more = len(self.bridge.missing()) - 1
                raise InvalidInputError(
                    f"robot {link.name!r}: no pose on {link.pose_topic} ({link.pose_type}) within {timeout_s:g} s"
                    + (f" (and {more} more robots)" if more else "")
                    + "; check the topic with 'ros2 topic echo' or raise [bridge] start_timeout_s; not starting")
            self.transport.spin_once(0.05)

    def start(self) -> None:
        """Wait for every robot, then start the control timer."""
        self.wait_for_robots()
        self.timer = self.transport.timer(1.0 / self.rate_hz, self._on_timer)

    def spin(self) -> None:
        """Run until the transport shuts down, Ctrl-C or SIGTERM (raised here as
        ``KeyboardInterrupt``, :class:`~quatform.errors.Terminated` for SIGTERM); zero commands
        on the way out (:meth:`close`)."""
        with _sigterm_interrupts():
            try:
                while self.transport.ok():
                    self.transport.spin_once(0.1)
            finally:
                self.close()

    def close(self) -> None:
        """Zero commands to every robot while the transport can still carry them, then close it,
        in that order, with SIGINT and SIGTERM ignored meanwhile (main thread; restored after): a
        repeated Ctrl-C cannot cut the zero command short. A context someone else already shut
        down can carry no message: the node logs one error line saying so instead of raising."""
        with _signals_ignored():
            try:
                if self.transport.ok():
                    self.publish_zero()
                else:
                    self.transport.log("error", "ROS 2 was shut down before the zero command could be sent: the "
                                       "robots keep their last command until their own timeout")
            finally:
                self.transport.close()


@contextlib.contextmanager
def _signals_ignored():
    """SIGINT and SIGTERM ignored (not queued) inside the block, in the main thread; restored after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def _sigterm_interrupts():
    """SIGTERM raises :class:`~quatform.errors.Terminated` (a ``KeyboardInterrupt``) inside the
    block (main thread only; restored after), so a terminated bridge sends its zero command as on
    Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
