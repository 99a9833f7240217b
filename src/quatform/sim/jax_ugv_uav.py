"""The closed loop of the ``ugv-uav`` kind (seed 001 §5: Pioneer 3-DX + Bebop 2) on JAX (sim layer),
kept while :class:`~quatform.control.ugv_uav.UgvUavController` is not ``pure``
(:func:`quatform.sim.loop.legacy_jax` hands its runs here).

:func:`simulate` has :func:`quatform.sim.simulate`'s signature and returns the same
:class:`~quatform.sim.log.Log` for a :class:`~quatform.sim.plants.ugv_uav.PioneerBebopPlant`,
a :class:`~quatform.control.ugv_uav.UgvUavController` (any of its three descriptions) and a
:class:`~quatform.sim.measurement.MotionCapture`; the one loop's JAX driver hands
such runs here. It runs NumPy's kernels,
written on any array namespace: the descriptions' ``forward_arrays``,
``inverse_jacobian_arrays`` (and the restricted one's ``reachable``, ``inverse_arrays``), the
law (:meth:`~quatform.control.ugv_uav.UgvUavController.cluster_rates`), the filters
(:class:`~quatform.control.filters.MocapScreen` ``frame_code``, ``ArenaWalls.limit``,
``HeadingLaw.rate``), the robots' actuation, brake and saturation, the plant's step, and the
motion capture's :meth:`~quatform.sim.measurement.MotionCapture.frame_pose`.

What does not depend on the state is computed on the host up front, as NumPy computes it:
the reference of every tick (NaN rows where the description cannot express it: the
controller brakes there), and the motion capture's
:meth:`~quatform.sim.measurement.MotionCapture.schedule` (which ticks see a new frame, the
plant step each frame and odometry sample reads, every frame's noise and faults, drawn from
the same streams in the same order). The motion capture's state (the plant outputs of the
last plant steps, the last frame) is in the scan's carry (its pure
:meth:`~quatform.sim.measurement.MotionCapture.read` and ``observe``); the controller's state
(:class:`~quatform.control.ugv_uav.UgvUavState`: the last good frame and its time, the start
of the current run of bad frames, the emergency stop, the Bebop's compensation memory) is
arrays in the carry, its branches (no frame yet, a reference the description cannot
express, the restricted description's robot-space fallback, the stop) all computed and
selected per tick. ``log.meta["controller_state"]`` is the final ``UgvUavState`` (its
``stop_reason`` the NumPy controller's words).

One world, as :class:`~quatform.sim.measurement.MotionCapture` measures one: the NumPy
controller raises on nothing that its screen lets through for these robots, so no world
fails here.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..algebra.validate import as_array
from ..control.base import Reference
from ..control.ugv_uav import BEBOP_PART, MOCAP_PART, ODOMETRY_PART, PIONEER_PART, UgvUavController, UgvUavState
from ..errors import InvalidInputError, ShapeError
from ..formations import UgvUavRestricted
from ..robots import BebopMemory
from . import jax_loop
from .loop import tree_map
from .log import Channel, Log
from .measurement import MotionCapture

__all__ = ["simulate"]

_RUNS = ("the jax backend runs the ugv-uav kind with its UgvUavController, the Pioneer-Bebop plant and the "
         "MotionCapture measurement")
#: The signals of the controller, in the order of ``signal_columns``.
_SIGNALS = ("cluster", "error", "robot_rates", "raw_finite", "stopped", "frame", "held", "outside", "used")
#: Batch axis of each carry slot: ``(x, mocap state, good, good_t, bad_since, stopped, stop_t,
#: stop_since, v_r, memory_t, v_dot)``; the per-tick inputs are one world's (no batch axis).
_AXES = ((0,) * 11, {})


def _check(plant, controller, measurement):
    if not isinstance(controller, UgvUavController):
        raise InvalidInputError(f"{_RUNS}; {type(controller).__name__} runs on numpy (--compute numpy)")
    if type(measurement) is not MotionCapture:
        raise InvalidInputError(f"{_RUNS}; the measurement {type(measurement).__name__} runs on numpy "
                                "(--compute numpy)")


def _references(controller, reference: Callable, n: int):
    """``(c, c_dot, hold)``: every tick's reference ``(T, n_c)`` and whether the controller
    holds (brakes) there (no reference, or a NaN in ``c``), checked as ``update`` checks it."""
    n_c = controller.formation.n_c
    c, cd = np.full((n, n_c), np.nan), np.full((n, n_c), np.nan)
    hold = np.ones(n, dtype=bool)
    for k in range(n):
        ref = reference(k)
        if ref is None:
            continue
        if not isinstance(ref, Reference):
            raise InvalidInputError(f"{controller.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(ref).__name__}")
        ck = np.asarray(ref.c, dtype=float)
        if ck.shape == (n_c,) and np.any(np.isnan(ck)):
            continue
        c[k], cd[k], hold[k] = as_array(ref.c, "reference.c", n_c), as_array(ref.c_dot, "reference.c_dot", n_c), False
    return c, cd, hold


def _freeze(v):
    """A hashable value of ``v`` (arrays by their bytes, dataclasses field by field)."""
    if isinstance(v, np.ndarray):
        return ("array", v.shape, v.tobytes())
    if isinstance(v, (tuple, list)):
        return tuple(_freeze(a) for a in v)
    if isinstance(v, dict):
        return tuple(sorted((k, _freeze(a)) for k, a in v.items()))
    if hasattr(v, "__dataclass_fields__") and not isinstance(v, type):
        return (type(v), tuple(_freeze(getattr(v, f)) for f in v.__dataclass_fields__))
    try:
        hash(v)
        return v
    except TypeError:
        return (type(v), _freeze(vars(v)))


def _config_key(plant, controller, mocap) -> tuple:
    """What a compiled tick depends on: the controller's settings, the plant's robots, floor and
    acceleration limits, the motion capture's ``ugv_z`` (two experiments with equal ones share one compilation)."""
    return (_freeze(vars(controller)), type(controller.formation), plant.pioneer, plant.bebop, plant.floor,
            plant.pioneer_accel, float(mocap.ugv_z))


