"""Desired motions of a team of N robots, in the team chart, with analytic rates (references layer).

A :class:`TeamMotion` states a formation's motion the way an operator thinks of it and
returns it in the chart every team description reads
(:class:`~quatform.formations.team_chart.TeamChart`: centroid, attitude quaternion, every
robot's position ``s_i`` in the formation frame, the robots' headings):

* the path of the formation's origin (:class:`OriginPath`): fixed, a line, seed 000 §4.1's
  rising spiral, or seed 001's lemniscate (Marciano 2021 eq. (5.4));
* the attitude (:class:`Attitude`): initial z-y-x Euler angles, then turns about world axes
  (:class:`Turn`, each at a constant rate like seed 000's ramps, or smooth);
* the shape: a template (:func:`template_positions`: line, ring, triangle, tetrahedron,
  grid, or explicit positions) about the origin, times a scale (:class:`Scale`: constant, a
  ramp, or breathing ``1 + a sin(2 pi t / T)``), with keyframed slot changes
  (:class:`Move`: one robot moving smoothly to a new slot);
* the headings (:class:`Headings`): the formation's heading (its initial yaw plus its turns
  about the vertical) plus offsets, the path's tangent plus offsets, or fixed.

The chart's centroid is the mean of the robots, so with the origin path ``o(t)``, the
attitude ``R(q)``, the scale ``sigma`` and the template ``T_i``: ``m = mean_i T_i``,
``s_i = sigma (T_i - m)``, ``x_c = o + R sigma m`` (``p_i = o + R sigma T_i``, seed 000
eqs. (16), (18) for N robots). Every rate is differentiated by hand (the tests compare them
with central differences); :class:`PlanMotion` turns a saved N-robot plan into the chart
(``TeamChart.from_robots``) with the rates of Horn's fit from first-order eigenvector
perturbation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..algebra import q_continuous
from ..errors import DegenerateInputError, InvalidInputError, ShapeError
from ..formations import geometry as g
from ..formations.layout import RobotLayout
from ..formations.team_chart import TeamChart, fit_attitude, horn_matrix

__all__ = ["OriginPath", "Turn", "Attitude", "Scale", "Move", "Headings", "TeamMotion", "PlanMotion",
           "template_positions", "TEMPLATES", "PATH_KINDS", "SCALE_KINDS", "HEADING_MODES", "PROFILES",
           "quaternion_of_euler", "smoothstep"]

#: Kinds of origin path.
PATH_KINDS = ("fixed", "line", "spiral", "lemniscate")
#: Named templates and the size key each reads (m).
TEMPLATES = {"line": "spacing", "ring": "radius", "triangle": "side", "tetrahedron": "edge", "grid": "spacing",
             "positions": None}
#: Kinds of scale.
SCALE_KINDS = ("constant", "ramp", "breathing")
#: Heading modes.
HEADING_MODES = ("formation", "path", "fixed")
#: Time profiles of a turn or a move.
PROFILES = ("linear", "smooth")


def _real(owner, **values):
    for key, v in values.items():
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)) \
                or not math.isfinite(v):
            raise InvalidInputError(f"{owner}: {key} must be a finite number, got {v!r}")


def _vec3(owner, key, v):
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{owner}: {key} must be 3 finite numbers, got {v!r}")
    return a


def smoothstep(x):
    """Quintic smoothstep ``10 x^3 - 15 x^4 + 6 x^5`` on ``[0, 1]`` (clipped) and its derivative
    ``30 x^2 (1 - x)^2``: zero rate and acceleration at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) ** 2


def _progress(t, start, duration, profile):
    """Fraction done in ``[0, 1]`` and its rate (1/s) of a change from ``start`` lasting ``duration``.

    ``linear``: constant rate inside ``[start, start + duration)`` (seed 000's ramps, as
    :class:`quatform.references.Ramp`); ``smooth``: :func:`smoothstep`."""
    x = (t - start) / duration
    if profile == "linear":
        inside = (t >= start) & (t < start + duration)
        return np.clip(x, 0.0, 1.0), np.where(inside, 1.0 / duration, 0.0)
    s, ds = smoothstep(x)
    return s, ds / duration


