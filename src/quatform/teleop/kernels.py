"""Small helpers of the teleoperation fast path (internal; teleop layer).

A control cycle works on one configuration of each arm: a handful of 3-vectors and
3x3 matrices. NumPy's general routines (``np.cross``, validated conversions) cost more
in call overhead than in arithmetic there, so these do the same on plain slices or
Python floats. Each is checked against its general counterpart in the tests.
"""

from __future__ import annotations

import math

import numpy as np

#: ``a @ LEVI`` reshaped to ``(..., 3, 3)`` is ``[a]x``: ``LEVI[j, 3 i + k] = epsilon_ijk``.
LEVI = np.zeros((3, 3, 3))
LEVI[0, 2, 1], LEVI[0, 1, 2], LEVI[1, 0, 2], LEVI[1, 2, 0], LEVI[2, 1, 0], LEVI[2, 0, 1] = 1, -1, 1, -1, 1, -1
LEVI = LEVI.reshape(3, 9)


def skew_rows(a) -> np.ndarray:
    """``[a]x`` of ``(..., 3)`` vectors, shape ``(..., 3, 3)``, in one product."""
    return (a @ LEVI).reshape(a.shape[:-1] + (3, 3))


def cross(a, b) -> np.ndarray:
    """``a x b`` on ``(..., 3)`` arrays (broadcasting) as ``[a]x b``: two products, no axis handling."""
    return (skew_rows(a) @ b[..., None])[..., 0]


def q_from_rotation(R) -> tuple:
    """Unit quaternion ``(w, x, y, z)``, ``w >= 0``, of one orthonormal 3x3 matrix (Shepperd).

    No validation: for matrices that are rotations by construction (products of DH
    transforms). The branch takes the largest of ``4w^2, 4x^2, 4y^2, 4z^2``.
    """
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = R.tolist() if isinstance(R, np.ndarray) else R
    c = (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22)
    k = max(range(4), key=c.__getitem__)
    big = 0.5 * math.sqrt(c[k])
    f = 0.25 / big
    if k == 0:
        q = (big, (m21 - m12) * f, (m02 - m20) * f, (m10 - m01) * f)
    elif k == 1:
        q = ((m21 - m12) * f, big, (m01 + m10) * f, (m02 + m20) * f)
    elif k == 2:
        q = ((m02 - m20) * f, (m01 + m10) * f, big, (m12 + m21) * f)
    else:
        q = ((m10 - m01) * f, (m02 + m20) * f, (m12 + m21) * f, big)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    s = 1.0 / n if q[0] >= 0 else -1.0 / n
    return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)
