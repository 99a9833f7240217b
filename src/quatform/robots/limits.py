"""Velocity limits of robots whose commands scale as a whole (robots layer).

A holonomic robot's command ``u = (v, w)`` (a linear velocity and an angular one, in one
frame) is limited by one factor ``s`` in ``[0, 1]``, so its direction is kept and a team
may share the smallest factor (:class:`~quatform.robots.team.Team`'s common limit). The
4-DOF, planar and free-body robots differ only in how many entries each part has. The same
formulas run on JAX arrays (under ``jax.jit``), where the norm is ``sqrt(v . v)`` throughout
(NumPy takes it so for every velocity below 1e150, and rescales larger ones).
"""

from __future__ import annotations

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats, concrete
from ..errors import InvalidInputError

__all__ = ["limit_factor", "saturate"]

#: Below this magnitude a velocity's squared norm is finite in float64 (one product).
_SQUARES_FINITE = 1e150


def _norm(v) -> np.ndarray:
    """Euclidean norm over the last axis, without overflow for entries up to float64's range."""
    if v.shape[-1] == 1:
        return abs(v[..., 0])
    if not concrete(v):  # traced (JAX): no test on values; squares finite below 1e150
        xp = namespace(v)
        return xp.sqrt(xp.sum(v * v, axis=-1))
    if v.size and np.max(np.abs(v)) < _SQUARES_FINITE:
        return np.sqrt(np.einsum("...i,...i->...", v, v))
    big = np.max(np.abs(v), axis=-1)
    return big * np.linalg.norm(v / np.where(big > 0, big, 1.0)[..., None], axis=-1)


def limit_factor(u, n_linear: int, max_speed: float, max_rate: float) -> np.ndarray:
    """Largest ``s`` in ``[0, 1]`` with ``|s v| <= max_speed`` and ``|s w| <= max_rate``, where
    ``v = u[..., :n_linear]`` and ``w`` the rest; 0 for a non-finite ``u``. Shape ``(...)``."""
    if not concrete(u):  # traced (JAX): the same formula, both branches selected
        xp = namespace(u)
        finite = xp.all(xp.isfinite(u), axis=-1)
        v = xp.where(finite[..., None], u, 0.0)
        s = xp.minimum(max_speed / _norm(v[..., :n_linear]), max_rate / _norm(v[..., n_linear:]))
        return xp.where(finite, xp.minimum(1.0, s), 0.0)
    u = np.asarray(u, dtype=float)
    finite = np.all(np.isfinite(u), axis=-1)
    v = u if finite.all() else np.where(finite[..., None], u, 0.0)
    with np.errstate(divide="ignore"):
        s = np.minimum(max_speed / _norm(v[..., :n_linear]), max_rate / _norm(v[..., n_linear:]))
    return np.where(finite, np.minimum(1.0, s), 0.0)


def saturate(u, factor, width: int, what: str) -> np.ndarray:
    """``u`` (``(..., width)``) scaled by ``factor(u)``; a command with factor 0 becomes zero.

    ``what`` names the command in the one-line error of a wrong shape.
    """
    u = as_floats(u)
    if u.shape[-1:] != (width,):
        raise InvalidInputError(f"a {what} command has shape (..., {width}), got {u.shape}")
    s = factor(u)[..., None]
    return namespace(u).where(s > 0, u * s, 0.0)
