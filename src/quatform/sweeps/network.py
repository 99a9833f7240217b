"""The ``network`` kind in a sweep: decentralised formations over delay, loss, rates, topology and gains.

Sweeps layer. A cell's trials run as one batch through the kind's own experiment
(:class:`~quatform.control.networked.NetworkedController`: B worlds, each drawing its links
from its own seed). Trial ``i`` draws its links from ``seed + i`` (``seed``: the spec's, or
the point's ``[vary.seed]`` value, in place of the scenario's ``[links] seed``) and its start
(the scenario's ``[initial]`` offsets and turns, ``initial_offset_m`` / ``initial_offset_rad``
in place of its ``position_m`` / ``angle_rad`` where varied) from
:func:`~quatform.sweeps.trials.trial_stream`. So the trials of every point and every law
read the same link uniforms (``Links``: one seed draws the same uniforms at any delay, loss
or rate) and the same starts (common random numbers), and trial ``i`` of a cell equals
``quatform run`` of its scenario with that seed and start (tested).

The point's values set the links (:data:`LINK_PARAMETERS`: ``link_delay_s`` ->
``delay_s`` ...), the topology (``graph_k``: a k-nearest graph of the desired points at
``t = 0``) and, with ``gain_scale``, the law's gains (its numeric fields).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import InvalidInputError
from ..network import Graph
from ..scenarios.network import NetworkScenario, desired_at_zero, start_points
from .spec import Parameter, Success, sweep_parameter
from .trials import SWEEP_KINDS, SweepKind, trial_stream

__all__ = ["NetworkSweep", "LINK_PARAMETERS"]

#: Sweep parameter -> the ``Links`` field it sets (for every edge or robot).
LINK_PARAMETERS = {"link_delay_s": "delay_s", "link_jitter_s": "jitter_s", "link_drop": "drop",
                   "send_rate_hz": "rate_hz", "max_age_s": "max_age_s"}


def _axis(name: str, value, spec, build):
    """``build()``, its one-line refusal naming the spec and the ``[vary]`` axis."""
    try:
        sc = build()
        sc.controller()
        return sc
    except InvalidInputError as exc:
        raise type(exc)(f"{spec.where}: [vary.{name}] value {value:g}: {exc}") from None


def _links(sc: NetworkScenario, value, spec, choice, field: str, name: str):
    return _axis(name, value, spec,
                 lambda: dataclasses.replace(sc, links=dataclasses.replace(sc.links, **{field: float(value)})))


def _graph_k(sc: NetworkScenario, value, spec, choice):
    """``sc`` with each robot hearing its ``value`` nearest (of the desired points at ``t = 0``)."""
    def build():
        pos = sc.team.layout.positions(desired_at_zero(sc.team, sc.motion))
        graph = Graph.k_nearest(pos, int(value))
        return dataclasses.replace(sc, links=dataclasses.replace(sc.links, graph=graph), switching=None)

    return _axis("graph_k", value, spec, build)


@dataclasses.dataclass(frozen=True)
class NetworkSweep(SweepKind):
    """How a sweep varies a ``network`` scenario (module docstring)."""

    cannot: tuple = ("noise_m", "noise_rad", "latency_s", "dropout_rate")
    #: Default success: the consensus error at the end at or under the scenario's
    #: ``converged_below``, every command finite and no two robots closer than the separation
    #: filter's distance.
    success: object = Success({"nonfinite_commands": 1}, (), ("converged", "separation_kept"))

    def gains(self, sc, choice: str) -> dict:
        law = sc.law
        return {f.name: getattr(law, f.name) for f in dataclasses.fields(law)
                if isinstance(getattr(law, f.name), (int, float)) and not isinstance(getattr(law, f.name), bool)}

    def with_gains(self, sc, choice: str, gains: dict):
        sc = dataclasses.replace(sc, law=dataclasses.replace(sc.law, **gains))
        sc.controller()  # the law, robots and links still fit
        return sc

    def batch(self, exp, values: dict, seed: int, point: int, trials: list):
        sc = exp.scenario
        initial = dict(sc.initial)
        for key, field in (("initial_offset_m", "position_m"), ("initial_offset_rad", "angle_rad")):
            if key in values:
                initial[field] = float(values[key])
        if initial.get("angle_rad", 0.0) > np.pi:
            raise InvalidInputError(f"sweep: initial_offset_rad = {initial['angle_rad']:g} turns a robot by more than "
                                    f"pi (the same turn the other way round); give at most {np.pi:.6g} rad")
        r0 = np.asarray(exp.reference(0)["robots"], dtype=float)
        x0 = np.stack([start_points(dataclasses.replace(sc, initial={
            **initial, "seed": int(trial_stream(seed, point, i).integers(2**63 - 1))}), r0) for i in trials])
        ctrl = exp.controller
        links = dataclasses.replace(ctrl.links, seed=int(seed) + int(trials[0]))  # world b: seed + trials[0] + b
        ctrl = dataclasses.replace(ctrl, links=links)
        return dataclasses.replace(exp, x0=x0, controller=ctrl, finish=lambda log: log), 0


for _name, _field, _unit, _help, _extra in (
        ("link_delay_s", "delay_s", "s", "transport delay of every link", {}),
        ("link_jitter_s", "jitter_s", "s", "width of every link's uniform extra delay", {}),
        ("link_drop", "drop", "1", "probability that a message is lost on any link", {"high": 1.0}),
        ("send_rate_hz", "rate_hz", "Hz", "every robot's send rate (at most the control rate)", {"low": 1e-9}),
        ("max_age_s", "max_age_s", "s", "age beyond which a robot drops a message as stale", {"low": 1e-9})):
    sweep_parameter(Parameter(_name, _unit, _help, kinds=("network",), **_extra,
                              apply=lambda sc, value, spec, choice, _f=_field, _n=_name: _links(sc, value, spec, choice,
                                                                                                  _f, _n)))
sweep_parameter(Parameter("graph_k", "robots", "each robot hears its k nearest (a k-nearest graph of the desired "
                          "points at t = 0)", low=1, high=100_000, integer=True, kinds=("network",), apply=_graph_k))
SWEEP_KINDS.add("network", NetworkSweep("network"))
