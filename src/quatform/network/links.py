"""The communication model of a robot team: which of its neighbours' messages each robot holds at each tick.

Formations and planning layer (imports the algebra's array kernels, errors, checks and the graph).

A :class:`Links` value is the radio between the robots: a :class:`~quatform.network.graph.Graph`
(or a switching schedule of graphs), per-edge delay, jitter and loss, each robot's send rate
and the age beyond which a message is stale. It follows the shape of the loop's measurement
models (``docs/architecture.md``, "Loop and log"): everything that does not depend on the
robots' states is drawn up front on the host (:meth:`Links.schedule`, each world from its own
seed), and the per-tick step reads from it purely (:meth:`Links.write`, :meth:`Links.read`,
branch-free on any array namespace: NumPy, JAX under ``jax.jit``).

The schedule stores, for every receive tick ``k``, world and edge ``(i, j)``, the lag
``k - s`` of the newest message of robot ``j`` that robot ``i`` holds at ``k`` (sent at tick
``s``; -1: none, or only a stale one); the state is a ring of the last ``L`` ticks'
outgoing messages of every robot, from which :meth:`Links.read` gathers by those lags.
``docs/networks.md`` ("Links: delay, loss, rate, switching") states what is drawn, from
which stream and in which order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import common_namespace
from ..checks import short
from ..errors import InvalidInputError, NonFiniteError, ShapeError
from .graph import Graph, positive

__all__ = ["Links", "delivered_edges", "inbox"]

#: Rounding allowance, in ticks: a delay of exactly ``m dt`` is ``m`` ticks, a send clock
#: exactly at a multiple of its period crosses it, a message exactly ``max_age_s`` old is valid.
TICK_TOL = 1e-9

#: Uniform draws per candidate edge and send tick: the loss draw, then the jitter draw.
DRAWS_PER_EDGE = 2


def _graphs(graph):
    """``(starts (S,), graphs)``: a :class:`Graph` as one interval from ``-inf``, or a switching
    schedule of ``(start_s, Graph)`` pairs checked (starts finite and increasing, one robot count)."""
    if isinstance(graph, Graph):
        return np.array([-math.inf]), (graph,)
    try:
        pairs = [tuple(p) for p in graph]
    except TypeError:
        raise InvalidInputError(f"links: graph {short(graph)} must be a Graph or a sequence of (start_s, Graph) "
                                f"pairs") from None
    if not pairs or any(len(p) != 2 or not isinstance(p[1], Graph) for p in pairs):
        raise InvalidInputError(f"links: graph {short(graph)} must be a Graph or a non-empty sequence of "
                                f"(start_s, Graph) pairs")
    starts = np.array([float(p[0]) if isinstance(p[0], (int, float, np.number)) and not isinstance(p[0], bool)
                       else math.nan for p in pairs])
    if not np.all(np.isfinite(starts)):
        k = int(np.argmax(~np.isfinite(starts)))
        raise NonFiniteError(f"links: start_s = {short(pairs[k][0])} of switching interval #{k + 1} must be a "
                             f"finite time in seconds")
    if np.any(np.diff(starts) <= 0.0):
        k = int(np.argmax(np.diff(starts) <= 0.0))
        raise InvalidInputError(f"links: switching starts must increase, yet interval #{k + 2} starts at "
                                f"{starts[k + 1]:.6g} s, not after #{k + 1} at {starts[k]:.6g} s; sort the "
                                f"intervals by start time and merge equal starts")
    counts = [p[1].n for p in pairs]
    if len(set(counts)) > 1:
        k = next(k for k, c in enumerate(counts) if c != counts[0])
        raise InvalidInputError(f"links: the graph of switching interval #{k + 1} has {counts[k]} robots, the "
                                f"first has {counts[0]}; give every interval's graph over the same robots")
    return starts, tuple(p[1] for p in pairs)


def _per_item(value, name: str, unit: str, count: int, item: str, strict: bool = False,
              upper: float = math.inf) -> np.ndarray:
    """``value`` (a number or one per ``item``, ``(count,)``) as a read-only ``(count,)`` float
    array, refused in one line unless every entry is finite, ``>= 0`` (``> 0`` where ``strict``)
    and at most ``upper``."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"links: {name} = {short(value)} must be a number or one per {item}, shape "
                                f"({count},){unit}") from None
    if a.ndim and a.shape != (count,):
        raise ShapeError(f"links: {name} must be a number or one per {item}, shape ({count},), got shape {a.shape}")
    a = np.broadcast_to(a, (count,)).copy()
    bad = ~np.isfinite(a) | (a <= 0.0 if strict else a < 0.0) | (a > upper)
    if np.any(bad):
        k = int(np.argmax(bad))
        where = f" of {item} #{k + 1}" if np.ndim(value) else ""
        span = f"in [0, {upper:g}]" if math.isfinite(upper) else ("> 0" if strict else ">= 0")
        raise InvalidInputError(f"links: {name}{where} = {short(float(a[k]))} must be a finite number {span}{unit}")
    a.setflags(write=False)
    return a


