"""Plane angles (algebra layer): the one wrapping rule every layer uses for angle differences."""

from __future__ import annotations

import numpy as np

from .kernels import concrete

__all__ = ["wrap_angle"]


def wrap_angle(a) -> np.ndarray:
    """Angles (rad, any shape) wrapped to ``[-pi, pi)``: ``a - 2 pi k`` for the right integer ``k``.

    NumPy input (or Python numbers) gives a float64 NumPy array; a JAX array stays one (the
    same floating-point remainder).
    """
    if concrete(a) or isinstance(a, (list, tuple)):
        a = np.asarray(a, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi
