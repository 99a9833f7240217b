"""A team: a tuple of robot models, the layout of the points they offer a formation.

Robots layer (above formations). A :class:`Team` stacks its robots' states and commands
robot after robot, knows the :class:`~quatform.formations.layout.RobotLayout` of the
points they offer, and actuates, saturates and steps them all. A holonomic team (seed
000) scales all its robots' commands by one common factor by default, so the formation's
motion keeps its direction; a mixed team (the Pioneer and the Bebop of seed 001)
saturates each robot on its own. Every method takes leading batch axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..algebra.validate import as_array
from ..errors import InvalidInputError
from ..formations.layout import RobotLayout
from .holonomic import HolonomicRobot

__all__ = ["Team"]


def _offsets(widths):
    out, k = [], 0
    for w in widths:
        out.append(slice(k, k + w))
        k += w
    return tuple(out), k


@dataclass(frozen=True)
class Team:
    """Robot models whose states, rates and commands are stacked robot after robot.

    Parameters
    ----------
    robots : tuple of robot models (:class:`~quatform.robots.model.RobotModel`)
        Default: two holonomic 4-DOF robots (seed 000).
    common_limit : bool or None
        Saturate every robot's command by one factor (the smallest any robot needs) so the
        formation's motion keeps its direction; only for holonomic robots. None: True for a
        team of holonomic robots, False otherwise (each robot saturated on its own).
    """

    robots: tuple = (HolonomicRobot(), HolonomicRobot())
    common_limit: bool | None = None

    def __post_init__(self):
        robots = tuple(self.robots)
        if not robots:
            raise InvalidInputError("a team needs at least one robot")
        object.__setattr__(self, "robots", robots)
        holonomic = all(isinstance(r, HolonomicRobot) for r in robots)
        common = holonomic if self.common_limit is None else bool(self.common_limit)
        if common and not holonomic:
            raise InvalidInputError("common_limit = True needs a team of HolonomicRobot models (their commands "
                                    "scale together); give common_limit = False or None")
        object.__setattr__(self, "common_limit", common)

    # -- layout -------------------------------------------------------------------------
    @cached_property
    def layout(self) -> RobotLayout:
        """The layout of the points the robots offer a formation."""
        return RobotLayout(tuple(r.point_kind for r in self.robots))

    @cached_property
    def state_slices(self) -> tuple:
        return _offsets(len(r.state_columns) for r in self.robots)[0]

    @cached_property
    def command_slices(self) -> tuple:
        return _offsets(len(r.command_columns) for r in self.robots)[0]

    @cached_property
    def rate_slices(self) -> tuple:
        return _offsets(r.n_rate for r in self.robots)[0]

    @property
    def n(self) -> int:
        """Number of commands (also of states for a holonomic team)."""
        return sum(len(r.command_columns) for r in self.robots)

    @property
    def n_state(self) -> int:
        return sum(len(r.state_columns) for r in self.robots)

    @property
    def n_rate(self) -> int:
        """Entries of the rate :meth:`actuate` takes (each robot's point rate, plus the yaw rate
        of a robot whose yaw is outside the formation)."""
        return sum(r.n_rate for r in self.robots)

    def _columns(self, attr):
        n = len(self.robots)
        return tuple(f"{c}{i + 1}" if n > 1 else c for i, r in enumerate(self.robots) for c in getattr(r, attr))

    @property
    def state_columns(self) -> tuple:
        """Each robot's state names with its number appended (``x1 ... theta2``)."""
        return self._columns("state_columns")

    @property
    def command_columns(self) -> tuple:
        return self._columns("command_columns")

    def split(self, x, slices=None) -> list:
        """Each robot's part of a stacked array (states by default), shapes ``(..., k_i)``."""
        x = np.asarray(x, dtype=float)
        return [x[..., s] for s in (self.state_slices if slices is None else slices)]

    def stack(self, parts) -> np.ndarray:
        """Robots' arrays (states or commands) stacked on the last axis."""
        return np.concatenate([np.asarray(p, dtype=float) for p in parts], axis=-1)

    # -- the robots together --------------------------------------------------------------
    def point(self, x) -> np.ndarray:
        """The robot state of the formation: every robot's point, shape ``(..., layout.size)``."""
        return self.stack([r.point(xi) for r, xi in zip(self.robots, self.split(x))])

    def initial_memory(self, batch: tuple = ()) -> tuple:
        """Every robot's actuation memory before the first step."""
        return tuple(r.initial_memory(batch) for r in self.robots)

    def actuate(self, x, rate, t: float, memory: tuple):
        """Unsaturated commands ``(..., n)`` for the stacked rates ``rate`` (``(..., n_rate)``)
        and the next memory (one entry per robot)."""
        xs, rates = self.split(x), self.split(rate, self.rate_slices)
        out = [r.actuate(xi, ri, t, mi) for r, xi, ri, mi in zip(self.robots, xs, rates, memory)]
        return self.stack([u for u, _ in out]), tuple(m for _, m in out)

    def brake(self, x, memory: tuple):
        """Commands that stop every robot (unsaturated) and the memory after a brake."""
        out = [r.brake(xi, mi) for r, xi, mi in zip(self.robots, self.split(x), memory)]
        return self.stack([u for u, _ in out]), tuple(m for _, m in out)

    def saturate(self, u) -> np.ndarray:
        """Team command within every robot's limits, finite.

        With :attr:`common_limit` one factor for all robots (the smallest any robot
        needs), so the formation's motion keeps its direction: limiting each robot on its
        own would bend the commanded cluster rate and distort the shape; a non-finite entry
        then stops the whole team. Otherwise each robot's :meth:`saturate`.

        Parameters
        ----------
        u : array_like, shape (..., n)

        Returns
        -------
        ndarray, shape (..., n)
        """
        u = np.asarray(u, dtype=float)
        if u.shape[-1:] != (self.n,):
            raise InvalidInputError(f"team command must have shape (..., {self.n}), got {u.shape}")
        if not self.common_limit:
            return self.stack([r.saturate(ui) for r, ui in zip(self.robots, self.split(u, self.command_slices))])
        if u.ndim == 1:
            return self.saturate_floats(u.tolist())
        s = np.min(np.stack([rb.limit_factor(u[..., sl]) for rb, sl in zip(self.robots, self.command_slices)]),
                   axis=0)
        return np.where(s[..., None] > 0, u * s[..., None], 0.0)

    def saturate_floats(self, u) -> np.ndarray:
        """:meth:`saturate` of a holonomic team for one command given as Python floats."""
        s = min(rb.limit_factor_floats(*u[sl]) for rb, sl in zip(self.robots, self.command_slices))
        return np.array([x * s for x in u]) if s > 0 else np.zeros(self.n)

    def step(self, x, u, dt: float) -> np.ndarray:
        """Team state after ``dt`` s of the command ``u`` (each robot's :meth:`step`; a holonomic
        team's command saturated by the common factor first)."""
        if self.common_limit:
            x = as_array(x, "r", self.n_state)
            return x + dt * self.saturate(u)
        us = self.split(self.saturate(u), self.command_slices)
        return self.stack([r.step(xi, ui, dt) for r, xi, ui in zip(self.robots, self.split(x), us)])
