"""A team: a tuple of robot models, the layout of the points they offer a formation.

Robots layer (above formations). A :class:`Team` stacks its robots' states and commands
robot after robot, knows the :class:`~quatform.formations.layout.RobotLayout` of the
points they offer, and actuates, saturates and steps them all. A team of holonomic robots
(seed 000's 4-DOF robots, planar holonomic robots, free bodies: commands that scale as a
whole) scales all its robots' commands by one common factor by default, so the formation's
motion keeps its direction; a team with other robots (the Pioneer and the Bebop of seed
001) saturates each robot on its own. Every method takes leading batch axes; ``gather``,
``scatter``, ``actuate``, ``limit_factor``, ``saturate`` and ``step`` also run on JAX arrays
(under ``jax.jit``: the compute backend's loop) with the models' same code, writing into no
array there.

Robots of one class with equal parameters form a :class:`RobotGroup`; every team method
gathers a group's entries into one ``(..., m, k)`` array (a view when the group's robots
are consecutive), calls the model once on it and scatters the result back, so a method
costs a fixed number of NumPy calls per group whatever the number of robots (1000 equal
robots are one call). A group of one robot is called on its own ``(..., k)`` slice, as a
robot model on its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats, concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError
from ..formations.layout import RobotLayout
from .holonomic import HolonomicRobot
from .planar import PlanarHolonomicRobot

__all__ = ["Team", "RobotGroup", "GroupIndex"]

#: A team of at most this many 4-DOF holonomic robots saturates one command in Python floats
#: (faster than NumPy calls at that size, and the seed-000 pair's results stay bitwise).
_FLOAT_PATH_MAX_ROBOTS = 8


def _offsets(widths):
    out, k = [], 0
    for w in widths:
        out.append(slice(k, k + w))
        k += w
    return tuple(out), k


@dataclass(frozen=True, eq=False)
class GroupIndex:
    """Where a group's robots sit in a stacked array (states, commands, rates or points).

    Attributes
    ----------
    m, k : int
        Robots in the group and entries per robot.
    block : slice or None
        The group's entries when its robots are consecutive (then a reshape gathers them).
    index : ndarray of int, shape (m, k)
        The entries of every robot of the group (used when ``block`` is None).
    """

    m: int
    k: int
    block: slice | None
    index: np.ndarray

    @classmethod
    def of(cls, slices) -> GroupIndex:
        """From the group's robots' slices (all of one width)."""
        slices = list(slices)
        k = slices[0].stop - slices[0].start
        index = np.array([np.arange(s.start, s.stop) for s in slices], dtype=np.intp).reshape(len(slices), k)
        flat = index.ravel()
        consecutive = np.array_equal(flat, np.arange(flat[0], flat[0] + flat.size))
        block = slice(int(flat[0]), int(flat[-1]) + 1) if consecutive else None
        return cls(len(slices), k, block, index)

    def gather(self, a) -> np.ndarray:
        """The group's entries of ``a`` (``(..., n)``): ``(..., m, k)``, or ``(..., k)`` for one robot."""
        if self.m == 1:
            return a[..., self.block] if self.block is not None else a[..., self.index[0]]
        if self.block is not None:
            return a[..., self.block].reshape(a.shape[:-1] + (self.m, self.k))
        return a[..., self.index]

    def scatter(self, out, part) -> None:
        """Write the group's ``part`` (as :meth:`gather` returns it) into ``out`` (``(..., n)``)."""
        if self.block is not None:
            if self.m > 1:
                part = np.reshape(part, np.shape(part)[:-2] + (self.m * self.k,))
            out[..., self.block] = part
        else:
            out[..., self.index if self.m > 1 else self.index[0]] = part


@dataclass(frozen=True, eq=False)
class RobotGroup:
    """Robots of one model (same class, equal parameters) in a team.

    Attributes
    ----------
    model : robot model
    robots : tuple of int
        The robots' numbers in the team, 0-based, in order.
    state, command, rate, point : GroupIndex
        Their entries in the stacked states, commands, rates and points.
    """

    model: object
    robots: tuple
    state: GroupIndex
    command: GroupIndex
    rate: GroupIndex
    point: GroupIndex

    @property
    def axis(self) -> tuple:
        """The robot axis the group's gathered arrays carry: ``(m,)``, or ``()`` for one robot."""
        return (len(self.robots),) if len(self.robots) > 1 else ()


