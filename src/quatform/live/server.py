"""A live run served over the Foxglove WebSocket protocol (live layer; extra ``live``).

:func:`serve` steps a :class:`~quatform.live.session.LiveSession` paced by a real-time factor
and streams every tick through a Foxglove SDK WebSocket server (``foxglove-sdk``, imported
only here: :func:`require_foxglove`):

* the topics of the run's ``run.mcap``, with the same ``ros2msg`` schemas and CDR bytes
  (:func:`quatform.bags.run_messages` of the ticks just run; the once-per-run topics, the
  paths and ``/quatform/log``, of the run so far, every few seconds and at the end, built from
  the paths' thinned ticks only, so that their cost stays bounded as the run goes);
  each message's log time is its scenario time (ns), which the server also broadcasts
  (Foxglove's time capability);
* :data:`GOAL_TOPIC`: a client publishing ``geometry_msgs/PoseStamped`` there (CDR with the
  ``ros2msg`` schema, or JSON with every field of the pose, numbers only; the channel's schema
  name one of :data:`GOAL_SCHEMAS`) sets the formation's goal (:meth:`LiveSession.set_goal`);
  anything else is answered by a status message naming what is wrong;
* parameters (Foxglove's parameters capability): ``gains.<key>`` (each of the controller's
  gains), ``min_separation_m`` (where the run has the barrier) and ``paused``; a value the
  session refuses is answered by a status message (level error) naming why, and not applied;
* pause and resume: Foxglove's playback controls (the playback-control capability: the app's
  play/pause button, its speed the real-time factor) and the ``paused`` parameter (for
  clients without playback controls, such as Lichtblick's parameters panel). The speed the
  server states is the real-time factor (1 for an unpaced run, whose factor is 0); a play or
  pause request changes the factor only when its speed differs from the one stated (the
  client changed it), so pausing an unpaced run and playing it again keeps it unpaced; a speed
  that is not finite, <= 0 or above :data:`MAX_SPEED` is answered by a status message and the
  factor kept.

Stopping (the duration reached, Ctrl-C, SIGTERM) writes the ticks done into the run's folder
as a run writes it (:meth:`LiveSession.write_into`; ``metrics.json``'s ``live.signal`` the
signal's number, and ``quatform run --live`` then exits with ``128 +`` it: 130, 143). A client
that disconnects changes nothing.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time

import numpy as np

from ..bags import run_messages
from ..bags.mcap import PATH_POSES
from ..errors import InvalidInputError, MissingDependencyError, QuatformError
from ..outputs import chosen_writers, writer_choices
from ..sim.output import staged_dir
from .session import PAUSED_PARAMETER, LiveSession

__all__ = ["GOAL_TOPIC", "GOAL_TYPE", "GOAL_SCHEMAS", "require_foxglove", "LiveServer", "serve", "parse_address",
           "PUBLISH_PERIOD_S", "ONCE_PERIOD_S", "MAX_SPEED"]

#: The topic an operator's goal pose arrives on, and its type.
GOAL_TOPIC = "/formation/goal"
GOAL_TYPE = "geometry_msgs/msg/PoseStamped"
#: Wall time between two publications of the ticks run (s), and between two of the
#: once-per-run topics (the paths of the run so far, ``/quatform/log``).
PUBLISH_PERIOD_S = 0.05
ONCE_PERIOD_S = 5.0
#: The largest real-time factor a client may ask for (scenario seconds per wall second).
MAX_SPEED = 1e3


def require_foxglove():
    """The ``foxglove`` module (the Foxglove SDK), or one line naming the install command."""
    try:
        import foxglove
    except ImportError:
        raise MissingDependencyError('quatform run --live needs the Foxglove SDK: pip install -e ".[live]"') from None
    return foxglove


def parse_address(text: str) -> tuple[str, int]:
    """``(host, port)`` of ``[HOST:]PORT`` (host default ``127.0.0.1``; port 0: any free one)."""
    host, _, port = str(text).rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise InvalidInputError(f"--live {text}: give [HOST:]PORT with a port 0-65535 (e.g. 8765 or 0.0.0.0:8765)")
    return host, number


#: The schema names a goal's channel may advertise (ROS 2's and ROS 1's spelling).
GOAL_SCHEMAS = (GOAL_TYPE, "geometry_msgs/PoseStamped")


def _pose_of_json(data: bytes) -> tuple:
    """``(position (3,), quaternion (w, x, y, z))`` of a JSON ``PoseStamped``; one line naming the
    first field missing or not a number (a string or a boolean is not one)."""
    try:
        msg = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"{GOAL_TOPIC}: not JSON ({exc})") from None

    def field(obj, *path):
        for name in path:
            if not isinstance(obj, dict) or name not in obj:
                raise InvalidInputError(f"{GOAL_TOPIC}: the goal has no field {'.'.join(path)}; publish a whole "
                                        f"{GOAL_TYPE}")
            obj = obj[name]
        if isinstance(obj, bool) or not isinstance(obj, (int, float)):
            raise InvalidInputError(f"{GOAL_TOPIC}: field {'.'.join(path)} = {obj!r} is not a number")
        return float(obj)

    return ([field(msg, "pose", "position", a) for a in "xyz"],
            [field(msg, "pose", "orientation", a) for a in "wxyz"])


class LiveServer:
    """The Foxglove WebSocket server of one live session (module docstring).

    Parameters
    ----------
    session : LiveSession
    host : str
        Address to bind (``127.0.0.1``: this machine only).
    port : int
        Port (0: a free one, :attr:`port`).
    realtime : float
        Scenario seconds per wall second (0: as fast as it runs).
    """

    def __init__(self, session: LiveSession, host: str = "127.0.0.1", port: int = 8765, realtime: float = 1.0):
        fg = require_foxglove()
        from foxglove.websocket import Capability, PlaybackState, PlaybackStatus

        self.fg, self.session, self.realtime = fg, session, float(realtime)
        self._PlaybackState, self._PlaybackStatus = PlaybackState, PlaybackStatus
        self.context = fg.Context()
        self.channels: dict = {}
        self.clients: dict = {}  # (client id, client channel id) -> (topic, encoding, schema name)
        self.store = None  # the stream's type store (the stepping thread's)
        self._goal_store = None  # the goals' (the SDK's threads', under the lock)
        self._lock = threading.Lock()
        end = int(round(float(session.times[-1]) * 1e9))
        try:
            self.server = fg.start_server(
                name=f"quatform {session.scenario.name}", host=host, port=port, context=self.context,
                capabilities=[Capability.ClientPublish, Capability.Parameters, Capability.Time,
                              Capability.PlaybackControl],
                server_listener=self, supported_encodings=["cdr", "json"], playback_time_range=(0, end))
        except RuntimeError as exc:  # the SDK's FoxgloveError: the address is refused
            text = str(exc)
            why = (f"port {port} on {host} is in use; give another or 0 (any free port)" if "in use" in text else
                   f"cannot listen on {host}:{port} ({text.split(': ', 1)[-1]}); give a host of this machine, "
                   "e.g. 127.0.0.1 or 0.0.0.0")
            raise InvalidInputError(f"--live: {why}") from None

    @property
    def port(self) -> int:
        return self.server.port

    @staticmethod
    def url(host: str, port: int) -> str:
        """``ws://HOST:PORT``, an IPv6 host in brackets."""
        return f"ws://[{host}]:{port}" if ":" in host else f"ws://{host}:{port}"

    # -- the stream -------------------------------------------------------------------------
    def publish(self, start: int, once: bool) -> None:
        """Send ticks ``start`` to ``session.k`` (every topic with one message per tick) and,
        when ``once``, the once-per-run topics of the run so far, built from the ticks its paths
        keep only (at most :data:`~quatform.bags.mcap.PATH_POSES`, the thinning ``run.mcap``'s
        paths use), so a publish's work does not grow with the run."""
        s = self.session
        if s.k > start:
            msgs = run_messages(s.log(start), store=self.store)
            self.store = msgs.store
            for topic, msgtype, data in msgs.every:
                channel = self._channel(topic, msgtype, msgs)
                for k, stamp in enumerate(msgs.ns.tolist()):
                    channel.log(data[k].tobytes(), log_time=stamp)
            self.server.broadcast_time(int(msgs.ns[-1]))
        if once and s.k:
            keep = np.unique(np.linspace(0, s.k - 1, min(s.k, PATH_POSES)).round().astype(int))
            whole = run_messages(s.log(ticks=keep), store=self.store, every=False, samples=s.k)
            self.store = whole.store
            last = int(round(float(s.times[s.k - 1]) * 1e9))
            for topic, msgtype, raw in whole.once:
                self._channel(topic, msgtype, whole).log(raw, log_time=last)

    def _channel(self, topic: str, msgtype: str, msgs):
        ch = self.channels.get(topic)
        if ch is None:
            schema = self.fg.Schema(name=msgtype, encoding="ros2msg", data=msgs.schema(msgtype).encode())
            ch = self.channels[topic] = self.fg.Channel(topic, schema=schema, message_encoding="cdr",
                                                         context=self.context)
        return ch

    def status(self, text: str, level: str = "Error") -> None:
        self.server.publish_status(text, getattr(self.fg.StatusLevel, level))

    def speed(self) -> float:
        """The real-time factor in force (0: unpaced)."""
        with self._lock:
            return self.realtime

    def _stated_speed(self) -> float:
        """The speed the playback state states: the factor, 1 for an unpaced run."""
        return self.realtime or 1.0

    def playback_state(self, request_id=None):
        s = self.session
        status = (self._PlaybackStatus.Ended if s.done else self._PlaybackStatus.Paused if s.paused
                  else self._PlaybackStatus.Playing)
        now = int(round(float(s.times[max(s.k - 1, 0)]) * 1e9))
        with self._lock:
            stated = self._stated_speed()
        return self._PlaybackState(status, now, stated, False, request_id)

    def stop(self) -> None:
        self.server.stop()

    # -- what clients send (the SDK's threads; every callback of foxglove.websocket.ServerListener) --
    def on_subscribe(self, client, channel) -> None:
        return None

    def on_unsubscribe(self, client, channel) -> None:
        return None

    def on_parameters_subscribe(self, param_names: list) -> None:
        return None

    def on_parameters_unsubscribe(self, param_names: list) -> None:
        return None

    def on_connection_graph_subscribe(self) -> None:
        return None

    def on_connection_graph_unsubscribe(self) -> None:
        return None

    def on_client_advertise(self, client, channel) -> None:
        with self._lock:
            self.clients[(client.id, channel.id)] = (channel.topic, channel.encoding, channel.schema_name)

    def on_client_unadvertise(self, client, client_channel_id: int) -> None:
        with self._lock:
            self.clients.pop((client.id, client_channel_id), None)

    def on_message_data(self, client, client_channel_id: int, data: bytes) -> None:
        with self._lock:
            topic, encoding, schema = self.clients.get((client.id, client_channel_id), (None, None, None))
        if topic != GOAL_TOPIC:
            return
        try:
            if schema not in GOAL_SCHEMAS:
                raise InvalidInputError(f"{GOAL_TOPIC}: the channel advertises schema {schema!r}; publish "
                                        f"{GOAL_TYPE}")
            if encoding == "json":
                p, q = _pose_of_json(data)
            elif encoding == "cdr":
                with self._lock:
                    if self._goal_store is None:
                        from rosbags.typesys import Stores, get_typestore

                        self._goal_store = get_typestore(Stores.ROS2_HUMBLE)
                    msg = self._goal_store.deserialize_cdr(bytes(data), GOAL_TYPE)
                pos, o = msg.pose.position, msg.pose.orientation
                p, q = [pos.x, pos.y, pos.z], [o.w, o.x, o.y, o.z]
            else:
                raise InvalidInputError(f"{GOAL_TOPIC}: encoding {encoding!r} is not read; publish {GOAL_TYPE} as "
                                        "cdr (ros2msg schema) or json")
            self.session.set_goal(p, q)
        except Exception as exc:  # noqa: BLE001 - whatever a client sends is answered, never raised in the SDK
            text = str(exc) if isinstance(exc, InvalidInputError) else \
                f"not a {GOAL_TYPE} ({type(exc).__name__}: {exc})"
            self.status(text if text.startswith(GOAL_TOPIC) else f"{GOAL_TOPIC}: {text}")

    def _parameters(self, names=None) -> list:
        fg = self.fg
        out = []
        for name, value in self.session.parameters().items():
            if names and name not in names:
                continue
            if isinstance(value, bool):
                out.append(fg.Parameter(name, value=value))
            elif isinstance(value, list):
                out.append(fg.Parameter(name, value=value, type=fg.ParameterType.Float64Array))
            else:
                out.append(fg.Parameter(name, value=float(value), type=fg.ParameterType.Float64))
        return out

    def on_get_parameters(self, client, param_names: list, request_id=None) -> list:
        return self._parameters(param_names)

    def on_set_parameters(self, client, parameters: list, request_id=None) -> list:
        for p in parameters:
            try:
                self.session.set_parameter(p.name, p.get_value())
            except Exception as exc:  # noqa: BLE001 - whatever a client sends is answered, never raised in the SDK
                self.status(str(exc) if isinstance(exc, InvalidInputError) else
                            f"live parameter {p.name} refused ({type(exc).__name__}: {exc})")
        if any(p.name == PAUSED_PARAMETER for p in parameters):
            self.server.broadcast_playback_state(self.playback_state())
        return self._parameters()

    def on_playback_control_request(self, request):
        from foxglove.websocket import PlaybackCommand

        self.session.set_parameter(PAUSED_PARAMETER, request.playback_command == PlaybackCommand.Pause)
        speed = float(request.playback_speed)
        with self._lock:  # the request's speed is a float32: a changed one differs from the stated one as such
            changed = np.float32(speed) != np.float32(self._stated_speed())
            good = np.isfinite(speed) and 0 < speed <= MAX_SPEED
            if changed and good:
                self.realtime = speed
        if changed and not good:
            self.status(f"playback speed {speed!r} refused: give a real-time factor > 0 and <= {MAX_SPEED:g}; "
                        "it stays as it was")
        self.server.publish_parameter_values(self._parameters([PAUSED_PARAMETER]))
        return self.playback_state(request.request_id)


