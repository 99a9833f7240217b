"""The one closed loop: one pure tick of plant, measurement model and controller, and its drivers.

Sim layer. :func:`make_tick` builds the tick of a run, ``tick(carry, xs) -> (carry, ys)``,
from three pure parts (:mod:`quatform.control.contract`, :mod:`.measurement`,
:mod:`.plants`), written once on the array namespace of its operands:

* ``carry = (x, ctrl_state, meas_state, fail_tick, reason)``: the plant state
  ``(*batch, n_x)``, the controller's and the measurement model's states (pytrees whose
  leading axes are the batch), each world's failing tick (-1: none) and its reason code
  (0: none);
* ``xs = {k, t, ref, meas, plant[, valid]}``: the tick's index and time, the controller's
  :meth:`~quatform.control.contract.Controller.reference_arrays` (of ``(reference, slice)``
  for a controller that draws its own inputs up front, :func:`scheduled_reference`), the
  tick's slice of the measurement's ``schedule`` and of the plant's ``inputs``
  (``(substeps, ...)``), and in a padded progress chunk whether the tick is real;
* ``ys = (x, measured, u, *signals)``, the signals in ``signal_columns`` order.

A tick reads the measurement, runs ``controller.tick``, steps the plant ``substeps`` times
of ``dt`` under the held commands, the measurement observing each output. A world whose tick
has ``code > 0`` (or, in a batch, whose command or plant state is not finite) is failed from
that tick on and frozen: its plant and controller state held, its commands zero, its
signals NaN; the others go on.

Two drivers run the same tick and build the same :class:`~quatform.sim.log.Log`
(:data:`quatform.sim.backends.SIM_BACKENDS`):

* :func:`simulate_numpy` iterates ``carry, y = tick(carry, xs[k])`` on NumPy arrays. A
  controller that is not ``pure`` runs through its ``update`` (the contract's default
  ``tick``); in a batch, :class:`HostWorlds` marks a world whose ``update`` raises failed
  with its own message and hands the others on. Stateful plants (MuJoCo) run here.
* :func:`simulate_jax` runs ``jax.jit(lax.scan(tick))`` with the batch spread over JAX's
  devices (:mod:`.jax_devices`), float64 in ``jax.enable_x64``, in ten chunks when
  ``progress`` is given. It runs what declares a pure step: a ``pure`` controller, a
  ``batchable`` plant, a measurement model with the four methods of the contract; anything
  else is refused in one line (:func:`jax_refusal`).

A failed world's one-line message is ``controller.update``'s, rerun on the host at its
failing tick on that world alone; a run of one world (no batch axes) raises it. On JAX, a
world whose failing code the host's ``update`` does not confirm (it does not raise there:
the separation barrier's array algorithm did not solve a programme the exact host solver
solves, :mod:`quatform.control.barrier`) is rerun on NumPy from its start, with its own
initial state, measurement schedule and reference; its channels replace the JAX run's and
``log.meta["numpy_worlds"]`` (bool, the batch shape) says which.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np

from ..algebra.kernels import common_namespace
from ..control.contract import Tick
from ..errors import InvalidInputError, MissingDependencyError, QuatformError, ShapeError
from . import jax_devices
from .log import Channel, Log
from .measurement import PerfectMeasurement

__all__ = ["COMMAND_CODE", "PLANT_CODE", "HOST_CODE", "START_CODE", "start_failures", "WORLD_ERRORS", "HostWorlds", "check_ticks", "config_key",
           "iterate_numpy", "jax_refusal", "make_tick", "map_worlds", "require_jax", "scan_ticks",
           "Stepper", "tick_inputs", "scheduled_reference", "simulate_jax", "simulate_numpy",
           "cached"]

#: What a controller may raise because of some worlds of a batch (their measurement left the
#: description's domain, two robots coincide ...); anything else (a TypeError: a bug) propagates.
WORLD_ERRORS = (QuatformError, ArithmeticError, ValueError)
#: Reason codes of the loop itself (a controller's are small positive numbers): a world's
#: command not finite; its plant state not finite after plant step ``j`` (``PLANT_CODE + j``);
#: a failure :class:`HostWorlds` found and worded on the host; an initial state not finite.
COMMAND_CODE = 1 << 40
PLANT_CODE = 2 << 40
HOST_CODE = 3 << 40
START_CODE = 4 << 40


def start_failures(x):
    """``(fail_tick, reason)`` before the first tick for the initial states ``x``
    (``(*batch, n_x)``): a world whose initial state is not finite has failed at tick 0
    (:data:`START_CODE`), so no plant or controller meets its values."""
    bad = ~np.all(np.isfinite(x), axis=-1)
    return np.where(bad, 0, -1).astype(np.int64), np.where(bad, START_CODE, 0).astype(np.int64)


def _where(xp, mask, a, b):
    """``a`` where ``mask`` (the batch shape) else ``b``, the mask broadcast over the trailing axes."""
    mask = xp.asarray(mask)
    a, b = xp.asarray(a), xp.asarray(b)
    return xp.where(xp.reshape(mask, mask.shape + (1,) * (max(a.ndim, b.ndim) - mask.ndim)), a, b)


def tree_map(fn, tree, *rest):
    """``fn`` on every leaf (array) of ``tree`` and the matching leaves of ``rest``, through
    tuples, NamedTuples, lists, dicts and dataclasses; None stays None."""
    if tree is None:
        return None
    if isinstance(tree, tuple) and hasattr(tree, "_fields"):
        return type(tree)(*(tree_map(fn, *parts) for parts in zip(tree, *rest)))
    if isinstance(tree, (tuple, list)):
        return type(tree)(tree_map(fn, *parts) for parts in zip(tree, *rest))
    if isinstance(tree, dict):
        return {k: tree_map(fn, v, *(r[k] for r in rest)) for k, v in tree.items()}
    if dataclasses.is_dataclass(tree) and not isinstance(tree, type):
        return dataclasses.replace(tree, **{f.name: tree_map(fn, getattr(tree, f.name), *(getattr(r, f.name)
                                                                                        for r in rest))
                                            for f in dataclasses.fields(tree) if f.init})
    return fn(tree, *rest)


def map_worlds(value, batch: tuple, fn, min_extra: int = 0):
    """``value`` with ``fn`` applied to every NumPy array in it whose leading axes are ``batch``
    (and that has at least ``min_extra`` axes more): through dataclasses, tuples, lists and
    dicts; anything else (None, numbers, flags) is kept."""
    if isinstance(value, np.ndarray):
        if value.ndim >= len(batch) + min_extra and value.shape[:len(batch)] == batch:
            return fn(value)
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.replace(value, **{f.name: map_worlds(getattr(value, f.name), batch, fn, min_extra)
                                             for f in dataclasses.fields(value) if f.init})
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return type(value)(*(map_worlds(v, batch, fn, min_extra) for v in value))
    if isinstance(value, (tuple, list)):
        return type(value)(map_worlds(v, batch, fn, min_extra) for v in value)
    if isinstance(value, dict):
        return {k: map_worlds(v, batch, fn, min_extra) for k, v in value.items()}
    return value


def _plant_step(plant, x, u, dt, t, w):
    """``plant.step`` with the substep's exogenous inputs ``w`` (none: the four-argument call
    a stateful plant keeps)."""
    return plant.step(x, u, dt, t) if w is None else plant.step(x, u, dt, t, w)


def plant_inputs(plant, times, dt: float, substeps: int):
    """The plant's exogenous inputs ``(T, substeps, ...)`` (``plant.inputs``), or None."""
    inputs = getattr(plant, "inputs", None)
    return None if inputs is None else inputs(times, dt, substeps)


