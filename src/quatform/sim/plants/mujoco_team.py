"""A MuJoCo world for a team of N robots: a plant of :func:`quatform.sim.simulate.simulate` (sim layer).

:func:`team_plant` makes one physics world for a :class:`~quatform.robots.Team`: each
:class:`~quatform.robots.HolonomicRobot` (a 4-DOF ``xyz_yaw`` robot) is flown as an
IRIS-like quadrotor in PX4-like velocity mode (the pair plant's model and cascade), each
:class:`~quatform.robots.Pioneer` is driven as the Pioneer 3-DX-like differential-drive
robot of the UGV-UAV plant (each model's :attr:`~quatform.robots.RobotModel.physics_kind`). The plant has the interface of
:class:`~quatform.sim.plants.KinematicTeam`: state and output the team's stacked robot
state (``team.state_columns``: a quadrotor's ``(x, y, z, theta)`` with its yaw continued,
a Pioneer's control point and heading ``(x, y, psi)``), commands the team's commands
(``team.command_columns``: a quadrotor's world velocity and yaw rate, a Pioneer's
``(v, omega)``). Like every MuJoCo plant it advances its own world (``batchable = False``;
:class:`~quatform.sim.plants.mujoco.PairPlant` is its two-quadrotor case, step for step).

The quadrotors' cascades run together on ``(N, ...)`` arrays
(:class:`~quatform.robots.physics.QuadrotorCascades`: one physics step costs a constant
number of NumPy calls whatever N) from :data:`~quatform.sim.mujoco_backend.VECTORISED_FROM`
quadrotors on, one per vehicle on Python floats below (faster there; the same forces to
rounding). :func:`~quatform.sim.plants.mujoco.physics_metrics` of a
team plant adds ``robots``: per robot its kind, largest tilt and collective rotor force
(quadrotors) and its collisions; :func:`~quatform.sim.plants.mujoco.physics_record` works
as for the pair.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...errors import InvalidInputError
from ...robots import ROBOT_MODELS, Team
from ...robots.physics import PIONEER_3DX
from ..mujoco_backend import PhysicsWorld, physics_timestep
from .mujoco import WorldPlant, start_state

__all__ = ["TeamPlant", "physics_kinds", "simulated_models", "team_plant"]

def simulated_models() -> dict:
    """The registered robot model classes the MuJoCo physics simulates, each with its
    :attr:`~quatform.robots.RobotModel.physics_kind`: ``"quadrotor"`` (an IRIS in PX4-like
    velocity mode, state ``(x, y, z, theta)``, commands ``(v_x, v_y, v_z, omega_z)``) or
    ``"diff-drive"`` (a Pioneer 3-DX, state its control point and heading, commands ``(v,
    omega)``)."""
    return {cls: cls.physics_kind for cls in ROBOT_MODELS.values() if cls.physics_kind is not None}


def physics_kinds(team: Team, what: str = "team_plant") -> list:
    """Each robot's :attr:`~quatform.robots.RobotModel.physics_kind`; a robot the MuJoCo physics cannot simulate
    (or a ``team`` that is not a :class:`~quatform.robots.Team`) is one line naming it."""
    if not isinstance(team, Team):
        raise InvalidInputError(f"{what}: team must be a quatform.robots.Team, got {type(team).__name__}")
    kinds = []
    for i, robot in enumerate(team.robots):
        kind = robot.physics_kind
        if kind is None:
            raise InvalidInputError(
                f"{what}: robot {i + 1} is a {type(robot).__name__} (point kind {robot.point_kind!r}), which the "
                f"MuJoCo physics cannot simulate; use {' or '.join(c.__name__ for c in simulated_models())} models "
                "(a quadrotor, a Pioneer 3-DX) or the kinematic physics (--physics kinematic)")
        kinds.append(kind)
    return kinds


def _indices(slices, picks, width: int) -> np.ndarray:
    """Entries of the stacked array that robots ``picks`` hold, shape ``(len(picks), width)``."""
    return np.array([list(range(slices[i].start, slices[i].stop)) for i in picks], dtype=int).reshape(-1, width)


class TeamPlant(WorldPlant):
    """N quadrotors and ground robots in one MuJoCo world (see the module docstring).

    Parameters
    ----------
    team : Team
        Its robots' models, each with a ``physics_kind``.
    x0 : array_like, shape (team.n_state,)
        The start: every quadrotor's ``(x, y, z, theta)`` (m, rad), every Pioneer's
        control point and heading.
    timestep : float
        Physics step, s.
    cascade_options : dict, optional
        Keyword arguments of :class:`~quatform.robots.physics.QuadrotorCascade`.
    floor_z : float, optional
        Ground height, m; default: the Pioneers' platform height ``Pioneer.z`` less the
        platform's 0.3 m over the floor (seed 001), or 0 without Pioneers.
    cascades : str
        :data:`~quatform.sim.mujoco_backend.CASCADE_MODES`: the quadrotors' cascades all at
        once on arrays, one per vehicle, or ``"auto"`` (whichever is faster for N).

    Attributes
    ----------
    team : Team
    kinds : tuple of str
        Each robot's ``physics_kind``.
    names : tuple of str
        ``robot1 ... robotN`` (the world's body names, the record's robots).
    """

    def __init__(self, team: Team, x0, timestep: float, cascade_options: dict | None = None,
                 floor_z: float | None = None, cascades: str = "auto", what: str = "team_plant"):
        kinds = physics_kinds(team, what)
        x = start_state(x0, team.n_state, what)
        self.team, self.kinds = team, tuple(kinds)
        self.names = tuple(f"robot{i + 1}" for i in range(len(kinds)))
        quads = [i for i, k in enumerate(kinds) if k == "quadrotor"]
        ugvs = [i for i, k in enumerate(kinds) if k == "diff-drive"]
        self._qx = _indices(team.state_slices, quads, 4)
        self._gx = _indices(team.state_slices, ugvs, 3)
        self._qu = _indices(team.command_slices, quads, 4)
        self._gu = _indices(team.command_slices, ugvs, 2)
        pioneers = [team.robots[i] for i in ugvs]
        for name in ("a", "z"):
            values = sorted({getattr(p, name) for p in pioneers})
            if len(values) > 1:
                raise InvalidInputError(f"{what}: the Pioneers' {name} differ ({values}); one world has one "
                                        "floor and one Pioneer model: give them the same value")
        self._platform_z = pioneers[0].z if pioneers else 0.0
        if floor_z is None:
            floor_z = self._platform_z - PIONEER_3DX.platform_height if pioneers else 0.0
        elif not (isinstance(floor_z, int | float) and math.isfinite(floor_z)):
            raise InvalidInputError(f"{what}: floor_z must be a finite height, m, got {floor_z!r}")
        ugv_params = dataclasses.replace(PIONEER_3DX, a=pioneers[0].a) if pioneers else PIONEER_3DX
        r = [x[s] for s in team.state_slices]
        world = PhysicsWorld(quads=[(self.names[i], r[i][0:3], r[i][3]) for i in quads],
                             ugvs=[(self.names[i], r[i][0:2], r[i][2]) for i in ugvs], floor_z=float(floor_z),
                             timestep=timestep, ugv_params=ugv_params, cascade_options=cascade_options,
                             cascades=cascades)
        world.track_quads = True  # each quadrotor's tilt and thrust for robot_metrics
        for i in quads:
            world.continue_yaw(self.names[i], r[i][3])  # yaws continued from the start's, not wrapped
        for i in ugvs:
            world.continue_yaw(self.names[i], r[i][2])
        self.floor_z = float(floor_z)
        super().__init__(world, x, timestep)

    @property
    def state_columns(self) -> tuple[str, ...]:
        return self.team.state_columns

    @property
    def command_columns(self) -> tuple[str, ...]:
        return self.team.command_columns

    def _command(self, u):
        if u.shape != (self.team.n,):
            raise InvalidInputError(f"{type(self).__name__}.step: u must have shape ({self.team.n},) (one world), "
                                    f"got {u.shape}")
        if len(self._qu):
            self.world.command_quads(u[self._qu])
        if len(self._gu):
            self.world.command_ugvs(u[self._gu])

    def _read(self):
        x = np.empty(self.team.n_state)
        if len(self._qx):
            x[self._qx] = self.world.quad_states()
        if len(self._gx):
            x[self._gx] = self.world.ugv_states()
        return x

    def robot_points(self, states) -> dict:
        """Robot name -> ``(T, 3)`` positions of ``states`` ``(T, team.n_state)``: the quadrotors'
        centres, the Pioneers' control points at their platform height."""
        s = np.asarray(states, dtype=float)
        out = {}
        qi, gi = iter(self._qx), iter(self._gx)
        for name, kind in zip(self.names, self.kinds):
            if kind == "quadrotor":
                out[name] = s[:, next(qi)[0:3]]
            else:
                g = next(gi)
                out[name] = np.c_[s[:, g[0:2]], np.full(len(s), self._platform_z)]
        return out

    def robot_metrics(self) -> dict:
        """``{"robots": {name: {...}}}``: each robot's kind and collisions (episodes it took part
        in); a quadrotor's largest tilt (rad) and collective rotor force (N, and as a fraction
        of the four rotors' most), sampled at every control tick."""
        w = self.world
        events = [set(pair.split("/")) for _, pair in w.contacts.events]
        tilt = np.arccos(np.clip(w.min_cos_tilt, -1.0, 1.0))
        f_all = 4.0 * w.quad_params.max_thrust
        robots, q = {}, 0
        for name, kind in zip(self.names, self.kinds):
            m = {"kind": kind, "collisions": sum(name in e for e in events)}
            if kind == "quadrotor":
                m.update(max_tilt_rad=float(tilt[q]), max_thrust_n=float(w.max_thrust[q]),
                         max_thrust_fraction=float(w.max_thrust[q] / f_all))
                q += 1
            robots[name] = m
        return {"robots": robots}


