"""The pure control tick of the seed-000 controllers (pair, team, with the separation barrier).

Each controller's :meth:`tick` on NumPy is its :meth:`update` bitwise (the same functions:
``update`` is the host's checks, ``reference_arrays``, ``tick`` and a raise where the code
says so); what ``update`` refuses is a code of the tick, world by world (robots on each other,
a measurement not finite or beyond 1e150, robots that start closer than the barrier's
minimum), and ``update`` still raises its one-line message; ``jax.jit`` of the same tick
equals NumPy's within 1e-9 on batches with such worlds, with references of ``q`` and ``-q``
and with a barrier that binds; a world the barrier's array algorithm does not solve takes
the exact host solver's commands on NumPy and is coded ``HOST`` under ``jax.jit``.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL
from conftest import short_scenario

from quatform.control import CONTROLLERS, TEAM_CONTROLLERS, Reference, SafeController, SafeState
from quatform.control.barrier import HOST
from quatform.control.contract import Tick
from quatform.errors import QuatformError
from quatform.formations import EuclideanPair, RobotSpace
from quatform.scenarios import KINDS

TEAM = KINDS["team"]
E_PAIR = np.array([0.1, 0.2, 1.0, 0.3, 0.4, 1.0, 0.1, 0.2])
PAIRS = [cls() for cls in CONTROLLERS.values()]


def _pair_inputs(ctrl, B, seed=0):
    rng = np.random.default_rng(seed)
    c, cd = ctrl.formation.from_euclidean(E_PAIR, rng.normal(size=8) * 0.3)
    r = EuclideanPair().inverse(E_PAIR) + 0.1 * rng.normal(size=(B, 8))
    return r, Reference(c, cd)


def _team(scenario, controller, B, seed=0, spread=0.05):
    exp = TEAM.experiment(short_scenario(scenario), controller=controller)
    rng = np.random.default_rng(seed)
    x = exp.x0[None] + spread * rng.standard_normal((B, exp.x0.size))
    return exp.controller, x, exp.reference(10)


def _flipped(ctrl, ref):
    """``ref`` with every sign-free block of its cluster state negated (``q`` -> ``-q``)."""
    c = np.array(ref.c, dtype=float)
    for s in getattr(ctrl.formation, "sign_free", ()):
        c[..., s] = -c[..., s]
    return Reference(c, ref.c_dot, ref.robots)


def _assert_tick_is_update(ctrl, x, ref, t=0.3, started=False):
    batch = x.shape[:-1]
    state = ctrl.init(batch)
    if started:
        state = SafeState(state.inner, np.ones(batch, dtype=bool))
    step = ctrl.update(t, x, ref, state)
    tick = ctrl.tick(state, x, ctrl.reference_arrays(ref), t)
    assert isinstance(tick, Tick) and ctrl.pure
    assert np.shape(tick.code) == batch and np.all(tick.code == 0)
    np.testing.assert_array_equal(tick.u, step.u)
    assert tick.signals.keys() == step.signals.keys() == ctrl.signal_columns().keys()
    for k, v in step.signals.items():
        np.testing.assert_array_equal(tick.signals[k], v, err_msg=k)


# -- NumPy: tick is update ---------------------------------------------------------------------------

@pytest.mark.parametrize("ctrl", PAIRS, ids=[c.name for c in PAIRS])
def test_pair_tick_is_update(ctrl):
    r, ref = _pair_inputs(ctrl, 5)
    _assert_tick_is_update(ctrl, r, ref)
    _assert_tick_is_update(ctrl, r[2], ref)  # one world (the Python-float kernels)
    _assert_tick_is_update(ctrl, r, _flipped(ctrl, ref))


@pytest.mark.parametrize("scenario", ["team-tetrahedron-helix", "team-triangle-over-ugv"])
@pytest.mark.parametrize("controller", TEAM_CONTROLLERS)
def test_team_and_safe_tick_is_update(scenario, controller):
    safe, x, ref = _team(scenario, controller, 3)
    for ctrl in (safe.inner, safe):
        _assert_tick_is_update(ctrl, x, ref)
        _assert_tick_is_update(ctrl, x[1], ref)


def test_step_keeps_its_float_path_and_equals_update():
    for ctrl in PAIRS:
        r, ref = _pair_inputs(ctrl, 1)
        np.testing.assert_allclose(ctrl.step(0.0, r[0], ref), ctrl.update(0.0, r[0], ref, None).u, rtol=0, atol=1e-12)


# -- refused worlds: codes on the tick, one-line errors from update ------------------------------------

def _broken(x, positions):
    """``x`` (B >= 4 worlds) with world 1's robot 2 on robot 1, world 2 NaN, world 3 beyond 1e150."""
    x = np.array(x)
    x[1, positions[1]] = x[1, positions[0]]
    x[2, 0] = np.nan
    x[3, 0] = 1e200
    return x


