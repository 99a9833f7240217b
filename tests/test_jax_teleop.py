"""The teleop kind on the jax compute backend (seed 003's teleoperator): the one loop's JAX
driver (:func:`quatform.sim.loop.simulate_jax`) of the pure ``TeleopController.tick``.

Each built-in teleop scenario with both orientation errors runs on NumPy and on JAX, cut to
a length that keeps its event (the hand's motion, the slave's contact with the wall, the
master in the virtual wall, the preload on the master's dead band, the tools at and through
roll-pitch-yaw pitch -90 deg); every channel of the finished log (:func:`teleop_finish`) and
every metric are compared. Tolerances: angles, positions and quaternions 1e-9 absolute (a
quaternion up to its sign: where ``w`` crosses 0, Shepperd's ``w >= 0`` picks the sign on a
rounding); rates, forces and torques 1e-9 relative to the column's peak (absolute below 1);
metrics 1e-9 relative.

The RPY law at the lock is chaotic on NumPy alone: 1e-15 rad on the master's first joint
changes its state by 2.9 rad (through 90) and 20 rad (held at 90) from t = 1.92 s and
2.41 s on, which no two implementations of its arithmetic can agree past; those two runs
stop before it (the Euler-parameter runs go through the lock).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL

from quatform.errors import InvalidInputError, NonFiniteError
from quatform.scenarios import KINDS, load_scenario
from quatform.sim.plants import KinematicTeam
from quatform.sim.trial_measurement import TickMeasurement
from quatform.teleop.controller import MAX_JOINT_ANGLE

pytest.importorskip("jax")

from quatform.sim.loop import simulate_jax as jax_simulate  # noqa: E402
from quatform.sim.simulate import simulate as numpy_simulate  # noqa: E402

TELEOP = KINDS["teleop"]
ERRORS = ("euler-parameters", "rpy")
#: (scenario, preload, duration_s per orientation error): long enough for the event.
CASES = {
    "teleop-free-motion": (False, {"euler-parameters": 0.8, "rpy": 0.8}),  # the hand moves from 0.3 s
    "teleop-pitch-hold-at-90": (False, {"euler-parameters": 3.1, "rpy": 2.3}),  # at the lock 3.0 s
    "teleop-pitch-through-90": (False, {"euler-parameters": 2.2, "rpy": 1.85}),  # through it at 2.0 s
    "teleop-preload": (True, {"euler-parameters": 1.0, "rpy": 1.0}),  # the push moves the slave from 0.3 s
    "teleop-virtual-wall": (False, {"euler-parameters": 1.6, "rpy": 1.6}),  # the master in the wall from 1.33 s
    "teleop-wall-contact": (False, {"euler-parameters": 1.4, "rpy": 1.4}),  # the slave on the wall from 1.14 s
}
#: Column prefixes of rates, forces and torques (compared relative to the column's peak).
SCALED = ("qd_", "F_", "M_", "tau_", "wall_force")


def _experiment(name, oe, duration_s=None, preload=None):
    pre, durations = CASES[name]
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration_s=durations[oe] if duration_s is None else duration_s)
    return TELEOP.experiment(sc, oe, pre if preload is None else preload)


def _assert_channels_equal(a, b):
    assert set(a.channels) == set(b.channels)
    for ch in a.channels:
        x, y = a[ch], b[ch]
        assert x.shape == y.shape, ch
        if ch in ("r_m", "r_s"):  # q and -q: the same orientation
            y = np.where(np.sum(x * y, axis=-1, keepdims=True) < 0, -y, y)
        cols = a.columns(ch)
        for c, col in enumerate(cols):
            scale = max(1.0, float(np.max(np.abs(x[..., c])))) if col.startswith(SCALED) else 1.0
            np.testing.assert_allclose(y[..., c], x[..., c], rtol=0, atol=TOL * scale, err_msg=f"{ch}.{col}")


def _assert_metrics_equal(m, n, path=""):
    if isinstance(m, dict):
        assert set(m) == set(n), path
        for k in m:
            _assert_metrics_equal(m[k], n[k], f"{path}{k}.")
    elif isinstance(m, (list, tuple)):
        assert len(m) == len(n), path
        for i, (x, y) in enumerate(zip(m, n)):
            _assert_metrics_equal(x, y, f"{path}{i}.")
    elif isinstance(m, float) and not isinstance(n, bool):
        assert math.isclose(m, n, rel_tol=TOL, abs_tol=TOL) or (math.isnan(m) and math.isnan(n)), (path, m, n)
    else:
        assert m == n, path


@pytest.mark.parametrize("oe", ERRORS)
@pytest.mark.parametrize("name", sorted(CASES))
def test_jax_equals_numpy(name, oe):
    exp = _experiment(name, oe)
    a, b = exp.run(backend="numpy"), exp.run(backend="jax")
    _assert_channels_equal(a, b)
    _assert_metrics_equal(exp.metrics(a), exp.metrics(b))
    assert "failed" not in b.meta and b.meta["controller_state"] is None
    # the event the run is cut to keep happened
    if name == "teleop-wall-contact":
        assert np.abs(a["F_s"]).max() > 1.0
    if name == "teleop-virtual-wall":
        assert a["wall_depth"].max() > 0.0 and np.abs(a["wall_force"]).max() > 0.1
    if name == "teleop-preload":
        assert np.ptp(a["p_master"][:, 1]) > 0.005  # the master followed the pushed slave
    if "90" in name and oe == "euler-parameters":  # at / through pitch -90 deg
        R20 = 2.0 * (a["r_s"][:, 1] * a["r_s"][:, 3] - a["r_s"][:, 0] * a["r_s"][:, 2])
        assert np.max(R20) > 0.999


def test_shepperd_selection_on_jax_is_the_float_branch():
    """``q_from_rotation`` on JAX computes all four branches and selects: each of them taken
    (turns of pi about x, y, z take branches 1-3) gives the float path's quaternion."""
    import jax
    import jax.numpy as jnp

    from quatform.algebra import matrix_from_q
    from quatform.teleop.kernels import q_from_rotation

    rng = np.random.default_rng(5)
    q = rng.standard_normal((40, 4))
    q = np.vstack([q / np.linalg.norm(q, axis=1, keepdims=True), np.eye(4), [[0.0, 1.0, 1e-9, 0.0]]])
    R = matrix_from_q(q)
    with jax.enable_x64(True):
        got = np.stack(jax.jit(q_from_rotation)(jnp.asarray(R)), axis=-1)
    want = np.array([q_from_rotation(r) for r in R])
    assert {int(np.argmax(np.abs(w))) for w in want} == {0, 1, 2, 3}
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_batch_equals_each_world_and_a_failed_world_is_frozen():
    exp = _experiment("teleop-wall-contact", "euler-parameters", duration_s=0.3)
    rng = np.random.default_rng(3)
    x0 = np.repeat(exp.x0[None], 3, axis=0)
    x0[:, :26] += 0.02 * rng.standard_normal((3, 26))  # the joints' angles and rates; the wrist sensor at 0
    x0[2, 0] = 2.0 * MAX_JOINT_ANGLE  # a reading no arm makes: the controller refuses it
    raw = dataclasses.replace(exp, finish=lambda log: log)
    batch = jax_simulate(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt)
    for w in range(2):
        one = dataclasses.replace(raw, x0=x0[w])
        _assert_channels_equal(one.run(backend="numpy"), batch.world(w))
    assert batch.meta["failed"].tolist() == [False, False, True]
    assert "t = 0 s: measurement q_m[0] = 2000 rad is beyond" in batch.meta["failure"][(2,)]
    assert np.all(batch["state"][:, 2] == x0[2]) and np.all(batch["command"][:, 2] == 0.0)
    assert np.all(np.isnan(batch["e"][:, 2]))
    on_numpy = numpy_simulate(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt)  # a batch there
    _assert_channels_equal(on_numpy, batch)
    assert on_numpy.meta["failure"] == batch.meta["failure"]
    told = []  # in ten chunks, with progress: the same run
    chunked = jax_simulate(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt, progress=told.append)
    assert told[-1] == 1.0 and len(told) == 10
    _assert_channels_equal(batch, chunked)


