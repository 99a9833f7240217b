"""The teleop kind's closed loop on JAX: ``jax.jit`` and ``lax.scan`` over the control cycles (sim layer).

:func:`simulate` has :func:`quatform.sim.simulate`'s signature and returns the same
:class:`~quatform.sim.log.Log` for seed 003's teleoperator: a
:class:`~quatform.sim.plants.teleop.TeleopPlant` under a
:class:`~quatform.teleop.TeleopController`, perfectly measured (what the teleop kind runs).
:func:`quatform.sim.jax_loop.simulate` hands such a run here (:data:`~quatform.sim.jax_loop.KIND_LOOPS`).
It runs the same kernels as NumPy, written once for both namespaces:

* the controller's law (:meth:`~quatform.teleop.TeleopController.law`: the arms' frames,
  Jacobians and mass matrix, the Euler-parameter or roll-pitch-yaw error, eqs. (14a),
  (14b), (11), (13), the virtual walls, the preload, the saturation);
* the plant's step (:meth:`~quatform.sim.plants.teleop.TeleopPlant.step_at`: the hand's
  spring, the master's friction as selections, the slave's Coriolis torques by finite
  differences of the mass matrix, the contact wall, the push);
* what moves the plant whatever its state (the hand's and the push's target paths) is
  sampled on the host for every plant step (:meth:`~quatform.sim.plants.teleop.TeleopPlant.targets_at`:
  the same floats as NumPy's step).

A batch of worlds (``x0`` of shape ``(*batch, n_x)``, each its own initial state; NumPy runs
one at a time) is ``jax.vmap`` of the one-world tick. What the controller refuses with an
exception (a measurement not finite or beyond what the arms can be) marks the world failed
at that cycle and freezes it (state held, torques zero, signals NaN; ``log.meta["failed"]``
and ``log.meta["failure"]`` with NumPy's one-line reason); a run of one world raises
NumPy's error, as :func:`quatform.sim.simulate` does. float64 inside ``jax.enable_x64(True)``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InvalidInputError
from ..teleop import TeleopController
from ..teleop.controller import MAX_JOINT_ANGLE, MAX_JOINT_RATE, MAX_WRIST_FORCE, MAX_WRIST_MOMENT
from .jax_loop import cached, check_ticks, initial_states, require_jax, scan_ticks
from .log import Channel, Log
from .plants.teleop import TeleopPlant
from .simulate import WORLD_ERRORS, PerfectMeasurement

__all__ = ["TELEOP_RUNS", "check_teleop", "teleop_tick_function", "simulate"]

#: What this loop runs, for the one-line refusal of anything else.
TELEOP_RUNS = ("the jax backend runs the teleop kind as a TeleopPlant under a TeleopController, perfectly "
               "measured")
#: The scan's carry ``(x, fail_tick, reason)``: the batch axis of each slot, and of no per-tick input
#: (:func:`quatform.sim.jax_loop.spread`).
TELEOP_AXES = ((0, 0, 0), {})


def check_teleop(plant, controller, measurement) -> None:
    """Refuse (one line, naming what runs here) what this loop does not run."""
    if not isinstance(plant, TeleopPlant):
        raise InvalidInputError(f"{TELEOP_RUNS}; the plant {type(plant).__name__} runs on numpy (--compute numpy)")
    if not isinstance(controller, TeleopController):
        raise InvalidInputError(f"{TELEOP_RUNS}; {type(controller).__name__} runs on numpy (--compute numpy)")
    if measurement is not None and type(measurement) is not PerfectMeasurement:
        raise InvalidInputError(f"{TELEOP_RUNS}; the measurement {type(measurement).__name__} runs on numpy "
                                "(--compute numpy)")
    if (plant.master.arm.n, plant.slave.arm.arm.n) != (controller.master.n, controller.slave.arm.n):
        raise InvalidInputError(f"{TELEOP_RUNS}; the controller's arms ({controller.master.n} and "
                                f"{controller.slave.arm.n} joints) are not the plant's ({plant.master.arm.n} and "
                                f"{plant.slave.arm.arm.n})")


def _bounds(controller) -> np.ndarray:
    """Each measured entry's bound (what :func:`quatform.teleop.controller._measured` accepts)."""
    n_m, n_s = controller.master.n, controller.slave.arm.n
    return np.concatenate([np.full(n_m, MAX_JOINT_ANGLE), np.full(n_m, MAX_JOINT_RATE), np.full(n_s, MAX_JOINT_ANGLE),
                           np.full(n_s, MAX_JOINT_RATE), np.full(3, MAX_WRIST_FORCE), np.full(3, MAX_WRIST_MOMENT)])


