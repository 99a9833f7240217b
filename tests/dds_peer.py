"""A DDS peer on loopback for the dds transport's tests and benchmark: plain Cyclone DDS, ROS 2's
names written out (``rt/...``, ``pkg::msg::dds_::Name_``), the bridge in another process.

Every participant (this process's and the bridge's) reads ``CYCLONEDDS_URI``: the loopback
interface only, multicast off, unicast discovery of the peers on 127.0.0.1, so no packet
leaves 127.0.0.1; each run has its own domain id (``ROS_DOMAIN_ID``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import quatform

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


def loopback_env(folder: Path) -> dict:
    """``CYCLONEDDS_URI`` (a config written into ``folder``) and a ``ROS_DOMAIN_ID`` of this run
    (from the process id: 1..200), for this process and the bridge's."""
    path = folder / "cyclonedds.xml"
    path.write_text(CONFIG)
    return {"CYCLONEDDS_URI": path.resolve().as_uri(), "ROS_DOMAIN_ID": str(1 + os.getpid() % 200)}


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
        from cyclonedds.domain import DomainParticipant

        from quatform.ros2.dds import IdlTypes

        from cyclonedds.core import WaitSet

        self.dp = DomainParticipant(domain_id)
        self.types = IdlTypes()
        self._topics: dict = {}
        self.waitset = WaitSet(self.dp)

    def _topic(self, name: str, msg_type: str):
        from cyclonedds.topic import Topic

        if (name, msg_type) not in self._topics:
            self._topics[name, msg_type] = Topic(self.dp, name, self.types.cls(msg_type))
        return self._topics[name, msg_type]

    @staticmethod
    def _qos(reliable: bool, transient_local: bool, depth: int):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.util import duration

        return Qos(Policy.Reliability.Reliable(duration(seconds=1)) if reliable else Policy.Reliability.BestEffort,
                   Policy.Durability.TransientLocal if transient_local else Policy.Durability.Volatile,
                   Policy.History.KeepLast(depth))

    def writer(self, name: str, msg_type: str, *, reliable=False, transient_local=False, depth=5):
        """A DataWriter on the DDS topic ``name`` (``rt/...``); :meth:`write` writes a rosbags message on it."""
        from cyclonedds.pub import DataWriter

        return DataWriter(self.dp, self._topic(name, msg_type), qos=self._qos(reliable, transient_local, depth))

    def reader(self, name: str, msg_type: str, *, reliable=True, depth=1000):
        """A DataReader on the DDS topic ``name`` (best effort matches a best-effort writer too)."""
        from cyclonedds.sub import DataReader

        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState

        r = DataReader(self.dp, self._topic(name, msg_type), qos=self._qos(reliable, False, depth))
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
