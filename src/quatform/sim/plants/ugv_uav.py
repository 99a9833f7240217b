"""The seed 001 plant: a Pioneer 3-DX and a Bebop 2 above a floor (sim layer).

The models are those of :mod:`quatform.robots`: the Pioneer's control point moving on
exact arcs under ``(v, omega)`` (seed 001 eqs. (3.1)-(3.2)) and the Bebop's first-order
body-velocity response to its commands (eq. (3.10)-(3.11)). The floor, ``floor`` metres
high, stops the Bebop's descent (it rests on it). Output: the 11 values
(:data:`~quatform.robots.pioneer_bebop.UGV_UAV_MEASURED_NAMES`); commands are the controller's 6.

With ``pioneer_accel = (a_v, a_omega)`` the Pioneer ramps its speeds as its firmware does
(the lab profile's rates are the MobileRobots simulator's P3-DX model's,
:mod:`quatform.scenarios.ugv_uav_profiles`): the speeds it runs,
``(v_p, omega_p)``, follow its commands by at most ``a_v dt`` and ``a_omega dt`` per plant
step, and the state appends them (13 values; the output stays the 11 the sensors see).
"""

from __future__ import annotations

import numpy as np

from ...algebra.kernels import as_floats, common_namespace, concrete
from ...errors import InvalidInputError
from ...robots import Bebop, Pioneer
from ...robots.pioneer_bebop import (BEBOP_COMMAND, BEBOP_PART, N_MEASURED, PIONEER_COMMAND, PIONEER_PART,
                                     UGV_UAV_MEASURED_NAMES)

__all__ = ["PioneerBebopPlant", "PIONEER_SPEED_COLUMNS", "ramp"]

#: What a plant with the Pioneer's acceleration limits appends: the speeds it runs (m/s, rad/s).
PIONEER_SPEED_COLUMNS = ("v_p_run", "omega_p_run")
#: The running speeds' entries of such a state (after the 11 output values).
_SPEEDS = slice(N_MEASURED, N_MEASURED + len(PIONEER_SPEED_COLUMNS))
#: The Bebop's height among its state's entries (the floor stops it).
_BEBOP_Z = np.arange(len(Bebop.state_columns)) == Bebop().state_entries("z")


def ramp(running, commanded, max_change):
    """The speeds after one step of at most ``max_change`` toward ``commanded`` (any namespace).

    Parameters
    ----------
    running, commanded : array_like, shape (..., k)
    max_change : array_like, shape (k,)
        Largest change per step (acceleration times the step), positive.

    Returns
    -------
    ndarray, shape (..., k)
    """
    running, commanded = as_floats(running), as_floats(commanded)
    xp = common_namespace(running, commanded)
    limit = np.asarray(max_change, dtype=float)
    return running + xp.clip(commanded - running, -limit, limit)


class PioneerBebopPlant:
    """Pioneer + Bebop + floor, for :func:`quatform.sim.simulate`.

    Parameters
    ----------
    pioneer : Pioneer
    bebop : Bebop
    floor : float
        Height of the floor, m (the UAV's ``z_b`` never goes below it).
    pioneer_accel : (float, float), optional
        The Pioneer's largest linear (m/s^2) and angular (rad/s^2) accelerations; None: it
        follows its commands at once (the state is then the 11 output values).
    """

    output_columns = UGV_UAV_MEASURED_NAMES
    batchable = True

    def __init__(self, pioneer: Pioneer, bebop: Bebop, floor: float, pioneer_accel=None):
        self.pioneer, self.bebop, self.floor = pioneer, bebop, float(floor)
        if pioneer_accel is not None:
            a = np.asarray(pioneer_accel, dtype=float)
            if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise InvalidInputError(f"pioneer_accel must be two positive numbers (m/s^2, rad/s^2), got "
                                        f"{pioneer_accel!r}")
            pioneer_accel = (float(a[0]), float(a[1]))
        self.pioneer_accel = pioneer_accel
        self.state_columns = UGV_UAV_MEASURED_NAMES + (PIONEER_SPEED_COLUMNS if pioneer_accel else ())

    def initial_state(self, y0) -> np.ndarray:
        """The state of the output ``y0`` (11 values) with the Pioneer at rest."""
        y0 = np.asarray(y0, dtype=float)
        speeds = np.zeros(y0.shape[:-1] + (len(PIONEER_SPEED_COLUMNS),))
        return np.concatenate([y0, speeds], axis=-1) if self.pioneer_accel else y0

    def output(self, x) -> np.ndarray:
        """What the sensors see: the 11 output values of the state, shape ``(..., 11)`` (a copy;
        a JAX array as it is)."""
        if concrete(x) or isinstance(x, (list, tuple)):
            return np.array(np.asarray(x, dtype=float)[..., :N_MEASURED])
        return x[..., :N_MEASURED]

    def step(self, x, u, dt: float, t: float = 0.0) -> np.ndarray:
        """The state after ``dt`` s of the commands ``u`` ``(..., 6)`` (held; any namespace)."""
        x, u = as_floats(x), as_floats(u)
        xp = common_namespace(x, u)
        b = self.bebop.step(x[..., BEBOP_PART], u[..., BEBOP_COMMAND], dt)
        b = xp.where(_BEBOP_Z, xp.maximum(b, self.floor), b)  # the floor
        u_p, tail = u[..., PIONEER_COMMAND], []
        if self.pioneer_accel:  # the firmware's ramp toward the (saturated) command
            u_p = ramp(x[..., _SPEEDS], self.pioneer.saturate(u_p), np.multiply(self.pioneer_accel, dt))
            tail = [u_p]
        return xp.concatenate([self.pioneer.step(x[..., PIONEER_PART], u_p, dt), b] + tail, axis=-1)
