"""The seed-000 pair controllers on the controller contract (:mod:`quatform.control.contract`).

Control layer (beside robots, above formations). A pair controller holds its formation
description, gains and the team's limits, and no state (``init() -> None``), so the same
object can drive a simulator or real robots: feed it the measured robot state and the
desired cluster state and rate, send the commands it returns. ``update`` also returns the
signals ``cluster`` (the measured cluster state), ``error`` and ``raw_finite``.

``update`` is the host's checks, :meth:`~quatform.control.contract.Controller.reference_arrays`
and the controller's pure :meth:`~quatform.control.contract.Controller.tick`, raising where the
tick's code says the data were refused (:data:`FAILURE_REASONS`); ``step`` of one formation
keeps its Python-float path (the real-time path).
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace
from ..algebra.validate import UNIT_TOLERANCE, as_array
from ..errors import DegenerateInputError, InvalidInputError, NonUnitError, ShapeError
from ..formations.pair_kernels import pack
from ..formations.base import MAX_MAGNITUDE, MIN_SEPARATION_M, Formation, check_magnitude
from ..formations.layout import POINT_KINDS
from ..formations.team_chart import team_positions
from ..robots import Team
from . import contract

__all__ = ["Reference", "StepResult", "Controller", "FAILURE_REASONS", "MEASURED_NOT_FINITE", "ROBOTS_COINCIDE",
           "measured_codes", "apart_robots", "batch_shape"]

#: :attr:`~quatform.control.contract.Tick.code` of a world whose measured robot state is not
#: finite or beyond :data:`~quatform.formations.base.MAX_MAGNITUDE` (``update`` refuses it).
MEASURED_NOT_FINITE = 1
#: :attr:`~quatform.control.contract.Tick.code` of a world whose measured robots are closer than
#: :data:`~quatform.formations.base.MIN_SEPARATION_M` (the formation is undefined there).
ROBOTS_COINCIDE = 2
#: Reason of each failure code of the seed-000 controllers' tick (pair and team).
FAILURE_REASONS = {MEASURED_NOT_FINITE: "the measured robot state is not finite (or beyond 1e150)",
                   ROBOTS_COINCIDE: f"the measured robots coincide (closer than {MIN_SEPARATION_M:g} m): a "
                                    "formation is undefined there"}


@dataclass(frozen=True)
class Reference:
    """Desired cluster state and rate in a controller's formation description.

    Attributes
    ----------
    c : ndarray, shape (..., n_c)
    c_dot : ndarray, shape (..., n_c)
    robots : ndarray, shape (..., n_r), optional
        The desired robot state (the robot-space reference). The measured yaws are
        unwrapped to within pi of its yaws before the forward kinematics, so a sensor's yaw
        reported mod 2 pi, or a reference whose yaws are wound by 2 pi, means the same
        formation. No description needs it any more: the dual-quaternion controller reads
        the desired robots from ``c`` itself (the sign of ``qhat_s`` is the branch of the
        half-way yaw, ``docs/derivations.md``, "The two-robot formations and controllers (seed 000)") and aligns to those.
    """

    c: np.ndarray
    c_dot: np.ndarray
    robots: np.ndarray | None = None


@dataclass(frozen=True)
class StepResult:
    """What one control step computed.

    Attributes
    ----------
    commands : ndarray, shape (n_r,)
        Saturated, finite robot commands.
    cluster : ndarray, shape (n_c,)
        Measured cluster state (forward kinematics with the reference as hint).
    error : ndarray, shape (n_c,)
        ``c - c_des`` (angles wrapped).
    raw_finite : bool or ndarray of bool
        False if the unsaturated command had a NaN or infinity (it was replaced by zero).
    """

    commands: np.ndarray
    cluster: np.ndarray
    error: np.ndarray
    raw_finite: bool


def check_units(comps, starts, dual=False, tol=UNIT_TOLERANCE):
    """Raise NonUnitError if a (dual) quaternion of a reference is not unit beyond ``tol``.

    ``comps``: components of the reference (floats or arrays); ``starts``: ``(index, name)``.
    """
    for i, name in starts:
        q = comps[i:i + 4]
        n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
        bad = abs(n2 ** 0.5 - 1.0) > tol
        if dual:
            d = comps[i + 4:i + 8]
            bad = bad | (abs(q[0] * d[0] + q[1] * d[1] + q[2] * d[2] + q[3] * d[3]) > tol)
        if bad if isinstance(bad, bool) else np.any(bad):
            raise NonUnitError(
                f"reference {name} is not a unit {'dual ' if dual else ''}quaternion "
                f"(norm {float(np.max(np.sqrt(n2))):.9g}); build references with formation.from_euclidean "
                "or normalise them"
            )


def gains(values, n, name):
    """Positive finite gain vector of length ``n`` (a scalar is repeated)."""
    try:
        g = np.broadcast_to(np.asarray(values, dtype=float), (n,)).copy()
    except (TypeError, ValueError):
        g = np.full(n, np.nan)
    if not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise InvalidInputError(f"{name} must be {n} positive finite gains, got {values!r}")
    return g


_TWO_PI = 2.0 * math.pi


def measured_codes(layout, m, r, apart=True, inclusive=False):
    """The failure code of each world of a tick, branch-free on any namespace: ``(...)`` ints.

    :data:`MEASURED_NOT_FINITE` where the measured ``m`` (``(..., n_m)``) has an entry not
    finite or beyond :data:`~quatform.formations.base.MAX_MAGNITUDE`; else, with ``apart``,
    :data:`ROBOTS_COINCIDE` where two robots of ``r`` (the robot state, ``(..., layout.size)``)
    are closer than :data:`~quatform.formations.base.MIN_SEPARATION_M` (``inclusive``: at most
    that, the pair kernels' rule ``d^2 <= d_min^2``; else the layout's ``d < d_min``); else 0.
    """
    if type(m) is np.ndarray and type(r) is np.ndarray and m.ndim == 1 and r.ndim == 1 and layout.n <= 8:
        mf = m.tolist()
        return np.asarray(_codes_floats(layout, mf, mf if r is m else r.tolist(), apart, inclusive))  # floats
    xp = array_namespace(r)
    with np.errstate(invalid="ignore", over="ignore"):
        bad_m = ~xp.all(xp.isfinite(m) & (xp.abs(m) <= MAX_MAGNITUDE), axis=-1)
        code = xp.where(bad_m, MEASURED_NOT_FINITE, 0)
        if apart and layout.n > 1:
            p = team_positions(layout, r)
            if xp is np and layout.n > _SCREEN_FROM and _screened(p, bad_m):
                return code  # no two robots within the minimum (RobotLayout.check_apart's screen)
            i, j = layout.pairs
            d = p[..., i, :] - p[..., j, :]
            d2 = xp.sum(d * d, axis=-1)
            close = (d2 <= MIN_SEPARATION_M * MIN_SEPARATION_M) if inclusive else (xp.sqrt(d2) < MIN_SEPARATION_M)
            code = xp.where(bad_m, code, xp.where(xp.any(close, axis=-1), ROBOTS_COINCIDE, 0))
    return code


#: Teams larger than this screen their robots' separations first on NumPy (:func:`_screened`).
_SCREEN_FROM = 16
#: The screen's fixed direction (``formations.layout``'s).
_SCREEN_DIRECTION = np.array([0.5773502691896258, 0.6172133998483676, 0.5345224838248488])
_SCREEN_DIRECTION = _SCREEN_DIRECTION / np.linalg.norm(_SCREEN_DIRECTION)


def _screened(p, skip) -> bool:
    """Whether every world of the positions ``p`` (``(..., N, 3)``, NumPy) but those ``skip``
    has no two robots within :data:`~quatform.formations.base.MIN_SEPARATION_M`, by the O(N
    log N) screen of :meth:`~quatform.formations.layout.RobotLayout.check_apart`: two robots
    are at least as far apart as their projections on one direction, so sorted neighbouring
    projections farther apart than the minimum clear every pair (False: measure them)."""
    proj = np.sort(p @ _SCREEN_DIRECTION, axis=-1)
    return bool(np.all(np.all(np.diff(proj, axis=-1) > MIN_SEPARATION_M, axis=-1) | skip))


def batch_shape(*arrays) -> tuple:
    """The broadcast of the arrays' leading axes (all but the last); ValueError where they do
    not broadcast."""
    first = arrays[0].shape[:-1]
    if all(a.shape[:-1] == first for a in arrays[1:]):
        return first
    return np.broadcast_shapes(*(a.shape[:-1] for a in arrays))


def _codes_floats(layout, m, r, apart, inclusive) -> int:
    """:func:`measured_codes` of one world given as lists of Python floats (the same tests)."""
    if not all(abs(v) <= MAX_MAGNITUDE for v in m):  # False for NaN
        return MEASURED_NOT_FINITE
    if not apart or layout.n < 2:
        return 0
    p = [[r[k] if k < layout.size else 0.0 for k in row] for row in layout.position_index.tolist()]
    lim = MIN_SEPARATION_M * MIN_SEPARATION_M
    for a, b in zip(*layout.pairs):
        pa, pb = p[a], p[b]
        d2 = (pa[0] - pb[0]) ** 2 + (pa[1] - pb[1]) ** 2 + (pa[2] - pb[2]) ** 2
        if (d2 <= lim) if inclusive else (math.sqrt(d2) < MIN_SEPARATION_M):
            return ROBOTS_COINCIDE
    return 0


def apart_robots(layout) -> np.ndarray:
    """A robot state of ``layout`` (``(layout.size,)``) whose robots are apart and in general
    position (robot ``a`` at ``(cos a, sin a, a / 4)`` m, yaw 0, orientation 1): what a tick
    computes on in place of a world it refuses (:func:`measured_codes`), so that no refused
    value raises or warns on NumPy; that world's outputs are discarded."""
    r = np.zeros(layout.size)
    for a, (o, k) in enumerate(zip(layout.offsets, layout.kinds)):
        kind = POINT_KINDS[k]
        for p, v in zip(kind.position, (math.cos(a), math.sin(a), 0.25 * a)):
            r[o + p] = v
        for q, (stem, _, what) in enumerate(kind.components):
            if what == "quaternion" and stem == "q_w":
                r[o + q] = 1.0
    return r