def make_tick(plant, controller, measurement, dt: float, substeps: int, *, control=None, step=None,
              freeze: bool = True):
    """The loop's tick ``(carry, xs) -> (carry, ys)`` (module docstring).

    Parameters
    ----------
    plant, controller, measurement
        The run's parts (:func:`quatform.sim.simulate`).
    dt : float
        Plant step, s.
    substeps : int
        Plant steps per control tick.
    control, step : callable, optional
        Stand-ins for ``controller.tick`` and ``plant.step`` (:class:`HostWorlds`).
    freeze : bool
        Freeze failed worlds (a batch). False: one world on NumPy, whose failure the driver
        raises; a tick whose code is not 0 then returns without stepping the plant.
    """
    # one world of a controller with update only: update itself (it raises), no codes to read
    code_free = not freeze and not controller.pure and control is None
    control = controller.tick if control is None else control
    names = tuple(controller.signal_columns())
    hold_state = bool(controller.pure)

    if step is None:
        def plant_step(x, u, t, w):
            return plant.step(x, u, dt, t) if w is None else plant.step(x, u, dt, t, w)
    else:
        def plant_step(x, u, t, w, failed=None):
            return step(x, u, dt, t, w, failed)

    def substep_inputs(xs, j):
        w = xs.get("plant")
        return None if w is None else {key: v[j] for key, v in w.items()}

    def tick(carry, xs):
        x, cs, ms, fail_tick, reason = carry
        ms, m = measurement.read(ms, xs["meas"])
        t = xs["t"]
        if not freeze:  # one world on NumPy: a failure ends the run (the driver raises)
            if code_free:  # update raises it
                out = controller.update(t, m, xs["ref"], cs)
            else:
                out = control(cs, m, xs["ref"], t)
                if np.any(out.code > 0):
                    return (x, cs, ms, xs["k"], out.code), None
            u, x_next = out.u, x
            for j in range(substeps):
                x_next = plant_step(x_next, u, t + j * dt, substep_inputs(xs, j))
                ms = measurement.observe(ms, plant.output(x_next), j)
            signals = out.signals
            return (x_next, out.state, ms, fail_tick, reason), (x, m, u) + tuple([signals[k] for k in names])
        out = control(cs, m, xs["ref"], t)
        xp = common_namespace(x, m, out.u, reason)
        u = xp.asarray(out.u, dtype=x.dtype)
        code = xp.where((out.code == 0) & ~xp.all(xp.isfinite(u), axis=-1), COMMAND_CODE, out.code)
        new = (reason == 0) & (code > 0)
        fail_tick = xp.where(new, xs["k"], fail_tick)
        reason = xp.where(new, code, reason)
        bad = reason > 0
        u = _where(xp, bad, 0.0, u)
        signals = tuple(_where(xp, bad, np.nan, xp.asarray(out.signals[k], dtype=x.dtype)) for k in names)
        state = tree_map(lambda a, b: _where(xp, bad, a, b), cs, out.state) if hold_state else out.state
        x_next = x
        for j in range(substeps):
            x_new = (plant_step(x_next, u, xs["t"] + j * dt, substep_inputs(xs, j)) if step is None else
                     plant_step(x_next, u, xs["t"] + j * dt, substep_inputs(xs, j), reason > 0))
            broken = (reason == 0) & ~xp.all(xp.isfinite(x_new), axis=-1)
            fail_tick = xp.where(broken, xs["k"], fail_tick)
            reason = xp.where(broken, PLANT_CODE + j, reason)
            x_next = _where(xp, reason > 0, x_next, x_new)
            ms = measurement.observe(ms, plant.output(x_next), j)
        new_carry = (x_next, state, ms, fail_tick, reason)
        if "valid" in xs:  # a padded tick past the run's end (progress chunks) changes nothing
            new_carry = tree_map(lambda a, b: xp.where(xs["valid"], a, b), new_carry, carry)
        return new_carry, (x, m, u) + signals

    return tick


