"""The files a run writes: one :class:`Writer` per format, registered by name (runs layer).

Every writer is one class; defining it registers one instance in :data:`WRITERS`.
:func:`quatform.runs.run` and :func:`~quatform.runs.compare` write every chosen writer's
files through the registry, and the CLI builds its output flags from it
(:func:`add_output_flags`: ``--no-NAME`` for an optional writer written by default,
``--NAME FILE`` for one that records into a file, ``--NAME`` for one off by default). A writer
says

* ``name``: its key and its flag;
* ``files``: the file names it writes in a run's folder (a recording: the suffix of its file);
* ``optional``: whether a user can switch it (``default``: on unless switched off);
* ``extra``: the ``pip install -e ".[extra]"`` it needs, or None;
* ``order``: when it writes among a run's writers (``metrics.json`` last: its presence says
  the run completed);
* ``applies(run)``: whether a run has what it writes (``graph.json``: a run over a graph).

The built-in ones: ``csv`` (``timeseries.csv``, the kind's channels), ``mcap`` (``run.mcap``
and ``foxglove-layout.json``, :mod:`quatform.bags`), ``rerun`` (a Rerun recording of every run
of the command, :mod:`quatform.bags.rerun`), ``metrics`` (strict ``metrics.json``). This
module imports none of them: each imports its format's module when it writes, so the CLI's
parser stays light.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from .errors import InvalidInputError
from .registry import Registry

__all__ = ["Writer", "WRITERS", "RunFiles", "CsvWriter", "McapWriter", "RerunWriter", "GraphWriter", "MetricsWriter",
           "chosen_writers", "add_output_flags", "writer_choices"]

#: Every writer by name, in the order its class was defined.
WRITERS = Registry("writer")


@dataclass(frozen=True)
class RunFiles:
    """One run's output, as a writer reads it.

    Attributes
    ----------
    log : quatform.sim.log.Log
    folder : Path
        The run's (staged) folder.
    kind : ScenarioKind
    csv_channels : tuple of str
        The channels the kind's ``timeseries.csv`` holds, in order.
    metrics : dict
        What ``metrics.json`` holds.
    """

    log: Any
    folder: Path
    kind: Any
    csv_channels: tuple
    metrics: dict


class Writer:
    """One output format (see the module docstring). A subclass with a ``name`` registers
    an instance of itself in :data:`WRITERS` when it is defined."""

    name: ClassVar[str] = ""
    files: ClassVar[tuple] = ()
    optional: ClassVar[bool] = False
    default: ClassVar[bool] = True
    extra: ClassVar[str | None] = None
    order: ClassVar[int] = 50
    #: The CLI's help line of its flag.
    help: ClassVar[str] = ""
    #: It records every run of a command into one file the user names (``--NAME FILE``),
    #: outside the output folder, instead of files in each run's folder.
    records: ClassVar[bool] = False

    def __init_subclass__(cls, register: bool = True, **kwargs):
        super().__init_subclass__(**kwargs)
        if register and cls.__dict__.get("name"):
            WRITERS.add(cls.name, cls())

    def applies(self, run: RunFiles) -> bool:
        """Whether the run has what this writer writes (every run, unless the writer says)."""
        return True

    def write(self, run: RunFiles) -> None:
        """Write this format's files of one run into ``run.folder``."""

    def check(self, path, out) -> Path:
        """A recording writer: ``path`` checked before anything runs (one line each)."""
        return Path(path)

    def record(self, logs: dict, path: Path, kind: str, name: str) -> None:
        """A recording writer: every run's log (``{label: log}``) into the file ``path``."""


def writer_choices(mcap: bool = True, rerun=None, writers: dict | None = None) -> dict:
    """Every writer's choice by name: its default, ``mcap`` / ``rerun`` (the keywords of
    :func:`quatform.runs.run`) and ``writers`` (``{name: bool or path}``) over it. An unknown
    name, or a switch of a writer that is always written, is one line."""
    chosen = {name: (w.default if not w.records else None) for name, w in WRITERS.items()}
    given = {"mcap": mcap, "rerun": rerun, **(writers or {})}
    for name, value in given.items():
        w = WRITERS.get(name)
        if w is None:
            from .checks import nearest

            raise InvalidInputError(f"unknown writer {name!r}{nearest(name, WRITERS)}; writers: {', '.join(WRITERS)}")
        if not w.optional and value is not True:
            raise InvalidInputError(f"the {name} writer is always written; it cannot be switched off")
        chosen[name] = value
    return chosen


def chosen_writers(choices: dict, out) -> tuple[list, dict]:
    """``(folder writers, {recording writer: checked path})`` of ``choices``
    (:func:`writer_choices`), in their ``order``; the recordings' paths are checked before any
    work (an extra missing, a path the run would replace ...)."""
    folder, recordings = [], {}
    for w in sorted(WRITERS.values(), key=lambda w: w.order):
        value = choices.get(w.name)
        if w.records:
            if value is not None:
                recordings[w] = w.check(value, out)
        elif value:
            folder.append(w)
    return folder, recordings


def _dashed(name: str) -> str:
    return name.replace("_", "-")


