"""Holonomic 4-DOF kinematic robot (velocity commands in x, y, z and yaw), seed 000 §4.1.

Robots layer. State ``(x, y, z, theta)``; command ``(v_x, v_y, v_z, omega_z)`` in the world
frame, held constant over a step, so the step is exact. The linear speed is limited in
norm (the direction is kept), the yaw rate in magnitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra._validate import as_array
from ..errors import InvalidInputError

__all__ = ["HolonomicRobot", "Team"]


@dataclass(frozen=True)
class HolonomicRobot:
    """A holonomic robot that takes velocity commands in x, y, z and yaw.

    Parameters
    ----------
    max_speed : float
        Largest linear speed ``||(v_x, v_y, v_z)||``, m/s.
    max_yaw_rate : float
        Largest ``|omega_z|``, rad/s.
    """

    max_speed: float = 2.5
    max_yaw_rate: float = 3.0

    def __post_init__(self):
        for name in ("max_speed", "max_yaw_rate"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInputError(f"{name} must be a positive finite number, got {v!r}")

    def saturate(self, u) -> np.ndarray:
        """Commands limited to the robot's speeds; non-finite commands become zero.

        Parameters
        ----------
        u : array_like, shape (..., 4)

        Returns
        -------
        ndarray, shape (..., 4)
        """
        if isinstance(u, np.ndarray) and u.shape == (4,):
            return np.array(self._saturate_one(*u.tolist()))
        u = np.array(u, dtype=float)
        if u.shape[-1:] != (4,):
            raise InvalidInputError(f"a 4-DOF robot command has shape (..., 4), got {u.shape}")
        bad = ~np.all(np.isfinite(u), axis=-1)
        u[bad] = 0.0
        speed = np.linalg.norm(u[..., :3], axis=-1)
        scale = np.minimum(1.0, self.max_speed / np.maximum(speed, 1e-300))
        u[..., :3] *= scale[..., None]
        u[..., 3] = np.clip(u[..., 3], -self.max_yaw_rate, self.max_yaw_rate)
        return u

    def _saturate_one(self, vx, vy, vz, wz):
        """Fast path for one command (Python floats)."""
        if not all(map(math.isfinite, (vx, vy, vz, wz))):
            return 0.0, 0.0, 0.0, 0.0
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        if speed > self.max_speed:
            s = self.max_speed / speed
            vx, vy, vz = vx * s, vy * s, vz * s
        return vx, vy, vz, min(max(wz, -self.max_yaw_rate), self.max_yaw_rate)

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` seconds of the saturated command ``u`` (exact)."""
        return as_array(x, "x", 4) + dt * self.saturate(u)


@dataclass(frozen=True)
class Team:
    """Robots whose states and commands are stacked: robot ``i`` owns entries ``4i:4i+4``."""

    robots: tuple[HolonomicRobot, ...] = (HolonomicRobot(), HolonomicRobot())

    @property
    def n(self) -> int:
        return 4 * len(self.robots)

    def saturate(self, u) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.shape[-1:] != (self.n,):
            raise InvalidInputError(f"team command must have shape (..., {self.n}), got {u.shape}")
        if u.ndim == 1:
            v = u.tolist()
            return np.array([x for i, rb in enumerate(self.robots) for x in rb._saturate_one(*v[4 * i:4 * i + 4])])
        return np.concatenate(
            [rb.saturate(u[..., 4 * i:4 * i + 4]) for i, rb in enumerate(self.robots)], axis=-1
        )

    def saturate_floats(self, u) -> np.ndarray:
        """:meth:`saturate` for one command given as a sequence of Python floats."""
        return np.array([x for i, rb in enumerate(self.robots) for x in rb._saturate_one(*u[4 * i:4 * i + 4])])

    def step(self, r, u, dt: float) -> np.ndarray:
        r = as_array(r, "r", self.n)
        return r + dt * self.saturate(u)
