"""The MuJoCo worlds are plants of the one loop, quatform.sim.simulate."""

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

from quatform.control import UGV_UAV_COMMAND_NAMES, UGV_UAV_MEASURED_NAMES
from conftest import Constant
from quatform.errors import InvalidInputError, ShapeError
from quatform.robots.physics import IRIS
from quatform.scenarios import load_scenario
from quatform.sim.mujoco_backend import IRIS_IDENTIFIED_K
from quatform.sim.plants.mujoco import pair_plant, physics_metrics, physics_record, ugv_uav_plant
from quatform.sim.simulate import simulate




R0 = np.array([0.0, 0.0, 2.0, 0.3, 1.0, 0.0, 2.0, -0.2])


def test_pair_plant_keeps_the_plant_contract():
    sc = load_scenario("mas-kitts-yaw-step")
    plant = pair_plant(sc, R0)
    assert plant.state_columns == ("x1", "y1", "z1", "theta1", "x2", "y2", "z2", "theta2")
    assert plant.output_columns == plant.state_columns and plant.batchable is False
    assert plant.command_columns == ("v_x1", "v_y1", "v_z1", "yaw_rate1", "v_x2", "v_y2", "v_z2", "yaw_rate2")
    assert plant.timestep == pytest.approx(sc.dt_s / 4) and np.array_equal(plant.x0, R0)
    assert plant.output(plant.x0) is plant.x0
    with pytest.raises(InvalidInputError, match="not the state the world is in"):
        plant.step(R0 + 0.1, np.zeros(8), sc.dt_s, 0.0)
    with pytest.raises(InvalidInputError, match="whole multiple"):
        plant.step(plant.x0, np.zeros(8), 1.5 * plant.timestep, 0.0)
    with pytest.raises(ShapeError, match=r"\(8,\)"):
        pair_plant(sc, np.zeros((2, 8)))
    with pytest.raises(InvalidInputError, match="finite"):
        pair_plant(sc, np.r_[R0[:7], np.nan])
    with pytest.raises(InvalidInputError, match="timestep"):
        pair_plant(sc, R0, timestep=-1.0)


def test_pair_plant_through_simulate_follows_the_velocity_commands():
    sc = load_scenario("mas-kitts-yaw-step")
    plant = pair_plant(sc, R0)
    times = np.arange(301) * 0.01  # 3 s, control every 10 ms
    v = (-0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0)  # robot 1 along -x, robot 2 along +y: apart
    log = simulate(plant, Constant(v), lambda k: None, times, plant.x0, dt=0.005, substeps=2)
    x = log["state"]
    assert x.shape == (301, 8) and log.columns("state") == plant.state_columns
    assert np.array_equal(x[0], R0)
    # the PX4-like velocity loop lags ~0.55 s: by 3 s each robot has gone ~0.5 * (3 - 0.55) m
    assert x[-1, 0] == pytest.approx(-0.5 * (3 - 0.55), abs=0.15) and abs(x[-1, 1]) < 0.05
    assert x[-1, 5] == pytest.approx(0.5 * (3 - 0.55), abs=0.15) and abs(x[-1, 4] - 1.0) < 0.05
    assert np.abs(x[:, [2, 6]] - 2.0).max() < 0.1  # the height held
    # a zero yaw-rate set point holds no heading: the tilt to accelerate turns each by ~0.08 rad
    assert np.abs(x[:, [3, 7]] - R0[[3, 7]]).max() < 0.15
    rec = physics_record(plant, log, "test")
    # one record per control tick, at its start: the same positions as the logged state
    assert rec.qpos.shape == (301, 14) and np.allclose(rec.qpos[:, 0:3], x[:, 0:3], atol=1e-12)
    assert np.allclose(rec.qpos[:, 7:10], x[:, 4:7], atol=1e-12) and np.array_equal(rec.t, times)
    assert np.array_equal(rec.robots["robot2"], x[:, 4:7]) and rec.title == "test"
    m = physics_metrics(plant)
    assert m == {"physics": "mujoco", "collisions": {"count": 0, "first_time_s": None, "bodies": []},
                 "physics_timestep_s": 0.0025}