def _floats(x, n):
    """``x`` as a list of ``n`` finite floats within the magnitude limit, or None when ``x`` is
    not one such float64 vector (then the checks of :func:`_checked` apply)."""
    if type(x) is np.ndarray and x.shape == (n,) and x.dtype == np.float64:
        v = x.tolist()
        if math.isfinite(sum(v)) and max(v) <= MAX_MAGNITUDE and min(v) >= -MAX_MAGNITUDE:
            return v
    return None


def _checked(x, name, n):
    """``as_array`` and the magnitude limit, with a fast path for one float64 vector of length ``n``."""
    if _floats(x, n) is not None:
        return x
    return check_magnitude(as_array(x, name, n), name)


class Controller(contract.Controller):
    """Base of the cluster-space controllers of seed 000: stateless (``init() -> None``)."""

    #: Name on the command line.
    name: str = ""
    formation: Formation
    team: Team
    feedforward: bool

    @property
    def command_names(self) -> tuple[str, ...]:
        """``u_x1 ... u_theta2``: the rates of the robot variables."""
        return tuple("u_" + v.name for v in self.formation.robot_variables)

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """``cluster`` and ``error`` (the formation's variables) and ``raw_finite``."""
        names = self.formation.names
        return {"cluster": names, "error": names, "raw_finite": ("raw_finite",)}

    def step(self, t: float, measured, reference: Reference = None) -> np.ndarray:
        """Robot commands (shape ``(..., n_r)``) for the measured robot state ``measured``.

        Equal to ``update(t, measured, reference, init()).u``, without building the signals.

        Parameters
        ----------
        t : float
            Time, s (the seed's controllers do not use it).
        measured : array_like, shape (..., n_r)
            Measured robot state; leading axes are a batch of formations.
        reference : Reference
            Desired cluster state and rate, shape ``(..., n_c)`` each.
        """
        c, err, r_dot = self._control(*self._inputs(measured, reference))
        if isinstance(r_dot, tuple) and isinstance(r_dot[0], float):
            return self.team.saturate_floats(r_dot)  # one formation: no array round trip
        return self.team.saturate(pack(r_dot))

    pure = property(lambda self: not getattr(self, "filters", ()),
                    doc="True: :meth:`tick` is pure (a controller with filters keeps its update on NumPy).")
    failure_reasons = FAILURE_REASONS

    def update(self, t: float, measured, reference: Reference, state=None) -> contract.Step:
        """One control update: ``Step(u, None, {"cluster", "error", "raw_finite"})``.

        The host's checks (one-line errors), :meth:`reference_arrays` and :meth:`tick`; where
        the tick's code refuses a world, the checked forward kinematics raise its one-line
        error. ``raw_finite`` (shape ``(..., 1)``) is 1 where the unsaturated command was
        finite, 0 where it had a NaN or infinity (the team then stops).
        """
        F = self.formation
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        r = _checked(measured, "measured robot state", F.n_r)
        ref = self.reference_arrays(reference)
        c, c_dot = ref["c"], ref["c_dot"]
        try:
            batch_shape(r, c, c_dot)
        except ValueError:
            raise ShapeError(
                f"batch shapes differ: measured {r.shape}, reference.c {c.shape}, "
                f"reference.c_dot {c_dot.shape}; give one reference per formation or one for all"
            ) from None
        out = self.tick(state, r, ref, t)
        if out.code.any():  # codes are >= 0
            self._control(*self._inputs(measured, reference))  # the checked chain: its one-line error
            raise DegenerateInputError(f"{self.name} controller: {self.failure_reasons[int(np.max(out.code))]}")
        return contract.Step(out.u, None, dict(out.signals))

    def reference_arrays(self, reference):
        """``{"c", "c_dot"[, "robots"]}``: the reference's arrays, checked (finite, within the
        magnitude limit, :attr:`checks`: a reference that is no formation is refused in one
        line). A controller with filters takes its :class:`Reference` as it is."""
        F = self.formation
        if getattr(self, "filters", ()):
            return reference
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        c = _checked(reference.c, "reference.c", F.n_c)
        out = {"c": c, "c_dot": _checked(reference.c_dot, "reference.c_dot", F.n_c)}
        if reference.robots is not None:
            out["robots"] = _checked(reference.robots, "reference.robots", F.n_r)
        comps = tuple(c.tolist()) if c.ndim == 1 else tuple(np.moveaxis(c, -1, 0))
        for check in getattr(self, "checks", ()):
            check(comps)
        return out

    def compute(self, t: float, measured, reference: Reference) -> StepResult:
        """:meth:`update` as a :class:`StepResult`: the commands and the signals by attribute."""
        s = self.update(t, measured, reference, None)
        ok = s.signals["raw_finite"][..., 0] > 0.5
        return StepResult(s.u, s.signals["cluster"], s.signals["error"], bool(ok) if ok.ndim == 0 else ok)

    def _inputs(self, measured, reference):
        """Checked ``(r, c_des, c_dot_des, aligned)``: tuples of Python floats for one formation
        given as float64 vectors (the fast path), arrays otherwise."""
        F = self.formation
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        r, c, c_dot = _floats(measured, F.n_r), _floats(reference.c, F.n_c), _floats(reference.c_dot, F.n_c)
        if r is not None and c is not None and c_dot is not None:
            if reference.robots is None:
                return tuple(r), tuple(c), tuple(c_dot), False
            ref = _floats(reference.robots, F.n_r)
            if ref is not None:
                for i in self.team.layout.yaw_indices:  # Formation.align on floats
                    r[i] += _TWO_PI * math.floor((ref[i] - r[i]) / _TWO_PI + 0.5)
                return tuple(r), tuple(c), tuple(c_dot), True
        r = _checked(measured, "measured robot state", F.n_r)
        c = _checked(reference.c, "reference.c", F.n_c)
        c_dot = _checked(reference.c_dot, "reference.c_dot", F.n_c)
        if not (r.shape[:-1] == c.shape[:-1] == c_dot.shape[:-1]):
            try:
                shape = np.broadcast_shapes(r.shape[:-1], c.shape[:-1], c_dot.shape[:-1])
            except ValueError:
                raise ShapeError(
                    f"batch shapes differ: measured {r.shape}, reference.c {c.shape}, "
                    f"reference.c_dot {c_dot.shape}; give one reference per formation or one for all"
                ) from None
            r, c, c_dot = (np.broadcast_to(a, shape + a.shape[-1:]) for a in (r, c, c_dot))
        if reference.robots is None:
            return r, c, c_dot, False
        return F.align(r, _checked(reference.robots, "reference.robots", F.n_r)), c, c_dot, True

    @abstractmethod
    def _control(self, r, c_des, c_dot_des, aligned):
        """Measured cluster state, error and unsaturated robot rates (arrays or component tuples).

        ``r``, ``c_des``, ``c_dot_des``: tuples of floats (one formation) or arrays (:meth:`_inputs`).

        ``aligned``: whether ``r``'s yaws were unwrapped near the reference's robots.
        """
