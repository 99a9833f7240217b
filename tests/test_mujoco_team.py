"""MuJoCo physics runs N quadrotors and ground robots, the quadrotors'
cascades evaluated together (robots.physics.QuadrotorCascades, sim.plants.mujoco_team)."""

from __future__ import annotations

import numpy as np
import pytest

from quatform.errors import MissingDependencyError
from quatform.sim.mujoco_backend import import_mujoco

try:  # quatform's import first: it picks the offscreen OpenGL before mujoco loads one
    import_mujoco()
except MissingDependencyError:
    pass
mujoco = pytest.importorskip("mujoco")  # the optional extra

from conftest import Constant
from quatform.errors import InvalidInputError, NonFiniteError, ShapeError
from quatform.robots import Bebop, HolonomicRobot, Pioneer, Team
from quatform.robots.physics import (
    IRIS,
    QuadrotorCascade,
    QuadrotorCascades,
    rotation_rows,
)
from quatform.scenarios import load_scenario
from quatform.sim.plants.mujoco import pair_plant, physics_metrics, physics_record
from quatform.sim.plants.mujoco_team import TeamPlant, simulated_models, team_plant
from quatform.sim.simulate import simulate

DT = 0.01  # control period, s (seed 000's)




def tetrahedron(z: float = 2.0, edge: float = 2.0) -> np.ndarray:
    """Four robots' ``(x, y, z, theta)`` at the corners of a regular tetrahedron (edge m)."""
    c = edge / np.sqrt(8.0)
    corners = c * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    return np.c_[corners + [0.0, 0.0, z], [0.0, 0.5, -0.5, 1.0]].ravel()


def test_four_quadrotors_hover_then_track_a_velocity_command():
    team = Team((HolonomicRobot(),) * 4)
    x0 = tetrahedron()
    plant = team_plant(team, x0, dt=DT)
    assert plant.state_columns == team.state_columns and plant.command_columns == team.command_columns
    assert plant.output_columns == plant.state_columns and plant.batchable is False
    assert plant.timestep == pytest.approx(0.0025) and plant.kinds == ("quadrotor",) * 4
    hover = simulate(plant, Constant((0.0,) * 16), lambda k: None, np.arange(101) * DT, plant.x0, dt=DT)
    assert np.abs(hover["state"] - x0).max() < 0.01  # 1 s at rest: the hover holds
    # every robot its own command (world velocity and yaw rate): 3 s later each moves at it
    v = np.array([[0.5, 0.0, 0.0, 0.0], [0.0, -0.4, 0.0, 0.3], [0.0, 0.0, 0.3, 0.0], [-0.3, 0.3, -0.2, -0.3]])
    log = simulate(plant, Constant(tuple(v.ravel())), lambda k: None, np.arange(301) * DT, hover["state"][-1], dt=DT)
    x = log["state"].reshape(-1, 4, 4)
    rate = (x[-1] - x[-51]) / (50 * DT)  # the last half second
    assert np.abs(rate[:, 0:3] - v[:, 0:3]).max() < 0.05
    assert np.abs(rate[:, 3] - v[:, 3]).max() < 0.02  # the yaw rate (yaw continued)
    m = physics_metrics(plant)
    assert m["collisions"]["count"] == 0 and set(m["robots"]) == {f"robot{i}" for i in range(1, 5)}
    assert all(r["kind"] == "quadrotor" and r["collisions"] == 0 and r["max_tilt_rad"] < 0.3 and
               0.5 < r["max_thrust_fraction"] < 1.0 for r in m["robots"].values())
    # robot 1 tilted to accelerate along x; robot 3 climbed straight up (more thrust, no tilt)
    assert m["robots"]["robot1"]["max_tilt_rad"] > 0.02 and m["robots"]["robot3"]["max_tilt_rad"] < 1e-6
    assert m["robots"]["robot3"]["max_thrust_n"] > IRIS.mass * 9.81 + 1.0


def test_a_mixed_team_of_three_quadrotors_and_a_pioneer_steps():
    pio = Pioneer(z=0.3)  # its platform 0.3 m up: the floor at 0
    team = Team((HolonomicRobot(), pio, HolonomicRobot(), HolonomicRobot()))
    x0 = np.r_[0.0, 2.0, 1.5, 0.0, 0.0, 0.0, 0.2, 2.0, -1.0, 1.5, 0.5, -2.0, -1.0, 1.5, -0.5]
    plant = team_plant(team, x0, dt=DT)
    assert plant.kinds == ("quadrotor", "diff-drive", "quadrotor", "quadrotor") and plant.floor_z == pytest.approx(0.0)
    assert plant.state_columns == team.state_columns and len(plant.x0) == 15
    u = np.zeros(team.n)
    u[team.command_slices[1]] = (0.3, 0.1)  # the Pioneer drives (v, omega) on a gentle arc
    times = np.arange(201) * DT
    log = simulate(plant, Constant(tuple(u)), lambda k: None, times, plant.x0, dt=DT)
    s = log["state"]
    g0, g1 = s[0, 4:7], s[-1, 4:7]
    ideal = Pioneer().step(g0, (0.3, 0.1), 2.0)  # the unicycle of seed 001 (the wheels lag a little)
    assert np.linalg.norm(g1[0:2] - ideal[0:2]) < 0.15 and abs(g1[2] - ideal[2]) < 0.05
    quads = np.r_[0:4, 7:15]
    assert np.abs(s[:, quads] - x0[quads]).max() < 0.01  # the quadrotors hover
    rec = physics_record(plant, log, "mixed")
    assert set(rec.robots) == set(plant.names) and rec.qpos.shape == (201, plant.world.model.nq)
    assert np.allclose(rec.robots["robot2"][:, 2], 0.3) and np.array_equal(rec.robots["robot3"], s[:, 7:10])
    m = physics_metrics(plant)
    assert m["collisions"]["count"] == 0 and m["robots"]["robot2"] == {"kind": "diff-drive", "collisions": 0}


