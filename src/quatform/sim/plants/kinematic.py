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
    """Each robot's state names numbered from 1 (``x1, y1, z1, theta1, x2, ...`` for 4-DOF robots)."""
    return tuple(f"{v}{i}" for i, robot in enumerate(team.robots, start=1) for v in robot.state_columns)


@dataclass(frozen=True)
class KinematicTeam:
    """A :class:`~quatform.robots.Team` as a plant (state and output: the robot state).

    Attributes
    ----------
    team : Team
        The robots; state ``(*batch, team.n_state)``, command ``(*batch, team.n)`` (``4 N`` each
        for seed 000's holonomic robots); the output is their points.
    """

    team: Team = Team()
    batchable = True

    @property
    def state_columns(self) -> tuple[str, ...]:
        return _team_columns(self.team)

    @property
    def output_columns(self) -> tuple[str, ...]:
        """The points the robots offer a formation (``team.layout``'s names; the state's for a
        holonomic team, whose state is its point)."""
        return self.state_columns if self.team.passthrough else self.team.layout.names

    def output(self, x) -> np.ndarray:
        """What a perfect sensor sees: every robot's point (``team.point``; the state itself for
        a holonomic team), shape ``(*batch, team.layout.size)``."""
        return x if self.team.passthrough else self.team.point(x)

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
