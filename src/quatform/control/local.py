"""The per-robot controller contract: each robot computes its command from its own measurement and its inbox.

Control layer (beside :mod:`.contract`). A decentralised formation runs one controller on
every robot. What a robot knows at a tick is its own measured state, the newest message of
each robot it hears (each stamped with its send time, possibly stale or missing:
:mod:`quatform.network.links`), the reference of its own part and its own state. A
:class:`LocalController` maps that to its command, its next state and named signals, and,
before that, to the message it sends:

* ``message(state, own, reference, t)`` -> ``(*batch, N, d)``: what each robot sends at the
  tick (its pose, its estimate of the leader ...). It is written to the links before the
  inbox is read, so a link of delay 0 delivers it within the same tick;
* ``tick(state, own, inbox, reference, t)`` -> :class:`LocalTick`.

Both are pure and branch-free on the array namespace (NumPy, JAX under ``jax.jit``), and
written for all robots at once along a robot axis: row ``i`` of every output depends on row
``i`` of the inputs only (``own[..., i, :]``, ``inbox[...][..., i, ...]``, the reference's
row ``i``, the state's row ``i``). So the same object computes a whole simulated team in one
call and one robot's node with ``N = 1`` (its own row; :class:`LocalController.robot_rows`),
and the contract test checks the row property for every registered local controller.

The inbox is :func:`quatform.network.links.inbox`'s padded layout: ``senders`` ``(N, W)``
(robot indices, -1: padding), ``messages`` ``(*batch, N, W, d)``, ``stamps`` ``(*batch, N,
W)`` s (``-inf`` where nothing valid is held) and ``valid`` ``(*batch, N, W)``.

:class:`~.networked.NetworkedController` runs a local controller and a
:class:`~quatform.network.Links` as one team controller of the loop (:mod:`quatform.sim.loop`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..registry import Registry

__all__ = ["LocalTick", "LocalController", "LOCAL_CONTROLLERS", "robot_rows"]

#: Every local controller type by its :attr:`LocalController.name` (filled when a subclass with
#: a name is defined).
LOCAL_CONTROLLERS = Registry("local controller")


@dataclass(frozen=True)
class LocalTick:
    """What one tick of every robot's local controller computed.

    Attributes
    ----------
    state : pytree of arrays
        Next state, leading axes ``(*batch, N)`` (None: stateless).
    u : array, shape (*batch, N, n_u)
        Each robot's command (its model's command columns), before its own saturation.
    signals : Mapping[str, array]
        Named outputs, each ``(*batch, N, k)`` (:meth:`LocalController.signal_columns`).
    code : int array, shape (*batch, N)
        0 where the robot's tick is valid, ``> 0`` naming why not
        (:attr:`LocalController.failure_reasons`).
    """

    state: Any
    u: Any
    signals: Mapping[str, Any]
    code: Any


def robot_rows(tree, rows, axis_from_end: int):
    """``tree``'s arrays restricted to the robots ``rows`` along their robot axis, which is
    ``axis_from_end`` axes before the end (an inbox's messages: 3; a ``(*batch, N, k)``
    value: 2). What one robot's node passes (``rows = [i]``)."""
    if tree is None:
        return None
    if isinstance(tree, dict):
        return {k: robot_rows(v, rows, axis_from_end) for k, v in tree.items()}
    if isinstance(tree, (tuple, list)):
        return type(tree)(robot_rows(v, rows, axis_from_end) for v in tree)
    a = np.asarray(tree)
    return np.take(a, rows, axis=a.ndim - axis_from_end)


class LocalController(ABC):
    """Base of the per-robot controllers (module docstring).

    A subclass sets :attr:`name`, :attr:`message_columns`, :attr:`own_columns` and
    :attr:`command_columns`, implements :meth:`message`, :meth:`tick` and
    :meth:`signal_columns`, and overrides :meth:`init` when it keeps a state; it registers in
    :data:`LOCAL_CONTROLLERS` by being defined. The object holds configuration only (gains,
    limits) and is frozen.
    """

    #: Name on the command line and in files ("" for an abstract base).
    name: str = ""
    #: What a robot sends: the columns of :meth:`message`'s last axis.
    message_columns: tuple[str, ...] = ()
    #: What a robot measures of itself: the columns of ``own``'s last axis.
    own_columns: tuple[str, ...] = ()
    #: Its command's columns (the robot model's).
    command_columns: tuple[str, ...] = ()
    #: Failure code -> one-line reason (0: none).
    failure_reasons: Mapping[int, str] = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("name"):
            LOCAL_CONTROLLERS.add(cls.name, cls)

    @classmethod
    def examples(cls) -> dict:
        """Instances the contract test runs: ``{label: (controller, n_robots)}``."""
        return {cls.name: (cls(), 4)}

    def example(self, n: int, rng: np.random.Generator) -> tuple:
        """``(own, reference)`` of ``n`` robots in general position, drawn from ``rng``: what the
        contract test feeds every registered local controller (``own`` ``(n, len(own_columns))``,
        ``reference`` as :meth:`reference_arrays` returns it)."""
        raise NotImplementedError(f"{type(self).__name__}.example")

    def consensus_error(self, own, desired):
        """The team's disagreement at each sample, ``(...)``, from every robot's own columns
        ``own`` and its desired ones ``desired`` (both ``(..., N, n_own)``, NumPy): by default
        the root mean square over the robots of ``|xi_i - mean(xi)|``, ``xi = p_i - p_des_i`` of
        the first three own columns (``x, y, z``), m: zero where the robots hold the desired
        shape about some common point. A law with another invariant overrides it."""
        if tuple(self.own_columns[:3]) != ("x", "y", "z"):
            raise NotImplementedError(f"{type(self).__name__}.consensus_error")
        xi = np.asarray(own, dtype=float)[..., :3] - np.asarray(desired, dtype=float)[..., :3]
        dev = xi - xi.mean(axis=-2, keepdims=True)
        return np.sqrt(np.mean(np.sum(dev * dev, axis=-1), axis=-1))

    def predicted_rate(self, graph, period_s: float, switching_period_s: float | None = None):
        """The decay rate of :meth:`consensus_error` the law's theory predicts on ``graph`` with
        perfect links at the control period ``period_s`` (1/s), or None where it gives none;
        with ``switching_period_s``, ``graph`` is one period's ``[(start_s, Graph), ...]`` of a
        schedule repeated every ``switching_period_s``."""
        return None

    def init(self, n: int, batch: tuple = ()):
        """The state before the first tick of ``n`` robots and ``batch`` worlds (None: stateless)."""
        return None

    @abstractmethod
    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """Column names of each signal of :meth:`tick`, in order."""

    def reference_arrays(self, reference, n: int):
        """The tick's reference as a pytree of NumPy arrays whose robot axis (``n`` rows) is
        the second from last of each leaf, checked on the host (one-line errors). The
        default takes a dict of arrays as it is."""
        return reference

    @abstractmethod
    def message(self, state, own, reference, t):
        """Each robot's outgoing message ``(*batch, N, d)`` at the tick (pure, per row)."""

    @abstractmethod
    def tick(self, state, own, inbox: dict, reference, t) -> LocalTick:
        """Each robot's command from its own row of ``own`` ``(*batch, N, n_own)``, ``inbox``,
        ``reference`` and ``state`` at time ``t`` (s): pure, branch-free, per row."""
