"""Task space of seed 003: the Euler-parameter error and task Jacobians, eqs. (8)-(19), and the RPY baseline.

Teleop layer. The Euler-parameter error and task Jacobian are the stiffness law's and live
with it in :mod:`quatform.control.stiffness` (re-exported here). The orientation part of
``x_s - x_m`` is ``delta_eps``, the vector part of the Euler parameters of ``R_M^T R_S``
(eqs. (8)-(10), in {M}); its rate is
``W (omega_S - omega_M)`` with ``W`` of eq. (19) (``docs/derivations.md``, seed 003 item 3),
so ``J = diag(I, W) J_f`` (eqs. (16), (18)) maps joint rates to the task-error rate.

The roll-pitch-yaw alternative the seed argues against is here too, as the baseline that
shows the artificial singularity: ZYX angles ``R = Rz(yaw) Ry(pitch) Rx(roll)``, an error
``rpy_S - rpy_M`` (wrapped) and the rate map ``E(rpy)^-1``, which divides by
``cos(pitch)`` (``docs/derivations.md``, seed 003 item 8).
"""

from __future__ import annotations

import numpy as np

from ..algebra import matrix_from_q, wrap_angle
from ..algebra.kernels import array_namespace
from ..algebra.validate import as_array
from ..control.stiffness import orientation_error, task_jacobian

__all__ = ["orientation_error", "task_jacobian", "rpy_from_q", "rpy_from_matrix", "rpy_error", "wrap_angle",
           "rpy_rate_from_angular_velocity", "rpy_rates", "rpy_task_jacobian"]


def rpy_from_q(q) -> np.ndarray:
    """ZYX angles ``(roll, pitch, yaw)`` of unit quaternions, ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    ``pitch = asin(-R_20)`` in ``[-pi/2, pi/2]``; at ``|pitch| = pi/2`` roll and yaw are not
    separately defined (gimbal lock) and this returns ``roll = atan2(R_21, R_22)`` of the
    rounded matrix, whatever that is. Shape ``(..., 3)``.
    """
    return rpy_from_matrix(matrix_from_q(q))


def rpy_from_matrix(R) -> np.ndarray:
    """:func:`rpy_from_q` of rotation matrices ``(..., 3, 3)`` (not validated; NumPy or JAX)."""
    xp = array_namespace(R)
    if xp is np:
        R = np.asarray(R, dtype=float)
    pitch = xp.arcsin(xp.clip(-R[..., 2, 0], -1.0, 1.0))
    roll = xp.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = xp.arctan2(R[..., 1, 0], R[..., 0, 0])
    return xp.stack([roll, pitch, yaw], axis=-1)


def rpy_error(q_m, q_s) -> np.ndarray:
    """``rpy(q_s) - rpy(q_m)`` with each difference wrapped to ``[-pi, pi)``, shape ``(..., 3)``."""
    return wrap_angle(rpy_from_q(q_s) - rpy_from_q(q_m))




def rpy_rate_from_angular_velocity(rpy) -> np.ndarray:
    """``E(rpy)^-1`` (shape ``(..., 3, 3)``): ``d/dt (roll, pitch, yaw) = E^-1 omega`` (base frame).

    ``omega = z yaw_dot + Rz(yaw) y pitch_dot + Rz(yaw) Ry(pitch) x roll_dot``; its inverse
    has ``1 / cos(pitch)`` in the roll and yaw rows: unbounded toward ``pitch = +-pi/2``
    (about 1e16 at the rounded pi/2). Returned as computed: the baseline is meant to show
    the singularity.
    """
    return rpy_rates(as_array(rpy, "rpy", 3))


def rpy_rates(rpy):
    """:func:`rpy_rate_from_angular_velocity` of angles already checked (NumPy or JAX arrays)."""
    xp = array_namespace(rpy)
    p, y = rpy[..., 1], rpy[..., 2]
    cp, sp, cy, sy = xp.cos(p), xp.sin(p), xp.cos(y), xp.sin(y)
    with np.errstate(divide="ignore", invalid="ignore"):
        tp = sp / cp
        rows = [
            [cy / cp, sy / cp, xp.zeros_like(p)],
            [-sy, cy, xp.zeros_like(p)],
            [cy * tp, sy * tp, xp.ones_like(p)],
        ]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def rpy_task_jacobian(J_f, q=None, rpy=None) -> np.ndarray:
    """``diag(I_3, E(rpy)^-1) J_f``: joint rates to ``(p_dot, rpy_dot)``, shape ``(..., 6, n)``.

    The angles are ``rpy_from_q(q)`` or given as ``rpy``.
    """
    J_f = as_array(J_f, "J_f", None)
    rpy = rpy_from_q(q) if rpy is None else rpy
    out = J_f.copy()
    out[..., 3:6, :] = rpy_rate_from_angular_velocity(rpy) @ J_f[..., 3:6, :]
    return out
