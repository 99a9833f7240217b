"""The dds transport against a real DDS peer on loopback: the bridge (``quatform ros2 --transport
dds``) in its own process, this process a plain Cyclone DDS participant publishing lab-style
mocap poses (seed 000's helix, two robots, 100 Hz) and reading the commands (tests/dds_peer.py).

With ``--use-sim-time`` the peer steps ``/clock`` one control period at a time after the poses
of that period (lockstep), so the bridge's ticks are the simulation's and its commands equal the
simulated ones; the stale-pose hold, the e-stop (latched, transient local) and the zero command
on exit show on the wire. No packet leaves 127.0.0.1 (CYCLONEDDS_URI: loopback, no multicast,
peers 127.0.0.1). Cyclone 11 binds its unicast receive sockets to 0.0.0.0 whatever the
configuration (docs/ros2.md, "Without ROS: the dds transport"): they send nothing off the host,
but a packet from another host to their ports would reach them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import math
import re
import signal
import struct
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("cyclonedds", reason="the dds extra is not installed (pip install -e \".[dds]\")")

from quatform import messages  # noqa: E402
from quatform.ros2.bridge import FormationBridge, experiment_for  # noqa: E402
from quatform.ros2.dds import IdlTypes, dds_service_topics, dds_topic, dds_type_name, ros_type_name  # noqa: E402
from quatform.ros2.robots_file import read_robots_file  # noqa: E402


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


H = _load("ros2_helpers", Path(__file__).parent / "fake_rclpy" / "ros2_helpers.py")
P = _load("dds_peer", Path(__file__).parent / "dds_peer.py")
DT_NS = 10_000_000  # the helix's dt_s
WAIT_S = 10.0  # the longest wait for one tick's commands (a loaded machine), never reached on a run that passes


@pytest.fixture(scope="module")
def loopback(tmp_path_factory):
    """CYCLONEDDS_URI and ROS_DOMAIN_ID of this module's runs, set in this process too (Cyclone
    reads them when the domain is first created here)."""
    env = P.loopback_env(tmp_path_factory.mktemp("dds"))
    mp = pytest.MonkeyPatch()
    for k, v in env.items():
        mp.setenv(k, v)
    yield env
    mp.undo()


def test_idl_types_are_ros2s_names_and_cdr():
    """The generated IDL types carry ROS 2's DDS type names and serialise to rosbags' CDR, byte for byte."""
    from quatform.ros2 import px4

    types = IdlTypes()
    for msg in (messages.twist([1, 2, 3], [4, 5, 6]), messages.twist_stamped(1.5, [1, 2, 3], [0, 0, 0.5], "world"),
                messages.pose_stamped(1.0, [1, 2, 3], [0.5, 0.5, 0.5, 0.5]),
                px4.vehicle_odometry(0.1, [1, 2, 3], [1, 0, 0, 0]), px4.trajectory_setpoint(0.1, [1, 2, 3], 0.3),
                px4.offboard_control_mode(0.1), messages.joint_state(0.5, ["a", "b"], [1.0, 2.0]),
                messages.msg_type("std_msgs/msg/Bool")(data=True),
                messages.msg_type("rosgraph_msgs/msg/Clock")(clock=messages.stamp_ns(123))):
        name = msg.__msgtype__
        sample = types.to_idl(msg)
        raw = sample.serialize()
        assert raw == bytes(types.store.serialize_cdr(msg, name)), name
        back = types.from_idl(type(sample).deserialize(raw), name)
        assert bytes(types.store.serialize_cdr(back, name)) == raw
    assert types.cls("geometry_msgs/msg/Twist").__idl_typename__ == "geometry_msgs::msg::dds_::Twist_"
    assert dds_type_name("px4_msgs/msg/VehicleOdometry") == "px4_msgs::msg::dds_::VehicleOdometry_"
    assert ros_type_name("geometry_msgs::msg::dds_::PointStamped_") == "geometry_msgs/msg/PointStamped"
    assert dds_topic("/r1/cmd_vel") == "rt/r1/cmd_vel"


@given(guid=st.integers(0, 2**64 - 1), seq=st.integers(-2**63, 2**63 - 1), data=st.booleans(),
       message=st.text(st.characters(codec="ascii", exclude_characters="\x00"), max_size=40))
@settings(max_examples=50, deadline=None)
def test_service_cdr_is_the_request_header_then_rosbags_fields(guid, seq, data, message):
    """The SetBool request and response on the wire of rmw_cyclonedds: Cyclone's own CDR of the
    IDL sample is the 4-byte encapsulation, the header (uint64 guid, int64 seq: 16 bytes, so the
    fields keep their 8-aligned start), then rosbags' CDR of the fields; it reads back."""
    types = IdlTypes()
    store = types.store
    for name, msg in (("std_srvs/srv/SetBool_Request", store.types["std_srvs/srv/SetBool_Request"](data=data)),
                      ("std_srvs/srv/SetBool_Response",
                       store.types["std_srvs/srv/SetBool_Response"](success=data, message=message))):
        sample = types.to_idl(msg, name, header=(guid, seq))
        raw = sample.serialize()
        fields = bytes(store.serialize_cdr(msg, name))
        assert raw == fields[:4] + struct.pack("<Qq", guid, seq) + fields[4:], name
        back = type(sample).deserialize(raw)
        assert (back.guid, back.seq) == (guid, seq)
        assert bytes(store.serialize_cdr(types.from_idl(back, name), name)) == fields
    assert types.service_cls("std_srvs/srv/SetBool_Request").__idl_typename__ == "std_srvs::srv::dds_::SetBool_Request_"
    assert types.service_cls("std_srvs/srv/SetBool_Response").__idl_typename__ == \
        "std_srvs::srv::dds_::SetBool_Response_"
    assert dds_service_topics("/quatform/set_estop") == ("rq/quatform/set_estopRequest", "rr/quatform/set_estopReply")


