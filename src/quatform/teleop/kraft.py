"""The Kraft KMC 9100 master of seed 003 (Fig. 1's Denavit-Hartenberg table).

Teleop layer. Modified DH parameters ``(alpha_{i-1}, a_{i-1}, d_i, theta_i at the pictured
pose)``; the table's last column is taken as the joint offset. ``d2 = 0.073``,
``d4 = 0.084``, ``d6 = 0.114``, ``a2 = 0.178``, ``a3 = 0.203`` m. Joints 1-5 carry
actuators; the wrist roll (joint 6) does not.
"""

from __future__ import annotations

import math

from .arm import DHLink, SerialArm

__all__ = ["KRAFT_MASTER"]

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
