"""A local law and the links as one controller of the loop (NetworkedController).

Oracles: the linear consensus's closed-form rate (the discrete loop ``x <- (I - k dt L) x``
of perfect links: ``Graph.predicted_rate(k, dt)``), the centralised Laplacian step on the
complete graph, NumPy against JAX (batched, delayed, lossy), and the links' own counts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from quatform.control.local_laws.position_consensus import PositionConsensus
from quatform.control.networked import NETWORK_SIGNALS, NetworkedController
from quatform.errors import InvalidInputError
from quatform.network import Graph, Links
from quatform.robots import FreeBodyRobot, HolonomicRobot, Team
from quatform.sim import simulate
from quatform.sim.plants.kinematic import KinematicTeam

DT = 0.01


def _setup(graph, links=None, gain=1.0, robot=None):
    n = graph.n
    team = Team.uniform(robot or HolonomicRobot(max_speed=1e3, max_yaw_rate=1e3), n, common_limit=False)
    links = links or Links(graph, max_age_s=0.5)
    ctrl = NetworkedController(PositionConsensus(gain), team, links, DT)
    a = 2 * np.pi * np.arange(n) / n
    off = np.c_[np.cos(a), np.sin(a), np.zeros(n)]
    ref = (lambda k: {"desired": off, "desired_rate": np.zeros((n, 3))})
    return team, ctrl, off, ref


def _x0(n, seed=0, batch=()):
    rng = np.random.default_rng(seed)
    x = np.zeros(batch + (n, 4))
    x[..., :3] = rng.normal(size=batch + (n, 3))
    return x.reshape(batch + (4 * n,))


def _disagreement(log, n, off):
    p = log["state"].reshape(log["state"].shape[:-1] + (n, 4))[..., :3] - off
    return np.linalg.norm(p - p.mean(axis=-2, keepdims=True), axis=(-2, -1))


@pytest.mark.parametrize("graph", [Graph.ring(8), Graph.ring(8, directed=False), Graph.complete(5),
                                   Graph(5, [(0, 1), (1, 2), (2, 3), (3, 4), (4, 0), (2, 0)],
                                         weights=[1.0, 2.0, 0.5, 1.5, 1.0, 0.7])],
                         ids=["directed-ring", "undirected-ring", "complete", "weighted-directed"])
def test_rate_is_lambda2s(graph):
    """Perfect links: the measured decay of the disagreement equals the discrete loop's predicted rate."""
    n = graph.n
    team, ctrl, off, ref = _setup(graph)
    times = np.arange(1500) * DT
    log = simulate(KinematicTeam(team), ctrl, ref, times, _x0(n))
    err = _disagreement(log, n, off)
    predicted = graph.predicted_rate(1.0, dt_s=DT)
    k0 = 200
    k1 = int(np.argmax(err < 1e-10 * err[0])) if np.any(err < 1e-10 * err[0]) else len(err) - 1
    slope = np.polyfit(times[k0:k1], np.log(err[k0:k1]), 1)[0]
    assert abs(-slope - predicted) <= 0.03 * predicted


def test_complete_graph_is_the_centralised_laplacian_step():
    """On the complete graph with perfect links every robot's command is the centralised
    ``-k L xi`` of the whole team (to rounding)."""
    g = Graph.complete(6)
    team, ctrl, off, ref = _setup(g, gain=0.8)
    times = np.arange(50) * DT
    log = simulate(KinematicTeam(team), ctrl, ref, times, _x0(6, 3))
    xi = log["state"].reshape(50, 6, 4)[..., :3] - off
    central = -0.8 * np.einsum("ij,tjk->tik", g.laplacian(), xi)
    u = log["command"].reshape(50, 6, 4)
    np.testing.assert_allclose(u[..., :3], central, rtol=0, atol=1e-12 * np.max(np.abs(central)))
    assert np.all(u[..., 3] == 0.0)


def test_network_signal_counts_the_links():
    g = Graph.ring(6, directed=False)
    links = Links(g, delay_s=0.03, jitter_s=0.02, drop=0.25, max_age_s=0.2, seed=4)
    team, ctrl, off, ref = _setup(g, links)
    times = np.arange(300) * DT
    log = simulate(KinematicTeam(team), ctrl, ref, times, _x0(6, 1, (3,)))
    net = log["network"]
    assert log.channels["network"].columns == NETWORK_SIGNALS
    sched = links.schedule(times, DT, (3,))
    assert ctrl.schedule(times, (3,))["messages_sent"].shape == (300, 3, 1)
    np.testing.assert_array_equal(net[..., 0], sched["messages_sent"])
    np.testing.assert_array_equal(net[..., 1], sched["messages_dropped"])
    np.testing.assert_array_equal(net[..., 2], sched["new"].sum(axis=-1))
    assert np.all(net[..., 3] <= 0.2 + 1e-12) and np.all(net[..., 3] >= 0.0)
    assert np.all(np.isfinite(log["command"]))


