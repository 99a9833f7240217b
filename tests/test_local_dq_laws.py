"""The dual-quaternion local laws (dq-laplacian, dq-consensus): the rates λ₂ predicts, tracking,
the double cover, what converges from random starts, the complete graph against the central law."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.algebra import dq_from_pose, dqconj, dqexp, dqlog_decoupled, dqmul, pose_from_dq, qmul
from quatform.control.local import LOCAL_CONTROLLERS
from quatform.control.local_laws import dq_pose as dqk
from quatform.control.local_laws.dq_consensus import DQConsensus, left_jacobian_times, log_coordinates
from quatform.control.local_laws.dq_laplacian import DQLaplacian
from quatform.control.networked import NetworkedController
from quatform.errors import InvalidInputError, NonUnitError, ShapeError
from quatform.network import Graph, Links
from quatform.robots import FreeBodyRobot, Team
from quatform.sim import simulate
from quatform.sim.plants.kinematic import KinematicTeam

N = 6
LAWS = {"dq-laplacian": DQLaplacian, "dq-consensus": DQConsensus}
#: A weighted directed graph with a spanning tree (robot 1, index 0, is heard by every robot).
WEIGHTED = Graph.from_edges(N, [(1, 0), (2, 1), (3, 2), (4, 3), (5, 4), (0, 5), (2, 0), (4, 1)],
                            weights=[1.0, 2.0, 0.5, 1.5, 1.0, 0.7, 0.3, 0.8])
GRAPHS = {"directed ring": Graph.ring(N), "undirected ring": Graph.ring(N, directed=False), "weighted": WEIGHTED}


def _team(n=N):
    return Team.uniform(FreeBodyRobot(max_speed=1e3, max_angular_rate=1e3), n, common_limit=False)


def _unit_q(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _state(x):
    """Flat plant state ``(*batch, n 7)`` of poses ``(*batch, n, 8)``."""
    q, t = pose_from_dq(x)
    return np.concatenate([t, q], axis=-1).reshape(x.shape[:-2] + (-1,))


def _poses(log, n):
    st_ = np.asarray(log.channels["state"].data)
    st_ = st_.reshape(st_.shape[:-1] + (n, 7))
    return dqk.pose_dq(st_)


def _error(law, x, x_d):
    """The consensus error of each tick ``(T, *batch)``: the spread of the ``y`` (aligned to robot 1's
    sign) or of their log coordinates about their mean."""
    y = dqk.formation_variable(x, x_d)
    z = dqk.aligned(y, y[..., :1, :]) if law == "dq-laplacian" else log_coordinates(y)
    return np.linalg.norm(z - z.mean(axis=-2, keepdims=True), axis=(-1, -2))


def _near_formation(rng, x_d, spread_rad=0.6, spread_m=0.5):
    """Poses ``c p_i x_d,i``: a common displacement ``c`` and per-robot perturbations ``p_i``."""
    c = dq_from_pose(_unit_q(rng, ()), rng.normal(size=3))
    axis = rng.normal(size=(len(x_d), 3))
    half = 0.5 * spread_rad * rng.uniform(0.3, 1.0, size=(len(x_d), 1))
    pq = np.concatenate([np.cos(half), np.sin(half) * axis / np.linalg.norm(axis, axis=1, keepdims=True)], axis=1)
    return dqmul(dqmul(c, dq_from_pose(pq, spread_m * rng.normal(size=(len(x_d), 3)))), x_d)


# ---------------------------------------------------------------------------------------------- rates


def _rate(law, graph, dt=0.02, ticks=800, window=(4.0, 14.0), seed=0):
    rng = np.random.default_rng(seed)
    x_d = dq_from_pose(_unit_q(rng, (N,)), rng.normal(size=(N, 3)))
    ctrl = NetworkedController(LAWS[law](1.0), _team(), Links(graph, max_age_s=0.5), dt)
    times = np.arange(ticks) * dt
    log = simulate(KinematicTeam(_team()), ctrl, lambda k: {"pose": x_d}, times, _state(_near_formation(rng, x_d)))
    err = _error(law, _poses(log, N), x_d)
    i0, i1 = np.searchsorted(times, window)
    return -(np.log(err[i1]) - np.log(err[i0])) / (times[i1] - times[i0]), err


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("graph", GRAPHS)
def test_consensus_rate_is_the_rate_lambda2_predicts(law, graph):
    # Linearised at consensus both laws are y_dot = -k (L ⊗ I) y; the loop holds each command for
    # dt, so the discrete prediction of Graph.predicted_rate(k, dt) applies.
    g, dt = GRAPHS[graph], 0.02
    measured, err = _rate(law, g, dt)
    predicted = g.predicted_rate(1.0, dt_s=dt)
    assert abs(measured / predicted - 1.0) <= 0.1, (measured, predicted)
    assert np.all(np.isfinite(err))


def test_pinned_leader_rate_is_the_least_real_part_of_l_plus_b():
    # A directed spanning tree rooted at robot 1 (its leader weight 2), distinct diagonal weights.
    tree = Graph.from_edges(N, [(1, 0), (2, 1), (3, 1), (4, 2), (5, 0)], weights=[1.5, 2.5, 1.0, 3.0, 2.2])
    b = np.array([2.0, 0, 0, 0, 0, 0])
    expected = np.min(np.linalg.eigvals(tree.laplacian() + np.diag(b)).real)
    rng = np.random.default_rng(4)
    x_d = dq_from_pose(_unit_q(rng, (N,)), rng.normal(size=(N, 3)))
    dt = 0.02
    ctrl = NetworkedController(DQConsensus(1.0), _team(), Links(tree, max_age_s=0.5), dt)
    times = np.arange(700) * dt
    log = simulate(KinematicTeam(_team()), ctrl, lambda k: {"pose": x_d, "leader": b}, times,
                   _state(_near_formation(rng, x_d)))
    ell = log_coordinates(dqk.formation_variable(_poses(log, N), x_d))
    err = np.linalg.norm(ell, axis=(-1, -2))  # distance of every robot from its desired pose
    i0, i1 = np.searchsorted(times, [6.0, 12.0])
    measured = -(np.log(err[i1]) - np.log(err[i0])) / (times[i1] - times[i0])
    discrete = -np.log(1.0 - dt * expected) / dt
    assert abs(measured / discrete - 1.0) <= 0.1, (measured, discrete)


# ------------------------------------------------------------------------------ time-varying formation


def _moving_formation(t, n=N):
    """Desired poses and world twists of a formation frame on a helix, spinning about z (past
    half a turn and on), with each robot's place in it breathing: ``x_d,i = x_0(t) r_i(t)``."""
    w0, rho0, vz = 0.8, 1.5, 0.3
    phi = 2 * np.pi * np.arange(n) / n
    rho, rho_dot = 1.0 + 0.3 * np.sin(t), 0.3 * np.cos(t)
    p0 = np.array([rho0 * np.cos(0.4 * t), rho0 * np.sin(0.4 * t), vz * t])
    v0 = np.array([-0.4 * rho0 * np.sin(0.4 * t), 0.4 * rho0 * np.cos(0.4 * t), vz])
    yaw = w0 * t + phi
    q = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=-1)
    off = rho * np.stack([np.cos(w0 * t + phi), np.sin(w0 * t + phi), 0 * phi], axis=-1)  # R0 o_i
    off_dot = rho_dot / rho * off + np.cross([0, 0, w0], off)
    pose = dq_from_pose(q, p0 + off)
    twist = np.concatenate([np.broadcast_to(v0, (n, 3)) + off_dot, np.tile([0, 0, w0], (n, 1))], axis=1)
    return {"pose": pose, "twist": twist}