def test_the_pair_plant_is_the_two_quadrotor_team_plant():
    """Step for step: the pair plant and a team plant of two HolonomicRobot models."""
    sc = load_scenario("mas-kitts-yaw-step")
    r0 = np.array([0.0, 0.0, 2.0, 0.3, 1.0, 0.0, 2.0, -0.2])
    u = (0.4, 0.0, 0.1, 0.5, 0.0, -0.3, 0.0, -0.5)
    times = np.arange(101) * sc.dt_s
    logs = [simulate(p, Constant(u), lambda k: None, times, p.x0, dt=sc.dt_s)
            for p in (pair_plant(sc, r0), team_plant(Team(), r0, dt=sc.dt_s))]
    assert np.array_equal(logs[0]["state"], logs[1]["state"])


@pytest.mark.parametrize("with_pioneer", [False, True])
def test_the_cascades_on_arrays_fly_as_the_cascades_one_by_one(with_pioneer):
    """The same team, its quadrotors' cascades vectorised or per vehicle: the same flight to
    rounding (2 s of a velocity command, four quadrotors, with and without a Pioneer)."""
    robots = (HolonomicRobot(),) * 4 + ((Pioneer(z=0.3),) if with_pioneer else ())
    x0 = np.r_[tetrahedron(), [3.0, 0.0, 0.5]] if with_pioneer else tetrahedron()
    team = Team(robots)
    u = np.r_[np.tile([0.4, -0.2, 0.1, 0.3], 4), [0.3, 0.2] if with_pioneer else []]
    times = np.arange(201) * DT
    plants = [team_plant(team, x0, dt=DT, cascades=mode) for mode in ("vectorised", "per-vehicle")]
    assert [p.world.vectorised for p in plants] == [True, False]
    logs = [simulate(p, Constant(tuple(u)), lambda k: None, times, p.x0, dt=DT) for p in plants]
    assert np.abs(logs[0]["state"] - logs[1]["state"]).max() < 1e-9
    assert np.abs(logs[0]["state"][-1] - x0).max() > 0.3  # they moved
    assert team_plant(Team((HolonomicRobot(),) * 6), np.r_[tetrahedron(), tetrahedron()[:8] + [0, 0, 3, 0] * 2],
                      dt=DT).world.vectorised  # "auto": arrays from VECTORISED_FROM quadrotors on
    with pytest.raises(InvalidInputError, match="cascades must be one of"):
        team_plant(team, x0, dt=DT, cascades="numba")


def test_batch_axes_and_bad_input_are_refused_in_one_line():
    team = Team((HolonomicRobot(),) * 4)
    x0 = tetrahedron()
    for bad, what in ((np.stack([x0, x0]), r"\(16,\)"), (x0[:12], r"\(16,\)")):
        with pytest.raises(ShapeError, match=what) as e:
            team_plant(team, bad, dt=DT)
        assert "\n" not in str(e.value)
    with pytest.raises(InvalidInputError, match="finite"):
        team_plant(team, np.r_[x0[:-1], np.nan], dt=DT)
    with pytest.raises(InvalidInputError, match="robot 2 is a Bebop.*HolonomicRobot or Pioneer") as e:
        team_plant(Team((HolonomicRobot(), Bebop())), np.zeros(12), dt=DT)
    assert "\n" not in str(e.value) and set(simulated_models().values()) == {"quadrotor", "diff-drive"}
    with pytest.raises(InvalidInputError, match="Team"):
        team_plant((HolonomicRobot(),), np.zeros(4), dt=DT)
    with pytest.raises(InvalidInputError, match="Pioneers' z differ"):
        team_plant(Team((Pioneer(z=0.3), Pioneer(z=0.5))), np.r_[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], dt=DT)
    with pytest.raises(InvalidInputError, match="does not divide"):
        team_plant(team, x0, dt=DT, timestep=0.003)
    with pytest.raises(InvalidInputError, match="dt must be positive"):
        team_plant(team, x0, dt=-1.0)
    with pytest.raises(InvalidInputError, match="cascade_options"):
        team_plant(team, x0, dt=DT, cascade_options={"tilt": 0.3})
    with pytest.raises(InvalidInputError, match="overlap"):  # two quadrotors in one place
        team_plant(team, np.r_[x0[:4], x0[:4] + 0.1, x0[8:]], dt=DT)
    plant = team_plant(team, x0, dt=DT)
    with pytest.raises(InvalidInputError, match="not the state the world is in"):
        plant.step(x0 + 0.1, np.zeros(16), DT, 0.0)
    with pytest.raises(InvalidInputError, match=r"u must have shape \(16,\)"):
        plant.step(plant.x0, np.zeros((2, 16)), DT, 0.0)
    with pytest.raises(InvalidInputError, match="batch"):  # simulate refuses a batch of worlds
        simulate(plant, Constant((0.0,) * 16), lambda k: None, np.arange(3) * DT, np.stack([x0, x0]), dt=DT)


