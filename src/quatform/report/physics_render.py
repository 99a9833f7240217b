"""Time-lapse pictures of physics runs, like seed 000 Figs. 19-20 (report layer).

:func:`render_time_lapse` draws the robots of a :class:`~quatform.sim.mujoco_backend.PhysicsRecord`
at evenly spaced times in one MuJoCo image, offscreen (EGL by default: Debian packages
``libegl1``, ``libegl-mesa0``, ``libgl1-mesa-dri``; OSMesa with ``MUJOCO_GL=osmesa`` and
``libosmesa6``): the earlier poses translucent, the last one solid, each robot's path as a
trail and, for two robots, the segment between them at every snapshot (the formation's
attitude). Where no offscreen OpenGL works, :func:`render_or_fallback` draws the same
time-lapse with matplotlib from the same physics states and says so.
"""

from __future__ import annotations

import math
import os
from itertools import pairwise
from pathlib import Path

import numpy as np

__all__ = ["RENDER_FILE", "render_or_fallback", "render_time_lapse"]

#: File name of the picture in a run's folder.
RENDER_FILE = "time_lapse.png"

_TRAIL_COLORS = ((0.15, 0.35, 0.85, 0.9), (0.9, 0.55, 0.1, 0.9), (0.2, 0.7, 0.3, 0.9), (0.6, 0.2, 0.7, 0.9))


def _camera_for(points, mj, fovy_deg=45.0, azimuth=-150.0, elevation=-15.0):
    cam = mj.MjvCamera()
    cam.type = mj.mjtCamera.mjCAMERA_FREE
    lo, hi = points.min(axis=0), points.max(axis=0)
    cam.lookat[:] = 0.5 * (lo + hi)
    extent = float(np.linalg.norm(hi - lo)) + 1.0
    cam.distance = 0.42 * extent / math.tan(math.radians(0.5 * fovy_deg))
    cam.azimuth, cam.elevation = azimuth, elevation
    return cam


def _add_connector(scn, mj, a, b, width, rgba):
    if scn.ngeom >= scn.maxgeom:
        return
    g = scn.geoms[scn.ngeom]
    mj.mjv_initGeom(g, mj.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                    np.asarray(rgba, dtype=np.float32))
    mj.mjv_connector(g, mj.mjtGeom.mjGEOM_CAPSULE, width, np.asarray(a, float), np.asarray(b, float))
    scn.ngeom += 1


def render_time_lapse(record, path, n_snapshots: int = 9, width: int = 1200, height: int = 800,
                      azimuth: float = -150.0, elevation: float = -15.0, trail_points: int = 300) -> Path:
    """Render the time-lapse of a physics run to a PNG file (MuJoCo, offscreen).

    Parameters
    ----------
    record : PhysicsRecord
    path : str or Path
    n_snapshots : int
        Poses drawn, evenly spaced in time (the last solid, the others translucent).
    azimuth, elevation : float
        Camera angles, degrees.
    """
    from matplotlib.image import imsave

    from ..sim.mujoco_backend import import_mujoco

    mj = import_mujoco()
    model = mj.MjModel.from_xml_string(record.xml)
    data = mj.MjData(model)
    T = len(record.qpos)
    ks = np.unique(np.linspace(0, T - 1, max(2, int(n_snapshots))).round().astype(int))
    names = list(record.robots)
    pts = np.concatenate([np.asarray(record.robots[n])[np.isfinite(record.robots[n]).all(axis=1)] for n in names])
    pts = pts[np.abs(pts).max(axis=1) < 1e3]
    cam = _camera_for(pts, mj, azimuth=azimuth, elevation=elevation)
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
                _add_connector(scn, mj, p1[k], p2[k], 0.012, (0.1, 0.1, 0.1, 0.85))
        img = renderer.render()
    path = Path(path)
    imsave(path, img)
    return path


def render_or_fallback(record, run, path, **kw) -> tuple[Path, str]:
    """:func:`render_time_lapse`, or where offscreen OpenGL fails, matplotlib's 3-D
    time-lapse of the same states. Returns ``(file, "mujoco" | "matplotlib (reason)")``."""
    try:
        return render_time_lapse(record, path, **kw), "mujoco"
    except Exception as exc:  # noqa: BLE001 - any GL failure: fall back, and say why
        reason = f"MUJOCO_GL={os.environ.get('MUJOCO_GL', '')}: {type(exc).__name__}: {exc}".splitlines()[0][:200]
    if hasattr(run, "ugv"):
        from .ugv_uav_plots import plot_ugv_uav_paths_3d

        return plot_ugv_uav_paths_3d(run, path), f"matplotlib ({reason})"
    from .plots import plot_paths_3d

    return plot_paths_3d(run, path), f"matplotlib ({reason})"