def test_time_varying_formation_tracked_on_a_directed_spanning_tree():
    # Robot 1 (index 0) is the root and the only pinned robot; the others hear their parent.
    tree = Graph.from_edges(N, [(1, 0), (2, 1), (3, 1), (4, 3), (5, 4)])
    b = np.array([1.0, 0, 0, 0, 0, 0])
    rng = np.random.default_rng(5)
    ref0 = _moving_formation(0.0)
    x0 = _near_formation(rng, ref0["pose"], spread_rad=2.0, spread_m=1.0)
    dt = 0.01
    ctrl = NetworkedController(DQConsensus(2.0), _team(), Links(tree, max_age_s=0.5), dt)
    times = np.arange(1200) * dt
    log = simulate(KinematicTeam(_team()), ctrl, lambda k: dict(_moving_formation(times[k]), leader=b), times, _state(x0))
    x = _poses(log, N)
    x_d = np.stack([_moving_formation(t)["pose"] for t in times])
    err = np.linalg.norm(log_coordinates(dqk.formation_variable(x, x_d)), axis=-1)  # (T, N) rad and m
    assert np.all(np.isfinite(err))
    assert err[0].max() >= 0.5
    # What is left is the hold of each command over a tick while the desired poses turn and
    # accelerate (about 1.3 m/s^2 here): O(dt), 2.8e-3 at dt = 0.01 and 1.4e-3 at dt = 0.005.
    assert err[-1].max() <= 0.5 * dt, err[-1]
    # The team's relative poses are those the formation asks for (a few mm and mrad).
    rel = dqmul(dqconj(x[-1, 0]), x[-1])
    rel_d = dqmul(dqconj(x_d[-1, 0]), x_d[-1])
    assert np.linalg.norm(log_coordinates(dqmul(rel, dqconj(rel_d))), axis=-1).max() <= dt


