"""Command-line interface ``quatform`` (top layer).

Errors are printed as one line, never a traceback: bad input (and a run too large for the
machine's memory) exits with status 2, file-system errors with 1, Ctrl-C with 130 and an
unexpected internal error with 3 (``QUATFORM_TRACEBACK=1`` shows its traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

from . import __version__
from .errors import QuatformError
from .papers import cited

#: Exit statuses.
EXIT_FILE_SYSTEM, EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 1, 2, 3, 130

CONTROLLER_NAMES = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")
FORMATION_NAMES = ("spherical", "restricted", "quaternion")


def _measurement_options(p):
    p.add_argument("--mocap-noise-m", type=float, metavar="SIGMA",
                   help="UGV-UAV: motion-capture position noise, standard deviation in m")
    p.add_argument("--mocap-latency-s", type=float, metavar="S", help="UGV-UAV: motion-capture latency in s")


def _feedforward_option(p):
    p.add_argument("--no-feedforward", action="store_true",
                   help="two-robot scenarios: drop the reference-velocity feedforward of the controllers "
                   "(seed 000 Fig. 13's runs; overrides the scenario's feedforward key)")


def _feedforward(sc, args):
    """The run's feedforward switch: off with --no-feedforward, else the scenario's (default on)."""
    if not getattr(args, "no_feedforward", False):
        return getattr(sc, "feedforward", True)
    if hasattr(sc, "mocap_noise_m") or hasattr(sc, "hand"):
        from .errors import InvalidInputError

        raise InvalidInputError(f"--no-feedforward applies to two-robot (seed 000) scenarios; {sc.name} is not one")
    return False


def _cited(source: str) -> list[str]:
    """The citations of the seed documents that a scenario's or plan's ``source`` names."""
    return [f"{p.tag}: {p.citation}" for p in cited(source)]


def _list(items):
    """``name  title (source)`` and, below it, the documents the source cites (authors, year, title)."""
    for name, title, source in items:
        print(f"{name:32s} {title} ({source})")
        for line in _cited(source):
            print(f"{'':32s}   {line}")


def _with_measurement(sc, args):
    import dataclasses

    from .errors import InvalidInputError

    # the values are checked with the scenario's own bounds (check_ugv_uav_scenario) below
    changes = {key: getattr(args, key) for key in ("mocap_noise_m", "mocap_latency_s")
               if getattr(args, key, None) is not None}
    if not changes:
        return sc
    if not hasattr(sc, "mocap_noise_m"):
        raise InvalidInputError("--mocap-noise-m and --mocap-latency-s apply to UGV-UAV scenarios only")
    from .scenarios.ugv_uav import check_ugv_uav_scenario

    sc = dataclasses.replace(sc, **changes)
    check_ugv_uav_scenario(sc, f"scenario {sc.name} with --mocap-noise-m/--mocap-latency-s")
    return sc


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), naming the command's --help."""

    def error(self, message):
        text = " ".join(str(message).split())
        if len(text) > 400:
            text = text[:396] + " ..."
        self.exit(EXIT_INPUT, f"{self.prog}: error: {text} (see '{self.prog} --help')\n")


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
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
    run.add_argument("--reference", metavar="PLAN",
                     help="two-robot scenarios: follow this plan file (from 'quatform plan', 2 robots in "
                     "space) instead of the scenario's path; yaws held at 0")
    run.add_argument("--backend", choices=("kinematic", "mujoco"), default="kinematic",
                     help='robot models (default) or MuJoCo physics (needs: pip install -e ".[mujoco]"); '
                     "mujoco adds collisions and a time-lapse picture")
    _feedforward_option(run)
    _measurement_options(run)

    plan = sub.add_parser(
        "plan",
        help="plan a formation motion (seed 002 shaped geodesics, seed 004 rigid formations on SE(3))",
        description="Solve SPEC (a built-in plan name, see 'quatform plans', or a .toml file) and write "
        "DIR/plan.npz, DIR/metrics.json (converged, solve_time_s, min_separation_m, deviations from the "
        "straight lines and from the rigid motion; for rigid-se3 specs also max_distance_change_m, "
        "max_nonholonomic_violation and energy) and PNG plots. Repeat --alpha to draw seed 002's "
        "panels: one folder per alpha and DIR/paths_by_alpha.png.",
    )
    plan.add_argument("spec", metavar="SPEC", help="built-in plan name or file.toml")
    plan.add_argument("--out", metavar="DIR", required=True, help="output folder")
    plan.add_argument("--alpha", type=float, action="append", metavar="A",
                      help="shaping weight in (0, 1) (overrides the spec's; repeatable)")
    plan.add_argument("--case", choices=("holonomic", "a", "b"),
                      help="seed 004 §4 airplanes: fully actuated robots, or airplanes ending as in case (a) or (b)")
    plan.add_argument("--no-plots", action="store_true", help="write the plan and metrics only")
    sub.add_parser("plans", help="list the built-in plan specs",
                   description="List the built-in plan specs with their titles and sources.")

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
                      help='robot models (default) or MuJoCo physics (two-robot scenarios; needs: '
                      'pip install -e ".[mujoco]")')
    _feedforward_option(cmp_)
    _measurement_options(cmp_)

    tele = sub.add_parser(
        "teleop",
        help="simulate a master-slave teleoperation scenario (seed 003)",
        description="Simulate SCENARIO (a built-in teleop-* name or a .toml file with kind = 'teleop'): "
        "the Kraft master, a 7-DOF slave, the operator's hand and the environment under seed 003's "
        "Euler-parameter stiffness controllers. Writes DIR/metrics.json, DIR/timeseries.csv and PNG plots.",
    )
    tele.add_argument("scenario", metavar="SCENARIO", help="built-in name (see 'quatform scenarios') or file.toml")
    tele.add_argument("--out", metavar="DIR", required=True, help="output folder")
    tele.add_argument("--orientation-error", choices=("euler-parameters", "rpy"),
                      help="the controllers' orientation error (default: the scenario's)")
    tele.add_argument("--preload", choices=("on", "off"),
                      help="the preload function on the master's actuators (default: the scenario's)")
    tele.add_argument("--no-plots", action="store_true", help="write metrics and time series only")

    sub.add_parser("scenarios", help="list the built-in scenarios",
                   description="List the built-in scenarios with their titles and sources.")
    return parser


