"""The operator's goal: the pure approach step, the charts' pose maps, and a live session
stepped tick by tick (no server: the Foxglove protocol is tests/test_live.py's)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.errors import InvalidInputError
from quatform.formations import geometry as g
from quatform.live import LiveSession
from quatform.references.goal import GOAL_RAMP_S, GOAL_SHARE, approach_pose, goal_limits
from quatform.robots import HolonomicRobot, Pioneer
from quatform.runs import run
from quatform.scenarios.team import TEAM_CHARTS

from live_triangle import triangle

TRIANGLE = triangle(2.0)

vec = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array)
quat = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda a: np.linalg.norm(a) > 0.1).map(
    lambda a: np.array(a) / np.linalg.norm(a))
positive = st.floats(0.01, 5.0)


def _angle(q, p):
    return 2.0 * np.arccos(np.clip(abs(float(np.dot(q, p))), 0.0, 1.0))


@settings(max_examples=200, deadline=None)
@given(vec, quat, vec, quat, positive, positive, st.floats(1e-3, 0.1))
def test_approach_is_bounded_and_shortest(p, q, pg, qg, vmax, wmax, dt):
    p1, q1, v, w = approach_pose(p, q, pg, qg, vmax, wmax, dt)
    assert np.all(np.isfinite(p1)) and np.all(np.isfinite(q1))
    assert np.linalg.norm(v) <= vmax * (1 + 1e-12)
    assert np.linalg.norm(w) <= wmax * (1 + 1e-12)
    np.testing.assert_allclose(np.linalg.norm(q1), 1.0, atol=1e-12)
    d0, d1 = np.linalg.norm(pg - p), np.linalg.norm(pg - p1)
    np.testing.assert_allclose(d1, max(d0 - vmax * dt, 0.0), atol=1e-9 * (1 + d0))
    a0, a1 = _angle(q, qg), _angle(q1, qg)  # along the shortest arc: the angle shrinks by the step
    np.testing.assert_allclose(a1, max(a0 - wmax * dt, 0.0), atol=1e-7)
    assert float(np.dot(q1, q)) > 0.0  # the sign continues q's
    # q_next = exp(w dt / 2) q (the rate the chart is given)
    rot = np.r_[np.cos(np.linalg.norm(w) * dt / 2), np.sinc(np.linalg.norm(w) * dt / 2 / np.pi) * w * dt / 2]
    np.testing.assert_allclose(g.mul(rot, q), q1, atol=1e-9)


@given(vec, quat, vec, quat)
def test_goal_sign_does_not_matter(p, q, pg, qg):
    a = approach_pose(p, q, pg, qg, 1.0, 1.0, 0.02)
    b = approach_pose(p, q, pg, -qg, 1.0, 1.0, 0.02)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, atol=1e-12)


@given(vec, quat)
def test_at_the_goal_nothing_moves(p, q):
    for goal in (q, -q):
        p1, q1, v, w = approach_pose(p, q, p, goal, 1.0, 1.0, 0.02)
        assert np.all(np.isfinite(np.r_[p1, q1, v, w]))
        np.testing.assert_array_equal(v, 0.0)
        np.testing.assert_array_equal(w, 0.0)
        np.testing.assert_allclose(q1, q, atol=1e-15)


def test_lands_on_the_goal_and_batches():
    p, q = np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1))
    pg = np.array([[0.01, 0, 0], [3.0, 4.0, 0]])
    qg = np.array([g.q_yaw(0.01), g.q_yaw(np.pi)])
    p1, q1, v, w = approach_pose(p, q, pg, qg, 1.0, 1.0, 0.1)
    np.testing.assert_array_equal(p1[0], pg[0])  # within one step: exactly there
    np.testing.assert_allclose(q1[0], qg[0], atol=1e-15)
    np.testing.assert_allclose(p1[1], [0.06, 0.08, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(w, axis=-1), [0.1, 1.0], atol=1e-12)  # half turn: a rate-limited step


@settings(max_examples=200, deadline=None)
@given(vec, quat, vec, quat, positive, positive, st.floats(1e-3, 0.1), vec, vec, positive, positive)
def test_approach_bounds_its_acceleration(p, q, pg, qg, vmax, wmax, dt, v0, w0, amax, alpha):
    v0 = v0 * min(1.0, vmax / max(np.linalg.norm(v0), 1e-300))  # a velocity the bounds allowed
    w0 = w0 * min(1.0, wmax / max(np.linalg.norm(w0), 1e-300))
    p1, q1, v, w = approach_pose(p, q, pg, qg, vmax, wmax, dt, v0, w0, amax, alpha)
    assert np.all(np.isfinite(np.r_[p1, q1, v, w]))
    assert np.linalg.norm(v - v0) <= amax * dt * (1 + 1e-9) + 1e-12
    assert np.linalg.norm(w - w0) <= alpha * dt * (1 + 1e-9) + 1e-12
    assert np.linalg.norm(v) <= vmax * (1 + 1e-9) and np.linalg.norm(w) <= wmax * (1 + 1e-9)
    np.testing.assert_allclose(p1, p + v * dt, atol=1e-12 * (1 + np.abs(p).max()))
    np.testing.assert_allclose(np.linalg.norm(q1), 1.0, atol=1e-12)


@pytest.mark.parametrize("amax, alpha", [(0.5, 0.7), (2.0, 5.0)])
def test_bounded_approach_lands_from_rest(amax, alpha):
    p, q, v, w = np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3)
    pg, qg = np.array([2.0, -1.0, 0.5]), g.q_yaw(2.5)
    vs = []
    for _ in range(2000):
        p, q, v, w = approach_pose(p, q, pg, qg, 1.0, 1.5, 0.02, v, w, amax, alpha)
        vs.append(np.r_[v, w])
    np.testing.assert_allclose(p, pg, atol=1e-12)
    np.testing.assert_allclose(abs(np.dot(q, qg)), 1.0, atol=1e-12)
    np.testing.assert_array_equal(vs[-1], 0.0)  # at rest there
    jumps = np.abs(np.diff(np.asarray(vs), axis=0, prepend=0.0))
    assert np.linalg.norm(jumps[:, :3], axis=1).max() <= amax * 0.02 * (1 + 1e-9)


def test_limits_from_the_robots():
    v, w = goal_limits((HolonomicRobot(max_speed=2.0), Pioneer()), radius=1.5)
    assert v == 0.5 * GOAL_SHARE * Pioneer().max_v and GOAL_SHARE < 1.0
    np.testing.assert_allclose(w, v / 1.5)


@pytest.mark.parametrize("chart", ["team", "pair"])
def test_posed_chart_moves_the_pose(chart):
    rng = np.random.default_rng(0)
    parts = TEAM_CHARTS[chart]
    if chart == "team":
        e = np.r_[0.5, -1.0, 2.0, g.q_yaw(0.3), np.array([[1.0, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0]]).ravel(),
                  np.zeros(3)]
    else:
        e = np.array([0.5, -1.0, 2.0, 0.3, 0.4, 1.0, 0.1, -0.2])
    ed = rng.normal(size=e.size)
    p, q = rng.normal(size=3), rng.normal(size=4)
    q /= np.linalg.norm(q)
    v, w = rng.normal(size=3), rng.normal(size=3)
    e1, ed1 = parts.posed(e, ed, p, q, v, w)
    p1, q1 = parts.pose(e1)
    np.testing.assert_allclose(p1, p, atol=1e-12)
    np.testing.assert_allclose(g.x_axis(q1), g.x_axis(q), atol=1e-12)  # the pair keeps the x axis (its segment)
    if chart == "team":
        np.testing.assert_allclose(q1, q, atol=1e-12)
    # the rates: e moves as the pose does (finite difference of the posed chart along (v, w))
    h = 1e-6
    rot = np.r_[np.cos(np.linalg.norm(w) * h / 2), np.sin(np.linalg.norm(w) * h / 2) * w / np.linalg.norm(w)]
    e2, _ = parts.posed(e + h * ed, ed, p + h * v, g.mul(rot, q), v, w, near=e1)
    np.testing.assert_allclose((e2 - e1) / h, ed1, atol=1e-5)


def _session(tmp_path, name="tri.toml", text=TRIANGLE):
    f = tmp_path / name
    f.write_text(text)
    return f, LiveSession(f, {"controller": "quaternion"})


def test_session_without_goal_is_the_run(tmp_path):
    f, s = _session(tmp_path)
    while not s.done:
        s.step()
    _, live = s.finish(tmp_path / "live", plots=False)
    _, ref = run(f, tmp_path / "run", plots=False, quiet=True, controller="quaternion")
    assert {k: v for k, v in live.items() if k not in ("wall_time_s", "live")} == \
        {k: v for k, v in ref.items() if k != "wall_time_s"}
    assert (tmp_path / "live" / "run.mcap").is_file() and (tmp_path / "live" / "timeseries.csv").is_file()


def test_goal_moves_the_reference_within_limits(tmp_path):
    _, s = _session(tmp_path, text=triangle(3.0))
    for _ in range(10):
        s.step()
    goal = np.array([1.0, 0.5, 1.2])
    s.set_goal(goal, g.q_yaw(np.pi / 2))
    while not s.done:
        s.step()
    log, m = s.finish(tmp_path / "out", plots=False)
    assert m["live"]["goal_ticks"] == [10]
    e_des = log["e_des"]
    np.testing.assert_array_equal(e_des[:11], s.chart[:11])  # the scenario's before; the goal's first tick starts
    assert np.linalg.norm(e_des[12, :3] - e_des[11, :3]) > 0.0  # where the reference was, and moves from there
    np.testing.assert_allclose(e_des[-1, :3], goal, atol=1e-12)
    np.testing.assert_allclose(abs(np.dot(e_des[-1, 3:7], g.q_yaw(np.pi / 2))), 1.0, atol=1e-12)
    steps = np.linalg.norm(np.diff(e_des[:, :3], axis=0), axis=1)
    assert np.all(steps <= s.max_speed * s.dt * (1 + 1e-9))
    # no velocity jump: from rest, the centroid's velocity changes by at most max_speed / GOAL_RAMP_S per s
    vel = np.diff(e_des[10:, :3], axis=0) / s.dt
    assert np.linalg.norm(np.diff(vel, axis=0, prepend=0.0), axis=1).max() <= \
        s.max_speed / GOAL_RAMP_S * s.dt * (1 + 1e-6)
    # the robots the reference implies move at most GOAL_SHARE of their limit (2.5 m/s): a margin
    # of (1 - GOAL_SHARE) of it left for the controller (a chord is shorter than its arc)
    robots = s.scenario.team.layout.positions(np.asarray(s._r))
    speeds = np.linalg.norm(np.diff(robots[10:], axis=0), axis=-1) / s.dt
    assert speeds.max() <= GOAL_SHARE * 2.5 * (1 + 1e-9)
    assert speeds.max() >= 0.5 * GOAL_SHARE * 2.5  # the bound is used, not a loose one
    # the robots follow it: the actual centroid ends near the goal
    assert np.linalg.norm(log["e"][-1, :3] - goal) < 0.2


def test_pair_file_follows_a_goal(tmp_path):
    s = LiveSession("mas-kitts-yaw-step", {"controller": "dual-quaternion"})
    s.set_goal([0.2, 0.1, 0.3], g.q_yaw(0.4))
    for _ in range(150):
        s.step()
    log = s.log()
    assert np.all(np.isfinite(log["e_des"]))
    assert np.linalg.norm(log["e_des"][-1, :3] - log["e_des"][0, :3]) > 0.1


def test_parameters_checked_by_the_controller(tmp_path):
    _, s = _session(tmp_path)
    s.step()
    before = s.parameters()
    assert before["gains.k_d"] > 0 and before["min_separation_m"] == 0.3 and before["paused"] is False
    for name, value in [("gains.k_d", -1.0), ("gains.k_d", float("nan")), ("gains.k_d", "fast"), ("gains.k_d", True),
                        ("gains.k_x", [1.0, 2.0]), ("gains.k_d", 200.0), ("min_separation_m", -0.1),
                        ("min_separation_m", 5.0), ("min_separation_m", 0.0), ("paused", 1), ("nope", 1.0),
                        ("gains.k_d", 10**400), ("gains.k_x", [1, 10**400, 1]), ("min_separation_m", -10**400)]:
        with pytest.raises(InvalidInputError) as exc:
            s.set_parameter(name, value)
        assert "\n" not in str(exc.value) and name in str(exc.value)
    assert s.parameters() == before
    s.set_parameter("gains.k_d", 9.0)  # replaced before any tick runs with it: not a change applied
    s.set_parameter("gains.k_d", 3.5)
    s.set_parameter("gains.k_x", [1.0, 2.0, 3.0])
    s.set_parameter("min_separation_m", 0.4)
    assert s.parameters()["gains.k_d"] == 3.5
    ctrl = s.stepper.controller
    s.step()  # from the next tick
    assert s.stepper.controller is not ctrl
    assert s.stepper.controller.inner.gains["k_d"] == 3.5 and s.stepper.controller.barrier.min_separation_m == 0.4
    assert s.changes[-1][0] == 1
    while not s.done:
        s.step()
    _, m = s.finish(tmp_path / "o", plots=False)
    changes = json.loads((tmp_path / "o" / "metrics.json").read_text())["live"]["parameter_changes"]
    assert changes == [[1, "gains.k_d", 3.5], [1, "gains.k_x", [1.0, 2.0, 3.0]], [1, "min_separation_m", 0.4]]
    assert m["safety_min_separation_m"] == 0.4  # the distance in force at the end


def test_array_gain_set_by_one_number_stays_an_array(tmp_path):
    _, s = _session(tmp_path)
    s.step()
    assert isinstance(s.parameters()["gains.k_x"], list)
    s.set_parameter("gains.k_x", 5)
    assert s.parameters()["gains.k_x"] == [5.0, 5.0, 5.0]
    s.step()
    assert s.changes == [(1, "gains.k_x", [5.0, 5.0, 5.0])]


def test_goal_refused_when_not_finite(tmp_path):
    _, s = _session(tmp_path)
    for bad in ([np.nan, 0, 0], [0, 0, 0]):
        with pytest.raises(InvalidInputError):
            s.set_goal(bad, [0, 0, 0, 0] if bad[0] == 0 else [1, 0, 0, 0])


def test_other_kinds_refused_in_one_line():
    with pytest.raises(InvalidInputError) as exc:
        LiveSession("teleop-free-motion", {})
    assert "\n" not in str(exc.value) and "--live" in str(exc.value)


def test_jax_runs_the_same_step():
    jax = pytest.importorskip("jax")
    rng = np.random.default_rng(3)
    p, pg = rng.normal(size=(2, 5, 3))
    q, qg = rng.normal(size=(2, 5, 4))
    q, qg = q / np.linalg.norm(q, axis=-1, keepdims=True), qg / np.linalg.norm(qg, axis=-1, keepdims=True)
    qg[0] = -q[0]  # the goal is the attitude itself, of the other sign
    with jax.enable_x64(True):
        out = jax.jit(approach_pose, static_argnums=(4, 5, 6))(*(jax.numpy.asarray(a) for a in (p, q, pg, qg)),
                                                                1.0, 2.0, 0.05)
        out = [np.asarray(a) for a in out]
    for a, b in zip(out, approach_pose(p, q, pg, qg, 1.0, 2.0, 0.05)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert np.all(np.isfinite(out[3]))
    v, w = rng.normal(size=(2, 5, 3))  # with acceleration bounds: the same step too
    with jax.enable_x64(True):
        step = jax.jit(approach_pose, static_argnums=(4, 5, 6, 9, 10))
        out = [np.asarray(a) for a in step(*(jax.numpy.asarray(a) for a in (p, q, pg, qg)), 1.0, 2.0, 0.05,
                                           jax.numpy.asarray(v), jax.numpy.asarray(w), 3.0, 4.0)]
    for a, b in zip(out, approach_pose(p, q, pg, qg, 1.0, 2.0, 0.05, v, w, 3.0, 4.0)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)


def test_live_server_without_the_sdk_names_the_extra(monkeypatch):
    import sys

    from quatform.errors import MissingDependencyError
    from quatform.live.server import require_foxglove

    monkeypatch.setitem(sys.modules, "foxglove", None)  # "not installed"
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[live\]"'):
        require_foxglove()
