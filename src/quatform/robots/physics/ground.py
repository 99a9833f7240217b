"""A Pioneer 3-DX-like differential-drive robot for MuJoCo physics.

Robots layer (physical models; no MuJoCo import). Two driven wheels on a common axle and
a rear caster, as seed 001 §3.1.1 describes the Pioneer 3-DX (Fig. 9). Each wheel is a
hinge joint with a velocity servo (a motor with its speed loop), so the robot is driven
by ``(v, omega)`` through the unicycle's wheel speeds; the rolling, slipping and tipping
are the physics engine's. Numbers: the Pioneer 3-DX data sheet (Adept MobileRobots):
455 x 381 x 237 mm, 9 kg, 195 mm wheels, 1.2 m/s top speed; the wheel track (0.33 m) is
read off its drawings, not given there. The control point is ``a`` ahead of the middle
of the axle (seed 001 Fig. 10, ``a = 0.15`` m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import InvalidInputError

__all__ = ["PIONEER_3DX", "DiffDriveParams", "diff_drive_mjcf", "wheel_speeds"]


@dataclass(frozen=True)
class DiffDriveParams:
    """Geometry and limits of a differential-drive robot (SI units).

    Attributes
    ----------
    mass : float
        kg (9).
    length, width : float
        Body footprint, m (0.455, 0.381).
    wheel_radius : float
        m (0.0975).
    track : float
        Distance between the wheels' contact points, m (0.33).
    a : float
        Control point ahead of the axle's middle, m (seed 001: 0.15).
    max_wheel_speed : float
        rad/s (1.2 m/s / 0.0975 m = 12.3).
    wheel_gain : float
        Velocity-servo gain, N m s (torque per rad/s of wheel speed error).
    max_wheel_torque : float
        N m, each wheel.
    platform_height : float
        Top of the landing platform above the floor, m (seed 001's scenarios put the
        platform 0.3 m over the floor).
    """

    mass: float = 9.0
    length: float = 0.455
    width: float = 0.381
    wheel_radius: float = 0.0975
    track: float = 0.33
    a: float = 0.15
    max_wheel_speed: float = 1.2 / 0.0975
    wheel_gain: float = 10.0
    max_wheel_torque: float = 6.0
    platform_height: float = 0.3

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InvalidInputError(f"DiffDriveParams {name} must be positive and finite, got {v!r}")
        if self.platform_height <= 2 * self.wheel_radius:
            raise InvalidInputError(f"platform_height {self.platform_height} must clear the wheels "
                                    f"(> {2 * self.wheel_radius:g} m)")


#: The Pioneer 3-DX (see :class:`DiffDriveParams`).
PIONEER_3DX = DiffDriveParams()


def wheel_speeds(v, omega, params: DiffDriveParams = PIONEER_3DX) -> np.ndarray:
    """Wheel speeds ``(left, right)``, rad/s, of the unicycle command ``(v, omega)`` (eq. (3.1)),
    scaled together into ``max_wheel_speed`` so the path's curvature is kept.

    ``v_{R,L} = v +- omega b / 2``, ``w = v / r`` (rolling without slip).
    """
    v, omega = np.asarray(v, dtype=float), np.asarray(omega, dtype=float)
    half = 0.5 * params.track * omega
    w = np.stack([(v - half) / params.wheel_radius, (v + half) / params.wheel_radius], axis=-1)
    w = np.where(np.isfinite(w), w, 0.0)
    big = np.max(np.abs(w), axis=-1, keepdims=True)
    return w * np.minimum(1.0, params.max_wheel_speed / np.maximum(big, 1e-300))


def diff_drive_mjcf(name: str, axle_xy, yaw: float, floor_z: float, rgba=(0.75, 0.15, 0.1, 1.0),
                    params: DiffDriveParams = PIONEER_3DX) -> tuple[str, str]:
    """MJCF of one differential-drive robot: ``(body, actuators)`` fragments.

    The free body's origin is the middle of the axle at wheel-centre height; it holds the
    chassis, the landing platform (top at ``floor_z + platform_height``), a frictionless
    rear caster and two wheel bodies on hinges (``{name}_left``, ``{name}_right``) with
    velocity servos of the same names.
    """
    p = params
    r = p.wheel_radius
    x, y = (float(c) for c in axle_xy)
    z = floor_z + r
    cq, sq = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    col = " ".join(f"{c:g}" for c in rgba)
    top = p.platform_height - r  # platform top above the body origin
    body_lo, body_hi = 0.06 - r, top - 0.02  # chassis from 6 cm over the floor to the platform
    half_w = 0.5 * p.width - 0.06  # the wheels sit in the chassis's side recesses
    xc = -0.04  # the axle is a little ahead of the chassis's centre
    caster_r = 0.04  # 3 mm below the tyres: always loaded; frictionless (priority over the floor's condim)
    # the chassis's mass puts the wheels and caster under load; the wheels are light
    lines = [
        f'<body name="{name}" pos="{x:.6g} {y:.6g} {z:.6g}" quat="{cq:.9g} 0 0 {sq:.9g}">',
        f'  <freejoint name="{name}_root"/>',
        (f'  <geom name="{name}_chassis" type="box" size="{0.5 * p.length:g} {half_w:g} {0.5 * (body_hi - body_lo):g}" '
        f'pos="{xc:g} 0 {0.5 * (body_hi + body_lo):g}" mass="{p.mass - 1.0:g}" rgba="{col}"/>'),
        (f'  <geom name="{name}_platform" type="box" size="{0.5 * p.length:g} {0.5 * p.width:g} 0.01" '
        f'pos="{xc:g} 0 {top - 0.01:g}" mass="0.6" rgba="0.25 0.25 0.25 1"/>'),
        (f'  <geom name="{name}_caster" type="sphere" size="{caster_r:g}" pos="{xc - 0.5 * p.length + 0.06:g} 0 '
        f'{caster_r - r - 0.003:g}" condim="1" priority="1" mass="0.1" rgba="0.1 0.1 0.1 1"/>'),
        f'  <site name="{name}_control_point" pos="{p.a:g} 0 {top:g}" size="0.02" rgba="1 1 0 1"/>',
    ]
    for side, sgn in (("left", 1), ("right", -1)):
        lines += [
            f'  <body name="{name}_{side}_wheel" pos="0 {sgn * 0.5 * p.track:g} 0">',
            f'    <joint name="{name}_{side}" type="hinge" axis="0 1 0" damping="0.01"/>',
            # the tyre touches the floor at one point (an ellipsoid): a cylinder's two rim
            # points scrub when the robot turns; the cylinder is drawn only
            (f'    <geom name="{name}_{side}_tyre" type="ellipsoid" size="{r:g} {r:g} 0.024" zaxis="0 1 0" '
             f'mass="0.15" friction="1.2 0.01 0.001" rgba="0.08 0.08 0.08 0"/>'),
            (f'    <geom type="cylinder" size="{r:g} 0.024" zaxis="0 1 0" mass="0" contype="0" conaffinity="0" '
             f'rgba="0.08 0.08 0.08 1"/>'),
            "  </body>",
        ]
    lines.append("</body>")
    acts = [f'<velocity name="{name}_{side}" joint="{name}_{side}" kv="{p.wheel_gain:g}" forcelimited="true" '
            f'forcerange="{-p.max_wheel_torque:g} {p.max_wheel_torque:g}" ctrllimited="true" '
            f'ctrlrange="{-p.max_wheel_speed:.6g} {p.max_wheel_speed:.6g}"/>' for side in ("left", "right")]
    return "\n".join(lines), "\n".join(acts)
