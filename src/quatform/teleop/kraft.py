"""The Kraft KMC 9100 master of seed 003 (Fig. 1's Denavit-Hartenberg table).

Teleop layer. Modified DH parameters ``(alpha_{i-1}, a_{i-1}, d_i, theta_i at the pictured
pose)``; the table's last column is taken as the joint offset. ``d2 = 0.073``,
``d4 = 0.084``, ``d6 = 0.114``, ``a2 = 0.178``, ``a3 = 0.203`` m. Joints 1-5 carry
actuators; the wrist roll (joint 6) does not.

Actuators (not in the seed; stated choices): full-scale torques 5, 5, 3, 0.6, 0.6 N m
(a desk-size electric master that reflects 10-15 N at the handle). The seed measured that
every joint needs ~10-20 % of full scale to move: the deadband here is 15 %. Its preload
function used ~10 %, reduced to ~5 % on wrist pitch and yaw (joints 4, 5) to stop
chattering at the switching line.
"""

from __future__ import annotations

import math

from .arm import DHLink, SerialArm

__all__ = ["KRAFT_MASTER", "KRAFT_FULL_SCALE", "KRAFT_DEADBAND", "KRAFT_PRELOAD"]

_D = math.radians
#: Seed 003 Fig. 1.
KRAFT_MASTER = SerialArm(
    links=(
        DHLink(0.0, 0.0, 0.0, _D(0)),
        DHLink(_D(90), 0.0, 0.073, _D(90)),
        DHLink(0.0, 0.178, 0.0, _D(-90)),
        DHLink(_D(-90), 0.203, 0.084, _D(0)),
        DHLink(_D(90), 0.0, 0.0, _D(90)),
        DHLink(_D(90), 0.0, 0.114, _D(0)),
    ),
    name="Kraft master",
    actuated=(True, True, True, True, True, False),
)

#: Full-scale actuator torques, N m (joint 6 has no actuator).
KRAFT_FULL_SCALE = (5.0, 5.0, 3.0, 0.6, 0.6, 0.0)
#: Fraction of full scale each joint needs to move (seed 003 §6: ~10-20 %).
KRAFT_DEADBAND = (0.15, 0.15, 0.15, 0.15, 0.15, 0.0)
#: Preload fractions of full scale (seed 003 §6: ~10 %, ~5 % on wrist pitch and yaw).
KRAFT_PRELOAD = (0.10, 0.10, 0.10, 0.05, 0.05, 0.0)
