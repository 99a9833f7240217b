"""The ROS 2 bridge on the dds transport, on loopback: round trip and sustained rates.

``quatform ros2 --transport dds`` runs in its own process on seed 000's helix (two robots,
quaternion controller); this process is a plain Cyclone DDS peer (``tests/dds_peer.py``:
loopback only, multicast off, its own domain id). Rows:

* **lockstep 100 Hz** (``--use-sim-time``): per tick the peer writes both robots' poses and a
  ``/clock`` step, then reads both commands computed from those poses; round trip = the peer's
  write of the poses to its read of the second command (median, p99), and the largest
  difference from the simulated commands (0 up to float rounding: the same ticks);
* **lockstep, unpaced**: the same as fast as the round trip allows: control ticks per second
  sustained (each: 3 messages in, 2 out);
* **timer R Hz** (wall clock, ``--rate R``): the peer writes poses at R Hz per robot for a few
  seconds; commands per second read per robot.

Run it from the repository root (~40 s)::

    PYTHONPATH=src python benchmarks/bench_dds_loopback.py [--ticks 1000]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import signal
import tempfile
import time
from pathlib import Path

import numpy as np

from quatform.ros2.bridge import FormationBridge, experiment_for
from quatform.ros2.robots_file import read_robots_file

ROOT = Path(__file__).resolve().parents[1]


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


P = _load("dds_peer", ROOT / "tests" / "dds_peer.py")
H = _load("ros2_helpers", ROOT / "tests" / "fake_rclpy" / "ros2_helpers.py")
DT_NS = 10_000_000


def _start(folder, env, *extra):
    robots = H.write(folder / "robots.toml", H.PAIR_ROBOTS.replace("timeout_s = 0.05", "timeout_s = 0.5"))
    args = ["ros2", "--transport", "dds", "--scenario", "mas-kitts-helix", "--robots", robots, "--controller",
            "quaternion", *extra]
    return P.quatform_process(args, env, folder / "bridge.log"), read_robots_file(robots)


def lockstep(folder, env, poses, u, ticks):
    proc, rf = _start(folder, env, "--use-sim-time")
    try:
        peer = P.PairPeer(int(env["ROS_DOMAIN_ID"]), rf)
        P.Peer.wait_matched(peer.pose_w + [peer.clock_w] + peer.cmd.readers, 30.0, proc)
        (p1, q1), (p2, q2) = poses
        c0 = P.started(peer, poses, DT_NS, proc, folder / "bridge.log")
        out = {}
        k = 1
        for label, paced in (("lockstep 100 Hz", True), ("lockstep, unpaced", False)):
            lat, t0 = [], time.monotonic()
            for n in range(ticks):
                if paced:
                    time.sleep(max(0.0, t0 + (n + 1) * 0.01 - time.monotonic()))
                c = c0 + k * DT_NS
                peer.step(c, (P.pose(k, p1, q1, c), P.pose(k, p2, q2, c)))
                if not peer.cmd.wait_for(c, 10.0):
                    raise SystemExit(f"no command at tick {k}: see {folder / 'bridge.log'}")
                lat.append(max(x[0] for x in peer.cmd.stamped(c)) - peer.sent_ns[-1])
                k += 1
            wall = time.monotonic() - t0
            got = np.array([[peer.cmd.stamped(c0 + j * DT_NS)[i][2] for i in range(2)] for j in range(k)])
            want = np.stack([np.c_[u[:k, 4 * i:4 * i + 3], np.zeros((k, 2)), u[:k, 4 * i + 3]] for i in range(2)], 1)
            ms = np.asarray(lat) * 1e-6
            out[label] = (np.median(ms), np.percentile(ms, 99), ticks / wall, float(np.abs(got - want).max()))
        return out
    finally:
        P.stop(proc, signal.SIGINT)


def timer(folder, env, poses, rate_hz, seconds):
    proc, rf = _start(folder, env, "--rate", str(rate_hz))
    try:
        peer = P.PairPeer(int(env["ROS_DOMAIN_ID"]), rf)
        P.Peer.wait_matched(peer.pose_w + peer.cmd.readers, 30.0, proc)
        (p1, q1), (p2, q2) = poses
        t0, n = time.monotonic(), 0
        start_counts = None
        while time.monotonic() - t0 < seconds + 1.0:
            time.sleep(max(0.0, t0 + n / rate_hz - time.monotonic()))
            t = time.time_ns()
            k = n % len(p1)
            for w, (p, q) in zip(peer.pose_w, ((p1, q1), (p2, q2))):
                peer.peer.write(w, P.pose(k, p, q, t))
            peer.cmd.poll(0.0)
            if start_counts is None and time.monotonic() - t0 >= 1.0:  # 1 s to start and settle
                start_counts, t1 = [len(b) for b in peer.cmd.got], time.monotonic()
            n += 1
        peer.cmd.poll(0.05)
        wall = time.monotonic() - t1
        return [(len(b) - s) / wall for b, s in zip(peer.cmd.got, start_counts)], (n - 1) / (time.monotonic() - t0)
    finally:
        P.stop(proc, signal.SIGINT)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args(argv)
    exp = experiment_for("mas-kitts-helix", "quaternion")
    log = exp.run()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        env = P.loopback_env(folder)
        os.environ.update(env)
        pr = FormationBridge(exp, read_robots_file(H.write(folder / "r.toml", H.PAIR_ROBOTS))).plant_robots
        poses = H.robot_poses(pr.models, pr.state_slices, log["state"])
        u = np.asarray(log["command"])
        print(f"{'run':<22}{'median ms':>10}{'p99 ms':>9}{'ticks/s':>9}{'max |du|':>10}")
        for label, (med, p99, rate, du) in lockstep(folder, env, poses, u, args.ticks).items():
            print(f"{label:<22}{med:>10.2f}{p99:>9.2f}{rate:>9.0f}{du:>10.1e}")
        for rate in (100, 500, 1000):
            got, sent = timer(folder, env, poses, rate, args.seconds)
            print(f"timer {rate} Hz: poses written {sent:.0f}/s per robot, commands read "
                  f"{', '.join(f'{g:.0f}' for g in got)}/s (r1, r2)")


if __name__ == "__main__":
    main()