@pytest.mark.parametrize("ctrl", PAIRS, ids=[c.name for c in PAIRS])
def test_pair_refused_worlds_are_codes_and_update_raises(ctrl):
    r, ref = _pair_inputs(ctrl, 5)
    x = _broken(r, (slice(0, 3), slice(4, 7)))
    with np.errstate(all="raise"):  # no refused value warns
        tick = ctrl.tick(None, x, ctrl.reference_arrays(ref), 0.0)
    apart = 0 if isinstance(ctrl.formation, RobotSpace) else 2
    assert tick.code.tolist() == [0, apart, 1, 1, 0]
    assert np.all(np.isfinite(tick.u[tick.code == 0]))
    if apart:
        with pytest.raises(QuatformError, match="coincide"):
            ctrl.update(0.0, x[1], ref)
        with pytest.raises(QuatformError, match="coincide"):
            ctrl.update(0.0, x[:2], ref)
    for w in (2, 3):
        with pytest.raises(QuatformError, match="measured robot state"):
            ctrl.update(0.0, x[w], ref)


@pytest.mark.parametrize("controller", TEAM_CONTROLLERS)
def test_team_refused_worlds_are_codes_and_update_raises(controller):
    safe, x, ref = _team("team-tetrahedron-helix", controller, 5)
    ctrl = safe.inner
    x = _broken(x, (slice(0, 3), slice(4, 7)))
    with np.errstate(all="raise"):
        tick = ctrl.tick(None, x, ctrl.reference_arrays(ref), 0.0)
    assert tick.code.tolist() == [0, 2, 1, 1, 0]
    with pytest.raises(QuatformError, match=r"^r: robots 1 and 2 coincide \(separation 0 m"):
        ctrl.update(0.0, x[1], ref)
    with pytest.raises(QuatformError, match="measured robot state"):
        ctrl.update(0.0, x[2], ref)


def test_safe_start_too_close_is_host_and_update_raises():
    safe, x, ref = _team("team-tetrahedron-helix", "quaternion", 3, spread=0.0)
    x = np.array(x)
    x[1, 4:7] = x[1, 0:3] + [0.5 * safe.barrier.min_separation_m, 0.0, 0.0]  # closer than the minimum
    tick = safe.tick(safe.init((3,)), x, safe.reference_arrays(ref), 0.0)
    assert tick.code.tolist() == [0, HOST, 0]
    assert isinstance(tick.state, SafeState) and np.all(tick.state.started)
    again = safe.tick(tick.state, x, safe.reference_arrays(ref), 0.02)  # started: the barrier's own business
    assert again.code[1] != HOST or not np.all(again.signals["safety_active"][1] == 0)
    with pytest.raises(QuatformError, match=r"^SafeController: robots 1 and 2 start 0\.25 m apart in world \(1,\)"):
        safe.update(0.0, x, ref, safe.init((3,)))


# -- the barrier on NumPy: the exact solver where the array algorithm does not solve ---------------

