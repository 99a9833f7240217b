"""``quatform replay``: a controller offline on a recorded bag's poses; bad bags are one line."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from quatform import messages
from quatform.cli import main
from quatform.errors import InvalidInputError
from quatform.ros2.bag_poses import read_bag_poses
from quatform.ros2.bridge import FormationBridge, experiment_for
from quatform.ros2.replay import replay
from quatform.ros2.robots_file import read_robots_file

_spec = importlib.util.spec_from_file_location("ros2_helpers", Path(__file__).parent / "fake_rclpy" / "ros2_helpers.py")
H = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(H)


@pytest.fixture
def pair_bag(tmp_path):
    """The helix (0.5 s) simulated, its poses written to an MCAP bag at the tick times; with
    the scenario file, the robots file and the simulated log."""
    # the CLI's scenario: the same reference over the bag's 0.5 s
    return {**H.simulated_pair_bag(tmp_path, 0.5), "scenario": "mas-kitts-helix"}


def test_replay_at_pose_times_gives_the_simulations_commands(pair_bag, tmp_path):
    out = tmp_path / "out"
    res = replay(pair_bag["bag"], pair_bag["sc"], pair_bag["robots"], out, controller="quaternion")
    log = pair_bag["log"]
    np.testing.assert_allclose(np.array([t.u for t in res.ticks]), log["command"], rtol=0, atol=1e-12)
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "commands.csv", "commands.mcap", "commands.png", "metrics.json"]
    m = json.loads((out / "metrics.json").read_text())
    assert m["ticks"] == m["ok_ticks"] == len(log.t) and m["stale_ticks"] == 0 and m["nonfinite_commands"] == 0
    assert m["poses"] == {"r1": len(log.t), "r2": len(log.t)} and m["controller"] == "quaternion"
    # the tracking error leaves out the identity's scalar parts (1 at zero error)
    names = pair_bag["exp"].controller.signal_columns()["error"]
    vec = [j for j, n in enumerate(names) if not n.endswith("_w")]
    want = np.abs(log["error"][:, vec]).max(axis=0)
    assert set(m["max_abs_tracking_error_by_variable"]) == {names[j] for j in vec} and "q_c_w" not in names[vec[3]]
    np.testing.assert_allclose(list(m["max_abs_tracking_error_by_variable"].values()), want, rtol=0, atol=1e-11)
    assert m["max_abs_tracking_error"] == pytest.approx(want.max(), abs=1e-12) and want.max() < 0.05
    assert "max_abs_error" not in m
    head = (out / "commands.csv").read_text().splitlines()[0].split(",")
    assert head[:4] == ["t", "reference_time", "status", "u_x1"] and "r2_angular_z" in head and "measured_theta2" in head
    # commands.mcap: the node's topics and messages, one per tick
    from rosbags.highlevel import AnyReader

    with AnyReader([out / "commands.mcap"]) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics == {"/r1/cmd_vel": "geometry_msgs/msg/TwistStamped", "/r2/cmd_vel": "geometry_msgs/msg/TwistStamped"}
        got = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
               if c.topic == "/r2/cmd_vel"]
    assert len(got) == len(log.t)
    lin, ang = messages.twist_from_msg(got[-1])
    np.testing.assert_allclose(np.r_[lin, ang[2]], log["command"][-1, 4:8], atol=1e-12)


def test_replay_cli_and_stale_frames(pair_bag, tmp_path, capsys):
    rf, msgs, ns = pair_bag["rf"], pair_bag["msgs"], pair_bag["ns"]
    keep = [k for k in range(len(ns)) if not 10 < k < 30]  # r1's mocap lost for 190 ms
    bag = H.write_bag(tmp_path / "gap", [
        (rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped", [(ns[k], msgs[0][k]) for k in keep]),
        (rf.robots[1].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, msgs[1])))])
    out = tmp_path / "gap-out"
    rc = main(["replay", str(bag), "--scenario", str(pair_bag["scenario"]), "--robots", str(pair_bag["robots"]),
               "--controller", "quaternion", "--rate", "50", "--out", str(out), "--no-plots"])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["rate_hz"] == 50.0 and m["stale_robots"] == ["r1"]
    # 50 Hz ticks at 20 ms ... 500 ms; r1's last pose before the gap at 100 ms, 50 ms timeout: 160 ... 280 ms stale
    assert m["ticks"] == 25 and m["stale_ticks"] == 7
    rows = np.loadtxt(out / "commands.csv", delimiter=",", skiprows=1)
    stale = rows[:, 2] == 1
    np.testing.assert_allclose(rows[stale, 0], np.arange(0.16, 0.285, 0.02), atol=1e-9)
    assert np.all(rows[stale, 3:11] == 0)
    assert "files in" in capsys.readouterr().out


def _cli_error(args, capsys):
    rc = main(args)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "Traceback" not in err
    return err


def test_bad_bags_are_one_line(pair_bag, tmp_path, capsys):
    rf, msgs, ns = pair_bag["rf"], pair_bag["msgs"], pair_bag["ns"]
    base = ["--scenario", str(pair_bag["scenario"]), "--robots", str(pair_bag["robots"]), "--controller",
            "quaternion", "--out", str(tmp_path / "o")]
    err = _cli_error(["replay", str(tmp_path / "nope"), *base], capsys)
    assert "does not exist" in err
    one = H.write_bag(tmp_path / "one", [(rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped",
                                          list(zip(ns, msgs[0])))])
    err = _cli_error(["replay", str(one), *base], capsys)
    assert "no topic /vrpn_client_node/r2/pose" in err and "robot 'r2'" in err and "/vrpn_client_node/r1/pose" in err
    odo = messages.msg_type("geometry_msgs/msg/PointStamped")
    wrong = H.write_bag(tmp_path / "wrong", [
        (rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, msgs[0]))),
        (rf.robots[1].pose_topic, "geometry_msgs/msg/PointStamped",
         [(t, odo(header=m.header, point=m.pose.position)) for t, m in zip(ns, msgs[1])])])
    err = _cli_error(["replay", str(wrong), *base], capsys)
    assert "/vrpn_client_node/r2/pose holds geometry_msgs/msg/PointStamped" in err and "pose_type = 'pose'" in err
    back = list(zip(ns, msgs[1]))
    back[5], back[6] = (back[5][0], back[6][1]), (back[6][0], back[5][1])  # header stamps out of order
    swapped = H.write_bag(tmp_path / "back", [
        (rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, msgs[0]))),
        (rf.robots[1].pose_topic, "geometry_msgs/msg/PoseStamped", back)])
    err = _cli_error(["replay", str(swapped), *base], capsys)
    assert "/vrpn_client_node/r2/pose" in err and "message 6 (counted from 0)" in err and "--stamps log" in err
    assert len(read_bag_poses(swapped, rf, "log").times_ns[1]) == len(ns)  # by receive time it reads
    _same_refusal_as_read_poses(swapped, rf.robots[1].pose_topic, "message 6 ")
    # stamps that never change (a publisher that does not stamp) tick once: refused
    frozen = H.pose_messages([(_positions(msgs[1]), _quaternions(msgs[1]))], np.full(len(ns), 0.25))[0]
    still = H.write_bag(tmp_path / "still", [
        (rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, msgs[0]))),
        (rf.robots[1].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns, frozen)))])
    err = _cli_error(["replay", str(still), *base], capsys)
    assert "r2" in err and "do not increase" in err and "message 1 (counted from 0)" in err and "--stamps log" in err
    _same_refusal_as_read_poses(still, rf.robots[1].pose_topic, "message 1 ")
    assert len(read_bag_poses(still, rf, "log").times_ns[1]) == len(ns)
    err = _cli_error(["replay", str(one), *base[:4], "--robots", str(H.write(tmp_path / "dup.toml", """
        [[robots]]
        name = "a"
        pose_topic = "/p"
        [[robots]]
        name = "b"
        pose_topic = "/p"
        """)), "--out", str(tmp_path / "o")], capsys)
    assert "the topic /p is named twice" in err
    assert not (tmp_path / "o").exists()


def _positions(msgs):
    return np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in msgs])


def _quaternions(msgs):
    return np.array([[m.pose.orientation.w, m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z]
                     for m in msgs])


def _same_refusal_as_read_poses(bag, topic, needle):
    """quatform.bags.read_poses refuses the bag too, naming the same message."""
    from quatform.bags import read_poses

    with pytest.raises(InvalidInputError, match="do not increase") as info:
        read_poses(bag, [topic])
    assert needle in str(info.value)


def test_ros2_command_without_rclpy_is_one_line(pair_bag, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "rclpy", None)
    for transport in ("rclpy", "auto"):
        if transport == "auto":  # neither middleware importable: one line naming both installs
            monkeypatch.setitem(sys.modules, "cyclonedds", None)
        err = _cli_error(["ros2", "--scenario", str(pair_bag["scenario"]), "--robots", str(pair_bag["robots"]),
                          "--controller", "quaternion", "--transport", transport], capsys)
        assert "source your ROS 2 installation" in err and ".[dds]" in err


def test_replay_refuses_a_bag_without_a_tick(pair_bag, tmp_path):
    rf, msgs, ns = pair_bag["rf"], pair_bag["msgs"], pair_bag["ns"]
    bag = H.write_bag(tmp_path / "late", [
        (rf.robots[0].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns[:3], msgs[0][:3]))),
        (rf.robots[1].pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(ns[5:6], msgs[1][5:6])))])
    with pytest.raises(InvalidInputError, match="no tick"):
        replay(bag, pair_bag["sc"], rf, tmp_path / "x", controller="quaternion", rate_hz=10.0)


def _robots_toml(n: int) -> str:
    return "".join(f'[[robots]]\nname = "robot_{i}"\npose_topic = "/robot_{i}/pose"\ncommand_type = "twist-stamped"\n'
                   for i in range(1, n + 1))


def _replay_of_a_run(tmp_path, scenario, controller: str, n_robots: int):
    """``quatform run`` of ``scenario``, its run.mcap replayed through ``replay`` with a robots file
    of ``/robot_i/pose``: (the ticks' commands, the run's timeseries.csv commands at the tick times)."""
    from quatform.runs import run

    run(scenario, tmp_path / "run", plots=False, quiet=True, controller=controller)
    robots = H.write(tmp_path / "robots.toml", _robots_toml(n_robots))
    res = replay(tmp_path / "run" / "run.mcap", scenario, robots, tmp_path / "replay", controller=controller,
                 plots=False)
    names = experiment_for(scenario, controller).controller.command_names
    with open(tmp_path / "run" / "timeseries.csv") as f:
        head = f.readline().strip().split(",")
    table = np.loadtxt(tmp_path / "run" / "timeseries.csv", delimiter=",", skiprows=1, ndmin=2)
    t_run, t_tick = table[:, 0], np.array([tk.t for tk in res.ticks])
    assert res.metrics["ok_ticks"] == len(t_tick) == len(t_run)  # a tick at every pose time: every step
    np.testing.assert_allclose(t_tick, t_run, rtol=0, atol=1e-9)
    return np.array([tk.u for tk in res.ticks]), table[:, [head.index(n) for n in names]]


def test_replaying_a_runs_mcap_gives_the_runs_commands(tmp_path):
    """A real ``quatform run mas-kitts-helix`` run.mcap replayed gives its commands (timeseries.csv's,
    9 significant digits) at the pose times."""
    got, want = _replay_of_a_run(tmp_path, "mas-kitts-helix", "quaternion", 2)
    assert np.abs(want).max() > 0.05  # the helix moves: the commands are not all zero
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_replaying_a_pioneer_runs_mcap_gives_the_runs_commands(tmp_path):
    """team-triangle-over-ugv (a Pioneer and three quadrotors; its first 10 s without the shape's
    moves): replayed, the run's commands."""
    got, want = _replay_of_a_run(tmp_path, H.short_triangle(tmp_path, 10.0), "quaternion", 4)
    assert np.abs(want).max() > 0.05
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


