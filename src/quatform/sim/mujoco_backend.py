"""MuJoCo physics backend: the same controllers drive physical robots (issue 7).

Sim layer. MuJoCo is optional: it is imported only when a physics run starts
(:func:`import_mujoco`), never when quatform is imported; without it a physics run
raises :class:`~quatform.errors.MissingDependencyError` naming
``pip install -e ".[mujoco]"`` (run in the quatform checkout: :data:`INSTALL_HINT`).

* :class:`PhysicsWorld` - the MJCF world of quadrotors and differential-drive robots
  (:mod:`quatform.robots.physics`), stepped with their low-level controllers in the
  loop, with a :class:`ContactMonitor` that reports collisions.
* :func:`pair_plant` - the plant of a seed 000 scenario (two quadrotors) for any of the
  four formation controllers (:func:`physics_controller`), run by the one
  :func:`~quatform.sim.simulate` like the kinematic team
  (:func:`quatform.scenarios.pair.simulate_physics`); :func:`physics_metrics` and
  :func:`physics_record` (collisions, MJCF, body poses for the pictures) read the run.
* :func:`simulate_ugv_uav_physics` - a seed 001 scenario with a Pioneer-like UGV and a
  quadrotor flown in Bebop-like attitude mode, the controller's dynamic compensation
  (4.47) using ``K1..K8`` identified from the simulated quadrotor (:func:`identify_k`).
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
from ..robots import Bebop
from ..robots.physics import (
    GRAVITY,
    IRIS,
    PIONEER_3DX,
    DiffDriveParams,
    QuadrotorCascade,
    QuadrotorParams,
    diff_drive_mjcf,
    quadrotor_mjcf,
    wheel_speeds,
    world_mjcf,
)

__all__ = ["BACKEND_LABEL", "INSTALL_HINT", "IRIS_IDENTIFIED_K", "PHYSICS_GAINS", "ContactMonitor", "PhysicsRecord",
           "PhysicsWorld", "identify_k", "import_mujoco", "physics_gains", "physics_timestep", "pair_plant",
           "PairPlant", "physics_controller", "physics_metrics", "physics_record",
           "simulate_ugv_uav_physics"]

#: How figures and tables name this backend (``PhysicsRecord.backend_label``).
BACKEND_LABEL = "MuJoCo physics"

#: ``K1..K8`` of seed 001 eq. (3.11) identified from the simulated IRIS in Bebop-like
#: attitude mode by :func:`identify_k` (steps and chirps, least squares; see
#: ``docs/physics.md``). K1 = K3 follow from the chosen 5 deg tilt, K5, K6 from the climb
#: loop's gain and full scale, K7, K8 from the yaw-rate loop's; only K2 = K4 (rotor drag over
#: mass) is a physical result.
IRIS_IDENTIFIED_K = (0.8058, 0.1709, 0.8058, 0.1709, 3.856, 3.784, 9.565, 4.663)

#: Seed 000 gains for two IRIS quadrotors, used by :func:`pair_plant` where a
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


def physics_gains(scenario, controller: str) -> tuple[dict, str]:
    """The gains a physics run of ``scenario`` gives ``controller``, and their source.

    A scenario on seed 000 Table 1 (made for kinematic robots) gets :data:`PHYSICS_GAINS`
    (``"physics"``); Table 2 (``"table2"``) and any other gains (``"scenario"``) are used
    as the scenario gives them. Returns ``(gains, source)``: keyword arguments of the
    controller class and a key of :data:`GAINS_SOURCES`.
    """
    if controller not in CONTROLLERS:
        raise InvalidInputError(f"unknown controller {controller!r}; choose one of {', '.join(CONTROLLERS)}")
    given = dict(scenario.gains.get(controller, {}))
    if _same_gains(given, TABLE1[controller]):
        return {k: list(v) if isinstance(v, list) else v for k, v in PHYSICS_GAINS[controller].items()}, "physics"
    return given, "table2" if _same_gains(given, TABLE2[controller]) else "scenario"


def _controller_gains(ctrl) -> dict:
    """The gains a seed 000 controller (a dataclass) runs with: its init fields but the team."""
    return {f.name: _plain(getattr(ctrl, f.name)) for f in dataclasses.fields(ctrl) if f.init and f.name != "team"}


#: The settings of a seed 001 controller that shape its commands (seed 001 §5, eq. (4.47)).
_UGV_UAV_GAIN_NAMES = ("k_x", "k_d", "k_w", "k_psi", "l_d", "compensation", "feedforward", "wall_margin",
                       "wall_gain", "derivative_filter_s")


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


def physics_timestep(dt: float, largest: float = 0.0025) -> float:
    """The largest physics step not above ``largest`` that divides ``dt`` evenly, s."""
    if not (math.isfinite(dt) and dt > 0):
        raise InvalidInputError(f"dt must be positive and finite, got {dt!r}")
    return dt / max(1, math.ceil(dt / largest - 1e-9))




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
    """

    def __init__(self, quads=(), ugvs=(), floor_z: float = 0.0, timestep: float = 0.0025,
                 quad_params: QuadrotorParams = IRIS, ugv_params: DiffDriveParams = PIONEER_3DX,
                 quad_mode: str = "velocity", cascade_options: dict | None = None):
        mj = import_mujoco()
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
        try:
            self.cascades = {n: QuadrotorCascade(quad_params, **(cascade_options or {})) for n in self.quad_names}
        except TypeError as exc:
            raise InvalidInputError(f"cascade_options {cascade_options!r}: {exc}; see QuadrotorCascade's "
                                    "parameters") from None
        geom = lambda n: mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, n)
        support = frozenset(geom(f"{n}_{g}") for n in self.ugv_names for g in ("left_tyre", "right_tyre", "caster"))
        landing = frozenset(geom(f"{n}_skid{i}") for n in self.quad_names for i in (0, 1))
        names = {0: "ground", **{v: k for k, v in body.items()}}
        self.contacts = ContactMonitor(names, support, landing)
        self._yaw = {}
        self._quad_cmd = {n: np.zeros(4) for n in self.quad_names}
        self._ugv_cmd = {n: np.zeros(2) for n in self.ugv_names}
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
        w, W = self.data.warning, self.mj.mjtWarning
        return tuple(int(w[k].number) for k in (W.mjWARN_BADQACC, W.mjWARN_BADQVEL, W.mjWARN_BADQPOS))

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
    def _unwrap(self, name, raw):
        prev = self._yaw.get(name)
        y = raw if prev is None else prev + float(wrap_angle(raw - prev))
        self._yaw[name] = y
        return y

    def continue_yaw(self, name, yaw: float):
        """Report ``name``'s yaw continued from ``yaw`` (rad) from now on (not wrapped)."""
        self._yaw[name] = float(yaw)

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

    def qpos(self) -> np.ndarray:
        return self.data.qpos.copy()

    # -- commands and stepping --------------------------------------------------------
    def command_quad(self, name, u):
        self._quad_cmd[name] = np.where(np.isfinite(u), np.asarray(u, dtype=float), 0.0).tolist()

    def command_ugv(self, name, v_omega):
        self._ugv_cmd[name] = np.asarray(v_omega, dtype=float)

    def step(self, n: int = 1):
        """``n`` physics steps, the low-level controllers and the rotor drag in the loop."""
        mj, m, d = self.mj, self.model, self.data
        dt = m.opt.timestep
        for name in self.ugv_names:
            w = wheel_speeds(*self._ugv_cmd[name], params=self.ugv_params)
            d.ctrl[self._wheels[name]] = w
        R = np.empty(9)
        quads = [(self._qadr[nm], self._vadr[nm], self._motors[nm], self._body[nm], self.cascades[nm],
                  self._quad_cmd[nm]) for nm in self.quad_names]
        velocity = self.quad_mode == "velocity"
        for _ in range(n):
            for a, va, motors, body, cas, u in quads:
                mj.mju_quat2Mat(R, d.qpos[a + 3:a + 7])
                Rl, vw = R.tolist(), d.qvel[va:va + 6].tolist()
                if velocity:
                    f = cas.velocity_mode(u[0:3], u[3], vw[0:3], Rl, vw[3:6], dt)
                else:
                    f = cas.attitude_mode(u, vw[0:3], Rl, vw[3:6])
                d.ctrl[motors] = f
                d.xfrc_applied[body, 0:3] = cas.rotor_drag(d.actuator_force[motors].tolist(), vw[0:3], Rl)
            t_before = d.time
            mj.mj_step(m, d)
            if not d.time > t_before:  # MuJoCo reset the state (time back to 0): a failed step
                self._check_step()
            self.contacts.check(m, d)
        self._check_step()  # the warning counters and the positions, once per call


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
    backend_label : str
        How figures name the backend (:data:`BACKEND_LABEL`).
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
    backend_label: str = BACKEND_LABEL

    def metrics(self) -> dict:
        """The keys a physics run adds to ``metrics.json`` beside the errors: ``gains``,
        ``gains_source`` (and its meaning, ``gains_source_note``) and ``physics_timestep_s``."""
        return {"gains": self.gains, "gains_source": self.gains_source,
                "gains_source_note": GAINS_SOURCES.get(self.gains_source, ""), "physics_timestep_s": self.timestep}


