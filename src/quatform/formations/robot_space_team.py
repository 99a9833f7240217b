"""Robot space of a team of N robots: ``c = r`` (seed 000 §3.1 for N robots), formations layer.

The singularity-free baseline of seed 000 §3.1: the controller tracks each robot's desired
point (from the chart's inverse, :meth:`TeamChart.robots`) and never meets a singular
Jacobian, but its motions are the robots' shortest paths, not the formation's (Fig. 4b),
and the formation it reports is read back from the robots through the chart, with a fixed
template and no memory of the reference's attitude beyond the hint (the ambiguity of §4.1).
:class:`RobotSpace`, the description of seed 000's robot-space controller, is the team of
two 4-DOF robots with the pair chart (seed 000's Euclidean variables).
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra.kernels import array_namespace, as_floats, concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError
from . import geometry as g
from . import special_sets as sp
from .base import Formation, Preset
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair
from .layout import POINT_KINDS, RobotLayout
from .team_chart import LawGroup, TeamChart, check_template, default_template, pair_chart, team_layout

__all__ = ["RobotSpaceTeam", "RobotSpace"]


def _numbers(robots: list) -> str:
    """Robot numbers ``[1, 2, 3, 5]`` as ``"1-3, 5"``."""
    runs, start = [], robots[0]
    for a, b in zip(robots, robots[1:] + [None]):
        if b != a + 1:
            runs.append(str(start) if start == a else f"{start}-{a}")
            start = b
    return ", ".join(runs)


class RobotSpaceTeam(Formation):
    """Seed 000 §3.1 for N robots of any point kinds: the cluster state is the robot state.

    Parameters
    ----------
    n : int, optional
        Number of 4-DOF robots (``xyz_yaw``).
    layout : RobotLayout, optional
        Any mix of point kinds instead of ``n``.
    template : array_like, shape (N, 3), optional
        The shape the chart fits the formation's attitude to when no reference is given
        (:func:`~.team_chart.default_template` by default).
    chart : {"team", "pair"}
        The operator's chart: the team chart (:class:`~.team_chart.TeamChart`) or, for two
        ``xyz_yaw`` robots, seed 000's Euclidean variables (eqs. (1)-(8) of the robots,
        :class:`~.euclidean_team.EuclideanPair`).

    Raises
    ------
    InvalidInputError
        ``chart="pair"`` for a team that is not two ``xyz_yaw`` robots.
    """

    name = "robot-space-team"
    key = "robot-space-team"
    singularity_on_arrays = True  # Formation.singularity_measure_arrays: robot_rate_arrays of the unit vectors
    team = True
    cluster_is_robot_state = True
    #: ``--controller robot-space``.
    controller = "robot-space"
    controller_order = 3
    #: Seed 000 Tables 1-2: the printed ``K_RS`` of robot 1 (``x, y, z, theta``) for every robot.
    gain_tables = {
        "table1": {"k_p": [1.5, 1.5, 1.5], "k_theta": 6.0},
        "table2": {"k_p": [0.06, 0.06, 0.03], "k_theta": 0.02},
    }

    def check_gains(self, gains) -> None:
        """Refuse free bodies (``pose`` points) without the orientation gain ``k_w``: seed
        000's robot-space gains (``K_RS`` of Tables 1 and 2) command a robot's x, y, z and yaw
        and give none for a 3-D orientation."""
        free = [i + 1 for i, kind in enumerate(self.layout.kinds) if kind == "pose"]
        if free and "k_w" not in gains:
            raise InvalidInputError(
                f"--controller {self.controller} cannot drive robot{'s' if len(free) > 1 else ''} {_numbers(free)} "
                f"(free bodies): seed 000's robot-space law and its gains (K_RS of Tables 1 and 2) command a robot's "
                "x, y, z and yaw, and give no gain for a free body's 3-D orientation; choose --controller quaternion "
                "or dual-quaternion, or give the orientation gain k_w (1/s, the quaternion law of seed 000 eq. (20)) "
                f"in [gains.{self.controller}]")

    @classmethod
    def examples(cls) -> dict:
        """The contract test's instances: a mix of point kinds."""
        return {cls.key: cls(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw")))}

    def __init__(self, n=None, *, layout=None, template=None, chart="team"):
        self.layout = team_layout(n, layout, "RobotSpaceTeam")
        #: the pair chart's conversions: seed 000 eqs. (1)-(8) (None: the team chart)
        self._pair = EuclideanPair() if pair_chart(chart, self.layout, "RobotSpaceTeam") else None
        self.chart_kind = chart
        self.chart = TeamChart(self.layout)
        self.template = (default_template(self.layout) if template is None
                         else check_template(template, self.layout.n))
        self.variables = self.layout.variables
        self.chart_variables = self.chart.variables if self._pair is None else EUCLIDEAN_VARIABLES

    def __repr__(self):
        return f"RobotSpaceTeam(layout={self.layout!r}, chart={self.chart_kind!r})"

    @functools.cached_property
    def sign_free(self) -> tuple:
        return tuple(slice(int(r[0]), int(r[0]) + 4) for r in self.layout.orientation_index)

    @functools.cached_property
    def law_groups(self) -> tuple[LawGroup, ...]:
        """Each robot's position (``position``; ``planar`` for a ground robot's x, y), yaw
        (``heading``) and orientation (``orientation``)."""
        L = self.layout
        pos = L.position_index
        pos = pos[np.all(pos < L.size, axis=1)]
        planar = [L.position_index[i, :2] for i, k in enumerate(L.kinds) if POINT_KINDS[k].position == (0, 1)]
        groups = [LawGroup("position", pos)] if len(pos) else []
        if planar:
            groups.append(LawGroup("planar", np.stack(planar)))
        if L.yaw_indices:
            groups.append(LawGroup("heading", np.array(L.yaw_indices, dtype=np.intp)[:, None]))
        if len(self.layout.orientation_index):
            groups.append(LawGroup("orientation", self.layout.orientation_index))
        return tuple(groups)

    def forward(self, r, *, near_c=None):
        r = self.check_robot_state(r)
        if self.robots_apart:  # robots on each other form no formation (c = r itself is defined there)
            self.check_apart(r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        return self.forward_arrays(r, near_c)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` without its checks, on arrays of any namespace (JAX under
        ``jax.jit``): the yaws wound near ``near_c``'s (:meth:`RobotLayout.wind`), the ``pose``
        robots' quaternions signed nearest its (:func:`.geometry.closest_sign`)."""
        if array_namespace(r) is np:
            out = np.array(r, dtype=float)
            if near_c is not None:
                out = self.layout.wind(out, near_c)
                rows = self.layout.orientation_index
                if len(rows):
                    out[..., rows] = g.closest_sign(out[..., rows], near_c[..., rows])
            return out
        if near_c is None:
            return r
        xp = array_namespace(r)
        out = self.layout.wind(r, near_c)
        rows = self.layout.orientation_index
        if len(rows):  # closest_sign without writes: each entry times its quaternion's sign (or 1)
            flip = xp.sum(out[..., rows] * near_c[..., rows], axis=-1) < 0.0
            sign = xp.concatenate([xp.ones(flip.shape[:-1] + (1,)), xp.where(flip, -1.0, 1.0)], axis=-1)
            out = out * sign[..., self._sign_index]
        return out

    @functools.cached_property
    def _sign_index(self) -> np.ndarray:
        """Each robot-state entry's column in ``(1, sign of pose robot 1, ...)``."""
        idx = np.zeros(self.layout.size, dtype=np.intp)
        for m, rows in enumerate(self.layout.orientation_index):
            idx[rows] = m + 1
        return idx

    def robot_rate_arrays(self, c, c_dot):
        """:meth:`robot_rate` without its checks, on arrays of any namespace: ``c_dot``."""
        if array_namespace(c_dot) is np:
            return self.robot_rate(c, c_dot)
        return array_namespace(c_dot).broadcast_to(c_dot, np.broadcast_shapes(c.shape, c_dot.shape))

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        return self.forward(c, near_c=None if near_r is None else self.check_robot_state(near_r, "near_r"))

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = r_dot``: the identity (seed 000 §3.1)."""
        r = self.check_robot_state(r)
        r_dot = as_array(r_dot, "r_dot", self.n_r)
        return np.broadcast_to(r_dot, np.broadcast_shapes(r.shape, r_dot.shape)).copy()

    def robot_rate(self, c, c_dot, *, r=None):
        """``r_dot = c_dot``: the identity."""
        c = np.asarray(c, dtype=float)
        c_dot = as_array(c_dot, "c_dot", self.n_c)
        return np.broadcast_to(c_dot, np.broadcast_shapes(c.shape, c_dot.shape)).copy()

    def length_scale(self, r):
        """1 m for any robots: the cluster state is the robots' own coordinates (``J = I``, no
        special set), so nothing is divided by the robots' separation. :meth:`singularity_measure`
        is 1 (robots on each other included) and :meth:`value_spread` is ``sqrt(n_r) delta``, the
        bound of ``c = r``."""
        return array_namespace(r).ones(np.shape(r)[:-1])

    def inverse_jacobian_at(self, c, *, r=None):
        """The identity ``(..., n_r, n_r)`` (robot space is its own cluster space), on NumPy or
        another array namespace."""
        if concrete(c) or isinstance(c, (list, tuple)):  # a host value: checked (shape, finite)
            c = self.check_robot_state(c, "c")
        c = as_floats(c)
        xp = array_namespace(c)
        return xp.broadcast_to(xp.eye(self.n_r), c.shape[:-1] + (self.n_r, self.n_r)).copy()

    def inverse_jacobian(self, r, *, near_c=None):
        """The identity ``(..., n_r, n_r)`` at any robots ``r``, robots on each other included
        (``c = r`` up to the yaws' turns and the quaternions' signs, which ``J`` does not see);
        :meth:`forward` still refuses robots on each other where :attr:`robots_apart`."""
        r = self.check_robot_state(r)
        if near_c is not None:
            self.check_cluster_state(near_c, "near_c")
        return self.inverse_jacobian_at(r, r=r)

    def special_sets(self):
        """None of its own; two ``xyz_yaw`` robots are checked on the pair's sets (seed 000), where
        the Euclidean chart is singular and the robot space is not."""
        if self.layout.kinds != ("xyz_yaw", "xyz_yaw"):
            return ()
        return sp.pair_sets("the Euclidean chart of eqs. (1)-(8) is singular here; the robot space is not")

    @property
    def chart_on_arrays(self) -> bool:
        """The pair chart runs on any array namespace (:meth:`to_chart_arrays`); the team chart on NumPy."""
        return self._pair is not None

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of the pair chart on checked arrays of any namespace (robots apart):
        seed 000's variables of the robots ``c``, wound to ``near_e``'s."""
        return self._pair.to_chart_arrays(self._pair.forward_arrays(c), near_e)

    def to_chart(self, c, *, near_e=None, r=None):
        """The team chart of the robots ``c`` (:meth:`TeamChart.from_robots` with this
        description's template where no ``near_e`` is given); ``chart="pair"``: seed 000's
        Euclidean variables of the robots, eqs. (1)-(8) (past ``|gamma_c| = pi/2`` they read
        ``beta_c + pi``, ``pi - gamma_c``, the ambiguity of §4.1), wound to ``near_e``'s."""
        c = self.check_cluster_state(c)
        if self._pair is not None:
            return self._pair.to_chart(self._pair.forward(c), near_e=near_e)
        return self.chart.from_robots(c, near_e=near_e, template=self.template)

    def from_chart(self, e, e_dot=None):
        """The robots (and their rates) of the chart values ``e`` (and ``e_dot``); ``chart="pair"``:
        the inverse of seed 000 eqs. (1)-(8) and its closed-form derivative."""
        if self._pair is not None:
            e = self._pair.check_cluster_state(e, "e")
            r = self._pair.inverse(e)
            return r if e_dot is None else (r, self._pair.robot_rate(e, as_array(e_dot, "e_dot", self.n_r)))
        e = self.chart.check(e)
        if e_dot is None:
            return self.chart.robots(e)
        return self.chart.robots(e), self.chart.robot_rates(e, e_dot)


class RobotSpace(Preset, RobotSpaceTeam):
    """Robot space of two 4-DOF robots, ``c = r``: the description of seed 000 §3.1,
    ``RobotSpaceTeam(2, chart="pair")`` taking robots on each other (:attr:`robots_apart`).

    Its chart is the Euclidean forward kinematics, eqs. (1)-(8), as the seed's robot-space
    controller reports the formation.
    """

    name = "robot"
    key = "robot"
    arguments = {"n": 2, "chart": "pair"}
    robots_apart = False
