"""Time-lapse pictures of physics runs, like seed 000 Figs. 19-20 (report layer).

:func:`render_time_lapse` draws the robots of a :class:`~quatform.sim.mujoco_backend.PhysicsRecord`
at evenly spaced times in one MuJoCo image, offscreen (EGL by default: Debian packages
``libegl1``, ``libegl-mesa0``, ``libgl1-mesa-dri``; OSMesa with ``MUJOCO_GL=osmesa`` and
``libosmesa6``): the earlier poses translucent, the last one solid, each robot's path as a
trail and, for two robots, the segment between them at every snapshot (the formation's
attitude). Where no offscreen OpenGL works, :func:`render_or_fallback` draws the same
time-lapse with matplotlib from the same physics states (:func:`plot_time_lapse`) and
says so.

Both pictures are annotated the same way: a title naming the physics (``MuJoCo
physics``), the scenario and the controller or formation; the time of every pose; a
legend (robots, formation segment, ghosts); and lengths in metres (a 1 m axis triad in
the MuJoCo scene, axes in m in matplotlib's).
"""

from __future__ import annotations

import dataclasses
import math
import os
import textwrap
from itertools import pairwise
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the '3d' projection)

from ..sim.output import writing

__all__ = ["RENDER_FILE", "annotate_render", "plot_time_lapse", "project_points", "render_or_fallback",
           "render_time_lapse", "time_lapse_figure", "time_lapse_title"]

#: File name of the picture in a run's folder.
RENDER_FILE = "time_lapse.png"

_TRAIL_COLORS = ((0.15, 0.35, 0.85, 0.9), (0.9, 0.55, 0.1, 0.9), (0.2, 0.7, 0.3, 0.9), (0.6, 0.2, 0.7, 0.9))
_AXIS_COLORS = ((0.85, 0.1, 0.1, 1.0), (0.1, 0.65, 0.1, 1.0), (0.1, 0.2, 0.9, 1.0))
_SEGMENT_COLOR = (0.1, 0.1, 0.1, 0.85)


def _snapshots(T: int, n_snapshots: int) -> np.ndarray:
    return np.unique(np.linspace(0, T - 1, max(2, int(n_snapshots))).round().astype(int))


def _finite_points(record) -> np.ndarray:
    pts = np.concatenate([np.asarray(p)[np.isfinite(p).all(axis=1)] for p in record.robots.values()])
    return pts[np.abs(pts).max(axis=1) < 1e3]


def time_lapse_title(record, ks, extra: str = "") -> str:
    """``"MuJoCo physics - <scenario>: <controller> controller"``, the poses' times (samples
    ``ks`` of the record) and ``extra``."""
    t = np.asarray(record.t)
    what = record.title or "physics run"
    step = f", every {t[ks[1]] - t[ks[0]]:.3g} s" if len(ks) > 1 else ""
    head = f"{record.physics_label} - {what}"
    return f"{head}\n{len(ks)} poses at t = {t[ks[0]]:.3g} to {t[ks[-1]]:.3g} s{step}{extra}"


def _legend_handles(record, ghosts: bool):
    names = list(record.robots)
    handles = [Line2D([], [], color=_TRAIL_COLORS[i % 4][:3], lw=2, label=f"{n} path") for i, n in enumerate(names)]
    if len(names) == 2:
        handles.append(Line2D([], [], color=_SEGMENT_COLOR[:3], lw=2.5, label="formation segment at each pose"))
    handles.append(Patch(facecolor="white", edgecolor="0.6", label=f"t of each pose (s), over {names[0]}"))
    if ghosts:
        handles += [Patch(facecolor=(0.5, 0.5, 0.5, 0.3), edgecolor="0.5", label="earlier poses (translucent)"),
                    Patch(facecolor=(0.5, 0.5, 0.5, 1.0), edgecolor="0.3", label="last pose (solid)")]
    return handles


def _camera_for(points, mj, fovy_deg=45.0, azimuth=-150.0, elevation=-15.0):
    cam = mj.MjvCamera()
    cam.type = mj.mjtCamera.mjCAMERA_FREE
    lo, hi = points.min(axis=0), points.max(axis=0)
    cam.lookat[:] = 0.5 * (lo + hi)
    extent = float(np.linalg.norm(hi - lo)) + 1.0
    cam.distance = 0.42 * extent / math.tan(math.radians(0.5 * fovy_deg))
    cam.azimuth, cam.elevation = azimuth, elevation
    return cam


