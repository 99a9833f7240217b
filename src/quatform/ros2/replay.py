"""``quatform replay``: a controller run offline on a recorded bag's poses (ROS 2 bridge layer).

The path from a lab log to a figure: the bag's pose messages (:mod:`quatform.ros2.bag_poses`)
go, in time order, into the same :class:`~quatform.ros2.bridge.FormationBridge` the live node
runs, which ticks at each pose time (default; of any robot) or at ``rate_hz`` from the
moment every robot has a pose (as the node's timer, started then, does); a pose and a tick at
one time: the pose first. The stale rule, the reference time and the commands are the node's,
so a bag replayed through the node and through ``replay`` gives the same commands.

Written into ``out`` atomically (:func:`~quatform.sim.output.staged_dir`): ``commands.csv``
(per tick: time, reference time, status, the controller's commands, each robot's twist and the
measured state), ``commands.mcap`` (the messages the node would have published, on its
topics), ``commands.png`` (commanded against measured, per robot) and ``metrics.json`` last.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..report.writers import write_columns, write_metrics
from ..sim.output import check_inputs_outside, staged_dir
from .bag_poses import read_bag_poses
from .bridge import STATUSES, FormationBridge, experiment_for
from .robots_file import RobotsFile, read_robots_file

__all__ = ["ReplayResult", "replay_ticks", "replay", "write_commands_mcap"]


@dataclass(frozen=True)
class ReplayResult:
    """What a replay computed.

    Attributes
    ----------
    ticks : list of :class:`~quatform.ros2.bridge.Tick`
    states : ndarray, shape (T, n_state)
        The measured plant state at each tick (NaN before a robot's first pose).
    metrics : dict
    """

    ticks: list
    states: np.ndarray
    metrics: dict


def _tick_times(poses, rate_hz):
    """The ticks, ns: after every robot has a pose (``ready``), each distinct pose time (of any
    robot) at or after it, or ``ready + k / rate_hz`` (k >= 1) up to the last pose."""
    ready = max(int(t[0]) for t in poses.times_ns)
    last = max(int(t[-1]) for t in poses.times_ns)
    if rate_hz is None:
        every = np.unique(np.concatenate(poses.times_ns))
        return [int(t) for t in every[every >= ready]]
    period = int(round(1e9 / rate_hz))
    n = (last - ready) // period
    if n > 10_000_000:
        raise InvalidInputError(f"--rate {rate_hz:g} Hz over the bag's {(last - ready) * 1e-9:.1f} s is {n:,} ticks; "
                                "give a lower rate")
    return [ready + k * period for k in range(1, n + 1)]


def replay_ticks(bridge: FormationBridge, poses, rate_hz: float | None = None) -> ReplayResult:
    """Run ``bridge`` on the bag's ``poses`` (:class:`~quatform.ros2.bag_poses.BagPoses`)."""
    if rate_hz is not None and not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InvalidInputError(f"--rate {rate_hz!r} must be a positive number of Hz")
    bridge.reset()
    events = heapq.merge(*[[(int(t), i, k) for k, t in enumerate(ts)] for i, ts in enumerate(poses.times_ns)])
    events = list(events)
    ticks, states = [], []
    j = 0
    for t_tick in _tick_times(poses, rate_hz):
        while j < len(events) and events[j][0] <= t_tick:
            t, i, k = events[j]
            bridge.on_pose(i, poses.messages[i][k], t)
            j += 1
        tick = bridge.tick(t_tick)
        ticks.append(tick)
        x = np.full(bridge.n_state, np.nan)
        for s, st in zip(bridge.plant_robots.state_slices, bridge.states):
            if st is not None:
                x[s] = st
        states.append(x)
    if not ticks:
        raise InvalidInputError("the bag has no tick after every robot's first pose; record longer or give --rate")
    return ReplayResult(ticks, np.asarray(states), _metrics(bridge, ticks, poses, rate_hz))


def _metrics(bridge, ticks, poses, rate_hz) -> dict:
    status = np.array([STATUSES.index(t.status) for t in ticks])
    ok = status == 0
    u = np.array([t.u for t in ticks])
    out = {
        "ticks": len(ticks), "ok_ticks": int(ok.sum()), "stale_ticks": int((status == 1).sum()),
        "estop_ticks": int((status == 2).sum()),
        "first_tick_s": ticks[0].t, "last_tick_s": ticks[-1].t, "reference_time_s": ticks[-1].tau,
        "first_tick_ns": ticks[0].t_ns, "last_tick_ns": ticks[-1].t_ns,
        "rate_hz": rate_hz, "poses": {n: int(len(ts)) for n, ts in zip(bridge.names, poses.times_ns)},
        "lost_frames": dict(zip(bridge.names, bridge.lost_frames)),
        "max_abs_command": dict(zip(bridge.experiment.controller.command_names,
                                    np.abs(u).max(axis=0).round(12).tolist())),
        "nonfinite_commands": int((~np.isfinite(u)).sum()),
        "stale_robots": sorted({n for t in ticks for n in t.stale}),
    }
    out.update(_tracking_error(bridge, ticks))
    return out


#: Endings of the error columns that are a (dual) quaternion block's scalar part ((w, x, y, z)
#: order, docs/conventions.md): 1 (or -1) at zero error, so they are left out of the error.
_SCALAR_PARTS = ("_w", "_rw")


def _tracking_error(bridge, ticks) -> dict:
    """``max_abs_tracking_error`` (over the ok ticks and the error's variables) and its value per
    variable: the controller's error signal without the scalar parts of its quaternion blocks
    (their body-frame error ``q_des* q`` is the identity at zero error; the vector part is
    ``sin(angle / 2)`` times the axis). Empty when no tick computed an error."""
    names = bridge.experiment.controller.signal_columns().get("error", ())
    errors = [t.signals["error"] for t in ticks if "error" in t.signals]
    keep = [j for j, n in enumerate(names) if not n.endswith(_SCALAR_PARTS)]
    if not errors or not keep:
        return {}
    e = np.abs(np.asarray(errors, dtype=float).reshape(len(errors), -1)[:, keep])
    per = np.nanmax(e, axis=0)
    return {"max_abs_tracking_error": float(per.max()),
            "max_abs_tracking_error_by_variable": {names[j]: round(float(v), 12) for j, v in zip(keep, per)}}


def write_commands_mcap(ticks, bridge, path: Path) -> Path:
    """The published messages of ``ticks`` as a one-file MCAP bag at ``path`` (each at its tick time)."""
    from ..bags.mcap import mcap_writer
    from .px4 import register_px4_types

    store = register_px4_types()
    with mcap_writer(path, compress=False) as writer:
        conns = {topic: writer.add_connection(topic, typ, typestore=store) for topic, typ, _ in bridge.command_topics()}
        for tick in ticks:
            for topic, msg in tick.messages:  # log time = header stamp = the tick's integer ns
                writer.write(conns[topic], tick.t_ns, store.serialize_cdr(msg, msg.__msgtype__))
    return path


def _csv(result: ReplayResult, bridge) -> tuple[list, np.ndarray]:
    names = ["t", "reference_time", "status"] + list(bridge.experiment.controller.command_names)
    for n in bridge.names:
        names += [f"{n}_{a}" for a in ("linear_x", "linear_y", "linear_z", "angular_x", "angular_y", "angular_z")]
    names += [f"measured_{c}" for c in bridge.experiment.plant.state_columns]
    rows = [np.concatenate([[t.t, t.tau, STATUSES.index(t.status)], t.u, *[np.r_[a, b] for a, b in t.twists], x])
            for t, x in zip(result.ticks, result.states)]
    return names, np.asarray(rows)


def _figure(result: ReplayResult, bridge, path: Path) -> Path:
    from ..report.replay_plots import plot_replay_commands

    t = (np.array([tk.t_ns for tk in result.ticks], dtype=np.int64) - result.ticks[0].t_ns) * 1e-9
    pr = bridge.plant_robots
    return plot_replay_commands(t, result.states, np.array([tk.u for tk in result.ticks]),
                                [tk.status != "ok" for tk in result.ticks], bridge.names, pr.models,
                                pr.state_slices, pr.command_slices, bridge.experiment.controller.command_names, path)


def replay(bag, scenario, robots, out, *, controller=None, reference=None, rate_hz: float | None = None,
           stamps: str = "header", plots: bool = True) -> ReplayResult:
    """Replay ``bag`` through the controller of ``scenario`` and write ``out`` (see the module docstring).

    Parameters
    ----------
    bag : path-like
        A rosbag2 folder or ``.mcap`` file with every robot's pose topic.
    scenario : object, str or path-like
        A loaded scenario, a built-in name or a ``.toml`` file.
    robots : RobotsFile or path-like
        ``robots.toml`` (:mod:`quatform.ros2.robots_file`).
    out : path-like
        Output folder.
    controller, reference : str, optional
        As ``quatform ros2`` (:func:`~quatform.ros2.bridge.experiment_for`).
    rate_hz : float, optional
        Tick rate; default: at each pose time (of any robot).
    stamps : str
        ``header`` (the messages' stamps) or ``log`` (the bag's receive times).
    plots : bool
        Draw ``commands.png``.
    """
    inputs = (bag, robots if not isinstance(robots, RobotsFile) else None, scenario, reference)
    check_inputs_outside(out, *inputs)  # before any work: the swap into out would delete them
    rf = robots if isinstance(robots, RobotsFile) else read_robots_file(robots)
    experiment = experiment_for(scenario, controller, reference)
    bridge = FormationBridge(experiment, rf)
    poses = read_bag_poses(bag, rf, stamps)
    result = replay_ticks(bridge, poses, rate_hz)
    metrics = {"bag": str(bag), "scenario": str(experiment.scenario.name), "controller": experiment.label,
               "stamps": stamps, **result.metrics}
    result = ReplayResult(result.ticks, result.states, metrics)
    with staged_dir(out, inputs=inputs) as tmp:
        names, rows = _csv(result, bridge)
        write_columns(names, rows, tmp / "commands.csv",  # the times exactly, to the nanosecond
                      ns={"t": [tk.t_ns for tk in result.ticks], "reference_time": [tk.tau_ns for tk in result.ticks]})
        write_commands_mcap(result.ticks, bridge, tmp / "commands.mcap")
        if plots:
            _figure(result, bridge, tmp / "commands.png")
        write_metrics(metrics, tmp / "metrics.json")
    return result
