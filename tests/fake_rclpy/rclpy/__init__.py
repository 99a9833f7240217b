"""A fake ``rclpy`` for quatform's tests: the small API the ROS 2 bridge uses, no ROS.

A discrete-event middleware (:mod:`rclpy.fake_bus`): messages are serialised to CDR with
rosbags' type store when published and deserialised when delivered, time is a simulated
clock in integer nanoseconds, and :func:`spin_once` runs the next due event (a delivery, then
a timer) within its timeout, moving the clock to it.

It refuses what the real rclpy (Humble and later) refuses: ``init`` takes keyword arguments
only and once per context; ``shutdown`` of a context already shut down, a publish, a
``spin_once`` or a new entity after shutdown raise (``RCLError``, ``ExternalShutdownException``);
the logger has ``warning`` (not the deprecated ``warn``). A simulated Ctrl-C
(:meth:`fake_bus.Bus.interrupt`) behaves as rclpy's own SIGINT handler does: unless
``init(signal_handler_options=SignalHandlerOptions.NO)`` turned it off, the context is shut
down before ``KeyboardInterrupt`` reaches the caller.
"""

from . import _rclpy_pybind11, executors, fake_bus, node, qos, signals  # noqa: F401

__all__ = ["init", "shutdown", "try_shutdown", "ok", "spin_once", "spin"]


def init(*, args=None, context=None, domain_id=None, signal_handler_options=None):
    if fake_bus.BUS.initialized:
        raise RuntimeError("Context.init() must only be called once")
    fake_bus.BUS.initialized = True
    fake_bus.BUS.signal_handler_options = (signals.SignalHandlerOptions.ALL if signal_handler_options is None
                                           else signals.SignalHandlerOptions(signal_handler_options))


def shutdown(*, context=None, uninstall_handlers=None):
    if not fake_bus.BUS.initialized:
        raise _rclpy_pybind11.RCLError("failed to shutdown: rcl_shutdown already called on the given context")
    fake_bus.BUS.initialized = False


def try_shutdown(*, context=None, uninstall_handlers=None):
    fake_bus.BUS.initialized = False


def ok(*, context=None):
    return fake_bus.BUS.initialized


def spin_once(a_node, *, executor=None, timeout_sec=None):
    if not fake_bus.BUS.initialized:
        raise executors.ExternalShutdownException()
    fake_bus.BUS.spin_once(a_node, timeout_sec)


def spin(a_node, executor=None):
    while fake_bus.BUS.initialized and fake_bus.BUS.spin_once(a_node, None):
        pass
