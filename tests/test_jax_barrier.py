"""The separation barrier's programme solved on JAX (:mod:`quatform.control.barrier`).

Team runs whose barrier binds tick after tick (robots that start in each other's slots and
cross) give NumPy's channels within 1e-9 on JAX, no world rerun on NumPy; a world whose
binding set is larger than the fixed candidate count falls back to NumPy's run and still
equals it; the kernel's commands equal :meth:`SeparationBarrier.filter`'s on random close
configurations of 2 to 6 robots (hypothesis).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL
from conftest import assert_logs_equal, short_scenario
from hypothesis import given, settings, strategies as st

from quatform.control.safety import SeparationBarrier
from quatform.robots import HolonomicRobot, PlanarHolonomicRobot, Team
from quatform.scenarios import KINDS
from quatform.sim.trial_measurement import TickMeasurement

SAFETY = ("min_separation", "safety_active")


def _crossing(scenario, controller, duration_s, cycles=(2, 2, 2, 2), seed=3):
    """``scenario`` as a batch of worlds, world ``w`` with robots ``1 ... cycles[w]`` started
    each in the next one's slot (moved by 2 cm), so their ways home cross: its barrier binds;
    noise and one tick of latency."""
    exp = KINDS["team"].experiment(short_scenario(scenario, duration_s), controller=controller)
    slots = exp.controller.team.state_slices
    B, T = len(cycles), len(exp.times)
    x0 = np.repeat(exp.x0[None], B, axis=0)
    for w, cycle in enumerate(cycles):
        for k in range(cycle):
            x0[w, slots[k]] = exp.x0[slots[(k + 1) % cycle]]
    rng = np.random.default_rng(seed)
    x0 = x0 + 0.02 * rng.standard_normal(x0.shape)
    noise = 0.002 * rng.standard_normal((T, B, x0.shape[-1]))
    return dataclasses.replace(exp, x0=x0, measurement=TickMeasurement(noise, 1), finish=lambda log: log)


def _assert_equal(a, b):
    assert_logs_equal(a, b)
    for key in SAFETY:
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)


@pytest.mark.parametrize("scenario, controller", [("team-three-bodies", "robot-space"),
                                                  ("team-ring-flip", "quaternion")])
def test_binding_runs_equal_numpy_without_reruns(scenario, controller):
    pytest.importorskip("jax")
    run = _crossing(scenario, controller, 1.2 if scenario == "team-three-bodies" else 2.0)
    a, b = run.run(backend="numpy"), run.run(backend="jax")
    active = a["safety_active"][..., 0]
    assert np.all(np.sum(active, axis=0) >= 5), np.sum(active, axis=0)  # every world binds, tick after tick
    assert "numpy_worlds" not in b.meta and "failed" not in b.meta  # every world solved on JAX
    _assert_equal(a, b)


def test_more_binding_pairs_than_candidates_fall_back_to_numpy(monkeypatch):
    pytest.importorskip("jax")
    from quatform.control import barrier as jax_barrier
    from quatform.sim import jax_loop

    monkeypatch.setattr(jax_barrier, "CANDIDATES", 1)  # one candidate: a world where two pairs bind is NumPy's
    run = _crossing("team-ring-flip", "quaternion", 2.0, cycles=(2, 3, 0))  # one pair, three pairs, none
    a, b = run.run(backend="numpy"), run.run(backend="jax")
    assert np.sum(a["safety_active"][..., 0], axis=0).tolist()[2] == 0
    assert b.meta["numpy_worlds"].tolist() == [False, True, False]
    _assert_equal(a, b)
    key = jax_loop.config_key(run.plant, run.controller)
    monkeypatch.undo()
    assert jax_loop.config_key(run.plant, run.controller) != key  # a compiled tick of K = 1 is not reused


# -- the kernel against SeparationBarrier.filter ------------------------------------------------------

TEAMS = {"two 4-DOF": (HolonomicRobot(), HolonomicRobot()),
         "four mixed": (HolonomicRobot(), PlanarHolonomicRobot(), HolonomicRobot(), PlanarHolonomicRobot()),
         "six planar": (PlanarHolonomicRobot(),) * 6}
_KERNELS = {}


def _kernel(name, barrier):
    import jax
    import jax.numpy as jnp

    from quatform.control.barrier import barrier_filter

    key = (name, barrier)
    if key not in _KERNELS:
        team = Team(TEAMS[name])
        _KERNELS[key] = team, jax.jit(lambda m, u: barrier_filter(barrier, team, m, u, jnp.ones(m.shape[0], dtype=bool)))
    return _KERNELS[key]


@pytest.mark.parametrize("name", list(TEAMS))
@pytest.mark.parametrize("range_m", [None, 0.8])
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_kernel_equals_the_exact_programme(name, range_m, seed):
    jax = pytest.importorskip("jax")
    barrier = SeparationBarrier(0.3, gamma=5.0, range_m=range_m)
    team, kernel = _kernel(name, barrier)
    rng = np.random.default_rng(seed)
    B = 4
    x = np.empty((B, team.n_state))
    for w in range(B):  # robots within 1.2 m of each other, at least the barrier's 0.3 m apart
        while True:
            p = rng.uniform(-0.6, 0.6, (len(team.robots), 3))
            p[:, 2] = np.where([isinstance(r, PlanarHolonomicRobot) for r in team.robots], 0.0, p[:, 2])
            d = np.linalg.norm(p[:, None] - p[None], axis=-1) + 9.0 * np.eye(len(p))
            if d.min() >= 0.31:
                break
        x[w] = np.concatenate([np.append(pk[:2 if isinstance(r, PlanarHolonomicRobot) else 3], rng.uniform(-3, 3))
                               for pk, r in zip(p, team.robots)])
    u = team.saturate(rng.uniform(-2.0, 2.0, (B, team.n)))
    expected, info = barrier.filter(team, x, u)
    with jax.enable_x64(True):
        got, sep, active, solved = (np.asarray(v) for v in kernel(x, u))
    assert np.all(solved)
    np.testing.assert_array_equal(active, info.active)
    np.testing.assert_allclose(got, expected, rtol=0, atol=TOL)
    np.testing.assert_array_equal(got[~active], u[~active])  # no pair binds: the commands bitwise
    np.testing.assert_allclose(sep.min(axis=-1), info.min_separation, rtol=0, atol=1e-12)


def test_a_start_at_the_minimum_to_rounding_is_kept_on_jax_as_on_numpy():
    """A barrier's minimum a few ulps above the robots' start separation (the pair's
    ``d = 2 d_c`` built by trigonometry reads 3.7699999999999996 against 3.77): NumPy's
    SafeController keeps the start (:func:`~quatform.control.safety.start_floor`), and the
    compiled tick reads the same floor, so no world is rerun on NumPy."""
    pytest.importorskip("jax")
    from quatform.control.safety import start_floor

    exp = KINDS["team"].experiment(short_scenario("team-ring-flip", 0.3), controller="quaternion")
    C = exp.controller
    P = C.team.layout.positions(C.team.point(exp.x0))
    sep = C.team.layout.separations(C.team.point(exp.x0)).min()
    d = np.nextafter(np.nextafter(sep, np.inf), np.inf)  # two ulps above the start
    assert sep < d and sep >= start_floor(P, d)[0]
    exp = dataclasses.replace(exp, controller=dataclasses.replace(C, barrier=dataclasses.replace(C.barrier,
                                                                                                 min_separation_m=d)))
    a, b = exp.run(backend="numpy"), exp.run(backend="jax")
    assert "numpy_worlds" not in b.meta and "failed" not in b.meta
    _assert_equal(a, b)
