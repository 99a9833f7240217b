"""A DDS peer on loopback for the dds transport's tests and benchmark: plain Cyclone DDS, ROS 2's
names written out (``rt/...``, ``pkg::msg::dds_::Name_``), the bridge in another process.

Every participant (this process's and the bridge's) reads ``CYCLONEDDS_URI``: the loopback
interface only, multicast off, unicast discovery of the peers on 127.0.0.1, so no packet
leaves 127.0.0.1 (Cyclone 11 still binds its unicast receive sockets to 0.0.0.0: no option
changes that, docs/ros2.md); the peer's readers and writers take the transport's own QoS
(:func:`~quatform.ros2.dds.dds_qos`); each test process has a domain id no other holds (``ROS_DOMAIN_ID``, a lock
file per domain), so parallel workers and runs never hear each other.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import quatform
from quatform import messages
from quatform.ros2.dds import dds_qos, dds_topic
from quatform.ros2.transport import QOS

#: Cyclone DDS 0.10 / 11 configuration: loopback, no multicast, unicast peers on 127.0.0.1.
CONFIG = """<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>
      <Peers><Peer address="127.0.0.1"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>
"""


#: The domains this process holds (their lock files stay open, so no other run takes them).
_HELD: dict = {}


def claim_domain() -> int:
    """A DDS domain id (1..232) no other process of these tests holds: an exclusive lock on a file
    per domain in the temporary directory, tried from a place drawn from the process id, kept
    until the process exits."""
    import fcntl
    import tempfile

    start = os.getpid() % 232
    for n in range(232):
        d = 1 + (start + n) % 232
        if d in _HELD:
            continue
        f = open(Path(tempfile.gettempdir()) / f"quatform-dds-domain-{d}.lock", "a")  # noqa: SIM115 - held
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        _HELD[d] = f
        return d
    raise RuntimeError("every DDS domain id 1..232 is held by another test run")


def loopback_env(folder: Path) -> dict:
    """``CYCLONEDDS_URI`` (a config written into ``folder``) and a ``ROS_DOMAIN_ID`` of its own
    (:func:`claim_domain`), for this process and the bridge's."""
    path = folder / "cyclonedds.xml"
    path.write_text(CONFIG)
    return {"CYCLONEDDS_URI": path.resolve().as_uri(), "ROS_DOMAIN_ID": str(claim_domain())}


