"""Command-line interface ``quatform`` (top layer).

Errors are printed as one line, never a traceback: bad input (and a run too large for the
machine's memory) exits with status 2, file-system errors with 1, Ctrl-C with 130, SIGTERM
where a command stops on it as on Ctrl-C (``quatform ros2``, a live run, which first writes its
folder) with 143, and an unexpected internal error with 3 (``QUATFORM_TRACEBACK=1`` shows its
traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass

from . import __version__
from .errors import QuatformError, Terminated

#: Exit statuses.
EXIT_FILE_SYSTEM, EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_TERMINATED = 1, 2, 3, 130, 143

#: The scenario kind ``quatform teleop`` runs (an alias of ``run`` for it).
TELEOP_KIND = "teleop"

_MUJOCO_NOTE = ('--physics mujoco simulates MuJoCo physics (needs: pip install -e ".[mujoco]") and adds '
                "collisions and a time-lapse picture.")


def _add_output_flags(p) -> None:
    """The output flags of the optional writers (:data:`quatform.outputs.WRITERS`): ``--no-mcap``
    (the ROS 2 bag every run writes), ``--rerun FILE.rrd`` (a Rerun recording) ..."""
    from .outputs import add_output_flags

    add_output_flags(p)


def _writers(args) -> dict:
    """The optional writers' choices of the parsed output flags."""
    from .outputs import output_choices

    return output_choices(args)


def _add_compute_flag(p) -> None:
    """``--compute`` (the closed loop's compute backend, :data:`quatform.sim.backends.SIM_BACKENDS`)."""
    from .sim.backends import SIM_BACKENDS

    p.add_argument("--compute", choices=tuple(SIM_BACKENDS), default="numpy",
                   help="compute backend of the closed loop: numpy (the reference, default) or jax (compiled with "
                   "jax.jit, float64, equal to NumPy within 1e-9, a chart's value near its singular set within "
                   "the digits it carries (docs/derivations.md); on a GPU when a CUDA JAX sees one; needs: "
                   'pip install -e ".[jax]"); not the same as --physics, which says what moves the robots')


def _cited(source: str) -> list[str]:
    """The citations of the seed documents that a scenario's or plan's ``source`` names."""
    from .papers import cited

    return [f"{p.tag}: {p.citation}" for p in cited(source)]


def _list(items):
    """``name  title (source)`` and, below it, the documents the source cites (authors, year, title)."""
    for name, title, source in items:
        print(f"{name:32s} {title} ({source})")
        for line in _cited(source):
            print(f"{'':32s}   {line}")


def _dashed(name: str) -> str:
    """An option's name as its flag spells it (``orientation_error`` -> ``orientation-error``)."""
    return name.replace("_", "-")


def _flag(option) -> str:
    """The command-line flag of a kind's option: ``--name`` (``_`` as ``-``); a switch that is on
    unless given (default True or None = the scenario's): ``--no-name``."""
    if option.type is bool and option.default is not False:
        return "--no-" + option.name.replace("_", "-")
    return option.flag


def _kind_options(kinds) -> dict:
    """The options of ``kinds`` by name, merged: ``{name: (option, kind names, choices)}``
    (choices: the union over the kinds, in order)."""
    merged: dict = {}
    for kind in kinds:
        for o in kind.options:
            first, names, choices = merged.get(o.name, (o, [], []))
            names.append(kind.name)
            choices.extend(c for c in (o.choices or ()) if c not in choices)
            merged[o.name] = (first, names, choices)
    return merged


def _add_kind_options(p, kinds) -> None:
    """The options of the scenario ``kinds`` as flags of the parser ``p`` (registry-built; each
    flag's help names the kinds that take it). Every value defaults to None: the kind's default."""
    for name, (o, names, choices) in _kind_options(kinds).items():
        which = f" [{', '.join(names)}]"
        if o.type is bool:
            const = o.default is False  # a switch off by default is turned on, else off
            p.add_argument(_flag(o), dest=name, action="store_const", const=const, default=None,
                           help=("" if const else "switch off: ") + o.help + which)
        elif o.choices is not None:
            p.add_argument(_flag(o), dest=name, choices=choices, default=None, help=o.help + which)
        else:
            p.add_argument(_flag(o), dest=name, type=o.type, default=None,
                           metavar=name.split("_")[-1].upper() if o.type is float else name.upper(),
                           help=o.help + which)


