"""Metrics regression check: run every built-in scenario with every choice through the CLI.

    python tools/metrics_regression.py record BASELINE.json [--mujoco] [--plots]
    python tools/metrics_regression.py compare BASELINE.json [--mujoco] [--rtol 1e-9]

``record`` writes every run's metrics.json (and, with --plots, the file names each run
wrote) into one JSON; ``compare`` runs the same list with the code on PYTHONPATH and
reports every value that differs beyond ``rtol`` relative (keys only in the new run are
listed as added). Timing keys (``wall_time_s``, ``solve_time_s``) are not compared.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

PAIR = ("mas-kitts-helix", "mas-kitts-spiral", "mas-kitts-yaw-step")
PAIR_CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")
UGV_UAV = ("marciano-circle", "marciano-front-to-over", "marciano-lemniscate")
FORMATIONS = ("spherical", "restricted", "quaternion")
TELEOP = ("teleop-free-motion", "teleop-pitch-hold-at-90", "teleop-pitch-through-90", "teleop-preload",
          "teleop-virtual-wall", "teleop-wall-contact")
TEAM = ("team-tetrahedron-helix", "team-ring-flip", "team-triangle-over-ugv", "team-grid-100", "team-three-bodies")
IGNORED = {"wall_time_s", "solve_time_s", "render_backend"}


def cases(mujoco: bool):
    for sc in PAIR:
        for c in PAIR_CONTROLLERS:
            yield f"{sc}/{c}", ["run", sc, "--controller", c]
            yield f"{sc}/{c}/no-ff", ["run", sc, "--controller", c, "--no-feedforward"]
            if mujoco:
                yield f"{sc}/{c}/mujoco", ["run", sc, "--controller", c, "--physics", "mujoco"]
    for sc in UGV_UAV:
        for f in FORMATIONS:
            yield f"{sc}/{f}", ["run", sc, "--formation", f]
            if mujoco:
                yield f"{sc}/{f}/mujoco", ["run", sc, "--formation", f, "--physics", "mujoco"]
    yield "marciano-circle/quaternion/mocap", ["run", "marciano-circle", "--formation", "quaternion",
                                               "--mocap-noise-m", "0.002", "--mocap-latency-s", "0.005"]
    for sc in TEAM:
        for c in PAIR_CONTROLLERS:
            yield f"{sc}/{c}", ["run", sc, "--controller", c]
    if mujoco:
        yield "team-tetrahedron-helix/quaternion/mujoco", ["run", "team-tetrahedron-helix", "--controller",
                                                           "quaternion", "--physics", "mujoco"]
    for sc in TELEOP:
        for oe in ("euler-parameters", "rpy"):
            for pre in ("on", "off"):
                yield f"{sc}/{oe}/{pre}", ["teleop", sc, "--orientation-error", oe, "--preload", pre]


def run_all(mujoco: bool, plots: bool, only: str | None):
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, (key, argv) in enumerate(cases(mujoco)):
            if only and only not in key:
                continue
            d = Path(tmp) / f"r{i}"
            cmd = [sys.executable, "-m", "quatform.cli", *argv, "--out", str(d)] + ([] if plots else ["--no-plots"])
            p = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
            if p.returncode != 0:
                out[key] = {"error": p.stderr.strip()[-500:]}
            else:
                m = json.loads((d / "metrics.json").read_text())
                out[key] = {"metrics": m, "files": sorted(f.name for f in d.iterdir())}
            print(f"{key}: {'ok' if p.returncode == 0 else 'FAILED'}", file=sys.stderr, flush=True)
    return out


def diff(a, b, rtol, path=""):
    """Differences between the old value ``a`` and the new ``b``: list of strings."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in a:
            if k in IGNORED:
                continue
            if k not in b:
                out.append(f"{path}{k}: removed")
            else:
                out += diff(a[k], b[k], rtol, f"{path}{k}.")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path[:-1]}: length {len(a)} -> {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in diff(x, y, rtol, f"{path}{i}.")]
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)) or not isinstance(b, (int, float)):
        return [] if a == b else [f"{path[:-1]}: {a!r} -> {b!r}"]
    if a == b or abs(a - b) <= rtol * max(abs(a), abs(b)) or (math.isnan(a) and math.isnan(b)):
        return []
    return [f"{path[:-1]}: {a!r} -> {b!r}"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("record", "compare"))
    ap.add_argument("baseline")
    ap.add_argument("--mujoco", action="store_true")
    ap.add_argument("--plots", action="store_true")
    ap.add_argument("--only", help="only the cases whose key contains this text")
    ap.add_argument("--rtol", type=float, default=1e-9)
    a = ap.parse_args()
    new = run_all(a.mujoco, a.plots, a.only)
    if a.mode == "record":
        Path(a.baseline).write_text(json.dumps(new, indent=1, sort_keys=True))
        return 0
    old = json.loads(Path(a.baseline).read_text())
    bad = 0
    for key, o in old.items():
        if key not in new:
            continue
        n = new[key]
        d = diff(o.get("metrics", o), n.get("metrics", n), a.rtol)
        if a.plots and "files" in o and "files" in n:
            missing = sorted(set(o["files"]) - set(n["files"]))
            d += [f"file missing: {f}" for f in missing]
        added = sorted(set(n.get("metrics", {})) - set(o.get("metrics", {})))
        if d:
            bad += 1
            print(f"{key}:\n  " + "\n  ".join(d))
        if added:
            print(f"{key}: added keys {', '.join(added)}")
    print(f"{bad} of {len([k for k in old if k in new])} cases differ beyond rtol = {a.rtol:g}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