# --------------------------------------------------------------------------- path

@dataclass(frozen=True)
class OriginPath:
    """The path of the formation's origin (the template's ``(0, 0, 0)``), m.

    ``fixed``: ``center``; ``line``: ``center + velocity t``; ``spiral`` (seed 000 §4.1):
    ``center + radius (cos w t, sin w t, 0) + (0, 0, climb t)``, ``w = 2 pi / period_s``;
    ``lemniscate`` (Marciano 2021 eq. (5.4)): ``center + (r_x sin w t, r_y sin 2 w t, 0)``,
    ``w = omega``.
    """

    kind: str = "fixed"
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 0.0
    period_s: float = 1.0
    climb_m_s: float = 0.0
    r_x: float = 1.0
    r_y: float = 1.0
    omega: float = 0.1

    def __post_init__(self):
        if self.kind not in PATH_KINDS:
            raise InvalidInputError(f"path kind {self.kind!r} unknown; choose one of {', '.join(PATH_KINDS)}")
        object.__setattr__(self, "center", _vec3("path", "center", self.center))
        object.__setattr__(self, "velocity", _vec3("path", "velocity", self.velocity))
        _real("path", radius=self.radius, period_s=self.period_s, climb_m_s=self.climb_m_s, r_x=self.r_x,
              r_y=self.r_y, omega=self.omega)
        if self.kind == "spiral" and not (self.radius > 0 and self.period_s > 0):
            raise InvalidInputError(f"spiral path: radius and period_s must be > 0, got {self.radius!r}, "
                                    f"{self.period_s!r} (a fixed point: kind = 'fixed')")
        if self.kind == "lemniscate" and self.omega == 0:
            raise InvalidInputError("lemniscate path: omega must be nonzero (rad/s; the path would stand still)")

    @property
    def moves(self) -> bool:
        """Whether the origin moves at all (a ``path`` heading needs it to)."""
        return self.kind != "fixed" and not (self.kind == "line" and not np.any(self.velocity))

    def __call__(self, t):
        """Position, velocity and acceleration, each ``t.shape + (3,)``."""
        t = np.asarray(t, dtype=float)
        p = np.broadcast_to(self.center, t.shape + (3,)).copy()
        v = np.zeros(t.shape + (3,))
        a = np.zeros(t.shape + (3,))
        if self.kind == "line":
            p += t[..., None] * self.velocity
            v[...] = self.velocity
        elif self.kind == "spiral":  # seed 000 §4.1 (the circle of its two-robot files)
            w = 2.0 * np.pi / self.period_s
            c, s = np.cos(w * t), np.sin(w * t)
            p[..., 0] += self.radius * c
            p[..., 1] += self.radius * s
            p[..., 2] += self.climb_m_s * t
            v[..., 0], v[..., 1], v[..., 2] = -self.radius * w * s, self.radius * w * c, self.climb_m_s
            a[..., 0], a[..., 1] = -self.radius * w * w * c, -self.radius * w * w * s
        elif self.kind == "lemniscate":  # Marciano 2021 eqs. (5.4)-(5.5)
            w = self.omega
            p[..., 0] += self.r_x * np.sin(w * t)
            p[..., 1] += self.r_y * np.sin(2 * w * t)
            v[..., 0], v[..., 1] = w * self.r_x * np.cos(w * t), 2 * w * self.r_y * np.cos(2 * w * t)
            a[..., 0], a[..., 1] = -w * w * self.r_x * np.sin(w * t), -4 * w * w * self.r_y * np.sin(2 * w * t)
        return p, v, a


# --------------------------------------------------------------------------- attitude

def quaternion_of_euler(yaw, pitch, roll) -> np.ndarray:
    """The unit quaternion of z-y-x Euler angles (rad): ``q_z(yaw) q_y(pitch) q_x(roll)``
    (the inverse of :meth:`TeamChart.reading`), shape ``(4,)``."""
    qx = np.array([math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0])
    return g.mul(g.mul(g.q_yaw(yaw), g.q_pitch_y(pitch)), qx)