class HostWorlds:
    """The worlds of a batch run by a controller that is not ``pure``, on NumPy (its
    ``update`` and a plant that may raise): which failed, and why.

    :meth:`tick` stands for ``controller.tick``: a failed world is handed a healthy world's
    measurement and controller state (its results are discarded), so a controller that raises
    because of one world does not stop the others; a world whose ``update`` alone raises is
    marked failed with its own message (code :data:`HOST_CODE`). :meth:`step` stands for
    ``plant.step`` in the same way (a world the plant refuses becomes NaN: the loop freezes
    it). The driver sets :attr:`failed` from the loop's reasons after every tick.
    """

    def __init__(self, batch: tuple, controller, plant):
        self.batch, self.controller, self.plant = batch, controller, plant
        self.failed = np.zeros(batch, dtype=bool)
        self.failure: dict = {}
        self.n_u = len(controller.command_names)
        self.widths = {k: len(c) for k, c in controller.signal_columns().items()}

    def _healthy(self):
        ok = np.argwhere(~self.failed)
        return tuple(int(i) for i in ok[0]) if ok.size else None

    def _shadow(self, m, state):
        """``m`` and ``state`` with every failed world's entries replaced by a healthy world's."""
        src, bad = self._healthy(), self.failed

        def put(a):
            a = a.copy()
            a[bad] = a[src]
            return a

        return map_worlds(np.asarray(m), self.batch, put, 1), map_worlds(state, self.batch, put)

    def _find(self, alone, what: str, exc) -> np.ndarray:
        """Mark the healthy worlds for which ``alone(idx)`` (the call on world ``idx`` only)
        raises, each with ``what`` and its own reason, and return them (bool, the batch
        shape); re-raise ``exc`` when none does."""
        new = np.zeros(self.batch, dtype=bool)
        for idx in np.ndindex(*self.batch):
            if self.failed[idx]:
                continue
            try:
                alone(idx)
            except WORLD_ERRORS as own:
                self.failure[tuple(int(i) for i in idx)] = what + " ".join(str(own).split())
                new[idx] = True
        if not new.any():
            raise exc
        self.failed |= new
        return new

    def tick(self, state, m, reference, t) -> Tick:
        """``controller.update`` on the batch, failed worlds shadowed, new failures found."""
        code = np.zeros(self.batch, dtype=np.int64)
        while True:
            if self._healthy() is None:
                return Tick(state, np.zeros(self.batch + (self.n_u,)),
                            {k: np.zeros(self.batch + (w,)) for k, w in self.widths.items()}, code)
            m_in, state_in = self._shadow(m, state) if self.failed.any() else (m, state)
            try:
                step = self.controller.update(t, m_in, reference, state_in)
            except WORLD_ERRORS as exc:
                def alone(idx, m_in=m_in, state_in=state_in):
                    take = (lambda a: a[idx])
                    self.controller.update(t, np.asarray(m_in)[idx], map_worlds(reference, self.batch, take, 1),
                                           map_worlds(state_in, self.batch, take))
                code[self._find(alone, f"t = {t:g} s: ", exc)] = HOST_CODE
                continue
            return Tick(step.state, np.asarray(step.u, dtype=float), step.signals, code)

    def step(self, x, u, dt: float, t: float, w=None, failed=None):
        """``plant.step`` on the batch: a failed world (``failed``, bool of the batch shape:
        the loop's failures up to this substep) steps a healthy world's state; a world the
        plant refuses is marked failed with its message and returned NaN."""
        if failed is not None:
            self.failed = np.asarray(failed, dtype=bool)
        healthy = self._healthy()
        if healthy is None:
            return x
        x_in = x
        if self.failed.any():
            x_in = x.copy()
            x_in[self.failed] = x[healthy]
        try:
            return _plant_step(self.plant, x_in, u, dt, t, w)
        except WORLD_ERRORS as exc:
            new = self._find(lambda idx: _plant_step(self.plant, x_in[idx], np.asarray(u)[idx], dt, t, w),
                             f"t = {t:g} s: the plant refused the world's state: ", exc)
            return np.where(new[..., None], np.nan, self.step(x, u, dt, t, w))  # the others, as they are


def check_ticks(times, substeps, dt, who: str = "simulate"):
    """Checked ``(times, dt)``: ``times`` ``(T,)`` finite and evenly spaced by ``substeps * dt``
    (``dt`` default ``(times[1] - times[0]) / substeps``); one-line errors naming ``who``."""
    times = np.asarray(times, dtype=float)
    if times.ndim != 1:
        raise ShapeError(f"{who}: times must have shape (T,), got {times.shape}")
    if not isinstance(substeps, int) or isinstance(substeps, bool) or substeps < 1:
        raise InvalidInputError(f"{who}: substeps must be a whole number >= 1, got {substeps!r}")
    n = times.size
    if dt is None:
        dt = float(times[1] - times[0]) / substeps if n > 1 else 0.0
    elif not (isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool) and math.isfinite(dt)
              and dt > 0):
        raise InvalidInputError(f"{who}: dt = {dt!r} must be a positive finite number of seconds (the plant step)")
    if not np.all(np.isfinite(times)):
        raise InvalidInputError(f"{who}: times must be finite (control ticks in s)")
    if n > 1:
        gaps = np.diff(times)
        tick = substeps * dt
        if not np.all(np.abs(gaps - tick) <= 1e-9 * max(tick, 1e-300) + 1e-12):
            worst = float(gaps[np.argmax(np.abs(gaps - tick))])
            raise InvalidInputError(
                f"{who}: the control ticks must be evenly spaced by substeps * dt = {substeps} * {dt!r} = "
                f"{tick!r} s, but one gap is {worst!r} s; give times = t0 + k * substeps * dt (the plant "
                "advances substeps steps of dt between ticks)")
    return times, float(dt)