def _bridge(tmp_path, loopback, *extra, name="bridge"):
    robots = H.write(tmp_path / "robots.toml", H.PAIR_ROBOTS)
    args = ["ros2", "--transport", "dds", "--scenario", "mas-kitts-helix", "--robots", robots, "--controller",
            "quaternion", *extra]
    return P.quatform_process(args, loopback, tmp_path / f"{name}.log"), read_robots_file(robots)


def _pace(t0: float, k: int, period_s: float = 0.01) -> None:
    """Sleep until ``t0 + k period_s`` (the mocap's 100 Hz)."""
    time.sleep(max(0.0, t0 + k * period_s - time.monotonic()))


def test_bridge_over_dds_gives_the_simulations_commands_and_holds_stops_and_zeros(tmp_path, loopback):
    exp = experiment_for(H.short_pair(0.5), "quaternion")
    log = exp.run()
    proc, rf = _bridge(tmp_path, loopback, "--use-sim-time")
    try:
        pr = FormationBridge(exp, rf).plant_robots
        (p1, q1), (p2, q2) = H.robot_poses(pr.models, pr.state_slices, log["state"])
        peer = P.PairPeer(int(loopback["ROS_DOMAIN_ID"]), rf)
        P.Peer.wait_matched(peer.pose_w + [peer.clock_w, peer.estop_w] + peer.cmd.readers, 30.0, proc)
        # the first tick: state 0 until the bridge (started on these poses) ticks at a /clock step
        c0 = 0
        while True:
            peer.step(c0, (P.pose(0, p1, q1, c0), P.pose(0, p2, q2, c0)))
            if peer.cmd.wait_for(c0, 1.0):
                break
            assert proc.poll() is None and c0 < 20 * DT_NS, (tmp_path / "bridge.log").read_text()
            c0 += DT_NS
        T = len(log.t)
        t0, lat = time.monotonic(), []
        for k in range(1, T):  # lockstep: state k, then the clock of tick k
            _pace(t0, k)
            c = c0 + k * DT_NS
            peer.step(c, (P.pose(k, p1, q1, c), P.pose(k, p2, q2, c)))
            assert peer.cmd.wait_for(c, WAIT_S), f"no command at tick {k}"
            lat.append(max(x[0] for x in peer.cmd.stamped(c)) - peer.sent_ns[-1])
        u = np.asarray(log["command"])
        for i in range(2):
            got = np.array([peer.cmd.stamped(c0 + k * DT_NS)[i][2] for k in range(T)])
            want = np.c_[u[:, 4 * i:4 * i + 3], np.zeros((T, 2)), u[:, 4 * i + 3]]
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
        # r2's mocap silent for 10 ticks (its timeout 50 ms): zero from the 5th tick on, then it resumes
        last = T - 1
        status = {}
        for j in range(25):
            k = T + j
            _pace(t0, k)
            c = c0 + k * DT_NS
            r2 = None if j < 10 else P.pose(last, p2, q2, c)
            peer.step(c, (P.pose(last, p1, q1, c), r2), estop=True if j == 18 else None)
            assert peer.cmd.wait_for(c, WAIT_S), f"no command at tick {k}"
            status[j] = [bool(np.any(x[2] != 0)) for x in peer.cmd.stamped(c)]
        # r2's last pose arrived with the clock at tick T - 2 (it reaches the bridge before the next
        # /clock step): ticks up to 50 ms after it run (j = 0..3, 20..50 ms), later ones are zero
        assert [j for j in range(18) if not any(status[j])] == list(range(4, 10))
        assert all(all(status[j]) for j in (0, 1, 2, 3, *range(10, 18)))
        assert not any(any(status[j]) for j in range(18, 25))  # the e-stop latches: zero while poses flow
        n_before = [len(b) for b in peer.cmd.got]
    finally:
        rc = P.stop(proc, signal.SIGINT)
    text = (tmp_path / "bridge.log").read_text()
    end = time.monotonic() + 5.0
    while any(len(b) == n for b, n in zip(peer.cmd.got, n_before)) and time.monotonic() < end:
        peer.cmd.poll(0.05)
    for box, n in zip(peer.cmd.got, n_before):  # Ctrl-C: one zero command to every robot before exiting
        assert len(box) == n + 1 and not np.any(box[-1][2])
    assert rc == 130 and "Traceback" not in text, text
    assert "stale pose from r2" in text and "e-stop engaged" in text
    lat_ms = np.asarray(lat) * 1e-6
    print(f"\nlockstep round trip pose -> command over DDS: median {np.median(lat_ms):.2f} ms, "
          f"p99 {np.percentile(lat_ms, 99):.2f} ms ({len(lat_ms)} ticks)")