def project_points(cam, fovy_deg, width, height, p):
    """Pixel ``(u, v)`` (from the top left) of world points ``p`` (N, 3) seen by MuJoCo's free
    camera ``cam`` (MuJoCo's ``mjv_updateCamera``: forward ``(ce ca, ce sa, se)``, up
    ``(-se ca, -se sa, ce)``, eye ``lookat - distance forward``; vertical field of view
    ``fovy``); ``nan`` behind the camera."""
    a, e = math.radians(cam.azimuth), math.radians(cam.elevation)
    fwd = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    up = np.array([-math.sin(e) * math.cos(a), -math.sin(e) * math.sin(a), math.cos(e)])
    right = np.cross(fwd, up)
    d = np.atleast_2d(p) - (np.asarray(cam.lookat) - cam.distance * fwd)
    depth = d @ fwd
    f = 0.5 * height / math.tan(math.radians(0.5 * fovy_deg))
    with np.errstate(divide="ignore", invalid="ignore"):
        u = 0.5 * width + f * (d @ right) / depth
        v = 0.5 * height - f * (d @ up) / depth
    bad = depth <= 1e-9
    return np.where(bad, np.nan, u), np.where(bad, np.nan, v)


def _add_connector(scn, mj, a, b, width, rgba):
    if scn.ngeom >= scn.maxgeom:
        return
    g = scn.geoms[scn.ngeom]
    mj.mjv_initGeom(g, mj.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                    np.asarray(rgba, dtype=np.float32))
    mj.mjv_connector(g, mj.mjtGeom.mjGEOM_CAPSULE, width, np.asarray(a, float), np.asarray(b, float))
    scn.ngeom += 1


