"""MuJoCo physics backend: the same controllers drive physical robots (issues 7, 13).

Sim layer. MuJoCo is optional: it is imported only when a physics world is made
(:func:`import_mujoco`), never when quatform is imported; without it a physics run
raises :class:`~quatform.errors.MissingDependencyError` naming
``pip install -e ".[mujoco]"`` (run in the quatform checkout: :data:`INSTALL_HINT`).

## Plants

The worlds are plants of :func:`quatform.sim.simulate.simulate` (``batchable = False``;
``step(x, u, dt, t)`` advances the world from the state it returned last and returns the
state read from it), in :mod:`quatform.sim.plants.mujoco`:

* ``pair_plant(scenario, x0, timestep=None, cascade_options=None) -> PairPlant``: two IRIS
  quadrotors in PX4-like velocity mode; ``x0`` (8,) = ``(x, y, z, yaw)`` per robot; state
  and output columns ``x1 y1 z1 theta1 x2 y2 z2 theta2``; commands ``(v_x, v_y, v_z, yaw
  rate)`` per robot. Run: ``simulate(plant, ctrl, ref, scenario.times, x0, dt=scenario.dt_s)``.
* ``ugv_uav_plant(scenario, x0, floor, k=IRIS_IDENTIFIED_K) -> UgvUavPlant``: a Pioneer-like
  UGV and an IRIS in Bebop-like attitude mode; ``x0`` (11,) the kinematic start, ``floor``
  the floor height; the world's own start is ``plant.x0`` (pass that to simulate); the
  controller compensates ``plant.uav_model`` (a ``Bebop`` with ``k`` and the scenario's
  ``max_fraction``); columns ``UGV_UAV_MEASURED_NAMES``; commands ``UGV_UAV_COMMAND_NAMES``.
  Run with ``dt=scenario.dt_s, substeps=round(control_period_s / dt_s)`` and the motion capture.
* ``physics_metrics(plant) -> {"physics": "mujoco", "collisions": {...}, "physics_timestep_s"}``.
* ``physics_record(plant, log, title="", gains=None, gains_source="") -> PhysicsRecord``:
  ``record.metrics()`` gives ``gains``, ``gains_source``, ``gains_source_note``,
  ``physics_timestep_s``; the picture is
  ``quatform.report.physics_render.render_or_fallback(record, log, path) -> (path, how)``.
* ``physics_controller(scenario, controller, feedforward=None, gains=None) -> (ctrl, gains,
  source)`` (here): the seed 000 controller of a physics run (a name gets
  ``physics_controller_gains(scenario, controller_name) -> (gains, source)``:
  :data:`PHYSICS_GAINS` in place of Table 1; an object runs as it is), the gains to record
  (``pair_controller_gains(ctrl)``, ``feedforward`` included) and their source.
  ``ugv_uav_controller_gains(controller, source="scenario") -> (gains, source)``: a seed 001
  controller's settings as recorded.

A physics run is one run of its plant: it does not re-run the kinematic simulation
(comparing them is a compare over the physics option).

This module holds what the plants are made of:

* :class:`PhysicsWorld` - the MJCF world of quadrotors and differential-drive robots
  (:mod:`quatform.robots.physics`), stepped with their low-level controllers in the
  loop, with a :class:`ContactMonitor` that reports collisions.
* the kinds run their plants themselves (``quatform.scenarios.pair.PairChartParts``,
  ``quatform.scenarios.ugv_uav.mujoco_experiment``).
* :func:`identify_k` - ``K1..K8`` of the quadrotor in Bebop-like attitude mode (seed 001
  eq. (3.11)) for the controller's dynamic compensation (4.47).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..algebra import wrap_angle
from ..control import CONTROLLERS, TABLE1, TABLE2
from ..errors import InvalidInputError, MissingDependencyError, NonFiniteError
from ..robots.physics import (
    GRAVITY,
    IRIS,
    PIONEER_3DX,
    DiffDriveParams,
    QuadrotorCascade,
    QuadrotorCascades,
    QuadrotorParams,
    diff_drive_mjcf,
    quadrotor_mjcf,
    rotation_rows,
    wheel_speeds,
    world_mjcf,
)

__all__ = ["CASCADE_MODES", "GAINS_SOURCES", "INSTALL_HINT", "IRIS_IDENTIFIED_K", "PHYSICS_GAINS", "PHYSICS_LABEL",
           "UGV_UAV_GAIN_NAMES", "VECTORISED_FROM", "ContactMonitor", "PhysicsRecord", "PhysicsWorld", "identify_k",
           "import_mujoco", "pair_controller_gains", "physics_controller", "physics_controller_gains", "physics_gains", "physics_timestep",
           "ugv_uav_controller_gains"]

#: How figures and tables name this physics (``PhysicsRecord.physics_label``).
PHYSICS_LABEL = "MuJoCo physics"

#: ``K1..K8`` of seed 001 eq. (3.11) identified from the simulated IRIS in Bebop-like
#: attitude mode by :func:`identify_k` (steps and chirps, least squares; see
#: ``docs/physics.md``). K1 = K3 follow from the chosen 5 deg tilt, K5, K6 from the climb
#: loop's gain and full scale, K7, K8 from the yaw-rate loop's; only K2 = K4 (rotor drag over
#: mass) is a physical result.
IRIS_IDENTIFIED_K = (0.8058, 0.1709, 0.8058, 0.1709, 3.856, 3.784, 9.565, 4.663)

#: Seed 000 gains for two IRIS quadrotors, used by :func:`simulate_physics` where a
#: scenario asks for Table 1 (seed 000 §4.1: kinematic MATLAB robots). Table 1's loops are
#: up to 20 1/s fast; the quadrotor follows a velocity command through its PX4-like PI
#: velocity loop (1.8, 0.4: a lag of ~0.55 s), so a proportional outer loop on it has a
#: decay rate of at most ~1/(2 x 0.55 s) = 0.9 1/s whatever its gain, and gains well above
#: ~1 1/s ring (Table 1's k_d = 20 limit-cycles ``d_c`` by ~0.8 m at ~0.5 Hz). Seed 000
#: Table 2 (§4.2) is what the paper flew on the Gazebo IRIS, gains 0.02-1 1/s; they are
#: made for the slow helix (time constants up to 50 s) and are kept for it. These sit
#: between the two: for each controller the gains that best settle the 180 deg formation
#: yaw step of ``mas-kitts-yaw-step`` (seed 000 Fig. 4) by ``metrics_from_s`` without
#: ringing, found by a grid search on this physics model (``docs/physics.md``, "Gains on
#: physics"); the centroid gains are 1 1/s. The dual-quaternion controller's three gains
#: act on both parts of each error dual quaternion (seed 000 eq. (28)): z turns the
#: formation and the robots' headings (1.0 is 0.4 rad off at 5 s; up to 2.0 holds, the
#: shape ballooning more), x settles the end of the turn (1.25 is still 0.14 rad off at
#: 5 s, 1.75 overshoots more), y pulls in the separation that the velocity lag swings
#: outwards while turning (with 3 half of it grows by 0.63 m and is 0.11 rad off at 5 s, with
#: 7 by 0.49 m, back within 0.02 m by 5 s). Seed 000 Table 2 and a scenario's own
#: ``[gains]`` reach the physics unchanged.
PHYSICS_GAINS = {
    "cluster-space": {"k": [1.0, 1.0, 1.0, 0.55, 0.55, 5.0, 1.5, 1.5]},  # (x, y, z, beta, gamma, d, phi1, phi2)
    "robot-space": {"k": [1.5, 1.5, 1.5, 2.0, 2.0, 1.5, 1.5, 1.5]},  # Table 1 capped at 2 1/s
    "quaternion": {"k_x": [1.0, 1.0, 1.0], "k_d": 5.0, "k_w": [1.3, 1.3, 1.3]},
    "dual-quaternion": {"k_dw": [1.5, 7.0, 1.5]},  # (x, y, z) parts: z turns, x settles, y holds the shape
}

#: ``gains_source`` of a physics run: where its gains came from.
GAINS_SOURCES = {
    "physics": "quatform's PHYSICS_GAINS for the MuJoCo IRIS, in place of the scenario's seed 000 Table 1",
    "table2": "seed 000 Table 2 (the paper's ROS/Gazebo IRIS gains), as the scenario asks",
    "scenario": "the scenario's gains (its [gains] over the controller's defaults)",
    "argument": "the gains passed to the physics run",
    "controller": "the controller object passed to the physics run",
}


def _plain(value):
    """A gain as JSON-ready numbers (float or list of floats; bools stay bools)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    a = np.asarray(value, dtype=float)
    return a.tolist() if a.ndim else float(a)