def _tick_function(plant, ctrl, mocap, dt, substeps):
    """One control tick on JAX arrays: ``(carry, xs_k) -> (carry, (x, m, u, *signals))``."""
    import jax.numpy as jnp

    F, p, b = ctrl.formation, ctrl.pioneer, ctrl.bebop
    restricted = isinstance(F, UgvUavRestricted)
    ff = 1.0 if ctrl.feedforward else 0.0
    k_x2 = np.r_[ctrl.k_x, ctrl.k_x]

    def actuation_commands(u_p, u_b):  # the team's saturation: each robot on its own
        return jnp.concatenate([p.saturate(u_p), b.saturate(u_b)], axis=-1)

    def rates_through(Ji, rate):  # Ji @ rate, (B, 6, n_c) (B, n_c)
        return (Ji * rate[..., None, :]).sum(axis=-1)

    def tick(carry, xs):
        x, ms, good, good_t, bad_since, stopped, stop_t, stop_since, v_r, mem_t, v_dot = carry
        B = x.shape[0]
        t = xs["t"]
        ms, m = mocap.read(ms, xs["meas"])  # the motion capture (MotionCapture.read)
        # -- the screen (UgvUavController.screen, _screened)
        has_good = jnp.isfinite(good_t)
        finite = jnp.all(jnp.isfinite(m[:, MOCAP_PART]), axis=-1)
        code = ctrl.mocap.frame_code(t, ctrl.measured_points(m), finite, ctrl.measured_points(good), good_t)
        ok = code == 0
        mo, go = m[:, ODOMETRY_PART], good[:, ODOMETRY_PART]
        odo = jnp.isfinite(mo)
        m_good = jnp.concatenate([m[:, MOCAP_PART], jnp.where(odo, mo, jnp.where(has_good[:, None], go, 0.0))], axis=-1)
        m_held = jnp.concatenate([good[:, MOCAP_PART], jnp.where(odo, mo, go)], axis=-1)
        used = jnp.where(ok[:, None], m_good, m_held)
        none = ~ok & ~has_good  # no good frame yet: nothing to go on
        held = ~ok & has_good
        good = jnp.where(ok[:, None], m_good, good)
        good_t = jnp.where(ok, t, good_t)
        bad_since = jnp.where(ok, jnp.nan, jnp.where(jnp.isnan(bad_since), t, bad_since))
        expire = ~ok & ~stopped & ctrl.mocap.expired(t, bad_since)
        stopped = stopped | expire
        stop_t = jnp.where(expire, t, stop_t)
        stop_since = jnp.where(expire, bad_since, stop_since)
        # -- the chain of Fig. 18 on the frame used
        points = ctrl.measured_points(used)
        r = jnp.concatenate(points, axis=-1)
        c_des = jnp.broadcast_to(xs["c"], (B, F.n_c))
        c_dot = jnp.broadcast_to(xs["cd"], (B, F.n_c))
        inside = F.reachable(r) if restricted else jnp.ones((B,), dtype=bool)
        c = F.forward_arrays(r, c_des)
        err, c_rate = ctrl.cluster_rates(c, c_des, c_dot)
        x_rate = rates_through(F.inverse_jacobian_arrays(c), c_rate)  # (4.42)
        if restricted:  # robot-space control toward INVKIN(c_des) (seed 000 §3.1)
            r_des = F.inverse_arrays(c_des)
            x_space = ff * rates_through(F.inverse_jacobian_arrays(c_des), c_dot) - k_x2 * jnp.tanh(r - r_des)
            x_rate = jnp.where(inside[:, None], x_rate, x_space)
            c = jnp.where(inside[:, None], c, jnp.nan)
            err = jnp.where(inside[:, None], err, jnp.nan)
        rates_finite = jnp.all(jnp.isfinite(x_rate), axis=-1)
        x_rate = ctrl.walls.limit(points, jnp.where(rates_finite[:, None], x_rate, 0.0))
        # the reference the description cannot express: hold (brake), the cluster of the robots
        hold = jnp.broadcast_to(xs["hold"], (B,))
        c_free = F.forward_arrays(r, None)
        outside_free = ~F.reachable(r) if restricted else jnp.zeros((B,), dtype=bool)
        # -- the commands: brake (no frame, hold, stopped) or actuate (3.5), (3.10), (4.47)-(4.51)
        brake = none | hold | stopped
        m_brake = jnp.where(none[:, None], m, used)
        u_b_brake, mem_brake = b.brake(m_brake[:, BEBOP_PART], BebopMemory(v_r, mem_t, v_dot))
        u_brake = actuation_commands(jnp.zeros((B, 2), dtype=x.dtype), u_b_brake)
        psi_rate = ctrl.heading.rate(used[:, 2], used[:, 6])  # (4.50)-(4.51), psi_bd = psi_p
        u_p, _ = p.actuate(used[:, PIONEER_PART], x_rate[:, 0:3], t)
        u_b, mem = b.actuate(used[:, BEBOP_PART], jnp.concatenate([x_rate[:, 3:6], psi_rate[:, None]], axis=-1), t,
                             BebopMemory(v_r, mem_t, v_dot))
        u = jnp.where(brake[:, None], u_brake, actuation_commands(u_p, u_b))
        v_r, mem_t, v_dot = (jnp.where(brake.reshape((B,) + (1,) * (a.ndim - 1)), a_brake, a)
                             for a, a_brake in ((mem.v_r, mem_brake.v_r), (mem.t, mem_brake.t),
                                                (mem.v_dot, mem_brake.v_dot)))
        # -- the signals (UgvUavController._step), branch by branch
        nan_c = jnp.full((B, F.n_c), jnp.nan, dtype=x.dtype)
        braking = none | hold
        cluster = jnp.where(none[:, None], nan_c, jnp.where(hold[:, None], jnp.where(outside_free[:, None], nan_c,
                                                                                      c_free), c))
        error = jnp.where(braking[:, None], nan_c, err)
        robot_rates = jnp.where(braking[:, None], 0.0, x_rate)
        raw_finite = jnp.where(none, 0.0, jnp.where(hold, 1.0, rates_finite.astype(x.dtype)))
        outside = jnp.where(none, False, jnp.where(hold, outside_free, ~inside))
        signals = (cluster, error, robot_rates, raw_finite[:, None], stopped.astype(x.dtype)[:, None],
                   code.astype(x.dtype)[:, None], (held & ~none).astype(x.dtype)[:, None],
                   outside.astype(x.dtype)[:, None], jnp.where(none[:, None], jnp.nan, used))
        # -- the plant, substeps of dt; the motion capture observing its outputs
        x_next = x
        for s in range(substeps):
            x_next = plant.step(x_next, u, dt, t + s * dt)
            ms = mocap.observe(ms, plant.output(x_next), s)
        new = (x_next, ms, good, good_t, bad_since, stopped, stop_t, stop_since, v_r, mem_t, v_dot)
        if "valid" in xs:  # a padded tick past the run's end (progress chunks) changes nothing
            new = tree_map(lambda a, a0: jnp.where(xs["valid"], a, a0), new, carry)
        return new, (x, m, u) + signals

    return tick