def _nan_pose(msg):
    point = messages.msg_type("geometry_msgs/msg/Point")(x=math.nan, y=0.0, z=1.0)
    pose = messages.msg_type("geometry_msgs/msg/Pose")(position=point, orientation=msg.pose.orientation)
    return dataclasses.replace(msg, pose=pose)


def test_latched_estop_wrong_type_and_nan_are_refused_in_one_line(tmp_path, loopback):
    """An e-stop published before the bridge starts (transient local) stops it from its first tick;
    a writer of PointStamped on a pose topic and NaN poses are one warning line each; SIGTERM
    sends the zero command."""
    exp = experiment_for(H.short_pair(0.5), "quaternion")
    x = exp.run()["state"]
    domain = int(loopback["ROS_DOMAIN_ID"])
    peer = P.Peer(domain)
    rf = read_robots_file(H.write(tmp_path / "robots.toml", H.PAIR_ROBOTS))
    estop = peer.writer("rt/quatform/estop", "std_msgs/msg/Bool", "latched")
    peer.write(estop, messages.msg_type("std_msgs/msg/Bool")(data=True))  # latched, before the bridge exists
    pose_w = [peer.writer(dds_topic(r.pose_topic), "geometry_msgs/msg/PoseStamped") for r in rf.robots]
    wrong = P.Peer(domain)  # another node publishing the wrong type on r2's pose topic
    point_w = wrong.writer(dds_topic(rf.robots[1].pose_topic), "geometry_msgs/msg/PointStamped")
    cmd = P.Commands(peer, [peer.reader(dds_topic(r.command_topic), "geometry_msgs/msg/TwistStamped")
                           for r in rf.robots])
    proc, _ = _bridge(tmp_path, loopback, "--rate", "100", name="bad")
    try:
        pr = FormationBridge(exp, rf).plant_robots
        (p1, q1), (p2, q2) = H.robot_poses(pr.models, pr.state_slices, x)
        P.Peer.wait_matched(pose_w + cmd.readers, 30.0, proc)
        point = messages.msg_type("geometry_msgs/msg/PointStamped")
        t0 = time.monotonic()
        for k in range(60):  # 0.6 s of 100 Hz mocap; every 7th pose of r1 a NaN
            _pace(t0, k)
            t = time.time_ns()
            m1 = P.pose(k % len(x), p1, q1, t)
            peer.write(pose_w[0], _nan_pose(m1) if k % 7 == 3 else m1)
            m2 = P.pose(k % len(x), p2, q2, t)
            peer.write(pose_w[1], m2)
            wrong.write(point_w, point(header=m2.header, point=m2.pose.position))
            cmd.poll(0.0)
        assert proc.poll() is None  # alive
        cmd.poll(0.2)
        n_before = [len(b) for b in cmd.got]
        assert min(n_before) >= 10 and not any(np.any(c[2]) for b in cmd.got for c in b)  # latched e-stop: all zero
    finally:
        rc = P.stop(proc, signal.SIGTERM)
    end = time.monotonic() + 5.0
    while any(len(b) == n for b, n in zip(cmd.got, n_before)) and time.monotonic() < end:
        cmd.poll(0.05)
    text = (tmp_path / "bad.log").read_text()
    assert rc == 143 and "quatform: terminated (SIGTERM)" in text and "Traceback" not in text, text
    lines = text.splitlines()
    lost = [s for s in lines if "lost frame on /vrpn_client_node/r1/pose" in s]
    assert len(lost) >= 5 and all(s.startswith("[WARN]") for s in lost)
    wrong_type = [s for s in lines if "publisher of geometry_msgs/msg/PointStamped on /vrpn_client_node/r2/pose" in s]
    assert len(wrong_type) == 1 and "reads geometry_msgs/msg/PoseStamped" in wrong_type[0]
    assert "e-stop engaged" in text
    assert all(len(b) > n and not np.any(b[-1][2]) for b, n in zip(cmd.got, n_before))  # SIGTERM: zero out


