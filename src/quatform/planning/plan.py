"""A planned motion of N robots, sampled at any rate, saved to and loaded from ``plan.npz``.

Planning layer. A :class:`Plan` holds knots (times, positions, velocities, accelerations)
and interpolates them with quintic Hermite polynomials, so ``sample(t)`` returns
positions, velocities and accelerations that are exact derivatives of one another
(C2 in time). The file format is described in ``docs/planning.md``.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..algebra import q_continuous, qslerp
from ..algebra.validate import as_array, as_unit_quaternion
from ..checks import check_work, short
from ..errors import InvalidInputError, ShapeError

__all__ = ["PLAN_FORMAT", "Plan", "load_plan"]

#: Value of the ``format`` entry of a plan file.
PLAN_FORMAT = "quatform-plan-1"


@dataclass(frozen=True, eq=False)
class Plan:
    """Robot positions over time, with consistent rates.

    Attributes
    ----------
    times : ndarray, shape (T,)
        Strictly increasing knot times, s (``T >= 2``).
    positions, velocities, accelerations : ndarray, shape (T, N, d)
        m, m/s, m/s^2 at the knots (``d = 2`` or 3).
    masses : ndarray, shape (N,)
    info : dict
        JSON-ready description: ``kind`` (e.g. ``"shaped-geodesic"``), its parameters.
    orientations : ndarray, shape (T, N, 4), optional
        The robots' orientations at the knots, unit quaternions ``(w, x, y, z)``, for plans
        that give them (``"rigid-se3"``); :meth:`orientations_at` interpolates them.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    masses: np.ndarray
    info: dict = field(default_factory=dict)
    orientations: np.ndarray | None = None

    def __post_init__(self):
        t = as_array(self.times, "times", None)
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
            raise InvalidInputError("plan times must be a strictly increasing 1-D array of at least 2 knots")
        p = as_array(self.positions, "positions", None)
        if p.ndim != 3 or p.shape[0] != t.size or p.shape[2] not in (2, 3):
            raise ShapeError(f"positions must have shape (T, N, d) = ({t.size}, N, 2 or 3), got {p.shape}")
        v = as_array(self.velocities, "velocities", p.shape[1:])
        a = as_array(self.accelerations, "accelerations", p.shape[1:])
        m = as_array(self.masses, "masses", None)
        if v.shape != p.shape or a.shape != p.shape or m.shape != (p.shape[1],):
            raise ShapeError(
                f"velocities and accelerations must have the positions' shape {p.shape} and masses "
                f"shape ({p.shape[1]},); got {v.shape}, {a.shape}, {m.shape}"
            )
        if not np.all(m > 0):  # seed 002 eq. (5): the kinetic energy needs positive masses
            k = int(np.argmax(~(m > 0)))
            raise InvalidInputError(f"plan masses[{k}] = {m[k]:g} kg must be > 0 (the robots' masses weigh the "
                                    "kinetic energy, seed 002 eq. (5)); plan again with positive masses")
        for name, val in (("times", t), ("positions", p), ("velocities", v), ("accelerations", a),
                          ("masses", m)):
            val.flags.writeable = False
            object.__setattr__(self, name, val)
        object.__setattr__(self, "info", dict(self.info))
        if self.orientations is not None:
            q = as_unit_quaternion(self.orientations, "orientations")
            if q.shape != p.shape[:2] + (4,):
                raise ShapeError(f"orientations must have shape (T, N, 4) = {p.shape[:2] + (4,)}, got {q.shape}")
            q = q_continuous(q, axis=0)
            q.flags.writeable = False
            object.__setattr__(self, "orientations", q)

    @property
    def n_robots(self) -> int:
        return self.positions.shape[1]

    @property
    def dim(self) -> int:
        return self.positions.shape[2]

    @property
    def duration_s(self) -> float:
        return float(self.times[-1] - self.times[0])

    def sample(self, t):
        """Positions, velocities and accelerations at times ``t`` (shape ``(K,)`` or scalar).

        Quintic Hermite interpolation of the knots; each output has shape ``t.shape + (N, d)``.
        Outside ``[times[0], times[-1]]`` the robots rest at the end positions.
        """
        t = as_array(t, "t", None)
        tt = np.clip(t, self.times[0], self.times[-1])
        k = np.clip(np.searchsorted(self.times, tt, side="right") - 1, 0, self.times.size - 2)
        h = (self.times[k + 1] - self.times[k])[..., None, None]
        x = ((tt - self.times[k]) / (self.times[k + 1] - self.times[k]))[..., None, None]
        p0, p1 = self.positions[k], self.positions[k + 1]
        v0, v1 = self.velocities[k] * h, self.velocities[k + 1] * h
        a0, a1 = self.accelerations[k] * h * h, self.accelerations[k + 1] * h * h
        # quintic Hermite basis on [0, 1] and its first two derivatives
        x2, x3, x4, x5 = x * x, x ** 3, x ** 4, x ** 5
        H = (1 - 10 * x3 + 15 * x4 - 6 * x5, x - 6 * x3 + 8 * x4 - 3 * x5, 0.5 * (x2 - 3 * x3 + 3 * x4 - x5),
             10 * x3 - 15 * x4 + 6 * x5, -4 * x3 + 7 * x4 - 3 * x5, 0.5 * (x3 - 2 * x4 + x5))
        dH = (-30 * x2 + 60 * x3 - 30 * x4, 1 - 18 * x2 + 32 * x3 - 15 * x4, 0.5 * (2 * x - 9 * x2 + 12 * x3 - 5 * x4),
              30 * x2 - 60 * x3 + 30 * x4, -12 * x2 + 28 * x3 - 15 * x4, 0.5 * (3 * x2 - 8 * x3 + 5 * x4))
        ddH = (-60 * x + 180 * x2 - 120 * x3, -36 * x + 96 * x2 - 60 * x3, 0.5 * (2 - 18 * x + 36 * x2 - 20 * x3),
               60 * x - 180 * x2 + 120 * x3, -24 * x + 84 * x2 - 60 * x3, 0.5 * (6 * x - 24 * x2 + 20 * x3))
        coef = (p0, v0, a0, p1, v1, a1)
        pos = sum(c * b for c, b in zip(coef, H))
        vel = sum(c * b for c, b in zip(coef, dH)) / h
        acc = sum(c * b for c, b in zip(coef, ddH)) / (h * h)
        outside = ((t < self.times[0]) | (t > self.times[-1]))[..., None, None]
        return pos, np.where(outside, 0.0, vel), np.where(outside, 0.0, acc)

    def orientations_at(self, t) -> np.ndarray:
        """The robots' orientations at times ``t``, shape ``t.shape + (N, 4)``: slerp between
        the knots (the plan's own rates are exact only at the knots). Raises if the plan has
        none."""
        if self.orientations is None:
            raise InvalidInputError(f"this plan ({self.info.get('kind', 'unknown kind')}) has no orientations")
        t = np.clip(as_array(t, "t", None), self.times[0], self.times[-1])
        k = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, self.times.size - 2)
        x = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        return qslerp(self.orientations[k], self.orientations[k + 1], x[..., None])

    def save(self, path) -> Path:
        """Write ``path`` (``.npz``): the arrays and ``info`` as JSON (``docs/planning.md``)."""
        path = Path(path)
        with open(path, "wb") as f:
            extra = {} if self.orientations is None else {"orientations": self.orientations}
            np.savez(f, format=np.array(PLAN_FORMAT), times=self.times, positions=self.positions,
                     velocities=self.velocities, accelerations=self.accelerations, masses=self.masses,
                     info=np.array(json.dumps(self.info)), **extra)
        return path