#: Compiled scans of recent configurations (:func:`_config_key`), newest last.
_CACHE: dict = {}


def simulate(plant, controller, reference: Callable, times, x0, *, dt: float | None = None, substeps: int = 1,
             measurement=None, progress: Callable | None = None, meta: dict | None = None) -> Log:
    """Run the ``ugv-uav`` closed loop of :func:`quatform.sim.simulate` compiled with JAX (same
    arguments, same Log: the channels ``state``, ``measured``, ``command`` and the controller's
    signals, each ``(T, k)``; ``meta["controller_state"]`` the final
    :class:`~quatform.control.ugv_uav.UgvUavState`).

    Raises
    ------
    InvalidInputError
        For another controller or measurement (one line naming what runs here), and the
        errors of :func:`quatform.sim.simulate`.
    ShapeError
        For an ``x0`` with batch axes (the motion capture measures one world at a time).
    """
    jax = jax_loop.require_jax()
    _check(plant, controller, measurement)
    times, dt = jax_loop.check_ticks(times, substeps, dt)
    n = times.size
    x, batch, _ = jax_loop.initial_states(plant, x0)
    if batch:
        raise ShapeError(f"jax simulate: MotionCapture measures one world at a time; give x0 of shape "
                         f"({len(plant.state_columns)},), got {x.shape}")
    c_ref, cd_ref, hold = _references(controller, reference, n)
    sched = measurement.schedule(times, dt, substeps)
    xs = {"t": times, "c": c_ref, "cd": cd_ref, "hold": hold, "meas": sched}

    def build():
        tick = _tick_function(plant, controller, measurement, dt, substeps)
        tick.compiled = jax.jit(lambda carry, xs: jax.lax.scan(tick, carry, xs)[::-1])
        return tick

    key = (_config_key(plant, controller, measurement), dt, substeps, "turns" in sched,
           tuple(measurement.init(plant.output(x), (1,), sched)["hist"].shape))
    step = jax_loop.cached(_CACHE, key, build)
    nan = np.full(1, np.nan)
    carry = (x[None], measurement.init(plant.output(x)[None], (1,), sched), np.full((1, 11), np.nan), nan, nan,
             np.zeros(1, dtype=bool), nan, nan, np.full((1, 4), np.nan), nan,
             np.zeros((1, 4)))
    with jax.enable_x64(True):
        ys, carry = jax_loop.scan_ticks(jax, step, carry, xs, n, progress, _AXES)
    names = ("state", "measured", "command") + _SIGNALS
    data = {k: np.asarray(v)[:, 0] for k, v in zip(names, ys)}
    good, good_t, bad_since, stopped, stop_t, stop_since, v_r, mem_t, v_dot = (np.asarray(a)[0] for a in carry[2:])
    state = UgvUavState(memory=(None, BebopMemory(v_r, np.asarray(float(mem_t)), v_dot)), stopped=bool(stopped),
                        stop_reason=controller.stop_reason(float(stop_t), float(stop_since)) if stopped else "",
                        good=good if np.isfinite(good_t) else None,
                        good_t=float(good_t) if np.isfinite(good_t) else None,
                        bad_since=float(bad_since) if np.isfinite(bad_since) else None)
    cols = {"state": plant.state_columns, "measured": measurement.columns, "command": controller.command_names,
            **controller.signal_columns()}
    chans = [Channel(k, tuple(cols[k]), data[k]) for k in names]
    return Log(times, chans, {"controller": controller.name, "controller_state": state, **(meta or {})})