def _same_gains(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.shape(a[k]) == np.shape(b[k]) and
                                    np.array_equal(np.asarray(a[k], float), np.asarray(b[k], float)) for k in a)


def physics_controller_gains(scenario, controller_name: str) -> tuple[dict, str]:
    """The gains a physics run of the seed 000 ``scenario`` gives ``controller_name``, and their source.

    A scenario on seed 000 Table 1 (made for kinematic robots) gets :data:`PHYSICS_GAINS`
    (``"physics"``); Table 2 (``"table2"``) and any other gains (``"scenario"``) are used
    as the scenario gives them. Returns ``(gains, source)``: keyword arguments of the
    controller class and a key of :data:`GAINS_SOURCES`.
    """
    if controller_name not in CONTROLLERS:
        raise InvalidInputError(f"unknown controller {controller_name!r}; choose one of {', '.join(CONTROLLERS)}")
    given = dict(scenario.gains.get(controller_name, {}))
    if _same_gains(given, TABLE1[controller_name]):
        return {k: list(v) if isinstance(v, list) else v for k, v in PHYSICS_GAINS[controller_name].items()}, "physics"
    return given, "table2" if _same_gains(given, TABLE2[controller_name]) else "scenario"


#: Another name of :func:`physics_controller_gains` (seed 000's physics runs use it).
physics_gains = physics_controller_gains


def pair_controller_gains(ctrl) -> dict:
    """The gains a seed 000 controller (a dataclass) runs with, JSON-ready: its init fields
    but the team (``feedforward`` included)."""
    return {f.name: _plain(getattr(ctrl, f.name)) for f in dataclasses.fields(ctrl) if f.init and f.name != "team"}


def physics_controller(scenario, controller, feedforward: bool | None = None,
                       gains: dict | None = None) -> tuple[object, dict, str]:
    """The seed 000 controller a physics run of ``scenario`` drives its quadrotors with.

    Parameters
    ----------
    controller : str or Controller
        A name: its gains from :func:`physics_controller_gains`, or ``gains`` (keyword
        arguments of its class, source ``"argument"``); or a controller object, run as it is
        (source ``"controller"``).
    feedforward : bool, optional
        For a name: feed the reference's rate forward; None keeps the scenario's.

    Returns
    -------
    (controller, gains, source)
        The controller object, the gains it runs with (:func:`pair_controller_gains`: what
        ``metrics.json`` records) and their source (a key of :data:`GAINS_SOURCES`).
    """
    if isinstance(controller, str):
        if gains is None:
            gains, source = physics_controller_gains(scenario, controller)
        else:
            source = "argument"
        try:
            ctrl = dataclasses.replace(scenario, gains={**scenario.gains, controller: dict(gains)}).controller(
                controller, feedforward)
        except TypeError as exc:  # an unknown gain name
            raise InvalidInputError(f"physics run: gains {gains!r} for {controller}: {exc}; use the "
                                    f"controller's gain names ({', '.join(TABLE1[controller])})") from None
    else:
        if gains is not None:
            raise InvalidInputError("physics run: pass gains with a controller name, not with a controller "
                                    f"object ({type(controller).__name__} already has its gains)")
        ctrl, source = controller, "controller"
    return ctrl, pair_controller_gains(ctrl), source


