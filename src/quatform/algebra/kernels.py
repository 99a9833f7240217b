"""Component-wise product kernels and the blocked driver that runs them (internal: shared by quatform's layers, not part of the user API).

The Hamilton product is 16 multiplications and 12 additions per quaternion. Written on
``(..., 4)`` arrays with strided component views, NumPy spends most of its time moving
memory; here the inputs are transposed block by block into contiguous component rows that
stay in cache, the kernel runs on those rows, and the result is written back. The kernels
only use ``+``, ``-`` and ``*``, so the same code also runs on Python floats, which is the
fast path for a single quaternion. The same kernels run on any array namespace with NumPy's
operators (JAX arrays inside ``jax.jit``): :func:`namespace` names the module of an operand,
:func:`concrete` says whether its values may be read on the host (a Python branch on them).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ShapeError


def namespace(x):
    """The module whose functions apply to ``x``: :mod:`math` for a Python float (or a NumPy
    float64, a float), :mod:`numpy` for NumPy arrays and scalars, otherwise the array's own
    namespace (``x.__array_namespace__()``: :mod:`jax.numpy` for a JAX array or tracer)."""
    if isinstance(x, float):
        return math
    if isinstance(x, (np.ndarray, np.generic, bool, int)):
        return np
    return x.__array_namespace__()


def array_namespace(x):
    """The array module for ``x``: :mod:`numpy` for Python numbers and NumPy, the array's own
    namespace otherwise (:func:`namespace` without :mod:`math`)."""
    return np if concrete(x) or isinstance(x, (list, tuple)) else x.__array_namespace__()


def common_namespace(*arrays):
    """NumPy, or the namespace of the first operand that is not concrete (a JAX array or tracer;
    None is skipped): the module a kernel on mixed operands (NumPy constants, JAX arrays) computes with."""
    return next((a.__array_namespace__() for a in arrays
                 if a is not None and not concrete(a) and not isinstance(a, (list, tuple))), np)


def dot_last(a, b):
    """``sum_i a_i b_i`` over the last axis: NumPy's ``einsum`` for NumPy arrays, the products'
    sum on another namespace (XLA runs a batched ``einsum`` as one tiny product per row)."""
    xp = array_namespace(a)
    if xp is np and array_namespace(b) is np:
        return np.einsum("...i,...i->...", a, b)
    return xp.sum(a * b, axis=-1)


def small_matmul(a, b):
    """``a @ b`` of broadcast ``(..., m, k)`` and ``(..., k, n)`` small matrices: NumPy's
    ``matmul`` for NumPy arrays, the products' sum over ``k`` on another namespace.

    XLA's CPU backend runs a batched ``dot`` of a few rows as one tiny matrix product per batch
    entry (a library call each); the multiply-sum is one fused loop over the batch (measured in
    ``docs/performance.md``, "Learning environments beside crazyflow"). The same values up to the
    order of the sum's rounding.
    """
    xp = array_namespace(a)
    if xp is np and array_namespace(b) is np:
        return np.matmul(a, b)
    xp = common_namespace(a, b)
    a, b = xp.asarray(a), xp.asarray(b)
    return xp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


#: Entries per row of :func:`hold`'s product with the identity.
HOLD_BLOCK = 4


def hold(a):
    """``a`` (``(..., k)``) computed once: ``a`` itself on NumPy, ``a @ I`` on another namespace.

    XLA's CPU fusion recomputes a chain of cheap operations inside every fused loop that
    consumes it (each of a stage's output components recomputes the stages before it: the
    compiled tick of the quaternion controller held about 4 950 fused operations against
    the 1 052 of its jaxpr). ``optimization_barrier`` does not stop it on the CPU; a ``dot``
    is not fused, so its operand is computed once. The dot is ``a``'s entries in rows of
    :data:`HOLD_BLOCK` (zero-padded) times the identity of that size: ``O(k)`` work (the whole
    ``k x k`` identity is ``O(k^2)``: 707 x 707 per world for a team of 100). The product is
    exact for finite values (``a_ik 1 + sum of +-0``), except that ``-0.0`` becomes ``+0.0``;
    a non-finite entry makes its row of :data:`HOLD_BLOCK` entries non-finite.
    """
    xp = array_namespace(a)
    if xp is np:
        return a
    k = a.shape[-1]
    rows = -(-k // HOLD_BLOCK)
    pad = xp.concatenate([a, xp.zeros(a.shape[:-1] + (rows * HOLD_BLOCK - k,), dtype=a.dtype)], axis=-1) \
        if rows * HOLD_BLOCK > k else a
    held = pad.reshape(a.shape[:-1] + (rows, HOLD_BLOCK)) @ xp.eye(HOLD_BLOCK, dtype=a.dtype)
    return held.reshape(a.shape[:-1] + (rows * HOLD_BLOCK,))[..., :k]


def concrete(x) -> bool:
    """Whether the values of ``x`` may be read on the host (a Python float or bool, NumPy):
    False for a JAX array (traced under ``jax.jit``), where a kernel takes both branches."""
    return isinstance(x, (float, bool, int, np.ndarray, np.generic))


def as_floats(x):
    """``x`` as a NumPy float array where its values are on the host (numbers, sequences,
    NumPy), a JAX array (traced under ``jax.jit``) as it is: the ``np.asarray(x, dtype=float)``
    of a kernel that runs on both."""
    return np.asarray(x, dtype=float) if concrete(x) or isinstance(x, (list, tuple)) else x


#: Rows per block: 4 or 8 component rows of this length fit comfortably in L2 cache.
BLOCK = 8192


def qmul_components(q0, q1, q2, q3, p0, p1, p2, p3):
    """Hamilton product ``q p`` on components (seed 001 eq. (2.18); (2.17) has sign typos)."""
    return (
        q0 * p0 - q1 * p1 - q2 * p2 - q3 * p3,
        q0 * p1 + q1 * p0 + q2 * p3 - q3 * p2,
        q0 * p2 - q1 * p3 + q2 * p0 + q3 * p1,
        q0 * p3 + q1 * p2 - q2 * p1 + q3 * p0,
    )


def dqmul_components(*c):
    """Dual-quaternion product ``(r1 + eps d1)(r2 + eps d2) = r1 r2 + eps (r1 d2 + d1 r2)``."""
    r1, d1, r2, d2 = c[0:4], c[4:8], c[8:12], c[12:16]
    r = qmul_components(*r1, *r2)
    a = qmul_components(*r1, *d2)
    b = qmul_components(*d1, *r2)
    return r + (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


def run_blocked(kernel, arrays, width_out: int) -> np.ndarray:
    """Apply a component kernel to broadcast ``(..., k_i)`` arrays, returning ``(..., width_out)``.

    Parameters
    ----------
    kernel : callable
        Takes the components of all inputs in order, returns ``width_out`` components.
    arrays : sequence of ndarray
        Validated float64 arrays; their leading axes broadcast together.
    width_out : int
        Number of output components.
    """
    try:
        lead = np.broadcast_shapes(*(a.shape[:-1] for a in arrays))
    except ValueError:
        shapes = " and ".join(str(a.shape) for a in arrays)
        raise ShapeError(
            f"operands with shapes {shapes} do not broadcast: their leading (batch) axes must "
            "be equal or 1"
        ) from None
    n = math.prod(lead)
    if n == 1:
        comps = [c for a in arrays for c in a.reshape(-1).tolist()]
        return np.array(kernel(*comps), dtype=np.float64).reshape(lead + (width_out,))
    flats = []
    for a in arrays:
        if math.prod(a.shape[:-1]) == 1:
            flats.append(None)  # constant operand: its components broadcast as scalars
        else:
            flats.append(np.broadcast_to(a, lead + a.shape[-1:]).reshape(n, a.shape[-1]))
    consts = [a.reshape(-1).tolist() if f is None else None for a, f in zip(arrays, flats)]
    out = np.empty((n, width_out))
    for start in range(0, n, BLOCK):
        stop = min(start + BLOCK, n)
        comps = []
        for f, c in zip(flats, consts):
            if f is None:
                comps.extend(c)
            else:
                comps.extend(np.ascontiguousarray(f[start:stop].T))
        res = kernel(*comps)
        blk = out[start:stop]
        for i, r in enumerate(res):
            blk[:, i] = r
    return out.reshape(lead + (width_out,))
