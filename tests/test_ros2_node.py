"""The ROS 2 bridge's node driven by a fake rclpy (tests/fake_rclpy): CDR on the wire, a
simulated clock; a bag replayed through the node gives the offline controller's commands."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from quatform import messages
from quatform.errors import InvalidInputError, MissingDependencyError
from quatform.ros2.bag_poses import read_bag_poses
from quatform.ros2.bridge import FormationBridge, experiment_for
from quatform.ros2.replay import replay_ticks
from quatform.ros2.robots_file import read_robots_file

FAKE = Path(__file__).parent / "fake_rclpy"
_spec = importlib.util.spec_from_file_location("ros2_helpers", FAKE / "ros2_helpers.py")
H = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(H)
DT_NS = 10_000_000  # the helix's dt_s = 0.01 s


def _pair_setup(tmp_path, duration_s=0.5, robots=H.PAIR_ROBOTS):
    exp = experiment_for(H.short_pair(duration_s), "quaternion")
    log = exp.run()
    rf = read_robots_file(H.write(tmp_path / "robots.toml", robots))
    return exp, log, rf


def _pair_bag(tmp_path, log, rf, exp):
    """A bag whose pose k is the simulated state k, published at (k + 1) dt (and state 0 again
    at 0): the node's tick j, at j dt, then reads state j - 1 at reference time (j - 1) dt, the
    simulation's tick j - 1."""
    pr = FormationBridge(exp, rf).plant_robots
    x = log["state"]
    x = np.concatenate([x[:1], x])
    poses = H.robot_poses(pr.models, pr.state_slices, x)
    times = np.arange(len(x)) * DT_NS
    msgs = H.pose_messages(poses, times * 1e-9)
    streams = [(link.pose_topic, "geometry_msgs/msg/PoseStamped", list(zip(times.tolist(), m)))
               for link, m in zip(rf.robots, msgs)]
    return H.write_bag(tmp_path / "poses", streams)


def _schedule_bag(bus, bag, rf):
    poses = read_bag_poses(bag, rf)
    for link, ts, ms in zip(rf.robots, poses.times_ns, poses.messages):
        for t, m in zip(ts, ms):
            bus.schedule(int(t), link.pose_topic, m)
    return poses


def _spin_until(rclpy, node, t_ns):
    bus = rclpy.fake_bus.BUS
    while bus.now_ns <= t_ns:  # every event at t_ns included
        rclpy.spin_once(node.transport.node, timeout_sec=0.001)


def _twists(bus, topic):
    return np.array([np.r_[messages.twist_from_msg(m)] .ravel() for _, m in bus.published[topic]])


def test_bag_through_the_node_gives_the_offline_commands(fake_ros, tmp_path):
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp, log, rf = _pair_setup(tmp_path)
    bag = _pair_bag(tmp_path, log, rf, exp)
    bus = fake_ros.fake_bus.BUS
    poses = _schedule_bag(bus, bag, rf)
    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    node.start()
    assert bus.now_ns == 0  # every robot's first pose arrived at 0: the timer starts there
    _spin_until(fake_ros, node, int(poses.times_ns[0][-1]))
    ticks = node.ticks
    T = len(log.t)
    assert len(ticks) == T and all(t.status == "ok" for t in ticks)
    u = log["command"]
    for i, link in enumerate(rf.robots):
        got = _twists(bus, link.command_topic)  # published TwistStamped, round-tripped through CDR
        want = np.c_[u[:, 4 * i:4 * i + 3], np.zeros((T, 2)), u[:, 4 * i + 3]]
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        assert bus.published[link.command_topic][0][1].header.frame_id == "world"
    # quatform replay of the same bag at the node's rate: the same commands, exactly
    offline = replay_ticks(FormationBridge(exp, rf), read_bag_poses(bag, rf), rate_hz=100.0)
    np.testing.assert_array_equal(np.array([t.u for t in offline.ticks]), np.array([t.u for t in ticks]))
    np.testing.assert_array_equal([t.tau for t in offline.ticks], [t.tau for t in ticks])


