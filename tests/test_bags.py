"""quatform.bags: run.mcap (ROS 2 messages in one MCAP file), read back exactly, and users' pose bags.

Oracles: rosbags' own reader and CDR deserialiser (the messages quatform builds in batches
are read back message by message by rosbags and compared with the log), and rosbags' writer
for the users' bags read by read_poses.
"""

import dataclasses
import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform import messages
from quatform.bags import INFO_TOPIC, MCAP_FILE, foxglove_layout, read_log, read_poses, scene_of, write_mcap
from quatform.bags.cdr import Batch, field_offsets
from quatform.cli import main
from quatform.errors import InvalidInputError, NonUnitError
from quatform.formations import FORMATIONS
from quatform.formations import geometry as g
from quatform.robots import Bebop, Pioneer
from quatform.scenarios import kind_of, load_scenario
from quatform.sim.log import Log

FREE_BODIES = """
kind = "team"
name = "free-bodies"
title = "three free bodies"
source = "a test scene"
duration_s = 0.4
dt_s = 0.02
metrics_from_s = 0.0
gains = "table1"
[[robots]]
model = "free-body"
count = 3
[shape]
template = "triangle"
side = 1.0
[path]
kind = "line"
center = [0.0, 0.0, 0.0]
velocity = [0.15, 0.0, 0.0]
[[attitude.turns]]
axis = [0.0, 0.0, -1.0]
angle = 1.0
start_s = 0.0
duration_s = 0.4
[headings]
mode = "fixed"
"""