def test_jax_equals_numpy_batched_lossy():
    pytest.importorskip("jax")
    from quatform.sim.loop import simulate_jax
    g = Graph.ring(5)
    links = Links(g, delay_s=0.05, jitter_s=0.02, drop=0.2, max_age_s=0.3, seed=1)
    team, ctrl, off, ref = _setup(g, links)
    times = np.arange(120) * DT
    x0 = _x0(5, 2, (3,))
    a = simulate(KinematicTeam(team), ctrl, ref, times, x0)
    b = simulate_jax(KinematicTeam(team), ctrl, ref, times, x0)
    for name in a.channels:
        np.testing.assert_allclose(b[name], a[name], rtol=1e-9, atol=1e-12, err_msg=name)


def test_refusals_are_one_line():
    g = Graph.ring(3)
    holo = Team.uniform(HolonomicRobot(), 3, common_limit=False)
    with pytest.raises(InvalidInputError, match="max_age_s = inf"):
        NetworkedController(PositionConsensus(), holo, Links(g), DT)
    with pytest.raises(InvalidInputError, match="period_s"):
        NetworkedController(PositionConsensus(), holo, Links(g, max_age_s=1.0), -1.0)
    with pytest.raises(InvalidInputError, match="robots"):
        NetworkedController(PositionConsensus(), Team.uniform(HolonomicRobot(), 4, common_limit=False),
                            Links(g, max_age_s=1.0), DT)
    with pytest.raises(InvalidInputError, match="mixes robot models"):
        NetworkedController(PositionConsensus(), Team((HolonomicRobot(), HolonomicRobot(), FreeBodyRobot())),
                            Links(g, max_age_s=1.0), DT)
    ctrl = NetworkedController(PositionConsensus(), holo, Links(g, max_age_s=1.0), DT)
    with pytest.raises(InvalidInputError, match="period_s"):
        ctrl.schedule(np.arange(10) * 0.02)
    with pytest.raises(InvalidInputError, match="gain"):
        PositionConsensus(gain=math.nan)


def test_radio_range_cuts_the_far_edges():
    """Two groups 50 m apart on a complete graph: with a 10 m range they never hear each other
    (each group agrees within itself, the team does not); without it the team agrees."""
    g = Graph.complete(6)
    team = Team.uniform(HolonomicRobot(max_speed=1e3, max_yaw_rate=1e3), 6, common_limit=False)
    ref = (lambda k: {"desired": np.zeros((6, 3)), "desired_rate": np.zeros((6, 3))})
    x0 = np.zeros((6, 4))
    x0[:3, 0] = [0.0, 1.0, 2.0]
    x0[3:, 0] = [50.0, 51.0, 52.0]
    times = np.arange(400) * DT
    out = {}
    for r in (None, 10.0):
        ctrl = NetworkedController(PositionConsensus(2.0), team, Links(g, max_age_s=0.1), DT, range_m=r)
        x = simulate(KinematicTeam(team), ctrl, ref, times, x0.reshape(-1))["state"][-1].reshape(6, 4)[:, 0]
        out[r] = x
    assert np.ptp(out[None]) < 1e-3
    assert np.ptp(out[10.0][:3]) < 1e-3 and np.ptp(out[10.0][3:]) < 1e-3
    assert out[10.0][3] - out[10.0][0] == pytest.approx(50.0, abs=1e-6)
    with pytest.raises(InvalidInputError, match="range_m"):
        NetworkedController(PositionConsensus(), team, Links(g, max_age_s=0.1), DT, range_m=0.0)


