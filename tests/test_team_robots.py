"""Team robots: the planar holonomic robot, the 6-DOF free body, the Pioneer's planar point
and the vectorised Team (one model call per group of equal robots)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.algebra import q_from_axis_angle, qmul
from quatform.errors import InvalidInputError, ShapeError
from quatform.formations.layout import POINT_KINDS
from quatform.robots import (
    Bebop,
    FreeBodyRobot,
    HolonomicRobot,
    Pioneer,
    PlanarHolonomicRobot,
    RobotModel,
    Team,
)

NEW = [PlanarHolonomicRobot(), FreeBodyRobot(), Pioneer(point_kind="xy_yaw")]
rng0 = np.random.default_rng(14)


def unit_q(rng, shape=()):
    q = rng.normal(size=tuple(shape) + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def random_state(model, rng, shape=()):
    x = rng.uniform(-1, 1, tuple(shape) + (len(model.state_columns),))
    if model.point_kind == "pose":
        x[..., 3:7] = unit_q(rng, shape)
    return x


# -- the models --------------------------------------------------------------------------

@pytest.mark.parametrize("robot", NEW, ids=lambda r: f"{r.name}-{r.point_kind}")
def test_new_models_implement_the_protocol(robot):
    assert isinstance(robot, RobotModel)
    x = random_state(robot, rng0)
    assert robot.point(x).shape == (POINT_KINDS[robot.point_kind].size,)
    u, mem = robot.actuate(x, np.full(robot.n_rate, 0.3), 0.0, robot.initial_memory())
    assert u.shape == (len(robot.command_columns),) and mem is None
    assert robot.saturate(np.full(u.shape, np.nan)).tolist() == [0.0] * u.size
    assert robot.step(x, u, 0.01).shape == x.shape
    np.testing.assert_array_equal(robot.brake(x, None)[0], np.zeros(u.size))


def test_bad_parameters_are_one_line():
    cases = [(lambda: PlanarHolonomicRobot(max_speed=-1.0), "max_speed"),
             (lambda: PlanarHolonomicRobot(max_yaw_rate=math.nan), "max_yaw_rate"),
             (lambda: FreeBodyRobot(max_angular_rate=0.0), "max_angular_rate"),
             (lambda: FreeBodyRobot(max_speed="fast"), "max_speed"),
             (lambda: Pioneer(point_kind="pose"), "point_kind"),
             (lambda: Team.uniform(HolonomicRobot(), 0), "whole number"),
             (lambda: Team((Pioneer(), PlanarHolonomicRobot()), common_limit=True), "Pioneer"),
             (lambda: Team.uniform(PlanarHolonomicRobot(), 3).saturate(np.zeros(8)), r"\(\.\.\., 9\)"),
             (lambda: PlanarHolonomicRobot().saturate(np.zeros(4)), r"\(\.\.\., 3\)"),
             (lambda: FreeBodyRobot().saturate(np.zeros(4)), r"\(\.\.\., 6\)")]
    for make, match in cases:
        with pytest.raises(InvalidInputError, match=match) as e:
            make()
        assert "\n" not in str(e.value)
    with pytest.raises(ShapeError, match="free-body state"):
        FreeBodyRobot().step(np.zeros(6), np.zeros(6), 0.1)


def test_planar_robot_steps_exactly_and_scales_its_command_as_a_whole():
    r = PlanarHolonomicRobot(max_speed=1.0, max_yaw_rate=2.0)
    x = np.array([0.5, -1.0, 3.0])
    u = np.array([0.3, -0.4, 1.0])  # within the limits
    np.testing.assert_array_equal(r.step(x, u, 0.1), x + 0.1 * u)
    big = np.array([3.0, 4.0, 1.0])  # 5 m/s
    np.testing.assert_allclose(r.saturate(big), big / 5.0, rtol=1e-15)
    np.testing.assert_allclose(r.saturate([0.0, 0.1, -8.0]), [0.0, 0.025, -2.0], rtol=1e-15)
    assert PlanarHolonomicRobot().point(x) is not None and r.passthrough and r.holonomic


@settings(max_examples=40, deadline=None)
@given(w=st.tuples(*[st.floats(-3, 3)] * 3).map(np.array), v=st.tuples(*[st.floats(-1, 1)] * 3).map(np.array),
       dt=st.floats(1e-3, 0.5), seed=st.integers(0, 2**31 - 1))
def test_free_body_step_is_the_exact_rotation(w, v, dt, seed):
    """q(dt) = rotation by |w| dt about w (world frame) times q(0): the solution of
    q_dot = 1/2 w q for a held w; two half steps equal one step."""
    body = FreeBodyRobot(max_speed=10.0, max_angular_rate=10.0)
    rng = np.random.default_rng(seed)
    x = np.r_[rng.uniform(-1, 1, 3), unit_q(rng)]
    u = np.r_[v, w]
    x1 = body.step(x, u, dt)
    a = np.linalg.norm(w)
    rot = q_from_axis_angle(w / a, a * dt) if a > 0 else np.array([1.0, 0, 0, 0])
    np.testing.assert_allclose(x1[3:], qmul(rot, x[3:]), atol=1e-13)
    np.testing.assert_allclose(x1[:3], x[:3] + dt * v, atol=1e-15)
    np.testing.assert_allclose(body.step(body.step(x, u, dt / 2), u, dt / 2), x1, atol=1e-12)
    assert abs(np.linalg.norm(x1[3:]) - 1.0) < 1e-15


def test_free_body_actuate_inverts_the_quaternion_rate_and_stays_unit():
    body = FreeBodyRobot()
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.normal(size=(50, 3)), unit_q(rng, (50,))], axis=-1)
    w = rng.uniform(-2, 2, (50, 3))
    v = rng.uniform(-1, 1, (50, 3))
    w_quat = np.concatenate([np.zeros((50, 1)), w], axis=-1)
    q_dot = 0.5 * qmul(w_quat, x[:, 3:])  # seed 001 eq. (2.32)
    q_dot = q_dot + 0.7 * x[:, 3:]  # a part along q (a norm change) is dropped
    u, _ = body.actuate(x, np.concatenate([v, q_dot], axis=-1), 0.0)
    np.testing.assert_allclose(u, np.concatenate([v, w], axis=-1), atol=1e-13)
    y = x[0]
    for _ in range(10000):
        y = body.step(y, [0.1, 0, 0, 2.9, -1.0, 0.5], 0.01)
    assert abs(np.linalg.norm(y[3:]) - 1.0) < 1e-14
    big = np.array([0.0, 0, 0, 6.0, 0, 8.0])  # 10 rad/s
    np.testing.assert_allclose(body.saturate(big), big * 0.3, rtol=1e-15)


@settings(max_examples=40, deadline=None)
@given(psi=st.floats(-7, 7), v=st.floats(-0.75, 0.75), w=st.floats(-1.7, 1.7), dt=st.floats(1e-3, 0.2))
def test_pioneer_mean_point_velocity_is_its_step_and_inverts_in_closed_form(psi, v, w, dt):
    p = Pioneer()
    x = np.array([0.3, -0.2, psi])
    mean = p.mean_point_velocity(psi, [v, w], dt)
    np.testing.assert_allclose(x[:2] + dt * mean, p.step(x, [v, w], dt)[:2], atol=1e-14)
    np.testing.assert_allclose(p.commands_from_mean_velocity(psi, mean, dt), [v, w], atol=1e-11)
    # dt -> 0: eq. (3.4)
    np.testing.assert_allclose(p.mean_point_velocity(psi, [v, w], 1e-9), p.point_velocity(psi, [v, w]), atol=1e-9)
    np.testing.assert_allclose(p.point_velocity(psi, [v, w]), p.forward_matrix(psi) @ [v, w], atol=1e-15)


def test_pioneer_offers_a_planar_point_on_request():
    p = Pioneer(point_kind="xy_yaw", z=0.3)
    x = np.array([1.0, 2.0, 0.4])
    np.testing.assert_array_equal(p.point(x), x)
    assert Team((p, PlanarHolonomicRobot())).layout.kinds == ("xy_yaw", "xy_yaw")
    assert Pioneer().point_kind == "xyz" and Team((Pioneer(),)).layout.kinds == ("xyz",)
    # the heading rate of the planar point is not commanded: eq. (3.5) of the control point rate
    u, _ = p.actuate(x, [0.2, -0.1, 5.0], 0.0, None)
    np.testing.assert_allclose(u, p.commands_from_velocity(0.4, [0.2, -0.1]), rtol=1e-15)


# -- the vectorised team -----------------------------------------------------------------

MIXED = (HolonomicRobot(), Pioneer(), HolonomicRobot(), Bebop(), Pioneer(point_kind="xy_yaw"),
         Pioneer(), Bebop(), HolonomicRobot(1.0, 1.0), PlanarHolonomicRobot(), FreeBodyRobot())


def per_robot(team, method, *arrays, slices):
    """The reference: each robot's method on its own slices, stacked."""
    parts = [getattr(r, method)(*(a[..., s] for a, s in zip(arrays, ss)))
             for r, ss in zip(team.robots, zip(*slices))]
    return np.concatenate(parts, axis=-1)


