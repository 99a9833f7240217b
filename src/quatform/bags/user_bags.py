"""A user's ROS 2 bag of poses as arrays (bags layer; ``quatform replay`` reads lab logs with it).

:func:`read_poses` reads ``geometry_msgs/PoseStamped`` and ``nav_msgs/Odometry`` topics (a
motion-capture system's ``/vrpn_client_node/<name>/pose``, a robot's ``odom``) from an MCAP
file, a rosbag2 folder (MCAP or SQLite 3) or a ``.db3`` file into one :class:`PoseTrack` per
topic: times (the messages' header stamps), positions and quaternions ``(w, x, y, z)`` (ROS
writes ``(x, y, z, w)`` by field name; :func:`quatform.messages.pose_from_msg` reorders).

Bad input is one line naming the topic and the fix: a missing topic (with the pose topics the
bag has), a topic of another message type, stamps that do not increase, a NaN, a quaternion
that is not unit (a pose stream's quaternions are unit to float precision; one off by more than
:data:`UNIT_TOLERANCE` is refused, smaller deviations are renormalised).
"""

from __future__ import annotations

import contextlib
import importlib
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import messages
from ..errors import InvalidInputError, NonUnitError, QuatformError
from ..registry import Registry
from .mcap_check import check_mcap

__all__ = ["PoseTrack", "read_poses", "pose_topics", "open_bag", "POSE_TYPES", "UNIT_TOLERANCE", "STAMP_SOURCES"]

#: Message types :func:`read_poses` reads, with the function giving ``(t, p, q_wxyz, frame_id)`` of a
#: message (a registry: another pose type, e.g. PX4's ``VehicleOdometry`` converted to ENU, is one
#: ``POSE_TYPES.add(type name, function)`` beside its function).
POSE_TYPES = Registry("bag pose type")
POSE_TYPES.add("geometry_msgs/msg/PoseStamped", messages.pose_from_msg)
POSE_TYPES.add("nav_msgs/msg/Odometry", messages.odometry_pose)
#: Largest ``| |q| - 1 |`` of a recorded quaternion that is renormalised rather than refused.
UNIT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class PoseTrack:
    """One topic's poses.

    Attributes
    ----------
    topic : str
    frame_id : str
        The frame of the first message's header.
    t : ndarray, shape (T,)
        Header stamps, s, increasing.
    position : ndarray, shape (T, 3)
        m.
    quaternion : ndarray, shape (T, 4)
        Unit ``(w, x, y, z)``, body to ``frame_id``.
    """

    topic: str
    frame_id: str
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray


def _decompression_errors() -> tuple:
    """The exception a damaged zstd chunk raises in rosbags' readers (``compression.zstd`` on
    Python 3.14, else ``backports.zstd``, as rosbags imports it); empty where neither is there."""
    for name in ("compression.zstd", "backports.zstd"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        return (module.ZstdError,)
    return ()


@contextlib.contextmanager
def open_bag(path):
    """An open ``rosbags.highlevel.AnyReader`` of the bag ``path``: an ``.mcap`` or ``.db3`` file, a
    rosbag2 folder (with ``metadata.yaml``) or a folder holding one ``.mcap`` file (a quatform
    run's folder: rosbags reads the file, not such a folder); types the bag does not define
    come from ROS 2 Humble's."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError

    p = Path(path)
    if not p.exists():
        raise InvalidInputError(f"bag {path} does not exist; give an .mcap or .db3 file or a rosbag2 folder")
    if p.is_dir() and not (p / "metadata.yaml").exists():  # a quatform run's folder: its one .mcap
        files = sorted(p.glob("*.mcap"))
        if not files and (p / "metrics.json").is_file():
            raise InvalidInputError(f"this run folder has no run.mcap (written with --no-mcap?): {path}; run it "
                                    "again without --no-mcap")
        if len(files) != 1:
            raise InvalidInputError(f"{path} is a folder without metadata.yaml (not a rosbag2 folder) and holds "
                                    f"{len(files)} .mcap files; give the .mcap file itself")
        p = files[0]
    if p.is_file() and p.suffix not in (".mcap", ".db3"):
        raise InvalidInputError(f"bag {path}: a ROS 2 bag is an .mcap or .db3 file or a rosbag2 folder, not "
                                f"{p.suffix or 'a file without suffix'}")
    for f in ([p] if p.is_file() else sorted(p.glob("*.mcap"))):
        if f.suffix == ".mcap":
            check_mcap(f)  # declared record lengths against the file, before the reader allocates them
    reader = AnyReader([p], default_typestore=messages.typestore())
    damaged = _decompression_errors()
    try:
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError, struct.error, *damaged) as exc:
        raise InvalidInputError(f"bag {path} cannot be read ({' '.join(str(exc).split())[:200]}); give a rosbag2 "
                                "folder or an .mcap file recorded with ros2 bag record") from None
    try:
        yield reader
    except QuatformError:
        raise
    except (ReaderError, AnyReaderError, struct.error, EOFError, *damaged) as exc:  # a chunk found bad while reading it
        raise InvalidInputError(f"bag {path} is truncated or corrupt ({' '.join(str(exc).split())[:200]}); copy or "
                                "record the file again") from None
    finally:
        reader.close()


def pose_topics(path) -> dict:
    """``{topic: message type}`` of the topics of the bag ``path`` that :func:`read_poses` reads."""
    with open_bag(path) as reader:
        return {c.topic: c.msgtype for c in reader.connections if c.msgtype in POSE_TYPES}


#: The time a pose is taken at: its header stamp, or when the recorder received it (the bag's log time).
STAMP_SOURCES = ("header", "log")


def read_poses(path, topics=None, stamps: str = "header") -> dict:
    """The poses of ``topics`` in the bag ``path``, one :class:`PoseTrack` per topic.

    Parameters
    ----------
    path : path-like
        An ``.mcap`` or ``.db3`` file or a rosbag2 folder.
    topics : sequence of str, optional
        The pose topics to read, in order (default: every ``PoseStamped`` and ``Odometry``
        topic of the bag).
    stamps : {"header", "log"}
        ``t`` from each message's ``header.stamp`` (default) or from the bag's log time (when
        the recorder received it: what a live node's stale-pose rule sees).

    Returns
    -------
    dict
        ``{topic: PoseTrack}`` in the order of ``topics``.
    """
    if stamps not in STAMP_SOURCES:
        raise InvalidInputError(f"read_poses: stamps = {stamps!r} is not one of {', '.join(STAMP_SOURCES)}")
    with open_bag(path) as reader:
        by_topic: dict = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, []).append(c)
        poses = sorted(t for t, cs in by_topic.items() if cs[0].msgtype in POSE_TYPES)
        wanted = poses if topics is None else [str(t) for t in topics]
        if not wanted:
            raise InvalidInputError(f"bag {path} has no PoseStamped or Odometry topic (it has "
                                    f"{', '.join(sorted(by_topic)) or 'no topics'}); record the robots' poses")
        out = {}
        for topic in wanted:
            if topic not in by_topic:
                from ..checks import nearest

                raise InvalidInputError(f"bag {path} has no topic {topic!r}{nearest(topic, by_topic)}; its pose topics "
                                        f"are {', '.join(poses) or 'none'}: name one of them (or record {topic})")
            conns = by_topic[topic]
            msgtype = conns[0].msgtype
            if msgtype not in POSE_TYPES:
                raise InvalidInputError(f"bag {path}: topic {topic} carries {msgtype}, not a pose; quatform reads "
                                        f"{' or '.join(POSE_TYPES)}: name a pose topic instead")
            convert = POSE_TYPES[msgtype]
            rows = [convert(reader.deserialize(raw, conn.msgtype)) for conn, _, raw in reader.messages(connections=conns)]
            if stamps == "log":
                times = [ts * 1e-9 for _, ts, _ in reader.messages(connections=conns)]
                rows = [(t, *row[1:]) for t, row in zip(times, rows)]
            out[topic] = _track(path, topic, rows)
    return out


def _track(path, topic: str, rows) -> PoseTrack:
    if not rows:
        raise InvalidInputError(f"bag {path}: topic {topic} has no messages; record it or name another topic")
    t = np.array([r[0] for r in rows])
    p = np.array([r[1] for r in rows])
    q = np.array([r[2] for r in rows])
    bad = np.flatnonzero(~(np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)))
    if bad.size:
        raise InvalidInputError(f"bag {path}: topic {topic} message {bad[0]} (t = {t[bad[0]]:.9f} s) has a NaN or "
                                "infinite pose; drop it from the bag (ros2 bag convert / filter) or re-record")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        k = back[0] + 1
        raise InvalidInputError(f"bag {path}: topic {topic} stamps do not increase: message {k} at t = {t[k]:.9f} s "
                                f"follows t = {t[k - 1]:.9f} s; record with the source's header stamps (a "
                                "monotonic clock) or sort and de-duplicate the messages")
    with np.errstate(over="ignore"):  # a damaged entry (1e200): an infinite norm, refused below, no warning
        norm = np.linalg.norm(q, axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > UNIT_TOLERANCE)
    if off.size:
        raise NonUnitError(f"bag {path}: topic {topic} message {off[0]} has a quaternion of norm {norm[off[0]]:.6g}; "
                           "a pose's orientation must be a unit quaternion: fix the publisher")
    return PoseTrack(topic, rows[0][3], t, p, q / norm[:, None])