def _started_in_lockstep(peer, proc, poses, log_path, ticks: int) -> int:
    """Step ``/clock`` until the bridge (started on state 0) ticks, then ``ticks`` more lockstep
    ticks; the ``/clock`` time of the last."""
    (p1, q1), (p2, q2) = poses
    c0 = P.started(peer, poses, DT_NS, proc, log_path)
    for k in range(1, ticks + 1):
        c = c0 + k * DT_NS
        peer.step(c, (P.pose(k, p1, q1, c), P.pose(k, p2, q2, c)))
        assert peer.cmd.wait_for(c, WAIT_S), f"no command at tick {k}"
    return c0 + ticks * DT_NS


@contextlib.contextmanager
def _sim_time_pair(tmp_path, loopback, name: str):
    """The bridge on the helix's pair with ``--use-sim-time`` (log ``<name>.log``) and its
    ``PairPeer``: a namespace of ``proc``, ``rf``, ``log_path``, ``poses`` (the simulation's robot
    poses) and ``peer``; on leaving, the bridge is stopped by SIGTERM and ``rc`` and ``text`` (its
    log) are set."""
    exp = experiment_for(H.short_pair(0.5), "quaternion")
    x = exp.run()["state"]
    proc, rf = _bridge(tmp_path, loopback, "--use-sim-time", name=name)
    run = SimpleNamespace(proc=proc, rf=rf, log_path=tmp_path / f"{name}.log")
    try:
        pr = FormationBridge(exp, rf).plant_robots
        run.poses = H.robot_poses(pr.models, pr.state_slices, x)
        run.peer = P.PairPeer(int(loopback["ROS_DOMAIN_ID"]), rf)
        yield run
    finally:
        run.rc = P.stop(proc, signal.SIGTERM)
        run.text = run.log_path.read_text()


