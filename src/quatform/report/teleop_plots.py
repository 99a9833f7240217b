"""Report layer: PNG figures of a teleoperation run (seed 003; above sim).

* :func:`plot_teleop_tracking` - master (registered) and slave tool positions, the
  position error and the true orientation error against time;
* :func:`plot_teleop_torques` - master and slave joint torques with their limits;
* :func:`plot_teleop_orientation` - roll-pitch-yaw angles of both tools, the pitch ±90 deg
  lines marked and the samples within :data:`GIMBAL_LOCK_DEG` of them shaded (roll and yaw
  undefined there: neither they nor their difference is drawn);
* :func:`plot_teleop_contact` - the slave's contact force against eq. (13)'s prediction
  and the force reflected to the operator (scenarios with a wall);
* :func:`plot_teleop_hysteresis` - master-slave error against the slave's position along
  the push (scenarios with a push: the preload's hysteresis loop);
* :func:`plot_teleop_virtual_wall` - the master's depth into its virtual walls and the
  hand's force;
* :func:`write_teleop_compare_plots` - the runs of a compare (one per orientation error) side
  by side: the position and orientation errors and the slave's torques against time.

Each reads the finished :class:`~quatform.sim.log.Log` of a run of the ``teleop`` kind
(:func:`quatform.scenarios.teleop.teleop_finish`; its ``meta`` holds the scenario and the
controller). Each figure is drawn on its own Agg canvas; nothing touches pyplot's global state.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..algebra import wrap_angle
from ..sim.log import Log
from ..teleop import rpy_from_q
from .figures import break_wraps, decimate, new_figure, save
from .figure_set import FIGURES, FigureSet

__all__ = ["plot_teleop_tracking", "plot_teleop_torques", "plot_teleop_orientation", "plot_teleop_contact",
           "plot_teleop_hysteresis", "plot_teleop_virtual_wall", "write_teleop_plots", "write_teleop_compare_plots"]


@dataclass(frozen=True)
class _Traces:
    """What the figures draw, from a teleop log: ``T`` samples (see ``teleop_finish``)."""

    scenario: object
    controller: object
    t: np.ndarray
    p_m: np.ndarray
    r_m: np.ndarray
    p_s: np.ndarray
    r_s: np.ndarray
    angle: np.ndarray
    tau_m: np.ndarray
    tau_s: np.ndarray
    F_s: np.ndarray
    F_hand: np.ndarray
    F_reflected: np.ndarray
    wall_depth: np.ndarray

    @classmethod
    def of(cls, log: Log) -> _Traces:
        ctrl = log.meta["teleop_controller"]
        n_m = ctrl.master.n
        u = log["command"]
        return cls(log.meta["scenario"], ctrl, log.t, log["p_m"], log["r_m"], log["p_s"], log["r_s"],
                   log["angle"][:, 0], u[:, :n_m], u[:, n_m:], log["F_s"], log["F_hand"], log["F_reflected"],
                   log["wall_depth"])


def _title(log: Log) -> str:
    c = log.meta["teleop_controller"]
    return (f"Jansen et al. 1990, {log.meta['scenario'].name}: {c.orientation_error} error, "
            f"preload {'on' if c.preload_nm is not None else 'off'}")


def _rpy_traces(r_m, r_s):
    """Roll, pitch, yaw of both tools for plotting, rad, ``(T, 3)`` each.

    The master's angles are unwrapped (no jump of 2 pi at +-180 deg); the slave's are drawn
    as the master's plus the wrapped difference ``wrap(rpy_s - rpy_m)``, so a slave roll of
    -180 deg against a master's +180 deg (the same orientation) reads as no error, and the
    gap between the two lines is what the RPY law takes as its error. Jumps that are left
    (roll and yaw jump by 180 deg through pitch +-90 deg: the angles are not defined there)
    are broken, not drawn as vertical lines.
    """
    a_m, a_s = rpy_from_q(r_m), rpy_from_q(r_s)
    m = np.unwrap(a_m, axis=0)
    s = m + wrap_angle(a_s - a_m)
    return tuple(np.stack([break_wraps(x[:, k], np.pi / 2) for k in range(3)], axis=1) for x in (m, s))


#: Half-width of the band around pitch ±90 deg shaded as gimbal lock, deg: within it roll and
#: yaw are individually undefined (only roll - yaw at +90 deg, roll + yaw at -90 deg is), so a
#: roll of -180 deg against 0 deg there is the same orientation, not an error. 3 deg holds the
#: whole branch switch of teleop-pitch-through-90 (both tools within 1.4 deg of -90 deg).
GIMBAL_LOCK_DEG = 3.0


@dataclass(frozen=True)
class _OrientationTraces:
    """What :func:`plot_teleop_orientation` draws, rad, ``T`` samples.

    ``master``, ``slave`` ``(T, 3)``: roll, pitch, yaw (:func:`_rpy_traces`), roll and yaw NaN
    where ``lock``; ``lock`` ``(T,)``: either tool's ``|pitch|`` within ``lock_deg`` of 90 deg;
    ``rpy_difference`` ``(T,)``: ``|wrap(rpy_s - rpy_m)|``, NaN where ``lock``; ``angle``
    ``(T,)``: the angle between the tools (defined everywhere: the error line).
    """

    master: np.ndarray
    slave: np.ndarray
    lock: np.ndarray
    rpy_difference: np.ndarray
    angle: np.ndarray


def _orientation_traces(r_m, r_s, angle, lock_deg: float = GIMBAL_LOCK_DEG) -> _OrientationTraces:
    """The traces of the orientation figure with the gimbal-lock band masked (:class:`_OrientationTraces`)."""
    rpy_m, rpy_s = rpy_from_q(r_m), rpy_from_q(r_s)
    lock = np.maximum(np.abs(rpy_m[:, 1]), np.abs(rpy_s[:, 1])) >= np.radians(90.0 - lock_deg)
    a_m, a_s = _rpy_traces(r_m, r_s)
    for a in (a_m, a_s):
        a[lock, 0] = np.nan
        a[lock, 2] = np.nan
    diff = np.linalg.norm(wrap_angle(rpy_s - rpy_m), axis=1)
    diff[lock] = np.nan
    return _OrientationTraces(a_m, a_s, lock, diff, np.asarray(angle, dtype=float))


def _spans(t, mask):
    """``(start, end)`` times of each run of True in ``mask`` (half a sample beyond each end)."""
    t, mask = np.asarray(t, dtype=float), np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    half = 0.5 * (t[1] - t[0]) if t.size > 1 else 0.0
    return [(t[a] - half, t[b - 1] + half) for a, b in zip(edges[0::2], edges[1::2])]


def plot_teleop_tracking(log: Log, path) -> Path:
    """Tool positions of master and slave, and the errors between them."""
    run = _Traces.of(log)
    i = decimate(len(run.t))
    t = run.t[i]
    fig = new_figure((10, 7))
    axes = fig.subplots(2, 2, sharex=True)
    for k, lab in enumerate("xyz"):
        ax = axes.flat[k]
        ax.plot(t, run.p_m[i, k], color="C3", ls="--", lw=1.0, label="master (registered)")
        ax.plot(t, run.p_s[i, k], color="C0", lw=1.2, label="slave")
        ax.set_ylabel(f"{lab} (m)")
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=8)
    ax = axes.flat[3]
    ax.semilogy(t, np.maximum(np.linalg.norm(run.p_s - run.p_m, axis=1)[i], 1e-9), color="C0", label="position (m)")
    ax.semilogy(t, np.maximum(run.angle[i], 1e-9), color="C2", label="orientation (rad)")
    ax.set_ylabel("|slave - master|")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    for ax in axes[1]:
        ax.set_xlabel("t (s)")
    fig.suptitle(_title(log))
    return save(fig, path)


def plot_teleop_torques(log: Log, path) -> Path:
    """Joint torques sent to each arm, with the limits dashed."""
    run = _Traces.of(log)
    i = decimate(len(run.t))
    t = run.t[i]
    fig = new_figure((10, 6))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, tau, lim, name in ((axes[0], run.tau_m, run.controller.master_limits, "master"),
                               (axes[1], run.tau_s, run.controller.slave_limits, "slave")):
        for j in range(tau.shape[1]):
            if lim[j] > 0:
                ax.plot(t, tau[i, j], lw=1.0, color=f"C{j}", label=f"joint {j + 1}")
        ax.set_ylabel(f"{name} torque (N m)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=4)
        top = float(np.abs(tau).max())
        for j in np.unique(lim[lim > 0]):
            if j <= 1.5 * max(top, 1e-9):
                ax.axhline(j, color="k", ls=":", lw=0.8)
                ax.axhline(-j, color="k", ls=":", lw=0.8)
    axes[1].set_xlabel("t (s)")
    fig.suptitle(_title(log) + " - torques (limits dotted)", fontsize=10)
    return save(fig, path)


def plot_teleop_orientation(log: Log, path) -> Path:
    """Roll, pitch, yaw of both tools (slave base axes, :func:`_rpy_traces`); pitch ±90 deg marked.

    The samples within :data:`GIMBAL_LOCK_DEG` of pitch ±90 deg are shaded; roll, yaw and the
    wrapped RPY difference are not drawn there (:func:`_orientation_traces`), the angle
    between the tools is.
    """
    run = _Traces.of(log)
    i = decimate(len(run.t))
    t = run.t[i]
    tr = _orientation_traces(run.r_m[i], run.r_s[i], run.angle[i])
    a_m, a_s = np.degrees(tr.master), np.degrees(tr.slave)
    spans = _spans(t, tr.lock)
    lock_label = f"gimbal lock (|pitch| > {90 - GIMBAL_LOCK_DEG:g}°): roll, yaw undefined"
    fig = new_figure((10, 6.5))
    axes = fig.subplots(4, 1, sharex=True)
    for ax in axes:
        for k, (t0, t1) in enumerate(spans):
            ax.axvspan(t0, t1, color="0.8", alpha=0.6, lw=0,
                       label=lock_label if k == 0 else None)
    for k, name in enumerate(("roll", "pitch", "yaw")):
        ax = axes[k]
        ax.plot(t, a_m[:, k], color="C3", ls="--", lw=1.0, label="master")
        ax.plot(t, a_s[:, k], color="C0", lw=1.2, label="slave")
        ax.set_ylabel(f"{name} (deg)")
        ax.grid(alpha=0.3)
        both = np.concatenate([a_m[:, k], a_s[:, k]])
        if np.isfinite(both).any():
            lo, hi = np.nanmin(both), np.nanmax(both)
            if hi - lo < 2.0:  # a still angle: a 2 deg window, not an axis of 1e-10 deg with an offset
                ax.set_ylim(0.5 * (lo + hi) - 1.0, 0.5 * (lo + hi) + 1.0)
        if name == "pitch":
            for y in (-90, 90):
                ax.axhline(y, color="r", ls=":", lw=0.8)
    axes[0].legend(fontsize=8)
    axes[3].semilogy(t, np.maximum(tr.angle, 1e-9), color="C2", label="angle between the tools")
    axes[3].semilogy(t, np.maximum(tr.rpy_difference, 1e-9), color="C1", ls="--", lw=1.0,
                     label="|wrapped RPY difference| (the RPY law's error; not drawn in gimbal lock)")
    axes[3].legend(fontsize=7)
    axes[3].set_ylabel("error (rad)")
    axes[3].set_xlabel("t (s)")
    axes[3].grid(alpha=0.3, which="both")
    fig.suptitle(_title(log) + "\nroll-pitch-yaw (gimbal lock at pitch ±90°); the slave drawn as the master + the "
                 "wrapped difference", fontsize=10)
    return save(fig, path)


def plot_teleop_contact(log: Log, path) -> Path:
    """Contact force against eq. (13), and the force reflected to the operator."""
    run = _Traces.of(log)
    sc = run.scenario
    i = decimate(len(run.t))
    t = run.t[i]
    n = np.asarray(sc.wall.normal, float)
    n = n / np.linalg.norm(n)
    F = -run.F_s @ n  # the wall's push on the slave, along its normal
    F13 = -(sc.gains_slave.kp[0:3] * (run.p_m - run.p_s)) @ n
    refl = np.linalg.norm(run.F_reflected, axis=1)
    fig = new_figure((10, 4.5))
    ax = fig.subplots()
    ax.plot(t, F[i], color="C0", lw=1.4, label="contact force (N)")
    ax.plot(t, F13[i], color="C3", ls="--", lw=1.0, label="eq. (13): K_ps (x_m - x_s)")
    ax.plot(t, refl[i], color="C2", lw=1.0, label="reflected to the operator (N)")
    for h in sc.holds:
        ax.axvline(h, color="k", ls=":", lw=0.8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("force (N)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(_title(log) + " - contact (holds dotted)", fontsize=10)
    return save(fig, path)


def plot_teleop_hysteresis(log: Log, path) -> Path:
    """Master-slave error against the slave's displacement along the first push."""
    run = _Traces.of(log)
    sc = run.scenario
    steps = [np.asarray(k[1], float) for k in sc.push.keys]
    nz = [s for s in steps if np.linalg.norm(s) > 1e-9]
    u = nz[0] / np.linalg.norm(nz[0]) if nz else np.array([1.0, 0.0, 0.0])
    i = decimate(len(run.t))
    x = (run.p_s[i] - run.p_s[0]) @ u
    e = (run.p_m[i] - run.p_s[i]) @ u
    fig = new_figure((10, 4.5))
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(1e3 * x, 1e3 * e, color="C0", lw=1.0)
    ax1.set_xlabel("slave displacement along the push (mm)")
    ax1.set_ylabel("master - slave (mm)")
    ax1.grid(alpha=0.3)
    ax2.plot(run.t[i], 1e3 * e, color="C0", lw=1.0)
    for h in sc.holds:
        ax2.axvline(h, color="k", ls=":", lw=0.8)
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("master - slave along the push (mm)")
    ax2.grid(alpha=0.3)
    fig.suptitle(_title(log) + " - hysteresis of the master", fontsize=10)
    return save(fig, path)


