"""Robot models (robots.model.RobotModel) and teams (robots.team.Team): seed 000 §4.1, seed 001 §3.1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.errors import InvalidInputError
from quatform.robots import ROBOT_MODELS, Bebop, BebopMemory, HolonomicRobot, Pioneer, RobotModel, Team, yaw_matrix
from quatform.robots.testing import check_robot_model

#: One default instance of every registered model class (each registers itself when defined).
MODELS = [cls() for cls in ROBOT_MODELS.values()]
finite = st.floats(-3.0, 3.0)


@pytest.mark.parametrize("robot", MODELS, ids=lambda r: r.name)
def test_every_model_implements_the_protocol(robot):
    assert isinstance(robot, RobotModel) and ROBOT_MODELS[robot.name] is type(robot)
    check_robot_model(robot)


def test_every_model_class_is_registered():
    import quatform.robots as pkg

    classes = {obj for obj in vars(pkg).values()
               if isinstance(obj, type) and issubclass(obj, RobotModel) and obj is not RobotModel}
    assert classes <= set(ROBOT_MODELS.values()) and len(ROBOT_MODELS) >= 5


@pytest.mark.parametrize("robot", [m for m in MODELS if hasattr(m, "n_rate")], ids=lambda r: r.name)
def test_actuate_batch_equals_single(robot):
    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (5, len(robot.state_columns)))
    R = rng.uniform(-1, 1, (5, robot.n_rate))
    mem = robot.initial_memory((5,))
    U, M = robot.actuate(X, R, 0.0, mem)
    U2, _ = robot.actuate(X, R * 0.5, 0.02, M)  # a second step uses the memory
    for i in range(5):
        u, m = robot.actuate(X[i], R[i], 0.0, robot.initial_memory())
        u2, _ = robot.actuate(X[i], R[i] * 0.5, 0.02, m)
        np.testing.assert_allclose(U[i], u, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(U2[i], u2, rtol=1e-13, atol=1e-13)


@settings(max_examples=30, deadline=None)
@given(psi=st.floats(-4, 4), vx=finite, vy=finite)
def test_pioneer_control_point_moves_at_the_commanded_rate(psi, vx, vy):
    """Eq. (3.5) inverts eq. (3.4): A_p (A_p^-1 xy_dot) = xy_dot, any heading."""
    p = Pioneer()
    u, _ = p.actuate(np.array([0.0, 0.0, psi]), np.array([vx, vy, 0.0]), 0.0, None)
    np.testing.assert_allclose(p.forward_matrix(psi) @ u, [vx, vy], atol=1e-12)


def test_bebop_compensation_is_eq_447_and_remembers_its_reference():
    b = Bebop()
    x = np.array([0, 0, 1, 0.4, 0.1, -0.2, 0.05, 0.0])
    rate = np.array([0.3, -0.1, 0.2, 0.5])
    u1, m1 = b.actuate(x, rate, 0.0, b.initial_memory())
    v_r = yaw_matrix(-0.4) @ rate  # (3.10)
    ld, kv, ku = np.array(b.l_d), b.k_v, b.k_u
    np.testing.assert_allclose(u1, (ld * (v_r - x[4:]) + kv * x[4:]) / ku, rtol=1e-14)  # no derivative yet
    u2, m2 = b.actuate(x, 2 * rate, 0.05, m1)
    alpha = 0.05 / (b.derivative_filter_s + 0.05)
    v_dot = alpha * (2 * v_r - v_r) / 0.05
    np.testing.assert_allclose(m2.v_dot, v_dot, rtol=1e-12)
    np.testing.assert_allclose(u2, (v_dot + ld * (2 * v_r - x[4:]) + kv * x[4:]) / ku, rtol=1e-12)
    ub, mb = b.brake(x, m2)  # brake: v_r = 0, memory forgets the reference, keeps the derivative
    np.testing.assert_allclose(ub, (-ld * x[4:] + kv * x[4:]) / ku, rtol=1e-14)
    assert np.all(np.isnan(mb.v_r)) and np.isnan(mb.t) and np.array_equal(mb.v_dot, m2.v_dot)
    # the next reference after a brake is not differentiated against the old one
    _, m3 = b.actuate(x, rate, 0.1, mb)
    np.testing.assert_array_equal(m3.v_dot, m2.v_dot)
    off = Bebop(compensation=False)
    np.testing.assert_allclose(off.actuate(x, rate, 0.0, off.initial_memory())[0], kv / ku * v_r, rtol=1e-14)


def test_bebop_refuses_bad_compensation_settings():
    with pytest.raises(InvalidInputError, match="l_d"):
        Bebop(l_d=(1, 2, -1, 1))
    with pytest.raises(InvalidInputError, match="derivative_filter_s"):
        Bebop(derivative_filter_s=-0.1)
    assert isinstance(BebopMemory.start((2,)).t, np.ndarray)


def test_default_team_is_two_holonomic_robots_with_a_common_limit():
    t = Team()
    assert t.n == 8 and t.common_limit and t.layout.kinds == ("xyz_yaw", "xyz_yaw")
    u = np.array([10.0, 0, 0, 0, 1.0, 0, 0, 0])  # robot 1 beyond 2.5 m/s
    s = t.saturate(u)
    np.testing.assert_allclose(s, u * 0.25, rtol=1e-14)  # one factor: direction kept
    np.testing.assert_allclose(t.saturate(np.tile(u, (3, 1))), np.tile(s, (3, 1)), rtol=1e-14)
    x = np.arange(8.0)
    np.testing.assert_allclose(t.step(x, u, 0.1), x + 0.1 * s)
    np.testing.assert_array_equal(t.point(x), x)
    assert t.saturate(np.r_[np.nan, u[1:]]).tolist() == [0.0] * 8


def test_ugv_uav_team_saturates_each_robot_and_stacks_points():
    p, b = Pioneer(z=0.3), Bebop(max_fraction=0.4)
    t = Team((p, b))
    assert not t.common_limit and t.layout.kinds == ("xyz", "xyz") and t.n == 6 and t.n_rate == 7
    x = np.r_[1.0, 2.0, 0.5, 0.0, 0.1, 1.5, 0.2, 0, 0, 0, 0]
    np.testing.assert_array_equal(t.point(x), [1.0, 2.0, 0.3, 0.0, 0.1, 1.5])
    u = np.array([5.0, 0.1, 3.0, -3.0, 0.1, 0.0])
    np.testing.assert_allclose(t.saturate(u), np.r_[p.saturate(u[0:2]), b.saturate(u[2:6])])
    np.testing.assert_allclose(t.step(x, u, 0.05), np.r_[p.step(x[0:3], u[0:2], 0.05), b.step(x[3:], u[2:], 0.05)])
    with pytest.raises(InvalidInputError, match="common_limit"):
        Team((p, b), common_limit=True)
    assert math.isclose(t.actuate(x, np.zeros(7), 0.0, t.initial_memory())[0][0], 0.0)


def test_a_team_names_where_each_robots_columns_sit():
    """``Team.state_entries`` / ``command_entries``: an int for one column, a slice for
    consecutive ones, offset by the robot's part; one-line errors for an unknown column or
    columns that are not consecutive."""
    t = Team((Pioneer(), Bebop()))
    x = np.arange(float(t.n_state))
    assert t.state_entries(1, "z") == 5 and x[t.state_entries(1, "z")] == x[t.state_slices[1]][2]
    assert t.state_entries(0, "x", "y") == slice(0, 2) and t.command_entries(1, "u_x", "u_y") == slice(2, 4)
    with pytest.raises(InvalidInputError, match=r"^column 'theta' is not among \('x', 'y', 'psi'\)$"):
        t.state_entries(0, "theta")
    with pytest.raises(InvalidInputError, match=r"^columns \('x', 'z'\) are not consecutive in"):
        t.state_entries(1, "x", "z")
    with pytest.raises(InvalidInputError, match=r"^no column named; choose from"):
        Bebop().state_entries()


@given(st.floats(0.05, 1.0))
def test_bebop_max_speed_is_the_norm_of_its_linear_top_velocities(fraction):
    b = Bebop(max_fraction=fraction)
    assert b.max_speed == float(np.linalg.norm((b.k_u / b.k_v * fraction)[:3]))
