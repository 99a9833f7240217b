"""Quaternion team: seed 000 §3.2 for N robots of any point kinds (formations layer).

``c = (x_c, q_c, s_1 .. s_N, q_c1 .. q_cM)``: the centroid (seed 000 eq. (9) for N robots,
§5: "x_c can still be the centroid"), a unit quaternion for the formation's attitude, the
shape (every robot's position in the formation frame, ``p_i = x_c + R(q_c) s_i``, seed 000
eqs. (16), (18) for N robots, ``sum s_i = 0``) and one unit quaternion per robot with a
heading (``xy_yaw``, ``xyz_yaw``, ``pose``; none for ``xyz``): its orientation relative to
the formation, ``q_ci = q_c* q_i`` (eqs. (12)-(13)). ``7 + 3 N + 4 M`` numbers for the
robots' degrees of freedom (``shape="frame"``).

``shape="separation"`` is seed 000's pair (§3.2, eqs. (9)-(19)), two ``xyz_yaw`` robots:
``c = (x_c, q_c, d_c, q_c1, q_c2)``, 16 numbers, the shape written by the one number ``d_c``,
half the separation, along the frame's x axis (``s_1 = (d_c, 0, 0) = -s_2``, eqs. (16), (18)).
Its maps are the seed's closed forms on components (:func:`quat_forward`,
:func:`quat_inverse_jvp`): Python floats for one formation (a controller's
real-time path, :attr:`component_kernels`), NumPy or JAX arrays for a batch.
:class:`QuaternionPair` is that shape with seed 000's Euclidean chart. The twist of ``q_c``
about the segment is not a function of the robots' positions: the seed fixes it with the
minimal rotation from ``i`` (eqs. (14)-(15)), undefined where ``x1 - x2`` points along ``-i``
(no continuous section of S^3 -> S^2 avoids such a point), so the description takes it from
``near_c`` (the desired state): the measured ``q_c`` is the point of its fibre nearest it,
and a measured segment exactly opposite the hinted one (a 180 deg formation error) takes the
half turn about the hint's z axis.

The attitude is the rotation of the best-fitting rigid copy of a reference shape
(:func:`~.team_chart.fit_attitude`, Horn 1987): the hint's shape and attitude (the
controller's reference, ``near_c``) or this description's template. For two robots it is
seed 000's frame, eqs. (10), (14)-(15) with the twist from the hint, exactly the
separation shape's forward map. The fit makes the shape law
blind to the attitude's rate (``docs/derivations.md``, "The quaternion
team"): at a fixed attitude the residual ``sum |s_i - s_des,i|^2`` has the rate ``2 sum (s -
s_des) . R^T (p_dot - x_c_dot)`` because the fit's stationarity ``sum s_des,i x s_i = 0``
kills the rotation term.

Rate maps are directional derivatives on ``(..., N, 3)`` and ``(..., M, 4)`` arrays: a
constant number of NumPy calls whatever N, no dense matrix.
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra.angles import map_entries
from ..algebra.kernels import array_namespace, small_matmul
from ..algebra.validate import as_array, as_unit_quaternion
from ..errors import DegenerateInputError, InvalidInputError, UnreachableError
from . import geometry as g
from . import pair_kernels as kern
from . import special_sets as sp
from .base import MIN_SEPARATION_M, Formation, Preset, Variable, quaternion_variables
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair
from .layout import POINT_KINDS, RobotLayout
from .special_sets import SpecialSet
from . import team_special_sets as tss
from .team_chart import (TIE, TIE_DECAY, LawGroup, TeamChart, check_template, default_template, fit_attitude, horn_matrix,
                         team_compose, team_layout, team_positions)

__all__ = ["QuaternionTeam", "QuaternionPair", "CHARTS", "SHAPES", "PLANAR_TOL", "TILT_TOL", "NEAR_VERTICAL"]

#: The charts a quaternion team reports in: the team chart (``formations.team_chart``) or,
#: for two 4-DOF robots, seed 000's Euclidean variables (eqs. (1)-(8)).
CHARTS = ("team", "pair")
#: The shape blocks: every robot's position in the formation frame (``s_1 .. s_N``), or seed
#: 000's half-separation ``d_c`` of two robots (module docstring).
SHAPES = ("frame", "separation")
#: Largest tilt (rad) of a robot's orientation that a 4-DOF robot is taken to reach.
TILT_TOL = 1e-6
#: Below this horizontal fraction of the segment, the pair chart reads the yaw from q_c's y axis.
NEAR_VERTICAL = 1e-2
#: Largest height (m, relative to ``max(1, |p|)``) at which a planar robot is taken to be on the ground.
PLANAR_TOL = 1e-9
_KZ = np.array([0.0, 0.0, 0.0, 1.0])
_EX = np.array([1.0, 0.0, 0.0])
#: The blocks of the separation shape's state: x_c, q_c, d_c, q_c1, q_c2.
_XC, _QC, _D, _Q1, _Q2 = slice(0, 3), slice(3, 7), 7, slice(8, 12), slice(12, 16)
_HALF_TURNS = (np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0, 0.0]), np.array([0.0, 1.0, 0.0, 0.0]))
#: Eigenvalues closer than this (relative to the fit's size) are taken as equal in the
#: divided differences of the fit's rate.
_CLOSE = 1e-13


# -- matrix kernels: one NumPy call per product on (..., N, k) arrays ------------------------------
# Hamilton product q p = L(q) p = R(p) q (docs/conventions.md), as 4 x 4 matrices gathered
# from q's components with signs.
_L_IDX = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_L_SIGN = np.array([[1.0, -1, -1, -1], [1, 1, -1, 1], [1, 1, 1, -1], [1, -1, 1, 1]])
_R_SIGN = np.array([[1.0, -1, -1, -1], [1, 1, 1, -1], [1, -1, 1, 1], [1, 1, -1, 1]])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])
_S_IDX = np.array([[0, 3, 2], [3, 0, 1], [2, 1, 0]])
_S_SIGN = np.array([[0.0, -1, 1], [1, 0, -1], [-1, 1, 0]])


def _left(q):
    """``L(q)`` with ``q p = L(q) p``, shape ``(..., 4, 4)``."""
    return q[..., _L_IDX] * _L_SIGN


def _right(p):
    """``R(p)`` with ``q p = R(p) q``, shape ``(..., 4, 4)``."""
    return p[..., _L_IDX] * _R_SIGN


def _rotation(q):
    """``R(q)`` (3 x 3) of a unit quaternion: the vector block of ``L(q) R(q*)`` (``v -> q v q*``)."""
    return small_matmul(_left(q), _right(q * _CONJ))[..., 1:, 1:]


def _skew(w):
    """``[w]x`` with ``[w]x v = w x v`` of the vector part ``w`` of a quaternion ``(..., 4)``
    (its scalar part ignored), shape ``(..., 3, 3)``."""
    return w[..., _S_IDX] * _S_SIGN


def _mT(a):
    return np.swapaxes(a, -1, -2)


# -- seed 000's pair (shape="separation"): closed forms on components -----------------------------
# Components are Python floats (one formation: a controller's real-time path, no NumPy call
# overhead) or broadcastable arrays of any namespace (a batch; JAX under jax.jit), one formula
# for all (pair_kernels' component algebra).

#: Below this norm the minimal rotation of eqs. (14)-(15) is taken as 0/0 (segment opposite the hint).
_EPS_ANTI = 1e-12


def quat_forward(r, qh, q1h=None, q2h=None, stage=None):
    """Forward kinematics, eqs. (9)-(15), with the twist of ``q_c`` taken from ``qh``.

    ``qh = (1, 0, 0, 0)`` gives the seed's minimal rotation from ``i`` (eqs. (14)-(15));
    any other ``qh`` gives the point of the measured fibre nearest ``qh``. ``q1h``, ``q2h``
    (optional) set the signs of ``q_c1``, ``q_c2``. ``stage`` (optional, a compiled loop's
    hold: ``ClusterController.chain``) maps the robots' half-yaw cosines and sines to equal
    ones computed once (each output component's loop would recompute them). Returns 16
    components.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    D = (dx * dx + dy * dy + dz * dz) ** 0.5
    ux, uy, uz = dx / D, dy / D, dz / D
    ax, ay, az = kern.x_axis(qh)
    # minimal rotation taking the hint's x axis to the segment: (1 + a.u, a x u), normalised;
    # for a.u < 0, 1 + a.u = |a x u|^2 / (1 - a.u) (no cancellation near the opposite direction)
    c = ax * ux + ay * uy + az * uz
    vx, vy, vz = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    vv = vx * vx + vy * vy + vz * vz
    if isinstance(c, float):
        w = 1.0 + c if c >= 0.0 else vv / (1.0 - c)
    else:
        L = kern.lib(c)
        w = L.where(c >= 0.0, 1.0 + c, vv / L.maximum(1.0 - c, 1.0))  # 1 - c >= 1 where used
    s = (w, vx, vy, vz)
    n = kern.qdot(s, s) ** 0.5
    anti = n < _EPS_ANTI
    if kern.any_true(anti):  # segment opposite the hint: half turn about the hint's z axis
        zx, zy, zz = kern.z_axis(qh)
        s = kern.select(anti, (0.0 * n, zx, zy, zz), s)
        n = kern.select(anti, (1.0 + 0.0 * n,), (n,))[0]
    s = kern.qscale(1.0 / n, s)
    qc = kern.qmul(*s, *qh)
    qcc = kern.qconj(qc)
    h1, h2 = kern.qyaw(t1), kern.qyaw(t2)
    if stage is not None:
        c1, s1, c2, s2 = stage((h1[0], h1[3], h2[0], h2[3]))
        h1, h2 = (c1, h1[1], h1[2], s1), (c2, h2[1], h2[2], s2)
    q1 = kern.qmul(*qcc, *h1)  # eqs. (12)-(13)
    q2 = kern.qmul(*qcc, *h2)
    if q1h is not None:
        q1 = kern.neg_if(kern.qdot(q1, q1h) < 0.0, q1)
        q2 = kern.neg_if(kern.qdot(q2, q2h) < 0.0, q2)
    return (0.5 * (x1 + x2), 0.5 * (y1 + y2), 0.5 * (z1 + z2), *qc, 0.5 * D, *q1, *q2)


def quat_inverse_jvp(c, cd):
    """Robot rates ``d INVKIN(c) [cd]`` of eqs. (16)-(19): the inverse Jacobian times ``cd``.

    ``x1 = x_c + d q_c i q_c*``; its rate is ``x_c' + d' u + 2 d vec(q_c' i q_c*)``;
    ``theta_i = yaw(q_c q_ci)``. Returns 8 components.
    """
    qc, d, q1, q2 = c[3:7], c[7], c[8:12], c[12:16]
    qcd, dd = cd[3:7], cd[7]
    ux, uy, uz = kern.x_axis(qc)
    m = kern.qmul(*kern.qmul(*qcd, 0.0, 1.0, 0.0, 0.0), *kern.qconj(qc))
    vx = dd * ux + 2.0 * d * m[1]
    vy = dd * uy + 2.0 * d * m[2]
    vz = dd * uz + 2.0 * d * m[3]
    out = []
    for qi_c, qi_cd, sign in ((q1, cd[8:12], 1.0), (q2, cd[12:16], -1.0)):
        qi = kern.qmul(*qc, *qi_c)
        qid = kern.qadd(kern.qmul(*qcd, *qi_c), kern.qmul(*qc, *qi_cd))
        out += [cd[0] + sign * vx, cd[1] + sign * vy, cd[2] + sign * vz, kern.yaw_rate(qi, qid)]
    return tuple(out)


class QuaternionTeam(Formation):
    """Seed 000 §3.2 for N robots: centroid, formation quaternion, shape, robot quaternions.

    Parameters
    ----------
    n : int, optional
        Number of 4-DOF robots (``xyz_yaw``), robot state ``(x1, y1, z1, theta1, ...)``.
    layout : RobotLayout, optional
        Any mix of point kinds instead of ``n`` (exactly one of ``n`` and ``layout``).
    template : array_like, shape (N, 3), optional
        The shape (m) the attitude is fitted to where no reference is given
        (:func:`~.team_chart.default_template`: the pair along x, the regular N-gon).
    shape : {"frame", "separation"}
        ``frame``: ``s_1 .. s_N``; ``separation``: seed 000's ``d_c`` of two ``xyz_yaw``
        robots, with ``chart="pair"`` (module docstring).
    chart : {"team", "pair"}
        The operator's chart of :meth:`to_chart` / :meth:`from_chart`: the team chart
        (:class:`~.team_chart.TeamChart`), or for two ``xyz_yaw`` robots seed 000's
        Euclidean variables (so the pair scenarios run this description).

    Raises
    ------
    InvalidInputError
        Neither or both of ``n`` and ``layout``; an unknown chart or shape; ``chart="pair"``
        or ``shape="separation"`` for other robots than two ``xyz_yaw``; ``shape="separation"``
        with the team chart.
    ShapeError, DegenerateInputError
        A template of the wrong size, non-finite, or with robots on each other.
    """

    name = "quaternion-team"
    key = "quaternion-team"
    #: On another namespace the dense Formation.singularity_measure_arrays (the O(N)
    #: singularity_measure below is NumPy's: the same value within rounding, 1e-14 in tests).
    singularity_on_arrays = True
    team = True
    #: ``--controller quaternion``.
    controller = "quaternion"
    controller_order = 0
    #: Seed 000 Tables 1-2, eq. (20): ``K_x, k_d, K_w`` as printed, the robots' yaws at ``K_w``'s
    #: rate (the pair's ``q_ci`` are eq. (20) blocks with ``K_w``).
    gain_tables = {
        "table1": {"k_x": [2.0, 2.0, 2.0], "k_d": 20.0, "k_w": [20.0, 20.0, 20.0], "k_theta": 20.0},
        "table2": {"k_x": [0.7, 0.7, 0.7], "k_d": 0.4, "k_w": [1.0, 1.0, 1.0], "k_theta": 1.0},
    }

    @classmethod
    def examples(cls) -> dict:
        """The contract test's instances: a mix of point kinds."""
        return {cls.key: cls(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz")))}

    def __init__(self, n=None, *, layout=None, template=None, shape="frame", chart="team"):
        L = self.layout = team_layout(n, layout, "QuaternionTeam")
        if chart not in CHARTS:
            raise InvalidInputError(f"QuaternionTeam: chart {chart!r} unknown; choose one of {', '.join(CHARTS)}")
        if shape not in SHAPES:
            raise InvalidInputError(f"QuaternionTeam: shape {shape!r} unknown; choose one of {', '.join(SHAPES)}")
        if (chart == "pair" or shape == "separation") and L.kinds != ("xyz_yaw", "xyz_yaw"):
            raise InvalidInputError(f"QuaternionTeam: chart='pair' and shape='separation' (seed 000's pair) are for "
                                    f"two xyz_yaw robots, the layout has {', '.join(L.kinds)}; use chart='team', "
                                    "shape='frame'")
        if shape == "separation" and chart != "pair":
            raise InvalidInputError("QuaternionTeam: shape='separation' is seed 000's pair state, read in seed 000's "
                                    "Euclidean variables: give chart='pair' (or shape='frame' for the team chart)")
        self.chart_name = chart
        self.shape = shape
        #: The separation shape (seed 000's pair) runs a controller on its component kernels.
        self.component_kernels = shape == "separation"
        self.template = default_template(L) if template is None else check_template(template, L.n)
        self.chart = TeamChart(L)
        heads = [(i, lab, k) for i, (lab, k) in enumerate(zip(L.labels, L.kinds)) if k != "xyz"]
        self._heads = heads
        shape_variables = ((Variable("d_c", "m", "length"),) if shape == "separation" else
                           tuple(Variable(f"s{lab}_{a}", "m", "position") for lab in L.labels for a in "xyz"))
        self.variables = (
            *(Variable(f"{a}_c", "m", "position") for a in "xyz"),
            *quaternion_variables("q_c"),
            *shape_variables,
            *(v for _, lab, _ in heads for v in quaternion_variables(f"q_c{lab}")),
        )
        self.chart_variables = EUCLIDEAN_VARIABLES if chart == "pair" else self.chart.variables
        N, M = L.n, len(heads)
        n_s = 1 if shape == "separation" else 3 * N  # d_c, or s_1 .. s_N
        self._s = 7 + np.arange(n_s).reshape((1, 1) if shape == "separation" else (N, 3))
        self._o = 7 + n_s + np.arange(4 * M).reshape(M, 4)
        kinds = [k for _, _, k in heads]
        self._yaw_rows = np.array([j for j, k in enumerate(kinds) if POINT_KINDS[k].yaw is not None], dtype=np.intp)
        self._pose_rows = np.array([j for j, k in enumerate(kinds) if k == "pose"], dtype=np.intp)
        self._all_yaw = len(self._yaw_rows) == M
        self._planar = np.array([i for i, k in enumerate(L.kinds) if k == "xy_yaw"], dtype=np.intp)
        self._yaw_r = np.array(L.yaw_indices, dtype=np.intp)
        self._mean_row = np.full((1, N), 1.0 / N)
        pos = L.position_index
        self._pos_rows = np.sort(pos[pos < L.size])  # robot rows of positions (a planar robot's x, y)
        self._a_rows = np.sort(np.concatenate([self._pos_rows, L.orientation_index.ravel()])).astype(np.intp)
        for a in (self._s, self._o, self._yaw_rows, self._pose_rows, self._planar, self._yaw_r, self._mean_row,
                  self._pos_rows, self._a_rows):
            a.setflags(write=False)

    def __repr__(self):
        return f"QuaternionTeam(layout={self.layout!r}, shape={self.shape!r}, chart={self.chart_name!r})"

    # -- layout of the state --------------------------------------------------------------
    @property
    def shape_index(self) -> np.ndarray:
        """Indices of ``s_1 .. s_N`` in ``c``, ``(N, 3)``."""
        return self._s

    @property
    def orientation_index(self) -> np.ndarray:
        """Indices of ``q_c1 .. q_cM`` in ``c``, ``(M, 4)`` (robots with a heading, in robot order)."""
        return self._o

    @functools.cached_property
    def sign_free(self) -> tuple:
        if self.shape == "separation":
            return (_QC, _Q1, _Q2)
        return (slice(3, 7),) + tuple(slice(int(r[0]), int(r[0]) + 4) for r in self._o)

    @functools.cached_property
    def law_groups(self) -> tuple[LawGroup, ...]:
        """Centroid (1 x 3), attitude (1 x 4), shape (N x 3; the separation shape's ``d_c``: 1 x
        1), orientation (M x 4)."""
        if self.shape == "separation":
            return (LawGroup("centroid", np.arange(3)[None, :]), LawGroup("attitude", np.arange(3, 7)[None, :]),
                    LawGroup("separation", np.array([[_D]])), LawGroup("orientation", np.arange(8, 16).reshape(2, 4)))
        groups = [LawGroup("centroid", np.arange(3)[None, :]), LawGroup("attitude", np.arange(3, 7)[None, :]),
                  LawGroup("shape", self._s)]
        if len(self._o):
            groups.append(LawGroup("orientation", self._o))
        return tuple(groups)

    def check_cluster_state(self, c, name="c"):
        """Finite ``(..., n_c)``, entries within the magnitude limit, ``q_c`` and every ``q_ci``
        unit within the unit tolerance (NonUnitError naming the block)."""
        c = super().check_cluster_state(c, name)
        as_unit_quaternion(c[..., 3:7], f"{name}[q_c]")
        if self.shape == "separation":
            for s, what in ((_Q1, "q_c1"), (_Q2, "q_c2")):
                as_unit_quaternion(c[..., s], f"{name}[{what}]")
            return c
        if len(self._o):
            as_unit_quaternion(self._heading_rows(c), f"{name}[q_c1..q_c{self._heads[-1][1]}]")
        return c

    # -- pieces shared by the maps -----------------------------------------------------------
    def _headings(self, r):
        """World orientations of the robots with a heading, ``(..., M, 4)``: ``q_yaw(theta_i)``
        or the pose quaternion."""
        L = self.layout
        if self._all_yaw:
            return g.q_yaw(r[..., self._yaw_r])
        xp = array_namespace(r)
        if xp is not np:  # JAX: the rows stacked, yaw rows then pose rows, and put in order
            rows = np.concatenate([self._yaw_rows, self._pose_rows])
            out = xp.concatenate([g.q_yaw(r[..., self._yaw_r]), r[..., L.orientation_index]], axis=-2)
            return out[..., np.argsort(rows), :]
        out = np.empty(r.shape[:-1] + (len(self._o), 4))
        if len(self._yaw_rows):
            out[..., self._yaw_rows, :] = g.q_yaw(r[..., self._yaw_r])
        out[..., self._pose_rows, :] = r[..., L.orientation_index]
        return out

    def _heading_rates(self, qi, r_dot):
        """Rates of :meth:`_headings` along ``r_dot``: ``1/2 theta_dot (0, 0, 0, 1) q_i`` (a yaw
        about world z) or the pose quaternion's rate."""
        L = self.layout
        if self._all_yaw:
            return 0.5 * r_dot[..., self._yaw_r, None] * g.mul(_KZ, qi)
        out = np.empty(np.broadcast_shapes(qi.shape[:-2], r_dot.shape[:-1]) + qi.shape[-2:])
        if len(self._yaw_rows):
            out[..., self._yaw_rows, :] = 0.5 * r_dot[..., self._yaw_r, None] * g.mul(_KZ, qi[..., self._yaw_rows, :])
        out[..., self._pose_rows, :] = r_dot[..., L.orientation_index]
        return out

    def _reference(self, near_c):
        """``(template, hint)`` of the fit: ``near_c``'s shape and attitude, else the template and 1."""
        if near_c is None:
            return self.template, None
        return self._shape_rows(near_c), near_c[..., 3:7]

    def _shape_rows(self, c):
        """``s_i`` of ``c`` as rows ``(..., N, 3)``: a view (the block ``self._s`` is contiguous);
        ``separation``: ``s_1 = (d_c, 0, 0) = -s_2`` (seed 000 eqs. (16), (18))."""
        if self.shape == "separation":
            xp, d = array_namespace(c), c[..., _D]
            z = xp.zeros_like(d)
            return xp.stack([xp.stack([d, z, z], axis=-1), xp.stack([-d, z, z], axis=-1)], axis=-2)
        return c[..., 7:7 + self._s.size].reshape(c.shape[:-1] + self._s.shape)

    def _heading_rows(self, c):
        """``q_ci`` of ``c`` as rows ``(..., M, 4)``: a view (the block ``self._o`` closes ``c``)."""
        return c[..., 7 + self._s.size:].reshape(c.shape[:-1] + self._o.shape)

    def _assemble(self, xc, q, s, qci):
        shape = np.broadcast_shapes(xc.shape[:-1], q.shape[:-1], s.shape[:-2], qci.shape[:-2])
        xp = array_namespace(s)
        if xp is not np:  # the same entries, concatenated
            parts = (xc, q, s.reshape(s.shape[:-2] + (-1,)), qci.reshape(qci.shape[:-2] + (-1,)))
            return xp.concatenate([xp.broadcast_to(a, shape + a.shape[-1:]) for a in parts], axis=-1)
        c = np.empty(shape + (self.n_c,))
        c[..., 0:3] = xc
        c[..., 3:7] = q
        c[..., 7:7 + s.shape[-2] * 3] = s.reshape(s.shape[:-2] + (-1,))
        c[..., 7 + s.shape[-2] * 3:] = qci.reshape(qci.shape[:-2] + (-1,))
        return c

    # -- kinematics ------------------------------------------------------------------------
    def forward(self, r, *, near_c=None):
        """``c`` of the robots ``r``: centroid (eq. (9)), the fit's attitude (eqs. (10),
        (14)-(15) for two robots), ``s_i = R(q_c)^T (p_i - x_c)``, ``q_ci = q_c* q_i`` (eqs.
        (12)-(13)) signed nearest ``near_c``'s.

        Parameters
        ----------
        r : array_like, shape (..., n_r)
        near_c : array_like, shape (..., n_c), optional
            The reference: its shape and attitude are the fit's template and hint, its
            ``q_ci`` set the signs. Default: the description's template, hint 1.

        Raises
        ------
        DegenerateInputError
            Two robots closer than ``MIN_SEPARATION_M``.
        """
        r = self.check_robot_state(r)
        self.check_apart(r)
        if near_c is not None:
            near_c = (self.check_cluster_state if self.shape == "separation" else super().check_cluster_state)(
                near_c, "near_c")
        return self.forward_arrays(r, near_c)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``, where the sign flip is a select): the caller has checked ``r`` (finite,
        robots apart) and ``near_c``. ``separation``: seed 000 eqs. (9)-(15) in closed form
        (:func:`quat_forward`; without ``near_c`` the seed's minimal rotation from
        ``i``, eqs. (14)-(15))."""
        if self.shape == "separation":
            if near_c is None:
                return kern.pack(quat_forward(kern.unpack(r), (1.0, 0.0, 0.0, 0.0)))
            h = kern.unpack(near_c)
            return kern.pack(quat_forward(kern.unpack(r), h[3:7], h[8:12], h[12:16]))
        xp = array_namespace(r)
        L = self.layout
        p = team_positions(L, r)
        mean_row = self._mean_row if xp is np else xp.asarray(self._mean_row)
        xc = small_matmul(mean_row, p)[..., 0, :]  # eq. (9) for N robots
        cen = p - xc[..., None, :]
        tmpl, hint = self._reference(near_c)
        q = fit_attitude(tmpl, cen, hint)  # Horn 1987; seed 000 eqs. (10), (14)-(15) for N = 2
        s = small_matmul(cen, _rotation(q))  # s_i = R^T (p_i - x_c), rows
        Lc = _left(q * _CONJ)
        if self._all_yaw:  # q_c* q_yaw(theta) = cos(theta/2) q_c* + sin(theta/2) q_c* k (eqs. (12)-(13))
            half = 0.5 * r[..., self._yaw_r]
            if xp is np:
                cs = np.empty(half.shape + (2,))
                cs[..., 0], cs[..., 1] = np.cos(half), np.sin(half)
            else:
                cs = xp.stack([xp.cos(half), xp.sin(half)], axis=-1)
            qci = small_matmul(cs, _mT(Lc[..., :, 0::3]))
        else:
            qci = small_matmul(self._headings(r), _mT(Lc))
        if near_c is not None and len(self._o):
            if xp is np:
                flip = np.einsum("...i,...i->...", qci, self._heading_rows(near_c)) < 0.0
                if flip.any():
                    qci = np.where(flip[..., None], -qci, qci)
            else:  # the flip selected (it changes nothing where no row flips)
                flip = xp.sum(qci * self._heading_rows(near_c), axis=-1) < 0.0
                qci = xp.where(flip[..., None], -qci, qci)
        return self._assemble(xc, q, s, qci)

    def forward_components(self, rc, near_c, stage=None):
        """``separation``: eqs. (10)-(15) on components, the twists of ``q_c``, ``q_c1``, ``q_c2``
        from ``near_c`` (the controller's reference): ``(c, rc)`` (``stage``:
        :func:`quat_forward`'s)."""
        if not self.component_kernels:
            return super().forward_components(rc, near_c, stage)
        kern.check_apart(rc, MIN_SEPARATION_M)
        return quat_forward(rc, near_c[3:7], near_c[8:12], near_c[12:16], stage=stage), rc

    def robot_rate_components(self, c, c_dot, rc):
        """``separation``: :meth:`robot_rate` on components (:func:`quat_inverse_jvp`)."""
        if not self.component_kernels:
            return super().robot_rate_components(c, c_dot, rc)
        return quat_inverse_jvp(c, c_dot)

    def inverse(self, c, *, near_r=None):
        """``p_i = x_c + R(q_c) s_i`` (eqs. (16), (18)), ``q_i = q_c q_ci`` (eqs. (17), (19));
        yaws unwrapped near ``near_r``'s.

        Raises
        ------
        UnreachableError
            A yaw robot whose ``q_c q_ci`` tilts (beyond ``TILT_TOL``), or a planar robot the
            shape puts off the ground (beyond ``PLANAR_TOL``).
        DegenerateInputError
            A shape that puts two robots on each other (``separation``: ``d_c`` below half the
            robots' minimum separation).
        """
        c = self.check_cluster_state(c)
        if self.shape == "separation" and np.any(c[..., _D] < 0.5 * MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"d_c must be at least {0.5 * MIN_SEPARATION_M:g} m (half the robots' separation), "
                f"got {float(np.min(c[..., _D]))!r}; a smaller d_c puts the robots on each other")
        L = self.layout
        q = c[..., 3:7]
        qn = q / np.linalg.norm(q, axis=-1, keepdims=True)
        p = c[..., None, 0:3] + self._shape_rows(c) @ _mT(_rotation(qn))  # eqs. (16), (18)
        qi = self._heading_rows(c) @ _mT(_left(q))  # eqs. (17), (19)
        if len(self._yaw_rows):
            qy = qi if self._all_yaw else qi[..., self._yaw_rows, :]
            tilt = np.linalg.norm(g.z_axis(qy / np.linalg.norm(qy, axis=-1, keepdims=True)) - g.EZ, axis=-1)
            if np.any(tilt > TILT_TOL):
                j = int(np.argmax(np.max(tilt.reshape(-1, tilt.shape[-1]), axis=0)))
                i, lab, _ = self._heads[int(self._yaw_rows[j])]
                raise UnreachableError(
                    f"q_c q_c{lab} tilts robot {self.layout.display_names[i]} by {float(np.max(tilt)):.3g} rad "
                    f"(limit {TILT_TOL:g}); it only "
                    f"yaws - give it a q_c{lab} whose product with q_c is a rotation about z (from_chart builds one)")
            yaws = g.yaw_of(qy)
        else:
            yaws = np.zeros(c.shape[:-1] + (0,))
        if len(self._planar):
            z = p[..., self._planar, 2]
            lim = PLANAR_TOL * np.maximum(1.0, np.linalg.norm(p[..., self._planar, :], axis=-1))
            if np.any(np.abs(z) > lim):
                j = int(np.argmax(np.max((np.abs(z) - lim).reshape(-1, z.shape[-1]), axis=0)))
                lab = L.display_names[int(self._planar[j])]
                raise UnreachableError(
                    f"the shape puts planar robot {lab} at z = {float(z.reshape(-1, z.shape[-1])[:, j].flat[0]):.3g} m "
                    "off the ground; give a shape and attitude with x_c + R(q_c) s_i on z = 0 (from_chart projects)")
        if near_r is not None:
            yaws = g.unwrap_near(yaws, L.yaws(self.check_robot_state(near_r, "near_r")))
        out = L.compose(p, yaws, qi[..., self._pose_rows, :])
        if L.n > 1:
            try:
                L.check_apart(out, MIN_SEPARATION_M, "the shape of c")
            except DegenerateInputError as exc:
                raise DegenerateInputError(f"{exc}; give each robot its own s_i") from None
        return out

    # -- rate maps ---------------------------------------------------------------------------
    def _fit_rate(self, tmpl, cen, cen_dot, hint, tmpl_dot=None, hint_dot=None):
        """``(q, q_dot)``: :func:`~.team_chart.fit_attitude` and its derivative as the centred
        positions move at ``cen_dot`` (and the template at ``tmpl_dot``, the hint at
        ``hint_dot``; default fixed).

        ``q = P h / |P h|`` with ``P = sum_k w_k v_k v_k^T`` (Horn's eigenvectors, weights
        ``w_k = phi(lambda_top - lambda_k)``); ``P' = V (D o (V^T N' V)) V^T + mu' V diag(dw/dmu)
        V^T``, ``D`` the divided differences of the weights (Daleckii-Krein), ``mu`` the top
        eigenvalue; ``q' = (I - q q^T) P' h / |P h|``. Where the top eigenvalue is simple this
        is the eigenvector perturbation ``sum_k v_k (v_k^T N' v) / (lambda - lambda_k)``; where
        it is tied (collinear robots or template), the rate of the hint's projection (plus
        ``(I - q q^T) P h' / |P h|`` for a moving hint, zero where the fit is unique).
        """
        Nm, Nd = horn_matrix(tmpl, cen), horn_matrix(tmpl, cen_dot)  # Horn 1987 eq. (35): bilinear
        if tmpl_dot is not None:
            Nd = Nd + horn_matrix(tmpl_dot, cen)
        lam, V = np.linalg.eigh(Nm)
        scale = np.sqrt(np.sum(np.asarray(tmpl) ** 2, axis=(-2, -1)) * np.sum(cen ** 2, axis=(-2, -1)))
        tie, tau = (TIE * scale)[..., None], (TIE_DECAY * scale + 1e-300)[..., None]
        gap = lam[..., -1:] - lam
        with np.errstate(under="ignore"):
            w = np.exp(-np.maximum(gap - tie, 0.0) / tau)
        dw_dgap = np.where(gap > tie, -w / tau, 0.0)
        h = np.broadcast_to(np.array([1.0, 0.0, 0.0, 0.0]) if hint is None else np.asarray(hint, float), lam.shape)

        def project(v):
            return np.einsum("...ik,...k->...i", V, w * np.einsum("...ik,...i->...k", V, v))

        ph = project(h)
        n = np.linalg.norm(ph, axis=-1)
        hh = h
        for turn in _HALF_TURNS:  # fit_attitude's fallback: the hint turned half a turn
            bad = n < 1e-9
            if not np.any(bad):
                break
            alt_h = g.mul(h, turn)
            alt = project(alt_h)
            an = np.linalg.norm(alt, axis=-1)
            hh = np.where(bad[..., None], alt_h, hh)
            ph = np.where(bad[..., None], alt, ph)
            n = np.where(bad, an, n)
        bad = n < 1e-9
        if np.any(bad):  # no hint breaks the tie: the top eigenvector (its own perturbation)
            top = V[..., :, -1]
            top = top * np.where(top[..., :1] < 0.0, -1.0, 1.0)
            hh = np.where(bad[..., None], top, hh)
            ph = np.where(bad[..., None], top, ph)
            n = np.where(bad, 1.0, n)
        q = ph / n[..., None]
        A = np.einsum("...ji,...jk,...kl->...il", V, Nd, V)  # V^T N' V
        dl = lam[..., :, None] - lam[..., None, :]
        dwl = -dw_dgap  # d w / d lambda_k at fixed mu
        close = np.abs(dl) <= _CLOSE * (scale[..., None, None] + 1e-300)
        with np.errstate(divide="ignore", invalid="ignore"):
            D = np.where(close, 0.5 * (dwl[..., :, None] + dwl[..., None, :]),
                         (w[..., :, None] - w[..., None, :]) / np.where(close, 1.0, dl))
        mu_dot = A[..., -1, -1]
        Vh = np.einsum("...ik,...i->...k", V, hh)
        Pd_h = np.einsum("...ik,...k->...i", V, np.einsum("...kl,...l->...k", D * A, Vh)
                         + mu_dot[..., None] * dw_dgap * Vh)
        if hint_dot is not None:
            Pd_h = Pd_h + project(np.broadcast_to(hint_dot, Pd_h.shape))
        Pd_h = Pd_h / n[..., None]
        q_dot = Pd_h - q * np.sum(q * Pd_h, axis=-1, keepdims=True)
        return q, q_dot

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot`` of the robots moving at ``r_dot``, at ``c = forward(r, near_c=near_c)``.

        ``x_c' = mean v_i``; ``q_c'`` the fit's rate (:meth:`_fit_rate`, template and hint
        fixed); ``s_i' = R^T (v_i - x_c') - omega_b x s_i`` with ``omega_b = 2 vec(q_c* q_c')``;
        ``q_ci' = q_c'* q_i + q_c* q_i'`` (eqs. (12)-(13)) with ``q_i' = 1/2 theta_i' (0, 0, 0,
        1) q_i`` for a yaw.
        """
        r = self.check_robot_state(r)
        r_dot = as_array(r_dot, "r_dot", self.n_r)
        c = self.forward(r, near_c=near_c)
        if self.shape == "separation":
            return self._separation_rate(c, r_dot)
        if near_c is not None:
            near_c = np.asarray(near_c, dtype=float)
        return self._rate(c, r, r_dot, near_c)

    def _separation_rate(self, c, r_dot):
        """``c_dot`` of the separation shape: the derivative of seed 000 eqs. (9)-(15) near the
        hint (no twist rate of ``q_c``): ``x_c' = (p1' + p2')/2``; ``q_c' = 1/2 (0, w) q_c`` with
        ``w = u x delta' / D`` (the minimal rotation of the segment ``u = delta / D``); ``d_c' =
        u . delta' / 2``; ``q_ci' = (q_c')* q_i + q_c* q_i'`` with ``q_i' = 1/2 theta_i' (0, 0,
        0, 1) q_i`` (eqs. (12)-(13))."""
        L = self.layout
        v, th_dot = L.positions(r_dot), L.yaws(r_dot)
        qc = c[..., _QC]
        u = g.x_axis(qc)
        D = 2.0 * c[..., _D]
        dd = v[..., 0, :] - v[..., 1, :]
        omega = np.cross(u, dd) / D[..., None]
        qc_dot = 0.5 * g.mul(np.concatenate([np.zeros(omega.shape[:-1] + (1,)), omega], axis=-1), qc)
        parts = [0.5 * (v[..., 0, :] + v[..., 1, :]), qc_dot, 0.5 * np.sum(u * dd, axis=-1)[..., None]]
        conj_qc_dot = g.conj(qc_dot)
        for k, s in ((0, _Q1), (1, _Q2)):
            qi = g.mul(qc, c[..., s])
            parts.append(g.mul(conj_qc_dot, qi) + th_dot[..., k, None] * g.mul(g.conj(qc), _yaw_rate_column(qi)))
        return g.concat(parts)

    def _rate(self, c, r, r_dot, near_c, near_dot=None):
        """:meth:`cluster_rate` at ``c = forward(r, near_c=near_c)``, the reference moving at
        ``near_dot`` (its shape and unit attitude's rates; default still)."""
        L = self.layout
        p, v = L.positions(r), L.positions(r_dot)
        cen = p - p.mean(axis=-2, keepdims=True)
        vbar = v.mean(axis=-2)
        cen_dot = v - vbar[..., None, :]
        tmpl, hint = self._reference(near_c)
        if near_dot is None:
            q, q_dot = self._fit_rate(tmpl, cen, cen_dot, hint)
        else:
            q, q_dot = self._fit_rate(tmpl, cen, cen_dot, hint, near_dot[..., self._s], near_dot[..., 3:7])
        q, q_dot = np.broadcast_arrays(q, q_dot)
        qc = g.conj(q)[..., None, :]
        wb = 2.0 * g.mul(g.conj(q), q_dot)[..., 1:]
        s = self._shape_rows(c)
        s_dot = g.rotate(qc, cen_dot) - np.cross(wb[..., None, :], s)
        qi = self._headings(r)
        qi_dot = self._heading_rates(qi, r_dot)
        qci_raw = g.mul(qc, qi)
        sign = np.where(np.sum(qci_raw * self._heading_rows(c), axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
        qci_dot = sign * (g.mul(g.conj(q_dot)[..., None, :], qi) + g.mul(qc, qi_dot))
        return self._assemble(vbar, q_dot, s_dot, qci_dot)

    def robot_rate(self, c, c_dot, *, r=None):
        """``r_dot`` of ``c`` moving at ``c_dot``: the derivative of eqs. (16)-(19).

        ``p_i' = x_c' + R(omega_b x s_i + s_i')`` with ``omega_b = 2 vec(q^* q_c') / |q_c|``
        (``q = q_c / |q_c|``), the yaw rate of ``q_c q_ci`` along ``q_c' q_ci + q_c q_ci'``
        (:func:`~.pair_kernels.yaw_rate`), a pose robot's ``q_c' q_ci + q_c q_ci'``. A planar
        robot's vertical rate is dropped (it has none). ``r`` is not needed (one branch).
        """
        return self.robot_rate_arrays(np.asarray(c, dtype=float), as_array(c_dot, "c_dot", self.n_c))

    def robot_rate_arrays(self, c, cd):
        """:meth:`robot_rate` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``). ``separation``: the derivative of seed 000 eqs. (16)-(19), the 8 x 16 matrix
        of Fig. 6 applied to ``cd`` (:func:`quat_inverse_jvp`)."""
        if self.shape == "separation":
            return kern.pack(quat_inverse_jvp(kern.unpack(c), kern.unpack(cd)))
        xp = array_namespace(cd)
        q, qd = c[..., 3:7], cd[..., 3:7]
        nq = xp.sqrt(xp.sum(q * q, axis=-1, keepdims=True))
        qn = q / nq
        wb = (2.0 / nq) * small_matmul(_left(qn * _CONJ), qd[..., None])[..., 0]  # (., w_b) = 2 q* q_c' / |q_c|
        R = _rotation(qn)
        # p_i' = x_c' + R (w_b x s_i + s_i') (eqs. (16), (18)), as rows: s (R [w_b]x)^T + s' R^T
        v = (cd[..., None, 0:3] + small_matmul(self._shape_rows(c), _mT(small_matmul(R, _skew(wb))))
             + small_matmul(self._shape_rows(cd), _mT(R)))
        qci, qcid = self._heading_rows(c), self._heading_rows(cd)
        Lq = _mT(_left(q))
        qi = small_matmul(qci, Lq)  # eqs. (17), (19)
        qid = small_matmul(qci, _mT(_left(qd))) + small_matmul(qcid, Lq)
        if self._all_yaw:
            th = kern.yaw_rate(tuple(xp.moveaxis(qi, -1, 0)), tuple(xp.moveaxis(qid, -1, 0)))
            return self.layout.compose(v, th) if xp is np else team_compose(self.layout, v, th)
        y = self._yaw_rows
        th = kern.yaw_rate(tuple(xp.moveaxis(qi[..., y, :], -1, 0)), tuple(xp.moveaxis(qid[..., y, :], -1, 0)))
        if xp is not np:
            return team_compose(self.layout, v, th, qid[..., self._pose_rows, :])
        return self.layout.compose(v, th, qid[..., self._pose_rows, :])

    # -- singularity measure ---------------------------------------------------------------------
    def singularity_measure(self, r, *, near_c=None):
        """:meth:`Formation.singularity_measure` (``sigma_min / sigma_max`` of the inverse
        Jacobian at the normalised formation) in O(N), without the dense ``n_r x n_c`` matrix.

        ``G = J J^T = D + U U^T``: the columns of ``s_i`` give ``R R^T = I`` on robot i's
        position rows, those of ``q_ci`` ``|q_c|^2 I`` on a pose robot's quaternion rows and
        ``|q_c|^2 |grad yaw(q_i)|^2`` (4 for a unit yaw) on a yaw row; ``U`` is the 7 columns of
        ``x_c`` and ``q_c`` (:meth:`robot_rate` of the unit vectors). With ``A`` the rows whose
        ``D`` is 1 and ``B`` the yaw rows, ``span(Q_A) + span(Q_B)`` (orthonormal bases of ``U``'s
        rows in A and in B) is invariant under ``G``, so its spectrum is that of the (at most)
        14 x 14 ``Q^T G Q`` plus ``D``'s values on the rest (``docs/derivations.md``).
        ``separation``: the singular values of the 8 x 16 inverse Jacobian
        (:meth:`Formation.singularity_measure`).
        """
        if self.shape == "separation":
            return super().singularity_measure(r, near_c=near_c)
        c = self.forward(self.normalised(r), near_c=near_c)
        U = np.moveaxis(self.robot_rate(c, self._basis(self.n_c, c.ndim - 1)[:7]), 0, -1)  # (..., n_r, 7)
        q2 = np.sum(c[..., 3:7] ** 2, axis=-1, keepdims=True)
        d = np.broadcast_to(q2, c.shape[:-1] + (self.n_r,)).copy()  # positions: 1 (R R^T), pose rows |q_c|^2
        d[..., self._pos_rows] = 1.0
        if len(self._yaw_r):  # |d theta / d q_ci|^2 = |q_c|^2 |grad yaw_of(q_i)|^2 (pair_kernels.yaw_of)
            qi = self._heading_rows(c) @ _mT(_left(c[..., 3:7]))
            if not self._all_yaw:
                qi = qi[..., self._yaw_rows, :]
            w, x, y, z = np.moveaxis(qi, -1, 0)
            n, dd = 2.0 * (w * z + x * y), w * w + x * x - y * y - z * z
            gn = 2.0 * np.stack([z, y, x, w], -1)
            gd = 2.0 * np.stack([w, x, -y, -z], -1)
            grad = (dd[..., None] * gn - n[..., None] * gd) / (n * n + dd * dd)[..., None]
            d[..., self._yaw_r] = q2 * np.sum(grad * grad, axis=-1)
        A, B = self._a_rows, self._yaw_r
        parts, rest = [], []
        for rows in (A, B):
            if not len(rows):
                continue
            Q = np.linalg.qr(U[..., rows, :])[0]  # (..., |rows|, k), k = min(7, |rows|)
            parts.append((rows, Q))
            if len(rows) > Q.shape[-1]:
                rest.append(d[..., rows])
        # Q^T G Q = Q^T D Q + (Q^T U)(Q^T U)^T on the block-diagonal basis
        QtU = np.concatenate([np.swapaxes(Q, -1, -2) @ U[..., rows, :] for rows, Q in parts], axis=-2)
        M = QtU @ np.swapaxes(QtU, -1, -2)
        k0 = 0
        for rows, Q in parts:
            k = Q.shape[-1]
            M[..., k0:k0 + k, k0:k0 + k] += np.swapaxes(Q, -1, -2) @ (d[..., rows, None] * Q)
            k0 += k
        lam = np.linalg.eigvalsh(M)
        lo, hi = lam[..., 0], lam[..., -1]
        for x in rest:
            lo, hi = np.minimum(lo, np.min(x, axis=-1)), np.maximum(hi, np.max(x, axis=-1))
        return np.sqrt(np.maximum(lo, 0.0) / hi)

    # -- charts ------------------------------------------------------------------------------
    def direct_state(self, e) -> np.ndarray:
        """``c`` read off team-chart values ``e`` as they stand: ``x_c``, ``q_c`` (normalised),
        ``s``, ``q_ci = q_c* q_i`` (``q_i = q_yaw(theta_i)`` or the chart's pose quaternion).
        :meth:`from_chart` is the state of the robots this places."""
        e = self.chart.check(e)
        xc, q, s = self.chart.parts(e)
        M = len(self._o)
        qi = np.empty(e.shape[:-1] + (M, 4))
        if len(self._yaw_rows):
            qi[..., self._yaw_rows, :] = g.q_yaw(e[..., self.chart.yaw_index])
        if len(self._pose_rows):
            qp = e[..., self.chart.orientation_index]
            qi[..., self._pose_rows, :] = qp / np.linalg.norm(qp, axis=-1, keepdims=True)
        return self._assemble(xc, q, s, g.mul(g.conj(q)[..., None, :], qi))

    def to_chart(self, c, *, near_e=None, r=None):
        """The chart of ``c``: the team chart (``x_c``, ``q_c``, ``s`` as they are; ``theta_i``
        the yaw of ``q_c q_ci`` unwrapped near ``near_e``'s, else near ``r``'s; a pose robot's
        ``q_c q_ci`` signed nearest ``near_e``'s), or with ``chart="pair"`` seed 000's
        Euclidean variables of the separation state (:meth:`to_pair` of a frame state), on the
        whole circle and regular at ``gamma_c = +-pi/2`` (:meth:`to_chart_arrays`)."""
        c = self.check_cluster_state(c)
        if self.chart_name == "pair":
            return self._pair_chart(c if self.shape == "separation" else self.to_pair(c),
                                    None if near_e is None else np.asarray(near_e, dtype=float))
        ch = self.chart
        e = np.empty(c.shape[:-1] + (ch.size,))
        e[..., 0:7] = c[..., 0:7]
        e[..., ch.shape_index] = self._shape_rows(c)
        qi = g.mul(c[..., None, 3:7], self._heading_rows(c))
        if len(self._yaw_rows):
            th = g.yaw_of(qi[..., self._yaw_rows, :])
            if near_e is not None:
                th = g.unwrap_near(th, ch.check(near_e, "near_e")[..., ch.yaw_index])
            elif r is not None:
                th = g.unwrap_near(th, self.layout.yaws(self.check_robot_state(r)))
            e[..., ch.yaw_index] = th
        if len(self._pose_rows):
            qp = qi[..., self._pose_rows, :]
            if near_e is not None:
                qp = g.closest_sign(qp, ch.check(near_e, "near_e")[..., ch.orientation_index])
            e[..., ch.orientation_index] = qp
        if near_e is not None:
            q = e[..., 3:7]
            e[..., 3:7] = g.closest_sign(q, ch.check(near_e, "near_e")[..., 3:7])
        return e

    @property
    def chart_on_arrays(self) -> bool:
        """The separation shape's pair chart runs on any array namespace (:meth:`to_chart_arrays`)."""
        return self.shape == "separation"

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of the separation shape on checked arrays of any namespace (NumPy,
        JAX), the branches selected."""
        if self.shape != "separation":
            return super().to_chart_arrays(c, near_e, r)
        return self._pair_chart(c, near_e)

    @staticmethod
    def _pair_chart(c, near_e=None):
        """Seed 000's Euclidean variables of a separation state ``c`` (any namespace).

        For a frame without twist (``q_c = q_z(beta + pi/2) q_y(-gamma)``) the y axis is
        ``(-cos beta, -sin beta, 0)``. Within ``NEAR_VERTICAL`` rad of the vertical, where
        eq. (4) is 0/0 or ill-conditioned, ``beta`` is read from the y axis and ``gamma`` from
        the segment in the frame turned by ``beta`` (exact for a twist-free frame, off by
        less than the twist times ``NEAR_VERTICAL`` otherwise); elsewhere ``beta`` and
        ``gamma`` are eqs. (4)-(5) of the segment, exactly, on the branch (``beta``,
        ``gamma``) or (``beta + pi``, ``pi - gamma``) that the y axis points to. ``u`` and
        ``y`` are orthogonal unit vectors, so ``y`` is far from vertical where ``u`` is near it.
        ``d_c`` is eq. (6); ``phi_i`` the yaw of ``q_c q_ci`` less ``beta`` (eqs. (7)-(8));
        angles unwrapped near ``near_e``'s.
        """
        xp = array_namespace(c)
        qc = c[..., _QC]
        y = g.rotate(qc, np.array([0.0, 1.0, 0.0]))
        u = g.x_axis(qc)
        rho_u, rho_y = xp.hypot(u[..., 0], u[..., 1]), xp.hypot(y[..., 0], y[..., 1])
        # near the vertical: beta from the y axis
        beta_y = xp.arctan2(-y[..., 1], -y[..., 0])
        psi = beta_y + 0.5 * np.pi
        gamma_y = xp.arctan2(u[..., 2], xp.cos(psi) * u[..., 0] + xp.sin(psi) * u[..., 1])
        # elsewhere: eqs. (4)-(5), branch from the y axis
        beta_u = xp.arctan2(-u[..., 0], u[..., 1])
        gamma_u = xp.arctan2(u[..., 2], rho_u)
        other = -(xp.cos(beta_u) * y[..., 0] + xp.sin(beta_u) * y[..., 1]) < 0.0
        beta_u = xp.where(other, beta_u + np.pi, beta_u)
        gamma_u = xp.where(other, np.pi - gamma_u, gamma_u)
        use_y = rho_u < NEAR_VERTICAL * rho_y
        beta = g.wrap(xp.where(use_y, beta_y, beta_u))
        gamma = g.wrap(xp.where(use_y, gamma_y, gamma_u))
        phi = [g.wrap(g.yaw_of(g.mul(qc, c[..., s])) - beta) for s in (_Q1, _Q2)]
        e = xp.stack([c[..., 0], c[..., 1], c[..., 2], beta, gamma, c[..., _D], *phi], axis=-1)
        if near_e is None:
            return e
        return map_entries(e, (3, 4, 6, 7), lambda a, b: g.unwrap_near(e[..., a:b], near_e[..., a:b]))

    @staticmethod
    def from_chart_arrays(e):
        """The separation state of seed 000's Euclidean variables ``e`` (checked arrays of any
        namespace): ``q_c = q_z(beta + pi/2) q_y(-gamma)``, ``q_ci = q_c* q_z(phi_i + beta)``,
        continuous in ``e``."""
        beta, gamma = e[..., 3], e[..., 4]
        qc = g.mul(g.q_yaw(beta + 0.5 * np.pi), g.q_pitch_y(-gamma))
        q1, q2 = g.q_yaw(e[..., 6] + beta), g.q_yaw(e[..., 7] + beta)
        return g.concat([e[..., 0:3], qc, e[..., 5:6], g.mul(g.conj(qc), q1), g.mul(g.conj(qc), q2)])

    @classmethod
    def _from_pair_chart(cls, e, e_dot=None):
        """The separation state (and rate) of seed 000's Euclidean variables (:meth:`from_chart_arrays`)."""
        e = EuclideanPair().check_cluster_state(e, "e")
        c = cls.from_chart_arrays(e)
        if e_dot is None:
            return c
        beta, gamma = e[..., 3], e[..., 4]
        qz, qy = g.q_yaw(beta + 0.5 * np.pi), g.q_pitch_y(-gamma)
        qc = c[..., _QC]
        q1, q2 = g.q_yaw(e[..., 6] + beta), g.q_yaw(e[..., 7] + beta)
        ed = as_array(e_dot, "e_dot", 8)
        qc_dot = ed[..., 3, None] * g.mul(_yaw_rate_column(qz), qy) + g.mul(
            qz, -ed[..., 4, None] * 0.5 * g.mul(qy, np.array([0.0, 0.0, 1.0, 0.0]))
        )
        cd = np.empty_like(c)
        cd[..., _XC] = ed[..., 0:3]
        cd[..., _QC] = qc_dot
        cd[..., _D] = ed[..., 5]
        for sl, qi, k in ((_Q1, q1, 6), (_Q2, q2, 7)):
            qi_dot = (ed[..., k] + ed[..., 3])[..., None] * _yaw_rate_column(qi)
            cd[..., sl] = g.mul(g.conj(qc_dot), qi) + g.mul(g.conj(qc), qi_dot)
        return c, cd

    def from_chart(self, e, e_dot=None):
        """The state (and rate) of the robots the chart places (:meth:`TeamChart.robots`:
        ``p_i = x_c + R(q_c) s_i``, a planar robot's z dropped), read on the chart's own
        branch: ``forward(chart.robots(e), near_c=direct_state(e))``; for a chart whose
        robots are its shape (``sum s_i = 0``, planar robots on the ground) that is
        :meth:`direct_state` itself. With ``chart="pair"``: the separation state of seed 000's
        Euclidean variables (:meth:`_from_pair_chart`; a frame state: its :meth:`from_pair`)."""
        if self.chart_name == "pair":
            out = self._from_pair_chart(e, e_dot)
            if self.shape == "separation":
                return out
            return self.from_pair(out) if e_dot is None else self.from_pair(*out)
        e = self.chart.check(e)
        ed = None if e_dot is None else as_array(e_dot, "e_dot", self.chart.size)
        rows = self.chart.orientation_index
        if len(rows):  # pose robots' quaternions normalised (and their rates projected)
            qp = e[..., rows]
            nqp = np.linalg.norm(qp, axis=-1, keepdims=True)
            e = np.array(e)
            e[..., rows] = qp / nqp
            if ed is not None:
                ed = np.array(np.broadcast_to(ed, np.broadcast_shapes(ed.shape, e.shape)))
                qh = e[..., rows]
                ed[..., rows] = (ed[..., rows] - qh * np.sum(qh * ed[..., rows], axis=-1, keepdims=True)) / nqp
        near = self.direct_state(e)
        r = self.chart.robots(e)
        c = self.forward(r, near_c=near)
        if ed is None:
            return c
        q = e[..., 3:7]
        nq = np.linalg.norm(q, axis=-1, keepdims=True)
        qn = q / nq
        near_dot = np.zeros(np.broadcast_shapes(near.shape, ed.shape[:-1] + near.shape[-1:]))
        near_dot[..., 3:7] = (ed[..., 3:7] - qn * np.sum(qn * ed[..., 3:7], axis=-1, keepdims=True)) / nq
        near_dot[..., self._s] = ed[..., self.chart.shape_index]
        return c, self._rate(c, r, self.chart.robot_rates(e, ed), near, near_dot)

    # -- the pair (N = 2) ---------------------------------------------------------------------
    def to_pair(self, c) -> np.ndarray:
        """Separation state ``(x_c, q_c, d_c, q_c1, q_c2)`` (:class:`QuaternionPair`'s) of a
        two-robot frame state.

        The pair's frame is ``q_c`` turned by the minimal rotation taking its x axis to ``s_1 -
        s_2`` (the identity where the shape lies along x, as :meth:`from_pair` puts it); ``d_c =
        |s_1 - s_2| / 2``, the midpoint ``x_c + R(q_c) (s_1 + s_2) / 2``."""
        if self.layout.kinds != ("xyz_yaw", "xyz_yaw") or self.shape != "frame":
            raise InvalidInputError(f"to_pair is for the frame state of two xyz_yaw robots; this team has "
                                    f"{', '.join(self.layout.kinds)}, shape {self.shape!r}")
        c = np.asarray(c, dtype=float)
        q = c[..., 3:7]
        s1, s2 = c[..., 7:10], c[..., 10:13]
        half = 0.5 * (s1 - s2)
        d = np.linalg.norm(half, axis=-1)
        u = half / np.maximum(d, 1e-300)[..., None]
        turn = g.swing(np.broadcast_to(_EX, u.shape), u, np.array([0.0, 0.0, 1.0]))
        qp = g.mul(q, turn)
        out = np.empty(c.shape[:-1] + (16,))
        out[..., 0:3] = c[..., 0:3] + g.rotate(q / np.linalg.norm(q, axis=-1, keepdims=True), 0.5 * (s1 + s2))
        out[..., 3:7] = qp
        out[..., 7] = d
        out[..., 8:12] = g.mul(g.conj(turn), c[..., 13:17])
        out[..., 12:16] = g.mul(g.conj(turn), c[..., 17:21])
        return out

    def from_pair(self, cp, cp_dot=None):
        """Frame state of a separation state (:class:`QuaternionPair`'s): ``s_1 = (d_c, 0, 0) =
        -s_2`` (seed 000 eqs. (16), (18): ``d_c`` along the frame's x axis), the quaternions as
        they are; with ``cp_dot`` also the rate."""
        if self.layout.kinds != ("xyz_yaw", "xyz_yaw") or self.shape != "frame":
            raise InvalidInputError(f"from_pair gives the frame state of two xyz_yaw robots; this team has "
                                    f"{', '.join(self.layout.kinds)}, shape {self.shape!r}")

        def one(a):
            a = np.asarray(a, dtype=float)
            out = np.zeros(a.shape[:-1] + (21,))
            out[..., 0:7] = a[..., 0:7]
            out[..., 7] = a[..., 7]
            out[..., 10] = -a[..., 7]
            out[..., 13:21] = a[..., 8:16]
            return out

        return one(cp) if cp_dot is None else (one(cp), one(cp_dot))

    # -- special sets --------------------------------------------------------------------------
    def special_sets(self):
        if self.shape == "separation":
            return sp.pair_sets("beta_c is undefined here; q_c is regular (its twist taken from near_c)")
        L = self.layout

        def on(gen):
            return lambda rng, n, eps: gen(L, rng, n, eps)

        return (
            SpecialSet("collinear", "robots on a line: Horn's matrix (1987 eq. (35)) has a double top eigenvalue, the "
                       "twist about the line is no function of the positions; the hint's projection decides (1 without "
                       "one), continuous; past the tie width (a gap of 1e-10 of the fit's size) and within the "
                       "window of 7.5e-7 the fit turns with a slope of 1 / (1e-9 size), and Horn's eigenvectors keep "
                       "about 1e-16 / gap of their digits, so round trips hold to 1e-6 there",
                       on(tss.team_collinear), round_trip_tol=1e-6),
            SpecialSet("vertical", "the formation's x axis vertical: the z-y-x reading (and seed 000 eq. (4) for two "
                       "robots) is atan2(0, 0); q_c is regular. A team of planar robots only stands on edge there: "
                       "their ground positions fall near one line (second singular value 1e-4 of the first at "
                       "1e-3 rad), the collinear set's conditioning, so round trips hold to its 1e-6",
                       on(tss.team_vertical), round_trip_tol=1e-6 if set(L.kinds) == {"xy_yaw"} else 1e-9),
            SpecialSet("anti-x", "p_1 - p_2 along -x: seed 000 eqs. (14)-(15) are 0/0; the fit has no such point (for "
                       "two robots without a hint: the half turn about the hint's z axis)", on(tss.team_anti_x)),
            SpecialSet("half-turn-attitude", "q_c a half turn from the hint: w = 0, the sign nearest the hint flips "
                       "(q and -q are one attitude; sign-free)", on(tss.team_half_turn_attitude)),
            SpecialSet("half-turn-yaws", "headings half a turn from the formation's and from each other: q_ci near a "
                       "rotation by pi (w = 0: eq. (20)'s sgn)", on(tss.team_half_turn_yaws)),
            SpecialSet("wound-yaws", "yaws wound by up to 50 turns: q_yaw(theta + 2 pi) = -q_yaw(theta), signs "
                       "nearest the reference's", on(tss.team_wound_yaws)),
        )


class QuaternionPair(Preset, QuaternionTeam):
    """Seed 000 §3.2: ``QuaternionTeam(2, shape="separation", chart="pair")``, the centroid, a
    unit quaternion whose x axis points from robot 2 to robot 1, half the separation and each
    robot's orientation in the cluster frame, ``c = (x_c, y_c, z_c, q_c[4], d_c, q_c1[4],
    q_c2[4])`` (eqs. (9)-(19)): 16 numbers for 8 degrees of freedom, in seed 000's Euclidean
    chart; its controller is :class:`~quatform.control.quaternion.QuaternionController`
    (eq. (20))."""

    name = "quaternion"
    key = "quaternion"
    arguments = {"n": 2, "shape": "separation", "chart": "pair"}


def _yaw_rate_column(q):
    """``d q / d theta`` for a yaw rotation about world z: ``1/2 (0, 0, 0, 1) q``."""
    return 0.5 * g.mul(_KZ, q)
