"""Every frame run.mcap holds is continuous along the run, and /formation/error's angle is the
orientation error metrics.json reports.

Oracles: the motion's own angular steps, computed from the robots' positions and the
reference's Euclidean variables without any quaternion frame (a pair: the angle between
consecutive segment directions and the steps of the desired yaw and pitch ``beta_c``,
``gamma_c``; a team: the rotation best fitting consecutive point sets), and the metrics'
error signals (``sim.metrics.errors_from_robots``).
"""

import dataclasses
import functools

import numpy as np
import pytest

from quatform import messages
from quatform.bags import write_mcap
from quatform.algebra import wrap_angle
from quatform.bags.scene import scene_of
from quatform.formations import FORMATIONS
from quatform.formations import geometry as g
from quatform.scenarios import kind_of, load_scenario
from quatform.sim.metrics import errors_from_robots
from quatform.formations.team_chart import fit_attitude

#: The scenarios whose motion is smooth (no designed step of the reference), each run whole.
SMOOTH = ("mas-kitts-helix", "mas-kitts-spiral", "team-three-bodies", "team-ring-flip", "team-tetrahedron-helix")
#: A frame's step may exceed the motion's largest step by this factor: the actual frame turns
#: with the segment and, nearest the desired one, with its twist (two steps at most), plus slack.
MARGIN = 3.0
#: ``2 acos |w|`` near 0 turns a rounding of ``w`` by k ulps (1.1e-16 each) into ``2 sqrt(2 k 1.1e-16)``:
#: 6e-8 rad for k = 4, the error of a product of quaternions and its dot.
ANGLE_ATOL = 1e-7


def _angle(q, p):
    """Rotation angle of ``q^-1 p`` (rad), sign-free: ``2 acos |q . p|``."""
    return 2.0 * np.arccos(np.clip(np.abs(np.sum(q * p, axis=-1)), 0.0, 1.0))


@functools.cache
def _run(name):
    sc = load_scenario(name)
    kind = kind_of(sc)
    exp = kind.experiment(sc, controller="quaternion")
    log = exp.run(None)
    return kind.parts_of(sc), log, exp.metrics(log)


def _segments(p):
    """Unit directions (T, 3) from robot 2 to robot 1 of positions (T, 2, 3)."""
    d = p[:, 0] - p[:, 1]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _motion_step(kind, log):
    """The motion's largest angular step between samples (rad), from positions and the reference's
    angles alone."""
    if kind == "pair":
        L = FORMATIONS["quaternion"].layout
        steps = [np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=-1), -1.0, 1.0))
                 for u in (_segments(L.positions(log["state"])), _segments(L.positions(log["r_des"])))]
        e_des = np.asarray(log["e_des"])  # seed 000 eqs. (4)-(5): q_c = q_z(beta) q_y(-gamma) turns at most by both
        twist = np.abs(np.diff(e_des[:, 3])) + np.abs(np.diff(e_des[:, 4]))
        return float(max(s.max() for s in steps) + twist.max())
    L = log.meta["layout"]
    out = 0.0
    for points in (log["points"], log["r_des"]):
        p = L.positions(np.asarray(points))
        c = p - p.mean(axis=-2, keepdims=True)
        out = max(out, float(np.max(_angle(fit_attitude(c[:-1], c[1:]), np.array([1.0, 0.0, 0.0, 0.0])))))
    return out


def _body_step(kind, log):
    """The bodies' largest angular step between samples (rad): their headings' (wrapped) and, for
    free bodies, their state quaternions' (the plant's own)."""
    steps = [0.0]
    if kind == "pair":
        L = FORMATIONS["quaternion"].layout
        steps += [np.max(np.abs(wrap_angle(np.diff(L.yaws(log[c]), axis=0)))) for c in ("state", "r_des")]
        return float(max(steps))
    L, team = log.meta["layout"], log.meta["team"]
    for points in (log["points"], log["r_des"]):
        r = np.asarray(points)
        if L.yaw_indices:
            steps.append(np.max(np.abs(wrap_angle(np.diff(L.yaws(r), axis=0)))))
        if len(L.orientation_index):
            q = L.orientations(r)
            steps.append(np.max(_angle(q[:-1], q[1:])))
    for model, x in zip(team.robots, team.split(np.asarray(log["state"]))):
        for stem in ("psi", "theta"):  # a robot whose point has no heading is drawn with its state's
            if stem in model.state_columns:
                steps.append(np.max(np.abs(wrap_angle(np.diff(x[:, model.state_columns.index(stem)])))))
    return float(max(steps))