def teleop_tick_function(plant, controller, dt: float, substeps: int):
    """One control cycle of every world: ``(carry, xs_k) -> (carry, (x, m, u, *signals))``.

    ``carry`` is ``(x, fail_tick, reason)`` (``(B, n_x)``, ``(B,)``, ``(B,)``; reason 1: the
    measurement was refused); ``xs_k`` holds the cycle's time ``t``, index ``k``, the hand's
    target ``p_h`` ``(substeps, 3)`` and ``r_h`` ``(substeps, 4)``, the push's ``push``
    ``(substeps, 3)`` (with a push) and ``valid`` (a padded cycle past the run's end changes
    nothing). The signals are :meth:`~quatform.teleop.TeleopController.signal_columns`'s, in order.
    """
    import jax
    import jax.numpy as jnp

    n_m, n_s = controller.master.n, controller.slave.arm.n
    i = np.cumsum([n_m, n_m, n_s, n_s])
    bounds = _bounds(controller)

    def world(x, xs):
        m = plant.output(x)  # a perfect measurement
        ok = jnp.all(jnp.isfinite(m) & (jnp.abs(m) <= bounds))
        out = controller.law(m[:i[0]], m[i[0]:i[1]], m[i[1]:i[2]], m[i[2]:i[3]], m[i[3]:], True)
        tau_m, tau_s, e, p_m, r_m, p_s, r_s, wall, finite, saturated, null_ok = out[:11]
        u = jnp.concatenate([tau_m, tau_s])
        x_next = x
        for s in range(substeps):
            x_next = plant.step_at(x_next, u, dt, (xs["p_h"][s], xs["r_h"][s]), xs["push"][s] if "push" in xs else None)
        flags = tuple(jnp.where(f, 1.0, 0.0)[None] for f in (finite, saturated, null_ok))
        signals = (p_m, jnp.stack(r_m), p_s, jnp.stack(r_s), e, wall) + flags
        return x_next, u, signals, ok

    worlds = jax.vmap(world, in_axes=(0, None))

    def tick(carry, xs):
        x, fail_tick, reason = carry
        x_next, u, signals, ok = worlds(x, xs)
        new = (reason == 0) & ~ok
        fail_tick = jnp.where(new, jnp.asarray(xs["k"], dtype=fail_tick.dtype), fail_tick)
        reason = jnp.where(new, 1, reason)
        bad = (reason > 0)[:, None]
        x_next = jnp.where(bad, x, x_next)
        u = jnp.where(bad, 0.0, u)
        signals = tuple(jnp.where(bad, jnp.nan, v) for v in signals)
        new_carry = (x_next, fail_tick, reason)
        if "valid" in xs:
            new_carry = tuple(jnp.where(xs["valid"], a, b) for a, b in zip(new_carry, carry))
        return new_carry, (x, x, u) + signals

    return tick


#: Compiled scans of recent runs, newest last: keyed by the plant's and the controller's
#: identity (held in the entry, so an identity is not reused while it is cached) and the steps.
_CACHE: dict = {}


def _compiled_scan(jax, plant, controller, dt: float, substeps: int):
    """``jax.jit`` of ``lax.scan`` of :func:`teleop_tick_function` (``.compiled`` of the tick), cached."""

    def build():
        tick = teleop_tick_function(plant, controller, dt, substeps)
        tick.compiled = jax.jit(lambda carry, xs: jax.lax.scan(tick, carry, xs)[::-1])
        tick.held = (plant, controller)
        return tick

    return cached(_CACHE, (id(plant), id(controller), dt, substeps), build)