def _triad_origin(points, floor_z, azimuth, elevation):
    """Where the 1 m axis triad stands: on the floor (or under the lowest robot), 0.4 m out
    from the corner of the robots' bounding box nearest the camera on its left, so the
    robots do not hide it."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    a, e = math.radians(azimuth), math.radians(elevation)
    fwd = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a)])
    right = np.array([math.sin(a), -math.cos(a)])
    corners = [np.array([x, y]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]
    c = min(corners, key=lambda q: float(q @ (fwd + right)))
    out = np.sign(c - 0.5 * (lo[0:2] + hi[0:2]))
    z = floor_z if floor_z is not None and floor_z < lo[2] else lo[2]
    return np.array([c[0] + 0.4 * out[0], c[1] + 0.4 * out[1], z])


def _floor_height(model) -> float | None:
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == 0:  # mjGEOM_PLANE
            return float(model.geom_pos[g][2])
    return None


def render_time_lapse(record, path, n_snapshots: int = 9, width: int = 1200, height: int = 800,
                      azimuth: float = -150.0, elevation: float = -15.0, trail_points: int = 300) -> Path:
    """Render the annotated time-lapse of a physics run to a PNG file (MuJoCo, offscreen).

    The MuJoCo image (``width`` x ``height`` pixels) carries a 1 m axis triad (x red, y
    green, z blue) on the floor; over it are written the title (:func:`time_lapse_title`),
    the time of each pose beside it and a legend.

    Parameters
    ----------
    record : PhysicsRecord
    path : str or Path
    n_snapshots : int
        Poses drawn, evenly spaced in time (the last solid, the others translucent).
    azimuth, elevation : float
        Camera angles, degrees.
    """
    from ..sim.mujoco_backend import import_mujoco

    mj = import_mujoco()
    model = mj.MjModel.from_xml_string(record.xml)
    data = mj.MjData(model)
    T = len(record.qpos)
    ks = _snapshots(T, n_snapshots)
    names = list(record.robots)
    pts = _finite_points(record)
    origin = _triad_origin(pts, _floor_height(model), azimuth, elevation)
    cam = _camera_for(np.vstack([pts, origin, origin + 1.1 * np.eye(3)]), mj, azimuth=azimuth, elevation=elevation)
    fovy = float(model.vis.global_.fovy)
    opt = mj.MjvOption()
    pert = mj.MjvPerturb()
    with mj.Renderer(model, height, width, max_geom=4000 + 80 * len(ks) * max(1, len(names))) as renderer:
        data.qpos[:] = record.qpos[ks[-1]]
        mj.mj_forward(model, data)
        renderer.update_scene(data, cam, opt)
        scn = renderer.scene
        for j, k in enumerate(ks[:-1]):
            data.qpos[:] = record.qpos[k]
            mj.mj_forward(model, data)
            n0 = scn.ngeom
            mj.mjv_addGeoms(model, data, opt, pert, mj.mjtCatBit.mjCAT_DYNAMIC, scn)
            alpha = 0.25 + 0.35 * j / max(1, len(ks) - 2)
            for g in range(n0, scn.ngeom):
                scn.geoms[g].rgba[3] = min(scn.geoms[g].rgba[3], alpha)
        # trails (decimated) and the formation segment at every snapshot
        idx = np.unique(np.linspace(0, T - 1, min(T, trail_points)).round().astype(int))
        for i, n in enumerate(names):
            p = np.asarray(record.robots[n])
            for a, b in pairwise(idx):
                if np.all(np.isfinite(p[[a, b]])) and np.abs(p[[a, b]]).max() < 1e3:
                    _add_connector(scn, mj, p[a], p[b], 0.008, _TRAIL_COLORS[i % 4])
        if len(names) == 2:
            p1, p2 = (np.asarray(record.robots[n]) for n in names)
            for k in ks:
                _add_connector(scn, mj, p1[k], p2[k], 0.012, _SEGMENT_COLOR)
        for axis in range(3):  # the 1 m scale: an axis triad on the floor
            _add_connector(scn, mj, origin, origin + np.eye(3)[axis], 0.015, _AXIS_COLORS[axis])
        img = renderer.render()
    fig = annotate_render(img, record, ks, lambda p: project_points(cam, fovy, width, height, p), origin)
    path = Path(path)
    with writing(path):  # a full disk names the picture
        fig.savefig(path, dpi=fig.dpi)
    return path


def _time_labels(points, times, near):
    """One label per place: poses whose anchors (``points``, (N, d)) fall within ``near``
    of an earlier label's share it (``"0, 1.25 s"``: a robot holding still). Returns
    ``[(point, text)]``; non-finite anchors get none."""
    places = []  # [point, [times]]
    for p, tt in zip(np.asarray(points, dtype=float), times):
        if not np.all(np.isfinite(p)):
            continue
        for q in places:
            if np.linalg.norm(p - q[0]) < near:
                q[1].append(tt)
                break
        else:
            places.append([p, [tt]])
    return [(q, ", ".join(f"{x:.3g}" for x in ts) + " s") for q, ts in places]


def annotate_render(img, record, ks, project, origin) -> Figure:
    """The rendered image (H, W, 3) in a figure of its size with the title, the time of each
    pose ``ks`` over the first robot, the labels of the 1 m triad at ``origin`` and a
    legend; ``project(points (N, 3)) -> (u, v)`` gives pixels of world points."""
    h, w = img.shape[:2]
    dpi = 100.0
    fs = max(5.0, min(11.0, w / 110.0))
    fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(img, interpolation="none")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.axis("off")
    t = np.asarray(record.t)
    first = np.asarray(next(iter(record.robots.values())), dtype=float)
    u, v = project(first[ks] + [0.0, 0.0, 0.3])
    px = 0.85 * fs * dpi / 72.0  # the labels' font size in pixels
    placed = []  # boxes (u0, u1, v0, v1) of the labels drawn so far
    for (uu, vv), label in _time_labels(np.c_[u, v], t[ks], 1.5 * px):
        half, tall = 0.3 * px * len(label) + 4, 1.5 * px
        for _ in range(8):  # lift a label off the ones it would cover
            if not any(uu - half < b[1] and uu + half > b[0] and vv - tall < b[3] and vv > b[2] for b in placed):
                break
            vv -= tall
        if 0 <= uu <= w and 0 <= vv <= h:
            placed.append((uu - half, uu + half, vv - tall, vv))
            ax.text(uu, vv, label, fontsize=fs * 0.85, ha="center", va="bottom",
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "0.6", "alpha": 0.8})
    tips = origin + 1.08 * np.eye(3)
    tu, tv = project(tips)
    for i, (name, uu, vv) in enumerate(zip(("x", "y", "z"), tu, tv)):
        if np.isfinite(uu) and np.isfinite(vv):
            ax.text(uu, vv, f"{name} (1 m)", color=_AXIS_COLORS[i][:3], fontsize=fs * 0.85, ha="center",
                    va="center", fontweight="bold")
    fig.text(0.01, 0.99, time_lapse_title(record, ks), fontsize=fs, ha="left", va="top",
             bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.6})
    handles = _legend_handles(record, ghosts=True)
    handles.append(Line2D([], [], color="0.3", lw=2, label="axes: 1 m each (x red, y green, z blue)"))
    ax.legend(handles=handles, loc="upper right", fontsize=fs * 0.8, framealpha=0.85)
    return fig


def plot_time_lapse(record, path, n_snapshots: int = 9, note: str = "", width: int = 1200,
                    height: int = 800) -> Path:
    """The time-lapse of a physics run drawn by matplotlib (where MuJoCo cannot render):
    :func:`time_lapse_figure` written to ``path``."""
    fig = time_lapse_figure(record, n_snapshots, note, width, height)
    path = Path(path)
    with writing(path):  # a full disk names the picture
        fig.savefig(path, dpi=fig.dpi)
    return path


def time_lapse_figure(record, n_snapshots: int = 9, note: str = "", width: int = 1200,
                      height: int = 800) -> Figure:
    """The matplotlib time-lapse: each robot's path, its position at ``n_snapshots`` evenly
    spaced times (earlier ones lighter) with the time written over the first robot, the
    formation segment at each of them, axes in m on one scale, a legend, and the title of
    :func:`time_lapse_title` with ``note`` (why this is not the MuJoCo picture)."""
    T = len(record.t)
    ks = _snapshots(T, n_snapshots)
    names = list(record.robots)
    t = np.asarray(record.t)
    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    for i, n in enumerate(names):
        p = np.asarray(record.robots[n], dtype=float)
        c = _TRAIL_COLORS[i % 4][:3]
        ax.plot(*p.T, color=c, lw=1.4)
        for j, k in enumerate(ks):
            alpha = 1.0 if j == len(ks) - 1 else 0.25 + 0.5 * j / max(1, len(ks) - 2)
            ax.scatter(*p[k], color=c, s=30, alpha=alpha, depthshade=False)
    if len(names) == 2:
        p1, p2 = (np.asarray(record.robots[n], dtype=float) for n in names)
        for k in ks:
            ax.plot(*np.stack([p1[k], p2[k]]).T, color=_SEGMENT_COLOR[:3], lw=1.2, alpha=0.8)
    first = np.asarray(record.robots[names[0]], dtype=float)[ks]
    pts = _finite_points(record)
    near = 0.08 * max(float(np.max(pts.max(axis=0) - pts.min(axis=0))), 1.0)
    for (x, y, z), label in _time_labels(first, t[ks], near):  # close together: one label
        ax.text(x, y, z + 0.15, label, fontsize=8, ha="center",
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "0.6", "alpha": 0.8})
    lo, top = pts.min(axis=0), pts.max(axis=0)
    center, span = 0.5 * (lo + top), np.maximum(top - lo, 0.25 * max(float(np.max(top - lo)), 1.0)) + 0.4
    for setter, c, s in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), center, span):
        setter(c - s / 2, c + s / 2)
    ax.set_box_aspect(tuple(span / span.max()))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    handles = _legend_handles(record, ghosts=False)
    handles += [Line2D([], [], color="0.5", marker="o", ls="none", alpha=0.4, label="earlier poses (lighter)"),
                Line2D([], [], color="0.2", marker="o", ls="none", label="last pose")]
    ax.legend(handles=handles, loc="upper right", fontsize=8)
    note = textwrap.fill(f"(picture: matplotlib{note})", width=max(40, int(width / 8)))
    fig.text(0.02, 0.98, time_lapse_title(record, ks, "\n" + note), fontsize=10, ha="left", va="top")
    return fig


def render_or_fallback(record, log, path, **kw) -> tuple[Path, str]:
    """:func:`render_time_lapse`, or where offscreen OpenGL fails, :func:`plot_time_lapse`
    of the same states. Returns ``(file, "mujoco" | "matplotlib (reason)")``.

    ``log`` (the :class:`~quatform.sim.log.Log` of the run the record belongs to, or None)
    names the picture where the record does not: its meta's ``scenario`` and ``controller``.
    """
    if not record.title and log is not None:
        meta = log.meta
        record = dataclasses.replace(record, title=f"{meta.get('scenario', 'physics run')}: "
                                                   f"{meta.get('controller', 'controller')}")
    try:
        return render_time_lapse(record, path, **kw), "mujoco"
    except Exception as exc:  # noqa: BLE001 - any GL failure: fall back, and say why
        reason = f"MUJOCO_GL={os.environ.get('MUJOCO_GL', '')}: {type(exc).__name__}: {exc}".splitlines()[0][:200]
    keep = {k: kw[k] for k in ("n_snapshots", "width", "height") if k in kw}
    return plot_time_lapse(record, path, note=f", no offscreen OpenGL: {reason}", **keep), f"matplotlib ({reason})"
