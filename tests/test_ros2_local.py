"""One robot's node of a network scenario: LocalBridge (no ROS) against the simulator, and
LocalNode driven by the fake rclpy (tests/fake_rclpy): its topics in its neighbours'
namespaces, its message and command, e-stop, stale pose and shutdown."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from quatform import cli, messages
from quatform.errors import InvalidInputError
from quatform.ros2.bridge import experiment_for
from quatform.ros2.local_bridge import MESSAGE_TYPE, SENDER_COLUMNS, LocalBridge
from quatform.ros2.robots_file import robots_from_dict
from quatform.scenarios import builtin_scenarios, load_scenario

FAKE = Path(__file__).parent / "fake_rclpy"
_spec = importlib.util.spec_from_file_location("ros2_helpers", FAKE / "ros2_helpers.py")
H = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(H)


def robots_file(n: int, timeout_s: float = 0.05, **extra):
    """``n`` robots ``r1 .. rn`` in namespaces ``/r1 .. /rn``, poses from a motion capture."""
    return robots_from_dict({"bridge": {"start_timeout_s": 1.0},
                             "robots": [{"name": f"r{k + 1}", "pose_topic": f"/mocap/r{k + 1}/pose",
                                         "timeout_s": timeout_s, **extra} for k in range(n)]}, "robots.toml")


def safe_switching(folder: Path, hold_unheard: bool):
    """net-switching with undirected halves, 2 s, a 2.5 m radio range and messages valid 50 ms
    (with hold_unheard: no range, 0.6 s), and each robot's separation filter at 0.9 m (it binds
    on some robot ticks from these starts)."""
    src = builtin_scenarios()["net-switching"].read_text()
    src = re.sub(r"(?m)^duration_s = .*$", "duration_s = 2.0", src)
    # with hold_unheard a neighbour not heard (out of range, or of the other half) stops the robot:
    # no range, and messages held 0.6 s, longer than an interval
    links = "max_age_s = 0.6" if hold_unheard else "max_age_s = 0.05\nrange_m = 2.5"
    src = src.replace("max_age_s = 0.01", links).replace("seed = 3", "seed = 5")
    src = src.replace("position_m = 1.0", "position_m = 1.2")
    src = src.replace('kind = "edges"\n', 'kind = "edges"\ndirected = false\n')  # the filter needs both ways
    src += f"\n[safety]\nmin_separation_m = 0.9\ngamma = 20.0\nhold_unheard = {str(hold_unheard).lower()}\n"
    return load_scenario(H.write(folder / "safe-switching.toml", src))


def short(name: str, duration_s: float):
    return dataclasses.replace(load_scenario(name), duration_s=duration_s)


def pose_stream(bridge: LocalBridge, state):
    """Each robot's ``(positions (T, 3), quaternions (T, 4))`` of the plant states ``state`` (T, n)."""
    pr = bridge.io.plant_robots
    return H.robot_poses(pr.models, pr.state_slices, np.asarray(state))


def run_team(exp, rf, log):
    """Every robot's LocalBridge on the simulated poses, with perfect links: each robot's message
    of tick k handed to the robots that hear it before their tick k. ``(u (T, N n_u), sent
    (T, N, d + 3), bridges, ticks)``."""
    n = exp.controller.n
    bridges = [LocalBridge(exp, i, rf) for i in range(n)]
    poses = pose_stream(bridges[0], log["state"])
    dt_ns = round(exp.controller.period_s * 1e9)
    us, sent, ticks = [], [], []
    for k in range(len(log.t)):
        now = k * dt_ns
        for i, b in enumerate(bridges):
            assert b.on_pose(i, messages.pose_stamped(now * 1e-9, poses[i][0][k], poses[i][1][k]), now)
        out = [b.message_now(now) for b in bridges]
        for b in bridges:
            for j in b.neighbours:
                b.receive(j, out[j], now)
        tk = [b.tick(now) for b in bridges]
        for a, t in zip(out, tk):
            np.testing.assert_array_equal(t.outgoing, a)  # the tick sends what it announced
        us.append(np.concatenate([t.u for t in tk]))
        sent.append(np.stack(out))
        ticks.append(tk)
    return np.array(us), np.array(sent), bridges, ticks


CASES = {"net-switching": lambda tmp: short("net-switching", 1.2),
         "net-consensus-ring": lambda tmp: short("net-consensus-ring", 0.6),
         "safety-range": lambda tmp: safe_switching(tmp, False),
         "safety-hold-unheard": lambda tmp: safe_switching(tmp, True)}


