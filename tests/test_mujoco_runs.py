"""Closed loop on physics: seed 000's controllers fly two quadrotors, seed 001's
controller drives a UGV and a quadrotor, collisions are reported, pictures are drawn."""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from quatform.errors import MissingDependencyError
from quatform.sim.mujoco_backend import import_mujoco

try:  # quatform's import first: it picks the offscreen OpenGL before mujoco loads one
    import_mujoco()
except MissingDependencyError:
    pass
mujoco = pytest.importorskip("mujoco")  # the optional extra

from quatform.cli import main
from quatform.robots.bebop import TABLE2_K
from quatform.scenarios.pair import run_pair, scenario_from_dict, simulate_physics
from quatform.scenarios import load_scenario
from quatform.scenarios.ugv_uav import mujoco_experiment, simulate_ugv_uav, ugv_uav_metrics
from quatform.sim import compute_metrics
from quatform.sim.mujoco_backend import (
    IRIS_IDENTIFIED_K,
)


@pytest.fixture(scope="module")
def helix_runs():
    """The seed's helix up to t = 34 s: past the first vertical pose (t = 30 s)."""
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=34.0)
    return {name: simulate_physics(sc, name) for name in ("cluster-space", "quaternion")}


def test_cluster_space_fails_at_the_vertical_pose_on_physics(helix_runs):
    run, rec = helix_runs["cluster-space"]
    m = compute_metrics(run)
    assert m["singularity_detected"] and 29.0 < m["first_singular_time_s"] < 31.0  # seed 000: ~30 s
    assert m["reference_lost"] and m["first_lost_time_s"] < 33.0
    assert rec.collisions["count"] == 0


def test_quaternion_follows_the_helix_on_physics(helix_runs):
    run, rec = helix_runs["quaternion"]
    m = compute_metrics(run)
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=34.0)  # the fixture's
    kin = compute_metrics(run_pair(sc, "quaternion"))
    assert not m["reference_lost"] and not m["singularity_detected"]
    assert m["max_cluster_position_error_m"] < 0.01 and m["max_shape_error_m"] < 0.03
    assert m["max_orientation_error_rad"] < 0.05 and m["max_recovered_euclidean_error_rad"] < 0.05
    # the physics adds lag the kinematic robots do not have
    assert m["max_robot_position_error_m"] > kin["max_robot_position_error_m"]
    assert rec.collisions["count"] == 0
    # the record's poses are the logged robot states
    assert rec.qpos.shape == (len(run.t), 14) and np.allclose(rec.qpos[:, 0:3], run["state"][:, 0:3])


def _pair(extra_path: dict, duration: float, z: float = 1.0) -> object:
    path = {"centroid": "line", "center": [0.0, 0.0, z], "velocity": [0.0, 0.0, 0.0], "beta_c": -1.5707963267948966,
            "d_c": 0.5, **extra_path}
    return scenario_from_dict({"name": "crash", "duration_s": duration, "dt_s": 0.01, "gains": "table1",
                               "path": path})


def test_a_formation_driven_into_the_ground_reports_the_collision():
    sc = _pair({"velocity": [0.0, 0.0, -0.6]}, 3.0)  # 1 m up, sinking at 0.6 m/s
    run, rec = simulate_physics(sc, "quaternion")
    c = rec.collisions
    assert c["count"] >= 2 and 1.0 < c["first_time_s"] < 2.2
    assert {"ground/robot1", "ground/robot2"} <= set(c["bodies"])
    assert run["state"][-1, 2] > -0.01 and run["state"][-1, 6] > -0.01  # the ground holds them up


def test_robots_driven_into_each_other_report_the_collision():
    sc = _pair({"ramps": [{"variable": "d_c", "start_s": 0.5, "duration_s": 1.5, "change": -0.45}]}, 3.0, z=2.0)
    run, rec = simulate_physics(sc, "quaternion")
    c = rec.collisions
    assert c["count"] >= 1 and c["bodies"][0] == "robot1/robot2"
    # the rotor discs (radius 0.127 m, hubs 0.25 m out) meet before the centres are 0.76 m apart
    k = np.searchsorted(run.t, c["first_time_s"])
    assert np.linalg.norm(run["state"][k, 0:3] - run["state"][k, 4:7]) < 0.77


