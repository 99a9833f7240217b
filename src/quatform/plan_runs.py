"""Plan a motion and write its files; use a plan as a run's reference (top layer, used by the CLI).

``plan_to_dir`` solves a plan spec and writes ``plan.npz``, ``metrics.json`` and the plots;
``scenario_with_plan`` makes a two-robot scenario follow a saved two-robot spatial plan.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from .errors import ConvergenceError, InvalidInputError
from .planning import load_plan_spec, make_plan
from .report.writers import write_json
from .sim.output import check_inputs_outside, staged_dir, writing

__all__ = ["PLAN_FILE", "meet_warning", "plan_alphas_to_dir", "plan_case_to_dir", "plan_to_dir", "scenario_with_plan"]

#: Name of the plan file ``quatform plan`` writes.
PLAN_FILE = "plan.npz"


def _spec_with_alpha(spec, alpha):
    if alpha is None:
        return spec
    if spec.kind != "shaped-geodesic":
        raise InvalidInputError(f"--alpha applies to shaped-geodesic specs; {spec.name} is {spec.kind!r}")
    return dataclasses.replace(spec, options={**spec.options, "alpha": alpha})


def plan_to_dir(spec, out, alpha=None, plots: bool = True):
    """Solve ``spec`` (a name, path or :class:`~quatform.planning.PlanSpec`) into ``out``.

    Writes ``out/plan.npz``, ``out/metrics.json`` and, with ``plots``, ``plan_paths.png``
    and ``plan_separation.png``. Returns ``(plan, metrics)``. A planner failure writes
    ``metrics.json`` with ``converged = false`` and the message, then raises. The folder is
    built by :func:`~quatform.sim.output.staged_dir` (it appears only when complete;
    ``metrics.json`` is written last).
    """
    given = spec
    spec = load_plan_spec(spec) if isinstance(spec, (str, Path)) else spec
    spec = _spec_with_alpha(spec, alpha)
    failure = None
    with staged_dir(out, inputs=(given,)) as tmp:
        try:
            plan, metrics = make_plan(spec)
        except ConvergenceError as exc:
            failure = exc
            write_json({"converged": False, "plan": spec.name, "kind": spec.kind, **spec.options, "error": str(exc)},
                       tmp / "metrics.json")
        else:
            _write_plan(spec, plan, metrics, tmp, plots)
    if failure is not None:
        raise failure
    return plan, metrics


def _write_plan(spec, plan, metrics, out, plots):
    """The files of a solved plan in the folder ``out``; ``metrics.json`` last."""
    with writing(out / PLAN_FILE):  # a full disk names the plan
        plan.save(out / PLAN_FILE)
    if plots:
        from .report.plan_plots import write_plan_plots

        write_plan_plots(plan, out, f"{spec.name} ({spec.source})", spec.min_clearance_m)
        if spec.kind == "rigid-se3":
            from .planning import rigid_formation_dict, rigid_plan_from_spec
            from .report.planning_plots import plot_rigid_formation_paths

            title = f"{spec.name} ({spec.source})" + (f", case {metrics['case']}" if "case" in metrics else "")
            plot_rigid_formation_paths(rigid_plan_from_spec(rigid_formation_dict(spec)), out / "formation_3d.png",
                                       title)
    write_json(metrics, out / "metrics.json")


def plan_case_to_dir(spec, out, case: str, plots: bool = True):
    """:func:`plan_to_dir` of a seed 004 ``[airplanes]`` spec with its ``case`` replaced."""
    check_inputs_outside(out, spec)
    spec = load_plan_spec(spec) if isinstance(spec, (str, Path)) else spec
    if "airplanes" not in spec.options:
        raise InvalidInputError(f"--case applies to specs with an [airplanes] table (seed 004 §4); {spec.name} "
                                "has none")
    spec = dataclasses.replace(spec, options={"airplanes": {**spec.options["airplanes"], "case": case}})
    return plan_to_dir(spec, out, plots=plots)


def plan_alphas_to_dir(spec, out, alphas, plots: bool = True):
    """One plan per ``alpha`` in ``out/alpha-<A>/`` and, with ``plots``, ``out/paths_by_alpha.png``
    (seed 002 Figs. 3-4). Returns ``{alpha: metrics}``; a failed alpha has ``converged = false``."""
    given = spec
    spec = load_plan_spec(spec) if isinstance(spec, (str, Path)) else spec
    plans, rows = {}, {}
    with staged_dir(out, inputs=(given,)) as tmp:
        for a in alphas:
            try:
                plans[a], rows[a] = plan_to_dir(spec, tmp / f"alpha-{a:g}", a, plots)
            except ConvergenceError:
                rows[a] = json.loads((tmp / f"alpha-{a:g}" / "metrics.json").read_text())
        if plots and plans:
            from .report.plan_plots import DPI, plot_alpha_panels

            title = f"{spec.name} ({spec.source})" if spec.source else spec.name
            plot_alpha_panels(plans, title).savefig(tmp / "paths_by_alpha.png", dpi=DPI)
    return rows


def meet_warning(metrics) -> str | None:
    """The warning line for a plan whose robots come closer than the clearance, else None."""
    if not metrics.get("robots_meet"):
        return None
    i, j = metrics["min_separation_robots"]
    return (f"robots {i} and {j} come within {metrics['min_separation_m']:.3g} m of each other at "
            f"t = {metrics['min_separation_time_s']:.3g} s (clearance {metrics['min_clearance_m']:g} m)")


def scenario_with_plan(sc, plan_file, yaws=(0.0, 0.0)):
    """Scenario ``sc`` (two robots, seed 000) with its path replaced by the saved plan
    (:func:`quatform.scenarios.pair.with_plan`: the ``reference`` option of a seed-000 run)."""
    from .scenarios.pair import with_plan

    return with_plan(sc, plan_file, yaws)
