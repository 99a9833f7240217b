"""Batched rollouts on JAX reduced to every trial's metrics as they run (sim layer).

A Monte Carlo of 10^4 trials of 6000 ticks would log 6 * 10^7 world-ticks of every channel
(tens of GB). :func:`rollout_metrics` runs the same compiled tick as
:func:`quatform.sim.jax_loop.simulate` (``pip install -e ".[jax]"``) and keeps only running
reductions of the error signals of :func:`quatform.sim.metrics.robot_errors` (the
representation-independent errors of seed 000's pair, from the robots' poses): each
trial's metrics come back as arrays over the batch, with the keys and the values of
:func:`quatform.sim.metrics.compute_metrics` (equal within 1e-9 in tests). Two metrics need
more than the robots' poses and are left out: the singularity measure (an SVD of the
description's Jacobian per tick) and the recovered Euclidean error (the description's
chart); a sweep that needs them runs :func:`~quatform.sim.jax_loop.simulate` and
``Experiment.metrics`` on a logged batch.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InvalidInputError, ShapeError
from . import jax_devices
from .jax_loop import (
    FAILURE_REASONS,
    cached,
    check_supported,
    check_ticks,
    config_key,
    hold,
    initial_carry,
    require_jax,
    stack_reference,
    team_parts,
    tick_function,
)
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
    check_supported(plant, ctrl, measurement)
    if team_parts(ctrl) is not None:
        raise InvalidInputError("rollout_metrics rolls out the pair kind's experiments; a team experiment runs on jax "
                                "through its log (Experiment.run(backend='jax'), quatform sweep --compute jax)")
    times, dt = check_ticks(experiment.times, experiment.substeps, experiment.dt)
    n = times.size
    x = np.array(experiment.x0 if x0 is None else x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),) or x.size == 0:
        raise ShapeError(f"rollout_metrics: x0 must have shape (*batch, {len(plant.state_columns)}) with at least "
                         f"one world, got {x.shape}")
    batch = x.shape[:-1]
    B = math.prod(batch)
    c_ref, cd_ref, r_ref = stack_reference(ctrl, experiment.reference, n, batch)
    if r_ref is None or r_ref.shape[1] != 1:
        raise InvalidInputError("rollout_metrics: the experiment's reference must give the desired robots, one "
                                "reference for every trial (the pair kind's)")
    e_des = np.asarray(experiment.scenario.path(times)[0], dtype=float)
    late = times >= experiment.meta["metrics_from_s"]
    tick = TickMeasurement() if measurement is None or isinstance(measurement, PerfectMeasurement) else measurement
    tick.check(plant.output(x), batch, n)
    noise = None if tick.noise is None else tick.noise[:n].reshape(n, B, -1)
    dropped = None if tick.dropped is None else tick.dropped[:n].reshape(n, B)
    step = (dt, experiment.substeps, tick.delay_ticks, noise is not None, dropped is not None)
    compiled = cached(_CACHE, (config_key(plant, ctrl), *step), lambda: _compile(
        jax, tick_function(plant, ctrl, *step, True), ctrl.team.layout, tick.delay_ticks))
    if trials_per_call is not None and (not isinstance(trials_per_call, (int, np.integer))
                                        or isinstance(trials_per_call, bool) or trials_per_call < 1):
        raise InvalidInputError(f"rollout_metrics: trials_per_call = {trials_per_call!r} must be a whole number >= 1 "
                                "(trials per compiled call), or None for the default")
    size = jax_devices.chunk_size(jax, B, trials_per_call)
    shared = {"t": times, "c": c_ref, "cd": cd_ref, "rd": r_ref, "ed": e_des[:, None, :], "late": late,
              "k": np.arange(n, dtype=np.int64)}
    xb = x.reshape(B, -1)
    outs = []
    with jax.enable_x64(True):
        for start in range(0, B, size):
            stop = min(start + size, B)
            sl = slice(start, stop)
            xs = dict(shared)
            if noise is not None:
                xs["noise"] = noise[:, sl]
            if dropped is not None:
                xs["dropped"] = dropped[:, sl]
            xs["x0"] = xb[sl]
            if stop - start < size:  # the last chunk padded to the compiled shape
                pad = size - (stop - start)
                xs["x0"] = np.concatenate([xs["x0"], np.repeat(xs["x0"][-1:], pad, axis=0)])
                for key in ("noise", "dropped"):
                    if key in xs:
                        xs[key] = np.concatenate([xs[key], np.repeat(xs[key][:, -1:], pad, axis=1)], axis=1)
            xs = jax_devices.place(jax, xs, {"x0": 0, "noise": 1, "dropped": 1})  # the chunk split over devices
            acc, fail_tick, reason = compiled(xs.pop("x0"), xs)
            outs.append(({k: np.asarray(v)[:stop - start] for k, v in acc.items()},
                         np.asarray(fail_tick)[:stop - start], np.asarray(reason)[:stop - start]))
    acc = {k: np.concatenate([o[0][k] for o in outs]).reshape(batch) for k in outs[0][0]}
    fail_tick = np.concatenate([o[1] for o in outs]).reshape(batch)
    reason = np.concatenate([o[2] for o in outs]).reshape(batch)
    first = acc.pop("first_lost")
    res = {"reference_lost": first >= 0,
           "first_lost_time_s": np.where(first >= 0, times[np.maximum(first, 0)], np.nan), **acc}
    res["failed"] = reason > 0
    res["failure"] = {tuple(int(i) for i in idx): f"t = {times[fail_tick[idx]]:g} s: "
                      f"{FAILURE_REASONS[int(reason[idx])]}" for idx in zip(*np.nonzero(reason))}
    return res


#: Compiled rollouts of recent configurations and steps (:func:`~quatform.sim.jax_loop.config_key`).
_CACHE: dict = {}


def _compile(jax, step, L, delay):
    """``jax.jit`` of the scan of ``step`` with the metrics reduced tick by tick."""
    import jax.numpy as jnp

    def body(carry, xs):
        inner, acc = carry
        inner, (xk, _, u, _, _, finite) = step(inner, xs)
        err = robot_errors(xk, xs["rd"], xs["ed"])
        held = hold(jnp.stack([err[k] for k in _ERRORS], axis=-1))  # each signal computed once
        err = {k: held[:, q] for q, k in enumerate(_ERRORS)}
        lost = xs["late"] & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                             | (err["robot_position"] > LOST_POSITION_M))
        speed = jnp.max(jnp.linalg.norm(L.positions(u), axis=-1), axis=-1)
        acc = dict(acc)
        for key, name in _MAXED.items():
            acc[name] = jnp.where(xs["late"], jnp.maximum(acc[name], err[key]), acc[name])
        acc["min_robot_separation_m"] = jnp.minimum(acc["min_robot_separation_m"], err["separation"])
        acc["nonfinite_commands"] = acc["nonfinite_commands"] + (finite[:, 0] < 0.5)
        acc["max_command_speed_m_s"] = jnp.maximum(acc["max_command_speed_m_s"], speed)
        acc["first_lost"] = jnp.where((acc["first_lost"] < 0) & lost, xs["k"], acc["first_lost"])
        return (inner, acc), None

    def run(x_b, xs_b):
        acc = {name: jnp.zeros(x_b.shape[0]) for name in _MAXED.values()}
        acc.update(min_robot_separation_m=jnp.full(x_b.shape[0], jnp.inf),
                   max_command_speed_m_s=jnp.zeros(x_b.shape[0]),
                   nonfinite_commands=jnp.zeros(x_b.shape[0], dtype=jnp.int64),
                   first_lost=jnp.full(x_b.shape[0], -1, dtype=jnp.int64))
        (inner, acc), _ = jax.lax.scan(body, (initial_carry(x_b, delay), acc), xs_b)
        return acc, inner[3], inner[4]

    return jax.jit(run)
