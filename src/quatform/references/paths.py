"""Cluster paths in Euclidean variables, and their conversion to any formation description.

References layer. ``EuclideanPath`` gives ``e(t) = (x_c, y_c, z_c, beta_c, gamma_c, d_c,
phi_1, phi_2)`` and its exact rate for the motions of seed 000 §4: a centroid on a circle
with a climb (the rising spiral of §4.1) or on a line (§4.2), linear ramps of any variable
(the 2 pi turns) and steps (Fig. 4). Angles are not wrapped: ``gamma_c`` runs through
``pi/2`` to ``2 pi``, and every description receives the same continuous motion.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError
from ..formations import EUCLIDEAN_VARIABLES
from ..formations.base import Formation

__all__ = ["Ramp", "Step", "EuclideanPath", "sample_reference"]

_INDEX = {v.name: i for i, v in enumerate(EUCLIDEAN_VARIABLES)}


def _finite(owner, **values):
    """Refuse a value that is not a finite real number, naming it."""
    for key, v in values.items():
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real) or not math.isfinite(v):
            raise InvalidInputError(f"{owner}: {key} must be a finite number, got {v!r}")


def _index(name):
    try:
        return _INDEX[name]
    except KeyError:
        raise InvalidInputError(
            f"unknown cluster variable {name!r}; use one of {', '.join(_INDEX)}"
        ) from None


@dataclass(frozen=True)
class Ramp:
    """Change ``variable`` by ``change`` at a constant rate from ``start_s`` for ``duration_s``."""

    variable: str
    start_s: float
    duration_s: float
    change: float

    def __post_init__(self):
        _index(self.variable)
        _finite(f"ramp of {self.variable}", start_s=self.start_s, duration_s=self.duration_s, change=self.change)
        if not self.duration_s > 0:
            raise InvalidInputError(f"ramp of {self.variable}: duration_s must be > 0, got {self.duration_s!r}")

    def value_rate(self, t):
        s = np.clip((t - self.start_s) / self.duration_s, 0.0, 1.0)
        inside = (t >= self.start_s) & (t < self.start_s + self.duration_s)
        return self.change * s, np.where(inside, self.change / self.duration_s, 0.0)


@dataclass(frozen=True)
class Step:
    """Change ``variable`` by ``change`` at ``time_s`` (no rate: the controllers see a jump)."""

    variable: str
    time_s: float
    change: float

    def __post_init__(self):
        _index(self.variable)
        _finite(f"step of {self.variable}", time_s=self.time_s, change=self.change)

    def value_rate(self, t):
        return np.where(t >= self.time_s, self.change, 0.0), np.zeros_like(t)


@dataclass(frozen=True)
class EuclideanPath:
    """A formation motion in Euclidean cluster variables.

    Parameters
    ----------
    initial : array_like, shape (8,)
        ``e(0)`` before the centroid motion: angles and ``d_c`` (the centroid entries are
        added to the centroid motion).
    centroid : {"circle", "line", "fixed"}
        ``circle``: ``center + radius (cos 2 pi t/T, sin 2 pi t/T, 0) + (0, 0, climb t)``;
        ``line``: ``center + velocity t``.
    center, velocity : array_like, shape (3,)
    radius, period_s, climb_m_s : float
    ramps, steps : tuple
        :class:`Ramp` and :class:`Step` changes added on top.
    """

    initial: np.ndarray = field(default_factory=lambda: np.array([0, 0, 0, 0, 0, 1.0, 0, 0]))
    centroid: str = "fixed"
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 0.0
    period_s: float = 1.0
    climb_m_s: float = 0.0
    ramps: tuple = ()
    steps: tuple = ()

    def __post_init__(self):
        for name in ("initial", "center", "velocity"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.initial.shape != (8,) or not np.all(np.isfinite(self.initial)):
            raise InvalidInputError(f"initial must be 8 finite numbers, got {self.initial!r}")
        for name in ("center", "velocity"):
            v = getattr(self, name)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InvalidInputError(f"{name} must be 3 finite numbers, got {v!r}")
        _finite("path", radius=self.radius, period_s=self.period_s, climb_m_s=self.climb_m_s)
        if self.centroid not in ("circle", "line", "fixed"):
            raise InvalidInputError(
                f"centroid must be 'circle', 'line' or 'fixed', got {self.centroid!r}"
            )
        if self.centroid == "circle":  # seed 000 §4.1: a circle needs a radius and a lap time
            for key in ("radius", "period_s"):
                if not getattr(self, key) > 0:
                    raise InvalidInputError(f"circle {key} must be > 0, got {getattr(self, key)!r} (a circle of "
                                            "radius 0 is a fixed point: use centroid='fixed')")

    def __call__(self, t):
        """``e(t)`` and ``e_dot(t)``, each shape ``(len(t), 8)`` (or ``(8,)`` for scalar ``t``)."""
        t = np.asarray(t, dtype=float)
        e = np.broadcast_to(self.initial, t.shape + (8,)).copy()
        ed = np.zeros(t.shape + (8,))
        if self.centroid == "circle":
            w = 2.0 * np.pi / self.period_s
            e[..., 0] += self.center[0] + self.radius * np.cos(w * t)
            e[..., 1] += self.center[1] + self.radius * np.sin(w * t)
            e[..., 2] += self.center[2] + self.climb_m_s * t
            ed[..., 0] = -self.radius * w * np.sin(w * t)
            ed[..., 1] = self.radius * w * np.cos(w * t)
            ed[..., 2] = self.climb_m_s
        else:
            v = self.velocity if self.centroid == "line" else np.zeros(3)
            e[..., 0:3] += self.center + t[..., None] * v
            ed[..., 0:3] = v
        for change in (*self.ramps, *self.steps):
            i = _index(change.variable)
            val, rate = change.value_rate(t)
            e[..., i] += val
            ed[..., i] += rate
        if np.any(e[..., 5] <= 0):
            first = float(np.broadcast_to(t, e.shape[:-1])[e[..., 5] <= 0].min())
            names = [f"{type(c).__name__.lower()} of d_c" for c in (*self.ramps, *self.steps) if c.variable == "d_c"]
            raise InvalidInputError(
                f"the path makes d_c <= 0 (min {float(e[..., 5].min()):.3g} m, first at t = {first:g} s): the robots "
                f"would meet; raise initial d_c or shrink the {' and '.join(names) or 'd_c changes'}"
            )
        return e, ed


def sample_reference(path: EuclideanPath, times, formation: Formation):
    """The path at ``times`` in ``formation``'s description.

    Returns
    -------
    e, e_dot : ndarray, shape (T, 8)
        Euclidean variables and rates.
    c, c_dot : ndarray, shape (T, n_c)
        The same motion in ``formation``.
    """
    e, ed = path(np.asarray(times, dtype=float))
    c, cd = formation.from_euclidean(e, ed)
    return e, ed, c, cd
