"""Run and compare scenarios and write their files (top layer, used by the CLI).

``run_scenario`` writes ``metrics.json``, ``timeseries.csv`` and the PNG plots of one
controller; ``compare_scenario`` runs all four controllers of seed 000 into
sub-folders and adds Fig. 13 and a table.

Every public ``run_*`` / ``compare_*`` function builds its output folder with
:func:`~quatform.sim.output.staged_dir`: the files appear under ``out`` only when the whole
run has finished (``metrics.json`` is written last); a failed or interrupted run leaves
``out`` as it was.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from .control import CONTROLLERS
from .scenarios.pair import BACKENDS, TABLE_COLUMNS, pair_csv_channels, run_pair
from .sim import (
    compute_metrics,
    load_scenario,
    write_columns,
    write_metrics,
    write_timeseries,
)
from .scenarios.teleop import TELEOP_COLUMNS
from .sim.output import atomic_write_text, staged_dir, write_json

__all__ = ["run_scenario", "compare_scenario", "format_table", "TABLE_COLUMNS", "run_ugv_uav",
           "compare_ugv_uav", "UGV_UAV_COLUMNS", "run_teleop", "TELEOP_COLUMNS", "BACKENDS", "physics_rows"]

def _progress(label):
    """Progress on a terminal (one updating line); nothing when stderr is a file or pipe."""
    if not sys.stderr.isatty():
        return None

    def report(fraction):
        print(f"\r  {label}: {fraction:4.0%}", end="", file=sys.stderr, flush=True)
    return report


def run_ugv_uav(sc, formation: str, out, plots: bool = True, quiet: bool = False, backend: str = "kinematic"):
    """A seed 001 run: ``metrics.json``, ``timeseries.csv``, plots; returns ``(run, metrics)``.

    ``backend="mujoco"``: a Pioneer-like UGV and an IRIS-like quadrotor in MuJoCo; the
    metrics add ``collisions``, ``render`` and the kinematic run's errors (``kinematic``).
    """
    _check_backend(backend)
    with staged_dir(out) as tmp:
        return _ugv_uav_into(sc, formation, tmp, Path(out), plots, quiet, backend)


def _ugv_uav_into(sc, formation, out, label, plots, quiet, backend):
    """:func:`run_ugv_uav` writing into the folder ``out`` (made here; ``label``: the name printed)."""
    from .scenarios.ugv_uav import UGV_UAV_KIND

    out.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    progress = None if quiet else _progress(f"{sc.name} / {formation} / {backend}")
    exp = UGV_UAV_KIND.experiment(sc, formation=formation, backend=backend)
    log = exp.run(progress)
    metrics = exp.metrics(log)
    metrics["wall_time_s"] = round(time.perf_counter() - t0, 3)
    write_columns(*log.table(exp.csv_channels), out / "timeseries.csv")
    if plots:
        from .report.ugv_uav_plots import write_ugv_uav_run_plots

        write_ugv_uav_run_plots(log, out)
    if backend == "mujoco":
        metrics["render"] = None
        if plots:
            from .report.physics_render import RENDER_FILE, render_or_fallback

            file, how = render_or_fallback(log.meta["physics_record"], log, out / RENDER_FILE)
            metrics["render"], metrics["render_backend"] = file.name, how
    write_metrics(metrics, out / "metrics.json")
    if not quiet:
        if log.meta["unreachable_at"] is not None:
            print(f"  {sc.name} / {formation}: reference unreachable from t = {log.meta['unreachable_at']:.2f} s: "
                  f"{log.meta['unreachable_message']}", file=sys.stderr)
        print(f"\r  {sc.name} / {formation}: done in {metrics['wall_time_s']:.1f} s -> {label}", file=sys.stderr)
    return log, metrics


UGV_UAV_COLUMNS = (
    ("formation", "formation", "{}"),
    ("unreachable_reference", "unreachable", "{}"),
    ("first_singular_time_s", "singular at (s)", "{:.2f}"),
    ("max_ugv_position_error_m", "UGV (m)", "{:.3f}"),
    ("max_uav_position_error_m", "UAV (m)", "{:.3f}"),
    ("max_uav_yaw_error_rad", "UAV yaw (rad)", "{:.3f}"),
    ("max_unexplained_cluster_jump", "state jump", "{:.1e}"),
    ("mocap_dropped_frames", "mocap dropped", "{}"),
    ("mocap_rejected_frames", "mocap rejected", "{}"),
    ("nonfinite_commands", "NaN cmds", "{}"),
)


def compare_ugv_uav(sc, out, quiet: bool = False):
    """Run the three descriptions of seed 001 on one scenario; plots, table; return the rows."""
    from .scenarios.ugv_uav import UGV_UAV_FORMATIONS

    with staged_dir(out) as tmp:
        runs, rows = [], []
        for name in UGV_UAV_FORMATIONS:
            run, m = _ugv_uav_into(sc, name, tmp / name, Path(out) / name, True, quiet, "kinematic")
            runs.append(run)
            rows.append(m)
        from .report.ugv_uav_plots import write_ugv_uav_compare_plots

        write_ugv_uav_compare_plots(runs, tmp)
        table = format_table(rows, UGV_UAV_COLUMNS)
        atomic_write_text(tmp / "comparison.md", f"# {sc.name}: {sc.title}\n\nSource: {sc.source}\n\n{table}\n")
        write_json(rows, tmp / "comparison.json")
    return rows


def _check_backend(backend):
    if backend not in BACKENDS:
        from .errors import InvalidInputError

        raise InvalidInputError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")


#: Metrics of the kinematic run that a physics run's ``metrics.json`` repeats beside its own.
_COMPARED_KEYS = ("reference_lost", "nonfinite_commands", "unreachable_reference", "max_unexplained_cluster_jump",
                  "first_lost_time_s", "first_singular_time_s", "max_cluster_position_error_m",
                  "max_shape_error_m", "max_orientation_error_rad", "max_robot_position_error_m",
                  "max_robot_yaw_error_rad", "max_recovered_euclidean_error_rad", "min_robot_separation_m",
                  "max_ugv_position_error_m", "max_uav_position_error_m", "max_uav_yaw_error_rad")


def _add_physics(metrics, record, run, kinematic_metrics, out, plots):
    """The physics run's own keys: backend, step, collisions, picture, the kinematic errors."""
    metrics["backend"] = "mujoco"
    metrics.update(record.metrics())  # gains, gains_source (+ note), physics_timestep_s
    metrics["collisions"] = record.collisions
    metrics["render"] = None
    if plots:
        from .report.physics_render import RENDER_FILE, render_or_fallback

        file, how = render_or_fallback(record, run, out / RENDER_FILE)
        metrics["render"], metrics["render_backend"] = file.name, how
    metrics["kinematic"] = {k: kinematic_metrics[k] for k in _COMPARED_KEYS if k in kinematic_metrics}