def _compare(scenario, out, args=None):
    from .runs import UGV_UAV_COLUMNS, compare_scenario, compare_ugv_uav, format_table
    from .sim import load_scenario

    sc = load_scenario(scenario)
    if hasattr(sc, "hand"):
        from .errors import InvalidInputError

        raise InvalidInputError(f"{sc.name} is a teleoperation scenario: run it with 'quatform teleop {scenario} "
                                "--out DIR' (with --orientation-error or --preload to compare)")
    if args is not None:
        sc = _with_measurement(sc, args)
    if hasattr(sc, "mocap_noise_m"):
        _feedforward(sc, args)  # refuses --no-feedforward
        if getattr(args, "backend", "kinematic") != "kinematic":
            from .errors import InvalidInputError

            raise InvalidInputError("compare --backend mujoco takes two-robot scenarios; run a UGV-UAV one "
                                    "with: quatform run SCENARIO --backend mujoco")
        print(format_table(compare_ugv_uav(sc, out), UGV_UAV_COLUMNS))
        print(f"\nfiles in {out}/ (one folder per formation, compare_formations.png, comparison.md)")
        return
    rows = compare_scenario(sc, out, backend=getattr(args, "backend", "kinematic"), feedforward=_feedforward(sc, args))
    if not rows[0].get("feedforward", True):
        print("feedforward: off (--no-feedforward)")
    print(format_table(rows))
    print(f"\nfiles in {out}/ (one folder per controller, compare_errors.png, comparison.md)")


def _plan(args):
    from .errors import ConvergenceError
    from .plan_runs import meet_warning, plan_alphas_to_dir, plan_to_dir

    keys = ("converged", "solve_time_s", "min_separation_m", "max_straight_line_deviation_m",
            "max_rigid_deviation_m", "max_distance_change_m", "max_nonholonomic_violation", "energy")
    if args.case is not None:
        from .errors import InvalidInputError
        from .plan_runs import plan_case_to_dir

        if args.alpha is not None:
            raise InvalidInputError("--alpha (seed 002 shaping) and --case (seed 004 airplanes) do not go together")

        rows = {None: plan_case_to_dir(args.spec, args.out, args.case, plots=not args.no_plots)[1]}
    elif args.alpha is not None and len(args.alpha) > 1:
        rows = plan_alphas_to_dir(args.spec, args.out, args.alpha, plots=not args.no_plots)
    else:
        alpha = args.alpha[0] if args.alpha else None
        _, m = plan_to_dir(args.spec, args.out, alpha, plots=not args.no_plots)
        rows = {m.get("alpha"): m}
    failed = []
    for a, m in rows.items():
        cells = ", ".join(f"{k} = {m[k]:.4g}" if isinstance(m.get(k), float) else f"{k} = {m.get(k)}"
                          for k in keys if k in m)
        print(f"alpha = {a}: {cells}" if a is not None else cells)
        warning = meet_warning(m)
        if warning:
            print(f"quatform: warning: {warning}", file=sys.stderr)
        if not m["converged"]:
            failed.append(m["error"])
    print(f"files in {args.out}/")
    if failed:
        raise ConvergenceError(failed[0])


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


