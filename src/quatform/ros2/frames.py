"""World and body frames of the ROS 2 bridge: REP-103 (ENU, FLU) and PX4's (NED, FRD).

ROS 2 bridge layer. quatform, ROS (REP-103) and MAVROS use an east-north-up world frame and
forward-left-up body frames; PX4's ``/fmu`` topics use north-east-down and forward-right-down
(PX4 User Guide, "ROS 2 User Guide: ROS 2/PX4 frame conventions"). Both changes are rotations
by pi: ``v_NED = (y, x, -z)`` of ``v_ENU`` (the rotation about ``(1, 1, 0)/sqrt 2``, quaternion
``(0, 1/sqrt 2, 1/sqrt 2, 0)``) and ``v_FRD = (x, -y, -z)`` of ``v_FLU`` (about x, quaternion
``(0, 1, 0, 0)``), so an orientation ``q`` (body FLU to world ENU) is
``q_NED_FRD = q_NED_ENU q q_FLU_FRD`` and back (``docs/derivations.md``, "The ROS 2 bridge").
Each converter is its own inverse. Arrays carry leading axes; quaternions ``(w, x, y, z)``.
"""

from __future__ import annotations

import math

import numpy as np

from ..formations import geometry as g

__all__ = ["ned_from_enu", "enu_from_ned", "frd_from_flu", "flu_from_frd", "q_ned_frd_from_enu_flu",
           "q_enu_flu_from_ned_frd", "Q_NED_ENU", "Q_FLU_FRD"]

_H = 1.0 / math.sqrt(2.0)
#: The rotation taking ENU coordinates to NED ones (pi about (1, 1, 0) / sqrt 2), (w, x, y, z).
Q_NED_ENU = np.array([0.0, _H, _H, 0.0])
#: The rotation taking FRD body coordinates to FLU ones (pi about x), (w, x, y, z).
Q_FLU_FRD = np.array([0.0, 1.0, 0.0, 0.0])


def ned_from_enu(v) -> np.ndarray:
    """``(..., 3)`` ENU vector in NED coordinates: ``(y, x, -z)`` (its own inverse)."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


enu_from_ned = ned_from_enu


def frd_from_flu(v) -> np.ndarray:
    """``(..., 3)`` FLU body vector in FRD coordinates: ``(x, -y, -z)`` (its own inverse)."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


flu_from_frd = frd_from_flu


def q_ned_frd_from_enu_flu(q) -> np.ndarray:
    """PX4's orientation (FRD body to NED world) of a REP-103 one (FLU body to ENU world), ``(..., 4)``."""
    return g.mul(g.mul(Q_NED_ENU, np.asarray(q, dtype=float)), Q_FLU_FRD)


def q_enu_flu_from_ned_frd(q) -> np.ndarray:
    """The REP-103 orientation (FLU body to ENU world) of PX4's (FRD body to NED world), ``(..., 4)``
    (both fixed rotations are their own inverses up to sign)."""
    return g.mul(g.mul(Q_NED_ENU, np.asarray(q, dtype=float)), Q_FLU_FRD)
