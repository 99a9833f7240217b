"""The closed loop: reference -> controller -> robots, logged at every step.

Sim layer. ``simulate`` runs one scenario with one controller and returns a :class:`Run`
holding every logged signal; ``metrics`` and ``report`` read it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..control import Reference
from ..control.base import Controller
from ..errors import InvalidInputError
from ..formations import EuclideanPair, RobotSpace
from ..references import sample_reference
from .loop import PerfectMeasurement, closed_loop
from .scenario import Scenario, check_scenario_work

__all__ = ["Run", "simulate"]


@dataclass(frozen=True)
class Run:
    """Logged signals of one closed-loop run (``T`` samples).

    Attributes
    ----------
    scenario : Scenario
    controller : Controller
    t : ndarray, shape (T,)
    r, r_des : ndarray, shape (T, 8)
        Measured and desired robot states.
    c, c_des : ndarray, shape (T, n_c)
        Measured and desired cluster states in the controller's description.
    e, e_des : ndarray, shape (T, 8)
        Euclidean variables recovered from the measured state by the controller's
        description (``formation.euclidean``), and the desired ones.
    u : ndarray, shape (T, 8)
        Commands sent (saturated, finite).
    raw_finite : ndarray of bool, shape (T,)
        False where the controller's unsaturated command was not finite.
    singularity : ndarray, shape (T,)
        ``formation.singularity_measure`` of the measured state.
    backend : str
        What moved the robots: ``"kinematic"`` (the robots' models) or the physics
        backend's label (``"MuJoCo physics"``); figures name it.
    """

    scenario: Scenario
    controller: Controller
    t: np.ndarray
    r: np.ndarray
    r_des: np.ndarray
    c: np.ndarray
    c_des: np.ndarray
    e: np.ndarray
    e_des: np.ndarray
    u: np.ndarray
    raw_finite: np.ndarray
    singularity: np.ndarray
    backend: str = "kinematic"


def simulate(scenario: Scenario, controller: str | Controller, feedforward: bool | None = None,
             r0=None, progress=None) -> Run:
    """Run ``scenario`` with ``controller`` (a name or an instance).

    Parameters
    ----------
    feedforward : bool, optional
        For a controller given by name: feed the reference's rate forward; default: the
        scenario's ``feedforward`` (an instance keeps its own).
    r0 : array_like, shape (8,), optional
        Initial robot state; default: the reference at ``t = 0`` displaced by the
        scenario's ``initial_offset`` (in Euclidean variables).
    progress : callable, optional
        Called as ``progress(fraction)`` about every 10 % of the run.
    """
    if not isinstance(scenario, Scenario):
        raise InvalidInputError(f"simulate: scenario must be a two-robot Scenario, got {type(scenario).__name__}")
    # up front, before the reference is sampled (a Scenario checks this when built; its
    # fields may have been swapped since by object.__setattr__)
    check_scenario_work(f"scenario {scenario.name!r}", scenario.duration_s, scenario.dt_s)
    ctrl = scenario.controller(controller, feedforward) if isinstance(controller, str) else controller
    F = ctrl.formation
    t = scenario.times
    e_des, _, c_des, cd_des = sample_reference(scenario.path, t, F)
    r_des = RobotSpace().from_euclidean(e_des)
    if r0 is None:
        r0 = EuclideanPair().inverse(e_des[0] + scenario.initial_offset)
    log = closed_loop(t, 1, scenario.dt_s, r0, ctrl.team.step, PerfectMeasurement(), ctrl.compute,
                      lambda k: Reference(c_des[k], cd_des[k], r_des[k]), progress)
    r, c, u, ok = log.states, log.cluster, log.commands, log.raw_finite
    e = F.to_chart(c, near_e=e_des, r=r)
    sing = F.singularity_measure(r, near_c=c_des)
    return Run(scenario, ctrl, t, r, r_des, c, c_des, e, e_des, u, ok, sing)
