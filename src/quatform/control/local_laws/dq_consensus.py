"""Dual-quaternion pose consensus and time-varying formation tracking on a directed spanning tree.

Control layer. Savino, Pimenta, Shah & Adorno (J. Franklin Inst. 357(1), 2020, arXiv
1810.08871) reach pose consensus by running the linear consensus protocol on the logarithms
of the agents' unit dual quaternions, ``vec6(log x)`` with dqrobotics' decoupled logarithm
``log x = log r + eps t/2``, and map the logarithm's rate onto the pose's through its
Jacobian ``Q8(x)`` (their Theorem 4; its rotation block ``Q4(r)``, their eq. (22), as DQ Robotics
implements them): the logarithms obey ``l_dot = -k (L ⊗ I6) l``, so consensus holds on every
directed graph with a spanning tree, at the rate ``k Re λ₂``.

Here robot ``i`` runs it on its formation variable ``y_i = x_i x_i^d(t)*`` (``x_i = y_i
x_i^d``), with the rotation vector ``theta_i = 2 log r(y_i)`` (the short way, ``|theta_i| <=
pi``) and the translation ``t_i`` of ``y_i`` (m), the same coordinates as ``vec6(log y_i)``
scaled by 2:

    (theta_i, t_i)_dot = k [sum_j a_ij valid_ij ((theta_j, t_j) - (theta_i, t_i)) - b_i (theta_i, t_i)]

``b_i >= 0`` (the reference's ``leader``) pins robot ``i`` to its own desired pose: with
``b = 0`` the team reaches consensus, ``x_i = c x_i^d(t)`` for a common ``c``; with ``b_r > 0``
at a root of the spanning tree (the leader) the whole team tracks its desired poses, ``y_i ->
1``, at the rate ``k min Re λ(L + diag(b))``. The rotation vector's rate becomes the angular
velocity of ``y_i`` through the left Jacobian of SO(3), ``w = J_l(theta) theta_dot`` (``Q4``'s
content in world coordinates), and the robot's command adds its desired pose's motion,
``x_dot x* = zeta_i + y_i xi_i^d y_i*`` (:func:`.dq_pose.pose_twist_commands`): the
time-varying formation is tracked without lag.

**What each robot knows.** Its own pose; its row of the reference: its desired pose
``x_i^d(t)`` and twist (the formation's motion composed with its own time-varying place in
it: a leader's moving reference enters every robot's desired pose) and its pinning weight
``b_i``; and, from its inbox only, its in-neighbours' ``y_j`` (each robot sends its own). No
robot needs another's desired pose or the leader's state.

**Double cover.** The short-way logarithm is the same for ``y`` and ``-y`` (the canonical sign,
decided at half a turn without a tie), so ``x``, ``-x``, ``x^d`` and ``-x^d`` give one command.
``theta = (2 atan2(|v|, |w|) / |v|) v`` is 2 at ``v = 0`` (no division by zero) and stays
finite at half a turn, where the chart's two representatives ``+-pi n`` of one rotation meet.

**Global on the chart, not on SO(3).** The consensus is linear on the closed ball ``|theta| <=
pi``, so every start converges (the linear protocol keeps the ``theta`` within their convex
hull); but the chart is centred on each robot's desired pose, not on its neighbours: two
robots a small angle apart across the half turn agree by turning the long way, through the
desired pose, and the agreed pose depends on where the chart is centred.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...algebra.kernels import common_namespace, dot_last
from ..local import LocalTick
from . import dq_pose as dq

__all__ = ["DQConsensus", "log_coordinates", "left_jacobian_times"]

_SMALL = 1e-2  # angles (rad) below which the series of the Jacobian's coefficients are used


def log_coordinates(y):
    """``(theta, t)`` ``(..., 6)`` of unit dual quaternions ``y`` ``(..., 8)``: the rotation vector
    (rad) of ``y``'s rotation the short way round, ``|theta| <= pi``, and its translation (m);
    ``2 vec6(log y)`` in dqrobotics' decoupled logarithm (Savino et al. 2020, Sec. 2). The same for
    ``y`` and ``-y``."""
    xp = common_namespace(y)
    y = dq.canonical(y)
    s = xp.sqrt(dot_last(y[..., 1:4], y[..., 1:4]))
    c = y[..., 0]
    ratio = xp.where(s > 0.0, 2.0 * xp.arctan2(s, c) / xp.where(s > 0.0, s, 1.0), 2.0)
    return xp.concatenate([ratio[..., None] * y[..., 1:4], dq.translation(y)], axis=-1)


def left_jacobian_times(theta, rate):
    """``J_l(theta) rate`` ``(..., 3)``: the world angular velocity (rad/s) of ``exp(theta)``
    whose rotation vector moves at ``rate`` (rad/s); ``J_l = I + a [theta]x + b [theta]x^2``,
    ``a = (1 - cos p)/p^2``, ``b = (p - sin p)/p^3``, ``p = |theta|``, by their series below
    ``_SMALL``."""
    xp = common_namespace(theta, rate)
    p2 = dot_last(theta, theta)
    p = xp.sqrt(p2)
    small = p < _SMALL
    ps = xp.where(small, 1.0, p)
    a = xp.where(small, 0.5 - p2 / 24.0 + p2 * p2 / 720.0, (1.0 - xp.cos(ps)) / (ps * ps))
    b = xp.where(small, 1.0 / 6.0 - p2 / 120.0 + p2 * p2 / 5040.0, (ps - xp.sin(ps)) / (ps * ps * ps))
    tr = dq.cross(theta, rate)
    return rate + a[..., None] * tr + b[..., None] * dq.cross(theta, tr)


@dataclass(frozen=True)
class DQConsensus(dq.PoseLaw):
    """Each robot: linear consensus on the log coordinates of ``y = x x_d*``, pinned by ``b`` (module docstring).

    Parameters
    ----------
    gain : float
        ``k``, 1/s, > 0.

    Reference (per tick): ``{"pose": (*batch?, N, 8)`` each robot's desired pose (unit dual
    quaternions); ``"twist": (*batch?, N, 6)`` their world ``(v, w)`` m/s and rad/s (default 0);
    ``"leader": (*batch?, N)`` the pinning weights ``b_i >= 0`` (default 0: leaderless)``}``.

    Signals: ``disagreement`` ``sum_j a_ij |l_j - l_i|`` of the log coordinates (rad and m
    together: the robot's local consensus error), ``pose_error`` ``|l_i|`` (how far the robot
    is from its desired pose) and ``neighbours``.
    """

    name = "dq-consensus"

    def signal_columns(self):
        return {"disagreement": ("disagreement",), "pose_error": ("pose_error",), "neighbours": ("neighbours",)}

    def reference_arrays(self, reference, n: int):
        return dq.check_reference(self.name, reference, n, {"leader": ((n,), "1 (a weight)", 0.0)})

    def tick(self, state, own, inbox, reference, t) -> LocalTick:
        xp = common_namespace(own, inbox["messages"])
        y = dq.formation_variable(dq.pose_dq(own), reference["pose"])               # (*b, N, 8)
        ell = log_coordinates(y)                                                     # (*b, N, 6)
        w = xp.where(inbox["valid"], xp.asarray(inbox["weights"], dtype=own.dtype), 0.0)  # (*b, N, W)
        diff = log_coordinates(inbox["messages"]) - ell[..., None, :]               # (*b, N, W, 6)
        b = xp.asarray(reference["leader"], dtype=own.dtype)[..., None]
        rate = self.gain * (xp.sum(w[..., None] * diff, axis=-2) - b * ell)         # Laplacian row
        omega = left_jacobian_times(ell[..., 0:3], rate[..., 0:3])
        zeta = dq.twist_dq(rate[..., 3:6], omega, ell[..., 3:6])                     # y_dot y*
        cmd = dq.pose_twist_commands(zeta, y, reference["pose"], reference["twist"], own[..., 0:3])
        dis = xp.sum(w * xp.sqrt(xp.sum(diff * diff, axis=-1)), axis=-1)
        err = xp.sqrt(xp.sum(ell * ell, axis=-1))
        count = xp.sum(xp.asarray(inbox["valid"], dtype=own.dtype), axis=-1)
        code = xp.zeros(own.shape[:-1], dtype=xp.int64)
        return LocalTick(None, cmd, {"disagreement": dis[..., None], "pose_error": err[..., None],
                                     "neighbours": count[..., None]}, code)