#: The settings of a seed 001 controller that shape its commands (seed 001 §5, eq. (4.47)).
UGV_UAV_GAIN_NAMES = ("k_x", "k_d", "k_w", "k_psi", "l_d", "compensation", "feedforward", "wall_margin",
                      "wall_gain", "derivative_filter_s")


def ugv_uav_controller_gains(controller, source: str = "scenario") -> tuple[dict, str]:
    """The settings a seed 001 ``controller`` runs with (:data:`UGV_UAV_GAIN_NAMES`, JSON-ready)
    and ``source`` (a key of :data:`GAINS_SOURCES`: ``"scenario"`` for the scenario's
    ``[gains]``, ``"argument"`` where the run overrides them)."""
    if source not in GAINS_SOURCES:
        raise InvalidInputError(f"gains source {source!r}; choose one of {', '.join(GAINS_SOURCES)}")
    return {n: _plain(getattr(controller, n)) for n in UGV_UAV_GAIN_NAMES}, source


#: How to install the optional extra, run in the quatform checkout (the extra named by the
#: package's name, ``quatform[mujoco]``, is looked up on a package index, not in the checkout).
INSTALL_HINT = 'pip install -e ".[mujoco]"'


def import_mujoco():
    """The ``mujoco`` module, imported on first use.

    With no display (``DISPLAY`` unset) and no ``MUJOCO_GL`` chosen, offscreen rendering
    uses EGL (Debian: ``libegl1``, ``libegl-mesa0``, ``libgl1-mesa-dri``). Where the chosen
    OpenGL library is missing (MuJoCo loads it at import), MuJoCo is loaded without
    rendering (``MUJOCO_GL=disable``) with a ``RuntimeWarning``: the physics runs, the
    pictures fall back to matplotlib.
    """
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"
    try:
        import mujoco
    except ImportError as exc:
        if exc.name == "mujoco":  # the package itself is missing
            raise MissingDependencyError(
                f"the MuJoCo physics backend needs the optional package 'mujoco' ({exc}); "
                f"install it from the quatform checkout with: {INSTALL_HINT}"
            ) from None
        failure = exc  # something mujoco imports for its OpenGL (PyOpenGL, libEGL, ...)
    except Exception as exc:  # noqa: BLE001 - mujoco loads the chosen OpenGL at import
        failure = exc
    else:
        return mujoco
    # the OpenGL library MUJOCO_GL names is missing: physics without MuJoCo pictures
    warnings.warn(f"MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} failed ({type(failure).__name__}: {failure}); "
                  "MuJoCo runs without offscreen rendering (pictures fall back to matplotlib); "
                  "see docs/physics.md for the packages", RuntimeWarning, stacklevel=2)
    for name in [m for m in sys.modules if m.split(".")[0] in ("mujoco", "OpenGL")]:
        del sys.modules[name]
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import mujoco
    except ImportError as exc:
        raise MissingDependencyError(
            f"the MuJoCo physics backend could not import 'mujoco' even without rendering ({exc}; first: "
            f"{failure}); reinstall it from the quatform checkout with: {INSTALL_HINT}"
        ) from None
    return mujoco


#: How :class:`PhysicsWorld` runs the quadrotors' cascades: ``"vectorised"`` (all at once on
#: ``(N, ...)`` arrays, :class:`~quatform.robots.physics.QuadrotorCascades`), ``"per-vehicle"``
#: (one :class:`~quatform.robots.physics.QuadrotorCascade` per vehicle on Python floats) or
#: ``"auto"`` (vectorised from :data:`VECTORISED_FROM` quadrotors on). Both give the same
#: forces to rounding (``tests/test_mujoco_team.py``).
CASCADE_MODES = ("auto", "vectorised", "per-vehicle")

#: Fewest quadrotors for which ``"auto"`` runs the cascades on arrays: one vectorised step
#: costs ~150 us of NumPy calls whatever N, one vehicle on Python floats ~30 us (CPU time
#: per physics step on this 2-core machine, ``docs/physics.md`` "Teams"): the arrays won
#: from 6 vehicles on (N = 4: 144 against 175 us; N = 6: 205 against 187 us; N = 10: 320
#: against 215 us). With the per-vehicle cascade on local floats the
#: per-vehicle loop is the faster one up to about 18 vehicles (simulated s per CPU s,
#: per vehicle / arrays: N = 6: 28.8 / 14.8; N = 10: 18.9 / 13.5; N = 16: 10.5 / 9.8;
#: N = 20: 8.4 / 8.7); the threshold is kept at 6 so that worlds of 6 or more quadrotors
#: keep their floats (the two ways agree to rounding, not bit for bit).
VECTORISED_FROM = 6


def physics_timestep(dt: float, largest: float = 0.0025) -> float:
    """The largest physics step not above ``largest`` that divides ``dt`` evenly, s."""
    if not (math.isfinite(dt) and dt > 0):
        raise InvalidInputError(f"dt must be positive and finite, got {dt!r}")
    return dt / max(1, math.ceil(dt / largest - 1e-9))


def _as_slice(ids: np.ndarray):
    """``ids`` (k,) as the slice it spans where they run ``lo, lo + 1, ...`` (a slice reads and
    writes the same entries as the index array, without a gather), else ``ids`` itself."""
    ids = np.asarray(ids, dtype=int)
    if ids.size and np.array_equal(ids, np.arange(ids[0], ids[0] + ids.size)):
        return slice(int(ids[0]), int(ids[0]) + ids.size)
    return ids


