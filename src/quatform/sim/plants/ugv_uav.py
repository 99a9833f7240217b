"""The seed 001 plant: a Pioneer 3-DX and a Bebop 2 above a floor (sim layer).

The models are those of :mod:`quatform.robots`: the Pioneer's control point moving on
exact arcs under ``(v, omega)`` (seed 001 eqs. (3.1)-(3.2)) and the Bebop's first-order
body-velocity response to its commands (eq. (3.10)-(3.11)). The floor, ``floor`` metres
high, stops the Bebop's descent (it rests on it). State and output are the same 11
values (:data:`UGV_UAV_STATE_COLUMNS`); commands are the controller's 6.
"""

from __future__ import annotations

import numpy as np

from ...algebra.kernels import as_floats, common_namespace, concrete
from ...robots import Bebop, Pioneer
from ..measurement import MOTION_CAPTURE_COLUMNS

__all__ = ["PioneerBebopPlant", "UGV_UAV_STATE_COLUMNS"]

#: The plant state: the Pioneer's control point ``(x_p, y_p, psi_p)`` (m, m, rad) and the
#: Bebop's pose and body-frame velocity ``(x_b, y_b, z_b, psi_b, v_x, v_y, z_dot, psi_dot)``.
UGV_UAV_STATE_COLUMNS = MOTION_CAPTURE_COLUMNS


class PioneerBebopPlant:
    """Pioneer + Bebop + floor, for :func:`quatform.sim.simulate`.

    Parameters
    ----------
    pioneer : Pioneer
    bebop : Bebop
    floor : float
        Height of the floor, m (the UAV's ``z_b`` never goes below it).
    """

    state_columns = UGV_UAV_STATE_COLUMNS
    output_columns = UGV_UAV_STATE_COLUMNS
    batchable = True

    def __init__(self, pioneer: Pioneer, bebop: Bebop, floor: float):
        self.pioneer, self.bebop, self.floor = pioneer, bebop, float(floor)

    def output(self, x) -> np.ndarray:
        """What the sensors see: the state itself, shape ``(..., 11)`` (a copy; a JAX array as it is)."""
        return np.array(x, dtype=float) if concrete(x) or isinstance(x, (list, tuple)) else x

    def step(self, x, u, dt: float, t: float = 0.0) -> np.ndarray:
        """The state ``(..., 11)`` after ``dt`` s of the commands ``u`` ``(..., 6)`` (held; any namespace)."""
        x, u = as_floats(x), as_floats(u)
        xp = common_namespace(x, u)
        b = self.bebop.step(x[..., 3:11], u[..., 2:6], dt)
        floor = xp.maximum(b[..., 2:3], self.floor)  # the floor
        return xp.concatenate([self.pioneer.step(x[..., 0:3], u[..., 0:2], dt), b[..., 0:2], floor, b[..., 3:]],
                              axis=-1)