def test_stale_pose_zeros_and_holds_then_resumes(fake_ros, tmp_path):
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp, log, rf = _pair_setup(tmp_path)
    bag = _pair_bag(tmp_path, log, rf, exp)
    bus = fake_ros.fake_bus.BUS
    poses = read_bag_poses(bag, rf)
    gap = (20 * DT_NS, 35 * DT_NS)  # robot r2's mocap drops out for 150 ms (its timeout: 50 ms)
    for i, (link, ts, ms) in enumerate(zip(rf.robots, poses.times_ns, poses.messages)):
        for t, m in zip(ts, ms):
            if not (i == 1 and gap[0] < t < gap[1]):
                bus.schedule(int(t), link.pose_topic, m)
    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    node.start()
    _spin_until(fake_ros, node, 45 * DT_NS)
    status = [t.status for t in node.ticks]
    stale = [k for k, s in enumerate(status) if s == "stale"]
    # tick k is at (k + 1) 10 ms: stale from 260 ms (60 ms after r2's last pose at 200 ms; its timeout is
    # 50 ms) until its poses resume at 350 ms
    assert stale == list(range(25, 34))
    for k in stale:
        assert node.ticks[k].stale == ("r2",)
        assert np.all(node.ticks[k].u == 0)
        for link in rf.robots:
            np.testing.assert_array_equal(_twists(bus, link.command_topic)[k], np.zeros(6))
    # held: the reference time does not advance while stale; it resumes where it stopped
    assert node.ticks[34].tau == node.ticks[24].tau and node.ticks[35].tau == pytest.approx(node.ticks[24].tau + 0.01)
    assert any("stale pose from r2" in text for level, text in bus.logs if level == "warning")


def test_estop_latches_until_released(fake_ros, tmp_path):
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp, log, rf = _pair_setup(tmp_path)
    bag = _pair_bag(tmp_path, log, rf, exp)
    bus = fake_ros.fake_bus.BUS
    _schedule_bag(bus, bag, rf)
    bool_ = messages.msg_type("std_msgs/msg/Bool")
    bus.schedule(10 * DT_NS + 1, "/quatform/estop", bool_(data=True))
    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    node.start()
    _spin_until(fake_ros, node, 30 * DT_NS)
    status = [t.status for t in node.ticks]
    assert status[:10] == ["ok"] * 10 and set(status[10:]) == {"estop"}  # latched: no release, poses fresh
    assert all(np.all(t.u == 0) for t in node.ticks[10:])
    n = len(node.ticks)
    response = bus.call("/quatform/set_estop", data=False)  # the service releases it
    assert response.success and "released" in response.message
    _spin_until(fake_ros, node, 35 * DT_NS)
    assert [t.status for t in node.ticks[n:]] == ["ok"] * (len(node.ticks) - n)
    assert node.ticks[n].tau == node.ticks[9].tau  # resumed where it was held
    bus.call("/quatform/set_estop", data=True)
    r1 = rf.robots[0].command_topic
    assert np.all(_twists(bus, r1)[-1] == 0)  # engaging publishes zero at once


def _started_pair(fake_ros, tmp_path):
    exp, log, rf = _pair_setup(tmp_path)
    bag = _pair_bag(tmp_path, log, rf, exp)
    _schedule_bag(fake_ros.fake_bus.BUS, bag, rf)
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    node.start()
    return node, rf


def test_fake_rclpy_refuses_what_rclpy_refuses(fake_ros):
    """The fake is as strict as rclpy: no deprecated ``warn``, no publish or spin after shutdown."""
    from rclpy._rclpy_pybind11 import RCLError
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node

    fake_ros.init()
    node = Node("n")
    assert not hasattr(node.get_logger(), "warn") and hasattr(node.get_logger(), "warning")
    pub = node.create_publisher(messages.msg_type("std_msgs/msg/Bool"), "/b", 10)
    fake_ros.shutdown()
    with pytest.raises(RCLError, match="publisher's context is invalid"):
        pub.publish(messages.msg_type("std_msgs/msg/Bool")(data=True))
    with pytest.raises(ExternalShutdownException):
        fake_ros.spin_once(node, timeout_sec=0.1)
    with pytest.raises(RCLError, match="already called"):
        fake_ros.shutdown()
    with pytest.raises(TypeError):
        fake_ros.init(None)  # keyword arguments only


def test_ctrl_c_sends_zero_to_every_robot_before_shutdown(fake_ros, tmp_path):
    node, rf = _started_pair(fake_ros, tmp_path)
    bus = fake_ros.fake_bus.BUS
    assert bus.signal_handler_options.name == "NO"  # rclpy's handler would shut the context down first
    t_stop = 10 * DT_NS + DT_NS // 2
    bus.interrupt(t_stop)
    with pytest.raises(KeyboardInterrupt):
        node.spin()
    for link in rf.robots:
        sent = bus.published[link.command_topic]
        assert len(sent) == 11 and sent[-1][0] == t_stop  # ten ticks, then the zero command at Ctrl-C
        tw = _twists(bus, link.command_topic)
        assert np.any(tw[:-1] != 0) and np.all(tw[-1] == 0)
    assert not fake_ros.ok() and bus.nodes == []  # shut down after the zero command
    assert not any(level == "error" for level, _ in bus.logs)