@pytest.mark.parametrize("case", list(CASES))
def test_each_robot_node_computes_the_simulated_command(case, tmp_path):
    """The LocalBridge of every robot, fed the simulated poses and each other's messages of the
    same tick (perfect links), commands what NetworkedController commands in the simulator."""
    sc = CASES[case](tmp_path)
    exp = experiment_for(sc)
    log = exp.run()
    rf = robots_file(exp.controller.n)
    u, sent, bridges, ticks = run_team(exp, rf, log)
    want = np.asarray(log["command"])
    np.testing.assert_allclose(u, want, rtol=0, atol=1e-12)
    assert all(t.status == "ok" for tk in ticks for t in tk)
    assert np.max(np.abs(want)) > 0.1  # the robots move
    if case.startswith("safety"):
        binding = np.array([[t.signals["safety"][0] for t in tk] for tk in ticks])
        sim = np.asarray(log["safety"]).reshape(binding.shape + (-1,))
        np.testing.assert_array_equal(binding, sim[..., 0])
        assert binding.sum() > 0  # the filter binds
    if case == "net-switching":  # each robot hears one neighbour at a time: its edge of the interval
        heard = np.array([[t.heard for t in tk] for tk in ticks])
        assert heard.max() == 1 and heard.min() == 0
    # the message layout: the law's columns, then the sender's position
    p = np.stack([bridges[0].io.plant_robots.models[i].point(np.asarray(log["state"])[:, s])[:, :3]
                  for i, s in enumerate(bridges[0].io.plant_robots.state_slices)], axis=1)
    np.testing.assert_allclose(sent[..., -3:], p, rtol=0, atol=1e-12)
    assert bridges[0].columns[-3:] == SENDER_COLUMNS


def test_message_rules_age_order_and_stale_pose():
    """Out-of-order and stale messages, a missing or stale own pose, the e-stop."""
    exp = experiment_for(short("net-switching", 1.0))
    rf = robots_file(8)
    b = LocalBridge(exp, 0, rf)  # robot 1 hears robot 2 in the first half of each second
    assert b.neighbours == (1,)
    d = len(b.columns)
    assert b.tick(0).status == "stale" and b.tick(0).outgoing is None and not any(
        topic.endswith("quatform/message") for topic, _ in b.tick(0).messages)
    assert np.all(b.tick(0).u == 0) and b.tick(0).stale == ("r1",)
    pose = messages.pose_stamped(0.0, [2.5, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0])
    b.on_pose(0, pose, 0)
    assert b.receive(1, np.full(d, 1.0), 10_000_000)
    assert b.receive(1, np.full(d, 2.0), 5_000_000)  # older, arriving later: never replaces the newer one
    assert not b.receive(1, np.full(d, 3.0), 10_000_000)  # the same stamp again
    values, age_ns, valid = b.held(10_000_000, 0.0)
    assert valid[0] and age_ns[0] == 0 and np.all(values[0] == 1.0)
    t = b.tick(10_000_000)
    assert t.status == "ok" and t.heard == 1 and t.outgoing is not None
    assert b.tick(20_000_000).heard == 1  # 10 ms old: max_age_s = 0.01 s, valid
    assert b.tick(20_000_001).heard == 0  # older: stale
    b.on_pose(0, pose, 20_000_001)
    assert b.tick(70_000_001).status == "ok"  # 50 ms after the pose arrived: its timeout_s
    t = b.tick(70_000_002)
    assert t.status == "stale" and t.outgoing is None and np.all(t.u == 0)
    b.on_pose(0, pose, 80_000_000)
    tau = b.tick(80_000_000).tau
    assert tau == pytest.approx(0.06)  # held while stale
    b.engage_estop()
    t = b.tick(90_000_000)
    assert t.status == "estop" and np.all(t.u == 0) and t.outgoing is not None and t.tau == tau
    with pytest.raises(InvalidInputError, match="does not hear robot 3"):
        b.receive(2, np.zeros(d), 0)
    bad = messages.joint_state(0.1, ["a"] * d, np.zeros(d))
    assert not b.on_message(1, bad) and b.lost_messages == 1


