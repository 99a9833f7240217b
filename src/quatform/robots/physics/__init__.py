"""Robots layer, physical models: MJCF descriptions and low-level controllers.

Nothing here imports MuJoCo: the models are MJCF text and the low-level controllers are
NumPy, so they can be read, tested and reused without the optional dependency. The
physics stepping lives in :mod:`quatform.sim.mujoco_backend` (sim layer).

* :mod:`.quadrotor` - an IRIS-like quadrotor (PX4 SITL ``iris`` numbers) and its
  cascaded low-level controller (velocity -> acceleration -> attitude and thrust ->
  body rates -> rotor forces), in PX4 velocity mode or Bebop-like attitude mode.
* :mod:`.cascades` - the cascades of N quadrotors evaluated together on ``(N, ...)`` arrays,
  and the vehicles' rotation matrices from their quaternions.
* :mod:`.ground` - a Pioneer 3-DX-like differential-drive robot driven by ``(v, omega)``.
* :mod:`.mjcf` - the world: floor, light, robots, integrator options.
"""

from .cascades import QuadrotorCascades, rotation_rows
from .ground import PIONEER_3DX, DiffDriveParams, diff_drive_mjcf, wheel_speeds
from .mjcf import world_mjcf
from .quadrotor import GRAVITY, IRIS, QuadrotorCascade, QuadrotorParams, quadrotor_mjcf

__all__ = [
    "GRAVITY",
    "IRIS",
    "PIONEER_3DX",
    "DiffDriveParams",
    "QuadrotorCascade",
    "QuadrotorCascades",
    "QuadrotorParams",
    "diff_drive_mjcf",
    "quadrotor_mjcf",
    "rotation_rows",
    "wheel_speeds",
    "world_mjcf",
]
