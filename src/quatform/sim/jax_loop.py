"""The pair and team kinds' closed loop on JAX, kept while their controllers are not ``pure`` (sim layer).

:func:`quatform.sim.loop.legacy_jax` hands a run here that the one loop's JAX driver
(:func:`quatform.sim.loop.simulate_jax`) cannot run yet, its controller having no pure
``tick``; this module goes once they have. :func:`simulate` has
:func:`quatform.sim.simulate`'s signature and returns the same
:class:`~quatform.sim.log.Log`; it runs the same kernels (``pip install -e ".[jax]"``):

* the controller's chain without its value checks
  (:meth:`~quatform.control.cluster.ClusterController.chain`: the formation's forward
  kinematics, the law of :mod:`quatform.control.laws`, the rate map), the measured yaws
  wound onto the reference's (:meth:`~quatform.formations.base.Formation.align`), the team's
  actuation, saturation and step (:class:`~quatform.robots.Team` and its robot models) -
  component arithmetic that runs on NumPy and on JAX arrays alike
  (:func:`quatform.algebra.kernels.namespace`);
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
kinematic holonomic robots) and the team kind's four team controllers (quaternion,
dual-quaternion of shape ``"frame"``, cluster-space, robot-space:
:meth:`~quatform.control.team.TeamController.chain`), bare or in a
:class:`~quatform.control.safety.SafeController`, on kinematic robots of
:data:`JAX_TEAM_ROBOTS` in any mix: 4-DOF and planar holonomic robots and free bodies (a team
of them shares one limit factor) and Pioneers offering ``xy_yaw`` points (their state; seed
001 eq. (3.5) actuation, each robot then saturated on its own, as
:meth:`~quatform.control.team.TeamController.update` does); anything else is refused in one
line naming what runs here.

The separation barrier: on JAX each tick solves
:class:`~quatform.control.safety.SeparationBarrier`'s programme in the compiled tick for a
team of 4-DOF and planar holonomic robots with one common limit factor
(:mod:`.jax_barrier`: the ``K`` pairs nearest to binding as candidates, Lawson and Hanson's
NNLS on their Gram matrix in a bounded loop, every pair checked at the solution, the common
limit factor), with its signals ``min_separation`` and ``safety_active``; where no pair
binds the commands pass bitwise. For other teams (Pioneers, free bodies) each tick computes
every pair's constraint (with the robots' point velocities of
:data:`~quatform.control.safety.POINT_MAPS`, :func:`point_velocities`, for robots whose
commands are not their points' rates): where no pair binds that is the whole filter. A
world where the programme binds and is not solved on JAX (another team; more binding pairs
than ``K``, no convergence, an infeasible programme), or whose robots start closer than the
barrier's minimum (which ``SafeController`` refuses), is rerun on NumPy from its start, with
its own initial state, measurement draws and reference, and its channels and failure
replace the JAX run's; ``log.meta["numpy_worlds"]`` (bool, the batch shape) says which,
when any.
"""

from __future__ import annotations

import math
from collections.abc import Callable
import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.validate import as_array
from ..control.base import Reference
from ..control.cluster import ClusterController
from ..control.safety import POINT_MAPS, SafeController, start_floor
from ..control.team import TeamController
from ..errors import (
    DegenerateInputError,
    InvalidInputError,
    ShapeError,
)
from ..formations import (
    DualQuaternionPair,
    DualQuaternionTeam,
    EuclideanPair,
    EuclideanTeam,
    QuaternionPair,
    QuaternionTeam,
    RobotSpace,
    RobotSpaceTeam,
)
from ..formations import pair_kernels as kern
from ..formations.base import MAX_MAGNITUDE, MIN_SEPARATION_M, check_magnitude
from ..formations.team_chart import team_positions
from ..robots import FreeBodyRobot, HolonomicRobot, Pioneer, PlanarHolonomicRobot
from ..control import barrier as jax_barrier
from . import loop
from .log import Channel, Log
from .loop import WORLD_ERRORS, cached, require_jax
from .measurement import PerfectMeasurement
from .plants import KinematicTeam
from .trial_measurement import TickMeasurement

