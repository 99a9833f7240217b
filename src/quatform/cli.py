"""Command-line interface ``quatform`` (top layer).

Errors are printed as one line: bad input exits with status 2, file-system errors with 1.
"""

from __future__ import annotations

import argparse
import sys

from . import __version__
from .errors import QuatformError


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
        help="show quatform at work on the seeds' questions",
        description="Show the algebra at work: the seed 000 cluster frame with both "
        "dual-quaternion square roots, Euler-angle vs quaternion rates through pitch 90 deg, "
        "and the drift of the seed 001 integrators.",
    )
    demo.add_argument("--out", metavar="DIR", help="also write summary.json and demo.png to DIR")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "demo":
            from . import demo

            demo.run(args.out)
    except QuatformError as exc:
        print(f"quatform: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"quatform: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
