"""A fake ``rclpy`` for quatform's tests: the small API the ROS 2 bridge uses, no ROS.

A discrete-event middleware (:mod:`rclpy.fake_bus`): messages are serialised to CDR with
rosbags' type store when published and deserialised when delivered, time is a simulated
clock in integer nanoseconds, and :func:`spin_once` runs the next due event (a delivery, then
a timer) within its timeout, moving the clock to it.
"""

from . import fake_bus, node, qos  # noqa: F401

__all__ = ["init", "shutdown", "ok", "spin_once", "spin"]


def init(args=None, context=None):
    fake_bus.BUS.initialized = True


def shutdown(context=None):
    fake_bus.BUS.initialized = False


def ok(context=None):
    return fake_bus.BUS.initialized


def spin_once(a_node, *, executor=None, timeout_sec=None):
    fake_bus.BUS.spin_once(a_node, timeout_sec)


def spin(a_node, executor=None):
    while fake_bus.BUS.initialized and fake_bus.BUS.spin_once(a_node, None):
        pass
