"""Solve time of seed 002's shaped geodesics (quatform.planning.solve_geodesic) for N robots.

For N = 2, 3, 5, 10 robots (default) in the plane and in space, the end configurations are
the seed's rigid displacement scaled up to N: a regular N-gon of unit circumradius (in space
tilted out of the x-y plane by 0.3 rad about x and with alternate robots lifted by 0.2 m, so
no three are collinear), centre of mass (0, 0, 0) -> (3, 0, 0), turned by 3 pi/4 about -z;
masses 1, 2, 1, 2, ... Each solve is the full call: continuation in alpha from 0.5, the
collocation solve (scipy.integrate.solve_bvp, tol 1e-6) and the forward-integration check.
Times are the median of ``--repeat`` runs (time.perf_counter). The last rows time alpha =
0.2 on the ends of N = 2 and 3 equal masses: two bodies have no geodesic (seed 002 item 3 of
docs/derivations.md) and the call raises ConvergenceError at once (the cone bound is checked
first); for three the continuation stalls near 0.37 and the restart from a path-energy
minimiser finds a symmetry-breaking geodesic.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from _common import fmt, machine_description

from quatform.errors import ConvergenceError
from quatform.planning import solve_geodesic


def ends(N: int, d: int):
    ang = 2 * np.pi * np.arange(N) / N
    p = np.stack([np.cos(ang), np.sin(ang), np.zeros(N)], 1)
    if d == 3:
        c, s = np.cos(0.3), np.sin(0.3)
        p = p @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T
        p[1::2, 2] += 0.2
    m = np.where(np.arange(N) % 2, 2.0, 1.0)
    p = p - (m[:, None] * p).sum(0) / m.sum()
    th = -3 * np.pi / 4
    Rz = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    q1 = p @ Rz.T + [3.0, 0.0, 0.0]
    return p[:, :d], q1[:, :d], m


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[2, 3, 5, 10], help="robot counts")
    ap.add_argument("--alpha", type=float, nargs="+", default=[0.99, 0.7], help="shaping weights")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    for line in machine_description({"scipy": True}):
        print(line)
    print()
    print("| N | d | alpha | solve (s) | nodes | continuation steps |")
    print("|---|---|---|---|---|---|")
    for d in (2, 3):
        for N in args.n:
            q0, q1, m = ends(N, d)
            for a in args.alpha:
                times = []
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    sol = solve_geodesic(q0, q1, m, a)
                    times.append(time.perf_counter() - t0)
                print(f"| {N} | {d} | {a:g} | {fmt(statistics.median(times))} | {sol.s.size} | "
                      f"{len(sol.continuation)} |")
    print()
    for N in (2, 3):  # two bodies: the cone bound, checked first; three: stall, then restart
        q0, q1, _ = ends(N, 2)
        t0 = time.perf_counter()
        try:
            sol = solve_geodesic(q0, q1, np.ones(N), 0.2)
            print(f"N = {N}, equal masses, alpha = 0.2: solved ({sol.guess}, energy {sol.energy:.6g}) after "
                  f"{time.perf_counter() - t0:.3g} s")
        except ConvergenceError as exc:
            print(f"failure (N = {N}, equal masses, alpha = 0.2): ConvergenceError after "
                  f"{time.perf_counter() - t0:.3g} s: {str(exc)[:100]}...")


if __name__ == "__main__":
    main()
