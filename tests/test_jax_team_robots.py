"""The team kind's Pioneer and free-body robots on the jax backend.

``team-triangle-over-ugv`` (a Pioneer offering ``xy_yaw``, three quadrotors, each robot
saturated on its own) under its four controllers, with its shape move (robot 2 over the UGV)
moved into a short run, and teams with free bodies under every description that takes them
run on NumPy and on JAX (batches with per-world starts, TickMeasurement noise, latency and
dropped frames) and every logged channel is compared within 1e-9; one world's finished log
(every channel) and metrics are equal; a world of a Pioneer team whose barrier binds is
NumPy's own run; the robot models' and the team's kernels (and the robots' point velocities
the barrier reads) under ``jax.jit`` equal NumPy's; what still runs on NumPy only is refused
in one line.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL
from conftest import assert_logs_equal, assert_metrics_equal, noisy_batch

from quatform.errors import InvalidInputError
from quatform.robots import FreeBodyRobot, HolonomicRobot, Pioneer, PlanarHolonomicRobot, Team
from quatform.scenarios import KINDS, builtin_scenarios
from quatform.tomlio import read_toml

TEAM = KINDS["team"]
UGV_CONTROLLERS = ("quaternion", "dual-quaternion", "cluster-space", "robot-space")
#: The descriptions that take pose robots (robot space with an orientation gain k_w).
POSE_CONTROLLERS = ("quaternion", "dual-quaternion", "robot-space")
SAFETY = ("min_separation", "safety_active")


def _ugv(duration_s=0.6, move_start_s=0.1, move_s=0.4):
    """``team-triangle-over-ugv`` cut to ``duration_s``, its shape move (robot 2 to hover over
    the UGV) starting at ``move_start_s`` and lasting ``move_s``."""
    data, where = read_toml("team-triangle-over-ugv", builtin_scenarios(), "scenario")
    data = dict(data, duration_s=duration_s, metrics_from_s=0.0,
                shape=dict(data["shape"], moves=[dict(data["shape"]["moves"][0], start_s=move_start_s,
                                                      duration_s=move_s)]))
    return TEAM.from_dict(data, str(where))


def _bodies(robots, name="free-bodies"):
    """A short team scenario of ``robots`` (``[[robots]]`` entries) around free bodies: a
    tetrahedron moving and turning about a tilted axis, robot space given an orientation gain."""
    data = {"kind": "team", "name": name, "duration_s": 0.6, "dt_s": 0.02,
            "gains": {"base": "table1", "robot-space": {"k_w": 6.0}}, "robots": robots,
            "shape": {"template": "tetrahedron", "edge": 1.2},
            "path": {"kind": "line", "center": [0.0, 0.0, 1.0], "velocity": [0.3, 0.1, 0.0]},
            "attitude": {"turns": [{"axis": [0.3, 0.2, 1.0], "angle": 1.0, "start_s": 0.0, "duration_s": 0.6}]},
            "headings": {"mode": "path"}, "safety": {"min_separation_m": 0.3}}
    return TEAM.from_dict(data, name)


BODY_TEAMS = {
    "free-bodies": [{"model": "free-body", "count": 4}],  # one common limit factor
    "mixed": [{"model": "free-body", "count": 2}, {"model": "pioneer", "count": 1},
              {"model": "quadrotor", "count": 1}],  # each robot on its own
}


def _assert_equal(a, b):
    assert_logs_equal(a, b)
    for key in SAFETY:
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)


# -- the Pioneer team --------------------------------------------------------------------------------

@pytest.mark.parametrize("controller", UGV_CONTROLLERS)
def test_triangle_over_ugv_batch_equals_numpy(controller):
    pytest.importorskip("jax")
    scenario = _ugv()
    assert not scenario.team.common_limit and type(scenario.team.robots[0]) is Pioneer
    batch = noisy_batch(TEAM.experiment(scenario, controller=controller))
    a, b = batch.run(backend="numpy"), batch.run(backend="jax")
    _assert_equal(a, b)
    assert "failed" not in b.meta and "numpy_worlds" not in b.meta  # every world ran on JAX
    # the run covers what is new here: the unicycle turning, each robot's own limit, robot 2's move over the UGV
    u = b["command"]
    assert np.abs(u[..., 1]).max() > 0.3 and np.all(np.abs(u[..., 1]) <= Pioneer().max_omega + 1e-12)
    speed = np.linalg.norm(u[..., 2:5], axis=-1)  # robot 2 at its own limit (the Pioneer not scaled with it)
    assert abs(speed.max() - scenario.team.robots[1].max_speed) < 1e-12
    desired = TEAM.experiment(scenario, controller=controller).reference(len(batch.times) - 1).robots
    assert np.linalg.norm(desired[3:5] - desired[0:2]) < 1e-9  # robot 2's (x, y) over the UGV's at the end


@pytest.mark.parametrize("scenario, controller", [("ugv", "quaternion"), ("mixed", "dual-quaternion")])
def test_one_world_after_finish_and_its_metrics_equal_numpy(scenario, controller):
    pytest.importorskip("jax")
    exp = TEAM.experiment(_ugv() if scenario == "ugv" else _bodies(BODY_TEAMS[scenario]), controller=controller)
    a, b = exp.run(backend="numpy"), exp.run(backend="jax")
    assert list(a.channels) == list(b.channels) and len(a.channels) > 10
    for key in a.channels:  # every channel of the finished log (the chart, the singularity measure, ...)
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))


def test_a_pioneer_world_whose_barrier_binds_is_numpys_run():
    pytest.importorskip("jax")
    exp = TEAM.experiment(_ugv(0.4), controller="robot-space")
    batch = noisy_batch(exp, B=3, spread=0.0)
    x0 = np.array(batch.x0)
    x0[2, 3:6] = [x0[2, 0], x0[2, 1], -0.55]  # world 2: robot 2 starts 0.55 m under the UGV, its way up through it
    run = dataclasses.replace(batch, x0=x0)
    a, b = run.run(backend="numpy"), run.run(backend="jax")
    assert np.nanmax(a["safety_active"][:, 2]) == 1.0 and np.nanmax(a["safety_active"][:, :2]) == 0.0
    assert b.meta["numpy_worlds"].tolist() == [False, False, True]
    _assert_equal(a, b)


# -- teams with free bodies ----------------------------------------------------------------------------

@pytest.mark.parametrize("team", BODY_TEAMS)
def test_the_descriptions_that_take_free_bodies(team):
    run, skipped = TEAM.compare_choices(_bodies(BODY_TEAMS[team]), "controller")
    assert run == POSE_CONTROLLERS and list(skipped) == ["cluster-space"]


@pytest.mark.parametrize("team", BODY_TEAMS)
@pytest.mark.parametrize("controller", POSE_CONTROLLERS)
def test_free_body_team_batch_equals_numpy(team, controller):
    pytest.importorskip("jax")
    scenario = _bodies(BODY_TEAMS[team])
    assert scenario.team.common_limit == (team == "free-bodies")
    batch = noisy_batch(TEAM.experiment(scenario, controller=controller))
    a, b = batch.run(backend="numpy"), batch.run(backend="jax")
    _assert_equal(a, b)
    assert "failed" not in b.meta and "numpy_worlds" not in b.meta
    q = b["state"][1:, :, 3:7]  # robot 1 (a free body) turned, its quaternion unit after the first step
    turn = 2.0 * np.arccos(np.minimum(1.0, np.abs(np.sum(q[-1] * q[0], axis=-1))))
    assert turn.min() > 0.02 and np.allclose(np.linalg.norm(q, axis=-1), 1.0, rtol=0, atol=1e-12), turn


# -- the kernels under jax.jit ------------------------------------------------------------------------

def test_team_kernels_under_jit_equal_numpy():
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from quatform.control.safety import POINT_MAPS, SeparationBarrier
    from quatform.sim import jax_loop

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
                                             jax_loop.point_velocities(barrier, team, x, us)))
            out = [np.asarray(v) for v in f(*(jnp.asarray(a) for a in (x, rate, u, us)))]
        # each robot's point velocity on its own (SeparationBarrier.filter's map of its model)
        V = np.stack([POINT_MAPS[type(rb)].velocity(rb, x[:, ss], us[:, cs], barrier.dt_s) for rb, ss, cs in
                      zip(team.robots, team.state_slices, team.command_slices)], axis=1)
        want = (team.actuate(x, rate, 0.0, team.initial_memory((B,)))[0], us, team.step(x, u, 0.02), x, V)
        for name, got, ref in zip(("actuate", "saturate", "step", "scatter", "point_velocities"), out, want):
            assert got.shape == ref.shape, name
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12, err_msg=name)
        assert np.all(want[1][2] == 0.0) == team.common_limit  # a common-limit team stops as a whole


# -- refusals ---------------------------------------------------------------------------------------------

def test_a_pioneer_offering_its_platform_point_is_refused_in_one_line():
    pytest.importorskip("jax")
    from quatform.control import team_controller
    from quatform.sim import jax_loop
    from quatform.sim.plants import KinematicTeam

    from quatform.scenarios.team import TEAM_TABLES

    team = Team((Pioneer(point_kind="xyz", z=0.3), HolonomicRobot(), HolonomicRobot()))
    ctrl = team_controller("quaternion", team, TEAM_TABLES["table1"]["quaternion"])
    with pytest.raises(InvalidInputError) as info:
        jax_loop.check_supported(KinematicTeam(team), ctrl, None)
    msg = str(info.value)
    assert "\n" not in msg and "point_kind = 'xyz' runs on numpy" in msg and "four team controllers" in msg