def _new_commands(cmd, n_before, timeout_s: float = WAIT_S) -> list:
    """Each robot's commands read after its first ``n_before`` (waiting up to ``timeout_s`` for one each)."""
    end = time.monotonic() + timeout_s
    while any(len(b) <= n for b, n in zip(cmd.got, n_before)) and time.monotonic() < end:
        cmd.poll(0.05)
    return [b[n:] for b, n in zip(cmd.got, n_before)]


def test_estop_acts_at_once_while_the_clock_stands_still_and_an_engage_is_never_lost(tmp_path, loopback):
    """With --use-sim-time and /clock stopped (a paused or dead simulator): an engage followed at
    once by a release still zeroes every robot, released commands resume at the next /clock step,
    and an engage alone zeroes every robot without a /clock step; SIGTERM exits with 143."""
    with _sim_time_pair(tmp_path, loopback, "still") as run:
        proc, log_path, poses, peer = run.proc, run.log_path, run.poses, run.peer
        (p1, q1), (p2, q2) = poses
        P.Peer.wait_matched(peer.pose_w + [peer.clock_w, peer.estop_w] + peer.cmd.readers, 30.0, proc)
        c = _started_in_lockstep(peer, proc, poses, log_path, 3)
        assert all(np.any(x[2] != 0) for x in peer.cmd.stamped(c))
        bool_msg = messages.msg_type("std_msgs/msg/Bool")
        n = [len(b) for b in peer.cmd.got]
        peer.peer.write(peer.estop_w, bool_msg(data=True))  # engage and release between two /clock samples
        peer.peer.write(peer.estop_w, bool_msg(data=False))
        new = _new_commands(peer.cmd, n)
        assert all(box and all(not np.any(m[2]) and m[1] == c for m in box) for box in new), log_path.read_text()
        c += DT_NS  # released: the next /clock step's commands are the controller's again
        peer.step(c, (P.pose(4, p1, q1, c), P.pose(4, p2, q2, c)))
        assert peer.cmd.wait_for(c, WAIT_S) and all(np.any(x[2] != 0) for x in peer.cmd.stamped(c))
        n = [len(b) for b in peer.cmd.got]
        peer.peer.write(peer.estop_w, bool_msg(data=True))  # /clock stands still: zero at once all the same
        new = _new_commands(peer.cmd, n)
        assert all(box and not np.any(box[-1][2]) for box in new), log_path.read_text()
        assert proc.poll() is None
    rc, text = run.rc, run.text
    assert rc == 143 and "quatform: terminated (SIGTERM)" in text and "Traceback" not in text, text
    assert text.count("e-stop engaged") == 2 and text.count("e-stop released") == 1, text


