"""What a run shows in 3-D: its bodies' poses, commands, formation frame, edges, arms and wrenches (bags layer).

One :class:`Scene` per run, read from its :class:`~quatform.sim.log.Log` by the builder its
scenario kind registers in :data:`SCENES` (``SCENES[kind name](log) -> Scene``), with the plot
panels of its Foxglove layout (``SCENES[kind name].plots(scene)``, :class:`Plot`). The MCAP
writer (:mod:`.mcap`) and the Rerun writer (:mod:`.rerun`) draw the same scene. Arrays have a
time axis first and a body axis next (``(T, N, 3)``, ``(T, N, 4)``), quaternions ``(w, x, y, z)``
(REP-103: the world frame ENU, a body frame FLU, x forward).

A body's orientation comes from its state: a 4-DOF robot ``(x, y, z, yaw)`` and a planar one
``(x, y, yaw)`` (at z = 0) the quaternion of its yaw about z (``formations.geometry.q_yaw``);
a free body its quaternion; a robot whose point has no heading (the Bebop in a team, whose yaw
is controlled outside the formation) its own state's heading, where the state has one.

Every frame is continuous along the run. A two-robot formation's frame is fixed by its
segment up to the twist about it, and no rule that reads one sample alone can fix the twist
without a jump somewhere (seed 000's minimal rotation from ``i``, eqs. (14)-(15), turns by
pi in one sample where the segment passes ``-i``: the helix at t = 40 s). So the desired
frame is the reference's own (the quaternion description's ``from_chart`` of the desired
Euclidean variables, continuous in them), or else the seed's frame at the first sample
carried along by the minimal rotation from each sample's segment to the next (parallel
transport, :func:`continuous_states`); the actual frame is the point of its fibre nearest the
desired one (``forward(r, near_c=...)``), so the angle between them is the angle between the
segments, the orientation error ``metrics.json`` reports. Every quaternion written, a body's
too, has the sign nearer the previous sample's (:func:`sign_continuous`; q and -q are one
rotation, but a plot of the components or a player that interpolates them would jump).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..control.networked import NETWORK_SIGNALS
from ..errors import InvalidInputError
from ..formations import FORMATIONS
from ..formations import geometry as g
from ..formations.layout import RobotLayout
from ..registry import Registry
from ..robots import Pioneer

__all__ = ["Scene", "Joints", "Wrench", "Rotors", "Odometry", "SCENES", "SceneKind", "Plot", "pioneer_base", "scene_of",
           "scene_kind", "COMMAND_TWISTS", "CommandTwist", "sign_continuous", "continuous_states", "formation_plots",
           "teleop_plots"]

#: Slots of a twist ``(v_x, v_y, v_z, w_x, w_y, w_z)``.
_TWIST = {"lx": 0, "ly": 1, "lz": 2, "ax": 3, "ay": 4, "az": 5}


@dataclass(frozen=True)
class CommandTwist:
    """How a robot model's commands read as a ``geometry_msgs/Twist``.

    Attributes
    ----------
    frame : str
        ``"world"`` (world-frame velocities) or ``"body"`` (the robot's FLU frame).
    slots : tuple of str
        The twist slot of each command entry (``lx`` linear x ... ``az`` angular z).
    """

    frame: str
    slots: tuple


#: Twist of each robot model's commands (by the model's ``name``). The Bebop's commands are the
#: fractions of its limits (pitch, roll, climb, yaw rate) in its body frame, as the ROS driver
#: ``bebop_autonomy`` reads its ``cmd_vel``; the Pioneer's ``(v, omega)`` its forward speed and
#: turn rate (``RosAria``'s ``cmd_vel``).
COMMAND_TWISTS = {
    "holonomic": CommandTwist("world", ("lx", "ly", "lz", "az")),
    "planar-holonomic": CommandTwist("world", ("lx", "ly", "az")),
    "free-body": CommandTwist("world", ("lx", "ly", "lz", "ax", "ay", "az")),
    "pioneer": CommandTwist("body", ("lx", "az")),
    "bebop": CommandTwist("body", ("lx", "ly", "lz", "az")),
}


@dataclass(frozen=True)
class Joints:
    """One arm's joints: ``names`` (J,), ``position`` rad, ``velocity`` rad/s, ``effort`` N m, each (T, J)."""

    arm: str
    names: tuple
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


@dataclass(frozen=True)
class Wrench:
    """A force (N) and torque (N m), each (T, 3), sensed in ``frame`` (``slave_wrist`` ...)."""

    name: str
    frame: str
    force: np.ndarray
    torque: np.ndarray


@dataclass(frozen=True)
class Rotors:
    """A quadrotor's four motor commands and rotor forces (N), each (T, 4), in a MuJoCo run.

    At sample ``k`` the force is the rotors' at ``t_k`` and the command the one in effect up to
    ``t_k`` (sent at ``t_(k-1)``; zero at ``t = 0``, when the rotors already spin at hover)."""

    body: str
    command: np.ndarray
    force: np.ndarray


@dataclass(frozen=True)
class Odometry:
    """A body's ``nav_msgs/Odometry`` as its own driver publishes it (the Bebop's ``bebop_autonomy``
    ``odom``): its pose (``position`` (T, 3) m, ``quaternion`` (T, 4)) with its twist in its body
    frame (FLU), ``linear`` m/s and ``angular`` rad/s, each (T, 3)."""

    body: str
    position: np.ndarray
    quaternion: np.ndarray
    linear: np.ndarray
    angular: np.ndarray


@dataclass(frozen=True)
class Scene:
    """The bodies of one run and what moves them.

    Attributes
    ----------
    bodies : tuple of str
        Frame and topic name of each body (``robot_1`` ..., ``pioneer``, ``master_hand``).
    parents : tuple of str
        The frame each body's pose is in (``world``, ``master_base`` ...).
    position, quaternion : ndarray, shapes (T, N, 3) and (T, N, 4)
        Each body's actual pose (the plant's state).
    position_desired, quaternion_desired : ndarray or None
        The reference's pose of each body.
    position_measured, quaternion_measured : ndarray or None
        What the controller read, where it differs from the state (a motion capture's noise).
    twist : ndarray, shape (T, N, 6), or None
        Each body's command as ``(v_x, v_y, v_z, w_x, w_y, w_z)`` in ``twist_frames``.
    twist_frames : tuple of str
        ``"world"`` or the body's own frame, per body.
    formation, formation_desired : tuple of ndarray or None
        The formation frame's ``(position (T, 3), quaternion (T, 4))`` in the world.
    edges, edges_desired : ndarray, shape (T, 2 E, 3), or None
        End points of the formation's edges (segment k: points 2k, 2k + 1), m, world.
    joints : tuple of Joints
    wrenches : tuple of Wrench
    static : tuple of (parent, child)
        Fixed identity frames (``/tf_static``): the arms' bases at the world origin.
    rotors : tuple of Rotors
        The quadrotors' motors in a MuJoCo run (whose bodies then carry their full attitude,
        tilt included, in ``quaternion``).
    odometry : tuple of Odometry
        Bodies whose driver publishes odometry (the UGV-UAV's Bebop).
    """

    bodies: tuple
    parents: tuple
    position: np.ndarray
    quaternion: np.ndarray
    position_desired: np.ndarray | None = None
    quaternion_desired: np.ndarray | None = None
    position_measured: np.ndarray | None = None
    quaternion_measured: np.ndarray | None = None
    twist: np.ndarray | None = None
    twist_frames: tuple = ()
    formation: tuple | None = None
    formation_desired: tuple | None = None
    edges: np.ndarray | None = None
    edges_desired: np.ndarray | None = None
    joints: tuple = ()
    wrenches: tuple = ()
    static: tuple = field(default_factory=tuple)
    rotors: tuple = ()
    odometry: tuple = ()


def _cols(log, channel: str, names) -> np.ndarray:
    """The columns ``names`` of ``channel``, ``(T, len(names))``; a missing one is one line."""
    have = log.columns(channel)
    missing = [n for n in names if n not in have]
    if missing:
        raise InvalidInputError(f"log channel {channel!r} has no column(s) {', '.join(missing)}; it has "
                                f"{', '.join(have)}")
    return np.asarray(log[channel], dtype=float)[:, [have.index(n) for n in names]]


def _layout_poses(layout: RobotLayout, r, heading=None) -> tuple[np.ndarray, np.ndarray]:
    """Positions (T, N, 3) and quaternions (T, N, 4) of the robots of ``layout`` at ``r`` (T, size);
    ``heading`` (T, N) the yaw of robots whose point has none (NaN: identity)."""
    p = layout.positions(r)
    q = np.zeros(p.shape[:-1] + (4,))
    q[..., 0] = 1.0
    yaw_robots = [i for i, k in enumerate(layout.kinds) if k in ("xy_yaw", "xyz_yaw")]
    if yaw_robots:
        q[:, yaw_robots] = g.q_yaw(layout.yaws(r))  # seed 001 eq. (2.14), the axis z
    pose_robots = [i for i, k in enumerate(layout.kinds) if k == "pose"]
    if pose_robots:
        q[:, pose_robots] = layout.orientations(r)
    if heading is not None:
        free = [i for i, k in enumerate(layout.kinds) if k == "xyz" and np.all(np.isfinite(heading[:, i]))]
        if free:
            q[:, free] = g.q_yaw(heading[:, free])
    return p, q


def _formation(log, channel: str, suffix: str = "") -> tuple | None:
    names = ("x_c", "y_c", "z_c", "q_c_w", "q_c_x", "q_c_y", "q_c_z")
    if channel not in log or not all(n + suffix in log.columns(channel) for n in names):
        return None
    c = _cols(log, channel, [n + suffix for n in names])
    return c[:, :3], c[:, 3:]


def pioneer_base(p: np.ndarray, psi: np.ndarray, a) -> np.ndarray:
    """The middle of a Pioneer's wheel axis (REP-105 ``base_link``) from its control point.

    Parameters
    ----------
    p : ndarray, shape (..., 3)
        The control point, m (quatform's Pioneer state ``(x, y, psi)`` is it).
    psi : ndarray, shape (...)
        The heading, rad.
    a : float or ndarray, shape (...)
        The control point's distance ahead of the axis, m (``robots.Pioneer.a``).

    Returns
    -------
    ndarray, shape (..., 3)
        ``p - a (cos psi, sin psi, 0)`` (seed 001 §3.1.1, eq. (3.5), Fig. 10).
    """
    a = np.asarray(a, dtype=float)
    out = np.array(p, dtype=float, copy=True)
    out[..., 0] -= a * np.cos(psi)
    out[..., 1] -= a * np.sin(psi)
    return out


def sign_continuous(q: np.ndarray) -> np.ndarray:
    """``q`` (T, ..., 4) with each sample's sign the one nearer the previous sample's (``q_k .
    q_(k-1) >= 0``, the first sample as it is): the same rotations, without sign jumps. A NaN
    sample keeps its neighbours' signs apart (the next one is compared with it: no flip)."""
    q = np.asarray(q, dtype=float)
    if q.shape[0] < 2:
        return q
    d = np.sum(q[1:] * q[:-1], axis=-1)
    flip = np.cumsum(np.where(np.isfinite(d), d < 0.0, False), axis=0) % 2 == 1
    out = q.copy()
    out[1:] = np.where(flip[..., None], -q[1:], q[1:])
    return out


def _cumulative_product(s: np.ndarray) -> np.ndarray:
    """``out[k] = s[k] s[k-1] ... s[0]`` of unit quaternions ``s`` (T, 4), normalised: a doubling
    scan (log2 T vectorised products; each result is a product of at most log2 T partial ones)."""
    out = np.array(s, dtype=float, copy=True)
    d = 1
    while d < out.shape[0]:
        out[d:] = g.mul(out[d:], out[:-d])  # the right side is computed from the previous pass
        d *= 2
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def continuous_states(formation, r: np.ndarray) -> np.ndarray:
    """Cluster states (T, n_c) of ``formation`` (a description whose variables 4-7 are ``q_c``, x
    axis along the robots' segment: the quaternion pair, the UGV-UAV quaternion) of the robots
    ``r`` (T, k), with a continuous ``q_c``: seed 000's minimal rotation from ``i`` (eqs. (14)-(15))
    at the first finite sample, then carried to each next sample by the minimal rotation taking
    its segment to the next one (parallel transport: the frame turns only as the segment does,
    never about it), each sample then the point of its fibre nearest that (``near_c``). NaN at
    samples with a NaN robot (a failed world); the transport joins the finite samples around them."""
    out = np.full((r.shape[0], formation.n_c), np.nan)
    ok = np.all(np.isfinite(r), axis=1)
    if not np.any(ok):
        return out
    c = formation.forward(r[ok])
    q = c[:, 3:7]
    u = g.x_axis(q)
    steps = np.concatenate([q[:1], g.swing(u[:-1], u[1:], g.z_axis(q[:-1]))], axis=0)
    hint = c.copy()
    hint[:, 3:7] = _cumulative_product(steps)
    out[ok] = formation.forward(r[ok], near_c=hint)
    return out


def _forward_frame(formation, r: np.ndarray, near: np.ndarray | None = None) -> tuple:
    """The formation frame ``(x_c (T, 3), q_c (T, 4))`` of the robots ``r`` (T, k) by ``formation``'s
    forward map (its first seven variables are ``x_c``, ``q_c``), each ``q_c`` the point of its
    fibre nearest ``near`` (T, n_c) (continuous where ``near`` is), or :func:`continuous_states`
    without ``near``; NaN at samples with a NaN robot or hint (a failed world)."""
    if near is None:
        out = continuous_states(formation, r)[:, :7]
    else:
        out = np.full((r.shape[0], 7), np.nan)
        ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(near), axis=1)
        if np.any(ok):
            out[ok] = formation.forward(r[ok], near_c=near[ok])[:, :7]
    return out[:, :3], out[:, 3:]


