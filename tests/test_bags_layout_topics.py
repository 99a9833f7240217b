"""The Foxglove layout written beside each run's run.mcap references only what that bag holds.

For a short run of every registered scenario kind (through quatform.runs.run, as the CLI writes
it): every topic of the layout's 3-D panel and of its plots is a channel of the run's run.mcap
(read with rosbags), every followed TF frame is in its /tf or /tf_static, every plot has a
series and every series reads a finite number from the last message of its topic (Foxglove's
message-path syntax: ``/topic.field.field`` and ``field[index]``).

Oracle: rosbags' reader and deserialiser of the written file.
"""

import dataclasses
import json
import math
import re

import pytest

from quatform import runs
from quatform.bags import FOXGLOVE_LAYOUT_FILE, MCAP_FILE, SCENES
from quatform.scenarios import KINDS, kind_aliases, load_scenario

#: A short run of each kind: (scenario, replaced fields, options).
SHORT = {
    "pair": ("mas-kitts-helix", {"duration_s": 0.2, "metrics_from_s": 0.0}, {"controller": "quaternion"}),
    "ugv-uav": ("marciano-circle", {"duration_s": 0.3, "transient_s": 0.1}, {}),
    "team": ("team-triangle-over-ugv", {"duration_s": 0.2, "metrics_from_s": 0.0}, {"controller": "quaternion"}),
    "teleop": ("teleop-wall-contact", {"duration_s": 0.05}, {}),
    "network": ("net-switching", {"duration_s": 0.2}, {}),
}
#: A team too large for topics per body (its robots drawn as pose arrays).
LARGE_TEAM = ("team-grid-100", {"duration_s": 0.1, "metrics_from_s": 0.0}, {"controller": "quaternion"})


def _bag(path):
    """``({topic: last message}, TF frames)`` of a run.mcap, read by rosbags."""
    from rosbags.highlevel import AnyReader

    last, frames = {}, set()
    with AnyReader([path]) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            last[conn.topic] = msg
            if conn.topic in ("/tf", "/tf_static"):
                for t in msg.transforms:
                    frames.update((t.header.frame_id, t.child_frame_id))
    return last, frames


def _value(msg, path: str) -> float:
    """The number at Foxglove message path ``path`` (``a.b[2].c``) of ``msg``."""
    for part in path.split("."):
        m = re.fullmatch(r"(\w+)(?:\[(\d+)\])?", part)
        msg = getattr(msg, m.group(1))
        if m.group(2) is not None:
            msg = msg[int(m.group(2))]
    return float(msg)


def _run(tmp_path, name, changes, options):
    sc = dataclasses.replace(load_scenario(name), **changes)
    runs.run(sc, tmp_path, plots=False, quiet=True, **options)
    return json.loads((tmp_path / FOXGLOVE_LAYOUT_FILE).read_text()), _bag(tmp_path / MCAP_FILE)


def _check(layout, last, frames):
    config = layout["configById"]
    three_d = [c for k, c in config.items() if k.startswith("3D!")]
    plots = {k: c for k, c in config.items() if k.startswith("Plot!")}
    assert three_d and plots
    for panel in three_d:
        assert panel["followTf"] in frames
        missing = sorted(t for t in panel["topics"] if t not in last)
        assert not missing, f"the 3-D panel shows topics the bag lacks: {missing}"
    for key, panel in plots.items():
        assert panel["paths"] and panel["foxglovePanelTitle"] and "title" not in panel, key
        for series in panel["paths"]:
            topic, _, field = series["value"].partition(".")
            assert topic in last, f"{key} plots {series['value']}: the bag has no {topic}"
            assert math.isfinite(_value(last[topic], field)), series["value"]

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(config)  # every panel is placed, once


def test_every_kind_is_covered():
    # scenes by the name a kind's parts are registered under: its own, or an alias it reads ("pair")
    assert set(SHORT) == set(SCENES) and {kind_aliases().get(k, k) for k in SHORT} == set(KINDS)


@pytest.mark.parametrize("kind", sorted(SHORT))
def test_a_runs_foxglove_layout_references_only_topics_its_bag_has(tmp_path, kind):
    layout, (last, frames) = _run(tmp_path, *SHORT[kind])
    _check(layout, last, frames)
    topics = {s["value"].split(".", 1)[0] for c in layout["configById"].values() for s in c.get("paths", [])}
    if kind == "teleop":  # the master and the slave, the task error, the torques, the wrench
        assert {"/master_hand/pose", "/slave_hand/pose", "/quatform/e", "/master/joint_states",
                "/slave/joint_states", "/slave_wrist/wrench"} <= topics
        assert {"/master_hand/path", "/slave_hand/path"} <= set(layout["configById"]["3D!quatform"]["topics"])
    elif kind == "network":  # the consensus error, the links' counts, the delivered edges
        assert {"/quatform/consensus_error", "/quatform/network"} <= topics
        shown = set(layout["configById"]["3D!quatform"]["topics"])
        assert {"/robot_1/path", "/robot_1/path_desired", "/formation/edges"} <= shown
    else:  # the formation frame against the reference, its error, the singularity measure
        assert {"/formation/pose", "/formation/pose_desired", "/formation/error", "/quatform/singularity"} <= topics
        shown = set(layout["configById"]["3D!quatform"]["topics"])
        bodies = {"pair": ("robot_1", "robot_2"), "ugv-uav": ("pioneer", "bebop"),
                  "team": ("robot_1", "robot_2", "robot_3", "robot_4")}[kind]
        assert {f"/{b}/path{s}" for b in bodies for s in ("", "_desired")} | {"/formation/edges"} <= shown


def test_a_large_teams_layout_shows_its_pose_arrays(tmp_path):
    layout, (last, frames) = _run(tmp_path, *LARGE_TEAM)
    _check(layout, last, frames)
    assert {"/robots/poses", "/robots/poses_desired"} <= set(layout["configById"]["3D!quatform"]["topics"])
