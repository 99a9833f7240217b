"""The closed loop on JAX: ``jax.jit`` and ``lax.scan`` over the control ticks (sim layer).

:func:`simulate` has :func:`quatform.sim.simulate`'s signature and returns the same
:class:`~quatform.sim.log.Log`; it runs the same kernels (``pip install -e ".[jax]"``):

* the controller's chain without its value checks
  (:meth:`~quatform.control.cluster.ClusterController.chain`: the formation's forward
  kinematics, the law of :mod:`quatform.control.laws`, the rate map), the measured yaws
  wound onto the reference's (:meth:`~quatform.formations.base.Formation.align`), the team's
  saturation and step (:class:`~quatform.robots.Team`) - component arithmetic that runs on
  NumPy and on JAX arrays alike (:func:`quatform.algebra.kernels.namespace`);
* the reference, which does not depend on the state: sampled on the host with NumPy for
  every tick (exact) and checked there once, as the controller checks it every tick;
* the measurement: perfect, or :class:`~quatform.sim.trial_measurement.TickMeasurement`
  (its noise and dropped frames are arrays drawn up front; its latency is a ring buffer of
  the last ``d + 1`` outputs in the scan's carry).

What the controller refuses with an exception (robots on each other, a non-finite measured
state) cannot raise inside a compiled loop: a world where it happens is marked failed at
that tick and frozen from then on, as :func:`quatform.sim.simulate` freezes one (its state
held, its commands zero, its signals NaN); ``log.meta["failed"]`` (bool, the batch shape)
and ``log.meta["failure"]`` (index tuple -> ``"t = ... s: reason"``) report it, as
:mod:`quatform.sim.backends` specifies. A run of one world (no batch axes) raises.

Precision: float64. The computation runs inside ``jax.enable_x64(True)`` (a context
manager: the user's global ``jax_enable_x64`` setting is left as it was). Devices: those of
JAX's default backend - the GPUs when a CUDA JAX is installed and sees one, otherwise one
CPU device per core (:mod:`.jax_devices`) - with the batch of worlds split over them; no
code changes. Supported: the pair kind's experiments (seed 000's four controllers on
kinematic holonomic robots); anything else is refused in one line naming what runs here.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.validate import as_array
from ..control.base import Reference
from ..control.cluster import ClusterController
from ..errors import (
    DegenerateInputError,
    InvalidInputError,
    MissingDependencyError,
    ShapeError,
)
from ..formations import DualQuaternionPair, EuclideanPair, QuaternionPair, RobotSpace
from ..formations import pair_kernels as kern
from ..formations.base import MAX_MAGNITUDE, MIN_SEPARATION_M, check_magnitude
from ..robots import HolonomicRobot
from . import jax_devices
from .log import Channel, Log
from .plants import KinematicTeam
from .simulate import PerfectMeasurement
from .trial_measurement import TickMeasurement

__all__ = [
    "FAILURE_REASONS",
    "JAX_FORMATIONS",
    "cached",
    "check_supported",
    "check_ticks",
    "config_key",
    "hold",
    "initial_carry",
    "require_jax",
    "simulate",
    "stack_reference",
    "tick_function",
]

#: Formation descriptions whose controllers run on JAX (seed 000's pair descriptions).
JAX_FORMATIONS = (QuaternionPair, DualQuaternionPair, EuclideanPair, RobotSpace)
#: What the backend runs, for the one-line refusal of anything else.
_RUNS = ("the jax backend runs the seed-000 pair experiments (cluster-space, robot-space, quaternion and "
         "dual-quaternion controllers on kinematic holonomic robots, perfect or TickMeasurement measurement)")
#: Reason of a failed world, by code (0: none).
FAILURE_REASONS = {1: "the measured robot state is not finite (or beyond 1e150)",
                   2: f"the measured robots coincide (closer than {MIN_SEPARATION_M:g} m): a two-robot formation "
                      "is undefined there"}


def require_jax():
    """The ``jax`` module (its CPU devices configured: :func:`.jax_devices.configure`), or one
    line naming the install command."""
    try:
        import jax
    except ImportError:
        raise MissingDependencyError('the jax compute backend needs JAX: pip install -e ".[jax]" '
                                     '(or --backend numpy)') from None
    jax_devices.configure(jax)  # one CPU device per core, before JAX starts its backends
    return jax


def check_supported(plant, controller, measurement) -> None:
    """Refuse (one line, naming what runs here) what the jax backend does not run."""
    if not isinstance(controller, ClusterController) or not isinstance(controller.formation, JAX_FORMATIONS):
        raise InvalidInputError(f"{_RUNS}; {type(controller).__name__} runs on numpy (--backend numpy)")
    if controller.filters:
        raise InvalidInputError(f"{_RUNS}; a controller with filters runs on numpy (--backend numpy)")
    team = controller.team
    if not (isinstance(plant, KinematicTeam) and plant.team == team and team.common_limit
            and all(type(r) is HolonomicRobot for r in team.robots)):
        raise InvalidInputError(f"{_RUNS}; the plant {type(plant).__name__} runs on numpy (--backend numpy)")
    if measurement is not None and type(measurement) not in (PerfectMeasurement, TickMeasurement):
        raise InvalidInputError(f"{_RUNS}; the measurement {type(measurement).__name__} runs on numpy "
                                "(--backend numpy)")


def check_ticks(times, substeps, dt):
    """Checked ``(times, dt)`` (the rules of :func:`quatform.sim.simulate`)."""
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size < 1:
        raise ShapeError(f"jax simulate: times must have shape (T,) with T >= 1, got {times.shape}")
    if not isinstance(substeps, int) or isinstance(substeps, bool) or substeps < 1:
        raise InvalidInputError(f"jax simulate: substeps must be a whole number >= 1, got {substeps!r}")
    if not np.all(np.isfinite(times)):
        raise InvalidInputError("jax simulate: times must be finite (control ticks in s)")
    if dt is None:
        dt = float(times[1] - times[0]) / substeps if times.size > 1 else 0.0
    elif not (isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool) and math.isfinite(dt)
              and dt > 0):
        raise InvalidInputError(f"jax simulate: dt = {dt!r} must be a positive finite number of seconds")
    if times.size > 1:
        gaps, tick = np.diff(times), substeps * dt
        if not np.all(np.abs(gaps - tick) <= 1e-9 * max(tick, 1e-300) + 1e-12):
            raise InvalidInputError(f"jax simulate: the control ticks must be evenly spaced by substeps * dt = "
                                    f"{tick!r} s; give times = t0 + k * substeps * dt")
    return times, float(dt)


def stack_reference(controller, reference: Callable, n: int, batch: tuple):
    """The reference of every tick, sampled and checked on the host: ``(c, c_dot, robots)``,
    each ``(T, B or 1, k)`` (``robots`` None when the reference gives none)."""
    refs = [reference(k) for k in range(n)]
    if not all(isinstance(r, Reference) for r in refs):
        bad = next(r for r in refs if not isinstance(r, Reference))
        raise InvalidInputError(f"{controller.name} controller: reference must be a Reference(c, c_dot), got "
                                f"{type(bad).__name__}")
    F = controller.formation
    has_robots = refs[0].robots is not None
    if any((r.robots is not None) != has_robots for r in refs):
        raise InvalidInputError("jax simulate: the reference gives the desired robots at some ticks only; "
                                "give Reference.robots at every tick or at none")
    out = []
    for name, width, get in (("reference.c", F.n_c, lambda r: r.c), ("reference.c_dot", F.n_c, lambda r: r.c_dot),
                             ("reference.robots", F.n_r, lambda r: r.robots)):
        if name == "reference.robots" and not has_robots:
            out.append(None)
            continue
        try:
            a = np.stack([np.asarray(get(r), dtype=float) for r in refs])
        except ValueError:
            raise ShapeError(f"jax simulate: {name} changes shape between ticks") from None
        a = check_magnitude(as_array(a, name, width), name)
        lead = a.shape[1:-1]
        if lead == ():
            a = a[:, None, :]
        elif lead == batch:
            a = a.reshape(n, -1, width)
        else:
            try:
                a = np.broadcast_to(a, (n,) + np.broadcast_shapes(lead, batch) + (width,)).reshape(n, -1, width)
            except ValueError:
                raise ShapeError(f"batch shapes differ: measured {batch}, {name} {lead}; give one reference per "
                                 "formation or one for all") from None
        out.append(a)
    for check in controller.checks:  # what update() checks every tick, once for every tick
        check(kern.unpack(out[0]))
    return tuple(out)


def simulate(plant, controller, reference: Callable, times, x0, *, dt: float | None = None, substeps: int = 1,
             measurement=None, progress: Callable | None = None, meta: dict | None = None) -> Log:
    """Run the closed loop of :func:`quatform.sim.simulate` compiled with JAX (same arguments, same Log).

    Parameters
    ----------
    plant, controller, reference, times, x0, dt, substeps, measurement, progress, meta
        As :func:`quatform.sim.simulate`; ``x0`` of shape ``(*batch, n_x)``. ``measurement``:
        None (perfect) or a :class:`~quatform.sim.trial_measurement.TickMeasurement`.
        ``progress(fraction)`` is called after each chunk of ``ceil(T / 10)`` ticks (the loop
        then runs in at most ten compiled chunks of one shape: one compilation).

    Returns
    -------
    Log
        Channels ``state``, ``measured``, ``command``, ``cluster``, ``error``, ``raw_finite``,
        each ``(T, *batch, k)``; ``meta["controller_state"]`` None (the controllers are
        stateless); ``meta["failed"]``, ``meta["failure"]`` where a world failed (module
        docstring).

    Raises
    ------
    MissingDependencyError
        Without JAX (``pip install -e ".[jax]"``).
    InvalidInputError
        For a plant, controller or measurement the backend does not run (one line naming
        what it runs), and the errors of :func:`quatform.sim.simulate`.
    """
    jax = require_jax()
    check_supported(plant, controller, measurement)
    times, dt = check_ticks(times, substeps, dt)
    n = times.size
    x = np.array(x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),):
        raise ShapeError(f"jax simulate: x0 must have shape (*batch, {len(plant.state_columns)}), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InvalidInputError("jax simulate: x0 must be finite")
    batch = x.shape[:-1]
    B = math.prod(batch)
    c_ref, cd_ref, r_ref = stack_reference(controller, reference, n, batch)
    tick = TickMeasurement() if measurement is None or isinstance(measurement, PerfectMeasurement) else measurement
    tick.start(float(times[0]), plant.output(x), batch)  # the shape checks of the measurement
    if any(arr is not None and arr.shape[0] < n for arr in (tick.noise, tick.dropped)):
        raise ShapeError(f"TickMeasurement: noise / dropped hold fewer than the run's {n} ticks; give (T, *batch, ...) "
                         f"with T = {n}")
    noise = None if tick.noise is None else tick.noise[:n].reshape(n, B, -1)
    dropped = None if tick.dropped is None else tick.dropped[:n].reshape(n, B)
    step = _compiled_scan(jax, plant, controller, dt, substeps, tick.delay_ticks, noise is not None,
                          dropped is not None, r_ref is not None)
    xs = {"t": times, "c": c_ref, "cd": cd_ref}
    for key, arr in (("rd", r_ref), ("noise", noise), ("dropped", dropped)):
        if arr is not None:
            xs[key] = arr
    with jax.enable_x64(True):
        ys, carry = _scan(jax, step, initial_carry(x.reshape(B, -1), tick.delay_ticks), xs, n, progress)
    names = ("state", "measured", "command", "cluster", "error", "raw_finite")
    data = {k: np.asarray(v)[:, :B].reshape((n,) + batch + (v.shape[-1],)) for k, v in zip(names, ys)}
    fail_tick, reason = (np.asarray(a)[:B].reshape(batch) for a in carry[3:5])
    extra = {}
    if np.any(reason > 0):
        if not batch:
            err = DegenerateInputError if int(reason) == 2 else InvalidInputError
            raise err(f"jax simulate: at t = {times[int(fail_tick)]:g} s {FAILURE_REASONS[int(reason)]}")
        extra = {"failed": reason > 0,
                 "failure": {tuple(int(i) for i in idx): f"t = {times[fail_tick[idx]]:g} s: "
                             f"{FAILURE_REASONS[int(reason[idx])]}" for idx in zip(*np.nonzero(reason))}}
    out_cols = tick.columns if tick.columns is not None else plant.output_columns
    cols = {"state": plant.state_columns, "measured": out_cols, "command": controller.command_names,
            **controller.signal_columns()}
    chans = [Channel(k, tuple(cols[k]), data[k]) for k in names]
    return Log(times, chans, {"controller": controller.name, "controller_state": None, **(meta or {}), **extra})


def _spread(jax, carry, xs, B):
    """The scan's carry and per-tick inputs spread over the devices (:mod:`.jax_devices`): the
    batch padded to a multiple of the device count with copies of the last world (cut from
    the results), its axis sharded."""
    size = jax_devices.chunk_size(jax, B, B)
    pad = size - B
    arrays = {f"carry{q}": a for q, a in enumerate(carry)}
    arrays.update(xs)
    axes = {"carry0": 0, "carry1": 1, "carry2": 0, "carry3": 0, "carry4": 0, "noise": 1, "dropped": 1}
    for key in ("c", "cd", "rd"):  # (T, B or 1, k): one reference for all worlds is replicated
        if key in xs and xs[key].shape[1] == B and B > 1:
            axes[key] = 1
    for key, axis in axes.items():
        if pad and key in arrays:
            a = np.asarray(arrays[key])
            arrays[key] = np.concatenate([a, np.repeat(np.take(a, [-1], axis=axis), pad, axis=axis)], axis=axis)
    arrays = jax_devices.place(jax, arrays, axes)
    return tuple(arrays.pop(f"carry{q}") for q in range(len(carry))), arrays


def initial_carry(x, delay):
    """``(x, past, last, fail_tick, reason)``: the state, the outputs of the last ``d + 1`` ticks
    (all ``y0``), the last reading, and each world's failure (tick -1, reason 0: none); NumPy
    or JAX arrays like ``x`` (``(B, n_x)``)."""
    xp = namespace(x)
    B = x.shape[0]
    return (x, xp.broadcast_to(x, (delay + 1,) + x.shape), x, xp.full(B, -1, dtype=xp.int64),
            xp.zeros(B, dtype=xp.int64))


def hold(a):
    """``a`` (``(B, k)``) computed once: ``a @ I``.

    XLA's CPU fusion recomputes a chain of cheap operations inside every fused loop that
    consumes it (each of a stage's output components recomputes the stages before it: the
    compiled tick of the quaternion controller held about 4 950 fused operations against
    the 1 052 of its jaxpr). ``optimization_barrier`` does not stop it on the CPU; a ``dot``
    is not fused, so its operand is computed once. The product is exact for finite values
    (``a_ik 1 + sum of +-0``), except that ``-0.0`` becomes ``+0.0``.
    """
    import jax.numpy as jnp

    return a @ jnp.eye(a.shape[-1], dtype=a.dtype)


def tick_function(plant, controller, dt, substeps, delay, noisy, lossy, aligned):
    """One control tick on JAX arrays: ``(carry, xs_k) -> (carry, (x, m, u, c, err, finite))``."""
    import jax.numpy as jnp

    F, team = controller.formation, controller.team
    L = team.layout
    i, j = L.pairs

    def tick(carry, xs):
        x, past, last, fail_tick, reason = carry

        def stage(comps):  # a stage's component tuple, materialised once (hold)
            a = hold(jnp.stack(jnp.broadcast_arrays(*[jnp.broadcast_to(v, x.shape[:1]) for v in comps]), axis=-1))
            return tuple(a[:, q] for q in range(a.shape[-1]))
        past = jnp.concatenate([past[1:], x[None]], axis=0) if delay else x[None]
        m = past[0]  # y(t_{k-d}); y0 before the first tick (TickMeasurement)
        if noisy:
            m = m + xs["noise"]
        if lossy:
            m = jnp.where(xs["dropped"][:, None], last, m)
        last = m
        c_des, c_dot_des = (jnp.broadcast_to(a, (x.shape[0], a.shape[-1])) for a in (xs["c"], xs["cd"]))
        r = F.align(m, xs["rd"]) if aligned else m
        r = hold(r)
        c, err, r_dot = (jnp.broadcast_to(kern.pack(v), (x.shape[0], F.n_c if k < 2 else F.n_r))
                         for k, v in enumerate(controller.chain(r, c_des, c_dot_des, stage=stage)))
        r_dot = hold(r_dot)
        finite = jnp.all(jnp.isfinite(r_dot), axis=-1, keepdims=True)
        u = hold(team.saturate(r_dot))
        # what update() refuses: a non-finite measured state, robots on each other
        p = L.positions(r)
        d = p[:, i, :] - p[:, j, :]
        close = jnp.any(jnp.sum(d * d, axis=-1) <= MIN_SEPARATION_M * MIN_SEPARATION_M, axis=-1)
        bad_m = ~jnp.all(jnp.isfinite(m) & (jnp.abs(m) <= MAX_MAGNITUDE), axis=-1)
        code = jnp.where(bad_m, 1, jnp.where(close, 2, 0))
        new = (reason == 0) & (code > 0)
        fail_tick = jnp.where(new, jnp.asarray(xs["k"], dtype=fail_tick.dtype), fail_tick)
        reason = jnp.where(new, code, reason)
        x_next = x
        for s in range(substeps):
            x_next = plant.step(x_next, u, dt, xs["t"] + s * dt)
        bad = (reason > 0)[:, None]  # a failed world is frozen: its state held, commands 0, signals NaN
        x_next = jnp.where(bad, x, x_next)
        u = jnp.where(bad, 0.0, u)
        c, err, finite = (jnp.where(bad, jnp.nan, v.astype(x.dtype)) for v in (c, err, finite))
        new_carry = (x_next, past, last, fail_tick, reason)
        if "valid" in xs:  # a padded tick past the run's end (progress chunks) changes nothing
            new_carry = tuple(jnp.where(xs["valid"], a, b) for a, b in zip(new_carry, carry))
        return new_carry, (x, m, u, c, err, finite)

    return tick


def config_key(plant, controller) -> tuple:
    """What a compiled tick depends on, as a hashable value: the controller's class, its
    formation's class (the pair descriptions hold no parameters), its law (gains), team,
    feed-forward and checks, and the plant's team. Two experiments with equal configurations
    (a sweep's chunks, a benchmark's repeats) share one compilation."""
    return (type(controller), type(controller.formation), controller.law, controller.team, controller.feedforward,
            controller.checks, type(plant), plant.team)


#: Compiled scans of recent configurations and steps, newest last (:func:`config_key`).
_CACHE: dict = {}
_CACHE_SIZE = 8


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


def _compiled_scan(jax, plant, controller, *key):
    """``jax.jit`` of ``lax.scan`` of :func:`tick_function` (``.compiled`` of the tick), cached."""

    def build():
        tick = tick_function(plant, controller, *key)
        tick.compiled = jax.jit(lambda carry, xs: jax.lax.scan(tick, carry, xs)[::-1])
        return tick

    return cached(_CACHE, (config_key(plant, controller), *key), build)


def _scan(jax, tick, carry, xs, n, progress):
    """``lax.scan`` of ``tick`` over the ``n`` ticks of ``xs`` (one compiled call, or ten
    chunks of one shape when ``progress`` is given), the batch spread over the devices
    (:func:`_spread`): ``(ys, carry)``, the batch padded as :func:`_spread` pads it."""
    xs = dict(xs, k=np.arange(n, dtype=np.int64))
    run = tick.compiled
    B = carry[0].shape[0]
    if progress is None:
        carry, xs = _spread(jax, carry, xs, B)
        ys, carry = run(carry, xs)
        return ys, carry
    size = -(-n // 10)
    xs["valid"] = np.ones(n, dtype=bool)
    pad = {k: np.concatenate([v, np.repeat(v[-1:] if k != "valid" else ~v[-1:], 10 * size - n, axis=0)])
           for k, v in xs.items()}
    carry, pad = _spread(jax, carry, pad, B)
    parts = []
    for chunk in range(10):
        take = min(size, n - chunk * size)
        if take <= 0:
            break
        ys, carry = run(carry, {k: v[chunk * size:(chunk + 1) * size] for k, v in pad.items()})
        parts.append([np.asarray(y)[:take] for y in ys])
        progress((chunk * size + take) / n)
    ys = [np.concatenate([p[q] for p in parts]) for q in range(len(parts[0]))]
    return ys, carry