def serve(session: LiveSession, out, *, host: str = "127.0.0.1", port: int = 8765, realtime: float = 1.0,
          plots: bool = True, writers: dict | None = None, quiet: bool = False, ready=None, inputs=()):
    """Run ``session`` live (module docstring) and write its folder ``out`` when it ends or is
    stopped (Ctrl-C, SIGTERM). The folder is checked and its staged sibling made before the
    server starts (:func:`~quatform.sim.output.staged_dir`, ``inputs`` the files the run reads),
    so an unusable ``out`` is one line before anything is served. ``ready(server)`` is called
    once the server listens. Returns ``(log, metrics)``; a failure in a tick is raised after the
    ticks before it are written."""
    if not (isinstance(realtime, (int, float)) and np.isfinite(realtime) and realtime >= 0):
        raise InvalidInputError(f"--realtime {realtime!r} must be a number >= 0 (1 = wall clock, 0 = unpaced)")
    chosen = chosen_writers(writer_choices(writers=writers), out)
    with staged_dir(out, inputs=inputs) as tmp:
        server = LiveServer(session, host, port, realtime)
        try:
            log, metrics, failure = _drive(session, server, out, tmp, chosen, host, realtime, plots, quiet, ready)
        finally:
            server.stop()
    if failure is not None:
        raise failure
    return log, metrics