def test_estop_service_answers_with_the_requests_header_and_zeroes_at_once(tmp_path, loopback):
    """A client of /quatform/set_estop on rmw_cyclonedds's wire (tests/dds_peer.py): data=true is
    answered with the request's (guid, seq) and success, and every robot's next commands are zero
    while /clock stands still; data=false releases: the next /clock step's commands are the
    controller's again."""
    with _sim_time_pair(tmp_path, loopback, "srv") as run:
        proc, log_path, poses, peer = run.proc, run.log_path, run.poses, run.peer
        (p1, q1), (p2, q2) = poses
        client = P.ServiceClient(peer.peer, run.rf.settings.estop_service, "std_srvs/srv/SetBool")
        P.Peer.wait_matched(peer.pose_w + [peer.clock_w] + peer.cmd.readers + [client.writer, client.reader],
                            30.0, proc)
        c = _started_in_lockstep(peer, proc, poses, log_path, 3)
        assert all(np.any(x[2] != 0) for x in peer.cmd.stamped(c))
        guid, n = 0x0110_2030_4050_6070, [len(b) for b in peer.cmd.got]
        reply = client.call(guid, 41, WAIT_S, data=True)
        assert reply is not None and (reply.guid, reply.seq) == (guid, 41) and reply.success, log_path.read_text()
        assert "engaged" in reply.message
        new = _new_commands(peer.cmd, n)
        assert all(box and all(not np.any(m[2]) and m[1] == c for m in box) for box in new), log_path.read_text()
        c += DT_NS  # engaged: the next /clock step's commands are zero too
        peer.step(c, (P.pose(4, p1, q1, c), P.pose(4, p2, q2, c)))
        assert peer.cmd.wait_for(c, WAIT_S) and not any(np.any(x[2]) for x in peer.cmd.stamped(c))
        reply = client.call(guid, 42, WAIT_S, data=False)
        assert reply is not None and (reply.guid, reply.seq) == (guid, 42) and reply.success
        assert reply.message == "e-stop released"
        c += DT_NS
        peer.step(c, (P.pose(5, p1, q1, c), P.pose(5, p2, q2, c)))
        assert peer.cmd.wait_for(c, WAIT_S) and all(np.any(x[2] != 0) for x in peer.cmd.stamped(c))
        assert [(r.guid, r.seq) for r in client.replies] == [(guid, 41), (guid, 42)]  # one reply per request
        assert proc.poll() is None
    rc, text = run.rc, run.text
    assert rc == 143 and "Traceback" not in text, text
    assert text.count("e-stop engaged") == 1 and text.count("e-stop released") == 1, text


@pytest.mark.parametrize("uri, said", [("file:///nonexistent-quatform.xml", "can't open configuration file"),
                                       ("<General><Tag", "parser error"),
                                       ('<General><Interfaces><NetworkInterface name="nosuch0"/></Interfaces>'
                                        "</General>", "nosuch0")])
