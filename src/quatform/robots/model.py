"""The robot-model contract: what a robot offers a formation and how it is commanded.

Robots layer (above formations). DQ Robotics' ``DQ_Kinematics`` is the model: any law works
with any robot, because the robot, the task (the formation) and the law are independent
axes. A robot model says

* ``point_kind``: the point it offers a formation (a
  :data:`~quatform.formations.layout.POINT_KINDS` key: a holonomic 4-DOF robot offers
  ``xyz_yaw``; the Pioneer 3-DX its control point; the Bebop 2 its position ``xyz``, its yaw
  being controlled outside the formation, seed 001 §4.3.3);
* ``state_columns`` / ``command_columns``: its own state and commands;
* ``point(x)``: the point of its state ``x``;
* ``actuate(x, rate, t, memory) -> (u, memory)``: how a rate of its point (and, for a robot
  whose yaw is outside the formation, the yaw rate appended) becomes its commands (identity;
  Pioneer seed 001 eq. (3.5); Bebop eq. (3.10) with the dynamic compensation (4.47), whose
  differentiated reference is the ``memory`` carried in the controller's state);
* ``saturate(u)``: commands within its limits, finite;
* ``step(x, u, dt) -> x``: its own motion for a held command (the kinematic plant);
* in a :class:`Team` also ``n_rate`` (entries of the rate ``actuate`` takes),
  ``initial_memory(batch)`` and ``brake(x, memory) -> (u, memory)`` (the actuation memory
  before the first step; commands that stop the robot);
* ``point_map``: how its commands move its point, for the separation barrier
  (:mod:`.point_map`); ``physics_kind``: the physical robot MuJoCo simulates it as;
* ``passthrough``: whether its commands are its point's rates (a controller may skip
  ``actuate``); ``holonomic``: whether its commands scale as a whole, with a
  ``limit_factor(u)`` (the largest ``s`` in ``[0, 1]`` with ``s u`` within the limits), so a
  team may saturate all its robots by one factor.

A :class:`Team` is a tuple of models and the :class:`~quatform.formations.layout.RobotLayout`
of the points they offer. Every method takes leading batch axes.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..errors import InvalidInputError
from ..registry import Registry

__all__ = ["RobotModel", "ROBOT_MODELS", "file_models", "column_unit", "column_entries"]

#: Every robot model class by its :attr:`RobotModel.name` (filled when a subclass is defined).
ROBOT_MODELS = Registry("robot model")


class RobotModel:
    """Base class of a robot model (see the module docstring).

    A subclass that sets :attr:`name` registers itself in :data:`ROBOT_MODELS` when it is
    defined, with what it knows besides its motion: the ``model`` values of a team file's
    ``[[robots]]`` entry it answers to (:attr:`file_names`, its limit keys
    :attr:`limit_keys`, :meth:`from_file`), its ROS 2 conversions (:attr:`ros_io`, a
    :class:`~quatform.robots.ros_io.RobotIO`: a measured pose to its state, its commands to
    twists), its point velocity for the separation barrier (:attr:`point_map`) and the
    physical robot MuJoCo simulates it as (:attr:`physics_kind`).
    """

    name: ClassVar[str] = ""
    point_kind: ClassVar[str] = ""
    state_columns: tuple
    command_columns: tuple
    passthrough: ClassVar[bool] = False
    holonomic: ClassVar[bool] = False
    #: The ``model`` values of a team file's ``[[robots]]`` entry that build this model.
    file_names: ClassVar[tuple] = ()
    #: The limit keys such an entry may hold (read by :meth:`from_file`).
    limit_keys: ClassVar[tuple] = ()
    #: Its ROS 2 conversions (None: the bridge does not drive it).
    ros_io: ClassVar[Any] = None
    #: How its commands move its point, for the separation barrier (a
    #: :class:`~quatform.robots.point_map.PointMap`; None: the barrier refuses it).
    point_map: ClassVar[Any] = None
    #: The physical robot the MuJoCo team plant simulates it as (``"quadrotor"``,
    #: ``"diff-drive"``: :mod:`quatform.sim.plants.mujoco_team`; None: MuJoCo cannot).
    physics_kind: ClassVar[str | None] = None
    #: The unit of each of its state and command columns (``"-"``: dimensionless).
    column_units: ClassVar[dict] = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("name"):
            ROBOT_MODELS.add(cls.name, cls)

    @classmethod
    def from_file(cls, table: dict, where: str, place: str, file_name: str):
        """The model of a team file's ``[[robots]]`` entry ``table`` whose ``model`` is
        ``file_name`` (one of :attr:`file_names`), its :attr:`limit_keys` read strictly."""
        raise NotImplementedError(f"{cls.__name__} is not read from team files")

    def state_entries(self, *names: str, start: int = 0):
        """Where its state columns ``names`` sit in an array whose entries from ``start`` on are
        its state (a team's stacked state: :meth:`~quatform.robots.Team.state_entries`):
        :func:`column_entries`."""
        return column_entries(self.state_columns, names, start)

    def command_entries(self, *names: str, start: int = 0):
        """Where its command columns ``names`` sit in an array whose entries from ``start`` on
        are its commands: :func:`column_entries`."""
        return column_entries(self.command_columns, names, start)

    def point(self, x) -> np.ndarray:
        """The point this robot offers a formation, shape ``(..., size of point_kind)``."""
        raise NotImplementedError

    def actuate(self, x, rate, t: float, memory: Any) -> tuple[np.ndarray, Any]:
        """Commands (shape ``(..., len(command_columns))``) that move the point at ``rate``."""
        raise NotImplementedError

    def saturate(self, u) -> np.ndarray:
        """``u`` within the robot's limits; a non-finite command becomes a stop."""
        raise NotImplementedError

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` s of the (saturated) command ``u``."""
        raise NotImplementedError


def column_unit(model, column: str) -> str:
    """The unit of ``model``'s state or command ``column`` (its class's :attr:`RobotModel.column_units`;
    ``"-"``: dimensionless or unknown)."""
    return getattr(model, "column_units", {}).get(column, "-")


def column_entries(columns: tuple, names: tuple, start: int = 0):
    """Where ``names`` (of ``columns``) sit in an array whose entries from ``start`` on are
    ``columns``: an int for one name, a slice for consecutive ones (in their order).

    Raises
    ------
    InvalidInputError
        A name not among ``columns``, or names that are not consecutive there.
    """
    missing = [n for n in names if n not in columns]
    if missing or not names:
        raise InvalidInputError(f"column {missing[0]!r} is not among {columns}" if missing else
                                f"no column named; choose from {columns}")
    idx = [start + columns.index(n) for n in names]
    if len(idx) == 1:
        return idx[0]
    if idx != list(range(idx[0], idx[0] + len(idx))):
        raise InvalidInputError(f"columns {names} are not consecutive in {columns}")
    return slice(idx[0], idx[-1] + 1)


def file_models() -> dict:
    """The models a team file's ``[[robots]] model`` names: ``{file name: model class}``."""
    return {fn: cls for cls in ROBOT_MODELS.values() for fn in cls.file_names}