def _options(args, kinds) -> dict:
    """The kind options of the parsed ``args`` (None where not given)."""
    return {name: getattr(args, name) for name in _kind_options(kinds)}


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), naming the command's --help."""

    def error(self, message):
        text = " ".join(str(message).split())
        if len(text) > 400:
            text = text[:396] + " ..."
        self.exit(EXIT_INPUT, f"{self.prog}: error: {text} (see '{self.prog} --help')\n")

    def _backend_line(self) -> str | None:
        """The line for ``--backend`` on a command that has ``--compute`` but no ``--backend``
        (run, compare, teleop): it names the two flags a backend could mean, ``--physics`` (what
        moves the robots, where the command has it) and ``--compute`` (the closed loop's compute
        backend). None for a command without ``--compute``."""
        choices = {a.dest: a.choices for a in self._actions if a.dest in ("physics", "compute", "backend")}
        if "compute" not in choices or "backend" in choices:
            return None
        flags = [(name, f"--{dest} {'|'.join(choices[dest])}")
                 for dest, name in (("physics", "physics"), ("compute", "compute backend")) if choices.get(dest)]
        what = ", ".join(f"the {name}{' is' if k == 0 else ''} {flag}" for k, (name, flag) in enumerate(flags))
        return f"--backend is not an option of {self.prog.split()[-1]}: {what}"

    def parse_known_args(self, args=None, namespace=None):
        given = sys.argv[1:] if args is None else list(args)
        given = given[:given.index("--")] if "--" in given else given
        if any(arg.partition("=")[0] == "--backend" for arg in given):  # before a missing --out is named
            line = self._backend_line()
            if line is not None:
                self.error(line)
        return super().parse_known_args(args, namespace)




def _demo_arguments(demo) -> None:
    demo.description = (
        "Run 'compare mas-kitts-spiral': the Euclidean cluster-space controller "
        "meets the singular pose at pitch 90 deg, the robot-space controller mis-reports the "
        "formation, the quaternion and dual-quaternion controllers track it. Writes every "
        "run's files and plots (and run.mcap) and prints the table.")
    demo.add_argument("--out", metavar="DIR", default="quatform-demo",
                      help="output folder (default: ./quatform-demo)")
    _add_output_flags(demo)


def _run_arguments(run) -> None:
    from .scenarios import KINDS

    run.description = (
        "Simulate SCENARIO (a built-in name or a .toml file of any kind: "
        f"{', '.join(KINDS)}) and write DIR/metrics.json, DIR/timeseries.csv, PNG plots and DIR/run.mcap "
        "(a ROS 2 bag for Foxglove, PlotJuggler and ros2 bag; docs/ecosystem.md) with DIR/foxglove-layout.json. Each "
        "option below names the scenario kinds that take it (a kind refuses the others); a "
        "two-robot scenario (seed 000) needs --controller. " + _MUJOCO_NOTE)
    run.add_argument("scenario", metavar="SCENARIO", help="built-in name (see 'quatform scenarios') or file.toml")
    run.add_argument("--out", metavar="DIR", required=True, help="output folder")
    run.add_argument("--no-plots", action="store_true", help="write metrics and time series only")
    _add_output_flags(run)
    _add_compute_flag(run)
    run.add_argument("--live", metavar="[HOST:]PORT", default=None,
                     help="serve the run over the Foxglove WebSocket protocol while it goes (team scenarios; "
                          "Foxglove: Open connection -> Foxglove WebSocket -> ws://127.0.0.1:PORT): the topics of "
                          "run.mcap, a goal pose on /formation/goal moves the formation, the gains and the barrier's "
                          "distance are parameters, pause/resume; bound to 127.0.0.1 unless HOST is given; Ctrl-C "
                          "stops and writes the ticks done (needs: pip install -e \".[live]\"; docs/ecosystem.md)")
    run.add_argument("--realtime", metavar="FACTOR", type=float, default=None,
                     help="with --live: scenario seconds per wall-clock second (1 = wall clock, the default; "
                          "0 = as fast as it runs)")
    _add_kind_options(run, tuple(KINDS.values()))


