"""The cluster-space controller: formation, law and team, stateless (control layer).

One control update (seed 000 Fig. 2): the measured robot state -> forward kinematics with
the reference as hint -> the cluster error (``Formation.errors``: angles wrapped) -> the
law (:mod:`quatform.control.laws`, here a :class:`~quatform.control.laws.BlockLaw`) ->
robot rates through the inverse Jacobian at the measured state -> the team's actuation
and saturation (:class:`~quatform.robots.Team`). The cluster-space and robot-space
controllers of seed 000 are instances (``ClusterSpaceController``,
``RobotSpaceController``); the quaternion and dual-quaternion controllers keep their own
kernels, which apply the inverse Jacobian as a directional derivative on floats.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InvalidInputError
from ..formations import pair_kernels as kern
from ..formations.base import Formation
from ..robots import Team
from .base import Controller
from .laws import BlockLaw

__all__ = ["ClusterController"]


@dataclass(frozen=True)
class ClusterController(Controller):
    """A stateless cluster-space controller of a formation, a law and a team.

    Parameters
    ----------
    formation : Formation
        The description the law acts in.
    law : BlockLaw
        Errors and commanded cluster rates from ``(c, c_des, c_dot_des, e)`` components.
    team : Team
        The robots: actuation (identity for holonomic robots) and saturation.
    feedforward : bool
        Whether the law adds the desired rate (the law's own setting is replaced by it).
    """

    formation: Formation = field(default=None)
    law: BlockLaw = field(default=None)
    team: Team = Team()
    feedforward: bool = True
    name = "cluster"

    def __post_init__(self):
        if not isinstance(self.formation, Formation) or not isinstance(self.law, BlockLaw):
            raise InvalidInputError("ClusterController needs a Formation and a BlockLaw (control.laws), got "
                                    f"{type(self.formation).__name__} and {type(self.law).__name__}")
        if self.law.n != self.formation.n_c:
            raise InvalidInputError(f"the law has {self.law.n} variables, the formation {self.formation.n_c}")
        if self.law.feedforward != self.feedforward:
            object.__setattr__(self, "law", replace(self.law, feedforward=self.feedforward))

    def _control(self, r, c_des, c_dot_des, aligned):
        F = self.formation
        r, c_des, c_dot_des = (np.asarray(a, dtype=float) for a in (r, c_des, c_dot_des))
        c = F.forward(r, near_c=c_des)
        err, rate = self.law(kern.unpack(c), kern.unpack(c_des), kern.unpack(c_dot_des),
                             kern.unpack(F.errors(c, c_des)))
        x_rate = np.einsum("...ij,...j->...i", F.inverse_jacobian_at(c, r=r), kern.pack(rate))
        u, _ = self.team.actuate(r, x_rate, 0.0, self.team.initial_memory(r.shape[:-1]))
        return c, kern.pack(err), u
