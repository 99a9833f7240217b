"""The DDS transport: ROS 2 on the wire without a ROS installation, through Cyclone DDS (ROS 2 bridge layer).

ROS 2's middleware is DDS (RTPS on UDP), interoperable at the wire level, so a process that
writes ``geometry_msgs::msg::dds_::Twist_`` on the DDS topic ``rt/r1/cmd_vel`` with ROS 2's
QoS is a publisher every ROS 2 node on the same domain sees. :class:`DdsTransport` is a
:class:`~quatform.ros2.transport.Transport` on Cyclone DDS's Python binding (``cyclonedds``,
``pip install -e ".[dds]"``, imported only here), following ROS 2's mapping (rmw_cyclonedds,
rmw_fastrtps; the ROS 2 design article "Topic and Service name mapping to DDS"):

* a topic ``/a/b`` is the DDS topic ``rt/a/b``; the type ``pkg/msg/Name`` the DDS type
  ``pkg::msg::dds_::Name_`` (:func:`dds_topic`, :func:`dds_type_name`);
* a service ``/a/s`` of type ``pkg/srv/S`` is a reader of ``pkg::srv::dds_::S_Request_`` on
  ``rq/a/sRequest`` and a writer of ``pkg::srv::dds_::S_Response_`` on ``rr/a/sReply``
  (:func:`dds_service_topics`), QoS ``QOS["service"]`` (rmw_qos_profile_services_default), in
  rmw_cyclonedds's wire format: the CDR of the request and of the reply starts with the request's
  identity, ``struct { uint64 guid; int64 seq; }`` (rmw_cyclonedds_cpp ``serdata.hpp``,
  ``cdds_request_header_t``: the last 8 bytes of the client's writer GUID, and the request's
  sequence number), followed by the fields; a reply carries its request's header
  (:meth:`IdlTypes.service_cls`). Fast DDS carries the request's identity in the RTPS inline QoS
  instead, so a Fast DDS client does not reach the service;
* the domain is ``ROS_DOMAIN_ID`` (default 0); Cyclone reads its configuration (interfaces,
  peers, multicast) from ``CYCLONEDDS_URI`` as for rmw_cyclonedds;
* samples are XCDR1 (plain CDR, little endian), the data representation ROS 2 uses;
* QoS as :data:`~quatform.ros2.transport.QOS` names them (sensor data best effort, commands
  reliable, the latched e-stop transient local);
* the participant's USER_DATA is ``enclave=/;``, as rmw writes it.

The DDS types are :class:`cyclonedds.idl.IdlStruct` dataclasses generated from one
description of each message, ``rosbags``' type store (:class:`IdlTypes`: the ROS 2 Humble
definitions quatform's messages and bags use, with PX4's ``px4_msgs``), so no message is
written twice; their CDR equals ``rosbags``' byte for byte (``tests/test_ros2_dds.py``). The
node logic's messages stay ``rosbags`` classes: :meth:`IdlTypes.to_idl` and
:meth:`IdlTypes.from_idl` convert field by field.

What ROS 2 nodes do that this transport does not: the ``ros_discovery_info`` topic
(``ros2 node list`` does not list the node; ``ros2 topic list`` and ``echo`` see its topics).

Clock: the system time, or with ``use_sim_time`` (ROS's parameter) the latest
``/clock`` (``rosgraph_msgs/Clock``): timers then fire as ``/clock`` passes them. Messages
taken together are handed on in the order their writers wrote them (DDS source timestamps,
the writers' system clocks), the ``/clock`` reader read first. With ``use_sim_time`` the node
acts at ``/clock`` steps: a message written before a ``/clock`` sample reaches the node before
the timers of that step, one written after it waits for the next ``/clock`` sample (the newest
of each reader's QoS depth kept), however the packets race on the network. So a pose written
before a step is read at that step's tick, and a neighbour's message sent at the tick of step
``k`` is read at step ``k + 1`` in every node (a simulator's lockstep; machines whose clocks
differ by more than a ``/clock`` period delay messages by that difference). Only data waits
(poses, neighbours' messages): a ``control`` subscription (the e-stop) and a service's requests
are handed on as soon as they are read, in the order written, whether or not ``/clock`` moves,
so an e-stop acts at once when the simulator pauses or dies; its reader keeps every sample
(``QOS["estop"]``), so an engage followed by a release before the node reads them still engages
(and zeroes) first.

Configuration: a participant Cyclone cannot create (a ``CYCLONEDDS_URI`` naming a missing file,
malformed XML, an interface this machine lacks) is one line naming ``CYCLONEDDS_URI``,
``ROS_DOMAIN_ID`` and what Cyclone said (its own lines on stderr are caught for it).

A writer of another type on a topic this node reads (a ``PointStamped`` on a pose topic) is
named in one warning line (from DDS's discovery of publications), and a sample that does not
decode is one warning line per topic: neither stops the node.
"""

