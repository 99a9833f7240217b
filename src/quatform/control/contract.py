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
* optionally ``schedule(times, batch)`` -> a dict of arrays ``(T, *batch, ...)``: inputs the
  controller draws up front per world, independent of the robots' states (a network's
  delivery lags, :class:`~quatform.control.networked.NetworkedController`); the loop then
  hands it ``(reference, the tick's slice)`` as the reference
  (:func:`quatform.sim.loop.scheduled_reference`).

The object itself holds configuration only (formation, law, gains, team, limits) and is
frozen, so one controller may drive any number of simulations or robots at once.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Step", "Tick", "Controller", "batch_shape_of"]


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


@dataclass(frozen=True)
class Tick:
    """What one pure, branch-free control tick computed (:meth:`Controller.tick`).

    Attributes
    ----------
    state : pytree of arrays
        The controller's next state (``None`` for a stateless controller); batch axes lead.
    u : array, shape (*batch, n_u)
        Commands (finite, within the robots' limits, where ``code`` is 0).
    signals : Mapping[str, array]
        Named outputs, each ``(*batch, k)`` (:meth:`Controller.signal_columns`).
    code : int array, shape (*batch,)
        0 where the tick is valid; ``> 0`` names why the world failed
        (:attr:`Controller.failure_reasons`): what :meth:`Controller.update` refuses with an
        exception, decided by selections instead, so the tick runs under ``jax.jit``.
    """

    state: Any
    u: Any
    signals: Mapping[str, Any]
    code: Any


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

    #: Whether :meth:`tick` is pure and branch-free on any array namespace (it then runs under
    #: ``jax.jit``; a controller with only :meth:`update` runs on NumPy).
    pure: bool = False
    #: Failure code of :attr:`Tick.code` -> one-line reason (0 is no failure).
    failure_reasons: Mapping[int, str] = {}

    def reference_arrays(self, reference):
        """The tick's ``reference`` (what :meth:`update` takes) as a pytree of NumPy arrays,
        checked on the host (one-line errors, as :meth:`update` raises them); leading axes are
        the batch's or none (one reference for every world). :meth:`tick` reads it."""
        return reference

    def tick(self, state, measured, reference, t) -> Tick:
        """One pure control tick: ``state``, ``measured`` (``(*batch, n_m)``), the tick's
        :meth:`reference_arrays` and the time ``t`` (s) in; :class:`Tick` out. No Python branch
        on data: what :meth:`update` refuses is a :attr:`Tick.code`.

        The default serves a controller that implements :meth:`update` only (NumPy, host):
        its step, code 0."""
        step = self.update(t, measured, reference, state)
        return Tick(step.state, step.u, step.signals, np.zeros(batch_shape_of(measured), dtype=np.int64))

    def step(self, t: float, measured, reference=None):
        """Commands for ``measured`` from the initial state (a stateless controller's whole job)."""
        return self.update(t, measured, reference, self.init(batch_shape_of(measured))).u