def _command(args) -> None:
    """Run the parsed command (every error propagates to :func:`main`)."""
    if args.command == "demo":
        _compare("mas-kitts-spiral", args.out)
    elif args.command == "compare":
        _compare(args.scenario, args.out, args)
    elif args.command == "run":
        from .errors import InvalidInputError
        from .runs import UGV_UAV_COLUMNS, run_scenario, run_ugv_uav
        from .sim import load_scenario

        sc = load_scenario(args.scenario)
        if hasattr(sc, "hand"):
            raise InvalidInputError(f"{sc.name} is a teleoperation scenario: run it with "
                                    f"'quatform teleop {args.scenario} --out DIR'")
        sc = _with_measurement(sc, args)
        if args.reference is not None:
            if hasattr(sc, "mocap_noise_m"):
                raise InvalidInputError(f"--reference applies to two-robot scenarios; {sc.name} is UGV-UAV")
            from .plan_runs import scenario_with_plan

            sc = scenario_with_plan(sc, args.reference)
        ff = _feedforward(sc, args)
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
                                      backend=args.backend, feedforward=ff)
            if not ff:
                print("feedforward: off (--no-feedforward)")
            _print_run(metrics)
    elif args.command == "teleop":
        from .errors import InvalidInputError
        from .runs import TELEOP_COLUMNS, format_table, run_teleop
        from .sim import load_scenario

        sc = load_scenario(args.scenario)
        if not hasattr(sc, "hand"):
            raise InvalidInputError(f"{sc.name} is not a teleoperation scenario: run it with "
                                    f"'quatform run {args.scenario} ...'")
        preload = None if args.preload is None else args.preload == "on"
        _, metrics = run_teleop(sc, args.out, args.orientation_error, preload, plots=not args.no_plots)
        print(format_table([metrics], TELEOP_COLUMNS))
    elif args.command == "plan":
        _plan(args)
    elif args.command == "plans":
        from .planning import builtin_plan_specs, load_plan_spec

        _list((name, spec.title, spec.source) for name, spec in
              ((name, load_plan_spec(name)) for name in sorted(builtin_plan_specs())))
    elif args.command == "scenarios":
        from .sim import builtin_scenarios, load_scenario

        _list((name, sc.title, sc.source) for name, sc in
              ((name, load_scenario(name)) for name in sorted(builtin_scenarios())))


def _say(line: str) -> None:
    """One line on stderr (after a newline if a progress line is open on a terminal)."""
    lead = "\n" if sys.stderr.isatty() else ""
    print(f"{lead}quatform: {line}", file=sys.stderr)


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A Python warning (e.g. NumPy's overflow) as one line, without the source line under it."""
    text = " ".join(str(message).split())[:300]
    print(f"quatform: warning: {category.__name__}: {text} ({os.path.basename(str(filename))}:{lineno})",
          file=sys.stderr if file is None else file)


def _what(args) -> str:
    """`` (COMMAND TARGET)`` for the one-line messages of :func:`main`."""
    target = getattr(args, "scenario", None) or getattr(args, "spec", None)
    return f"{args.command} {target}" if target else str(args.command)


@contextlib.contextmanager
def _sigint_ignored():
    """SIGINT ignored (not queued) inside the block, in the main thread; restored after it."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def main(argv: list[str] | None = None) -> int:
    """Run the ``quatform`` command; return its exit status (0 success, 1 file system, 2 bad
    input or too large, 3 internal error, 130 interrupted). Nothing but one line reaches stderr."""
    parser = _build_parser()
    args = None
    import warnings

    shown = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        _command(args)
    except QuatformError as exc:
        _say(f"error: {exc}")
        return EXIT_INPUT
    except KeyboardInterrupt:
        with _sigint_ignored():  # a second Ctrl-C while saying so must not end the process by the signal
            out = getattr(args, "out", None)
            _say("interrupted (Ctrl-C)" + (f"; {out} left as it was, no partial files written" if out else ""))
        return EXIT_INTERRUPTED
    except MemoryError:
        what = _what(args) if args is not None else "quatform"
        _say(f"error: out of memory running {what}; shorten the run or coarsen it (scenario duration_s / dt_s, "
             "plan knots) or set QUATFORM_MAX_MEMORY_BYTES lower so the work is refused up front")
        return EXIT_INPUT
    except RecursionError:
        _say(f"error: input nested too deeply for {_what(args) if args is not None else 'quatform'}; "
             "flatten the nested arrays or tables of the input file")
        return EXIT_INPUT
    except BrokenPipeError:
        # stdout went away (e.g. `quatform scenarios | head -1`): stop quietly, as other tools do
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return EXIT_FILE_SYSTEM
    except OSError as exc:
        msg = exc.strerror or str(exc) or type(exc).__name__
        name = str(exc.filename) if exc.filename is not None else ""
        if len(name) > 200:
            name = name[:90] + "..." + name[-90:]
        _say(f"error: {' '.join(f'{msg}: {name}'.split())}".rstrip(": ")[:500])
        return EXIT_FILE_SYSTEM
    except Exception as exc:  # noqa: BLE001 - no traceback may reach a user
        if os.environ.get("QUATFORM_TRACEBACK"):
            raise
        text = " ".join(str(exc).split())[:300]
        _say(f"internal error: {type(exc).__name__}: {text} (running {_what(args) if args is not None else 'quatform'}); "
             "please report it with the command line; QUATFORM_TRACEBACK=1 shows the traceback")
        return EXIT_INTERNAL
    finally:
        warnings.showwarning = shown
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
