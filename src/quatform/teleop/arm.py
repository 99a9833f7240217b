"""Serial arms in the modified Denavit-Hartenberg convention (Craig), seed 003 Fig. 1.

Teleop layer. Link ``i`` is ``(alpha_{i-1}, a_{i-1}, d_i, theta_offset_i)``: the frame
``i-1 -> i`` transform is ``Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`` with
``theta_i = q_i + theta_offset_i``. Forward kinematics returns the tool position and a
unit quaternion ``(w, x, y, z)``; the Jacobian is the geometric one in the base frame,
``[p_dot; omega] = J q_dot`` (seed 003 eq. (15), the "force-reflecting" Jacobian).
All functions take joint vectors with leading batch axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..algebra import q_from_matrix
from ..algebra.kernels import array_namespace
from ..algebra.validate import as_array
from ..errors import ShapeError
from .kernels import cross, q_from_rotation

__all__ = ["DHLink", "SerialArm"]


@dataclass(frozen=True)
class DHLink:
    """One revolute link, modified DH: ``alpha_prev`` (rad), ``a_prev`` (m), ``d`` (m), ``offset`` (rad)."""

    alpha_prev: float
    a_prev: float
    d: float
    offset: float = 0.0


@dataclass(frozen=True)
class SerialArm:
    """A chain of revolute :class:`DHLink`, optionally with a fixed tool offset along the last z.

    Parameters
    ----------
    links : tuple of DHLink
    name : str
    actuated : tuple of bool
        Which joints have actuators (the Kraft master's wrist roll has none).
    tool_d : float
        Tool point's distance along the last joint's z axis, m (a flange).
    """

    links: tuple
    name: str = "arm"
    actuated: tuple | None = None
    tool_d: float = 0.0

    @property
    def n(self) -> int:
        return len(self.links)

    def _q(self, q):
        if array_namespace(q) is not np:  # a JAX array (traced): its shape only
            if q.shape[-1:] != (self.n,):
                raise ShapeError(f"{self.name}: joint vector must have shape (..., {self.n}), got {q.shape}")
            return q
        q = as_array(q, "q", None)
        if q.shape[-1:] != (self.n,):
            raise ShapeError(f"{self.name}: joint vector must have shape (..., {self.n}), got {q.shape}")
        return q

    @cached_property
    def _constants(self):
        """Per-link offsets, ``cos alpha``, ``sin alpha`` and the transform's constant entries
        (``a``, ``-sin(alpha) d``, ``cos(alpha) d``, the third column), computed once."""
        L = self.links
        alpha = np.array([x.alpha_prev for x in L])
        ca, sa = np.cos(alpha), np.sin(alpha)
        a, d = np.array([x.a_prev for x in L]), np.array([x.d for x in L])
        template = np.zeros((len(L), 4, 4))
        template[:, 0, 3], template[:, 1, 2], template[:, 1, 3] = a, -sa, -sa * d
        template[:, 2, 2], template[:, 2, 3], template[:, 3, 3] = ca, ca * d, 1.0
        return np.array([x.offset for x in L]), ca, sa, template

    def frames(self, q) -> np.ndarray:
        """Homogeneous transforms ``0_T_i`` of every link frame, shape ``(..., n, 4, 4)``."""
        return self.frames_unchecked(self._q(q))

    def frames_unchecked(self, q):
        """:meth:`frames` of a float array already validated (the control cycle's fast path;
        NumPy or JAX, :func:`quatform.algebra.kernels.array_namespace`)."""
        xp = array_namespace(q)
        offset, ca, sa, template = self._constants
        th = q + offset
        ct, st = xp.cos(th), xp.sin(th)
        # every link's Rx(alpha) Tx(a) Rz(theta) Tz(d) at once, Craig eq. (3.6): the constant
        # entries come from the template, the rotation's first two columns from theta
        T0 = xp.broadcast_to(template, q.shape + (4, 4))
        cols = xp.stack([xp.stack([ct, st * ca, st * sa, T0[..., 3, 0]], axis=-1),
                         xp.stack([-st, ct * ca, ct * sa, T0[..., 3, 1]], axis=-1)], axis=-1)
        A = xp.concatenate([cols, T0[..., :, 2:]], axis=-1)
        T = A[..., 0, :, :]
        out = [T]
        for i in range(1, self.n):
            T = T @ A[..., i, :, :]
            out.append(T)
        return xp.stack(out, axis=-3)

    def tool(self, F) -> np.ndarray:
        """Tool point of the frames ``F``: ``tool_d`` along the last frame's z axis, ``(..., 3)``."""
        return F[..., -1, 0:3, 3] + self.tool_d * F[..., -1, 0:3, 2]

    def forward(self, q, F=None):
        """Tool position (``(..., 3)``, m) and orientation (unit quaternion ``(..., 4)``).

        ``F``: this arm's :meth:`frames` at ``q`` if already computed (shared with
        :meth:`jacobian` and a mass matrix, so a control step computes them once).
        """
        F = self.frames(q) if F is None else F
        R = F[..., -1, 0:3, 0:3]
        # the frames are orthonormal by construction: one configuration takes the float path
        return self.tool(F), (array_namespace(R).asarray(q_from_rotation(R)) if R.ndim == 2 else q_from_matrix(R))

    def jacobian(self, q, F=None) -> np.ndarray:
        """Geometric Jacobian ``[p_dot; omega] = J q_dot`` in the base frame, ``(..., 6, n)``.

        Column ``i``: ``[z_i x (p - o_i); z_i]`` with ``z_i``, ``o_i`` the axis and origin of
        joint ``i`` (frame ``i`` of the modified convention).
        """
        F = self.frames(q) if F is None else F
        xp = array_namespace(F)
        p = self.tool(F)
        z = F[..., :, 0:3, 2]
        o = F[..., :, 0:3, 3]
        J = xp.concatenate([xp.swapaxes(cross(z, p[..., None, :] - o), -1, -2), xp.swapaxes(z, -1, -2)], axis=-2)
        return np.ascontiguousarray(J) if xp is np else J  # row-major: products with J take one BLAS path
