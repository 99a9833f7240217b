"""Euler-parameter task space of seed 003: orientation error and task Jacobians, eqs. (8)-(19).

Teleop layer. The orientation part of ``x_s - x_m`` is ``delta_eps``, the vector part of
the Euler parameters of ``R_M^T R_S`` (eqs. (8)-(10), in {M}); its rate is
``W (omega_S - omega_M)`` with ``W`` of eq. (19) (``docs/derivations.md``, seed 003 item 3),
so ``J = diag(I, W) J_f`` (eqs. (16), (18)) maps joint rates to the task-error rate.
"""

from __future__ import annotations

import numpy as np

from ..algebra import relative_euler_parameters, w_matrix
from ..algebra._validate import as_array

__all__ = ["orientation_error", "task_jacobian"]


def orientation_error(q_m, q_s) -> np.ndarray:
    """``delta_eps`` (shape ``(..., 3)``): ``sin(angle/2)`` times the axis of ``R_M^T R_S``, in {M}.

    The sign follows the short way (``delta_eps4 >= 0``), so the error is 0 for ``q_s = -q_m``.
    """
    e = relative_euler_parameters(q_m, q_s)
    # relative_euler_parameters returns (eps4, eps_vec); keep the short way
    s = np.where(e[..., :1] < 0, -1.0, 1.0)
    return (s * e)[..., 1:]


def task_jacobian(J_f, q_m, q_s) -> np.ndarray:
    """``diag(I_3, W(q_m, q_s)) J_f`` (eqs. (16), (18)), shape ``(..., 6, n)``.

    ``J_f``: a force-reflecting Jacobian (``[p_dot; omega]``, base frame) of either arm.
    """
    J_f = as_array(J_f, "J_f", None)
    W = w_matrix(q_m, q_s)
    out = J_f.copy()
    out[..., 3:6, :] = W @ J_f[..., 3:6, :]
    return out
