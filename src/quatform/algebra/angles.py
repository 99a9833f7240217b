"""Plane angles (algebra layer): the one wrapping rule every layer uses for angle differences."""

from __future__ import annotations

import numpy as np

from .kernels import array_namespace, concrete

__all__ = ["TIE_TURNS", "map_entries", "wrap_angle", "wrap_entries"]


#: Turns by which a yaw difference a hair short of half a turn is read as half a turn when a
#: yaw is wound to within pi of a reference (``floor(d / 2 pi + 1/2 + TIE_TURNS)`` whole turns):
#: a 180 deg step is a tie between the two ways round that the rounding of ``d / 2 pi`` (and
#: of ``atan2``) would break one way on NumPy and the other on JAX, which divides by a
#: constant through its reciprocal (docs/derivations.md, "A half turn's tie on every backend").
TIE_TURNS = 1e-12


def wrap_angle(a) -> np.ndarray:
    """Angles (rad, any shape) wrapped to ``[-pi, pi)``: ``a - 2 pi k`` for the right integer ``k``.

    NumPy input (or Python numbers) gives a float64 NumPy array; a JAX array stays one (the
    same floating-point remainder).
    """
    if concrete(a) or isinstance(a, (list, tuple)):
        a = np.asarray(a, dtype=float)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def map_entries(e, indices, f):
    """``e`` (``(..., k)``, any array namespace) with its entries ``indices`` (of the last
    axis) replaced by ``f(a, b)``, the new values of the run ``e[..., a:b]`` of neighbouring
    indices; the other entries as they are.

    ``e`` is cut into runs of neighbouring chosen and other entries and joined again: the
    values of ``where(mask, f(whole), e)``, without computing ``f`` on the entries that are
    not chosen (a compiled loop would take a floating-point remainder per entry there, and
    XLA folds a gather of the entries back into the whole array).
    """
    idx = sorted(set(int(i) for i in np.ravel(indices)))
    if not idx:
        return e
    k = e.shape[-1]
    chosen = np.zeros(k, dtype=bool)
    chosen[idx] = True
    cuts = [0] + [q for q in range(1, k) if chosen[q] != chosen[q - 1]] + [k]
    runs = [f(a, b) if chosen[a] else e[..., a:b] for a, b in zip(cuts[:-1], cuts[1:])]
    return runs[0] if len(runs) == 1 else array_namespace(e).concatenate(runs, axis=-1)


def wrap_entries(e, angles):
    """``e`` with its entries ``angles`` (indices of the last axis) wrapped by
    :func:`wrap_angle`, the others as they are (:func:`map_entries`): the floats of
    ``e[..., angles] = wrap_angle(e[..., angles])`` (NumPy: that assignment on a copy, one
    gather and one scatter whatever the number of runs)."""
    if concrete(e):
        out = np.array(e, dtype=float)
        idx = np.asarray(angles, dtype=np.intp).ravel()
        if idx.size:
            out[..., idx] = wrap_angle(out[..., idx])
        return out
    return map_entries(e, angles, lambda a, b: wrap_angle(e[..., a:b]))
