"""Cluster-space and robot-space proportional controllers, seed 000 §2 and §3.1.

Control layer; both are :class:`~quatform.control.cluster.ClusterController` instances
with a proportional law. Cluster space (Fig. 2): errors in the Euclidean cluster variables,
``c_dot_cmd = -K e + c_dot_des``, turned into robot rates by the inverse Jacobian; at a
vertical segment that matrix loses rank and ``beta_c`` cannot be controlled. Robot space
(Fig. 3): the reference is converted to robot space and ``r_dot_cmd = -K (r - r_des) +
r_dot_des``; no Jacobian is inverted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DegenerateInputError
from ..formations import EuclideanPair, RobotSpace
from ..formations.base import MIN_SEPARATION_M, Formation
from ..robots import Team
from .base import gains
from .cluster import ClusterController
from .laws import Block, BlockLaw


def _proportional(k, feedforward):
    """``-K e + c_dot_des`` on every variable (seed 000 Fig. 2 / Fig. 3)."""
    return BlockLaw((Block("proportional", 0, len(k), tuple(k.tolist())),), feedforward)


def _robots_apart(cd):
    """A reference with the robots on each other is no formation (the cluster-space
    controller refuses ``d_c`` below ``MIN_SEPARATION_M / 2`` the same way)."""
    d = ((cd[0] - cd[4]) ** 2 + (cd[1] - cd[5]) ** 2 + (cd[2] - cd[6]) ** 2) ** 0.5  # robot space (x1 .. theta2)
    bad = d < MIN_SEPARATION_M
    if bad if isinstance(bad, bool) else np.any(bad):
        raise DegenerateInputError(
            f"reference robots are {float(np.min(d)):.3g} m apart: no formation (at least "
            f"{MIN_SEPARATION_M:g} m); give desired robots apart"
        )


__all__ = ["ClusterSpaceController", "RobotSpaceController", "TABLE1", "TABLE2"]

#: Seed 000 Table 1 (MATLAB simulations, §4.1), in the printed order.
TABLE1 = {
    "cluster-space": {"k": [1, 1, 1, 10, 10, 5, 5, 10]},
    "robot-space": {"k": [1.5, 1.5, 1.5, 6, 6, 1.5, 1.5, 1.5]},
    "quaternion": {"k_x": [2, 2, 2], "k_d": 20, "k_w": [20, 20, 20]},
    "dual-quaternion": {"k_dw": [15, 15, 15]},
}
#: Seed 000 Table 2 (ROS/Gazebo simulations, §4.2).
TABLE2 = {
    "cluster-space": {"k": [0.06, 0.06, 0.03, 0.02, 0.02, 0.03, 0.03, 0.03]},
    "robot-space": {"k": [0.06, 0.06, 0.03, 0.02, 0.02, 0.03, 0.03, 0.03]},
    "quaternion": {"k_x": [0.7, 0.7, 0.7], "k_d": 0.4, "k_w": [1, 1, 1]},
    "dual-quaternion": {"k_dw": [0.5, 0.5, 0.5]},
}


@dataclass(frozen=True)
class ClusterSpaceController(ClusterController):
    """Seed 000 Fig. 2: ``r_dot = J^-1(c) (-K (c - c_des) + c_dot_des)`` on eqs. (1)-(8).

    Parameters
    ----------
    k : array_like, shape (8,)
        Gains on ``(x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)``, 1/s.
    """

    k: np.ndarray = field(default_factory=lambda: np.array(TABLE1["cluster-space"]["k"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=EuclideanPair, init=False)
    law: BlockLaw = field(default=None, init=False)
    checks: tuple = field(default=(), init=False)
    filters: tuple = field(default=(), init=False)
    name = "cluster-space"

    def __post_init__(self):
        object.__setattr__(self, "k", gains(self.k, 8, "k"))
        object.__setattr__(self, "law", _proportional(self.k, self.feedforward))  # Fig. 2


@dataclass(frozen=True)
class RobotSpaceController(ClusterController):
    """Seed 000 §3.1, Fig. 3: ``r_dot = -K (r - r_des) + r_dot_des``.

    Parameters
    ----------
    k : array_like, shape (8,)
        Gains on ``(x1, y1, z1, theta1, x2, y2, z2, theta2)``, 1/s (Table 1's printed order).
    """

    k: np.ndarray = field(default_factory=lambda: np.array(TABLE1["robot-space"]["k"], float))
    team: Team = Team()
    feedforward: bool = True
    formation: Formation = field(default_factory=RobotSpace, init=False)
    law: BlockLaw = field(default=None, init=False)
    checks: tuple = field(default=(_robots_apart,), init=False)
    filters: tuple = field(default=(), init=False)
    name = "robot-space"

    def __post_init__(self):
        object.__setattr__(self, "k", gains(self.k, 8, "k"))
        object.__setattr__(self, "law", _proportional(self.k, self.feedforward))  # Fig. 3
