"""The learning environments: the functional core on the simulator's tick, NumPy and JAX, and
the ecosystem's own checkers (gymnasium's ``check_env``, PettingZoo's API and seed tests)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from quatform.envs import functional, key, split
from quatform.scenarios import load_scenario

TEAM = "team-tetrahedron-helix"
NET = "net-consensus-ring"


def short(name: str, duration_s: float):
    """The built-in scenario ``name`` cut to ``duration_s`` (a shorter Experiment.run)."""
    sc = load_scenario(name)
    return dataclasses.replace(sc, duration_s=duration_s, metrics_from_s=min(sc.metrics_from_s, 0.0))


def episode(core, params, seed: int, actions=None, steps=None):
    """``(states, obs, rewards)`` of an episode of ``steps`` (default: to its end) on NumPy."""
    k = key(seed)
    k, first = split(k)
    obs, st = core.reset(first, params)
    xs, os, rs = [st.x], [obs], []
    for j in range(core.T - 1 if steps is None else steps):
        k, now = split(k)
        a = np.zeros(core.n_u) if actions is None else actions[j]
        obs, st, r, term, trunc, _ = core.step(now, st, a, params)
        xs.append(st.x)
        os.append(obs)
        rs.append(r)
        if term or trunc:
            break
    return np.array(xs), np.array(os), np.array(rs)


@pytest.mark.parametrize("name,duration", [(TEAM, 0.6), ("mas-kitts-helix", 0.6), (NET, 0.6)])
def test_zero_residual_episode_is_the_simulators_run(name, duration):
    core = functional(short(name, duration))
    log = core.experiment.run()
    states, obs, rewards = episode(core, core.default_params, 0)
    assert len(states) == core.T == len(log.t)
    assert np.array_equal(states, log["state"])  # bitwise: the env steps the loop's own tick
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rewards))
    assert obs.shape[-1] == core.n_obs


def test_seed_reproduces_the_episode_with_noise():
    core = functional(TEAM, duration_s=0.3, noise_m=0.01, noise_rad=0.01, start_noise_m=0.05)
    p = core.default_params
    acts = np.random.default_rng(3).uniform(-1, 1, (core.T, core.n_u))
    a, b, c = (episode(core, p, s, acts) for s in (7, 7, 8))
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert not np.array_equal(a[0], c[0]) and not np.array_equal(a[1], c[1])


def test_random_draws_are_normal_and_keys_split_apart():
    from quatform.envs import normal

    z = normal(np.stack([key(s) for s in range(200)]), 0, 500)
    assert abs(float(z.mean())) < 0.01 and abs(float(z.std()) - 1.0) < 0.01
    k1, k2 = split(key(0))
    assert not np.array_equal(k1, k2) and k1.dtype == np.uint32


def test_no_nan_at_coincident_robots_and_at_minus_q():
    core = functional(TEAM, duration_s=0.1, min_separation=0.0)
    p = core.default_params
    together = p._replace(x0=np.zeros_like(p.x0))
    obs, st = core.reset(key(0), together)
    obs2, st, r, term, trunc, info = core.step(key(1), st, np.ones(core.n_u), together)
    for v in (obs, obs2, r):
        assert np.all(np.isfinite(v))
    assert bool(term) and bool(info["collided"])
    # the reference's attitude as -q: one attitude, finite errors
    q = slice(3, 7) if core.formation.names[3].startswith("q") else None
    if q is not None:
        flipped = p._replace(c_des=np.concatenate([p.c_des[:, :3], -p.c_des[:, q], p.c_des[:, 7:]], axis=-1))
        o_pos, _ = core.reset(key(0), p)
        o_neg, _ = core.reset(key(0), flipped)
        assert np.all(np.isfinite(o_neg))
    net = functional(NET, duration_s=0.1)
    pn = net.default_params
    flat, _ = net._orientation
    r0 = pn.r_des[0].copy()
    r0[flat] = -r0[flat]  # every robot at its desired point, its quaternion as -q
    o, _ = net.reset(key(0), pn._replace(x0=r0))
    e_r = o[net.n_c:net.n_c + net.n_r]
    assert np.all(np.isfinite(o)) and np.max(np.abs(e_r)) < 1e-12


@pytest.mark.parametrize("name", [TEAM, NET])
def test_jax_form_jits_vmaps_and_equals_numpy(name):
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from quatform.errors import InvalidInputError

    core = functional(name, duration_s=0.1, noise_m=0.01, start_noise_m=0.02)
    p = core.default_params
    B = 4
    keys = np.stack([key(s) for s in range(B)])
    acts = np.random.default_rng(0).uniform(-1, 1, (core.T, B, core.n_u))
    obs, st = core.reset(keys, p)
    ref = [(obs, None, None)]
    for k in range(core.T - 1):
        obs, st, r, term, trunc, _ = core.step(keys + np.uint32(k + 1), st, acts[k], p)
        ref.append((obs, r, trunc))
    with jax.enable_x64(True):
        jp = jax.tree_util.tree_map(jnp.asarray, p)
        reset = jax.jit(jax.vmap(core.reset, in_axes=(0, None)))
        step = jax.jit(jax.vmap(core.step, in_axes=(0, 0, 0, None)))
        obs, st = reset(jnp.asarray(keys), jp)
        np.testing.assert_allclose(np.asarray(obs), ref[0][0], rtol=1e-9, atol=1e-9)
        for k in range(core.T - 1):
            obs, st, r, term, trunc, _ = step(jnp.asarray(keys + np.uint32(k + 1)), st, jnp.asarray(acts[k]), jp)
            np.testing.assert_allclose(np.asarray(obs), ref[k + 1][0], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(np.asarray(r), ref[k + 1][1], rtol=1e-9, atol=1e-12)
            assert np.array_equal(np.asarray(trunc), ref[k + 1][2])
    with pytest.raises(InvalidInputError, match="float64"):  # JAX without x64 computes in float32
        core.reset(jnp.asarray(keys), jax.tree_util.tree_map(jnp.asarray, p))


def test_numpy_batch_equals_single_worlds_on_a_network():
    core = functional(NET, duration_s=0.2, noise_m=0.01)
    p = core.default_params
    keys = np.stack([key(s) for s in range(3)])
    obs, st = core.reset(keys, p)
    singles = [core.reset(keys[i], p) for i in range(3)]
    for i in range(3):
        np.testing.assert_allclose(obs[i], singles[i][0], rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------- gymnasium

def test_gymnasium_check_env_passes_without_warnings():
    gymnasium = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    import quatform.envs  # noqa: F401  (registers quatform/Formation-v0)

    for name in (TEAM, NET):
        env = gymnasium.make("quatform/Formation-v0", scenario=name, duration_s=0.2, noise_m=0.01)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped)
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        assert env.spec.max_episode_steps is None  # truncation is the scenario's duration
        steps, trunc = 0, False
        while not trunc:
            obs, _, term, trunc, _ = env.step(np.zeros(env.action_space.shape))
            steps += 1
            assert not term and env.observation_space.contains(obs)
        assert steps == env.unwrapped.core.T - 1


def test_vector_env_is_single_envs_on_a_batch_axis_with_next_step_autoreset():
    gymnasium = pytest.importorskip("gymnasium")
    import quatform.envs  # noqa: F401

    kw = dict(scenario=TEAM, duration_s=0.1, noise_m=0.01)
    N = 3
    venv = gymnasium.make_vec("quatform/Formation-v0", num_envs=N, vectorization_mode="vector_entry_point", **kw)
    assert type(venv.unwrapped).__name__ == "FormationVectorEnv"
    singles = [gymnasium.make("quatform/Formation-v0", **kw) for _ in range(N)]
    obs, _ = venv.reset(seed=5)
    single = np.array([e.reset(seed=5 + i)[0] for i, e in enumerate(singles)])
    np.testing.assert_array_equal(obs, single)
    rng = np.random.default_rng(1)
    ended = np.zeros(N, dtype=bool)
    resets = 0
    for _ in range(2 * venv.unwrapped.core.T):
        a = rng.uniform(-1, 1, (N, venv.unwrapped.core.n_u))
        obs, r, term, trunc, info = venv.step(a)
        for i, e in enumerate(singles):
            if ended[i]:  # gymnasium's next-step autoreset: this step resets the world
                o, _ = e.reset()
                np.testing.assert_array_equal(obs[i], o)
                assert r[i] == 0.0 and not term[i] and not trunc[i]
                resets += 1
            else:
                o, ri, ti, tri, _ = e.step(a[i])
                np.testing.assert_array_equal(obs[i], o)
                assert r[i] == pytest.approx(ri, rel=1e-12, abs=1e-15)  # a batched sum's rounding
                assert term[i] == ti and trunc[i] == tri
        if not ended.all():
            assert info["min_separation_m"].shape == (N,)
            assert np.array_equal(info["_min_separation_m"], ~ended)  # a reset world has no terms
        ended = term | trunc
    assert resets >= N


# ----------------------------------------------------------------------------- pettingzoo

@pytest.mark.parametrize("name", [TEAM, NET])
def test_pettingzoo_parallel_api_and_seed_tests(name):
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    import quatform.envs

    def make():
        return quatform.envs.parallel_env(scenario=name, duration_s=0.2, noise_m=0.01)

    env = make()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parallel_api_test(env, num_cycles=30)
        parallel_seed_test(make)
    assert len(env.possible_agents) == env.core.layout.n
    obs, _ = env.reset(seed=0)
    acts = {a: np.zeros(env.action_space(a).shape) for a in env.agents}
    _, rewards, _, _, _ = env.step(acts)
    assert all(np.isfinite(v) for v in rewards.values())


def test_network_agent_sees_what_its_inbox_delivered():
    pytest.importorskip("pettingzoo")
    import quatform.envs

    env = quatform.envs.parallel_env(scenario=NET, duration_s=0.3)
    obs, _ = env.reset(seed=0)
    own = 2 * len(env._points[0])
    rows = obs["robot_0"][own:own + 5 * env.slots].reshape(env.slots, 5)
    assert not rows[:, 0].any()  # nothing delivered before the first tick
    for _ in range(3):
        obs, *_ = env.step({a: np.zeros(env.action_space(a).shape) for a in env.agents})
    rows = obs["robot_0"][own:own + 5 * env.slots].reshape(env.slots, 5)
    assert rows[:, 0].any() and np.all(rows[:, 4] >= 0.0)


def test_velocity_action_is_the_commands_in_units_of_the_limits():
    core = functional(TEAM, duration_s=0.1, action="velocity")
    p = core.default_params
    obs, st = core.reset(key(0), p)
    _, st1, _, _, _, info = core.step(key(1), st, np.zeros(core.n_u), p)
    assert np.array_equal(st1.x, st.x) and not np.any(info["commands"])  # no command: the robots hold
    a = np.zeros(core.n_u)
    a[0] = 1.0  # the first robot at its top speed along x
    _, st2, _, _, _, info = core.step(key(1), st, a, p)
    assert info["commands"][0] == pytest.approx(p.action_scale[0], rel=1e-12)
    assert st2.x[0] - st.x[0] == pytest.approx(p.action_scale[0] * core.dt * core.substeps, rel=1e-9)


@pytest.mark.parametrize("bad", [dict(noise_m=-1.0), dict(weights=(1.0, 2.0)), dict(loss_m=0.0), dict(action="fly"),
                                 dict(collision_m=float("nan")), dict(controller=3), dict(foo=1),
                                 dict(duration_s="5"), dict(duration_s=1e9), dict(residual_scale=1e308),
                                 dict(residual_scale=float("inf")), dict(residual_scale=-0.1)])
def test_bad_options_are_one_line_errors(bad):
    from quatform.errors import InvalidInputError

    bad = {"duration_s": 0.1, **bad}
    with pytest.raises(InvalidInputError) as exc:
        functional(TEAM, **bad)
    assert "\n" not in str(exc.value) and str(exc.value).startswith("envs:")
    name = next(k for k in bad if k != "duration_s") if len(bad) > 1 else "duration_s"
    assert name in str(exc.value) or "action" in str(exc.value)


def test_bad_env_arguments_are_one_line_errors():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("pettingzoo")
    import quatform.envs
    from quatform.errors import InvalidInputError

    kw = dict(vectorization_mode="vector_entry_point", scenario=TEAM, duration_s=0.1)
    for n in (0, -1, 2.5, "4", True):
        with pytest.raises(InvalidInputError, match="num_envs"):
            gymnasium.make_vec("quatform/Formation-v0", num_envs=n, **kw)
    venv = gymnasium.make_vec("quatform/Formation-v0", num_envs=3, **kw)
    with pytest.raises(InvalidInputError, match="call reset"):
        venv.step(np.zeros((3, venv.unwrapped.core.n_u)))
    for seed in ([1, 2], -1, "x", [1, 2, "3"]):
        with pytest.raises(InvalidInputError, match="seed"):
            venv.reset(seed=seed)
    venv.reset(seed=[1, None, np.int64(3)])
    env = gymnasium.make("quatform/Formation-v0", scenario=TEAM, duration_s=0.1).unwrapped
    with pytest.raises(InvalidInputError, match="call reset"):
        env.step(np.zeros(env.core.n_u))
    pz = quatform.envs.parallel_env(scenario=TEAM, duration_s=0.1)
    with pytest.raises(InvalidInputError, match="call reset"):
        pz.step({})
    for nb in (0, 2.5, "3", True):
        with pytest.raises(InvalidInputError, match="neighbours"):
            quatform.envs.parallel_env(scenario=TEAM, duration_s=0.1, neighbours=nb)
    with pytest.raises(InvalidInputError, match="network scenario"):
        quatform.envs.parallel_env(scenario=NET, duration_s=0.1, neighbours=2)


def test_without_gymnasium_the_env_modules_say_what_to_install(monkeypatch):
    import importlib
    import sys

    from quatform.errors import MissingDependencyError

    for module, missing in (("quatform.envs.gym", "gymnasium"), ("quatform.envs.parallel", "pettingzoo")):
        monkeypatch.setitem(sys.modules, missing, None)
        monkeypatch.delitem(sys.modules, module, raising=False)
        with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[envs\]"'):
            importlib.import_module(module)


@pytest.mark.parametrize("name", [TEAM, NET, "net-affine-maneuver"])
def test_a_batch_of_worlds_at_different_ticks_steps_as_each_alone(name):
    from quatform.sim.loop import tree_map

    core = functional(name, duration_s=0.3, noise_m=0.01)
    p = core.default_params
    _, s0 = core.reset(key(0), p)
    _, s1 = core.reset(key(1), p)
    for j in range(3):
        s1 = core.step(key(10 + j), s1, np.zeros(core.n_u), p)[1]
    batch = tree_map(lambda a, b: np.stack([np.asarray(a), np.asarray(b)]), s0, s1)
    keys = np.stack([key(20), key(21)])
    acts = np.random.default_rng(0).uniform(-1, 1, (2, core.n_u))
    out = core.step(keys, batch, acts, p)
    for i, s in enumerate((s0, s1)):
        alone = core.step(keys[i], s, acts[i], p)
        np.testing.assert_allclose(out[0][i], alone[0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out[1].x[i], alone[1].x, rtol=1e-12, atol=1e-12)
        assert out[1].k[i] == alone[1].k


def test_team_agent_sees_its_nearest_robots():
    pytest.importorskip("pettingzoo")
    import quatform.envs

    env = quatform.envs.parallel_env(scenario=TEAM, duration_s=0.1, neighbours=2)
    obs, _ = env.reset(seed=0)
    p = env.core.layout.positions(env.state())
    own = 2 * len(env._points[0])
    rows = obs["robot_0"][own:own + 5 * env.slots].reshape(env.slots, 5)
    d = np.linalg.norm(p[1:] - p[0], axis=-1)
    nearest = 1 + np.argsort(d)[:2]
    np.testing.assert_allclose(rows[:, 1:4], p[nearest] - p[0], rtol=0, atol=1e-12)
    assert np.all(rows[:, 0] == 1.0) and np.all(rows[:, 4] == 0.0)


def test_a_deleted_parallel_env_is_freed():
    pytest.importorskip("pettingzoo")
    import gc
    import weakref

    import quatform.envs

    env = quatform.envs.parallel_env(scenario=TEAM, duration_s=0.1)
    env.reset(seed=0)
    assert env.observation_space("robot_0") is env.observation_space("robot_0")  # one object per agent
    env.action_space("robot_1")
    ref = weakref.ref(env)
    del env
    gc.collect()
    assert ref() is None


def test_env_reward_is_the_mean_of_the_agents_rewards():
    pytest.importorskip("pettingzoo")
    import quatform.envs

    core = functional(TEAM, action="velocity", duration_s=0.5, collision_m=0.01)
    p = core.default_params
    _, st = core.reset(key(0), p)
    rng = np.random.default_rng(0)
    for j in range(5):
        _, st, r, _, _, info = core.step(key(j), st, rng.uniform(-1, 1, core.n_u), p)
        assert info["robot_rewards"].shape == (core.layout.n,)
        assert r == pytest.approx(np.mean(info["robot_rewards"]), rel=1e-12, abs=1e-15)
    env = quatform.envs.parallel_env(scenario=TEAM, duration_s=0.5, action="velocity", collision_m=0.01)
    env.reset(seed=0)
    k0, s0 = env._key, env._state
    _, rewards, _, _, _ = env.step({a: np.full(env.action_space(a).shape, 0.5) for a in env.agents})
    _, _, r, _, _, info = env.core.step(split(k0)[1], s0, np.full(core.n_u, 0.5), p)
    assert [rewards[a] for a in env.possible_agents] == list(info["robot_rewards"])
    assert np.mean(list(rewards.values())) == pytest.approx(r, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("mode", ["residual", "velocity"])
def test_a_nan_action_stops_its_robot_only_and_inf_is_the_limit(mode):
    core = functional(TEAM, action=mode, duration_s=0.3)
    p = core.default_params
    _, st = core.reset(key(0), p)
    for j in range(3):
        st = core.step(key(j), st, np.full(core.n_u, 0.1), p)[1]
    first = core.team.command_slices[0]
    a = np.full(core.n_u, 0.1)
    a[first.start] = np.nan
    _, _, r, term, _, info = core.step(key(9), st, a, p)
    _, _, _, _, _, clean = core.step(key(9), st, np.full(core.n_u, 0.1), p)
    zero = np.full(core.n_u, 0.1)
    zero[first] = 0.0
    _, _, _, _, _, held = core.step(key(9), st, zero, p)
    assert np.all(np.isfinite(info["commands"]))
    np.testing.assert_array_equal(info["commands"], held["commands"])  # robot 0 takes no action
    np.testing.assert_array_equal(info["commands"][first.stop:], clean["commands"][first.stop:])  # the others act
    assert bool(info["bad_action"]) and bool(term) and r == -p.loss_penalty
    assert not clean["bad_action"]
    big = core.step(key(9), st, np.full(core.n_u, np.inf), p)[5]["commands"]
    one = core.step(key(9), st, np.ones(core.n_u), p)[5]["commands"]
    np.testing.assert_array_equal(big, one)
    assert np.any(one != 0.0)


def test_host_envs_refuse_non_finite_and_misshapen_actions():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("pettingzoo")
    import quatform.envs
    from quatform.errors import InvalidInputError, NonFiniteError, ShapeError

    env = gymnasium.make("quatform/Formation-v0", scenario=TEAM, duration_s=0.1).unwrapped
    env.reset(seed=0)
    n = env.core.n_u
    for bad, err in ((np.full(n, np.nan), NonFiniteError), (np.full(n, np.inf), NonFiniteError),
                     (np.ones(n - 1), ShapeError), (["a"] * n, InvalidInputError)):
        with pytest.raises(err) as exc:
            env.step(bad)
        assert "\n" not in str(exc.value)
    venv = gymnasium.make_vec("quatform/Formation-v0", num_envs=2, vectorization_mode="vector_entry_point",
                              scenario=TEAM, duration_s=0.1)
    venv.reset(seed=0)
    with pytest.raises(ShapeError):
        venv.step(np.zeros(n))
    pz = quatform.envs.parallel_env(scenario=TEAM, duration_s=0.1)
    pz.reset(seed=0)
    with pytest.raises(NonFiniteError):
        pz.step({"robot_0": np.full(pz.action_space("robot_0").shape, np.nan)})
    with pytest.raises(InvalidInputError, match="robot_99"):
        pz.step({"robot_99": np.zeros(4)})


def test_observation_is_a_function_of_the_attitude():
    core = functional(NET, duration_s=0.3, start_noise_m=0.05)  # no reading noise: q + n is not -(-q + n)
    p = core.default_params
    _, st = core.reset(key(0), p)
    for j in range(3):
        st = core.step(key(j), st, np.full(core.n_u, 0.2), p)[1]
    rows = np.asarray(core.layout.orientation_index).reshape(-1, 4)
    assert rows.size
    x = np.array(st.x)
    x[rows[::2].ravel()] *= -1.0  # every other robot's quaternion as -q
    np.testing.assert_array_equal(core.observe(st._replace(x=x), p), core.observe(st, p))


def test_a_world_stepped_past_its_end_stays_at_its_last_tick():
    core = functional(TEAM, duration_s=0.1)
    p = core.default_params
    _, st = core.reset(key(0), p)
    for j in range(core.T - 1):
        obs, st, _, term, trunc, _ = core.step(key(j), st, np.zeros(core.n_u), p)
    assert bool(trunc) and int(st.k) == core.T - 1 and obs[-1] == 1.0
    last = st
    for j in range(3):
        obs, st, _, term, trunc, info = core.step(key(50 + j), st, np.ones(core.n_u), p)
        assert bool(trunc) and not bool(term) and int(st.k) == core.T - 1 and obs[-1] == 1.0
        np.testing.assert_array_equal(st.x, last.x)
        assert not np.any(info["commands"])
    # in a batch, the ended world stays and the other steps on
    _, fresh = core.reset(key(1), p)
    from quatform.sim.loop import tree_map
    batch = tree_map(lambda a, b: np.stack([np.asarray(a), np.asarray(b)]), last, fresh)
    _, out, _, _, trunc, _ = core.step(np.stack([key(7), key(8)]), batch, np.zeros((2, core.n_u)), p)
    np.testing.assert_array_equal(out.x[0], last.x)
    assert list(out.k) == [core.T - 1, 1] and list(trunc) == [True, False]


def test_vector_env_steps_and_infos_are_gymnasiums_sync_vector_envs():
    gymnasium = pytest.importorskip("gymnasium")
    import quatform.envs  # noqa: F401

    kw = dict(scenario=TEAM, duration_s=0.1, action="velocity", start_noise_m=0.05, noise_m=0.01)
    N = 3
    ours = gymnasium.make_vec("quatform/Formation-v0", num_envs=N, vectorization_mode="vector_entry_point", **kw)
    sync = gymnasium.make_vec("quatform/Formation-v0", num_envs=N, vectorization_mode="sync", **kw)
    np.testing.assert_array_equal(ours.reset(seed=7)[0], sync.reset(seed=7)[0])
    rng = np.random.default_rng(0)
    partial = empty = 0
    for _ in range(3 * ours.unwrapped.core.T):
        a = rng.uniform(-1, 1, (N, ours.unwrapped.core.n_u))
        o1, r1, te1, tr1, i1 = ours.step(a)
        o2, r2, te2, tr2, i2 = sync.step(a)
        np.testing.assert_allclose(o1, o2, rtol=1e-12, atol=1e-15)  # a batch's rounding
        np.testing.assert_allclose(r1, r2, rtol=1e-12, atol=1e-15)
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        assert sorted(i1) == sorted(i2)
        for k in i1:
            assert i1[k].shape == i2[k].shape and i1[k].dtype == i2[k].dtype, k
            np.testing.assert_allclose(i1[k], i2[k], rtol=1e-12, atol=1e-15)
        masks = [v for k, v in i1.items() if k.startswith("_")]
        partial += bool(masks) and not masks[0].all()
        empty += not i1
    assert partial + empty > 0  # some step reset a world


def test_the_barrier_filters_the_policys_residual_on_numpy_and_jax():
    core = functional(TEAM, residual_scale=2.0, duration_s=2.0, collision_m=0.01)
    assert core.controller.shielded
    d_min = core.controller.base.barrier.min_separation_m
    p = core.default_params
    pos = core.layout.positions(core.plant.output(p.x0))
    toward = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    a = np.zeros(core.n_u)
    s0, s1 = core.team.command_slices[:2]
    a[s0.start:s0.start + 3], a[s1.start:s1.start + 3] = toward, -toward  # robots 0 and 1 at each other, flat out
    keys = [key(j) for j in range(core.T - 1)]

    def run(c, params):
        obs, st = c.reset(key(0), params)
        out, ms = [obs], []
        for k in keys:
            obs, st, _, _, _, info = c.step(k, st, a, params)
            out.append(obs)
            ms.append(float(info["min_separation_m"]))
        return np.array(out), ms

    obs, ms = run(core, p)
    assert min(ms) >= d_min - 1e-3 and min(ms) <= d_min + 0.05  # it binds, and holds
    free = functional(TEAM, residual_scale=2.0, duration_s=2.0, collision_m=0.01, min_separation=0.0)
    assert min(run(free, free.default_params)[1]) < 0.5 * d_min  # unshielded, the policy brings them together
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    with jax.enable_x64(True):
        pj = jax.tree_util.tree_map(jnp.asarray, p)

        def body(st, k):
            obs, st, _, _, _, _ = core.step(k, st, jnp.asarray(a), pj)
            return st, obs

        _, s = core.reset(jnp.asarray(key(0)), pj)
        _, oj = jax.jit(lambda s, ks: jax.lax.scan(body, s, ks))(s, jnp.asarray(np.stack(keys)))
        np.testing.assert_allclose(np.asarray(oj), obs[1:], rtol=1e-9, atol=1e-9)


def test_envs_pickle_mid_episode_and_go_on_alike():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("pettingzoo")
    import copy
    import pickle

    import quatform.envs

    kw = dict(scenario=TEAM, duration_s=0.2, noise_m=0.01, start_noise_m=0.02)
    env = gymnasium.make("quatform/Formation-v0", **kw).unwrapped
    venv = gymnasium.make_vec("quatform/Formation-v0", num_envs=2, vectorization_mode="vector_entry_point", **kw)
    pz = quatform.envs.parallel_env(**kw)
    a = np.full(env.core.n_u, 0.3)
    env.reset(seed=1)
    venv.reset(seed=1)
    pz.reset(seed=1)
    env.step(a)
    for original in (env, venv.unwrapped, pz):
        for clone in (lambda e: pickle.loads(pickle.dumps(e)), copy.deepcopy):
            twin = clone(original)
            if original is pz:
                acts = {n: np.full(pz.action_space(n).shape, 0.3) for n in pz.agents}
                assert twin.step(acts)[0]["robot_0"].tolist() == original.step(acts)[0]["robot_0"].tolist()
            else:
                act = a if original is env else np.stack([a, a])
                np.testing.assert_array_equal(twin.step(act)[0], original.step(act)[0])