@dataclass(frozen=True)
class Turn:
    """A turn of the formation by ``angle`` (rad) about the world axis ``axis``, from
    ``start_s`` for ``duration_s`` (``profile``: ``linear``, a constant rate as seed 000's
    ramps, or ``smooth``)."""

    axis: np.ndarray
    angle: float
    start_s: float
    duration_s: float
    profile: str = "linear"

    def __post_init__(self):
        a = _vec3("turn", "axis", self.axis)
        n = float(np.linalg.norm(a))
        if not n > 0:
            raise InvalidInputError("turn: axis must be a nonzero vector (the world axis to turn about)")
        object.__setattr__(self, "axis", a / n)
        _real("turn", angle=self.angle, start_s=self.start_s, duration_s=self.duration_s)
        if not self.duration_s > 0:
            raise InvalidInputError(f"turn: duration_s must be > 0, got {self.duration_s!r}")
        if self.profile not in PROFILES:
            raise InvalidInputError(f"turn: profile {self.profile!r} unknown; choose one of {', '.join(PROFILES)}")

    def angle_rate(self, t):
        """Angle turned so far (rad) and its rate (rad/s), each ``t.shape``."""
        s, ds = _progress(t, self.start_s, self.duration_s, self.profile)
        return self.angle * s, self.angle * ds


@dataclass(frozen=True)
class Attitude:
    """Initial z-y-x Euler angles (rad) and turns about world axes, applied in order:
    ``q(t) = A_n(t) ... A_1(t) q_0`` with ``A_k = (cos a_k/2, sin a_k/2 u_k)``."""

    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    turns: tuple = ()

    def __post_init__(self):
        _real("attitude", yaw=self.yaw, pitch=self.pitch, roll=self.roll)
        object.__setattr__(self, "turns", tuple(self.turns))
        for tr in self.turns:
            if not isinstance(tr, Turn):
                raise InvalidInputError(f"attitude: turns must be Turn values, got {type(tr).__name__}")

    def __call__(self, t):
        """``q (t.shape + (4,))`` and ``q_dot``: ``q_dot = sum_k A_n .. A_k+1 (a_k'/2 u_k) A_k .. A_1 q_0``
        (``dA/dt = (a'/2) u A`` for a turn about a fixed axis ``u``)."""
        t = np.asarray(t, dtype=float)
        q = np.broadcast_to(quaternion_of_euler(self.yaw, self.pitch, self.roll), t.shape + (4,)).copy()
        qd = np.zeros(t.shape + (4,))
        for tr in self.turns:
            a, ad = tr.angle_rate(t)
            A = np.concatenate([np.cos(0.5 * a)[..., None], np.sin(0.5 * a)[..., None] * tr.axis], axis=-1)
            omega = np.concatenate([np.zeros(t.shape + (1,)), 0.5 * ad[..., None] * tr.axis], axis=-1)
            qd = g.mul(A, qd) + g.mul(omega, g.mul(A, q))  # product rule on A_k (A_k-1 .. q_0)
            q = g.mul(A, q)
        return q, qd

    def heading(self, t):
        """The formation's heading (rad) and its rate: the initial yaw plus the turns about the
        world vertical (axis ``(0, 0, +-1)``), smooth whatever the other turns do (the z-y-x yaw
        of ``q`` is undefined at pitch +-pi/2)."""
        t = np.asarray(t, dtype=float)
        h, hd = np.full(t.shape, float(self.yaw)), np.zeros(t.shape)
        for tr in self.turns:
            if abs(abs(tr.axis[2]) - 1.0) < 1e-12:
                a, ad = tr.angle_rate(t)
                h, hd = h + np.sign(tr.axis[2]) * a, hd + np.sign(tr.axis[2]) * ad
        return h, hd


# --------------------------------------------------------------------------- shape