def _random_states(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[0] = (1.0, 0.0, 0.0, 0.0)  # level
    q[1] = (np.cos(0.25 * np.pi), 0.0, np.sin(0.25 * np.pi), 0.0)  # body x vertical: the heading falls back
    return rotation_rows(q), rng.normal(size=(n, 3)) * 2, rng.normal(size=(n, 3)) * 2


def test_the_vectorised_cascade_is_the_per_vehicle_cascade():
    rng = np.random.default_rng(14)
    n = 200
    R, v, w = _random_states(rng, n)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ref = np.empty(9)
    for i in range(n):  # MuJoCo's own rotation matrix, within rounding
        mujoco.mju_quat2Mat(ref, q[i])
        assert np.allclose(rotation_rows(q[i:i + 1])[0], ref, rtol=0, atol=1e-15)
    v_cmd, yaw = rng.normal(size=(n, 3)) * 3, rng.normal(size=n) * 4
    v_cmd[2, 1], yaw[3], yaw[4] = np.nan, np.inf, np.nan  # non-finite set points hold zero
    bank = QuadrotorCascades(n, tilt_max=0.5)
    bank.integral = integ = rng.normal(size=(n, 3))
    f = bank.velocity_mode(v_cmd, yaw, v, R, w, 0.0025)
    u = rng.uniform(-1.5, 1.5, size=(n, 4))
    u[5, 2] = np.nan
    fa = bank.attitude_mode(u, v, R, w)
    thrust, tau = rng.uniform(-5, 30, n), rng.normal(size=(n, 3)) * 2  # many rotors saturate
    fm = bank.mix(thrust, tau)
    forces = rng.uniform(-1, 8, size=(n, 4))
    drag = bank.rotor_drag(forces, v, R)
    saturated = 0
    for i in range(n):
        one = QuadrotorCascade(tilt_max=0.5)
        one._integral = integ[i].tolist()
        assert np.allclose(one.velocity_mode(v_cmd[i], yaw[i], v[i], R[i], w[i], 0.0025), f[i], rtol=0, atol=1e-12)
        assert np.allclose(one._integral, bank.integral[i], rtol=0, atol=1e-15)
        assert np.allclose(one.attitude_mode(u[i], v[i], R[i], w[i]), fa[i], rtol=0, atol=1e-12)
        mixed = np.array(one.mix(thrust[i], tau[i]))
        saturated += bool(np.any(mixed == 0.0) or np.any(mixed == IRIS.max_thrust))
        assert np.allclose(mixed, fm[i], rtol=0, atol=1e-12)
        assert np.allclose(one.rotor_drag(forces[i], v[i], R[i]), drag[i], rtol=0, atol=1e-12)
    assert saturated > n // 4  # the desaturation was exercised


def test_the_vectorised_cascade_refuses_a_non_finite_state_and_keeps_its_integrators():
    R, v, w = _random_states(np.random.default_rng(3), 3)
    bank = QuadrotorCascades(3)
    v[1, 0] = np.nan
    with pytest.raises(NonFiniteError, match="not finite"):
        bank.velocity_mode(np.zeros((3, 3)), np.zeros(3), v, R, w, 0.0025)
    assert np.all(bank.integral == 0.0)
    with pytest.raises(InvalidInputError, match="positive number of vehicles"):
        QuadrotorCascades(0)
    with pytest.raises(InvalidInputError, match=r"shape \(3, 3\)"):
        bank.integral = np.zeros(3)


def test_team_plant_in_the_plants_registry_of_kinds():
    """Every registered robot model with a physics kind is one the plant accepts (the models say, not a
    re-typed list); a TeamPlant is made through team_plant with the scenario helper's call."""
    for cls in simulated_models():
        x0 = tetrahedron()[:4] if cls is HolonomicRobot else np.zeros(3)
        plant = team_plant(Team((cls(),)), x0, dt=DT)
        assert isinstance(plant, TeamPlant) and plant.names == ("robot1",)
