"""The dual-quaternion local laws against their theory: rates against λ₂, and what converges.

Two measurements, each through :class:`~quatform.control.networked.NetworkedController` and
:func:`quatform.sim.simulate` with perfect links (free bodies, kinematic plant, NumPy):

* **rates**: for ``dq-laplacian`` and ``dq-consensus`` on four 6-robot graphs (directed ring,
  undirected ring, a weighted directed graph with a spanning tree, complete graph), the rate
  at which the consensus error decays from a start near the formation (slope of its log
  between ``2 / r`` and ``min(12 / r, 14 s)``, ``r`` the predicted rate; dt 0.02 s, gain 1/s) against ``Graph.predicted_rate`` (continuous
  ``k Re λ₂`` and the loop's discrete rate);
* **random starts**: ``--worlds`` (1 000) random poses (uniform rotations, positions from a unit
  normal) on a 6-robot undirected ring, one batch of worlds per law, 20 s: the fraction whose
  consensus error ends below 1e-3 (and, for the Laplacian law, the fraction whose ring loop of
  shortest-way relative rotations is contractible in SO(3)); the same on the complete graph.

Run it from the repository root (about 3 minutes on the 2-core machine)::

    PYTHONPATH=src python benchmarks/bench_dq_laws.py
    PYTHONPATH=src python benchmarks/bench_dq_laws.py --worlds 200
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from quatform.algebra import dq_from_pose, dqmul, pose_from_dq
from quatform.control.local_laws import dq_pose as dqk
from quatform.control.local_laws.dq_consensus import DQConsensus, log_coordinates
from quatform.control.local_laws.dq_laplacian import DQLaplacian
from quatform.control.networked import NetworkedController
from quatform.network import Graph, Links
from quatform.robots import FreeBodyRobot, Team
from quatform.sim import simulate
from quatform.sim.plants.kinematic import KinematicTeam

N = 6
LAWS = {"dq-laplacian": DQLaplacian, "dq-consensus": DQConsensus}
GRAPHS = {
    "directed ring": Graph.ring(N),
    "undirected ring": Graph.ring(N, directed=False),
    "weighted directed": Graph.from_edges(N, [(1, 0), (2, 1), (3, 2), (4, 3), (5, 4), (0, 5), (2, 0), (4, 1)],
                                          weights=[1.0, 2.0, 0.5, 1.5, 1.0, 0.7, 0.3, 0.8]),
    "complete": Graph.complete(N),
}


def unit_q(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def state(x):
    q, t = pose_from_dq(x)
    return np.concatenate([t, q], axis=-1).reshape(x.shape[:-2] + (-1,))


def run(law, graph, x_d, x0, dt, ticks):
    team = Team.uniform(FreeBodyRobot(max_speed=1e3, max_angular_rate=1e3), N, common_limit=False)
    ctrl = NetworkedController(LAWS[law](1.0), team, Links(graph, max_age_s=0.5), dt)
    times = np.arange(ticks) * dt
    log = simulate(KinematicTeam(team), ctrl, lambda k: {"pose": x_d}, times, state(x0))
    s = np.asarray(log.channels["state"].data)
    y = dqk.formation_variable(dqk.pose_dq(s.reshape(s.shape[:-1] + (N, 7))), x_d)
    z = dqk.aligned(y, y[..., :1, :]) if law == "dq-laplacian" else log_coordinates(y)
    return times, np.linalg.norm(z - z.mean(axis=-2, keepdims=True), axis=(-1, -2))


def contractible(y0):
    s = y0[..., 0, :]
    for i in range(1, N):
        s = dqk.aligned(y0[..., i, :], s)
    return np.sum(dqk.aligned(y0[..., 0, :], s)[..., :4] * y0[..., 0, :4], axis=-1) > 0


def rates(dt: float = 0.02):
    print("| law | graph | λ₂ | predicted k λ₂ | predicted, dt 0.02 s | measured | measured / predicted (dt) |")
    print("|---|---|---|---|---|---|---|")
    for law in LAWS:
        for name, g in GRAPHS.items():
            rng = np.random.default_rng(0)
            x_d = dq_from_pose(unit_q(rng, (N,)), rng.normal(size=(N, 3)))
            c = dq_from_pose(unit_q(rng, ()), rng.normal(size=3))
            axis = rng.normal(size=(N, 3))
            half = 0.3 * rng.uniform(0.3, 1.0, size=(N, 1))
            p = np.concatenate([np.cos(half), np.sin(half) * axis / np.linalg.norm(axis, axis=1, keepdims=True)], 1)
            x0 = dqmul(dqmul(c, dq_from_pose(p, 0.5 * rng.normal(size=(N, 3)))), x_d)
            times, err = run(law, g, x_d, x0, dt, 800)
            pd = g.predicted_rate(1.0, dt_s=dt)
            # from e^-2 of the start to e^-12 (or 14 s), above the rounding floor
            i0, i1 = np.searchsorted(times, [2.0 / pd, min(12.0 / pd, 14.0)])
            measured = -(np.log(err[i1]) - np.log(err[i0])) / (times[i1] - times[i0])
            pc = g.predicted_rate(1.0)
            print(f"| {law} | {name} | {g.lambda2():.4f} | {pc:.4f} | {pd:.4f} | {measured:.4f} | {measured / pd:.4f} |")


def random_starts(worlds: int, dt: float = 0.02, seconds: float = 20.0):
    print(f"\n| law | graph | worlds | converged (error < 1e-3 at {seconds:g} s) | loop contractible | wall s |")
    print("|---|---|---|---|---|---|")
    for law, name in (("dq-laplacian", "undirected ring"), ("dq-consensus", "undirected ring"),
                      ("dq-laplacian", "directed ring"), ("dq-laplacian", "complete")):
        rng = np.random.default_rng(1)
        x_d = dq_from_pose(unit_q(rng, (N,)), rng.normal(size=(N, 3)))
        x0 = dq_from_pose(unit_q(rng, (worlds, N)), rng.normal(size=(worlds, N, 3)))
        t0 = time.perf_counter()
        _, err = run(law, GRAPHS[name], x_d, x0, dt, int(round(seconds / dt)))
        wall = time.perf_counter() - t0
        loop = contractible(dqk.formation_variable(x0, x_d)).mean() if "ring" in name else float("nan")
        print(f"| {law} | {name} | {worlds} | {np.mean(err[-1] < 1e-3):.3f} | {loop:.3f} | {wall:.1f} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=1000, help="random starts per law (default 1000)")
    args = parser.parse_args()
    rates()
    random_starts(args.worlds)


if __name__ == "__main__":
    main()
