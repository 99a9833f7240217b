"""The bridge's control logic without ROS: poses in, one control tick, commands out.

ROS 2 bridge layer. :class:`FormationBridge` holds a scenario kind's
:class:`~quatform.scenarios.base.Experiment` (its controller, reference and plant: the robots
and the layout of their states) and a :class:`~quatform.ros2.robots_file.RobotsFile`; the
node (:mod:`quatform.ros2.node`) feeds it the messages its transport delivers and calls
:meth:`FormationBridge.tick` on its timer, and ``quatform replay`` feeds it a bag's poses, so
both compute the same commands from the same inputs.

Each tick, with every robot's latest pose (converted to its model's state on arrival,
:mod:`quatform.ros2.robot_io`):

* e-stop engaged (latched until released): every command zero;
* a robot without a pose younger than its ``timeout_s`` (time since it arrived): every command
  zero and the controller held (its state and the reference time do not advance);
* else the plant state is assembled robot by robot, the plant's own output gives the
  controller's measured values, the reference is the experiment's at the reference time
  ``tau`` (which advances by the time between consecutive running ticks), and the command is
  split robot by robot and turned into twists.

Times are integer nanoseconds (ROS time), so a replay and a node that see the same stamps
compute the same ``tau`` exactly.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from .. import messages
from ..errors import InvalidInputError
from .endpoints import COMMAND_WRITERS, POSE_READERS, pose_sample
from .robot_io import PoseSample, plant_robots, robot_io
from .robots_file import RobotsFile

__all__ = ["FormationBridge", "Tick", "STATUSES", "experiment_for"]

#: What a tick did: ``ok`` (commands computed), ``stale`` (a pose too old: zero, held),
#: ``estop`` (e-stop latched: zero, held).
STATUSES = ("ok", "stale", "estop")


@dataclass(frozen=True)
class Tick:
    """One control tick.

    Attributes
    ----------
    t : float
        Its time, s (ROS time; ``t_ns`` exactly).
    status : str
        One of :data:`STATUSES`.
    tau : float
        The reference time, s.
    u : ndarray, shape (n_u,)
        The plant command sent (zeros unless ``ok``).
    twists : tuple of (linear (3,), angular (3,))
        Each robot's twist, in its command frame.
    stale : tuple of str
        The robots whose pose was too old.
    signals : dict
        The controller's signals of this tick (empty unless ``ok``).
    messages : tuple of (topic, message)
        What to publish (``rosbags`` messages), stamped ``t_ns`` exactly.
    t_ns : int
        Its time, integer nanoseconds (ROS time): the pose stamp that triggered it, in a replay.
    tau_ns : int
        The reference time, integer nanoseconds.
    """

    t: float
    status: str
    tau: float
    u: np.ndarray
    twists: tuple
    stale: tuple
    signals: dict
    messages: tuple
    t_ns: int = 0
    tau_ns: int = 0


def experiment_for(scenario, controller=None, reference=None):
    """The :class:`~quatform.scenarios.base.Experiment` of ``scenario`` (loaded or a name/file)
    that the bridge runs: the kind's own, with ``controller`` (a kind with a ``controller``
    option; for the UGV-UAV kind, its ``formation``) and ``reference`` (a plan.npz, for the
    kinds that take one). A kind without the option is one line."""
    from ..runs import given_options
    from ..scenarios import kind_of, load_scenario

    sc = load_scenario(scenario) if isinstance(scenario, (str, os.PathLike)) else scenario
    kind = kind_of(sc)
    own = {o.name for o in kind.options}
    axis = "controller" if "controller" in own else kind.compare_over
    options = {}
    if controller is not None:
        if axis is None:
            raise InvalidInputError(f"{sc.name} is a {kind.name} scenario: it has no controller choice; leave "
                                    "--controller out")
        options[axis] = controller
    if reference is not None:
        options["reference"] = reference
    options = given_options(kind, options, where=str(sc.name), spell=lambda o: "--" + o.name.replace("_", "-"))
    return kind.experiment(sc, **options)


class FormationBridge:
    """The bridge's state and its control tick (see the module docstring).

    Parameters
    ----------
    experiment : Experiment
        A scenario kind's experiment on its kinematic plant (:func:`experiment_for`).
    robots : RobotsFile
        One robot per robot of the plant, in its order.
    """

    def __init__(self, experiment, robots: RobotsFile):
        self.experiment = experiment
        self.robots = robots
        where = str(getattr(experiment.scenario, "name", "scenario"))
        self.plant_robots = pr = plant_robots(experiment.plant, where)
        models = pr.models
        if len(robots.robots) != len(models):
            kinds = ", ".join(robot_io(m).kind for m in models)
            n = len(robots.robots)
            raise InvalidInputError(f"{robots.where} names {n} robot{'' if n == 1 else 's'}, {where} has "
                                    f"{len(models)} ({kinds}); give one [[robots]] table per robot, in the "
                                    "scenario's order")
        self.ios = tuple(robot_io(m) for m in models)
        frames = []
        for link, io, model in zip(robots.robots, self.ios, models):
            writer = COMMAND_WRITERS[link.command_type]
            if io.needs_twist and link.pose_type == "pose":
                raise InvalidInputError(f"{robots.where}: robot {link.name!r} is a {io.kind}, whose measured state holds "
                                        "its velocity; give it pose_type = 'odometry' (nav_msgs/Odometry) or 'px4'")
            if writer.setpoint and not io.setpoint:
                raise InvalidInputError(f"{robots.where}: robot {link.name!r} is a {io.kind}: a {link.command_type} "
                                        "velocity setpoint takes a world velocity and a yaw rate, which its commands "
                                        "are not; give command_type = 'twist' or 'twist-stamped'")
            frame = "world" if writer.setpoint else (link.command_frame or io.natural_frame)
            if frame == "world" and io.world_twist is None:
                raise InvalidInputError(f"{robots.where}: robot {link.name!r} is a {io.kind}, commanded in its body "
                                        "frame; set command_frame = 'body' or leave it out")
            frames.append(frame)
        self.frames = tuple(frames)
        # the robots of one model and command frame, converted together (one call per group)
        groups: dict = {}
        for i, (model, frame) in enumerate(zip(models, frames)):
            groups.setdefault((type(model), model, frame), []).append(i)
        self._groups = tuple(
            (self.ios[idx[0]], models[idx[0]], frame, np.array(idx),
             np.array([np.arange(pr.command_slices[i].start, pr.command_slices[i].stop) for i in idx]),
             np.array([np.arange(pr.state_slices[i].start, pr.state_slices[i].stop) for i in idx]))
            for (_, _, frame), idx in groups.items())
        self.n_state = len(experiment.plant.state_columns)
        self.n_u = len(experiment.controller.command_names)
        times = np.asarray(experiment.times, dtype=float)
        self.n_ref = times.size
        self.ref_dt = float(times[1] - times[0]) if times.size > 1 else 1.0
        self.timeouts_ns = np.array([round(link.timeout_s * 1e9) for link in robots.robots], dtype=np.int64)
        self.reset()

    # -- state ------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every pose; the controller's initial state; reference time 0; e-stop released."""
        n = len(self.robots.robots)
        self.poses: list[PoseSample | None] = [None] * n
        self.states: list[np.ndarray | None] = [None] * n
        self.received_ns = np.zeros(n, dtype=np.int64)  # when each robot's latest pose arrived, ns
        self.has_pose = np.zeros(n, dtype=bool)
        self.controller_state = self.experiment.controller.init(())
        self.tau_ns = 0
        self.last_tick_ns: int | None = None
        self.last_ok = False
        self.estop = False
        self.lost_frames = [0] * n

    @property
    def names(self) -> tuple:
        return self.robots.names

    def pose_topics(self) -> tuple:
        """``(topic, msg_type, qos)`` of every robot's pose, in order."""
        return tuple((link.pose_topic, POSE_READERS[link.pose_type].msg_type, POSE_READERS[link.pose_type].qos)
                     for link in self.robots.robots)

    def command_topics(self) -> tuple:
        """``(topic, msg_type, qos)`` of everything the bridge publishes."""
        return tuple(t for link in self.robots.robots for t in COMMAND_WRITERS[link.command_type].topics(link))

    def zero_messages(self, stamp) -> tuple:
        """``(topic, message)`` of a zero command to every robot, stamped ``stamp`` (a
        ``builtin_interfaces/Time``): what the e-stop and the shutdown publish."""
        zero = np.zeros(3)
        return tuple(m for link, frame in zip(self.robots.robots, self.frames)
                     for m in COMMAND_WRITERS[link.command_type].build(link, stamp, zero, zero,
                                                                       self.robots.settings.world_frame, frame))

    def on_pose(self, i: int, msg, received_ns: int) -> bool:
        """Robot ``i``'s pose message, arrived at ``received_ns``; False for a lost frame (a NaN,
        a non-unit quaternion, or no velocity where the model's state holds one: not used, so
        the robot goes stale after its timeout)."""
        link = self.robots.robots[i]
        pose = pose_sample(link.pose_type, msg)
        if pose is None or (self.ios[i].needs_twist and pose.twist is None):  # a Bebop's frame without velocity
            self.lost_frames[i] += 1
            return False
        self.states[i] = self.ios[i].state(self.plant_robots.models[i], pose, self.states[i])
        self.poses[i] = pose
        self.received_ns[i] = int(received_ns)
        self.has_pose[i] = True
        return True

    def missing(self) -> tuple:
        """Indices of the robots without a pose yet."""
        return tuple(np.flatnonzero(~self.has_pose).tolist())

    def stale(self, now_ns: int) -> tuple:
        """Indices of the robots whose latest pose is older than their timeout (or absent)."""
        return tuple(np.flatnonzero(~self.has_pose | (now_ns - self.received_ns > self.timeouts_ns)).tolist())

    def engage_estop(self) -> None:
        """Latch the e-stop: every tick sends zero commands until :meth:`release_estop`."""
        self.estop = True

    def release_estop(self) -> None:
        """Release the e-stop (the controller resumes from where it was held)."""
        self.estop = False

    # -- the tick ---------------------------------------------------------------------------
    def reference_index(self, tau: float) -> int:
        """The experiment's reference sample at reference time ``tau`` s (the last one after its end)."""
        return min(self.n_ref - 1, max(0, int(math.floor(tau / self.ref_dt + 1e-9))))

    def tick(self, now_ns: int) -> Tick:
        """One control tick at ``now_ns`` (see the module docstring)."""
        now_ns = int(now_ns)
        if self.last_tick_ns is not None and now_ns < self.last_tick_ns:
            raise InvalidInputError(f"bridge tick at {now_ns * 1e-9:.9f} s is before the previous one "
                                    f"({self.last_tick_ns * 1e-9:.9f} s); ticks must not go back in time")
        stale = self.stale(now_ns)
        status = "estop" if self.estop else ("stale" if stale else "ok")
        u = np.zeros(self.n_u)
        signals = {}
        if status == "ok":
            if self.last_ok:
                self.tau_ns += now_ns - self.last_tick_ns
            tau = self.tau_ns * 1e-9
            x = np.empty(self.n_state)
            for s, state in zip(self.plant_robots.state_slices, self.states):
                x[s] = state
            measured = self.experiment.plant.output(x)
            step = self.experiment.controller.update(tau, measured, self.experiment.reference(self.reference_index(tau)),
                                                     self.controller_state)
            u = np.asarray(step.u, dtype=float).reshape(self.n_u)
            if not np.all(np.isfinite(u)):  # controllers send finite commands; never pass on one that is not
                raise InvalidInputError(f"the controller returned a non-finite command at t = {tau:.3f} s; "
                                        "the bridge stops rather than publish it")
            self.controller_state = step.state
            signals = {k: np.asarray(v, dtype=float) for k, v in step.signals.items()}
        self.last_ok = status == "ok"
        self.last_tick_ns = now_ns
        t = messages.stamp_ns(now_ns)  # the messages' stamp: the integer ns, no float round trip
        twists = np.zeros((len(self.robots.robots), 6))
        if status == "ok":
            q = np.array([p.quaternion for p in self.poses])
            for io, model, frame, idx, ui, xi in self._groups:
                lin, ang = io.twist(model, u[ui], x[xi], q[idx], frame)
                twists[idx, 0:3], twists[idx, 3:6] = lin, ang
        msgs = []
        for i, link in enumerate(self.robots.robots):  # one message (or two) per robot: ROS's I/O
            msgs.extend(COMMAND_WRITERS[link.command_type].build(link, t, twists[i, 0:3], twists[i, 3:6],
                                                                 self.robots.settings.world_frame, self.frames[i]))
        return Tick(now_ns * 1e-9, status, self.tau_ns * 1e-9, u, tuple((w[0:3], w[3:6]) for w in twists),
                    tuple(self.names[i] for i in stale), signals, tuple(msgs), now_ns,
                    self.tau_ns)
