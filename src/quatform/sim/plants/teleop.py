"""Seed 003's teleoperator as one plant: two arms, the operator's hand, the slave's environment.

Sim layer, plants. :class:`TeleopPlant` is a plant of :func:`quatform.sim.simulate.simulate`:

* the **master** (:class:`~quatform.robots.arms.KraftMaster`: joint inertias, viscous
  friction, and the static and Coulomb friction that makes each actuated joint need ~15 % of
  full scale to move, the "dead region" of seed 003 §6; joint 6 unactuated) is driven by the
  controller's torques and by a **hand** (:class:`Hand`), a spring-damper pulling the handle
  toward a commanded pose path;
* the **slave** (:class:`~quatform.robots.arms.PandaSlave`: the 7-DOF arm with its mass
  matrix, Coriolis and centrifugal torques and joint damping) is driven by the controller's
  torques and by its environment: a **wall** (:class:`ContactWall`) of given stiffness and
  damping, and optionally a **push** (:class:`SlavePush`), an external spring moving its tool
  (what moves the slave when the master follows it);
* the wrist **sensor** reads the force the slave exerts on its environment at the end of
  each step, so the controller of the next cycle sees it (``F_s`` in the state).

State (:attr:`TeleopPlant.state_columns`): ``q_m``, ``qd_m``, ``q_s``, ``qd_s`` and the wrist
reading ``F_s`` (force, then a zero moment); the output is the whole state (a perfect
measurement: what :class:`~quatform.teleop.TeleopController` measures, in its
``measured_columns`` order). One step is one control cycle: semi-implicit Euler, torques
held (the master's friction resolved per joint, its inertia being diagonal). What the
environment does in a step that is not in the state (the hand's force, the force the
master's actuators make at the handle, the master's depth into its virtual walls) is
recomputed from logged states and commands by :meth:`TeleopPlant.forces`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...algebra import q_from_axis_angle, qmul, qslerp
from ...algebra.kernels import array_namespace, qmul_components
from ...robots.arms import KraftMaster, PandaSlave
from ...teleop import KRAFT_MASTER
from ...teleop.kernels import over_worlds

__all__ = ["HandKey", "Hand", "SlavePush", "ContactWall", "TeleopPlant", "angle_between"]


def _smooth(s):
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@dataclass(frozen=True)
class HandKey:
    """Where the hand holds the master's handle at ``t_s``: master joints ``q`` (whose tool
    pose it is), or ``move`` (m) and ``turn`` (rotation vector, rad) from the home pose,
    both in the master's base axes. Between two joint keys the path is interpolated in
    joint space; otherwise pose by pose (position linearly, orientation by slerp), with a
    smooth start and stop."""

    t_s: float
    q: tuple | None = None
    move: tuple = (0.0, 0.0, 0.0)
    turn: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Hand:
    """The operator's hand: a spring-damper on the handle (N/m, N s/m, N m/rad, N m s/rad)."""

    keys: tuple = (HandKey(0.0),)
    stiffness: float = 400.0
    damping: float = 20.0
    rot_stiffness: float = 4.0
    rot_damping: float = 0.2

    def key_poses(self, home) -> list:
        """Each key's handle pose ``(p, r)``; ``home`` is the master's home tool pose."""
        return [self._pose(k, home) for k in self.keys]

    def target(self, t, poses):
        """The commanded handle pose ``(p, r)`` at ``t`` (master base frame); ``poses`` from
        :meth:`key_poses`."""
        keys = self.keys
        k = 0
        while k + 1 < len(keys) and t >= keys[k + 1].t_s:
            k += 1
        if k + 1 >= len(keys) or t <= keys[k].t_s:
            return poses[k]
        a, b = keys[k], keys[k + 1]
        s = _smooth((t - a.t_s) / (b.t_s - a.t_s))
        if a.q is not None and b.q is not None:
            qa, qb = np.asarray(a.q, float), np.asarray(b.q, float)
            return KRAFT_MASTER.forward(qa + s * (qb - qa))
        (pa, ra), (pb, rb) = poses[k], poses[k + 1]
        return pa + s * (pb - pa), qslerp(ra, rb, s)

    def targets(self, ts, poses):
        """:meth:`target` at each time of ``ts`` ``(T,)``: positions ``(T, 3)``, orientations ``(T, 4)``."""
        ts = np.asarray(ts, dtype=float)
        keys = self.keys
        kt = np.array([k.t_s for k in keys])
        seg = np.searchsorted(kt[1:], ts, side="right")  # the key each time follows (the while loop of target)
        p = np.array([poses[k][0] for k in seg], dtype=float).reshape(ts.shape + (3,))
        r = np.array([poses[k][1] for k in seg], dtype=float).reshape(ts.shape + (4,))
        for k in range(len(keys) - 1):
            sel = np.flatnonzero((seg == k) & (ts > kt[k]))
            if not sel.size:
                continue
            a, b = keys[k], keys[k + 1]
            x = np.clip((ts[sel] - a.t_s) / (b.t_s - a.t_s), 0.0, 1.0)
            s = (x * x * (3.0 - 2.0 * x))[:, None]  # _smooth
            if a.q is not None and b.q is not None:
                qa, qb = np.asarray(a.q, float), np.asarray(b.q, float)
                p[sel], r[sel] = KRAFT_MASTER.forward(qa + s * (qb - qa))
            else:
                (pa, ra), (pb, rb) = poses[k], poses[k + 1]
                p[sel], r[sel] = pa + s * (pb - pa), qslerp(ra, rb, s[:, 0])
        return p, r

    @staticmethod
    def _pose(key, home):
        if key.q is not None:
            return KRAFT_MASTER.forward(np.asarray(key.q, float))
        p0, r0 = home
        turn = np.asarray(key.turn, float)
        angle = float(np.linalg.norm(turn))
        r = r0 if angle == 0.0 else qmul(q_from_axis_angle(turn / angle, angle), r0)
        return p0 + np.asarray(key.move, float), r