def physics_controller(scenario, controller, feedforward: bool | None = None,
                       gains: dict | None = None) -> tuple[object, dict, str]:
    """The seed 000 controller a physics run of ``scenario`` drives its quadrotors with.

    ``controller``: a name (its gains from :func:`physics_gains`, or ``gains``: keyword
    arguments of its class, source ``"argument"``; ``feedforward`` None keeps the
    scenario's) or a controller object, run as it is (source ``"controller"``). Returns
    ``(controller, gains, source)``: the object, the gains it runs with (what
    ``metrics.json`` records) and their source (a key of :data:`GAINS_SOURCES`).
    """
    if isinstance(controller, str):
        if gains is None:
            gains, source = physics_gains(scenario, controller)
        else:
            source = "argument"
        try:
            ctrl = dataclasses.replace(scenario, gains={**scenario.gains, controller: dict(gains)}).controller(
                controller, feedforward)
        except TypeError as exc:  # an unknown gain name
            raise InvalidInputError(f"simulate_physics: gains {gains!r} for {controller}: {exc}; use the "
                                    f"controller's gain names ({', '.join(TABLE1[controller])})") from None
    else:
        if gains is not None:
            raise InvalidInputError("simulate_physics: pass gains with a controller name, not with a controller "
                                    f"object ({type(controller).__name__} already has its gains)")
        ctrl, source = controller, "controller"
    return ctrl, _controller_gains(ctrl), source


