"""A run as one MCAP file of ROS 2 messages, and back (bags layer).

:func:`write_mcap` writes one world of a :class:`~quatform.sim.log.Log` as a single ``.mcap``
file (ROS 2 profile, CDR messages, ``ros2msg`` schemas embedded, zstd chunks) through
``rosbags.rosbag2.Writer``, the rosbag2 writer with MCAP storage: that writer makes a bag
folder (``metadata.yaml`` beside ``<folder>.mcap``); the ``.mcap`` carries its own schemas,
channels and summary, so it is moved out as ``run.mcap`` and the folder removed. That one
file is what PlotJuggler 4 and Foxglove open, what ``rosbags.rosbag2.Reader`` and
``rosbags.highlevel.AnyReader`` read, and ``ros2 bag info run.mcap`` describes.

Topics (``docs/ecosystem.md`` lists their types and rates): per body ``/<body>/pose``
(``geometry_msgs/PoseStamped``, the actual pose), ``/<body>/pose_desired``,
``/<body>/pose_measured`` (only where the measurement differs from the state),
``/<body>/cmd_vel`` (``geometry_msgs/TwistStamped``), ``/<body>/path`` and
``/<body>/path_desired`` (``nav_msgs/Path``, once); ``/tf`` (``tf2_msgs/TFMessage``: world to
each body, to ``<body>_desired``, to ``formation`` and ``formation_desired``), ``/tf_static``;
``/formation/pose``, ``/formation/pose_desired``, ``/formation/error`` (their difference),
``/formation/edges``
(``visualization_msgs/MarkerArray``, LINE_LIST); MuJoCo runs: each quadrotor's
``/<body>/rotors`` (``quatform_msgs/msg/Rotors``: collective thrust, four motor commands, four
rotor forces, N) and its full attitude in its pose and TF; the UGV-UAV's ``/bebop/odom``
(``nav_msgs/Odometry``: pose and body twist, as ``bebop_autonomy`` publishes); teleoperation: ``/<arm>/joint_states``
(``sensor_msgs/JointState``), ``/slave_wrist/wrench`` (``geometry_msgs/WrenchStamped``);
and every channel of the log as ``/quatform/<channel>``, a message whose fields are the
channel's column names (``quatform_msgs/msg/<Channel>``: a header and one ``float64`` per
column, defined in the file), with ``/quatform/log`` (``std_msgs/String``, once: JSON of the
channels' columns, dtypes and the log's plain meta) so :func:`read_log` rebuilds the log
exactly.

Every message of a topic has one shape, so a topic's ``T`` messages are built at once as CDR
bytes (:class:`.cdr.Batch`); the writer then costs a few microseconds per message.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import messages
from ..errors import InvalidInputError
from ..formations import geometry as g
from ..sim.log import Channel, Log
from ..sim.output import writing
from .cdr import Batch
from .scene import Scene, scene_of

__all__ = ["MCAP_FILE", "INFO_TOPIC", "CHANNEL_PREFIX", "write_mcap", "run_messages", "RunMessages", "read_log",
           "channel_topic", "PATH_POSES", "FORMATION_ERROR_FIELDS"]

#: The file every run writes.
MCAP_FILE = "run.mcap"
#: The topic of the JSON description of the log (channels, columns, dtypes, meta).
INFO_TOPIC = "/quatform/log"
#: The log's channels are ``CHANNEL_PREFIX + name``.
CHANNEL_PREFIX = "/quatform/"
#: The package of the named-channel message types.
MSG_PACKAGE = "quatform_msgs"
#: Poses in each ``nav_msgs/Path`` (the run's samples, evenly thinned to at most this many).
PATH_POSES = 300
#: Scenes of up to this many bodies get topics per body (pose, desired pose, command); a larger team
#: gets ``/robots/poses`` and ``/robots/poses_desired`` (``geometry_msgs/PoseArray``, robot order)
#: instead: rosbags' writer costs about 10 ms per topic and some microseconds per message, so
#: three topics for each of 100 robots would cost more than the run. ``/tf`` names every robot.
PER_BODY_TOPICS_UP_TO = 10
#: Version of the ``/quatform/log`` description.
INFO_VERSION = 1


def channel_topic(name: str) -> str:
    """The topic of the log channel ``name`` (``/quatform/cluster``)."""
    return CHANNEL_PREFIX + name


def _field_names(columns) -> list[str]:
    """Valid, distinct ROS 2 field names for ``columns`` (lower case, ``[a-z0-9_]``, no ``__``, not ``header``)."""
    out, seen = [], {"header"}
    for c in columns:
        s = re.sub(r"_+", "_", re.sub(r"[^a-z0-9_]", "_", str(c).lower())).strip("_")
        s = s if s and s[0].isalpha() else "v_" + s
        s = s.rstrip("_")
        base, k = s, 2
        while s in seen:
            s, k = f"{base}_{k}", k + 1
        seen.add(s)
        out.append(s)
    return out


def _type_names(channels) -> dict:
    """``quatform_msgs/msg/<CamelCase>`` of each channel name, distinct."""
    out, seen = {}, set()
    for name in channels:
        camel = "".join(part[:1].upper() + part[1:] for part in re.split(r"[^A-Za-z0-9]+", name) if part) or "Channel"
        camel = camel if camel[0].isalpha() else "C" + camel
        base, k = camel, 2
        while camel in seen:
            camel, k = f"{base}{k}", k + 1
        seen.add(camel)
        out[name] = f"{MSG_PACKAGE}/msg/{camel}"
    return out


def _plain(value):
    """``value`` if JSON holds it exactly (str, bool, int, finite float, None, lists and dicts of
    them), else a sentinel ``_SKIP``."""
    if isinstance(value, (str, bool)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else _SKIP
    if isinstance(value, (list, tuple)):
        items = [_plain(v) for v in value]
        return _SKIP if any(v is _SKIP for v in items) else {"__tuple__": items} if isinstance(value, tuple) else items
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        items = {k: _plain(v) for k, v in value.items()}
        return _SKIP if any(v is _SKIP for v in items.values()) else items
    return _SKIP


_SKIP = object()


def _unplain(value):
    if isinstance(value, dict):
        if set(value) == {"__tuple__"}:
            return tuple(_unplain(v) for v in value["__tuple__"])
        return {k: _unplain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_unplain(v) for v in value]
    return value


def _stamps(t: np.ndarray) -> np.ndarray:
    """Nanoseconds of the times ``t`` (s): finite, >= 0 and increasing (one line naming the first bad one)."""
    bad = np.flatnonzero(~np.isfinite(t) | (t < 0))
    if bad.size:
        raise InvalidInputError(f"a ROS 2 bag's times must be finite and >= 0 s; the log's t[{bad[0]}] = "
                                f"{t[bad[0]]!r} (shift the scenario to start at t >= 0)")
    ns = np.round(t * 1e9).astype(np.int64)
    back = np.flatnonzero(np.diff(ns) <= 0)
    if back.size:
        raise InvalidInputError(f"a ROS 2 bag's times must increase by at least 1 ns; the log's t[{back[0] + 1}] = "
                                f"{t[back[0] + 1]!r} s follows {t[back[0]]!r} s")
    return ns


class _Topics:
    """The topics of one file being built: ``(topic, msgtype, Batch or one message)`` in order."""

    def __init__(self, store, ns: np.ndarray, every: bool = True):
        self.store, self.ns, self.build_every = store, ns, every
        self.sec = (ns // 1_000_000_000).astype(np.int32)
        self.nanosec = (ns % 1_000_000_000).astype(np.uint32)
        self.every: list = []   # (topic, Batch): one message per sample
        self.once: list = []    # (topic, msgtype, message): one message at the first time

    def stamp_columns(self, *prefix) -> dict:
        return {prefix + ("stamp", "sec"): self.sec, prefix + ("stamp", "nanosec"): self.nanosec}

    def add(self, topic: str, template, columns: dict) -> None:
        batch = Batch.build(self.store, template, columns, self.ns.size) if self.build_every else \
            Batch(template.__msgtype__, np.zeros((0, 0), dtype=np.uint8))
        self.every.append((topic, batch))

    def add_once(self, topic: str, msg) -> None:
        self.once.append((topic, msg.__msgtype__, msg))


def _pose_columns(prefix: tuple, p: np.ndarray, q: np.ndarray, position="position", orientation="orientation") -> dict:
    """Columns of a pose (``p`` (T, 3), ``q`` (T, 4) w, x, y, z) at ``prefix`` (ROS order x, y, z, w by name)."""
    cols = {prefix + (position, a): p[:, i] for i, a in enumerate("xyz")}
    cols.update({prefix + (orientation, a): q[:, i] for i, a in enumerate("wxyz")})
    return cols


_IDENTITY = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])


def _scene_topics(topics: _Topics, scene: Scene, t: np.ndarray) -> None:
    t0 = float(t[0])
    hdr = topics.stamp_columns("header")
    n = len(scene.bodies)
    transforms = []  # (parent, child, p (T, 3), q (T, 4))

    def poses(topic, parent, p, q):
        topics.add(topic, messages.pose_stamped(t0, *_IDENTITY, parent), {**hdr, **_pose_columns(("pose",), p, q)})

    per_body = n <= PER_BODY_TOPICS_UP_TO
    for i, (body, parent) in enumerate(zip(scene.bodies, scene.parents)):
        p, q = scene.position[:, i], scene.quaternion[:, i]
        transforms.append((parent, body, p, q))
        if per_body:
            poses(f"/{body}/pose", parent, p, q)
        if scene.position_desired is not None:
            pd, qd = scene.position_desired[:, i], scene.quaternion_desired[:, i]
            transforms.append((parent, f"{body}_desired", pd, qd))
            if per_body:
                poses(f"/{body}/pose_desired", parent, pd, qd)
        if not per_body:
            continue
        if scene.position_measured is not None:
            poses(f"/{body}/pose_measured", parent, scene.position_measured[:, i], scene.quaternion_measured[:, i])
        if scene.twist is not None:
            tw = scene.twist[:, i]
            cols = {**hdr, **{("twist", part, a): tw[:, 3 * k + j] for k, part in enumerate(("linear", "angular"))
                              for j, a in enumerate("xyz")}}
            topics.add(f"/{body}/cmd_vel", messages.twist_stamped(t0, [0, 0, 0], [0, 0, 0], scene.twist_frames[i]), cols)
    if not per_body:
        for suffix, p, q in (("", scene.position, scene.quaternion),
                             ("_desired", scene.position_desired, scene.quaternion_desired)):
            if p is None:
                continue
            cols = dict(hdr)
            for i in range(n):
                cols.update(_pose_columns(("poses", i), p[:, i], q[:, i]))
            template = messages.pose_array(t0, np.zeros((n, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), scene.parents[0])
            topics.add(f"/robots/poses{suffix}", template, cols)
    for name, pq in (("formation", scene.formation), ("formation_desired", scene.formation_desired)):
        if pq is not None:
            topic = "/formation/pose" if name == "formation" else "/formation/pose_desired"
            poses(topic, "world", *pq)
            transforms.append(("world", name, *pq))
    if scene.formation is not None and scene.formation_desired is not None:
        _formation_error(topics, scene, t0)
    if transforms:
        template = messages.tf_message([messages.transform_stamped(t0, a, b, *_IDENTITY) for a, b, _, _ in transforms])
        cols = {}
        for k, (_, _, p, q) in enumerate(transforms):
            cols.update(topics.stamp_columns("transforms", k, "header"))
            cols.update(_pose_columns(("transforms", k, "transform"), p, q, "translation", "rotation"))
        topics.add("/tf", template, cols)
    if scene.static:
        topics.add_once("/tf_static", messages.tf_message([messages.transform_stamped(t0, a, b, *_IDENTITY)
                                                           for a, b in scene.static]))
    markers, cols = [], {}
    for k, (ns, edges, rgba) in enumerate((("edges", scene.edges, (0.2, 0.4, 1.0, 1.0)),
                                           ("edges_desired", scene.edges_desired, (0.1, 0.8, 0.3, 0.6)))):
        if edges is None:
            continue
        j = len(markers)
        markers.append(messages.line_list(t0, np.zeros((edges.shape[1], 3)), ns=ns, marker_id=k, rgba=rgba))
        cols.update(topics.stamp_columns("markers", j, "header"))
        cols.update({("markers", j, "points", e, a): edges[:, e, c] for e in range(edges.shape[1])
                     for c, a in enumerate("xyz")})
    if markers:
        topics.add("/formation/edges", messages.marker_array(markers), cols)
    for arm in scene.joints:
        template = messages.joint_state(t0, arm.names, np.zeros(len(arm.names)), np.zeros(len(arm.names)),
                                        np.zeros(len(arm.names)))
        cols = {**hdr}
        for part, a in (("position", arm.position), ("velocity", arm.velocity), ("effort", arm.effort)):
            cols.update({(part, j): a[:, j] for j in range(len(arm.names))})
        topics.add(f"/{arm.arm}/joint_states", template, cols)
    for w in scene.wrenches:
        cols = {**hdr, **{("wrench", part, a): arr[:, j] for part, arr in (("force", w.force), ("torque", w.torque))
                          for j, a in enumerate("xyz")}}
        topics.add(f"/{w.name}/wrench", messages.wrench_stamped(t0, [0, 0, 0], [0, 0, 0], w.frame), cols)
    if scene.rotors:
        fields = ["thrust"] + [f"command_{j}" for j in range(1, 5)] + [f"force_{j}" for j in range(1, 5)]
        name = f"{MSG_PACKAGE}/msg/Rotors"
        topics.store.register({name: messages.named_type(fields)})
        template = messages.named_message(topics.store.types[name], t0, fields, np.zeros(len(fields)))
        for r in scene.rotors:
            values = np.concatenate([r.force.sum(axis=1, keepdims=True), r.command, r.force], axis=1)
            topics.add(f"/{r.body}/rotors", template, {**hdr, **{(f,): values[:, j] for j, f in enumerate(fields)}})
    for od in scene.odometry:
        i = scene.bodies.index(od.body)
        parent = scene.parents[i]
        cols = {**hdr, **_pose_columns(("pose", "pose"), od.position, od.quaternion),
                **{("twist", "twist", part, a): v[:, j] for part, v in (("linear", od.linear), ("angular", od.angular))
                   for j, a in enumerate("xyz")}}
        topics.add(f"/{od.body}/odom", messages.odometry(t0, *_IDENTITY, [0, 0, 0], [0, 0, 0], parent, od.body), cols)
    if per_body:
        _paths(topics, scene, t)


#: Fields of ``/formation/error`` (``quatform_msgs/msg/FormationError``).
FORMATION_ERROR_FIELDS = ("x", "y", "z", "angle")


def _formation_error(topics: _Topics, scene: Scene, t0: float) -> None:
    """``/formation/error``: the desired formation frame less the actual one, the same fields for
    every controller (the Foxglove layout plots them): ``x, y, z`` the position error, m, world;
    ``angle`` the rotation between the frames, ``2 acos |w|`` of ``conj(q_c) q_c_des``, rad
    (the rotation angle between the frames: twice Huynh's ``Phi_3 = arccos |q_1 . q_2|``, Huynh
    2009, "Metrics for 3D rotations: comparison and analysis", J. Math. Imaging Vis. 35)."""
    (p, q), (pd, qd) = scene.formation, scene.formation_desired
    w = np.abs(g.mul(g.conj(q), qd)[:, 0])
    values = np.concatenate([pd - p, 2.0 * np.arccos(np.clip(w, 0.0, 1.0))[:, None]], axis=1)
    name = f"{MSG_PACKAGE}/msg/FormationError"
    topics.store.register({name: messages.named_type(FORMATION_ERROR_FIELDS)})
    template = messages.named_message(topics.store.types[name], t0, FORMATION_ERROR_FIELDS,
                                      np.zeros(len(FORMATION_ERROR_FIELDS)))
    topics.add("/formation/error", template, {**topics.stamp_columns("header"),
                                             **{(f,): values[:, j] for j, f in enumerate(FORMATION_ERROR_FIELDS)}})


def _paths(topics: _Topics, scene: Scene, t: np.ndarray) -> None:
    """``/<body>/path`` and ``/<body>/path_desired``: the whole run's poses (thinned), once at the start.

    Every path of one parent frame has one layout, so they are built together as one batch."""
    keep = np.unique(np.linspace(0, t.size - 1, min(t.size, PATH_POSES)).round().astype(int))
    ns = topics.ns[keep]
    sec, nanosec = (ns // 1_000_000_000).astype(np.int32), (ns % 1_000_000_000).astype(np.uint32)
    by_parent: dict = {}
    for i, (body, parent) in enumerate(zip(scene.bodies, scene.parents)):
        for suffix, p, q in (("", scene.position, scene.quaternion),
                             ("_desired", scene.position_desired, scene.quaternion_desired)):
            if p is not None:
                by_parent.setdefault(parent, []).append((f"/{body}/path{suffix}", p[keep, i], q[keep, i]))
    for parent, paths in by_parent.items():
        m = len(paths)
        template = messages.path(float(t[0]), t[keep], np.zeros((keep.size, 3)),
                                 np.tile([1.0, 0.0, 0.0, 0.0], (keep.size, 1)), parent)
        p = np.stack([a for _, a, _ in paths], axis=0)  # (paths, P, 3)
        q = np.stack([b for _, _, b in paths], axis=0)
        cols = {("header", "stamp", "sec"): np.repeat(topics.sec[:1], m),
                ("header", "stamp", "nanosec"): np.repeat(topics.nanosec[:1], m)}
        for j in range(keep.size):
            cols[("poses", j, "header", "stamp", "sec")] = np.repeat(sec[j:j + 1], m)
            cols[("poses", j, "header", "stamp", "nanosec")] = np.repeat(nanosec[j:j + 1], m)
            cols.update({("poses", j, "pose", "position", a): p[:, j, c] for c, a in enumerate("xyz")})
            cols.update({("poses", j, "pose", "orientation", a): q[:, j, c] for c, a in enumerate("wxyz")})
        batch = Batch.build(topics.store, template, cols, m)
        topics.once.extend((topic, batch.msgtype, batch.data[k]) for k, (topic, _, _) in enumerate(paths))


def _channel_topics(topics: _Topics, log: Log) -> dict:
    """Every channel as ``/quatform/<name>`` (its message type registered in ``topics.store``);
    returns the ``/quatform/log`` description of the channels."""
    types = _type_names(log.channels)
    described = {}
    defs = {}
    for name, ch in log.channels.items():
        fields = _field_names(ch.columns)
        defs[types[name]] = messages.named_type(fields)
        described[name] = {"topic": channel_topic(name), "type": types[name], "columns": list(ch.columns),
                           "fields": fields, "dtype": np.asarray(ch.data).dtype.str}
    topics.store.register(defs)
    t0 = float(log.t[0])
    hdr = topics.stamp_columns("header")
    for name, ch in log.channels.items():
        d = described[name]
        template = messages.named_message(topics.store.types[d["type"]], t0, d["fields"], np.zeros(len(d["fields"])))
        data = np.asarray(ch.data, dtype=float)
        topics.add(d["topic"], template, {**hdr, **{(f,): data[:, j] for j, f in enumerate(d["fields"])}})
    return described


def _fresh_store():
    """A new ROS 2 Humble type store (the run's own ``quatform_msgs`` types are registered in it)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


@dataclass(frozen=True)
class RunMessages:
    """A run's messages as ``run.mcap`` holds them, by topic (:func:`run_messages`).

    Attributes
    ----------
    store : rosbags Typestore
        The ROS 2 types, the run's own ``quatform_msgs`` among them.
    ns : ndarray of int64, shape (T,)
        Each sample's stamp (and log time), ns.
    every : list of (topic, msgtype, ndarray)
        The topics with one message per sample: their CDR bytes ``(T, nbytes)`` (uint8).
    once : list of (topic, msgtype, bytes)
        The topics with one message at the first sample (``/quatform/log``, the paths, ``/tf_static``).
    """

    store: object
    ns: np.ndarray
    every: list
    once: list

    def schema(self, msgtype: str) -> str:
        """The ``ros2msg`` schema of ``msgtype`` as ``run.mcap`` embeds it (rosbags' writer's own text)."""
        return self.store.generate_msgdef(msgtype, ros_version=2)[0]


def run_messages(log: Log, *, kind: str | None = None, scene: bool | Scene = True, store=None, every: bool = True,
                 samples: int | None = None) -> RunMessages:
    """The messages of one world's ``log`` by topic, CDR-encoded: what :func:`write_mcap` writes
    (``kind`` and ``scene`` as it takes them) and a live run streams. ``store``: the type store
    of an earlier call on a log of the same run to reuse (rosbags compiles each type's
    serialiser once per store: a fresh one costs about 0.1 s), default a fresh one.
    ``every=False`` serialises the once-per-run topics only (``every`` then holds each topic's
    type with no bytes, ``(0, 0)``); ``samples``: the count ``/quatform/log`` states (default
    ``len(log)``; a live run gives the ticks done with a log of the paths' thinned ticks)."""
    if len(log) == 0:
        raise InvalidInputError("the log has no samples; there is nothing to write to an MCAP file")
    ns = _stamps(log.t)
    topics = _Topics(_fresh_store() if store is None else store, ns, every)
    kind = kind or log.meta.get("kind")
    if isinstance(scene, Scene):
        _scene_topics(topics, scene, log.t)
    elif scene:
        if kind is None:
            raise InvalidInputError("write_mcap needs the log's scenario kind for its poses: give kind= "
                                    "(pair, team, teleop, ugv-uav) or scene=False")
        _scene_topics(topics, scene_of(log, kind), log.t)
    described = _channel_topics(topics, log)
    meta = {k: v for k, v in ((k, _plain(v)) for k, v in log.meta.items()) if v is not _SKIP}
    info = {"version": INFO_VERSION, "kind": kind, "samples": len(log) if samples is None else int(samples), "channels": described, "meta": meta,
            "topics": [topic for topic, _ in topics.every] + [topic for topic, _, _ in topics.once]}
    topics.once.insert(0, (INFO_TOPIC, "std_msgs/msg/String", messages.string(json.dumps(info))))
    once = [(topic, msgtype, bytes(msg) if isinstance(msg, np.ndarray) else
             bytes(topics.store.serialize_cdr(msg, msgtype))) for topic, msgtype, msg in topics.once]
    return RunMessages(topics.store, ns, [(topic, batch.msgtype, batch.data) for topic, batch in topics.every], once)


def write_mcap(log: Log, path, *, kind: str | None = None, world=None, scene: bool | Scene = True) -> Path:
    """Write ``log`` as one MCAP file of ROS 2 messages (see the module docstring for the topics).

    Parameters
    ----------
    log : Log
        One world (a batched log needs ``world``).
    path : path-like
        The ``.mcap`` file (replaced if it exists; written beside and moved in when complete).
    kind : str, optional
        The scenario kind whose :data:`~quatform.bags.scene.SCENES` builder reads the poses
        (default ``log.meta["kind"]``).
    world : int or tuple, optional
        Which world of a batched log to write (MCAP holds one world: the others are left out).
    scene : bool or Scene
        Write the standard messages (poses, commands, TF, markers ...) besides the channels: of
        this :class:`~quatform.bags.scene.Scene` (``scene_of(log, kind)``, built once by a caller
        that also writes the run's Foxglove layout), or of ``scene_of(log, kind)`` when True.

    Returns
    -------
    Path
        ``path``.
    """
    if log.batch_shape:
        if world is None:
            raise InvalidInputError(f"the log holds a batch of worlds {log.batch_shape}; an MCAP file holds one: "
                                    "give world=i (the world to write)")
        log = log.world(world)
    path = Path(path)
    msgs = run_messages(log, kind=kind, scene=scene)
    ns = msgs.ns
    with mcap_writer(path) as writer:
        once = [(writer.add_connection(topic, msgtype, typestore=msgs.store, **_qos(topic)), raw)
                for topic, msgtype, raw in msgs.once]
        every = [(writer.add_connection(topic, msgtype, typestore=msgs.store), data)
                 for topic, msgtype, data in msgs.every]
        for conn, raw in once:
            writer.write(conn, int(ns[0]), memoryview(raw))
        views = [(conn, memoryview(data.tobytes()), data.shape[1]) for conn, data in every]
        write = writer.write
        for k, stamp in enumerate(ns.tolist()):  # time order, so a player reads the file front to back
            for conn, view, size in views:
                write(conn, stamp, view[k * size:(k + 1) * size])
    return path


#: Topics recorded with the transient-local QoS their publishers offer (a late subscriber gets
#: the last message): ``/tf_static``, as tf2's static broadcaster publishes it.
LATCHED_TOPICS = ("/tf_static",)


def _qos(topic: str) -> dict:
    """``add_connection`` keywords of ``topic``: for :data:`LATCHED_TOPICS` the profile tf2_ros's
    ``StaticBroadcasterQoS`` offers (keep last 1, reliable, transient local; other policies at
    ROS 2's defaults), which rosbag2 stores as the channel's ``offered_qos_profiles`` and
    ``ros2 bag play`` offers again; other topics leave it empty (the player's default)."""
    if topic not in LATCHED_TOPICS:
        return {}
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(0, 0)
    latched = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, zero, zero,
                  QosLiveliness.AUTOMATIC, zero, False)
    return {"offered_qos_profiles": [latched]}