def plot_teleop_virtual_wall(log: Log, path) -> Path:
    """Depth of the master's tool into its virtual walls, and the hand's force."""
    run = _Traces.of(log)
    i = decimate(len(run.t))
    t = run.t[i]
    fig = new_figure((10, 4.5))
    ax1, ax2 = fig.subplots(1, 2)
    for k, w in enumerate(run.scenario.virtual_walls):
        ax1.plot(t, 1e3 * w.thickness_m * run.wall_depth[i, k], color=f"C{k}", label=f"wall {k + 1}")
        ax1.axhline(1e3 * w.thickness_m, color=f"C{k}", ls=":", lw=0.9,
                    label=f"its thickness ({w.resist_force_n:g} N to cross)")
    ax1.axhline(0.0, color="k", lw=0.6)
    ax1.set_xlabel("t (s)")
    ax1.set_ylabel("depth into the wall (mm)")
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.plot(t, np.linalg.norm(run.F_hand[i], axis=1), color="C3")
    for w in run.scenario.virtual_walls:
        ax2.axhline(w.resist_force_n, color="r", ls=":", lw=0.9)
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("hand force on the master (N)")
    ax2.grid(alpha=0.3)
    fig.suptitle(_title(log) + " - virtual wall", fontsize=10)
    return save(fig, path)