#: A wall-clock bag: 1.7e9 s since the epoch, plus an odd 123 ns so no stamp is a round number.
EPOCH_NS = 1_700_000_000_000_000_123


@pytest.fixture(scope="module")
def epoch_replay(tmp_path_factory):
    """The helix's 80 s at 100 Hz recorded with epoch stamps (integer ns), replayed (no plots)."""
    tmp = tmp_path_factory.mktemp("epoch")
    sc = H.short_pair(80.0)
    exp = experiment_for(sc, "quaternion")
    log = exp.run()
    robots = H.write(tmp / "robots.toml", H.PAIR_ROBOTS)
    rf = read_robots_file(robots)
    pr = FormationBridge(exp, rf).plant_robots
    ns = [EPOCH_NS + k * 10_000_000 for k in range(len(log.t))]
    poses = H.robot_poses(pr.models, pr.state_slices, log["state"])
    time = messages.msg_type("builtin_interfaces/msg/Time")

    def pose(n, p, q):  # stamped in integer ns, as a recorder stamps it
        msg = messages.pose_stamped(0.0, p, q)
        msg.header.stamp = time(sec=n // 1_000_000_000, nanosec=n % 1_000_000_000)
        return msg

    streams = [(link.pose_topic, "geometry_msgs/msg/PoseStamped", [(n, pose(n, p[k], q[k])) for k, n in enumerate(ns)])
               for link, (p, q) in zip(rf.robots, poses)]
    bag = H.write_bag(tmp / "lab", streams)
    out = tmp / "out"
    replay(bag, sc, robots, out, controller="quaternion", plots=False)
    return {"ns": ns, "out": out, "log": log}


def test_commands_csv_of_a_wall_clock_bag_keeps_every_stamp(epoch_replay):
    """commands.csv's t is not written with 9 significant digits (80 s at 1.7e9 s would give 9
    distinct values): each row's t reads, as a decimal, the pose stamp of its tick to the nanosecond."""
    lines = (epoch_replay["out"] / "commands.csv").read_text().splitlines()
    head = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    t_text = [r[head.index("t")] for r in rows]
    sec, frac = zip(*(s.split(".") for s in t_text))
    got = [int(a) * 1_000_000_000 + int(b) for a, b in zip(sec, frac)]
    assert got == epoch_replay["ns"] and len(set(got)) == len(got) == 8001
    tau = [r[head.index("reference_time")] for r in rows]
    assert tau[0] == "0.000000000" and tau[-1] == "80.000000000"
    assert len({float(s) for s in t_text}) == 8001  # distinct as floats too (238 ns apart at most, 10 ms steps)


def test_commands_mcap_stamps_are_the_triggering_pose_stamps(epoch_replay):
    """Each command's header stamp and log time equal the pose stamp that triggered its tick
    (they were about 128 ns off: the stamp went through float seconds)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([epoch_replay["out"] / "commands.mcap"]) as reader:
        stamps = [(log_ns, reader.deserialize(raw, c.msgtype).header.stamp)
                  for c, log_ns, raw in reader.messages() if c.topic == "/r1/cmd_vel"]
    got = [(log_ns, s.sec * 1_000_000_000 + s.nanosec) for log_ns, s in stamps]
    assert [a for a, _ in got] == epoch_replay["ns"]
    assert [b for _, b in got] == epoch_replay["ns"]
    m = json.loads((epoch_replay["out"] / "metrics.json").read_text())
    assert (m["first_tick_ns"], m["last_tick_ns"]) == (epoch_replay["ns"][0], epoch_replay["ns"][-1])
