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

import dataclasses
import math
from typing import Callable

import numpy as np

from ..control.contract import Step
from ..errors import InvalidInputError, QuatformError, ShapeError
from .log import Channel, Log

__all__ = ["simulate", "PerfectMeasurement", "WORLD_ERRORS"]


class PerfectMeasurement:
    """The plant's output, exactly and at once."""

    columns = None

    def start(self, t0: float, y0, batch: tuple = ()) -> None:
        self._y = y0

    def observe(self, t: float, y) -> None:
        self._y = y

    def read(self, t: float):
        return self._y


#: What a controller may raise because of some worlds of a batch (their measurement left the
#: description's domain, two robots coincide ...); anything else (a TypeError: a bug) propagates.
WORLD_ERRORS = (QuatformError, ArithmeticError, ValueError)


def _map_worlds(value, batch: tuple, fn, min_extra: int = 0):
    """``value`` with ``fn`` applied to every array in it whose leading axes are ``batch``
    (and that has at least ``min_extra`` axes more): through dataclasses, tuples, lists and
    dicts; anything else (None, numbers, flags) is kept."""
    if isinstance(value, np.ndarray):
        if value.ndim >= len(batch) + min_extra and value.shape[:len(batch)] == batch:
            return fn(value)
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.replace(value, **{f.name: _map_worlds(getattr(value, f.name), batch, fn, min_extra)
                                             for f in dataclasses.fields(value) if f.init})
    if isinstance(value, (tuple, list)):
        return type(value)(_map_worlds(v, batch, fn, min_extra) for v in value)
    if isinstance(value, dict):
        return {k: _map_worlds(v, batch, fn, min_extra) for k, v in value.items()}
    return value


class _Worlds:
    """Which worlds of a batched run failed, and why (the contract of :mod:`quatform.sim.backends`).

    A failed world is frozen: its plant state stays the last finite one, its commands are zero
    and its signals NaN from then on. The controller keeps running on the healthy worlds: the
    failed ones are handed a healthy world's measurement and controller state (their results
    are discarded), so a controller that raises because of one world does not stop the others.
    """

    def __init__(self, batch: tuple, controller):
        self.batch = batch
        self.failed = np.zeros(batch, dtype=bool)
        self.failure: dict = {}
        self.n_u = len(controller.command_names)
        self.widths = {k: len(c) for k, c in controller.signal_columns().items()}

    def _mark(self, mask, reason: str) -> None:
        new = np.asarray(mask, dtype=bool) & ~self.failed
        for idx in zip(*np.nonzero(new)):
            self.failure[tuple(int(i) for i in idx)] = reason
        self.failed |= new

    def _healthy(self):
        ok = np.argwhere(~self.failed)
        return tuple(int(i) for i in ok[0]) if ok.size else None

    def _shadow(self, m, state):
        """``m`` and ``state`` with every failed world's entries replaced by a healthy world's."""
        src = self._healthy()
        bad = self.failed

        def put(a):
            a = a.copy()
            a[bad] = a[src]
            return a

        return _map_worlds(np.asarray(m), self.batch, put, 1), _map_worlds(state, self.batch, put)

    def _find(self, alone, what: str, exc) -> None:
        """Mark the healthy worlds for which ``alone(idx)`` (the batch's call on world ``idx``
        only) raises, each with ``what`` and its own reason; re-raise ``exc`` when none does."""
        found = False
        for idx in np.ndindex(*self.batch):
            if self.failed[idx]:
                continue
            try:
                alone(idx)
            except WORLD_ERRORS as own:
                mask = np.zeros(self.batch, dtype=bool)
                mask[idx] = True
                self._mark(mask, what + " ".join(str(own).split()))
                found = True
        if not found:
            raise exc

    def update(self, controller, t: float, m, reference, state) -> Step:
        """``controller.update`` on the batch, failed worlds masked and new failures marked."""
        if self.failed.any() and self._healthy() is not None:
            m, state = self._shadow(m, state)
        if self._healthy() is None:
            return self._masked(Step(np.zeros(self.batch + (self.n_u,)), state,
                                     {k: np.zeros(self.batch + (w,)) for k, w in self.widths.items()}))
        try:
            step = controller.update(t, m, reference, state)
        except WORLD_ERRORS as exc:
            def alone(idx):
                take = (lambda a: a[idx])
                controller.update(t, np.asarray(m)[idx], _map_worlds(reference, self.batch, take, 1),
                                  _map_worlds(state, self.batch, take))
            self._find(alone, f"t = {t:g} s: ", exc)
            return self.update(controller, t, m, reference, state)
        u = np.asarray(step.u, dtype=float)
        self._mark(~np.all(np.isfinite(u), axis=-1), f"t = {t:g} s: non-finite command")
        return self._masked(step) if self.failed.any() else step

    def _masked(self, step: Step) -> Step:
        bad = self.failed[..., None]
        return Step(np.where(bad, 0.0, step.u), step.state,
                    {k: np.where(bad, np.nan, np.asarray(v, dtype=float)) for k, v in step.signals.items()})

    def step(self, plant, x, u, dt: float, t: float):
        """``plant.step`` on the batch: a failed world steps a healthy world's state (its result
        discarded: it stays at ``x``), worlds the plant refuses or that become non-finite are
        marked failed."""
        healthy = self._healthy()
        if healthy is None:
            return x
        x_in = x
        if self.failed.any():
            x_in = x.copy()
            x_in[self.failed] = x[healthy]
        try:
            x_new = plant.step(x_in, u, dt, t)
        except WORLD_ERRORS as exc:
            self._find(lambda idx: plant.step(x_in[idx], np.asarray(u)[idx], dt, t),
                       f"t = {t:g} s: the plant refused the world's state: ", exc)
            return self.step(plant, x, u, dt, t)
        self._mark(~np.all(np.isfinite(x_new), axis=-1), f"t = {t + dt:g} s: non-finite plant state")
        return np.where(self.failed[..., None], x, x_new) if self.failed.any() else x_new


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
        controller's state after the last tick (why it stopped, what it held ...). A batched
        run in which some worlds fail (non-finite state or command, a controller raising for
        them) goes on with the others: ``meta["failed"]`` (bool, the batch shape) and
        ``meta["failure"]`` (world index tuple -> one-line reason) say which and why; a failed
        world is frozen (state held, zero commands, NaN signals). One world runs as before:
        its errors propagate.
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
    worlds = _Worlds(batch, controller) if batch else None
    for k in range(n):
        t = float(times[k])
        m = measurement.read(t)
        if worlds is None:
            step = controller.update(t, m, reference(k), state)
        else:
            step = worlds.update(controller, t, m, reference(k), state)
        state = step.state
        xs.append(x)
        ms.append(m)
        us.append(step.u)
        for key, lst in sig.items():
            lst.append(step.signals[key])
        for j in range(substeps):
            if worlds is None:
                x = plant.step(x, step.u, dt, t + j * dt)
            else:
                x = worlds.step(plant, x, step.u, dt, t + j * dt)
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
    info = {"controller": controller.name, "controller_state": state, **(meta or {})}
    if worlds is not None and worlds.failed.any():
        info.update(failed=worlds.failed.copy(), failure=dict(worlds.failure))
    return Log(times, chans, info)
