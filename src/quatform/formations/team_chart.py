"""The team chart: the operator's variables of a formation of N robots (formations layer).

Every team description (quaternion, dual-quaternion, Euclidean, robot space) states and
reports its formation in one chart, the variables a user sets in a scenario file:

* the centroid ``x_c`` (m), seed 000 eq. (9) for N robots (§5: "x_c can still be the centroid");
* the formation's attitude ``q_c``, a unit quaternion;
* the shape: every robot's position ``s_i`` in the formation frame (m), ``p_i = x_c +
  R(q_c) s_i`` (seed 000 eqs. (16), (18) for N robots), ``sum_i s_i = 0``;
* each robot's heading: its world yaw ``theta_i`` (rad, a real number: it may be wound by
  turns) for ``xy_yaw`` and ``xyz_yaw`` robots, its world orientation ``q_i`` for ``pose``
  robots, nothing for ``xyz`` robots.

From robots, the attitude is the rotation that best maps a template shape onto the
centred robots (:func:`fit_attitude`, Horn 1987): for a rigid template at the robots it is
exact, for two robots it is seed 000's frame (eqs. (14)-(15), the minimal rotation from
the hint's x axis), and in between it is the attitude of the best-fitting rigid copy of the
template. The chart's own Euler angles (:meth:`TeamChart.reading`) are for reading only.

:class:`LawGroup` is how a description tells a controller which of its variables form a
block of one law (a centroid, a shape, a quaternion, a dual quaternion); :data:`ROLE_WIDTHS`
lists the roles.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace, qmul_components, small_matmul
from ..algebra.validate import as_array
from ..errors import InvalidInputError, ShapeError
from . import geometry as g
from .layout import POINT_KINDS, RobotLayout, Variable

__all__ = ["TeamChart", "LawGroup", "ROLE_WIDTHS", "fit_attitude", "default_template", "check_template",
           "horn_matrix", "team_compose", "team_positions", "team_layout", "pair_chart", "TIE", "TIE_DECAY",
           "CENTROID", "ATTITUDE"]

#: Width of each block role (the last axis of :attr:`LawGroup.index`); ``control.team`` maps
#: a role to its law and gain key.
ROLE_WIDTHS = {"centroid": 3, "shape": 3, "separation": 1, "attitude": 4, "orientation": 4, "pose": 8,
               "relative-pose": 8, "position": 3, "planar": 2, "heading": 1, "variables": 1}

#: Eigenvalue gaps (relative to the fit's size) at which two attitudes fit equally: the weight
#: of an eigenvector is exactly 1 for a gap ``lambda_top - lambda_k`` up to ``TIE * size``
#: (rounding: an exact tie computes as a gap of about 1e-16), then ``exp(-(gap - TIE size)
#: / (TIE_DECAY size))``, continuous, and exactly 0 past about ``7.5e-7 size``.
TIE = 1e-10
TIE_DECAY = 1e-9

#: The pose entries that open every team chart (:attr:`TeamChart.variables`): the centroid
#: ``x_c`` (m) and the attitude ``q_c``; the shape ``s_1 .. s_N`` and the headings follow.
CENTROID, ATTITUDE = slice(0, 3), slice(3, 7)


@dataclass(frozen=True, eq=False)
class LawGroup:
    """A block of a description's variables that one law acts on.

    Attributes
    ----------
    role : str
        A :data:`ROLE_WIDTHS` key (``centroid``, ``shape``, ``separation`` (seed 000's ``d_c``),
        ``attitude``, ``orientation``,
        ``pose``, ``relative-pose``, ``position``, ``planar`` (a ground robot's x, y),
        ``heading``, ``variables``).
    index : ndarray of int, shape (M, k)
        The variables of each of the M rows (``k = ROLE_WIDTHS[role]``).
    """

    role: str
    index: np.ndarray

    def __post_init__(self):
        if self.role not in ROLE_WIDTHS:
            raise InvalidInputError(f"law group role {self.role!r} unknown; choose one of {', '.join(ROLE_WIDTHS)}")
        idx = np.asarray(self.index, dtype=np.intp)
        if idx.ndim != 2 or idx.shape[1] != ROLE_WIDTHS[self.role]:
            raise ShapeError(f"a {self.role} law group needs an index of shape (M, {ROLE_WIDTHS[self.role]}), "
                             f"got {idx.shape}")
        idx.setflags(write=False)
        object.__setattr__(self, "index", idx)


def team_layout(n=None, layout=None, owner: str = "team") -> RobotLayout:
    """The layout of a team description: ``n`` 4-DOF robots or ``layout``, exactly one of them."""
    if (n is None) == (layout is None):
        raise InvalidInputError(f"{owner}: give the number of robots n (4-DOF robots) or a RobotLayout, "
                                f"exactly one of them; got n={n!r}, layout={layout!r}")
    if layout is None:
        if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 2:
            raise InvalidInputError(f"{owner}: a formation needs a whole number of robots n >= 2, got {n!r}")
        return RobotLayout.uniform("xyz_yaw", int(n))
    if not isinstance(layout, RobotLayout):
        raise InvalidInputError(f"{owner}: layout must be a RobotLayout, got {type(layout).__name__}")
    if layout.n < 2:
        raise InvalidInputError(f"{owner}: a formation needs at least 2 robots, the layout has {layout.n}")
    return layout


def pair_chart(chart, layout: RobotLayout, owner: str) -> bool:
    """Whether a description's ``chart`` (``"team"`` or ``"pair"``) is seed 000's Euclidean
    variables (``"pair"``, for two ``xyz_yaw`` robots only) rather than the team chart."""
    if chart not in ("team", "pair"):
        raise InvalidInputError(f"{owner}: chart must be 'team' or 'pair', got {chart!r}")
    if chart == "pair" and layout.kinds != ("xyz_yaw", "xyz_yaw"):
        raise InvalidInputError(f"{owner}: chart='pair' (seed 000's variables) needs two xyz_yaw robots, the layout "
                                f"has {layout.kinds}; use chart='team'")
    return chart == "pair"


def default_template(layout: RobotLayout) -> np.ndarray:
    """The shape a description fits its attitude to when nothing else is given, ``(N, 3)`` m.

    Two robots: ``(+-0.5, 0, 0)``, seed 000's pair along its x axis (robot 1 on +x, eq. (16));
    more: the regular N-gon of radius 1 in the formation's x-y plane, robot 1 on +x.
    """
    n = layout.n
    if n == 1:
        return np.zeros((1, 3))
    if n == 2:
        return np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    a = 2.0 * np.pi * np.arange(n) / n
    return np.stack([np.cos(a), np.sin(a), np.zeros(n)], axis=-1)


def check_template(template, n: int, name: str = "template", min_separation: float = 1e-9) -> np.ndarray:
    """A finite ``(..., n, 3)`` shape whose robots are apart, centred on its centroid.

    Raises
    ------
    ShapeError
        Wrong shape (naming the expected one).
    InvalidInputError
        Non-finite entries.
    DegenerateInputError
        Two robots of the template closer than ``min_separation`` (m).
    """
    from ..errors import DegenerateInputError

    t = np.asarray(template, dtype=float) if not isinstance(template, np.ndarray) else template.astype(float)
    if t.ndim < 2 or t.shape[-2:] != (n, 3):
        raise ShapeError(f"{name} must have shape (..., {n}, 3) (one position per robot), got {t.shape}; "
                         f"give {n} positions in the formation frame")
    if not np.all(np.isfinite(t)):
        raise InvalidInputError(f"{name} has NaN or infinite entries; give finite positions (m)")
    if n > 1:
        i, j = np.triu_indices(n, 1)
        d = np.linalg.norm(t[..., i, :] - t[..., j, :], axis=-1)
        if np.any(d < min_separation):
            k = int(np.argmin(np.min(d.reshape(-1, d.shape[-1]), axis=0)))
            raise DegenerateInputError(
                f"{name} puts robots {i[k] + 1} and {j[k] + 1} on each other (separation {float(np.min(d)):.3g} m); "
                "give every robot its own position")
    return t - t.mean(axis=-2, keepdims=True)


def horn_matrix(template, centred) -> np.ndarray:
    """Horn's 4 x 4 matrix of the fit of ``template`` onto ``centred`` (both ``(..., N, 3)``).

    Horn 1987 ("Closed-form solution of absolute orientation using unit quaternions",
    J. Opt. Soc. Am. A 4(4)) eq. (35) with ``S_ab = sum_i t_i,a c_i,b``: ``q^T N q =
    sum_i c_i . R(q) t_i`` for every unit ``q``, so the top eigenvector is the best
    rotation. ``N``'s 16 entries are sums of ``S``'s (eq. (35) written out), ``S`` a product
    of the robots' rows (:func:`~quatform.algebra.kernels.small_matmul`). Shape ``(..., 4, 4)``;
    O(N).
    """
    xp = array_namespace(centred)
    S = small_matmul(xp.swapaxes(xp.asarray(template), -1, -2), centred)
    xx, xy, xz, yx, yy, yz, zx, zy, zz = (S[..., a, b] for a in range(3) for b in range(3))
    rows = ((xx + yy + zz, yz - zy, zx - xz, xy - yx),
            (yz - zy, xx - yy - zz, xy + yx, zx + xz),
            (zx - xz, xy + yx, yy - xx - zz, yz + zy),
            (xy - yx, zx + xz, yz + zy, zz - xx - yy))
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def _project(V, w, v):
    """``V diag(w) V^T v`` of eigenvectors ``V`` (``(..., 4, 4)``, columns), weights ``w`` and
    ``v`` (``(..., 4)``), as products' sums (:func:`~quatform.algebra.kernels.small_matmul`)."""
    c = small_matmul(v[..., None, :], V)[..., 0, :]  # V^T v
    return small_matmul(V, (w * c)[..., :, None])[..., 0]


_HALF_TURNS = (np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0, 0.0]), np.array([0.0, 1.0, 0.0, 0.0]))


def fit_attitude(template, centred, hint=None) -> np.ndarray:
    """The attitude ``q`` that best maps ``template`` onto ``centred``: ``max sum c_i . R(q) t_i``.

    Horn 1987: the top eigenvector of :func:`horn_matrix`. Where several attitudes fit
    equally (a collinear template or robots: the twist about the line; two attitudes of
    one fit) the hint decides: ``q`` is the hint's projection onto the top eigenspace,
    each eigenvector weighted by a continuous function of its gap to the top eigenvalue
    (1 at a tie, 0 past a gap of 7.5e-7 of the fit's size: a matrix function of Horn's
    matrix, so ``q`` is continuous in the robots wherever the projection is not zero), i.e.
    the attitude of the fit nearest the hint. For two robots that is the minimal rotation
    taking the hint's x axis to the segment, seed 000 eqs. (14)-(15) with the twist from
    the hint. Where the hint is a half turn from every best fit (the projection vanishes:
    a formation error of pi) the hint turned half a turn about its z axis (then y, x) is
    projected instead, seed 000's pair rule (``docs/derivations.md``).

    Parameters
    ----------
    template, centred : array_like, shape (..., N, 3)
        Positions in the formation frame and measured positions minus their centroid (m).
    hint : array_like, shape (..., 4), optional
        Unit quaternion; default the identity.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternion, sign nearest the hint.
    """
    xp = array_namespace(centred)
    if xp is not np:  # another namespace (JAX, traced): the same formulas, branches selected
        return _fit_attitude_xp(xp, template, centred, hint)
    Nm = horn_matrix(template, centred)
    lam, V = np.linalg.eigh(Nm)
    t, c = np.asarray(template, dtype=float), np.asarray(centred, dtype=float)
    scale = np.sqrt(np.einsum("...ij,...ij->...", t, t) * np.einsum("...ij,...ij->...", c, c))
    tie, tau = (TIE * scale)[..., None], (TIE_DECAY * scale + 1e-300)[..., None]
    arg = -np.maximum(lam[..., -1:] - lam - tie, 0.0) / tau
    w = np.where(arg < -700.0, 0.0, np.exp(np.maximum(arg, -700.0)))  # (..., 4): 1 for the top, 0 past a gap
    h = np.broadcast_to(np.array([1.0, 0.0, 0.0, 0.0]) if hint is None else np.asarray(hint, dtype=float),
                        lam.shape)
    q = _project(V, w, h)
    n = np.sqrt(np.einsum("...i,...i->...", q, q))
    for turn in _HALF_TURNS:  # the hint a half turn from every fit: seed 000's pair rule
        if not n.min() < 1e-9:
            break
        bad = n < 1e-9
        alt = _project(V, w, g.mul(h, turn))
        an = np.linalg.norm(alt, axis=-1)
        q = np.where(bad[..., None], alt, q)
        n = np.where(bad, an, n)
    bad = n < 1e-9
    if bad.any():  # no hint breaks the tie: the top eigenvector, its first nonzero entry positive
        top = V[..., :, -1]
        top = top * np.where(top[..., :1] < 0.0, -1.0, 1.0)
        q = np.where(bad[..., None], top, q)
        n = np.where(bad, 1.0, n)
    return q / n[..., None]


def _mul_xp(xp, q, p):
    """Hamilton product of broadcast ``(..., 4)`` arrays of the namespace ``xp``
    (:func:`~quatform.algebra.kernels.qmul_components`, as :func:`.geometry.mul`)."""
    q, p = xp.asarray(q), xp.asarray(p)
    return xp.stack(xp.broadcast_arrays(*qmul_components(*(q[..., k] for k in range(4)),
                                                          *(p[..., k] for k in range(4)))), axis=-1)


def _fit_attitude_xp(xp, template, centred, hint):
    """:func:`fit_attitude` on an array namespace whose values cannot be read (JAX under
    ``jax.jit``): every half-turn alternative and the top-eigenvector fallback computed and
    selected where the projection vanishes (``docs/derivations.md``, "The team kind
    on JAX"). ``V w V^T h`` does not depend on the eigenvectors' signs, so another ``eigh``
    gives the same ``q`` up to rounding."""
    Nm = horn_matrix(template, centred)
    lam, V = xp.linalg.eigh(Nm)
    t = xp.asarray(template)
    scale = xp.sqrt(xp.sum(t * t, axis=(-2, -1)) * xp.sum(centred * centred, axis=(-2, -1)))
    tie, tau = (TIE * scale)[..., None], (TIE_DECAY * scale + 1e-300)[..., None]
    arg = -xp.maximum(lam[..., -1:] - lam - tie, 0.0) / tau
    w = xp.where(arg < -700.0, 0.0, xp.exp(xp.maximum(arg, -700.0)))
    h = xp.broadcast_to(xp.asarray([1.0, 0.0, 0.0, 0.0]) if hint is None else xp.asarray(hint), lam.shape)
    q = _project(V, w, h)
    n = xp.sqrt(xp.sum(q * q, axis=-1))
    for turn in _HALF_TURNS:  # the loop of fit_attitude with every step taken: where no entry is bad it changes nothing
        bad = n < 1e-9
        alt = _project(V, w, _mul_xp(xp, h, turn))
        an = xp.sqrt(xp.sum(alt * alt, axis=-1))
        q = xp.where(bad[..., None], alt, q)
        n = xp.where(bad, an, n)
    bad = n < 1e-9
    top = V[..., :, -1]
    top = top * xp.where(top[..., :1] < 0.0, -1.0, 1.0)
    q = xp.where(bad[..., None], top, q)
    n = xp.where(bad, 1.0, n)
    return q / n[..., None]


@dataclass(frozen=True)
class TeamChart:
    """The chart of a team of robots laid out by ``layout`` (module docstring).

    Parameters
    ----------
    layout : RobotLayout
    """

    layout: RobotLayout

    # -- layout of the chart ------------------------------------------------------------
    @functools.cached_property
    def variables(self) -> tuple[Variable, ...]:
        L = self.layout
        out = [Variable(f"{a}_c", "m", "position") for a in "xyz"]
        out += [Variable(f"q_c_{a}", "1", "quaternion") for a in "wxyz"]
        out += [Variable(f"s{lab}_{a}", "m", "position") for lab in L.labels for a in "xyz"]
        for lab, k in zip(L.labels, L.kinds):
            if POINT_KINDS[k].yaw is not None:
                out.append(Variable(f"theta{lab}", "rad", "angle"))
            elif k == "pose":
                out += [Variable(f"q{lab}_{a}", "1", "quaternion") for a in "wxyz"]
        return tuple(out)

    @property
    def size(self) -> int:
        return len(self.variables)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables)

    @functools.cached_property
    def shape_index(self) -> np.ndarray:
        """Indices of ``s_1 .. s_N`` in the chart, ``(N, 3)``."""
        return ATTITUDE.stop + np.arange(3 * self.layout.n).reshape(self.layout.n, 3)

    @functools.cached_property
    def _headings(self):
        """(chart yaw indices, robot yaw indices, chart quaternion rows, robot quaternion rows)."""
        L = self.layout
        i = ATTITUDE.stop + 3 * L.n
        ey, eq = [], []
        for k in L.kinds:
            if POINT_KINDS[k].yaw is not None:
                ey.append(i)
                i += 1
            elif k == "pose":
                eq.append(range(i, i + 4))
                i += 4
        return (np.array(ey, dtype=np.intp), np.array(L.yaw_indices, dtype=np.intp),
                np.array(eq, dtype=np.intp).reshape(-1, 4), L.orientation_index)

    @property
    def yaw_index(self) -> np.ndarray:
        """Chart indices of the robots' yaws (``theta_i``), in robot order."""
        return self._headings[0]

    @property
    def orientation_index(self) -> np.ndarray:
        """Chart indices of the ``pose`` robots' quaternions, ``(M, 4)``."""
        return self._headings[2]

    def check(self, e, name: str = "e") -> np.ndarray:
        return as_array(e, name, self.size)

    # -- chart -> robots ----------------------------------------------------------------
    def parts(self, e):
        """``(x_c (..., 3), q_c (..., 4) normalised, s (..., N, 3))`` of chart values ``e``."""
        q = e[..., ATTITUDE]
        return e[..., CENTROID], q / np.linalg.norm(q, axis=-1, keepdims=True), e[..., self.shape_index]

    def robots(self, e) -> np.ndarray:
        """The robot state of chart values ``e``: ``p_i = x_c + R(q_c) s_i`` and the headings.

        Parameters
        ----------
        e : array_like, shape (..., size)

        Returns
        -------
        ndarray, shape (..., layout.size)
        """
        e = self.check(e)
        xc, q, s = self.parts(e)
        p = xc[..., None, :] + g.rotate(q[..., None, :], s)
        return self._compose(p, e)

    def _compose(self, p, e):
        L = self.layout
        ey, ry, eq, rq = self._headings
        r = np.zeros(e.shape[:-1] + (L.size,))
        flat = L.position_index.ravel()
        keep = flat < L.size  # a planar robot's z is dropped
        r[..., flat[keep]] = p.reshape(p.shape[:-2] + (3 * L.n,))[..., keep]
        r[..., ry] = e[..., ey]
        if len(eq):
            r[..., rq] = e[..., eq]
        return r

    def robot_rates(self, e, e_dot) -> np.ndarray:
        """``d robots(e) / dt`` along ``e_dot``: ``p_i' = x_c' + w x R s_i + R s_i'`` with ``w = 2
        (q_c' q_c*)_vec`` (the part of ``q_c'`` along ``q_c`` changes no rotation), the
        headings' rates as given. Shape ``(..., layout.size)``."""
        e = self.check(e)
        ed = as_array(e_dot, "e_dot", self.size)
        xc, q, s = self.parts(e)
        qd = ed[..., ATTITUDE] / np.linalg.norm(e[..., ATTITUDE], axis=-1, keepdims=True)
        w = 2.0 * g.mul(qd, g.conj(q))[..., 1:]
        Rs = g.rotate(q[..., None, :], s)
        v = ed[..., None, CENTROID] + np.cross(w[..., None, :], Rs) + g.rotate(q[..., None, :], ed[..., self.shape_index])
        return self._compose(v, ed)

    # -- robots -> chart ------------------------------------------------------------------
    def from_robots(self, r, *, near_e=None, template=None) -> np.ndarray:
        """Chart values of the robot state ``r`` (``(..., layout.size)``).

        Centroid; attitude by :func:`fit_attitude` of ``near_e``'s shape (else ``template``,
        else :func:`default_template`) with ``near_e``'s attitude as the hint (else the
        identity); ``s_i = R(q_c)^T (p_i - x_c)``; yaws wound to within pi of ``near_e``'s,
        ``pose`` quaternions signed nearest ``near_e``'s.
        """
        L = self.layout
        r = as_array(r, "r", L.size)
        p = L.positions(r)
        xc = p.mean(axis=-2)
        cen = p - xc[..., None, :]
        if near_e is not None:
            near_e = self.check(near_e, "near_e")
            _, hq, tmpl = self.parts(near_e)
        else:
            hq = None
            tmpl = default_template(L) if template is None else check_template(template, L.n)
        q = fit_attitude(tmpl, cen, hq)
        s = g.rotate(g.conj(q)[..., None, :], cen)
        shape = np.broadcast_shapes(r.shape[:-1], q.shape[:-1])
        e = np.zeros(shape + (self.size,))
        e[..., CENTROID] = xc
        e[..., ATTITUDE] = q
        e[..., self.shape_index] = s
        ey, ry, eq, rq = self._headings
        yaw = r[..., ry]
        if near_e is not None and len(ey):
            yaw = yaw + 2.0 * math.pi * np.floor((near_e[..., ey] - yaw) / (2.0 * math.pi) + 0.5)
        e[..., ey] = yaw
        if len(eq):
            qi = r[..., rq]
            if near_e is not None:
                qi = g.closest_sign(qi, near_e[..., eq])
            e[..., eq] = qi
        return e

    @staticmethod
    def reading(e) -> np.ndarray:
        """z-y-x Euler angles ``(yaw, pitch, roll)`` (rad) of the attitude, shape ``(..., 3)``.

        For figures and tables only: at pitch +-pi/2 yaw and roll are not separate (the
        gimbal lock of seed 000 eq. (5)); the controllers never use them.
        """
        w, x, y, z = np.moveaxis(np.asarray(e, dtype=float)[..., ATTITUDE], -1, 0)
        n = w * w + x * x + y * y + z * z
        yaw = np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)
        pitch = np.arcsin(np.clip(2.0 * (w * y - z * x) / n, -1.0, 1.0))
        roll = np.arctan2(2.0 * (w * x + y * z), w * w - x * x - y * y + z * z)
        return np.stack([yaw, pitch, roll], axis=-1)


@functools.lru_cache(maxsize=64)
def _compose_gather(layout: RobotLayout) -> np.ndarray:
    """Index of every robot-state entry in ``concat(positions (3 N), yaws, orientations (4 M))``."""
    src = np.empty(layout.size, dtype=np.intp)
    flat = layout.position_index.ravel()
    keep = flat < layout.size
    src[flat[keep]] = np.flatnonzero(keep)
    n_yaw = len(layout.yaw_indices)
    src[list(layout.yaw_indices)] = 3 * layout.n + np.arange(n_yaw)
    if len(layout.orientation_index):
        src[layout.orientation_index.ravel()] = 3 * layout.n + n_yaw + np.arange(layout.orientation_index.size)
    return src


def team_compose(layout: RobotLayout, positions, yaws=None, orientations=None):
    """:meth:`RobotLayout.compose` on arrays of any namespace (JAX under ``jax.jit``), without
    its checks: the same entries gathered from ``positions`` (``(..., N, 3)``), ``yaws``
    (``(..., len(yaw_indices))``) and ``orientations`` (``(..., M, 4)``); a planar robot's z
    dropped."""
    xp = array_namespace(positions)
    parts = [positions.reshape(positions.shape[:-2] + (3 * layout.n,))]
    if len(layout.yaw_indices):
        parts.append(yaws)
    if len(layout.orientation_index):
        parts.append(orientations.reshape(orientations.shape[:-2] + (-1,)))
    shape = np.broadcast_shapes(*(a.shape[:-1] for a in parts))
    src = xp.concatenate([xp.broadcast_to(a, shape + a.shape[-1:]) for a in parts], axis=-1)
    return src[..., _compose_gather(layout)]


def team_positions(layout: RobotLayout, r):
    """:meth:`RobotLayout.positions` on arrays of any namespace (JAX under ``jax.jit``),
    without its checks: ``(..., N, 3)``, a planar robot at z = 0 (the same entries)."""
    xp = array_namespace(r)
    if xp is np:
        return layout.positions(r)
    padded = xp.concatenate([r, xp.zeros(r.shape[:-1] + (1,), dtype=r.dtype)], axis=-1)
    return padded[..., layout.position_index]
