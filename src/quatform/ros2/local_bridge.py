"""One robot's side of a decentralised formation on ROS 2: pose and neighbours' messages in, command and message out.

ROS 2 bridge layer (no rclpy: the node is :mod:`.local_node`). :class:`LocalBridge` runs, for
one robot of a ``kind = "network"`` scenario, the scenario's
:class:`~quatform.control.local.LocalController` with ``N = 1`` (its own rows:
:func:`~quatform.control.local.robot_rows`), composed exactly as
:class:`~quatform.control.networked.NetworkedController` composes it for that robot in the
simulator: the law's message with the robot's position appended, its inbox row (the
in-neighbours of the scenario's graph, each slot's edge weight), the messages from beyond
``range_m`` left out, the law's tick, the separation filter of ``[safety]`` on its velocity,
and the robot model's saturation. So the object the simulator runs is the one each robot's
node runs (``tests/test_ros2_local.py`` checks the commands against
:func:`quatform.sim.simulate` tick by tick).

What it holds:

* its own pose, converted to its model's state on arrival (the robot model's ROS I/O,
  through :class:`~quatform.ros2.bridge.FormationBridge`, which also checks the robots file
  against the scenario);
* the messages of each in-neighbour of the last ``links.max_age_s``, each with its stamp (the
  sender's send time, the message header's, integer ns);
* the law's state and the reference time ``tau``, which advances by the time between
  consecutive running ticks (as :class:`FormationBridge`'s).

Each tick at ``now_ns``:

* no own pose yet, or one older than the robot's ``timeout_s`` (since it arrived): status
  ``stale``, zero command, **no message** (the neighbours then hold its last one until it is
  ``max_age_s`` old), the law and ``tau`` held;
* e-stop engaged (latched until released): status ``estop``, zero command, the law and
  ``tau`` held; the message is still sent (its pose is fresh, and the neighbours' separation
  filters need it);
* else the message and the command.

At a tick, robot ``i`` uses of neighbour ``j`` the newest message the graph carried: the
scenario's graph at its send time (``tau - age`` on this robot's reference clock) has the
edge ``j -> i`` (a switching schedule; a message sent while it has not is not carried, as on
the simulated links); a reordered older message never replaces a newer one. It is valid when
its age ``now_ns - stamp`` is at most ``links.max_age_s`` and, with ``range_m``, its sender
was within ``range_m`` of this robot's position now. The law sees the
time ``t = tau`` and each stamp as ``tau - age`` (a stamp ahead of this robot's clock counts
as age 0), so ages, not clocks, reach it, as in the simulator.

The message on the wire (:data:`MESSAGE_TYPE`, ``sensor_msgs/JointState``: a header stamp and
named float64 values, in every ROS 2 installation): ``header.stamp`` the send time,
``header.frame_id`` the world frame, ``name`` the law's message columns then ``sender_x,
sender_y, sender_z``, ``position`` their values (the sender's position in m, world ENU),
``velocity`` and ``effort`` empty. A message whose names are not these, or whose values are
not finite, is refused (a neighbour running another law or another scenario).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import messages
from ..control.local import robot_rows
from ..control.networked import SAFETY_SIGNALS, NetworkedController
from ..errors import InvalidInputError
from ..network.links import TICK_TOL
from .bridge import FormationBridge, Tick
from .endpoints import COMMAND_WRITERS, POSE_READERS
from .robots_file import RobotsFile, resolve_topic

__all__ = ["LocalBridge", "RobotTick", "MESSAGE_TYPE", "MESSAGE_TOPIC", "SENDER_COLUMNS", "local_experiment"]

#: The ROS 2 type of a robot's message to its neighbours.
MESSAGE_TYPE = "sensor_msgs/msg/JointState"
#: Its topic, relative to the sending robot's namespace: ``/<namespace>/quatform/message``.
MESSAGE_TOPIC = "quatform/message"
#: The names of the sender's position after the law's message columns.
SENDER_COLUMNS = ("sender_x", "sender_y", "sender_z")


@dataclass(frozen=True)
class RobotTick(Tick):
    """One robot's control tick (:class:`~quatform.ros2.bridge.Tick`'s fields for that robot,
    and what it sends).

    Attributes
    ----------
    outgoing : ndarray, shape (d + 3,) or None
        The message sent: the law's message columns and the robot's position, m (None: none
        sent, the robot's pose is missing or stale).
    heard : int
        How many in-neighbours' messages were valid at the tick.
    """

    outgoing: np.ndarray | None = None
    heard: int = 0


def local_experiment(experiment, where: str):
    """``experiment``'s :class:`NetworkedController`, or one line for a scenario of another kind."""
    ctrl = experiment.controller
    if not isinstance(ctrl, NetworkedController):
        kind = getattr(experiment, "meta", {}).get("kind", type(ctrl).__name__)
        raise InvalidInputError(f"{where} is a {kind} scenario, whose controller sees every robot at once: one "
                                "robot's node runs a network scenario; use quatform ros2 without --robot (the "
                                "bridge) for the centralised kinds")
    return ctrl


class LocalBridge:
    """One robot's node of a network scenario, without ROS (see the module docstring).

    Parameters
    ----------
    experiment : Experiment
        A ``kind = "network"`` scenario's experiment
        (:func:`~quatform.ros2.bridge.experiment_for`).
    robot : int
        The robot's index, 0-based, in the scenario's (and the robots file's) order.
    robots : RobotsFile
        Every robot of the scenario, in its order (the neighbours' namespaces carry their
        messages), each with its own namespace.
    """

    def __init__(self, experiment, robot: int, robots: RobotsFile):
        where = str(getattr(experiment.scenario, "name", "scenario"))
        self.ctrl = ctrl = local_experiment(experiment, where)
        n = ctrl.n
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < n:
            raise InvalidInputError(f"robot {robot!r} is not a robot of {where}, whose robots are 1..{n} (index "
                                    f"0..{n - 1}); give one of them")
        self.experiment = experiment
        self.robot = i = int(robot)
        self.io = FormationBridge(experiment, robots)  # the robots file against the scenario; each robot's pose I/O
        self.robots = robots
        self.link = robots.robots[i]
        self.message_topics = tuple(resolve_topic(r.namespace, MESSAGE_TOPIC) for r in robots.robots)
        if len(set(self.message_topics)) < n:
            a = next(k for k, t in enumerate(self.message_topics) if self.message_topics.index(t) != k)
            b = self.message_topics.index(self.message_topics[a])
            raise InvalidInputError(f"{robots.where}: robots {robots.robots[b].name!r} and {robots.robots[a].name!r} "
                                    f"would both send on {self.message_topics[a]}; give each robot its own namespace")
        law, L = ctrl.local, ctrl.team.layout
        self.law = law
        self.columns = tuple(law.message_columns) + SENDER_COLUMNS
        self.model = self.io.plant_robots.models[i]
        # the robot's own columns and position within its point (a planar point's z: the zero appended)
        base, size = L.slice(i).start, L.slice(i).stop - L.slice(i).start
        self._own = ctrl.own_index()[i] - base
        pos = np.asarray(L.position_index[i]) - base
        self._pos = np.where(np.asarray(L.position_index[i]) >= L.size, size, pos)
        # its inbox row: the candidate in-neighbours of the links (the simulator's padded width) and their weights
        E = len(ctrl.links.edges)
        self.senders = ctrl.senders[i:i + 1]
        self.weights = ctrl.slot_weights[i:i + 1]
        slot = np.maximum(self.senders[0], 0)
        code = ctrl.links.edges[:, 0] * n + ctrl.links.edges[:, 1]
        # each slot's candidate edge (padding: masked by its sender -1)
        self._edge = np.minimum(np.searchsorted(code, i * n + slot), max(E - 1, 0))
        self._slots = {int(j): w for w, j in enumerate(self.senders[0]) if j >= 0}
        self.max_age_ns = math.floor(ctrl.links.max_age_s * 1e9 + 0.5)
        self.timeout_ns = int(self.io.timeouts_ns[i])
        self.reset()

    # -- state ------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the pose and every message; the law's initial state; reference time 0; e-stop released."""
        self.io.reset()
        W = self.senders.shape[1]
        self.history: list[dict] = [{} for _ in range(W)]  # per slot: {stamp_ns: values} of the last max_age_s
        self.lost_messages = 0
        self.state = self.law.init(1, ())
        self.tau_ns = 0
        self.last_tick_ns: int | None = None
        self.last_ok = False
        self.estop = False

    @property
    def names(self) -> tuple:
        return self.robots.names

    @property
    def neighbours(self) -> tuple:
        """The in-neighbours' indices (0-based), in slot order: the robots whose messages it hears."""
        return tuple(self._slots)

    def pose_topics(self) -> tuple:
        """``((topic, msg_type, qos),)`` of its own pose."""
        return ((self.link.pose_topic, POSE_READERS[self.link.pose_type].msg_type,
                 POSE_READERS[self.link.pose_type].qos),)

    def neighbour_topics(self) -> tuple:
        """``(sender index, topic, msg_type, qos)`` of each in-neighbour's message."""
        return tuple((j, self.message_topics[j], MESSAGE_TYPE, "sensor") for j in self._slots)

    def command_topics(self) -> tuple:
        """``(topic, msg_type, qos)`` of everything it publishes: its command(s) and its message."""
        return COMMAND_WRITERS[self.link.command_type].topics(self.link) + (
            (self.message_topics[self.robot], MESSAGE_TYPE, "sensor"),)

    def zero_messages(self, stamp) -> tuple:
        """``(topic, message)`` of its zero command, stamped ``stamp``."""
        zero, world = np.zeros(3), self.robots.settings.world_frame
        return COMMAND_WRITERS[self.link.command_type].build(self.link, stamp, zero, zero, world,
                                                            self.io.frames[self.robot])

    def on_pose(self, i: int, msg, received_ns: int) -> bool:
        """Its pose message, arrived at ``received_ns``; False for a lost frame
        (:meth:`FormationBridge.on_pose`)."""
        if i != self.robot:
            raise InvalidInputError(f"robot {self.names[self.robot]!r}'s node reads its own pose, not robot "
                                    f"{self.names[i]!r}'s")
        return self.io.on_pose(i, msg, received_ns)

    def missing(self) -> tuple:
        """``(robot,)`` while it has no pose yet, else ``()``."""
        return () if self.io.has_pose[self.robot] else (self.robot,)

    def on_message(self, j: int, msg) -> bool:
        """Neighbour ``j``'s message (a :data:`MESSAGE_TYPE`); False where it is refused (names
        that are not this law's, a value that is not finite) or already held (:meth:`receive`)."""
        names = tuple(msg.name)
        values = np.asarray(msg.position, dtype=float)
        if names != self.columns or values.shape != (len(self.columns),) or not np.all(np.isfinite(values)):
            self.lost_messages += 1
            return False
        return self.receive(j, values, messages.nanoseconds(msg.header.stamp))

    def receive(self, j: int, values, stamp_ns: int) -> bool:
        """Neighbour ``j``'s message ``values`` ``(d + 3,)`` sent at ``stamp_ns``; False where a
        message of that stamp is held already. The slot keeps the messages of the last
        ``max_age_s`` (by their stamps), so a tick takes the newest one the graph carried."""
        w = self._slots.get(int(j))
        if w is None:
            heard = ", ".join(str(k + 1) for k in self._slots) or "none"
            raise InvalidInputError(f"robot {self.names[self.robot]!r} does not hear robot {j + 1} in the scenario's "
                                    f"graph (its in-neighbours: {heard})")
        box, stamp_ns = self.history[w], int(stamp_ns)
        if stamp_ns in box:
            return False
        box[stamp_ns] = np.array(values, dtype=float)
        self._forget(w, max(box) - self.max_age_ns)
        return True

    def _forget(self, w: int, before_ns: int) -> None:
        """Drop slot ``w``'s messages stamped before ``before_ns`` (never valid again)."""
        box = self.history[w]
        for stamp in [s for s in box if s < before_ns]:
            del box[stamp]

    def held(self, now_ns: int, tau: float):
        """``(values (W, d + 3), age_ns (W,), valid (W,))``: each slot's newest message carried
        by the graph (the edge active at its send time ``tau - age`` on this robot's reference
        clock: a message sent while the graph has not the edge is not carried, as on the
        simulated links), valid where one is held and at most ``max_age_s`` old; a reordered
        older message never replaces a newer one."""
        links, W = self.ctrl.links, self.senders.shape[1]
        values = np.zeros((W, len(self.columns)))
        age_ns = np.zeros(W, dtype=np.int64)
        valid = np.zeros(W, dtype=bool)
        for w, box in enumerate(self.history):
            self._forget(w, now_ns - self.max_age_ns)
            if not box:
                continue
            stamps = np.fromiter(box, dtype=np.int64, count=len(box))
            age = np.maximum(now_ns - stamps, 0) * 1e-9
            sent = np.maximum(np.searchsorted(links.starts, tau - age + TICK_TOL * self.ctrl.period_s,
                                              side="right") - 1, 0)
            carried = links.active[sent, self._edge[w]]
            if np.any(carried):
                newest = int(np.max(stamps[carried]))
                values[w], age_ns[w], valid[w] = box[newest], now_ns - newest, True
        return values, age_ns, valid

    def stale(self, now_ns: int) -> bool:
        """Its pose is missing or older than its ``timeout_s``."""
        return bool(not self.io.has_pose[self.robot] or now_ns - self.io.received_ns[self.robot] > self.timeout_ns)

    def engage_estop(self) -> None:
        """Latch the e-stop: zero commands until :meth:`release_estop`."""
        self.estop = True

    def release_estop(self) -> None:
        self.estop = False

    # -- the tick ---------------------------------------------------------------------------
    def own(self):
        """``(own (1, n_own), position (1, 3))`` of its pose's state."""
        point = np.asarray(self.model.point(self.io.states[self.robot]), dtype=float)
        ext = np.concatenate([point, [0.0]])
        return ext[self._own][None], ext[self._pos][None]

    def reference(self, tau: float):
        """Its rows of the law's reference at reference time ``tau`` s (``(1, ...)`` each leaf)."""
        exp = self.experiment
        ref, _ = self.ctrl.reference_arrays((exp.reference(self.io.reference_index(tau)), None))
        return robot_rows(ref, [self.robot], 2)

    def outgoing(self, own, p, ref, tau: float) -> np.ndarray:
        """Its message ``(d + 3,)``: the law's columns and its position."""
        msg = self.law.message(self.state, own, ref, tau)
        return np.concatenate([np.asarray(msg, dtype=float), p], axis=-1)[0]

    def message_now(self, now_ns: int):
        """The message a tick at ``now_ns`` would send (None where it sends none), without
        ticking: what a test with perfect links hands the neighbours before their ticks."""
        if self.stale(now_ns):
            return None
        tau = self._tau_ns(now_ns, running=not self.estop) * 1e-9
        own, p = self.own()
        return self.outgoing(own, p, self.reference(tau), tau)

    def _tau_ns(self, now_ns: int, running: bool) -> int:
        return self.tau_ns + (now_ns - self.last_tick_ns if running and self.last_ok else 0)

    def inbox(self, now_ns: int, tau: float, p):
        """Its inbox row at ``now_ns`` (the simulator's layout, N = 1, with ``weights``) and its
        senders' positions ``(1, W, 3)`` (0 where none is held)."""
        ctrl = self.ctrl
        d = len(self.law.message_columns)
        held, age_ns, valid = self.held(now_ns, tau)
        age = np.maximum(age_ns, 0) * 1e-9
        held = np.where(valid[:, None], held, 0.0)
        sender = held[None, :, d:]
        if ctrl.range_m is not None:
            valid = valid & ctrl.in_range(sender, p[:, None, :])[0]
        valid = valid[None]
        box = {"senders": self.senders, "messages": np.where(valid[..., None], held[None, :, :d], 0.0),
               "stamps": np.where(valid, tau - age[None], -math.inf), "valid": valid, "weights": self.weights}
        return box, sender

    def tick(self, now_ns: int) -> RobotTick:
        """One control tick at ``now_ns`` (see the module docstring)."""
        now_ns = int(now_ns)
        if self.last_tick_ns is not None and now_ns < self.last_tick_ns:
            raise InvalidInputError(f"robot {self.names[self.robot]!r}: tick at {now_ns * 1e-9:.9f} s is before the "
                                    f"previous one ({self.last_tick_ns * 1e-9:.9f} s); ticks must not go back in time")
        stale = self.stale(now_ns)
        status = "stale" if stale else ("estop" if self.estop else "ok")
        ctrl, law = self.ctrl, self.law
        n_u = len(self.model.command_columns)
        u = np.zeros(n_u)
        signals, sent, heard = {}, None, 0
        if not stale:
            self.tau_ns = self._tau_ns(now_ns, running=status == "ok")
            tau = self.tau_ns * 1e-9
            own, p = self.own()
            ref = self.reference(tau)
            sent = self.outgoing(own, p, ref, tau)
            if status == "ok":
                box, sender = self.inbox(now_ns, tau, p)
                heard = int(np.sum(box["valid"]))
                out = law.tick(self.state, own, box, ref, tau)
                code = int(np.max(np.asarray(out.code), initial=0))
                if code > 0:
                    raise InvalidInputError(f"robot {self.names[self.robot]!r}: {law.name}: "
                                            f"{law.failure_reasons.get(code, 'failure')}")
                safe = None
                if ctrl.safety is not None:  # its velocity filtered against what it knows of its neighbours
                    valid = box["valid"]
                    sensed = (valid | (self.senders >= 0)) if ctrl.hold_unheard else valid
                    age = np.where(valid, tau - np.where(valid, box["stamps"], 0.0), math.inf)
                    safe, sig = ctrl.safety.filter(ctrl.law_velocity(out.u), p, sender, age, sensed)
                    signals["safety"] = np.array([float(np.asarray(sig[k])[0]) for k in SAFETY_SIGNALS])
                u = np.asarray(ctrl.commands(out.u, safe), dtype=float).reshape(n_u)
                if not np.all(np.isfinite(u)):  # never pass on a command that is not finite
                    raise InvalidInputError(f"robot {self.names[self.robot]!r}: {law.name} returned a non-finite "
                                            f"command at t = {tau:.3f} s; the node stops rather than publish it")
                self.state = out.state
                signals.update({k: np.asarray(v, dtype=float)[0] for k, v in out.signals.items()})
        self.last_ok = status == "ok"
        self.last_tick_ns = now_ns
        return self._tick(now_ns, status, u, signals, sent, heard)

    def _tick(self, now_ns, status, u, signals, sent, heard) -> RobotTick:
        i, link, frame = self.robot, self.link, self.io.frames[self.robot]
        t = messages.stamp_ns(now_ns)
        lin, ang = np.zeros(3), np.zeros(3)
        if status == "ok":
            lin, ang = self.io.ios[i].twist(self.model, u, self.io.states[i], self.io.poses[i].quaternion, frame)
        msgs = list(COMMAND_WRITERS[link.command_type].build(link, t, np.asarray(lin, dtype=float),
                                                             np.asarray(ang, dtype=float),
                                                             self.robots.settings.world_frame, frame))
        if sent is not None:
            msgs.append((self.message_topics[i], messages.joint_state(t, self.columns, sent,
                                                                      frame_id=self.robots.settings.world_frame)))
        return RobotTick(now_ns * 1e-9, status, self.tau_ns * 1e-9, u, ((lin, ang),),
                         (self.names[i],) if status == "stale" else (), signals, tuple(msgs), now_ns, self.tau_ns,
                         sent, heard)
