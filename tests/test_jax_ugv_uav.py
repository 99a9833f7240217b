"""The ugv-uav kind (seed 001 §5) on the JAX backend equals NumPy within 1e-9."""

import dataclasses
import math

import numpy as np
import pytest

from quatform.scenarios import load_scenario
from quatform.scenarios.ugv_uav import UGV_UAV_FORMATIONS, ugv_uav_experiment, with_profile

jax = pytest.importorskip("jax")

#: Short runs of the three built-in scenarios; front-to-over switches from in front to over at 4 s.
SHORT = {
    "marciano-circle": dict(duration_s=5.0),
    "marciano-lemniscate": dict(duration_s=5.0),
    "marciano-front-to-over": dict(duration_s=8.0, uav_front_until_s=4.0, transient_s=1.0, switch_transient_s=1.0),
}
#: A lossy lab: noise on positions and orientations, latency, lost and glitched frames.
FAULTS = dict(duration_s=6.0, mocap_noise_m=0.003, mocap_noise_rad=0.01, mocap_latency_s=0.013,
              mocap_dropout_rate=0.5, mocap_glitch_rate=0.2, transient_s=1.0)


def assert_equal_runs(exp):
    """NumPy's and JAX's finished logs: every channel within 1e-9 (NaN where NaN), the
    controller's final state and the metrics equal; returns NumPy's log."""
    a, b = exp.run(), exp.run(backend="jax")
    assert list(a.channels) == list(b.channels) and len(a.channels) == 26
    for name in a.channels:
        x, y = np.asarray(a[name], dtype=float), np.asarray(b[name], dtype=float)
        assert x.shape == y.shape, name
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(y, x, rtol=0, atol=1e-9, equal_nan=True, err_msg=name)
        assert a.columns(name) == b.columns(name)
    sa, sb = a.meta["controller_state"], b.meta["controller_state"]
    assert (bool(sa.stopped), sa.stop_reason, bool(np.isnan(sa.good_t)), bool(np.isnan(sa.bad_since))) == \
        (bool(sb.stopped), sb.stop_reason, bool(np.isnan(sb.good_t)), bool(np.isnan(sb.bad_since)))
    np.testing.assert_allclose(sb.memory[1].v_dot, sa.memory[1].v_dot, rtol=0, atol=1e-9)
    assert a.meta["stop_reason"] == b.meta["stop_reason"] and a.meta["stopped_at"] == b.meta["stopped_at"]
    ma, mb = exp.metrics(a), exp.metrics(b)
    assert ma.keys() == mb.keys()
    for k, v in ma.items():
        if isinstance(v, float) and not (isinstance(mb[k], float) and math.isnan(v) and math.isnan(mb[k])):
            assert mb[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
        elif not isinstance(v, float):
            assert mb[k] == v, k
    return a


@pytest.mark.parametrize("formation", list(UGV_UAV_FORMATIONS))
@pytest.mark.parametrize("name", list(SHORT))
def test_builtin_scenarios_equal_numpy(name, formation):
    sc = dataclasses.replace(load_scenario(name), **SHORT[name])
    log = assert_equal_runs(ugv_uav_experiment(sc, formation))
    if name == "marciano-front-to-over" and formation == "restricted":
        # in front at platform level the restricted description holds (brakes): both branches ran
        reach = log["reachable"][:, 0]
        assert 0 < reach.sum() < reach.size


@pytest.mark.parametrize("formation", ["quaternion", "spherical"])
def test_the_lab_profile_equals_numpy(formation):
    """The lab's world (motion-capture rate, latency, noise; the Pioneer's acceleration limits,
    two more state columns) runs the same on JAX."""
    sc = with_profile(dataclasses.replace(load_scenario("marciano-circle"), **SHORT["marciano-circle"]), "lab")
    log = assert_equal_runs(ugv_uav_experiment(sc, formation))
    assert log["state"].shape[1] == 13 and np.any(log["state"][1:, 11] != log["command"][:-1, 0])  # ramping


@pytest.mark.parametrize("formation", ["quaternion", "restricted"])
def test_faulty_motion_capture_equals_numpy(formation):
    """Noise, latency, dropped and glitched frames: the screen rejects, holds and finally stops."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), **FAULTS)
    log = assert_equal_runs(ugv_uav_experiment(sc, formation, max_hold_s=0.1))
    frames = np.bincount(log["frame"][:, 0].astype(int), minlength=3)
    assert np.all(frames > 0)  # good, dropped and rejected frames
    assert log["held"].sum() > 0
    assert log["stopped"][-1, 0] == 1.0 and log.meta["stop_reason"].startswith("motion capture")


def test_schedule_replays_the_streams():
    """MotionCapture.schedule draws a frame's draws from the world's own streams (world i:
    seed + i; a batch of one world reads what one world reads)."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), **FAULTS)
    exp = ugv_uav_experiment(sc, "quaternion")
    mocap = exp.measurement
    s = mocap.schedule(exp.times[:20], exp.dt, exp.substeps)
    assert s["new"][0] and s["turns"].shape == (20, 2, 4)
    noise, turns, lost, glitched = mocap._draw(*mocap._streams(mocap.seed))
    np.testing.assert_array_equal(noise, s["noise"][0])
    np.testing.assert_array_equal(turns, s["turns"][0])
    assert (lost, glitched) == (s["lost"][0], s["glitched"][0])
    b = mocap.schedule(exp.times[:20], exp.dt, exp.substeps, (1, 2))
    for key, v in s.items():
        np.testing.assert_array_equal(b[key][:, 0, 0], v, err_msg=key)
    assert not np.array_equal(b["noise"][:, 0, 1], s["noise"])
    np.testing.assert_array_equal(b["noise"][:, 0, 1][s["new"]][0],
                                  mocap._draw(*mocap._streams(mocap.seed + 1))[0])


def test_progress_chunks_change_nothing():
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=1.0)
    exp = ugv_uav_experiment(sc, "quaternion")
    told = []
    a, b = exp.run(backend="jax"), exp.run(told.append, backend="jax")
    assert told[-1] == 1.0 and told == sorted(told) and 5 <= len(told) <= 10
    for name in a.channels:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_a_batch_equals_its_worlds_run_alone():
    """A batch of worlds (own starts; world i reads the motion capture's streams of seed + i)
    on JAX: each world's finished channels and metrics equal that world's run alone (the
    scenario's seed + i, its start) within 1e-9."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), **FAULTS, seed=3)
    exp = ugv_uav_experiment(sc, "quaternion")
    x0 = np.stack([exp.x0, exp.x0 + np.r_[0.05, -0.05, 0.1, np.zeros(8)]])
    batch = dataclasses.replace(exp, x0=x0).run(backend="jax")
    assert batch["r_true"].shape == (len(batch.t), 2, 6) and batch.meta["stopped_at"].shape == (2,)
    for b in range(2):
        one = dataclasses.replace(ugv_uav_experiment(dataclasses.replace(sc, seed=3 + b), "quaternion"), x0=x0[b])
        alone, world = one.run(backend="jax"), batch.world(b)
        for name in alone.channels:
            np.testing.assert_allclose(np.asarray(world[name], float), np.asarray(alone[name], float), rtol=0,
                                       atol=1e-9, equal_nan=True, err_msg=name)
        ma, mb = one.metrics(alone), exp.metrics(world)
        assert ma.keys() == mb.keys()
        for k, v in ma.items():
            if isinstance(v, float):
                assert mb[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
            else:
                assert mb[k] == v, k


def test_without_a_motion_capture_the_outputs_are_read_exactly():
    """measurement=None: the controller reads the plant's outputs as they are, on both drivers."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=1.0)
    exp = dataclasses.replace(ugv_uav_experiment(sc, "quaternion"), measurement=None)
    a, b = exp.run(), exp.run(backend="jax")
    np.testing.assert_array_equal(a["measured"], a["state"][:, :11])
    for name in a.channels:
        np.testing.assert_allclose(np.asarray(b[name], float), np.asarray(a[name], float), rtol=0, atol=1e-9,
                                   equal_nan=True, err_msg=name)
