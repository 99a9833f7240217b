"""The learning environments' one functional core: ``reset(key, params)`` and ``step(key, state, action, params)``.

Envs layer (beside runs and cli, above scenarios). A :class:`FormationCore` is built from a
scenario (a team file, seed 000's pair files through it, or a network file) and runs the
simulator's own tick (:func:`quatform.sim.loop.make_tick`) on the array namespace of its
operands: the same function steps one NumPy world, a batch of NumPy worlds on leading axes,
and JAX worlds under ``jax.jit`` and ``jax.vmap``. The policy's action reaches the tick
through its reference input: :class:`ActionController` wraps the scenario's controller and
reads ``(reference, action)``; with a zero residual its commands are the scenario
controller's own, so an episode equals :meth:`~quatform.scenarios.base.Experiment.run`'s
states bitwise (``docs/envs.md``).

Randomness (the start's perturbation, the measurement noise) comes from ``key``, a
``uint32`` array ``(*batch, 2)`` (the layout of ``jax.random.PRNGKey``), through a
counter-based hash written on the array namespace (:func:`normal`): NumPy and JAX draw the
same numbers from the same key.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, NamedTuple

import numpy as np

from ..algebra.kernels import common_namespace
from ..checks import nearest, short
from ..control.contract import Controller, Tick
from ..control.safety import SafeController
from ..errors import InvalidInputError, NonFiniteError, ShapeError
from ..formations.team_chart import team_positions
from ..scenarios import kind_of, load_scenario
from ..sim.loop import START_CODE, make_tick, plant_inputs, scheduled_reference, tree_map
from ..sim.measurement import PerfectMeasurement

__all__ = ["ACTION_MODES", "OBS_BOUND", "ActionController", "EnvParams", "EnvState", "FormationCore", "NoisyReading",
           "functional", "host_action", "key", "normal", "split"]

#: What an action is: a residual added to the scenario controller's commands, or the commands.
ACTION_MODES = ("residual", "velocity")
#: Every observation entry lies in ``[-OBS_BOUND, OBS_BOUND]`` (m, rad, 1): clipped there.
OBS_BOUND = 1e4
#: The largest ``residual_scale``: a residual of twice a command's limit moves the saturated
#: sum from any base command to either limit, so a larger one only adds overflow.
MAX_RESIDUAL_SCALE = 2.0
#: The options of :func:`functional` besides ``scenario``, ``controller`` and ``action``.
OPTIONS = ("residual_scale", "noise_m", "noise_rad", "start_noise_m", "weights", "separation_m", "collision_m",
           "loss_m", "loss_penalty", "duration_s", "min_separation")


# --------------------------------------------------------------------------- randomness

_M1, _M2 = 0x7FEB352D, 0x846CA68B  # lowbias32 (C. Wellons, "Prospecting for hash functions", 2018)
_GOLDEN = 0x9E3779B9


def _hash32(xp, x):
    """Wellons' ``lowbias32`` integer hash of ``uint32`` ``x`` (wrapping products), any namespace."""
    x = x ^ (x >> 16)
    x = x * xp.asarray(_M1, dtype=xp.uint32)
    x = x ^ (x >> 15)
    x = x * xp.asarray(_M2, dtype=xp.uint32)
    return x ^ (x >> 16)


def _bits(key, stream: int, n: int):
    """``(*batch, n)`` ``uint32`` hashes of ``key`` ``(*batch, 2)``, the stream and the counter
    ``0..n-1``: two words of the key and stream, each mixing both key words, offset the counter
    and mask its hash (no two keys' sequences overlap but by a 2^-64 chance)."""
    xp = common_namespace(key)
    key = xp.asarray(key, dtype=xp.uint32)
    k0, k1 = key[..., 0:1], key[..., 1:2]
    s1 = xp.asarray((stream * 2 * _GOLDEN + 1) & 0xFFFFFFFF, dtype=xp.uint32)
    s2 = xp.asarray((stream * 2 * _GOLDEN + 2 * _GOLDEN) & 0xFFFFFFFF, dtype=xp.uint32)
    b1 = _hash32(xp, k0 ^ _hash32(xp, k1 ^ s1))
    b2 = _hash32(xp, k1 ^ _hash32(xp, k0 ^ s2))
    return _hash32(xp, _hash32(xp, xp.arange(n, dtype=xp.uint32) + b1) ^ b2)


def _unit(xp, hi, lo):
    """Floats in ``[0, 1)`` of 53 random bits: 27 of ``hi``, 26 of ``lo`` (``uint32``)."""
    return (xp.asarray(hi >> 5, dtype=xp.float64) * 67108864.0 + xp.asarray(lo >> 6, dtype=xp.float64)) \
        / 9007199254740992.0


