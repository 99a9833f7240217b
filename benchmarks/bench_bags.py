"""Cost of ``run.mcap``: the 60 s, 100 Hz, two-robot ``mas-kitts-spiral`` run.

Columns, in CPU time of this process (``time.process_time``, best of ``--repeat``):

* **simulate**: the run itself (``experiment.run()``, quaternion controller), for scale;
* **write_mcap**: the whole ``run.mcap`` (every topic, rosbags' writer, zstd chunks);
* **read_log**: reading it back into the log;
* **poses: batch** / **poses: per message**: the T ``PoseStamped`` of one topic built as one
  CDR byte array (``quatform.bags.cdr.Batch``) against the peer, one
  ``quatform.messages.pose_stamped`` plus ``rosbags`` ``serialize_cdr`` per sample (what a
  writer calling rosbags message by message does), and their ratio.

Run it from the repository root (~15 s)::

    PYTHONPATH=src python benchmarks/bench_bags.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from quatform import messages
from quatform.bags import read_log, write_mcap
from quatform.bags.cdr import Batch
from quatform.formations import geometry as g
from quatform.scenarios import kind_of, load_scenario


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    sc = load_scenario("mas-kitts-spiral")
    kind = kind_of(sc)
    exp = kind.experiment(sc, controller="quaternion")
    log = exp.run(None)
    t_sim = best(lambda: exp.run(None), 1)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.mcap"
        t_write = best(lambda: write_mcap(log, path, kind=kind.name), args.repeat)
        t_read = best(lambda: read_log(path), args.repeat)
        size = path.stat().st_size
    state = log["state"]
    p, q = state[:, 0:3], g.q_yaw(state[:, 3])
    ns = np.round(log.t * 1e9).astype(np.int64)
    store = messages.typestore()
    template = messages.pose_stamped(0.0, [0, 0, 0], [1, 0, 0, 0], "world")
    cols = {("header", "stamp", "sec"): (ns // 10**9).astype(np.int32),
            ("header", "stamp", "nanosec"): (ns % 10**9).astype(np.uint32)}
    cols.update({("pose", "position", a): p[:, i] for i, a in enumerate("xyz")})
    cols.update({("pose", "orientation", a): q[:, i] for i, a in enumerate("wxyz")})
    t_batch = best(lambda: Batch.build(store, template, cols, len(log)), args.repeat)

    def per_message():
        for k in range(len(log)):
            msg = messages.pose_stamped(float(log.t[k]), p[k], q[k], "world")
            store.serialize_cdr(msg, msg.__msgtype__)
    t_each = best(per_message, args.repeat)
    print(f"mas-kitts-spiral, quaternion: {len(log)} samples ({log.t[-1]:.0f} s at {1 / (log.t[1] - log.t[0]):.0f} Hz), "
          f"2 robots; CPU s, best of {args.repeat}")
    print(f"  simulate            {t_sim:8.3f} s")
    print(f"  write_mcap          {t_write:8.3f} s  ({size / 1e6:.1f} MB; {t_write / t_sim:.2f} x the run)")
    print(f"  read_log            {t_read:8.3f} s")
    print(f"  poses: batch        {t_batch * 1e3:8.2f} ms")
    print(f"  poses: per message  {t_each * 1e3:8.2f} ms  (rosbags serialize_cdr each; {t_each / t_batch:.0f} x the batch)")


if __name__ == "__main__":
    main()
