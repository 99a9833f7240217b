"""Plane angles (algebra layer): the one wrapping rule every layer uses for angle differences."""

from __future__ import annotations

import numpy as np

__all__ = ["wrap_angle"]


def wrap_angle(a) -> np.ndarray:
    """Angles (rad, any shape) wrapped to ``[-pi, pi)``: ``a - 2 pi k`` for the right integer ``k``."""
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
