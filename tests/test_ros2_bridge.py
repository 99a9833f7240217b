"""The ROS 2 bridge without ROS: robots.toml, frames, pose/command conversions, the control tick."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform import messages
from quatform.errors import InvalidInputError
from quatform.formations import geometry as g
from quatform.robots import Bebop, Pioneer
from quatform.ros2 import frames
from quatform.ros2.bridge import FormationBridge, experiment_for
from quatform.ros2.endpoints import pose_sample
from quatform.ros2.robot_io import PoseSample, robot_io
from quatform.ros2.robots_file import read_robots_file, robots_from_dict

_spec = importlib.util.spec_from_file_location("ros2_helpers", Path(__file__).parent / "fake_rclpy" / "ros2_helpers.py")
H = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(H)

unit_q = st.lists(st.floats(-1, 1), min_size=4, max_size=4).map(np.array).filter(
    lambda q: np.linalg.norm(q) > 0.1).map(lambda q: q / np.linalg.norm(q))
vec3 = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array)


# -- robots.toml --------------------------------------------------------------------------------
def _robots(**extra):
    base = {"name": "r1", "pose_topic": "/mocap/r1/pose"}
    return {"robots": [{**base, **extra}, {"name": "r2", "pose_topic": "/mocap/r2/pose", "namespace": "/r2"}]}


def test_robots_file_reads_topics_namespaces_and_defaults(tmp_path):
    rf = read_robots_file(H.write(tmp_path / "robots.toml", H.PAIR_ROBOTS))
    assert rf.names == ("r1", "r2")
    r1 = rf.robots[0]
    assert (r1.pose_topic, r1.command_topic, r1.command_type, r1.command_frame, r1.timeout_s) == (
        "/vrpn_client_node/r1/pose", "/r1/cmd_vel", "twist-stamped", None, 0.05)
    assert rf.settings.start_timeout_s == 1.0 and rf.settings.estop_topic == "/quatform/estop"
    px4 = robots_from_dict(_robots(namespace="/px4_1", command_type="px4"), "f.toml").robots[0]
    assert px4.command_topic == "/px4_1/fmu/in/trajectory_setpoint"
    assert px4.offboard_topic == "/px4_1/fmu/in/offboard_control_mode"
    mavros = robots_from_dict(_robots(command_type="mavros"), "f.toml").robots[0]
    assert mavros.command_topic == "/r1/mavros/setpoint_velocity/cmd_vel"  # under the default namespace /r1
    bare = robots_from_dict(_robots(namespace=""), "f.toml").robots[0]
    assert bare.command_topic == "/cmd_vel"


@pytest.mark.parametrize("data, words", [
    (_robots(timeout=0.2), ["unknown key 'timeout'", "did you mean 'timeout_s'"]),
    ({**_robots(), "brige": {}}, ["unknown key 'brige'", "'bridge'"]),
    (_robots(pose_type="posestamped"), ["pose_type", "pose, odometry, px4"]),
    (_robots(timeout_s=-1.0), ["timeout_s"]),
    (_robots(pose_topic="/mocap/r2/pose"), ["/mocap/r2/pose is named twice", "'r1' pose_topic", "'r2' pose_topic"]),
    (_robots(command_topic="/mocap/r2/pose"), ["/mocap/r2/pose is named twice"]),
    (_robots(name="r2"), ["two [[robots]] are named 'r2'"]),
    (_robots(command_type="px4", command_frame="body"), ["world-frame"]),
    (_robots(pose_topic="/a//b"), ["not a valid ROS 2 name"]),
    ({"robots": []}, ["no [[robots]]"]),
])
def test_robots_file_bad_input_is_one_line(data, words):
    with pytest.raises(InvalidInputError) as err:
        robots_from_dict(data, "robots.toml")
    text = str(err.value)
    assert "\n" not in text and text.startswith("robots.toml")
    for w in words:
        assert w in text


# -- frames -------------------------------------------------------------------------------------
@settings(max_examples=50, deadline=None)
@given(q=unit_q, v=vec3, w=vec3)
def test_ned_frd_conversions_are_the_same_rotation(q, v, w):
    """A body vector seen in the world: ENU/FLU and NED/FRD agree; each conversion is its own inverse."""
    q_ned = frames.q_ned_frd_from_enu_flu(q)
    np.testing.assert_allclose(frames.ned_from_enu(g.rotate(q, v)), g.rotate(q_ned, frames.frd_from_flu(v)),
                               atol=1e-12)
    np.testing.assert_allclose(g.closest_sign(frames.q_enu_flu_from_ned_frd(q_ned), q), q, atol=1e-12)
    np.testing.assert_allclose(frames.enu_from_ned(frames.ned_from_enu(w)), w, atol=0)


#: Independent constructions: the axes of NED in ENU coordinates (north = ENU y,
#: east = ENU x, down = -ENU z) and of FRD in FLU ones (forward, right = -left, down = -up), as matrices.
M_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
M_FRD_FLU = np.diag([1.0, -1.0, -1.0])


def _matrix(q_wxyz):
    """Rotation matrix of a (w, x, y, z) quaternion by scipy (scalar-last), not quatform's algebra."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.r_[q_wxyz[1:], q_wxyz[0]]).as_matrix()