__all__ = [
    "FAILURE_REASONS",
    "JAX_FORMATIONS",
    "JAX_TEAM_FORMATIONS",
    "JAX_TEAM_ROBOTS",
    "cached",
    "check_supported",
    "check_ticks",
    "config_key",
    "LOOP_AXES",
    "hold",
    "initial_carry",
    "initial_states",
    "point_velocities",
    "scan_ticks",
    "simulate",
    "stack_reference",
    "team_parts",
    "team_tick_function",
    "tick_function",
]

#: Formation descriptions whose controllers run on JAX (seed 000's pair descriptions).
JAX_FORMATIONS = (QuaternionPair, DualQuaternionPair, EuclideanPair, RobotSpace)
#: Team descriptions whose :class:`~quatform.control.team.TeamController` runs on JAX.
JAX_TEAM_FORMATIONS = (QuaternionTeam, DualQuaternionTeam, EuclideanTeam, RobotSpaceTeam)
#: Robot models of a team that runs on JAX (kinematic; a Pioneer offering its state, ``xy_yaw``),
#: in any mix, with one common limit factor or each robot saturated on its own.
JAX_TEAM_ROBOTS = (HolonomicRobot, PlanarHolonomicRobot, Pioneer, FreeBodyRobot)
#: What the backend runs, for the one-line refusal of anything else.
_RUNS = ("the jax backend runs the seed-000 pair experiments (its four controllers on kinematic holonomic robots) "
         "and the team kind's four team controllers (quaternion, dual-quaternion of shape 'frame', cluster-space, "
         "robot-space; with or without the separation barrier) on kinematic robots (4-DOF, planar, free-body, "
         "Pioneer offering 'xy_yaw'; any mix), perfect or TickMeasurement measurement")
#: Reason of a failed world, by code (0: none). Code 3 is no failure: the world is rerun on
#: NumPy (:func:`simulate`), whose log replaces it.
FAILURE_REASONS = {1: "the measured robot state is not finite (or beyond 1e150)",
                   2: f"the measured robots coincide (closer than {MIN_SEPARATION_M:g} m): a "
                      "formation is undefined there",
                   3: "the separation barrier's programme is not solved on JAX (it runs on the host)"}
#: Failure code of a world whose separation barrier JAX does not solve (rerun on NumPy).
_HOST = 3


def team_parts(controller):
    """``(team controller, barrier or None)`` of a team experiment's controller (a
    :class:`~quatform.control.team.TeamController`, bare or in a
    :class:`~quatform.control.safety.SafeController`), else None."""
    if isinstance(controller, SafeController) and isinstance(controller.inner, TeamController):
        return controller.inner, controller.barrier
    if isinstance(controller, TeamController):
        return controller, None
    return None


def check_supported(plant, controller, measurement) -> None:
    """Refuse (one line, naming what runs here) what the jax backend does not run."""
    parts = team_parts(controller)
    if parts is not None:
        inner, _ = parts
        if not isinstance(inner.formation, JAX_TEAM_FORMATIONS):
            raise InvalidInputError(f"{_RUNS}; the {inner.name} team controller ({type(inner.formation).__name__}) "
                                    "runs on numpy (--compute numpy)")
        if isinstance(inner.formation, DualQuaternionTeam) and inner.formation.shape != "frame":
            raise InvalidInputError(f"{_RUNS}; DualQuaternionTeam(shape={inner.formation.shape!r}) runs on numpy "
                                    "(--compute numpy)")
        team = inner.team
        if controller.team != team:
            raise InvalidInputError(f"{_RUNS}; a SafeController over another team than its controller's runs on "
                                    "numpy (--compute numpy)")
        if not (isinstance(plant, KinematicTeam) and plant.team == team
                and all(type(r) in JAX_TEAM_ROBOTS for r in team.robots)):
            models = sorted({type(r).__name__ for r in team.robots})
            raise InvalidInputError(f"{_RUNS}; the plant {type(plant).__name__} of {', '.join(models)} robots runs on "
                                    "numpy (--compute numpy)")
        if any(type(r) is Pioneer and r.point_kind != "xy_yaw" for r in team.robots):  # the loop measures states
            raise InvalidInputError(f"{_RUNS}; a Pioneer of point_kind = 'xyz' runs on numpy (--compute numpy)")
        if measurement is not None and type(measurement) not in (PerfectMeasurement, TickMeasurement):
            raise InvalidInputError(f"{_RUNS}; the measurement {type(measurement).__name__} runs on numpy "
                                    "(--compute numpy)")
        return
    if not isinstance(controller, ClusterController) or not isinstance(controller.formation, JAX_FORMATIONS):
        raise InvalidInputError(f"{_RUNS}; {type(controller).__name__} runs on numpy (--compute numpy)")
    if controller.filters:
        raise InvalidInputError(f"{_RUNS}; a controller with filters runs on numpy (--compute numpy)")
    team = controller.team
    if not (isinstance(plant, KinematicTeam) and plant.team == team and team.common_limit
            and all(type(r) is HolonomicRobot for r in team.robots)):
        raise InvalidInputError(f"{_RUNS}; the plant {type(plant).__name__} runs on numpy (--compute numpy)")
    if measurement is not None and type(measurement) not in (PerfectMeasurement, TickMeasurement):
        raise InvalidInputError(f"{_RUNS}; the measurement {type(measurement).__name__} runs on numpy "
                                "(--compute numpy)")