def _pair_edges(p: np.ndarray, pairs) -> np.ndarray:
    """End points (T, 2 E, 3) of the segments between the bodies ``pairs`` ((i, j), ...) of ``p`` (T, N, 3)."""
    idx = np.asarray(pairs, dtype=np.intp).reshape(-1)
    return p[:, idx]


def _with_physics(scene: Scene, log, bodies: dict) -> Scene:
    """``scene`` with a MuJoCo run's quadrotors (``log.meta["physics_record"]``, a
    :class:`~quatform.sim.mujoco_backend.PhysicsRecord`) drawn with their full attitude and
    their rotors; ``bodies`` maps the world's quadrotor names to the scene's bodies. A kinematic
    run, or a record that does not cover every tick, leaves ``scene`` as it is."""
    record = log.meta.get("physics_record")
    attitude = None if record is None else record.attitude
    if attitude is None or len(record.t) != len(log):
        return scene
    q = scene.quaternion.copy()
    rotors = []
    for j, name in enumerate(record.quads):
        if name in bodies:
            i = scene.bodies.index(bodies[name])
            q[:, i] = attitude[:, j]
            rotors.append(Rotors(bodies[name], record.rotor_command[:, j], record.rotor_force[:, j]))
    return dataclasses.replace(scene, quaternion=q, rotors=tuple(rotors))


