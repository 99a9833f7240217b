"""Time of one tick of the decentralised separation barrier on a dense swarm, beside the centralised one.

The swarm: ``N`` robots (default 1 000) on a jittered cubic lattice of 1 m spacing (each
site moved by up to +-0.2 m per axis, so every pair is at least 0.6 m apart), the barrier
``d = 0.6`` m, ``gamma = 4`` 1/s, ``v_max = 1.5`` m/s. Each robot senses its ``k`` nearest
(default 6: ``N k`` sensed pairs, robot and neighbour), their positions as sent up to 50 ms
ago (each message's age uniform in ``[0, 0.05]`` s, the neighbour moved back along a random
direction by up to ``v_max age``). The nominal commands point at the swarm's centre at
``v_max``, so many halves bind. ``numpy.random.default_rng(seed)`` draws it all.

Timed (the median of ``--repeat`` calls, single world, NumPy):

* **neighbour**: :meth:`NeighbourBarrier.filter` of every robot at once (one tick of the
  team: each robot's filter is one row of it);
* **centralised**: :meth:`SeparationBarrier.filter` of the team's points as a layout of
  ``xyz`` points with the same ``d`` and ``gamma`` on the true positions (exact over every
  pair: its k-d tree finds the pairs within reach), and the ratio of the two times.

Printed beside them: the sensed pairs, the pairs whose half the nominal command breaks
(``binding``), the robots with at least one, those whose programme went to the fallback,
and the centralised programme's binding constraints.

Run it from the repository root::

    python benchmarks/bench_neighbour_barrier.py
    python benchmarks/bench_neighbour_barrier.py --robots 4000 --k 8 --repeat 51
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _common import fmt, machine_description
from scipy.spatial import cKDTree

from quatform.control.neighbour_barrier import NeighbourBarrier
from quatform.control.safety import SeparationBarrier
from quatform.formations.layout import RobotLayout

D_MIN, GAMMA, V_MAX, MAX_AGE = 0.6, 4.0, 1.5, 0.05


def swarm(n: int, k: int, seed: int):
    """``(u_nom, p, p_nb, age, valid)`` of the swarm described above."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.stack(np.meshgrid(*(np.arange(side, dtype=float),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)[:n]
    p = grid + rng.uniform(-0.2, 0.2, grid.shape)
    _, idx = cKDTree(p).query(p, k=k + 1)
    nb = idx[:, 1:]
    age = rng.uniform(0.0, MAX_AGE, (n, k))
    back = rng.normal(size=(n, k, 3))
    back *= (V_MAX * age * rng.uniform(0.0, 1.0, (n, k)) / np.linalg.norm(back, axis=-1))[..., None]
    p_nb = p[nb] - back
    centre = p.mean(axis=0)
    u_nom = V_MAX * (centre - p) / np.maximum(np.linalg.norm(centre - p, axis=-1, keepdims=True), 1e-9)
    return u_nom, p, p_nb, age, np.ones((n, k), dtype=bool)


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--k", type=int, default=6, help="neighbours each robot senses")
    parser.add_argument("--repeat", type=int, default=31)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    for line in machine_description({"scipy": True}):
        print(line)
    u_nom, p, p_nb, age, valid = swarm(args.robots, args.k, args.seed)
    bar = NeighbourBarrier(D_MIN, V_MAX, gamma=GAMMA)
    u, sig = bar.filter(u_nom, p, p_nb, age, valid)
    t_nb = median_time(lambda: bar.filter(u_nom, p, p_nb, age, valid), args.repeat)

    central = SeparationBarrier(D_MIN, gamma=GAMMA)
    layout = RobotLayout.uniform("xyz", args.robots)
    x, v = p.reshape(-1), u_nom.reshape(-1)
    _, info = central.filter(layout, x, v)
    t_c = median_time(lambda: central.filter(layout, x, v), max(3, args.repeat // 4))

    print(f"swarm   : {args.robots} robots, {args.k} nearest each, d = {D_MIN} m, gamma = {GAMMA} 1/s, "
          f"v_max = {V_MAX} m/s, ages up to {MAX_AGE * 1e3:.0f} ms")
    print(f"sensed pairs {int(valid.sum())}, binding pairs {int(sig['binding'].sum())}, robots with a binding "
          f"half {int((sig['binding'] > 0).sum())}, fallback {int(sig['fallback'].sum())}, scaled "
          f"{int((sig['scale'] < 1.0).sum())}")
    print(f"neighbour   tick (all robots): {fmt(t_nb * 1e3)} ms (median of {args.repeat})")
    print(f"centralised filter           : {fmt(t_c * 1e3)} ms ({int(info.constraints)} binding constraints), "
          f"{fmt(t_c / t_nb)} x the neighbour tick")


if __name__ == "__main__":
    main()
