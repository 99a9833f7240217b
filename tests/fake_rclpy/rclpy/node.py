"""``rclpy.node.Node`` of the fake: publishers, subscriptions, timers, services, clock, logger."""

from __future__ import annotations

from . import fake_bus


def _context_valid(what: str) -> None:
    if not fake_bus.BUS.initialized:
        from ._rclpy_pybind11 import RCLError

        raise RCLError(f"failed to create {what}: rcl node's context is invalid")


class Time:
    def __init__(self, nanoseconds: int):
        self.nanoseconds = int(nanoseconds)

    def to_msg(self):
        from quatform.messages import msg_type

        return msg_type("builtin_interfaces/msg/Time")(sec=self.nanoseconds // 10**9, nanosec=self.nanoseconds % 10**9)


class Clock:
    def now(self) -> Time:
        return Time(fake_bus.BUS.now_ns)


class Logger:
    def __init__(self, name):
        self.name = name

    def _log(self, level, text):
        fake_bus.BUS.logs.append((level, text))

    def debug(self, text, **kwargs):
        self._log("debug", text)

    def info(self, text, **kwargs):
        self._log("info", text)

    def warning(self, text, **kwargs):  # rclpy's RcutilsLogger: ``warn`` is deprecated, gone from the fake
        self._log("warning", text)

    def error(self, text, **kwargs):
        self._log("error", text)

    def fatal(self, text, **kwargs):
        self._log("fatal", text)


class Publisher:
    def __init__(self, msg_type, topic, qos):
        self.msg_type, self.topic, self.qos = msg_type, topic, qos

    def publish(self, msg):
        if not isinstance(msg, self.msg_type):
            raise TypeError(f"publisher of {self.msg_type.__name__} on {self.topic} got {type(msg).__name__}")
        fake_bus.BUS.publish(self.topic, msg)


class Subscription:
    def __init__(self, node, msg_type, topic, callback, qos):
        self.node, self.msg_type, self.topic, self.callback, self.qos = node, msg_type, topic, callback, qos


class Timer:
    def __init__(self, period_ns, callback):
        self.period_ns = period_ns
        self.callback = callback
        self.next_due = fake_bus.BUS.now_ns + period_ns
        self.cancelled = False

    def cancel(self):
        self.cancelled = True


class Node:
    def __init__(self, node_name, *, namespace=None, **kwargs):
        _context_valid("node")
        self.name = node_name
        self.namespace = namespace
        self.timers: list[Timer] = []
        self._clock = Clock()
        self._logger = Logger(node_name)
        fake_bus.BUS.nodes.append(self)

    def create_subscription(self, msg_type, topic, callback, qos_profile, **kwargs):
        _context_valid("subscription")
        sub = Subscription(self, msg_type, topic, callback, qos_profile)
        fake_bus.BUS.subscriptions.setdefault(topic, []).append(sub)
        return sub

    def create_publisher(self, msg_type, topic, qos_profile, **kwargs):
        _context_valid("publisher")
        pub = Publisher(msg_type, topic, qos_profile)
        fake_bus.BUS.publishers[topic] = pub
        return pub

    def create_timer(self, timer_period_sec, callback, **kwargs):
        _context_valid("timer")
        t = Timer(int(round(timer_period_sec * 1e9)), callback)
        self.timers.append(t)
        return t

    def create_service(self, srv_type, srv_name, callback, **kwargs):
        _context_valid("service")
        fake_bus.BUS.services[srv_name] = (srv_type, callback)
        return srv_name

    def get_clock(self):
        return self._clock

    def get_logger(self):
        return self._logger

    def destroy_node(self):
        fake_bus.BUS.nodes.remove(self)
        for subs in fake_bus.BUS.subscriptions.values():
            subs[:] = [s for s in subs if s.node is not self]
