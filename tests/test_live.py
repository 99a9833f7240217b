"""``quatform run --live``: a real WebSocket client on 127.0.0.1 speaking the Foxglove protocol
(subprotocol ``foxglove.sdk.v1``; JSON ops, binary message data) against the live server on a
free port. Bounded: short scenarios, fast real-time factors, timeouts on every wait."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("foxglove")
websockets = pytest.importorskip("websockets")

from quatform.formations import geometry as g  # noqa: E402
from quatform.live import LiveSession  # noqa: E402
from quatform.live.server import GOAL_TOPIC, GOAL_TYPE, serve  # noqa: E402

from live_triangle import triangle  # noqa: E402

SUBPROTOCOL = "foxglove.sdk.v1"
ROOT = Path(__file__).resolve().parents[1]



@pytest.fixture
def scenario(tmp_path):
    def make(duration=2.0):
        f = tmp_path / f"tri-{duration:g}.toml"
        f.write_text(triangle(duration))
        return f
    return make


class Live:
    """A live run served in a thread of this process, on a free port of 127.0.0.1."""

    def __init__(self, path, out, realtime, controller="quaternion"):
        self.session = LiveSession(path, {"controller": controller})
        self.out, self.result, self.error = out, None, None
        ready = threading.Event()

        def go():
            try:
                self.result = serve(self.session, out, port=0, realtime=realtime, plots=False, quiet=True,
                                    ready=lambda srv: (setattr(self, "port", srv.port), ready.set()))
            except BaseException as exc:  # noqa: BLE001 - handed to the test
                self.error = exc
                ready.set()

        self.thread = threading.Thread(target=go, daemon=True)
        self.thread.start()
        assert ready.wait(30)
        if self.error:
            raise self.error

    def join(self, timeout=60):
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the live run did not finish"
        if self.error:
            raise self.error
        return self.result


class Client:
    """The Foxglove protocol from the client's side (what Foxglove and Lichtblick send)."""

    def __init__(self, ws):
        self.ws, self.channels, self.statuses, self.params = ws, {}, [], {}
        self.messages, self.times, self.subs = {}, [], {}

    async def pump(self, seconds, until=None):
        """Read for ``seconds`` (or until ``until()``): advertisements, statuses, parameters, messages."""
        end = time.monotonic() + seconds
        while time.monotonic() < end and not (until and until()):
            try:
                m = await asyncio.wait_for(self.ws.recv(), max(0.01, end - time.monotonic()))
            except asyncio.TimeoutError:
                break
            except websockets.ConnectionClosed:
                return False
            if isinstance(m, str):
                d = json.loads(m)
                if d["op"] == "advertise":
                    self.channels.update({c["id"]: c for c in d["channels"]})
                elif d["op"] == "status":
                    self.statuses.append(d)
                elif d["op"] == "parameterValues":
                    self.params.update({p["name"]: p["value"] for p in d["parameters"]})
            elif m[0] == 1:  # message data: subscription id, log time, payload
                sub, stamp = struct.unpack_from("<IQ", m, 1)
                self.messages.setdefault(self.subs[sub], []).append((stamp, bytes(m[13:])))
            elif m[0] == 2:  # time
                self.times.append(struct.unpack_from("<Q", m, 1)[0])
        return True

    async def subscribe_all(self):
        self.subs = {i: c["topic"] for i, c in enumerate(self.channels.values())}
        await self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": cid} for i, cid in enumerate(self.channels)]}))

    async def set(self, name, value, rid="s"):
        await self.ws.send(json.dumps({"op": "setParameters", "parameters": [{"name": name, "value": value}],
                                       "id": rid}))

    async def publish_goal(self, encoding, p, q):
        """Advertise ``/formation/goal`` and send one ``PoseStamped`` (``q`` as ``(w, x, y, z)``)."""
        pose = {"position": dict(zip("xyz", p)), "orientation": dict(zip("wxyz", q))}
        if encoding == "json":
            schema, payload = "", json.dumps({"header": {"frame_id": "world"}, "pose": pose}).encode()
        else:
            from rosbags.typesys import Stores, get_typestore

            store = get_typestore(Stores.ROS2_HUMBLE)
            T = store.types
            msg = T[GOAL_TYPE](T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](0, 0), "world"),
                               T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](*p),
                                                           T["geometry_msgs/msg/Quaternion"](q[1], q[2], q[3], q[0])))
            schema = store.generate_msgdef(GOAL_TYPE, ros_version=2)[0]
            payload = bytes(store.serialize_cdr(msg, GOAL_TYPE))
        await self.ws.send(json.dumps({"op": "advertise", "channels": [
            {"id": 5, "topic": GOAL_TOPIC, "encoding": encoding, "schemaName": GOAL_TYPE, "schema": schema,
             "schemaEncoding": "ros2msg" if encoding == "cdr" else "jsonschema"}]}))
        await asyncio.sleep(0.05)
        await self.ws.send(b"\x01" + struct.pack("<I", 5) + payload)