def physics_rows(metrics) -> list:
    """Two table rows of a physics run: the kinematic run's errors, then the physics run's."""
    label = metrics["controller"]
    if "kinematic" not in metrics:  # a run on one backend (the UGV-UAV kind: compare over the backend)
        return [dict(metrics, controller=f"{label} (mujoco)", formation=f"{metrics['formation']} (mujoco)")]
    return [dict(metrics["kinematic"], controller=f"{label} (kinematic)", formation=f"{metrics['formation']} (kinematic)"),
            dict(metrics, controller=f"{label} (mujoco)", formation=f"{metrics['formation']} (mujoco)")]


def _feedforward(sc, feedforward):
    """The feedforward switch of a run: ``feedforward`` when given, else the scenario's (default on)."""
    return bool(getattr(sc, "feedforward", True)) if feedforward is None else bool(feedforward)


def run_scenario(scenario, controller: str, out, plots: bool = True, quiet: bool = False,
                 backend: str = "kinematic", feedforward: bool | None = None):
    """Simulate, write ``out/metrics.json``, ``out/timeseries.csv`` and plots; return the metrics.

    ``backend="mujoco"``: two IRIS-like quadrotors in MuJoCo; the metrics add
    ``collisions``, ``render`` (the time-lapse picture) and the kinematic run's errors
    (``kinematic``). ``feedforward=False`` drops the reference-velocity feedforward of the
    controller (seed 000 Fig. 13 runs without it); ``None`` takes the scenario's setting.
    ``metrics.json`` records it as ``feedforward``.
    """
    _check_backend(backend)
    sc = load_scenario(scenario) if not hasattr(scenario, "path") else scenario
    with staged_dir(out) as tmp:
        return _pair_into(sc, controller, tmp, Path(out), plots, quiet, backend, _feedforward(sc, feedforward))