def test_pair_plant_hovers_on_zero_commands_and_a_new_plant_starts_afresh():
    sc = load_scenario("mas-kitts-yaw-step")
    times = np.arange(101) * sc.dt_s
    logs = [simulate(p, Constant((0.0,) * 8), lambda k: None, times, p.x0, dt=sc.dt_s)
            for p in (pair_plant(sc, R0), pair_plant(sc, R0))]
    assert np.abs(logs[0]["state"] - R0).max() < 0.01
    assert np.array_equal(logs[0]["state"], logs[1]["state"])  # deterministic, no state shared


def test_ugv_uav_plant_starts_on_its_skids_and_carries_the_identified_model():
    sc = load_scenario("marciano-circle")
    floor = sc.center[2] - sc.floor_below_platform_m
    x0 = np.r_[0.0, 1.0, 0.0, 0.0, 0.4, floor - 0.2, 0.0, 0.0, 0.0, 0.0, 0.0]  # the UAV in the floor
    plant = ugv_uav_plant(sc, x0, floor)
    assert plant.state_columns == UGV_UAV_MEASURED_NAMES and plant.command_columns == UGV_UAV_COMMAND_NAMES
    assert plant.x0[5] == pytest.approx(floor + IRIS.leg_height, abs=1e-3)  # raised onto its skids
    assert np.allclose(plant.x0[0:3], x0[0:3], atol=1e-9) and np.allclose(plant.x0[[3, 4, 6]], x0[[3, 4, 6]], atol=1e-9)
    assert plant.uav_model.k == IRIS_IDENTIFIED_K and plant.uav_model.max_fraction == sc.max_fraction
    times = np.arange(51) * sc.control_period_s
    log = simulate(plant, Constant((0.3, 0.0, 0.0, 0.0, 0.0, 0.0)), lambda k: None, times, plant.x0,
                   dt=sc.dt_s, substeps=round(sc.control_period_s / sc.dt_s))
    x = log["state"]
    # the UGV rolls ahead at 0.3 m/s (its wheels' lag: a few cm short), the UAV stays on the floor
    assert x[-1, 0] == pytest.approx(0.3 * times[-1], abs=0.06) and abs(x[-1, 1] - 1.0) < 0.01
    assert np.abs(x[:, 3:6] - plant.x0[3:6]).max() < 0.01
    rec = physics_record(plant, log)
    assert rec.qpos.shape == (51, plant.world.model.nq) and np.allclose(rec.robots["ugv"][:, 2], sc.center[2])
    assert physics_metrics(plant)["collisions"]["count"] == 0


def test_ugv_uav_plant_under_the_seed_001_controller_through_simulate():
    """The seed 001 controller (on the controller contract) flies the physics plant in the
    one loop: the UAV takes off from the floor towards its place over the UGV, nothing collides."""
    import dataclasses

    from quatform.control import Reference
    from quatform.scenarios.ugv_uav import simulate_ugv_uav

    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=6.0)
    kin = simulate_ugv_uav(sc, "quaternion")  # the kinematic start and reference of this scenario
    floor = sc.center[2] - sc.floor_below_platform_m
    plant = ugv_uav_plant(sc, kin["state"][0], floor)
    ctrl = sc.controller("quaternion", bebop=plant.uav_model)
    n = round(sc.control_period_s / sc.dt_s)
    log = simulate(plant, ctrl, lambda k: Reference(kin["c_des"][k], np.zeros(ctrl.formation.n_c)), kin.t, plant.x0,
                   dt=sc.dt_s, substeps=n)
    x = log["state"]
    assert x.shape == (len(kin.t), 11) and np.all(log["raw_finite"] == 1.0) and np.all(log["frame"] == 0)
    assert x[0, 5] == pytest.approx(floor + IRIS.leg_height, abs=1e-3)
    assert x[-1, 5] > x[0, 5] + 0.5  # it took off (the reference is 1.5 m above the platform)
    assert physics_metrics(plant)["collisions"]["count"] == 0
    assert not log.meta["controller_state"].stopped and log.meta["controller_state"].stop_reason == ""
