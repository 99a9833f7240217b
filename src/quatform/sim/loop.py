"""The UGV-UAV runs' own closed loop (seed 001), until they move to :func:`quatform.sim.simulate`.

Sim layer. ``closed_loop`` integrates a plant with a fixed step, lets a measurement model
see every plant state, and calls the controller every ``substeps`` plant steps with the
measurement available then and the reference of that tick (zero-order hold of the
commands). The UGV-UAV runs of seed 001 (motion capture, Pioneer and Bebop) use it; the
two-robot runs of seed 000 run on :func:`quatform.sim.simulate`.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["closed_loop", "History", "LoopLog"]


@dataclass(frozen=True)
class LoopLog:
    """Per control tick: true ``states``, ``measured`` values, the controller's ``cluster``
    state, ``commands`` and ``raw_finite`` flags (arrays with a leading axis of ticks)."""

    states: np.ndarray
    measured: np.ndarray
    cluster: np.ndarray
    commands: np.ndarray
    raw_finite: np.ndarray


class History:
    """True states by time, for measurements with latency (kept as long as needed)."""

    def __init__(self, horizon_s: float):
        self.horizon = horizon_s
        self.t: list[float] = []
        self.x: list[np.ndarray] = []

    def add(self, t, x):
        self.t.append(t)
        self.x.append(x)
        while len(self.t) > 2 and self.t[1] < t - self.horizon:
            self.t.pop(0)
            self.x.pop(0)

    def at(self, t):
        """The latest state at or before ``t`` (the oldest kept before that)."""
        i = bisect.bisect_right(self.t, t + 1e-12) - 1
        return self.x[max(i, 0)]


def closed_loop(times, substeps: int, dt: float, x0, plant_step: Callable, measurement, compute: Callable,
                reference_at: Callable, progress: Callable | None = None) -> LoopLog:
    """Run the loop over the control ticks ``times`` (``times[k+1] - times[k] = substeps dt``).

    Parameters
    ----------
    plant_step : callable ``(x, u, dt) -> x``
    measurement : object with ``observe(t, x)`` (every plant step) and ``read(t)``
    compute : callable ``(t, measured, reference) -> result`` with ``.commands``,
        ``.cluster`` and ``.raw_finite``
    reference_at : callable ``k -> Reference``
    progress : callable ``fraction -> None``, about every 10 %
    """
    n = len(times)
    x = np.asarray(x0, dtype=float)
    logs = {k: [] for k in ("states", "measured", "cluster", "commands", "ok")}
    tick = max(1, n // 10)
    measurement.observe(float(times[0]) if n else 0.0, x.copy())
    for k in range(n):
        t = float(times[k])
        m = measurement.read(t)
        res = compute(t, m, reference_at(k))
        logs["states"].append(x.copy())
        logs["measured"].append(np.array(m, dtype=float))
        logs["cluster"].append(res.cluster)
        logs["commands"].append(res.commands)
        logs["ok"].append(bool(res.raw_finite))
        for j in range(substeps):
            x = plant_step(x, res.commands, dt)
            measurement.observe(t + (j + 1) * dt, x.copy())
        if progress is not None and (k + 1) % tick == 0:
            progress((k + 1) / n)

    def stack(key, width):
        return np.array(logs[key], dtype=float).reshape(n, width)

    return LoopLog(stack("states", x.size), stack("measured", len(logs["measured"][0]) if n else 0),
                   np.array(logs["cluster"], dtype=float).reshape(n, -1) if n else np.zeros((0, 0)),
                   stack("commands", len(logs["commands"][0]) if n else 0), np.array(logs["ok"], dtype=bool))
