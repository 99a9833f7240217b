"""Measurement models for :func:`quatform.sim.simulate`: what a controller reads of the plant.

Sim layer. A measurement model follows the contract of :mod:`quatform.sim.simulate`:
``columns`` (names of what ``read`` returns, or None for the plant's outputs),
``start(t0, y0, batch)`` before the first tick, ``observe(t, y)`` after every plant step
and ``read(t)`` at every control tick. :class:`PerfectMeasurement` (the plant's output at
once) lives beside ``simulate``; here are the models with a past:

* :class:`LatencyHistory` - the plant outputs by time, for measurements with latency;
* :class:`MotionCapture` - seed 001 §3.2: the lab's motion capture of a Pioneer and a
  Bebop (rate, noise, latency, dropouts, glitches) and the Bebop's own odometry.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..algebra import q_from_axis_angle
from ..algebra.kernels import common_namespace
from ..errors import InvalidInputError, ShapeError
from ..formations import geometry as g

__all__ = ["LatencyHistory", "MotionCapture", "MOTION_CAPTURE_COLUMNS"]

#: What :class:`MotionCapture` reads: the Pioneer's control point and heading, the Bebop's
#: pose (motion capture) and its body-frame velocity (its odometry); the 11 measured values
#: of :class:`quatform.control.UgvUavController`.
MOTION_CAPTURE_COLUMNS = ("x_p", "y_p", "psi_p", "x_b", "y_b", "z_b", "psi_b", "v_x_b", "v_y_b", "z_dot_b",
                          "psi_dot_b")


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
    (200 ms). :meth:`read` returns the controller's 11 values (:data:`MOTION_CAPTURE_COLUMNS`)
    from the plant's output, the 11-value state of
    :class:`quatform.sim.plants.ugv_uav.UgvUavPlant`. Faults for testing: each frame is lost
    (all NaN) with probability ``dropout_rate``, or else reads the UAV's marker at the UGV
    (at height ``ugv_z``) with ``glitch_rate``.

    One world at a time (``batch`` must be ``()``); the random streams are seeded by
    ``seed`` (the noise) and ``[seed, 1]`` (the faults), so the noise is the same with and
    without faults. :meth:`start` begins a run afresh (the same streams again), so one model
    serves any number of runs, one after the other.
    """

    columns = MOTION_CAPTURE_COLUMNS

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
        self._reset()

    def _reset(self) -> None:
        """Fresh random streams (the noise's and, apart, the faults') and no frames yet."""
        self.rng = np.random.default_rng(self.seed)
        self.fault_rng = np.random.default_rng([self.seed, 1])
        self.history = LatencyHistory(self.latency + self.odo + 1.0)
        self._frame_t, self._pose = None, None

    # -- the measurement contract -------------------------------------------------------
    def start(self, t0: float, y0, batch: tuple = ()) -> None:
        """The plant's output ``y0`` (11 values) at the first tick ``t0``, s."""
        if batch:
            raise ShapeError(f"MotionCapture measures one world at a time; got batch shape {batch}")
        self._reset()
        self.observe(t0, y0)

    def observe(self, t: float, y) -> None:
        """The plant's output ``y`` (11 values) at time ``t``, s."""
        self.history.add(t, np.array(y, dtype=float))

    def read(self, t: float) -> np.ndarray:
        """The 11 measured values available to the controller at ``t``, s."""
        frame_t = self._frame_time(t)
        if frame_t != self._frame_t:
            self._pose = self.frame_pose(self.history.at(frame_t - self.latency), *self._draw())
            self._frame_t = frame_t
        return np.r_[self._pose, self.history.at(self._odometry_time(t))[7:11]]

    def _frame_time(self, t: float) -> float:
        """Time of the motion-capture frame available at ``t``, s (frames every ``1 / rate_hz``)."""
        return math.floor(t * self.rate + 1e-9) / self.rate

    def _odometry_time(self, t: float) -> float:
        """Time of the Bebop's odometry sample available at ``t``, s."""
        return math.floor(t / self.odo + 1e-9) * self.odo

    def _draw(self):
        """One frame's random draws, in the order of their streams: ``(noise (5,), turns, lost,
        glitched)``: the position noise, the two orientations' noise rotations (unit
        quaternions ``(2, 4)``, or None without orientation noise), whether the frame is lost
        and whether it reads the UAV's marker at the UGV."""
        noise = self.rng.normal(0.0, self.noise_m, 5) if self.noise_m > 0 else np.zeros(5)
        turns = None
        if self.noise_rad > 0:
            turns = []
            for _ in range(2):  # the UGV's heading, then the UAV's
                axis = self.rng.normal(size=3)
                turns.append(q_from_axis_angle(axis / np.linalg.norm(axis), self.rng.normal(0.0, self.noise_rad)))
            turns = np.stack(turns)
        lost = self.dropout_rate > 0 and self.fault_rng.random() < self.dropout_rate
        glitched = not lost and self.glitch_rate > 0 and self.fault_rng.random() < self.glitch_rate
        return noise, turns, lost, glitched

    def frame_pose(self, x, noise, turns, lost, glitched):
        """The 7 pose values of a frame of the plant output ``x`` (``(..., 11)``) with its draws
        (:meth:`_draw`; leading axes as ``x``'s, ``turns`` ``(..., 2, 4)`` or None), on any
        array namespace (NumPy, JAX under ``jax.jit``): the positions plus the noise, the yaws
        read from the noise-rotated quaternions; all NaN where the frame is lost, the UAV's
        position read at the UGV (at ``ugv_z``) where it is glitched."""
        xp = common_namespace(x, noise, lost, glitched, turns)
        pose = xp.concatenate([x[..., 0:2] + noise[..., 0:2], self._orientation(x[..., 2:3], turns, 0),
                               x[..., 3:6] + noise[..., 2:5], self._orientation(x[..., 6:7], turns, 1)], axis=-1)
        at_ugv = xp.concatenate([pose[..., 0:3], pose[..., 0:2], xp.full(np.shape(pose[..., :1]), float(self.ugv_z)),
                                 pose[..., 6:7]], axis=-1)  # the UAV's marker read at the UGV
        pose = xp.where(xp.asarray(glitched)[..., None], at_ugv, pose)
        return xp.where(xp.asarray(lost)[..., None], np.nan, pose)  # a lost frame

    @staticmethod
    def _orientation(psi, turns, i):
        """The yaw ``(..., 1)`` read from the quaternion of ``psi`` (``(..., 1)``) turned by ``turns[..., i, :]``."""
        q = g.q_yaw(psi[..., 0])
        if turns is not None:
            q = g.mul(turns[..., i, :], q)
        yaw = g.yaw_of(q)  # the lab receives a quaternion; the controllers need the yaw
        return common_namespace(q).asarray(yaw)[..., None]

    def schedule(self, times, dt: float, substeps: int) -> dict:
        """What :meth:`read` will do at each control tick of a run of :func:`quatform.sim.simulate`
        (ticks ``times``, ``substeps`` plant steps of ``dt`` between them), which does not depend
        on the plant's states: drawn here with the same streams in the same order, for a loop
        that consumes them (:mod:`quatform.sim.jax_ugv_uav`). The model is left fresh.

        Returns
        -------
        dict
            ``new`` (T,) bool: a new frame at the tick; ``pose_step``, ``odometry_step`` (T,)
            int: the plant step (0: the start, ``k substeps + j``: after step ``j`` of tick
            ``k - 1``...) whose output the frame and the odometry read; ``noise`` (T, 5),
            ``turns`` (T, 2, 4) or None, ``lost``, ``glitched`` (T,) bool: the draws of each
            new frame (zeros elsewhere).
        """
        times = np.asarray(times, dtype=float)
        n = times.size
        self._reset()
        steps = LatencyHistory(self.history.horizon)  # the plant steps by time, as the outputs are kept
        new, lost, glitched = (np.zeros(n, dtype=bool) for _ in range(3))
        pose_step, odo_step = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        noise = np.zeros((n, 5))
        turns = None if self.noise_rad <= 0 else np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (n, 2, 1))
        frame = None
        if n:
            steps.add(float(times[0]), 0)
        for k in range(n):
            t = float(times[k])
            frame_t = self._frame_time(t)
            if frame_t != frame:
                new[k], frame = True, frame_t
                pose_step[k] = steps.at(frame_t - self.latency)
                noise[k], turn, lost[k], glitched[k] = self._draw()
                if turns is not None:
                    turns[k] = turn
            odo_step[k] = steps.at(self._odometry_time(t))
            for j in range(substeps):
                steps.add(t + (j + 1) * dt, k * substeps + j + 1)
        self._reset()
        return {"new": new, "pose_step": pose_step, "odometry_step": odo_step, "noise": noise, "turns": turns,
                "lost": lost, "glitched": glitched}