def add_output_flags(p) -> None:
    """The output flags of every optional writer on the parser ``p`` (dest ``writer_NAME``):
    ``--no-NAME`` (written by default), ``--NAME FILE`` (a recording), ``--NAME`` (off by default)."""
    for name, w in WRITERS.items():
        if not w.optional:
            continue
        needs = f' (needs: pip install -e ".[{w.extra}]")' if w.extra else ""
        if w.records:
            p.add_argument(f"--{_dashed(name)}", dest=f"writer_{name}", metavar=f"FILE{''.join(w.files)}",
                           default=None, help=w.help + needs)
        elif w.default:
            p.add_argument(f"--no-{_dashed(name)}", dest=f"writer_{name}", action="store_false", default=True,
                           help=w.help + needs)
        else:
            p.add_argument(f"--{_dashed(name)}", dest=f"writer_{name}", action="store_true", default=False,
                           help=w.help + needs)


def output_choices(args) -> dict:
    """The writers' choices of parsed arguments (:func:`add_output_flags`): ``{name: value}``."""
    return {name: getattr(args, f"writer_{name}") for name, w in WRITERS.items()
            if w.optional and hasattr(args, f"writer_{name}")}


# --------------------------------------------------------------------------- the built-in writers

class CsvWriter(Writer):
    """``timeseries.csv``: the kind's channels side by side (:func:`quatform.report.writers.write_timeseries`)."""

    name = "csv"
    files = ("timeseries.csv",)
    order = 0

    def write(self, run: RunFiles) -> None:
        from .report.writers import write_timeseries

        write_timeseries(run.log, run.folder / self.files[0], run.csv_channels)


class McapWriter(Writer):
    """``run.mcap`` (the log as ROS 2 messages: the kind's scene, ``quatform.bags.SCENES``, and
    every channel) and, for a kind with a scene, ``foxglove-layout.json``."""

    name = "mcap"
    files = ("run.mcap", "foxglove-layout.json")
    optional = True
    order = 10
    help = ("do not write run.mcap (the run as ROS 2 messages: poses, commands, TF, formation edges, every logged "
            "channel; opens in Foxglove, PlotJuggler, ros2 bag) nor foxglove-layout.json")

    def write(self, run: RunFiles) -> None:
        from .bags import MCAP_FILE, SCENES, scene_of, write_foxglove_layout, write_mcap

        kind = run.log.meta.get("kind", run.kind.name)  # the name its scene is registered under
        # a kind without a scene (quatform.bags.SCENES) still gets its channels, and no layout
        scene = scene_of(run.log, kind) if kind in SCENES else None
        write_mcap(run.log, run.folder / MCAP_FILE, kind=kind, scene=False if scene is None else scene)
        if scene is not None:
            write_foxglove_layout(run.folder, kind, scene)


class RerunWriter(Writer):
    """A Rerun recording (``.rrd``) of every run of the command, each under ``/<value>/`` in a
    compare (:func:`quatform.bags.rerun.write_rerun`)."""

    name = "rerun"
    files = (".rrd",)
    optional = True
    default = False
    records = True
    extra = "rerun"
    order = 20
    help = "also write the run as a Rerun recording (3-D scene and time series)"

    def check(self, path, out) -> Path:
        """``path`` as a path, checked before anything runs: rerun-sdk installed, a ``.rrd``
        name, a writable existing folder, not inside the output folder ``out`` (which the run
        replaces). Each a one-line :class:`~quatform.errors.InvalidInputError`."""
        from .bags.rerun import require_rerun

        require_rerun()
        p = Path(path)
        parent = Path(os.path.abspath(p)).parent
        if p.suffix != ".rrd":
            raise InvalidInputError(f"--rerun {path}: a Rerun recording is a .rrd file; give FILE.rrd")
        if Path(os.path.abspath(out)) in (parent, *parent.parents):
            raise InvalidInputError(f"--rerun {path} is inside the output folder {out}, which the run replaces; "
                                    "give a .rrd file outside it")
        if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
            raise InvalidInputError(f"--rerun {path}: folder {parent} does not exist or is not writable; "
                                    "give a .rrd file in a writable folder")
        return p

    def record(self, logs: dict, path: Path, kind: str, name: str) -> None:
        from .bags.rerun import write_rerun

        write_rerun(logs, path, kind=kind, name=name)


class GraphWriter(Writer):
    """``graph.json`` of a run whose robots talk over a graph (its log's ``meta["graph"]``,
    :func:`quatform.scenarios.network.graph_record`): the robots, each graph's edges with
    their weights and the switching schedule. Other runs write nothing."""

    name = "graph"
    files = ("graph.json",)
    order = 30

    def applies(self, run: RunFiles) -> bool:
        return isinstance(run.log.meta.get("graph"), dict)

    def write(self, run: RunFiles) -> None:
        if self.applies(run):
            from .report.writers import write_json

            write_json(run.log.meta["graph"], run.folder / self.files[0])


class MetricsWriter(Writer):
    """``metrics.json``, strict JSON (:func:`quatform.report.writers.write_metrics`), written
    last: a folder holding it is a completed run."""

    name = "metrics"
    files = ("metrics.json",)
    order = 1000

    def write(self, run: RunFiles) -> None:
        from .report.writers import write_metrics

        write_metrics(run.metrics, run.folder / self.files[0])