def template_positions(name: str, n: int, size: float | None = None, rows: int | None = None,
                       positions=None) -> np.ndarray:
    """Robot positions of a named template in the formation frame, ``(n, 3)`` m, about the origin.

    ``line``: along x, ``spacing`` apart; ``ring``: the regular n-gon of ``radius`` in the
    x-y plane, robot 1 on +x (:func:`~quatform.formations.default_template` scaled);
    ``triangle``: 3 robots, equilateral of ``side``, robot 1 on +x; ``tetrahedron``: 4
    robots, regular of ``edge``, standing on a horizontal face (robots 1 and 2 on an edge
    along x, robot 1 on +x as seed 000's pair, robot 3 on +y) with robot 4 on top; ``grid``:
    ``rows`` x ``n / rows`` robots ``spacing`` apart in the x-y plane, row after row;
    ``positions``: the given ``(n, 3)`` positions.
    """
    if name not in TEMPLATES:
        from ..checks import nearest

        raise InvalidInputError(f"template {name!r} unknown{nearest(name, TEMPLATES)}; choose one of "
                                f"{', '.join(TEMPLATES)}")
    if name == "positions":
        p = np.asarray(positions, dtype=float)
        if p.shape != (n, 3):
            raise ShapeError(f"template positions must be {n} positions of 3 numbers (one per robot), got shape "
                             f"{p.shape}")
        if not np.all(np.isfinite(p)):
            raise InvalidInputError("template positions must be finite numbers (m)")
        return p
    size = 1.0 if size is None else float(size)
    if not (math.isfinite(size) and size > 0):
        raise InvalidInputError(f"template {name!r}: its {TEMPLATES[name]} must be > 0 m, got {size!r}")
    need = {"triangle": 3, "tetrahedron": 4}
    if name in need and n != need[name]:
        raise ShapeError(f"a {name} template holds {need[name]} robots, the team has {n}; use template = "
                         "'positions' or 'ring' for another number")
    if name == "line":
        return np.stack([(np.arange(n) - 0.5 * (n - 1)) * size, np.zeros(n), np.zeros(n)], axis=-1)
    if name in ("ring", "triangle"):
        radius = size if name == "ring" else size / math.sqrt(3.0)
        a = 2.0 * np.pi * np.arange(n) / n
        return np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)], axis=-1)
    if name == "tetrahedron":  # base triangle at -h/4 (edge 1-2 along x, robot 1 on +x), apex at 3h/4
        h = size * math.sqrt(2.0 / 3.0)
        r_in = size / (2.0 * math.sqrt(3.0))
        return np.array([[0.5 * size, -r_in, -0.25 * h], [-0.5 * size, -r_in, -0.25 * h], [0.0, 2.0 * r_in, -0.25 * h],
                         [0.0, 0.0, 0.75 * h]])
    rows = int(round(math.sqrt(n))) if rows is None else int(rows)
    if rows < 1 or n % rows:
        raise ShapeError(f"a grid of {n} robots in {rows} rows is not whole; give rows that divide {n}")
    cols = n // rows
    i, j = np.divmod(np.arange(n), cols)
    return np.stack([(j - 0.5 * (cols - 1)) * size, (i - 0.5 * (rows - 1)) * size, np.zeros(n)], axis=-1)


@dataclass(frozen=True)
class Scale:
    """The template's scale ``sigma(t)`` (1): ``constant`` ``value``; ``ramp`` from ``value`` to
    ``to`` between ``start_s`` and ``start_s + duration_s`` (``profile``); ``breathing``
    ``value (1 + amplitude sin(2 pi (t - start_s) / period_s))``."""

    kind: str = "constant"
    value: float = 1.0
    to: float = 1.0
    start_s: float = 0.0
    duration_s: float = 1.0
    amplitude: float = 0.0
    period_s: float = 1.0
    profile: str = "linear"

    def __post_init__(self):
        if self.kind not in SCALE_KINDS:
            raise InvalidInputError(f"scale kind {self.kind!r} unknown; choose one of {', '.join(SCALE_KINDS)}")
        _real("scale", value=self.value, to=self.to, start_s=self.start_s, duration_s=self.duration_s,
              amplitude=self.amplitude, period_s=self.period_s)
        if self.profile not in PROFILES:
            raise InvalidInputError(f"scale: profile {self.profile!r} unknown; choose one of {', '.join(PROFILES)}")
        for key in ("value", "duration_s", "period_s"):
            if not getattr(self, key) > 0:
                raise InvalidInputError(f"scale: {key} must be > 0, got {getattr(self, key)!r}")
        if self.kind == "ramp" and not self.to > 0:
            raise InvalidInputError(f"scale: to = {self.to!r} must be > 0 (a scale of 0 puts every robot on "
                                    "the origin)")
        if self.kind == "breathing" and not 0 <= self.amplitude < 1:
            raise InvalidInputError(f"scale: amplitude = {self.amplitude!r} must be in [0, 1) (at 1 the "
                                    "formation shrinks to a point)")

    def __call__(self, t):
        """``sigma`` and ``sigma_dot`` (1/s), each ``t.shape``."""
        t = np.asarray(t, dtype=float)
        if self.kind == "constant":
            return np.full(t.shape, self.value), np.zeros(t.shape)
        if self.kind == "ramp":
            s, ds = _progress(t, self.start_s, self.duration_s, self.profile)
            return self.value + (self.to - self.value) * s, (self.to - self.value) * ds
        w = 2.0 * np.pi / self.period_s
        ph = w * (t - self.start_s)
        return self.value * (1.0 + self.amplitude * np.sin(ph)), self.value * self.amplitude * w * np.cos(ph)