# -------------------------------------------------------------------------------------- double cover


def _tick(law, graph, x, x_d, extra=None):
    """One tick through the networked controller: the command ``(n, 6)`` and signals."""
    n = len(x_d)
    ctrl = NetworkedController(LAWS[law](1.5), _team(n), Links(graph, max_age_s=0.5), 0.02)
    xs = ctrl.schedule(np.arange(2) * 0.02)
    step = ctrl.update(0.0, np.asarray(x, dtype=float).reshape(-1),
                       (dict({"pose": x_d}, **(extra or {})), {k: v[0] for k, v in xs.items()}))
    return np.asarray(step.u).reshape(n, 6), step.signals


def _signs(flags):
    return np.where(np.asarray(flags), -1.0, 1.0)[:, None]


@pytest.mark.parametrize("law", LAWS)
@settings(max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), flips=st.lists(st.booleans(), min_size=8, max_size=8))
def test_q_and_minus_q_give_one_command(law, seed, flips):
    rng = np.random.default_rng(seed)
    n = 4
    x = dq_from_pose(_unit_q(rng, (n,)), rng.normal(size=(n, 3)))
    x_d = dq_from_pose(_unit_q(rng, (n,)), rng.normal(size=(n, 3)))
    g = Graph.complete(n)
    twist = rng.normal(size=(n, 6))
    u, _ = _tick(law, g, _state(x[None])[0], x_d, {"twist": twist})
    flipped = _state((x * _signs(flips[:n]))[None])[0]  # the measured quaternion's sign
    u2, _ = _tick(law, g, flipped, x_d * _signs(flips[n:]), {"twist": twist})
    np.testing.assert_allclose(u2, u, rtol=0, atol=1e-10 * (1.0 + np.abs(u).max()))