def check_ticks(times, substeps, dt):
    """Checked ``(times, dt)`` (:func:`quatform.sim.loop.check_ticks`; at least one tick)."""
    times, dt = loop.check_ticks(times, substeps, dt, "jax simulate")
    if times.size < 1:
        raise ShapeError(f"jax simulate: times must have shape (T,) with T >= 1, got {times.shape}")
    return times, dt


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
    x, batch, B = initial_states(plant, x0)
    parts = team_parts(controller)
    c_ref, cd_ref, r_ref = stack_reference(controller if parts is None else parts[0], reference, n, batch)
    tick = TickMeasurement() if measurement is None or isinstance(measurement, PerfectMeasurement) else measurement
    tick.check(plant.output(x), batch, n)  # the shape checks of the measurement
    noise = None if tick.noise is None else tick.noise[:n].reshape(n, B, -1)
    dropped = None if tick.dropped is None else tick.dropped[:n].reshape(n, B)
    step = _compiled_scan(jax, plant, controller, dt, substeps, tick.delay_ticks, noise is not None,
                          dropped is not None, r_ref is not None)
    xs = {"t": times, "c": c_ref, "cd": cd_ref}
    for key, arr in (("rd", r_ref), ("noise", noise), ("dropped", dropped)):
        if arr is not None:
            xs[key] = arr
    with jax.enable_x64(True):
        # the last chunk's progress is told when the run is complete (after any NumPy reruns)
        held = None if progress is None else (lambda f: progress(f) if f < 1.0 else None)
        ys, carry = scan_ticks(jax, step, initial_carry(x.reshape(B, -1), tick.delay_ticks), xs, n, held)
    names = ("state", "measured", "command", "cluster", "error", "raw_finite")
    if parts is not None and parts[1] is not None:
        names += ("min_separation", "safety_active")
    data = {k: np.asarray(v)[:, :B].reshape((n,) + batch + (v.shape[-1],)) for k, v in zip(names, ys)}
    fail_tick, reason = (np.array(a)[:B].reshape(batch) for a in carry[3:5])
    extra = {}
    host_failure = {}
    if np.any(reason == _HOST):  # barriers JAX did not solve: those worlds' runs are NumPy's
        host_failure = _rerun_on_host(plant, controller, times, x, dt, substeps, tick, noise, dropped,
                                      (c_ref, cd_ref, r_ref), reason == _HOST, data, names, meta)
        extra["numpy_worlds"] = reason == _HOST
        reason[reason == _HOST] = 0
    if progress is not None:
        progress(1.0)
    if np.any(reason > 0) or host_failure:
        worlds = list(zip(*np.nonzero(reason))) if batch else [()]  # one world: its reason raised
        failure = {tuple(int(i) for i in idx): _failure_reason(controller, times, data["measured"], fail_tick, reason,
                                                               (c_ref, cd_ref, r_ref), tuple(int(i) for i in idx))
                   for idx in worlds}
        failure.update(host_failure)
        failed = reason > 0
        for idx in host_failure:
            failed[idx] = True
        extra.update(failed=failed, failure=dict(sorted(failure.items())))
    out_cols = tick.columns if tick.columns is not None else plant.output_columns
    cols = {"state": plant.state_columns, "measured": out_cols, "command": controller.command_names,
            **controller.signal_columns()}
    chans = [Channel(k, tuple(cols[k]), data[k]) for k in names]
    return Log(times, chans, {"controller": controller.name, "controller_state": None, **(meta or {}), **extra})


