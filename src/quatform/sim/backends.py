"""Compute backends of the closed loop: one registry of functions with ``simulate``'s signature.

Sim layer. A backend is a driver of the one tick of :mod:`quatform.sim.loop`. NumPy
(:func:`quatform.sim.simulate`) is the reference and the default; JAX (``pip install -e
".[jax]"``, :func:`quatform.sim.loop.simulate_jax`) runs the same tick compiled and returns
the same :class:`~quatform.sim.log.Log`, equal to NumPy's within 1e-9. A backend is registered by name with the module that defines it, so
its package is imported only when it is used.

Contract of a backend: ``backend(plant, controller, reference, times, x0, *, dt, substeps,
measurement, progress, meta) -> Log``. A batched run in which some worlds fail (non-finite
state, coincident robots) does not raise for them: ``log.meta["failed"]`` is a bool array of
the batch shape and ``log.meta["failure"]`` maps each failed world's index tuple to its
one-line reason (both absent when every world finished).
"""

from __future__ import annotations

from importlib import import_module

from ..checks import nearest
from ..errors import InvalidInputError

__all__ = ["SIM_BACKENDS", "simulator"]

#: Backend name -> ``"module:function"`` (imported on first use).
SIM_BACKENDS = {
    "numpy": "quatform.sim.simulate:simulate",
    "jax": "quatform.sim.loop:simulate_jax",
}


def simulator(name: str = "numpy"):
    """The closed-loop function of the backend ``name`` (one line naming the valid ones when unknown)."""
    if name not in SIM_BACKENDS:
        raise InvalidInputError(f"unknown compute backend {name!r}{nearest(name, SIM_BACKENDS)}; "
                                f"one of {', '.join(SIM_BACKENDS)}")
    module, function = SIM_BACKENDS[name].split(":")
    return getattr(import_module(module), function)
