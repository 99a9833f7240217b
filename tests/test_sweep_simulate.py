"""Per-world failure marking of a batched run (sim.simulate, the contract of sim.backends)."""

import dataclasses

import numpy as np
import pytest

from quatform.errors import InvalidInputError
from quatform.scenarios import KINDS, load_scenario


@pytest.fixture(scope="module")
def helix():
    return dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=3.0, metrics_from_s=1.0)


def _batch(exp, x0):
    return dataclasses.replace(exp, x0=x0, finish=lambda log: log).run()


@pytest.mark.parametrize("controller", ["cluster-space", "quaternion"])
def test_failing_worlds_are_marked_and_the_rest_go_on(helix, controller):
    exp = KINDS["team"].experiment(helix, controller=controller)
    x0 = np.repeat(exp.x0[None], 4, axis=0)
    x0[1, 4:7] = x0[1, 0:3]  # robots on top of each other
    x0[2, 0] = np.nan  # a non-finite start
    x0[3, 1] += 0.05  # a healthy world off the reference
    log = _batch(exp, x0)
    failed = np.asarray(log.meta["failed"])
    assert failed.tolist() == [False, True, True, False]
    assert set(log.meta["failure"]) == {(1,), (2,)}
    assert "coincide" in log.meta["failure"][(1,)]
    assert "nan" in log.meta["failure"][(2,)]
    # the healthy worlds equal their own single-world runs
    for i in (0, 3):
        one = dataclasses.replace(exp, x0=x0[i]).run()
        assert np.allclose(log["state"][:, i], one["state"], rtol=0, atol=1e-12)
        assert np.allclose(log["command"][:, i], one["command"], rtol=0, atol=1e-12)
    # a failed world is frozen with zero commands
    assert np.all(log["command"][:, 1] == 0.0)
    assert np.all(log["state"][:, 1] == log["state"][0, 1])


def test_non_finite_plant_state_is_caught(helix):
    exp = KINDS["team"].experiment(helix, controller="robot-space")

    class Blowup:
        """The kinematic plant, except world 1 goes to infinity at the 5th step."""

        def __init__(self, inner):
            self.inner, self.k = inner, 0
            self.state_columns, self.output_columns, self.batchable = (inner.state_columns, inner.output_columns,
                                                                       True)

        def output(self, x):
            return self.inner.output(x)

        def step(self, x, u, dt, t):
            self.k += 1
            x = self.inner.step(x, u, dt, t)
            if self.k == 5:
                x = x.copy()
                x[1, 0] = np.inf
            return x

    x0 = np.repeat(exp.x0[None], 3, axis=0)
    log = dataclasses.replace(exp, plant=Blowup(exp.plant), x0=x0, finish=lambda log: log).run()
    assert np.asarray(log.meta["failed"]).tolist() == [False, True, False]
    assert "non-finite plant state" in log.meta["failure"][(1,)]
    assert np.all(np.isfinite(log["state"]))
    assert np.allclose(log["state"][:, 0], log["state"][:, 2], rtol=0, atol=0)


def test_all_worlds_failing_still_returns_a_log(helix):
    exp = KINDS["team"].experiment(helix, controller="quaternion")
    x0 = np.repeat(exp.x0[None], 2, axis=0)
    x0[:, 4:7] = x0[:, 0:3]
    log = _batch(exp, x0)
    assert np.asarray(log.meta["failed"]).all()
    assert log["state"].shape[:2] == (len(exp.times), 2)


def test_one_world_still_raises(helix):
    exp = KINDS["team"].experiment(helix, controller="quaternion")
    x0 = exp.x0.copy()
    x0[4:7] = x0[0:3]
    with pytest.raises(InvalidInputError, match="coincide"):
        dataclasses.replace(exp, x0=x0).run()


def test_a_clean_batch_has_no_failure_keys(helix):
    exp = KINDS["team"].experiment(helix, controller="dual-quaternion")
    log = _batch(exp, np.repeat(exp.x0[None], 2, axis=0))
    assert "failed" not in log.meta and "failure" not in log.meta


@pytest.mark.parametrize("controller", ["cluster-space", "quaternion", "dual-quaternion"])
def test_finish_reads_a_failed_world_as_nan(helix, controller):
    """Seed 000's chart's finish on a batch with a failed world (robots on each other; robot
    space has no formation to lose, so its robots go on): its chart and singularity measure
    NaN from its failure on, the healthy world's as its own run."""
    exp = KINDS["team"].experiment(helix, controller=controller)
    x0 = np.repeat(exp.x0[None], 2, axis=0)
    x0[1, 4:7] = x0[1, 0:3]
    log = dataclasses.replace(exp, x0=x0).run()
    assert np.all(np.isnan(log["singularity"][:, 1])) and np.all(np.isnan(log["e"][:, 1]))
    one = exp.run()
    assert np.allclose(log["singularity"][:, 0], one["singularity"], rtol=0, atol=1e-12)
    assert np.allclose(log["e"][:, 0], one["e"], rtol=0, atol=1e-12)
