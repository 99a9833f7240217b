"""MuJoCo worlds as plants of :func:`quatform.sim.simulate.simulate` (sim layer).

A MuJoCo world is stateful: its ``MjData`` holds positions, velocities, the rotors' filter
states, contacts and the low-level controllers' integrators, none of which fit in the
robot state a formation controller reads. So a physics plant keeps its world and advances
it: ``step(x, u, dt, t)`` takes the state it returned last (it refuses any other: a world
cannot be set back), sends ``u`` to the robots' low-level controllers, runs the physics for
``dt`` and returns the robot state read from it. Such a plant runs one world at a time
(``batchable = False``). It keeps its record for the metrics and the picture: the MuJoCo
positions ``qpos`` at the start of every call (with the call's time) and the contact
monitor's collisions.

* :class:`PairPlant` (:func:`pair_plant`) - two IRIS quadrotors in PX4-like velocity mode
  (seed 000): state and output ``(x, y, z, yaw)`` per robot, commands
  ``(v_x, v_y, v_z, yaw rate)`` per robot in the world frame.
* :class:`UgvUavPlant` (:func:`ugv_uav_plant`) - a Pioneer-like UGV and an IRIS in
  Bebop-like attitude mode (seed 001 §3): state and output the 11 values the seed 001
  controller reads, commands its 6.
* :class:`~quatform.sim.plants.mujoco_team.TeamPlant` (:func:`~quatform.sim.plants.mujoco_team.team_plant`)
  - N quadrotors and Pioneers for a ``robots.Team``; the pair plant is its
  two-quadrotor case (the same world calls, the same numbers).
* :func:`physics_metrics` - the keys a physics run adds to ``metrics.json``;
  :func:`physics_record` - the :class:`~quatform.sim.mujoco_backend.PhysicsRecord` of a run
  (for :func:`quatform.report.physics_render.render_or_fallback`).

MuJoCo itself is imported when a plant is made (:func:`~quatform.sim.mujoco_backend.import_mujoco`),
never when this module is imported.
"""

from __future__ import annotations

import math

import numpy as np

from ...control import UGV_UAV_COMMAND_NAMES, UGV_UAV_MEASURED_NAMES
from ...errors import InvalidInputError, ShapeError
from ...formations.layout import RobotLayout
from ...robots import Bebop
from ...robots.physics import IRIS
from ..mujoco_backend import (
    IRIS_IDENTIFIED_K,
    PHYSICS_LABEL,
    PhysicsRecord,
    PhysicsWorld,
    physics_timestep,
)

__all__ = ["PairPlant", "UgvUavPlant", "WorldPlant", "pair_plant", "physics_metrics", "physics_record", "start_state", "ugv_uav_plant"]

#: Robot state of the seed 000 pair: ``(x, y, z, yaw)`` of each quadrotor.
PAIR_LAYOUT = RobotLayout.uniform("xyz_yaw", 2)


