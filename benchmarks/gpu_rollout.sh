#!/usr/bin/env bash
# Robot-steps/s of quatform's JAX rollouts on a GPU, batch sizes 10^3 .. 10^6.
#
# Run from anywhere on the GPU machine (needs only a package registry): it makes a virtual
# environment in ${QF_GPU_VENV:-/tmp/quatform-gpu}, installs quatform with its jax extra and
# CUDA 12 JAX ("jax[cuda12]": jaxlib plus the jax-cuda12-plugin and NVIDIA's CUDA, cuDNN, cuBLAS
# ... wheels; needs an NVIDIA driver >= 525), prints the device, then for each controller the
# robot-steps/s (worlds x 2 robots x ticks / s, best of 2 after a compiling warm-up) of
# quatform.sim.jax_rollout.rollout_metrics on seed 000's helix, and the 10^4-trial helix Monte
# Carlo end to end. About 3 minutes (most of it the install).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
VENV="${QF_GPU_VENV:-/tmp/quatform-gpu}"
TICKS="${QF_GPU_TICKS:-200}"
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e "$ROOT[jax]" "jax[cuda12]"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
cd "$ROOT"
"$VENV/bin/python" - "$TICKS" <<'PY'
import sys
import time

import jax

sys.path.insert(0, "benchmarks")
from bench_rollout import CONTROLLERS, experiment, monte_carlo, starts  # noqa: E402

from quatform.sim.jax_rollout import rollout_metrics  # noqa: E402

ticks = int(sys.argv[1])
print("jax", jax.__version__, "devices:", jax.devices(), flush=True)
if jax.default_backend() != "gpu":
    print("WARNING: JAX sees no GPU; the numbers below are the CPU's", flush=True)
print(f"M robot-steps/s, {ticks} ticks of mas-kitts-helix")
print(f"{'controller':<18}" + "".join(f"{f'10^{e}':>10}" for e in range(3, 7)), flush=True)
for c in CONTROLLERS:
    ex = experiment(c, ticks)
    row = []
    for e in range(3, 7):
        worlds = 10 ** e
        x0 = starts(ex, worlds)
        rollout_metrics(ex, x0)  # compile
        best = float("inf")
        for _ in range(2):
            t0 = time.perf_counter()
            rollout_metrics(ex, x0)
            best = min(best, time.perf_counter() - t0)
        row.append(worlds * 2 * ticks / best / 1e6)
    print(f"{c:<18}" + "".join(f"{v:>10.1f}" for v in row), flush=True)
mc = monte_carlo(10_000, trials_per_call=10_000)
print(f"helix Monte Carlo {mc['trials']} trials x {mc['ticks']} ticks, quaternion controller: {mc['total_s']:.1f} s end to end "
      f"(batch {mc['build_s']:.1f} s, rollout + metrics {mc['rollout_and_metrics_s']:.1f} s)", flush=True)
PY