@pytest.mark.parametrize("name", SMOOTH)
def test_no_frame_of_a_smooth_run_jumps(name):
    """Between consecutive samples no written frame turns by more than MARGIN times the motion's
    largest step (the helix's desired frame turned by pi at t = 40 s), nor changes its sign."""
    kind, log, _ = _run(name)
    scene = scene_of(log, kind)
    formation_bound = MARGIN * _motion_step(kind, log) + ANGLE_ATOL
    body_bound = MARGIN * _body_step(kind, log) + ANGLE_ATOL
    frames = {"formation": (scene.formation[1], formation_bound),
              "formation_desired": (scene.formation_desired[1], formation_bound)}
    for what in ("quaternion", "quaternion_desired", "quaternion_measured"):
        q = getattr(scene, what)
        if q is not None:
            frames.update({f"{what}[{b}]": (q[:, i], body_bound) for i, b in enumerate(scene.bodies)})
    for what, (q, bound) in frames.items():
        steps = _angle(q[:-1], q[1:])
        k = int(np.argmax(steps))
        assert steps[k] <= bound, f"{what} turns {steps[k]:.3g} rad at t = {log.t[k + 1]:.2f} s (bound {bound:.3g})"
        assert np.all(np.sum(q[:-1] * q[1:], axis=-1) >= 0.0), what


@pytest.mark.parametrize("name", SMOOTH)
def test_the_plotted_error_angle_is_the_metrics_orientation_error(name):
    kind, log, metrics = _run(name)
    scene = scene_of(log, kind)
    angle = _angle(scene.formation[1], scene.formation_desired[1])
    # the pair: the angle between the segments; a team: its chart's attitude error
    want = errors_from_robots(log)["orientation" if kind == "pair" else "recovered_attitude"]
    np.testing.assert_allclose(angle, want, rtol=0, atol=ANGLE_ATOL)
    late = log.t >= log.meta["metrics_from_s"]
    # a team's metric is the attitude of the best fit of the points (Horn), its chart's the
    # attitude its description recovers: the same where the shape is held
    assert np.max(angle[late]) == pytest.approx(metrics["max_orientation_error_rad"], abs=ANGLE_ATOL)


def test_the_helix_upside_down_is_written_without_a_flip(tmp_path):
    """At t = 40 s the helix's formation is upside down (its segment along -x): /formation/error
    reads the metrics' ~1e-7 rad there, not pi, and /formation/pose_desired and the TF
    formation_desired turn by the roll rate (2 pi / 40 s) times dt."""
    from rosbags.highlevel import AnyReader

    kind, log, metrics = _run("mas-kitts-helix")
    path = write_mcap(log, tmp_path / "run.mcap", kind=kind)
    got: dict = {}
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic in ("/formation/error", "/formation/pose_desired", "/tf")]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/tf":
                tf = next(t.transform for t in msg.transforms if t.child_frame_id == "formation_desired")
                got.setdefault("tf", []).append([tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z])
            elif conn.topic == "/formation/error":
                got.setdefault("angle", []).append(msg.angle)
            else:
                got.setdefault("desired", []).append(messages.pose_from_msg(msg)[2])
    k40 = int(np.argmin(np.abs(log.t - 40.0)))
    angle = np.asarray(got["angle"])
    assert angle[k40] < 1e-6 and np.max(angle[log.t >= 5.0]) == pytest.approx(metrics["max_orientation_error_rad"],
                                                                             abs=ANGLE_ATOL)
    rate_step = 2 * np.pi / 40.0 * 0.01  # the roll's rate times dt
    for what in ("desired", "tf"):
        q = np.asarray(got[what])
        assert np.max(_angle(q[:-1], q[1:])) <= 1.01 * rate_step, what