def test_groups_are_equal_models_in_order_of_first_appearance():
    t = Team(MIXED)
    assert [g.robots for g in t.groups] == [(0, 2), (1, 5), (3, 6), (4,), (7,), (8,), (9,)]
    assert len(Team.uniform(HolonomicRobot(), 1000).groups) == 1
    assert Team.uniform(HolonomicRobot(), 1000).groups[0].state.block == slice(0, 4000)


@pytest.mark.parametrize("batch", [(), (3,), (2, 2)])
def test_mixed_team_equals_its_robots_one_by_one(batch):
    rng = np.random.default_rng(5)
    t = Team(MIXED)
    x = np.concatenate([random_state(r, rng, batch) for r in t.robots], axis=-1)
    u = rng.uniform(-3, 3, batch + (t.n,))
    rate = rng.uniform(-1, 1, batch + (t.n_rate,))
    np.testing.assert_array_equal(t.point(x), per_robot(t, "point", x, slices=[t.state_slices]))
    np.testing.assert_array_equal(t.saturate(u), per_robot(t, "saturate", u, slices=[t.command_slices]))
    steps = [r.step(x[..., s], r.saturate(u[..., c]), 0.05) for r, s, c in zip(t.robots, t.state_slices,
                                                                               t.command_slices)]
    np.testing.assert_array_equal(t.step(x, u, 0.05), np.concatenate(steps, axis=-1))
    mem = t.initial_memory(batch)
    U, M = t.actuate(x, rate, 0.0, mem)
    U2, _ = t.actuate(x, 0.5 * rate, 0.02, M)
    for i, r in enumerate(t.robots):  # each robot with its own memory
        xs, rs, cs = t.state_slices[i], t.rate_slices[i], t.command_slices[i]
        ui, mi = r.actuate(x[..., xs], rate[..., rs], 0.0, r.initial_memory(batch))
        ui2, _ = r.actuate(x[..., xs], 0.5 * rate[..., rs], 0.02, mi)
        np.testing.assert_allclose(U[..., cs], ui, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(U2[..., cs], ui2, rtol=1e-13, atol=1e-13)
    B, _ = t.brake(x, t.initial_memory(batch))
    ref = [r.brake(x[..., s], r.initial_memory(batch))[0] for r, s in zip(t.robots, t.state_slices)]
    np.testing.assert_allclose(B, np.concatenate(ref, axis=-1), rtol=1e-14, atol=1e-14)


def test_batch_equals_single():
    rng = np.random.default_rng(6)
    t = Team(MIXED)
    X = np.concatenate([random_state(r, rng, (4,)) for r in t.robots], axis=-1)
    U = rng.uniform(-3, 3, (4, t.n))
    S = t.step(X, U, 0.02)
    for b in range(4):
        np.testing.assert_allclose(t.step(X[b], U[b], 0.02), S[b], rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(t.point(X[b]), t.point(X)[b], rtol=0, atol=0)


@pytest.mark.parametrize("model", [HolonomicRobot(), PlanarHolonomicRobot(), FreeBodyRobot()],
                         ids=lambda m: m.name)
def test_holonomic_teams_share_one_factor(model):
    """A team of holonomic robots scales every command by the smallest factor any robot needs
    (the formation's motion keeps its direction); batch and single agree; NaN stops the team."""
    rng = np.random.default_rng(7)
    t = Team.uniform(model, 20)
    assert t.common_limit
    u = rng.uniform(-1, 1, (3, t.n))
    u[1, 5] = 40.0
    s = t.saturate(u)
    f = np.array([min(model.limit_factor(ui[c]) for c in t.command_slices) for ui in u])
    np.testing.assert_allclose(s, u * f[:, None], rtol=1e-15)
    for b in range(3):
        np.testing.assert_allclose(t.saturate(u[b]), s[b], rtol=1e-15, atol=1e-300)
    bad = u[0].copy()
    bad[3] = np.nan
    assert np.all(t.saturate(bad) == 0.0)
    x = np.concatenate([random_state(model, rng) for _ in range(20)])
    ref = np.concatenate([model.step(x[sl], s[0][c], 0.1) for sl, c in zip(t.state_slices, t.command_slices)])
    np.testing.assert_allclose(t.step(x, u[0], 0.1), ref, rtol=1e-14, atol=1e-14)


def test_bebop_group_memory_carries_the_robot_axis():
    t = Team.uniform(Bebop(), 3)
    mem = t.initial_memory((2,))
    assert len(mem) == 1 and mem[0].v_r.shape == (2, 3, 4) and mem[0].t.shape == (2, 3)
    assert not t.common_limit and not t.passthrough


def test_gather_and_scatter_are_inverse():
    rng = np.random.default_rng(8)
    t = Team(MIXED)
    for part, n in (("state", t.n_state), ("command", t.n), ("rate", t.n_rate), ("point", t.layout.size)):
        a = rng.normal(size=(2, n))
        parts = t.gather(a, part)
        assert len(parts) == len(t.groups)
        np.testing.assert_array_equal(t.scatter(parts, part), a)
    with pytest.raises(InvalidInputError, match="groups"):
        t.scatter([np.zeros(3)], "state")


def test_seed000_pair_team_is_unchanged():
    """The default team (the seed's pair) keeps its float path: bitwise the saturated command."""
    t = Team()
    u = np.array([10.0, 0, 0, 0, 1.0, 0, 0, 0])
    np.testing.assert_array_equal(t.saturate(u), np.array([x * 0.25 for x in u]))
    assert t.passthrough and t.common_limit and len(t.groups) == 1


# -- the team's kernels under jax.jit -----------------------------------------------------------------

def test_team_kernels_under_jit_equal_numpy():
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from quatform.control.safety import SeparationBarrier
    from quatform.control.barrier import point_velocities

    barrier = SeparationBarrier(0.3, gamma=5.0, dt_s=0.02)
    robots = (Pioneer(point_kind="xy_yaw"), FreeBodyRobot(max_speed=1.0), HolonomicRobot(max_speed=0.9),
              PlanarHolonomicRobot(), FreeBodyRobot(max_speed=1.0), Pioneer(point_kind="xy_yaw"))
    rng = np.random.default_rng(3)
    B = 64
    for team in (Team(robots), Team(robots[1:5])):
        x = rng.standard_normal((B, team.n_state))
        for g in team.groups:  # unit quaternions for the free bodies
            if type(g.model) is FreeBodyRobot:
                for sl in (team.state_slices[i] for i in g.robots):
                    q = x[:, sl][:, 3:7]
                    x[:, sl.start + 3:sl.stop] = q / np.linalg.norm(q, axis=-1, keepdims=True)
        rate = 2.0 * rng.standard_normal((B, team.n_rate))
        u = 2.0 * rng.standard_normal((B, team.n))
        u[0] = 0.0  # the Pioneer's straight step (omega dt below 1e-9), a free body's zero turn
        u[1, 1] = 1e-12
        u[2, 3] = np.nan  # a non-finite command
        u[3] *= 1e-3  # within the limits
        us = team.saturate(u)
        with jax.enable_x64(True):
            f = jax.jit(lambda x, r, u, us: (team.actuate(x, r, 0.0, team.initial_memory((B,)))[0], team.saturate(u),
                                             team.step(x, u, 0.02), team.scatter(team.gather(x), "state"),
                                             point_velocities(barrier, team, x, us)))
            out = [np.asarray(v) for v in f(*(jnp.asarray(a) for a in (x, rate, u, us)))]
        # each robot's point velocity on its own (SeparationBarrier.filter's map of its model)
        V = np.stack([rb.point_map.velocity(rb, x[:, ss], us[:, cs], barrier.dt_s) for rb, ss, cs in
                      zip(team.robots, team.state_slices, team.command_slices)], axis=1)
        want = (team.actuate(x, rate, 0.0, team.initial_memory((B,)))[0], us, team.step(x, u, 0.02), x, V)
        for name, got, ref in zip(("actuate", "saturate", "step", "scatter", "point_velocities"), out, want):
            assert got.shape == ref.shape, name
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12, err_msg=name)
        assert np.all(want[1][2] == 0.0) == team.common_limit  # a common-limit team stops as a whole
