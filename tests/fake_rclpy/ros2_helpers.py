"""Shared helpers of the ROS 2 bridge tests: short scenarios, robots files, pose bags (no ROS)."""

from __future__ import annotations

import dataclasses
import re
import textwrap
from pathlib import Path

import numpy as np

from quatform import messages
from quatform.formations import geometry as g
from quatform.scenarios import builtin_scenarios, load_scenario

PAIR_ROBOTS = """
[bridge]
start_timeout_s = 1.0

[[robots]]
name = "r1"
namespace = "/r1"
pose_topic = "/vrpn_client_node/r1/pose"
timeout_s = 0.05

[[robots]]
name = "r2"
namespace = "/r2"
pose_topic = "/vrpn_client_node/r2/pose"
timeout_s = 0.05
"""


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text))
    return path


def short_pair(duration_s: float = 1.0):
    """seed 000's helix, ``duration_s`` long (metrics from 0)."""
    return dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=duration_s, metrics_from_s=0.0)


def short_triangle(folder: Path, duration_s: float = 1.0):
    """The team-triangle-over-ugv scenario (a Pioneer and three quadrotors) without its move, short."""
    src = builtin_scenarios()["team-triangle-over-ugv"].read_text()
    src = re.sub(r"(?m)^duration_s = .*$", f"duration_s = {duration_s}", src, count=1)
    src = src.replace("metrics_from_s = 5.0", "metrics_from_s = 0.0")
    src = re.sub(r"\[\[shape.moves\]\][\s\S]*?(?=\n\[path\])", "", src)
    return load_scenario(write(folder / "triangle.toml", src))


def robot_poses(models, slices, x):
    """Each robot's ``(position (T, 3), quaternion (T, 4))`` of the plant states ``x`` (T, n): the
    pose a motion capture sees (a Pioneer's: the middle of its wheel axis, ``a`` behind the
    control point)."""
    out = []
    for model, s in zip(models, slices):
        xs = x[:, s]
        name = type(model).__name__
        if name == "FreeBodyRobot":
            out.append((xs[:, 0:3], xs[:, 3:7]))
        elif name == "Pioneer":
            psi = xs[:, 2]
            p = np.stack([xs[:, 0] - model.a * np.cos(psi), xs[:, 1] - model.a * np.sin(psi), np.zeros_like(psi)], -1)
            out.append((p, g.q_yaw(psi)))
        elif name == "PlanarHolonomicRobot":
            out.append((np.stack([xs[:, 0], xs[:, 1], np.zeros(len(xs))], -1), g.q_yaw(xs[:, 2])))
        else:
            out.append((xs[:, 0:3], g.q_yaw(xs[:, 3])))
    return out


def pose_messages(poses, times_s):
    """``PoseStamped`` messages of :func:`robot_poses`' output at ``times_s``: per robot a list."""
    return [[messages.pose_stamped(t, p[k], q[k]) for k, t in enumerate(times_s)] for p, q in poses]


def write_bag(path: Path, streams) -> Path:
    """A rosbag2 folder in MCAP storage; ``streams``: ``(topic, msg_type, [(t_ns, msg), ...])``."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from quatform.ros2.px4 import register_px4_types

    store = register_px4_types()
    rows = []
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        for topic, typ, msgs in streams:
            c = w.add_connection(topic, typ, typestore=store)
            rows.extend((t, i, c, m, typ) for i, (t, m) in enumerate(msgs))
        for t, _, c, m, typ in sorted(rows, key=lambda r: r[0]):
            w.write(c, t, store.serialize_cdr(m, typ))
    return path


def simulated_pair_bag(folder: Path, duration_s: float) -> dict:
    """The helix (``duration_s``) simulated with the quaternion controller and its poses written
    to an MCAP bag at the tick times: ``{"bag", "robots", "rf", "sc", "log", "exp", "msgs", "ns"}``."""
    from quatform.ros2.bridge import FormationBridge, experiment_for
    from quatform.ros2.robots_file import read_robots_file

    sc = short_pair(duration_s)
    exp = experiment_for(sc, "quaternion")
    log = exp.run()
    robots = write(folder / "robots.toml", PAIR_ROBOTS)
    rf = read_robots_file(robots)
    pr = FormationBridge(exp, rf).plant_robots
    msgs = pose_messages(robot_poses(pr.models, pr.state_slices, log["state"]), log.t)
    ns = [int(round(t * 1e9)) for t in log.t]
    bag = write_bag(folder / "lab", [(link.pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, m)))
                                     for link, m in zip(rf.robots, msgs)])
    return {"bag": bag, "robots": robots, "rf": rf, "sc": sc, "log": log, "exp": exp, "msgs": msgs, "ns": ns}