def _initial(plant, x0, who: str):
    """``(x, batch)``: the initial states as floats ``(*batch, n_x)`` (one-line errors)."""
    x = np.array(x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),):
        raise ShapeError(f"{who}: x0 must have shape (*batch, {len(plant.state_columns)}), got {x.shape}")
    batch = x.shape[:-1]
    if batch and not plant.batchable:
        raise InvalidInputError(f"{who}: the plant {type(plant).__name__} runs one world at a time; "
                                f"give x0 without batch axes (got batch shape {batch})")
    if batch and math.prod(batch) == 0:
        raise ShapeError(f"{who}: x0 of shape {x.shape} holds no world; give at least one")
    return x, batch


def _failure(controller, reference, times, dt, measured, state, fail_tick, reason, batch, idx, host=None,
             confirm=False):
    """World ``idx``'s one-line failure (``"t = ... s: reason"``): :class:`HostWorlds`' message,
    the loop's own, or ``controller.update`` rerun on that world alone at its failing tick
    (``measured`` ``(T, *batch, n_m)``, ``state`` the final controller state: a failed world's
    is held from its failing tick); a run of one world (``idx == ()``) raises it. ``confirm``:
    None where that ``update`` does not raise (the host runs what the tick did not: the
    world is the host's to rerun)."""
    if host is not None and idx in host.failure:
        return host.failure[idx]
    k, code = int(fail_tick[idx]), int(reason[idx])
    t = float(times[k])
    if code == COMMAND_CODE:
        return f"t = {t:g} s: non-finite command"
    if PLANT_CODE <= code < HOST_CODE:
        return f"t = {t + (code - PLANT_CODE) * dt + dt:g} s: non-finite plant state"
    if code == START_CODE:
        return f"t = {t:g} s: the initial state holds a nan or inf; give every world a finite x0"
    take = (lambda a: a[idx])
    try:
        controller.update(t, measured[(k, *idx)], map_worlds(reference(k), batch, take, 1),
                          map_worlds(state, batch, take))
    except WORLD_ERRORS as own:
        if not idx:
            raise
        return f"t = {t:g} s: " + " ".join(str(own).split())
    if confirm:
        return None
    text = controller.failure_reasons.get(code, f"failure code {code}")
    if not idx:
        raise InvalidInputError(f"simulate: at t = {t:g} s {text}")
    return f"t = {t:g} s: {text}"


def _log(plant, controller, measurement, times, batch, data, state, failure, meta, extra=None) -> Log:
    """The run's :class:`Log` from its channels ``data`` (name -> ``(T, *batch, k)``)."""
    out_cols = measurement.columns if measurement.columns is not None else plant.output_columns
    cols = {"state": plant.state_columns, "measured": out_cols, "command": controller.command_names,
            **controller.signal_columns()}
    chans = [Channel(k, tuple(cols[k]), data[k]) for k in cols]
    info = {"controller": controller.name, "controller_state": state, **(meta or {}), **(extra or {})}
    if failure:
        failed = np.zeros(batch, dtype=bool)
        for idx in failure:
            failed[idx] = True
        info.update(failed=failed, failure=dict(sorted(failure.items())))
    return Log(times, chans, info)


def scheduled_reference(controller, reference: Callable, times, batch: tuple) -> Callable:
    """The reference the loop hands a controller that draws its own inputs up front
    (``controller.schedule(times, batch)``: a network's deliveries, per world): each tick's
    ``(reference(k), the schedule's slice k)``; for any other controller ``reference`` itself."""
    draw = getattr(controller, "schedule", None)
    if draw is None:
        return reference
    sched = draw(times, batch)
    return lambda k: (reference(k), {key: v[k] for key, v in sched.items()})


def simulate_numpy(plant, controller, reference: Callable, times, x0, *, dt: float | None = None,
                   substeps: int = 1, measurement=None, progress: Callable | None = None,
                   meta: dict | None = None) -> Log:
    """The NumPy driver: :func:`make_tick` iterated over the ticks (:func:`quatform.sim.simulate`)."""
    times, dt = check_ticks(times, substeps, dt)
    x, batch = _initial(plant, x0, "simulate")
    reference = scheduled_reference(controller, reference, times, batch)
    measurement = PerfectMeasurement() if measurement is None else measurement
    sched = measurement.schedule(times, dt, substeps, batch)
    ms = measurement.init(plant.output(x), batch, sched)
    data, state, failure = iterate_numpy(plant, controller, measurement, reference, times, dt, substeps, x, batch, sched,
                                    ms, progress)
    return _log(plant, controller, measurement, times, batch, data, state, failure, meta)


