"""Run and compare any scenario and write its files (top layer, used by the CLI).

One :func:`run` and one :func:`compare` for every scenario kind of
:data:`quatform.scenarios.KINDS`. A run builds the kind's
:class:`~quatform.scenarios.base.Experiment` for the chosen options, simulates it
(``log = experiment.run(progress)``), computes its metrics from the log, draws the kind's
figures (:func:`quatform.report.figures_of`) and writes every chosen writer's files through
the registry :data:`quatform.outputs.WRITERS`, in their order: ``timeseries.csv`` (the kind's
``csv_channels``), ``run.mcap`` (the log as ROS 2 messages, with ``foxglove-layout.json``
beside it; ``mcap=False`` skips both), any other registered writer, and ``metrics.json``
last. ``rerun=FILE.rrd`` also writes the run (a compare: every run, each under
``/<value>/``) as a Rerun recording (extra ``rerun``; its name and folder checked before
anything runs; written before the output folder is swapped in, so an interrupted run leaves
neither); ``writers={name: choice}`` switches any optional writer. A compare runs every value of one option (the kind's ``compare_over``, or ``over``:
``physics`` compares the kinematic models with MuJoCo physics) into ``out/<value>/``, then draws
the kind's compare figures and writes ``comparison.md`` / ``comparison.json`` with the kind's
table columns.

Besides the experiment, a run reads two conventions of the log's ``meta``: a physics run's
plant record under ``"physics_record"`` (its time-lapse picture is drawn when plots are, and
``metrics.json`` gets ``render`` / ``render_backend``), and ``"unreachable_at"`` /
``"unreachable_message"`` (when the reference left what the description can express;
printed on stderr).

Every output folder is built with :func:`~quatform.sim.output.staged_dir`: the files appear
under ``out`` only when the whole run has finished; a failed or interrupted run leaves ``out``
as it was.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from .checks import nearest
from .errors import InvalidInputError
from .report import figures_of
from .outputs import RunFiles, chosen_writers, writer_choices
from .report.writers import write_json
from .scenarios import Option, kind_of, load_scenario
from .sim.backends import simulator
from .sim.output import atomic_write_text, staged_dir

__all__ = ["run", "compare", "format_table", "compare_columns", "progress_line", "given_options", "write_outputs",
           "record_options", "record_runs", "check_physics_on"]


def progress_line(label: str):
    """Progress on a terminal (one updating line); nothing when stderr is a file or pipe."""
    if not sys.stderr.isatty():
        return None

    def report(fraction):
        print(f"\r  {label}: {fraction:4.0%}", end="", file=sys.stderr, flush=True)
    return report


def _scenario(scenario):
    """A loaded scenario: ``scenario`` itself, or the file or built-in name it is."""
    return load_scenario(scenario) if isinstance(scenario, (str, os.PathLike)) else scenario


def given_options(kind, options: dict, *, where: str, spell=None) -> dict:
    """``options`` without the ones left unset (None), each checked to be one of ``kind``'s.

    An option the kind does not take is one line naming the kind, the option and the options
    it takes; a value outside an option's choices names them. ``spell(option)`` is how an
    option is named in those lines (the CLI: its flag; default: the keyword).
    """
    spell = spell or (lambda option: option.name)
    own = {o.name: o for o in kind.options}
    given = {k: v for k, v in options.items() if v is not None}
    for name, value in given.items():
        if name not in own:
            takes = ", ".join(spell(o) for o in kind.options) or "no options"
            label = spell(Option(name, "", type=type(value)))
            raise InvalidInputError(f"{where} is a {kind.name} scenario: {label} does not apply to it; "
                                    f"it takes {takes}")
        choices = own[name].choices
        if choices is not None and value not in choices:
            raise InvalidInputError(f"{where}: {spell(own[name])} = {value!r} is not one of {', '.join(choices)}"
                                    f"{nearest(str(value), choices)}")
    return given


def record_options(kind, experiment, metrics: dict) -> dict:
    """``metrics`` plus the resolved value of each of the kind's options that the experiment's
    ``meta`` records and the metrics do not already hold (e.g. ``feedforward``)."""
    for option in kind.options:
        if option.name in experiment.meta and option.name not in metrics:
            metrics[option.name] = experiment.meta[option.name]
    return metrics


def _run_into(kind, sc, folder: Path, shown, plots: bool, quiet: bool, options: dict, writers=None,
              compute: str = "numpy"):
    """One run of ``sc`` with ``options`` written into ``folder`` (made here; ``shown``: the path
    printed; ``writers``: the folder writers, :func:`quatform.outputs.chosen_writers`, default
    every one written by default; ``compute``: the closed loop's backend,
    :data:`quatform.sim.backends.SIM_BACKENDS`). Returns ``(log, metrics)``."""
    folder.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    experiment = kind.experiment(sc, **options)
    label = f"{sc.name} / {experiment.label}" if experiment.label else str(sc.name)
    shown_progress = None if quiet else progress_line(label)
    log = experiment.run(shown_progress) if compute == "numpy" else experiment.run(shown_progress, backend=compute)
    metrics = record_options(kind, experiment, dict(experiment.metrics(log)))
    if compute != "numpy":  # the reference's files stay as they were
        metrics["compute_backend"] = compute
    metrics["wall_time_s"] = round(time.perf_counter() - t0, 3)
    write_outputs(kind, sc, experiment, log, folder, metrics, plots, writers)
    if not quiet:
        if log.meta.get("unreachable_at") is not None:
            print(f"\r  {label}: reference unreachable from t = {log.meta['unreachable_at']:.2f} s: "
                  f"{log.meta.get('unreachable_message')}", file=sys.stderr)
        print(f"\r  {label}: done in {metrics['wall_time_s']:.1f} s -> {shown}", file=sys.stderr)
    return log, metrics


def write_outputs(kind, sc, experiment, log, folder: Path, metrics: dict, plots: bool = True, writers=None) -> None:
    """A run's files in ``folder``: the kind's figures (when ``plots``), a physics run's
    picture, and every writer's files in their order (``metrics.json``, holding ``metrics``,
    last). ``experiment`` is the run's :class:`~quatform.scenarios.base.Experiment` (its
    ``csv_channels``), ``writers`` as :func:`_run_into` takes them."""
    if plots:
        figures_of(kind.parts_of(sc)).run(log, folder)
    _picture(log, folder, plots, metrics)
    if writers is None:
        writers, _ = chosen_writers(writer_choices(), folder)
    files = RunFiles(log, folder, kind, tuple(experiment.csv_channels), metrics)
    for writer in writers:  # in their order: metrics.json last
        writer.write(files)


def _picture(log, folder: Path, plots: bool, metrics: dict) -> None:
    """A physics run's time-lapse picture (its plant's record in ``log.meta["physics_record"]``):
    drawn when ``plots``; ``metrics`` gets ``render`` (its file name, or None) and ``render_backend``."""
    record = log.meta.get("physics_record")
    if record is None:
        return
    metrics["render"] = None
    if plots:
        from .report.physics_render import RENDER_FILE, render_or_fallback

        file, how = render_or_fallback(record, log, folder / RENDER_FILE)
        metrics["render"], metrics["render_backend"] = file.name, how


def run(scenario, out, *, plots: bool = True, quiet: bool = False, mcap: bool = True, rerun=None,
        compute: str = "numpy", writers: dict | None = None, **options):
    """Simulate one scenario with one choice; write ``out/timeseries.csv``, the figures and
    ``out/metrics.json`` (last).

    Parameters
    ----------
    scenario : object, str or path-like
        A loaded scenario of any registered kind, or a built-in name or ``.toml`` file.
    out : path-like
        Output folder (built beside, swapped in when complete).
    plots : bool
        Draw the kind's figures.
    quiet : bool
        No progress or summary on stderr.
    mcap : bool
        Write ``out/run.mcap`` (and ``out/foxglove-layout.json``).
    rerun : path-like, optional
        Also write the run as this Rerun recording (``.rrd``; needs the extra ``rerun``).
    compute : str
        The closed loop's compute backend (:data:`quatform.sim.backends.SIM_BACKENDS`):
        ``numpy`` (the reference) or ``jax`` (compiled, equal to NumPy within 1e-9; ``pip
        install -e ".[jax]"``); recorded as ``compute_backend`` in the metrics when not NumPy.
    writers : dict, optional
        Any optional writer's choice by name (:data:`quatform.outputs.WRITERS`: ``True`` /
        ``False``, or a recording's path), over ``mcap`` and ``rerun``.
    **options
        The kind's options (:attr:`ScenarioKind.options`: ``controller``, ``formation``,
        ``physics``, ``feedforward``, ``orientation_error`` ...); None means the default.

    Returns
    -------
    log : quatform.sim.log.Log
    metrics : dict
        What ``metrics.json`` holds (with ``wall_time_s``).
    """
    sc = _scenario(scenario)
    kind = kind_of(sc)
    given = given_options(kind, options, where=str(sc.name))
    simulator(compute)  # an unknown backend: one line before any work
    check_physics_on(kind, sc, given, compute)
    folder_writers, recordings = chosen_writers(writer_choices(mcap, rerun, writers), out)
    with staged_dir(out, inputs=(scenario, given.get("reference"))) as tmp:
        log, metrics = _run_into(kind, sc, tmp, Path(out), plots, quiet, given, folder_writers, compute)
        record_runs(recordings, {"": log}, kind, sc)
    return log, metrics


def record_runs(recordings: dict, logs: dict, kind, sc) -> None:
    """Every recording writer's file of ``logs``, written inside the run's staged folder: an
    interrupted or failed write leaves neither the recording nor the folder."""
    for writer, path in recordings.items():
        writer.record(logs, path, kind.parts_of(sc), str(sc.name))


#: The physics every compute backend runs: the kinematic models (``--physics kinematic``).
KINEMATIC = "kinematic"


def check_physics_on(kind, sc, given: dict, compute: str, over: str | None = None) -> None:
    """Refuse, before any run, a physics other than the kinematic models (MuJoCo, which runs
    on NumPy) on another compute backend: the run's own ``physics`` or, in a compare over
    ``physics``, each of its choices."""
    if compute == "numpy":
        return
    own = {o.name: o for o in kind.options}
    if "physics" not in own:
        return
    physics = own["physics"].choices if over == "physics" else (given.get("physics", KINEMATIC),)
    for value in physics:
        if value != KINEMATIC:
            raise InvalidInputError(f"{sc.name}: --physics {value} runs on NumPy only, not on --compute {compute}; "
                                    f"run it with --compute numpy (--compute {compute} runs --physics {KINEMATIC})")


def _suffix(options: dict) -> str:
    """The non-default choices of a compare in words, for its title (`` (no feedforward)``)."""
    words = [("" if v else "no ") + k.replace("_", " ") if isinstance(v, bool) else f"{k.replace('_', ' ')} {v}"
             for k, v in options.items()]
    return f" ({', '.join(words)})" if words else ""


def compare(scenario, out, *, over: str | None = None, plots: bool = True, quiet: bool = False, mcap: bool = True,
            rerun=None, compute: str = "numpy", spell=None, over_spell=None, writers: dict | None = None,
            **options) -> list:
    """Run every value of one option of a scenario's kind, each into ``out/<value>/``; draw the
    kind's compare figures; write ``comparison.md`` and ``comparison.json``. A value the
    scenario cannot take (:meth:`~quatform.scenarios.base.ScenarioKind.compare_choices`) is
    left out, named with the reason in ``comparison.md`` and on stderr.

    Parameters
    ----------
    scenario : object, str or path-like
        As in :func:`run`.
    out : path-like
    over : str, optional
        The option to vary (default: the kind's ``compare_over``), e.g. ``physics``.
    plots : bool
        Draw each run's figures and the compare figures (False: metrics, time series and
        the table only).
    quiet : bool
    mcap : bool
        Write each run's ``run.mcap`` (and ``foxglove-layout.json``).
    rerun : path-like, optional
        Also write every run into this one Rerun recording, each under ``/<value>/``.
    compute : str
        As in :func:`run`, for every run.
    writers : dict, optional
        As in :func:`run`, for every run (a recording holds them all).
    spell, over_spell : callable, optional
        How an error line names an option (``spell(option)``, as in :func:`given_options`;
        the CLI: its flag) and an option's name as ``over`` takes it (``over_spell(name)``;
        the CLI: ``orientation-error``); default: the keywords.
    **options
        The other options, fixed for every run.

    Returns
    -------
    list of dict
        The runs' metrics, in the order of the option's choices (those run).
    """
    sc = _scenario(scenario)
    kind = kind_of(sc)
    spell = spell or (lambda option: option.name)
    over_spell = over_spell or (lambda name: name)
    given = given_options(kind, options, where=str(sc.name), spell=spell)
    axis = kind.compare_over if over is None else over
    own = {o.name: o for o in kind.options}
    if axis is None or axis not in own or own[axis].choices is None:
        axes = [over_spell(o.name) for o in kind.options if o.choices is not None]
        shown = axis if axis is None else over_spell(axis)
        raise InvalidInputError(f"{sc.name} is a {kind.name} scenario: it has no compare over {shown!r}; "
                                f"compare over one of {', '.join(axes) or 'nothing'}")
    if axis in given:
        raise InvalidInputError(f"{sc.name}: compare runs every {axis.replace('_', ' ')} "
                                f"({', '.join(own[axis].choices)}); do not give {spell(own[axis])}")
    columns = compare_columns(kind, axis, sc)
    simulator(compute)
    check_physics_on(kind, sc, given, compute, over=axis)
    values, skipped = kind.compare_choices(sc, axis)
    folder_writers, recordings = chosen_writers(writer_choices(mcap, rerun, writers), out)
    if not quiet:
        for value, why in skipped.items():
            print(f"  {sc.name} / {value}: not run: {why}", file=sys.stderr)
    with staged_dir(out, inputs=(scenario, given.get("reference"))) as tmp:
        logs, rows = [], []
        for value in values:
            log, metrics = _run_into(kind, sc, tmp / value, Path(out) / value, plots, quiet, {**given, axis: value},
                                     folder_writers, compute)
            logs.append(log)
            rows.append({axis: value, **metrics})
        if plots:
            figures_of(kind.parts_of(sc)).compare(logs, tmp)
        table = format_table(rows, columns)
        left = "".join(f"\nNot run: {value} ({why})\n" for value, why in skipped.items())
        atomic_write_text(tmp / "comparison.md",
                          f"# {sc.name}: {sc.title}{_suffix(given)}\n\nSource: {sc.source}\n\n{table}\n{left}")
        write_json(rows, tmp / "comparison.json")
        record_runs(recordings, dict(zip(values, logs)), kind, sc)
    return rows


def compare_columns(kind, axis: str, scenario=None) -> tuple:
    """The table columns of a compare over ``axis``: the kind's (of ``scenario``:
    :meth:`~quatform.scenarios.ScenarioKind.columns_of`), led by the axis when they lack it."""
    columns = tuple(kind.table_columns if scenario is None else kind.columns_of(scenario))
    if axis in [key for key, _, _ in columns]:
        return columns
    return ((axis, axis.replace("_", " "), "{}"), *columns)


def format_table(rows, columns) -> str:
    """A Markdown table of metrics rows; ``columns``: (metrics key, header, format) each."""
    head = "| " + " | ".join(h for _, h, _ in columns) + " |"
    sep = "|" + "|".join("---" for _ in columns) + "|"
    lines = [head, sep]
    for m in rows:
        cells = ["-" if m.get(k) is None else fmt.format(m[k]) for k, _, fmt in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