@dataclass
class ContactMonitor:
    """Collisions among robots and with the ground, counted as episodes.

    A contact is a collision unless it is a wheel or caster (``support``) on the ground.
    A landing gear (``landing``: the quadrotors' skids) on the ground in the first
    ``settle_s`` seconds is resting, not a collision (a quadrotor standing on the floor):
    only those geoms against the floor are whitelisted, never another part of the robot
    and never two robots. A resting pair stays so until it has been apart for ``release_s``
    (a take-off scrapes the floor for a moment before it leaves it); then its next touch
    counts. Collisions are counted per pair as episodes: a pair in contact again less than
    ``release_s`` after its last contact is the same episode (a bounce, a scrape), not a
    new collision.
    """

    names: dict  # root body id -> robot name (0: "ground")
    support: frozenset  # geom ids allowed to touch the ground (wheels, caster)
    landing: frozenset = frozenset()  # geom ids resting on the ground at the start (skids)
    settle_s: float = 0.05
    release_s: float = 0.5
    events: list = field(default_factory=list)  # (time, "a/b"): the start of each episode
    _last: dict = field(default_factory=dict)  # pair -> last time in contact
    _resting: set = field(default_factory=set)

    def check(self, model, data):
        if not data.ncon and not self._resting:  # nothing touches, nothing rests: nothing to do
            return
        now = {}  # pair -> only landing gear on the ground so far
        for i in range(data.ncon):
            c = data.contact[i]
            if c.dist > 0.0:
                continue
            g1, g2 = int(c.geom1), int(c.geom2)
            b1, b2 = int(model.body_rootid[model.geom_bodyid[g1]]), int(model.body_rootid[model.geom_bodyid[g2]])
            if b1 == b2:
                continue
            if (b1 == 0 and g2 in self.support) or (b2 == 0 and g1 in self.support):
                continue
            gear = (b1 == 0 and g2 in self.landing) or (b2 == 0 and g1 in self.landing)
            pair = tuple(sorted((self.names.get(b1, str(b1)), self.names.get(b2, str(b2)))))
            now[pair] = now.get(pair, True) and gear
        t = float(data.time)
        for pair in [p for p in self._resting if t - self._last[p] > self.release_s]:
            self._resting.discard(pair)  # it has left: its next touch counts
        for pair, gear_only in now.items():
            last = self._last.get(pair)
            self._last[pair] = t
            if gear_only and (pair in self._resting or (t <= self.settle_s and last is None)):
                self._resting.add(pair)
                continue
            if pair in self._resting:  # a resting robot touches the ground with another part
                self._resting.discard(pair)
            elif last is not None and t - last <= self.release_s:
                continue  # the same episode
            self.events.append((t, "/".join(pair)))

    def summary(self) -> dict:
        """``{"count", "first_time_s", "bodies"}``: collision episodes, the first one's time,
        and the pairs in order of first collision."""
        pairs = []
        for _, p in self.events:
            if p not in pairs:
                pairs.append(p)
        return {"count": len(self.events), "first_time_s": self.events[0][0] if self.events else None,
                "bodies": pairs}


