"""Planar holonomic ground robot (velocity commands in x, y and yaw): the ground kind of issue 14.

Robots layer. State ``(x, y, theta)``; command ``(v_x, v_y, omega_z)`` in the world frame,
held over a step, so the step is exact: the planar analogue of the 4-DOF robot of seed 000
§4.1 (:class:`~quatform.robots.holonomic.HolonomicRobot`). It offers a formation its whole
state, an ``xy_yaw`` point (its position is ``(x, y, 0)``). A command beyond the limits
(speed in norm, yaw rate in magnitude) is scaled down as a whole, its direction kept; a team
of holonomic robots scales all its commands by one factor (:mod:`quatform.robots.team`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.validate import as_array
from ..errors import InvalidInputError

__all__ = ["PlanarHolonomicRobot"]


@dataclass(frozen=True)
class PlanarHolonomicRobot:
    """A holonomic ground robot that takes velocity commands in x, y and yaw.

    Parameters
    ----------
    max_speed : float
        Largest planar speed ``||(v_x, v_y)||``, m/s.
    max_yaw_rate : float
        Largest ``|omega_z|``, rad/s.
    """

    max_speed: float = 2.5
    max_yaw_rate: float = 3.0

    name = "planar-holonomic"
    #: It offers a formation its whole state, a planar point.
    point_kind = "xy_yaw"
    state_columns = ("x", "y", "theta")
    command_columns = ("v_x", "v_y", "omega_z")
    #: Entries of the rate :meth:`actuate` takes: the point's.
    n_rate = 3
    #: Its commands are its point's rates (a controller may skip :meth:`actuate`).
    passthrough = True
    #: Its commands scale as a whole (:meth:`limit_factor`), so a team may share one factor.
    holonomic = True

    def __post_init__(self):
        for name in ("max_speed", "max_yaw_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v > 0):
                raise InvalidInputError(f"PlanarHolonomicRobot {name} must be a positive finite number, got {v!r}")

    def point(self, x) -> np.ndarray:
        """The planar point: the state itself, shape ``(..., 3)``."""
        return np.asarray(x, dtype=float)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """The commands are the point's world rates: ``(rate, memory)``."""
        return np.asarray(rate, dtype=float), memory

    def brake(self, x, memory=None):
        """Commands that stop the robot: zero, shape ``(..., 3)``."""
        return np.zeros(np.shape(x)[:-1] + (3,)), memory

    def limit_factor(self, u) -> np.ndarray:
        """Largest ``s`` in ``[0, 1]`` with ``s u`` within the limits (0 for a non-finite ``u``).

        Parameters
        ----------
        u : ndarray, shape (..., 3)

        Returns
        -------
        ndarray, shape (...)
        """
        u = np.asarray(u, dtype=float)
        finite = np.all(np.isfinite(u), axis=-1)
        v = np.where(finite[..., None], u, 0.0)
        speed = np.hypot(v[..., 0], v[..., 1])
        with np.errstate(divide="ignore", over="ignore"):
            s = np.minimum(self.max_speed / speed, self.max_yaw_rate / np.abs(v[..., 2]))
        return np.where(finite, np.minimum(1.0, s), 0.0)

    def saturate(self, u) -> np.ndarray:
        """Commands limited to the robot's speeds, direction kept; non-finite ones become zero.

        Parameters
        ----------
        u : array_like, shape (..., 3)

        Returns
        -------
        ndarray, shape (..., 3)
        """
        u = np.asarray(u, dtype=float)
        if u.shape[-1:] != (3,):
            raise InvalidInputError(f"a planar robot command has shape (..., 3) (v_x, v_y, omega_z), got {u.shape}")
        s = self.limit_factor(u)[..., None]
        return np.where(s > 0, u * s, 0.0)

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` s of the saturated command ``u`` (exact for a held command)."""
        return as_array(x, "planar robot state", 3) + dt * self.saturate(u)
