"""Matrix forms of the products: Hamilton operators and the seed's partial derivatives.

Part of the algebra layer. ``qplus(q) @ p == qmul(q, p) == qminus(p) @ q`` (the Hamilton
"plus" and "minus" operators). They are the Jacobians of the product, and the partial
derivatives of seed 001 §2.2.7 are all built from them:

============  ======================================  =====================================
seed 001      derivative                              quatform
============  ======================================  =====================================
(2.40)        d(q p)/dq                               ``qminus(p)``
(2.41)        d(q p*)/dq                              ``qminus(qconj(p))``
(2.42)        d(q p)/dp                               ``qplus(q)``
(2.43)        d(q p*)/dp                              ``qplus(q) @ CONJ``
(2.45)        d(q v q*)/dv                            ``jac_qrotate_vector(q)``
(2.46)        d(q* v q)/dv                            ``jac_qrotate_vector(qconj(q))``
(2.47)        d(q v q*)/dq                            ``jac_qrotate_quaternion(q, v)``
============  ======================================  =====================================
"""

from __future__ import annotations

import numpy as np

from .validate import as_array, as_dual_quaternion, as_quaternion

__all__ = [
    "CONJ",
    "skew",
    "qplus",
    "qminus",
    "dqplus",
    "dqminus",
    "jac_qrotate_vector",
    "jac_qrotate_quaternion",
]

#: ``diag(1, -1, -1, -1)``: ``CONJ @ q == qconj(q)``.
CONJ = np.diag([1.0, -1.0, -1.0, -1.0])


def skew(v) -> np.ndarray:
    """Cross-product matrix ``[v]x`` with ``[v]x u = v x u`` (seed 001 eq. (2.44)).

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    v = as_array(v, "v", 3)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -z, y
    S[..., 1, 0], S[..., 1, 2] = z, -x
    S[..., 2, 0], S[..., 2, 1] = -y, x
    return S


def qplus(q) -> np.ndarray:
    """Left-product matrix: ``qplus(q) @ p == qmul(q, p)``.

    seed 001 eq. (2.42): ``[[w, -u^T], [u, w I + [u]x]]``.

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    q = as_quaternion(q)
    w, x, y, z = (q[..., i] for i in range(4))
    rows = [[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def qminus(p) -> np.ndarray:
    """Right-product matrix: ``qminus(p) @ q == qmul(q, p)``.

    seed 001 eq. (2.40): ``[[w, -u^T], [u, w I - [u]x]]``.

    Parameters
    ----------
    p : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    p = as_quaternion(p, "p")
    w, x, y, z = (p[..., i] for i in range(4))
    rows = [[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _dual_block(P, D):
    top = np.concatenate([P, np.zeros_like(P)], axis=-1)
    bottom = np.concatenate([D, P], axis=-1)
    return np.concatenate([top, bottom], axis=-2)


def dqplus(dq) -> np.ndarray:
    """Left-product matrix of dual quaternions: ``dqplus(a) @ b == dqmul(a, b)``.

    ``[[qplus(r), 0], [qplus(d), qplus(r)]]`` for ``a = r + eps d``. Shape (..., 8, 8).
    """
    dq = as_dual_quaternion(dq)
    return _dual_block(qplus(dq[..., :4]), qplus(dq[..., 4:]))


def dqminus(dq) -> np.ndarray:
    """Right-product matrix of dual quaternions: ``dqminus(b) @ a == dqmul(a, b)``.

    ``[[qminus(r), 0], [qminus(d), qminus(r)]]`` for ``b = r + eps d``. Shape (..., 8, 8).
    """
    dq = as_dual_quaternion(dq)
    return _dual_block(qminus(dq[..., :4]), qminus(dq[..., 4:]))


def jac_qrotate_vector(q) -> np.ndarray:
    """``d(q v q*)/dv`` for any quaternion ``q`` (not normalised).

    seed 001 eq. (2.45): ``(w^2 - |u|^2) I + 2 u u^T + 2 w [u]x``; equals
    ``||q||^2 matrix_from_q(q/||q||)``. For (2.46), ``d(q* v q)/dv``, pass ``qconj(q)``.

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = as_quaternion(q)
    w, u = q[..., 0], q[..., 1:]
    eye = np.eye(3)
    return (
        (w * w - np.einsum("...i,...i->...", u, u))[..., None, None] * eye
        + 2.0 * u[..., :, None] * u[..., None, :]
        + 2.0 * w[..., None, None] * skew(u)
    )


def jac_qrotate_quaternion(q, v) -> np.ndarray:
    """``d(q v q*)/dq``, the vector part of ``q (0, v) q*`` differentiated in ``q``.

    seed 001 eq. (2.47), whose printed bracket is garbled; derived form:
    ``2 [ w v + u x v  |  (u.v) I + u v^T - v u^T - w [v]x ]`` (3 x 4, columns ``w, x, y, z``),
    for any (not necessarily unit) ``q``.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 4)
    """
    q = as_quaternion(q)
    v = as_array(v, "v", 3)
    w, u = q[..., 0], q[..., 1:]
    shape = np.broadcast_shapes(u.shape, v.shape)[:-1]
    J = np.empty(shape + (3, 4))
    J[..., :, 0] = 2.0 * (w[..., None] * v + np.cross(u, v))
    J[..., :, 1:] = 2.0 * (
        np.einsum("...i,...i->...", u, v)[..., None, None] * np.eye(3)
        + u[..., :, None] * v[..., None, :]
        - v[..., :, None] * u[..., None, :]
        - w[..., None, None] * skew(v)
    )
    return J
