"""The unit-dual-quaternion Laplacian formation law: position and attitude on a directed graph.

Control layer. Cui, Qi, Chen & Wang (arXiv 2508.10519, 2025) control a team of rigid bodies
through the Laplacian of a unit dual quaternion directed graph (UDQDG), whose arc ``(i, j)``
carries the desired relative configuration; they prove convergence to the desired formation
"modulo a right-multiplicative constant" at an R-linear rate set by λ₂ of that Laplacian, and
compute the states by a projected iteration (abstract; their equation numbers are not cited
here, as their text is not at hand: ``docs/derivations.md``, "Dual-quaternion Laplacian
law"). The Laplacian of a consistent scheme is similar to the graph's own Laplacian through
the diagonal of desired poses (Qi & Cui, arXiv 2401.05132), so its λ₂ is the graph's.

Here, robot ``i`` at pose ``x_i`` (unit dual quaternion, ``docs/conventions.md``) with desired
pose ``x_i^d`` has the formation variable ``y_i = x_i x_i^d*`` (``x_i = y_i x_i^d``) and sends
it. The Laplacian row of the UDQDG, ``sum_j a_ij (x_i - x_j x_j^d* x_i^d) = sum_j a_ij (y_i -
y_j) x_i^d``, is the graph Laplacian on the ``y``: each robot moves its ``y_i`` along

    u_i = k sum_j a_ij valid_ij (y~_j - y_i)          (in R^8)
    y_i_dot = zeta_i y_i,   zeta_i = vec(u_i y_i*)    (both parts' vector parts)

with ``y~_j`` the sign of ``y_j`` nearest ``y_i`` (:func:`.dq_pose.aligned`). ``zeta_i`` is the
projection of ``u_i`` onto the tangent space of the unit dual quaternions at ``y_i`` (written
as a twist), the continuous counterpart of the paper's projected iteration; near consensus
``u_i y_i*`` has scalar parts of second order, so the linearisation is ``y_dot = -k (L ⊗ I) y``
and the consensus error decays at ``k Re λ₂`` (:meth:`quatform.network.Graph.predicted_rate`;
the loop's discrete rate with ``dt_s``). The robot's command adds its desired pose's motion:
``x_dot x* = zeta_i + y_i xi_i^d y_i*`` (:func:`.dq_pose.pose_twist_commands`).

The team reaches ``x_i = c x_i^d`` for one constant ``c`` common to all (here a left factor:
quatform's poses are frames in the world, ``x = q + eps 1/2 t q``, so ``c`` moves the whole
desired formation rigidly; the paper writes its constant as a right factor of its
configuration vector). What robot ``i`` needs: its pose, its row of the reference (its
desired pose and twist) and the ``y_j`` its inbox holds.

**Double cover.** ``x``, ``-x``, ``x^d`` and ``-x^d`` give the same command: flipping ``x_i``
or ``x_i^d`` flips ``y_i``, which flips every ``y~_j`` and ``u_i``, and ``u_i y_i*`` stays;
flipping ``x_j`` leaves ``y~_j``. Half a turn apart (orthogonal primary parts) the sign is
decided without a tie (:func:`.dq_pose.aligned`). No step divides or takes an angle.

**Almost global, not global.** Consensus is reached from almost every start, not every one:
a ring holds twisted equilibria (the robots' rotations spread round a full turn, each pulled
equally both ways), stable for long enough rings, and the set of starts that ends on them
has positive measure (``docs/networks.md``, "Dual-quaternion laws", measures the fraction).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...algebra.kernels import common_namespace
from ..local import LocalTick
from . import dq_pose as dq

__all__ = ["DQLaplacian"]


@dataclass(frozen=True)
class DQLaplacian(dq.PoseLaw):
    """Each robot: ``y_i_dot = vec(k sum_j a_ij (y~_j - y_i) y_i*) y_i``, ``y = x x_d*`` (module docstring).

    Parameters
    ----------
    gain : float
        ``k``, 1/s, > 0.

    Reference (per tick): ``{"pose": (*batch?, N, 8)`` each robot's desired pose, a unit dual
    quaternion; ``"twist": (*batch?, N, 6)`` its world ``(v, w)`` in m/s and rad/s, default 0``}``.

    Signals: ``disagreement`` ``sum_j a_ij |y~_j - y_i|`` (the robot's local consensus error)
    and ``neighbours`` (how many messages it holds).
    """

    name = "dq-laplacian"

    def signal_columns(self):
        return {"disagreement": ("disagreement",), "neighbours": ("neighbours",)}

    def reference_arrays(self, reference, n: int):
        return dq.check_reference(self.name, reference, n)

    def tick(self, state, own, inbox, reference, t) -> LocalTick:
        xp = common_namespace(own, inbox["messages"])
        y = dq.formation_variable(dq.pose_dq(own), reference["pose"])             # (*b, N, 8)
        w = xp.where(inbox["valid"], xp.asarray(inbox["weights"], dtype=own.dtype), 0.0)  # (*b, N, W)
        diff = dq.aligned(inbox["messages"], y[..., None, :]) - y[..., None, :]  # (*b, N, W, 8)
        u = self.gain * xp.sum(w[..., None] * diff, axis=-2)                     # Laplacian row, R^8
        zeta = dq.pure(dq.dqmul(u, dq.dqconj(y)))                                # tangent projection
        cmd = dq.pose_twist_commands(zeta, y, reference["pose"], reference["twist"], own[..., 0:3])
        dis = xp.sum(w * xp.sqrt(xp.sum(diff * diff, axis=-1)), axis=-1)
        count = xp.sum(xp.asarray(inbox["valid"], dtype=own.dtype), axis=-1)
        code = xp.zeros(own.shape[:-1], dtype=xp.int64)
        return LocalTick(None, cmd, {"disagreement": dis[..., None], "neighbours": count[..., None]}, code)