def _binding(scenario, controller, B=6, seed=2):
    """Worlds (but the first) with robot ``b`` put just beyond the barrier's minimum from
    robot ``a``, on the far side from its own slot: its way home runs through ``a``, the
    barrier binds."""
    safe, x, ref = _team(scenario, controller, B, seed=seed, spread=0.0)
    slots = safe.team.state_slices
    width = [s.stop - s.start for s in slots]
    same = [i for i in range(len(slots)) if width[i] == width[-1]]  # robots of one model (x, y, z first)
    d = safe.barrier.min_separation_m
    rng = np.random.default_rng(seed)
    x = np.array(x)
    for w in range(1, B):
        a, b = same[0], same[1 + w % (len(same) - 1)]
        pa, home = x[w, slots[a]][:3], x[0, slots[b]][:3]
        away = (pa - home) / np.linalg.norm(pa - home)
        x[w, slots[b].start:slots[b].start + 3] = pa + 1.05 * d * away + 0.01 * rng.standard_normal(3)
    return safe, x, ref


@pytest.mark.parametrize("scenario", ["team-ring-flip", "team-triangle-over-ugv"])
def test_safe_tick_with_the_barrier_binding_is_update(scenario):
    safe, x, ref = _binding(scenario, "quaternion")
    _assert_tick_is_update(safe, x, ref, started=True)
    tick = safe.tick(SafeState(None, True), x, safe.reference_arrays(ref), 0.3)
    assert np.all(tick.signals["safety_active"][1:] > 0) and np.all(tick.code == 0)


def test_the_array_algorithm_on_numpy_is_the_host_solver(monkeypatch):
    from quatform.control import barrier

    safe, x, ref = _binding("team-ring-flip", "quaternion", B=8)
    slots, d = safe.team.state_slices, safe.barrier.min_separation_m
    for b in (3, 5):  # world 1: robots 4 and 6 also come home through robot 1 (three binding pairs)
        pa, home = x[1, slots[0]][:3], x[0, slots[b]][:3]
        side = np.cross(pa - home, [0.0, 0.0, 1.0 if b == 3 else -1.0])
        x[1, slots[b].start:slots[b].start + 3] = pa + 1.05 * d * side / np.linalg.norm(side)
    u = safe.inner.update(0.3, x, ref).u
    ok, started = np.zeros(len(x), dtype=np.int64), np.ones(len(x), dtype=bool)
    host = safe._filter_host(x, u, ok, started, False)
    arrays = safe._filter_arrays(x, u, ok, started)
    assert np.all(arrays[3] == 0) and np.all(host[3] == 0) and np.all(host[2][1:])  # every world solved, binding
    for a, b in zip(arrays[:3], host[:3]):
        np.testing.assert_allclose(a, b, rtol=0, atol=TOL)
    monkeypatch.setattr(barrier, "CANDIDATES", 1)  # a world of two binding pairs is the host's
    code = safe._filter_arrays(x, u, ok, started)[3]
    assert np.any(code == HOST) and np.any(code == 0)


# -- JAX: jax.jit(tick) equals NumPy's tick ------------------------------------------------------------

def _jit(ctrl):
    import jax

    def run(state, m, ref, t):
        k = ctrl.tick(state, m, ref, t)
        return k.state, k.u, dict(k.signals), k.code

    return jax.jit(run)


def _assert_jax_equals_numpy(ctrl, x, refs, solved_only=False, started=False):
    jax = pytest.importorskip("jax")
    run = _jit(ctrl)
    batch = x.shape[:-1]
    state0 = ctrl.init(batch)
    if started:
        state0 = SafeState(state0.inner, np.ones(batch, dtype=bool))
    for ref in refs:
        arrays = ctrl.reference_arrays(ref)
        a = ctrl.tick(state0, x, arrays, 0.3)
        with jax.enable_x64(True):
            state, u, signals, code = jax.tree_util.tree_map(np.asarray, run(state0, x, arrays, 0.3))
        ok = a.code == 0
        if solved_only:  # a world JAX leaves to the host is NumPy's exact solve
            assert np.all((code == a.code) | ((code == HOST) & ok))
            ok = ok & (code == 0)
        else:
            np.testing.assert_array_equal(code, a.code)
        np.testing.assert_allclose(u[ok], a.u[ok], rtol=0, atol=TOL)
        for k, v in a.signals.items():
            np.testing.assert_allclose(signals[k][ok], v[ok], rtol=0, atol=TOL, err_msg=k)
        if isinstance(state, SafeState):
            assert np.all(state.started)
    return code


