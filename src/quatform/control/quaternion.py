"""Quaternion and dual-quaternion cluster-space controllers, seed 000 eqs. (20)-(33).

Control layer. Errors are taken in the body frame, ``qe = q_des* q`` (the seed prints
``q q_des``, which is not the error of its own proof: the proof needs ``qe_dot = 1/2 qe
omega`` with the command ``q_dot = 1/2 q omega``; see ``docs/derivations.md``). The
feedback ``omega = -sgn(qe_0) K qe_vec`` (with ``sgn(0) = +1``) drives ``qe`` to ``+-1``,
whichever is nearer; the feed-forward ``q_dot_des q_des* q`` makes ``qe`` constant when
there is no feedback. The rotation of the dual-quaternion shape ``qhat_s`` is the
exception: its sign is the branch of the half-way yaw (``-qhat_s`` is the formation turned
half a turn), so it is driven to ``+qhat_s_des`` (``omega_p = -K qe_vec``, no sgn); its
translation keeps the seed's ``-sgn(qe_p0) K qe_d_vec``, which makes the translation error
shrink (``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").

Both controllers refuse a reference that is no formation of two 4-DOF robots (robots on
each other, a robot rolled or pitched) before computing anything.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DegenerateInputError, UnreachableError
from ..formations import DualQuaternionPair, QuaternionPair
from ..formations import geometry as g
from ..formations import pair_kernels as kern
from ..formations.base import MIN_SEPARATION_M, Formation
from ..formations.quaternion_team import TILT_TOL
from ..robots import Team
from .base import check_units, gains
from .cluster import ClusterController
from .cluster_space import TABLE1
from .laws import Block, BlockLaw

__all__ = [
    "QuaternionController",
    "DualQuaternionController",
    "quaternion_lyapunov",
    "dual_quaternion_lyapunov",
    "dual_quaternion_law_lyapunov",
]

_QSL = (slice(3, 7), slice(8, 12), slice(12, 16))


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
        qe = kern.pack(kern.dqmul(kern.dqconj(kern.unpack(c_des[..., s])), kern.unpack(c[..., s])))
        v = v + 1.0 - qe[..., 0] ** 2 + np.einsum("...i,...i->...", qe[..., 1:4], qe[..., 1:4]) \
            + np.einsum("...i,...i->...", qe[..., 5:8], qe[..., 5:8])
    return v


def dual_quaternion_law_lyapunov(c, c_des):
    """``sum_k |qhat_e_k - sigma_k|^2 = sum_k (2 (1 - sigma_k p0_k) + |d_k|^2)``, ``k = c, s``: the
    function the law as implemented decreases (``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").

    ``qhat_e = qhat_des* qhat`` as in eq. (28); ``sigma_c = sgn(p0_c)`` (the sign of ``qhat_c``
    means nothing), ``sigma_s = +1`` (the sign of ``qhat_s`` is the branch). Under the law with
    ``K = k I`` and a still reference, ``dV/dt = -sum_k k (|p_vec_k|^2 + |p0_k| |d_k|^2) <= 0``
    for every error (for ``qhat_c`` this is also the seed's eq. (28), for which eq. (29) is not a
    Lyapunov function beyond 90 deg) -- **of the cluster state the controller computes**, not of
    every cluster state of the same robots.

    ``c`` must be that state: ``DualQuaternionController.compute(t, r, ref).cluster``, eqs.
    (26)-(27) of the robots with their yaws moved by whole turns onto the branch of
    ``c_des`` (each within pi of the desired robot's yaw, the shape's yaw error within
    3 pi / 2; ``docs/derivations.md``, "The two-robot formations and controllers (seed 000)"). ``DualQuaternionPair.forward(r)``
    of the robots' own yaws is another lift of the same formation when a yaw has wound a
    turn away, and ``V`` of it need not decrease: from yaw errors of (2.83, -3.02) rad it rises
    in 814 of 1500 steps of 1 ms, while ``V`` of the controller's state falls in every one.

    Parameters
    ----------
    c : array_like, shape (..., 16)
        The controller's cluster state (``StepResult.cluster``; see above).
    c_des : array_like, shape (..., 16)
        The desired cluster state the controller was given (``Reference.c``).

    Returns
    -------
    ndarray, shape (...)
    """
    c, c_des = np.asarray(c, float), np.asarray(c_des, float)
    v = 0.0
    for s in (slice(0, 8), slice(8, 16)):
        qe = kern.pack(kern.dqmul(kern.dqconj(kern.unpack(c_des[..., s])), kern.unpack(c[..., s])))
        p0 = np.abs(qe[..., 0]) if s.start == 0 else qe[..., 0]
        v = v + 2.0 * (1.0 - p0) + np.einsum("...i,...i->...", qe[..., 4:8], qe[..., 4:8])
    return v


def _largest(x):
    """Largest of a float or an array of floats."""
    return x if isinstance(x, float) else float(np.max(x))


def check_yaw_only(q, what, tol=TILT_TOL):
    """Raise UnreachableError if the rotation ``q`` (4 components, unit within the unit
    tolerance) is not about z beyond ``tol``: the tilt ``|R(q) e_z - e_z|`` that
    ``formation.inverse`` refuses."""
    n2 = kern.qdot(q, q)
    zx, zy, zz = kern.z_axis(q)
    tilt = ((zx / n2) ** 2 + (zy / n2) ** 2 + (zz / n2 - 1.0) ** 2) ** 0.5
    bad = tilt > tol
    if bad if isinstance(bad, bool) else np.any(bad):
        raise UnreachableError(
            f"reference {what} tilts by {_largest(tilt):.3g} rad (limit {tol:g}); a 4-DOF robot only "
            "yaws - build references with formation.from_euclidean"
        )


def check_quaternion_reference(cd):
    """Seed 000 eqs. (16)-(19) must give two robots apart, each yawed only: refuse
    ``d_c < MIN_SEPARATION_M / 2`` and a robot quaternion ``q_c q_ci`` that tilts."""
    d = cd[7]
    bad = d < 0.5 * MIN_SEPARATION_M
    if bad if isinstance(bad, bool) else np.any(bad):
        raise DegenerateInputError(
            f"reference d_c = {float(np.min(d))!r} m puts the robots on each other (it must be at least "
            f"{0.5 * MIN_SEPARATION_M:g} m, half their separation)"
        )
    for i, name in ((8, "q_c q_c1"), (12, "q_c q_c2")):
        check_yaw_only(kern.qmul(*cd[3:7], *cd[i:i + 4]), name)  # eqs. (17), (19)


def check_dual_quaternion_reference(cd):
    """Eqs. (26)-(27) must give two robots apart, each yawed only: refuse rotations of
    ``qhat_c``, ``qhat_s`` that tilt and a shape that translates less than
    ``MIN_SEPARATION_M`` (``qhat_s`` carries ``p1 - p2`` in robot 2's frame)."""
    check_yaw_only(cd[0:4], "qhat_c")
    check_yaw_only(cd[8:12], "qhat_s")
    tx, ty, tz = kern.translation(cd[8:16])
    sep = (tx * tx + ty * ty + tz * tz) ** 0.5
    bad = sep < MIN_SEPARATION_M
    if bad if isinstance(bad, bool) else np.any(bad):
        raise DegenerateInputError(
            f"reference qhat_s translates by {float(np.min(sep)):.3g} m: the robots would be on each "
            f"other (the shape must separate them by at least {MIN_SEPARATION_M:g} m)"
        )


def _quaternion_reference(cd):
    """Refuse a reference that is no formation of two 4-DOF robots (eqs. (9)-(19))."""
    check_units(cd, ((3, "q_c"), (8, "q_c1"), (12, "q_c2")))
    check_quaternion_reference(cd)


def _dual_quaternion_reference(cd):
    """Refuse a reference that is no formation of two 4-DOF robots (eqs. (26)-(27))."""
    check_units(cd, ((0, "qhat_c"), (8, "qhat_s")), dual=True)
    check_dual_quaternion_reference(cd)


@dataclass(frozen=True)
class QuaternionController(ClusterController):
    """Seed 000 eq. (20) with position and shape loops (§3.2), on eqs. (9)-(19): a
    :class:`~quatform.control.cluster.ClusterController` of :class:`QuaternionPair`.

    Parameters
    ----------
    k_x : array_like, shape (3,)
        Gains on the centroid, 1/s.
    k_d : float
        Gain on ``d_c``, 1/s.
    k_w : array_like, shape (3,)
        Diagonal of ``K_w``: gains on the three vector components of each error quaternion
        (of ``q_c``, ``q_c1`` and ``q_c2`` alike, as in eq. (20)), 1/s.
    """

    k_x: np.ndarray = field(default_factory=lambda: np.array(TABLE1["quaternion"]["k_x"], float))
    k_d: float = TABLE1["quaternion"]["k_d"]
    k_w: np.ndarray = field(default_factory=lambda: np.array(TABLE1["quaternion"]["k_w"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=QuaternionPair, init=False)
    law: BlockLaw = field(default=None, init=False)
    checks: tuple = field(default=(_quaternion_reference,), init=False)
    filters: tuple = field(default=(), init=False)
    name = "quaternion"

    def __post_init__(self):
        object.__setattr__(self, "k_x", gains(self.k_x, 3, "k_x"))
        object.__setattr__(self, "k_d", float(gains(self.k_d, 1, "k_d")[0]))
        object.__setattr__(self, "k_w", gains(self.k_w, 3, "k_w"))
        kx, kw = tuple(self.k_x.tolist()), tuple(self.k_w.tolist())
        # seed 000 §3.2: position and shape loops proportional, eq. (20) on the three quaternions
        object.__setattr__(self, "law", BlockLaw((Block("proportional", 0, 3, kx), Block("quaternion", 3, 4, kw),
                                                  Block("proportional", 7, 1, (self.k_d,)),
                                                  Block("quaternion", 8, 4, kw), Block("quaternion", 12, 4, kw)),
                                                 self.feedforward))


@dataclass(frozen=True)
class DualQuaternionController(ClusterController):
    """Seed 000 eq. (28) on eqs. (26)-(27): a :class:`~quatform.control.cluster.ClusterController`
    of :class:`DualQuaternionPair`; the cluster pose ``qhat_c`` (sign free) and the shape
    ``qhat_s`` (its rotation's sign is the branch of the half-way yaw) each a block.

    Not collision-free: with the robots in place and their yaws off by more than about 2 rad
    the shape's translation error (robot 2's yaw error turning the relative position) is
    corrected along a chord and the robots can come arbitrarily close. To hold them apart
    wrap it: ``SafeController(DualQuaternionController(), SeparationBarrier(d, dt_s=dt))``
    (:mod:`quatform.control.safety`; a seed-000 file's ``[safety] min_separation_m``,
    ``docs/derivations.md``, "The dual-quaternion pair's yaw-only starts").

    Parameters
    ----------
    k_dw : array_like, shape (3,)
        Gains on the primary and dual vector parts of the error dual quaternions, 1/s.
    """

    k_dw: np.ndarray = field(default_factory=lambda: np.array(TABLE1["dual-quaternion"]["k_dw"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=DualQuaternionPair, init=False)
    law: BlockLaw = field(default=None, init=False)
    checks: tuple = field(default=(_dual_quaternion_reference,), init=False)
    filters: tuple = field(default=(), init=False)
    name = "dual-quaternion"

    def __post_init__(self):
        object.__setattr__(self, "k_dw", gains(self.k_dw, 3, "k_dw"))
        kw = tuple(self.k_dw.tolist())
        object.__setattr__(self, "law", BlockLaw((Block("dual-quaternion", 0, 8, kw),
                                                  Block("dual-quaternion-branch", 8, 8, kw)), self.feedforward))