def connect(port):
    return websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=10,
                              max_size=None)


def test_stream_is_run_mcap(scenario, tmp_path):
    from rosbags.highlevel import AnyReader

    live = Live(scenario(2.0), tmp_path / "out", realtime=2.0)

    async def client():
        async with connect(live.port) as ws:
            c = Client(ws)
            await c.pump(0.3)
            await c.subscribe_all()
            await c.pump(20)  # until the run ends and the server closes
            return c

    c = asyncio.run(client())
    _, metrics = live.join()
    assert metrics["live"]["ticks"] == metrics["live"]["of_ticks"] == 101
    with AnyReader([tmp_path / "out" / "run.mcap"]) as reader:
        conns = {conn.topic: conn for conn in reader.connections}
        advertised = {ch["topic"]: ch for ch in c.channels.values()}
        assert set(advertised) == set(conns)
        for topic, ch in advertised.items():
            assert (ch["schemaName"], ch["schemaEncoding"], ch["encoding"]) == (conns[topic].msgtype, "ros2msg", "cdr")
            assert ch["schema"] == conns[topic].msgdef.data
        stored = {}
        for conn, stamp, raw in reader.messages():
            stored.setdefault(conn.topic, {})[stamp] = bytes(raw)
        assert len(c.messages) == len(conns)
        for topic, received in c.messages.items():
            for stamp, raw in received:
                reader.deserialize(raw, conns[topic].msgtype)  # decodes with the MCAP's schema
            if topic in ("/quatform/reading", "/quatform/reading_des"):  # Euler angles unwrapped along the
                for stamp, raw in received:  # stream's blocks: the file's up to whole turns
                    a, b = (reader.deserialize(r, conns[topic].msgtype) for r in (raw, stored[topic][stamp]))
                    names = [f for f in a.__dataclass_fields__ if f not in ("header", "__msgtype__")]
                    turns = (np.array([getattr(a, f) for f in names]) - [getattr(b, f) for f in names]) / (2 * np.pi)
                    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)
            elif topic.startswith("/quatform/") and topic != "/quatform/log":  # channels: the file's bytes
                for stamp, raw in received:
                    assert raw == stored[topic][stamp], topic
        poses = c.messages["/formation/pose"]
        assert len(poses) >= 50  # the ticks after the subscription, each once
        assert len({s for s, _ in poses}) == len(poses)
    assert c.times and max(c.times) == int(round(2.0 * 1e9))


@pytest.mark.parametrize("encoding", ["json", "cdr"])
def test_goal_moves_the_reference(scenario, tmp_path, encoding):
    live = Live(scenario(3.0), tmp_path / "out", realtime=3.0)
    goal = [0.6, -0.4, 1.3]

    async def client():
        async with connect(live.port) as ws:
            c = Client(ws)
            await c.pump(0.2)
            sent = live.session.k
            await c.publish_goal(encoding, goal, g.q_yaw(0.5))
            await c.pump(20)
            return c, sent

    c, sent = asyncio.run(client())
    log, metrics = live.join()
    assert not c.statuses
    (tick,) = metrics["live"]["goal_ticks"]
    assert sent <= tick < log.t.size
    e_des = log["e_des"]
    np.testing.assert_array_equal(e_des[:tick + 1, :3], live.session.chart[:tick + 1, :3])
    np.testing.assert_allclose(e_des[-1, :3], goal, atol=1e-12)
    np.testing.assert_allclose(abs(np.dot(e_des[-1, 3:7], g.q_yaw(0.5))), 1.0, atol=1e-12)
    assert np.linalg.norm(log["e"][-1, :3] - goal) < 0.1  # the robots followed