class PairPlant:
    """Two simulated IRIS quadrotors in PX4-like velocity mode as a plant of
    :func:`quatform.sim.simulate` (seed 000 §4.2's robots).

    State and output: the 8 robot variables ``x1 ... theta2`` (m, rad; the yaws continued,
    not wrapped); command each robot's ``(v_x, v_y, v_z, yaw rate)`` in the world frame. One
    world (MuJoCo's data is the state that advances, ``batchable = False``): ``step`` sends
    the command and runs ``round(dt / timestep)`` physics steps; ``times`` and ``qpos`` record
    each call's time and the MuJoCo positions at its start.
    """

    batchable = False
    state_columns = ("x1", "y1", "z1", "theta1", "x2", "y2", "z2", "theta2")
    output_columns = state_columns

    def __init__(self, x0, timestep: float, cascade_options: dict | None = None):
        x = np.asarray(x0, dtype=float)
        if x.shape != (8,):
            raise InvalidInputError(f"pair_plant: x0 must have shape (8,) (one world: a MuJoCo plant is not "
                                    f"batched), got {x.shape}")
        self.world = PhysicsWorld(quads=[("robot1", x[0:3], x[3]), ("robot2", x[4:7], x[7])], timestep=timestep,
                                  cascade_options=cascade_options)
        self.world.continue_yaw("robot1", x[3])  # yaws continued from the scenario's, not wrapped
        self.world.continue_yaw("robot2", x[7])
        self.x0, self.timestep = x, timestep
        self.times: list[float] = []
        self.qpos: list[np.ndarray] = []

    def output(self, x):
        return x

    def step(self, x, u, dt, t=0.0):
        self.times.append(float(t))
        self.qpos.append(self.world.qpos())
        self.world.command_quad("robot1", u[0:4])
        self.world.command_quad("robot2", u[4:8])
        self.world.step(round(dt / self.timestep))
        return np.r_[self.world.quad_state("robot1"), self.world.quad_state("robot2")]


def pair_plant(scenario, x0, timestep: float | None = None, cascade_options: dict | None = None) -> PairPlant:
    """The two-quadrotor plant of a seed 000 scenario starting at ``x0`` (shape (8,)); the
    physics step is ``timestep`` or the largest up to 2.5 ms dividing ``scenario.dt_s``."""
    return PairPlant(x0, physics_timestep(scenario.dt_s) if timestep is None else float(timestep), cascade_options)