def _twist(u: np.ndarray, spec: CommandTwist) -> np.ndarray:
    out = np.zeros(u.shape[:-1] + (6,))
    out[..., [_TWIST[s] for s in spec.slots]] = u
    return out


def _differs(a, b) -> bool:
    return a.shape != b.shape or not np.array_equal(a, b)


def pair_scene(log) -> Scene:
    """Seed 000's two 4-DOF robots (state ``x_i, y_i, z_i, theta_i``; commands world rates)."""
    layout = RobotLayout.uniform("xyz_yaw", 2)
    names = layout.names
    p, q = _layout_poses(layout, _cols(log, "state", names))
    pd, qd = _layout_poses(layout, _cols(log, "r_des", [n + "_des" for n in names])) if "r_des" in log else (None, None)
    pm, qm = _layout_poses(layout, _cols(log, "measured", names))
    u = np.asarray(log["command"], dtype=float).reshape(len(log), 2, 4)
    # the formation frame of every controller: the quaternion pair's forward map of the robots,
    # nearest the desired frame: the quaternion description's of the desired Euclidean variables
    # (continuous in them), else the desired robots' carried along the run
    frame = FORMATIONS["quaternion"]
    formation_desired = near = None
    if "r_des" in log:
        r_des = _cols(log, "r_des", [n + "_des" for n in names])
        near = _desired_states(frame, log, r_des)
        formation_desired = _forward_frame(frame, r_des, near)
    formation = _forward_frame(frame, _cols(log, "state", names), near)
    scene = Scene(bodies=("robot_1", "robot_2"), parents=("world", "world"), position=p, quaternion=q,
                  position_desired=pd, quaternion_desired=qd,
                  **({"position_measured": pm, "quaternion_measured": qm} if _differs(pm, p) else {}),
                  twist=_twist(u, COMMAND_TWISTS["holonomic"]), twist_frames=("world", "world"),
                  formation=formation, formation_desired=formation_desired,
                  edges=_pair_edges(p, [(0, 1)]), edges_desired=None if pd is None else _pair_edges(pd, [(0, 1)]))
    return _with_physics(scene, log, {"robot1": "robot_1", "robot2": "robot_2"})