def test_one_world_raises_numpys_error():
    exp = _experiment("teleop-free-motion", "euler-parameters", duration_s=0.05)
    x0 = exp.x0.copy()
    x0[7] = np.nan
    with pytest.raises(NonFiniteError, match="measurement qd_m") as numpy_error:
        dataclasses.replace(exp, x0=x0).run(backend="numpy")
    with pytest.raises(NonFiniteError, match="measurement qd_m") as jax_error:
        dataclasses.replace(exp, x0=x0).run(backend="jax")
    assert str(jax_error.value) == str(numpy_error.value)


def test_a_delayed_measurement_runs_on_both_drivers():
    """Any pure measurement model runs on JAX: a TickMeasurement of one tick's latency."""
    exp = _experiment("teleop-free-motion", "euler-parameters", duration_s=0.05)
    x0 = np.stack([exp.x0, exp.x0])
    runs = [sim(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt,
                measurement=TickMeasurement(delay_ticks=1)) for sim in (numpy_simulate, jax_simulate)]
    _assert_channels_equal(*runs)
    np.testing.assert_array_equal(runs[0]["measured"][1], runs[0]["state"][0])


def test_a_plant_that_is_not_batchable_is_refused_in_one_line():
    exp = _experiment("teleop-free-motion", "euler-parameters", duration_s=0.05)
    team = KINDS["team"].experiment(load_scenario("team-three-bodies"), controller="quaternion")

    class OneAtATime(KinematicTeam):
        batchable = False

    with pytest.raises(InvalidInputError, match="runs on numpy") as err:
        jax_simulate(OneAtATime(team.plant.team), exp.controller, exp.reference, exp.times, team.x0, dt=exp.dt)
    assert "\n" not in str(err.value)
