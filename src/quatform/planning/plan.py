"""A planned motion of N robots, sampled at any rate, saved to and loaded from ``plan.npz``.

Planning layer. A :class:`Plan` holds knots (times, positions, velocities, accelerations)
and interpolates them with quintic Hermite polynomials, so ``sample(t)`` returns
positions, velocities and accelerations that are exact derivatives of one another
(C2 in time). The file format is described in ``docs/planning.md``.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..algebra import q_continuous, qslerp
from ..algebra.validate import as_array, as_unit_quaternion
from ..checks import MAX_NUMBER, check_work, short
from ..errors import InvalidInputError, ShapeError

__all__ = ["PLAN_FORMAT", "PLAN_MAX_ABS", "PLAN_MIN_STEP_S", "Plan", "check_plan_rates", "load_plan"]

#: Value of the ``format`` entry of a plan file.
PLAN_FORMAT = "quatform-plan-1"

#: Largest magnitude of any number of a plan (times s, positions m, velocities m/s,
#: accelerations m/s^2, masses kg): the bound of every number quatform reads
#: (:data:`quatform.checks.MAX_NUMBER`).
PLAN_MAX_ABS = MAX_NUMBER
#: Smallest spacing of a plan's knot times, s. With every number within ``B =``
#: :data:`PLAN_MAX_ABS` and every knot spacing ``h`` in ``[1/B, 2B]``, each of the six terms
#: of :meth:`Plan.sample` (``p``, ``v h`` or ``a h^2``, at most ``4 B^3``, times a quintic
#: Hermite basis value or derivative, at most ``10 / sqrt(3)``, then divided by ``h`` or
#: ``h^2``) stays below ``24 B^3``, their sum below ``150 B^3`` (about 1.5e38): finite, as are
#: the squared distances and energies computed from it.
PLAN_MIN_STEP_S = 1.0 / PLAN_MAX_ABS
#: Units of the plan's arrays, for messages.
_UNITS = {"times": "s", "positions": "m", "velocities": "m/s", "accelerations": "m/s^2", "masses": "kg",
          "orientations": ""}


def _check_bounded(name: str, value) -> None:
    """Refuse a plan array with a NaN, an infinity or an entry beyond +-:data:`PLAN_MAX_ABS`
    (one line naming the array, the first such entry and the bound); a non-numeric array is
    left to :func:`~quatform.algebra.validate.as_array`."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return
    bad = ~(np.abs(a) <= PLAN_MAX_ABS)  # NaN too
    if bad.any():
        k = int(np.argmax(bad.ravel()))
        where = f" at index {tuple(int(i) for i in np.unravel_index(k, a.shape))}" if a.ndim else ""
        unit = f" {_UNITS[name]}" if _UNITS[name] else ""
        raise InvalidInputError(f"plan {name} holds {float(a.ravel()[k]):.6g}{unit}{where}, beyond the bound "
                                f"|value| <= {PLAN_MAX_ABS:g}{unit} of every plan number (docs/planning.md, "
                                "plan files); re-plan it")


def check_plan_rates(duration_s: float, rate, rate2, where: str | None = None) -> None:
    """Refuse a planned motion whose rates would leave the plan's bounds, naming ``duration_s``.

    ``rate`` and ``rate2`` are the motion's first and second derivatives per unit of the
    normalised time ``s = t / T`` (``T = duration_s``); the plan's velocities are
    ``rate / T`` and accelerations ``rate2 / T^2``, within :data:`PLAN_MAX_ABS` when
    ``T >= max(max|rate| / B, sqrt(max|rate2| / B))``: the shortest duration named in the
    message (prefixed by ``where``, the spec's name, when given).
    """
    T = float(duration_s)
    at = f"{where}: " if where else ""
    d1 = float(np.max(np.abs(rate), initial=0.0))
    d2 = float(np.max(np.abs(rate2), initial=0.0))
    shortest = max(d1 / PLAN_MAX_ABS, np.sqrt(d2 / PLAN_MAX_ABS))
    if not (np.isfinite(d1) and np.isfinite(d2)):
        raise InvalidInputError(f"{at}duration_s = {T:g} s: the planned motion's rates are not finite; re-plan it")
    if T < shortest:
        what, value = (("velocities", f"{d1 / T:.3g} m/s") if d1 / T > PLAN_MAX_ABS
                       else ("accelerations", f"{d2 / (T * T):.3g} m/s^2"))
        raise InvalidInputError(f"{at}duration_s = {T:g} s makes the plan's {what} reach {value}, beyond the bound "
                                f"{PLAN_MAX_ABS:g} of every plan number; give a duration_s of at least "
                                f"{_round_up(shortest):g} s (docs/planning.md)")


def _round_up(x: float) -> float:
    """``x > 0`` rounded up to three significant digits (a bound quoted in a message that,
    given back, passes)."""
    step = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x / step * (1 + 1e-12)) * step


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
        for name in _UNITS:
            if getattr(self, name) is not None:
                _check_bounded(name, getattr(self, name))
        t = as_array(self.times, "times", None)
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
            raise InvalidInputError("plan times must be a strictly increasing 1-D array of at least 2 knots")
        close = np.diff(t) < PLAN_MIN_STEP_S
        if close.any():
            k = int(np.argmax(close))
            raise InvalidInputError(f"plan times {k} and {k + 1} are {t[k + 1] - t[k]:.3g} s apart, closer than the "
                                    f"bound {PLAN_MIN_STEP_S:g} s of a plan's knot spacing (1 / {PLAN_MAX_ABS:g}: "
                                    "its sampled rates divide by the spacing squared; docs/planning.md); re-plan "
                                    "it with a longer duration_s or fewer knots")
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
            arrays = {name: z[name] for name in ("times", "positions", "velocities", "accelerations", "masses")}
            info = _read_info(path, str(z["info"]))
            orientations = z["orientations"] if "orientations" in z.files else None
        try:
            return Plan(**arrays, info=info, orientations=orientations)
        except InvalidInputError as exc:  # name the file
            raise type(exc)(f"{path}: {exc}") from None
    except (ValueError, KeyError, zipfile.BadZipFile, EOFError, OSError) as exc:
        if isinstance(exc, InvalidInputError):
            raise
        raise InvalidInputError(f"{path} is not a readable quatform plan file: {short(str(exc), 200)}") from None
