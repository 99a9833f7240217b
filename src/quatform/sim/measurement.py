"""Measurement models of the closed loop (:mod:`quatform.sim.loop`): what a controller reads of the plant.

Sim layer. A measurement model is pure, as the loop's other parts are: ``columns`` (names of
what it reads, or None for the plant's outputs); ``schedule(times, dt, substeps, batch)``,
everything that does not depend on the plant's states (each world's noise, latency, lost
frames), drawn up front on the host as arrays with a leading tick axis; ``init(y0, batch,
schedule)``, its state before the first tick; ``observe(state, y, j)`` after plant step ``j``
of a tick and ``read(state, xs)`` -> ``(state, measured)`` at a tick (``xs`` the tick's
slice of the schedule), both on any array namespace (NumPy, JAX under ``jax.jit``):

* :class:`PerfectMeasurement` - the plant's output, exactly and at once;
* :class:`MotionCapture` - seed 001 §3.2: the lab's motion capture of a Pioneer and a
  Bebop (rate, noise, latency, dropouts, glitches) and the Bebop's own odometry;
* :class:`LatencyHistory` - values by time, with which :meth:`MotionCapture.schedule`
  finds the plant step a frame reads.

:class:`~quatform.sim.trial_measurement.TickMeasurement` (batched trials) is the third.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..algebra import q_from_axis_angle
from ..algebra.kernels import common_namespace
from ..errors import InvalidInputError
from ..formations import geometry as g
from ..robots.pioneer_bebop import MOCAP_PART, ODOMETRY_PART, PSI_B, PSI_P, UAV_XYZ, UGV_UAV_MEASURED_NAMES, UGV_XY

__all__ = ["LatencyHistory", "MotionCapture", "PerfectMeasurement"]


class PerfectMeasurement:
    """The plant's output, exactly and at once (its state: the last output)."""

    columns = None

    def schedule(self, times, dt: float, substeps: int, batch: tuple = ()) -> dict:
        return {}

    def init(self, y0, batch: tuple = (), schedule: dict | None = None):
        return y0

    def observe(self, state, y, j: int):
        return y

    def read(self, state, xs: dict):
        return state, state


def _width(entries: slice) -> int:
    """How many entries a slice of consecutive ones picks."""
    return entries.stop - entries.start


#: A frame's pose: the motion capture's part of the Pioneer-Bebop state (its first entries, so
#: a pose's entries are the state's: ``UGV_XY``, ``PSI_P``, ``UAV_XYZ``, ``PSI_B``).
_N_POSE = _width(MOCAP_PART)
#: A frame's position noise: the UGV's ``(x, y)``, then the UAV's ``(x, y, z)``, m.
_NOISE_UGV = slice(0, _width(UGV_XY))
_NOISE_UAV = slice(_NOISE_UGV.stop, _NOISE_UGV.stop + _width(UAV_XYZ))
_N_NOISE = _NOISE_UAV.stop


class LatencyHistory:
    """Plant outputs by time, kept for ``horizon_s`` seconds (at least two samples).

    Parameters
    ----------
    horizon_s : float
        How far back, s, :meth:`at` may be asked.
    """

    def __init__(self, horizon_s: float):
        self.horizon = float(horizon_s)
        self.t: list[float] = []
        self.x: list[np.ndarray] = []

    def add(self, t: float, x) -> None:
        """Record the output ``x`` at time ``t`` (s, not decreasing); forget what is older than the horizon."""
        self.t.append(t)
        self.x.append(x)
        while len(self.t) > 2 and self.t[1] < t - self.horizon:
            self.t.pop(0)
            self.x.pop(0)

    def at(self, t: float):
        """The latest output at or before ``t`` (the oldest kept before that)."""
        i = bisect.bisect_right(self.t, t + 1e-12) - 1
        return self.x[max(i, 0)]