def write_teleop_plots(log: Log, out_dir) -> list[Path]:
    """The figures that apply to the run of ``log``, written into ``out_dir`` (``FIGURES["teleop"].run``)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sc = log.meta["scenario"]
    paths = [plot_teleop_tracking(log, out / "tracking.png"), plot_teleop_torques(log, out / "torques.png"),
             plot_teleop_orientation(log, out / "orientation_rpy.png")]
    if sc.wall is not None:
        paths.append(plot_teleop_contact(log, out / "contact.png"))
    if sc.push is not None:
        paths.append(plot_teleop_hysteresis(log, out / "hysteresis.png"))
    if sc.virtual_walls:
        paths.append(plot_teleop_virtual_wall(log, out / "virtual_wall.png"))
    return paths


def write_teleop_compare_plots(logs, out_dir) -> list[Path]:
    """The runs of one scenario with different choices (``FIGURES["teleop"].compare``):
    ``compare_errors.png``, each run's position error, orientation error (the angle between
    the tools) and largest slave torque against time, labelled by ``log.meta["label"]``."""
    logs = list(logs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig = new_figure((10, 7))
    axes = fig.subplots(3, 1, sharex=True)
    for k, log in enumerate(logs):
        run = _Traces.of(log)
        i = decimate(len(run.t))
        label = log.meta.get("label", f"run {k + 1}")
        axes[0].semilogy(run.t[i], np.maximum(np.linalg.norm(run.p_s - run.p_m, axis=1)[i], 1e-9), color=f"C{k}",
                         lw=1.0, label=label)
        axes[1].semilogy(run.t[i], np.maximum(run.angle[i], 1e-9), color=f"C{k}", lw=1.0, label=label)
        axes[2].plot(run.t[i], np.abs(run.tau_s).max(axis=1)[i], color=f"C{k}", lw=1.0, label=label)
    for ax, name in zip(axes, ("position error (m)", "orientation error (rad)", "max |slave torque| (N m)")):
        ax.set_ylabel(name)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("t (s)")
    if logs:
        fig.suptitle(f"Jansen et al. 1990, {logs[0].meta['scenario'].name}: the choices compared", fontsize=10)
    return [save(fig, out / "compare_errors.png")]


FIGURES.add("teleop", FigureSet(write_teleop_plots, write_teleop_compare_plots))