from __future__ import annotations

import importlib
import itertools
import os
import re
import sys
import tempfile
import time
from collections.abc import Callable

import numpy as np

from ..errors import InvalidInputError, MissingDependencyError
from .transport import QOS, QosProfile, Transport, ros_domain_id

__all__ = ["import_cyclonedds", "dds_topic", "dds_service_topics", "dds_type_name", "ros_type_name", "dds_qos",
           "IdlTypes", "DdsTransport", "DDS_MISSING", "SERVICE_DEFINITIONS", "REQUEST_HEADER"]

#: The line a machine without the binding gets.
DDS_MISSING = ("--transport dds needs Cyclone DDS's Python binding (cyclonedds), which is not installed here: "
               "pip install -e \".[dds]\"")

#: Samples taken per reader and pass.
_TAKE = 256

#: The ROS 2 services the transport serves that ``rosbags``' type store lacks, as ``.srv`` text
#: (request ``---`` response; std_srvs's ``SetBool.srv``, comments left out).
SERVICE_DEFINITIONS = {"std_srvs/srv/SetBool": "bool data\n---\nbool success\nstring message\n"}

#: The request identity rmw_cyclonedds puts before a request's and a reply's fields
#: (``cdds_request_header_t``): the client's writer GUID's last 8 bytes, the sequence number.
REQUEST_HEADER = (("guid", "uint64"), ("seq", "int64"))


def import_cyclonedds():
    """``cyclonedds`` with the modules the transport uses, or :class:`MissingDependencyError` (one line)."""
    try:
        dds = importlib.import_module("cyclonedds")
        for sub in ("core", "domain", "topic", "pub", "sub", "qos", "util", "builtin", "idl", "idl.types"):
            importlib.import_module(f"cyclonedds.{sub}")
    except ImportError:
        raise MissingDependencyError(DDS_MISSING) from None
    return dds


def dds_topic(topic: str) -> str:
    """The DDS topic of the absolute ROS 2 topic ``topic``: ``/r1/cmd_vel`` -> ``rt/r1/cmd_vel``."""
    if not topic.startswith("/"):
        raise InvalidInputError(f"topic {topic!r} is not an absolute ROS 2 name (/...)")
    return "rt" + topic


def dds_service_topics(name: str) -> tuple[str, str]:
    """The request and reply DDS topics of the absolute ROS 2 service ``name``:
    ``/quatform/set_estop`` -> ``("rq/quatform/set_estopRequest", "rr/quatform/set_estopReply")``."""
    if not name.startswith("/"):
        raise InvalidInputError(f"service {name!r} is not an absolute ROS 2 name (/...)")
    return f"rq{name}Request", f"rr{name}Reply"


