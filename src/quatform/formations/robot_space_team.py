"""Robot space of a team of N robots: ``c = r`` (seed 000 §3.1 for N robots), formations layer.

The singularity-free baseline of seed 000 §3.1: the controller tracks each robot's desired
point (from the chart's inverse, :meth:`TeamChart.robots`) and never meets a singular
Jacobian, but its motions are the robots' shortest paths, not the formation's (Fig. 4b),
and the formation it reports is read back from the robots through the chart, with a fixed
template and no memory of the reference's attitude beyond the hint (the ambiguity of §4.1).
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra.kernels import array_namespace
from ..algebra.validate import as_array
from ..errors import InvalidInputError
from . import geometry as g
from .base import Formation
from .layout import POINT_KINDS, RobotLayout
from .team_chart import LawGroup, TeamChart, check_template, default_template

__all__ = ["RobotSpaceTeam", "team_layout"]


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
    """

    name = "robot-space-team"
    key = "robot-space-team"
    singularity_on_arrays = True  # Formation.singularity_measure_arrays: robot_rate_arrays of the unit vectors
    team = True
    #: ``--controller robot-space``.
    controller = "robot-space"
    controller_order = 3
    #: Seed 000 Tables 1-2: the printed ``K_RS`` of robot 1 (``x, y, z, theta``) for every robot.
    gain_tables = {
        "table1": {"k_p": [1.5, 1.5, 1.5], "k_theta": 6.0},
        "table2": {"k_p": [0.06, 0.06, 0.03], "k_theta": 0.02},
    }

    @classmethod
    def examples(cls) -> dict:
        """The contract test's instances: a mix of point kinds."""
        return {cls.key: cls(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw")))}

    def __init__(self, n=None, *, layout=None, template=None):
        self.layout = team_layout(n, layout, "RobotSpaceTeam")
        self.chart = TeamChart(self.layout)
        self.template = (default_template(self.layout) if template is None
                         else check_template(template, self.layout.n))
        self.variables = self.layout.variables
        self.chart_variables = self.chart.variables

    def __repr__(self):
        return f"RobotSpaceTeam(layout={self.layout!r})"

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
        """1 m for any robots, as for the pair's :class:`~.euclidean_pair.RobotSpace`: the cluster
        state is the robots' own coordinates (``J = I``, no special set), so nothing is divided
        by the robots' separation. :meth:`singularity_measure` is 1 (robots on each other
        included) and :meth:`value_spread` is ``sqrt(n_r) delta``, the bound of ``c = r``."""
        return array_namespace(r).ones(np.shape(r)[:-1])

    def inverse_jacobian(self, r, *, near_c=None):
        """The identity ``(..., n_r, n_r)`` at any robots ``r``, robots on each other included
        (``c = r`` up to the yaws' turns and the quaternions' signs, which ``J`` does not see),
        as for the pair's robot space; :meth:`forward` still refuses robots on each other."""
        r = self.check_robot_state(r)
        if near_c is not None:
            self.check_cluster_state(near_c, "near_c")
        return self.inverse_jacobian_at(r, r=r)

    def to_chart(self, c, *, near_e=None, r=None):
        """The team chart of the robots ``c`` (:meth:`TeamChart.from_robots` with this
        description's template where no ``near_e`` is given)."""
        c = self.check_cluster_state(c)
        return self.chart.from_robots(c, near_e=near_e, template=self.template)

    def from_chart(self, e, e_dot=None):
        e = self.chart.check(e)
        if e_dot is None:
            return self.chart.robots(e)
        return self.chart.robots(e), self.chart.robot_rates(e, e_dot)