def test_the_separation_filter_holds_every_pair_apart_under_delay_and_loss():
    """Robots told to meet at one point (every desired offset 0) on a lossy, delayed complete
    graph: each filters its own velocity, and no pair comes closer than the distance set;
    JAX equals NumPy with the filter in the loop."""
    from quatform.control.neighbour_barrier import NeighbourBarrier

    n = 8
    g = Graph.complete(n)
    team = Team.uniform(HolonomicRobot(max_speed=1.0, max_yaw_rate=1.0), n, common_limit=False)
    links = Links(g, delay_s=0.04, jitter_s=0.03, drop=0.2, max_age_s=0.3, seed=2)
    barrier = NeighbourBarrier(0.4, 1.0, gamma=10.0, dt_s=0.05)
    ctrl = NetworkedController(PositionConsensus(2.0), team, links, 0.05, safety=barrier, hold_unheard=True)
    ref = (lambda k: {"desired": np.zeros((n, 3)), "desired_rate": np.zeros((n, 3))})
    a = 2 * np.pi * np.arange(n) / n
    x0 = np.zeros((n, 4))
    x0[:, :3] = np.c_[2 * np.cos(a), 2 * np.sin(a), 0.1 * np.arange(n)]
    times = np.arange(200) * 0.05
    log = simulate(KinematicTeam(team), ctrl, ref, times, x0.reshape(-1))
    p = log["state"].reshape(200, n, 4)[..., :3]
    i, j = np.triu_indices(n, 1)
    gaps = np.linalg.norm(p[:, i] - p[:, j], axis=-1)
    assert gaps.min() >= 0.4 - 1e-12
    assert gaps.min() <= 0.6  # they did come close: the filter bound them
    assert log.channels["safety"].columns[:4] == ("binding1", "clearance_m1", "scale1", "fallback1")
    pytest.importorskip("jax")
    from quatform.sim.loop import simulate_jax

    b = simulate_jax(KinematicTeam(team), ctrl, ref, times[:60], x0.reshape(-1))
    a_ = simulate(KinematicTeam(team), ctrl, ref, times[:60], x0.reshape(-1))
    np.testing.assert_allclose(b["state"], a_["state"], rtol=1e-9, atol=1e-12)


def test_a_law_whose_command_is_not_finite_fails_the_world():
    """The robots' saturation would turn a NaN into 0: the world fails instead (one line), and a
    run of one world raises it."""
    import dataclasses as dc

    @dc.dataclass(frozen=True)
    class Broken(PositionConsensus):
        def tick(self, state, own, inbox, reference, t):
            out = super().tick(state, own, inbox, reference, t)
            return dc.replace(out, u=out.u * np.nan)

    g = Graph.ring(4)
    team = Team.uniform(HolonomicRobot(), 4, common_limit=False)
    ctrl = NetworkedController(Broken(), team, Links(g, max_age_s=0.1), DT)
    ref = (lambda k: {"desired": np.zeros((4, 3)), "desired_rate": np.zeros((4, 3))})
    log = simulate(KinematicTeam(team), ctrl, ref, np.arange(5) * DT, _x0(4, 0, (2,)))
    assert np.all(log.meta["failed"])
    assert "not finite" in log.meta["failure"][(0,)] and "\n" not in log.meta["failure"][(0,)]
    with pytest.raises(InvalidInputError, match="not finite"):
        simulate(KinematicTeam(team), ctrl, ref, np.arange(5) * DT, _x0(4))


def test_the_ring_of_held_messages_is_bounded():
    g = Graph.ring(3)
    team = Team.uniform(HolonomicRobot(), 3, common_limit=False)
    with pytest.raises(InvalidInputError, match="more than 1,000,000"):
        NetworkedController(PositionConsensus(), team, Links(g, max_age_s=1e6), DT)
    ctrl = NetworkedController(PositionConsensus(), team, Links(g, max_age_s=1e6), DT, run_ticks=50)
    assert ctrl.init()["links"]["ring"].shape == (50, 3, 6)


def test_each_robot_acts_at_its_own_rate():
    """A robot of rate r (links.rate_hz) computes and sends at its own ticks and holds its command
    between them; at the loop's rate it acts every tick."""
    g = Graph.ring(4, directed=False)
    team = Team.uniform(HolonomicRobot(max_speed=1e3, max_yaw_rate=1e3), 4, common_limit=False)
    ref = (lambda k: {"desired": np.zeros((4, 3)), "desired_rate": np.zeros((4, 3))})
    rates = [100.0, 50.0, 25.0, 10.0]  # every 1, 2, 4 and 10 ticks of 10 ms
    ctrl = NetworkedController(PositionConsensus(), team, Links(g, rate_hz=rates, max_age_s=0.5), DT)
    times = np.arange(40) * DT
    u = simulate(KinematicTeam(team), ctrl, ref, times, _x0(4, 3))["command"].reshape(40, 4, 4)[..., :3]
    for i, every in enumerate((1, 2, 4, 10)):
        changes = np.flatnonzero(np.any(np.diff(u[:, i], axis=0) != 0.0, axis=-1)) + 1
        assert np.all(changes % every == 0), (i, changes)
        assert len(changes) > 0