class PhysicsWorld:
    """Quadrotors and differential-drive robots in one MuJoCo model, stepped with their
    low-level controllers.

    Parameters
    ----------
    quads : sequence of (name, position (3,), yaw)
    ugvs : sequence of (name, control point (2,), heading)
    floor_z : float
        Ground height, m.
    timestep : float
        Physics step, s.
    quad_params, ugv_params : physical numbers
    quad_mode : "velocity" or "attitude"
        How quadrotor commands are read: world ``(v_x, v_y, v_z, yaw rate)`` (seed 000) or
        Bebop-like ``(u_x, u_y, u_z, u_psi)`` fractions (seed 001).
    cascade_options : dict, optional
        Keyword arguments of :class:`~quatform.robots.physics.QuadrotorCascade`.
    cascades : str
        A :data:`CASCADE_MODES` entry: the cascades all at once on arrays or one per vehicle
        (``"auto"``: on arrays from :data:`VECTORISED_FROM` quadrotors on).
    """

    def __init__(self, quads=(), ugvs=(), floor_z: float = 0.0, timestep: float = 0.0025,
                 quad_params: QuadrotorParams = IRIS, ugv_params: DiffDriveParams = PIONEER_3DX,
                 quad_mode: str = "velocity", cascade_options: dict | None = None, cascades: str = "auto"):
        mj = import_mujoco()
        if cascades not in CASCADE_MODES:
            raise InvalidInputError(f"cascades must be one of {', '.join(CASCADE_MODES)}, got {cascades!r}")
        if quad_mode not in ("velocity", "attitude"):
            raise InvalidInputError(f"quad_mode must be 'velocity' or 'attitude', got {quad_mode!r}")
        self.mj, self.quad_mode = mj, quad_mode
        self.quad_params, self.ugv_params = quad_params, ugv_params
        palette = ((0.15, 0.35, 0.85, 1), (0.9, 0.55, 0.1, 1), (0.2, 0.7, 0.3, 1), (0.6, 0.2, 0.7, 1))
        bodies, acts = [], []
        for i, (name, pos, yaw) in enumerate(quads):
            b, a = quadrotor_mjcf(name, pos, yaw, palette[i % 4], quad_params)
            bodies.append(b)
            acts.append(a)
        for name, cp, psi in ugvs:
            axle = np.asarray(cp, dtype=float) - ugv_params.a * np.array([math.cos(psi), math.sin(psi)])
            b, a = diff_drive_mjcf(name, axle, psi, floor_z, params=ugv_params)
            bodies.append(b)
            acts.append(a)
        self.xml = world_mjcf(bodies, acts, timestep=timestep, floor_z=floor_z)
        self.model = mj.MjModel.from_xml_string(self.xml)
        self.data = mj.MjData(self.model)
        m = self.model
        self.quad_names = [q[0] for q in quads]
        self.ugv_names = [u[0] for u in ugvs]
        body = {n: mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, n) for n in self.quad_names + self.ugv_names}
        self._qadr = {n: int(m.jnt_qposadr[m.body_jntadr[body[n]]]) for n in body}
        self._vadr = {n: int(m.jnt_dofadr[m.body_jntadr[body[n]]]) for n in body}
        self._body = body
        act = lambda n: mj.mj_name2id(m, mj.mjtObj.mjOBJ_ACTUATOR, n)
        self._motors = {n: [act(f"{n}_motor{i}") for i in range(4)] for n in self.quad_names}
        self._wheels = {n: [act(f"{n}_left"), act(f"{n}_right")] for n in self.ugv_names}
        # the quadrotors' low-level controllers: all together on (N, ...) arrays
        # (robots.physics.cascades; each quantity read with one gather, every actuator written
        # with one assignment), or one per vehicle on Python floats, whichever is faster here
        self.vectorised = cascades == "vectorised" or (cascades == "auto" and len(self.quad_names) >= VECTORISED_FROM)
        self.cascade = QuadrotorCascades(max(len(self.quad_names), 1), quad_params, **(cascade_options or {}))
        self.cascades = {n: QuadrotorCascade(quad_params, **(cascade_options or {})) for n in self.quad_names}
        q = [self._qadr[n] for n in self.quad_names]
        v = [self._vadr[n] for n in self.quad_names]
        self._quad_qidx = np.array(q, dtype=int)[None] + np.arange(7)[:, None]  # (7, N): qpos rows
        self._quad_vidx = np.array(v, dtype=int)[None] + np.arange(6)[:, None]  # (6, N): qvel rows
        self._quad_ridx = 9 * np.array([body[n] for n in self.quad_names], dtype=int)[None] + np.arange(9)[:, None]
        self._quad_bodies = np.array([body[n] for n in self.quad_names], dtype=int)
        self._motor_ids = np.array([self._motors[n] for n in self.quad_names], dtype=int).reshape(-1, 4)
        self._ugv_qidx = np.array([self._qadr[n] for n in self.ugv_names], dtype=int)[None] + np.arange(7)[:, None]
        self._wheel_ids = np.array([self._wheels[n] for n in self.ugv_names], dtype=int).reshape(-1, 2)
        self._index = {**{n: i for i, n in enumerate(self.quad_names)}, **{n: i for i, n in enumerate(self.ugv_names)}}
        geom = lambda n: mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, n)
        support = frozenset(geom(f"{n}_{g}") for n in self.ugv_names for g in ("left_tyre", "right_tyre", "caster"))
        landing = frozenset(geom(f"{n}_skid{i}") for n in self.quad_names for i in (0, 1))
        names = {0: "ground", **{v: k for k, v in body.items()}}
        self.contacts = ContactMonitor(names, support, landing)
        self._quad_yaw = np.full(len(self.quad_names), np.nan)  # last yaw reported (nan: none yet)
        self._ugv_yaw = np.full(len(self.ugv_names), np.nan)
        self._quad_cmd = np.zeros((len(self.quad_names), 4))
        self._ugv_cmd = np.zeros((len(self.ugv_names), 2))
        # the largest tilt (as its cosine) and collective rotor force of each quadrotor so far,
        # sampled at the end of every step() call where track_quads is set (the team plant's
        # per-robot metrics)
        self.track_quads = False
        self.min_cos_tilt = np.ones(len(self.quad_names))
        self.max_thrust = np.zeros(len(self.quad_names))
        # start at rest: the motors already spin at hover thrust in the air
        hover = quad_params.mass * GRAVITY / 4.0
        for n, pos, _ in quads:
            airborne = pos[2] > floor_z + quad_params.leg_height + 0.05
            for a in self._motors[n]:
                self.data.act[m.actuator_actadr[a]] = hover if airborne else 0.0
        mj.mj_forward(m, self.data)
        self._check_start_clearance(names, support | landing)
        self.contacts.check(m, self.data)
        self._warnings = self._warning_counts()

    def _check_start_clearance(self, names, gear, tol: float = 0.005):
        """Refuse a start where robots overlap each other, or sink into the floor deeper than
        ``tol`` (a landing gear or wheel standing on it is fine; another part touching it is not)."""
        m, d = self.model, self.data
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            b1, b2 = int(m.body_rootid[m.geom_bodyid[g1]]), int(m.body_rootid[m.geom_bodyid[g2]])
            if b1 == b2:
                continue
            n1, n2 = names.get(b1, str(b1)), names.get(b2, str(b2))
            if b1 != 0 and b2 != 0 and c.dist < 0.0:
                raise InvalidInputError(f"robots {n1} and {n2} overlap at the start ({-c.dist:.3f} m): "
                                        "place them apart (for a UGV-UAV scenario: change uav_start)")
            if (b1 == 0 or b2 == 0) and (c.dist < -tol or (g1 not in gear and g2 not in gear and c.dist < 0.0)):
                robot = n2 if b1 == 0 else n1
                raise InvalidInputError(f"robot {robot} starts below the floor ({-c.dist:.3f} m into it): "
                                        "raise it to stand on its wheels or skids")

    def _warning_counts(self) -> tuple:
        W = self.mj.mjtWarning
        return tuple(self.data.warning.number[[int(W.mjWARN_BADQACC), int(W.mjWARN_BADQVEL),
                                               int(W.mjWARN_BADQPOS)]].tolist())

    def _check_step(self):
        """After ``mj_step``: MuJoCo resets the state and only logs a warning when the
        accelerations, velocities or positions go bad; a physics run must not go on from a
        reset as if nothing happened."""
        counts = self._warning_counts()
        if counts != self._warnings or not math.isfinite(float(np.sum(self.data.qpos))) or self.data.time <= 0.0:
            what = [n for n, a, b in zip(("accelerations", "velocities", "positions"), self._warnings, counts) if b > a]
            self._warnings = counts
            raise NonFiniteError(f"MuJoCo step failed at t = {self.data.time:.4f} s: non-finite or huge "
                                 f"{', '.join(what) or 'positions'} (MuJoCo reset the state); a robot was "
                                 "commanded or pushed beyond what the integrator can follow: check the "
                                 "commands, the timestep and the start poses")

    # -- states ----------------------------------------------------------------------
    def _yaws(self, name):
        return (self._quad_yaw, self._index[name]) if name in self._motors else (self._ugv_yaw, self._index[name])

    def _unwrap(self, name, raw):
        yaws, i = self._yaws(name)
        prev = yaws[i]
        y = raw if math.isnan(prev) else prev + float(wrap_angle(raw - prev))
        yaws[i] = y
        return y

    def continue_yaw(self, name, yaw: float):
        """Report ``name``'s yaw continued from ``yaw`` (rad) from now on (not wrapped)."""
        yaws, i = self._yaws(name)
        yaws[i] = float(yaw)

    def quad_pose(self, name):
        """``(position (3,), world velocity (3,), R (3, 3), body angular velocity (3,), yaw)``
        at the current time; the yaw in ``(-pi, pi]`` (:meth:`quad_state` continues it)."""
        # from qpos, not xpos/xmat: after mj_step those still hold the step's start
        d, a, va = self.data, self._qadr[name], self._vadr[name]
        R = np.empty(9)
        self.mj.mju_quat2Mat(R, d.qpos[a + 3:a + 7])
        R = R.reshape(3, 3)
        return d.qpos[a:a + 3].copy(), d.qvel[va:va + 3].copy(), R, d.qvel[va + 3:va + 6].copy(), \
            math.atan2(R[1, 0], R[0, 0])

    def quad_state(self, name) -> np.ndarray:
        """``(x, y, z, yaw)`` with a continuous yaw (seed 000's robot state)."""
        p, _, _, _, yaw = self.quad_pose(name)
        return np.array([p[0], p[1], p[2], self._unwrap(name, yaw)])

    def ugv_state(self, name) -> np.ndarray:
        """``(x, y, heading)`` of the control point ``a`` ahead of the axle (seed 001 §3.1.1)."""
        d, a = self.data, self._qadr[name]
        R = np.empty(9)
        self.mj.mju_quat2Mat(R, d.qpos[a + 3:a + 7])
        psi = math.atan2(R[3], R[0])
        cp = d.qpos[a:a + 2] + self.ugv_params.a * np.array([R[0], R[3]])
        return np.array([cp[0], cp[1], self._unwrap(name, psi)])

    @staticmethod
    def _continued(prev, raw):
        """``raw`` yaws continued from ``prev`` (``wrap_angle`` of the change; ``raw`` where unset)."""
        return np.where(np.isnan(prev), raw, prev + wrap_angle(raw - np.where(np.isnan(prev), raw, prev)))

    def quad_states(self) -> np.ndarray:
        """``(x, y, z, yaw)`` of every quadrotor, shape (N, 4), yaws continued (:meth:`quad_state`
        for all at once: one gather, one rotation per vehicle on arrays; vehicle by vehicle
        where the cascades run so, to keep the per-vehicle world's numbers)."""
        if not self.vectorised:  # quad_state's numbers, without its copies
            d, R = self.data, np.empty(9)
            out = np.empty((len(self.quad_names), 4))
            for i, n in enumerate(self.quad_names):
                a = self._qadr[n]
                self.mj.mju_quat2Mat(R, d.qpos[a + 3:a + 7])
                out[i, 0:3] = d.qpos[a:a + 3]
                out[i, 3] = self._unwrap(n, math.atan2(R[3], R[0]))
            return out
        q = self.data.qpos[self._quad_qidx]  # (7, N)
        R = rotation_rows(q[3:7].T)
        self._quad_yaw = self._continued(self._quad_yaw, np.arctan2(R[:, 3], R[:, 0]))
        return np.concatenate([q[0:3], self._quad_yaw[None]]).T

    def ugv_states(self) -> np.ndarray:
        """``(x, y, heading)`` of every UGV's control point, shape (M, 3), headings continued."""
        if not self.vectorised:
            return np.array([self.ugv_state(n) for n in self.ugv_names]).reshape(-1, 3)
        q = self.data.qpos[self._ugv_qidx]  # (7, M)
        R = rotation_rows(q[3:7].T)
        c, s = R[:, 0], R[:, 3]
        self._ugv_yaw = self._continued(self._ugv_yaw, np.arctan2(s, c))
        a = self.ugv_params.a
        return np.stack([q[0] + a * c, q[1] + a * s, self._ugv_yaw], axis=1)

    def qpos(self) -> np.ndarray:
        return self.data.qpos.copy()

    def quad_quaternions(self) -> np.ndarray:
        """Every quadrotor's attitude, unit ``(w, x, y, z)`` (MuJoCo's order, body to world),
        shape (N, 4), in ``quad_names`` order."""
        return np.array([self.data.qpos[self._qadr[n] + 3:self._qadr[n] + 7] for n in self.quad_names]).reshape(-1, 4)

    def rotor_commands(self) -> np.ndarray:
        """Every quadrotor's four motor commands (the actuators' ``ctrl``, N), shape (N, 4)."""
        return self.data.ctrl[self._motor_ids].copy()

    def rotor_forces(self) -> np.ndarray:
        """Every quadrotor's four rotor forces (the actuators' force, N), shape (N, 4)."""
        return self.data.actuator_force[self._motor_ids].copy()

    # -- commands and stepping --------------------------------------------------------
    def command_quad(self, name, u):
        """Hold ``u`` (4,) as ``name``'s set point (a non-finite entry: zero)."""
        u = np.asarray(u, dtype=float)
        self._quad_cmd[self._index[name]] = np.where(np.isfinite(u), u, 0.0)

    def command_quads(self, u):
        """Hold ``u`` (N, 4) as every quadrotor's set point, in ``quad_names`` order."""
        u = np.asarray(u, dtype=float)
        self._quad_cmd = np.where(np.isfinite(u), u, 0.0).reshape(len(self.quad_names), 4)

    def command_ugv(self, name, v_omega):
        self._ugv_cmd[self._index[name]] = np.asarray(v_omega, dtype=float)

    def command_ugvs(self, v_omega):
        """Hold ``(v, omega)`` (M, 2) for every UGV, in ``ugv_names`` order."""
        self._ugv_cmd = np.asarray(v_omega, dtype=float).reshape(len(self.ugv_names), 2)

    def step(self, n: int = 1):
        """``n`` physics steps, the low-level controllers and the rotor drag in the loop (every
        quadrotor's cascade at once, :class:`~quatform.robots.physics.QuadrotorCascades`, or
        one per vehicle: :attr:`vectorised`)."""
        d = self.data
        if self.ugv_names:
            u = self._ugv_cmd
            d.ctrl[self._wheel_ids] = wheel_speeds(u[:, 0], u[:, 1], params=self.ugv_params)
        if self.vectorised:
            self._step_vectorised(n)
        else:
            self._step_per_vehicle(n)

    def _step_per_vehicle(self, n: int):
        """The quadrotors one after another, on Python floats (the per-vehicle loop)."""
        mj, m, d = self.mj, self.model, self.data
        dt = m.opt.timestep
        quat2mat, mj_step, check = mj.mju_quat2Mat, mj.mj_step, self.contacts.check
        nq = len(self.quad_names)
        # each vehicle's rotation, written by mju_quat2Mat from its quaternion (views into
        # MjData's buffers, which keep their memory): one tolist a step for all of them
        R = np.empty((nq, 9))
        rotations = [(R[i], d.qpos[a + 3:a + 7]) for i, a in enumerate(self._qadr[nm] for nm in self.quad_names)]
        velocity = self.quad_mode == "velocity"
        quads = [(self._vadr[nm], 4 * i, (self.cascades[nm].step_velocity if velocity else
                                          self.cascades[nm].step_attitude), self._quad_cmd[i].tolist())
                 for i, nm in enumerate(self.quad_names)]
        # every motor command and every body's drag written with one assignment a step
        motors, bodies = _as_slice(self._motor_ids.ravel()), _as_slice(self._quad_bodies)
        ctrl, xfrc, force = d.ctrl, d.xfrc_applied, d.actuator_force
        for _ in range(n):
            # read once a step (mj_step writes them)
            qvel, fq = d.qvel.tolist(), force[motors].tolist()
            for rot, q in rotations:
                quat2mat(rot, q)
            f, drag = [], []
            for (va, k, step, u), Rl in zip(quads, R.tolist()):
                fi, di = step(u, qvel[va:va + 6], Rl, fq[k:k + 4], dt)
                f += fi
                drag.append(di)
            if nq:
                ctrl[motors] = f
                xfrc[bodies, 0:3] = drag
            t_before = d.time
            mj_step(m, d)
            if not d.time > t_before:  # MuJoCo reset the state (time back to 0): a failed step
                self._check_step()
            check(m, d)
        self._after_steps()

    def _step_vectorised(self, n: int):
        """Every quadrotor at once: one gather per quantity, one assignment per actuator kind."""
        mj, m, d = self.mj, self.model, self.data
        dt = m.opt.timestep
        qvel, ctrl, force, xfrc = d.qvel, d.ctrl, d.actuator_force, d.xfrc_applied
        xmat = d.xmat.reshape(-1)  # a view: MuJoCo's body rotations, rows first
        cas, ridx, vidx, motors, bodies = self.cascade, self._quad_ridx, self._quad_vidx, self._motor_ids, \
            self._quad_bodies
        quads, velocity = len(self.quad_names) > 0, self.quad_mode == "velocity"
        if quads:  # the set points held for this call's n steps
            u = self._quad_cmd
            if velocity:
                cas.hold_velocity(u[:, 0:3], u[:, 3])
            else:
                cas.hold_attitude(u)
        for _ in range(n):
            t_before = d.time
            # mj_step in its two halves (MuJoCo's documented split): the first computes the
            # kinematics of the current qpos, so the controllers read each body's rotation
            # (xmat: mju_quat2Mat of its normalised quaternion) instead of recomputing it
            mj.mj_step1(m, d)
            if quads:
                R = xmat[ridx].T  # (N, 9), the transpose of a contiguous (9, N)
                vel = qvel[vidx]  # (6, N)
                v, w = vel[0:3].T, vel[3:6].T
                f = cas.velocity_forces(v, R, w, dt) if velocity else cas.attitude_forces(v, R, w)
                ctrl[motors] = f
                xfrc[bodies, 0:3] = cas.rotor_drag(force[motors], v, R)
            mj.mj_step2(m, d)
            if not d.time > t_before:  # MuJoCo reset the state (time back to 0): a failed step
                self._check_step()
            self.contacts.check(m, d)
        self._after_steps()

    def _after_steps(self):
        """Once per call: the failure checks, and each quadrotor's tilt and thrust sampled."""
        d = self.data
        self._check_step()  # the warning counters and the positions, once per call
        if self.track_quads and self.quad_names:  # sampled once per call (each control tick)
            q0, q1, q2, q3 = d.qpos[self._quad_qidx[3:7]]
            cos_tilt = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3  # R_22 (mju_quat2Mat)
            np.minimum(self.min_cos_tilt, cos_tilt, out=self.min_cos_tilt)
            np.maximum(self.max_thrust, np.add.reduce(d.actuator_force[self._motor_ids], axis=1), out=self.max_thrust)


