"""Small helpers of the teleoperation fast path (internal; teleop layer).

A control cycle works on one configuration of each arm: a handful of 3-vectors and
3x3 matrices. NumPy's general routines (``np.cross``, validated conversions) cost more
in call overhead than in arithmetic there, so these do the same on plain slices or
Python floats. Each is checked against its general counterpart in the tests. They run on
JAX arrays too (the teleop kind's tick under ``jax.jit``, :mod:`quatform.sim.loop`).
:func:`over_worlds` runs a one-configuration function on every world of a batch.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra.kernels import array_namespace

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


def _shepperd(k, big, f, m01, m02, m10, m12, m20, m21):
    """The quaternion of Shepperd's branch ``k`` (its largest component ``big``, ``f = 1 / (4 big)``)."""
    if k == 0:
        return (big, (m21 - m12) * f, (m02 - m20) * f, (m10 - m01) * f)
    if k == 1:
        return ((m21 - m12) * f, big, (m01 + m10) * f, (m02 + m20) * f)
    if k == 2:
        return ((m02 - m20) * f, (m01 + m10) * f, big, (m12 + m21) * f)
    return ((m10 - m01) * f, (m02 + m20) * f, (m12 + m21) * f, big)


def q_from_rotation(R) -> tuple:
    """Unit quaternion ``(w, x, y, z)``, ``w >= 0``, of one orthonormal 3x3 matrix (Shepperd).

    No validation: for matrices that are rotations by construction (products of DH
    transforms). The branch takes the largest of ``4w^2, 4x^2, 4y^2, 4z^2`` (the first of
    equal ones). A NumPy matrix runs on Python floats; a JAX array (traced, whose values
    the host cannot read) computes every branch and selects (the same floats).
    """
    if array_namespace(R) is np:
        (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = R.tolist() if isinstance(R, np.ndarray) else R
        sqrt, rest = math.sqrt, (m01, m02, m10, m12, m20, m21)
        c = (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22)
        k = max(range(4), key=c.__getitem__)
        big = 0.5 * sqrt(c[k])
        q = _shepperd(k, big, 0.25 / big, *rest)
        n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        s = 1.0 / n if q[0] >= 0 else -1.0 / n
        return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)
    xp = R.__array_namespace__()
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = (R[..., i, j] for i in range(3) for j in range(3))
    rest = (m01, m02, m10, m12, m20, m21)
    c = (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22)
    k = xp.argmax(xp.stack(c, axis=-1), axis=-1)
    q = [0.0] * 4
    for branch in range(4):  # every branch (a negative c gives NaN where it is not taken)
        big = 0.5 * xp.sqrt(c[branch])
        cand = _shepperd(branch, big, 0.25 / big, *rest)
        q = [xp.where(k == branch, a, b) for a, b in zip(cand, q)]
    n = xp.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    s = xp.where(q[0] >= 0, 1.0 / n, -1.0 / n)
    return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)


def _stack(outs):
    """The per-world results ``outs`` (equal structures of tuples, lists, dicts and arrays) stacked
    leaf by leaf along a new first axis."""
    first = outs[0]
    if isinstance(first, (tuple, list)):
        return type(first)(_stack([o[q] for o in outs]) for q in range(len(first)))
    if isinstance(first, dict):
        return {k: _stack([o[k] for o in outs]) for k in first}
    return np.stack([np.asarray(o) for o in outs])


def over_worlds(fn, batch_ndim: int, *args):
    """``fn(*args)`` on every world: ``args`` are arrays whose first ``batch_ndim`` axes are the
    batch (None passes as it is; ``fn`` closes over what every world shares); the results (tuples, dicts of arrays) get
    those axes first. ``jax.vmap`` on JAX arrays, a loop over the worlds on NumPy; with no batch
    axes, ``fn(*args)`` itself."""
    if batch_ndim == 0:
        return fn(*args)
    batched = [a for a in args if a is not None]
    xp = array_namespace(batched[0])
    if xp is not np:
        import jax

        axes = tuple(None if a is None else 0 for a in args)
        f = fn
        for _ in range(batch_ndim):
            f = jax.vmap(f, in_axes=axes)
        return f(*args)
    batch = np.shape(batched[0])[:batch_ndim]

    def shaped(tree, fill=None):
        if isinstance(tree, (tuple, list)):
            return type(tree)(shaped(v, fill) for v in tree)
        if isinstance(tree, dict):
            return {k: shaped(v, fill) for k, v in tree.items()}
        tree = np.asarray(tree)
        return np.zeros(batch + tree.shape, tree.dtype) if fill else tree.reshape(batch + tree.shape[1:])

    if 0 in batch:  # no world: one world of zeros gives every output's shape and type
        with np.errstate(all="ignore"):
            return shaped(fn(*(None if a is None else np.zeros(np.shape(a)[batch_ndim:], np.asarray(a).dtype)
                               for a in args)), fill=True)
    outs = [fn(*(None if a is None else a[idx] for a in args)) for idx in np.ndindex(*batch)]
    return shaped(_stack(outs))
