"""Command-line interface ``quatform`` (top layer).

Errors are printed as one line: bad input exits with status 2, file-system errors with 1.
"""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .errors import QuatformError

CONTROLLER_NAMES = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")
FORMATION_NAMES = ("spherical", "restricted", "quaternion")


def _measurement_options(p):
    p.add_argument("--mocap-noise-m", type=float, metavar="SIGMA",
                   help="UGV-UAV: motion-capture position noise, standard deviation in m")
    p.add_argument("--mocap-latency-s", type=float, metavar="S", help="UGV-UAV: motion-capture latency in s")


def _with_measurement(sc, args):
    import dataclasses

    from .errors import InvalidInputError

    changes = {}
    for opt, field in (("mocap_noise_m", "mocap_noise_m"), ("mocap_latency_s", "mocap_latency_s")):
        v = getattr(args, opt, None)
        if v is not None:
            if not (v >= 0):
                raise InvalidInputError(f"--{opt.replace('_', '-')} must be >= 0, got {v!r}")
            changes[field] = v
    if not changes:
        return sc
    if not hasattr(sc, "mocap_noise_m"):
        raise InvalidInputError("--mocap-noise-m and --mocap-latency-s apply to UGV-UAV scenarios only")
    return dataclasses.replace(sc, **changes)


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="quatform",
        description="Singularity-free control of robot teams and robot arms with quaternions, "
        "dual quaternions and Euler parameters.",
    )
    parser.add_argument("--version", action="version", version=f"quatform {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="compare the four seed 000 controllers on the rising spiral",
        description="Run 'compare mas-kitts-spiral': the Euclidean cluster-space controller "
        "meets the singular pose at pitch 90 deg, the robot-space controller mis-reports the "
        "formation, the quaternion and dual-quaternion controllers track it. Writes every "
        "run's files and plots and prints the table.",
    )
    demo.add_argument("--out", metavar="DIR", default="quatform-demo",
                      help="output folder (default: ./quatform-demo)")

    run = sub.add_parser(
        "run",
        help="simulate one scenario with one controller",
        description="Simulate SCENARIO (a built-in name or a .toml file) and write DIR/metrics.json, "
        "DIR/timeseries.csv and PNG plots. Two-robot scenarios (seed 000) take --controller; "
        "UGV-UAV scenarios (seed 001) take --formation and the motion-capture options.",
    )
    run.add_argument("scenario", metavar="SCENARIO", help="built-in name (see 'quatform scenarios') or file.toml")
    run.add_argument("--controller", choices=CONTROLLER_NAMES,
                     help="controller of a two-robot (seed 000) scenario")
    run.add_argument("--formation", choices=FORMATION_NAMES,
                     help="formation description of a UGV-UAV (seed 001) scenario (default: quaternion)")
    run.add_argument("--out", metavar="DIR", required=True, help="output folder")
    run.add_argument("--no-plots", action="store_true", help="write metrics and time series only")
    run.add_argument("--backend", choices=("kinematic", "mujoco"), default="kinematic",
                     help="robot models (default) or MuJoCo physics (needs: pip install quatform[mujoco]); "
                     "mujoco adds collisions and a time-lapse picture")
    _measurement_options(run)

    cmp_ = sub.add_parser(
        "compare",
        help="run all four controllers on one scenario",
        description="Run SCENARIO with every controller (seed 000) or every formation description "
        "(seed 001 UGV-UAV) into DIR/<name>/, draw the errors side by side (seed 000 Fig. 13) and "
        "print a table.",
    )
    cmp_.add_argument("scenario", metavar="SCENARIO")
    cmp_.add_argument("--out", metavar="DIR", required=True, help="output folder")
    cmp_.add_argument("--backend", choices=("kinematic", "mujoco"), default="kinematic",
                      help="robot models (default) or MuJoCo physics (two-robot scenarios)")
    _measurement_options(cmp_)

    sub.add_parser("scenarios", help="list the built-in scenarios",
                   description="List the built-in scenarios with their titles and sources.")
    return parser


def _compare(scenario, out, args=None):
    from .runs import UGV_UAV_COLUMNS, compare_scenario, compare_ugv_uav, format_table
    from .sim import load_scenario

    sc = load_scenario(scenario)
    if args is not None:
        sc = _with_measurement(sc, args)
    if hasattr(sc, "mocap_noise_m"):
        if getattr(args, "backend", "kinematic") != "kinematic":
            from .errors import InvalidInputError

            raise InvalidInputError("compare --backend mujoco takes two-robot scenarios; run a UGV-UAV one "
                                    "with: quatform run SCENARIO --backend mujoco")
        print(format_table(compare_ugv_uav(sc, out), UGV_UAV_COLUMNS))
        print(f"\nfiles in {out}/ (one folder per formation, compare_formations.png, comparison.md)")
        return
    rows = compare_scenario(sc, out, backend=getattr(args, "backend", "kinematic"))
    print(format_table(rows))
    print(f"\nfiles in {out}/ (one folder per controller, compare_errors.png, comparison.md)")


def _print_run(metrics, columns=None):
    """The run's table row; a physics run: the kinematic row above it, and its collisions."""
    from .runs import TABLE_COLUMNS, format_table, physics_rows

    columns = columns or TABLE_COLUMNS
    if metrics.get("backend") != "mujoco":
        print(format_table([metrics], columns))
        return
    print(format_table(physics_rows(metrics), columns))
    c = metrics["collisions"]
    print(f"\ncollisions: {c['count']}" + (f" (first at t = {c['first_time_s']:.2f} s: {', '.join(c['bodies'])})"
                                           if c["count"] else ""))
    if metrics.get("render"):
        print(f"picture: {metrics['render']} ({metrics['render_backend']})")


def main(argv: list[str] | None = None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "demo":
            _compare("mas-kitts-spiral", args.out)
        elif args.command == "compare":
            _compare(args.scenario, args.out, args)
        elif args.command == "run":
            from .errors import InvalidInputError
            from .runs import UGV_UAV_COLUMNS, run_scenario, run_ugv_uav
            from .sim import load_scenario

            sc = _with_measurement(load_scenario(args.scenario), args)
            if hasattr(sc, "mocap_noise_m"):
                if args.controller is not None:
                    raise InvalidInputError(
                        f"{sc.name} is a UGV-UAV scenario: choose its description with --formation "
                        f"{{{','.join(FORMATION_NAMES)}}}, not --controller")
                _, metrics = run_ugv_uav(sc, args.formation or "quaternion", args.out, plots=not args.no_plots,
                                         backend=args.backend)
                _print_run(metrics, UGV_UAV_COLUMNS)
            else:
                if args.formation is not None:
                    raise InvalidInputError(f"{sc.name} is a two-robot scenario: --formation does not apply")
                if args.controller is None:
                    raise InvalidInputError(
                        f"{sc.name} is a two-robot scenario: give --controller "
                        f"{{{','.join(CONTROLLER_NAMES)}}}")
                _, metrics = run_scenario(sc, args.controller, args.out, plots=not args.no_plots,
                                          backend=args.backend)
                _print_run(metrics)
        elif args.command == "scenarios":
            from .sim import builtin_scenarios, load_scenario

            for name in sorted(builtin_scenarios()):
                sc = load_scenario(name)
                print(f"{name:24s} {sc.title} ({sc.source})")
    except QuatformError as exc:
        print(f"quatform: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"quatform: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
