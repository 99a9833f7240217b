"""Sim layer, plants: what :func:`quatform.sim.simulate.simulate` integrates (one module each).

A plant has ``state_columns``, ``output_columns``, ``batchable``, ``output(x)`` and
``step(x, u, dt, t) -> x``. :mod:`.teleop` holds seed 003's two arms with the operator's
hand and the slave's environment.
"""
