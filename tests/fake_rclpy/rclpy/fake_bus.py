"""The fake middleware: CDR on the wire, a simulated clock, scheduled deliveries (test controls)."""

from __future__ import annotations

import heapq
import itertools


class Bus:
    def __init__(self):
        self.reset()

    def reset(self, now_ns: int = 0):
        self.initialized = False
        self.signal_handler_options = None
        self.interrupt_ns: int | None = None  # a simulated Ctrl-C at this time
        self.now_ns = int(now_ns)
        self.subscriptions: dict = {}
        self.publishers: dict = {}
        self.services: dict = {}
        self.nodes: list = []
        self.logs: list = []
        self.published: dict = {}  # topic -> [(time_ns, message deserialised from its CDR)]
        self._queue: list = []  # (time_ns, seq, topic, type name, cdr bytes)
        self._seq = itertools.count()

    @staticmethod
    def _store():
        from quatform.ros2.px4 import register_px4_types

        return register_px4_types()

    def _wire(self, msg):
        name = msg.__msgtype__
        return name, self._store().serialize_cdr(msg, name)

    # -- test controls --------------------------------------------------------------------------
    def schedule(self, time_ns: int, topic: str, msg) -> None:
        """A message another node publishes on ``topic`` at ``time_ns`` (serialised now)."""
        name, data = self._wire(msg)
        heapq.heappush(self._queue, (int(time_ns), next(self._seq), topic, name, data))

    def interrupt(self, time_ns: int) -> None:
        """A Ctrl-C (SIGINT) at ``time_ns``, seen by the next :meth:`spin_once` that reaches it."""
        self.interrupt_ns = int(time_ns)

    def _sigint(self) -> None:
        """What a SIGINT does to a spinning process: rclpy's handler (installed unless ``init`` was
        given ``SignalHandlerOptions.NO`` or ``SIGTERM``) shuts the context down first, then
        Python's raises ``KeyboardInterrupt``."""
        self.now_ns = max(self.now_ns, self.interrupt_ns)
        self.interrupt_ns = None
        if self.signal_handler_options is not None and self.signal_handler_options.name in ("SIGINT", "ALL"):
            self.initialized = False
        raise KeyboardInterrupt

    def call(self, service: str, **fields):
        """Call a service with a request of ``fields``; returns its response."""
        srv_type, callback = self.services[service]
        return callback(srv_type.Request(**fields), srv_type.Response())

    # -- the middleware -----------------------------------------------------------------------
    def publish(self, topic: str, msg) -> None:
        if not self.initialized:
            from ._rclpy_pybind11 import RCLError

            raise RCLError("Failed to publish: publisher's context is invalid")
        name, data = self._wire(msg)
        self.published.setdefault(topic, []).append((self.now_ns, self._store().deserialize_cdr(data, name)))
        if self.subscriptions.get(topic):
            heapq.heappush(self._queue, (self.now_ns, next(self._seq), topic, name, data))

    def _deliver(self, topic, name, data) -> None:
        for sub in list(self.subscriptions.get(topic, ())):
            msg = self._store().deserialize_cdr(data, name)
            if not isinstance(msg, sub.msg_type):
                raise TypeError(f"{topic}: a {name} delivered to a subscription of {sub.msg_type.__name__}")
            sub.callback(msg)

    def spin_once(self, node, timeout_sec) -> bool:
        """Run the next event within ``timeout_sec`` (None: whenever it is); False if none ran."""
        limit = None if timeout_sec is None else self.now_ns + int(round(timeout_sec * 1e9))
        if self.interrupt_ns is not None and (limit is None or self.interrupt_ns <= limit):
            t_first = self._queue[0][0] if self._queue else None
            due = [t.next_due for t in node.timers if not t.cancelled]
            if t_first is not None:
                due.append(t_first)
            if not due or self.interrupt_ns <= min(due):
                self._sigint()
        t_msg = self._queue[0][0] if self._queue else None
        timers = [t for t in node.timers if not t.cancelled]
        timer = min(timers, key=lambda t: t.next_due) if timers else None
        candidates = [t for t in (t_msg, None if timer is None else timer.next_due) if t is not None]
        if not candidates:
            if limit is not None:
                self.now_ns = limit
            return False
        t_next = min(candidates)
        if limit is not None and t_next > limit:
            self.now_ns = limit
            return False
        self.now_ns = max(self.now_ns, t_next)
        if t_msg is not None and t_msg <= t_next:  # deliveries before a timer due at the same time
            _, _, topic, name, data = heapq.heappop(self._queue)
            self._deliver(topic, name, data)
        else:
            timer.next_due += timer.period_ns
            timer.callback()
        return True


BUS = Bus()