def test_parameters_set_and_refused(scenario, tmp_path):
    live = Live(scenario(2.0), tmp_path / "out", realtime=2.0)

    async def client():
        async with connect(live.port) as ws:
            c = Client(ws)
            await ws.send(json.dumps({"op": "getParameters", "parameterNames": [], "id": "g"}))
            await c.pump(2, until=lambda: "gains.k_d" in c.params)
            first = dict(c.params)
            await c.set("gains.k_d", -1.0, "bad")
            await c.pump(2, until=lambda: c.statuses)
            refused = dict(c.params)
            await c.set("gains.k_d", "fast", "bad2")
            await c.set("gains.k_x", [1.0, 2.0], "bad3")
            await c.pump(2, until=lambda: len(c.statuses) >= 3)
            await c.set("gains.k_d", 7.5, "good")
            await c.pump(2, until=lambda: c.params.get("gains.k_d") == 7.5)
            return c, first, refused

    c, first, refused = asyncio.run(client())
    _, metrics = live.join()
    assert first["gains.k_d"] == 20.0 and first["min_separation_m"] == 0.3 and first["paused"] is False
    assert len(c.statuses) == 3 and all(s["level"] == 2 for s in c.statuses)
    assert "k_d = -1.0 must be positive" in c.statuses[0]["message"]
    assert refused["gains.k_d"] == 20.0
    assert c.params["gains.k_d"] == 7.5
    assert [ch[1:] for ch in metrics["live"]["parameter_changes"]] == [["gains.k_d", 7.5]]
    assert live.session.stepper.controller.inner.gains["k_d"] == 7.5


def test_client_that_vanishes_leaves_the_run_going(scenario, tmp_path):
    live = Live(scenario(2.0), tmp_path / "out", realtime=2.0)

    async def client():
        ws = await connect(live.port)
        c = Client(ws)
        await c.pump(0.2)
        await c.subscribe_all()
        await c.pump(0.2)
        ws.transport.abort()  # no close handshake: the client is gone
        return c

    c = asyncio.run(client())
    assert c.messages
    _, metrics = live.join()
    assert metrics["live"]["ticks"] == 101 and not metrics["live"]["stopped"]
    assert (tmp_path / "out" / "metrics.json").is_file()


def _playback(command: int, speed: float, rid: str) -> bytes:
    """A playback control request (opcode 3): command (0 play, 1 pause), speed, no seek, request id."""
    return struct.pack("<BBfBQI", 3, command, speed, 0, 0, len(rid)) + rid.encode()