def _drive(session, server, out, tmp, chosen, host, realtime, plots, quiet, ready):
    """:func:`serve`'s loop: step paced, publish, stop on the duration, Ctrl-C, SIGTERM or a
    failure (whose ticks before it are written, then it is returned), write the folder. A
    signal sets a flag the loop reads between ticks, so no tick is cut in half; one that comes
    while the folder is written changes nothing."""
    stop = threading.Event()
    main = threading.current_thread() is threading.main_thread()

    def stopped_by(signum, frame):
        if not stop.is_set():
            stop.signum = int(signum)
            stop.set()

    old = {sig: signal.signal(sig, stopped_by) for sig in (signal.SIGINT, signal.SIGTERM)} if main else {}
    try:
        return _loop(session, server, out, tmp, chosen, host, realtime, plots, quiet, ready, stop)
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _loop(session, server, out, tmp, chosen, host, realtime, plots, quiet, ready, stop):
    say = (lambda text: None) if quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    say(f"  {session.scenario.name}: live on {server.url(host, server.port)} (Foxglove: Open connection -> Foxglove "
        f"WebSocket); {session.times.size} ticks, real time x{realtime:g}; Ctrl-C stops and writes {out}")
    failure, t0 = None, time.perf_counter()
    session.step()  # the first tick advertises every topic before a client is told to come
    server.publish(0, True)
    sent, last_pub, last_once, last_say = 1, time.perf_counter(), time.perf_counter(), 0.0
    if ready is not None:
        ready(server)
    anchor_wall, anchor_t = None, None
    try:
        while not session.done and not stop.is_set():
            now = time.perf_counter()
            if session.paused:
                anchor_wall = None
                time.sleep(PUBLISH_PERIOD_S)
                continue
            if anchor_wall is None or server.speed() != realtime:
                realtime = server.speed()
                anchor_wall, anchor_t = now, float(session.times[session.k])
            while not session.done and not session.paused and not stop.is_set() and \
                    time.perf_counter() - now < PUBLISH_PERIOD_S and (
                    realtime == 0 or float(session.times[session.k]) - anchor_t
                    <= (time.perf_counter() - anchor_wall) * realtime):
                session.step()
            now = time.perf_counter()
            if now - last_pub >= PUBLISH_PERIOD_S or session.done:
                once = now - last_once >= ONCE_PERIOD_S
                server.publish(sent, once)
                sent, last_pub = session.k, now
                last_once = now if once else last_once
            if now - last_say >= 1.0:
                t = float(session.times[session.k - 1])
                say(f"  {session.scenario.name}: t = {t:.2f} s ({session.k}/{session.times.size} ticks)")
                last_say = now
            if realtime and not session.done:
                wait = anchor_wall + (float(session.times[session.k]) - anchor_t) / realtime - time.perf_counter()
                time.sleep(min(max(wait, 0.0), PUBLISH_PERIOD_S))
    except Exception as exc:  # noqa: BLE001 - any failure: the ticks before it are written, then it is raised
        failure = exc
        text = str(exc) if isinstance(exc, QuatformError) else f"{type(exc).__name__}: {exc}"
        say(f"  {session.scenario.name}: failed at tick {session.k}: {text}; writing the ticks before it to {out}")
    stopped = stop.is_set() or failure is not None
    if stop.is_set():
        say(f"\n  {session.scenario.name}: stopped at tick {session.k}; writing {out}")
    try:
        server.publish(sent, True)  # the last ticks, and the whole run's paths
        server.server.broadcast_playback_state(server.playback_state())
    except Exception as exc:  # noqa: BLE001 - a failing stream still leaves the ticks written
        if failure is None:
            failure, stopped, text = exc, True, f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - t0
    log, metrics = session.write_into(tmp, chosen, plots=plots, stopped=stopped, wall_s=wall,
                                      failure=None if failure is None else text,
                                      signal=getattr(stop, "signum", None))
    say(f"  {session.scenario.name}: {session.k} ticks in {wall:.1f} s -> {out}")
    return log, metrics, failure
