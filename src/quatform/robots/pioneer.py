"""Pioneer 3-DX: a unicycle driven through a control point ahead of its wheel axis (seed 001 §3.1.1).

Robots layer. State ``(x, y, psi)``: the control point, a distance ``a`` ahead of the
middle of the wheel axis, and the heading. Commands ``(v, omega)``, eq. (3.1). The
control point moves by eq. (3.4), ``[x_dot, y_dot] = A_p [v, omega]`` with ``A_p`` of
eq. (3.2); the controller inverts it, eqs. (3.3), (3.5). A step integrates the unicycle
exactly for a command held over the step. As a robot model (:mod:`quatform.robots.model`)
it offers a formation its control point at the height ``z`` of its landing platform.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra.validate import as_array
from ..errors import InvalidInputError

__all__ = ["Pioneer"]


@dataclass(frozen=True)
class Pioneer:
    """Unicycle with control point ahead of the axis.

    Parameters
    ----------
    a : float
        Distance from the middle of the wheel axis to the control point, m (seed 001:
        0.15 m).
    max_v : float
        Largest ``|v|``, m/s. The Pioneer 3-DX's rated top speed is 1.2 m/s; 0.75 m/s is a
        lab limit chosen here for a 6 x 4 m arena (the thesis does not give its own).
    max_omega : float
        Largest ``|omega|``, rad/s (100 deg/s, chosen likewise).
    z : float
        Height of the point it offers a formation (the landing platform), m.
    """

    a: float = 0.15
    max_v: float = 0.75
    max_omega: float = 100.0 * math.pi / 180.0
    z: float = 0.0

    name = "pioneer"
    #: It offers a formation its control point, lifted to the platform height ``z``.
    point_kind = "xyz"
    state_columns = ("x", "y", "psi")
    command_columns = ("v", "omega")
    #: Entries of the rate :meth:`actuate` takes: the point's (its z rate is ignored).
    n_rate = 3

    def __post_init__(self):
        if not np.isfinite(self.z):
            raise InvalidInputError(f"Pioneer z must be finite, got {self.z!r}")
        for name in ("a", "max_v", "max_omega"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInputError(f"Pioneer {name} must be positive and finite, got {v!r}")

    def point(self, x) -> np.ndarray:
        """``(x, y, z)``: the control point at the platform height, shape ``(..., 3)``."""
        x = np.asarray(x, dtype=float)
        return np.stack([x[..., 0], x[..., 1], np.full(x.shape[:-1], self.z)], axis=-1)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """``(v, omega)`` that move the control point at the world rate ``rate[..., 0:2]``,
        eq. (3.5) (:meth:`commands_from_velocity`), and ``memory`` unchanged."""
        x, rate = np.asarray(x, dtype=float), np.asarray(rate, dtype=float)
        return self.commands_from_velocity(x[..., 2], rate[..., 0:2]), memory

    def brake(self, x, memory=None):
        """Commands that stop the robot: zero, shape ``(..., 2)``."""
        return np.zeros(np.shape(x)[:-1] + (2,)), memory

    def forward_matrix(self, psi) -> np.ndarray:
        """``A_p`` of eq. (3.2): ``[x_dot, y_dot] = A_p [v, omega]``, shape ``(..., 2, 2)``."""
        c, s = np.cos(psi), np.sin(psi)
        return np.stack([np.stack([c, -self.a * s], -1), np.stack([s, self.a * c], -1)], -2)

    def commands_from_velocity(self, psi, xy_dot) -> np.ndarray:
        """``[v, omega] = A_p^-1 [x_dot, y_dot]``, eqs. (3.3), (3.5); shape ``(..., 2)``.

        ``A_p`` has determinant ``a``: invertible for every heading.
        """
        xy_dot = np.asarray(xy_dot, dtype=float)
        c, s = np.cos(psi), np.sin(psi)
        v = c * xy_dot[..., 0] + s * xy_dot[..., 1]
        w = (-s * xy_dot[..., 0] + c * xy_dot[..., 1]) / self.a
        return np.stack([v, w], axis=-1)

    def saturate(self, u) -> np.ndarray:
        """``(v, omega)`` scaled as a whole into the limits (path curvature kept); NaN -> 0."""
        u = np.asarray(u, dtype=float)
        finite = np.all(np.isfinite(u), axis=-1)
        u = np.where(finite[..., None], u, 0.0)
        with np.errstate(divide="ignore"):
            s = np.minimum(self.max_v / np.abs(u[..., 0]), self.max_omega / np.abs(u[..., 1]))
        return u * np.minimum(1.0, s)[..., None]

    def step(self, state, u, dt: float) -> np.ndarray:
        """State ``(x, y, psi)`` after ``dt`` s of the saturated command ``(v, omega)`` (exact arc)."""
        state = as_array(state, "Pioneer state", 3)
        v, w = np.moveaxis(self.saturate(u), -1, 0)
        x, y, psi = np.moveaxis(state, -1, 0)
        # middle of the wheel axis moves on an arc; the control point follows rigidly
        cx, cy = x - self.a * np.cos(psi), y - self.a * np.sin(psi)
        psi1 = psi + w * dt
        small = np.abs(w * dt) < 1e-9
        with np.errstate(divide="ignore", invalid="ignore"):
            R = np.where(small, 0.0, v / np.where(small, 1.0, w))
        dx = np.where(small, v * dt * np.cos(psi + 0.5 * w * dt), R * (np.sin(psi1) - np.sin(psi)))
        dy = np.where(small, v * dt * np.sin(psi + 0.5 * w * dt), -R * (np.cos(psi1) - np.cos(psi)))
        cx, cy = cx + dx, cy + dy
        return np.stack([cx + self.a * np.cos(psi1), cy + self.a * np.sin(psi1), psi1], axis=-1)