def _desired_states(frame, log, r_des: np.ndarray) -> np.ndarray:
    """The desired cluster states (T, 16) of a pair: ``frame.from_chart`` of the desired Euclidean
    variables (``e_des``, seed 000 eqs. (1)-(8), whose ``q_c`` is continuous in them), else
    :func:`continuous_states` of the desired robots."""
    if "e_des" not in log:
        return continuous_states(frame, r_des)
    e_des = np.asarray(log["e_des"], dtype=float)
    out = np.full((len(log), frame.n_c), np.nan)
    ok = np.all(np.isfinite(e_des), axis=1)
    if np.any(ok):
        out[ok] = frame.from_chart(e_des[ok])
    return out


def ugv_uav_scene(log) -> Scene:
    """Seed 001's Pioneer (planar, z = 0) and Bebop; the desired Pioneer heading, which the
    formation leaves free, is its actual one.

    The Pioneer's pose is its base (the middle of its wheel axis, REP-105 ``base_link``), ``a``
    behind the control point its state holds (:func:`pioneer_base`; ``a`` of the kind's default
    :class:`~quatform.robots.Pioneer`, which its controller drives, or ``log.meta["pioneer_a"]``);
    the formation's edges join the control point and the Bebop (the formation's points). The
    Bebop also gets its odometry (its state's velocities as a body twist)."""
    layout = RobotLayout(("xy_yaw", "xyz_yaw"))
    state = ("x_p", "y_p", "psi_p", "x_b", "y_b", "z_b", "psi_b")
    a = float(log.meta.get("pioneer_a", Pioneer().a))
    points, q = _layout_poses(layout, _cols(log, "state", state))
    psi = _cols(log, "state", ("psi_p",))[:, 0]
    p = points.copy()
    p[:, 0] = pioneer_base(points[:, 0], psi, a)
    pm, qm = _layout_poses(layout, _cols(log, "measured", state))
    pm[:, 0] = pioneer_base(pm[:, 0], _cols(log, "measured", ("psi_p",))[:, 0], a)
    pd = qd = points_d = None
    if "r_des" in log:
        des = _cols(log, "r_des", ("x_p_des", "y_p_des", "x_b_des", "y_b_des", "z_b_des"))
        psi_b = _cols(log, "ts_headings", ("psi_b_des",)) if "ts_headings" in log else _cols(log, "state", ("psi_b",))
        points_d, qd = _layout_poses(layout, np.concatenate([des[:, :2], psi[:, None], des[:, 2:], psi_b], axis=1))
        pd = points_d.copy()
        pd[:, 0] = pioneer_base(points_d[:, 0], psi, a)
    u = _cols(log, "command", ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b"))
    twist = np.stack([_twist(u[:, :2], COMMAND_TWISTS["pioneer"]), _twist(u[:, 2:], COMMAND_TWISTS["bebop"])], axis=1)
    # the formation frame of every description: the UGV-UAV quaternion description's forward map
    # of the robots' points (the Pioneer's control point at the platform height, the Bebop); the
    # desired one carried along the run, the actual one nearest it
    frame = FORMATIONS["ugv-uav-quaternion"]
    formation_desired = near = None
    if "r_des" in log:
        near = continuous_states(frame, _cols(log, "r_des", ("x_p_des", "y_p_des", "z_p_des", "x_b_des", "y_b_des",
                                                             "z_b_des")))
        formation_desired = near[:, :3], near[:, 3:7]
    formation = _forward_frame(frame, _cols(log, "r_true", ("x_p", "y_p", "z_p", "x_b", "y_b", "z_b")), near)
    scene = Scene(bodies=("pioneer", "bebop"), parents=("world", "world"), position=p, quaternion=q,
                  position_desired=pd, quaternion_desired=qd,
                  **({"position_measured": pm, "quaternion_measured": qm} if _differs(pm, p) else {}),
                  twist=twist, twist_frames=("pioneer", "bebop"),
                  formation=formation, formation_desired=formation_desired,
                  edges=_pair_edges(points, [(0, 1)]),
                  edges_desired=None if points_d is None else _pair_edges(points_d, [(0, 1)]))
    scene = _with_physics(scene, log, {"uav": "bebop"})
    # the Bebop's odometry is what the controller read of it (the measured state: its velocities
    # come from the drone's odometry, every odometry_period_s in seed 001 §3.1.2)
    velocity = _cols(log, "measured", ("psi_b", "v_x_b", "v_y_b", "z_dot_b", "psi_dot_b"))
    return dataclasses.replace(scene, odometry=(_bebop_odometry(pm[:, 1], qm[:, 1], velocity),))


def _bebop_odometry(p: np.ndarray, q: np.ndarray, state: np.ndarray) -> Odometry:
    """The Bebop's odometry at ``p`` (T, 3), ``q`` (T, 4) with the body twist of its state
    ``(psi, v_x, v_y, z_dot, psi_dot)`` (T, 5): ``(v_x, v_y)`` are in its heading frame and
    ``z_dot`` vertical (seed 001 eq. (3.8)), turned into the world by ``q_yaw(psi)`` and into the
    body frame by ``conj(q)``; the angular rate is the yaw rate about the world's z in the body
    frame."""
    psi, v_x, v_y, z_dot, psi_dot = state.T
    v_world = g.rotate(g.q_yaw(psi), np.stack([v_x, v_y, z_dot], axis=-1))
    w_world = np.stack([np.zeros_like(psi), np.zeros_like(psi), psi_dot], axis=-1)
    body = g.conj(q)
    return Odometry("bebop", p, q, g.rotate(body, v_world), g.rotate(body, w_world))


#: Teams of up to this many robots draw every pair as an edge; larger ones a star from the formation's
#: origin (the team chart's centroid, whose shape vectors ``s_i`` point at the robots).
ALL_PAIRS_UP_TO = 6


def _team_edges(p: np.ndarray, origin) -> np.ndarray:
    """Every pair for a small team; a star from the formation's origin (else a chain) for a large one."""
    n = p.shape[1]
    if n <= ALL_PAIRS_UP_TO:
        i, j = np.triu_indices(n, 1)
        return _pair_edges(p, np.stack([i, j], axis=1))
    if origin is None:
        return _pair_edges(p, np.stack([np.arange(n - 1), np.arange(1, n)], axis=1))
    both = np.concatenate([np.broadcast_to(origin[:, None, :], p.shape), p], axis=-1)  # (T, N, 6)
    return both.reshape(p.shape[0], 2 * n, 3)


def team_scene(log) -> Scene:
    """A team: the robots' points (``points``, ``r_des``) read with the run's layout."""
    layout, team = log.meta.get("layout"), log.meta.get("team")
    if not isinstance(layout, RobotLayout) or team is None:
        raise InvalidInputError("a team log needs meta['layout'] (its RobotLayout) and meta['team'] (its "
                                "Team), which a log read back from run.mcap lacks: write the log a team "
                                "experiment's run returned (quatform run), or write_mcap(log, path, scene=False)")
    state = np.asarray(log["state"], dtype=float)
    heading = np.full((len(log), layout.n), np.nan)
    parts = team.split(state)
    for i, (model, x) in enumerate(zip(team.robots, parts)):
        for stem in ("psi", "theta"):
            if stem in model.state_columns:
                heading[:, i] = x[:, model.state_columns.index(stem)]
                break
    points, q = _layout_poses(layout, np.asarray(log["points"], dtype=float), heading)
    points_d = qd = None
    if "r_des" in log:
        points_d, qd = _layout_poses(layout, np.asarray(log["r_des"], dtype=float), heading)
    # a Pioneer's pose is its base, a behind the control point the formation moves (its point)
    pioneers = [i for i, model in enumerate(team.robots) if isinstance(model, Pioneer)]
    a = np.array([team.robots[i].a for i in pioneers])
    p, pd = points, points_d
    if pioneers:
        p = points.copy()
        p[:, pioneers] = pioneer_base(points[:, pioneers], heading[:, pioneers], a)
        if points_d is not None:
            pd = points_d.copy()
            pd[:, pioneers] = pioneer_base(points_d[:, pioneers], heading[:, pioneers], a)
    u = np.asarray(log["command"], dtype=float)
    twist = np.zeros((len(log), layout.n, 6))
    frames = []
    for i, (model, ui) in enumerate(zip(team.robots, team.split(u, team.command_slices))):
        spec = COMMAND_TWISTS.get(model.name)
        if spec is None:
            raise InvalidInputError(f"robot model {model.name!r} has no entry in quatform.bags.scene.COMMAND_TWISTS; "
                                    f"add how its commands {model.command_columns} read as a twist")
        twist[:, i] = _twist(ui, spec)
        frames.append("world" if spec.frame == "world" else f"robot_{layout.labels[i]}")
    # the formation frame of every controller: the team chart's x_c, q_c (channels e, e_des)
    formation, formation_desired = _formation(log, "e"), _formation(log, "e_des", "_des")
    bodies = tuple(f"robot_{lab}" for lab in layout.labels)
    scene = Scene(bodies=bodies, parents=("world",) * layout.n, position=p, quaternion=q,
                  position_desired=pd, quaternion_desired=qd, twist=twist, twist_frames=tuple(frames),
                  formation=formation, formation_desired=formation_desired,
                  edges=_team_edges(points, None if formation is None else formation[0]),
                  edges_desired=None if points_d is None else _team_edges(points_d, None if formation_desired is None
                                                                          else formation_desired[0]))
    # the team plant names its world bodies robot1 ... robotN, in robot order
    return _with_physics(scene, log, {f"robot{i + 1}": body for i, body in enumerate(bodies)})


def teleop_scene(log) -> Scene:
    """Seed 003's master and slave: their hands' poses in their base frames (both bases at the
    world origin, so the slave's hand is drawn over the master's), joint states, the wrist wrench."""
    p = np.stack([_cols(log, "p_m", ("p_m_x", "p_m_y", "p_m_z")), _cols(log, "p_s", ("p_s_x", "p_s_y", "p_s_z"))], axis=1)
    q = np.stack([_cols(log, "r_m", ("r_m_w", "r_m_x", "r_m_y", "r_m_z")),
                  _cols(log, "r_s", ("r_s_w", "r_s_x", "r_s_y", "r_s_z"))], axis=1)
    state = log.columns("state")
    command = log.columns("command")
    arms = []
    for arm, tag in (("master", "m"), ("slave", "s")):
        names = tuple(c for c in state if c.startswith(f"q_{tag}"))
        j = [c[len(f"q_{tag}"):] for c in names]
        arms.append(Joints(arm, tuple(f"{arm}_joint_{k}" for k in j), _cols(log, "state", names),
                           _cols(log, "state", [f"qd_{tag}{k}" for k in j]),
                           _cols(log, "command", [f"tau_{tag}{k}" for k in j])
                           if all(f"tau_{tag}{k}" in command for k in j) else np.zeros((len(log), len(j)))))
    wrench = Wrench("slave_wrist", "slave_base", _cols(log, "state", ("F_s_x", "F_s_y", "F_s_z")),
                    _cols(log, "state", ("M_s_x", "M_s_y", "M_s_z")))
    return Scene(bodies=("master_hand", "slave_hand"), parents=("master_base", "slave_base"), position=p,
                 quaternion=q, joints=tuple(arms), wrenches=(wrench,),
                 static=(("world", "master_base"), ("world", "slave_base")))


@dataclass(frozen=True)
class Plot:
    """One plot panel of a run's Foxglove layout.

    Attributes
    ----------
    key : str
        The panel's id is ``Plot!<key>``.
    title : str
        The panel's title, with the units (Foxglove's ``foxglovePanelTitle``).
    series : tuple of (str, str)
        ``(message path, label)`` of each line: ``/topic.field.field`` or ``/topic.field[index]``
        in Foxglove's message-path syntax, of a topic the kind's ``run.mcap`` has.
    """

    key: str
    title: str
    series: tuple


def formation_plots(scene: Scene) -> tuple:
    """The plots of a formation run (pair, UGV-UAV, team): the formation frame's position and
    attitude against the reference (``/formation/pose``, ``/formation/pose_desired``), their
    difference (``/formation/error``) and the singularity measure (``/quatform/singularity``),
    topics every controller's run has; a MuJoCo run's quadrotors' thrust (``/<body>/rotors``);
    none where the scene has no formation frame."""
    if scene.formation is None:
        return ()
    desired = scene.formation_desired is not None
    poses = (("/formation/pose", ""),) + ((("/formation/pose_desired", " desired"),) if desired else ())
    position = tuple((f"{topic}.pose.position.{a}", f"{a}_c{tag}") for topic, tag in poses for a in "xyz")
    attitude = tuple((f"{topic}.pose.orientation.{a}", f"q_c_{a}{tag}") for topic, tag in poses for a in "wxyz")
    error = ((tuple((f"/formation/error.{a}", f"error {a} (m)") for a in "xyz")
              + (("/formation/error.angle", "error angle (rad)"),)) if desired else ())
    error += (("/quatform/singularity.singularity_measure", "singularity measure"),)
    plots = (Plot("position", "Formation position (m): actual and desired", position),
             Plot("attitude", "Formation attitude q_c (w, x, y, z): actual and desired", attitude),
             Plot("error", "Formation error (desired - actual) and singularity measure", error))
    if scene.rotors:  # a MuJoCo run: each quadrotor's collective thrust
        plots += (Plot("rotors", "Rotor thrust (N): the sum of each quadrotor's rotor forces",
                       tuple((f"/{r.body}/rotors.thrust", f"{r.body} thrust") for r in scene.rotors)),)
    return plots


#: Columns of a teleoperation run's task error channel ``e`` (``/quatform/e``): the position
#: error (m) and the orientation error (``delta_eps``, or roll-pitch-yaw in rad), seed 003.
TELEOP_ERROR_FIELDS = tuple(f"e_{i}" for i in range(1, 7))


def teleop_plots(scene: Scene) -> tuple:
    """The plots of a teleoperation run (seed 003): the hands' positions (the master's registered
    into the slave's base, so the two lines of an axis coincide when the slave follows), the task
    error ``e`` with the angle between the hands, each arm's joint torque commands and the wrist
    wrench."""
    hands = tuple((f"/{body}/pose.pose.position.{a}", f"{body} {a}") for body in scene.bodies for a in "xyz")
    error = (tuple((f"/quatform/e.{f}", f + (" (m)" if i < 3 else "")) for i, f in enumerate(TELEOP_ERROR_FIELDS))
             + (("/quatform/angle.angle", "angle between the hands (rad)"),))
    torques = tuple((f"/{arm.arm}/joint_states.effort[{j}]", name) for arm in scene.joints
                    for j, name in enumerate(arm.names))
    plots = [Plot("hands", "Hand positions (m): master (registered) and slave", hands),
             Plot("error", "Task error e: position e_1..e_3 (m), orientation e_4..e_6; angle between the hands (rad)",
                  error),
             Plot("torques", "Joint torque commands (N m)", torques)]
    for w in scene.wrenches:
        plots.append(Plot(f"wrench_{w.name}", f"{w.name} wrench: force (N) and torque (N m), in {w.frame}",
                          tuple((f"/{w.name}/wrench.wrench.{part}.{a}", f"{part} {a}")
                                for part in ("force", "torque") for a in "xyz")))
    return tuple(p for p in plots if p.series)


#: Most edges a network run's bag draws per tick (a larger graph's are thinned evenly).
SCENE_EDGES = 600


def network_scene(log):
    """The robots of a network run (:func:`team_scene`) with the edges that
    delivered a message at each tick as the markers (``/formation/edges``): a segment from the
    sender to the receiver, collapsed onto the receiver at a tick its edge delivered nothing."""
    scene = team_scene(log)
    world, batch = log.meta.get("world") or (), log.meta.get("batch") or ()
    b = int(np.ravel_multi_index(world, batch)) if world else 0
    links = log.meta["links"]
    links = dataclasses.replace(links, seed=links.seed + b)  # world b of a batch draws from seed + b
    new = links.schedule(log.t, float(log.meta["dt_s"]))["new"]
    edges = np.asarray(log.meta["graph"]["links"]["candidate_edges"], dtype=int) - 1
    pick = np.linspace(0, len(edges) - 1, min(len(edges), SCENE_EDGES)).astype(int) if len(edges) else \
        np.zeros(0, dtype=int)
    p = scene.position
    recv, send = p[:, edges[pick, 0]], p[:, edges[pick, 1]]
    other = np.where(new[:, pick, None], send, recv)
    seg = np.stack([recv, other], axis=2).reshape(len(p), 2 * len(pick), 3)
    return dataclasses.replace(scene, edges=seg, edges_desired=None)


def network_plots(scene) -> tuple:
    """The plots of a network run's layout: the consensus error, and what the links carried per
    tick with the oldest message used (the channels ``consensus_error`` and ``network``)."""
    return (Plot("consensus", "Consensus error (the law's unit: m for the position laws)",
                 (("/quatform/consensus_error.consensus_error", "consensus error"),)),
            Plot("links", "Links per tick: messages sent, lost, delivered (count); oldest message used (s)",
                 tuple((f"/quatform/network.{c}", c) for c in NETWORK_SIGNALS)))


@dataclass(frozen=True)
class SceneKind:
    """What a scenario kind's run shows: ``build(log) -> Scene`` (its bodies, frames, edges ...)
    and ``plots(scene) -> tuple of Plot`` (the plot panels of its Foxglove layout, of topics its
    ``run.mcap`` has). ``SCENES[kind](log)`` builds the scene."""

    build: Callable
    plots: Callable

    def __call__(self, log) -> Scene:
        return self.build(log)


#: Scene and plots of each scenario kind (by :attr:`ScenarioKind.name`); a kind's module (here,
#: or the file defining a new kind) adds its entry with ``SCENES.add(name, SceneKind(build,
#: plots))``, and its runs get their bag's poses, TF and markers and their Foxglove layout.
SCENES = Registry("scene")
SCENES.add("pair", SceneKind(pair_scene, formation_plots))
SCENES.add("ugv-uav", SceneKind(ugv_uav_scene, formation_plots))
SCENES.add("team", SceneKind(team_scene, formation_plots))
SCENES.add("teleop", SceneKind(teleop_scene, teleop_plots))
SCENES.add("network", SceneKind(network_scene, network_plots))


def scene_of(log, kind: str | None = None) -> Scene:
    """The :class:`Scene` of one world's ``log`` (``kind``: default ``log.meta["kind"]``)."""
    kind = kind or log.meta.get("kind")
    return _signs_continuous(scene_kind(kind).build(log))


def scene_kind(kind: str) -> SceneKind:
    """The :class:`SceneKind` of scenario kind ``kind`` (one line naming the kinds where it has none)."""
    if kind not in SCENES:
        from ..checks import nearest

        raise InvalidInputError(f"no scene for scenario kind {kind!r}{nearest(str(kind), SCENES)}; kinds: "
                                f"{', '.join(SCENES)}")
    return SCENES[kind]


def _signs_continuous(scene: Scene) -> Scene:
    """``scene`` with every quaternion series :func:`sign_continuous`."""
    def pose(pq):
        return None if pq is None else (pq[0], sign_continuous(pq[1]))

    def maybe(q):
        return None if q is None else sign_continuous(q)

    return dataclasses.replace(
        scene, quaternion=sign_continuous(scene.quaternion), quaternion_desired=maybe(scene.quaternion_desired),
        quaternion_measured=maybe(scene.quaternion_measured), formation=pose(scene.formation),
        formation_desired=pose(scene.formation_desired),
        odometry=tuple(dataclasses.replace(od, quaternion=sign_continuous(od.quaternion)) for od in scene.odometry))