class MotionCapture:
    """Seed 001 §3.2: the lab's measurements of the two robots.

    Poses come from the motion-capture system at ``rate_hz``, ``latency_s`` old, each
    position coordinate with Gaussian noise of ``noise_m``, the orientation as a quaternion
    (rotated by a random angle of standard deviation ``noise_rad``) from which the yaw is
    read; the Bebop's body velocity comes from its own odometry every ``odometry_period_s``
    (200 ms). :meth:`read` returns the controller's 11 values
    (:data:`~quatform.robots.pioneer_bebop.UGV_UAV_MEASURED_NAMES`) from the plant's output, the
    same 11 values of :class:`quatform.sim.plants.ugv_uav.PioneerBebopPlant`. Faults for
    testing: each frame is lost (all NaN) with probability ``dropout_rate``, or else reads the
    UAV's marker at the UGV (at height ``ugv_z``) with ``glitch_rate``.

    The random streams of a world are seeded by ``seed`` (the noise) and ``[seed, 1]`` (the
    faults), so the noise is the same with and without faults; world ``i`` of a batch reads
    with ``seed + i`` (:meth:`schedule`). The object holds settings only: one model serves any
    number of runs.
    """

    columns = UGV_UAV_MEASURED_NAMES

    def __init__(self, rate_hz=100.0, noise_m=0.0, noise_rad=0.0, latency_s=0.0, odometry_period_s=0.2,
                 seed=0, dropout_rate=0.0, glitch_rate=0.0, ugv_z=0.0):
        if not (rate_hz > 0 and noise_m >= 0 and noise_rad >= 0 and latency_s >= 0 and odometry_period_s > 0
                and 0 <= dropout_rate < 1 and 0 <= glitch_rate < 1):
            raise InvalidInputError("motion capture: rate_hz, odometry_period_s > 0, noise, latency >= 0 and "
                                    "dropout_rate, glitch_rate in [0, 1)")
        self.rate, self.noise_m, self.noise_rad = rate_hz, noise_m, noise_rad
        self.latency, self.odo = latency_s, odometry_period_s
        self.seed = seed
        self.dropout_rate, self.glitch_rate, self.ugv_z = dropout_rate, glitch_rate, ugv_z

    @staticmethod
    def _streams(seed):
        """The random streams of a world of ``seed``: the noise's and, apart, the faults'."""
        return np.random.default_rng(seed), np.random.default_rng([seed, 1])

    # -- the measurement contract (quatform.sim.loop) ---------------------------------
    def init(self, y0, batch: tuple = (), schedule: dict | None = None) -> dict:
        """The measurement state before the first tick: ``hist`` ``(*batch, L, 11)``, the plant
        outputs of the last ``L`` plant steps (oldest first, all ``y0``; ``L`` the farthest
        step back that ``schedule`` reads, plus one) and ``pose`` ``(*batch, 7)``, the last
        frame's pose (NaN: none yet)."""
        y0 = np.asarray(y0, dtype=float)
        offsets = [np.max(schedule[k], initial=0) for k in ("pose_off", "odo_off")] if schedule else [0]
        length = int(max(offsets)) + 1
        hist = np.broadcast_to(y0[..., None, :], tuple(batch) + (length, y0.shape[-1])).copy()
        return {"hist": hist, "pose": np.full(tuple(batch) + (_N_POSE,), np.nan)}

    def observe(self, state: dict, y, j: int) -> dict:
        """``state`` with the plant output ``y`` (``(*batch, 11)``) after a plant step appended
        to its ring of the last plant steps (any array namespace)."""
        xp = common_namespace(state["hist"], y)
        hist = state["hist"]
        return {"hist": xp.concatenate([hist[..., 1:, :], y[..., None, :]], axis=-2), "pose": state["pose"]}

    def read(self, state: dict, xs: dict):
        """``(state, measured)`` at a control tick: a new frame (where the tick's ``xs["new"]``)
        of the plant output ``xs["pose_off"]`` plant steps back with its draws
        (:meth:`frame_pose`), else the last frame's pose, and the odometry of the output
        ``xs["odo_off"]`` steps back; ``measured`` ``(*batch, 11)`` (:data:`UGV_UAV_MEASURED_NAMES`).
        Pure and branch-free (NumPy, JAX under ``jax.jit``)."""
        hist = state["hist"]
        xp = common_namespace(hist, xs["noise"])
        length, width = hist.shape[-2], hist.shape[-1]

        def back(off):  # the output ``off`` steps before the newest, (*batch, 11)
            idx = xp.broadcast_to(xp.asarray(length - 1 - off)[..., None, None], hist.shape[:-2] + (1, width))
            return xp.take_along_axis(hist, idx, axis=-2)[..., 0, :]

        fresh = self.frame_pose(back(xs["pose_off"]), xs["noise"], xs.get("turns"), xs["lost"], xs["glitched"])
        pose = xp.where(xp.asarray(xs["new"])[..., None], fresh, state["pose"])
        m = xp.concatenate([pose, back(xs["odo_off"])[..., ODOMETRY_PART]], axis=-1)
        return {"hist": hist, "pose": pose}, m

    def _frame_time(self, t: float) -> float:
        """Time of the motion-capture frame available at ``t``, s (frames every ``1 / rate_hz``)."""
        return math.floor(t * self.rate + 1e-9) / self.rate

    def _odometry_time(self, t: float) -> float:
        """Time of the Bebop's odometry sample available at ``t``, s."""
        return math.floor(t / self.odo + 1e-9) * self.odo

    def _draw(self, rng, fault_rng):
        """One frame's random draws from the streams ``rng``, ``fault_rng`` (:meth:`_streams`), in
        the order of their streams: ``(noise (5,), turns, lost,
        glitched)``: the position noise, the two orientations' noise rotations (unit
        quaternions ``(2, 4)``, or None without orientation noise), whether the frame is lost
        and whether it reads the UAV's marker at the UGV."""
        noise = rng.normal(0.0, self.noise_m, _N_NOISE) if self.noise_m > 0 else np.zeros(_N_NOISE)
        turns = None
        if self.noise_rad > 0:
            turns = []
            for _ in range(2):  # the UGV's heading, then the UAV's
                axis = rng.normal(size=3)
                turns.append(q_from_axis_angle(axis / np.linalg.norm(axis), rng.normal(0.0, self.noise_rad)))
            turns = np.stack(turns)
        lost = self.dropout_rate > 0 and fault_rng.random() < self.dropout_rate
        glitched = not lost and self.glitch_rate > 0 and fault_rng.random() < self.glitch_rate
        return noise, turns, lost, glitched

    def frame_pose(self, x, noise, turns, lost, glitched):
        """The 7 pose values (``MOCAP_PART``) of a frame of the plant output ``x`` (``(..., 11)``)
        with its draws (:meth:`_draw`; leading axes as ``x``'s, ``turns`` ``(..., 2, 4)`` or None), on any
        array namespace (NumPy, JAX under ``jax.jit``): the positions plus the noise, the yaws
        read from the noise-rotated quaternions; all NaN where the frame is lost, the UAV's
        position read at the UGV (at ``ugv_z``) where it is glitched."""
        xp = common_namespace(x, noise, lost, glitched, turns)
        pose = xp.concatenate([x[..., UGV_XY] + noise[..., _NOISE_UGV], self._orientation(x[..., PSI_P], turns, 0),
                               x[..., UAV_XYZ] + noise[..., _NOISE_UAV], self._orientation(x[..., PSI_B], turns, 1)],
                              axis=-1)
        ugv_point = xp.concatenate([pose[..., UGV_XY], xp.full(np.shape(pose)[:-1] + (1,), float(self.ugv_z))],
                                   axis=-1)
        at_ugv = xp.concatenate([pose[..., :UAV_XYZ.start], ugv_point, pose[..., UAV_XYZ.stop:]],
                                axis=-1)  # the UAV's marker read at the UGV
        pose = xp.where(xp.asarray(glitched)[..., None], at_ugv, pose)
        return xp.where(xp.asarray(lost)[..., None], np.nan, pose)  # a lost frame

    @staticmethod
    def _orientation(psi, turns, i):
        """The yaw ``(..., 1)`` read from the quaternion of ``psi`` (``(...)``) turned by ``turns[..., i, :]``."""
        q = g.q_yaw(psi)
        if turns is not None:
            q = g.mul(turns[..., i, :], q)
        yaw = g.yaw_of(q)  # the lab receives a quaternion; the controllers need the yaw
        return common_namespace(q).asarray(yaw)[..., None]

    def schedule(self, times, dt: float, substeps: int, batch: tuple = ()) -> dict:
        """What :meth:`read` does at each control tick of a run of :mod:`quatform.sim.loop`
        (ticks ``times``, ``substeps`` plant steps of ``dt`` between them), which does not
        depend on the plant's states, drawn up front. World ``i`` of the batch (flat index)
        draws from the streams of ``seed + i`` (:meth:`_draw`'s order), so a batch of one world
        reads what one world of ``seed`` reads.

        Returns
        -------
        dict
            Each ``(T, *batch, ...)``: ``new`` bool, a new frame at the tick; ``pose_off``,
            ``odo_off`` int, how many plant steps before the tick's newest output (the one at
            the tick) the frame and the odometry read; ``noise`` ``(T, *batch, 5)``,
            ``turns`` ``(T, *batch, 2, 4)`` (only with orientation noise), ``lost``,
            ``glitched`` bool: the draws of each new frame (zeros elsewhere).
        """
        times = np.asarray(times, dtype=float)
        n = times.size
        batch = tuple(batch)
        steps = LatencyHistory(self.latency + self.odo + 1.0)  # the plant steps by time, as the outputs are kept
        new = np.zeros(n, dtype=bool)
        pose_off, odo_off = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        frame = None
        if n:
            steps.add(float(times[0]), 0)
        for k in range(n):
            t = float(times[k])
            frame_t = self._frame_time(t)
            if frame_t != frame:
                new[k], frame = True, frame_t
                pose_off[k] = k * substeps - steps.at(frame_t - self.latency)
            odo_off[k] = k * substeps - steps.at(self._odometry_time(t))
            for j in range(substeps):
                steps.add(t + (j + 1) * dt, k * substeps + j + 1)
        frames = np.flatnonzero(new)
        worlds = max(1, int(np.prod(batch, dtype=np.int64)))
        noise = np.zeros((n, worlds, _N_NOISE))
        turns = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (n, worlds, 2, 1)) if self.noise_rad > 0 else None
        lost, glitched = np.zeros((n, worlds), dtype=bool), np.zeros((n, worlds), dtype=bool)
        for i in range(worlds):
            rng, fault_rng = self._streams(self.seed + i)
            for k in frames:
                noise[k, i], turn, lost[k, i], glitched[k, i] = self._draw(rng, fault_rng)
                if turns is not None:
                    turns[k, i] = turn

        def shaped(a, tail=()):
            return a.reshape((n,) + batch + tail)

        out = {"new": np.broadcast_to(new.reshape((n,) + (1,) * len(batch)), (n,) + batch).copy(),
               "pose_off": np.broadcast_to(pose_off.reshape((n,) + (1,) * len(batch)), (n,) + batch).copy(),
               "odo_off": np.broadcast_to(odo_off.reshape((n,) + (1,) * len(batch)), (n,) + batch).copy(),
               "noise": shaped(noise, (_N_NOISE,)), "lost": shaped(lost), "glitched": shaped(glitched)}
        if turns is not None:
            out["turns"] = shaped(turns, (2, 4))
        return out