def normal(key, stream: int, n: int):
    """``(*batch, n)`` standard normal draws of ``key`` (``uint32 (*batch, 2)``) and ``stream``
    (Box and Muller 1958: ``sqrt(-2 ln u1) cos(2 pi u2)`` of two 53-bit uniforms), the same on
    NumPy and JAX."""
    xp = common_namespace(key)
    w = _bits(key, stream, 4 * n)
    u1 = 1.0 - _unit(xp, w[..., 0:n], w[..., n:2 * n])  # (0, 1]: its logarithm is finite
    u2 = _unit(xp, w[..., 2 * n:3 * n], w[..., 3 * n:])
    return xp.sqrt(-2.0 * xp.log(u1)) * xp.cos(2.0 * math.pi * u2)


def key(seed: int) -> np.ndarray:
    """The key ``uint32 (2,)`` of a whole-number ``seed`` (the words of ``jax.random.PRNGKey(seed)``)."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or not 0 <= int(seed) < 2 ** 64:
        raise InvalidInputError(f"envs: a seed is a whole number in [0, 2**64), got {seed!r}")
    seed = int(seed)
    return np.array([seed >> 32, seed & 0xFFFFFFFF], dtype=np.uint32)


def split(key, num: int = 2):
    """``num`` new keys ``(num, *batch, 2)`` of ``key`` ``(*batch, 2)`` (any namespace)."""
    xp = common_namespace(key)
    words = _bits(key, 0x5EED, 2 * num)
    words = xp.reshape(words, words.shape[:-1] + (num, 2))
    return xp.moveaxis(words, -2, 0)


# --------------------------------------------------------------------------- the action in the tick

@dataclasses.dataclass(frozen=True)
class ActionController(Controller):
    """The scenario's controller ``base`` with the policy's action: the loop's controller of an env.

    The tick's reference is ``(base reference arrays, action)``; the action ``(*batch, n_u)``,
    in the commands' units (the env scales the policy's ``[-1, 1]`` by ``params.action_scale``), is

    * ``"residual"``: added to ``base``'s commands, the sum saturated by the team's limits; a
      world whose action is all zero takes ``base``'s commands as they are (bitwise);
    * ``"velocity"``: the commands themselves, saturated.

    ``base`` ticks in both modes (its state, signals and failure codes are the loop's). Where
    ``base`` is :class:`~quatform.control.safety.SafeController` (the team kind's separation
    barrier), the action acts on its inner controller's nominal commands and the barrier
    filters the result (:meth:`SafeController.shield`): a policy cannot drive robots through
    the barrier's distance.
    """

    base: Controller
    team: Any
    mode: str = "residual"

    def __post_init__(self):
        if self.mode not in ACTION_MODES:
            raise InvalidInputError(f"envs: action = {self.mode!r}; choose one of {', '.join(ACTION_MODES)}")

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def command_names(self) -> tuple[str, ...]:
        return self.base.command_names

    def signal_columns(self) -> dict:
        return self.base.signal_columns()

    @property
    def pure(self) -> bool:
        return self.base.pure

    @property
    def failure_reasons(self):
        return self.base.failure_reasons

    def init(self, batch: tuple = ()):
        return self.base.init(batch)

    def reference_arrays(self, reference):
        """``base``'s (the env adds the action at each tick)."""
        return self.base.reference_arrays(reference)

    def update(self, t, measured, reference, state):
        raise InvalidInputError("envs: ActionController runs through its pure tick only")

    @property
    def shielded(self) -> bool:
        """Whether ``base`` filters its nominal commands through the team's separation barrier
        (:class:`~quatform.control.safety.SafeController`): the action then joins the nominal
        commands before the barrier, which filters the policy's commands too."""
        return isinstance(self.base, SafeController)

    def tick(self, state, measured, reference, t) -> Tick:
        ref, action = reference
        base = self.base
        out = base.inner.tick(state.inner, measured, ref, t) if self.shielded else base.tick(state, measured, ref, t)
        xp = common_namespace(measured, out.u, action)
        a = xp.asarray(action, dtype=xp.float64)
        if self.mode == "velocity":
            u = self.team.saturate(xp.broadcast_to(a, out.u.shape))
        else:
            zero = xp.all(a == 0.0, axis=-1, keepdims=True)
            u = xp.where(zero, out.u, self.team.saturate(out.u + a))
        out = Tick(out.state, u, out.signals, out.code)
        return base.shield(state, measured, out) if self.shielded else out


class NoisyReading(PerfectMeasurement):
    """A measurement model: the plant's output plus the tick's ``noise`` (``xs["noise"]``,
    drawn by the env from its key), at once; its state is the last output."""

    def read(self, state, xs: dict):
        return state, state + xs["noise"]


# --------------------------------------------------------------------------- params and state

class EnvParams(NamedTuple):
    """What an episode reads (a pytree of arrays: ``jax.jit`` traces it, ``jax.vmap`` maps it
    with ``in_axes=None``). Shapes for ``T`` control ticks, ``n_x`` plant states, ``n_m``
    measured values, ``n_u`` commands, ``n_r`` robot points, ``n_c`` chart variables.

    Attributes
    ----------
    refs : pytree, leaves ``(T, ...)``
        The controller's reference arrays of every tick.
    times : (T,)
        Control ticks, s.
    x0 : (n_x,)
        Initial plant state (the scenario's start).
    r_des : (T, n_r)
        Desired robot points.
    c_des : (T, n_c)
        Desired cluster state of the description (``n_c = 0`` for a network scenario).
    action_scale : (n_u,)
        Units of an action entry of 1 (m/s, rad/s ...).
    noise_std : (n_m,)
        Standard deviation of the measurement noise of each measured value.
    start_std : (n_x,)
        Standard deviation of the start's perturbation of each state entry.
    weights : (3,)
        Reward weights ``(tracking, effort, separation)``.
    separation_m : ()
        Distance below which a pair is penalised, m.
    collision_m : ()
        Distance below which a pair has collided (termination), m.
    loss_m : ()
        Root-mean-square position error beyond which the formation is lost (termination), m.
    loss_penalty : ()
        Reward of a step that ends in a failure of the loop or a non-finite state.
    """

    refs: Any
    times: Any
    x0: Any
    r_des: Any
    c_des: Any
    action_scale: Any
    noise_std: Any
    start_std: Any
    weights: Any
    separation_m: Any
    collision_m: Any
    loss_m: Any
    loss_penalty: Any


class EnvState(NamedTuple):
    """An episode's state, leading axes the batch.

    Attributes
    ----------
    x : (*batch, n_x)
        Plant state.
    ctrl, meas : pytree
        The controller's and the measurement model's states.
    fail_tick, reason : (*batch,) int64
        The loop's failing tick (-1: none) and reason code (0: none).
    k : (*batch,) int64
        The next control tick.
    noise : (*batch, n_m)
        The noise of the next tick's reading.
    """

    x: Any
    ctrl: Any
    meas: Any
    fail_tick: Any
    reason: Any
    k: Any
    noise: Any


# --------------------------------------------------------------------------- the core

def _probe_limits(team, n_u: int) -> np.ndarray:
    """The largest command each column alone takes through the team's saturation (``(n_u,)``)."""
    big = 1e6 * np.eye(n_u)
    lim = np.abs(np.diagonal(np.asarray(team.saturate(big), dtype=float)))
    return np.where(lim > 0, lim, 1.0)


class FormationCore:
    """The functional environment of one scenario and controller (module docstring).

    Build it with :func:`functional`. ``reset`` and ``step`` are pure functions of their
    arguments (this object is configuration only).

    Observation ``(n_obs,)`` float64, in order: the description's chart error ``e`` (``n_c``:
    :meth:`~quatform.formations.base.Formation.errors` of its forward map of the measured
    robots against the reference's cluster state: centroid, attitude, shape and headings in the
    description's variables; none for a network scenario), the robots' error against their
    desired points (``n_r``, yaws wound), the measured robots (``n_r``) and the episode's
    elapsed fraction (1). Non-finite entries read 0; every entry is clipped to
    ``[-OBS_BOUND, OBS_BOUND]``.
    """

    def __init__(self, experiment, action: str = "residual", residual_scale: float = 0.25,
                 noise_m: float = 0.0, noise_rad: float = 0.0, start_noise_m: float = 0.0,
                 weights=(1.0, 0.01, 10.0), separation_m: float | None = None, collision_m: float | None = None,
                 loss_m: float = 10.0, loss_penalty: float = 100.0, duration_s: float | None = None):
        ex = experiment
        self.experiment = ex
        _check_options(noise_m=noise_m, noise_rad=noise_rad, start_noise_m=start_noise_m, loss_penalty=loss_penalty)
        if duration_s is not None:
            _check_options(positive=True, duration_s=duration_s)
            if duration_s > float(ex.times[-1]) + 1e-9 * ex.dt:
                raise InvalidInputError(f"envs: duration_s = {duration_s!r} is beyond the scenario's "
                                        f"{float(ex.times[-1]):g} s; give at most that (or a longer scenario)")
        _check_options(positive=True, residual_scale=residual_scale, loss_m=loss_m,
                       **{k: v for k, v in (("separation_m", separation_m), ("collision_m", collision_m))
                          if v is not None})
        if residual_scale > MAX_RESIDUAL_SCALE:
            raise InvalidInputError(f"envs: residual_scale = {residual_scale!r} must be at most {MAX_RESIDUAL_SCALE:g} "
                                    "(a residual of twice the limits already spans every saturated command)")
        w = np.asarray(weights, dtype=float) if np.ndim(weights) == 1 else np.full(0, np.nan)
        if w.shape != (3,) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise InvalidInputError(f"envs: weights = {weights!r} must be three finite numbers >= 0 (tracking, "
                                    "effort, separation)")
        base = ex.controller
        team = getattr(base, "team", None) or getattr(ex.plant, "team", None)
        if team is None or not getattr(base, "pure", False) or not getattr(ex.plant, "batchable", False):
            raise InvalidInputError(f"envs: {ex.label} needs a pure controller, a batchable plant and a team of robots "
                                    "(the team and network scenarios on kinematic physics)")
        if ex.measurement is not None:
            raise InvalidInputError("envs: the scenario's measurement model is the env's own (noise_m, noise_rad)")
        if plant_inputs(ex.plant, ex.times[:1], ex.dt, ex.substeps) is not None:
            raise InvalidInputError("envs: a plant with exogenous inputs is not an env's")
        self.team, self.layout, self.plant = team, team.layout, ex.plant
        n_u = len(base.command_names)
        limits = _probe_limits(team, n_u)
        scale = limits if action == "velocity" else residual_scale * limits
        self.controller = ActionController(base, team, action)
        self.action_mode = action
        self.noisy = bool(noise_m > 0 or noise_rad > 0)
        self.measurement = NoisyReading() if self.noisy else PerfectMeasurement()
        self.dt, self.substeps = float(ex.dt), int(ex.substeps)
        times = np.asarray(ex.times, dtype=float)
        if duration_s is not None:
            times = times[times <= float(duration_s) + 1e-9 * ex.dt]
        if times.size < 2:
            raise InvalidInputError("envs: an episode needs at least two control ticks (raise duration_s)")
        self.T = int(times.size)
        self.tick = make_tick(self.plant, self.controller, self.measurement, self.dt, self.substeps)
        reference = scheduled_reference(base, ex.reference, times, ())
        refs = [base.reference_arrays(reference(k)) for k in range(self.T)]
        refs = tree_map(lambda *a: np.stack([np.asarray(v) for v in a]), refs[0], *refs[1:])
        x0 = np.asarray(ex.x0, dtype=float)
        y0 = np.asarray(self.plant.output(x0), dtype=float)
        self.n_x, self.n_m, self.n_u, self.n_r = x0.shape[-1], y0.shape[-1], n_u, self.layout.size
        inner = getattr(base, "inner", base)
        self.formation = getattr(inner, "formation", None)
        r_des, c_des = self._desired(ex, times)
        self.n_c = c_des.shape[-1]
        self.n_obs = self.n_c + 2 * self.n_r + 1
        yaw = np.zeros(self.n_m, dtype=bool)
        if self.n_m == self.n_r:
            yaw[list(self.layout.yaw_indices)] = True
        sep = separation_m
        if sep is None:
            safety = ex.meta.get("safety") or {}
            sep = float(safety.get("min_separation_m", 0.3)) if safety.get("enabled", True) else 0.3
        col = 0.5 * sep if collision_m is None else float(collision_m)
        start = np.zeros(self.n_x)
        if self.n_x == self.n_r:
            start[self.layout.position_index.ravel()[self.layout.position_index.ravel() < self.n_r]] = start_noise_m
        self.default_params = EnvParams(
            refs=refs, times=times, x0=x0, r_des=r_des, c_des=c_des, action_scale=scale,
            noise_std=np.where(yaw, noise_rad, noise_m).astype(float), start_std=start,
            weights=np.asarray(weights, dtype=float), separation_m=np.float64(sep), collision_m=np.float64(col),
            loss_m=np.float64(loss_m), loss_penalty=np.float64(loss_penalty))

    def _desired(self, ex, times):
        """``(r_des (T, n_r), c_des (T, n_c))`` of the experiment's reference."""
        T = times.size
        ref0 = ex.reference(0)
        if hasattr(ref0, "robots") and ref0.robots is not None:  # a team scenario's Reference
            r_des = np.stack([np.asarray(ex.reference(k).robots, dtype=float) for k in range(T)])
            c_des = np.stack([np.asarray(ex.reference(k).c, dtype=float) for k in range(T)])
            return r_des, c_des
        if isinstance(ref0, dict) and "robots" in ref0:  # a network scenario's
            return np.stack([np.asarray(ex.reference(k)["robots"], dtype=float) for k in range(T)]), np.zeros((T, 0))
        raise InvalidInputError(f"envs: the reference of {ex.label} names no desired robots")

    # -- the functional form ------------------------------------------------------------
    def reset(self, key, params: EnvParams):
        """``(obs, state)`` of a new episode: the scenario's start, perturbed by
        ``params.start_std`` (stream 0 of ``key``), and the first reading's noise (stream 1)."""
        xp = common_namespace(key, params.x0)
        _check_float64(xp)
        key = xp.asarray(key)
        batch = tuple(key.shape[:-1])
        x = params.x0 + params.start_std * normal(key, 0, self.n_x)
        x = xp.broadcast_to(x, batch + (self.n_x,))
        bad = ~xp.all(xp.isfinite(x), axis=-1)
        fail_tick = xp.where(bad, 0, -1).astype(xp.int64)
        reason = xp.where(bad, START_CODE, 0).astype(xp.int64)
        ctrl = tree_map(lambda a: xp.asarray(a), self.controller.init(batch))
        meas = self.measurement.init(self.plant.output(x), batch, {})
        noise = params.noise_std * normal(key, 1, self.n_m)
        state = EnvState(x, ctrl, meas, fail_tick, reason, xp.zeros(batch, dtype=xp.int64),
                         xp.broadcast_to(noise, batch + (self.n_m,)))
        return self.observe(state, params), state

    def step(self, key, state: EnvState, action, params: EnvParams):
        """``(obs, state, reward, terminated, truncated, info)`` of one control tick under
        ``action`` (``(*batch, n_u)`` in ``[-1, 1]``): the loop's tick
        (:func:`~quatform.sim.loop.make_tick`), then the next reading's noise from ``key``
        (stream 1), the observation, the reward and the episode's end (``docs/envs.md``).

        A world already at its last tick (``state.k == T - 1``: truncated) stays there: its
        state is returned unchanged, its commands read 0, ``truncated`` stays True and the
        elapsed fraction 1 (a batch of worlds steps on while some have ended)."""
        xp = common_namespace(key, state.x, action)
        _check_float64(xp)
        k = xp.minimum(state.k, self.T - 1)
        ref = tree_map(lambda a: xp.asarray(a)[k], params.refs)
        a, bad_action = self.action_commands(action, params)
        xs = {"k": k, "t": xp.asarray(params.times)[k], "ref": (ref, a),
              "meas": {"noise": state.noise} if self.noisy else {}, "plant": None}
        carry, ys = self.tick((state.x, state.ctrl, state.meas, state.fail_tick, state.reason), xs)
        # the next reading's noise, drawn only where a reading carries it (noise_m or noise_rad > 0)
        noise = (xp.broadcast_to(params.noise_std * normal(key, 1, self.n_m), state.noise.shape) if self.noisy
                 else state.noise)
        new = EnvState(*carry, state.k + 1, noise)
        past = state.k >= self.T - 1  # a world stepped past its last tick stays there, unchanged
        new = tree_map(lambda old, now: xp.where(_lead(xp, past, now), old, now), state, new)
        u = xp.where(past[..., None], 0.0, ys[2])
        obs = self.observe(new, params)
        reward, terminated, info = self.judge(new, u, params, bad_action)
        truncated = (new.k >= self.T - 1) & ~terminated
        return obs, new, reward, terminated, truncated, info

    def action_commands(self, action, params: EnvParams):
        """``(a (*batch, n_u), bad (*batch,))``: the policy's ``action`` in the commands' units.

        Each entry is clipped to ``[-1, 1]`` (an infinite entry is its limit) and scaled by
        ``params.action_scale``. A robot with a NaN entry takes no action this tick (its entries
        read 0: in ``"residual"`` mode the scenario controller's commands, in ``"velocity"``
        mode zero) and ``bad`` flags its world (the step ends it as lost, ``info["bad_action"]``);
        the other robots act as asked. The Gymnasium and PettingZoo envs refuse a non-finite
        action before it reaches the core (one-line :class:`~quatform.errors.NonFiniteError`).
        """
        xp = common_namespace(action, params.action_scale)
        a = xp.clip(xp.asarray(action, dtype=xp.float64), -1.0, 1.0)
        _, commands, owner = self._groups
        bad_robot = self._per_robot(xp.asarray(xp.isnan(a), dtype=xp.float64), commands) > 0.0
        bad = xp.take(bad_robot, xp.asarray(owner), axis=-1)
        return xp.where(bad, 0.0, a) * params.action_scale, xp.any(bad_robot, axis=-1)

    # -- what an episode reads --------------------------------------------------------------
    def desired(self, state: EnvState, params: EnvParams):
        """``(r_des (*batch, n_r), c_des (*batch, n_c))`` at the state's tick."""
        xp = common_namespace(state.x)
        k = xp.minimum(state.k, self.T - 1)
        return xp.asarray(params.r_des)[k], xp.asarray(params.c_des)[k]

    def measured(self, state: EnvState):
        """What the next tick reads: the plant's output plus the drawn noise, ``(*batch, n_m)``."""
        y = self.plant.output(state.x)
        return y + state.noise if self.noisy else y

    @functools.cached_property
    def _orientation(self):
        """``(flat (4M,), owner (n_r,))``: the entries of the pose robots' quaternions and, for
        every point entry, the quaternion it belongs to (``M``: none)."""
        rows = np.asarray(self.layout.orientation_index, dtype=np.intp).reshape(-1, 4)
        owner = np.full(self.n_r, rows.shape[0], dtype=np.intp)
        for j, row in enumerate(rows):
            owner[row] = j
        return rows.ravel(), owner

    def signed(self, m, r_des):
        """The robots ``m`` ``(*batch, n_r)`` with each pose robot's quaternion signed nearest
        its desired one in ``r_des`` (``q`` and ``-q`` are one attitude: the result is a
        function of the attitude); a quaternion exactly orthogonal to its desired one keeps its
        sign (``q . q_des < 0`` flips)."""
        flat, owner = self._orientation
        if not flat.size:
            return m
        xp = common_namespace(m, r_des)
        r_des = xp.broadcast_to(r_des, m.shape)
        q = xp.reshape(xp.take(m, xp.asarray(flat), axis=-1), m.shape[:-1] + (-1, 4))
        qd = xp.reshape(xp.take(r_des, xp.asarray(flat), axis=-1), m.shape[:-1] + (-1, 4))
        flip = xp.sum(q * qd, axis=-1) < 0.0
        flip = xp.concatenate([flip, xp.zeros(flip.shape[:-1] + (1,), dtype=bool)], axis=-1)
        return xp.where(xp.take(flip, xp.asarray(owner), axis=-1), -m, m)

    def robot_error(self, m, r_des):
        """The measured robots ``m`` minus their desired points ``(*batch, n_r)``, yaws wound
        to within pi, a pose robot's quaternion signed nearest its desired one
        (:meth:`signed`); 0 where not finite."""
        xp = common_namespace(m, r_des)
        r_des = xp.broadcast_to(r_des, m.shape)
        return _finite(xp, self.layout.wind(self.signed(m, r_des), r_des) - r_des)

    def chart_error(self, m, r_des, c_des):
        """The description's error ``(*batch, n_c)`` of its forward map of the measured robots
        ``m`` (wound onto ``r_des``) against ``c_des`` (:meth:`Formation.errors`: angles
        wrapped); 0 where not finite (robots on each other); ``(*batch, 0)`` for a network
        scenario."""
        xp = common_namespace(m, r_des)
        if self.n_c == 0:
            return xp.zeros(m.shape[:-1] + (0,))
        F = self.formation
        with np.errstate(all="ignore"):
            near = xp.broadcast_to(c_des, m.shape[:-1] + (self.n_c,))
            c = F.forward_arrays(F.align(m, xp.broadcast_to(r_des, m.shape)), near)
            return _finite(xp, F.errors(c, c_des))

    def observe(self, state: EnvState, params: EnvParams):
        """The observation ``(*batch, n_obs)`` (class docstring)."""
        xp = common_namespace(state.x)
        e_c, e_r, m, frac = self.observed(state, params)
        return bounded(xp, xp.concatenate([e_c, e_r, m, frac], axis=-1))

    def observed(self, state: EnvState, params: EnvParams, chart: bool = True):
        """What an observation reads: ``(e_c (*batch, n_c), e_r (*batch, n_r), m (*batch, n_r),
        frac (*batch, 1))``, the chart error (:meth:`chart_error`; ``(*batch, 0)`` unless
        ``chart``), the robots' errors (:meth:`robot_error`), the measured robots (each
        quaternion :meth:`signed`, 0 where not finite) and the elapsed fraction ``k / (T - 1)``."""
        xp = common_namespace(state.x)
        r_des, c_des = self.desired(state, params)
        m = self.signed(self.measured(state), r_des)
        e_c = self.chart_error(m, r_des, c_des) if chart else xp.zeros(m.shape[:-1] + (0,))
        frac = xp.asarray(state.k, dtype=xp.float64)[..., None] / (self.T - 1)
        return e_c, self.robot_error(m, r_des), _finite(xp, m), frac

    def separations(self, x):
        """``(*batch, N, N)`` distances between the robots' positions (``inf`` on the diagonal), m."""
        xp = common_namespace(x)
        p = team_positions(self.layout, self.plant.output(x))
        d2 = xp.sum((p[..., :, None, :] - p[..., None, :, :]) ** 2, axis=-1)
        eye = np.eye(self.layout.n, dtype=bool)
        return xp.where(eye, xp.inf, xp.sqrt(xp.where(eye, 1.0, d2)))

    @functools.cached_property
    def _groups(self):
        """``(points (N, K_r), commands (N, K_u), owner (n_u,))``: each robot's point entries and
        commands as indices, padded with the index one past the end (a padded 0 reads there),
        and the robot of each command."""
        L, team = self.layout, self.team

        def padded(slices, size):
            width = max(s.stop - s.start for s in slices)
            out = np.full((len(slices), width), size, dtype=np.intp)
            for i, s in enumerate(slices):
                out[i, :s.stop - s.start] = np.arange(s.start, s.stop)
            return out

        commands = padded(team.command_slices, self.n_u)
        owner = np.zeros(self.n_u, dtype=np.intp)
        for i, s in enumerate(team.command_slices):
            owner[s] = i
        return padded([L.slice(i) for i in range(L.n)], self.n_r), commands, owner

    def _per_robot(self, v, index):
        """``(*batch, N)``: the sum of ``v`` ``(*batch, n)`` over each robot's entries ``index``
        (:attr:`_groups`)."""
        xp = common_namespace(v)
        v = xp.concatenate([v, xp.zeros(v.shape[:-1] + (1,), dtype=v.dtype)], axis=-1)
        taken = xp.take(v, xp.asarray(index.ravel()), axis=-1)
        return xp.sum(xp.reshape(taken, v.shape[:-1] + index.shape), axis=-1)

    def robot_terms(self, state: EnvState, u, params: EnvParams):
        """Each robot's reward terms ``(tracking, effort, separation)``, each ``(*batch, N)``, and
        the robots' distances ``(*batch, N, N)`` (``docs/envs.md``): ``|e_i|^2`` of its error
        against its desired point (yaws wound, rad counted as m), ``|u_i|^2`` of its commands,
        ``sum_j max(0, d_sep - d_ij)^2 / 2``; of the true state, 0 where not finite."""
        xp = common_namespace(state.x, u)
        points, commands, _ = self._groups
        r_des, _ = self.desired(state, params)
        e_r = self.robot_error(_finite(xp, self.plant.output(state.x)), r_des)
        d = self.separations(_finite(xp, state.x))
        short = xp.maximum(params.separation_m - d, 0.0)  # the diagonal's inf: 0
        return (self._per_robot(e_r * e_r, points), self._per_robot(_finite(xp, u) ** 2, commands),
                0.5 * xp.sum(short * short, axis=-1), d, e_r)

    def judge(self, state: EnvState, u, params: EnvParams, bad_action=False):
        """``(reward, terminated, info)`` of the state a tick reached under the commands ``u``
        (``docs/envs.md``). Robot ``i``'s reward is ``-(w_t tracking_i + w_e effort_i + w_s
        separation_i)`` (:meth:`robot_terms`), ``-loss_penalty`` where the loop failed or the
        state is not finite; the env's reward is the robots' mean; ``info["robot_rewards"]``
        ``(*batch, N)`` holds each robot's (the PettingZoo agents'). The episode ends on a
        collision (two robots nearer than ``collision_m``) or a loss (the loop's failure code, a
        non-finite state, a NaN in the action (``bad_action``, :meth:`action_commands`), a
        root-mean-square position error beyond ``loss_m``)."""
        xp = common_namespace(state.x, u)
        N = self.layout.n
        tracking, effort, separation, d, e_r = self.robot_terms(state, u, params)
        failed = ~xp.all(xp.isfinite(state.x), axis=-1) | (state.reason != 0) | bad_action
        w = params.weights
        per = -(w[0] * tracking + w[1] * effort + w[2] * separation)
        per = xp.where(~failed[..., None] & xp.isfinite(per), per, -params.loss_penalty)
        min_sep = xp.min(xp.reshape(d, d.shape[:-2] + (-1,)), axis=-1)
        pos = self.layout.position_index.ravel()
        pos = pos[pos < self.n_r]
        rms = xp.sqrt(xp.sum(xp.take(e_r, xp.asarray(pos), axis=-1) ** 2, axis=-1) / N)
        collided = min_sep < params.collision_m
        lost = failed | (rms > params.loss_m)
        info = {"tracking": xp.sum(tracking, axis=-1) / N, "effort": xp.sum(effort, axis=-1) / N,
                "separation": xp.sum(separation, axis=-1) / N, "min_separation_m": min_sep,
                "position_rms_m": rms, "collided": collided, "lost": lost, "reason": state.reason, "commands": u,
                "robot_rewards": per, "bad_action": xp.broadcast_to(xp.asarray(bad_action), failed.shape)}
        return xp.sum(per, axis=-1) / N, collided | lost, info


class Rebuilt:
    """Pickling of an env by its constructor's arguments (``self._init``, ``(args, kwargs)``)
    and its episode's state (the attributes named in ``_episode``): unpickling builds the env
    again and restores that state, so an env pickles (a scenario's experiment holds closures
    that do not) and ``copy.deepcopy`` copies its attributes as they are."""

    _episode: tuple = ()

    def __getstate__(self) -> dict:
        out = {"_init": self._init, **{k: self.__dict__[k] for k in self._episode if k in self.__dict__}}
        if self.params is not self.core.default_params:
            out["params"] = self.params
        return out

    def __setstate__(self, state: dict) -> None:
        state = dict(state)
        args, kwargs = state.pop("_init")
        self.__init__(*args, **kwargs)
        self.__dict__.update(state)

    def __deepcopy__(self, memo):
        import copy

        new = object.__new__(type(self))
        memo[id(self)] = new
        new.__dict__.update(copy.deepcopy(self.__dict__, memo))
        return new


def _check_options(positive: bool = False, **values) -> None:
    """Refuse (one line) an option that is not a finite number ``>= 0`` (``> 0`` if ``positive``)."""
    for name, v in values.items():
        ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v) \
            and (v > 0 if positive else v >= 0)
        if not ok:
            raise InvalidInputError(f"envs: {name} = {v!r} must be a finite number {'>' if positive else '>='} 0")


