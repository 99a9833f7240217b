"""Sim layer: the plants :func:`quatform.sim.simulate` runs (one module per plant).

A plant has ``state_columns``, ``output_columns``, ``batchable``, ``output(x)`` and
``step(x, u, dt, t) -> x`` (see :mod:`quatform.sim.simulate`). :mod:`.kinematic` holds the
kinematic team, :mod:`.ugv_uav` the Pioneer and Bebop with the floor, :mod:`.teleop` the two
arms with the hand and the environment, :mod:`.mujoco` the MuJoCo worlds (two IRIS
quadrotors of seed 000; a Pioneer-like UGV and an IRIS in Bebop-like attitude mode of seed 001).
"""

from .kinematic import KinematicTeam

__all__ = ["KinematicTeam"]
