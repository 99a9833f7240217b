"""The controller contract: ``step(t, measured_robot_state, reference) -> robot commands``.

Control layer (beside robots, above formations). A controller holds its formation
description, gains and the team's limits, and no hidden state, so the same object can
drive a simulator or real robots: feed it the measured robot state and the desired
cluster state and rate, send the commands it returns.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..algebra._validate import as_array
from ..errors import InvalidInputError
from ..formations.base import Formation
from ..robots import Team

__all__ = ["Reference", "StepResult", "Controller", "sgn"]


@dataclass(frozen=True)
class Reference:
    """Desired cluster state and rate in a controller's formation description.

    Attributes
    ----------
    c : ndarray, shape (n_c,)
    c_dot : ndarray, shape (n_c,)
    """

    c: np.ndarray
    c_dot: np.ndarray


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
    raw_finite : bool
        False if the unsaturated command had a NaN or infinity (it was replaced by zero).
    """

    commands: np.ndarray
    cluster: np.ndarray
    error: np.ndarray
    raw_finite: bool


def sgn(x):
    """Signum with ``sgn(0) = +1``: the seed's ``sgn(q_0)`` must pick a side at a 180 deg error."""
    return np.where(x < 0.0, -1.0, 1.0)


def gains(values, n, name):
    """Positive finite gain vector of length ``n`` (a scalar is repeated)."""
    g = np.broadcast_to(np.asarray(values, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise InvalidInputError(f"{name} must be {n} positive finite gains, got {values!r}")
    return g


class Controller(ABC):
    """Base of the cluster-space controllers of seed 000."""

    #: Name on the command line.
    name: str = ""
    formation: Formation
    team: Team
    feedforward: bool

    def step(self, t: float, measured, reference: Reference) -> np.ndarray:
        """Robot commands for measured robot state ``measured`` (shape ``(n_r,)``)."""
        return self.compute(t, measured, reference).commands

    def compute(self, t: float, measured, reference: Reference) -> StepResult:
        """One control step, with the intermediate quantities the simulator logs."""
        r = as_array(measured, "measured robot state", self.formation.n_r)
        c_des = as_array(reference.c, "reference.c", self.formation.n_c)
        c_dot = as_array(reference.c_dot, "reference.c_dot", self.formation.n_c)
        c, err, r_dot = self._control(r, c_des, c_dot)
        finite = bool(np.all(np.isfinite(r_dot)))
        return StepResult(self.team.saturate(r_dot), c, err, finite)

    @abstractmethod
    def _control(self, r, c_des, c_dot_des):
        """Return measured cluster state, error and unsaturated robot rates."""
