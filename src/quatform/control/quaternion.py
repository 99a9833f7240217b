"""Quaternion and dual-quaternion cluster-space controllers, seed 000 eqs. (20)-(33).

Control layer. Errors are taken in the body frame, ``qe = q_des* q`` (the seed prints
``q q_des``, which is not the error of its own proof: the proof needs ``qe_dot = 1/2 qe
omega`` with the command ``q_dot = 1/2 q omega``; see ``docs/derivations.md``). The
feedback ``omega = -sgn(qe_0) K qe_vec`` (with ``sgn(0) = +1``) drives ``qe`` to ``+-1``,
whichever is nearer; the feed-forward ``q_dot_des q_des* q`` makes ``qe`` constant when
there is no feedback.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..formations import DualQuaternionPair, QuaternionPair
from ..formations import _geometry as g
from ..formations.base import Formation
from ..robots import Team
from .base import Controller, gains, sgn
from .cluster_space import TABLE1

__all__ = [
    "QuaternionController",
    "DualQuaternionController",
    "quaternion_lyapunov",
    "dual_quaternion_lyapunov",
]

_QSL = (slice(3, 7), slice(8, 12), slice(12, 16))


def _dqmul(a, b):
    return np.concatenate([g.mul(a[..., :4], b[..., :4]),
                           g.mul(a[..., :4], b[..., 4:]) + g.mul(a[..., 4:], b[..., :4])], axis=-1)


def _dqconj(a):
    return a * np.array([1.0, -1, -1, -1, 1, -1, -1, -1])


def quaternion_lyapunov(c, c_des, formation: QuaternionPair | None = None):
    """Seed 000 eq. (21): ``1/2 (|e_x|^2 + e_d^2 + sum_j (1 - qe_0j^2 + |qe_vec_j|^2))``.

    ``1 - qe_0^2 + |qe_vec|^2 = 2 |qe_vec|^2 = 2 sin^2(angle/2)``: sign-invariant.

    Parameters
    ----------
    c, c_des : array_like, shape (..., 16)

    Returns
    -------
    ndarray, shape (...)
    """
    c, c_des = np.asarray(c, float), np.asarray(c_des, float)
    ex = c[..., 0:3] - c_des[..., 0:3]
    ed = c[..., 7] - c_des[..., 7]
    v = np.einsum("...i,...i->...", ex, ex) + ed * ed
    for s in _QSL:
        qe = g.mul(g.conj(c_des[..., s]), c[..., s])
        v = v + 1.0 - qe[..., 0] ** 2 + np.einsum("...i,...i->...", qe[..., 1:], qe[..., 1:])
    return 0.5 * v


def dual_quaternion_lyapunov(c, c_des):
    """Seed 000 eq. (29): ``sum_k (1 - qe_p0^2 + |qe_p_vec|^2 + |qe_d_vec|^2)``, ``k = c, s``."""
    c, c_des = np.asarray(c, float), np.asarray(c_des, float)
    v = 0.0
    for s in (slice(0, 8), slice(8, 16)):
        qe = _dqmul(_dqconj(c_des[..., s]), c[..., s])
        v = v + 1.0 - qe[..., 0] ** 2 + np.einsum("...i,...i->...", qe[..., 1:4], qe[..., 1:4]) \
            + np.einsum("...i,...i->...", qe[..., 5:8], qe[..., 5:8])
    return v


@dataclass(frozen=True)
class QuaternionController(Controller):
    """Seed 000 eq. (20) with position and shape loops (§3.2), on eqs. (9)-(19).

    Parameters
    ----------
    k_x : array_like, shape (3,)
        Gains on the centroid, 1/s.
    k_d : float
        Gain on ``d_c``, 1/s.
    k_w : array_like, shape (3,)
        Gains on the vector parts of the error quaternions of ``q_c``, ``q_c1``, ``q_c2``, 1/s.
    """

    k_x: np.ndarray = field(default_factory=lambda: np.array(TABLE1["quaternion"]["k_x"], float))
    k_d: float = TABLE1["quaternion"]["k_d"]
    k_w: np.ndarray = field(default_factory=lambda: np.array(TABLE1["quaternion"]["k_w"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=QuaternionPair)
    name = "quaternion"

    def __post_init__(self):
        object.__setattr__(self, "k_x", gains(self.k_x, 3, "k_x"))
        object.__setattr__(self, "k_d", float(gains(self.k_d, 1, "k_d")[0]))
        object.__setattr__(self, "k_w", gains(self.k_w, 3, "k_w"))

    def _control(self, r, c_des, c_dot_des):
        F = self.formation
        c = F.forward(r, c_des)
        err = c - c_des
        cmd = np.empty(16)
        cmd[0:3] = -self.k_x * err[0:3]  # x_c_dot = -K_x e_xc (+ x_c_dot_des)
        cmd[7] = -self.k_d * err[7]
        for s in _QSL:
            q, qd = c[s], c_des[s]
            qe = g.mul(g.conj(qd), q)  # body-frame error (eq. (20), order corrected)
            err[s] = qe
            w = np.zeros(4)
            w[1:] = -sgn(qe[0]) * self.k_w * qe[1:]
            cmd[s] = 0.5 * g.mul(q, w)  # eq. (20)
            if self.feedforward:
                cmd[s] += g.mul(g.mul(c_dot_des[s], g.conj(qd)), q)
        if self.feedforward:
            cmd[0:3] += c_dot_des[0:3]
            cmd[7] += c_dot_des[7]
        return c, err, F.inverse_jacobian_at(c, r) @ cmd


@dataclass(frozen=True)
class DualQuaternionController(Controller):
    """Seed 000 eq. (28) on eqs. (26)-(27).

    Parameters
    ----------
    k_dw : array_like, shape (3,)
        Gains on the primary and dual vector parts of the error dual quaternions, 1/s.
    """

    k_dw: np.ndarray = field(default_factory=lambda: np.array(TABLE1["dual-quaternion"]["k_dw"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=DualQuaternionPair)
    name = "dual-quaternion"

    def __post_init__(self):
        object.__setattr__(self, "k_dw", gains(self.k_dw, 3, "k_dw"))

    def _control(self, r, c_des, c_dot_des):
        F = self.formation
        c = F.forward(r, c_des)
        err = np.empty(16)
        cmd = np.empty(16)
        for s in (slice(0, 8), slice(8, 16)):
            q, qd = c[s], c_des[s]
            qe = _dqmul(_dqconj(qd), q)  # body-frame error (eq. (28), order corrected)
            err[s] = qe
            w = np.zeros(8)
            k = -sgn(qe[0]) * self.k_dw
            w[1:4] = k * qe[1:4]
            w[5:8] = k * qe[5:8]
            cmd[s] = 0.5 * _dqmul(q, w)  # eq. (28)
            if self.feedforward:
                cmd[s] += _dqmul(_dqmul(c_dot_des[s], _dqconj(qd)), q)
        return c, err, F.inverse_jacobian_at(c, r) @ cmd