#: Arrays a plan file may hold, and the dtype kind each must have (``"f"`` float, ``"U"`` text).
_PLAN_ARRAYS = {"format": "U", "times": "f", "positions": "f", "velocities": "f", "accelerations": "f",
                "masses": "f", "info": "U", "orientations": "f"}
#: Longest ``info`` JSON string accepted, characters, and its deepest nesting.
INFO_MAX_CHARS = 1_000_000
INFO_MAX_DEPTH = 8


def _check_headers(path: Path) -> None:
    """Read every ``.npy`` header of the archive before any array, and refuse what would not
    fit: unknown or object dtypes, and sizes beyond this machine's memory
    (:func:`~quatform.checks.check_work`), so a header that claims 1e13 elements is refused
    before anything is allocated."""
    with zipfile.ZipFile(path) as zf:
        total = 0.0
        for item in zf.infolist():
            name = item.filename[:-4] if item.filename.endswith(".npy") else item.filename
            if name not in _PLAN_ARRAYS:
                raise InvalidInputError(f"{path}: unexpected entry {short(item.filename)} in a plan file; "
                                        f"a plan holds {', '.join(_PLAN_ARRAYS)} (docs/planning.md)")
            with zf.open(item) as f:
                try:
                    version = np.lib.format.read_magic(f)
                    if version not in ((1, 0), (2, 0)):
                        raise ValueError(f"unsupported .npy format version {version}")
                    read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                            else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read(f)
                except (ValueError, OSError, EOFError) as exc:
                    raise InvalidInputError(f"{path}: entry {name!r} is not a NumPy array ({exc})") from None
            if dtype.hasobject or dtype.kind != _PLAN_ARRAYS[name]:
                raise InvalidInputError(f"{path}: entry {name!r} has dtype {dtype}; a plan file stores "
                                        f"{'text' if _PLAN_ARRAYS[name] == 'U' else 'floats'} there")
            count = float(np.prod([float(k) for k in shape])) if shape else 1.0
            if name in ("format", "info") and shape != ():
                raise InvalidInputError(f"{path}: entry {name!r} must be a single string, got shape {shape}")
            total += count * dtype.itemsize
        check_work(str(path), "the array sizes in its .npy headers", total, bytes_per_step=1.0,
                   fix="this is not a plan quatform wrote; re-plan it")