@pytest.mark.parametrize("law", LAWS)
def test_half_a_turn_apart_decides_without_a_tie(law):
    # Primary parts exactly orthogonal (dot 0): robot 2 is robot 1 turned by pi about x, and the
    # command is the same for every sign of both poses, finite, and turns them towards each other.
    q = np.array([[1.0, 0, 0, 0], [0.0, 1, 0, 0]])
    x = dq_from_pose(q, np.zeros((2, 3)))
    x_d = dq_from_pose(np.tile([1.0, 0, 0, 0], (2, 1)), np.zeros((2, 3)))
    g = Graph.ring(2, directed=False)
    cmds = [_tick(law, g, _state((x * _signs([a, b]))[None])[0], x_d)[0] for a in (0, 1) for b in (0, 1)]
    for u in cmds:
        assert np.all(np.isfinite(u))
        np.testing.assert_array_equal(u, cmds[0])
    w = cmds[0][:, 3:]
    assert w[0, 0] != 0.0 and w[0, 0] == -w[1, 0]  # opposite turns about x: the half turn closes


@pytest.mark.parametrize("law", LAWS)
def test_antipodal_starts_in_the_closed_loop(law):
    # Robot pairs at q and -q of one pose (already agreed: nothing moves), and robots half a turn
    # apart (they agree, never NaN), on an undirected ring of 4.
    n, dt = 4, 0.02
    g = Graph.ring(n, directed=False)
    x_d = dq_from_pose(np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 3)))
    same = np.tile(dq_from_pose(np.array([0.6, 0.0, 0.8, 0.0]), np.array([1.0, 2.0, 3.0])), (n, 1))
    same = same * _signs([0, 1, 0, 1])
    half = dq_from_pose(np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [1.0, 0, 0, 0], [0, 0, 1.0, 0]]),
                        np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]))
    ctrl = NetworkedController(LAWS[law](1.0), _team(n), Links(g, max_age_s=0.5), dt)
    times = np.arange(600) * dt
    log = simulate(KinematicTeam(_team(n)), ctrl, lambda k: {"pose": x_d}, times,
                   np.stack([_state(same[None])[0], _state(half[None])[0]]))
    cmd = np.asarray(log.channels["command"].data)
    assert np.all(np.isfinite(cmd))
    np.testing.assert_array_equal(cmd[:, 0], 0.0)
    err = _error(law, _poses(log, n), x_d)
    assert err[-1, 1] <= 1e-4 * err[0, 1]