@dataclass(frozen=True)
class Move:
    """Robot ``robot`` (0-based) moves in the formation frame from its slot to ``to`` (m, template
    units, before the scale) between ``start_s`` and ``start_s + duration_s`` (``smooth`` by
    default: it starts and stops at rest)."""

    robot: int
    to: np.ndarray
    start_s: float
    duration_s: float
    profile: str = "smooth"

    def __post_init__(self):
        if isinstance(self.robot, bool) or not isinstance(self.robot, (int, np.integer)) or self.robot < 0:
            raise InvalidInputError(f"move: robot must be a robot index >= 0, got {self.robot!r}")
        object.__setattr__(self, "to", _vec3("move", "to", self.to))
        _real("move", start_s=self.start_s, duration_s=self.duration_s)
        if not self.duration_s > 0:
            raise InvalidInputError(f"move: duration_s must be > 0, got {self.duration_s!r}")
        if self.profile not in PROFILES:
            raise InvalidInputError(f"move: profile {self.profile!r} unknown; choose one of {', '.join(PROFILES)}")


@dataclass(frozen=True)
class Headings:
    """The robots' headings: ``formation`` (the formation's heading, :meth:`Attitude.heading`,
    plus ``offsets``), ``path`` (the origin path's tangent ``atan2(y', x')`` plus ``offsets``)
    or ``fixed`` (``offsets`` as world yaws). ``offsets``: rad, one per robot (or one for all).
    A ``pose`` robot's orientation is the formation's attitude (``formation``), or the yaw
    quaternion of its heading (``path``, ``fixed``)."""

    mode: str = "formation"
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(1))

    def __post_init__(self):
        if self.mode not in HEADING_MODES:
            raise InvalidInputError(f"headings mode {self.mode!r} unknown; choose one of {', '.join(HEADING_MODES)}")
        o = np.atleast_1d(np.asarray(self.offsets, dtype=float))
        if o.ndim != 1 or not np.all(np.isfinite(o)):
            raise InvalidInputError(f"headings offsets must be finite numbers (rad), got {self.offsets!r}")
        object.__setattr__(self, "offsets", o)


# --------------------------------------------------------------------------- the motion

@dataclass(frozen=True, eq=False)
class TeamMotion:
    """A formation motion of the robots laid out by ``layout`` (module docstring).

    Parameters
    ----------
    layout : RobotLayout
    template : array_like, shape (N, 3)
        Robot slots in the formation frame about its origin, m (:func:`template_positions`).
    path : OriginPath
    attitude : Attitude
    scale : Scale
    moves : tuple of Move
    headings : Headings

    Calling it at times ``t`` (shape ``(T,)`` or scalar) gives ``(e, e_dot)``, each
    ``t.shape + (chart.size,)``, in :attr:`chart`'s layout, time axis first.

    Raises
    ------
    ShapeError
        A template of the wrong size, offsets of the wrong length.
    DegenerateInputError
        Two robots of the template (or of a move) on each other.
    """

    layout: RobotLayout
    template: np.ndarray
    path: OriginPath = field(default_factory=OriginPath)
    attitude: Attitude = field(default_factory=Attitude)
    scale: Scale = field(default_factory=Scale)
    moves: tuple = ()
    headings: Headings = field(default_factory=Headings)

    def __post_init__(self):
        if not isinstance(self.layout, RobotLayout):
            raise InvalidInputError(f"TeamMotion: layout must be a RobotLayout, got {type(self.layout).__name__}")
        n = self.layout.n
        t = np.asarray(self.template, dtype=float)
        if t.shape != (n, 3):
            raise ShapeError(f"TeamMotion: the template has shape {t.shape} for a team of {n} robots; give {n} "
                             "positions of 3 numbers (m)")
        if not np.all(np.isfinite(t)):
            raise InvalidInputError("TeamMotion: the template has NaN or infinite entries; give finite positions (m)")
        t = t.copy()
        t.setflags(write=False)
        object.__setattr__(self, "template", t)
        object.__setattr__(self, "moves", tuple(self.moves))
        for mv in self.moves:
            if not isinstance(mv, Move):
                raise InvalidInputError(f"TeamMotion: moves must be Move values, got {type(mv).__name__}")
            if mv.robot >= n:
                raise InvalidInputError(f"TeamMotion: a move names robot {mv.robot + 1}, the team has {n} robots")
        off = self.headings.offsets
        if off.size not in (1, n):
            raise ShapeError(f"TeamMotion: {off.size} heading offsets for {n} robots; give one or {n}")
        if self.headings.mode == "path" and not self.path.moves:
            raise InvalidInputError("TeamMotion: headings mode 'path' follows the path's tangent, but the path "
                                    "does not move; use mode 'formation' or 'fixed'")
        self._check_apart()

    @property
    def chart(self) -> TeamChart:
        return TeamChart(self.layout)

    def _check_apart(self) -> None:
        """Refuse a template whose robots coincide, at the start and at the end of every move
        and on the way (each moved robot against the others, sampled every 1/64 of the move)."""
        times = [0.0]
        for mv in self.moves:
            times += list(mv.start_s + mv.duration_s * np.linspace(0.0, 1.0, 65))
        T, _ = self.template_at(np.asarray(times))
        n = self.layout.n
        i, j = np.triu_indices(n, 1)
        for k in range(len(times)):
            d = np.linalg.norm(T[k, i] - T[k, j], axis=-1)
            if d.size and d.min() < 1e-6:
                a = int(np.argmin(d))
                when = "in the template" if k == 0 else f"at t = {times[k]:g} s (during a move)"
                raise DegenerateInputError(
                    f"TeamMotion: robots {i[a] + 1} and {j[a] + 1} coincide {when} (separation {d[a]:.3g} m); give "
                    "every robot its own slot")

    def template_at(self, t):
        """The slots with the moves applied, ``T (t.shape + (N, 3))`` and their rate."""
        t = np.asarray(t, dtype=float)
        T = np.broadcast_to(self.template, t.shape + self.template.shape).copy()
        Td = np.zeros_like(T)
        for mv in self.moves:  # each move from where the earlier ones left the robot
            s, ds = _progress(t, mv.start_s, mv.duration_s, mv.profile)
            frm = self._slot_before(mv)
            T[..., mv.robot, :] = np.where((t >= mv.start_s)[..., None], frm + (mv.to - frm) * s[..., None],
                                           T[..., mv.robot, :])
            Td[..., mv.robot, :] = Td[..., mv.robot, :] + (mv.to - frm) * ds[..., None]
        return T, Td

    def _slot_before(self, mv) -> np.ndarray:
        """Where robot ``mv.robot`` is when the move ``mv`` starts (after the moves listed before it)."""
        slot = self.template[mv.robot]
        for other in self.moves:
            if other is mv:
                break
            if other.robot == mv.robot:
                slot = other.to
        return np.asarray(slot, dtype=float)

    def __call__(self, t):
        """``(e, e_dot)`` at times ``t`` (module docstring), analytic rates."""
        t = np.asarray(t, dtype=float)
        L = self.layout
        chart = self.chart
        o, od, oa = self.path(t)
        q, qd = self.attitude(t)
        sig, sigd = self.scale(t)
        T, Td = self.template_at(t)
        m, md = T.mean(axis=-2), Td.mean(axis=-2)
        s = sig[..., None, None] * (T - m[..., None, :])
        sd = sigd[..., None, None] * (T - m[..., None, :]) + sig[..., None, None] * (Td - md[..., None, :])
        w = 2.0 * g.mul(qd, g.conj(q))[..., 1:]  # world angular velocity
        Rm = g.rotate(q, sig[..., None] * m)
        xc = o + Rm
        xcd = od + np.cross(w, Rm) + g.rotate(q, sigd[..., None] * m + sig[..., None] * md)
        e = np.zeros(t.shape + (chart.size,))
        ed = np.zeros_like(e)
        e[..., 0:3], ed[..., 0:3] = xc, xcd
        e[..., 3:7], ed[..., 3:7] = q, qd
        e[..., chart.shape_index], ed[..., chart.shape_index] = s, sd
        ny, nq = len(chart.yaw_index), len(chart.orientation_index)
        if ny or nq:
            off = np.broadcast_to(self.headings.offsets, (L.n,))
            mode = self.headings.mode
            if mode == "formation":
                h, hd = self.attitude.heading(t)
            elif mode == "path":  # the tangent's angle, unwrapped along the samples; d atan2(y', x') / dt
                h = np.arctan2(od[..., 1], od[..., 0])
                if h.ndim:
                    h = np.unwrap(h)
                hd = (od[..., 0] * oa[..., 1] - od[..., 1] * oa[..., 0]) / (od[..., 0] ** 2 + od[..., 1] ** 2)
            else:
                h, hd = np.zeros(t.shape), np.zeros(t.shape)
            yaw_robots = [i for i, k in enumerate(L.kinds) if k in ("xy_yaw", "xyz_yaw")]
            pose_robots = [i for i, k in enumerate(L.kinds) if k == "pose"]
            if ny:
                e[..., chart.yaw_index] = h[..., None] + off[yaw_robots]
                ed[..., chart.yaw_index] = np.broadcast_to(hd[..., None], t.shape + (ny,))
            if nq:
                if mode == "formation":  # the body turns with the formation
                    qi, qid = q[..., None, :], qd[..., None, :]
                    qi = np.broadcast_to(qi, t.shape + (nq, 4))
                    qid = np.broadcast_to(qid, t.shape + (nq, 4))
                else:
                    ang = h[..., None] + off[pose_robots]
                    qi = g.q_yaw(ang)
                    qid = np.zeros(qi.shape)
                    qid[..., 0] = -0.5 * np.sin(0.5 * ang) * hd[..., None]
                    qid[..., 3] = 0.5 * np.cos(0.5 * ang) * hd[..., None]
                e[..., chart.orientation_index] = qi
                ed[..., chart.orientation_index] = qid
        return e, ed