def test_continuous_states_carry_the_frame_along_a_segment_through_minus_x():
    """A segment turning in the x-z plane through -x: the seed's minimal rotation from x turns by
    pi where it passes -x; the carried frame turns by the segment's step, about y only."""
    from quatform.bags.scene import continuous_states

    F = FORMATIONS["quaternion"]
    a = np.linspace(0.0, 2 * np.pi, 401)  # the segment's angle from x about y (0.9 deg steps)
    u = np.stack([np.cos(a), np.zeros_like(a), -np.sin(a)], axis=-1)
    r = np.zeros((a.size, 8))
    r[:, 0:3], r[:, 4:7] = 0.5 * u, -0.5 * u
    seed = F.forward(r)[:, 3:7]
    assert np.max(_angle(seed[:-1], seed[1:])) == pytest.approx(np.pi)
    q = continuous_states(F, r)[:, 3:7]
    np.testing.assert_allclose(_angle(q[:-1], q[1:]), a[1] - a[0], rtol=1e-9)
    np.testing.assert_allclose(q[:, [1, 3]], 0.0, atol=1e-12)  # about y only: no twist
    np.testing.assert_allclose(g.x_axis(q), u, atol=1e-12)


def test_sign_continuous_keeps_rotations_and_removes_sign_jumps():
    from quatform.bags.scene import sign_continuous

    q = g.q_yaw(np.linspace(0.0, 6 * np.pi, 50))
    flipped = np.where((np.arange(50) % 7 == 3)[:, None], -q, q)
    flipped[20] = np.nan
    out = sign_continuous(flipped)
    finite = np.all(np.isfinite(out), axis=1)
    np.testing.assert_array_equal(np.abs(out[finite]), np.abs(flipped[finite]))
    pairs = np.sum(out[:-1] * out[1:], axis=-1)
    assert np.all(pairs[np.isfinite(pairs)] >= 0.0)
    np.testing.assert_array_equal(out[0], flipped[0])


def test_a_failed_worlds_nan_samples_stay_nan_and_the_frame_resumes():
    from quatform.bags.scene import continuous_states

    F = FORMATIONS["quaternion"]
    a = np.linspace(0.0, 1.0, 20)
    r = np.zeros((20, 8))
    r[:, 0], r[:, 2], r[:, 4], r[:, 6] = np.cos(a), np.sin(a), -np.cos(a), -np.sin(a)
    r[5:8] = np.nan
    c = continuous_states(F, r)
    assert np.all(np.isnan(c[5:8])) and np.all(np.isfinite(c[[4, 8]]))
    np.testing.assert_allclose(g.x_axis(c[8, 3:7]), r[8, 0:3] / np.linalg.norm(r[8, 0:3]), atol=1e-12)


def test_a_ugv_uav_runs_error_angle_is_the_angle_between_its_segments():
    """The UGV-UAV frames: the desired one carried along the run, the actual one nearest it, so
    the plotted angle is the metrics' orientation error (the angle between the segments
    Pioneer -> Bebop, ``ugv_uav_metrics``), at every sample."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=2.0, transient_s=0.0)
    kind = kind_of(sc)
    log = kind.experiment(sc).run(None)
    scene = scene_of(log, kind.parts_of(sc))
    angle = _angle(scene.formation[1], scene.formation_desired[1])
    p, pd = (np.asarray(log[c]).reshape(len(log), 2, 3) for c in ("r_true", "r_des"))
    d, dd = p[:, 1] - p[:, 0], pd[:, 1] - pd[:, 0]
    cos = np.sum(d * dd, axis=-1) / (np.linalg.norm(d, axis=-1) * np.linalg.norm(dd, axis=-1))
    np.testing.assert_allclose(angle, np.arccos(np.clip(cos, -1.0, 1.0)), rtol=0, atol=ANGLE_ATOL)
    bound = MARGIN * max(float(np.max(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=-1), -1, 1))))
                         for u in (d / np.linalg.norm(d, axis=-1, keepdims=True),
                                   dd / np.linalg.norm(dd, axis=-1, keepdims=True))) + ANGLE_ATOL
    for q in (scene.formation[1], scene.formation_desired[1]):
        assert np.max(_angle(q[:-1], q[1:])) <= bound
