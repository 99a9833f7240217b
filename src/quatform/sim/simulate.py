"""The closed loop, plant, measurement model, controller and reference, B worlds per tick, on NumPy.

Sim layer. :func:`simulate` integrates any plant with a fixed step ``dt``, lets a
measurement model see every plant output (its own rates, noise, latency and dropouts are
its business), calls the controller every ``substeps`` plant steps on the measurement
available then and the reference of that tick (zero-order hold of the commands), and
returns one :class:`~quatform.sim.log.Log`. The initial state may carry leading batch axes:
then the plant, the measurement model and the controller run on all worlds at once, one
Python iteration per tick (crazyflow's ``(worlds, ..., k)`` state axes). It is the NumPy
driver of the one tick of :mod:`quatform.sim.loop`, which says what the parts are:

* plant: ``state_columns``, ``output_columns``, ``batchable``, ``output(x)``, optional
  ``inputs(times, dt, substeps)`` and ``step(x, u, dt, t[, w])`` (:mod:`quatform.sim.plants`);
* measurement: ``columns``, ``schedule``, ``init``, ``observe``, ``read``
  (:mod:`quatform.sim.measurement`);
* controller: :class:`quatform.control.contract.Controller`;
* reference: a callable ``k -> reference`` for the tick index ``k`` (what the controller's
  ``update`` takes; ``None`` for a controller without a reference).
"""

from __future__ import annotations

from typing import Callable

from .log import Log
from .loop import WORLD_ERRORS, simulate_numpy
from .measurement import PerfectMeasurement

__all__ = ["simulate", "PerfectMeasurement", "WORLD_ERRORS"]


def simulate(plant, controller, reference: Callable, times, x0, *, dt: float | None = None, substeps: int = 1,
             measurement=None, progress: Callable | None = None, meta: dict | None = None) -> Log:
    """Run the closed loop over the control ticks ``times``.

    Parameters
    ----------
    plant, controller, reference, measurement
        See the module docstring; ``measurement`` defaults to :class:`PerfectMeasurement`.
    times : array_like, shape (T,)
        Control ticks, s, evenly spaced by ``substeps * dt``.
    x0 : array_like, shape (*batch, n_x)
        Initial plant state of every world.
    dt : float, optional
        Plant step, s; default ``(times[1] - times[0]) / substeps``.
    substeps : int
        Plant steps per control tick.
    progress : callable, optional
        ``progress(fraction)`` about every 10 % of the ticks.
    meta : dict, optional
        Stored in the log's ``meta``.

    Returns
    -------
    Log
        Channels ``state`` (the plant state at each tick, before its command acts),
        ``measured`` (what the controller read), ``command`` and every signal the
        controller returns, each ``(T, *batch, k)``; ``meta["controller_state"]`` is the
        controller's state after the last tick (why it stopped, what it held ...). A batched
        run in which some worlds fail (non-finite state or command, a controller raising for
        them) goes on with the others: ``meta["failed"]`` (bool, the batch shape) and
        ``meta["failure"]`` (world index tuple -> one-line reason) say which and why; a failed
        world is frozen (state held, zero commands, NaN signals). One world runs as before:
        its errors propagate.
    """
    return simulate_numpy(plant, controller, reference, times, x0, dt=dt, substeps=substeps,
                          measurement=measurement, progress=progress, meta=meta)