def test_ugv_and_quadrotor_hold_the_formation_with_identified_compensation():
    """Seed 001 §5.1 (circle), shortened: the take-off transient (20 s) and a few seconds
    of the formation; the bounds are the kinematic runs' (UGV 0.1 m, UAV 0.2 m)."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=24.0)
    exp = mujoco_experiment(sc, "quaternion")
    run = exp.run()
    m, rec = exp.metrics(run), run.meta["physics_record"]
    assert m["max_ugv_position_error_m"] < 0.1 and m["max_uav_position_error_m"] < 0.2
    assert not m["reference_lost"] and m["nonfinite_commands"] == 0
    assert rec.collisions["count"] == 0  # taking off from the floor is not a collision
    assert run["state"][-1, 5] > 1.3  # in the air, 1.5 m over the platform
    assert m["uav_model_k"] == list(IRIS_IDENTIFIED_K)  # the physics run compensated with the identified K
    assert ugv_uav_metrics(simulate_ugv_uav(sc))["uav_model_k"] == list(TABLE2_K)  # the kinematic one: Table 2
    # without the compensation (4.47) the quadrotor's 6 s velocity lag (1/K2) loses the formation
    exp_nc = mujoco_experiment(sc, "quaternion", compensation=False)
    m_nc = exp_nc.metrics(exp_nc.run())
    assert m_nc["reference_lost"] and m_nc["max_uav_position_error_m"] > 10 * m["max_uav_position_error_m"]


def test_uav_starts_where_uav_start_says_in_the_ugv_frame():
    """The lemniscate starts with the UGV heading 72 deg: uav_start (0, -0.6) is to its right
    in its own frame (it was added in world axes, inside the UGV), kinematic and physics."""
    sc = dataclasses.replace(load_scenario("marciano-lemniscate"), duration_s=1.0)
    physics = mujoco_experiment(sc).run()
    for run in (simulate_ugv_uav(sc), physics):
        x = run["state"]
        psi = x[0, 2]
        assert abs(psi) > 1.0  # the case that matters: not heading along x
        d = x[0, 3:5] - x[0, 0:2]
        body = [np.cos(psi) * d[0] + np.sin(psi) * d[1], -np.sin(psi) * d[0] + np.cos(psi) * d[1]]
        assert np.allclose(body, sc.uav_start[0:2], atol=0.02)
    assert physics.meta["physics_record"].collisions["count"] == 0


def test_cli_runs_the_physics_and_writes_collisions_and_picture(tmp_path, capsys):
    toml = tmp_path / "short.toml"
    toml.write_text('name = "short"\nduration_s = 2.0\ngains = "table2"\n[path]\ncentroid = "line"\n'
                    'center = [0.0, 0.0, 2.0]\nvelocity = [0.0, 0.1, 0.0]\nd_c = 0.5\nbeta_c = -1.5707963267948966\n')
    out = tmp_path / "run"
    assert main(["run", str(toml), "--physics", "mujoco", "--controller", "dual-quaternion", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["physics"] == "mujoco" and m["collisions"] == {"count": 0, "first_time_s": None, "bodies": []}
    assert m["render"] == "time_lapse.png" and (out / m["render"]).stat().st_size > 10_000
    # a physics run is one run of its plant: no kinematic re-run inside it (compare --over physics)
    assert "kinematic" not in m
    text = capsys.readouterr().out
    assert "| dual-quaternion |" in text and "(kinematic)" not in text and "collisions: 0" in text


def test_compare_over_physics_tables_the_physics(tmp_path, capsys):
    """``compare --over physics``: one row per physics, led by a ``physics`` column (the compute
    backend is another option, ``--compute``)."""
    toml = tmp_path / "short.toml"
    toml.write_text('name = "short"\nduration_s = 0.5\n[path]\ncentroid = "line"\ncenter = [0.0, 0.0, 2.0]\n')
    out = tmp_path / "cmp"
    assert main(["compare", str(toml), "--over", "physics", "--controller", "quaternion", "--out", str(out),
                 "--no-plots", "--no-mcap"]) == 0
    rows = json.loads((out / "comparison.json").read_text())
    assert [r["physics"] for r in rows] == ["kinematic", "mujoco"] and all("backend" not in r for r in rows)
    assert (out / "comparison.md").read_text().count("| physics | controller |") == 1
    assert "| physics | controller |" in capsys.readouterr().out


def test_picture_falls_back_to_matplotlib_without_offscreen_gl(tmp_path):
    """MUJOCO_GL=disable: the physics runs, the picture is matplotlib's and says why."""
    import subprocess
    import sys

    toml = tmp_path / "short.toml"
    toml.write_text('name = "short"\nduration_s = 1.0\n[path]\ncentroid = "line"\ncenter = [0.0, 0.0, 2.0]\n')
    out = tmp_path / "run"
    env = dict(os.environ, MUJOCO_GL="disable")
    code = ("import sys; from quatform.cli import main; sys.exit(main(['run', sys.argv[1], '--physics', "
            "'mujoco', '--controller', 'quaternion', '--out', sys.argv[2]]))")
    res = subprocess.run([sys.executable, "-c", code, str(toml), str(out)], env=env, capture_output=True,
                         text=True, check=False, timeout=120)
    assert res.returncode == 0, res.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["render"] == "time_lapse.png" and (out / "time_lapse.png").stat().st_size > 10_000
    assert m["render_backend"].startswith("matplotlib (MUJOCO_GL=disable")


def test_time_lapse_renders_offscreen(tmp_path):
    """Where an offscreen OpenGL context can be made, the picture is MuJoCo's, not the
    fallback's (skipped only where the context itself cannot be made)."""
    from matplotlib.image import imread

    from quatform.report.physics_render import render_or_fallback

    try:
        ctx = mujoco.GLContext(64, 64)
        ctx.make_current()
        ctx.free()
    except Exception as exc:  # noqa: BLE001 - whichever way the OpenGL of this machine fails
        pytest.skip(f"no offscreen OpenGL context here (MUJOCO_GL={os.environ.get('MUJOCO_GL')}: "
                    f"{type(exc).__name__}: {exc})")
    sc = _pair({"velocity": [0.0, 0.3, 0.0]}, 1.0, z=2.0)
    run, rec = simulate_physics(sc, "dual-quaternion")
    path, how = render_or_fallback(rec, None, tmp_path / "t.png", n_snapshots=3, width=320, height=240)
    assert how == "mujoco"
    img = imread(path)
    assert img.shape[:2] == (240, 320)
    assert img[..., :3].std() > 0.02  # a scene, not a blank frame
