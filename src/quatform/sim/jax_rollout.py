"""Batched rollouts on JAX reduced to every trial's metrics as they run (sim layer).

A Monte Carlo of 10^4 trials of 6000 ticks would log 6 * 10^7 world-ticks of every channel
(tens of GB). :func:`rollout_metrics` runs the loop's one compiled tick
(:func:`quatform.sim.loop.compiled_run`, the scan of :func:`quatform.sim.loop.simulate_jax`;
``pip install -e ".[jax]"``) and carries, beside the loop's carry, running reductions of the
error signals of :func:`quatform.sim.metrics.error_signals` (the function
:func:`~quatform.sim.metrics.compute_metrics` reads a log with): each trial's metrics come
back as arrays over the batch, with the keys and the values of ``compute_metrics`` of the
logged run (equal within 1e-9 in tests). It reduces any batched kinematic experiment with a
pure controller whose reference gives the desired robots: the team kind in either chart
(seed 000's two robots, any N, with or without the separation barrier).

The desired chart and the ticks whose singularity measure a run computes are the kind's
own: its ``finish`` applied to a log of the reference (:func:`_desired`). The singularity
metrics need the description's :meth:`~quatform.formations.base.Formation.singularity_measure_arrays`
and the recovered chart error its :meth:`~quatform.formations.base.Formation.to_chart_arrays`
on JAX; a description that does not offer them on the array namespace (its
``singularity_on_arrays`` / ``chart_on_arrays`` False: the team descriptions' team
charts) has those keys absent from the result, as has a run with
``formation_metrics=False``; its sweep runs :func:`~quatform.sim.loop.simulate_jax`
and ``Experiment.metrics`` on a logged batch.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra.kernels import hold
from ..errors import InvalidInputError, ShapeError
from . import jax_devices
from .log import Channel, Log
from .loop import cached, check_ticks, compiled_run, config_key, require_jax, scan_ticks, tree_map
from .measurement import PerfectMeasurement
from .metrics import (LOST_ANGLE_RAD, LOST_POSITION_M, TEAM_CHART, command_speed, error_signals,
                      singular_threshold)
from .trial_measurement import TickMeasurement

__all__ = ["ROLLOUT_METRICS", "rollout_metrics"]

#: The metrics :func:`rollout_metrics` may return (keys of ``compute_metrics``), besides
#: ``failed`` and ``failure``; the last ones where the run has them (module docstring).
ROLLOUT_METRICS = ("reference_lost", "first_lost_time_s", "max_cluster_position_error_m", "max_shape_error_m",
                   "max_orientation_error_rad", "max_robot_position_error_m", "robot_position_error_median_m",
                   "min_robot_separation_m", "nonfinite_commands", "max_command_speed_m_s",
                   "max_robot_yaw_error_rad", "safety_active_time_s", "singularity_detected",
                   "first_singular_time_s", "min_singularity_measure", "max_recovered_euclidean_error_rad",
                   "max_recovered_attitude_error_rad", "max_recovered_heading_error_rad")
#: Error signals reduced to their largest value after ``metrics_from_s``, by metric.
_MAXED = {"cluster_position": "max_cluster_position_error_m", "shape": "max_shape_error_m",
          "orientation": "max_orientation_error_rad", "robot_position": "max_robot_position_error_m",
          "robot_yaw": "max_robot_yaw_error_rad", "recovered_euclidean": "max_recovered_euclidean_error_rad",
          "recovered_attitude": "max_recovered_attitude_error_rad",
          "recovered_heading": "max_recovered_heading_error_rad"}
_REDUCERS: dict = {}


def rollout_metrics(experiment, x0=None, measurement=None, *, trials_per_call: int | None = None,
                    formation_metrics: bool = True) -> dict:
    """Every trial's metrics of a batched experiment, rolled out on JAX without a log.

    Parameters
    ----------
    experiment : Experiment
        Of the team kind (``TEAM.experiment(scenario, controller=...)``, a seed-000 file's
        too): kinematic robots whose state is their point, a pure
        controller, a reference that gives the desired robots, the ticks and
        ``meta["metrics_from_s"]``.
    x0 : array_like, shape (*batch, n_state), optional
        Initial robots of every trial (default: the experiment's ``x0``).
    measurement : TickMeasurement, optional
        Noise ``(T, *batch, n_state)``, latency and dropped frames of every trial (default:
        the experiment's; None: perfect).
    trials_per_call : int, optional
        Trials per compiled call (one compilation; chunks bound the device memory), rounded
        up to a multiple of the device count. Default: :func:`.jax_devices.chunk_size` (a
        cache-sized chunk per CPU core, the whole batch on a GPU). Each call's trials are
        spread over JAX's devices (:mod:`.jax_devices`) where that is safe on the CPU
        (:func:`.jax_devices.shardable`): a rollout with the separation barrier (its solver
        loop and batched solves) or the singularity measure (an SVD) stays on one device.
    formation_metrics : bool
        Reduce the metrics that need the controller's description at every tick: its
        singularity measure (the singular values of its inverse Jacobian, at the ticks the kind
        measures) and the recovered chart's error (default True; off, a rollout runs at the
        speed of the errors from the robots alone, spread over every device). On the CPU they
        cost up to about ten times the tick and run on one device.

    Returns
    -------
    dict
        The keys of :data:`ROLLOUT_METRICS` the run has (module docstring) as arrays of the
        batch shape (a time NaN where the event never happened), ``failed`` (bool) and
        ``failure`` (index tuple -> reason) as in :mod:`quatform.sim.backends`.
    """
    jax = require_jax()
    plant, ctrl = experiment.plant, experiment.controller
    measurement = experiment.measurement if measurement is None else measurement
    team = getattr(getattr(ctrl, "inner", ctrl), "team", None)
    if team is None or not ctrl.pure or not plant.batchable or team.n_state != team.layout.size:
        raise InvalidInputError("rollout_metrics reduces batched experiments of kinematic robots whose state is their "
                                "point, with a pure controller (the pair and the team kinds); another experiment runs "
                                "on jax through its log (Experiment.run(backend='jax'), quatform sweep --compute jax)")
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
                                "reference for every trial (the pair and the team kinds')")
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
    desired = _desired(experiment, times, plant, ctrl)
    meta = desired.meta
    F = getattr(ctrl, "formation", None) or ctrl.inner.formation
    chart = meta.get("chart", TEAM_CHART)
    spec = {"layout": meta["layout"], "team": meta["team"], "chart": chart, "n_chart": desired["e_des"].shape[-1],
            "chart_of": F if formation_metrics and F.chart_on_arrays else None,
            "measure": F if formation_metrics and F.singularity_on_arrays else None,
            "threshold": singular_threshold(meta["layout"].n), "finite": signals.index("raw_finite"),
            "cluster": signals.index("cluster"),
            "safety": signals.index("safety_active") if "safety_active" in signals else None}
    reduce = cached(_REDUCERS, config_key(spec), lambda: _reducer(**spec))
    extra = {"ed": np.asarray(desired["e_des"], dtype=float), "late": times >= experiment.meta["metrics_from_s"],
             "sing_at": np.isfinite(np.asarray(desired["singularity"])[:, 0])}
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
    acc = {k: np.concatenate([o[0][k] for o in outs]).reshape(batch + v.shape[1:]) for k, v in outs[0][0].items()}
    fail_tick = np.concatenate([o[1] for o in outs]).reshape(batch)
    reason = np.concatenate([o[2] for o in outs]).reshape(batch)
    res = _results(acc, times)
    res["failed"] = reason > 0
    res["failure"] = {}
    for idx in zip(*np.nonzero(reason)):
        idx = tuple(int(i) for i in idx)
        res["failure"][idx] = _reason(ctrl, experiment.reference, times, measurement, sched, ms, plant, x, dt,
                                      experiment.substeps, fail_tick, reason, batch, idx)
    return res


def _desired(experiment, times, plant, ctrl) -> Log:
    """The experiment's ``finish`` applied to a log of its reference (the desired robots as
    the measured ones, the desired cluster state as the controller's): its ``e_des`` is the
    desired chart a logged run holds, its ``singularity`` NaN at the ticks the kind does not
    measure, its meta the ``layout``, ``team`` and ``chart`` the metrics read."""
    refs = [experiment.reference(k) for k in range(times.size)]
    r_des = np.stack([np.asarray(ref.robots, dtype=float) for ref in refs])
    c_des = np.stack([np.asarray(ref.c, dtype=float) for ref in refs])
    log = Log(times, [Channel("state", tuple(plant.state_columns), r_des),
                      Channel("cluster", tuple(ctrl.signal_columns()["cluster"]), c_des)], dict(experiment.meta))
    return experiment.finish(log)


def _results(acc: dict, times) -> dict:
    """The metrics of the reduced accumulators (:func:`_reducer`), by ``compute_metrics``' keys."""
    first = acc.pop("first_lost")
    res = {"reference_lost": first >= 0, "first_lost_time_s": np.where(first >= 0, times[np.maximum(first, 0)], np.nan)}
    res["robot_position_error_median_m"] = np.median(acc.pop("robot_position_each"), axis=-1)
    if "first_singular" in acc:
        first = acc.pop("first_singular")
        res.update(singularity_detected=first >= 0,
                   first_singular_time_s=np.where(first >= 0, times[np.maximum(first, 0)], np.nan))
    if "safety_ticks" in acc:
        res["safety_active_time_s"] = acc.pop("safety_ticks") * (float(times[1] - times[0]) if times.size > 1 else 0.0)
    return {**res, **acc}


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


def _reducer(layout, team, chart, n_chart, chart_of, measure, threshold, finite, cluster, safety):
    """``(start, step)`` of :func:`quatform.sim.loop.compiled_run`: the metrics reduced tick by
    tick from the loop's outputs ``ys = (x, measured, u, *signals)`` (``signals[finite]`` is
    ``raw_finite``, ``signals[cluster]`` the controller's cluster state, ``signals[safety]``
    the barrier's ``safety_active``) and the tick's ``xs`` (``ref``, ``ed``, ``late``,
    ``sing_at``, ``k``; ``n_chart`` chart values); ``chart_of`` and ``measure`` the description whose chart and
    singularity measure are reduced, or None. Built once per configuration
    (:func:`~quatform.sim.loop.cached`), so a compiled rollout is reused."""
    import jax.numpy as jnp

    probe, e = np.ones((1, layout.size)), None if chart_of is None else np.zeros((1, n_chart))
    with np.errstate(all="ignore"):  # which signals the run has: those of one (degenerate) state
        present = set(error_signals(layout, probe, probe, e, e, chart=chart))

    def signals_of(ys, xs):
        xk = ys[0]
        e = None if chart_of is None else chart_of.to_chart_arrays(ys[3 + cluster], xs["ed"], xk)
        return error_signals(layout, xk, xs["ref"]["robots"], e, None if e is None else xs["ed"], chart=chart)

    def start(carry):
        B = carry[0].shape[0]
        acc = {_MAXED[k]: jnp.zeros(B) for k in present if k in _MAXED}
        acc.update(robot_position_each=jnp.zeros((B, layout.n)), min_robot_separation_m=jnp.full(B, jnp.inf),
                   max_command_speed_m_s=jnp.zeros(B), nonfinite_commands=jnp.zeros(B, dtype=jnp.int64),
                   first_lost=jnp.full(B, -1, dtype=jnp.int64))
        if safety is not None:
            acc["safety_ticks"] = jnp.zeros(B, dtype=jnp.int64)
        if measure is not None:
            acc.update(min_singularity_measure=jnp.full(B, jnp.inf), first_singular=jnp.full(B, -1, dtype=jnp.int64))
        return acc

    def step(acc, ys, xs):
        xk, u, raw_finite = ys[0], ys[2], ys[3 + finite]
        err = signals_of(ys, xs)
        names = [k for k in err if k != "robot_position_each"]
        held = hold(jnp.concatenate([jnp.stack([err[k] for k in names], axis=-1), err["robot_position_each"]],
                                    axis=-1))  # each signal computed once
        each = held[:, len(names):]
        err = {k: held[:, q] for q, k in enumerate(names)}
        late = xs["late"]
        lost = late & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                       | (err["robot_position"] > LOST_POSITION_M))
        acc = dict(acc)
        for key, name in _MAXED.items():
            if key in err:
                acc[name] = jnp.where(late, jnp.maximum(acc[name], err[key]), acc[name])
        acc["robot_position_each"] = jnp.where(late, jnp.maximum(acc["robot_position_each"], each),
                                               acc["robot_position_each"])
        acc["min_robot_separation_m"] = jnp.minimum(acc["min_robot_separation_m"], err["separation"])
        acc["nonfinite_commands"] = acc["nonfinite_commands"] + (raw_finite[:, 0] < 0.5)
        acc["max_command_speed_m_s"] = jnp.maximum(acc["max_command_speed_m_s"], command_speed(team, u))
        acc["first_lost"] = jnp.where((acc["first_lost"] < 0) & lost, xs["k"], acc["first_lost"])
        if safety is not None:
            acc["safety_ticks"] = acc["safety_ticks"] + (ys[3 + safety][:, 0] > 0.5)
        if measure is not None:  # counted at the ticks the kind measures
            s = jnp.where(xs["sing_at"], measure.singularity_measure_arrays(xk, xs["ref"]["c"]), jnp.inf)
            acc["min_singularity_measure"] = jnp.minimum(acc["min_singularity_measure"], s)
            acc["first_singular"] = jnp.where((acc["first_singular"] < 0) & (s < threshold), xs["k"],
                                              acc["first_singular"])
        return acc

    return start, step
