"""Command-line interface ``quatform`` (top layer).

Errors are printed as one line: bad input exits with status 2, file-system errors with 1.
"""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .errors import QuatformError

CONTROLLER_NAMES = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")


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
        "DIR/timeseries.csv and PNG plots.",
    )
    run.add_argument("scenario", metavar="SCENARIO", help="built-in name (see 'quatform scenarios') or file.toml")
    run.add_argument("--controller", required=True, choices=CONTROLLER_NAMES)
    run.add_argument("--out", metavar="DIR", required=True, help="output folder")
    run.add_argument("--no-plots", action="store_true", help="write metrics and time series only")

    cmp_ = sub.add_parser(
        "compare",
        help="run all four controllers on one scenario",
        description="Run SCENARIO with every controller into DIR/<controller>/, draw the errors in "
        "Euclidean cluster variables side by side (seed 000 Fig. 13) and print a table.",
    )
    cmp_.add_argument("scenario", metavar="SCENARIO")
    cmp_.add_argument("--out", metavar="DIR", required=True, help="output folder")

    sub.add_parser("scenarios", help="list the built-in scenarios",
                   description="List the built-in scenarios with their titles and sources.")
    return parser


def _compare(scenario, out):
    from .runs import compare_scenario, format_table

    rows = compare_scenario(scenario, out)
    print(format_table(rows))
    print(f"\nfiles in {out}/ (one folder per controller, compare_errors.png, comparison.md)")


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
            _compare(args.scenario, args.out)
        elif args.command == "run":
            from .runs import format_table, run_scenario

            _, metrics = run_scenario(args.scenario, args.controller, args.out, plots=not args.no_plots)
            print(format_table([metrics]))
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