def _pair_into(sc, controller, out, label, plots, quiet, backend, ff):
    """:func:`run_scenario` writing into the folder ``out`` (made here; ``label``: the name printed)."""
    out.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    progress = None if quiet else _progress(f"{sc.name} / {controller} / {backend}")
    if backend == "mujoco":
        from .scenarios.pair import simulate_physics

        run, record = simulate_physics(sc, controller, feedforward=ff, progress=progress)
    else:
        run = run_pair(sc, controller, feedforward=ff, progress=progress)
    metrics = compute_metrics(run)
    metrics["feedforward"] = ff
    metrics["wall_time_s"] = round(time.perf_counter() - t0, 3)
    if backend == "mujoco":
        _add_physics(metrics, record, run, compute_metrics(run_pair(sc, controller, feedforward=ff)), out, plots)
    write_timeseries(run, out / "timeseries.csv", pair_csv_channels(run.meta["formation"]))
    if plots:
        from .report import write_run_plots

        write_run_plots(run, out)
    write_metrics(metrics, out / "metrics.json")
    if not quiet:
        print(f"\r  {sc.name} / {controller}: done in {metrics['wall_time_s']:.1f} s -> {label}", file=sys.stderr)
    return run, metrics


def format_table(rows, columns=TABLE_COLUMNS) -> str:
    """A Markdown table of metrics rows."""
    head = "| " + " | ".join(h for _, h, _ in columns) + " |"
    sep = "|" + "|".join("---" for _ in columns) + "|"
    lines = [head, sep]
    for m in rows:
        cells = ["-" if m.get(k) is None else fmt.format(m[k]) for k, _, fmt in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def compare_scenario(scenario, out, quiet: bool = False, backend: str = "kinematic",
                     feedforward: bool | None = None):
    """Run every controller; write their folders, ``compare_errors.png``, ``separation.png``,
    ``comparison.json`` and ``comparison.md``; return the metrics rows (a physics backend:
    each run's kinematic row above its own). ``feedforward`` as in :func:`run_scenario`."""
    _check_backend(backend)
    sc = load_scenario(scenario) if not hasattr(scenario, "path") else scenario
    ff = _feedforward(sc, feedforward)
    with staged_dir(out) as tmp:
        runs, rows = [], []
        for name in CONTROLLERS:
            run, m = _pair_into(sc, name, tmp / name, Path(out) / name, True, quiet, backend, ff)
            runs.append(run)
            rows.extend(physics_rows(m) if backend == "mujoco" else [m])
        from .report import write_compare_plots

        write_compare_plots(runs, tmp)
        table = format_table(rows)
        feed = "" if ff else " (no feedforward)"
        atomic_write_text(tmp / "comparison.md",
                          f"# {sc.name}: {sc.title}{feed}\n\nSource: {sc.source}\n\n{table}\n")
        write_json(rows, tmp / "comparison.json")
    return rows


def run_teleop(sc, out, orientation_error=None, preload=None, plots: bool = True, quiet: bool = False):
    """A seed 003 run: ``metrics.json``, ``timeseries.csv``, plots; returns ``(log, metrics)``."""
    from .scenarios.teleop import TELEOP

    exp = TELEOP.experiment(sc, orientation_error=orientation_error, preload=preload)
    with staged_dir(out) as tmp:
        t0 = time.perf_counter()
        log = exp.run(progress=None if quiet else _progress(sc.name))
        metrics = exp.metrics(log)
        metrics["wall_time_s"] = round(time.perf_counter() - t0, 3)
        write_columns(*log.table(exp.csv_channels), tmp / "timeseries.csv")
        if plots:
            from .report.teleop_plots import write_teleop_plots

            write_teleop_plots(log, tmp)
        write_metrics(metrics, tmp / "metrics.json")
    if not quiet:
        print(f"\r  {sc.name}: done in {metrics['wall_time_s']:.1f} s -> {out}", file=sys.stderr)
    return log, metrics