def _failure_reason(controller, times, measured, fail_tick, reason, refs, idx):
    """NumPy's reason for world ``idx``'s failure: ``controller.update`` at its failing tick on
    its measured state, as :func:`quatform.sim.simulate` calls it on one world, gives the
    same one-line message (``"t = ... s: ..."``); a run of one world raises it, as there.
    :data:`FAILURE_REASONS` where that call does not refuse (a test of the compiled tick
    that the host does not make the same way)."""
    k = int(fail_tick[idx])
    flat = int(np.ravel_multi_index(idx, fail_tick.shape)) if idx else 0
    c, cd, rd = (None if a is None else a[k, flat if a.shape[1] > 1 else 0] for a in refs)
    try:
        controller.update(float(times[k]), measured[(k, *idx)], Reference(c, cd, rd), controller.init(()))
    except WORLD_ERRORS as own:
        if not idx:
            raise
        return f"t = {times[k]:g} s: " + " ".join(str(own).split())
    text = FAILURE_REASONS[int(reason[idx])]
    if not idx:
        raise (DegenerateInputError if int(reason) == 2 else InvalidInputError)(
            f"jax simulate: at t = {times[k]:g} s {text}")
    return f"t = {times[k]:g} s: {text}"


#: Batch axis of each slot of the pair and team ticks' carry (:func:`initial_carry`) and of
#: their per-tick inputs beyond the references (whose axis is 1 when they hold one per world).
LOOP_AXES = ((0, 1, 0, 0, 0), {"noise": 1, "dropped": 1})


def _rerun_on_host(plant, controller, times, x, dt, substeps, tick, noise, dropped, refs, host, data, names, meta):
    """Run the worlds ``host`` (bool, the batch shape) on NumPy (:func:`quatform.sim.simulate`:
    their separation barrier's programme is not solved on JAX, or their robots start too
    close for it) with their own initial states, measurement draws and references, and write
    their channels into ``data``; their failures (world index tuple -> reason) are returned."""
    from .simulate import simulate as numpy_simulate

    batch = host.shape
    n = times.size
    sel = np.flatnonzero(host.reshape(-1))
    pick = [np.asarray(a)[:, sel if a.shape[1] > 1 else np.zeros(sel.size, dtype=np.intp)] if a is not None else None
            for a in refs]

    def reference(k):
        return Reference(pick[0][k], pick[1][k], None if pick[2] is None else pick[2][k])

    if not batch:  # one world: NumPy's run as it is (it raises where that world fails)
        sel = slice(None)
        pick = [None if a is None else np.asarray(a)[:, 0] for a in refs]
    measurement = TickMeasurement(None if noise is None else noise[:, sel][:, 0] if not batch else noise[:, sel],
                                  tick.delay_ticks, None if dropped is None else
                                  dropped[:, 0] if not batch else dropped[:, sel], columns=tick.columns)
    x_host = x if not batch else x.reshape(-1, x.shape[-1])[sel]
    log = numpy_simulate(plant, controller, reference, times, x_host, dt=dt, substeps=substeps,
                         measurement=measurement, meta=meta)
    for k in names:
        flat = np.array(data[k]).reshape((n, -1, data[k].shape[-1]))
        flat[:, sel] = log[k].reshape((n, -1, data[k].shape[-1]))
        data[k] = flat.reshape(data[k].shape)
    out = {}
    for local, reason in log.meta.get("failure", {}).items():
        idx = np.unravel_index(int(sel[local[0]]), batch)
        out[tuple(int(i) for i in idx)] = reason
    return out