@pytest.mark.parametrize("ctrl", PAIRS, ids=[c.name for c in PAIRS])
def test_pair_jit_tick_equals_numpy(ctrl):
    r, ref = _pair_inputs(ctrl, 6)
    x = _broken(r, (slice(0, 3), slice(4, 7)))
    _assert_jax_equals_numpy(ctrl, x, [ref, _flipped(ctrl, ref)])


@pytest.mark.parametrize("controller", TEAM_CONTROLLERS)
def test_team_jit_tick_equals_numpy(controller):
    safe, x, ref = _team("team-tetrahedron-helix", controller, 6)
    x = _broken(x, (slice(0, 3), slice(4, 7)))
    _assert_jax_equals_numpy(safe.inner, x, [ref, _flipped(safe.inner, ref)])


@pytest.mark.parametrize("scenario", ["team-ring-flip", "team-triangle-over-ugv"])
def test_safe_jit_tick_equals_numpy_with_the_barrier_binding(scenario):
    safe, x, ref = _binding(scenario, "quaternion")
    x = np.concatenate([x, _broken(x[:4], (slice(0, 3), slice(4, 7)))[1:]])
    code = _assert_jax_equals_numpy(safe, x, [ref, _flipped(safe.inner, ref)], solved_only=True, started=True)
    if scenario == "team-ring-flip":  # 4-DOF holonomic robots: the array algorithm solves every binding world
        assert np.all(code[:6] == 0)
    else:  # a Pioneer: a binding world is the host's
        assert np.any(code == HOST)


# -- free bodies (pose points: a unit quaternion per robot) ----------------------------------------

def _free_bodies(controller, B=5, seed=4):
    data = {"kind": "team", "name": "free-bodies", "duration_s": 0.6, "dt_s": 0.02,
            "gains": {"base": "table1", "robot-space": {"k_w": 6.0}},
            "robots": [{"model": "free-body", "count": 4}],
            "shape": {"template": "tetrahedron", "edge": 1.2},
            "path": {"kind": "line", "center": [0.0, 0.0, 1.0], "velocity": [0.3, 0.1, 0.0]},
            "attitude": {"turns": [{"axis": [0.3, 0.2, 1.0], "angle": 1.0, "start_s": 0.0, "duration_s": 0.6}]},
            "headings": {"mode": "path"}, "safety": {"min_separation_m": 0.3}}
    exp = TEAM.experiment(TEAM.from_dict(data, "free-bodies"), controller=controller)
    rng = np.random.default_rng(seed)
    x = np.repeat(exp.x0[None], B, axis=0)
    pos = [s.start + k for s in exp.controller.team.state_slices for k in range(3)]
    x[:, pos] += 0.05 * rng.standard_normal((B, len(pos)))
    return exp.controller, x, exp.reference(10)


@pytest.mark.parametrize("controller", ["quaternion", "dual-quaternion", "robot-space"])  # no Euclidean chart
def test_free_body_team_tick_is_update_and_jit_equals_numpy(controller):
    safe, x, ref = _free_bodies(controller)
    for ctrl in (safe.inner, safe):
        _assert_tick_is_update(ctrl, x, ref)
    x = _broken(x, (slice(0, 3), slice(7, 10)))
    assert safe.inner.tick(None, x, safe.inner.reference_arrays(ref), 0.0).code.tolist() == [0, 2, 1, 1, 0]
    _assert_jax_equals_numpy(safe.inner, x, [ref, _flipped(safe.inner, ref)])


# -- the team chain on NumPy: the same floats as update() ------------------------------------------

TEAM_CONTROLLERS = ("quaternion", "dual-quaternion", "cluster-space", "robot-space")


@pytest.mark.parametrize("scenario", ["team-tetrahedron-helix", "team-three-bodies", "team-triangle-over-ugv"])
@pytest.mark.parametrize("controller", TEAM_CONTROLLERS)
def test_chain_on_numpy_is_update_bitwise(scenario, controller):
    exp = KINDS["team"].experiment(short_scenario(scenario), controller=controller)
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
