"""Filters around a cluster-space law, as data (control layer).

A filter is a frozen value: its settings are fields, and anything it remembers between
steps lives in the controller's state, not in the filter. Each is written once on the array
namespace of its operands (NumPy, or JAX under ``jax.jit``), branch-free: selections, not
Python branches on data.

* :class:`MocapScreen`: seed 001's lab — classify a motion-capture frame as good,
  dropped (a NaN or infinity) or rejected (implausible), so the last good frame can stand
  in for up to ``max_hold_s``.
* :class:`ArenaWalls`: slow the robots' world rates toward the walls of the flight arena
  (seed 001 §3.4) so they stop short of them.
* :class:`HeadingLaw`: the UAV's yaw law, seed 001 eqs. (4.50)-(4.51).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import common_namespace
from ..errors import InvalidInputError
from ..formations import geometry as g

__all__ = ["MocapScreen", "ArenaWalls", "HeadingLaw", "FRAME_GOOD", "FRAME_DROPPED", "FRAME_REJECTED"]

#: The names of the classes :meth:`MocapScreen.frame_code` gives a motion-capture frame (codes 0, 1, 2).
FRAME_GOOD, FRAME_DROPPED, FRAME_REJECTED = "good", "dropped", "rejected"


@dataclass(frozen=True)
class MocapScreen:
    """Plausibility of motion-capture frames of robot positions (seed 001's lab).

    Parameters
    ----------
    top_speeds : tuple of float
        Per robot, the farthest it can move per second, m/s (with a margin).
    jump_margin_m : float
        Added to the distance a robot may move between frames (the measurement noise), m.
    min_separation_m : float
        Robots closer than this are a misread frame (two markers read as one), m.
    max_hold_s : float
        Longest time, s, the last good frame may stand in for bad ones.
    """

    top_speeds: tuple
    jump_margin_m: float = 0.05
    min_separation_m: float = 0.05
    max_hold_s: float = 0.5

    def __post_init__(self):
        for name in ("jump_margin_m", "min_separation_m", "max_hold_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInputError(f"{name} must be a positive number, got {v!r}")

    def frame_code(self, t, points, finite, good_points, good_t):
        """The class of a frame, on arrays of any namespace (NumPy, JAX under ``jax.jit``): 0
        good (:data:`FRAME_GOOD`), 1 dropped (:data:`FRAME_DROPPED`: a pose not finite), 2
        rejected (:data:`FRAME_REJECTED`: two robots within ``min_separation_m``, or one
        farther from its last good position than its top speed allows in the time since, plus
        ``jump_margin_m``); shape that of ``finite``.

        Parameters
        ----------
        t : float or array
            Time of the frame, s.
        points : sequence of arrays, shape (..., 3) each
        finite : bool array, shape (...)
        good_points : sequence of arrays (..., 3), or None
            The last good frame's positions (anything where there is none).
        good_t : float or array, shape (...), or None
            Its time, s; NaN where there is no good frame yet (its positions are not read there).
        """
        xp = common_namespace(t, finite, good_t, *points, *(good_points or ()))

        def dist(a, b):
            d = a - b
            return xp.sqrt(xp.sum(d * d, axis=-1))

        rejected = xp.zeros(np.shape(finite), dtype=bool)
        for i in range(len(points)):
            for j in range(i + 1, len(points)):
                rejected = rejected | (dist(points[j], points[i]) < self.min_separation_m)
        if good_points is not None:
            dt = t - good_t
            dt = xp.where(0.0 > dt, 0.0, dt)  # max(t - good_t, 0)
            for p, q, v in zip(points, good_points, self.top_speeds):
                rejected = rejected | (dist(p, q) > v * dt + self.jump_margin_m)
        return xp.where(finite, xp.where(rejected, 2, 0), 1)

    def expired(self, t, bad_since):
        """Whether bad frames since ``bad_since`` have lasted longer than ``max_hold_s`` (floats
        or arrays of any namespace; False where ``bad_since`` is NaN)."""
        return t - bad_since > self.max_hold_s + 1e-9


@dataclass(frozen=True)
class ArenaWalls:
    """The walls of a box arena: world rates toward a wall are limited to ``gain`` times the
    distance left before ``margin``, so the robots stop short of it (and never push out).

    Parameters
    ----------
    box : ndarray, shape (3, 2)
        ``((x_min, x_max), (y_min, y_max), (z_min, z_max))``, m.
    margin : float
        Distance, m, short of a wall where the robots stop.
    gain : float
        Largest rate per metre of room left, 1/s.
    free : tuple of (robot, axis)
        Axes of robots' points the walls do not limit (a ground robot's fixed height).
    """

    box: np.ndarray
    margin: float = 0.3
    gain: float = 1.0
    free: tuple = ()

    def __post_init__(self):
        box = np.asarray(self.box, dtype=float)
        if box.shape != (3, 2) or np.any(box[:, 0] >= box[:, 1]):
            raise InvalidInputError(f"arena must be ((x_min, x_max), (y_min, y_max), (z_min, z_max)), got {self.box!r}")
        if not (self.margin >= 0 and self.gain > 0):
            raise InvalidInputError(f"arena margin must be >= 0 and gain > 0, got {self.margin!r}, {self.gain!r}")
        object.__setattr__(self, "box", box)

    def limit(self, points, rates) -> np.ndarray:
        """``rates`` (the points' world rates, 3 per robot) limited by the walls.

        Parameters
        ----------
        points : sequence of arrays, shape (..., 3) each
        rates : array, shape (..., 3 N)
        """
        xp = common_namespace(rates, *points)
        rates = np.asarray(rates, dtype=float) if xp is np else rates
        out = [rates[..., i] for i in range(rates.shape[-1])]
        for k, pos in enumerate(points):
            for axis in range(3):
                if (k, axis) in self.free:
                    continue
                lo, hi = self.box[axis]
                room_hi = hi - self.margin - pos[..., axis]
                room_lo = pos[..., axis] - (lo + self.margin)
                room_hi = xp.where(room_hi > 0.0, room_hi, 0.0)  # max(0, room): NaN reads as no room
                room_lo = xp.where(room_lo > 0.0, room_lo, 0.0)
                i = 3 * k + axis
                top, bottom = self.gain * room_hi, -self.gain * room_lo
                out[i] = xp.where(top < out[i], top, out[i])  # min(rate, top)
                out[i] = xp.where(bottom > out[i], bottom, out[i])  # max(rate, bottom)
        return xp.stack(out, axis=-1)


@dataclass(frozen=True)
class HeadingLaw:
    """Yaw rate of a robot whose yaw is outside the formation: seed 001 eqs. (4.50)-(4.51),
    ``psi_dot_r = k tanh(wrap(psi_des - psi))`` (the UAV faces the way the UGV does,
    ``psi_des = psi_p``).

    Parameters
    ----------
    k : float
        Gain, rad/s (3 in seed 001 §5).
    """

    k: float = 3.0

    def __post_init__(self):
        if not (np.isfinite(self.k) and self.k > 0):
            raise InvalidInputError(f"k_psi must be a positive number, got {self.k!r}")

    def rate(self, psi_des, psi):
        """Yaw rate, rad/s, for the yaw ``psi`` toward ``psi_des`` (floats or arrays)."""
        return self.k * common_namespace(psi_des, psi).tanh(g.wrap(psi_des - psi))  # (4.50)-(4.51)