def initial_states(plant, x0):
    """``(x, batch, B)``: the initial states ``x0`` as a float array of shape ``(*batch, n_x)``
    for ``plant``, the batch shape and the number of worlds (at least one; one-line errors)."""
    x = np.array(x0, dtype=float)
    if x.shape[-1:] != (len(plant.state_columns),):
        raise ShapeError(f"jax simulate: x0 must have shape (*batch, {len(plant.state_columns)}), got {x.shape}")
    batch = x.shape[:-1]
    B = math.prod(batch)
    if B == 0:
        raise ShapeError(f"jax simulate: x0 of shape {x.shape} holds no world; give at least one")
    return x, batch, B


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


def _measure(xs, x, past, last, delay, noisy, lossy):
    """The tick's reading (:class:`~quatform.sim.trial_measurement.TickMeasurement` on JAX
    arrays): ``(past, m)``, the outputs of the last ``delay + 1`` ticks and ``m = y(t_{k-d})``
    (``y0`` before the first tick) plus the tick's noise, the last reading where the frame
    is dropped."""
    import jax.numpy as jnp

    past = jnp.concatenate([past[1:], x[None]], axis=0) if delay else x[None]
    m = past[0]
    if noisy:
        m = m + xs["noise"]
    if lossy:
        m = jnp.where(xs["dropped"][:, None], last, m)
    return past, m


def _end_tick(plant, dt, substeps, xs, carry, state, code, u, signals):
    """The end of a compiled tick (pair and team): a world's first failure ``code`` (> 0)
    recorded, the plant stepped ``substeps`` times, a failed world frozen (its state held,
    its commands 0, its ``signals`` NaN), a padded tick past the run's end (progress chunks)
    changing nothing. ``state`` is ``(x, past, last, fail_tick, reason)`` of this tick, ``carry``
    the tick's input: ``(new_carry, u, signals)``."""
    import jax.numpy as jnp

    x, past, last, fail_tick, reason = state
    new = (reason == 0) & (code > 0)
    fail_tick = jnp.where(new, jnp.asarray(xs["k"], dtype=fail_tick.dtype), fail_tick)
    reason = jnp.where(new, code, reason)
    x_next = x
    for s in range(substeps):
        x_next = plant.step(x_next, u, dt, xs["t"] + s * dt)
    bad = (reason > 0)[:, None]
    x_next = jnp.where(bad, x, x_next)
    u = jnp.where(bad, 0.0, u)
    signals = tuple(jnp.where(bad, jnp.nan, v.astype(x.dtype)) for v in signals)
    new_carry = (x_next, past, last, fail_tick, reason)
    if "valid" in xs:
        new_carry = tuple(jnp.where(xs["valid"], a, b) for a, b in zip(new_carry, carry))
    return new_carry, u, signals


def tick_function(plant, controller, dt, substeps, delay, noisy, lossy, aligned):
    """One control tick on JAX arrays: ``(carry, xs_k) -> (carry, (x, m, u, c, err, finite))``
    (a team controller in a :class:`~quatform.control.safety.SafeController`: also
    ``min_separation`` and ``safety_active``, :func:`team_tick_function`)."""
    import jax.numpy as jnp

    if team_parts(controller) is not None:
        return team_tick_function(plant, controller, dt, substeps, delay, noisy, lossy, aligned)
    F, team = controller.formation, controller.team
    L = team.layout
    i, j = L.pairs
    apart = not isinstance(F, RobotSpace)  # robot space is defined with the robots on each other

    def tick(carry, xs):
        x, past, last, fail_tick, reason = carry

        def stage(comps):  # a stage's component tuple, materialised once (hold)
            a = hold(jnp.stack(jnp.broadcast_arrays(*[jnp.broadcast_to(v, x.shape[:1]) for v in comps]), axis=-1))
            return tuple(a[:, q] for q in range(a.shape[-1]))
        past, m = _measure(xs, x, past, last, delay, noisy, lossy)
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
        close = jnp.any(jnp.sum(d * d, axis=-1) <= MIN_SEPARATION_M * MIN_SEPARATION_M, axis=-1) & apart
        bad_m = ~jnp.all(jnp.isfinite(m) & (jnp.abs(m) <= MAX_MAGNITUDE), axis=-1)
        code = jnp.where(bad_m, 1, jnp.where(close, 2, 0))
        new_carry, u, out = _end_tick(plant, dt, substeps, xs, carry, (x, past, last, fail_tick, reason), code, u,
                                      (c, err, finite))
        return new_carry, (x, m, u) + out

    return tick