@contextlib.contextmanager
def mcap_writer(path, compress: bool = True):
    """An open ``rosbags.rosbag2.Writer`` (MCAP storage, zstd chunks when ``compress``) whose
    bag becomes the one file ``path`` when the block ends without an error.

    rosbags writes a rosbag2 folder (``metadata.yaml`` beside the ``.mcap``); PlotJuggler 4
    opens one ``.mcap`` file, and the file alone holds its schemas, channels and summary, so
    the folder is written beside ``path`` and only its ``.mcap`` is moved in (atomically);
    a failed write leaves ``path`` as it was.

    rosbags names the ``.mcap`` after its folder (``<folder>/<folder>.mcap``) and records that
    name in the rosbag2 metadata the file carries (``relative_file_paths``, ``files``), so the
    folder is ``<stem>`` (``path``'s name less ``.mcap``) inside a staging folder beside
    ``path``: the metadata names the file that is moved in (``run.mcap``)."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    path = Path(path)
    staging = path.with_name(f".{path.name}.partial")
    folder = staging / (path.name.removesuffix(".mcap") or "bag")
    if staging.exists():
        shutil.rmtree(staging)
    try:
        staging.mkdir()
        with writing(path):  # a full disk names the bag
            writer = Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP)
            if compress:
                writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            with writer:
                yield writer
            os.replace(folder / f"{folder.name}.mcap", path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _info(reader, path) -> dict:
    conns = [c for c in reader.connections if c.topic == INFO_TOPIC]
    if not conns:
        raise InvalidInputError(f"{path} is not a quatform run (no {INFO_TOPIC} topic); read a ROS 2 bag's poses "
                                "with quatform.bags.read_poses")
    for conn, _, raw in reader.messages(connections=conns):
        info = json.loads(reader.deserialize(raw, conn.msgtype).data)
        if info.get("version") != INFO_VERSION:
            raise InvalidInputError(f"{path}: {INFO_TOPIC} version {info.get('version')!r}; this quatform reads "
                                    f"version {INFO_VERSION}")
        return info
    raise InvalidInputError(f"{path}: the {INFO_TOPIC} topic has no message")


def read_log(path) -> Log:
    """The :class:`~quatform.sim.log.Log` a quatform ``run.mcap`` was written from.

    Every channel comes back exactly (the same float64 numbers, dtype and column names), the
    times to the nanosecond (the messages' stamps), the meta that JSON holds exactly (strings,
    numbers, flags and tuples of them; objects such as the scenario are left out).

    Parameters
    ----------
    path : path-like
        A ``.mcap`` file (or the rosbag2 folder holding it).
    """
    from .user_bags import open_bag

    with open_bag(path) as reader:
        info = _info(reader, path)
        by_topic = {c.topic: c for c in reader.connections}
        wanted = {d["topic"] for d in info["channels"].values()}
        raw_of: dict = {topic: [] for topic in wanted}
        for conn, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic in wanted]):
            raw_of[conn.topic].append(raw)  # one pass over the file, in time order
        t = None
        channels = []
        for name, d in info["channels"].items():
            conn = by_topic.get(d["topic"])
            raws = raw_of[d["topic"]]
            if conn is None or len(raws) != info["samples"]:
                raise InvalidInputError(f"{path}: topic {d['topic']} (log channel {name!r}) has {len(raws)} messages "
                                        f"for {info['samples']} samples; the file is incomplete: write the run again")
            template = reader.deserialize(raws[0], conn.msgtype)
            data = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), -1)
            paths = [("header", "stamp", "sec"), ("header", "stamp", "nanosec")] + [(f,) for f in d["fields"]]
            cols = Batch.read(reader.typestore, template, data, paths)
            if t is None:
                ns = cols[paths[0]].astype(np.int64) * 1_000_000_000 + cols[paths[1]].astype(np.int64)
                t = ns / 1e9
            values = np.stack([cols[p] for p in paths[2:]], axis=1) if d["fields"] else np.zeros((len(raws), 0))
            channels.append(Channel(name, tuple(d["columns"]), values.astype(np.dtype(d["dtype"]))))
    return Log(np.zeros(0) if t is None else t, channels, {k: _unplain(v) for k, v in info["meta"].items()})
