"""Sim layer, plants: what :func:`quatform.sim.simulate.simulate` integrates (one module each).

A plant has ``state_columns``, ``output_columns``, ``batchable``, ``output(x)`` and
``step(x, u, dt, t) -> x``. :mod:`.mujoco` holds the MuJoCo worlds (two IRIS quadrotors of
seed 000; a Pioneer-like UGV and an IRIS in Bebop-like attitude mode of seed 001).
"""