def team_tick_function(plant, controller, dt, substeps, delay, noisy, lossy, aligned):
    """One control tick of a team experiment on JAX arrays: ``(carry, xs_k) -> (carry, (x, m,
    u, c, err, finite[, min_separation, safety_active]))``.

    The chain of :meth:`~quatform.control.team.TeamController.chain`, the team's saturation
    and step; what :meth:`~quatform.control.team.TeamController.update` refuses (a measured
    state not finite or beyond 1e150, two robots closer than ``MIN_SEPARATION_M``, every pair
    of the layout) marks the world failed. With a separation barrier
    (:class:`~quatform.control.safety.SeparationBarrier`): its filter on JAX
    (:func:`.jax_barrier.barrier_filter`, a team it runs: :func:`.jax_barrier.solves`; other
    teams: the test whether any pair binds), its minimum separation over every pair and
    whether it changed the commands; a world whose programme binds and is not solved exactly
    on JAX, or whose robots start closer than the barrier's minimum, is marked with code 3
    and rerun on NumPy (:func:`simulate`).
    """
    import jax.numpy as jnp

    inner, barrier = team_parts(controller)
    F, team = inner.formation, inner.team
    L = team.layout
    i, j = L.pairs

    def tick(carry, xs):
        x, past, last, fail_tick, reason = carry
        B = x.shape[0]

        def stage(a):  # an array materialised once (hold)
            return hold(jnp.broadcast_to(a, (B,) + a.shape[-1:]))
        past, m = _measure(xs, x, past, last, delay, noisy, lossy)
        last = m
        c_des, c_dot_des = (jnp.broadcast_to(a, (B, a.shape[-1])) for a in (xs["c"], xs["cd"]))
        r = hold(F.align(m, xs["rd"]) if aligned else m)
        c, err, r_dot = inner.chain(r, c_des, c_dot_des, stage=stage)
        c, err, r_dot = (jnp.broadcast_to(v, (B, v.shape[-1])) for v in (c, err, r_dot))
        r_dot = hold(r_dot)
        # TeamController.update: the robots' actuation (of a fresh memory), a non-finite command
        # stopping the team, the saturation (a common-limit team's factor is 0 there already)
        u = r_dot if team.passthrough else team.actuate(r, r_dot, xs["t"], team.initial_memory((B,)))[0]
        finite = jnp.all(jnp.isfinite(u), axis=-1, keepdims=True)
        u = hold(team.saturate(u if team.common_limit else jnp.where(finite, u, 0.0)))
        # what update() refuses: a non-finite measured state, robots on each other
        p = team_positions(L, r)
        d = p[:, i, :] - p[:, j, :]
        dist = jnp.sqrt(jnp.sum(d * d, axis=-1))  # (B, pairs)
        close = jnp.any(dist < MIN_SEPARATION_M, axis=-1)
        bad_m = ~jnp.all(jnp.isfinite(m) & (jnp.abs(m) <= MAX_MAGNITUDE), axis=-1)
        code = jnp.where(bad_m, 1, jnp.where(close, 2, 0))
        signals = ()
        if barrier is not None and jax_barrier.solves(team):  # SeparationBarrier.filter on JAX (jax_barrier)
            u, sep, active, solved = jax_barrier.barrier_filter(barrier, team, m, u, (reason == 0) & (code == 0))
        elif barrier is not None:  # SeparationBarrier.filter where no pair binds: u itself; where one does: NumPy's
            P = team_positions(L, m)
            V = team_positions(L, u) if team.passthrough else point_velocities(barrier, team, m, u)
            _, sep, _, _, _, active = jax_barrier.pair_constraints(barrier, L, P, V)
            solved = ~active
        if barrier is not None:
            floor = start_floor(team_positions(L, m), barrier.min_separation_m)  # SafeController._check_start
            start = (xs["k"] == 0) & jnp.any(sep < floor, axis=-1)
            code = jnp.where(start, _HOST, jnp.where(code > 0, code, jnp.where(solved, 0, _HOST)))
            signals = (jnp.min(sep, axis=-1, keepdims=True), active[:, None])
        new_carry, u, out = _end_tick(plant, dt, substeps, xs, carry, (x, past, last, fail_tick, reason), code, u,
                                      (c, err, finite) + signals)
        return new_carry, (x, m, u) + out

    return tick