def _check_float64(xp) -> None:
    """Refuse (one line) a namespace that computes in float32 (JAX without ``jax_enable_x64``):
    the core is the simulator's float64 tick."""
    if xp is not np and xp.asarray(0.0).dtype != np.float64:  # a float's default dtype: no warning
        raise InvalidInputError("envs: the functional core runs in float64; on JAX call it inside "
                                "jax.enable_x64(True) (or set jax.config.update('jax_enable_x64', True))")


def host_action(action, shape: tuple, where: str) -> np.ndarray:
    """The action of a host-side env as float64 ``shape``, or a one-line error: not numbers
    (:class:`InvalidInputError`), another shape (:class:`ShapeError`), a NaN or infinite entry
    (:class:`NonFiniteError`: a broken policy is refused, not stepped)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: the action must be numbers of shape {shape}, got {short(action)}") \
            from None
    if a.shape != tuple(shape):
        raise ShapeError(f"{where}: the action has shape {a.shape}; give an array of shape {tuple(shape)} in [-1, 1]")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{where}: the action holds NaN or infinity at entries "
                             f"{short(np.argwhere(~np.isfinite(a)).ravel().tolist())}; give finite numbers in [-1, 1]")
    return a


def _lead(xp, mask, a):
    """``mask`` ``(*batch,)`` with ``a``'s trailing axes as ones (to select whole worlds)."""
    return xp.reshape(mask, tuple(mask.shape) + (1,) * (xp.asarray(a).ndim - mask.ndim))


