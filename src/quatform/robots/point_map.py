"""How a robot model's commands move its point: what the separation barrier reads and writes.

Robots layer. The separation barrier (:class:`~quatform.control.safety.SeparationBarrier`,
Wang, Ames and Egerstedt 2017, with the Robotarium's single-integrator certificate) keeps
the robots' points apart by changing their point velocities; a robot model says how its
commands map to that velocity and back through its :attr:`RobotModel.point_map
<quatform.robots.model.RobotModel.point_map>` (None: its commands are no such map, e.g. the
Bebop with its dynamic compensation, and the barrier refuses it). A :class:`PointMap` offers

* ``velocity(model, x, u, dt)``: the point's velocity, m/s, ``(..., 3)`` (a planar point's z
  entry 0), the instantaneous one (``dt`` None) or the mean over a command held ``dt`` s; on
  NumPy and JAX arrays alike;
* ``commands(model, x, u, v, dt)``: the commands that move the point at ``v`` (the entries
  that do not move it, a yaw rate or an angular velocity, kept from ``u``);
* ``scaled(model, x, u_new, v, s, dt)``: the commands of the point velocity ``s v``
  (``s`` in ``(0, 1]``, the limit factor);
* ``factor(model, x, u_new, v, dt)``: the largest ``s`` in ``[0, 1]`` with
  ``scaled(..., s, ...)`` within the model's limits;
* ``planar``: whether the point moves at a fixed height (its z velocity is not a variable).

:class:`VelocityCommands` is the map of a model whose first commands are its point's
velocity (the 4-DOF and planar holonomic robots, a free body's linear velocity); the
Pioneer's control point has its own (:class:`~quatform.robots.pioneer.UnicyclePointMap`,
seed 001 eqs. (3.4)-(3.5)). Every array takes leading batch axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace

__all__ = ["PointMap", "VelocityCommands"]


class PointMap:
    """The point-velocity map of a robot model (see the module docstring)."""

    #: Whether the point moves at a fixed height (its z velocity is 0 and not a variable).
    planar: bool = False

    def velocity(self, model, x, u, dt):
        """The point's velocity, m/s, shape ``(..., 3)``."""
        raise NotImplementedError

    def commands(self, model, x, u, v, dt):
        """Commands, shape of ``u``, that move the point at ``v`` (``(..., 3)``, m/s)."""
        raise NotImplementedError

    def scaled(self, model, x, u_new, v, s, dt):
        """The commands of the point velocity ``s v`` (``s``: the batch shape)."""
        raise NotImplementedError

    def factor(self, model, x, u_new, v, dt):
        """The largest ``s`` in ``[0, 1]`` whose :meth:`scaled` commands are within the limits."""
        raise NotImplementedError


@dataclass(frozen=True)
class VelocityCommands(PointMap):
    """A model whose first commands are its point's world velocity: the first three entries
    (``planar``: the first two, at z rate 0); the others (a yaw rate, an angular velocity)
    pass. Scaling the commands scales the velocity, so the limit factor is the model's
    ``limit_factor(u)``.
    """

    planar: bool = False

    def velocity(self, model, x, u, dt):
        if not self.planar:
            return u[..., 0:3]
        xp = array_namespace(u)
        return xp.concatenate([u[..., 0:2], xp.zeros(u.shape[:-1] + (1,))], axis=-1)

    def commands(self, model, x, u, v, dt):
        d = 2 if self.planar else 3
        return np.concatenate([v[..., 0:d], u[..., d:]], axis=-1)

    def scaled(self, model, x, u_new, v, s, dt):
        return s[..., None] * u_new

    def factor(self, model, x, u_new, v, dt):
        return model.limit_factor(u_new)