def _plan_arguments(plan) -> None:
    plan.description = (
        "Solve SPEC (a built-in plan name, see 'quatform plans', or a .toml file) and write "
        "DIR/plan.npz, DIR/metrics.json (converged, solve_time_s, min_separation_m, deviations from the "
        "straight lines and from the rigid motion; for rigid-se3 specs also max_distance_change_m, "
        "max_nonholonomic_violation and energy) and PNG plots. Repeat --alpha to draw seed 002's "
        "panels: one folder per alpha and DIR/paths_by_alpha.png.")
    plan.add_argument("spec", metavar="SPEC", help="built-in plan name or file.toml")
    plan.add_argument("--out", metavar="DIR", required=True, help="output folder")
    plan.add_argument("--alpha", type=float, action="append", metavar="A",
                      help="shaping weight in (0, 1) (overrides the spec's; repeatable)")
    plan.add_argument("--case", choices=("holonomic", "a", "b"),
                      help="seed 004 §4 airplanes: fully actuated robots, or airplanes ending as in case (a) or (b)")
    plan.add_argument("--no-plots", action="store_true", help="write the plan and metrics only")


def _plans_arguments(p) -> None:
    p.description = "List the built-in plan specs with their titles and sources."


def _compare_arguments(cmp_) -> None:
    from .scenarios import KINDS

    kinds = tuple(KINDS.values())
    cmp_.description = (
        "Run SCENARIO with every value of its kind's compare option (the controllers of a "
        "two-robot scenario, the formation descriptions of a UGV-UAV one, the orientation errors of a "
        "teleoperation one), or of --over (e.g. --over physics: kinematic models against MuJoCo physics), "
        "into DIR/<value>/; draw them side by side (seed 000 Fig. 13) and print a table. The other "
        "options are fixed for every run. " + _MUJOCO_NOTE)
    cmp_.add_argument("scenario", metavar="SCENARIO")
    cmp_.add_argument("--out", metavar="DIR", required=True, help="output folder")
    axes = sorted({_dashed(o.name) for k in kinds for o in k.options if o.choices is not None})
    cmp_.add_argument("--over", metavar="OPTION", choices=axes, type=_dashed,
                      help=f"the option to vary: one of {', '.join(axes)} that the scenario's kind takes "
                      "(default: the kind's compare option)")
    cmp_.add_argument("--no-plots", action="store_true", help="write metrics, time series and the table only")
    _add_output_flags(cmp_)
    _add_compute_flag(cmp_)
    _add_kind_options(cmp_, kinds)


def _teleop_arguments(tele) -> None:
    from .scenarios import KINDS

    tele.description = (
        "Simulate SCENARIO (a built-in teleop-* name or a .toml file with kind = 'teleop'): "
        "the Kraft master, a 7-DOF slave, the operator's hand and the environment under seed 003's "
        "Euler-parameter stiffness controllers. Writes DIR/metrics.json, DIR/timeseries.csv and PNG plots. "
        "The same as 'quatform run' for a teleoperation scenario.")
    tele.add_argument("scenario", metavar="SCENARIO", help="built-in name (see 'quatform scenarios') or file.toml")
    tele.add_argument("--out", metavar="DIR", required=True, help="output folder")
    tele.add_argument("--no-plots", action="store_true", help="write metrics and time series only")
    _add_output_flags(tele)
    _add_compute_flag(tele)
    _add_kind_options(tele, (KINDS[TELEOP_KIND],))


def _scenarios_arguments(p) -> None:
    p.description = "List the built-in scenarios of every kind with their titles and sources."