def bounded(xp, obs):
    """An observation's entries: 0 where not finite, clipped to ``[-OBS_BOUND, OBS_BOUND]``."""
    return xp.clip(_finite(xp, obs), -OBS_BOUND, OBS_BOUND)


def _finite(xp, a):
    return xp.where(xp.isfinite(a), a, 0.0)


def functional(scenario, controller: str | None = None, *, action: str = "residual", **options) -> FormationCore:
    """The functional environment of ``scenario`` (a built-in name, a TOML path or a loaded team
    or network scenario).

    Parameters
    ----------
    controller : str, optional
        The team kind's controller (default ``"quaternion"``); a network scenario's law (default:
        its own).
    action : {"residual", "velocity"}
        What the policy's action is (:class:`ActionController`).
    **options
        Of :class:`FormationCore`: ``residual_scale``, ``noise_m``, ``noise_rad``,
        ``start_noise_m``, ``weights``, ``separation_m``, ``collision_m``, ``loss_m``,
        ``loss_penalty``, ``duration_s`` (an episode shorter than the scenario's), and
        ``min_separation`` (the team kind's barrier, m; 0: off).
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise InvalidInputError(f"envs: unknown option {unknown[0]!r}{nearest(unknown[0], OPTIONS)}; the options are "
                                f"{', '.join(OPTIONS)} (docs/envs.md)")
    if controller is not None and not isinstance(controller, str):
        raise InvalidInputError(f"envs: controller = {short(controller)} must be a controller's name (a string), "
                                "e.g. 'quaternion'")
    sc = load_scenario(scenario) if isinstance(scenario, (str, bytes)) or hasattr(scenario, "__fspath__") \
        else scenario
    kind = kind_of(sc)
    build = {k: options.pop(k) for k in ("min_separation",) if k in options}
    if kind.name == "team":
        ex = kind.experiment(sc, controller=controller or "quaternion", **build)
    elif kind.name == "network":
        if build:
            raise InvalidInputError("envs: min_separation is an option of the team kind's scenarios")
        ex = kind.experiment(sc, law=controller)
    else:
        raise InvalidInputError(f"envs: {getattr(sc, 'name', sc)!r} is a {kind.name} scenario; the environments "
                                "run the team and network kinds")
    return FormationCore(ex, action=action, **options)