@dataclass(frozen=True)
class SlavePush:
    """An external spring-damper pulling the slave's tool toward ``home + move(t)`` (slave
    base axes): ``keys`` are ``(t_s, (dx, dy, dz))`` pairs, interpolated smoothly."""

    keys: tuple
    stiffness: float = 2000.0
    damping: float = 60.0

    def target(self, t, home):
        keys = self.keys
        k = 0
        while k + 1 < len(keys) and t >= keys[k + 1][0]:
            k += 1
        if k + 1 >= len(keys) or t <= keys[k][0]:
            return home + np.asarray(keys[min(k, len(keys) - 1)][1], float)
        (ta, ma), (tb, mb) = keys[k], keys[k + 1]
        s = _smooth((t - ta) / (tb - ta))
        return home + np.asarray(ma, float) + s * (np.asarray(mb, float) - np.asarray(ma, float))


@dataclass(frozen=True)
class ContactWall:
    """A frictionless wall in the slave's workspace: free side ``normal . (p - point) >= 0``.

    Inside, the wall pushes the tool point out with ``stiffness depth + damping (inward
    speed)`` along ``normal`` (N/m, N s/m).
    """

    point: tuple
    normal: tuple
    stiffness: float = 5000.0
    damping: float = 50.0

    def force_on_slave(self, p, v):
        """The wall's force on the tool point ``p`` moving at ``v`` (slave axes, N) and its
        depth (m; 0 outside); NumPy or JAX arrays."""
        xp = array_namespace(p)
        n = np.asarray(self.normal, float)
        n = n / np.linalg.norm(n)
        depth = -xp.dot(n, p - np.asarray(self.point, float))
        inward = xp.maximum(-xp.dot(n, v), 0.0)
        inside = depth > 0.0
        return xp.where(inside, (self.stiffness * depth + self.damping * inward) * n, 0.0), xp.where(inside, depth, 0.0)


def angle_between(q1, q2) -> np.ndarray:
    """Rotation angle of ``q1* q2`` (rad, in ``[0, pi]``), precise for small angles; ``(..., 4)`` -> ``(...)``."""
    q1, q2 = np.asarray(q1, float), np.asarray(q2, float)
    d = qmul_components(q1[..., 0], -q1[..., 1], -q1[..., 2], -q1[..., 3], *np.moveaxis(q2, -1, 0))
    return 2.0 * np.arctan2(np.sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3]), np.abs(d[0]))


