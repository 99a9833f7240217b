"""The closed loop shared by every simulation: plant, measurement, controller, reference.

Sim layer. ``closed_loop`` integrates a plant with a fixed step, lets a measurement model
see every plant state, and calls the controller every ``substeps`` plant steps with the
measurement available then and the reference of that tick (zero-order hold of the
commands). The two-robot runs of seed 000 (perfect measurement, holonomic robots) use it;
the UGV-UAV runs of seed 001 go through :func:`quatform.sim.simulate.simulate`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["closed_loop", "PerfectMeasurement", "LoopLog"]


@dataclass(frozen=True)
class LoopLog:
    """Per control tick: true ``states``, ``measured`` values, the controller's ``cluster``
    state, ``commands`` and ``raw_finite`` flags (arrays with a leading axis of ticks)."""

    states: np.ndarray
    measured: np.ndarray
    cluster: np.ndarray
    commands: np.ndarray
    raw_finite: np.ndarray


class PerfectMeasurement:
    """The true state, at once."""

    def observe(self, t: float, x: np.ndarray) -> None:
        self._x = x

    def read(self, t: float) -> np.ndarray:
        return self._x


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