@pytest.mark.parametrize("how", ["parameter", "playback"])
def test_pause_holds_time(scenario, tmp_path, how):
    live = Live(scenario(2.0), tmp_path / "out", realtime=2.0)

    async def client():
        async with connect(live.port) as ws:
            c = Client(ws)
            await c.pump(2, until=lambda: c.times)
            if how == "parameter":
                await c.set("paused", True)
                await c.pump(2, until=lambda: c.params.get("paused") is True)
            else:  # Foxglove's playback bar
                await ws.send(_playback(1, 2.0, "pause"))
                await c.pump(2, until=lambda: live.session.paused)
            await c.pump(0.3)
            k, seen = live.session.k, len(c.times)
            held = max(c.times)
            await c.pump(0.5)
            after = (live.session.k, max(c.times[seen:], default=held))
            if how == "parameter":
                await c.set("paused", False)
            else:
                await ws.send(_playback(0, 2.0, "play"))
            await c.pump(20)
            return k, held, after

    k, held, (k_after, time_after) = asyncio.run(client())
    _, metrics = live.join()
    assert k_after == k and time_after == held and k < 101
    assert metrics["live"]["ticks"] == 101


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_stop_writes_the_ticks_done(scenario, tmp_path, sig):
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    p = subprocess.Popen([sys.executable, "-m", "quatform", "run", str(scenario(60.0)), "--controller", "quaternion",
                          "--out", str(out), "--no-plots", "--live", "0", "--realtime", "1"],
                         stderr=subprocess.PIPE, text=True, env=env)
    try:
        lines, end = [], time.monotonic() + 60
        while time.monotonic() < end:
            line = p.stderr.readline()
            lines.append(line)
            if "ticks)" in line and "t = 0.00 s" not in line:  # a progress line past the first tick
                break
        assert "live on ws://127.0.0.1:" in "".join(lines)
        p.send_signal(sig)
        rest = p.communicate(timeout=60)[1]
    finally:
        p.kill()
    assert p.returncode == 128 + sig, rest  # 130, 143: after writing the folder
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["live"]["stopped"] and 0 < metrics["live"]["ticks"] < 3001
    assert metrics["live"]["signal"] == sig
    assert (out / "run.mcap").is_file() and (out / "timeseries.csv").is_file()
    rows = (out / "timeseries.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == metrics["live"]["ticks"]


def test_help_names_live_and_realtime(capsys):
    from quatform.cli import main

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = capsys.readouterr().out
    assert "--live [HOST:]PORT" in text and "--realtime FACTOR" in text


def test_publish_work_is_bounded(scenario, monkeypatch):
    """A publish serialises the ticks since the last one, and the once-per-run topics from the
    paths' thinned ticks only (at most PATH_POSES), however long the run has gone; their
    messages are those of the whole run's."""
    import quatform.live.server as live_server
    from quatform.bags import run_messages
    from quatform.bags.mcap import PATH_POSES

    session = LiveSession(scenario(20.0), {"controller": "quaternion"})
    server = live_server.LiveServer(session, port=0, realtime=0)
    built = []

    def counted(log, **kw):
        built.append((len(log), kw.get("every", True)))
        return run_messages(log, **kw)

    monkeypatch.setattr(live_server, "run_messages", counted)
    sent = {}
    monkeypatch.setattr(server, "_channel", lambda topic, msgtype, msgs: type(
        "C", (), {"log": lambda self, raw, log_time: sent.setdefault(topic, []).append(raw)})())
    try:
        for k in (400, 1000):
            while session.k < k:
                session.step()
            built.clear()
            server.publish(k - 5, True)
            assert built == [(5, True), (min(k, PATH_POSES), False)]
        whole = run_messages(session.log(0), store=server.store)
        for topic, _, raw in whole.once:
            if topic == "/quatform/log":
                assert json.loads(bytes(sent[topic][-1][8:-1]).decode())["samples"] == 1000
            else:
                assert sent[topic][-1] == raw, topic
    finally:
        server.stop()


def test_unusable_out_is_refused_before_serving(scenario, tmp_path):
    from quatform.errors import QuatformError

    (tmp_path / "afile").write_text("a file")
    session = LiveSession(scenario(2.0), {"controller": "quaternion"})
    served = []
    with pytest.raises((QuatformError, OSError)) as info:
        serve(session, tmp_path / "afile" / "sub", port=0, realtime=0, quiet=True, ready=served.append)
    assert not served and session.k == 0
    assert "afile" in str(info.value)


def test_failure_writes_the_ticks_before_it(scenario, tmp_path, monkeypatch):
    session = LiveSession(scenario(2.0), {"controller": "quaternion"})
    plain = session.reference

    def failing(k):
        if k == 30:
            raise RuntimeError("injected")
        return plain(k)

    monkeypatch.setattr(session, "reference", failing)
    with pytest.raises(RuntimeError, match="injected"):
        serve(session, tmp_path / "out", port=0, realtime=0, plots=False, quiet=True)
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["live"]["ticks"] == 30 and metrics["live"]["stopped"]
    assert metrics["live"]["failure"] == "RuntimeError: injected"
    rows = (tmp_path / "out" / "timeseries.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == 30


def test_port_in_use_is_one_line(scenario, tmp_path):
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
        p = subprocess.run([sys.executable, "-m", "quatform", "run", str(scenario(2.0)), "--controller", "quaternion",
                            "--out", str(tmp_path / "out"), "--no-plots", "--live", str(port)],
                           capture_output=True, text=True, env=env, timeout=60)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == (f"quatform: error: --live: port {port} on 127.0.0.1 is in use; give another or 0 "
                                "(any free port)")
    assert not (tmp_path / "out").exists()


def test_ipv6_url_in_brackets():
    from quatform.live.server import LiveServer, parse_address

    assert parse_address("[::1]:8765") == ("::1", 8765)
    assert LiveServer.url("::1", 8765) == "ws://[::1]:8765"
    assert LiveServer.url("127.0.0.1", 0) == "ws://127.0.0.1:0"


def test_playback_speed_keeps_unpaced_and_refuses_absurd(scenario):
    from types import SimpleNamespace

    from foxglove.websocket import PlaybackCommand

    from quatform.live.server import MAX_SPEED, LiveServer

    session = LiveSession(scenario(2.0), {"controller": "quaternion"})
    server = LiveServer(session, port=0, realtime=0)
    said = []
    server.status = lambda text, level="Error": said.append(text)
    try:
        def request(command, speed):
            return server.on_playback_control_request(SimpleNamespace(
                playback_command=getattr(PlaybackCommand, command), playback_speed=speed, request_id="r"))

        request("Pause", 1.0)
        assert session.paused and server.speed() == 0
        request("Play", 1.0)  # the stated speed of an unpaced run, unchanged by the client: still unpaced
        assert not session.paused and server.speed() == 0 and not said
        request("Play", 4.0)
        assert server.speed() == 4.0
        for bad in (float("inf"), float("nan"), 10 * MAX_SPEED, -1.0):
            request("Play", bad)
            assert server.speed() == 4.0
        assert len(said) == 4 and all("refused" in text for text in said)
    finally:
        server.stop()


def test_changes_from_another_thread_land_between_ticks(scenario):
    session = LiveSession(scenario(4.0), {"controller": "quaternion"})
    done = threading.Event()
    errors = []

    def client():
        i = 0
        while not done.is_set():
            try:
                session.set_parameter("gains.k_d", 10.0 + i % 2)
                session.set_parameter("min_separation_m", 0.3 - 0.05 * (i % 2))
            except Exception as exc:  # noqa: BLE001 - handed to the test
                errors.append(exc)
            i += 1

    t = threading.Thread(target=client, daemon=True)
    t.start()
    try:
        while not session.done:
            session.step()
    finally:
        done.set()
        t.join(10)
    assert not errors
    ticks = [c[0] for c in session.changes]
    assert ticks == sorted(ticks) and ticks and ticks[-1] < session.times.size
    assert np.all(np.isfinite(session.log()["command"]))


@pytest.mark.parametrize("payload, said", [
    ('{"pose": {}}', "no field pose.position.x"),
    ('{"pose": {"position": {"x": 0, "y": 0, "z": 1}}}', "no field pose.orientation.w"),
    ('{"pose": {"position": {"x": "0.5", "y": 0, "z": 1}, "orientation": {"w": 1, "x": 0, "y": 0, "z": 0}}}',
     "pose.position.x = '0.5' is not a number"),
    ('{"pose": {"position": {"x": 0, "y": true, "z": 1}, "orientation": {"w": 1, "x": 0, "y": 0, "z": 0}}}',
     "pose.position.y = True is not a number"),
    ('{"pose": {"position": {"x": 1e200, "y": 0, "z": 1}, "orientation": {"w": 1, "x": 0, "y": 0, "z": 0}}}',
     "farther than 1e+06 m"),
    ('{"pose": {', "not JSON"),
])
def test_goal_json_refused(scenario, payload, said):
    from types import SimpleNamespace

    from quatform.live.server import LiveServer

    session = LiveSession(scenario(2.0), {"controller": "quaternion"})
    session.step()
    server = LiveServer(session, port=0, realtime=0)
    statuses = []
    server.status = lambda text, level="Error": statuses.append(text)
    client = SimpleNamespace(id=1)
    try:
        server.on_client_advertise(client, SimpleNamespace(id=5, topic=GOAL_TOPIC, encoding="json",
                                                           schema_name=GOAL_TYPE))
        server.on_message_data(client, 5, payload.encode())
        assert len(statuses) == 1 and said in statuses[0] and statuses[0].startswith(GOAL_TOPIC + ": ")
        assert not statuses[0].startswith(f"{GOAL_TOPIC}: {GOAL_TOPIC}")
        assert "goal" not in session._pending
        server.on_client_advertise(client, SimpleNamespace(id=6, topic=GOAL_TOPIC, encoding="json",
                                                           schema_name="std_msgs/msg/String"))
        server.on_message_data(client, 6, b'{"pose": {"position": {"x": 0, "y": 0, "z": 1}, '
                                          b'"orientation": {"w": 1, "x": 0, "y": 0, "z": 0}}}')
        assert "schema 'std_msgs/msg/String'" in statuses[-1] and "goal" not in session._pending
    finally:
        server.stop()