def _targets(plant, times, dt: float, substeps: int) -> dict:
    """The hand's and the push's targets at every plant step (host, NumPy: the floats of
    :meth:`~quatform.sim.plants.teleop.TeleopPlant.step`), each ``(T, substeps, k)``."""
    hand_p, hand_r, push = [], [], []
    for t in times:
        for j in range(substeps):
            (p_h, r_h), target = plant.targets_at(float(t) + j * dt)
            hand_p.append(p_h)
            hand_r.append(r_h)
            push.append(target)
    n = len(times)
    xs = {"p_h": np.asarray(hand_p, float).reshape(n, substeps, 3),
          "r_h": np.asarray(hand_r, float).reshape(n, substeps, 4)}
    if plant.push is not None:
        xs["push"] = np.asarray(push, float).reshape(n, substeps, 3)
    return xs


def simulate(plant, controller, reference: Callable, times, x0, *, dt: float | None = None, substeps: int = 1,
             measurement=None, progress: Callable | None = None, meta: dict | None = None) -> Log:
    """Run the teleop closed loop of :func:`quatform.sim.simulate` compiled with JAX (same arguments, same Log).

    Parameters
    ----------
    plant : TeleopPlant
    controller : TeleopController
    reference : callable
        Unused (each arm's reference is the other arm).
    times, dt, substeps, progress, meta
        As :func:`quatform.sim.simulate`.
    x0 : array_like, shape (*batch, n_x)
        Each world's initial state (NumPy runs one world; here a batch is one vmapped run).
    measurement : None or PerfectMeasurement

    Returns
    -------
    Log
        Channels ``state``, ``measured``, ``command`` and the controller's signals, each
        ``(T, *batch, k)``; ``meta["controller_state"]`` None (the controller is stateless);
        ``meta["failed"]``, ``meta["failure"]`` where a world of a batch failed.
    """
    jax = require_jax()
    check_teleop(plant, controller, measurement)
    times, dt = check_ticks(times, substeps, dt)
    n = times.size
    x, batch, B = initial_states(plant, x0)
    tick = _compiled_scan(jax, plant, controller, dt, substeps)
    xs = dict(_targets(plant, times, dt, substeps), t=times)
    carry = (x.reshape(B, -1), np.full(B, -1, dtype=np.int64), np.zeros(B, dtype=np.int64))
    with jax.enable_x64(True):
        ys, carry = scan_ticks(jax, tick, carry, xs, n, progress, TELEOP_AXES)
    columns = controller.signal_columns()
    names = ("state", "measured", "command") + tuple(columns)
    data = {k: np.asarray(v)[:, :B].reshape((n,) + batch + (v.shape[-1],)) for k, v in zip(names, ys)}
    fail_tick, reason = (np.asarray(a)[:B].reshape(batch) for a in carry[1:3])
    extra = {}
    if np.any(reason > 0):
        worlds = list(zip(*np.nonzero(reason))) if batch else [()]
        failure = {tuple(int(i) for i in idx): _failure_reason(controller, times, data["measured"], fail_tick,
                                                               tuple(int(i) for i in idx)) for idx in worlds}
        extra.update(failed=reason > 0, failure=dict(sorted(failure.items())))
    cols = {"state": plant.state_columns, "measured": plant.output_columns, "command": controller.command_names,
            **columns}
    chans = [Channel(k, tuple(cols[k]), data[k]) for k in names]
    return Log(times, chans, {"controller": controller.name, "controller_state": None, **(meta or {}), **extra})


def _failure_reason(controller, times, measured, fail_tick, idx) -> str:
    """NumPy's reason for world ``idx``'s failure: ``controller.update`` on its measurement at
    its failing cycle (the one-line refusal :func:`quatform.sim.simulate` gets); a run of one
    world raises it, as there."""
    k = int(fail_tick[idx])
    try:
        controller.update(float(times[k]), measured[(k, *idx)])
    except WORLD_ERRORS as own:
        if not idx:
            raise
        return f"t = {times[k]:g} s: " + " ".join(str(own).split())
    text = "the measurement is not finite or beyond what the arms can be"  # the compiled test only
    if not idx:
        raise InvalidInputError(f"jax simulate: at t = {times[k]:g} s {text}")
    return f"t = {times[k]:g} s: {text}"
