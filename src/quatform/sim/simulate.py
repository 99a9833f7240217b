"""The one closed loop: plant, measurement model, controller and reference, B worlds per tick.

Sim layer. :func:`simulate` integrates any plant with a fixed step ``dt``, lets a
measurement model see every plant state (its own rates, noise, latency and dropouts are
its business), calls the controller every ``substeps`` plant steps on the measurement
available then and the reference of that tick (zero-order hold of the commands), and
returns one :class:`~quatform.sim.log.Log`. The initial state may carry leading batch axes:
then the plant, the measurement model and the controller run on all worlds at once, one
Python iteration per tick (crazyflow's ``(worlds, ..., k)`` state axes).

Contracts (duck-typed; every object of quatform that plays a role implements them):

* plant: ``state_columns`` (names of the state's entries), ``output_columns`` (names of
  what a sensor sees), ``batchable`` (bool: whether ``x0`` may carry batch axes),
  ``output(x) -> y`` and ``step(x, u, dt, t) -> x`` (pure: returns the next state).
* measurement: ``columns`` (or None: the plant's outputs), ``start(t0, y0, batch)``,
  ``observe(t, y)`` after every plant step and ``read(t) -> measured``.
* controller: :class:`quatform.control.contract.Controller` (``init``, ``update``,
  ``command_names``, ``signal_columns``).
* reference: a callable ``k -> reference`` for the tick index ``k`` (what the controller's
  ``update`` takes; ``None`` for a controller without a reference).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..errors import InvalidInputError, ShapeError
from .log import Channel, Log

__all__ = ["simulate", "PerfectMeasurement"]


class PerfectMeasurement:
    """The plant's output, exactly and at once."""

    columns = None

    def start(self, t0: float, y0, batch: tuple = ()) -> None:
        self._y = y0

    def observe(self, t: float, y) -> None:
        self._y = y

    def read(self, t: float):
        return self._y


def simulate(plant, controller, reference: Callable, times, x0, *, dt: float | None = None, substeps: int = 1,
             measurement=None, progress: Callable | None = None, meta: dict | None = None) -> Log:
    """Run the closed loop over the control ticks ``times``.

    Parameters
    ----------
    plant, controller, reference, measurement
        See the module docstring; ``measurement`` defaults to :class:`PerfectMeasurement`.
    times : array_like, shape (T,)
        Control ticks, s, evenly spaced by ``substeps * dt``.
    x0 : array_like, shape (*batch, n_x)
        Initial plant state of every world.
    dt : float, optional
        Plant step, s; default ``(times[1] - times[0]) / substeps``.
    substeps : int
        Plant steps per control tick.
    progress : callable, optional
        ``progress(fraction)`` about every 10 % of the ticks.
    meta : dict, optional
        Stored in the log's ``meta``.

    Returns
    -------
    Log
        Channels ``state`` (the plant state at each tick, before its command acts),
        ``measured`` (what the controller read), ``command`` and every signal the
        controller returns, each ``(T, *batch, k)``; ``meta["controller_state"]`` is the
        controller's state after the last tick (why it stopped, what it held ...).
    """
    times = np.asarray(times, dtype=float)
    if times.ndim != 1:
        raise ShapeError(f"simulate: times must have shape (T,), got {times.shape}")
    if not isinstance(substeps, int) or isinstance(substeps, bool) or substeps < 1:
        raise InvalidInputError(f"simulate: substeps must be a whole number >= 1, got {substeps!r}")
    n = times.size
    if dt is None:
        dt = float(times[1] - times[0]) / substeps if n > 1 else 0.0
    elif not (isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool) and math.isfinite(dt)
              and dt > 0):
        raise InvalidInputError(f"simulate: dt = {dt!r} must be a positive finite number of seconds (the plant step)")
    if not np.all(np.isfinite(times)):
        raise InvalidInputError("simulate: times must be finite (control ticks in s)")
    if n > 1:
        gaps = np.diff(times)
        tick = substeps * dt
        if not np.all(np.abs(gaps - tick) <= 1e-9 * max(tick, 1e-300) + 1e-12):
            worst = float(gaps[np.argmax(np.abs(gaps - tick))])
            raise InvalidInputError(
                f"simulate: the control ticks must be evenly spaced by substeps * dt = {substeps} * {dt!r} = "
                f"{tick!r} s, but one gap is {worst!r} s; give times = t0 + k * substeps * dt (the plant "
                "advances substeps steps of dt between ticks)")
    x = np.array(x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),):
        raise ShapeError(f"simulate: x0 must have shape (*batch, {len(plant.state_columns)}), got {x.shape}")
    batch = x.shape[:-1]
    if batch and not plant.batchable:
        raise InvalidInputError(f"simulate: the plant {type(plant).__name__} runs one world at a time; "
                                f"give x0 without batch axes (got batch shape {batch})")
    measurement = PerfectMeasurement() if measurement is None else measurement
    columns = controller.signal_columns()
    state = controller.init(batch)
    t0 = float(times[0]) if n else 0.0
    measurement.start(t0, plant.output(x), batch)
    xs, ms, us = [], [], []
    sig = {k: [] for k in columns}
    tick = max(1, n // 10)
    for k in range(n):
        t = float(times[k])
        m = measurement.read(t)
        step = controller.update(t, m, reference(k), state)
        state = step.state
        xs.append(x)
        ms.append(m)
        us.append(step.u)
        for key, lst in sig.items():
            lst.append(step.signals[key])
        for j in range(substeps):
            x = plant.step(x, step.u, dt, t + j * dt)
            measurement.observe(t + (j + 1) * dt, plant.output(x))
        if progress is not None and (k + 1) % tick == 0:
            progress((k + 1) / n)
    out_cols = measurement.columns if measurement.columns is not None else plant.output_columns

    def stack(lst, width):
        if not lst:
            return np.zeros((0,) + batch + (width,))
        return np.asarray(lst, dtype=float).reshape((n,) + batch + (width,))

    chans = [Channel("state", plant.state_columns, stack(xs, len(plant.state_columns))),
             Channel("measured", out_cols, stack(ms, len(out_cols))),
             Channel("command", controller.command_names, stack(us, len(controller.command_names)))]
    for key, cols in columns.items():
        chans.append(Channel(key, cols, stack(sig[key], len(cols))))
    return Log(times, chans, {"controller": controller.name, "controller_state": state, **(meta or {})})