def test_sigterm_sends_zero_as_ctrl_c_does(fake_ros, tmp_path):
    import os
    import signal

    node, rf = _started_pair(fake_ros, tmp_path)
    bus = fake_ros.fake_bus.BUS
    node.transport.node.create_timer(0.055, lambda: os.kill(os.getpid(), signal.SIGTERM))

    def not_the_node(signum, frame):  # a node that does not take SIGTERM over ends up here, not killed
        raise RuntimeError("SIGTERM reached the test's handler")

    previous = signal.signal(signal.SIGTERM, not_the_node)
    try:
        with pytest.raises(KeyboardInterrupt):
            node.spin()
        assert signal.getsignal(signal.SIGTERM) is not_the_node  # restored
    finally:
        signal.signal(signal.SIGTERM, previous)
    for link in rf.robots:
        assert bus.published[link.command_topic][-1][0] == 55 * DT_NS // 10
        assert np.all(_twists(bus, link.command_topic)[-1] == 0)
    assert not fake_ros.ok()


def test_a_second_signal_during_close_does_not_cut_the_zero_command_short(fake_ros, tmp_path):
    """Ctrl-C and SIGTERM arriving while the node publishes its zero commands are ignored: every
    robot still gets its zero command, and the signals' handlers are restored after."""
    import os
    import signal

    node, rf = _started_pair(fake_ros, tmp_path)
    bus = fake_ros.fake_bus.BUS
    _spin_until(fake_ros, node, 3 * DT_NS)
    first = rf.robots[0].command_topic
    publish = node.publishers[first]

    def publish_then_signal(msg):  # the first robot's zero command, then two more signals
        publish(msg)
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)

    node.publishers[first] = publish_then_signal
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    node.close()
    assert {sig: signal.getsignal(sig) for sig in handlers} == handlers
    for link in rf.robots:
        assert np.all(_twists(bus, link.command_topic)[-1] == 0)
    assert not fake_ros.ok()


def test_transport_auto_takes_rclpy_where_importable_else_dds_else_one_line(fake_ros, monkeypatch, capsys):
    from quatform.ros2.cli import make_transport
    from quatform.ros2.rclpy_transport import RclpyTransport

    assert isinstance(make_transport("auto"), RclpyTransport)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--transport auto: rclpy" in err[0]
    monkeypatch.setitem(sys.modules, "rclpy", None)
    if importlib.util.find_spec("cyclonedds") is not None:
        from quatform.ros2.dds import DdsTransport

        assert isinstance(make_transport("auto"), DdsTransport)
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--transport auto: dds" in err[0] and "rclpy is not importable" in err[0]
    monkeypatch.setitem(sys.modules, "cyclonedds", None)
    with pytest.raises(MissingDependencyError) as info:
        make_transport("auto")
    text = str(info.value)
    assert "source your ROS 2 installation" in text and 'pip install -e ".[dds]"' in text and "\n" not in text


