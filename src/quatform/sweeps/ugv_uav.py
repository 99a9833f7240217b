"""The ``ugv-uav`` kind in a sweep (seed 001 §5: a Pioneer and a Bebop under motion capture).

Sweeps layer. A cell's trials run as one batch through the kind's own experiment: B worlds
of :class:`~quatform.sim.plants.ugv_uav.PioneerBebopPlant`, read by one
:class:`~quatform.sim.measurement.MotionCapture` whose schedule draws world ``b`` from the
streams of its ``seed + b`` (:meth:`~quatform.sim.measurement.MotionCapture.schedule`). So
trial ``i`` reads the motion capture of ``seed + i`` (``seed``: the spec's, or the point's
``[vary.seed]`` value, in place of the scenario file's ``seed``): trial ``i`` of a cell equals
``quatform run`` of its scenario with ``seed = seed + i`` and the cell's values, within 1e-9
(tested). The trials of every point and every formation read the same streams (common
random numbers: the formations face the same frames, and a noise axis scales the same
draws).

The point's values set the scenario's motion capture (:data:`MOCAP_KEYS`: ``noise_m`` ->
``mocap_noise_m``, ...), ``gain_scale`` the controller's feedback gains (:data:`GAIN_KEYS`,
eqs. (4.40)-(4.46) of seed 001: ``k_x``, ``k_d``, ``k_w``, ``k_psi``), ``settle_s`` the
scenario's ``transient_s``; ``initial_offset_m`` / ``initial_offset_rad`` move each trial's
start: the UGV's and the UAV's horizontal position (``x_p, y_p, x_b, y_b``, m) and both
headings (``psi_p, psi_b``, rad) by uniforms in ``[-a, a]``, the first draws of the trial's
:func:`~quatform.sweeps.trials.trial_stream` (the UAV stays on the floor, at rest).
"""

from __future__ import annotations

import copy
import dataclasses
import inspect

import numpy as np

from ..control import UgvUavController
from ..scenarios.ugv_uav import LOST_UAV_M, LOST_UGV_M, check_ugv_uav_scenario
from .spec import Parameter, Success, sweep_parameter
from .trials import SWEEP_KINDS, SweepKind, trial_offsets

__all__ = ["UgvUavSweep", "MOCAP_KEYS", "GAIN_KEYS", "OFFSET_COLUMNS"]

#: Sweep parameter -> the scenario's motion-capture key it sets.
MOCAP_KEYS = {"noise_m": "mocap_noise_m", "noise_rad": "mocap_noise_rad", "latency_s": "mocap_latency_s",
              "dropout_rate": "mocap_dropout_rate", "glitch_rate": "mocap_glitch_rate"}
#: The controller's feedback gains ``gain_scale`` multiplies (keywords of UgvUavController).
GAIN_KEYS = ("k_x", "k_d", "k_w", "k_psi")
#: State columns an initial offset moves: by ``initial_offset_m`` (m) and ``initial_offset_rad`` (rad).
OFFSET_COLUMNS = {"m": ("x_p", "y_p", "x_b", "y_b"), "rad": ("psi_p", "psi_b")}

_DEFAULTS = {k: p.default for k, p in inspect.signature(UgvUavController).parameters.items() if k in GAIN_KEYS}


@dataclasses.dataclass(frozen=True)
class UgvUavSweep(SweepKind):
    """How a sweep varies a ``ugv-uav`` scenario (module docstring)."""

    settle_key: str | None = "transient_s"
    #: Default success: after the transient the UGV within 0.1 m and the UAV within 0.4 m of
    #: their references (the kind's own ``reference_lost`` bounds), and the screen never stopped the run.
    success: object = Success({"max_ugv_position_error_m": LOST_UGV_M, "max_uav_position_error_m": LOST_UAV_M},
                              ("reference_lost", "run_stopped"))

    scenario_keys: tuple = tuple(MOCAP_KEYS)

    def robots(self, exp) -> int:
        return 2

    def scenario(self, sc, values: dict):
        own = {MOCAP_KEYS[k]: float(v) for k, v in values.items() if k in self.scenario_keys}
        if not own:
            return sc
        sc = dataclasses.replace(sc, **own)
        check_ugv_uav_scenario(sc, f"scenario {sc.name} with {', '.join(f'{k} = {v:g}' for k, v in own.items())}")
        return sc

    def gains(self, sc, choice: str) -> dict:
        return {k: sc.gains.get(k, _DEFAULTS[k]) for k in GAIN_KEYS}

    def with_gains(self, sc, choice: str, gains: dict):
        sc = dataclasses.replace(sc, gains={**sc.gains, **gains})
        check_ugv_uav_scenario(sc)
        sc.controller(choice)  # the gains make a controller
        return sc

    def batch(self, exp, values: dict, seed: int, point: int, trials: list):
        columns = tuple(exp.plant.state_columns)
        moved = [(columns.index(c), values.get(f"initial_offset_{unit}", 0.0))
                 for unit, names in OFFSET_COLUMNS.items() for c in names]
        off = trial_offsets(seed, point, trials, len(moved))  # (B, 6), in OFFSET_COLUMNS' order
        x0 = np.repeat(np.asarray(exp.x0, dtype=float)[None], len(trials), axis=0)
        for j, (col, a) in enumerate(moved):
            x0[:, col] += a * off[:, j]
        mocap = copy.copy(exp.measurement)  # settings only: world b reads the streams of seed + b
        mocap.seed = int(seed) + int(trials[0])
        delay = int(round(exp.scenario.mocap_latency_s / (exp.substeps * exp.dt)))  # the cell's, in control ticks
        return dataclasses.replace(exp, x0=x0, measurement=mocap, finish=lambda log: log), delay


sweep_parameter(Parameter("glitch_rate", "1", "probability that a motion-capture frame reads the UAV's marker at the "
                          "UGV", high=1.0, high_open=True, kinds=("ugv-uav",)))
SWEEP_KINDS.add("ugv-uav", UgvUavSweep("ugv-uav"))
