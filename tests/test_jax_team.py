"""The team kind on the jax compute backend.

Short pieces of the built-in team scenarios run on NumPy and on JAX (batches with
TickMeasurement noise, latency and dropped frames; one world) and every logged channel is
compared within 1e-9, the separation barrier's signals included; a world whose robots sit on
each other fails alone; a world whose barrier JAX cannot solve is NumPy's own run (the
barrier solved on JAX: test_jax_barrier.py); the team sweep gives the same rows on both
backends; what does not run on JAX is refused in one line.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL
from conftest import assert_logs_equal, assert_metrics_equal, noisy_batch, short_scenario

from quatform.control.team import TeamController
from quatform.errors import InvalidInputError
from quatform.scenarios import KINDS

TEAM = KINDS["team"]
JAX_CONTROLLERS = ("quaternion", "dual-quaternion", "cluster-space", "robot-space")
SAFETY = ("min_separation", "safety_active")


def _assert_equal(a, b, channels=()):
    assert_logs_equal(a, b)
    for key in channels:
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)


# -- the chain on NumPy: the same floats as update() (no JAX needed) ------------------------------

@pytest.mark.parametrize("scenario", ["team-tetrahedron-helix", "team-three-bodies", "team-triangle-over-ugv"])
@pytest.mark.parametrize("controller", JAX_CONTROLLERS)
def test_chain_on_numpy_is_update_bitwise(scenario, controller):
    exp = TEAM.experiment(short_scenario(scenario), controller=controller)
    ctrl = exp.controller.inner
    rng = np.random.default_rng(0)
    x = exp.x0[None] + 0.05 * rng.standard_normal((3, exp.x0.size))
    ref = exp.reference(10)
    step = ctrl.update(0.0, x, ref)
    c, err, r_dot = ctrl.chain(ctrl.formation.align(x, ref.robots), ref.c, ref.c_dot)
    assert np.array_equal(c, step.signals["cluster"])
    assert np.array_equal(err, step.signals["error"])
    team, r = ctrl.team, ctrl.formation.align(x, ref.robots)
    u = r_dot if team.passthrough else team.actuate(r, r_dot, 0.0, team.initial_memory((3,)))[0]
    assert np.array_equal(team.saturate(u), step.u)


# -- JAX against NumPy -----------------------------------------------------------------------------

@pytest.mark.parametrize("scenario", ["team-tetrahedron-helix", "team-ring-flip", "team-three-bodies"])
@pytest.mark.parametrize("controller", JAX_CONTROLLERS)
def test_batch_equals_numpy(scenario, controller):
    pytest.importorskip("jax")
    batch = noisy_batch(TEAM.experiment(short_scenario(scenario, 0.4), controller=controller))
    a, b = batch.run(backend="numpy"), batch.run(backend="jax")
    _assert_equal(a, b, SAFETY)
    assert "failed" not in b.meta and "numpy_worlds" not in b.meta  # every world ran on JAX


def test_one_world_and_its_metrics_equal_numpy():
    pytest.importorskip("jax")
    exp = TEAM.experiment(short_scenario("team-ring-flip", 0.4), controller="quaternion")
    a, b = exp.run(backend="numpy"), exp.run(backend="jax")
    _assert_equal(a, b, SAFETY)
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))


def test_without_the_barrier_equals_numpy():
    pytest.importorskip("jax")
    exp = TEAM.experiment(short_scenario("team-tetrahedron-helix", 0.3), controller="quaternion")
    bare = dataclasses.replace(noisy_batch(exp), controller=exp.controller.inner)
    assert isinstance(bare.controller, TeamController)
    _assert_equal(bare.run(backend="numpy"), bare.run(backend="jax"))


def test_a_world_with_robots_on_each_other_fails_alone():
    pytest.importorskip("jax")
    exp = TEAM.experiment(short_scenario("team-tetrahedron-helix", 0.3), controller="quaternion")
    batch = noisy_batch(exp, B=3, spread=0.0, sigma=0.0)
    x0 = np.array(batch.x0)
    x0[1, 4:7] = x0[1, 0:3]  # robot 2 on robot 1 in world 1
    for ctrl in (exp.controller.inner, exp.controller):  # bare (JAX marks it) and with the barrier (NumPy's run)
        run = dataclasses.replace(batch, x0=x0, controller=ctrl)
        a, b = run.run(backend="numpy"), run.run(backend="jax")
        assert b.meta["failed"].tolist() == [False, True, False] == a.meta["failed"].tolist()
        assert list(b.meta["failure"]) == [(1,)] and b.meta["failure"][(1,)].startswith("t = 0 s: ")
        assert np.all(b["command"][:, 1] == 0.0) and np.all(np.isnan(b["cluster"][:, 1]))
        for w in (0, 2):  # the rest go on, as on NumPy
            for key in ("state", "command", "cluster", "error"):
                np.testing.assert_allclose(b[key][:, w], a[key][:, w], rtol=0, atol=TOL, err_msg=key)


def test_a_world_whose_barrier_jax_cannot_solve_is_numpys_run(monkeypatch):
    pytest.importorskip("jax")
    from quatform.control import barrier as jax_barrier
    from quatform.sim import jax_loop

    calls = []
    rerun = jax_loop._rerun_on_host
    monkeypatch.setattr(jax_loop, "_rerun_on_host", lambda *a, **k: calls.append(1) or rerun(*a, **k))
    solve = jax_barrier.barrier_filter  # as if no world where a pair binds were solved (test_jax_barrier: K pairs)
    monkeypatch.setattr(jax_barrier, "barrier_filter", lambda *a: (lambda r: r[:3] + (~r[2],))(solve(*a)))
    monkeypatch.setattr(jax_loop, "_CACHE", {})  # no compiled tick of the real filter

    def reruns():
        return len(calls)
    exp = TEAM.experiment(short_scenario("team-three-bodies", 0.4), controller="robot-space")
    batch = noisy_batch(exp, B=3, spread=0.0)
    x0 = np.array(batch.x0)
    p1, p2 = x0[2, 0:2], x0[2, 3:5]  # world 2: robot 1 behind robot 2 (0.35 m, barrier 0.3 m), its way home through it
    x0[2, 0:2] = p2 + 0.35 * (p2 - p1) / np.linalg.norm(p2 - p1)
    run = dataclasses.replace(batch, x0=x0)
    seen = []
    a, b = run.run(backend="numpy"), run.run(backend="jax", progress=lambda f: seen.append((f, reruns())))
    assert np.nanmax(a["safety_active"][:, 2]) == 1.0 and np.nanmax(a["safety_active"][:, :2]) == 0.0
    assert b.meta["numpy_worlds"].tolist() == [False, False, True]
    _assert_equal(a, b, SAFETY)
    # progress reaches 1 only once the NumPy rerun is done, in as many calls as chunks
    assert seen[-1] == (1.0, 1) and all(f < 1.0 and k == 0 for f, k in seen[:-1]) and len(seen) <= 10
    one = dataclasses.replace(exp, x0=x0[2], finish=lambda log: log)  # one world: NumPy's run as it is
    a, b = one.run(backend="numpy"), one.run(backend="jax")
    assert b.meta["numpy_worlds"] == np.True_
    _assert_equal(a, b, SAFETY)


# -- the sweep --------------------------------------------------------------------------------------

def test_team_sweep_on_jax_equals_numpy(tmp_path):
    pytest.importorskip("jax")
    from quatform.sweeps import run_sweep
    from quatform.sweeps.spec import sweep_from_dict

    data = {"name": "tiny-team", "scenario": "team-grid-100", "trials": 2, "seed": 0, "duration_s": 0.5,
            "settle_s": 0.0, "controllers": ["quaternion"],
            "vary": {"team_size": {"values": [4]}, "noise_m": {"values": [0.005]}, "noise_rad": {"values": [0.005]},
                     "initial_offset_m": {"values": [0.1]}, "initial_offset_rad": {"values": [0.1]}}}
    spec = sweep_from_dict(data, "tiny-team")
    rows = {}
    for backend in ("numpy", "jax"):
        run_sweep(spec, tmp_path / backend, backend=backend, plots=False, quiet=True)
        rows[backend] = json.loads((tmp_path / backend / "results.json").read_text())["rows"]
    assert len(rows["jax"]) == len(rows["numpy"]) == 2
    for a, b in zip(rows["numpy"], rows["jax"]):
        assert a.keys() == b.keys()
        for key, value in a.items():
            if isinstance(value, float) and np.isfinite(value):
                assert abs(b[key] - value) <= TOL, key
            elif not isinstance(value, float):
                assert b[key] == value, key


# -- refusals ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("scenario, controller, what", [
    ("team-triangle-over-ugv", "quaternion", "the plant TeamPlant of HolonomicRobot, Pioneer robots runs on numpy"),
])
def test_what_does_not_run_on_jax_is_refused_in_one_line(scenario, controller, what):
    pytest.importorskip("jax")
    pytest.importorskip("mujoco")
    exp = TEAM.experiment(short_scenario(scenario, 0.1), controller=controller, physics="mujoco")
    with pytest.raises(InvalidInputError) as info:
        exp.run(backend="jax")
    msg = str(info.value)
    assert "\n" not in msg and what in msg and "four team controllers" in msg


def test_rollout_metrics_stays_pair_only():
    pytest.importorskip("jax")
    from quatform.sim.jax_rollout import rollout_metrics

    exp = TEAM.experiment(short_scenario("team-tetrahedron-helix", 0.1), controller="quaternion")
    with pytest.raises(InvalidInputError, match="rollout_metrics rolls out the pair kind's experiments; a team") as info:
        rollout_metrics(exp)
    assert "\n" not in str(info.value)
