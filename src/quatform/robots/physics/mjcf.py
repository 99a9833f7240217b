"""The physics world as MJCF text: floor, light, sky, robots, integrator options.

Robots layer (physical models; no MuJoCo import).
"""

from __future__ import annotations

from ...errors import InvalidInputError

__all__ = ["world_mjcf"]


def world_mjcf(bodies, actuators, timestep: float = 0.0025, floor_z: float = 0.0,
               integrator: str = "implicitfast", air: bool = True) -> str:
    """A complete MJCF model.

    Parameters
    ----------
    bodies, actuators : sequences of str
        Fragments from :func:`~quatform.robots.physics.quadrotor_mjcf` and
        :func:`~quatform.robots.physics.diff_drive_mjcf`.
    timestep : float
        Physics step, s. 2.5 ms (400 Hz) by default: the quadrotor's rate loop runs every
        step, as PX4's does at 250-1000 Hz.
    floor_z : float
        Height of the ground plane, m.
    integrator : str
        ``"implicitfast"`` (default): the wheels' velocity servos and joint damping are
        integrated implicitly, so stiff servos stay stable at this step; ``"RK4"`` and
        ``"Euler"`` are accepted too.
    air : bool
        Air density and viscosity of sea level (MuJoCo's inertia-box drag model).
    """
    if not (0 < timestep <= 0.01):
        raise InvalidInputError(f"timestep must be in (0, 0.01] s, got {timestep!r}")
    if integrator not in ("implicitfast", "implicit", "RK4", "Euler"):
        raise InvalidInputError(f"integrator must be implicitfast, implicit, RK4 or Euler, got {integrator!r}")
    fluid = ' density="1.225" viscosity="1.8e-5"' if air else ""
    return "\n".join([
        '<mujoco model="quatform">',
        f'  <option timestep="{timestep:g}" integrator="{integrator}" gravity="0 0 -9.81"{fluid}/>',
        ('  <visual><global offwidth="1600" offheight="1200"/>'
        '<headlight ambient="0.35 0.35 0.35" diffuse="0.5 0.5 0.5"/></visual>'),
        "  <asset>",
        ('    <texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.84 0.86" rgb2="0.72 0.74 0.77" '
        'width="512" height="512"/>'),
        '    <material name="grid" texture="grid" texrepeat="1 1" texuniform="true" reflectance="0"/>',
        ('    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.75 0.85 0.95" rgb2="1 1 1" '
        'width="256" height="256"/>'),
        "  </asset>",
        "  <worldbody>",
        '    <light name="sun" directional="true" pos="0 0 10" dir="0.3 0.2 -1" diffuse="0.6 0.6 0.6" castshadow="false"/>',
        f'    <geom name="floor" type="plane" size="0 0 0.05" pos="0 0 {floor_z:g}" material="grid"/>',
        *("    " + line for b in bodies for line in b.splitlines()),
        "  </worldbody>",
        "  <actuator>",
        *("    " + line for a in actuators for line in a.splitlines()),
        "  </actuator>",
        "</mujoco>",
    ])
