"""The ``teleop`` kind in a sweep (seed 003: the Kraft master and the 7-DOF slave).

Sweeps layer. A cell's trials run as one batch through the kind's own experiment (B worlds
of :class:`~quatform.sim.plants.teleop.TeleopPlant`: on NumPy world by world, on JAX
``vmap``-ed). The kind has no measurement model (the controller reads the plant's state), so
noise, latency and lost frames are not its parameters. A trial differs from another by its
start: ``initial_offset_rad`` moves every joint angle of both arms (``q_m1..q_m6``,
``q_s1..q_s7``) by uniforms in ``[-a, a]``, the first draws of the trial's
:func:`~quatform.sweeps.trials.trial_stream` (the arms at rest); the operator's hand, the push
and the registration stay the scenario's (the homes). ``gain_scale`` multiplies the
controller's stiffness and damping (:data:`GAIN_NAMES`: ``gains_master.kp_pos`` ... of the
scenario's ``[controller]``; each arm's springs are checked against the integration's
stability limit before anything runs), ``preload`` switches the preload function (seed 003
§6) off (0) or on (1). ``duration_s`` keeps the ``holds_s`` within it; the kind has no
settling time (``settle_s`` is refused).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..control.stiffness import StiffnessGains
from ..scenarios.teleop import check_teleop_stiffness
from .spec import Parameter, Success, sweep_parameter
from .trials import SWEEP_KINDS, SweepKind, trial_offsets

__all__ = ["TeleopSweep", "GAIN_NAMES", "OFFSET_COLUMNS"]

_ARMS = ("gains_master", "gains_slave")
_GAINS = tuple(f.name for f in dataclasses.fields(StiffnessGains))
#: The names ``gain_scale`` knows: ``<arm>.<gain>`` of the scenario's ``[controller]``.
GAIN_NAMES = tuple(f"{arm}.{g}" for arm in _ARMS for g in _GAINS)
#: State columns ``initial_offset_rad`` moves: every joint angle of both arms, rad.
OFFSET_COLUMNS = tuple(f"q_m{i + 1}" for i in range(6)) + tuple(f"q_s{i + 1}" for i in range(7))


def _preload(sc, value, spec, choice):
    """``sc`` with the preload function off (0) or on (1)."""
    return dataclasses.replace(sc, preload=bool(value))


@dataclasses.dataclass(frozen=True)
class TeleopSweep(SweepKind):
    """How a sweep varies a ``teleop`` scenario (module docstring)."""

    cannot: tuple = ("noise_m", "noise_rad", "latency_s", "dropout_rate", "initial_offset_m")
    settle_key: str | None = None
    #: Default success: at the end of the run the slave's tool within 1 cm and 0.05 rad of the
    #: registered master's.
    success: object = Success({"final_position_error_m": 0.01, "final_orientation_error_rad": 0.05}, ())

    def robots(self, exp) -> int:
        return 2

    def shorten(self, sc, duration_s, settle_s):
        if duration_s is None:
            return sc
        return dataclasses.replace(sc, duration_s=duration_s, holds=tuple(h for h in sc.holds if h <= duration_s))

    def gains(self, sc, choice: str) -> dict:
        return {f"{arm}.{g}": getattr(getattr(sc, arm), g) for arm in _ARMS for g in _GAINS}

    def with_gains(self, sc, choice: str, gains: dict):
        arms = {arm: StiffnessGains(**{g: gains[f"{arm}.{g}"] for g in _GAINS}) for arm in _ARMS}
        sc = dataclasses.replace(sc, **arms)
        check_teleop_stiffness(sc)
        return sc

    def batch(self, exp, values: dict, seed: int, point: int, trials: list):
        columns = tuple(exp.plant.state_columns)
        off = trial_offsets(seed, point, trials, len(OFFSET_COLUMNS))  # (B, 13), in OFFSET_COLUMNS' order
        x0 = np.repeat(np.asarray(exp.x0, dtype=float)[None], len(trials), axis=0)
        a = values.get("initial_offset_rad", 0.0)
        for j, c in enumerate(OFFSET_COLUMNS):
            x0[:, columns.index(c)] += a * off[:, j]
        return dataclasses.replace(exp, x0=x0, finish=lambda log: log), 0


sweep_parameter(Parameter("preload", "1", "the teleop master's preload function off (0) or on (1)", low=0,
                          high=1, integer=True, kinds=("teleop",), apply=_preload))
SWEEP_KINDS.add("teleop", TeleopSweep("teleop"))