@dataclass(frozen=True)
class PhysicsRecord:
    """What a physics run adds to the logged signals.

    Attributes
    ----------
    xml : str
        The MJCF of the world (to render it again).
    t : ndarray, shape (T,)
    qpos : ndarray, shape (T, nq)
        MuJoCo positions at every control tick.
    robots : dict
        Robot name -> ``(T, 3)`` positions (the quadrotors' centres, the UGVs' control points).
    collisions : dict
        :meth:`ContactMonitor.summary`.
    timestep : float
        The physics step, s.
    gains : dict
        The controller's gains and settings in this run (JSON-ready).
    gains_source : str
        Where they came from: a key of :data:`GAINS_SOURCES`.
    title : str
        The scenario and controller or formation, for the pictures.
    physics_label : str
        How figures name the physics (:data:`PHYSICS_LABEL`).
    quads : tuple of str
        The quadrotors' names (world bodies, the ``robots`` keys), in the order of the arrays below.
    attitude : ndarray, shape (T, N, 4), or None
        Each quadrotor's attitude at every control tick, unit ``(w, x, y, z)``, body to world.
    rotor_command, rotor_force : ndarray, shape (T, N, 4), or None
        Each quadrotor's motor commands and rotor forces (N) at every control tick.
    """

    xml: str
    t: np.ndarray
    qpos: np.ndarray
    robots: dict
    collisions: dict
    timestep: float
    gains: dict = field(default_factory=dict)
    gains_source: str = ""
    title: str = ""
    physics_label: str = PHYSICS_LABEL
    quads: tuple = ()
    attitude: np.ndarray | None = None
    rotor_command: np.ndarray | None = None
    rotor_force: np.ndarray | None = None

    def metrics(self) -> dict:
        """The keys a physics run adds to ``metrics.json`` beside the errors: ``gains``,
        ``gains_source`` (and its meaning, ``gains_source_note``) and ``physics_timestep_s``."""
        return {"gains": self.gains, "gains_source": self.gains_source,
                "gains_source_note": GAINS_SOURCES.get(self.gains_source, ""), "physics_timestep_s": self.timestep}


