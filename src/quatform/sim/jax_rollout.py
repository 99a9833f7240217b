"""Batched rollouts on JAX reduced to every trial's metrics as they run (sim layer).

A Monte Carlo of 10^4 trials of 6000 ticks would log 6 * 10^7 world-ticks of every channel
(tens of GB). :func:`rollout_metrics` runs the loop's one compiled tick
(:func:`quatform.sim.loop.compiled_run`, the scan of :func:`quatform.sim.loop.simulate_jax`;
``pip install -e ".[jax]"``) and carries, beside the loop's carry, running reductions of the
error signals of :func:`quatform.sim.metrics.robot_errors` (the representation-independent
errors of a two-robot formation, from the robots' poses against the reference's
``robots``): each trial's metrics come back as arrays over the batch, with the keys and the
values of :func:`quatform.sim.metrics.compute_metrics` (equal within 1e-9 in tests). It
reduces any experiment of two kinematic robots whose reference gives the robots (the pair
kind, with or without the separation barrier). Two metrics need the description's chart,
whose formulas run on NumPy only, and are left out: the singularity measure and the
recovered Euclidean error; a sweep that needs them runs
:func:`~quatform.sim.loop.simulate_jax` and ``Experiment.metrics`` on a logged batch.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..algebra.kernels import hold
from ..errors import InvalidInputError, ShapeError
from ..formations.base import PAIR_LAYOUT
from . import jax_devices
from .loop import check_ticks, compiled_run, require_jax, scan_ticks, tree_map
from .metrics import LOST_ANGLE_RAD, LOST_POSITION_M, robot_errors
from .measurement import PerfectMeasurement
from .trial_measurement import TickMeasurement

__all__ = ["ROLLOUT_METRICS", "rollout_metrics"]

#: The metrics :func:`rollout_metrics` returns (keys of ``compute_metrics``), and ``failed``.
ROLLOUT_METRICS = ("reference_lost", "first_lost_time_s", "max_cluster_position_error_m", "max_shape_error_m",
                   "max_orientation_error_rad", "max_robot_position_error_m", "max_robot_yaw_error_rad",
                   "min_robot_separation_m", "nonfinite_commands", "max_command_speed_m_s")
_ERRORS = ("cluster_position", "shape", "orientation", "robot_position", "robot_yaw", "separation")
_MAXED = {"cluster_position": "max_cluster_position_error_m", "shape": "max_shape_error_m",
          "orientation": "max_orientation_error_rad", "robot_position": "max_robot_position_error_m",
          "robot_yaw": "max_robot_yaw_error_rad"}


def rollout_metrics(experiment, x0=None, measurement=None, *, trials_per_call: int | None = None) -> dict:
    """Every trial's metrics of a batched pair experiment, rolled out on JAX without a log.

    Parameters
    ----------
    experiment : Experiment
        Of the pair kind (``PAIR.experiment(scenario, controller=...)``): its plant,
        controller, reference, ticks and ``meta["metrics_from_s"]``; the desired Euclidean
        variables are its scenario's path at its ticks.
    x0 : array_like, shape (*batch, 8), optional
        Initial robots of every trial (default: the experiment's ``x0``).
    measurement : TickMeasurement, optional
        Noise ``(T, *batch, 8)``, latency and dropped frames of every trial (default: the
        experiment's; None: perfect).
    trials_per_call : int, optional
        Trials per compiled call (one compilation; chunks bound the device memory), rounded
        up to a multiple of the device count. Default: :func:`.jax_devices.chunk_size` (a
        cache-sized chunk per CPU core, the whole batch on a GPU). Each call's trials are
        spread over JAX's devices (:mod:`.jax_devices`).

    Returns
    -------
    dict
        :data:`ROLLOUT_METRICS` as arrays of the batch shape (``first_lost_time_s`` NaN where
        the reference was never lost), ``failed`` (bool) and ``failure`` (index tuple ->
        reason) as in :mod:`quatform.sim.backends`.
    """
    jax = require_jax()
    plant, ctrl = experiment.plant, experiment.controller
    measurement = experiment.measurement if measurement is None else measurement
    team = getattr(getattr(ctrl, "inner", ctrl), "team", None)
    if team is None or team.layout != PAIR_LAYOUT or not ctrl.pure or not plant.batchable:
        raise InvalidInputError("rollout_metrics reduces experiments of two kinematic robots with a pure controller "
                                "(the pair kind's); another experiment runs on jax through its log "
                                "(Experiment.run(backend='jax'), quatform sweep --compute jax)")
    times, dt = check_ticks(experiment.times, experiment.substeps, experiment.dt, "rollout_metrics")
    n = times.size
    x = np.array(experiment.x0 if x0 is None else x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),) or x.size == 0:
        raise ShapeError(f"rollout_metrics: x0 must have shape (*batch, {len(plant.state_columns)}) with at least "
                         f"one world, got {x.shape}")
    batch = x.shape[:-1]
    B = math.prod(batch)
    ref0 = experiment.reference(0)
    if getattr(ref0, "robots", None) is None or np.shape(ref0.robots) != (len(plant.state_columns),):
        raise InvalidInputError("rollout_metrics: the experiment's reference must give the desired robots, one "
                                "reference for every trial (the pair kind's)")
    if trials_per_call is not None and (not isinstance(trials_per_call, (int, np.integer))
                                        or isinstance(trials_per_call, bool) or trials_per_call < 1):
        raise InvalidInputError(f"rollout_metrics: trials_per_call = {trials_per_call!r} must be a whole number >= 1 "
                                "(trials per compiled call), or None for the default")
    measurement = PerfectMeasurement() if measurement is None else measurement
    if isinstance(measurement, TickMeasurement):
        measurement.check(plant.output(x), batch, n)
    sched = measurement.schedule(times, dt, experiment.substeps, batch)
    ms = measurement.init(plant.output(x), batch, sched)
    signals = tuple(ctrl.signal_columns())
    reduce = _reducer(signals.index("raw_finite"))
    extra = {"ed": np.asarray(experiment.scenario.path(times)[0], dtype=float),
             "late": times >= experiment.meta["metrics_from_s"]}
    run, carry, xs, (carry_axes, xs_axes) = compiled_run(jax, plant, ctrl, measurement, experiment.reference, times,
                                                         dt, experiment.substeps, x, batch, sched, ms, reduce, extra)
    size = min(jax_devices.chunk_size(jax, B, trials_per_call), B)
    xs = dict(xs, k=np.arange(n, dtype=np.int64))
    leaves, tree = jax.tree_util.tree_flatten(xs)
    axes = jax.tree_util.tree_leaves({k: jax.tree_util.tree_map(lambda _: xs_axes.get(k, -1), v) if
                                      isinstance(xs_axes.get(k, -1), int) else xs_axes[k] for k, v in xs.items()})
    outs = []
    with jax.enable_x64(True):
        for start in range(0, B, size):
            stop = min(start + size, B)
            take = np.minimum(np.arange(start, start + size), stop - 1)  # the last chunk padded to the compiled shape
            chunk_carry = jax.tree_util.tree_map(lambda a: np.asarray(a)[take], carry)
            chunk_xs = jax.tree_util.tree_unflatten(tree, [np.take(np.asarray(a), take, axis=ax) if ax >= 0 else a
                                                           for a, ax in zip(leaves, axes)])
            inner, acc = scan_ticks(jax, run, chunk_carry, chunk_xs, n, None, size, carry_axes, xs_axes)
            outs.append(({k: np.asarray(v)[:stop - start] for k, v in acc.items()},
                         np.asarray(inner[3])[:stop - start], np.asarray(inner[4])[:stop - start]))
    acc = {k: np.concatenate([o[0][k] for o in outs]).reshape(batch) for k in outs[0][0]}
    fail_tick = np.concatenate([o[1] for o in outs]).reshape(batch)
    reason = np.concatenate([o[2] for o in outs]).reshape(batch)
    first = acc.pop("first_lost")
    res = {"reference_lost": first >= 0,
           "first_lost_time_s": np.where(first >= 0, times[np.maximum(first, 0)], np.nan), **acc}
    res["failed"] = reason > 0
    res["failure"] = {}
    for idx in zip(*np.nonzero(reason)):
        idx = tuple(int(i) for i in idx)
        res["failure"][idx] = _reason(ctrl, experiment.reference, times, measurement, sched, ms, plant, x, dt,
                                      experiment.substeps, fail_tick, reason, batch, idx)
    return res


def _reason(ctrl, reference, times, measurement, sched, ms, plant, x, dt, substeps, fail_tick, reason, batch, idx):
    """World ``idx``'s one-line failure: the loop's (:func:`quatform.sim.loop._failure`) at its
    failing tick, its measurement and controller state from its own rerun on NumPy up to that
    tick (a rollout keeps neither)."""
    from .loop import iterate_numpy, map_worlds

    k = int(fail_tick[idx])
    flat = int(np.ravel_multi_index(idx, batch)) if batch else 0
    B = math.prod(batch)
    one = (lambda a: np.asarray(a).reshape((B,) + np.shape(a)[len(batch):])[[flat]])
    n_sub = k + 1
    sub_sched = {key: np.asarray(v).reshape((times.size, B) + np.shape(v)[1 + len(batch):])[:n_sub, [flat]]
                 for key, v in sched.items()}
    data, state, failure = iterate_numpy(plant, ctrl, measurement, lambda j: map_worlds(reference(j), batch, one, 1),
                                    times[:n_sub], dt, substeps, one(x), (1,), sub_sched,
                                    map_worlds(tree_map(np.asarray, ms), batch, one), None)
    if (0,) in failure:
        return failure[(0,)]
    return f"t = {times[k]:g} s: {ctrl.failure_reasons.get(int(reason[idx]), 'failure code ' + str(int(reason[idx])))}"


@functools.lru_cache(maxsize=None)
def _reducer(finite: int):
    """``(start, step)`` of :func:`quatform.sim.loop.compiled_run`: the metrics reduced tick by
    tick from the loop's outputs ``ys = (x, measured, u, *signals)`` (``signals[finite]`` is
    ``raw_finite``) and the tick's ``xs`` (``ref["robots"]``, ``ed``, ``late``, ``k``); one
    pair of functions per index, so a compiled rollout is cached."""
    import jax.numpy as jnp

    def start(carry):
        B = carry[0].shape[0]
        acc = {name: jnp.zeros(B) for name in _MAXED.values()}
        acc.update(min_robot_separation_m=jnp.full(B, jnp.inf), max_command_speed_m_s=jnp.zeros(B),
                   nonfinite_commands=jnp.zeros(B, dtype=jnp.int64), first_lost=jnp.full(B, -1, dtype=jnp.int64))
        return acc

    def step(acc, ys, xs):
        xk, u, raw_finite = ys[0], ys[2], ys[3 + finite]
        err = robot_errors(xk, xs["ref"]["robots"], xs["ed"])
        held = hold(jnp.stack([err[k] for k in _ERRORS], axis=-1))  # each signal computed once
        err = {k: held[:, q] for q, k in enumerate(_ERRORS)}
        lost = xs["late"] & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                             | (err["robot_position"] > LOST_POSITION_M))
        speed = jnp.max(jnp.linalg.norm(PAIR_LAYOUT.positions(u), axis=-1), axis=-1)
        acc = dict(acc)
        for key, name in _MAXED.items():
            acc[name] = jnp.where(xs["late"], jnp.maximum(acc[name], err[key]), acc[name])
        acc["min_robot_separation_m"] = jnp.minimum(acc["min_robot_separation_m"], err["separation"])
        acc["nonfinite_commands"] = acc["nonfinite_commands"] + (raw_finite[:, 0] < 0.5)
        acc["max_command_speed_m_s"] = jnp.maximum(acc["max_command_speed_m_s"], speed)
        acc["first_lost"] = jnp.where((acc["first_lost"] < 0) & lost, xs["k"], acc["first_lost"])
        return acc

    return start, step