def point_velocities(barrier, team, x, u):
    """The robots' point velocities, m/s, ``(B, N, 3)``, at the measured state ``x`` for the
    team's commands ``u`` (``(B, n_state)`` and ``(B, n)``), as
    :meth:`~quatform.control.safety.SeparationBarrier.filter` reads them
    (:data:`~quatform.control.safety.POINT_MAPS`: a Pioneer's mean control-point velocity over
    the barrier's ``dt_s``, seed 001 eq. (3.4); a free body's linear velocity)."""
    import jax.numpy as jnp

    parts, robots = [], []
    for g, xg, ug in zip(team.groups, team.gather(x), team.gather(u, "command")):
        v = POINT_MAPS[type(g.model)].velocity(g.model, xg, ug, barrier.dt_s)
        parts.append(v if g.axis else v[..., None, :])
        robots.extend(g.robots)
    V = jnp.concatenate(parts, axis=-2) if len(parts) > 1 else parts[0]
    return V if robots == sorted(robots) else V[..., np.argsort(robots), :]


def config_key(plant, controller) -> tuple:
    """What a compiled tick depends on, as a hashable value: the controller's class, its
    formation's class (the pair descriptions hold no parameters), its law (gains), team,
    feed-forward and checks, the plant's team and a barrier's candidate count
    (:data:`.jax_barrier.CANDIDATES`). Two experiments with equal configurations (a sweep's
    chunks, a benchmark's repeats) share one compilation."""
    parts = team_parts(controller)
    if parts is not None:  # a team description holds its layout and template; the gains are a dict
        inner, barrier = parts
        F = inner.formation
        gains = tuple(sorted((k, tuple(np.ravel(v).tolist())) for k, v in inner.gains.items()))
        return (type(controller), type(F), F.layout, np.asarray(F.template).tobytes(), gains, inner.team,
                inner.feedforward, barrier, type(plant), plant.team,
                None if barrier is None else jax_barrier.CANDIDATES)
    return (type(controller), type(controller.formation), controller.law, controller.team, controller.feedforward,
            controller.checks, type(plant), plant.team)


#: Compiled scans of recent configurations and steps, newest last (:func:`config_key`).
_CACHE: dict = {}


def _compiled_scan(jax, plant, controller, *key):
    """``jax.jit`` of ``lax.scan`` of :func:`tick_function` (``.compiled`` of the tick), cached."""

    def build():
        tick = tick_function(plant, controller, *key)
        tick.compiled = jax.jit(lambda carry, xs: jax.lax.scan(tick, carry, xs)[::-1])
        return tick

    return cached(_CACHE, (config_key(plant, controller), *key), build)


def scan_ticks(jax, tick, carry, xs, n, progress, axes=LOOP_AXES):
    """:func:`quatform.sim.loop.scan_ticks` of ``tick.compiled`` (the jitted scan of ``tick``)
    for a carry whose slots are arrays (or dicts of arrays with the batch axis first) and
    per-tick inputs named in ``axes`` (:data:`LOOP_AXES`); the references ``c``, ``cd``,
    ``rd`` of shape ``(T, B or 1, k)`` are split when they hold one per world."""
    B = jax.tree_util.tree_leaves(carry)[0].shape[0]
    carry_axes, named = axes
    leaf_axes = [axis for slot, axis in zip(carry, carry_axes) for _ in jax.tree_util.tree_leaves(slot)]
    xs_axes = {k: 1 if k in ("c", "cd", "rd") and v.shape[1] == B and B > 1 else named.get(k, -1)
               for k, v in xs.items()}
    return loop.scan_ticks(jax, tick.compiled, carry, xs, n, progress, B, leaf_axes, xs_axes)