def physics_metrics(plant: PairPlant) -> dict:
    """``{"backend", "collisions", "physics_timestep_s"}`` of a run of ``plant``."""
    return {"backend": "mujoco", "collisions": plant.world.contacts.summary(), "physics_timestep_s": plant.timestep}


def physics_record(plant: PairPlant, log, title: str = "", gains: dict | None = None,
                   gains_source: str = "") -> PhysicsRecord:
    """The :class:`PhysicsRecord` of a run of ``plant`` (its log ``log``): the MuJoCo
    positions at the log's ticks, the robots' centres, the collisions."""
    t, r = log.t, log["state"]
    q = np.array(plant.qpos[:len(t)]) if plant.qpos else np.zeros((0, plant.world.model.nq))
    return PhysicsRecord(plant.world.xml, t[:len(q)], q, {"robot1": r[:, 0:3], "robot2": r[:, 4:7]},
                         plant.world.contacts.summary(), plant.timestep, dict(gains or {}), gains_source, title)


# -- seed 001: UGV + quadrotor --------------------------------------------------------------
def simulate_ugv_uav_physics(sc, formation: str = "quaternion", k=IRIS_IDENTIFIED_K, progress=None,
                             compensation: bool | None = None, **controller_options):
    """A seed 001 scenario with a Pioneer-like UGV and an IRIS in Bebop-like attitude mode.

    The controller is seed 001's (Fig. 18) with the scenario's ``[gains]`` (all of them:
    ``compensation = false`` turns the dynamic compensation (4.47) off), its compensation
    using ``k`` (default: identified from this quadrotor); the motion capture and odometry
    are those of :class:`~quatform.sim.ugv_uav.MotionCapture`. ``compensation`` (where not
    None) and ``controller_options`` override the scenario's gains. Returns
    ``(UgvUavRun, PhysicsRecord)``; the record's ``gains`` are the controller's.
    """
    from .ugv_uav import simulate_ugv_uav

    holder = {}

    def plant_factory(x0, floor):
        h = physics_timestep(sc.dt_s)
        z0 = max(x0[5], floor + IRIS.leg_height)
        world = PhysicsWorld(quads=[("uav", (x0[3], x0[4], z0), x0[6])], ugvs=[("ugv", x0[0:2], x0[2])],
                             floor_z=floor, timestep=h, quad_mode="attitude")
        holder["world"], holder["qpos"], holder["h"] = world, [], h
        n = round(sc.dt_s / h)

        def state():
            _, v, R, w, _ = world.quad_pose("uav")
            s = world.quad_state("uav")
            c, si = math.cos(s[3]), math.sin(s[3])
            psi_dot = float(R[2, :] @ w)  # world z component of the body rate
            return np.r_[world.ugv_state("ugv"), s, c * v[0] + si * v[1], -si * v[0] + c * v[1], v[2], psi_dot]

        def plant(x, u, dt):
            holder["qpos"].append(world.qpos())
            world.command_ugv("ugv", u[0:2])
            world.command_quad("uav", u[2:6])
            world.step(n)
            return state()

        return state(), plant

    bebop = Bebop(k=tuple(k), max_fraction=sc.max_fraction)
    if compensation is not None and not isinstance(compensation, bool | np.bool_):
        raise InvalidInputError(f"simulate_ugv_uav_physics: compensation must be true, false or None (the "
                                f"scenario's), got {compensation!r}")
    options = dict(controller_options, **({} if compensation is None else {"compensation": bool(compensation)}))
    ctrl = sc.controller(formation, bebop=bebop, **options)  # the one simulate_ugv_uav builds: its gains
    used = {n: _plain(getattr(ctrl, n)) for n in _UGV_UAV_GAIN_NAMES if hasattr(ctrl, n)}
    run = simulate_ugv_uav(sc, formation, progress=progress, plant_factory=plant_factory, bebop=bebop, **options)
    run = dataclasses.replace(run, backend=BACKEND_LABEL)
    world = holder["world"]
    spc = max(1, round(sc.control_period_s / sc.dt_s))  # plant calls per control tick
    q = np.array(holder["qpos"][::spc][:len(run.t)])
    rec = PhysicsRecord(world.xml, run.t[:len(q)], q,
                        {"ugv": np.c_[run.ugv[:, 0:2], np.full(len(run.t), sc.center[2])], "uav": run.uav[:, 0:3]},
                        world.contacts.summary(), holder["h"], used, "argument" if options else "scenario",
                        f"{sc.name}: {formation} formation")
    return run, rec


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
