"""Input checks shared by the algebra layer (internal: shared by quatform's layers, not part of the user API).

Every public algebra function passes its array arguments through these helpers, so that a
wrong shape, a NaN or a non-unit quaternion is reported once, clearly, with the fix.
"""

from __future__ import annotations

import numpy as np

from ..errors import NonFiniteError, NonUnitError, ShapeError

#: Largest accepted deviation of a unit quaternion's norm from 1 (``| ||q|| - 1 |``).
#: Inputs within it are renormalised silently; inputs beyond it raise NonUnitError.
UNIT_TOLERANCE = 1e-6


def _first(mask: np.ndarray) -> int:
    """Flat index of the first True of ``mask`` (-1 if none), without listing every True entry
    (``np.argwhere`` of a huge bad array would allocate ndim integers per entry)."""
    flat = np.ravel(mask)
    if flat.size == 0:
        return -1
    i = int(np.argmax(flat))
    return i if flat[i] else -1


def _where(mask: np.ndarray, first: int | None = None) -> str:
    """`` at index (i, j, ...)`` of the first True of ``mask``, or ``""`` (0-d or none)."""
    mask = np.asarray(mask)
    first = _first(mask) if first is None else first
    if first < 0 or mask.ndim == 0:
        return ""
    return f" at index {tuple(int(i) for i in np.unravel_index(first, mask.shape))}"


def _value_at(values, mask: np.ndarray) -> tuple[float, str]:
    """The first entry of ``values`` where ``mask`` holds, and its `` at index ...`` (cheap)."""
    first = _first(mask)
    return float(np.ravel(values)[first]), _where(mask, first)


def as_array(x, name: str, last: int | tuple[int, ...] | None) -> np.ndarray:
    """Return ``x`` as a finite float64 array whose trailing shape is ``last``.

    Parameters
    ----------
    x : array_like
    name : str
        Name of the argument, used in error messages.
    last : int, tuple of int or None
        Required trailing dimension(s); ``None`` accepts any shape.
    """
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name} must be a numeric array, got {type(x).__name__}: {str(exc)[:200]}") from None
    if last is not None:
        tail = (last,) if isinstance(last, int) else tuple(last)
        if a.ndim < len(tail) or a.shape[a.ndim - len(tail):] != tail:
            want = "(..., " + ", ".join(str(t) for t in tail) + ")"
            raise ShapeError(f"{name} must have shape {want}, got shape {a.shape}")
    # One cheap reduction finds a NaN/inf; only then is the offending entry located.
    if not np.isfinite(np.add.reduce(a, axis=None)):
        bad = ~np.isfinite(a)
        if bad.any():
            value, where = _value_at(a, bad)
            raise NonFiniteError(
                f"{name} contains {value!r}{where}; every entry must be finite "
                "(check the measurement or the upstream computation that produced it)"
            )
    return a


def as_quaternion(q, name: str = "q") -> np.ndarray:
    """Finite ``(..., 4)`` array."""
    return as_array(q, name, 4)


def as_unit_quaternion(q, name: str = "q", tol: float = UNIT_TOLERANCE) -> np.ndarray:
    """Finite ``(..., 4)`` array of unit quaternions, renormalised within ``tol``.

    Raises
    ------
    NonUnitError
        If some ``| ||q|| - 1 | > tol``.
    """
    a = as_quaternion(q, name)
    n = np.sqrt(np.einsum("...i,...i->...", a, a))
    dev = np.abs(n - 1.0)
    if dev.size and dev.max() > tol:
        value, where = _value_at(n, dev > tol)
        raise NonUnitError(
            f"{name} must be a unit quaternion but has norm {value:.9g}"
            f"{where} (tolerance {tol:g}); normalise it with "
            "quatform.algebra.qnormalize if its direction is meaningful"
        )
    return a / n[..., None]


def as_dual_quaternion(dq, name: str = "dq") -> np.ndarray:
    """Finite ``(..., 8)`` array."""
    return as_array(dq, name, 8)


def as_unit_dual_quaternion(dq, name: str = "dq", tol: float = UNIT_TOLERANCE) -> np.ndarray:
    """Finite ``(..., 8)`` array of unit dual quaternions, renormalised within ``tol``.

    A dual quaternion ``r + eps d`` is unit when ``||r|| = 1`` and ``r . d = 0``.

    Raises
    ------
    NonUnitError
        If ``| ||r|| - 1 | > tol`` or ``|r . d| > tol * max(1, ||d||)``.
    """
    a = as_dual_quaternion(dq, name)
    r, d = a[..., :4], a[..., 4:]
    n = np.sqrt(np.einsum("...i,...i->...", r, r))
    rd = np.einsum("...i,...i->...", r, d)
    dn = np.sqrt(np.einsum("...i,...i->...", d, d))
    bad_n = np.abs(n - 1.0) > tol
    bad_o = np.abs(rd) > tol * np.maximum(1.0, dn)
    if np.any(bad_n):
        value, where = _value_at(n, bad_n)
        raise NonUnitError(
            f"{name} must be a unit dual quaternion but its primary part has norm "
            f"{value:.9g}{where} "
            f"(tolerance {tol:g}); normalise it with quatform.algebra.dqnormalize"
        )
    if np.any(bad_o):
        value, where = _value_at(rd, bad_o)
        raise NonUnitError(
            f"{name} must be a unit dual quaternion but primary . dual = "
            f"{value:.3g}{where} "
            f"(tolerance {tol:g}); normalise it with quatform.algebra.dqnormalize"
        )
    return divide_by_dual_norm(r, d, n)


def divide_by_dual_norm(r: np.ndarray, d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``(r + eps d) / ||r + eps d||`` given ``n = ||r||`` (nonzero), as a ``(..., 8)`` array.

    ``r' = r/n``, ``d' = d/n - (r' . d/n) r'``, so ``||r'|| = 1`` and ``r' . d' = 0``.
    """
    r1 = r / n[..., None]
    d1 = d / n[..., None]
    d1 = d1 - np.einsum("...i,...i->...", r1, d1)[..., None] * r1
    return np.concatenate([r1, d1], axis=-1)
