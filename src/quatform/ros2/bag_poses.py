"""Reading the robots' pose messages from a recorded ROS 2 bag (ROS 2 bridge layer).

:func:`read_bag_poses` opens the bag with :func:`quatform.bags.open_bag` (an ``.mcap`` or
``.db3`` file or a rosbag2 folder; PX4's message definitions registered) and returns every
robot's pose *messages* with their times: the bridge reads velocities (odometry) and PX4's
NED/FRD frames from the messages themselves, so this keeps them rather than the position
and quaternion arrays of :func:`quatform.bags.read_poses`. Bad input is one line naming the
topic and the fix: a missing topic, a topic of another type, a topic without messages, time
stamps that do not increase (equal ones too, as :func:`quatform.bags.read_poses`; messages are
counted from 0 in both). A NaN or non-unit pose is not refused here: the bridge drops it as a
lost frame, as the live node does, so a replay gives the node's commands.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bags.user_bags import STAMP_SOURCES, open_bag
from ..errors import InvalidInputError
from .endpoints import POSE_READERS
from .px4 import register_px4_types
from .robots_file import RobotsFile

__all__ = ["BagPoses", "read_bag_poses", "STAMP_SOURCES"]



@dataclass(frozen=True)
class BagPoses:
    """Every robot's pose messages of a bag.

    Attributes
    ----------
    times_ns : tuple of ndarray (int64), one per robot
        Each message's time, ns, increasing.
    messages : tuple of lists, one per robot
        The deserialised messages, in time order.
    topics : dict
        Every topic of the bag and its type.
    """

    times_ns: tuple
    messages: tuple
    topics: dict


def read_bag_poses(bag, robots: RobotsFile, stamps: str = "header") -> BagPoses:
    """Each robot's pose messages of ``bag`` (``robots``: the topics and types; ``stamps``: one of
    :data:`STAMP_SOURCES`)."""
    if stamps not in STAMP_SOURCES:
        raise InvalidInputError(f"--stamps {stamps!r} is not one of {', '.join(STAMP_SOURCES)}")
    path = Path(bag)
    register_px4_types()  # the bag may hold PX4's VehicleOdometry
    with open_bag(path) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        for link in robots.robots:
            want = POSE_READERS[link.pose_type].msg_type
            have = topics.get(link.pose_topic)
            if have is None:
                pose_like = [f"{t} ({ty})" for t, ty in topics.items()
                             if ty in [r.msg_type for r in POSE_READERS.values()]]
                raise InvalidInputError(
                    f"{path}: no topic {link.pose_topic} (robot {link.name!r} pose_topic in {robots.where}); the bag's "
                    f"pose topics: {', '.join(pose_like) or 'none'}; fix pose_topic or record the topic")
            if have != want:
                other = [k for k, r in POSE_READERS.items() if r.msg_type == have]
                fix = (f"set pose_type = {other[0]!r}" if other else
                       f"record a {', '.join(r.msg_type for r in POSE_READERS.values())}")
                raise InvalidInputError(f"{path}: topic {link.pose_topic} holds {have}, but robot {link.name!r} has "
                                        f"pose_type = {link.pose_type!r} ({want}); {fix}")
        index = {link.pose_topic: i for i, link in enumerate(robots.robots)}
        times = [[] for _ in robots.robots]
        msgs = [[] for _ in robots.robots]
        conns = [c for c in reader.connections if c.topic in index]
        for conn, log_ns, raw in reader.messages(connections=conns):
            i = index[conn.topic]
            msg = reader.deserialize(raw, conn.msgtype)
            if stamps == "log":
                t_ns = int(log_ns)
            else:  # the header stamp in integer ns (float seconds would move an epoch stamp by ~100 ns)
                t_ns = POSE_READERS[robots.robots[i].pose_type].stamp_ns(msg)
            times[i].append(t_ns)
            msgs[i].append(msg)
    out = []
    for link, ts in zip(robots.robots, times):
        if not ts:
            raise InvalidInputError(f"{path}: topic {link.pose_topic} (robot {link.name!r}) has no messages; record "
                                    "the robot's poses")
        a = np.asarray(ts, dtype=np.int64)
        back = np.flatnonzero(np.diff(a) <= 0)  # the rule of quatform.bags.read_poses: equal stamps too
        if back.size:
            k = int(back[0]) + 1
            fix = ("fix the publisher's clock (a monotonic one), or replay with --stamps log (the recorder's "
                   "receive times)" if stamps == "header" else "sort and de-duplicate the messages")
            raise InvalidInputError(
                f"bag {path}: topic {link.pose_topic} (robot {link.name!r}) {stamps} stamps do not increase: "
                f"message {k} (counted from 0) at t = {a[k] * 1e-9:.9f} s follows t = {a[k - 1] * 1e-9:.9f} s; {fix}")
        out.append(a)
    return BagPoses(tuple(out), tuple(msgs), topics)
