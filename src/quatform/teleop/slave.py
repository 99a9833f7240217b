"""A 7-DOF slave arm with a joint-space mass matrix (seed 003's slave is not specified).

Teleop layer. Kinematics: the Franka Emika Panda in the modified DH convention of its
maker's documentation (``alpha_{i-1}, a_{i-1}, d_i``: ``(0, 0, 0.333)``, ``(-pi/2, 0, 0)``,
``(pi/2, 0, 0.316)``, ``(pi/2, 0.0825, 0)``, ``(-pi/2, -0.0825, 0.384)``, ``(pi/2, 0, 0)``,
``(pi/2, 0.088, 0)``, flange ``d = 0.107``). Inertia: an explicit approximation, stated
here and in ``docs/derivations.md``: link masses as in the arm's public description
(rounded: 4.97, 0.65, 3.23, 3.59, 1.23, 1.67, 0.74 kg), each link a slender rod from its
joint to the next (centre of mass at the middle, ``m L^2 / 12`` across, a radius of
5 cm along), not the identified values. Enough for the kinetic-energy-weighted inverse
``J_bar = M^-1 J^T (J M^-1 J^T)^-1`` of eq. (13) and for simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .arm import DHLink, SerialArm

__all__ = ["PANDA", "RigidArm", "PANDA_SLAVE"]

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
    """

    arm: SerialArm
    masses: tuple = field(default=(4.97, 0.65, 3.23, 3.59, 1.23, 1.67, 0.74))
    radius: float = 0.05

    def _coms(self, q, F=None):
        """Centres of mass ``(..., n, 3)``, rod directions ``(..., n, 3)`` and lengths ``(..., n)``."""
        F = self.arm.frames(q) if F is None else F
        o = F[..., :, 0:3, 3]
        tip = self.arm.tool(F)
        ends = np.concatenate([o[..., 1:, :], tip[..., None, :]], axis=-2)
        seg = ends - o
        L = np.linalg.norm(seg, axis=-1)
        u = np.where(L[..., None] > 1e-9, seg / np.maximum(L, 1e-12)[..., None], F[..., :, 0:3, 2])
        return F, 0.5 * (o + ends), u, L

    def mass_matrix(self, q, F=None) -> np.ndarray:
        """``M(q)`` (``(..., n, n)``): ``sum_i m_i J_ci^T J_ci + J_wi^T I_i J_wi``.

        ``J_ci`` column ``j <= i`` is ``z_j x (c_i - o_j)``, ``J_wi`` column ``j <= i`` is
        ``z_j`` (zero beyond link ``i``); all links at once.
        """
        F, com, u, L = self._coms(q, F)
        z, o = F[..., :, 0:3, 2], F[..., :, 0:3, 3]
        n = self.arm.n
        m = np.asarray(self.masses, dtype=float)
        lower = np.tril(np.ones((n, n)))[..., None]  # [i, j]: joint j moves link i
        # (..., i, j, 3)
        Jv = np.cross(z[..., None, :, :], com[..., :, None, :] - o[..., None, :, :]) * lower
        Jw = np.broadcast_to(z[..., None, :, :], Jv.shape) * lower
        across = m * L ** 2 / 12.0  # (..., i)
        along = m * self.radius ** 2 / 2.0
        # I_i w = across (w - u (u.w)) + along u (u.w), for each column w = Jw[..., i, j, :]
        uw = np.einsum("...ik,...ijk->...ij", u, Jw)
        Iw = across[..., None, None] * (Jw - u[..., :, None, :] * uw[..., None]) + (along[:, None, None] * u[..., :, None, :] * uw[..., None])
        return (np.einsum("i,...ijk,...ilk->...jl", m, Jv, Jv)
                + np.einsum("...ijk,...ilk->...jl", Jw, Iw))

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


PANDA_SLAVE = RigidArm(PANDA)
