"""The Euler-parameter stiffness law of seed 003, eqs. (14a)/(14b), with its task error (control layer).

Control layer; imports :mod:`quatform.algebra` only, so every controller (the teleoperator
of :mod:`quatform.teleop.controller` today, a cluster-space controller tomorrow) can use it.
The task error is ``e = x_s - x_m``: the position difference in the base frame and
``delta_eps``, the vector part of the Euler parameters of ``R_M^T R_S`` (eqs. (8)-(10)).
Its rate is ``J_s q_s_dot - J_m q_m_dot`` with ``J = diag(I, W) J_f`` (eqs. (16), (18)).
The torques are the generalized forces of the spring ``1/2 e^T K_p e`` plus damping,
eqs. (14a), (14b):

* master: ``tau_m = J_m^T (K_pm e + K_vm e_dot) + v J_mf^T F_s`` (eq. (14a) prints
  ``J_m^T F_s``; a wrench is mapped by the force-reflecting Jacobian, as in eq. (11));
* slave: ``tau_s = -J_s^T (K_ps e + K_vs e_dot) + tau_red``.

``F_s`` is the wrench the slave exerts on its environment (the wrist sensor's reading),
so a negative ``v`` pushes the operator back. ``tau_red`` is a null-space objective
projected with the dynamically consistent projector ``I - J^T J_bar^T``, so that
``J_bar^T tau_red = 0`` and eq. (13) holds exactly. Beside the law: the preload function
and deadband of seed 003 §6, the virtual-wall force of §7, and the explicit integration's
stability limit the scenario checks use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra import relative_euler_parameters, w_matrix
from ..algebra.kernels import array_namespace, concrete
from ..algebra.validate import as_array, as_unit_quaternion
from ..errors import InvalidInputError

__all__ = ["StiffnessGains", "orientation_error", "task_jacobian", "task_error", "master_torque", "slave_torque",
           "redundancy_torque", "force_stability_term", "preload", "deadband", "virtual_wall_force",
           "explicit_stiffness_limit", "effective_mass"]


def orientation_error(q_m, q_s) -> np.ndarray:
    """``delta_eps`` (shape ``(..., 3)``): ``sin(angle/2)`` times the axis of ``R_M^T R_S``, in {M}.

    Seed 003 eqs. (8)-(10). The sign follows the short way (``delta_eps4 >= 0``), so the
    error is 0 for ``q_s = -q_m``.
    """
    e = relative_euler_parameters(q_m, q_s)
    # relative_euler_parameters returns (eps4, eps_vec); keep the short way
    s = np.where(e[..., :1] < 0, -1.0, 1.0)
    return (s * e)[..., 1:]


def task_jacobian(J_f, q_m, q_s) -> np.ndarray:
    """``diag(I_3, W(q_m, q_s)) J_f`` (seed 003 eqs. (16), (18), W of (19)), shape ``(..., 6, n)``.

    ``J_f``: a force-reflecting Jacobian (``[p_dot; omega]``, base frame) of either arm.
    ``W`` takes the same short-way sign as :func:`orientation_error`, so ``J_s q_s_dot -
    J_m q_m_dot`` is the rate of the error that function returns, whichever signs the two
    quaternions have.
    """
    J_f = as_array(J_f, "J_f", None)
    q_m, q_s = np.asarray(q_m, float), np.asarray(q_s, float)
    sign = np.where(np.sum(q_m * q_s, axis=-1) < 0, -1.0, 1.0)[..., None, None]
    W = sign * w_matrix(q_m, q_s)
    out = J_f.copy()
    out[..., 3:6, :] = W @ J_f[..., 3:6, :]
    return out


@dataclass(frozen=True)
class StiffnessGains:
    """Diagonal stiffness and damping of the task error: ``K_p = diag(kp_pos*I, kp_rot*I)``.

    ``kp_rot`` multiplies ``delta_eps`` (dimensionless, ``sin(angle/2)``), and the torque it
    makes goes through ``W ~ R^T / 2``: for a small error of ``theta`` rad the restoring
    torque is ``kp_rot theta / 4`` N m (``kv_rot`` likewise: ``kv_rot / 4`` N m s/rad).
    """

    kp_pos: float = 300.0
    kp_rot: float = 10.0
    kv_pos: float = 20.0
    kv_rot: float = 0.5

    def __post_init__(self):
        for name in ("kp_pos", "kp_rot", "kv_pos", "kv_rot"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InvalidInputError(f"{name} must be finite and >= 0, got {v!r}")

    @property
    def kp(self) -> np.ndarray:
        return np.r_[np.full(3, self.kp_pos), np.full(3, self.kp_rot)]

    @property
    def kv(self) -> np.ndarray:
        return np.r_[np.full(3, self.kv_pos), np.full(3, self.kv_rot)]


def task_error(p_m, q_m, p_s, q_s) -> np.ndarray:
    """``e = [p_s - p_m; delta_eps(q_m, q_s)]``, shape ``(..., 6)`` (seed 003 eq. (12) with (9))."""
    p_m, p_s = as_array(p_m, "p_m", 3), as_array(p_s, "p_s", 3)
    q_m, q_s = as_unit_quaternion(q_m, "q_m"), as_unit_quaternion(q_s, "q_s")
    return np.concatenate([p_s - p_m, orientation_error(q_m, q_s)], axis=-1)


def master_torque(J_mf, q_m, q_s, e, e_dot, gains: StiffnessGains, F_s=None, v=0.0) -> np.ndarray:
    """Eq. (14a): ``J_m^T (K_pm e + K_vm e_dot) + v J_mf^T F_s``, shape ``(..., n_m)``."""
    q_m, q_s = np.asarray(q_m, float), np.asarray(q_s, float)
    J_m = task_jacobian(J_mf, q_m, q_s)
    wrench = gains.kp * np.asarray(e, float) + gains.kv * np.asarray(e_dot, float)
    tau = np.einsum("...ji,...j->...i", J_m, wrench)
    if F_s is not None:
        tau = tau + np.asarray(v, float)[..., None] * np.einsum("...ji,...j->...i", J_mf, np.asarray(F_s, float))
    return tau


def slave_torque(J_sf, q_m, q_s, e, e_dot, gains: StiffnessGains, tau_red=None) -> np.ndarray:
    """Eq. (14b): ``-J_s^T (K_ps e + K_vs e_dot) + tau_red``, shape ``(..., n_s)``."""
    q_m, q_s = np.asarray(q_m, float), np.asarray(q_s, float)
    J_s = task_jacobian(J_sf, q_m, q_s)
    wrench = gains.kp * np.asarray(e, float) + gains.kv * np.asarray(e_dot, float)
    tau = -np.einsum("...ji,...j->...i", J_s, wrench)
    return tau if tau_red is None else tau + tau_red


def redundancy_torque(J_sf, J_bar, q, q_dot, q_rest, k_null=5.0, d_null=1.0) -> np.ndarray:
    """``(I - J^T J_bar^T)(-k (q - q_rest) - d q_dot)``: a posture spring in the null space.

    The projector is the dynamically consistent one, so ``J_bar^T tau_red = 0``: the
    redundancy torque produces no task-space force (eq. (13)'s last term vanishes).
    """
    n = J_sf.shape[-1]
    N = np.eye(n) - np.swapaxes(J_sf, -1, -2) @ np.swapaxes(J_bar, -1, -2)
    return N @ (-k_null * (np.asarray(q, float) - q_rest) - d_null * np.asarray(q_dot, float))


def force_stability_term(x_m_dot=None, F_s=None, k_for=None, constant=-0.5):
    """``v`` of eq. (11): a negative constant, or ``-k_for x_m_dot^T F_s`` if ``k_for`` is given."""
    if k_for is None:
        if not (np.isfinite(constant) and constant < 0):
            raise InvalidInputError(f"the constant force-stability term v must be finite and negative, "
                                    f"got {constant!r}")
        return constant
    if not (np.isfinite(k_for) and k_for >= 0):
        raise InvalidInputError(f"k_for must be finite and >= 0 (v = -k_for x_m_dot . F_s), got {k_for!r}")
    if concrete(x_m_dot) and concrete(F_s):
        return -k_for * float(np.dot(np.asarray(x_m_dot, float), np.asarray(F_s, float)))
    return -k_for * array_namespace(F_s).dot(x_m_dot, F_s)  # JAX arrays (traced)


def deadband(tau, width) -> np.ndarray:
    """A joint that needs ``width`` to move: ``sign(tau) max(|tau| - width, 0)``."""
    tau, width = np.asarray(tau, float), np.asarray(width, float)
    return np.sign(tau) * np.maximum(np.abs(tau) - width, 0.0)


def preload(tau, offset, switch=None) -> np.ndarray:
    """The preload function (the inverse of a deadband), seed 003's implementation section.

    ``tau + offset sign(tau)``, with the sign replaced by a ramp ``tau / switch`` for
    ``|tau| < switch`` (default ``offset / 2``) so the command does not chatter at zero.
    """
    tau, offset = np.asarray(tau, float), np.asarray(offset, float)
    switch = offset / 2.0 if switch is None else np.asarray(switch, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ramp = np.minimum(np.maximum(tau / switch, -1.0), 1.0)
    return tau + offset * np.where(switch > 0, ramp, np.sign(tau))


def virtual_wall_force(p, p_dot, normal, offset, stiffness, damping=0.0) -> np.ndarray:
    """Repelling force of a virtual wall ``n . p <= offset`` in the master's Cartesian space.

    Zero on the free side; inside, ``-(k depth + b n . p_dot) n`` (the damping only resists
    motion into the wall). Shape ``(..., 3)``; NumPy or JAX arrays.
    """
    xp = array_namespace(p)
    if xp is np:
        p, p_dot = np.asarray(p, float), np.asarray(p_dot, float)
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    depth = xp.einsum("...i,i->...", p, n) - offset
    inward = xp.maximum(xp.einsum("...i,i->...", p_dot, n), 0.0)
    mag = xp.where(depth > 0, stiffness * depth + damping * inward, 0.0)
    return -mag[..., None] * n


def explicit_stiffness_limit(mass, damping, dt) -> np.ndarray:
    """The stiffest spring a sampled, explicitly integrated mass-spring-damper holds stably, N/m.

    A mass ``m`` on a spring ``k`` and a damper ``c`` whose force is computed at the start of
    each period ``dt`` and held over it (a digital controller's zero-order hold, and the
    simulator's semi-implicit Euler step ``v' = v + dt (-k x - c v) / m``, ``x' = x + dt v'``)
    has the step matrix ``[[1 - dt^2 k/m, dt (1 - dt c/m)], [-dt k/m, 1 - dt c/m]]``, of trace
    ``2 - dt^2 k/m - dt c/m`` and determinant ``1 - dt c/m``. By the Jury criterion its
    eigenvalues lie inside the unit circle iff ``0 < dt c/m < 2`` and
    ``k dt^2 + 2 c dt < 4 m``, i.e. ``k < (4 m - 2 c dt) / dt^2`` (``docs/derivations.md``,
    "Teleoperation (seed 003): walls, gains and limits"). Rotations likewise, with an inertia (kg m^2), a
    stiffness (N m/rad) and a damping (N m s/rad).

    Parameters
    ----------
    mass : array_like
        Effective mass (kg) or inertia (kg m^2), ``> 0``.
    damping : array_like
        Damping in parallel with the spring (N s/m or N m s/rad), ``>= 0``.
    dt : float
        Period, s.

    Returns
    -------
    ndarray
        The limit (same shape as the broadcast inputs); ``<= 0`` when the damping alone is
        unstable (``c dt >= 2 m``).
    """
    m, c = np.asarray(mass, float), np.asarray(damping, float)
    return (4.0 * m - 2.0 * c * dt) / (dt * dt)


def effective_mass(J, M_inv, direction=None) -> np.ndarray:
    """Mass (or inertia) a tool has along ``direction`` or, if None, its lightest direction.

    ``1 / (u^T J M^-1 J^T u)`` (operational-space inertia, Khatib): ``J`` ``(..., 3, n)`` the
    translational (or rotational) rows of a base-frame Jacobian, ``M_inv`` ``(..., n, n)`` the
    inverse joint-space mass matrix. Without a direction, ``1 / lambda_max(J M^-1 J^T)``, the
    least over all directions.
    """
    A = np.asarray(J, float) @ np.asarray(M_inv, float) @ np.swapaxes(np.asarray(J, float), -1, -2)
    if direction is None:
        return 1.0 / np.linalg.eigvalsh(A)[..., -1]
    u = np.asarray(direction, float)
    u = u / np.linalg.norm(u)
    return 1.0 / np.einsum("i,...ij,j->...", u, A, u)
