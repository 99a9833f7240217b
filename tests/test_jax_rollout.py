"""Batches on the jax backend: TickMeasurement, failed worlds, progress,
and the reduced rollout of a Monte Carlo (:func:`quatform.sim.jax_rollout.rollout_metrics`),
each equal to NumPy within 1e-9.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from conftest import BACKEND_TOL as TOL  # noqa: E402
from conftest import assert_logs_equal, short_scenario  # noqa: E402

from quatform.errors import InvalidInputError, ShapeError
from quatform.scenarios.pair import PAIR
from quatform.sim.backends import simulator
from quatform.sim.jax_rollout import ROLLOUT_METRICS, rollout_metrics
from quatform.sim.metrics import compute_metrics
from quatform.sim.trial_measurement import TickMeasurement

CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_batch_with_tick_measurement_equals_numpy(controller):
    """Three worlds from offset starts, with noise, two ticks of latency and dropped frames."""
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.5), controller=controller)
    T = ex.times.size
    rng = np.random.default_rng(7)
    x0 = ex.x0 + rng.normal(0.0, 0.2, (3, 8))
    meas = TickMeasurement(rng.normal(0.0, 0.01, (T, 3, 8)), 2, rng.random((T, 3)) < 0.2)
    ex = dataclasses.replace(ex, x0=x0, measurement=meas)
    a, b = ex.run(backend="numpy"), ex.run(backend="jax")
    assert_logs_equal(a, b)
    assert "failed" not in b.meta



def test_batch_axes_kept_and_no_feedforward():
    ex = PAIR.experiment(short_scenario("mas-kitts-helix", 0.3), controller="quaternion", feedforward=False)
    x0 = np.broadcast_to(ex.x0, (2, 2, 8)) + np.arange(4.0).reshape(2, 2, 1) * 0.05
    ex = dataclasses.replace(ex, x0=x0)
    a, b = ex.run(backend="numpy"), ex.run(backend="jax")
    assert b["state"].shape == (ex.times.size, 2, 2, 8)
    assert_logs_equal(a, b)



def test_progress_in_tenths_and_same_log():
    ex = PAIR.experiment(short_scenario("mas-kitts-yaw-step", 0.33), controller="dual-quaternion")
    seen = []
    log = ex.run(progress=seen.append, backend="jax")
    T = ex.times.size
    assert len(seen) == -(-T // -(-T // 10))  # chunks of ceil(T / 10) ticks
    assert seen[-1] == pytest.approx(1.0) and np.all(np.diff(seen) > 0)
    assert_logs_equal(ex.run(backend="numpy"), log)



def test_coincident_robots_fail_that_world_only():
    """NumPy refuses robots on each other; the compiled loop marks that world and goes on."""
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.2), controller="quaternion")
    x0 = np.stack([ex.x0, ex.x0])
    x0[1, 4:7] = x0[1, 0:3]  # robot 2 on robot 1
    # the loop itself (Experiment.finish reads every world's cluster state: a sweep masks failed ones)
    log = simulator("jax")(ex.plant, ex.controller, ex.reference, ex.times, x0, dt=ex.dt)
    assert log.meta["failed"].tolist() == [False, True]
    assert set(log.meta["failure"]) == {(1,)} and "coincide" in log.meta["failure"][(1,)]
    good = simulator("numpy")(ex.plant, ex.controller, ex.reference, ex.times, x0[:1], dt=ex.dt)
    np.testing.assert_allclose(log["state"][:, :1], good["state"], atol=TOL)
    np.testing.assert_array_equal(log["state"][:, 1], np.broadcast_to(x0[1], log["state"][:, 1].shape))
    assert np.all(log["command"][:, 1] == 0.0) and np.all(np.isnan(log["cluster"][:, 1]))



def test_one_world_failure_raises_like_numpy():
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.2), controller="dual-quaternion")
    x0 = ex.x0.copy()
    x0[4:7] = x0[0:3]
    with pytest.raises(InvalidInputError, match="coincide"):
        dataclasses.replace(ex, x0=x0).run(backend="jax")



@pytest.mark.parametrize("controller", ["quaternion", "robot-space"])
def test_rollout_metrics_equal_compute_metrics(controller):
    """The reduced rollout's metrics equal compute_metrics of each world of a logged NumPy batch."""
    ex = PAIR.experiment(short_scenario("mas-kitts-helix", 0.8), controller=controller)
    ex = dataclasses.replace(ex, meta={**ex.meta, "metrics_from_s": 0.3})
    T = ex.times.size
    rng = np.random.default_rng(3)
    x0 = ex.x0 + rng.normal(0.0, 0.08, (5, 8))
    meas = TickMeasurement(rng.normal(0.0, 0.004, (T, 5, 8)), 1, rng.random((T, 5)) < 0.05)
    res = rollout_metrics(ex, x0, meas, trials_per_call=2)  # chunks of 2, the last one padded
    log = PAIR.experiment(dataclasses.replace(short_scenario("mas-kitts-helix", 0.8), metrics_from_s=0.3),
                          controller=controller)
    log = dataclasses.replace(log, x0=x0, measurement=meas).run(backend="numpy")
    for i in range(5):
        want = compute_metrics(log.world(i))
        for key in ROLLOUT_METRICS:
            got, exp = res[key][i], want[key]
            if exp is None:
                assert np.isnan(got), key
            elif isinstance(exp, bool):
                assert bool(got) == exp, key
            else:
                assert float(got) == pytest.approx(float(exp), abs=TOL), key
    assert not res["failed"].any() and res["failure"] == {}