def _split(x, n_m, n_s):
    i = np.cumsum([n_m, n_m, n_s, n_s])
    return x[..., :i[0]], x[..., i[0]:i[1]], x[..., i[1]:i[2]], x[..., i[2]:i[3]]


@dataclass(frozen=True)
class TeleopPlant:
    """The master, the slave, the hand and the environment (see the module docstring).

    Parameters
    ----------
    master : KraftMaster
    slave : PandaSlave
    hand : Hand
    hand_poses : list
        Each hand key's handle pose ``(p, r)`` (:meth:`Hand.key_poses` at the master's home).
    p_s0 : ndarray, shape (3,)
        The slave's home tool position, m (the push's origin).
    push : SlavePush, optional
    wall : ContactWall, optional
    virtual_walls : tuple of VirtualWall
        The controller's walls, for their depth (:meth:`forces`).
    """

    master: KraftMaster
    slave: PandaSlave
    hand: Hand
    hand_poses: list
    p_s0: np.ndarray
    push: SlavePush | None = None
    wall: ContactWall | None = None
    virtual_walls: tuple = ()

    #: A batch steps world by world (the slave's Coriolis torques and the master's friction take
    #: one configuration).
    batchable = True

    @property
    def state_columns(self) -> tuple:
        return (self.master.state_columns[:self.master.arm.n] + self.master.state_columns[self.master.arm.n:]
                + self.slave.state_columns + ("F_s_x", "F_s_y", "F_s_z", "M_s_x", "M_s_y", "M_s_z"))

    @property
    def output_columns(self) -> tuple:
        return self.state_columns

    def output(self, x):
        return x

    def _hand_wrench(self, hand_pose, p_master, r_master, v_m):
        """The hand's wrench on the handle ``[force; moment]`` (master axes); ``hand_pose``
        the hand's target ``(p, r)`` (:meth:`Hand.target`)."""
        xp = array_namespace(p_master)
        h = self.hand
        p_h, r_h = hand_pose
        d = qmul_components(*r_h, r_master[0], -r_master[1], -r_master[2], -r_master[3])  # the hand's error
        short = d[0] >= 0  # the short way
        d = tuple(xp.where(short, c, -c) for c in d)
        return xp.concatenate([h.stiffness * (p_h - p_master) - h.damping * v_m[0:3],
                               h.rot_stiffness * 2.0 * xp.stack(d[1:]) - h.rot_damping * v_m[3:6]])

    def _environment_force(self, push_target, p_s, v_s):
        """The wall's and the push's force on the slave's tool (slave axes), N; ``push_target``
        the push's target (:meth:`SlavePush.target`; None without a push)."""
        F_env = array_namespace(p_s).zeros(3)
        if self.wall is not None:
            F_env = F_env + self.wall.force_on_slave(p_s, v_s)[0]
        if self.push is not None:
            F_env = F_env + self.push.stiffness * (push_target - p_s) - self.push.damping * v_s
        return F_env

    def targets_at(self, t):
        """What moves the plant at ``t`` independently of its state: the hand's target pose
        ``(p, r)`` and the push's target position (None without a push)."""
        return self.hand.target(t, self.hand_poses), None if self.push is None else self.push.target(t, self.p_s0)

    def inputs(self, times, dt: float, substeps: int) -> dict:
        """The exogenous inputs of every plant step of a run (:mod:`quatform.sim.loop`): the
        hand's target ``p_h`` ``(T, substeps, 3)``, ``r_h`` ``(T, substeps, 4)`` and, with a push,
        its target ``push`` ``(T, substeps, 3)`` (:meth:`targets_at` at ``t_k + j dt``)."""
        hand_p, hand_r, push = [], [], []
        for t in np.asarray(times, dtype=float):
            for j in range(substeps):
                (p_h, r_h), target = self.targets_at(float(t) + j * dt)
                hand_p.append(p_h)
                hand_r.append(r_h)
                push.append(target)
        n = len(times)
        out = {"p_h": np.asarray(hand_p, float).reshape(n, substeps, 3),
               "r_h": np.asarray(hand_r, float).reshape(n, substeps, 4)}
        if self.push is not None:
            out["push"] = np.asarray(push, float).reshape(n, substeps, 3)
        return out

    def step(self, x, u, dt: float, t: float, w: dict | None = None):
        """The state one control cycle later under the held torques ``u`` (``tau_m``, ``tau_s``),
        ``(*batch, n_x)`` and ``(*batch, n_u)``; ``w`` the step's slice of :meth:`inputs`
        (None: :meth:`targets_at` ``t``). Pure, on NumPy or JAX arrays; a batch runs world by
        world (:func:`quatform.teleop.kernels.over_worlds`: the arms take one configuration)."""
        if w is None:
            (p_h, r_h), target = self.targets_at(t)
        else:
            p_h, r_h, target = w["p_h"], w["r_h"], w.get("push")
        return over_worlds(lambda xi, ui: self._step_one(xi, ui, dt, (p_h, r_h), target), np.ndim(x) - 1, x, u)

    def _step_one(self, x, u, dt: float, hand_pose, push_target):
        """:meth:`step` of one world with the hand's and the push's targets given."""
        xp = array_namespace(x)
        M, S = self.master, self.slave
        n_m = M.arm.n
        q_m, qd_m, q_s, qd_s = _split(x, n_m, S.arm.arm.n)
        Fm = M.arm.frames(q_m)
        J_mf = M.arm.jacobian(q_m, Fm)
        p_master, r_master = M.arm.forward(q_m, Fm)
        wrench = self._hand_wrench(hand_pose, p_master, r_master, J_mf @ qd_m)
        x_m = M.step(x[:2 * n_m], u[:n_m] + J_mf.T @ wrench, dt)
        arm = S.arm.arm
        Fs = arm.frames(q_s)
        J_sf = arm.jacobian(q_s, Fs)
        p_s = arm.tool(Fs)
        F_env = self._environment_force(push_target, p_s, J_sf[0:3] @ qd_s)
        x_s = S.step(x[2 * n_m:-6], u[n_m:] + J_sf[0:3].T @ F_env, dt, M=S.arm.mass_matrix(q_s, Fs))
        # the wrist sensor: what the slave exerts on its environment
        return xp.concatenate([x_m, x_s, -F_env, xp.zeros(3)])

    def forces(self, t, x, u) -> dict:
        """What the environment did at each logged tick, from the states ``x`` ``(T, n_x)``
        and the commands ``u`` ``(T, n_u)`` at the times ``t`` ``(T,)``:

        ``p_master`` ``(T, 3)`` the master's tool in its own base frame, m; ``F_hand``
        ``(T, 3)`` the hand's force on the master (master axes), N; ``F_reflected`` ``(T, 3)``
        the force at the handle the master actuators' torques make (the least-squares
        solution of ``J_mf^T [F; m] = tau_m``), N; ``wall_depth`` ``(T, n_walls)`` the master's
        depth into each virtual wall over that wall's thickness (<= 0 outside, > 1 through it).
        """
        M = self.master
        n_m = M.arm.n
        q_m, qd_m, _, _ = _split(np.asarray(x, float), n_m, self.slave.arm.arm.n)
        Fm = M.arm.frames(q_m)
        J_mf = M.arm.jacobian(q_m, Fm)
        p_master = M.arm.tool(Fm)
        v_m = np.einsum("...ij,...j->...i", J_mf, qd_m)
        p_h, _ = self.hand.targets(t, self.hand_poses)
        F_hand = self.hand.stiffness * (p_h - p_master) - self.hand.damping * v_m[:, 0:3]  # as in _hand_wrench
        tau_m = np.asarray(u, float)[:, :n_m]
        F_reflected = np.einsum("...ij,...j->...i", np.linalg.pinv(np.swapaxes(J_mf, -1, -2)), tau_m)[:, 0:3]
        depth = np.stack([w.depth(p_master) / w.thickness_m for w in self.virtual_walls], axis=-1) \
            if self.virtual_walls else np.zeros((len(t), 0))
        return {"p_master": p_master, "F_hand": F_hand, "F_reflected": F_reflected, "wall_depth": depth}