def test_one_line_refusals(tmp_path):
    exp = experiment_for(short("net-switching", 1.0))
    with pytest.raises(InvalidInputError, match=r"robots are 1\.\.8") as e:
        LocalBridge(exp, 8, robots_file(8))
    assert "\n" not in str(e.value)
    with pytest.raises(InvalidInputError, match="for the centralised kinds"):
        LocalBridge(experiment_for(H.short_pair(0.2), "quaternion"), 0, robots_file(2))
    shared = robots_from_dict({"robots": [{"name": f"r{k}", "namespace": "", "pose_topic": f"/mocap/r{k}/pose",
                                           "command_topic": f"/r{k}/cmd_vel"} for k in range(1, 9)]}, "robots.toml")
    with pytest.raises(InvalidInputError, match="'r1' and 'r2' would both send on /quatform/message; give each "
                                                "robot its own namespace"):
        LocalBridge(exp, 0, shared)
    with pytest.raises(InvalidInputError, match="names 7 robots"):
        LocalBridge(exp, 0, robots_file(7))


def test_cli_one_line_errors(tmp_path, capsys):
    rf = tmp_path / "robots.toml"
    rf.write_text("".join(f'[[robots]]\nname = "r{k}"\npose_topic = "/mocap/r{k}/pose"\n\n' for k in range(1, 9)))
    base = ["ros2", "--scenario", "net-switching", "--robots", str(rf)]
    for args, needle in ((["--robot", "9"], "--robot 9 is out of range: net-switching has robots 1..8"),
                         (["--robot", "cf1"], "neither a robot number"),
                         ([], "start one per robot with --robot I")):
        assert cli.main(base + args) == 2
        err = capsys.readouterr().err.strip()
        assert needle in err and "\n" not in err
    pair = tmp_path / "pair.toml"
    pair.write_text(H.PAIR_ROBOTS)
    assert cli.main(["ros2", "--scenario", "mas-kitts-helix", "--robots", str(pair), "--controller", "quaternion",
                     "--robot", "1"]) == 2
    assert "use quatform ros2 without --robot (the bridge) for the centralised kinds" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["ros2", "--help"])
    assert "--robot I" in capsys.readouterr().out


# --------------------------------------------------------------------------- the node

DT_NS = 20_000_000  # net-switching's dt_s


def _node_setup(fake_ros, robot=2, duration_s=0.6, pose_until=None, extra=()):
    """Robot ``robot``'s LocalNode on net-switching; its poses (sim state k at (k + 1) dt, state 0
    also at 0) and its neighbours' messages of tick k (stamped and delivered at (k + 1) dt,
    perfect links) scheduled on the fake bus: its tick j at j dt is the simulator's tick j - 1."""
    from quatform.ros2.local_node import LocalNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp = experiment_for(short("net-switching", duration_s))
    log = exp.run()
    rf = robots_file(8)
    _, sent, bridges, _ = run_team(exp, rf, log)
    bus = fake_ros.fake_bus.BUS
    b = LocalBridge(exp, robot, rf)
    p, q = pose_stream(b, log["state"])[robot]
    T = len(log.t)
    for k in range(-1, T):
        t = (k + 1) * DT_NS
        if pose_until is None or t <= pose_until:
            bus.schedule(t, rf.robots[robot].pose_topic, messages.pose_stamped(t * 1e-9, p[max(k, 0)], q[max(k, 0)]))
        if k >= 0:
            for j in b.neighbours:
                msg = messages.joint_state(messages.stamp_ns(t), b.columns, sent[k, j], frame_id="world")
                bus.schedule(t, f"/r{j + 1}/quatform/message", msg)
    for t, topic, msg in extra:
        bus.schedule(t, topic, msg)
    node = LocalNode(b, 50.0, RclpyTransport(fake_ros))
    return node, log, sent, rf


def _spin_until(rclpy, node, t_ns):
    bus = rclpy.fake_bus.BUS
    while bus.now_ns <= t_ns:
        rclpy.spin_once(node.transport.node, timeout_sec=0.001)


