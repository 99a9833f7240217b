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
        frame_t = math.floor(t * self.rate + 1e-9) / self.rate
        if frame_t != self._frame_t:
            x = self.history.at(frame_t - self.latency)
            noise = self.rng.normal(0.0, self.noise_m, 5) if self.noise_m > 0 else np.zeros(5)
            self._pose = np.r_[x[0:2] + noise[0:2], self._orientation(x[2]), x[3:6] + noise[2:5],
                               self._orientation(x[6])]
            if self.dropout_rate > 0 and self.fault_rng.random() < self.dropout_rate:
                self._pose[:] = np.nan  # a lost frame
            elif self.glitch_rate > 0 and self.fault_rng.random() < self.glitch_rate:
                self._pose[3:6] = [self._pose[0], self._pose[1], self.ugv_z]  # the UAV's marker read at the UGV
            self._frame_t = frame_t
        odo_t = math.floor(t / self.odo + 1e-9) * self.odo
        return np.r_[self._pose, self.history.at(odo_t)[7:11]]

    def _orientation(self, psi):
        q = g.q_yaw(psi)
        if self.noise_rad > 0:
            axis = self.rng.normal(size=3)
            q = g.mul(q_from_axis_angle(axis / np.linalg.norm(axis), self.rng.normal(0.0, self.noise_rad)), q)
        return g.yaw_of(q)  # the lab receives a quaternion; the controllers need the yaw