def _group_models(robots):
    """Robot indices grouped by model (class and parameters), in order of first appearance."""
    groups: list[tuple[object, list]] = []
    by_hash: dict = {}
    for i, r in enumerate(robots):
        try:
            key = (type(r), r)
            g = by_hash.get(key)
        except TypeError:  # an unhashable model: compare with every group
            key, g = None, next((grp for grp in groups if type(grp[0]) is type(r) and grp[0] == r), None)
        if g is None:
            g = (r, [])
            groups.append(g)
            if key is not None:
                by_hash[key] = g
        g[1].append(i)
    return groups


@dataclass(frozen=True)
class Team:
    """Robot models whose states, rates and commands are stacked robot after robot.

    Parameters
    ----------
    robots : tuple of robot models (:class:`~quatform.robots.model.RobotModel`)
        Default: two holonomic 4-DOF robots (seed 000).
    common_limit : bool or None
        Saturate every robot's command by one factor (the smallest any robot needs) so the
        formation's motion keeps its direction; only for holonomic robots (models whose
        ``holonomic`` is True: :class:`~quatform.robots.HolonomicRobot`,
        :class:`~quatform.robots.PlanarHolonomicRobot`, :class:`~quatform.robots.FreeBodyRobot`).
        None: True for a team of holonomic robots, False otherwise (each robot saturated on
        its own).
    """

    robots: tuple = (HolonomicRobot(), HolonomicRobot())
    common_limit: bool | None = None

    def __post_init__(self):
        robots = tuple(self.robots)
        if not robots:
            raise InvalidInputError("a team needs at least one robot")
        object.__setattr__(self, "robots", robots)
        holonomic = all(r.holonomic for r in robots)
        common = holonomic if self.common_limit is None else bool(self.common_limit)
        if common and not holonomic:
            bad = next(r for r in robots if not r.holonomic)
            raise InvalidInputError(f"common_limit = True needs a team of holonomic robots (commands that scale "
                                    f"together), got a {type(bad).__name__}; give common_limit = False or None")
        object.__setattr__(self, "common_limit", common)

    @classmethod
    def uniform(cls, model, n: int, common_limit: bool | None = None) -> Team:
        """``n`` robots of one model (one group: every method is one call of the model)."""
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
            raise InvalidInputError(f"Team.uniform needs a whole number of robots >= 1, got {n!r}")
        return cls((model,) * int(n), common_limit)

    # -- layout -------------------------------------------------------------------------
    @cached_property
    def layout(self) -> RobotLayout:
        """The layout of the points the robots offer a formation."""
        return RobotLayout(tuple(r.point_kind for r in self.robots))

    @cached_property
    def passthrough(self) -> bool:
        """Whether the commands are the formation's robot rates themselves (holonomic robots
        whose commands are their points' rates, seed 000 §4.1): a controller then skips
        :meth:`actuate`."""
        return all(r.passthrough for r in self.robots)

    @cached_property
    def state_slices(self) -> tuple:
        return _offsets(len(r.state_columns) for r in self.robots)[0]

    @cached_property
    def command_slices(self) -> tuple:
        return _offsets(len(r.command_columns) for r in self.robots)[0]

    @cached_property
    def rate_slices(self) -> tuple:
        return _offsets(r.n_rate for r in self.robots)[0]

    @cached_property
    def point_slices(self) -> tuple:
        return tuple(self.layout.slice(i) for i in range(len(self.robots)))

    def state_entries(self, robot: int, *names: str):
        """Where robot ``robot``'s state columns ``names`` sit in the team's stacked state: an int
        for one name, a slice for consecutive ones (:meth:`RobotModel.state_entries`)."""
        return self.robots[robot].state_entries(*names, start=self.state_slices[robot].start)

    def command_entries(self, robot: int, *names: str):
        """Where robot ``robot``'s command columns ``names`` sit in the team's stacked commands."""
        return self.robots[robot].command_entries(*names, start=self.command_slices[robot].start)

    @cached_property
    def groups(self) -> tuple[RobotGroup, ...]:
        """The robots grouped by model, in order of first appearance (:class:`RobotGroup`)."""
        out = []
        for model, idx in _group_models(self.robots):
            out.append(RobotGroup(model, tuple(idx),
                                  *(GroupIndex.of(sl[i] for i in idx) for sl in
                                    (self.state_slices, self.command_slices, self.rate_slices, self.point_slices))))
        return tuple(out)

    @cached_property
    def _float_path(self) -> bool:
        return self.common_limit and len(self.robots) <= _FLOAT_PATH_MAX_ROBOTS and all(
            type(r) is HolonomicRobot for r in self.robots)

    @cached_property
    def _additive(self) -> bool:
        """A common-limit team whose step is ``x + dt u`` (its states are its commands' integrals)."""
        return self.common_limit and all(type(r) in (HolonomicRobot, PlanarHolonomicRobot) for r in self.robots)

    @cached_property
    def n(self) -> int:
        """Number of commands (also of states for a holonomic team)."""
        return sum(len(r.command_columns) for r in self.robots)

    @cached_property
    def n_state(self) -> int:
        return sum(len(r.state_columns) for r in self.robots)

    @cached_property
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
        """Each robot's part of a stacked array (states by default), shapes ``(..., k_i)`` (views).

        One view per robot; the team's own methods work per group (:meth:`gather`)."""
        x = np.asarray(x, dtype=float)
        return [x[..., s] for s in (self.state_slices if slices is None else slices)]

    def stack(self, parts) -> np.ndarray:
        """Robots' arrays (states or commands) stacked on the last axis (one concatenation)."""
        return np.concatenate([np.asarray(p, dtype=float) for p in parts], axis=-1)

    def gather(self, a, part: str = "state") -> list:
        """Each group's entries of the stacked array ``a``: ``(..., m, k)`` (``(..., k)`` for a
        group of one robot), one NumPy call per group.

        Parameters
        ----------
        a : array_like, shape (..., n of that part)
        part : str
            ``"state"``, ``"command"``, ``"rate"`` or ``"point"``.
        """
        if concrete(a) or isinstance(a, (list, tuple)):
            a = np.asarray(a, dtype=float)
        return [getattr(g, part).gather(a) for g in self.groups]

    def scatter(self, parts, part: str = "state", batch: tuple | None = None) -> np.ndarray:
        """The stacked array of the groups' ``parts`` (as :meth:`gather` returns them).

        Parameters
        ----------
        parts : sequence of arrays, one per group
        part : str
            ``"state"``, ``"command"``, ``"rate"`` or ``"point"``.
        batch : tuple, optional
            Leading axes of the result (default: broadcast of the parts').
        """
        if len(parts) != len(self.groups):
            raise InvalidInputError(f"Team.scatter: {len(parts)} parts for {len(self.groups)} groups")
        idx = [getattr(g, part) for g in self.groups]
        tails = [2 if ix.m > 1 else 1 for ix in idx]  # the robot axis and the entries, or the entries
        if batch is None:
            batch = np.broadcast_shapes(*(np.shape(p)[:np.ndim(p) - t] for p, t in zip(parts, tails)))
        batch = tuple(batch)
        one = idx[0]
        if not all(concrete(p) or isinstance(p, (list, tuple)) for p in parts):  # JAX: no writes into an array
            xp = next(namespace(p) for p in parts if not concrete(p) and not isinstance(p, (list, tuple)))
            flat = [xp.broadcast_to(xp.asarray(p, dtype=float), batch + np.shape(p)[np.ndim(p) - t:]).reshape(
                batch + (ix.m * ix.k,)) for p, t, ix in zip(parts, tails, idx)]
            out = xp.concatenate(flat, axis=-1) if len(flat) > 1 else flat[0]
            order = np.concatenate([ix.index.ravel() for ix in idx])
            return out if np.array_equal(order, np.arange(order.size)) else out[..., np.argsort(order)]
        if len(idx) == 1 and one.block is not None and one.block == slice(0, one.m * one.k):
            p = np.broadcast_to(parts[0], batch + np.shape(parts[0])[np.ndim(parts[0]) - tails[0]:])
            return np.array(p, dtype=float).reshape(batch + (one.m * one.k,))
        n = sum(ix.m * ix.k for ix in idx)
        out = np.empty(batch + (n,))
        for p, ix in zip(parts, idx):
            ix.scatter(out, p)
        return out

    # -- the robots together --------------------------------------------------------------
    def point(self, x) -> np.ndarray:
        """The robot state of the formation: every robot's point, shape ``(..., layout.size)``
        (any array namespace)."""
        x = as_floats(x)
        return self.scatter([g.model.point(xg) for g, xg in zip(self.groups, self.gather(x))], "point", x.shape[:-1])

    def initial_memory(self, batch: tuple = ()) -> tuple:
        """Every group's actuation memory before the first step (one entry per group, with the
        group's robot axis after ``batch``; a team of distinct models has one per robot)."""
        return tuple(g.model.initial_memory(tuple(batch) + g.axis) for g in self.groups)

    def actuate(self, x, rate, t: float, memory: tuple):
        """Unsaturated commands ``(..., n)`` for the stacked rates ``rate`` (``(..., n_rate)``)
        and the next memory (one entry per group)."""
        x, rate = as_floats(x), as_floats(rate)
        out = [g.model.actuate(xg, rg, t, mg)
               for g, xg, rg, mg in zip(self.groups, self.gather(x), self.gather(rate, "rate"), memory)]
        batch = np.broadcast_shapes(x.shape[:-1], rate.shape[:-1])
        return self.scatter([u for u, _ in out], "command", batch), tuple(m for _, m in out)

    def brake(self, x, memory: tuple):
        """Commands that stop every robot (unsaturated) and the memory after a brake."""
        x = np.asarray(x, dtype=float)
        out = [g.model.brake(xg, mg) for g, xg, mg in zip(self.groups, self.gather(x), memory)]
        return self.scatter([u for u, _ in out], "command", x.shape[:-1]), tuple(m for _, m in out)

    def limit_factor(self, u) -> np.ndarray:
        """The common factor of a holonomic team: the smallest any robot needs, shape ``(...)``
        (0 where a command is not finite)."""
        xp = namespace(u)
        s = None
        for g, ug in zip(self.groups, self.gather(u, "command")):
            f = g.model.limit_factor(ug)
            if g.axis:
                f = xp.min(f, axis=-1)
            s = f if s is None else xp.minimum(s, f)
        return s

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
        u = as_floats(u)
        if u.shape[-1:] != (self.n,):
            raise InvalidInputError(f"team command must have shape (..., {self.n}), got {u.shape}")
        if not self.common_limit:
            return self.scatter([g.model.saturate(ug) for g, ug in zip(self.groups, self.gather(u, "command"))],
                                "command", u.shape[:-1])
        if u.ndim == 1 and self._float_path and concrete(u):
            return self.saturate_floats(u.tolist())
        s = self.limit_factor(u)
        return namespace(u).where(s[..., None] > 0, u * s[..., None], 0.0)

    def saturate_floats(self, u) -> np.ndarray:
        """:meth:`saturate` of a holonomic team for one command given as Python floats."""
        if not self._float_path:
            return self.saturate(np.array(u, dtype=float))
        s = 1.0
        for rb, sl in zip(self.robots, self.command_slices):
            f = rb.limit_factor_floats(*u[sl])
            if f < s:
                s = f
        return np.array([x * s for x in u]) if s > 0 else np.zeros(self.n)

    def step(self, x, u, dt: float) -> np.ndarray:
        """Team state after ``dt`` s of the command ``u`` (each group's :meth:`step` on the
        team-saturated command; a team of 4-DOF and planar holonomic robots: ``x + dt u``
        with the common factor, exact)."""
        if self._additive:
            x = as_array(x, "r", self.n_state) if concrete(x) else x
            return x + dt * self.saturate(u)
        x = as_floats(x)
        us = self.gather(self.saturate(u), "command")
        return self.scatter([g.model.step(xg, ug, dt) for g, xg, ug in zip(self.groups, self.gather(x), us)],
                            "state")