def team_plant(team: Team, x0, *, dt: float, timestep: float | None = None, cascade_options: dict | None = None,
               floor_z: float | None = None, cascades: str = "auto") -> TeamPlant:
    """The MuJoCo plant of ``team`` (see the module docstring).

    Parameters
    ----------
    team : Team
        :class:`~quatform.robots.HolonomicRobot` models (quadrotors) and
        :class:`~quatform.robots.Pioneer` models (ground robots), in any order.
    x0 : array_like, shape (team.n_state,)
        The start (``plant.x0``): give it to :func:`~quatform.sim.simulate.simulate`.
    dt : float
        The plant step the run calls ``step`` with, s; sets the physics step when
        ``timestep`` is None (the largest up to 2.5 ms that divides it).
    timestep : float, optional
        Physics step, s; must divide ``dt``.
    cascade_options : dict, optional
        Keyword arguments of :class:`~quatform.robots.physics.QuadrotorCascade`.
    floor_z : float, optional
        Ground height, m (default: see :class:`TeamPlant`).
    cascades : str
        ``"auto"`` (default), ``"vectorised"`` or ``"per-vehicle"`` (see :class:`TeamPlant`).
    """
    h = physics_timestep(dt)
    if timestep is not None:
        if not (isinstance(timestep, int | float) and math.isfinite(timestep) and timestep > 0):
            raise InvalidInputError(f"team_plant: timestep must be a positive number of seconds, got {timestep!r}")
        n = round(dt / timestep)
        if n < 1 or abs(n * timestep - dt) > 1e-9 * dt:
            raise InvalidInputError(f"team_plant: timestep {timestep!r} s does not divide dt = {dt!r} s; give a "
                                    "divisor of dt, or timestep=None")
        h = float(timestep)
    return TeamPlant(team, x0, h, cascade_options, floor_z, cascades)