def _depth(value, limit: int) -> int:
    """Nesting depth of JSON ``value`` (stops counting past ``limit``)."""
    if limit < 0 or not isinstance(value, (dict, list)):
        return 0
    items = value.values() if isinstance(value, dict) else value
    return 1 + max((_depth(v, limit - 1) for v in items), default=0)


def _read_info(path: Path, text_: str) -> dict:
    """The plan's ``info``: a JSON object of bounded size and depth, else one line."""
    if len(text_) > INFO_MAX_CHARS:
        raise InvalidInputError(f"{path}: info is {len(text_)} characters, more than {INFO_MAX_CHARS}; "
                                "it should be a short JSON description (docs/planning.md)")
    try:
        info = json.loads(text_)
    except (ValueError, RecursionError) as exc:
        raise InvalidInputError(f"{path}: info is not JSON ({short(str(exc))}); re-plan it") from None
    if not isinstance(info, dict):
        raise InvalidInputError(f"{path}: info must be a JSON object (kind, name, alpha, ...), got a "
                                f"{type(info).__name__}: {short(info)}")
    if _depth(info, INFO_MAX_DEPTH + 1) > INFO_MAX_DEPTH:
        raise InvalidInputError(f"{path}: info is nested more than {INFO_MAX_DEPTH} levels deep; a plan's info "
                                "is a flat description (docs/planning.md)")
    return info


def load_plan(path) -> Plan:
    """Read a plan written by :meth:`Plan.save`; a file of another kind raises InvalidInputError.

    The archive's ``.npy`` headers are read first: entries that are not plan arrays, object
    or unexpected dtypes and sizes beyond this machine's memory are refused before any
    array is read; ``info`` must be a JSON object at most :data:`INFO_MAX_DEPTH` deep.
    """
    path = Path(path)
    try:
        _check_headers(path)
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z.files or str(z["format"]) != PLAN_FORMAT:
                raise InvalidInputError(f"{path} is not a quatform plan file (format {PLAN_FORMAT!r})")
            return Plan(z["times"], z["positions"], z["velocities"], z["accelerations"], z["masses"],
                        _read_info(path, str(z["info"])), z["orientations"] if "orientations" in z.files else None)
    except (ValueError, KeyError, zipfile.BadZipFile, EOFError, OSError) as exc:
        if isinstance(exc, InvalidInputError):
            raise
        raise InvalidInputError(f"{path} is not a readable quatform plan file: {short(str(exc), 200)}") from None