def dds_type_name(msg_type: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs::msg::dds_::Twist_`` (ROS 2's DDS type name)."""
    pkg, kind, name = msg_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def ros_type_name(dds_name: str) -> str:
    """The ROS 2 name of a DDS type name (:func:`dds_type_name`'s inverse; another name as it is)."""
    parts = dds_name.split("::")
    if len(parts) == 4 and parts[2] == "dds_" and parts[3].endswith("_"):
        return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"
    return dds_name


def dds_qos(profile: QosProfile | str):
    """The Cyclone DDS ``Qos`` of ``profile`` (a :class:`~quatform.ros2.transport.QosProfile` or
    a name of :data:`~quatform.ros2.transport.QOS`): its reliability (a reliable writer blocks
    up to 100 ms on a full history), durability and history, and the XCDR1 data representation."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    p = QOS[profile] if isinstance(profile, str) else profile
    return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)) if p.reliable else
               Policy.Reliability.BestEffort,
               Policy.Durability.TransientLocal if p.transient_local else Policy.Durability.Volatile,
               Policy.History.KeepAll if p.keep_all else Policy.History.KeepLast(p.depth),
               Policy.DataRepresentation(use_cdrv0_representation=True))


#: The prefix of Cyclone's own log lines (``<time> [<domain>] <thread>: ``).
_CYCLONE_PREFIX = re.compile(r"^\s*\d+\.\d+\s+\[\d+\]\s+[^:]*:\s*")


def _participant(domain_id: int, qos):
    """A ``DomainParticipant``; one that Cyclone refuses is one line naming the configuration
    (Cyclone's own lines on file descriptor 2 meanwhile are caught and quoted in it)."""
    from cyclonedds.core import DDSException
    from cyclonedds.domain import DomainParticipant

    sys.stderr.flush()
    with tempfile.TemporaryFile() as caught:
        try:
            saved = os.dup(2)
        except OSError:  # no file descriptor 2 (a daemon's): nothing to catch
            saved = None
        else:
            os.dup2(caught.fileno(), 2)
        try:
            participant, failure = DomainParticipant(domain_id, qos=qos), None
        except DDSException as exc:
            participant, failure = None, exc
        finally:
            if saved is not None:
                os.dup2(saved, 2)
                os.close(saved)
        caught.seek(0)
        said = caught.read().decode(errors="replace")
    if failure is None:
        sys.stderr.write(said)  # what Cyclone says on a participant it creates stays visible
        return participant
    lines = [_CYCLONE_PREFIX.sub("", line).strip().rstrip(".") for line in said.splitlines()]
    why = "; ".join(line for line in lines if line) or str(failure)
    env = {k: f"{k}={os.environ[k]!r}" if k in os.environ else f"{k} unset"
           for k in ("ROS_DOMAIN_ID", "CYCLONEDDS_URI")}
    raise InvalidInputError(
        f"Cyclone DDS cannot create its participant on domain {domain_id} ({env['ROS_DOMAIN_ID']}) with "
        f"{env['CYCLONEDDS_URI']}: {why[:300]}; fix CYCLONEDDS_URI "
        "(a file:// URI of an existing file, or inline XML, naming interfaces this machine has: ip addr) or unset "
        "it for Cyclone's defaults")


class IdlTypes:
    """IDL classes of ROS 2 messages generated from ``rosbags``' type store, and the conversions.

    Parameters
    ----------
    store : rosbags Typestore, optional
        The definitions (default: quatform's, with ``px4_msgs``).
    """

    #: The IDL of ROS 2's primitives (rosidl: ``byte`` is an octet, ``char`` a uint8).
    PRIMITIVES = ("bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
                  "float32", "float64")

    def __init__(self, store=None):
        if store is None:
            from .px4 import register_px4_types

            store = register_px4_types()
        self.store = store
        self._classes: dict = {}
        self._plans: dict = {}
        self._fields: dict = {}
        self._service_classes: dict = {}
        self._register_services()

    def _register_services(self) -> None:
        """Register the request and response messages of :data:`SERVICE_DEFINITIONS` the store
        lacks, as ``pkg/srv/Name_Request`` and ``pkg/srv/Name_Response`` (rosidl's names)."""
        from rosbags.typesys import get_types_from_msg

        types = {}
        for srv, text in SERVICE_DEFINITIONS.items():
            request, response = text.split("---")
            for part, fields in (("Request", request), ("Response", response)):
                name = f"{srv}_{part}"
                if name not in self.store.fielddefs:  # rosbags names it pkg/srv/msg/...: renamed as rosidl names it
                    (definition,) = get_types_from_msg(fields, name).values()
                    types[name] = definition
        if types:
            self.store.register(types)

    def _primitive(self, kind: str, bound: int):
        t = importlib.import_module("cyclonedds.idl.types")
        if kind == "string":
            return t.bounded_str[bound] if bound else str
        if kind == "bool":
            return bool
        return {"byte": t.byte, "char": t.uint8}.get(kind) or getattr(t, kind)

    def _field(self, nodetype, desc):
        """The IDL type of one field, and its plan entry ``(kind, sub)``."""
        from rosbags.interfaces import Nodetype

        t = importlib.import_module("cyclonedds.idl.types")
        if nodetype == Nodetype.BASE:
            return self._primitive(*desc), ("base", desc[0])
        if nodetype == Nodetype.NAME:
            return self.cls(desc), ("struct", desc)
        (sub_type, sub_desc), bound = desc
        if sub_type == Nodetype.BASE:
            inner = self._primitive(*sub_desc)
            kind = ("strings", None) if sub_desc[0] == "string" else ("numbers", sub_desc[0])
        else:
            inner, kind = self.cls(sub_desc), ("structs", sub_desc)
        if nodetype == Nodetype.ARRAY:
            return t.array[inner, bound], kind
        return (t.sequence[inner, bound] if bound else t.sequence[inner]), kind

    def cls(self, msg_type: str):
        """The :class:`cyclonedds.idl.IdlStruct` of ``msg_type`` (``pkg/msg/Name``), typename
        ``pkg::msg::dds_::Name_``; an unknown type is one line."""
        if msg_type in self._classes:
            return self._classes[msg_type]
        if msg_type not in self.store.fielddefs:
            raise InvalidInputError(f"no definition of the ROS 2 message {msg_type} for the dds transport")
        make = importlib.import_module("cyclonedds.idl").make_idl_struct
        fields, plan = {}, []
        for fname, (nodetype, desc) in self.store.fielddefs[msg_type][1]:
            fields[fname], kind = self._field(nodetype, desc)
            plan.append((fname, *kind))
        cls = make(msg_type.replace("/", "_"), dds_type_name(msg_type), fields)
        self._classes[msg_type], self._plans[msg_type], self._fields[msg_type] = cls, tuple(plan), fields
        return cls

    def service_cls(self, msg_type: str):
        """The :class:`cyclonedds.idl.IdlStruct` of a service's request or response ``msg_type``
        (``pkg/srv/Name_Request``, ``pkg/srv/Name_Response``) on the wire of rmw_cyclonedds:
        :data:`REQUEST_HEADER`'s ``guid`` (uint64) and ``seq`` (int64) first, then the fields,
        typename ``pkg::srv::dds_::Name_Request_`` (16 header bytes: the fields keep their
        alignment, so the CDR is the header's 16 bytes followed by the fields' own CDR)."""
        if msg_type not in self._service_classes:
            self.cls(msg_type)
            t = importlib.import_module("cyclonedds.idl.types")
            fields = {name: getattr(t, kind) for name, kind in REQUEST_HEADER}
            clash = set(fields) & set(self._fields[msg_type])
            if clash:
                raise InvalidInputError(f"{msg_type} has a field named {sorted(clash)[0]}, which the dds "
                                        "transport's request header takes")
            fields.update(self._fields[msg_type])
            make = importlib.import_module("cyclonedds.idl").make_idl_struct
            self._service_classes[msg_type] = make(msg_type.replace("/", "_") + "_wire", dds_type_name(msg_type),
                                                   fields)
        return self._service_classes[msg_type]

    def to_idl(self, msg, msg_type: str | None = None, header: tuple[int, int] | None = None):
        """The IDL sample of the ``rosbags`` message ``msg``; with ``header`` ``(guid, seq)``, of a
        service's request or response, that header first (:meth:`service_cls`)."""
        msg_type = msg_type or msg.__msgtype__
        cls = self.cls(msg_type)
        out = {}
        for fname, kind, sub in self._plans[msg_type]:
            v = getattr(msg, fname)
            if kind == "base":
                v = str(v) if sub == "string" else (bool(v) if sub == "bool" else
                                                    (float(v) if sub.startswith("float") else int(v)))
            elif kind == "struct":
                v = self.to_idl(v, sub)
            elif kind == "numbers":
                v = np.asarray(v).tolist()
            elif kind == "strings":
                v = [str(s) for s in v]
            else:
                v = [self.to_idl(s, sub) for s in v]
            out[fname] = v
        if header is not None:
            return self.service_cls(msg_type)(**dict(zip((n for n, _ in REQUEST_HEADER), header)), **out)
        return cls(**out)

    def from_idl(self, sample, msg_type: str):
        """The ``rosbags`` message of the IDL sample ``sample`` (numeric arrays as NumPy arrays,
        as rosbags holds them)."""
        out = {}
        for fname, kind, sub in self._plans[msg_type]:
            v = getattr(sample, fname)
            if kind == "struct":
                v = self.from_idl(v, sub)
            elif kind == "numbers":
                v = np.asarray(v, dtype=_NUMPY.get(sub, sub))
            elif kind == "strings":
                v = list(v)
            elif kind == "structs":
                v = [self.from_idl(s, sub) for s in v]
            out[fname] = v
        return self.store.types[msg_type](**out)


#: NumPy dtypes of the ROS 2 primitives whose names are not NumPy's.
_NUMPY = {"byte": "uint8", "char": "uint8", "bool": "bool"}

_LEVELS = {"info": "INFO", "warning": "WARN", "error": "ERROR"}


class _Timer:
    def __init__(self, period_ns: int, callback: Callable, now_ns: int):
        self.period_ns, self.callback, self.next_due = period_ns, callback, now_ns + period_ns

    def run_if_due(self, now_ns: int) -> None:
        if now_ns >= self.next_due:  # one call, however many periods passed (rcl skips the missed ones)
            self.next_due += self.period_ns * ((now_ns - self.next_due) // self.period_ns + 1)
            self.callback()


class DdsTransport(Transport):
    """A :class:`~quatform.ros2.transport.Transport` on Cyclone DDS (see the module docstring).

    Parameters
    ----------
    domain_id : int, optional
        The DDS domain (default ``ROS_DOMAIN_ID``, else 0).
    use_sim_time : bool
        The node's clock is ``/clock``'s (ROS's ``use_sim_time``), else the system time.
    store : rosbags Typestore, optional
        The message definitions (:class:`IdlTypes`).
    """

    name = "dds"

    def __init__(self, domain_id: int | None = None, use_sim_time: bool = False, store=None):
        import_cyclonedds()
        self.domain_id = ros_domain_id() if domain_id is None else int(domain_id)
        self.use_sim_time = bool(use_sim_time)
        self.types = IdlTypes(store)
        self.participant = None
        self._closed = False

    # -- the node -----------------------------------------------------------------------------
    def open(self, name, namespace=None):
        from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication
        from cyclonedds.core import Policy, Qos, ReadCondition, WaitSet

        self.logger = ".".join(p for p in ((namespace or "").strip("/").replace("/", "."), name) if p)
        self.participant = _participant(self.domain_id, Qos(Policy.Userdata(data=b"enclave=/;")))
        self.waitset = WaitSet(self.participant)
        self.readers: list = []  # (reader, msg_type, topic, callback, control)
        self._served: set = set()  # the readers of service requests: their callbacks take the IDL sample
        self.writers: list = []
        self.topics: dict = {}
        self.reads: dict = {}  # DDS topic -> the ROS type read there
        self.timers: list = []
        self._said: set = set()
        self._clock_ns = 0
        self._clock_written = None  # the source timestamp of the newest /clock sample
        self._pending: list = []  # data (source timestamp, reader, sequence, sample) held for the next /clock step
        self._seq = itertools.count()
        self.depths: list = []
        self.publications = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
        self.waitset.attach(ReadCondition(self.publications, self._mask()))
        if self.use_sim_time:  # read first in every pass (see the module docstring)
            self.subscribe("/clock", "rosgraph_msgs/msg/Clock", "clock", self._on_clock)

    @staticmethod
    def _mask() -> int:
        from cyclonedds.core import InstanceState, SampleState, ViewState

        return SampleState.Any | ViewState.Any | InstanceState.Any

    def _topic(self, topic: str, msg_type: str):
        from cyclonedds.topic import Topic

        key = (dds_topic(topic), msg_type)
        if key not in self.topics:
            self.topics[key] = Topic(self.participant, key[0], self.types.cls(msg_type))
        return self.topics[key]

    def subscribe(self, topic, msg_type, qos, callback, *, control=False):
        from cyclonedds.core import ReadCondition
        from cyclonedds.sub import DataReader

        reader = DataReader(self.participant, self._topic(topic, msg_type), qos=dds_qos(qos))
        self.waitset.attach(ReadCondition(reader, self._mask()))
        self.readers.append((reader, msg_type, topic, callback, bool(control)))
        self.depths.append(QOS[qos].depth)
        self.reads[dds_topic(topic)] = msg_type

    def publisher(self, topic, msg_type, qos):
        from cyclonedds.pub import DataWriter

        writer = DataWriter(self.participant, self._topic(topic, msg_type), qos=dds_qos(qos))
        self.writers.append((writer, QOS[qos].reliable))
        to_idl = self.types.to_idl

        def publish(msg):
            writer.write(to_idl(msg, msg_type))
        return publish

    def service(self, name, srv_type, callback):
        """Serve ``name`` as rmw_cyclonedds does (see the module docstring): each request read on
        ``rq/<name>Request`` is answered at once (a control input, never held to ``/clock``) on
        ``rr/<name>Reply`` with the request's header and ``callback(request)``'s fields."""
        from cyclonedds.core import ReadCondition
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        rq, rr = dds_service_topics(name)
        req_type, resp_type = f"{srv_type}_Request", f"{srv_type}_Response"
        qos = dds_qos("service")
        reader = DataReader(self.participant, Topic(self.participant, rq, self.types.service_cls(req_type)), qos=qos)
        writer = DataWriter(self.participant, Topic(self.participant, rr, self.types.service_cls(resp_type)), qos=qos)
        response = self.types.store.types[resp_type]

        def serve(sample):
            fields = callback(self.types.from_idl(sample, req_type))
            writer.write(self.types.to_idl(response(**fields), resp_type, header=(sample.guid, sample.seq)))

        self.waitset.attach(ReadCondition(reader, self._mask()))
        self._served.add(len(self.readers))
        self.readers.append((reader, req_type, name, serve, True))
        self.depths.append(QOS["service"].depth)
        self.writers.append((writer, True))

    def timer(self, period_s, callback):
        t = _Timer(max(1, round(period_s * 1e9)), callback, self.now_ns())
        self.timers.append(t)
        return t

    def now_ns(self):
        return self._clock_ns if self.use_sim_time else time.time_ns()

    def ok(self):
        return not self._closed and self.participant is not None

    def log(self, level, text):
        """One line on stderr, as rcutils prints it: ``[WARN] [<time>] [<logger>]: text``."""
        stamp = self.now_ns()
        print(f"[{_LEVELS.get(level, level.upper())}] [{stamp // 10**9}.{stamp % 10**9:09d}] [{self.logger}]: {text}",
              file=sys.stderr, flush=True)

    def _warn_once(self, key, text: str) -> None:
        if key not in self._said:
            self._said.add(key)
            self.log("warning", text)

    # -- spinning -----------------------------------------------------------------------------
    def _on_clock(self, msg) -> None:
        from .. import messages

        self._clock_ns = max(self._clock_ns, messages.nanoseconds(msg.clock))  # /clock never goes back
        for t in self.timers:
            t.run_if_due(self._clock_ns)

    def spin_once(self, timeout_s):
        if not self.ok():
            raise InvalidInputError("the dds transport is closed")
        wait_ns = max(0, round(timeout_s * 1e9))
        if self.timers and not self.use_sim_time:
            wait_ns = min(wait_ns, max(0, min(t.next_due for t in self.timers) - self.now_ns()))
        self.waitset.wait(wait_ns)
        self._check_publications()
        self._dispatch()
        if not self.use_sim_time:
            now = self.now_ns()
            for t in self.timers:
                t.run_if_due(now)

    def _dispatch(self) -> None:
        """Take every reader (``/clock`` first) and hand the samples on in the order they were
        written; with ``use_sim_time``, a data sample written after the newest ``/clock`` sample
        waits for the next one, a control sample (the e-stop) never waits (see the module docstring)."""
        samples = self._pending
        for k, (reader, msg_type, topic, _, _) in enumerate(self.readers):
            try:
                got = reader.take(N=_TAKE)
            except Exception as exc:  # noqa: BLE001 - a peer's bytes that do not decode must not stop the node
                self._warn_once(("undecodable", topic), f"a message on {topic} does not decode as {msg_type} "
                                f"({type(exc).__name__}); such messages are not read")
                continue
            for s in got:
                info = getattr(s, "sample_info", None)
                if info is not None and info.valid_data:
                    samples.append((info.source_timestamp, k, next(self._seq), s))
        samples.sort(key=lambda item: item[:3])
        cut = len(samples)
        if self.use_sim_time:
            clocks = [n for n, item in enumerate(samples) if item[1] == 0]
            if clocks or self._clock_written is not None:
                cut = clocks[-1] + 1 if clocks else 0
        control = [r[4] for r in self.readers]
        ready = [item for n, item in enumerate(samples) if n < cut or control[item[1]]]
        self._pending = self._held([item for item in samples[cut:] if not control[item[1]]])
        for written, k, _, s in ready:
            _, msg_type, _, callback, _ = self.readers[k]
            if self.use_sim_time and k == 0:
                self._clock_written = written
            callback(s if k in self._served else self.types.from_idl(s, msg_type))

    def _held(self, samples: list) -> list:
        """The data samples waiting for the next ``/clock`` step, at most each reader's QoS depth of the newest."""
        count: dict = {}
        keep = []
        for item in reversed(samples):
            count[item[1]] = count.get(item[1], 0) + 1
            if count[item[1]] <= self.depths[item[1]]:
                keep.append(item)
        return keep[::-1]

    def _check_publications(self) -> None:
        """One warning line per writer of another type on a topic this node reads."""
        for pub in self.publications.take(N=_TAKE):
            want = self.reads.get(getattr(pub, "topic_name", None))
            if want is None or pub.type_name == dds_type_name(want):
                continue
            topic = pub.topic_name[2:]
            self._warn_once(("type", pub.topic_name, pub.type_name),
                            f"a publisher of {ros_type_name(pub.type_name)} on {topic}, where this node reads {want}: "
                            "its messages are not read (check the publisher, or the robots file's pose_type)")

    def close(self):
        """Wait (up to 1 s) for every reliable reader to acknowledge what was written (the zero
        command), then delete the participant and everything in it."""
        if self.participant is None:
            return
        from cyclonedds.util import duration

        deadline = time.monotonic() + 1.0
        for writer, reliable in self.writers:
            if reliable:
                writer.wait_for_acks(duration(seconds=max(0.0, deadline - time.monotonic())))
        self._closed = True
        self.readers = self.writers = self.timers = []
        self.topics, self.publications, self.waitset, self.participant = {}, None, None, None
