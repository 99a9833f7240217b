"""A 7-DOF slave arm with a joint-space mass matrix (seed 003's slave is not specified).

Teleop layer. Kinematics: the Franka Emika Panda in the modified DH convention of its
maker's documentation (``alpha_{i-1}, a_{i-1}, d_i``: ``(0, 0, 0.333)``, ``(-pi/2, 0, 0)``,
``(pi/2, 0, 0.316)``, ``(pi/2, 0.0825, 0)``, ``(-pi/2, -0.0825, 0.384)``, ``(pi/2, 0, 0)``,
``(pi/2, 0.088, 0)``, flange ``d = 0.107``). Inertia: an explicit approximation, stated
here and in ``docs/derivations.md``: link masses as in the arm's public description
(rounded: 4.97, 0.65, 3.23, 3.59, 1.23, 1.67, 0.74 kg), each link a slender rod from its
joint to the next (centre of mass at the middle, ``m L^2 / 12`` across, a radius of
5 cm along), not the identified values, plus each joint's reflected motor-rotor inertia
("armature", 0.1 kg m^2: a rotor of ~1e-5 kg m^2 behind a 100:1 harmonic drive). Enough
for the kinetic-energy-weighted inverse ``J_bar = M^-1 J^T (J M^-1 J^T)^-1`` of eq. (13)
and for simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..algebra.kernels import array_namespace, concrete
from .kernels import skew_rows
from .arm import DHLink, SerialArm

__all__ = ["PANDA", "RigidArm", "PANDA_SLAVE", "PANDA_TORQUE_LIMITS", "PANDA_VELOCITY_LIMITS"]

_H = math.pi / 2
#: Franka Emika Panda, modified DH (Craig), flange 0.107 m along the last z.
PANDA = SerialArm(
    links=(
        DHLink(0.0, 0.0, 0.333), DHLink(-_H, 0.0, 0.0), DHLink(_H, 0.0, 0.316), DHLink(_H, 0.0825, 0.0),
        DHLink(-_H, -0.0825, 0.384), DHLink(_H, 0.0, 0.0), DHLink(_H, 0.088, 0.0),
    ),
    name="Panda slave",
    tool_d=0.107,
)

#: The Panda's joint torque limits as its maker publishes them, N m.
PANDA_TORQUE_LIMITS = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
#: The Panda's rated joint speeds as its maker publishes them, rad/s (the bound on measured
#: rates, :data:`.controller.MAX_JOINT_RATE`, is derived from them; the simulator does not
#: enforce them).
PANDA_VELOCITY_LIMITS = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)


@dataclass(frozen=True)
class RigidArm:
    """A :class:`SerialArm` with link masses: mass matrix, kinetic energy, weighted inverse.

    Parameters
    ----------
    arm : SerialArm
    masses : tuple of float
        Mass of each link, kg.
    radius : float
        Radius of gyration about each rod's own axis, m.
    armature : float
        Reflected rotor inertia added to each joint (the diagonal of ``M``), kg m^2.
    """

    arm: SerialArm
    masses: tuple = field(default=(4.97, 0.65, 3.23, 3.59, 1.23, 1.67, 0.74))
    radius: float = 0.05
    armature: float = 0.0

    @cached_property
    def _constants(self):
        """What does not change with ``q``: each rod's length (the distance between
        consecutive joint origins is fixed by the DH geometry), its inertia across and
        along, the suffix sums of the former, index helpers."""
        F = self.arm.frames(np.zeros(self.arm.n))
        o = F[:, 0:3, 3]
        ends = np.vstack([o[1:], self.arm.tool(F)[None]])
        L = np.linalg.norm(ends - o, axis=-1)
        n = self.arm.n
        m = np.asarray(self.masses, dtype=float)
        across = m * L ** 2 / 12.0
        along = m * self.radius ** 2 / 2.0
        tail = np.cumsum(across[::-1])[::-1]  # sum over links i >= k
        k = np.maximum.outer(np.arange(n), np.arange(n))
        lower = np.tril(np.ones((n, n)))
        return {"L": L, "inv_L": np.where(L > 1e-9, 1.0 / np.maximum(L, 1e-12), 0.0)[:, None],
                "no_rod": (L <= 1e-9).astype(float)[:, None], "lower": lower,
                "lower_sqrt_m": lower[:, :, None] * np.sqrt(m)[:, None, None],
                "G_weight": tail[k], "c": (along - across)[:, None], "armature": self.armature * np.eye(n),
}

    def _coms(self, q, F=None):
        """Centres of mass ``(..., n, 3)``, rod directions ``(..., n, 3)`` and lengths ``(n,)``.

        A rod of zero length (two coincident joint origins) takes its joint's axis as its
        direction; its inertia is then the "along" value about every axis that matters.
        """
        F = self.arm.frames(q) if F is None else F
        xp = array_namespace(F)
        K = self._constants
        o = F[..., :, 0:3, 3]
        ends = xp.concatenate([o[..., 1:, :], self.arm.tool(F)[..., None, :]], axis=-2)
        seg = ends - o
        u = seg * K["inv_L"] + K["no_rod"] * F[..., :, 0:3, 2]
        return F, 0.5 * (o + ends), u, K["L"]

    def mass_matrix(self, q, F=None) -> np.ndarray:
        """``M(q)`` (``(..., n, n)``): ``sum_i m_i J_ci^T J_ci + J_wi^T I_i J_wi + armature I``.

        ``J_ci`` column ``j <= i`` is ``z_j x (c_i - o_j)``, ``J_wi`` column ``j <= i`` is
        ``z_j`` (zero beyond link ``i``). A rod's inertia is ``across I + (along - across) u u^T``,
        so the rotational part is ``(z_j . z_l) sum_{i >= max(j, l)} across_i`` plus
        ``B^T diag(along - across) B`` with ``B_ij = u_i . z_j`` (``j <= i``): all links at once.
        """
        F, com, u, _ = self._coms(q, F)
        xp = array_namespace(F)
        K = self._constants
        z, o = F[..., :, 0:3, 2], F[..., :, 0:3, 3]
        n = self.arm.n
        Zx = skew_rows(z)  # [z_j]x
        D = com[..., :, None, :, None] - o[..., None, :, :, None]  # (..., i, j, 3, 1)
        Jv = (Zx[..., None, :, :, :] @ D)[..., 0] * K["lower_sqrt_m"]
        A = xp.reshape(xp.swapaxes(Jv, -3, -2), Jv.shape[:-3] + (n, 3 * n))
        zt = xp.swapaxes(z, -1, -2)
        B = (u @ zt) * K["lower"]  # (..., i, j)
        return (A @ xp.swapaxes(A, -1, -2) + (z @ zt) * K["G_weight"] + xp.swapaxes(B, -1, -2) @ (K["c"] * B)
                + K["armature"])

    def coriolis(self, q, qd, M=None, h: float = 1e-7) -> np.ndarray:
        """Coriolis and centrifugal torques ``C(q, qd) qd`` (``(n,)``, N m) of one configuration.

        From the mass matrix (the Lagrange equations): ``C qd = M_dot qd - 1/2 d/dq
        (qd^T M qd)``, with ``M_dot = dM/dq . qd`` and the gradient by forward differences of
        ``M`` (step ``h`` rad; relative error ~1e-7), the ``n + 1`` shifted configurations in
        one batched call; ``M``: the mass matrix at ``q`` if already computed. Its power is
        ``qd^T C qd = 1/2 qd^T M_dot qd``, so without torques the kinetic energy is conserved.
        NumPy or JAX arrays (a JAX ``qd`` at rest takes the moving branch on a unit speed and
        selects the zeros).
        """
        xp = array_namespace(qd)
        if xp is np:
            q, qd = np.asarray(q, float), np.asarray(qd, float)
        n = self.arm.n
        speed = xp.linalg.norm(qd)
        if concrete(speed) and speed == 0.0:
            return np.zeros(n)
        rest = speed == 0.0
        unit = speed if concrete(speed) else xp.where(rest, 1.0, speed)
        M = self.mass_matrix(q) if M is None else M
        Ms = self.mass_matrix(q + h * xp.concatenate([(qd / unit)[None], np.eye(n)])) - M
        M_dot = (unit / h) * Ms[0]
        grad = xp.einsum("i,kij,j->k", qd, Ms[1:], qd) / h
        out = M_dot @ qd - 0.5 * grad
        return out if concrete(speed) else xp.where(rest, 0.0, out)

    def generalized_inverse(self, q, J=None, F=None) -> np.ndarray:
        """``J_bar = M^-1 J^T (J M^-1 J^T)^-1`` (seed 003 eq. (13)), shape ``(..., n, 6)``.

        Of all joint rates that produce a task rate, ``J_bar`` gives the one of least kinetic
        energy.
        """
        F = self.arm.frames(q) if F is None else F
        J = self.arm.jacobian(q, F) if J is None else J
        M = self.mass_matrix(q, F)
        MiJt = np.linalg.solve(M, np.swapaxes(J, -1, -2))
        return MiJt @ np.linalg.inv(J @ MiJt)


PANDA_SLAVE = RigidArm(PANDA, armature=0.1)