def start_state(x0, n: int, what: str) -> np.ndarray:
    """``x0`` as the start of one world, shape ``(n,)``, finite (one line naming ``what`` otherwise)."""
    x = np.asarray(x0, dtype=float)
    if x.shape != (n,):
        raise ShapeError(f"{what}: x0 must have shape ({n},) (one world: a MuJoCo plant is not batched), "
                         f"got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InvalidInputError(f"{what}: x0 must be finite, got {x.tolist()}")
    return x


class WorldPlant:
    """What every physics plant shares (the pair, the UGV-UAV, the team plant): the world,
    its step, the record."""

    batchable = False

    def __init__(self, world: PhysicsWorld, x0: np.ndarray, timestep: float):
        self.world = world
        self.timestep = timestep
        self.x0 = x0  # the state the world starts in: give it to simulate as x0
        self._x = x0
        self.times: list[float] = []  # time of each step call, s
        self.qpos: list[np.ndarray] = []  # MuJoCo positions at the start of each call
        # the quadrotors' attitudes, motor commands and rotor forces at the start of each call
        self.attitudes: list[np.ndarray] = []
        self.rotor_commands: list[np.ndarray] = []
        self.rotor_forces: list[np.ndarray] = []

    @property
    def output_columns(self) -> tuple[str, ...]:
        return self.state_columns

    def robot_metrics(self) -> dict:
        """Per-robot keys :func:`physics_metrics` adds (none for the seed 000 and 001 plants;
        the team plant's ``robots``)."""
        return {}

    def output(self, x):
        """What a sensor sees: the robot state itself."""
        return x

    def _substeps(self, dt: float) -> int:
        n = round(dt / self.timestep)
        if n < 1 or abs(n * self.timestep - dt) > 1e-9 * dt:
            raise InvalidInputError(f"{type(self).__name__}.step: dt = {dt!r} s is not a whole multiple of the "
                                    f"physics step {self.timestep!r} s; make the plant for this dt "
                                    "(timestep=None picks one)")
        return n

    def step(self, x, u, dt: float, t: float) -> np.ndarray:
        """Send ``u`` and run the physics for ``dt`` s; returns the state read after it.

        ``x`` must be the state this plant returned last (or ``x0``): the world cannot be
        set to another one.
        """
        if x is not self._x and not np.array_equal(x, self._x):
            raise InvalidInputError(f"{type(self).__name__}.step: x is not the state the world is in (a MuJoCo "
                                    "plant advances its own world; step it from the state it returned, "
                                    "starting at plant.x0)")
        n = self._substeps(dt)
        self.times.append(float(t))
        self.qpos.append(self.world.qpos())
        self.attitudes.append(self.world.quad_quaternions())
        self.rotor_commands.append(self.world.rotor_commands())
        self.rotor_forces.append(self.world.rotor_forces())
        self._command(np.asarray(u, dtype=float))
        self.world.step(n)
        self._x = self._read()
        return self._x


class PairPlant(WorldPlant):
    """Two IRIS quadrotors (seed 000 §4.2's robots) in PX4-like velocity mode.

    State and output: ``(x_1, y_1, z_1, theta_1, x_2, y_2, z_2, theta_2)`` (m, rad; the
    yaws continued, not wrapped). Commands: ``(v_x, v_y, v_z, yaw rate)`` per robot in the
    world frame (m/s, rad/s), held for each step; a non-finite entry holds that set point at
    zero (:meth:`PhysicsWorld.command_quad`).
    """

    state_columns = PAIR_LAYOUT.names
    command_columns = tuple(f"{c}{i}" for i in (1, 2) for c in ("v_x", "v_y", "v_z", "yaw_rate"))
    names = ("robot1", "robot2")

    def __init__(self, x0, timestep: float, cascade_options: dict | None = None):
        x = start_state(x0, PAIR_LAYOUT.size, "pair_plant")
        world = PhysicsWorld(quads=[(n, x[PAIR_LAYOUT.slice(i)][0:3], x[PAIR_LAYOUT.slice(i)][3])
                                    for i, n in enumerate(self.names)], timestep=timestep,
                             cascade_options=cascade_options)
        for i, n in enumerate(self.names):
            world.continue_yaw(n, x[PAIR_LAYOUT.slice(i)][3])  # yaws continued from the start's, not wrapped
        super().__init__(world, x, timestep)

    def _command(self, u):
        self.world.command_quads(u.reshape(2, 4))

    def _read(self):
        return self.world.quad_states().ravel()  # both at once, as the team plant reads them

    def robot_points(self, states) -> dict:
        """Robot name -> ``(T, 3)`` positions of ``states`` ``(T, 8)`` (the quadrotors' centres)."""
        p = PAIR_LAYOUT.positions(np.asarray(states, dtype=float))
        return {n: p[:, i] for i, n in enumerate(self.names)}


class UgvUavPlant(WorldPlant):
    """A Pioneer-like UGV and an IRIS in Bebop-like attitude mode (seed 001 §3).

    State and output: the 11 values of :data:`~quatform.control.UGV_UAV_MEASURED_NAMES`
    (the UGV's control point and heading, the UAV's pose and its body-frame velocity, the
    yaw rate about the world z axis). Commands: :data:`~quatform.control.UGV_UAV_COMMAND_NAMES`
    (the UGV's ``(v, omega)``, the UAV's ``(u_x, u_y, u_z, u_psi)`` fractions).

    Attributes
    ----------
    uav_model : Bebop
        The UAV model for the controller's dynamic compensation (seed 001 eq. (4.47)):
        ``K1..K8`` identified from this quadrotor (:data:`IRIS_IDENTIFIED_K`) and the
        scenario's ``max_fraction``.
    platform_z : float
        Height at which the UGV's point is drawn (the scenario's ``center`` z), m.
    """

    state_columns = UGV_UAV_MEASURED_NAMES
    command_columns = UGV_UAV_COMMAND_NAMES

    def __init__(self, x0, floor: float, timestep: float, uav_model: Bebop, platform_z: float):
        x = start_state(x0, len(UGV_UAV_MEASURED_NAMES), "ugv_uav_plant")
        z0 = max(x[5], floor + IRIS.leg_height)  # standing on its skids, not in the floor
        world = PhysicsWorld(quads=[("uav", (x[3], x[4], z0), x[6])], ugvs=[("ugv", x[0:2], x[2])],
                             floor_z=floor, timestep=timestep, quad_mode="attitude")
        self.uav_model, self.platform_z, self.floor = uav_model, float(platform_z), float(floor)
        super().__init__(world, None, timestep)
        self.x0 = self._x = self._read()

    def _command(self, u):
        self.world.command_ugv("ugv", u[0:2])
        self.world.command_quad("uav", u[2:6])

    def _read(self):
        w = self.world
        _, v, R, omega, _ = w.quad_pose("uav")
        s = w.quad_state("uav")
        c, si = math.cos(s[3]), math.sin(s[3])
        psi_dot = float(R[2, :] @ omega)  # world z component of the body rate
        return np.r_[w.ugv_state("ugv"), s, c * v[0] + si * v[1], -si * v[0] + c * v[1], v[2], psi_dot]

    def robot_points(self, states) -> dict:
        """Robot name -> ``(T, 3)`` positions of ``states`` ``(T, 11)``: the UGV's control point
        at the platform height, the UAV's centre."""
        s = np.asarray(states, dtype=float)
        return {"ugv": np.c_[s[:, 0:2], np.full(len(s), self.platform_z)], "uav": s[:, 3:6]}


def pair_plant(scenario, x0, timestep: float | None = None, cascade_options: dict | None = None) -> PairPlant:
    """The two-quadrotor plant for a seed 000 scenario.

    Parameters
    ----------
    scenario : Scenario
        Its ``dt_s`` sets the physics step when ``timestep`` is None.
    x0 : array_like, shape (8,)
        Start ``(x, y, z, yaw)`` of each robot, m and rad.
    timestep : float, optional
        Physics step, s (default: the largest up to 2.5 ms dividing ``dt_s``).
    cascade_options : dict, optional
        Keyword arguments of :class:`~quatform.robots.physics.QuadrotorCascade`.
    """
    if timestep is not None and not (isinstance(timestep, int | float) and math.isfinite(timestep) and timestep > 0):
        raise InvalidInputError(f"pair_plant: timestep must be a positive number of seconds, got {timestep!r}")
    h = physics_timestep(scenario.dt_s) if timestep is None else float(timestep)
    return PairPlant(x0, h, cascade_options)


def ugv_uav_plant(scenario, x0, floor: float, k=IRIS_IDENTIFIED_K) -> UgvUavPlant:
    """The UGV + quadrotor plant for a seed 001 scenario.

    Parameters
    ----------
    scenario : UgvUavScenario
        Its ``dt_s`` sets the physics step; ``max_fraction`` and ``center`` the UAV model
        and the platform height.
    x0 : array_like, shape (11,)
        The start of the kinematic run (the UAV is raised onto its skids where it would be
        in the floor); the plant's own start is ``plant.x0`` (read from the physics).
    floor : float
        Floor height, m.
    k : 8 floats
        ``K1..K8`` of the UAV model the controller compensates (``plant.uav_model``).
    """
    return UgvUavPlant(x0, floor, physics_timestep(scenario.dt_s),
                       Bebop(k=tuple(k), max_fraction=scenario.max_fraction), scenario.center[2])


def physics_metrics(plant: WorldPlant) -> dict:
    """``{"physics", "collisions", "physics_timestep_s"}`` of a run of ``plant``, and ``robots``
    (each robot's kind, tilt, thrust and collisions) for a
    :class:`~quatform.sim.plants.mujoco_team.TeamPlant`."""
    return {"physics": "mujoco", "collisions": plant.world.contacts.summary(), "physics_timestep_s": plant.timestep,
            **plant.robot_metrics()}


def physics_record(plant: WorldPlant, log, title: str = "", gains: dict | None = None,
                   gains_source: str = "") -> PhysicsRecord:
    """The :class:`PhysicsRecord` of a run of ``plant`` (its :class:`~quatform.sim.log.Log`:
    ``log``): the MuJoCo positions and robot points at the log's ticks, the collisions."""
    t = np.asarray(log.t, dtype=float)
    times = np.asarray(plant.times, dtype=float)
    q = np.asarray(plant.qpos, dtype=float).reshape(len(times), plant.world.model.nq)
    if len(times):
        tol = 1e-6 * max(plant.timestep, 1e-12)
        idx = np.clip(np.searchsorted(times, t - tol), 0, len(times) - 1)
        ok = np.abs(times[idx] - t) <= tol
        n = int(np.argmin(ok)) if not ok.all() else len(t)  # ticks the plant was stepped from
        idx = idx[:n]
    else:
        idx, n = np.zeros(0, dtype=int), 0
    points = plant.robot_points(log["state"][:n])
    n_quads = len(plant.world.quad_names)

    def at_ticks(rows):
        return np.asarray(rows, dtype=float).reshape(len(times), n_quads, 4)[idx]

    return PhysicsRecord(plant.world.xml, t[:n], q[idx], points, plant.world.contacts.summary(), plant.timestep,
                         dict(gains or {}), gains_source, title, PHYSICS_LABEL, tuple(plant.world.quad_names),
                         at_ticks(plant.attitudes), at_ticks(plant.rotor_commands), at_ticks(plant.rotor_forces))
