"""The one loop (:mod:`quatform.sim.loop`): one tick, two drivers.

A toy pure controller with a state (a running sum) and a failure code, and a toy pure plant
with an exogenous input, run on the NumPy and the JAX drivers: the same channels, the same
frozen world (plant and controller state held from its failing tick, commands zero, signals
NaN) and the same one-line message (``update`` rerun on that world at its failing tick).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from quatform.algebra.kernels import common_namespace
from quatform.control.contract import Controller, Step, Tick
from quatform.errors import InvalidInputError
from quatform.sim.loop import make_tick, simulate_numpy
from quatform.sim.measurement import PerfectMeasurement
from quatform.sim.trial_measurement import TickMeasurement

LIMIT = 5.0


class Summing(Controller):
    """``u = r - m``; its state sums what it measured; it refuses ``|m| > LIMIT``."""

    name = "summing"
    command_names = ("u",)
    pure = True
    failure_reasons = {1: "the measurement is beyond the limit"}

    def signal_columns(self):
        return {"sum": ("sum",), "over": ("over",)}

    def init(self, batch=()):
        return {"sum": np.zeros(tuple(batch) + (1,))}

    def reference_arrays(self, reference):
        return {"r": np.asarray(reference, dtype=float)}

    def tick(self, state, measured, reference, t):
        xp = common_namespace(measured, state["sum"])
        total = state["sum"] + measured
        over = xp.abs(measured[..., 0]) > LIMIT
        return Tick({"sum": total}, reference["r"] - measured, {"sum": total, "over": over[..., None]},
                    xp.where(over, 1, 0))

    def update(self, t, measured, reference, state):
        m = np.asarray(measured, dtype=float)
        if np.any(np.abs(m) > LIMIT):
            raise InvalidInputError(f"summing controller: measured {m[0]:g} is beyond +-{LIMIT:g}")
        out = self.tick(state, m, self.reference_arrays(reference), t)
        return Step(out.u, out.state, out.signals)


class Pushed:
    """``x' = u + push(t)``, one state; the push is an exogenous input."""

    state_columns = output_columns = ("x",)
    batchable = True

    def output(self, x):
        return x

    def inputs(self, times, dt, substeps):
        t = np.asarray(times)[:, None] + dt * np.arange(substeps)[None, :]
        return {"push": (0.5 * np.sin(t))[..., None]}

    def step(self, x, u, dt, t, w=None):
        push = 0.5 * np.sin(t) if w is None else w["push"]
        return x + dt * (u + push)


TIMES = np.arange(40) * 0.2
X0 = np.array([[0.0], [1.0], [2.0]])


def reference(k):  # world 2 is driven past the limit
    return np.array([[1.0], [-2.0], [9.0]])


def test_numpy_and_jax_drivers_agree_and_freeze_a_failed_world():
    pytest.importorskip("jax")
    from quatform.sim.loop import simulate_jax

    ctrl, plant = Summing(), Pushed()
    a = simulate_numpy(plant, ctrl, reference, TIMES, X0, substeps=2, measurement=TickMeasurement(delay_ticks=1))
    b = simulate_jax(plant, ctrl, reference, TIMES, X0, substeps=2, measurement=TickMeasurement(delay_ticks=1))
    for name in a.channels:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-12, atol=1e-12, err_msg=name)
    assert a.meta["failed"].tolist() == [False, False, True] == b.meta["failed"].tolist()
    assert a.meta["failure"] == b.meta["failure"]
    (message,) = a.meta["failure"].values()
    assert message.startswith("t = ") and "summing controller: measured" in message and "\n" not in message
    k = int(np.argmax(np.isnan(a["sum"][:, 2, 0])))  # the failing tick
    assert np.all(a["state"][k + 1:, 2] == a["state"][k + 1, 2]) and np.all(a["command"][k:, 2] == 0.0)
    held = a.meta["controller_state"]["sum"][2]  # the state held from the failing tick
    np.testing.assert_allclose(held, a["sum"][k - 1, 2])
    np.testing.assert_allclose(b.meta["controller_state"]["sum"], a.meta["controller_state"]["sum"])


def test_one_world_raises_updates_error():
    with pytest.raises(InvalidInputError, match="summing controller: measured"):
        simulate_numpy(Pushed(), Summing(), lambda k: np.array([9.0]), TIMES, np.array([2.0]))


def test_the_numpy_driver_is_its_tick_iterated():
    ctrl, plant, meas = Summing(), Pushed(), PerfectMeasurement()
    two = (lambda k: reference(k)[:2])  # noqa: E731
    log = simulate_numpy(plant, ctrl, two, TIMES[:5], X0[:2], measurement=meas)
    tick = make_tick(plant, ctrl, meas, 0.2, 1)
    w = plant.inputs(TIMES[:5], 0.2, 1)
    carry = (X0[:2], ctrl.init((2,)), meas.init(X0[:2], (2,)), np.full(2, -1), np.zeros(2, dtype=np.int64))
    for k in range(5):
        carry, y = tick(carry, {"k": k, "t": float(TIMES[k]), "ref": ctrl.reference_arrays(two(k)),
                                "meas": {}, "plant": {"push": w["push"][k]}})
        np.testing.assert_array_equal(y[0], log["state"][k])
        np.testing.assert_array_equal(y[2], log["command"][k])


@pytest.mark.parametrize("backend", ["numpy", "jax"])
def test_a_world_that_starts_not_finite_fails_at_the_start_alone(backend):
    """Guards against: a batch world whose x0 holds a NaN reaching a plant that refuses it (the
    whole NumPy batch lost) or failing a step later with a reason that names neither."""
    if backend == "jax":
        pytest.importorskip("jax")
    from quatform.scenarios import KINDS, load_scenario
    from quatform.sim.backends import simulator

    exp = KINDS["ugv-uav"].experiment(dataclasses.replace(load_scenario("marciano-circle"), duration_s=0.5),
                                      formation="quaternion")
    x0 = np.stack([exp.x0, exp.x0])
    x0[1, 0] = np.nan
    log = simulator(backend)(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt,
                             substeps=exp.substeps, measurement=exp.measurement)
    assert log.meta["failed"].tolist() == [False, True]
    assert log.meta["failure"][(1,)].startswith("t = 0 s: the initial state holds a nan")
    assert np.all(np.isfinite(log["command"])) and np.all(log["command"][:, 1] == 0.0)
