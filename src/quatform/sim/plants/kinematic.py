"""The kinematic team plant: every robot follows its own model for a held command.

Sim layer. Seed 000's robots (§4.1) are holonomic 4-DOF robots that move at the commanded
velocity; :meth:`quatform.robots.Team.step` integrates that exactly over a step, so the
plant's state is the stacked robot state ``r`` and what a sensor sees is ``r`` itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...robots import Team

__all__ = ["KinematicTeam"]


def _team_columns(team: Team) -> tuple[str, ...]:
    """``x1, y1, z1, theta1, x2, ...``: the 4-DOF state of each robot, numbered from 1."""
    return tuple(f"{v}{i}" for i in range(1, len(team.robots) + 1) for v in ("x", "y", "z", "theta"))


@dataclass(frozen=True)
class KinematicTeam:
    """A :class:`~quatform.robots.Team` as a plant (state and output: the robot state).

    Attributes
    ----------
    team : Team
        The robots; state and command of shape ``(*batch, 4 N)``.
    """

    team: Team = Team()
    batchable = True

    @property
    def state_columns(self) -> tuple[str, ...]:
        return _team_columns(self.team)

    @property
    def output_columns(self) -> tuple[str, ...]:
        return self.state_columns

    def output(self, x) -> np.ndarray:
        """What a perfect sensor sees: the state itself, shape ``(*batch, 4 N)``."""
        return x

    def step(self, x, u, dt: float, t: float = 0.0) -> np.ndarray:
        """State after ``dt`` s of the held command ``u`` (exact; seed 000 §4.1 kinematics).

        Parameters
        ----------
        x, u : ndarray, shape (*batch, 4 N)
            Robot state (m, rad) and command (m/s, rad/s), saturated by the team.
        dt : float
            Step, s.
        t : float
            Time, s (unused: the robots are time-invariant).
        """
        return self.team.step(x, u, dt)