def iterate_numpy(plant, controller, measurement, reference, times, dt, substeps, x, batch, sched, ms, progress):
    """The NumPy iteration of :func:`make_tick` from the plant states ``x`` ``(*batch, n_x)``,
    the measurement's ``schedule`` and initial state ``ms``: ``(data, state, failure)``, the
    channels (name -> ``(T, *batch, k)``), the final controller state and each failed world's
    one-line reason (a run of one world raises it)."""
    n = times.size
    inputs = plant_inputs(plant, times, dt, substeps)
    # a batch's worlds on the host: a failed world steps a healthy world's state (the plant
    # refuses a state that is not finite), and update's failures are found world by world
    host = HostWorlds(batch, controller, plant) if batch else None
    tick = make_tick(plant, controller, measurement, dt, substeps,
                     control=None if host is None or controller.pure else host.tick,
                     step=None if host is None else host.step, freeze=bool(batch))
    carry = (x, controller.init(batch), ms) + (start_failures(x) if batch else (np.int64(-1), np.int64(0)))
    if host is not None:
        host.failed = carry[4] > 0
    every = max(1, n // 10)
    ys = []
    for k in range(n):
        carry, y = advance(tick, controller, measurement, reference(k), times, dt, k, sched, inputs, carry,
                           one_world=not batch)
        if host is not None:
            host.failed = carry[4] > 0
        ys.append(y)
        if progress is not None and (k + 1) % every == 0:
            progress((k + 1) / n)
    data = _channels(plant, controller, measurement, ys, batch)
    failure = {}
    reason, fail_tick = carry[4], carry[3]
    if batch and np.any(reason > 0):
        for idx in zip(*np.nonzero(reason)):
            idx = tuple(int(i) for i in idx)
            failure[idx] = _failure(controller, reference, times, dt, data["measured"], carry[1], fail_tick, reason,
                                    batch, idx, host)
    return data, carry[1], failure



def advance(tick, controller, measurement, ref, times, dt, k: int, sched: dict, inputs, carry, *, one_world: bool):
    """Tick ``k`` of the NumPy driver, the loop body :func:`iterate_numpy` and :class:`Stepper`
    share: ``tick`` (:func:`make_tick`) on ``carry`` with the tick's inputs
    (:func:`tick_inputs` of the reference ``ref``). Returns ``(carry, y)``; with ``one_world``,
    a failure in the tick raises as ``update`` raises it."""
    xs = tick_inputs(controller, ref, times, k, sched, inputs)
    after, y = tick(carry, xs)
    if one_world and after[4] > 0:
        _raise_failure(controller, measurement, ref, times, dt, xs, carry, after)
    return after, y


def tick_inputs(controller, ref, times, k: int, sched: dict, inputs) -> dict:
    """The NumPy driver's ``xs`` of tick ``k`` (module docstring): its index and time, the
    controller's reference arrays of ``ref`` (``ref`` itself for a controller that is not
    ``pure``), the tick's slice of the measurement's ``sched`` and of the plant's ``inputs``."""
    return {"k": k, "t": float(times[k]), "ref": controller.reference_arrays(ref) if controller.pure else ref,
            "meas": {key: v[k] for key, v in sched.items()},
            "plant": None if inputs is None else {key: v[k] for key, v in inputs.items()}}


def _raise_failure(controller, measurement, ref, times, dt, xs, before, carry):
    """A one-world run's failure at tick ``xs["k"]``, raised as ``update`` raises it."""
    k = xs["k"]
    _, m = measurement.read(before[2], xs["meas"])
    _failure(controller, lambda _k: ref, times, dt, {(k,): m}, before[1], np.int64(k), carry[4], (), ())


def _channels(plant, controller, measurement, ys: list, batch: tuple) -> dict:
    """The channels (name -> ``(T, *batch, k)``) of the ticks' outputs ``ys`` (:func:`make_tick`)."""
    n = len(ys)
    names = ("state", "measured", "command") + tuple(controller.signal_columns())
    widths = (len(plant.state_columns), None, len(controller.command_names)) + tuple(
        len(c) for c in controller.signal_columns().values())
    out_cols = measurement.columns if measurement.columns is not None else plant.output_columns
    data = {}
    for q, (name, width) in enumerate(zip(names, widths)):
        shape = (n,) + batch + (len(out_cols) if width is None else width,)
        data[name] = np.asarray([y[q] for y in ys], dtype=float).reshape(shape) if n else np.zeros(shape)
    return data


class Stepper:
    """The NumPy driver of one world, one tick at a time: :func:`make_tick` iterated by the
    caller (a live run, which shapes each tick's reference as it goes and may replace the
    controller between ticks).

    Parameters
    ----------
    plant, controller, reference, times, x0, dt, substeps, measurement
        As :func:`quatform.sim.simulate` takes them, for one world (``x0`` of shape ``(n_x,)``).

    Attributes
    ----------
    k : int
        Ticks done.
    carry : tuple
        The loop's carry after them.
    """

    def __init__(self, plant, controller, reference: Callable, times, x0, *, dt: float | None = None,
                 substeps: int = 1, measurement=None):
        self.times, self.dt = check_ticks(times, substeps, dt, "stepper")
        x, batch = _initial(plant, x0, "stepper")
        if batch:
            raise ShapeError(f"stepper: one world at a time; give x0 of shape ({len(plant.state_columns)},), "
                             f"got batch shape {batch}")
        self.plant, self.substeps = plant, substeps
        self.measurement = PerfectMeasurement() if measurement is None else measurement
        self.sched = self.measurement.schedule(self.times, self.dt, substeps, ())
        self.inputs = plant_inputs(plant, self.times, self.dt, substeps)
        self.reference = scheduled_reference(controller, reference, self.times, ())
        ms = self.measurement.init(plant.output(x), (), self.sched)
        self.carry = (x, controller.init(()), ms, np.int64(-1), np.int64(0))
        self.ys: list = []
        self.use(controller)

    @property
    def k(self) -> int:
        return len(self.ys)

    def use(self, controller) -> None:
        """Run the next ticks with ``controller`` (the loop's tick rebuilt; the carry kept: its
        state must have the structure of the one it replaces, e.g. the same controller with
        other gains)."""
        self.controller = controller
        self._tick = make_tick(self.plant, controller, self.measurement, self.dt, self.substeps, freeze=False)

    def step(self, ref=None):
        """Run tick :attr:`k` with the reference ``ref`` (default ``reference(k)``); a failure
        raises as :func:`quatform.sim.simulate` raises it. Returns the tick's outputs ``ys``."""
        k = self.k
        if k >= self.times.size:
            raise InvalidInputError(f"stepper: the run's {self.times.size} ticks are done")
        ref = self.reference(k) if ref is None else ref
        self.carry, y = advance(self._tick, self.controller, self.measurement, ref, self.times, self.dt, k,
                                self.sched, self.inputs, self.carry, one_world=True)
        self.ys.append(y)
        return y

    def log(self, meta: dict | None = None, start: int = 0, ticks=None) -> Log:
        """The :class:`Log` of ticks ``start`` to :attr:`k`, or of the increasing tick indices
        ``ticks`` (int array, each below :attr:`k`) when given (what :func:`quatform.sim.simulate`
        returns for them; ``meta["controller_state"]`` the state after the last tick done)."""
        ticks = np.arange(start, self.k) if ticks is None else np.asarray(ticks, dtype=int)
        data = _channels(self.plant, self.controller, self.measurement, [self.ys[i] for i in ticks.tolist()], ())
        return _log(self.plant, self.controller, self.measurement, self.times[ticks], (), data,
                    self.carry[1], {}, meta)

# -- the JAX driver -----------------------------------------------------------------------

def require_jax():
    """The ``jax`` module (its CPU devices configured: :func:`.jax_devices.configure`), or one
    line naming the install command."""
    try:
        import jax
    except ImportError:
        raise MissingDependencyError('the jax compute backend needs JAX: pip install -e ".[jax]" '
                                     '(or --compute numpy)') from None
    jax_devices.configure(jax)  # one CPU device per core, before JAX starts its backends
    return jax


#: Compiled scans of recent runs, newest last (:func:`cached`).
_CACHE: dict = {}
_CACHE_SIZE = 8
#: :func:`.jax_devices.shardable`'s answers, by compiled run and input layout.
_SHARDABLE: dict = {}


def cached(cache: dict, key: tuple, build: Callable):
    """``cache[key]``, built by ``build()`` when missing; the cache keeps its newest
    :data:`_CACHE_SIZE` entries."""
    hit = cache.pop(key, None)
    if hit is None:
        hit = build()
    cache[key] = hit
    while len(cache) > _CACHE_SIZE:
        cache.pop(next(iter(cache)))
    return hit


def spread(jax, carry, xs, B: int, carry_axes, xs_axes):
    """The scan's ``carry`` and per-tick inputs ``xs`` (pytrees) spread over the devices
    (:mod:`.jax_devices`): the batch padded to a multiple of the device count with copies of
    the last world (cut from the results), its axis sharded. ``carry_axes`` and ``xs_axes``
    are the batch axis of each leaf, in ``jax.tree_util`` order (-1: none, replicated)."""
    size = jax_devices.chunk_size(jax, B, B)
    pad = size - B
    leaves_c, tree_c = jax.tree_util.tree_flatten(carry)
    leaves_x, tree_x = jax.tree_util.tree_flatten(xs)
    arrays, where = {}, {}
    for tag, leaves, axes in (("c", leaves_c, carry_axes), ("x", leaves_x, xs_axes)):
        for q, (a, axis) in enumerate(zip(leaves, axes)):
            a = np.asarray(a)
            if axis >= 0 and pad:
                a = np.concatenate([a, np.repeat(np.take(a, [-1], axis=axis), pad, axis=axis)], axis=axis)
            arrays[f"{tag}{q}"] = a
            if axis >= 0:
                where[f"{tag}{q}"] = axis
    arrays = jax_devices.place(jax, arrays, where)
    return (jax.tree_util.tree_unflatten(tree_c, [arrays[f"c{q}"] for q in range(len(leaves_c))]),
            jax.tree_util.tree_unflatten(tree_x, [arrays[f"x{q}"] for q in range(len(leaves_x))]))


def scan_ticks(jax, run, carry, xs, n: int, progress, B: int, carry_axes, xs_axes: dict):
    """``run`` (the jitted ``lax.scan`` of a tick: ``(carry, xs) -> (ys, carry)``) over the
    ``n`` ticks of ``xs`` (a dict, each leaf ``(T, ...)``), in one call or in ten chunks of
    one shape when ``progress`` is given (``xs["valid"]`` marks the padded ticks), the batch
    spread over the devices (:func:`spread`): ``(ys, carry)``, the batch padded as
    :func:`spread` pads it. ``carry_axes``: the batch axis of each leaf of ``carry``;
    ``xs_axes``: key of ``xs`` -> the batch axis of its every leaf (an int) or a pytree of
    them (-1 or a missing key: none). The batch stays on JAX's default device where the scan
    cannot be sharded safely on the CPU (:func:`.jax_devices.shardable`: a loop in the tick, or
    a LAPACK call on matrices larger than 4 x 4, can stall with the batch over several CPU
    devices), an answer kept per ``run`` and input layout."""
    xs = dict(xs, k=np.arange(n, dtype=np.int64))
    if progress is not None:
        size = -(-n // 10)
        xs = jax.tree_util.tree_map(lambda v: np.concatenate([v, np.repeat(v[-1:], 10 * size - n, axis=0)]), xs)
        xs["valid"] = np.arange(10 * size) < n

    def axes_of(key, value):
        axis = xs_axes.get(key, -1)
        return jax.tree_util.tree_map(lambda _: axis, value) if isinstance(axis, int) else axis

    leaf_axes = jax.tree_util.tree_leaves({key: axes_of(key, v) for key, v in xs.items()})
    layout = (run, jax.tree_util.tree_structure((carry, xs)),
              tuple(np.shape(a) for a in jax.tree_util.tree_leaves((carry, xs))))
    if cached(_SHARDABLE, layout, lambda: jax_devices.shardable(jax, run, carry, xs)):
        carry, xs = spread(jax, carry, xs, B, carry_axes, leaf_axes)
    if progress is None:
        return run(carry, xs)
    parts = []
    for chunk in range(10):
        take = min(size, n - chunk * size)
        if take <= 0:
            break
        ys, carry = run(carry, jax.tree_util.tree_map(lambda v: v[chunk * size:(chunk + 1) * size], xs))
        parts.append([np.asarray(y)[:take] for y in ys])
        progress((chunk * size + take) / n)
    return [np.concatenate([p[q] for p in parts]) for q in range(len(parts[0]))], carry


def _batched(leaf, batch: tuple) -> bool:
    """Whether a reference leaf ``(T, ...)`` holds one entry per world: its axes after ``T``
    begin with ``batch`` and one more axis follows (a reference array has one per world)."""
    return leaf.ndim >= len(batch) + 2 and leaf.shape[1:1 + len(batch)] == batch


#: What the JAX driver asks of a measurement model (:mod:`.measurement`).
MEASUREMENT_CONTRACT = ("schedule", "init", "observe", "read")


def jax_refusal(plant, controller, measurement) -> str | None:
    """Why the JAX driver cannot run these parts, in one line, or None: it runs a controller
    whose ``pure`` is True, a ``batchable`` plant (its ``step`` pure: a stateful MuJoCo plant
    is not) and a measurement model with :data:`MEASUREMENT_CONTRACT`, decided from what the
    objects declare."""
    why = []
    if not getattr(controller, "pure", False):
        why.append(f"the controller {type(controller).__name__} has no pure tick (pure = False)")
    if not getattr(plant, "batchable", False):
        why.append(f"the plant {type(plant).__name__} has no pure step (batchable = False)")
    if measurement is not None and not all(callable(getattr(measurement, a, None)) for a in MEASUREMENT_CONTRACT):
        why.append(f"the measurement model {type(measurement).__name__} lacks "
                   f"{'/'.join(a for a in MEASUREMENT_CONTRACT if not callable(getattr(measurement, a, None)))}")
    if not why:
        return None
    return ("the jax compute backend runs pure controllers (controller.pure), plants with a pure step "
            "(plant.batchable) and measurement models with schedule/init/observe/read; " + "; ".join(why)
            + " (use --compute numpy)")


def _fingerprint(value, depth: int = 0):
    """A hashable value equal for two configurations that trace to one program: dataclass
    fields, public attributes, containers and small arrays by value (types included); a
    large array (more than 4096 entries: data a run feeds in, such as a measurement's draws)
    by its shape and 257 probed entries; a function by identity."""
    if depth > 12:
        return ("id", id(value))
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes, type)):
        return (type(value), value)
    if isinstance(value, np.ndarray):
        if value.size <= 4096:
            return ("array", value.shape, value.dtype.str, value.tobytes())
        probe = np.linspace(0, value.size - 1, 257).astype(np.intp)  # a large array is data: its shape and a probe
        return ("large", value.shape, value.dtype.str, value.flat[probe].tobytes())
    if isinstance(value, np.generic):
        return (type(value), value.item())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value),) + tuple(_fingerprint(getattr(value, f.name), depth + 1)
                                      for f in dataclasses.fields(value) if f.compare)
    if isinstance(value, (tuple, list)):
        return (type(value),) + tuple(_fingerprint(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return (dict,) + tuple(sorted(((repr(k), _fingerprint(v, depth + 1)) for k, v in value.items()),
                                      key=lambda kv: kv[0]))
    if callable(value) and not hasattr(value, "__dict__"):
        return ("id", id(value))
    if type(value).__eq__ is not object.__eq__:
        try:
            return (type(value), hash(value), value)
        except TypeError:
            pass
    if hasattr(value, "__dict__"):  # its public attributes, not what it caches (cached_property)
        cls = type(value)
        return (cls,) + _fingerprint({k: v for k, v in vars(value).items() if not k.startswith("_")
                                      and not isinstance(getattr(cls, k, None), functools.cached_property)},
                                     depth + 1)
    return ("id", id(value))


def config_key(*parts) -> tuple:
    """What a compiled scan of ``parts`` (plant, controller, measurement, ...) depends on, as
    a hashable value (:func:`_fingerprint`): two experiments with equal configurations (a
    sweep's chunks, a benchmark's repeats) share one compilation. The compiled entry keeps
    the objects it was traced with, so an identity in the key is never reused."""
    return tuple(_fingerprint(p) for p in parts)


def _numpy_worlds(plant, controller, measurement, reference, times, dt, substeps, x, batch, sched, ms, sel, data):
    """Rerun the worlds ``sel`` (flat indices, or None: the one world) on NumPy
    (:func:`iterate_numpy`) with their own initial states, schedule, measurement state and
    reference; their channels replace ``data``'s (name -> ``(T, *batch, k)``, in place).
    Returns ``(state_of, failure)``: the rerun's final controller state and each of their
    failures by the batch's world index tuples."""
    if not batch:
        sub, st, failure = iterate_numpy(plant, controller, measurement, reference, times, dt, substeps, x, batch, sched,
                                    ms, None)
        data.update(sub)
        return st, failure
    B, n = math.prod(batch), times.size
    flat = (lambda a: np.asarray(a).reshape((B,) + np.shape(a)[len(batch):])[sel])
    sub_sched = {k: np.asarray(v).reshape((n, B) + np.shape(v)[1 + len(batch):])[:, sel] for k, v in sched.items()}
    sub_ms = map_worlds(tree_map(np.asarray, ms), batch, flat)

    def sub_reference(k):
        return map_worlds(reference(k), batch, flat, 1)

    sub, st, failure = iterate_numpy(plant, controller, measurement, sub_reference, times, dt, substeps, flat(x),
                                (len(sel),), sub_sched, sub_ms, None)
    for k, v in sub.items():
        full = np.array(data[k]).reshape((n, B) + data[k].shape[1 + len(batch):])
        full[:, sel] = v
        data[k] = full.reshape(data[k].shape)
    return st, {tuple(int(i) for i in np.unravel_index(int(sel[local[0]]), batch)): why
                for local, why in failure.items()}


def simulate_jax(plant, controller, reference: Callable, times, x0, *, dt: float | None = None,
                 substeps: int = 1, measurement=None, progress: Callable | None = None,
                 meta: dict | None = None) -> Log:
    """The JAX driver: ``jax.jit(lax.scan(make_tick(...)))`` (module docstring; the arguments
    and the Log of :func:`quatform.sim.simulate`).

    Raises
    ------
    MissingDependencyError
        Without JAX (``pip install -e ".[jax]"``).
    InvalidInputError
        For parts without a pure step (:func:`jax_refusal`, one line) and the errors of
        :func:`quatform.sim.simulate`.
    """
    jax = require_jax()
    why = jax_refusal(plant, controller, measurement)
    if why is not None:
        raise InvalidInputError(f"jax simulate: {why}")
    times, dt = check_ticks(times, substeps, dt, "jax simulate")
    if times.size < 1:
        raise ShapeError("jax simulate: times must hold at least one tick")
    x, batch = _initial(plant, x0, "jax simulate")
    reference = scheduled_reference(controller, reference, times, batch)
    B = math.prod(batch)
    n = times.size
    measurement = PerfectMeasurement() if measurement is None else measurement
    sched = measurement.schedule(times, dt, substeps, batch)
    ms = measurement.init(plant.output(x), batch, sched)
    run, carry, xs, axes = compiled_run(jax, plant, controller, measurement, reference, times, dt, substeps, x, batch,
                                        sched, ms)
    with jax.enable_x64(True):
        ys, carry = scan_ticks(jax, run, carry, xs, n, None if progress is None else
                               (lambda f: progress(f) if f < 1.0 else None), B, *axes)
    names = ("state", "measured", "command") + tuple(controller.signal_columns())
    data = {k: np.asarray(v)[:, :B].reshape((n,) + batch + np.shape(v)[2:]) for k, v in zip(names, ys)}
    state = jax.tree_util.tree_map(lambda a: np.asarray(a)[:B].reshape(batch + np.shape(a)[1:]), carry[1])
    fail_tick, reason = (np.asarray(a)[:B].reshape(batch) for a in carry[3:5])
    failure, rerun = {}, []
    for idx in (list(zip(*np.nonzero(reason))) if batch else [()] if reason > 0 else []):
        idx = tuple(int(i) for i in idx)
        why = _failure(controller, reference, times, dt, data["measured"], state, fail_tick, reason, batch, idx,
                       confirm=True)
        if why is None:
            rerun.append(idx)
        else:
            failure[idx] = why
    extra = {}
    if rerun:  # worlds the host runs where the compiled tick did not (module docstring)
        sel = np.array([np.ravel_multi_index(i, batch) for i in rerun], dtype=np.intp) if batch else None
        st, more = _numpy_worlds(plant, controller, measurement, reference, times, dt, substeps, x, batch, sched,
                                 ms, sel, data)
        if batch:
            def put(a, b):
                a = np.array(a)
                a.reshape((B,) + a.shape[len(batch):])[sel] = b
                return a
            state = tree_map(put, state, st)
        else:
            state = st
        failure.update(more)
        extra["numpy_worlds"] = np.zeros(batch, dtype=bool)
        for idx in rerun:
            extra["numpy_worlds"][idx] = True
    if progress is not None:
        progress(1.0)
    return _log(plant, controller, measurement, times, batch, data, state, failure, meta, extra)


def compiled_run(jax, plant, controller, measurement, reference, times, dt, substeps, x, batch, sched, ms,
                 reduce=None, extra=None):
    """The compiled scan of the loop's tick and its inputs: ``(run, carry, xs, (carry_axes,
    xs_axes))`` for :func:`scan_ticks` over the ``B`` worlds of ``batch`` (flattened), the
    controller's :meth:`reference_arrays` of every tick stacked with a leading T axis.
    ``extra``: more per-tick inputs (name -> ``(T, ...)``, the same for every world) for
    ``reduce``: ``(init(carry) -> acc, step(acc, ys, xs) -> acc)``, a reduction of each tick's
    outputs carried beside the loop's carry instead of the outputs (a rollout that keeps no
    log, :mod:`.jax_rollout`); the compiled entry is cached by :func:`config_key` (and
    ``reduce``'s identity)."""
    n, B = times.size, math.prod(batch)
    sched = {key: np.asarray(v).reshape((n, B) + np.shape(v)[1 + len(batch):]) for key, v in sched.items()}
    inputs = plant_inputs(plant, times, dt, substeps)
    refs = [controller.reference_arrays(reference(k)) for k in range(n)]
    refs = jax.tree_util.tree_map(lambda *a: np.stack([np.asarray(v) for v in a]), *refs) if refs[0] is not None \
        else None
    ref_axes = jax.tree_util.tree_map(lambda a: 1 if _batched(a, batch) else -1, refs)
    refs = jax.tree_util.tree_map(lambda a: a.reshape((n, B) + a.shape[1 + len(batch):]) if _batched(a, batch)
                                  else a, refs)
    flat = (lambda a: np.asarray(a).reshape((B,) + np.shape(a)[len(batch):]))
    xb = flat(x)
    carry = (xb, map_worlds(tree_map(np.asarray, controller.init(batch)), batch, flat),
             map_worlds(tree_map(np.asarray, ms), batch, flat),
             *(start_failures(xb) if batch else (np.full(B, -1, dtype=np.int64), np.zeros(B, dtype=np.int64))))
    xs = {"t": times, "ref": refs, "meas": sched, "plant": inputs, **(extra or {})}

    def build():
        tick = make_tick(plant, controller, measurement, dt, substeps)
        if reduce is None:
            return jax_devices.jit(jax, lambda c, s: jax.lax.scan(tick, c, s)[::-1]), (plant, controller, measurement)
        start, step = reduce

        def body(c, s):
            inner, acc = c
            inner, ys = tick(inner, s)
            return (inner, step(acc, ys, s)), None

        run = jax_devices.jit(jax, lambda c, s: jax.lax.scan(body, (c, start(c)), s)[0])
        return run, (plant, controller, measurement)

    key = (config_key(plant, controller, measurement), dt, substeps, reduce, jax.tree_util.tree_structure(xs))
    run, _ = cached(_CACHE, key, build)
    carry_axes = [0] * len(jax.tree_util.tree_leaves(carry))
    return run, carry, xs, (carry_axes, {"ref": ref_axes, "meas": 1})