#: Excitation of :func:`identify_k` per channel: (duration s, step period s, chirp end Hz).
#: The horizontal channels are slow (time constant ``1/K2`` ~ 6 s): their steps last long
#: enough to show the drag, their chirp stays below the attitude loop's bandwidth.
IDENTIFICATION_EXCITATION = {"x": (40.0, 10.0, 0.3), "y": (40.0, 10.0, 0.3), "z": (8.0, 1.5, 1.0),
                             "psi": (8.0, 1.5, 1.0)}


def identify_k(timestep: float = 0.0025, excitation: dict | None = None):
    """``K1..K8`` of seed 001 eq. (3.11) identified from the simulated quadrotor.

    Each channel of the Bebop-like attitude mode is excited alone from a hover: during the
    first half of its run, steps of +-0.5 that alternate every ``period``; during the second,
    a chirp of amplitude 0.5 from 0.02 Hz to ``f_end`` (:data:`IDENTIFICATION_EXCITATION`).
    The body-frame velocity ``v`` is recorded at every physics step, differentiated by
    central differences, and ``v_dot = K_u u - K_v v`` (the body-frame model; seed 001
    prints it in the world frame, ``docs/derivations.md``) is fitted by least squares per
    channel.

    Returns
    -------
    k : tuple of 8 floats
        ``(K1, K2, ..., K8)``.
    fit : dict
        Per channel: ``r2`` of the fit of ``v_dot`` and the number of ``samples``.
    """
    exc = dict(IDENTIFICATION_EXCITATION, **(excitation or {}))
    k, fit = [], {}
    for ch, name in enumerate(("x", "y", "z", "psi")):
        duration, period, f_end = exc[name]
        n = round(duration / timestep)
        t = np.arange(n) * timestep
        half = 0.5 * duration
        steps = 0.5 * np.where((t // period) % 2 == 0, 1.0, -1.0)
        f = 0.02 + (f_end - 0.02) * (t - half) / half
        chirp = 0.5 * np.sin(2 * np.pi * np.cumsum(np.where(t >= half, f, 0.0)) * timestep)
        u_ch = np.where(t < half, steps, chirp)
        world = PhysicsWorld(quads=[("uav", (0.0, 0.0, 3.0), 0.0)], floor_z=-100.0, timestep=timestep,
                             quad_mode="attitude")
        v = np.zeros(n)
        u = np.zeros(4)
        for i in range(n):
            u[ch] = u_ch[i]
            world.command_quad("uav", u)
            _, vel, R, w, yaw = world.quad_pose("uav")
            c, s = math.cos(yaw), math.sin(yaw)
            v[i] = (c * vel[0] + s * vel[1], -s * vel[0] + c * vel[1], vel[2], float(R[2, :] @ w))[ch]
            world.step(1)
        vdot = (v[2:] - v[:-2]) / (2 * timestep)
        A = np.c_[u_ch[1:-1], -v[1:-1]]
        sol, *_ = np.linalg.lstsq(A, vdot, rcond=None)
        r2 = 1.0 - np.sum((vdot - A @ sol) ** 2) / np.sum((vdot - vdot.mean()) ** 2)
        k.extend(float(x) for x in sol)
        fit[name] = {"r2": float(r2), "samples": len(vdot)}
    return tuple(k), fit