def test_a_configuration_cyclone_refuses_is_one_line(uri, said, tmp_path, loopback, monkeypatch, capsys):
    """A CYCLONEDDS_URI Cyclone cannot use (a missing file, malformed XML, an unknown interface) is
    one line naming it and ROS_DOMAIN_ID, exit 2, not an internal error."""
    from quatform import cli

    monkeypatch.setenv("CYCLONEDDS_URI", uri)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(P.claim_domain()))  # a domain this process has not created yet
    robots = H.write(tmp_path / "robots.toml", H.PAIR_ROBOTS)
    rc = cli.main(["ros2", "--transport", "dds", "--scenario", "mas-kitts-helix", "--robots", str(robots),
                   "--controller", "quaternion"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "internal error" not in err, err
    assert f"CYCLONEDDS_URI={uri!r}" in err and "ROS_DOMAIN_ID=" in err and said in err, err


def _ring3(folder: Path) -> Path:
    """net-consensus-ring with three robots (no antipodal reports), 0.4 s, and links of one tick's
    delay (20 ms): what a robot's node hears at a tick over the wire in lockstep, its neighbour's
    message of the tick before."""
    from quatform.scenarios import builtin_scenarios

    src = builtin_scenarios()["net-consensus-ring"].read_text()
    src = re.sub(r"(?m)^duration_s = .*$", "duration_s = 0.4", src)
    src = src.replace("count = 12", "count = 3")
    src = re.sub(r"(?m)^antipodal = .*\n", "", src)
    src += "\n[links]\ndelay_s = 0.02\nmax_age_s = 0.05\n"
    return H.write(folder / "ring3.toml", src)


RING_ROBOTS = "".join(f"""
[[robots]]
name = "r{k}"
pose_topic = "/mocap/r{k}/pose"
timeout_s = 0.1
""" for k in (1, 2, 3)) + "\n[bridge]\nstart_timeout_s = 5.0\n"


def test_one_node_per_robot_over_dds_hears_its_neighbour_and_gives_the_simulations_commands(tmp_path, loopback):
    """Three robots' nodes (three processes, each in its namespace) on the directed ring: each
    reads its pose and its neighbour's /rJ/quatform/message over DDS; in lockstep on /clock their
    commands are the simulator's (links of one tick's delay) within 1e-9."""
    from quatform.ros2.local_bridge import LocalBridge

    scenario = _ring3(tmp_path)
    robots = H.write(tmp_path / "robots.toml", RING_ROBOTS)
    exp = experiment_for(scenario)
    log = exp.run()
    rf = read_robots_file(robots)
    b = LocalBridge(exp, 0, rf)
    pr = b.io.plant_robots
    poses = H.robot_poses(pr.models, pr.state_slices, log["state"])
    procs = [P.quatform_process(["ros2", "--transport", "dds", "--use-sim-time", "--scenario", scenario, "--robots",
                                 robots, "--robot", k], loopback, tmp_path / f"r{k}.log") for k in (1, 2, 3)]
    try:
        peer = P.Peer(int(loopback["ROS_DOMAIN_ID"]))
        pose_w = [peer.writer(f"rt/mocap/r{k}/pose", "geometry_msgs/msg/PoseStamped") for k in (1, 2, 3)]
        clock_w = peer.writer("rt/clock", "rosgraph_msgs/msg/Clock", "clock")
        cmd = P.Commands(peer, [peer.reader(f"rt/r{k}/cmd_vel", "geometry_msgs/msg/TwistStamped") for k in (1, 2, 3)])
        said = [peer.reader(f"rt/r{k}/quatform/message", "sensor_msgs/msg/JointState", "sensor")
                for k in (1, 2, 3)]
        for proc in procs:
            P.Peer.wait_matched(pose_w + [clock_w] + cmd.readers + said, 30.0, proc)
        clock = messages.msg_type("rosgraph_msgs/msg/Clock")
        sent = [[] for _ in said]

        def step(k, c):
            for w, (p, q) in zip(pose_w, poses):
                peer.write(w, P.pose(k, p, q, c))
            peer.write(clock_w, clock(clock=messages.stamp_ns(c)))

        dt = 20_000_000
        c0 = 0
        while True:  # state 0 until every node (each started on its pose) ticks at one /clock step
            step(0, c0)
            if cmd.wait_for(c0, 1.0):
                break
            assert all(p.poll() is None for p in procs) and c0 < 20 * dt
            assert not any(cmd.stamped(c0)), "the robots' nodes started at different /clock steps"
            c0 += dt
        T = len(log.t)
        for k in range(T):
            if k:
                # every node must hold its neighbour's message of tick k - 1 before the /clock step of
                # tick k (the peer has them): a 50 ms margin for the nodes' DDS threads on busy cores
                time.sleep(0.05)
                step(k, c0 + k * dt)
                assert cmd.wait_for(c0 + k * dt, WAIT_S), f"no command at tick {k}"
            end = time.monotonic() + WAIT_S  # every robot's message of this tick, before the next /clock step
            while True:
                for box, r in zip(sent, said):
                    box.extend(m for _, m in peer.take(r))
                if all(any(messages.nanoseconds(m.header.stamp) == c0 + k * dt for m in box) for box in sent):
                    break
                assert time.monotonic() < end, f"no message at tick {k}"
                peer.wait(0.01)
    finally:
        codes = [P.stop(p, signal.SIGINT) for p in procs]
    texts = [(tmp_path / f"r{k}.log").read_text() for k in (1, 2, 3)]
    assert codes == [130] * 3 and not any("Traceback" in t for t in texts), texts
    u = np.asarray(log["command"])
    for i in range(3):
        got = np.array([cmd.stamped(c0 + k * dt)[i][2] for k in range(T)])
        np.testing.assert_allclose(got, u[:, 6 * i:6 * i + 6], rtol=0, atol=1e-9)
        assert np.any(got[1:] != 0)
        m = sent[i][-1]  # the law's columns and the sender's position, as LocalBridge names them
        assert tuple(m.name) == b.columns
        np.testing.assert_allclose(np.asarray(m.position)[-3:], poses[i][0][T - 1], rtol=0, atol=1e-12)