def test_context_shut_down_elsewhere_logs_instead_of_raising(fake_ros, tmp_path):
    """rclpy initialised by someone else with its signal handlers: Ctrl-C shuts the context down
    before the node sees it; no message can go out, and the node says so in one line."""
    fake_ros.init()
    node, rf = _started_pair(fake_ros, tmp_path)
    bus = fake_ros.fake_bus.BUS
    bus.interrupt(5 * DT_NS + DT_NS // 2)
    with pytest.raises(KeyboardInterrupt):
        node.spin()
    errors = [text for level, text in bus.logs if level == "error"]
    assert len(errors) == 1 and "before the zero command" in errors[0]
    assert len(bus.published[rf.robots[0].command_topic]) == 5 and bus.nodes == []


def test_missing_robot_refuses_to_start(fake_ros, tmp_path):
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp, _, rf = _pair_setup(tmp_path)
    bus = fake_ros.fake_bus.BUS
    bus.schedule(0, rf.robots[0].pose_topic, messages.pose_stamped(0.0, [0, 0, 1], [1, 0, 0, 0]))
    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    with pytest.raises(InvalidInputError) as err:
        node.start()
    text = str(err.value)
    assert "\n" not in text and "'r2'" in text and "/vrpn_client_node/r2/pose" in text and "1 s" in text
    assert node.timer is None


PX4_ROBOTS = """
[[robots]]
name = "x500_1"
namespace = "/px4_1"
pose_topic = "fmu/out/vehicle_odometry"
pose_type = "px4"
command_type = "px4"

[[robots]]
name = "x500_2"
namespace = "/px4_2"
pose_topic = "fmu/out/vehicle_odometry"
pose_type = "px4"
command_type = "px4"
"""


def test_px4_odometry_in_and_setpoints_out(fake_ros, tmp_path):
    from quatform.ros2 import px4
    from quatform.ros2.node import BridgeNode
    from quatform.ros2.rclpy_transport import RclpyTransport

    exp, log, rf = _pair_setup(tmp_path, 0.2, PX4_ROBOTS)
    assert rf.robots[0].pose_topic == "/px4_1/fmu/out/vehicle_odometry"
    pr = FormationBridge(exp, rf).plant_robots
    x = np.concatenate([log["state"][:1], log["state"]])
    bus = fake_ros.fake_bus.BUS
    for link, (p, q) in zip(rf.robots, H.robot_poses(pr.models, pr.state_slices, x)):
        for k in range(len(x)):
            bus.schedule(k * DT_NS, link.pose_topic, px4.vehicle_odometry(k * 0.01, p[k], q[k]))
    node = BridgeNode(FormationBridge(exp, rf), 100.0, RclpyTransport(fake_ros))
    node.start()
    _spin_until(fake_ros, node, (len(x) - 1) * DT_NS)
    u = log["command"]
    for i, link in enumerate(rf.robots):
        sp = [m for _, m in bus.published[link.command_topic]]
        mode = [m for _, m in bus.published[link.offboard_topic]]
        assert len(sp) == len(mode) == len(u)
        assert all(m.velocity and not m.position for m in mode)
        v_ned = np.array([m.velocity for m in sp])
        # float32 on PX4's wire (positions and quaternions in, velocities out)
        np.testing.assert_allclose(v_ned, np.c_[u[:, 4 * i + 1], u[:, 4 * i], -u[:, 4 * i + 2]], atol=2e-4)
        np.testing.assert_allclose([m.yawspeed for m in sp], -u[:, 4 * i + 3], atol=2e-4)
        assert all(np.isnan(m.position).all() and np.isnan(m.yaw) for m in sp)
        assert sp[0].timestamp == 10_000  # µs of the first tick (10 ms)


def test_to_ros_copies_fields_into_another_class():
    """On a ROS machine a rosbags message becomes the installation's class, field by field."""
    from quatform.ros2 import rclpy_transport as node_mod

    class Vec:
        @classmethod
        def get_fields_and_field_types(cls):
            return {"x": "double", "y": "double", "z": "double"}

    class Tw:
        @classmethod
        def get_fields_and_field_types(cls):
            return {"linear": "geometry_msgs/Vector3", "angular": "geometry_msgs/Vector3"}

    classes = {"geometry_msgs/msg/Twist": Tw, "geometry_msgs/msg/Vector3": Vec}
    orig = node_mod.ros_class
    node_mod.ros_class = classes.__getitem__
    try:
        out = node_mod.to_ros(messages.twist([1.0, 2.0, 3.0], [0.0, 0.0, 0.5]))
    finally:
        node_mod.ros_class = orig
    assert isinstance(out, Tw) and isinstance(out.linear, Vec)
    assert (out.linear.x, out.linear.y, out.linear.z, out.angular.z) == (1.0, 2.0, 3.0, 0.5)


def test_without_rclpy_one_line_says_to_source_ros(monkeypatch):
    from quatform.ros2.rclpy_transport import import_rclpy

    monkeypatch.setitem(sys.modules, "rclpy", None)  # import rclpy raises ImportError
    with pytest.raises(MissingDependencyError, match="source your ROS 2 installation") as err:
        import_rclpy()
    assert "--transport dds" in str(err.value) and "\n" not in str(err.value)


def test_without_cyclonedds_the_dds_transport_is_one_line(monkeypatch, tmp_path, capsys):
    from quatform import cli
    from quatform.ros2.dds import DdsTransport

    monkeypatch.setitem(sys.modules, "cyclonedds", None)  # import cyclonedds raises ImportError
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[dds\]"'):
        DdsTransport()
    robots = H.write(tmp_path / "robots.toml", H.PAIR_ROBOTS)
    rc = cli.main(["ros2", "--transport", "dds", "--scenario", "mas-kitts-helix", "--robots", str(robots),
                   "--controller", "quaternion"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and '.[dds]' in err


def test_ros_domain_id_is_read_and_checked():
    from quatform.ros2.transport import ros_domain_id

    assert ros_domain_id({}) == 0 and ros_domain_id({"ROS_DOMAIN_ID": " 42 "}) == 42
    for bad in ("x", "-1", "233"):
        with pytest.raises(InvalidInputError, match="ROS_DOMAIN_ID"):
            ros_domain_id({"ROS_DOMAIN_ID": bad})