def quatform_process(args, env: dict, log: Path) -> subprocess.Popen:
    """``quatform ARGS`` in a new process (this checkout's quatform), stderr and stdout to ``log``."""
    src = str(Path(quatform.__file__).resolve().parents[1])
    full = {**os.environ, **env, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    code = "import sys; from quatform.cli import main; sys.exit(main(sys.argv[1:]))"
    out = open(log, "w")  # noqa: SIM115 - closed with the process by stop()
    proc = subprocess.Popen([sys.executable, "-c", code, *map(str, args)], env=full, stdout=out,
                            stderr=subprocess.STDOUT)
    proc.log_file = out
    return proc


def stop(proc: subprocess.Popen, sig=signal.SIGINT, timeout_s: float = 10.0) -> int:
    """Send ``sig`` and wait for the process (killed after ``timeout_s``); its exit status."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout_s)
    proc.log_file.close()
    return proc.returncode


class Peer:
    """A Cyclone DDS participant publishing and reading ROS 2 messages (``rosbags`` classes).

    Parameters
    ----------
    domain_id : int
    """

    def __init__(self, domain_id: int):
        from cyclonedds.core import WaitSet
        from cyclonedds.domain import DomainParticipant

        from quatform.ros2.dds import IdlTypes

        self.dp = DomainParticipant(domain_id)
        self.types = IdlTypes()
        self._topics: dict = {}
        self.waitset = WaitSet(self.dp)

    def _topic(self, name: str, msg_type: str):
        from cyclonedds.topic import Topic

        if (name, msg_type) not in self._topics:
            self._topics[name, msg_type] = Topic(self.dp, name, self.types.cls(msg_type))
        return self._topics[name, msg_type]

    def writer(self, name: str, msg_type: str, qos: str = "sensor"):
        """A DataWriter on the DDS topic ``name`` (``rt/...``) with the transport's QoS of the
        :data:`~quatform.ros2.transport.QOS` name ``qos`` (:func:`~quatform.ros2.dds.dds_qos`);
        :meth:`write` writes a rosbags message on it."""
        from cyclonedds.pub import DataWriter

        return DataWriter(self.dp, self._topic(name, msg_type), qos=dds_qos(qos))

    def reader(self, name: str, msg_type: str, qos: str = "default", depth: int = 1000):
        """A DataReader on the DDS topic ``name`` with the transport's QoS ``qos``, keeping the
        last ``depth`` samples (a reader's own history, not matched against the writer's)."""
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
        from cyclonedds.sub import DataReader

        r = DataReader(self.dp, self._topic(name, msg_type), qos=dds_qos(dataclasses.replace(QOS[qos], depth=depth)))
        r.msg_type = msg_type
        self.waitset.attach(ReadCondition(r, SampleState.Any | ViewState.Any | InstanceState.Any))
        return r

    def wait(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for a message on any of its readers."""
        self.waitset.wait(max(0, round(timeout_s * 1e9)))

    def write(self, writer, msg) -> None:
        writer.write(self.types.to_idl(msg))

    def take(self, reader) -> list:
        """The messages ``reader`` holds, as ``(receive time ns, rosbags message)``."""
        now = time.perf_counter_ns()
        return [(now, self.types.from_idl(s, reader.msg_type)) for s in reader.take(N=1000)
                if getattr(s, "sample_info", None) is not None and s.sample_info.valid_data]

    @staticmethod
    def wait_matched(entities, timeout_s: float, proc=None) -> None:
        """Wait until each writer and reader of ``entities`` has a remote match (``proc`` must stay alive)."""
        end = time.monotonic() + timeout_s
        while True:
            if all((e.get_matched_subscriptions() if hasattr(e, "get_matched_subscriptions")
                    else e.get_matched_publications()) for e in entities):
                return
            if proc is not None and proc.poll() is not None:
                raise AssertionError(f"the bridge exited ({proc.returncode}) before the peer matched it")
            if time.monotonic() > end:
                raise AssertionError(f"no DDS match within {timeout_s} s")
            time.sleep(0.02)


def _command(msg):
    lin, ang = messages.twist_from_msg(msg)
    return np.r_[lin, ang]


class Commands:
    """Every command the peer reads, per robot: ``[(receive ns, stamp ns, twist (6,))]``."""

    def __init__(self, peer, readers):
        self.peer, self.readers = peer, readers
        self.got = [[] for _ in readers]

    def poll(self, timeout_s: float) -> None:
        self.peer.wait(timeout_s)
        for box, r in zip(self.got, self.readers):
            box.extend((t, messages.nanoseconds(m.header.stamp), _command(m)) for t, m in self.peer.take(r))

    def stamped(self, stamp_ns: int) -> list:
        """Each robot's last command stamped ``stamp_ns`` (None where none yet)."""
        return [next((c for c in reversed(box) if c[1] == stamp_ns), None) for box in self.got]

    def wait_for(self, stamp_ns: int, timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while any(c is None for c in self.stamped(stamp_ns)):
            if time.monotonic() > end:
                return False
            self.poll(min(0.05, max(0.0, end - time.monotonic())))
        return True


def pose(k, p, q, stamp_ns):
    """``PoseStamped`` of sample ``k`` of ``(p, q)`` stamped ``stamp_ns``."""
    return messages.pose_stamped(messages.stamp_ns(stamp_ns), p[k], q[k])


class PairPeer:
    """The peer of the pair: pose writers (sensor QoS), ``/clock``, the latched e-stop, command readers."""

    def __init__(self, domain_id: int, rf):
        self.peer = peer = Peer(domain_id)
        self.pose_w = [peer.writer(dds_topic(r.pose_topic), "geometry_msgs/msg/PoseStamped") for r in rf.robots]
        self.clock_w = peer.writer("rt/clock", "rosgraph_msgs/msg/Clock", "clock")
        self.estop_w = peer.writer("rt/quatform/estop", "std_msgs/msg/Bool", "latched")
        self.cmd = Commands(peer, [peer.reader(dds_topic(r.command_topic), "geometry_msgs/msg/TwistStamped")
                                    for r in rf.robots])
        self.sent_ns: list = []

    def step(self, clock_ns: int, poses, estop=None) -> None:
        """Each robot's pose (None: not sent), the e-stop (if given), then ``/clock`` = ``clock_ns``."""
        self.sent_ns.append(time.perf_counter_ns())
        for w, msg in zip(self.pose_w, poses):
            if msg is not None:
                self.peer.write(w, msg)
        if estop is not None:
            self.peer.write(self.estop_w, messages.msg_type("std_msgs/msg/Bool")(data=estop))
        self.peer.write(self.clock_w, messages.msg_type("rosgraph_msgs/msg/Clock")(clock=messages.stamp_ns(clock_ns)))


def started(peer, poses, dt_ns: int, proc, log_path, steps: int = 20) -> int:
    """Step ``/clock`` from 0 with each robot's first pose (``poses``: ``[(p, q)]`` samples) until
    the bridge (started on state 0) answers a step; that step's ``/clock`` time, ns. An
    AssertionError with the bridge's log if it exits or has not answered within ``steps``."""
    c0 = 0
    while True:
        peer.step(c0, tuple(pose(0, p, q, c0) for p, q in poses))
        if peer.cmd.wait_for(c0, 1.0):
            return c0
        assert proc.poll() is None and c0 < steps * dt_ns, Path(log_path).read_text()
        c0 += dt_ns


class ServiceClient:
    """A client of a ROS 2 service on the wire of rmw_cyclonedds: a writer of the request on
    ``rq/<name>Request`` and a reader of the reply on ``rr/<name>Reply``, both with the header
    ``(guid, seq)`` first (:meth:`~quatform.ros2.dds.IdlTypes.service_cls`) and the transport's
    service QoS (:func:`~quatform.ros2.dds.dds_qos`).

    Parameters
    ----------
    peer : Peer
    name : str
        The absolute service name.
    srv_type : str
        ``pkg/srv/Name``.
    """

    def __init__(self, peer: Peer, name: str, srv_type: str):
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from quatform.ros2.dds import dds_service_topics

        self.peer, self.srv_type = peer, srv_type
        rq, rr = dds_service_topics(name)
        req_cls = peer.types.service_cls(f"{srv_type}_Request")
        resp_cls = peer.types.service_cls(f"{srv_type}_Response")
        self.writer = DataWriter(peer.dp, Topic(peer.dp, rq, req_cls), qos=dds_qos("service"))
        self.reader = DataReader(peer.dp, Topic(peer.dp, rr, resp_cls), qos=dds_qos("service"))
        self.waitset = WaitSet(peer.dp)
        self.waitset.attach(ReadCondition(self.reader, SampleState.Any | ViewState.Any | InstanceState.Any))
        self.replies: list = []

    def call(self, guid: int, seq: int, timeout_s: float, **fields):
        """Write the request ``fields`` with the header ``(guid, seq)``; the IDL reply carrying that
        header (None if none within ``timeout_s``). Every reply read is kept in :attr:`replies`."""
        request = self.peer.types.store.types[f"{self.srv_type}_Request"](**fields)
        self.writer.write(self.peer.types.to_idl(request, f"{self.srv_type}_Request", header=(guid, seq)))
        end = time.monotonic() + timeout_s
        while True:
            self.replies += [s for s in self.reader.take(N=100)
                             if getattr(s, "sample_info", None) is not None and s.sample_info.valid_data]
            got = next((s for s in self.replies if (s.guid, s.seq) == (guid, seq)), None)
            if got is not None or time.monotonic() > end:
                return got
            self.waitset.wait(max(0, round(min(0.05, end - time.monotonic()) * 1e9)))
