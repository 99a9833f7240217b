"""Sim layer: the plants :func:`quatform.sim.simulate` runs (one module per plant).

A plant has ``state_columns``, ``output_columns``, ``batchable``, ``output(x)`` and a pure
``step(x, u, dt, t) -> x`` (see :mod:`quatform.sim.simulate`). ``kinematic``: a team of robot
models; ``mujoco``: the physics worlds (imported on use: MuJoCo is optional).
"""

from .kinematic import KinematicTeam

__all__ = ["KinematicTeam"]