def _batch(batch) -> tuple:
    try:
        b = tuple(batch)
    except TypeError:
        raise ShapeError(f"links: batch {short(batch)} must be a tuple of world counts, e.g. () or (8,)") from None
    if any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 1 for s in b):
        raise ShapeError(f"links: batch {short(batch)} must be a tuple of positive integers (world counts), "
                         f"e.g. () or (8,)")
    return tuple(int(s) for s in b)


@dataclass(frozen=True, eq=False)
class Links:
    """The radio between the robots of a team: delay, jitter, loss, send rates, switching, staleness.

    Parameters
    ----------
    graph : Graph or sequence of (float, Graph)
        Who hears whom: edge ``(i, j)`` carries robot ``j``'s messages to robot ``i``. A
        switching schedule is ``(start_s, Graph)`` pairs, starts in s and increasing, every
        graph over the same robots; the graph of ``start_s`` holds from then until the next
        start (the first also before its start). The candidate edges are the union of the
        graphs' edges (sorted by receiver, then sender, as :class:`Graph` sorts); an edge
        carries what is sent while the graph of the sending tick has it (a message in
        flight when the edge goes arrives).
    delay_s : float or array_like, shape (E,)
        Transport delay of each candidate edge, s, >= 0.
    jitter_s : float or array_like, shape (E,)
        Width of the uniform extra delay ``[0, jitter_s)`` drawn per message, s, >= 0 (messages
        may arrive out of order).
    drop : float or array_like, shape (E,)
        Probability that a message on the edge is lost, in ``[0, 1]``.
    rate_hz : float or array_like, shape (N,), optional
        Each robot's send rate (its control rate), Hz, > 0 and at most the loop's ``1/dt``:
        robot ``j`` sends at the first tick and at each tick where its clock ``t r_j`` crosses
        an integer. None: every robot sends every tick.
    max_age_s : float
        A message older than this at the receiver is stale and not used, s, > 0 (``inf``:
        never stale). A message exactly ``max_age_s`` old is valid.
    seed : int
        World ``b`` of a batch (flat index) draws from the stream of ``seed + b``, >= 0.

    Attributes
    ----------
    n : int
        Number of robots.
    edges : ndarray of int, shape (E, 2)
        The candidate edges ``(receiver, sender)``, sorted (read-only).
    starts : ndarray, shape (S,)
        Start of each switching interval, s (``-inf`` for a single graph).
    active : ndarray of bool, shape (S, E)
        Whether interval ``s``'s graph has candidate edge ``e``.
    """

    graph: object
    delay_s: object = 0.0
    jitter_s: object = 0.0
    drop: object = 0.0
    rate_hz: object = None
    max_age_s: float = math.inf
    seed: int = 0

    def __post_init__(self):
        starts, graphs = _graphs(self.graph)
        n = graphs[0].n
        codes = [g.edges[:, 0] * n + g.edges[:, 1] for g in graphs]
        union = np.unique(np.concatenate(codes))
        edges = np.stack([union // n, union % n], axis=1).astype(np.int64)
        active = np.stack([np.isin(union, c) for c in codes])
        count = len(edges)
        age = self.max_age_s
        if isinstance(age, bool) or not isinstance(age, (int, float, np.number)) or math.isnan(age) or age <= 0:
            raise InvalidInputError(f"links: max_age_s = {short(age)} must be a number > 0 s (inf: messages "
                                    f"never go stale)")
        seed = self.seed
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InvalidInputError(f"links: seed = {short(seed)} must be an integer >= 0 (world b draws from "
                                    f"seed + b)")
        for a in (starts, edges, active):
            a.setflags(write=False)
        if not isinstance(self.graph, Graph):
            object.__setattr__(self, "graph", tuple(zip(starts.tolist(), graphs)))
        for name, value in (("n", n), ("edges", edges), ("starts", starts), ("active", active),
                            ("delay_s", _per_item(self.delay_s, "delay_s", " s", count, "candidate edge")),
                            ("jitter_s", _per_item(self.jitter_s, "jitter_s", " s", count, "candidate edge")),
                            ("drop", _per_item(self.drop, "drop", " (a probability)", count, "candidate edge",
                                               upper=1.0)),
                            ("rate_hz", None if self.rate_hz is None else
                             _per_item(self.rate_hz, "rate_hz", " Hz (None: every tick)", n, "robot", strict=True)),
                            ("max_age_s", float(age)), ("seed", int(seed))):
            object.__setattr__(self, name, value)

    # ------------------------------------------------------------------ host: the schedule
    def horizon_ticks(self, dt: float, n_ticks: int) -> int:
        """The oldest lag, in ticks, at which a message is still valid in a run of ``n_ticks``
        ticks of ``dt`` s: ``floor(max_age_s / dt + 1e-9)`` (a message exactly ``max_age_s`` old
        is valid), at most ``n_ticks - 1``. A ring of ``horizon_ticks + 1`` holds every lag
        any chunk of the run's schedule reads."""
        dt = positive(dt, "dt", " s", "links")
        h = n_ticks - 1 if math.isinf(self.max_age_s) else math.floor(self.max_age_s / dt + TICK_TOL)
        return max(0, min(h, n_ticks - 1))

    def robot_ticks(self, times, s0: int = 0, s1: int | None = None) -> np.ndarray:
        """``(s1 - s0, N)`` bool: whether robot ``j`` acts (computes and sends) at the ticks ``s0 ..
        s1 - 1`` of ``times`` (``(T,)``, s): at the first tick and wherever its clock ``t r_j``
        crosses an integer (every tick without ``rate_hz``)."""
        times = np.asarray(times, dtype=float)
        s1 = len(times) if s1 is None else s1
        if self.rate_hz is None:
            return np.ones((s1 - s0, self.n), dtype=bool)
        t = times[max(s0 - 1, 0):s1]
        clock = np.floor(t[:, None] * self.rate_hz[None, :] + TICK_TOL)
        robot = np.concatenate([np.ones((1, self.n), dtype=bool), clock[1:] > clock[:-1]])
        return robot[(1 if s0 > 0 else 0):][:s1 - s0]

    def _sends(self, times: np.ndarray, dt: float, s0: int, s1: int) -> np.ndarray:
        """``(s1 - s0, E)`` bool: whether each candidate edge carries a message sent at ticks
        ``s0 .. s1 - 1`` (its sender's clock crossed a period and the tick's graph has the edge)."""
        robot = self.robot_ticks(times, s0, s1)
        interval = np.maximum(np.searchsorted(self.starts, times[s0:s1] + TICK_TOL * dt, side="right") - 1, 0)
        return robot[:, self.edges[:, 1]] & self.active[interval]

    def schedule(self, times, dt: float, batch: tuple = (), ticks: tuple | None = None) -> dict:
        """Which message each robot holds of each in-neighbour at each tick, drawn up front.

        For every world ``b`` (flat index of ``batch``), candidate edge ``e`` and send tick
        ``s``: the message is sent (its sender's rate, the edge active at ``t_s``), lost (a
        uniform draw ``u_drop < drop``), and arrives ``ceil((delay_s + jitter_s u_jit) / dt
        - 1e-9)`` ticks later (delay 0: the tick it is sent). The uniforms come from
        ``numpy.random.Generator(PCG64(seed + b))`` in the order: tick by tick from tick 0,
        for each tick the ``E`` loss draws then the ``E`` jitter draws (edges in
        :attr:`edges` order), drawn whether or not the edge sends, so tick ``s``'s draws start
        at the stream's ``2 E s``-th double and a chunk skips to them
        (``PCG64.advance``): a chunked schedule equals the whole, and one seed draws the same
        uniforms at any delay, loss or rate.

        Parameters
        ----------
        times : array_like, shape (T,)
            The run's tick times, s (uniform, ``dt`` apart).
        dt : float
            Tick length, s, > 0; every ``rate_hz`` is at most ``1 / dt``.
        batch : tuple of int
            Shape of the batch of worlds.
        ticks : (int, int), optional
            The receive ticks ``k0 .. k1 - 1`` to draw (default all ``T``); a loop draws chunk by
            chunk and gets what one call gives. A chunk looks back ``horizon_ticks + 1`` send
            ticks (all of them when ``max_age_s`` is ``inf``).

        Returns
        -------
        dict
            Each entry with a leading tick axis ``k0 .. k1 - 1``:

            * ``lag`` ``(K, *batch, E)`` int16 (int32 where ``horizon_ticks`` exceeds 32 767):
              ``k - s``, the age in ticks of the newest message delivered by tick ``k`` (the
              largest send tick among those arrived; a reordered older arrival never replaces
              it), -1 where none has arrived or it is older than ``max_age_s``;
            * ``new`` ``(K, *batch, E)`` bool: that message arrived at tick ``k``;
            * ``messages_sent``, ``messages_dropped`` ``(K, *batch)`` int32: messages sent on
              candidate edges at tick ``k`` and those of them lost (a world's totals: the sums
              over the tick axis).

            3 bytes per (tick, world, edge) with int16 lags, plus 8 per (tick, world).

        Raises
        ------
        InvalidInputError
            ``dt`` not > 0, times not finite and increasing, a rate above ``1 / dt``, a batch
            that is not positive integers, a tick range outside ``0 .. T``.
        """
        dt = positive(dt, "dt", " s", "links")
        times = np.asarray(times, dtype=float)
        if times.ndim != 1 or not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0.0):
            raise InvalidInputError(f"links: times must be finite increasing tick times, shape (T,), s; got "
                                    f"{short(times.tolist() if times.ndim else times)}")
        batch = _batch(batch)
        T = len(times)
        k0, k1 = (0, T) if ticks is None else ticks
        if not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in (k0, k1)) or not (
                0 <= k0 <= k1 <= T):
            raise InvalidInputError(f"links: ticks {short(ticks)} must be a range (k0, k1) with 0 <= k0 <= k1 <= "
                                    f"{T} (the run's ticks)")
        if self.rate_hz is not None and np.any(self.rate_hz * dt > 1.0 + TICK_TOL):
            j = int(np.argmax(self.rate_hz))
            raise InvalidInputError(f"links: rate_hz = {self.rate_hz[j]:.6g} Hz of robot {j + 1} is above the loop's "
                                    f"1/dt = {1.0 / dt:.6g} Hz (a robot cannot send faster than the loop ticks); "
                                    f"lower it to at most {1.0 / dt:.6g} Hz or shorten dt")
        h = self.horizon_ticks(dt, max(T, 1))
        lag_type = np.int16 if h <= np.iinfo(np.int16).max else np.int32
        s0 = 0 if math.isinf(self.max_age_s) else max(0, k0 - h - 1)
        E, worlds, K = len(self.edges), math.prod(batch), k1 - k0
        lag = np.empty((K, worlds, E), dtype=lag_type)
        new = np.empty((K, worlds, E), dtype=bool)
        sent = np.empty((K, worlds), dtype=np.int32)
        dropped = np.empty((K, worlds), dtype=np.int32)
        sends = self._sends(times, dt, s0, k1)
        rows = np.arange(s0, k1)
        for b in range(worlds):
            lag[:, b], new[:, b], sent[:, b], dropped[:, b] = self._world(b, sends, rows, dt, h, k0)
        shape = (K,) + batch
        return {"lag": lag.reshape(shape + (E,)), "new": new.reshape(shape + (E,)),
                "messages_sent": sent.reshape(shape), "messages_dropped": dropped.reshape(shape)}

    def _world(self, b: int, sends: np.ndarray, rows: np.ndarray, dt: float, h: int, k0: int):
        """``(lag, new, sent, dropped)`` of world ``b`` at receive ticks ``k0 .. rows[-1]``, from
        the messages sent at ticks ``rows`` (``sends`` ``(len(rows), E)``)."""
        E, s0 = sends.shape[1], (int(rows[0]) if len(rows) else k0)
        stream = np.random.PCG64(self.seed + b)
        stream.advance(DRAWS_PER_EDGE * E * s0)
        u = np.random.Generator(stream).random((len(rows), DRAWS_PER_EDGE, E))
        lost = u[:, 0] < self.drop
        delay = np.maximum(np.ceil((self.delay_s + self.jitter_s * u[:, 1]) / dt - TICK_TOL), 0.0).astype(np.int64)
        arrival = rows[:, None] + delay
        r, e = np.nonzero(sends & ~lost & (arrival <= (rows[-1] if len(rows) else -1)))
        newest = np.full(sends.shape, -1, dtype=np.int64)  # the newest send tick arriving at each tick
        np.maximum.at(newest, (arrival[r, e] - s0, e), rows[r])
        newest = np.maximum.accumulate(newest, axis=0)      # ... arrived by each tick
        before = np.concatenate([np.full((1, E), -1, dtype=np.int64), newest[:-1]])
        age = rows[:, None] - newest
        valid = (newest >= 0) & (age <= h)
        keep = slice(k0 - s0, None)
        return (np.where(valid, age, -1)[keep], (valid & (newest > before))[keep],
                np.sum(sends, axis=1)[keep], np.sum(sends & lost, axis=1)[keep])

    # ------------------------------------------------------------------ the pure step
    def init(self, outgoing0, batch: tuple = (), schedule: dict | None = None, length: int | None = None) -> dict:
        """The links' state before the first tick.

        Parameters
        ----------
        outgoing0 : array_like, shape (N, d) or (*batch, N, d)
            A message of each robot (fills the ring; never read as valid).
        batch : tuple of int
            Shape of the batch of worlds.
        schedule : dict, optional
            :meth:`schedule`'s output; the ring holds its longest lag.
        length : int, optional
            Ring length ``L``, at least the schedule's longest lag + 1 (a loop drawing chunk by
            chunk passes ``horizon_ticks(dt, T) + 1``).

        Returns
        -------
        dict
            ``ring`` ``(*batch, L, N, d)``: the outgoing messages of the last ``L`` ticks, oldest
            first; ``stamps`` ``(*batch, L)``: their send times, s (``-inf``: none yet).
        """
        batch = _batch(batch)
        m = np.asarray(outgoing0, dtype=float)
        if m.ndim < 2 or m.shape[-2] != self.n or m.shape[:-2] not in ((), batch):
            raise ShapeError(f"links: outgoing0 must be (N, d) or (*batch, N, d) with N = {self.n} robots and batch "
                             f"{batch}, got shape {m.shape}")
        if not np.all(np.isfinite(m)):
            raise NonFiniteError("links: outgoing0 holds NaN or infinity; give finite messages")
        longest = 0
        if schedule is not None:
            lag = np.asarray(schedule["lag"])
            if lag.shape[1:] != batch + (len(self.edges),):
                raise ShapeError(f"links: schedule lags of shape {lag.shape} for batch {batch} and "
                                 f"{len(self.edges)} edges; draw the schedule with the same batch")
            longest = int(np.max(lag, initial=-1)) + 1
        if length is None:
            length = max(longest, 1)
        if isinstance(length, bool) or not isinstance(length, (int, np.integer)) or length < max(longest, 1):
            raise InvalidInputError(f"links: ring length {short(length)} must be an integer of at least "
                                    f"{max(longest, 1)} (the schedule's longest lag + 1)")
        ring = np.broadcast_to(m[..., None, :, :], batch + (int(length),) + m.shape[-2:]).copy()
        return {"ring": ring, "stamps": np.full(batch + (int(length),), -math.inf)}

    @staticmethod
    def write(state: dict, outgoing, t) -> dict:
        """``state`` with the tick's outgoing messages ``(*batch, N, d)``, sent at ``t`` (s), as the
        ring's newest entry (the oldest leaves). Write before :meth:`read` in a tick: a message of
        delay 0 is read the tick it is sent. Pure (any array namespace); the shape check reads
        static shapes only, so it holds under ``jax.jit``.

        Raises
        ------
        ShapeError
            ``outgoing`` not of the ring's ``(*batch, N, d)``.
        """
        ring, stamps = state["ring"], state["stamps"]
        want = tuple(ring.shape[:-3]) + tuple(ring.shape[-2:])
        got = getattr(outgoing, "shape", None)
        if got is None or tuple(got) != want:
            seen = f"shape {tuple(got)}" if got is not None else short(outgoing)
            raise ShapeError(f"links: outgoing messages must be (*batch, N, d) = {want} (the ring's batch, robots "
                             f"and message size), got {seen}; write one message per robot of each world")
        xp = common_namespace(ring, outgoing, t)
        now = xp.asarray(t, dtype=stamps.dtype)[..., None]  # t: () or one per world
        now = xp.broadcast_to(now, stamps.shape[:-1] + (1,))
        return {"ring": xp.concatenate([ring[..., 1:, :, :], outgoing[..., None, :, :]], axis=-3),
                "stamps": xp.concatenate([stamps[..., 1:], now], axis=-1)}

    def read(self, state: dict, xs: dict):
        """What each edge's receiver holds at the tick: ``(messages, stamps, valid)``.

        Parameters
        ----------
        state : dict
            :meth:`init`'s state after this tick's :meth:`write`.
        xs : dict
            The tick's slice of :meth:`schedule` (``lag`` ``(*batch, E)``).

        Returns
        -------
        messages : array, shape (*batch, E, d)
            Edge ``(i, j)``'s newest message of robot ``j`` at robot ``i``; 0 where not valid.
        stamps : array, shape (*batch, E)
            Its send time, s; ``-inf`` where not valid.
        valid : array of bool, shape (*batch, E)
            A message has arrived and is at most ``max_age_s`` old (the schedule's lag >= 0; a lag
            the ring does not hold is not valid).

        Pure and branch-free: gathers by index arrays and ``where`` (NumPy, JAX under ``jax.jit``).
        """
        ring, stamps = state["ring"], state["stamps"]
        xp = common_namespace(ring, xs["lag"])
        length, n, d = ring.shape[-3:]
        batch = ring.shape[:-3]
        lag = xp.asarray(xs["lag"], dtype=xp.int32)
        valid = (lag >= 0) & (lag < length)
        slot = (length - 1) - xp.where(valid, lag, 0)
        flat = slot * n + xp.asarray(self.edges[:, 1], dtype=xp.int32)
        count = flat.shape[-1]
        got = xp.take_along_axis(xp.reshape(ring, batch + (length * n, d)),
                                 xp.broadcast_to(flat[..., None], batch + (count, d)), axis=-2)
        when = xp.take_along_axis(stamps, slot, axis=-1)
        return xp.where(valid[..., None], got, 0.0), xp.where(valid, when, -math.inf), valid


