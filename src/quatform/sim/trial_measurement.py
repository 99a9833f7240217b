"""A measurement model of batched trials whose randomness is drawn up front (sweeps, backends).

Sim layer. Monte Carlo trials vary the motion capture's noise, latency and dropped frames.
:class:`TickMeasurement` takes them as arrays fixed before the run (drawn from each trial's
seed by the caller), so every compute backend of :mod:`quatform.sim.backends` reads the same
numbers and a trial's result does not depend on the backend, the batch it ran in or the
worker that ran it. At control tick ``k`` it returns

``m_k = y(t_{k-d}) + noise_k``   (``y(t_j)`` = y0 for ``j < 0``),

except where ``dropped_k``: then it returns ``m_{k-1}`` again (a lost frame holds the last one
read; ``m_{-1} = y0``). ``d`` is the latency in control ticks.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError, ShapeError

__all__ = ["TickMeasurement"]


class TickMeasurement:
    """Delayed, noisy, lossy reading of the plant's output at each control tick.

    Parameters
    ----------
    noise : array_like, shape (T, *batch, k), optional
        Added to the (delayed) output read at tick ``k`` (units of the output's columns).
    delay_ticks : int
        Latency ``d`` >= 0, control ticks.
    dropped : array_like of bool, shape (T, *batch), optional
        Ticks whose frame is lost in each world.
    columns : tuple of str, optional
        Names of what is read (None: the plant's outputs).
    """

    def __init__(self, noise=None, delay_ticks: int = 0, dropped=None, columns=None):
        if not isinstance(delay_ticks, (int, np.integer)) or isinstance(delay_ticks, bool) or delay_ticks < 0:
            raise InvalidInputError(f"TickMeasurement: delay_ticks = {delay_ticks!r} must be a whole number >= 0")
        self.noise = None if noise is None else np.asarray(noise, dtype=float)
        if self.noise is not None and not np.all(np.isfinite(self.noise)):
            raise InvalidInputError("TickMeasurement: the noise must be finite")
        self.dropped = None if dropped is None else np.asarray(dropped, dtype=bool)
        self.delay_ticks = int(delay_ticks)
        self.columns = columns

    def start(self, t0: float, y0, batch: tuple = ()) -> None:
        y0 = np.asarray(y0, dtype=float)
        for name, arr, tail in (("noise", self.noise, y0.shape[-1:]), ("dropped", self.dropped, ())):
            if arr is not None and arr.shape[1:] != tuple(batch) + tail:
                raise ShapeError(f"TickMeasurement: {name} of shape {arr.shape} for batch {tuple(batch)} "
                                 f"and outputs {y0.shape}; give (T, *batch{', k' if tail else ''})")
        self._past = [y0] * (self.delay_ticks + 1)  # y at the last d + 1 ticks, oldest first
        self._latest = y0
        self._last = y0
        self._k = 0

    def observe(self, t: float, y) -> None:
        self._latest = y

    def read(self, t: float):
        k = self._k
        self._k += 1
        if k:
            self._past = self._past[1:] + [self._latest]
        m = self._past[0]
        if self.noise is not None:
            m = m + self.noise[k]
        if self.dropped is not None:
            m = np.where(self.dropped[k][..., None], self._last, m)
        self._last = m
        return m