@pytest.mark.parametrize("law", LAWS)
def test_no_nan_at_the_identity_and_at_half_a_turn(law):
    # y = 1 (dqlog at the identity) and y a half turn (the log's two representatives meet).
    q = np.array([[1.0, 0, 0, 0], [0.0, 0, 0, 1], [0.0, 1, 0, 0], [np.cos(1e-9), np.sin(1e-9), 0, 0]])
    x = dq_from_pose(q, np.zeros((4, 3)))
    x_d = dq_from_pose(np.tile([1.0, 0, 0, 0], (4, 1)), np.zeros((4, 3)))
    u, signals = _tick(law, Graph.complete(4), _state(x[None])[0], x_d, {"leader": np.ones(4)} if law == "dq-consensus"
                       else None)
    assert np.all(np.isfinite(u)) and all(np.all(np.isfinite(np.asarray(s))) for s in signals.values())
    ell = log_coordinates(x)
    np.testing.assert_allclose(ell[0], 0.0, atol=0)
    np.testing.assert_allclose(np.linalg.norm(ell[1:3, :3], axis=-1), np.pi, rtol=1e-15)
    np.testing.assert_allclose(ell[3, :3], [2e-9, 0, 0], rtol=1e-12)


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), scale=st.sampled_from([0.0, 1e-9, 1e-3, 0.5, 2.0, np.pi]))
def test_left_jacobian_is_the_derivative_of_the_exponential(seed, scale):
    # w = 2 vec(q_dot q*) with q_dot = Dexp_{theta/2}[theta_dot/2], the dual part of dqexp (its docstring).
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    theta = scale * axis / np.linalg.norm(axis)
    rate = rng.normal(size=3)
    e = dqexp(np.concatenate([[0.0], theta / 2, [0.0], rate / 2]))
    expected = 2.0 * qmul(e[4:], e[:4] * [1, -1, -1, -1])[1:]
    np.testing.assert_allclose(left_jacobian_times(theta, rate), expected, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------ what converges


def _ring_loop_contractible(y0):
    """Whether each world's loop of shortest-way relative rotations round the ring (robot 1, 2,
    ... n, 1) is contractible in SO(3): following the nearest sign round it returns to robot 1's."""
    s = y0[..., 0, :]
    for i in range(1, y0.shape[-2]):
        s = dqk.aligned(y0[..., i, :], s)
    return np.sum(dqk.aligned(y0[..., 0, :], s)[..., :4] * y0[..., 0, :4], axis=-1) > 0


@pytest.mark.parametrize("law", LAWS)
def test_random_starts_on_a_ring(law):
    # 48 random poses on an undirected ring of 6. The log-chart consensus converges from every
    # start; the Laplacian law converges exactly where the ring's loop of shortest-way relative
    # rotations is contractible in SO(3) (pi_1 = Z2): elsewhere it ends on a twisted equilibrium.
    rng = np.random.default_rng(11)
    B, dt = 48, 0.05
    x_d = dq_from_pose(_unit_q(rng, (N,)), rng.normal(size=(N, 3)))
    x0 = dq_from_pose(_unit_q(rng, (B, N)), rng.normal(size=(B, N, 3)))
    ctrl = NetworkedController(LAWS[law](1.0), _team(), Links(GRAPHS["undirected ring"], max_age_s=0.5), dt)
    times = np.arange(400) * dt
    log = simulate(KinematicTeam(_team()), ctrl, lambda k: {"pose": x_d}, times, _state(x0))
    err = _error(law, _poses(log, N), x_d)
    converged = err[-1] <= 1e-3
    assert not np.any(np.isnan(err))
    if law == "dq-consensus":
        assert converged.all()
    else:
        contractible = _ring_loop_contractible(dqk.formation_variable(x0, x_d))
        np.testing.assert_array_equal(converged, contractible)
        assert 0 < contractible.sum() < B
        assert err[-1][~contractible].min() >= 0.5  # stuck, not slow


# ------------------------------------------------------------------ complete graph = central law


def _central(law, x, x_d, k, b):
    """The central law on the full Laplacian ``L`` of the complete graph, from the public algebra."""
    n = len(x_d)
    L = Graph.complete(n).laplacian()
    y = dqmul(x, dqconj(x_d))
    q, t = pose_from_dq(x)
    if law == "dq-laplacian":
        y = y * np.where(y[:, :4] @ y[0, :4] < 0, -1.0, 1.0)[:, None]  # one hemisphere (all pairs acute)
        zeta = dqmul(-k * (L @ y), dqconj(y))
        zeta[:, [0, 4]] = 0.0
    else:
        lg = 2.0 * dqlog_decoupled(y, shortest=True)
        ell = np.concatenate([lg[:, 1:4], lg[:, 5:8]], axis=1)
        rate = -k * (L + np.diag(b)) @ ell
        e = dqexp(np.concatenate([np.zeros((n, 1)), ell[:, :3] / 2, np.zeros((n, 1)), rate[:, :3] / 2], axis=1))
        omega = 2.0 * qmul(e[:, 4:], e[:, :4] * [1, -1, -1, -1])[:, 1:]
        ty = ell[:, 3:]
        zeta = np.concatenate([np.zeros((n, 1)), omega / 2, np.zeros((n, 1)),
                               (rate[:, 3:] + np.cross(ty, omega)) / 2], axis=1)
    w = 2.0 * zeta[:, 1:4]
    return np.concatenate([2.0 * zeta[:, 5:8] - np.cross(t, w), w], axis=1)


@pytest.mark.parametrize("law", LAWS)
def test_complete_graph_equals_the_central_law(law):
    n, dt, k = 5, 0.02, 1.3
    rng = np.random.default_rng(7)
    x_d = dq_from_pose(_unit_q(rng, (n,)), rng.normal(size=(n, 3)))
    b = np.array([0.0, 0.5, 0, 0, 0]) if law == "dq-consensus" else np.zeros(n)
    ctrl = NetworkedController(LAWS[law](k), _team(n), Links(Graph.complete(n), max_age_s=0.5), dt)
    times = np.arange(150) * dt
    log = simulate(KinematicTeam(_team(n)), ctrl, lambda k: {"pose": x_d, "leader": b} if law == "dq-consensus"
                   else {"pose": x_d}, times, _state(_near_formation(rng, x_d, spread_rad=1.5, spread_m=2.0)[None])[0])
    x = _poses(log, n)
    cmd = np.asarray(log.channels["command"].data).reshape(len(times), n, 6)
    for i in range(0, len(times), 10):
        np.testing.assert_allclose(cmd[i], _central(law, x[i], x_d, k, b), rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- checks and registry


def test_registered():
    assert LOCAL_CONTROLLERS.get("dq-laplacian") is DQLaplacian
    assert LOCAL_CONTROLLERS.get("dq-consensus") is DQConsensus


@pytest.mark.parametrize("law", LAWS)
def test_reference_and_gain_errors_are_one_line(law):
    c = LAWS[law]()
    x_d = dq_from_pose(np.tile([1.0, 0, 0, 0], (3, 1)), np.zeros((3, 3)))
    cases = [({}, InvalidInputError, "needs 'pose'"),
             ({"pose": x_d[:2]}, ShapeError, "(*batch, 3, 8)"),
             ({"pose": 2 * x_d}, NonUnitError, "robot 1 is not a unit dual quaternion"),
             ({"pose": x_d, "twist": np.full((3, 6), np.nan)}, InvalidInputError, "NaN"),
             ({"pose": x_d, "twist": np.zeros((3, 5))}, ShapeError, "'twist'")]
    if law == "dq-consensus":
        cases.append(({"pose": x_d, "leader": [1.0, -1.0, 0.0]}, InvalidInputError, "negative"))
    for ref, exc, text in cases:
        with pytest.raises(exc, match=None) as info:
            c.reference_arrays(ref, 3)
        assert text in str(info.value) and "\n" not in str(info.value)
    for bad in (0.0, -1.0, np.nan, True):
        with pytest.raises(InvalidInputError, match="gain"):
            LAWS[law](bad)


# ----------------------------------------------------------------------------------------------- JAX


@pytest.mark.parametrize("law", LAWS)
def test_jax_equals_numpy(law):
    pytest.importorskip("jax")
    from quatform.sim.loop import simulate_jax

    n, dt = 4, 0.02
    rng = np.random.default_rng(3)
    x_d = dq_from_pose(_unit_q(rng, (n,)), rng.normal(size=(n, 3)))
    links = Links(Graph.ring(n), delay_s=0.04, drop=0.2, max_age_s=0.5, seed=2)
    ctrl = NetworkedController(LAWS[law](1.0), _team(n), links, dt)
    x0 = _state(dq_from_pose(_unit_q(rng, (2, n)), rng.normal(size=(2, n, 3))))
    ref = lambda k: {"pose": x_d, "twist": np.tile([0.1, 0, 0, 0, 0, 0.2], (n, 1))}  # noqa: E731
    times = np.arange(60) * dt
    a = simulate(KinematicTeam(_team(n)), ctrl, ref, times, x0).channels
    b = simulate_jax(KinematicTeam(_team(n)), ctrl, ref, times, x0).channels
    for key in a:
        np.testing.assert_allclose(np.asarray(b[key].data), np.asarray(a[key].data), rtol=0, atol=1e-9, err_msg=key)


@pytest.mark.parametrize("law", LAWS)
def test_each_robot_computes_from_its_own_row(law):
    # One robot's node (its row of everything, N = 1) computes the team's row bit for bit.
    rng = np.random.default_rng(8)
    n, w, b = 4, 3, 2
    c = LAWS[law](1.2)
    own = _state(dq_from_pose(_unit_q(rng, (b, n)), rng.normal(size=(b, n, 3)))).reshape(b, n, 7)
    ref = c.reference_arrays({"pose": dq_from_pose(_unit_q(rng, (n,)), rng.normal(size=(n, 3))),
                              "twist": rng.normal(size=(n, 6)), "leader": rng.random(n)}, n)
    senders = rng.integers(0, n, size=(n, w))
    sent = c.message(None, own, ref, 0.0)
    box = {"senders": senders, "weights": rng.random((n, w)), "valid": rng.random((b, n, w)) > 0.3,
           "stamps": np.zeros((b, n, w)), "messages": sent[:, senders]}
    full = c.tick(None, own, box, ref, 0.0)
    for i in range(n):
        row = {"senders": senders[[i]], "weights": box["weights"][[i]], "valid": box["valid"][:, [i]],
               "stamps": box["stamps"][:, [i]], "messages": box["messages"][:, [i]]}
        one = c.tick(None, own[:, [i]], row, {k: v[[i]] for k, v in ref.items()}, 0.0)
        np.testing.assert_array_equal(one.u, full.u[:, [i]])
        for key in full.signals:
            np.testing.assert_array_equal(one.signals[key], full.signals[key][:, [i]])


def test_pose_consensus_under_switching_reaches_the_period_rate():
    """Free bodies on two halves of a directed ring, switching every 0.5 s (neither alone has a
    spanning tree, their union has one; Thunberg, Goncalves & Hu's setting on SE(3)): the pose
    consensus converges at the rate of one period's transition matrix of the linearisation;
    with the two halves never joined (a union without spanning tree) it does not."""
    from quatform.control.local_laws.dq_consensus import DQConsensus
    from quatform.control.networked import NetworkedController
    from quatform.network import Graph, Links
    from quatform.network.graph import switching_rate
    from quatform.robots import FreeBodyRobot, Team
    from quatform.sim import simulate
    from quatform.sim.plants.kinematic import KinematicTeam

    n, dt = 6, 0.02
    a = [(0.0, Graph(n, [(0, 1), (2, 3), (4, 5)])), (0.5, Graph(n, [(1, 2), (3, 4), (5, 0)]))]
    split = [(0.0, Graph(n, [(0, 1), (1, 2), (2, 0)])), (0.5, Graph(n, [(3, 4), (4, 5), (5, 3)]))]
    rng = np.random.default_rng(7)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    x0 = np.concatenate([rng.normal(size=(n, 3)), q], axis=-1).reshape(-1)
    team = Team.uniform(FreeBodyRobot(max_speed=50.0, max_angular_rate=50.0), n, common_limit=False)
    desired = np.tile([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], (n, 1))
    desired[:, 0] = np.arange(n)
    ref = (lambda k: {"desired": desired, "desired_rate": np.zeros((n, 7))})
    times = np.arange(3000) * dt
    law = DQConsensus(2.0)
    errs = {}
    for label, pattern in (("union", a), ("split", split)):
        sched = [(r + s, g) for r in range(60) for s, g in pattern]
        ctrl = NetworkedController(law, team, Links(sched, max_age_s=0.01), dt)
        log = simulate(KinematicTeam(team), ctrl, ref, times, x0)
        own = np.asarray(log["measured"]).reshape(len(times), n, 7)
        errs[label] = law.consensus_error(own, np.broadcast_to(desired, own.shape))
    e = errs["union"]
    k0, k1 = int(np.argmax(e < 0.3 * e.max())), int(np.argmax(e < 1e-9 * e.max()) or len(e) - 1)
    measured = -np.polyfit(times[k0:k1], np.log(e[k0:k1]), 1)[0]
    predicted = law.predicted_rate(a, dt, switching_period_s=1.0)
    assert predicted == switching_rate(a, 1.0, 2.0, dt) > 0.0
    assert abs(measured - predicted) <= 0.1 * predicted
    assert law.predicted_rate(split, dt, switching_period_s=1.0) == 0.0
    assert errs["split"][-1] >= 0.1 * errs["split"][0]
