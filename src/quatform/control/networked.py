"""A team whose robots each run a local controller on what the links deliver, as one controller of the loop.

Control layer. :class:`NetworkedController` joins a
:class:`~quatform.control.local.LocalController`, the team's robots and their
:class:`~quatform.network.Links` into a :class:`~quatform.control.contract.Controller` with a
pure tick, so the simulator's one loop (:mod:`quatform.sim.loop`) runs a decentralised team
on NumPy and JAX, batched and swept, as it runs any other controller. One tick:

1. each robot's own row of the measurement (its point's columns, by name);
2. the messages every robot sends (:meth:`LocalController.message`), each with its sender's
   position, written to the links' ring (:meth:`Links.write`);
3. what each robot holds of its in-neighbours, by the tick's slice of the links' schedule
   (:meth:`Links.read`), grouped per robot (:func:`~quatform.network.links.inbox`, with each
   slot's edge weight), less what came from beyond the radio's range (``range_m``);
4. the local controllers' tick, each robot's command mapped by name onto its model's
   command columns (a column the law does not set is 0), its velocity filtered against the
   neighbours it knows of (``safety``, :mod:`.neighbour_barrier`) and saturated by its own
   model (each robot limits itself: no common factor, which would need the whole team).

The links' delivery lags are drawn up front per world (:meth:`schedule`, the contract's
hook): the loop hands each tick's slice beside the reference, so the tick's reference is
``(reference, links slice)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import common_namespace
from ..errors import InvalidInputError, ShapeError
from ..formations.layout import POINT_KINDS
from ..formations.team_chart import team_positions
from ..network.links import Links, inbox
from ..robots import Team
from . import contract
from .local import LocalController
from .neighbour_barrier import SIGNALS, NeighbourBarrier

__all__ = ["NetworkedController", "NETWORK_SIGNALS", "SAFETY_SIGNALS", "VELOCITY_COLUMNS", "LAW_NOT_FINITE",
           "MAX_RING_TICKS"]

#: The per-world signal of the links at each tick (columns of the ``network`` signal).
NETWORK_SIGNALS = ("messages_sent", "messages_dropped", "messages_delivered", "max_age_s")
#: Each robot's columns of the ``safety`` signal (:func:`.neighbour_barrier.neighbour_filter`'s signals).
SAFETY_SIGNALS = SIGNALS
#: The tick's code where the local law's command is not finite (above the laws' own codes).
LAW_NOT_FINITE = 1 << 20
#: Longest ring of a run, in ticks (``max_age_s / period_s``, at most the run's ticks).
MAX_RING_TICKS = 1_000_000
#: The command columns the separation filter sets: the robot's linear velocity, m/s.
VELOCITY_COLUMNS = ("v_x", "v_y", "v_z")


def _slots(links: Links) -> tuple:
    """``(senders, weights)`` ``(N, W)`` of every robot's inbox slots (:func:`inbox`'s layout):
    each slot's sender (-1: padding) and the weight of its edge in the first graph that has it
    (0 at padding)."""
    graphs = [links.graph] if not isinstance(links.graph, tuple) else [g for _, g in links.graph]
    n = links.n
    code = links.edges[:, 0] * n + links.edges[:, 1]
    weights = np.full(len(code), np.nan)
    for g in reversed(graphs):
        weights[np.searchsorted(code, g.edges[:, 0] * n + g.edges[:, 1])] = g.weights
    box = inbox((weights[:, None], np.zeros(len(code)), np.ones(len(code), dtype=bool)), links)
    return box["senders"], box["messages"][..., 0]


def tree_where(xp, acts, new, old):
    """``new`` where the robot acts, else ``old``, leaf by leaf of a local controller's state
    (leaves ``(*batch, N, ...)``; ``acts`` ``(*batch, N)`` bool)."""
    if isinstance(new, dict):
        return {k: tree_where(xp, acts, new[k], old[k]) for k in new}
    if isinstance(new, (tuple, list)):
        return type(new)(tree_where(xp, acts, a, b) for a, b in zip(new, old))
    return xp.where(xp.reshape(acts, acts.shape + (1,) * (new.ndim - acts.ndim)), new, old)


@dataclass(frozen=True, eq=False)
class NetworkedController(contract.Controller):
    """Every robot of ``team`` runs ``local`` on its own measurement and what ``links`` deliver.

    Parameters
    ----------
    local : LocalController
        The law each robot runs.
    team : Team
        The robots, one model for all (a homogeneous team), ``links.n`` of them.
    links : Links
        Who hears whom, with delay, jitter, loss, rates and staleness; its ``max_age_s`` must be
        finite (the ring holds that long a history).
    period_s : float
        The control tick, s: the links' tick (the loop's ticks must be this far apart).
    range_m : float, optional
        Radio range, m: a message whose sender was farther than this from its receiver (the
        sender's position when it sent, the receiver's now) is not used, so the graph the
        robots use switches with their positions (None: every delivered message is used).
    safety : NeighbourBarrier, optional
        Each robot filters its own velocity against the neighbours it holds messages of (their
        positions when they sent, and the age of each: :mod:`.neighbour_barrier`); its
        ``max_speed_m_s`` must be at least the robots' own speed limit.
    hold_unheard : bool
        With ``safety``: an in-neighbour without a valid message is a neighbour of unknown
        position and the robot stays until it is heard (the safe reading of a fixed graph;
        :meth:`NeighbourBarrier.filter_inbox`).
    run_ticks : int, optional
        The most ticks a run it drives has: the ring of held messages is at most that long
        (no message is older than the run). None: ``max_age_s / period_s`` ticks, at most
        :data:`MAX_RING_TICKS`.

    Attributes
    ----------
    senders, slot_weights : ndarray, shape (N, W)
        Every robot's inbox slots (:func:`~quatform.network.links.inbox`'s layout): each slot's
        sender (-1: padding) and its edge's weight (0 at padding).
    """

    local: LocalController
    team: Team
    links: Links
    period_s: float
    range_m: float | None = None
    safety: NeighbourBarrier | None = None
    hold_unheard: bool = False
    run_ticks: int | None = None

    pure = True

    def __post_init__(self):
        if not isinstance(self.local, LocalController):
            raise InvalidInputError(f"networked controller: local must be a LocalController, got "
                                    f"{type(self.local).__name__}")
        if not isinstance(self.links, Links):
            raise InvalidInputError(f"networked controller: links must be a quatform.network.Links, got "
                                    f"{type(self.links).__name__}")
        models = {type(m) for m in self.team.robots}
        if len(models) != 1 or len(set(self.team.robots)) != 1:
            raise InvalidInputError(f"networked controller: the team mixes robot models "
                                    f"({', '.join(sorted({m.name for m in self.team.robots}))}); a networked team "
                                    f"is one model for every robot, e.g. Team.uniform(model, n)")
        if self.team.layout.n != self.links.n:
            raise InvalidInputError(f"networked controller: the team has {self.team.layout.n} robots and the links "
                                    f"{self.links.n}; build the graph over the team's robots")
        p = self.period_s
        if isinstance(p, bool) or not isinstance(p, (int, float, np.number)) or not math.isfinite(p) or p <= 0:
            raise InvalidInputError(f"networked controller: period_s = {p!r} must be a positive number of seconds "
                                    f"(the control tick)")
        r = self.range_m
        if r is not None and (isinstance(r, bool) or not isinstance(r, (int, float, np.number)) or not math.isfinite(r)
                              or r <= 0):
            raise InvalidInputError(f"networked controller: range_m = {r!r} must be a positive number of metres (the "
                                    f"radio range) or None")
        if not math.isfinite(self.links.max_age_s):
            raise InvalidInputError("networked controller: links.max_age_s = inf; give a finite age beyond which a "
                                    "message is stale (e.g. max_age_s=1.0 s): a robot keeps that long a history")
        model = self.team.robots[0]
        unknown = [c for c in self.local.command_columns if c not in model.command_columns]
        if unknown:
            raise InvalidInputError(f"networked controller: {self.local.name} commands {', '.join(unknown)}, which "
                                    f"the {model.name} robot has not (its commands: "
                                    f"{', '.join(model.command_columns)}); choose a robot model it can drive")
        if self.safety is not None:
            if not isinstance(self.safety, NeighbourBarrier):
                raise InvalidInputError(f"networked controller: safety must be a NeighbourBarrier, got "
                                        f"{type(self.safety).__name__}")
            if any(c not in model.command_columns for c in VELOCITY_COLUMNS):
                raise InvalidInputError(f"networked controller: the separation filter commands a velocity "
                                        f"(v_x, v_y, v_z), which the {model.name} robot does not take (its "
                                        f"commands: {', '.join(model.command_columns)}); choose a holonomic model")
            limit = getattr(model, "max_speed", None)
            if limit is None or limit > self.safety.max_speed_m_s * (1 + 1e-12):
                raise InvalidInputError(f"networked controller: the separation filter assumes every robot within "
                                        f"{self.safety.max_speed_m_s:g} m/s, and the {model.name} robots go up to "
                                        f"{limit} m/s; give the filter max_speed_m_s >= the robots' max_speed")
        own = self.own_index()  # raises where a robot lacks a column
        object.__setattr__(self, "_own", own)
        senders, weights = _slots(self.links)
        object.__setattr__(self, "senders", senders)
        object.__setattr__(self, "slot_weights", weights)
        ring = int(min(math.floor(self.links.max_age_s / float(p) + 1e-9), 2 * MAX_RING_TICKS)) + 1
        if self.run_ticks is not None:
            if isinstance(self.run_ticks, bool) or not isinstance(self.run_ticks, (int, np.integer)) or \
                    self.run_ticks < 1:
                raise InvalidInputError(f"networked controller: run_ticks = {self.run_ticks!r} must be a whole "
                                        f"number of ticks >= 1 (or None)")
            ring = min(ring, int(self.run_ticks))
        if ring > MAX_RING_TICKS:
            raise InvalidInputError(f"networked controller: links.max_age_s = {self.links.max_age_s:g} s keeps "
                                    f"{ring - 1:,} ticks of messages at {float(p):g} s a tick, more than "
                                    f"{MAX_RING_TICKS:,}; give a shorter max_age_s or run_ticks (the run's ticks)")
        object.__setattr__(self, "_ring", ring)

    # ------------------------------------------------------------------ names
    @property
    def name(self) -> str:
        return self.local.name

    @property
    def model(self):
        """The robots' one model."""
        return self.team.robots[0]

    @property
    def n(self) -> int:
        """Number of robots."""
        return self.links.n

    @property
    def command_names(self) -> tuple[str, ...]:
        return tuple(f"{c}{label}" for label in self.team.layout.labels for c in self.model.command_columns)

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """The local controller's signals, robot after robot (``<column><label>``), ``network``
        (:data:`NETWORK_SIGNALS`, per world) and, with ``safety``, each robot's
        :data:`SAFETY_SIGNALS`."""
        labels = self.team.layout.labels
        out = {k: tuple(f"{c}{label}" for label in labels for c in cols)
               for k, cols in self.local.signal_columns().items()}
        out["network"] = NETWORK_SIGNALS
        if self.safety is not None:
            out["safety"] = tuple(f"{c}{label}" for label in labels for c in SAFETY_SIGNALS)
        return out

    def own_index(self) -> np.ndarray:
        """``(N, n_own)`` indices of each robot's :attr:`LocalController.own_columns` in the
        measurement (the team layout's point names ``<column><label>``)."""
        names = self.team.layout.names
        labels = self.team.layout.labels
        out = np.empty((self.n, len(self.local.own_columns)), dtype=np.int64)
        for i, label in enumerate(labels):
            for c, col in enumerate(self.local.own_columns):
                key = f"{col}{label}"
                if key not in names:
                    point = ", ".join(c[0] for c in POINT_KINDS[self.team.layout.kinds[i]].components)
                    raise InvalidInputError(f"networked controller: {self.local.name} reads {col!r} of each robot, "
                                            f"which the {self.model.name} robots do not offer (robot {label}'s "
                                            f"point: {point}); choose a robot model whose point has it")
                out[i, c] = names.index(key)
        return out

    # ------------------------------------------------------------------ the contract
    def init(self, batch: tuple = ()):
        d = len(self.local.message_columns) + 3  # the law's message and the sender's position
        return {"local": self.local.init(self.n, tuple(batch)),
                "links": self.links.init(np.zeros((self.n, d)), tuple(batch), length=self._ring),
                "held": np.zeros(tuple(batch) + (self.n, len(self.model.command_columns)))}

    def schedule(self, times, batch: tuple = ()) -> dict:
        """The links' delivery schedule of the run's ticks ``times`` (``(T,)``, ``period_s`` apart),
        drawn per world (:meth:`Links.schedule`; the message counts ``(T, *batch, 1)``)."""
        times = np.asarray(times, dtype=float)
        if times.size > 1 and abs(float(times[1] - times[0]) - self.period_s) > 1e-9 * self.period_s:
            raise InvalidInputError(f"networked controller: the loop ticks every {float(times[1] - times[0]):g} s, "
                                    f"the controller's period_s is {self.period_s:g} s; give the run's control "
                                    f"period")
        out = self.links.schedule(times, self.period_s, batch)
        for key in ("messages_sent", "messages_dropped"):  # a trailing axis: a per-world value of the loop
            out[key] = out[key][..., None]
        acts = self.links.robot_ticks(times)  # (T, N): each robot's own control ticks, alike in every world
        lead = (len(times),) + (1,) * len(tuple(batch))
        out["acts"] = np.broadcast_to(acts.reshape(lead + (self.n,)), (len(times),) + tuple(batch) + (self.n,))
        return out

    def reference_arrays(self, reference):
        """``(the law's reference, links slice)``. A reference with ``robots`` (the team's desired
        points ``(*batch?, layout.size)``) and ``robots_rate`` (their rates) gives the law each
        robot's rows of its own columns as ``desired`` and ``desired_rate`` ``(*batch?, N,
        n_own)``; its other keys pass as they are."""
        ref, links = reference
        if isinstance(ref, dict) and "robots" in ref:
            ref = dict(ref)
            for key, out in (("robots", "desired"), ("robots_rate", "desired_rate")):
                if key in ref:
                    ref[out] = np.asarray(ref.pop(key), dtype=float)[..., self._own]
        return self.local.reference_arrays(ref, self.n), links

    def received(self, ring, xs, p, t):
        """Each robot's inbox (:func:`~quatform.network.links.inbox`, with the slots' ``weights``),
        its senders' positions when they sent ``(*batch, N, W, 3)`` and the number of edges that
        delivered a new message in range at the tick ``(*batch,)``: the ring's messages carry the
        sender's position after the law's columns. With :attr:`range_m`, a message whose sender
        was farther than ``range_m`` from the receiver's position ``p`` now is not valid (out of
        radio range)."""
        xp = common_namespace(p)
        msgs, stamps, valid = self.links.read(ring, xs)            # per candidate edge (*batch, E, ...)
        d = len(self.local.message_columns)
        if self.range_m is not None:
            valid = valid & self.in_range(msgs[..., d:], xp.take(p, xp.asarray(self.links.edges[:, 0]), axis=-2))
            msgs = xp.where(valid[..., None], msgs, 0.0)
            stamps = xp.where(valid, stamps, -math.inf)
        delivered = xp.sum(xp.asarray(xp.asarray(xs["new"]) & valid, dtype=xp.int32), axis=-1)
        box = inbox((msgs, stamps, valid), self.links)
        sender = box["messages"][..., d:]
        box.update(messages=box["messages"][..., :d], weights=self.slot_weights)
        return box, sender, delivered

    def tick(self, state, measured, reference, t) -> contract.Tick:
        ref, xs = reference
        xp = common_namespace(measured)
        own = xp.take(measured, xp.asarray(self._own.reshape(-1)), axis=-1)
        own = xp.reshape(own, own.shape[:-1] + self._own.shape)
        p = team_positions(self.team.layout, measured)
        outgoing = xp.concatenate([self.local.message(state["local"], own, ref, t), p], axis=-1)
        ring = self.links.write(state["links"], outgoing, t)
        box, sender, delivered = self.received(ring, xs, p, t)
        out = self.local.tick(state["local"], own, box, ref, t)
        batch = measured.shape[:-1]
        n_u = len(self.local.command_columns)
        if tuple(out.u.shape[-2:]) != (self.n, n_u):
            raise ShapeError(f"networked controller: {self.local.name}'s tick commands shape {tuple(out.u.shape)}, "
                             f"not (*batch, {self.n}, {n_u}) (its command_columns {self.local.command_columns})")
        # a law whose command is not finite fails the world (the robots' saturation would hide it as 0)
        law_bad = ~xp.all(xp.isfinite(out.u), axis=(-2, -1))
        signals = {k: xp.reshape(v, batch + (-1,)) for k, v in out.signals.items()}
        safe = None
        if self.safety is not None:  # each robot filters its own velocity against what it knows of its neighbours
            valid = box["valid"]
            sensed = (valid | xp.asarray(box["senders"] >= 0)) if self.hold_unheard else valid
            now = xp.asarray(t, dtype=measured.dtype)[..., None, None]  # t: () or per world
            age = xp.where(valid, now - xp.where(valid, box["stamps"], 0.0), math.inf)
            safe, sig = self.safety.filter(self.law_velocity(out.u), p, sender, age, sensed)
            signals["safety"] = xp.reshape(xp.stack([xp.asarray(sig[k], dtype=measured.dtype) for k in SAFETY_SIGNALS],
                                                    axis=-1), batch + (-1,))
        u = self.commands(out.u, safe)
        # a robot acts at its own rate (links.rate_hz): between its ticks it holds its command and state
        acts = xp.asarray(xs["acts"]) if "acts" in xs else xp.ones(batch + (self.n,), dtype=bool)
        u = xp.where(acts[..., None], xp.reshape(u, batch + (self.n, -1)), state["held"])
        held = u
        u = xp.reshape(u, batch + (-1,))
        local_state = None if out.state is None else tree_where(xp, acts, out.state, state["local"])
        age = xp.where(box["valid"], xp.asarray(t)[..., None, None] - box["stamps"], 0.0)
        columns = (xs["messages_sent"][..., 0], xs["messages_dropped"][..., 0], delivered,
                   xp.max(xp.reshape(age, age.shape[:-2] + (-1,)), axis=-1, initial=0.0))
        signals["network"] = xp.stack([xp.broadcast_to(xp.asarray(c, dtype=measured.dtype), batch) for c in columns],
                                      axis=-1)
        code = xp.max(out.code, axis=-1) if out.code.shape[-1:] else xp.zeros(batch, dtype=xp.int64)
        code = xp.where((code == 0) & law_bad, LAW_NOT_FINITE, code)
        return contract.Tick({"local": local_state, "links": ring, "held": held}, u, signals, code)

    @property
    def failure_reasons(self):
        return {LAW_NOT_FINITE: f"{self.local.name}'s command is not finite (a NaN or infinity from the law)",
                **self.local.failure_reasons}

    def update(self, t, measured, reference, state=None) -> contract.Step:
        """:meth:`tick` on the host, raising the local controller's reason where a robot's code is set.
        ``reference`` is ``(reference, links slice)`` as the loop gives it."""
        measured = np.asarray(measured, dtype=float)
        if state is None:
            state = self.init(measured.shape[:-1])
        out = self.tick(state, measured, self.reference_arrays(reference), t)
        code = np.asarray(out.code)
        if np.any(code > 0):
            raise InvalidInputError(f"{self.name}: {self.failure_reasons.get(int(np.max(code)), 'failure')}")
        return contract.Step(out.u, out.state, dict(out.signals))

    # ------------------------------------------------------------------ one robot's composition (also LocalBridge's)
    def in_range(self, sender, receiver):
        """Whether a sender (its position when it sent) is within :attr:`range_m` of its receiver
        (its position now), m, broadcast over leading axes: the radio's rule (a pair exactly
        ``range_m`` apart hears)."""
        gap = sender - receiver
        return common_namespace(gap).sum(gap * gap, axis=-1) <= self.range_m * self.range_m

    def commands(self, u, safe=None):
        """The local commands ``(*batch, N, n_local)`` as the team's ``(*batch, N n_u)``, each robot
        saturated by its model; ``safe`` (``(*batch, N, 3)``, m/s) replaces the velocity columns
        (the separation filter's output)."""
        xp = common_namespace(u)
        cols = self.model.command_columns
        parts = self._columns(u, cols)
        if safe is not None:
            for a, c in enumerate(VELOCITY_COLUMNS):
                parts[cols.index(c)] = safe[..., a]
        full = self.model.saturate(xp.stack(parts, axis=-1))  # scaling a safe command down keeps it safe
        return xp.reshape(full, full.shape[:-2] + (-1,))

    def law_velocity(self, u):
        """The linear velocity ``(*batch, N, 3)`` m/s the law commands (0 where it sets none)."""
        return common_namespace(u).stack(self._columns(u, VELOCITY_COLUMNS), axis=-1)

    def _columns(self, u, names) -> list:
        """The law's commands ``u`` of the columns ``names``, each ``(*batch, N)`` (0 where the law
        sets none)."""
        xp = common_namespace(u)
        local = self.local.command_columns
        zero = xp.zeros(u.shape[:-1], dtype=u.dtype)
        return [u[..., local.index(c)] if c in local else zero for c in names]