@settings(max_examples=50, deadline=None)
@given(q=unit_q, p=vec3, v=vec3, w=vec3)
def test_ned_frd_conversions_match_explicit_matrices(q, p, v, w):
    """Poses and twists through PX4's VehicleOdometry against the explicit ENU->NED and FLU->FRD
    matrices and scipy's rotation matrices: ``R_NED_FRD = M_NED_ENU R_ENU_FLU M_FRD_FLU^T``."""
    from quatform.ros2.px4 import vehicle_odometry, vehicle_odometry_pose

    q = q / np.linalg.norm(q)
    np.testing.assert_allclose(frames.ned_from_enu(p), M_NED_ENU @ p, atol=0)
    np.testing.assert_allclose(frames.frd_from_flu(w), M_FRD_FLU @ w, atol=0)
    R = _matrix(q)
    want = M_NED_ENU @ R @ M_FRD_FLU.T
    np.testing.assert_allclose(_matrix(frames.q_ned_frd_from_enu_flu(q)), want, atol=1e-12)
    np.testing.assert_allclose(_matrix(frames.q_ned_frd_from_enu_flu(q)) @ (M_FRD_FLU @ v), M_NED_ENU @ (R @ v),
                               atol=1e-9)
    # a VehicleOdometry (float32 fields): NED position and velocity, FRD body rates, then back
    v_world = R @ v
    msg = vehicle_odometry(1.5, p, q, v_world, w)
    np.testing.assert_allclose(msg.position, M_NED_ENU @ p, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(msg.velocity, M_NED_ENU @ v_world, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(msg.angular_velocity, M_FRD_FLU @ w, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(_matrix(np.asarray(msg.q, dtype=float) / np.linalg.norm(msg.q)), want, atol=1e-6)
    t, p_back, q_back, (lin, ang) = vehicle_odometry_pose(msg)
    assert t == pytest.approx(1.5)
    np.testing.assert_allclose(p_back, p, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(_matrix(q_back), R, atol=1e-6)
    np.testing.assert_allclose(lin, R.T @ v_world, rtol=1e-5, atol=1e-4)  # the body (FLU) velocity
    np.testing.assert_allclose(ang, w, rtol=1e-6, atol=1e-5)


def test_ned_of_a_yaw_is_its_negation_from_north():
    """Facing east in ENU (yaw 0) is yaw pi/2 in NED (heading measured from north toward east)."""
    q_ned = frames.q_ned_frd_from_enu_flu(np.array([1.0, 0, 0, 0]))
    assert g.yaw_of(q_ned) == pytest.approx(np.pi / 2)
    q_ned = frames.q_ned_frd_from_enu_flu(g.q_yaw(0.3))
    assert g.yaw_of(q_ned) == pytest.approx(np.pi / 2 - 0.3)


# -- pose and command conversions ----------------------------------------------------------------
def test_pioneer_state_is_its_control_point_and_twist_is_v_omega():
    model = Pioneer(a=0.15)
    io = robot_io(model)
    psi = 2.0
    pose = PoseSample(0.0, np.array([1.0, 2.0, 0.0]), g.q_yaw(psi))
    x = io.state(model, pose, None)
    np.testing.assert_allclose(x, [1 + 0.15 * np.cos(psi), 2 + 0.15 * np.sin(psi), psi], atol=1e-15)
    lin, ang = io.twist(model, np.array([0.4, -0.2]), x, pose.quaternion, "body")
    np.testing.assert_array_equal(np.r_[lin, ang], [0.4, 0, 0, 0, 0, -0.2])
    # a later heading just past pi is unwound next to the previous one (continuous)
    x2 = io.state(model, PoseSample(0.1, pose.position, g.q_yaw(np.pi + 0.1)), np.array([0, 0, 3.1]))
    assert x2[2] == pytest.approx(np.pi + 0.1)


def test_bebop_state_from_odometry_level_flight():
    model = Bebop()
    io = robot_io(model)
    psi = 0.7
    q = g.q_yaw(psi)
    pose = PoseSample(0.0, np.array([0.0, 1.0, 1.5]), q, (np.array([0.3, -0.1, 0.2]), np.array([0, 0, 0.4])))
    x = io.state(model, pose, None)
    # level: body velocity is the Bebop frame's (seed 001 eq. (3.8)), z_dot the world's, psi_dot = r
    np.testing.assert_allclose(x, [0, 1, 1.5, psi, 0.3, -0.1, 0.2, 0.4], atol=1e-12)
    with pytest.raises(InvalidInputError, match="odometry"):
        io.state(model, PoseSample(0.0, pose.position, q), None)


def test_holonomic_body_twist_is_in_its_heading_frame():
    from quatform.robots import HolonomicRobot

    m = HolonomicRobot()
    io = robot_io(m)
    x = np.array([0.0, 0.0, 1.0, np.pi / 2])
    lin, ang = io.twist(m, np.array([0.0, 1.0, 0.5, 0.2]), x, g.q_yaw(np.pi / 2), "body")
    np.testing.assert_allclose(np.r_[lin, ang], [1.0, 0.0, 0.5, 0, 0, 0.2], atol=1e-15)  # north is ahead


def test_lost_frames_never_reach_a_command():
    nan = messages.msg_type("geometry_msgs/msg/PoseStamped")
    good = messages.pose_stamped(1.0, [1, 2, 3], [1, 0, 0, 0])
    assert pose_sample("pose", good) is not None
    good.pose.position.x = float("nan")
    assert pose_sample("pose", good) is None
    bad_q = messages.pose_stamped(1.0, [1, 2, 3], [1, 0, 0, 0])
    bad_q.pose.orientation.w = 0.5  # non-unit
    assert pose_sample("pose", bad_q) is None
    assert nan is type(good)


@pytest.mark.filterwarnings("error")
def test_a_damaged_quaternion_is_a_lost_frame_without_an_overflow_warning():
    """An entry of 1e200 (a damaged frame) printed numpy's "overflow encountered in multiply"
    on stderr of the node and of replay before dropping the frame."""
    huge = messages.pose_stamped(1.0, [1, 2, 3], [1, 0, 0, 0])
    huge.pose.orientation.w = 1e200
    assert pose_sample("pose", huge) is None


# -- the bridge ----------------------------------------------------------------------------------
def test_team_with_a_pioneer_matches_the_simulation(tmp_path):
    """team-triangle-over-ugv (a Pioneer under three quadrotors, the separation barrier on):
    measured poses of the simulated run -> the bridge's commands are the simulation's."""
    sc = H.short_triangle(tmp_path, 0.5)
    exp = experiment_for(sc, "quaternion")
    log = exp.run()
    rf = robots_from_dict({"robots": [{"name": n, "pose_topic": f"/vrpn_client_node/{n}/pose", "namespace": f"/{n}"}
                                      for n in ("ugv", "uav1", "uav2", "uav3")]}, "robots.toml")
    b = FormationBridge(exp, rf)
    assert b.frames == ("body", "world", "world", "world")
    pr = b.plant_robots
    msgs = H.pose_messages(H.robot_poses(pr.models, pr.state_slices, log["state"]), log.t)
    u = []
    for k, t in enumerate(log.t):
        ns = int(round(t * 1e9))
        for i in range(4):
            assert b.on_pose(i, msgs[i][k], ns)
        tick = b.tick(ns)
        assert tick.status == "ok" and tick.tau == pytest.approx(t, abs=1e-12)
        u.append(tick.u)
        lin, ang = tick.twists[0]
        np.testing.assert_array_equal(np.r_[lin, ang], [tick.u[0], 0, 0, 0, 0, tick.u[1]])  # (v, omega)
    np.testing.assert_allclose(np.array(u), log["command"], rtol=0, atol=1e-12)
    # uav2 in its heading frame: its group converts apart; the others' twists do not change
    rows = [{"name": n, "pose_topic": f"/vrpn_client_node/{n}/pose", "namespace": f"/{n}"}
            for n in ("ugv", "uav1", "uav2", "uav3")]
    rows[2]["command_frame"] = "body"
    b2 = FormationBridge(exp, robots_from_dict({"robots": rows}, "robots.toml"))
    for i in range(4):
        b2.on_pose(i, msgs[i][-1], 0)
    tick2 = b2.tick(0)
    theta = b2.states[2][3]
    v = tick2.u[b2.plant_robots.command_slices[2]]
    lin, ang = tick2.twists[2]
    np.testing.assert_allclose(lin, [np.cos(theta) * v[0] + np.sin(theta) * v[1],
                                     -np.sin(theta) * v[0] + np.cos(theta) * v[1], v[2]], atol=1e-14)
    assert ang[2] == v[3]
    for i in (1, 3):
        np.testing.assert_array_equal(np.r_[tick2.twists[i]], np.r_[tick2.u[b2.plant_robots.command_slices[i]][:3],
                                                                    0, 0, tick2.u[b2.plant_robots.command_slices[i]][3]])


def test_bridge_refuses_what_the_robots_cannot_take(tmp_path):
    sc = H.short_triangle(tmp_path, 0.2)
    exp = experiment_for(sc, "quaternion")
    four = [{"name": f"r{i}", "pose_topic": f"/p{i}"} for i in range(4)]
    with pytest.raises(InvalidInputError, match=r"names 3 robots, .* has 4 \(Pioneer"):
        FormationBridge(exp, robots_from_dict({"robots": four[:3]}, "robots.toml"))
    with pytest.raises(InvalidInputError, match=r"names 1 robot, .* has 4 \(Pioneer"):  # one: no plural
        FormationBridge(exp, robots_from_dict({"robots": four[:1]}, "robots.toml"))
    with pytest.raises(InvalidInputError, match="robot 'r0' is a Pioneer.*command_frame = 'body'"):
        FormationBridge(exp, robots_from_dict({"robots": [{**four[0], "command_frame": "world"}, *four[1:]]}, "f"))
    with pytest.raises(InvalidInputError, match="robot 'r0' is a Pioneer.*px4 velocity setpoint"):
        FormationBridge(exp, robots_from_dict({"robots": [{**four[0], "command_type": "px4"}, *four[1:]]}, "f"))


def test_controller_option_maps_to_the_kind():
    with pytest.raises(InvalidInputError, match="teleop"):
        FormationBridge(experiment_for("teleop-free-motion"), robots_from_dict(
            {"robots": [{"name": "arm", "pose_topic": "/arm"}]}, "robots.toml"))
    exp = experiment_for("marciano-circle", "quaternion")  # ugv-uav: --controller is its formation
    rf = robots_from_dict({"robots": [{"name": "p3dx", "pose_topic": "/p"},
                                      {"name": "bebop", "pose_topic": "/b", "pose_type": "odometry"}]}, "robots.toml")
    b = FormationBridge(exp, rf)
    assert b.frames == ("body", "body")
    with pytest.raises(InvalidInputError, match="odometry"):
        FormationBridge(exp, robots_from_dict({"robots": [{"name": "p", "pose_topic": "/p"},
                                                          {"name": "b", "pose_topic": "/b"}]}, "robots.toml"))
    with pytest.raises(InvalidInputError, match="formation"):
        experiment_for("marciano-circle", "dual-quaternion-typo")


def test_ugv_uav_tick_on_measured_poses():
    """seed 001's Pioneer + Bebop: a tick on odometry-style poses gives finite commands
    (v, omega) and Bebop fractions within [-1, 1], in their body frames."""
    exp = experiment_for("marciano-circle", "quaternion")
    rf = robots_from_dict({"robots": [{"name": "p3dx", "pose_topic": "/p", "pose_type": "odometry"},
                                      {"name": "bebop", "pose_topic": "/b", "pose_type": "odometry"}]}, "robots.toml")
    b = FormationBridge(exp, rf)
    odo = messages.msg_type("nav_msgs/msg/Odometry")
    x0 = exp.x0
    for k in range(5):
        t = k * 0.03
        for i, (p, psi) in enumerate(((np.r_[x0[0] - 0.15 * np.cos(x0[2]), x0[1] - 0.15 * np.sin(x0[2]), 0.0], x0[2]),
                                      (x0[3:6], x0[6]))):
            pose = messages.pose_stamped(t, p, g.q_yaw(psi))
            twist = messages.msg_type("geometry_msgs/msg/TwistWithCovariance")(twist=messages.twist([0, 0, 0], [0, 0, 0]),
                                                                             covariance=np.zeros(36))
            pwc = messages.msg_type("geometry_msgs/msg/PoseWithCovariance")(pose=pose.pose, covariance=np.zeros(36))
            assert b.on_pose(i, odo(header=pose.header, child_frame_id="base_link", pose=pwc, twist=twist),
                             int(t * 1e9))
        tick = b.tick(int(t * 1e9))
        assert tick.status == "ok" and np.all(np.isfinite(tick.u))
        assert np.all(np.abs(tick.u[2:6]) <= 1.0)
    assert np.any(tick.u != 0)


def test_importing_the_bridge_and_cli_does_not_import_rclpy_or_cyclonedds():
    import subprocess
    import sys

    code = ("import sys, quatform.cli, quatform.ros2, quatform.ros2.node, quatform.ros2.replay, quatform.ros2.dds, "
            "quatform.ros2.rclpy_transport; quatform.cli._build_parser(); "
            "print('rclpy' in sys.modules, 'cyclonedds' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False False"
