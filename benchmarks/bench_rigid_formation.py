"""Time to plan seed 004 §4's five-airplane formation (holonomic, cases (a) and (b)).

For each case the script measures, best of ``--repeat`` runs (:mod:`timeit` style):

* **plan**: ``airplanes_plan(case)``, the whole planning procedure: input checks, the
  formation metric (eq. (15)), the constraint null spaces and the end twists that
  minimise the energy of the cubic (airplanes, §3.2; optimal within the cubic family
  only), the projected GA(3) curve, each robot's projected SO(3)
  geodesic (holonomic) or its velocity-aligned attitude (airplanes: an interpolated frame
  rate and an ODE solve, rtol 1e-12);
* **sample**: ``plan.sample(plan.times)``, all robots on the 201-sample grid (one
  batched call: SVD projection and analytic rates);
* **metrics**: ``plan.metrics()`` (several samplings, 64-node quadratures).

It also prints the checks of ``plan.metrics()``: the largest change of a pairwise
distance, the lateral speed of the airplanes at the ends and along the path, and the
ambient energy of the cubic (not the least over all curves with those ends and twists:
docs/derivations.md, "Planning (seeds 002 and 004)", item 4).

Run it from the repository root::

    python benchmarks/bench_rigid_formation.py             # 5 repeats (~15 s)
    python benchmarks/bench_rigid_formation.py --repeat 3
"""

from __future__ import annotations

import argparse

from _common import best_time, fmt, machine_description

from quatform.planning import AIRPLANE_CASES, airplanes_plan


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="repeats, best taken (default 5)")
    args = parser.parse_args(argv)
    print("\n".join(machine_description({})))
    print()
    print("| case | plan (ms) | sample 201 t (ms) | metrics (ms) | max distance change (m) "
          "| lateral speed at ends (m/s) | along path (m/s) | energy (J) |")
    print("|---|---|---|---|---|---|---|---|")
    for case in AIRPLANE_CASES:
        t_plan = best_time(lambda c=case: airplanes_plan(c), args.repeat, 0.2)
        plan = airplanes_plan(case)
        t_sample = best_time(lambda p=plan: p.sample(p.times), args.repeat, 0.2)
        t_metrics = best_time(plan.metrics, args.repeat, 0.2)
        m = plan.metrics()
        print(
            f"| {case} | {fmt(1e3 * t_plan)} | {fmt(1e3 * t_sample)} | {fmt(1e3 * t_metrics)} "
            f"| {m['max_distance_change_m']:.1e} | {m['max_nonholonomic_violation']:.1e} "
            f"| {m['max_path_nonholonomic_violation']:.1e} | {m['energy']:.2f} |"
        )


if __name__ == "__main__":
    main()
