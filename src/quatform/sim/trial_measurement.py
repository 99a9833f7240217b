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

from ..algebra.kernels import common_namespace
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

    def check(self, y0, batch: tuple = (), n: int | None = None) -> None:
        """Refuse (one line) noise or dropped frames of another batch, output width or (with
        ``n``) fewer than ``n`` ticks than a run of the plant output ``y0`` for ``batch``."""
        y0 = np.asarray(y0, dtype=float)
        for name, arr, tail in (("noise", self.noise, y0.shape[-1:]), ("dropped", self.dropped, ())):
            if arr is not None and arr.shape[1:] != tuple(batch) + tail:
                raise ShapeError(f"TickMeasurement: {name} of shape {arr.shape} for batch {tuple(batch)} "
                                 f"and outputs {y0.shape}; give (T, *batch{', k' if tail else ''})")
            if arr is not None and n is not None and arr.shape[0] < n:
                raise ShapeError(f"TickMeasurement: {name} holds fewer than the run's {n} ticks; give "
                                 f"(T, *batch, ...) with T = {n}")

    # -- the measurement contract (quatform.sim.loop) ---------------------------------
    def schedule(self, times, dt: float, substeps: int, batch: tuple = ()) -> dict:
        """The tick's ``noise`` ``(T, *batch, k)`` and ``dropped`` ``(T, *batch)``, where given."""
        n = np.size(times)
        out = {}
        for name, arr in (("noise", self.noise), ("dropped", self.dropped)):
            if arr is not None:
                if arr.shape[0] < n or arr.shape[1:1 + len(batch)] != tuple(batch):
                    raise ShapeError(f"TickMeasurement: {name} of shape {arr.shape} for {n} ticks and batch "
                                     f"{tuple(batch)}; give (T, *batch, ...) with T = {n}")
                out[name] = arr[:n]
        return out

    def init(self, y0, batch: tuple = (), schedule: dict | None = None) -> dict:
        """``past`` ``(*batch, d + 1, k)``: the outputs of the last ``d + 1`` ticks, oldest
        first (all ``y0``); ``latest`` the newest output; ``last`` the last reading."""
        self.check(y0, batch)
        y0 = np.asarray(y0, dtype=float)
        past = np.broadcast_to(y0[..., None, :], y0.shape[:-1] + (self.delay_ticks + 1, y0.shape[-1])).copy()
        return {"past": past, "latest": y0, "last": y0}

    def observe(self, state: dict, y, j: int) -> dict:
        return {"past": state["past"], "latest": y, "last": state["last"]}

    def read(self, state: dict, xs: dict):
        """``(state, m_k)``: the newest output shifted into ``past`` (at the first tick it is
        ``y0``, as every entry is), ``m_k = past[0] + noise_k``, the last reading where the
        frame is dropped (any array namespace)."""
        past, latest = state["past"], state["latest"]
        xp = common_namespace(past, latest)
        past = xp.concatenate([past[..., 1:, :], latest[..., None, :]], axis=-2)
        m = past[..., 0, :]
        if "noise" in xs:
            m = m + xs["noise"]
        if "dropped" in xs:
            m = xp.where(xp.asarray(xs["dropped"])[..., None], state["last"], m)
        return {"past": past, "latest": latest, "last": m}, m
