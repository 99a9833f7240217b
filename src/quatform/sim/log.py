"""The one log every simulation returns: time plus named channels with column names.

Sim layer. python-control's single ``TimeResponseData`` for every simulation is the model:
whatever the plant, the controller or the scenario kind, :func:`~quatform.sim.simulate`
returns a :class:`Log`, and the metrics, the writers (CSV, JSON, ...) and the figures read
it. A channel is an array of shape ``(T, *batch, k)``: time first, then the batch axes of
the worlds simulated together, then its ``k`` named columns. Post-processing adds channels
(desired values, chart variables, singularity measures) with :meth:`Log.with_channels`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..errors import InvalidInputError, ShapeError

__all__ = ["Channel", "Log"]


@dataclass(frozen=True)
class Channel:
    """One logged signal.

    Attributes
    ----------
    name : str
        Key in the log (``state``, ``measured``, ``command``, ``cluster`` ...).
    columns : tuple of str
        Name of each of the ``k`` entries of the last axis.
    data : ndarray, shape (T, *batch, k)
    """

    name: str
    columns: tuple
    data: np.ndarray

    def __post_init__(self):
        data = np.asarray(self.data)
        columns = tuple(str(c) for c in self.columns)
        if data.ndim < 2 or data.shape[-1] != len(columns):
            raise ShapeError(f"log channel {self.name!r}: data of shape {data.shape} for {len(columns)} columns; "
                             "a channel is (T, *batch, k) with k named columns")
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "columns", columns)


@dataclass(frozen=True)
class Log:
    """Time and named channels of one simulation (of B worlds when batched).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Time of each sample, s.
    channels : Mapping[str, Channel]
        In the order they were added.
    meta : Mapping[str, object]
        What produced it (scenario, controller, physics, ...).
    """

    t: np.ndarray
    channels: Mapping = field(default_factory=dict)
    meta: Mapping = field(default_factory=dict)

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        if t.ndim != 1:
            raise ShapeError(f"log time must have shape (T,), got {t.shape}")
        chans = {}
        for ch in (self.channels.values() if isinstance(self.channels, Mapping) else self.channels):
            if ch.data.shape[0] != t.size:
                raise ShapeError(f"log channel {ch.name!r} has {ch.data.shape[0]} samples for {t.size} times")
            chans[ch.name] = ch
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "channels", MappingProxyType(chans))
        object.__setattr__(self, "meta", MappingProxyType(dict(self.meta)))

    # -- access -------------------------------------------------------------------
    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.channels[name].data
        except KeyError:
            from ..checks import nearest

            raise InvalidInputError(f"log has no channel {name!r}{nearest(name, self.channels)}; it has "
                                    f"{', '.join(self.channels)}") from None

    def __contains__(self, name) -> bool:
        return name in self.channels

    def columns(self, name: str) -> tuple[str, ...]:
        return self.channels[name].columns if name in self.channels else self[name]

    def get(self, name: str, default=None):
        return self.channels[name].data if name in self.channels else default

    @property
    def batch_shape(self) -> tuple:
        """Leading batch axes shared by the channels (``()`` for one world)."""
        for ch in self.channels.values():
            return ch.data.shape[1:-1]
        return ()

    def __len__(self) -> int:
        return self.t.size

    # -- derived logs -------------------------------------------------------------
    def with_channels(self, *channels: Channel, **meta) -> Log:
        """This log with ``channels`` added (a channel of an existing name replaces it) and ``meta`` updated."""
        chans = dict(self.channels)
        for ch in channels:
            chans[ch.name] = ch
        return Log(self.t, chans, {**self.meta, **meta})

    def add(self, name: str, columns, data, **meta) -> Log:
        """:meth:`with_channels` for one channel given as its parts."""
        return self.with_channels(Channel(name, tuple(columns), data), **meta)

    def world(self, index) -> Log:
        """The log of one world of a batch (``index``: an int or a tuple over the batch axes)."""
        index = index if isinstance(index, tuple) else (index,)
        if len(index) != len(self.batch_shape):
            raise ShapeError(f"log.world: index {index} for batch shape {self.batch_shape}")
        sel = (slice(None),) + index + (slice(None),)
        return Log(self.t, [Channel(c.name, c.columns, c.data[sel]) for c in self.channels.values()],
                   {**self.meta, "world": index})

    def table(self, names=None) -> tuple[list[str], np.ndarray]:
        """Column names (``t`` first) and the ``(T, n)`` array of the channels ``names``
        (default: all) side by side, for one world; column names are the channels' own, so
        two channels with the same columns (``state`` and ``measured`` of a perfect
        measurement) repeat them: name the channels to write (the kinds' ``csv_channels``
        do)."""
        if self.batch_shape:
            raise ShapeError(f"log.table needs one world; this log has batch shape {self.batch_shape} "
                             "(select one with log.world(i))")
        names = list(self.channels) if names is None else list(names)
        for n in names:
            self[n]  # an unknown channel: one line naming the channels there are
        cols = ["t"] + [c for n in names for c in self.channels[n].columns]
        data = [self.t[:, None]] + [np.asarray(self[n], dtype=float) for n in names]
        return cols, np.hstack(data) if self.t.size else np.zeros((0, len(cols)))
