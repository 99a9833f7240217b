"""The controller contract shared by every quatform controller (control layer).

Drake's ``StateFeedbackControllerInterface`` is the model: named inputs and outputs, and the
controller's own state kept outside the object. One control update takes the time, the
measured values, the reference and the controller's state and returns a :class:`Step`: the
commands, the next state and named output signals (the cluster state it measured, its
errors, what it made of the measurement ...) that a simulator logs and a robot bridge
publishes, instead of reading the controller's internals.

* ``init(batch=())`` -> the state before the first update (``None`` for a stateless
  controller). Resetting a controller is ``state = ctrl.init()``; an emergency stop, a held
  measurement or a filter's memory are fields of that state, so they are data.
* ``update(t, measured, reference, state)`` -> :class:`Step`. Every array may carry leading
  batch axes (B formations at once); the state carries the same axes.
* ``step(t, measured, reference)`` -> commands only, from the initial state: the one call a
  stateless controller needs on a real robot (and the README's example).

The object itself holds configuration only (formation, law, gains, team, limits) and is
frozen, so one controller may drive any number of simulations or robots at once.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Step", "Controller", "batch_shape_of"]


@dataclass(frozen=True)
class Step:
    """What one control update computed.

    Attributes
    ----------
    u : ndarray, shape (..., n_u)
        Commands to send: finite and within the robots' limits.
    state : object
        The controller's state for the next update (``None`` for a stateless controller).
    signals : Mapping[str, ndarray]
        Named outputs, each of shape ``(..., k)`` with the columns
        :meth:`Controller.signal_columns` names (``cluster``, ``error``, ``raw_finite`` ...).
    """

    u: np.ndarray
    state: Any = None
    signals: Mapping[str, np.ndarray] = field(default_factory=dict)


def batch_shape_of(measured) -> tuple:
    """Leading batch axes of a measured array (all but its last axis); ``()`` for a single
    measurement or a measurement that is not an array (a value object)."""
    shape = np.shape(measured) if isinstance(measured, (np.ndarray, list, tuple)) else ()
    return tuple(shape[:-1])


class Controller(ABC):
    """Base of every controller: configuration in the object, state passed explicitly.

    Subclasses set :attr:`name` and :attr:`command_names`, implement :meth:`update` and
    :meth:`signal_columns`, and override :meth:`init` when they keep a state.
    """

    #: Name on the command line and in files.
    name: str = ""

    @property
    @abstractmethod
    def command_names(self) -> tuple[str, ...]:
        """Column names of the commands ``Step.u``."""

    @abstractmethod
    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """Column names of each output signal of :meth:`update`, in order."""

    def init(self, batch: tuple = ()):
        """The controller state before the first update, for ``batch`` leading axes."""
        return None

    @abstractmethod
    def update(self, t: float, measured, reference, state) -> Step:
        """One control update (see the module docstring)."""

    def step(self, t: float, measured, reference=None):
        """Commands for ``measured`` from the initial state (a stateless controller's whole job)."""
        return self.update(t, measured, reference, self.init(batch_shape_of(measured))).u