def _build_parser(only=None) -> argparse.ArgumentParser:
    """The ``quatform`` parser: every subcommand by name (:data:`COMMANDS`), with its own
    options for the commands in ``only`` (default: all of them). ``quatform
    --help`` builds none, so it imports none of the layers below."""
    parser = _Parser(
        prog="quatform",
        description="Singularity-free control of robot teams and robot arms with quaternions, "
        "dual quaternions and Euler parameters.",
    )
    parser.add_argument("--version", action="version", version=f"quatform {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, command in COMMANDS.items():
        p = sub.add_parser(name, help=command.help)
        if only is None or name in only:
            command.arguments(p)
    return parser


def _given_command(argv) -> str | None:
    """The subcommand named in ``argv``: its first word that is not an option (the top-level
    options take no value), or None."""
    return next((a for a in argv if not a.startswith("-")), None)


def _compare(scenario, out, options=None, over=None, plots=True, writers=None, compute="numpy") -> None:
    from .runs import compare, compare_columns, format_table, given_options
    from .scenarios import kind_of, load_scenario
    from .sim.output import check_inputs_outside

    check_inputs_outside(out, scenario)  # a scenario file in --out: refused before any work
    sc = load_scenario(scenario)
    kind = kind_of(sc)
    options = given_options(kind, options or {}, where=str(sc.name), spell=_flag)
    rows = compare(sc, out, over=over, plots=plots, writers=writers, compute=compute, spell=_flag,
                   over_spell=_dashed, **options)
    _say_options(kind, options)
    axis = over or kind.compare_over
    print(format_table(rows, compare_columns(kind, axis, sc)))
    drawn = ", the compare plots" if plots else ""
    print(f"\nfiles in {out}/ (one folder per {axis.replace('_', ' ')}{drawn}, comparison.md)")
    _say_recordings(writers)


def _say_options(kind, options) -> None:
    """One stdout line per switch turned off (``feedforward: off (--no-feedforward)``)."""
    for o in kind.options:
        if o.type is bool and options.get(o.name) is False:
            print(f"{o.name.replace('_', ' ')}: off ({_flag(o)})")


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


def _print_run(metrics, columns) -> None:
    """The run's table row; a physics run: its collisions and picture below it."""
    from .runs import format_table

    print(format_table([metrics], columns))
    c = metrics.get("collisions")
    if c is not None:
        print(f"\ncollisions: {c['count']}" + (f" (first at t = {c['first_time_s']:.2f} s: {', '.join(c['bodies'])})"
                                               if c["count"] else ""))
    if metrics.get("render"):
        print(f"picture: {metrics['render']} ({metrics['render_backend']})")


def _run(args, kinds) -> int | None:
    """``quatform run`` (and ``teleop``): one run of any kind with the given options; a live run
    stopped by a signal returns ``128 + signal`` (130 SIGINT, 143 SIGTERM)."""
    from .runs import given_options, run
    from .scenarios import kind_of, load_scenario
    from .sim.output import check_inputs_outside

    check_inputs_outside(args.out, args.scenario)  # a scenario file in --out: refused before any work
    sc = load_scenario(args.scenario)
    kind = kind_of(sc)
    if args.command == "teleop" and kind.name != TELEOP_KIND:
        from .errors import InvalidInputError

        raise InvalidInputError(f"{sc.name} is not a teleoperation scenario (its kind is {kind.name}): run it "
                                f"with 'quatform run {args.scenario} ...'")
    options = given_options(kind, _options(args, kinds), where=str(sc.name), spell=_flag)
    writers = _writers(args)
    live = getattr(args, "live", None)
    if live is None and getattr(args, "realtime", None) is not None:
        from .errors import InvalidInputError

        raise InvalidInputError("--realtime paces a live run; give --live [HOST:]PORT too")
    if live is not None:
        metrics = _live(args, sc, options, writers)
    else:
        _, metrics = run(sc, args.out, plots=not args.no_plots, writers=writers, compute=args.compute, **options)
    _say_options(kind, options)
    _print_run(metrics, kind.columns_of(sc))
    _say_recordings(writers)
    signum = metrics.get("live", {}).get("signal")
    return None if signum is None else 128 + int(signum)


def _live(args, sc, options, writers) -> dict:
    """``quatform run --live``: the run served over the Foxglove WebSocket protocol
    (:func:`quatform.live.server.serve`); its folder written when it ends or is stopped."""
    from .errors import InvalidInputError
    from .live import LiveSession
    from .live.server import parse_address, require_foxglove, serve

    if args.compute != "numpy":
        raise InvalidInputError(f"--live steps the run on NumPy, tick by tick; drop --compute {args.compute}")
    host, port = parse_address(args.live)
    require_foxglove()  # before any work
    session = LiveSession(sc, options)
    realtime = 1.0 if args.realtime is None else args.realtime
    _, metrics = serve(session, args.out, host=host, port=port, realtime=realtime, plots=not args.no_plots,
                       writers=writers, inputs=(args.scenario, options.get("reference")))
    return metrics


def _say_recordings(writers) -> None:
    """One stdout line per recording written (``rerun recording: FILE.rrd``)."""
    from .outputs import WRITERS

    for name, value in (writers or {}).items():
        if WRITERS[name].records and value is not None:
            print(f"{name} recording: {value}")


def _plans(args) -> None:
    from .planning import builtin_plan_specs, load_plan_spec

    _list((name, spec.title, spec.source) for name, spec in
          ((name, load_plan_spec(name)) for name in sorted(builtin_plan_specs())))


def _scenarios(args) -> None:
    from .scenarios import builtin_scenarios, kind_of, load_scenario

    loaded = ((name, load_scenario(name)) for name in sorted(builtin_scenarios()))
    _list((name, f"{sc.title} [{kind_of(sc).name}]", sc.source) for name, sc in loaded)


def _sweeps_cli():
    from .sweeps import cli

    return cli


def _kinds():
    from .scenarios import KINDS

    return KINDS


def _ros2_cli():
    from .ros2 import cli

    return cli


@dataclass(frozen=True)
class Command:
    """A subcommand: its one-line help, the function adding its description and options to its
    parser (importing the modules they come from: the scenario kinds, the compute backends, the
    sweeps, the ROS 2 bridge), and the function running it on the parsed arguments."""

    help: str
    arguments: Callable
    run: Callable


#: Every subcommand, in the order ``quatform --help`` lists them. The top-level parser is built
#: from the names and help lines alone; a command's options only for the command given
#: (:func:`_build_parser`), so ``quatform --help`` imports none of the layers below.
COMMANDS = {
    "demo": Command(
        "compare the four seed 000 controllers on the rising spiral",
        _demo_arguments,
        lambda args: _compare("mas-kitts-spiral", args.out, writers=_writers(args))),
    "run": Command(
        "simulate one scenario of any kind with one choice",
        _run_arguments,
        lambda args: _run(args, _kinds().values())),
    "plan": Command(
        "plan a formation motion (seed 002 shaped geodesics, seed 004 rigid formations on SE(3))",
        _plan_arguments,
        _plan),
    "plans": Command(
        "list the built-in plan specs",
        _plans_arguments,
        _plans),
    "compare": Command(
        "run every choice of one option (every controller, every formation description ...) on one scenario",
        _compare_arguments,
        lambda args: _compare(args.scenario, args.out, _options(args, _kinds().values()),
                              args.over and args.over.replace("-", "_"),
                              not args.no_plots, _writers(args), args.compute)),
    "teleop": Command(
        "simulate a master-slave teleoperation scenario (seed 003; 'run' for teleop scenarios)",
        _teleop_arguments,
        lambda args: _run(args, (_kinds()[TELEOP_KIND],))),
    "scenarios": Command(
        "list the built-in scenarios of every kind",
        _scenarios_arguments,
        _scenarios),
    "sweep": Command(
        "run a Monte Carlo sweep (controllers x noise, latency, gains, starts, team sizes)",
        lambda p: _sweeps_cli().sweep_arguments(p),
        lambda args: _sweeps_cli().sweep_command(args)),
    "sweeps": Command(
        "list the built-in sweeps",
        lambda p: _sweeps_cli().sweeps_arguments(p),
        lambda args: _sweeps_cli().sweeps_command(args)),
    "ros2": Command(
        "drive real robots over ROS 2 with a scenario's controller (needs a sourced ROS 2)",
        lambda p: _ros2_cli().ros2_arguments(p),
        lambda args: _ros2_cli().run_ros2(args)),
    "replay": Command(
        "run a controller offline on a recorded bag's poses and write what it would have commanded",
        lambda p: _ros2_cli().replay_arguments(p),
        lambda args: _ros2_cli().run_replay(args)),
}


def _command(args) -> int | None:
    """Run the parsed command (every error propagates to :func:`main`); a nonzero exit status
    it returns (a live run stopped by a signal) is the command's."""
    return COMMANDS[args.command].run(args)


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
    input or too large, 3 internal error, 130 interrupted, 143 terminated). Nothing but one line
    reaches stderr."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = _build_parser(only=(_given_command(argv),))  # only the command given: 'quatform --help' stays light
    args = None
    import warnings

    shown = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        status = _command(args)
        if type(status) is int and status:  # noqa: E721 - an exit status, never another command's value
            return status
    except QuatformError as exc:
        _say(f"error: {exc}")
        return EXIT_FILE_SYSTEM if isinstance(exc, OSError) else EXIT_INPUT  # OutputWriteError: a full disk
    except KeyboardInterrupt as exc:
        why = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted (Ctrl-C)"
        with _sigint_ignored():  # a second Ctrl-C while saying so must not end the process by the signal
            out = getattr(args, "out", None)
            if getattr(args, "command", None) == "sweep" and out:  # a sweep keeps its finished chunks
                kept = "trials" if os.path.isdir(os.path.join(out, "trials")) else "chunks"  # Parquet shards or JSON
                _say(f"{why}; the chunks finished so far are kept in {out}/{kept} and no table was "
                     "written: rerun the same command to resume")
            else:
                _say(why + (f"; {out} left as it was, no partial files written" if out else ""))
        return EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED
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