def test_node_topics_in_the_neighbours_namespaces(fake_ros):
    node, _, _, rf = _node_setup(fake_ros)
    bus = fake_ros.fake_bus.BUS
    subs = {topic: s[0] for topic, s in bus.subscriptions.items() if s}
    # robot 3 hears robot 4 in the first half of each second (the edge [3, 4]), no one in the second
    assert set(subs) == {"/mocap/r3/pose", "/r4/quatform/message", "/quatform/estop"}
    assert subs["/r4/quatform/message"].msg_type.__msgtype__ == MESSAGE_TYPE
    assert subs["/r4/quatform/message"].qos == fake_ros.qos.qos_profile_sensor_data  # best effort
    assert set(bus.publishers) == {"/r3/cmd_vel", "/r3/quatform/message"}
    assert bus.publishers["/r3/quatform/message"].qos == fake_ros.qos.qos_profile_sensor_data
    assert node.transport.node.namespace == "/r3" and node.transport.node.name == "quatform_r3"
    assert set(bus.services) == {"/r3/quatform/set_estop"}  # one service per robot's node


def test_node_publishes_the_simulated_command_and_message(fake_ros):
    node, log, sent, rf = _node_setup(fake_ros)
    bus = fake_ros.fake_bus.BUS
    node.start()
    T = len(log.t)
    _spin_until(fake_ros, node, T * DT_NS)
    assert [t.status for t in node.ticks] == ["ok"] * T
    u = np.asarray(log["command"])[:, 8:12]  # robot 3's (v_x, v_y, v_z, omega_z)
    tw = np.array([np.r_[messages.twist_from_msg(m)].ravel() for _, m in bus.published["/r3/cmd_vel"]])
    np.testing.assert_allclose(tw, np.c_[u[:, :3], np.zeros((T, 2)), u[:, 3]], rtol=0, atol=1e-12)
    out = bus.published["/r3/quatform/message"]  # round-tripped through CDR
    assert len(out) == T
    for k, (t_ns, m) in enumerate(out):
        assert t_ns == (k + 1) * DT_NS and messages.nanoseconds(m.header.stamp) == t_ns
        assert tuple(m.name) == ("xi_x", "xi_y", "xi_z") + SENDER_COLUMNS and m.header.frame_id == "world"
        np.testing.assert_array_equal(np.asarray(m.position), sent[k, 2])


def test_stale_pose_sends_no_message_and_zero(fake_ros):
    node, log, _, rf = _node_setup(fake_ros, pose_until=10 * DT_NS)
    bus = fake_ros.fake_bus.BUS
    node.start()
    _spin_until(fake_ros, node, 20 * DT_NS)
    status = [t.status for t in node.ticks]
    # its last pose at 200 ms, timeout 50 ms: ticks after 250 ms are stale
    assert status == ["ok"] * 12 + ["stale"] * 8
    assert len(bus.published["/r3/quatform/message"]) == 12
    assert all(np.all(t.u == 0) for t in node.ticks[12:])
    assert any("stale pose from r3" in text for level, text in bus.logs if level == "warning")


def test_estop_and_ctrl_c(fake_ros):
    bool_ = messages.msg_type("std_msgs/msg/Bool")
    node, _, _, rf = _node_setup(fake_ros, extra=[(5 * DT_NS + 1, "/quatform/estop", bool_(data=True))])
    bus = fake_ros.fake_bus.BUS
    bus.interrupt(12 * DT_NS + DT_NS // 2)
    node.start()
    with pytest.raises(KeyboardInterrupt):
        node.spin()
    status = [t.status for t in node.ticks]
    assert status == ["ok"] * 5 + ["estop"] * 7
    cmd = bus.published["/r3/cmd_vel"]
    tw = np.array([np.r_[messages.twist_from_msg(m)].ravel() for _, m in cmd])
    assert np.any(tw[:5] != 0) and np.all(tw[5:] == 0)  # zero at once, latched, and at Ctrl-C
    assert cmd[-1][0] == 12 * DT_NS + DT_NS // 2
    assert len(bus.published["/r3/quatform/message"]) == 12  # its position still goes out under the e-stop
    assert not fake_ros.ok() and bus.nodes == []


def test_node_warns_once_of_a_neighbour_of_another_law(fake_ros):
    other = messages.joint_state(messages.stamp_ns(DT_NS), ["y_rw"] * 6, np.zeros(6))
    node, _, _, rf = _node_setup(fake_ros, extra=[(DT_NS // 2, "/r4/quatform/message", other),
                                                  (DT_NS // 2 + 1, "/r4/quatform/message", other)])
    bus = fake_ros.fake_bus.BUS
    node.start()
    _spin_until(fake_ros, node, 3 * DT_NS)
    warnings = [text for level, text in bus.logs if level == "warning"]
    assert len(warnings) == 1 and "robot 'r4' sends y_rw" in warnings[0]
    assert node.bridge.lost_messages == 2