def delivered_edges(xs: dict):
    """``(*batch, E)`` bool: the candidate edges whose receiver got a new newest message at the
    tick (``xs`` the tick's slice of :meth:`Links.schedule`; ``numpy.flatnonzero`` of a world's
    row names them)."""
    return xs["new"]


def inbox(received, graph) -> dict:
    """Each robot's received messages grouped by receiver, padded to the largest in-degree.

    A padded ``(N, max_in)`` layout with a mask rather than ``(N + 1,)`` offsets: a per-robot
    law then runs on fixed shapes over all robots at once (the same branch-free code on NumPy
    and under ``jax.jit``), where offsets need segment reductions that differ between
    namespaces. Edges are sorted by receiver, so slot ``m`` of robot ``i`` is its ``m``-th
    in-neighbour in increasing order.

    Parameters
    ----------
    received : tuple
        :meth:`Links.read`'s ``(messages (*batch, E, d), stamps (*batch, E), valid (*batch, E))``.
    graph : Graph or Links
        Whose edges (``.n``, ``.edges``, sorted by receiver) index ``received``: the
        :class:`Links`' candidate edges.

    Returns
    -------
    dict
        ``senders`` ``(N, max_in)`` int (-1: padding), ``messages`` ``(*batch, N, max_in, d)``
        (0 at padding), ``stamps`` ``(*batch, N, max_in)`` s (``-inf`` at padding), ``valid``
        ``(*batch, N, max_in)`` bool (False at padding).

    Raises
    ------
    ShapeError
        ``received`` not a ``(messages, stamps, valid)`` triple of those shapes, or of another
        edge count than ``graph``'s (static shapes only: it holds under ``jax.jit``).
    """
    shapes = [getattr(a, "shape", None) for a in received] if isinstance(received, (tuple, list)) else []
    if (len(shapes) != 3 or any(q is None for q in shapes) or len(shapes[0]) < 2
            or tuple(shapes[1]) != tuple(shapes[0][:-1]) or tuple(shapes[2]) != tuple(shapes[1])):
        seen = f"shapes {[None if q is None else tuple(q) for q in shapes]}" if shapes else short(received)
        raise ShapeError(f"links: received must be Links.read's (messages (*batch, E, d), stamps (*batch, E), "
                         f"valid (*batch, E)), got {seen}; pass what read returns")
    messages, stamps, valid = received
    edges, n = np.asarray(graph.edges), graph.n
    if messages.shape[-2] != len(edges):
        raise ShapeError(f"links: inbox of {messages.shape[-2]} received messages for {len(edges)} edges; pass the "
                         f"graph (or Links) whose edges read them")
    counts = np.bincount(edges[:, 0], minlength=n)
    width = int(np.max(counts, initial=0))
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    index = np.zeros((n, width), dtype=np.int64)
    senders = np.full((n, width), -1, dtype=np.int64)
    pos = np.arange(len(edges)) - first[edges[:, 0]]
    index[edges[:, 0], pos] = np.arange(len(edges))
    senders[edges[:, 0], pos] = edges[:, 1]
    mask = senders >= 0
    xp = common_namespace(messages, stamps, valid)
    flat = index.reshape(-1)
    shape = messages.shape[:-2] + (n, width)
    got = xp.reshape(xp.take(messages, flat, axis=-2), shape + messages.shape[-1:])
    return {"senders": senders,
            "messages": xp.where(mask[..., None], got, 0.0),
            "stamps": xp.where(mask, xp.reshape(xp.take(stamps, flat, axis=-1), shape), -math.inf),
            "valid": xp.logical_and(xp.asarray(mask), xp.reshape(xp.take(valid, flat, axis=-1), shape))}
