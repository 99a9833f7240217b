"""The Pioneer 3-DX and Bebop 2 team of seed 001: where each robot's values sit in its stacked arrays.

Robots layer. The team's stacked state is what the UGV-UAV controller measures, the seed-001
plant steps and the motion capture reads (11 values: the Pioneer's control point and heading,
the Bebop's pose and body-frame velocity); its stacked commands are what the controller sends
(6 values). Every index here is derived once from the team's slices
(:attr:`~quatform.robots.Team.state_slices`), the models' columns and the formation's layout
labels (:data:`~quatform.formations.UGV_UAV_LAYOUT`), so no reader writes a number.
"""

from __future__ import annotations

from ..formations.ugv_uav import UGV_UAV_LAYOUT
from .bebop import Bebop
from .pioneer import Pioneer
from .team import Team

__all__ = ["PIONEER_BEBOP", "PIONEER_PART", "BEBOP_PART", "PIONEER_COMMAND", "BEBOP_COMMAND",
           "UGV_UAV_MEASURED_NAMES", "UGV_UAV_COMMAND_NAMES", "UGV_XY", "PSI_P", "UAV_XYZ", "PSI_B",
           "ODOMETRY_PART", "MOCAP_PART", "V_P", "UAV_XY_COMMAND", "N_MEASURED"]

#: The Pioneer-Bebop team whose models' columns lay out the stacked state and commands (robot
#: 0 the Pioneer, the formation's UGV; robot 1 the Bebop, its UAV); only its layout is read.
PIONEER_BEBOP = Team((Pioneer(), Bebop()))
_UGV, _UAV = range(len(PIONEER_BEBOP.robots))
#: The Pioneer's and the Bebop's entries of the stacked state (what each robot's actuation
#: reads) and of the stacked commands.
PIONEER_PART, BEBOP_PART = PIONEER_BEBOP.state_slices
PIONEER_COMMAND, BEBOP_COMMAND = PIONEER_BEBOP.command_slices
#: Names of the 11 stacked state values: each robot's state columns with its label of the
#: formation's layout (``x_p ... psi_p, x_b ... psi_dot_b``).
UGV_UAV_MEASURED_NAMES = tuple(c + lab for r, lab in zip(PIONEER_BEBOP.robots, UGV_UAV_LAYOUT.labels)
                               for c in r.state_columns)
#: Names of the 6 stacked commands (the Pioneer's, then the Bebop's).
UGV_UAV_COMMAND_NAMES = tuple(c + lab for r, lab in zip(PIONEER_BEBOP.robots, UGV_UAV_LAYOUT.labels)
                              for c in r.command_columns)
#: Named entries of the stacked state: the Pioneer's control point ``(x, y)`` and heading, the
#: Bebop's position, yaw and body-frame velocity (its odometry).
UGV_XY = PIONEER_BEBOP.state_entries(_UGV, "x", "y")
PSI_P = PIONEER_BEBOP.state_entries(_UGV, "psi")
UAV_XYZ = PIONEER_BEBOP.state_entries(_UAV, "x", "y", "z")
PSI_B = PIONEER_BEBOP.state_entries(_UAV, "psi")
ODOMETRY_PART = PIONEER_BEBOP.state_entries(_UAV, "v_x", "v_y", "z_dot", "psi_dot")
#: The motion capture's part of the stacked state (both robots' poses, first) and the odometry's.
MOCAP_PART = slice(0, ODOMETRY_PART.start)
#: Named entries of the commands: the Pioneer's forward speed, the Bebop's horizontal commands.
V_P = PIONEER_BEBOP.command_entries(_UGV, "v")
UAV_XY_COMMAND = PIONEER_BEBOP.command_entries(_UAV, "u_x", "u_y")
N_MEASURED = len(UGV_UAV_MEASURED_NAMES)