def test_short_tick_measurement_refused_in_one_line():
    ex = PAIR.experiment(short_scenario("mas-kitts-spiral", 0.2), controller="quaternion")
    meas = TickMeasurement(np.zeros((3, 8)), 0)  # 3 ticks of noise for a run of 21
    with pytest.raises(ShapeError, match="fewer than the run's 21 ticks"):
        dataclasses.replace(ex, measurement=meas).run(backend="jax")


@pytest.mark.parametrize("bad", [0, -1, 0.5, 2.5, "3", True, float("nan"), float("inf")])
def test_trials_per_call_must_be_a_whole_number(bad):
    ex = PAIR.experiment(short_scenario("mas-kitts-helix", 0.05), controller="quaternion")
    with pytest.raises(InvalidInputError, match="trials_per_call"):
        rollout_metrics(ex, np.broadcast_to(ex.x0, (2, 8)), trials_per_call=bad)


def test_an_empty_batch_is_refused_in_one_line():
    ex = PAIR.experiment(short_scenario("mas-kitts-helix", 0.05), controller="quaternion")
    with pytest.raises(ShapeError, match="at least one world"):
        rollout_metrics(ex, np.zeros((0, 8)))
    with pytest.raises(ShapeError, match="holds no world"):
        dataclasses.replace(ex, x0=np.zeros((0, 8))).run(backend="jax")


def test_failure_reasons_are_numpys_and_a_nan_start_fails_alone():
    """A world starting with NaN and one with its robots on each other fail with NumPy's own
    reasons; robot space (defined with robots on each other) goes on as on NumPy."""
    for controller in ("quaternion", "robot-space"):
        ex = PAIR.experiment(short_scenario("mas-kitts-helix", 0.1), controller=controller)
        x0 = np.repeat(ex.x0[None], 3, axis=0)
        x0[1, 0] = np.nan
        x0[2, 4:7] = x0[2, 0:3]
        ex = dataclasses.replace(ex, x0=x0, finish=lambda log: log)
        a, b = ex.run(backend="numpy"), ex.run(backend="jax")
        assert np.array_equal(a.meta["failed"], b.meta["failed"])
        assert a.meta["failure"] == b.meta["failure"]
        assert b.meta["failed"].tolist() == [False, True, controller != "robot-space"]
