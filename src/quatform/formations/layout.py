"""Robot layouts: how N robots' points are stacked in a robot state vector.

Formations layer (beside :mod:`.base`). A formation describes a team whose robots each
offer it one *point* of a kind: a planar ground point ``(x, y, yaw)``, a 4-DOF point
``(x, y, z, yaw)``, a position ``(x, y, z)`` (a robot whose yaw is controlled outside
the formation, seed 001 §4.3.3) or a full pose ``(x, y, z, q_w, q_x, q_y, q_z)``. A
:class:`RobotLayout` knows the offsets of every robot's entries, their names and units,
the robots' positions as a ``(..., N, 3)`` array, all pairwise separations and the yaw
winding, so no code outside a representation's own kernels writes ``r[..., 4:7]``.

Layouts are frozen, hashable values (cached slices); ``RobotLayout.uniform("xyz_yaw", 2)``
is the robot space of seed 000, ``RobotLayout(("xyz", "xyz"))`` that of seed 001.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.angles import TIE_TURNS
from ..algebra.kernels import concrete
from ..errors import DegenerateInputError, InvalidInputError

__all__ = ["PointKind", "POINT_KINDS", "RobotLayout", "Variable"]

_TWO_PI = 2.0 * math.pi
#: Teams larger than this screen coincident robots by sorted projections (:meth:`RobotLayout.check_apart`).
_SCREEN_FROM = 16
#: A unit direction with no simple relation to the axes (grids and rings of robots project apart).
_SCREEN_DIRECTION = np.array([0.5773502691896258, 0.6172133998483676, 0.5345224838248488])
_SCREEN_DIRECTION = _SCREEN_DIRECTION / np.linalg.norm(_SCREEN_DIRECTION)


@dataclass(frozen=True)
class Variable:
    """One component of a state vector.

    Attributes
    ----------
    name : str
        Column name (``x_c``, ``q_c_w`` ...), used in time-series files.
    unit : str
        ``m``, ``rad`` or ``1`` (quaternion components).
    kind : str
        ``position``, ``length``, ``angle`` or ``quaternion`` (a component of a unit
        quaternion or of a unit dual quaternion's part).
    """

    name: str
    unit: str
    kind: str


@dataclass(frozen=True)
class PointKind:
    """What one robot offers a formation.

    Attributes
    ----------
    name : str
        Registry key (``xy_yaw``, ``xyz_yaw``, ``xyz``, ``pose``).
    components : tuple of (name stem, unit, kind)
        The entries in order; names get the robot's number appended (``x1``, ``theta1``).
    position : tuple of int
        Offsets of ``x, y[, z]`` within the point (a planar point has no ``z``: 0 m).
    yaw : int or None
        Offset of the yaw angle (rad), if the point carries one as a real number.
    """

    name: str
    components: tuple
    position: tuple
    yaw: int | None

    @property
    def size(self) -> int:
        return len(self.components)


#: Point kinds by name.
POINT_KINDS = {
    k.name: k
    for k in (
        PointKind("xy_yaw", (("x", "m", "position"), ("y", "m", "position"), ("theta", "rad", "angle")), (0, 1), 2),
        PointKind("xyz_yaw", (("x", "m", "position"), ("y", "m", "position"), ("z", "m", "position"),
                              ("theta", "rad", "angle")), (0, 1, 2), 3),
        PointKind("xyz", (("x", "m", "position"), ("y", "m", "position"), ("z", "m", "position")), (0, 1, 2), None),
        PointKind("pose", (("x", "m", "position"), ("y", "m", "position"), ("z", "m", "position"),
                           ("q_w", "1", "quaternion"), ("q_x", "1", "quaternion"), ("q_y", "1", "quaternion"),
                           ("q_z", "1", "quaternion")), (0, 1, 2), None),
    )
}


@dataclass(frozen=True)
class RobotLayout:
    """N robots, each of a point kind, stacked robot after robot.

    Parameters
    ----------
    kinds : tuple of str
        One :data:`POINT_KINDS` key per robot.
    labels : tuple of str, optional
        Suffix of each robot's variable names (default ``"1" ... "N"``).
    display_names : tuple of str, optional
        Each robot's name in messages (``"robots UGV and UAV coincide"``); default the
        ``labels``. Column names use the ``labels`` only.
    """

    kinds: tuple
    labels: tuple | None = None
    display_names: tuple | None = None

    def __post_init__(self):
        kinds = tuple(self.kinds)
        if len(kinds) < 1:
            raise InvalidInputError("a robot layout needs at least one robot")
        for k in kinds:
            if k not in POINT_KINDS:
                from ..checks import nearest

                raise InvalidInputError(f"unknown point kind {k!r}{nearest(k, POINT_KINDS)}; choose one of "
                                        f"{', '.join(POINT_KINDS)}")
        labels = tuple(str(i + 1) for i in range(len(kinds))) if self.labels is None else tuple(self.labels)
        if len(labels) != len(kinds):
            raise InvalidInputError(f"robot layout: {len(labels)} labels for {len(kinds)} robots")
        shown = labels if self.display_names is None else tuple(str(d) for d in self.display_names)
        if len(shown) != len(kinds):
            raise InvalidInputError(f"robot layout: {len(shown)} display names for {len(kinds)} robots")
        object.__setattr__(self, "kinds", kinds)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "display_names", shown)

    @classmethod
    def uniform(cls, kind: str, n: int) -> RobotLayout:
        """``n`` robots of one kind."""
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise InvalidInputError(f"a robot layout needs a whole number of robots >= 1, got {n!r}")
        return cls((kind,) * n)

    # -- sizes and offsets ----------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of robots."""
        return len(self.kinds)

    @functools.cached_property
    def offsets(self) -> tuple[int, ...]:
        """Index of each robot's first entry; ``offsets[-1] + size of the last`` is :attr:`size`."""
        out, i = [], 0
        for k in self.kinds:
            out.append(i)
            i += POINT_KINDS[k].size
        return tuple(out)

    @functools.cached_property
    def size(self) -> int:
        """Length of the robot state vector."""
        return sum(POINT_KINDS[k].size for k in self.kinds)

    def slice(self, i: int) -> slice:
        """Entries of robot ``i`` (0-based)."""
        return slice(self.offsets[i], self.offsets[i] + POINT_KINDS[self.kinds[i]].size)

    @functools.cached_property
    def variables(self) -> tuple[Variable, ...]:
        """Every entry as a :class:`Variable` (``x1, y1, z1, theta1, x2 ...``)."""
        out = []
        for k, lab in zip(self.kinds, self.labels):
            out += [Variable(f"{stem}{lab}", unit, kind) for stem, unit, kind in POINT_KINDS[k].components]
        return tuple(out)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables)

    @functools.cached_property
    def yaw_indices(self) -> tuple[int, ...]:
        """Indices of the robots' yaw angles (robots whose point has one)."""
        return tuple(o + POINT_KINDS[k].yaw for o, k in zip(self.offsets, self.kinds) if POINT_KINDS[k].yaw is not None)

    @functools.cached_property
    def position_index(self):
        """``(N, 3)`` gather indices into ``r`` padded by one zero entry (planar z)."""
        idx = np.full((self.n, 3), self.size, dtype=np.intp)
        for i, (o, k) in enumerate(zip(self.offsets, self.kinds)):
            for j, p in enumerate(POINT_KINDS[k].position):
                idx[i, j] = o + p
        return idx

    # -- geometry -----------------------------------------------------------------------
    def check(self, r, name: str = "r") -> np.ndarray:
        """``r`` as a float array whose last axis has :attr:`size` entries."""
        if concrete(r) or isinstance(r, (list, tuple)):
            r = np.asarray(r, dtype=float)
        if r.shape[-1:] != (self.size,):
            raise InvalidInputError(f"{name} must have shape (..., {self.size}) for {self.n} robots "
                                    f"({', '.join(self.kinds)}), got {r.shape}")
        return r

    @functools.cached_property
    def _uniform_xyz(self):
        """Point size if every robot has one kind whose first three entries are ``x, y, z``."""
        k = POINT_KINDS[self.kinds[0]]
        return k.size if len(set(self.kinds)) == 1 and k.position == (0, 1, 2) else None

    def positions(self, r) -> np.ndarray:
        """Robot positions, m, shape ``(..., N, 3)`` (a planar robot at z = 0).

        A view of ``r`` where the layout allows (one point kind with ``x, y, z`` first):
        read it, do not write into it.
        """
        r = self.check(r)
        k = self._uniform_xyz
        if k is not None:
            return r.reshape(r.shape[:-1] + (self.n, k))[..., :3]
        padded = np.concatenate([r, np.zeros(r.shape[:-1] + (1,))], axis=-1)
        # C order, so that reductions over the last axis sum in the order of a plain slice
        return np.ascontiguousarray(padded[..., self.position_index])

    def yaws(self, r) -> np.ndarray:
        """The yaw entries, rad, shape ``(..., len(yaw_indices))`` (a view where the layout allows)."""
        r = self.check(r)
        if self._uniform_xyz == 4 and self.kinds[0] == "xyz_yaw":
            return r.reshape(r.shape[:-1] + (self.n, 4))[..., 3]
        return r[..., list(self.yaw_indices)]

    def separations(self, r) -> np.ndarray:
        """Distances between every two robots, m, shape ``(..., N (N - 1) / 2)`` in the order
        ``(1, 2), (1, 3), ... (2, 3), ...`` (:attr:`pairs`)."""
        p = self.positions(r)
        i, j = self.pairs
        d = p[..., i, :] - p[..., j, :]
        return np.sqrt(np.einsum("...k,...k->...", d, d))

    @functools.cached_property
    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Robot indices ``(i, j)``, ``i < j``, of :meth:`separations`."""
        i, j = np.triu_indices(self.n, 1)
        return i, j

    def min_separation(self, r) -> np.ndarray:
        """Smallest distance between two robots, m, shape ``(...)`` (inf for one robot)."""
        s = self.separations(r)
        return np.min(s, axis=-1) if s.shape[-1] else np.full(s.shape[:-1], np.inf)

    def check_apart(self, r, min_m: float, name: str = "r") -> None:
        """Raise DegenerateInputError (naming the robots) if two robots are closer than ``min_m``.

        For a team of more than :data:`_SCREEN_FROM` robots, first an O(N log N) screen: the
        positions projected on one fixed direction and sorted; two robots are at least as far
        apart as their projections, so neighbouring projections ``min_m`` apart clear every
        pair. Only where the screen fails are all pairs measured.
        """
        if self.n > _SCREEN_FROM:
            proj = np.sort(self.positions(r) @ _SCREEN_DIRECTION, axis=-1)
            if np.all(np.diff(proj, axis=-1) >= min_m):
                return
        s = self.separations(r)
        close = s < min_m
        if np.any(close):
            at = np.argwhere(close)[0]
            i, j = (int(a[at[-1]]) for a in self.pairs)
            raise DegenerateInputError(
                f"{name}: robots {self.display_names[i]} and {self.display_names[j]} coincide (separation "
                f"{float(s[tuple(at)]):.3g} m, at least {min_m:g} m needed"
                + (f", at index {tuple(int(k) for k in at[:-1])}" if len(at) > 1 else "")
                + "); a formation needs its robots apart")

    def wind(self, r, r_ref) -> np.ndarray:
        """``r`` with each yaw moved by whole turns to within pi of ``r_ref``'s (same robots; a
        difference within :data:`~quatform.algebra.angles.TIE_TURNS` turns short of half a turn
        is half a turn)."""
        idx = self.yaw_indices
        if r.ndim == 1 and r_ref.ndim == 1 and concrete(r) and concrete(r_ref):  # one state: Python floats
            out = r.tolist()
            ref = r_ref.tolist()
            for i in idx:
                out[i] += _TWO_PI * math.floor((ref[i] - out[i]) / _TWO_PI + 0.5 + TIE_TURNS)
            return np.array(out)
        if not concrete(r):  # an array of another namespace (JAX): the same formula, selected
            xp = namespace(r)
            turns = _TWO_PI * xp.floor((r_ref - r) / _TWO_PI + 0.5 + TIE_TURNS)
            return xp.where(self.yaw_mask, r + turns, r)
        out = np.array(np.broadcast_to(r, np.broadcast_shapes(r.shape, r_ref.shape)), dtype=float)
        if idx:
            i = np.asarray(idx, dtype=np.intp)
            out[..., i] += _TWO_PI * np.floor((r_ref[..., i] - out[..., i]) / _TWO_PI + 0.5 + TIE_TURNS)
        return out

    @functools.cached_property
    def yaw_mask(self) -> np.ndarray:
        """Bool array of :attr:`size`: True at the yaw entries (:attr:`yaw_indices`)."""
        mask = np.zeros(self.size, dtype=bool)
        mask[list(self.yaw_indices)] = True
        return mask

    def compose(self, positions, yaws=(), orientations=None) -> np.ndarray:
        """Robot state of ``positions`` (m, ``(..., N, 3)``), ``yaws`` (rad,
        ``(..., len(yaw_indices))``) and, for ``pose`` points, ``orientations`` (unit
        quaternions ``(..., len(orientation_index), 4)``): the inverse of :meth:`positions`,
        :meth:`yaws` and :meth:`orientations`.

        A planar robot's ``z`` is dropped. Linear, so it also composes robot rates from
        point velocities and yaw (or quaternion) rates.
        """
        p = np.asarray(positions, dtype=float)
        if p.shape[-2:] != (self.n, 3):
            raise InvalidInputError(f"positions must have shape (..., {self.n}, 3), got {p.shape}")
        y = np.asarray(yaws, dtype=float)
        n_yaw = len(self.yaw_indices)
        n_q = len(self.orientation_index)
        if n_q and orientations is None:
            raise InvalidInputError(f"RobotLayout.compose: the layout has {n_q} pose point(s); give their "
                                    "orientations (unit quaternions, shape (..., M, 4))")
        shape = p.shape[:-2]
        if n_yaw:
            if y.shape[-1:] != (n_yaw,):
                raise InvalidInputError(f"yaws must have shape (..., {n_yaw}), got {y.shape}")
            shape = np.broadcast_shapes(shape, y.shape[:-1])
            if self._uniform_xyz == 4 and self.kinds[0] == "xyz_yaw":  # robot after robot: x, y, z, yaw
                p = np.broadcast_to(p, shape + (self.n, 3))
                return np.concatenate([p, np.broadcast_to(y, shape + (self.n,))[..., None]], axis=-1).reshape(
                    shape + (self.size,))
        elif self._uniform_xyz == 3:  # robot after robot: x, y, z
            return p.reshape(shape + (self.size,)).copy()
        if n_q:
            o = np.asarray(orientations, dtype=float)
            if o.shape[-2:] != (n_q, 4):
                raise InvalidInputError(f"orientations must have shape (..., {n_q}, 4), got {o.shape}")
            shape = np.broadcast_shapes(shape, o.shape[:-2])
        r = np.empty(shape + (self.size,))
        flat = self.position_index.ravel()
        keep = flat < self.size
        r[..., flat[keep]] = p.reshape(p.shape[:-2] + (3 * self.n,))[..., keep]
        if n_yaw:
            r[..., list(self.yaw_indices)] = y
        if n_q:
            r[..., self.orientation_index] = o
        return r

    @functools.cached_property
    def orientation_index(self) -> np.ndarray:
        """Indices of the ``pose`` points' quaternions ``(q_w, q_x, q_y, q_z)``, shape ``(M, 4)``."""
        rows = [range(o + 3, o + 7) for o, k in zip(self.offsets, self.kinds) if k == "pose"]
        return np.array(rows, dtype=np.intp).reshape(-1, 4)

    def orientations(self, r) -> np.ndarray:
        """The ``pose`` points' quaternions, shape ``(..., M, 4)``."""
        return self.check(r)[..., self.orientation_index]

    def stack(self, points) -> np.ndarray:
        """One robot state from a sequence of per-robot points (each ``(..., size of its kind)``)."""
        if len(points) != self.n:
            raise InvalidInputError(f"stack: {len(points)} points for {self.n} robots")
        return np.concatenate([np.asarray(p, dtype=float) for p in points], axis=-1)

    def split(self, r) -> list[np.ndarray]:
        """The per-robot points of ``r`` (views)."""
        r = self.check(r)
        return [r[..., self.slice(i)] for i in range(self.n)]