#: (scenario, replaced fields, options): every kind, planar, 4-DOF, mixed and free-body robots.
CASES = {
    "pair": ("mas-kitts-helix", {"duration_s": 1.0, "metrics_from_s": 0.0}, {"controller": "quaternion"}),
    "ugv-uav": ("marciano-circle", {"duration_s": 0.6, "transient_s": 0.1, "mocap_noise_m": 0.002}, {}),
    "teleop": ("teleop-wall-contact", {"duration_s": 0.05}, {}),
    "team-planar": ("team-three-bodies", {"duration_s": 0.4}, {"controller": "quaternion"}),
    "team-mixed": ("team-triangle-over-ugv", {"duration_s": 0.4, "metrics_from_s": 0.0}, {"controller": "quaternion"}),
    "team-free": (None, {}, {"controller": "quaternion"}),
}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``{case: (kind name, log, run.mcap)}`` of short runs of every kind."""
    folder = tmp_path_factory.mktemp("bags")
    (folder / "free.toml").write_text(FREE_BODIES)
    out = {}
    for case, (name, changes, options) in CASES.items():
        sc = load_scenario(name or folder / "free.toml")
        sc = dataclasses.replace(sc, **changes) if changes else sc
        kind = kind_of(sc)
        log = kind.experiment(sc, **options).run(None)
        out[case] = (kind.parts_of(sc), log, write_mcap(log, folder / f"{case}.mcap", kind=kind.parts_of(sc)))
    return out


@functools.cache
def _read_all(path):
    """``{topic: (msgtype, [(log time ns, message)])}`` read by rosbags' own reader (the oracle)."""
    from rosbags.highlevel import AnyReader

    out = {}
    with AnyReader([path]) as reader:
        for conn, ts, raw in reader.messages():
            out.setdefault(conn.topic, (conn.msgtype, []))[1].append((ts, reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.mark.parametrize("case", list(CASES))
def test_read_log_round_trips_every_channel_exactly(runs, case):
    _, log, path = runs[case]
    back = read_log(path)
    assert list(back.channels) == list(log.channels)
    for name, ch in log.channels.items():
        assert back.channels[name].columns == ch.columns
        assert back[name].dtype == np.asarray(ch.data).dtype
        np.testing.assert_array_equal(back[name], ch.data)  # to the float
    assert np.max(np.abs(back.t - log.t)) <= 0.5e-9 + 1e-15 * np.max(log.t)  # to the nanosecond
    for key in ("controller", "label"):
        assert back.meta[key] == log.meta[key]


@pytest.mark.parametrize("case", list(CASES))
def test_rosbags_reads_the_standard_messages_one_per_sample(runs, case):
    _, log, path = runs[case]
    topics = _read_all(path)
    n = len(log)
    expected = {"pair": ("/robot_1/pose", "/robot_2/pose_desired", "/robot_1/cmd_vel", "/tf", "/formation/edges",
                         "/formation/pose", "/formation/pose_desired", "/robot_1/path_desired"),
                "ugv-uav": ("/pioneer/pose", "/bebop/pose", "/bebop/pose_measured", "/pioneer/cmd_vel",
                            "/bebop/cmd_vel", "/tf", "/formation/edges", "/formation/pose",
                            "/formation/pose_desired", "/bebop/odom"),
                "teleop": ("/master_hand/pose", "/slave_hand/pose", "/master/joint_states", "/slave/joint_states",
                           "/slave_wrist/wrench", "/tf", "/tf_static"),
                "team-planar": ("/robot_3/pose", "/robot_3/cmd_vel", "/tf", "/formation/edges", "/formation/pose"),
                "team-mixed": ("/robot_1/pose", "/robot_4/pose_desired", "/robot_1/cmd_vel", "/tf",
                               "/formation/pose", "/formation/pose_desired"),
                "team-free": ("/robot_2/pose", "/robot_2/cmd_vel", "/tf")}[case]
    missing = [t for t in expected if t not in topics]
    assert not missing, f"missing topics {missing}; have {sorted(topics)}"
    once = ("/tf_static", INFO_TOPIC)
    for topic, (msgtype, msgs) in topics.items():
        if topic in once or topic.endswith(("/path", "/path_desired")):
            assert len(msgs) == 1, topic
        else:
            assert len(msgs) == n, f"{topic}: {len(msgs)} messages for {n} samples"
            stamps = np.array([messages.seconds(_stamp(msgtype, m)) for _, m in msgs])
            np.testing.assert_allclose(stamps, log.t, rtol=0, atol=1e-9)
            np.testing.assert_array_equal(np.array([ts for ts, _ in msgs]), np.round(log.t * 1e9).astype(np.int64))
    for topic, (msgtype, msgs) in topics.items():  # every quaternion of a pose, path or transform is unit
        for _, m in msgs[:: max(1, n // 7)]:
            for o in _orientations(msgtype, m):
                assert abs(np.sqrt(o.w ** 2 + o.x ** 2 + o.y ** 2 + o.z ** 2) - 1.0) < 1e-9, topic


def _stamp(msgtype, m):
    return {"tf2_msgs/msg/TFMessage": lambda: m.transforms[0].header.stamp,
            "nav_msgs/msg/Odometry": lambda: m.header.stamp,
            "visualization_msgs/msg/MarkerArray": lambda: m.markers[0].header.stamp}.get(msgtype, lambda: m.header.stamp)()


def _orientations(msgtype, m):
    return {"geometry_msgs/msg/PoseStamped": lambda: [m.pose.orientation],
            "geometry_msgs/msg/PoseArray": lambda: [p.orientation for p in m.poses],
            "nav_msgs/msg/Path": lambda: [p.pose.orientation for p in m.poses],
            "nav_msgs/msg/Odometry": lambda: [m.pose.pose.orientation],
            "tf2_msgs/msg/TFMessage": lambda: [t.transform.rotation for t in m.transforms]}.get(msgtype, list)()


def test_a_pair_runs_poses_commands_and_frames_are_its_state(runs):
    """/robot_i/pose is robot i's (x, y, z) and the quaternion of its yaw; cmd_vel its world rates;
    /tf holds world -> robots, desired robots, formation (the cluster channel's x_c, q_c)."""
    _, log, path = runs["pair"]
    topics = _read_all(path)
    state, u, cluster = log["state"], log["command"], log["cluster"]
    cc = log.columns("cluster")
    k = len(log) // 2
    for i in range(2):
        _, p, q, frame = messages.pose_from_msg(topics[f"/robot_{i + 1}/pose"][1][k][1])
        assert frame == "world"
        np.testing.assert_array_equal(p, state[k, 4 * i:4 * i + 3])
        np.testing.assert_allclose(q, g.q_yaw(state[k, 4 * i + 3]), atol=1e-15)
        tw = topics[f"/robot_{i + 1}/cmd_vel"][1][k][1]
        assert tw.header.frame_id == "world"
        lin, ang = messages.twist_from_msg(tw)
        np.testing.assert_array_equal(np.r_[lin, ang[2]], u[k, 4 * i:4 * i + 4])
        np.testing.assert_array_equal(ang[:2], [0.0, 0.0])
    tf = {t.child_frame_id: t for t in topics["/tf"][1][k][1].transforms}
    assert set(tf) == {"robot_1", "robot_2", "robot_1_desired", "robot_2_desired", "formation", "formation_desired"}
    f = tf["formation"].transform
    # the formation frame: the quaternion pair's forward map of the robots (for every controller);
    # this quaternion run's own cluster x_c, q_c agree with it
    frame = FORMATIONS["quaternion"].forward(state[k])[:7]
    for got in (frame, cluster[k, [cc.index(c) for c in ("x_c", "y_c", "z_c", "q_c_w", "q_c_x", "q_c_y", "q_c_z")]]):
        np.testing.assert_allclose([f.translation.x, f.translation.y, f.translation.z], got[:3], atol=1e-12)
        np.testing.assert_allclose([f.rotation.w, f.rotation.x, f.rotation.y, f.rotation.z], got[3:], atol=1e-9)
    edges = topics["/formation/edges"][1][k][1].markers
    assert edges[0].type == 5 and edges[0].ns == "edges"  # LINE_LIST between the two robots
    np.testing.assert_array_equal([[pt.x, pt.y, pt.z] for pt in edges[0].points],
                                  [state[k, 0:3], state[k, 4:7]])
    named = topics["/quatform/cluster"][1][k][1]
    assert named.x_c == cluster[k, cc.index("x_c")] and named.q_c1_w == cluster[k, cc.index("q_c1_w")]


def test_ugv_uav_bodies_are_planar_pioneer_and_bebop_with_body_frame_commands(runs):
    _, log, path = runs["ugv-uav"]
    topics = _read_all(path)
    cols = log.columns("state")
    k = len(log) - 1
    _, p, q, _ = messages.pose_from_msg(topics["/pioneer/pose"][1][k][1])
    assert p[2] == 0.0  # planar: z = 0
    psi = log["state"][k, cols.index("psi_p")]
    np.testing.assert_allclose(g.yaw_of(q), psi, atol=1e-12)
    # its base (REP-105 base_link), a behind the control point its state holds
    a = Pioneer().a
    np.testing.assert_allclose(p[:2] + a * np.array([np.cos(psi), np.sin(psi)]),
                               log["state"][k, [cols.index("x_p"), cols.index("y_p")]], atol=1e-12)
    edge = topics["/formation/edges"][1][k][1].markers[0].points[0]  # the edges join the control point
    np.testing.assert_array_equal([edge.x, edge.y], log["state"][k, [cols.index("x_p"), cols.index("y_p")]])
    _, p, _, _ = messages.pose_from_msg(topics["/bebop/pose"][1][k][1])
    np.testing.assert_array_equal(p, log["state"][k, [cols.index(c) for c in ("x_b", "y_b", "z_b")]])
    tw = topics["/pioneer/cmd_vel"][1][k][1]
    assert tw.header.frame_id == "pioneer"
    assert (tw.twist.linear.x, tw.twist.angular.z) == tuple(log["command"][k, :2])
    _, pm, _, _ = messages.pose_from_msg(topics["/bebop/pose_measured"][1][k][1])
    assert not np.array_equal(pm, p)  # the motion capture's noise


def test_teleop_joint_states_and_wrench_are_the_arms_state(runs):
    _, log, path = runs["teleop"]
    topics = _read_all(path)
    cols = log.columns("state")
    k = len(log) - 1
    js = topics["/slave/joint_states"][1][k][1]
    assert list(js.name) == [f"slave_joint_{j}" for j in range(1, 8)]
    np.testing.assert_array_equal(js.position, log["state"][k, [cols.index(f"q_s{j}") for j in range(1, 8)]])
    np.testing.assert_array_equal(js.velocity, log["state"][k, [cols.index(f"qd_s{j}") for j in range(1, 8)]])
    ucols = log.columns("command")
    np.testing.assert_array_equal(js.effort, log["command"][k, [ucols.index(f"tau_s{j}") for j in range(1, 8)]])
    w = topics["/slave_wrist/wrench"][1][k][1].wrench
    np.testing.assert_array_equal([w.force.x, w.force.y, w.force.z],
                                  log["state"][k, [cols.index(c) for c in ("F_s_x", "F_s_y", "F_s_z")]])
    static = topics["/tf_static"][1][0][1].transforms
    assert {(t.header.frame_id, t.child_frame_id) for t in static} == {("world", "master_base"), ("world", "slave_base")}


def test_a_free_body_is_drawn_with_its_own_quaternion(runs):
    _, log, path = runs["team-free"]
    topics = _read_all(path)
    pts, names = log["points"], log.columns("points")
    k = len(log) - 1
    _, _, q, _ = messages.pose_from_msg(topics["/robot_2/pose"][1][k][1])
    np.testing.assert_array_equal(q, pts[k, [names.index(c) for c in ("q_w2", "q_x2", "q_y2", "q_z2")]])
    tw = topics["/robot_2/cmd_vel"][1][k][1]
    ucols = log.columns("command")
    np.testing.assert_array_equal(np.r_[messages.twist_from_msg(tw)],
                                  log["command"][k, [ucols.index(c + "2") for c in ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z")]])


def test_read_poses_reads_a_runs_own_poses(runs):
    _, log, path = runs["pair"]
    track = read_poses(path, ["/robot_2/pose"])["/robot_2/pose"]
    np.testing.assert_array_equal(track.position, log["state"][:, 4:7])
    np.testing.assert_allclose(track.quaternion, g.q_yaw(log["state"][:, 7]), atol=1e-15)
    assert track.frame_id == "world" and np.max(np.abs(track.t - log.t)) < 1e-9


def _get(msg, path):
    """The field of ``msg`` at ``path`` (names and sequence indices)."""
    for key in path:
        msg = msg[key] if isinstance(key, int) else getattr(msg, key)
    return msg


unit = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda v: 0.1 < np.linalg.norm(v)).map(lambda v: np.array(v) / np.linalg.norm(v))
vec = st.tuples(*[st.floats(-1e6, 1e6, allow_subnormal=False)] * 3).map(np.array)


@settings(max_examples=10, deadline=None)
@given(t=st.floats(0, 1e5), p=vec, q=unit, v=vec, pts=st.lists(vec, min_size=2, max_size=6).filter(lambda x: len(x) % 2 == 0),
       names=st.lists(st.text("abcxyz_", min_size=1, max_size=6), min_size=1, max_size=4))
def test_batched_cdr_equals_rosbags_serialiser(t, p, q, v, pts, names):
    """Messages built as one byte array equal rosbags' serialisation of each message."""
    store = messages.typestore()
    j = np.arange(len(names), dtype=float)
    cases = [
        (messages.pose_stamped(t, p, q, "world"), ("pose",), lambda m: m.pose, "position", "orientation"),
        (messages.tf_message([messages.transform_stamped(t, "world", n, p, q) for n in names]), None, None, "", ""),
        (messages.marker_array([messages.line_list(t, np.array(pts))]), None, None, "", ""),
        (messages.joint_state(t, names, j, 2 * j, 3 * j), None, None, "", ""),
        (messages.wrench_stamped(t, v, -v, "wrist"), None, None, "", ""),
    ]
    for msg, *_ in cases:
        zero = store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)
        offsets, nbytes = field_offsets(store, msg)
        raw = np.frombuffer(bytes(store.serialize_cdr(msg, msg.__msgtype__)), dtype=np.uint8)
        assert nbytes == raw.size
        # every numeric field read at its offset is the message's own value
        values = Batch.read(store, msg, raw[None, :], list(offsets))
        for path, got in values.items():
            assert got[0] == _get(zero, path), (msg.__msgtype__, path)
        # a batch of two with changed numbers serialises like rosbags does each message
        cols = {path: np.array([values[path][0], values[path][0]]) for path in offsets}
        first = next(path for path, (_, dt) in offsets.items() if dt == "<f8")
        cols[first] = np.array([1.5, -2.25])
        batch = Batch.build(store, msg, cols, 2)
        for k in range(2):
            m = store.deserialize_cdr(batch.data[k].tobytes(), msg.__msgtype__)
            assert _get(m, first) == cols[first][k]
            assert bytes(store.serialize_cdr(m, msg.__msgtype__)) == batch.data[k].tobytes()


def test_a_large_team_gets_pose_arrays_instead_of_topics_per_robot(runs, tmp_path, monkeypatch):
    from quatform.bags import mcap

    monkeypatch.setattr(mcap, "PER_BODY_TOPICS_UP_TO", 2)
    _, log, _ = runs["team-planar"]
    topics = _read_all(write_mcap(log, tmp_path / "team.mcap", kind="team"))
    assert "/robot_1/pose" not in topics and "/robot_1/cmd_vel" not in topics
    msgs = topics["/robots/poses"][1]
    assert len(msgs) == len(log)
    k = len(log) - 1
    np.testing.assert_array_equal([[p.position.x, p.position.y, p.position.z] for p in msgs[k][1].poses],
                                  np.c_[log["points"][k, 0::3], log["points"][k, 1::3], np.zeros(3)])
    assert {t.child_frame_id for t in topics["/tf"][1][k][1].transforms} >= {"robot_1", "robot_3_desired"}


def test_a_batched_log_writes_the_world_it_is_told_and_refuses_otherwise(tmp_path):
    t = np.arange(5) * 0.1
    data = np.arange(5 * 3 * 2, dtype=float).reshape(5, 3, 2)
    log = Log(t, [], {}).add("x", ("a", "b"), data)
    with pytest.raises(InvalidInputError, match="world=i"):
        write_mcap(log, tmp_path / "b.mcap", scene=False)
    back = read_log(write_mcap(log, tmp_path / "b.mcap", world=2, scene=False))
    np.testing.assert_array_equal(back["x"], data[:, 2])
    assert back.meta["world"] == (2,)


def test_times_must_be_non_negative_and_increasing(tmp_path):
    for t, match in ((np.array([-0.1, 0.0]), "t >= 0"), (np.array([0.0, 0.0]), "increase")):
        with pytest.raises(InvalidInputError, match=match):
            write_mcap(Log(t, [], {}).add("x", ("a",), np.zeros((2, 1))), tmp_path / "x.mcap", scene=False)


def _user_bag(folder, storage, topics):
    """A rosbag2 bag written by rosbags: ``topics`` = {name: (msgtype, [(t, p, q)])}."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = messages.typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(folder, version=9, storage_plugin=plugin) as w:
        for name, (msgtype, rows) in topics.items():
            conn = w.add_connection(name, msgtype, typestore=store)
            for k, (t, p, q) in enumerate(rows):
                if msgtype == "geometry_msgs/msg/PoseStamped":
                    msg = messages.pose_stamped(t, p, q, "mocap")
                elif msgtype == "nav_msgs/msg/Odometry":
                    ps = messages.pose_stamped(t, p, q, "odom")
                    cov = np.zeros(36)
                    msg = messages.msg_type(msgtype)(
                        header=ps.header, child_frame_id="base_link",
                        pose=messages.msg_type("geometry_msgs/msg/PoseWithCovariance")(pose=ps.pose, covariance=cov),
                        twist=messages.msg_type("geometry_msgs/msg/TwistWithCovariance")(
                            twist=messages.twist([0, 0, 0], [0, 0, 0]), covariance=cov))
                else:
                    msg = messages.string("x")
                w.write(conn, 1_000_000 * (k + 1), store.serialize_cdr(msg, msgtype))  # received in order
    return folder


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_read_poses_of_a_users_bag(tmp_path, storage):
    rng = np.random.default_rng(3)
    t = np.arange(6) * 0.05
    p = rng.normal(size=(6, 3))
    q = rng.normal(size=(6, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    bag = _user_bag(tmp_path / "bag", storage, {
        "/vrpn_client_node/cf1/pose": ("geometry_msgs/msg/PoseStamped", list(zip(t, p, q))),
        "/cf2/odom": ("nav_msgs/msg/Odometry", list(zip(t, -p, q))),
        "/chatter": ("std_msgs/msg/String", [(0.0, None, None)]),
    })
    files = [bag] + sorted(bag.glob("*.mcap" if storage == "mcap" else "*.db3"))  # the folder and its file
    for path in files:
        tracks = read_poses(path, ["/vrpn_client_node/cf1/pose", "/cf2/odom"])
        assert list(tracks) == ["/vrpn_client_node/cf1/pose", "/cf2/odom"]
        a, b = tracks.values()
        np.testing.assert_array_equal(a.position, p)
        np.testing.assert_allclose(a.quaternion, q, atol=1e-15)  # (w, x, y, z) back from ROS's (x, y, z, w)
        np.testing.assert_array_equal(b.position, -p)
        np.testing.assert_allclose(a.t, t, atol=1e-9)
        assert a.frame_id == "mocap" and b.frame_id == "odom"
    assert set(read_poses(bag)) == {"/vrpn_client_node/cf1/pose", "/cf2/odom"}  # default: every pose topic
    received = read_poses(bag, ["/cf2/odom"], stamps="log")["/cf2/odom"]  # the recorder's times
    np.testing.assert_allclose(received.t, 1e-3 * np.arange(1, 7), atol=1e-12)
    with pytest.raises(InvalidInputError, match=r"no topic '/vrpn_client_node/cf3/pose'.*cf1/pose") as e:
        read_poses(bag, ["/vrpn_client_node/cf3/pose"])
    assert "\n" not in str(e.value)
    with pytest.raises(InvalidInputError, match="/chatter carries std_msgs/msg/String, not a pose"):
        read_poses(bag, ["/chatter"])


@pytest.mark.filterwarnings("error")
def test_a_quaternion_of_huge_entries_is_refused_without_an_overflow_warning(tmp_path):
    """A damaged pose (a quaternion entry of 1e200) printed numpy's "RuntimeWarning: overflow
    encountered in multiply" on stderr before the one-line refusal."""
    q = np.array([1e200, 0.0, 0.0, 0.0])
    bag = _user_bag(tmp_path / "huge", "mcap", {"/r/pose": ("geometry_msgs/msg/PoseStamped", [(0.0, np.zeros(3), q)])})
    with pytest.raises(NonUnitError, match="/r/pose message 0 has a quaternion of norm inf"):
        read_poses(bag)


def test_read_poses_refuses_bad_stamps_and_non_unit_quaternions(tmp_path):
    q = np.array([1.0, 0.0, 0.0, 0.0])
    rows = [(0.0, np.zeros(3), q), (0.2, np.zeros(3), q), (0.1, np.zeros(3), q)]
    bag = _user_bag(tmp_path / "back", "mcap", {"/r/pose": ("geometry_msgs/msg/PoseStamped", rows)})
    with pytest.raises(InvalidInputError, match=r"/r/pose stamps do not increase: message 2 at t = 0\.1"):
        read_poses(bag)
    bag = _user_bag(tmp_path / "norm", "mcap", {"/r/pose": ("geometry_msgs/msg/PoseStamped",
                                                            [(0.0, np.zeros(3), 2 * q)])})
    with pytest.raises(NonUnitError, match="/r/pose message 0 has a quaternion of norm 2"):
        read_poses(bag)
    with pytest.raises(InvalidInputError, match="does not exist"):
        read_poses(tmp_path / "nothing.mcap")
    (tmp_path / "x.txt").write_text("x")
    with pytest.raises(InvalidInputError, match=r"\.mcap or \.db3"):
        read_poses(tmp_path / "x.txt")
    with pytest.raises(InvalidInputError, match="not a quatform run"):
        read_log(bag)


def _layout_values(topics, log, kind):
    """Every plotted ``/topic.field.path`` of the run's Foxglove layout read from the last message
    of its topic in ``topics`` (a KeyError or AttributeError where a run lacks one)."""
    layout = foxglove_layout(kind, scene_of(log, kind))
    plotted = [p["value"] for panel in layout["configById"].values() for p in panel.get("paths", [])]
    out = {}
    for value in plotted:
        topic, *fields = value.split(".")
        m = topics[topic][1][-1][1]
        for f in fields:
            m = getattr(m, f)
        out[value] = float(m)
    return out


@pytest.mark.parametrize("case", [c for c in CASES if c != "teleop"])
def test_the_foxglove_layout_plots_fields_every_formation_run_has(runs, case):
    """Every plotted path of the run's layout is a numeric field of a topic the run has."""
    kind, log, path = runs[case]
    topics = _read_all(path)
    values = _layout_values(topics, log, kind)
    assert len(values) >= 10 and all(np.isfinite(v) for v in values.values())
    layout = foxglove_layout(kind, scene_of(log, kind))
    three_d = next(c for k, c in layout["configById"].items() if k.startswith("3D!"))
    assert three_d["followTf"] == "world"
    if case == "pair":
        for topic in ("/formation/edges", "/robot_1/path", "/robot_1/path_desired"):
            assert topic in topics and three_d["topics"][topic]["visible"]


def test_cli_run_writes_run_mcap_that_rosbags_reads_one_message_per_sample(tmp_path, capsys):
    """A team run writes its bag, reads it back and logs it to Rerun (plots off)."""
    out = tmp_path / "run"
    assert main(["run", "mas-kitts-helix", "--controller", "quaternion", "--out", str(out), "--no-plots"]) == 0
    from rosbags.rosbag2 import Reader

    with Reader(out / MCAP_FILE) as reader:  # the single file, as rosbags reads it
        counts = {c.topic: c.msgcount for c in reader.connections}
    n = len(read_log(out))  # the run's folder: its run.mcap
    assert n == 8001
    for topic in ("/robot_1/pose", "/robot_1/pose_desired", "/robot_2/cmd_vel", "/tf", "/formation/edges",
                  "/quatform/cluster", "/quatform/error"):
        assert counts[topic] == n, topic
    assert (out / "foxglove-layout.json").is_file() and (out / "metrics.json").is_file()
    skip = tmp_path / "skip"
    assert main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(skip), "--no-plots",
                 "--no-mcap"]) == 0
    assert not (skip / MCAP_FILE).exists() and (skip / "metrics.json").is_file()
    capsys.readouterr()
    for command in ("run", "compare", "teleop", "demo"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = capsys.readouterr().out
        assert "--no-mcap" in text and "--rerun" in text, command


def test_a_mujoco_run_adds_each_quadrotors_rotors_and_full_attitude(tmp_path):
    pytest.importorskip("mujoco")
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=0.3, metrics_from_s=0.0)
    kind = kind_of(sc)
    log = kind.experiment(sc, controller="quaternion", physics="mujoco").run(None)
    record = log.meta["physics_record"]
    topics = _read_all(write_mcap(log, tmp_path / "mj.mcap", kind=kind.parts_of(sc)))
    n = len(log)
    for i in (1, 2):
        msgs = topics[f"/robot_{i}/rotors"][1]
        assert len(msgs) == n
        m = msgs[-1][1]
        forces = [m.force_1, m.force_2, m.force_3, m.force_4]
        np.testing.assert_array_equal(forces, record.rotor_force[-1, i - 1])
        assert m.thrust == pytest.approx(sum(forces), rel=1e-12) and m.thrust > 0.0
        _, _, q, _ = messages.pose_from_msg(topics[f"/robot_{i}/pose"][1][-1][1])
        np.testing.assert_array_equal(q, record.attitude[-1, i - 1])  # tilt included
        yaw = log["state"][-1, 4 * (i - 1) + 3]
        assert abs(np.angle(np.exp(1j * (g.yaw_of(q) - yaw)))) < 1e-6  # its yaw is the state's
    np.testing.assert_array_equal(read_log(tmp_path / "mj.mcap")["state"], log["state"])
    rotors = foxglove_layout(kind.parts_of(sc), scene_of(log, kind.parts_of(sc)))["configById"]["Plot!rotors"]["paths"]
    assert [s["value"] for s in rotors] == ["/robot_1/rotors.thrust", "/robot_2/rotors.thrust"]


@pytest.mark.parametrize("make, match", [
    (lambda: messages.line_list(0.0, np.zeros((3, 3))), r"\(2 E, 3\)"),
    (lambda: messages.joint_state(0.0, ["a", "b"], [1.0]), "joint state position"),
    (lambda: messages.wrench_stamped(0.0, [np.nan, 0, 0], [0, 0, 0], "w"), "force"),
    (lambda: messages.pose_array(0.0, np.zeros((2, 3)), np.zeros((3, 4))), "pose array"),
    (lambda: messages.path(0.0, [0.0], np.zeros((2, 3)), np.zeros((2, 4))), "a path is"),
    (lambda: messages.named_type(["x_c", "F_s_x"]), "F_s_x"),
    (lambda: messages.named_type(["a", "a"]), "distinct"),
    (lambda: messages.transform_stamped(0.0, "world", "r", [0, 0], [1, 0, 0, 0]), "pose"),
])
def test_new_message_builders_refuse_bad_input_in_one_line(make, match):
    with pytest.raises(InvalidInputError, match=match) as e:
        make()
    assert "\n" not in str(e.value)


def _pose_sample(msg):
    from quatform.ros2.robot_io import PoseSample

    if msg.__msgtype__ == "nav_msgs/msg/Odometry":
        t, p, q, _ = messages.odometry_pose(msg)
        tw = msg.twist.twist
        return PoseSample(t, p, q, (np.array([tw.linear.x, tw.linear.y, tw.linear.z]),
                                    np.array([tw.angular.x, tw.angular.y, tw.angular.z])))
    t, p, q, _ = messages.pose_from_msg(msg)
    return PoseSample(t, p, q)


@pytest.mark.parametrize("case, topic, model, channel, columns", [
    ("ugv-uav", "/pioneer/pose", Pioneer(), "state", ("x_p", "y_p", "psi_p")),
    ("ugv-uav", "/pioneer/pose_measured", Pioneer(), "measured", ("x_p", "y_p", "psi_p")),
    ("ugv-uav", "/bebop/odom", Bebop(), "measured", ("x_b", "y_b", "z_b", "psi_b", "v_x_b", "v_y_b", "z_dot_b",
                                                     "psi_dot_b")),
    ("team-mixed", "/robot_1/pose", Pioneer(), "state", ("x1", "y1", "psi1"))])
def test_the_ros2_bridge_reads_a_runs_poses_back_as_the_state(runs, case, topic, model, channel, columns):
    """A Pioneer's pose is its base: the bridge's +a gives the state's control point back; the
    Bebop's odometry (pose + body twist) gives the whole state the controller read (the replay contract)."""
    from quatform.ros2.robot_io import robot_io

    _, log, path = runs[case]
    msgs = _read_all(path)[topic][1]
    cols = log.columns(channel)
    io = robot_io(model)
    for k in (0, len(log) // 2, len(log) - 1):
        got = io.state(model, _pose_sample(msgs[k][1]), None)
        np.testing.assert_allclose(got, log[channel][k, [cols.index(c) for c in columns]], atol=1e-12)
    if topic == "/bebop/odom":
        m = msgs[-1][1]
        assert (m.header.frame_id, m.child_frame_id) == ("world", "bebop")


def _controllers(name):
    """The controller choices of scenario ``name``'s kind (its ``controller`` option)."""
    return next(o.choices for o in kind_of(load_scenario(name)).options if o.name == "controller")


@pytest.mark.parametrize("name, controller", [("mas-kitts-helix", c) for c in _controllers("mas-kitts-helix")]
                         + [("team-triangle-over-ugv", c) for c in _controllers("team-triangle-over-ugv")]
                         + [("marciano-circle", None)])
def test_every_controller_gets_the_formation_frame(tmp_path, name, controller):
    """/formation/pose, /formation/pose_desired and the formation TF frames for every description:
    a pair's from the quaternion pair's forward map of the robots (nearest the reference's frame), a
    team's from its chart (e, e_des)."""
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration_s=0.2, **({"transient_s": 0.0} if name == "marciano-circle" else
                                                    {"metrics_from_s": 0.0}))
    kind = kind_of(sc)
    log = kind.experiment(sc, **({"controller": controller} if controller else {})).run(None)
    topics = _read_all(write_mcap(log, tmp_path / "run.mcap", kind=kind.parts_of(sc)))
    for topic in ("/formation/pose", "/formation/pose_desired"):
        assert len(topics[topic][1]) == len(log)
    k = len(log) - 1
    _, p, q, _ = messages.pose_from_msg(topics["/formation/pose"][1][k][1])
    if kind.parts_of(sc) == "team":
        e, ec = log["e"], log.columns("e")
        np.testing.assert_array_equal(np.r_[p, q], e[k, [ec.index(c) for c in ("x_c", "y_c", "z_c", "q_c_w", "q_c_x",
                                                                                   "q_c_y", "q_c_z")]])
    elif kind.parts_of(sc) == "pair":
        F = FORMATIONS["quaternion"]
        want = F.forward(log["state"][k], near_c=F.from_chart(log["e_des"][k]))[:7]
        np.testing.assert_allclose(np.r_[p, q], want, atol=1e-12)
    assert {"formation", "formation_desired"} <= {t.child_frame_id for t in topics["/tf"][1][k][1].transforms}
    _, pd, qd, _ = messages.pose_from_msg(topics["/formation/pose_desired"][1][k][1])
    err = topics["/formation/error"][1][k][1]
    np.testing.assert_allclose([err.x, err.y, err.z], pd - p, atol=1e-12)
    assert err.angle == pytest.approx(2 * np.arccos(min(1.0, abs(float(np.dot(q, qd))))), abs=1e-9)
    assert len(_layout_values(topics, log, kind.parts_of(sc))) >= 10  # the layout's plots have data for every controller


def test_a_read_back_team_log_is_refused_with_one_line(runs, tmp_path):
    _, _, path = runs["team-mixed"]
    back = read_log(path)
    with pytest.raises(InvalidInputError, match="read back from run.mcap.*scene=False"):
        write_mcap(back, tmp_path / "again.mcap", kind="team")
    assert write_mcap(back, tmp_path / "again.mcap", kind="team", scene=False).is_file()


def test_read_log_of_a_no_mcap_run_folder_says_so(tmp_path):
    assert main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(tmp_path / "r"), "--no-plots",
                 "--no-mcap"]) == 0
    with pytest.raises(InvalidInputError, match=r"this run folder has no run.mcap \(written with --no-mcap\?\)"):
        read_log(tmp_path / "r")


REPLAY_ROBOTS = {
    "marciano-circle": [("pioneer", "/pioneer/pose_measured", "pose"), ("bebop", "/bebop/odom", "odometry")],
    "team-triangle-over-ugv": [(f"robot_{i}", f"/robot_{i}/pose", "pose") for i in range(1, 5)],
}


@pytest.mark.parametrize("name, options", [("marciano-circle", []),
                                           ("team-triangle-over-ugv", ["--controller", "quaternion"])])
def test_replaying_a_runs_mcap_gives_the_runs_commands(tmp_path, capsys, name, options):
    """quatform replay on a run's own run.mcap (the Pioneer's base pose, the Bebop's odometry)
    commands what the run commanded."""
    import csv
    import re

    from quatform.scenarios import builtin_scenarios

    text = builtin_scenarios()[name].read_text()
    toml = tmp_path / f"{name}.toml"
    for key, value in (("duration_s", 1.0), ("transient_s", 0.5), ("metrics_from_s", 0.0)):
        text = re.sub(rf"(?m)^{key} = .*$", f"{key} = {value}", text, count=1)
    text = re.sub(r"(?ms)^\[\[shape\.moves\]\].*?(?=^\[path\])", "", text)  # its move starts after 1 s
    toml.write_text(text)
    assert main(["run", str(toml), *options, "--out", str(tmp_path / "run"), "--no-plots"]) == 0
    have = set(_read_all(tmp_path / "run" / MCAP_FILE))
    robots = tmp_path / "robots.toml"  # what the controller read: pose_measured where the run has one
    topic = {n: t if t in have else t.removesuffix("_measured") for n, t, _ in REPLAY_ROBOTS[name]}
    robots.write_text("".join(f'[[robots]]\nname = "{n}"\npose_topic = "{topic[n]}"\npose_type = "{k}"\n'
                              for n, _, k in REPLAY_ROBOTS[name]))
    assert main(["replay", str(tmp_path / "run" / MCAP_FILE), "--scenario", str(toml), *options, "--robots",
                 str(robots), "--out", str(tmp_path / "rp")]) == 0
    log = read_log(tmp_path / "run" / MCAP_FILE)
    with open(tmp_path / "rp" / "commands.csv") as f:
        rows = list(csv.reader(f))
    got = np.array([[float(v) for v in row] for row in rows[1:]])[:, [rows[0].index(c) for c in log.columns("command")]]
    assert got.shape == log["command"].shape
    np.testing.assert_allclose(got, log["command"], rtol=1e-8, atol=1e-9)  # commands.csv: 9 significant digits