# --------------------------------------------------------------------------- plans

@dataclass(frozen=True, eq=False)
class PlanMotion:
    """A saved N-robot plan (:class:`quatform.planning.Plan`) as a team motion in the chart.

    The plan's positions (a planar plan at height ``altitude_m``) are the robots'; the chart
    is :meth:`TeamChart.from_robots` with the plan's first shape as the template (the
    attitude starts at the identity), the quaternion kept on one sign along the samples; the
    headings are ``headings`` (rad, fixed; one or one per robot). The plan's time runs
    ``time_scale`` times slower (its rates divided by it). Rates: ``x_c' = mean v_i``; the
    attitude's by first-order perturbation of Horn's top eigenvector (Horn 1987 eq. (35)):
    ``q' = sum_k (v_k . N' q) / (lambda_top - lambda_k) v_k`` with ``N'`` Horn's matrix of
    the template and the centred velocities; ``s_i' = R^T (v_i - x_c') - R^T (w x R s_i)``.
    """

    layout: RobotLayout
    plan: object
    altitude_m: float = 0.0
    time_scale: float = 1.0
    headings: np.ndarray = field(default_factory=lambda: np.zeros(1))

    def __post_init__(self):
        from ..planning import Plan

        if not isinstance(self.plan, Plan):
            raise InvalidInputError(f"PlanMotion: plan must be a quatform Plan, got {type(self.plan).__name__}")
        if self.plan.n_robots != self.layout.n:
            raise ShapeError(f"the plan moves {self.plan.n_robots} robots, the scenario's team has {self.layout.n}; "
                             "plan for the team's robots or use a scenario with as many")
        _real("plan motion", altitude_m=self.altitude_m, time_scale=self.time_scale)
        if not self.time_scale > 0:
            raise InvalidInputError(f"plan motion: time_scale must be > 0, got {self.time_scale!r}")
        h = np.atleast_1d(np.asarray(self.headings, dtype=float))
        if h.size not in (1, self.layout.n) or not np.all(np.isfinite(h)):
            raise ShapeError(f"plan motion: give one heading or {self.layout.n}, finite (rad); got {self.headings!r}")
        object.__setattr__(self, "headings", h)

    @property
    def duration_s(self) -> float:
        return self.plan.duration_s * self.time_scale

    def positions(self, t):
        """Robot positions and velocities (``t.shape + (N, 3)``) at run times ``t``."""
        tau = self.plan.times[0] + np.asarray(t, dtype=float) / self.time_scale
        p, v, _ = self.plan.sample(tau)
        v = v / self.time_scale
        if p.shape[-1] == 2:
            p = np.concatenate([p, np.full(p.shape[:-1] + (1,), float(self.altitude_m))], axis=-1)
            v = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)
        return p, v

    @property
    def template(self) -> np.ndarray:
        p, _ = self.positions(np.zeros(1))
        return p[0] - p[0].mean(axis=0)

    def __call__(self, t):
        """``(e, e_dot)`` at the run times ``t`` (a sequence, shape ``(T,)``: the attitude's sign
        is kept continuous along it), each ``(T, chart.size)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        chart = TeamChart(self.layout)
        L = self.layout
        p, v = self.positions(t)
        tmpl = self.template
        xc, xcd = p.mean(axis=-2), v.mean(axis=-2)
        cen, cend = p - xc[..., None, :], v - xcd[..., None, :]
        q = q_continuous(fit_attitude(tmpl, cen), axis=0)  # one sign along the samples
        lam, V = np.linalg.eigh(horn_matrix(tmpl, cen))
        Nd = horn_matrix(tmpl, cend)
        gap = lam[..., -1:] - lam[..., :-1]
        proj = np.einsum("tik,tij,tj->tk", V[..., :, :-1], Nd, q)
        with np.errstate(divide="ignore", invalid="ignore"):
            coef = np.where(gap > 1e-12 * np.abs(lam[..., -1:]), proj / gap, 0.0)
        qd = np.einsum("tik,tk->ti", V[..., :, :-1], coef)
        w = 2.0 * g.mul(qd, g.conj(q))[..., 1:]
        s = g.rotate(g.conj(q)[..., None, :], cen)
        sd = g.rotate(g.conj(q)[..., None, :], cend - np.cross(w[..., None, :], cen))
        e = np.zeros(t.shape + (chart.size,))
        ed = np.zeros_like(e)
        e[..., 0:3], ed[..., 0:3] = xc, xcd
        e[..., 3:7], ed[..., 3:7] = q, qd
        e[..., chart.shape_index], ed[..., chart.shape_index] = s, sd
        hy = np.broadcast_to(self.headings, (L.n,))
        yaw_robots = [i for i, k in enumerate(L.kinds) if k in ("xy_yaw", "xyz_yaw")]
        if len(chart.yaw_index):
            e[..., chart.yaw_index] = hy[yaw_robots]
        if len(chart.orientation_index):
            pose_robots = [i for i, k in enumerate(L.kinds) if k == "pose"]
            e[..., chart.orientation_index] = g.q_yaw(np.broadcast_to(hy[pose_robots], t.shape + (len(pose_robots),)))
        return e, ed
