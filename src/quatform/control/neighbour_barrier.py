"""Decentralised separation barrier: each robot filters its own velocity command against the neighbours it senses.

Control layer (imports the algebra's array kernels and the errors).

:class:`~quatform.control.safety.SeparationBarrier` keeps every pair of a team apart from one
process that sees every robot. Here each robot keeps itself apart from the neighbours it
hears, from what it knows of them: each neighbour's position as last received and the age
of that message. The pair constraint of Wang, Ames and Egerstedt 2017 (IEEE T-RO 33(3)) on
the single-integrator certificate ``h_ij = |p_i - p_j|^2 - d^2`` (the Robotarium's, as
:mod:`~quatform.control.safety` takes it) is split between the two robots, each taking half
(their §IV decentralised certificates), and made robust to the neighbour's unknown motion
since its message was sent (at most ``v_max age``). With ``y = p_i - q_j`` (``q_j`` the
position received, ``a_j`` its age, ``r = v_max a_j``) robot ``i``'s half is

    2 y . u - 2 r |u| >= -gamma max(0, h_lo) / 2,    h_lo = max(|y| - r, 0)^2 - d^2

(``docs/derivations.md``, "Decentralised separation barrier"): ``h_lo`` is a lower bound of
the true ``h_ij``, ``2 y . u - 2 r |u|`` one of the true ``2 p_ij . u``, and the clamp at 0
makes ``u = 0`` satisfy every half. Two robots that obey their halves (and the speed bound
``|u| <= v_max``) while holding their commands over a common tick of ``dt`` with
``gamma dt <= 1`` keep ``|p_i - p_j| >= d`` at every instant, whatever the delays and losses
(a lost message only ages what the receiver holds).

Each robot's programme, ``min |u - u_nom|^2`` over its halves and ``|u| <= v_max``, is solved
with ``2 r |u|`` taken at its bound ``2 r v_max`` (a halfspace that implies the half inside
the speed ball), exactly: in 3-D its solution is the projection of ``u_nom`` on the planes of
at most three halfspaces, and among those projections whose multipliers are all >= 0 it is
the one farthest from ``u_nom`` (weak duality), so a fixed number of closed-form candidates
(the subsets of at most three of the :data:`CANDIDATES` halfspaces nearest to being broken
at ``u_nom``; all of them where a robot hears at most that many) gives it, with no iteration.
One test against every halfspace certifies it; where it fails (a linearised programme with
no solution, or one the candidates do not span), the robot takes its saturated nominal
command. A last step scales the command by the largest factor in ``[0, 1]`` that keeps every
exact half and the speed bound (0 keeps them all), so the command always satisfies them.

Pure and branch-free on the array namespace (:func:`quatform.algebra.kernels.common_namespace`):
the same code runs on NumPy and under ``jax.jit``; row ``i`` of every output depends only on
row ``i`` of the inputs (the function runs on one robot's node with ``N = 1``).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import common_namespace
from ..checks import short
from ..errors import InvalidInputError, ShapeError

__all__ = ["CANDIDATES", "SIGNALS", "NeighbourBarrier", "neighbour_filter"]

#: Most halfspaces of one robot's programme solved exactly (the static size ``K``): a robot
#: that hears more keeps the ``K`` nearest to being violated at its nominal command.
CANDIDATES = 8

#: The named signals :func:`neighbour_filter` returns beside the commands, each ``(*batch, N)``.
SIGNALS = ("binding", "clearance_m", "scale", "fallback")

#: Relative margin by which the programme's halfspaces are tightened, so that its solution
#: meets the exact halves despite rounding (about 5 000 ulps of the terms of a half).
_MARGIN = 1e-12


def _subsets(K: int, k: int) -> np.ndarray:
    """``(C(K, k), k)`` indices of the ``k``-subsets of ``range(K)`` (lexicographic)."""
    return np.array(list(itertools.combinations(range(K), k)), dtype=np.intp).reshape(-1, k)


@functools.lru_cache(maxsize=None)
def _pairs_of_triples(K: int) -> tuple:
    """For each 3-subset ``(j1, j2, j3)`` of ``range(K)``, the indices among the 2-subsets (of
    :func:`_subsets`) of ``(j1, j2)``, ``(j1, j3)``, ``(j2, j3)``."""
    index = {tuple(pair): k for k, pair in enumerate(_subsets(K, 2).tolist())}
    triples = _subsets(K, 3).tolist()
    return tuple(np.array([index[(t[a], t[b])] for t in triples], dtype=np.intp).reshape(-1)
                 for a, b in ((0, 1), (0, 2), (1, 2)))


@functools.lru_cache(maxsize=None)
def _sets(K: int) -> np.ndarray:
    """``(3, S)``: the halfspaces of each candidate of :func:`_filter` (the empty set, then the
    subsets of 1, 2 and 3 of ``range(K)``), 0 where a candidate has fewer than three."""
    sets = [np.zeros((3, 1), dtype=np.intp)]
    for k in range(1, min(K, 3) + 1):
        sets.append(np.pad(_subsets(K, k).T, ((0, 3 - k), (0, 0))))
    return np.concatenate(sets, axis=1)


def _positive(value, name: str, unit: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not (
            math.isfinite(value) and value > 0.0):
        raise InvalidInputError(f"NeighbourBarrier: {name} = {short(value)} must be a finite number > 0{unit} "
                                f"({what})")
    return float(value)


@dataclass(frozen=True)
class NeighbourBarrier:
    """Per-robot separation barrier certificates with shared responsibility, robust to message age.

    Parameters
    ----------
    min_separation_m : float
        Smallest distance ``d`` two robots may come to, m.
    max_speed_m_s : float
        Speed bound of every robot, m/s: each robot's command is saturated to it, and a
        neighbour's position ``age`` s old is known within ``max_speed_m_s * age``.
    gamma : float
        Barrier rate, 1/s (Wang et al. 2017's linear class-K function): a pair closes in no
        faster than ``gamma h / (2 |p_ij|)``. The guarantee needs ``gamma dt <= 1`` for the
        tick ``dt`` over which the commands are held.
    dt_s : float or None
        The tick, s: given, ``gamma dt_s <= 1`` is checked.

    Notes
    -----
    The promise (``docs/derivations.md``, "Decentralised separation barrier"): robots that
    start at least ``d`` apart, each run this filter at every tick of a common clock of
    period ``dt`` (``gamma dt <= 1``) and hold its command over the tick, never come closer
    than ``d`` (between ticks included), provided every pair that can come within reach of
    ``d`` is sensed by both robots: each holds a message of the other (of any age; a lost
    message only ages the one held) or marks it unknown (the robot then stays).
    """

    min_separation_m: float
    max_speed_m_s: float
    gamma: float = 5.0
    dt_s: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "min_separation_m", _positive(self.min_separation_m, "min_separation_m", " m",
                                                               "the smallest distance two robots may come to"))
        object.__setattr__(self, "max_speed_m_s", _positive(self.max_speed_m_s, "max_speed_m_s", " m/s",
                                                            "every robot's speed bound"))
        object.__setattr__(self, "gamma", _positive(self.gamma, "gamma", " 1/s", "the barrier rate"))
        if self.dt_s is not None:
            object.__setattr__(self, "dt_s", _positive(self.dt_s, "dt_s", " s", "the tick the commands are held"))
            if self.gamma * self.dt_s > 1.0 + 1e-12:
                raise InvalidInputError(f"NeighbourBarrier: gamma * dt_s = {self.gamma * self.dt_s:.6g} > 1: the "
                                        f"sampled pair may cross the barrier; give gamma <= {1.0 / self.dt_s:.6g} 1/s")

    def filter(self, u_nom, p, p_nb, age_s, valid):
        """:func:`neighbour_filter` with this barrier's parameters."""
        return neighbour_filter(self, u_nom, p, p_nb, age_s, valid)

    def filter_inbox(self, u_nom, p, inbox: dict, t, hold_unheard: bool = False):
        """:func:`neighbour_filter` on an inbox of :func:`quatform.network.inbox`'s layout.

        Parameters
        ----------
        u_nom : array, shape (*batch, N, 3)
            Nominal velocity commands, m/s.
        p : array, shape (*batch, N, 3)
            Each robot's own position, m.
        inbox : dict
            ``senders`` ``(N, W)`` int (-1: padding), ``messages`` ``(*batch, N, W, d)`` whose
            first 3 entries are the sender's position at its send time (m), ``stamps``
            ``(*batch, N, W)`` send times, s, ``valid`` ``(*batch, N, W)`` bool.
        t : float or array
            The time now, s (``age = t - stamp``).
        hold_unheard : bool
            False (default): a slot without a valid message is no neighbour. True: a slot of
            a sender (``senders >= 0``) without a valid message is a neighbour of unknown
            position, and the robot stays (its command 0) until its message arrives; the
            safe choice where every slot is a neighbour the robot must avoid (a fixed graph),
            not where the slots are the union of switching graphs.

        Returns
        -------
        As :func:`neighbour_filter`.
        """
        messages, stamps, valid = inbox["messages"], inbox["stamps"], inbox["valid"]
        if messages.shape[-1] < 3:
            raise ShapeError(f"NeighbourBarrier.filter_inbox: messages of {messages.shape[-1]} entries; the first 3 "
                             f"must be the sender's position, m")
        xp = common_namespace(messages, stamps, valid, t)
        sensed = valid
        if hold_unheard:
            sensed = xp.logical_or(valid, xp.asarray(np.asarray(inbox["senders"]) >= 0))
        age = xp.where(valid, t - xp.where(valid, stamps, 0.0), xp.inf)
        return neighbour_filter(self, u_nom, p, messages[..., :3], age, sensed)


def neighbour_filter(barrier: NeighbourBarrier, u_nom, p, p_nb, age_s, valid):
    """Each robot's velocity command filtered against the neighbours it senses.

    Parameters
    ----------
    barrier : NeighbourBarrier
        ``d`` (``min_separation_m``), ``gamma``, ``v_max`` (``max_speed_m_s``).
    u_nom : array, shape (*batch, N, 3)
        Nominal velocity commands, m/s (saturated to ``v_max`` here; a row that is not
        finite is taken as 0).
    p : array, shape (*batch, N, 3)
        Each robot's own position, m (a robot whose position is not finite stays: command 0).
    p_nb : array, shape (*batch, N, W, 3)
        Robot ``i``'s slot ``w``: the neighbour's position at its send time, m (the padded
        inbox layout of :func:`quatform.network.inbox`).
    age_s : array, shape (*batch, N, W)
        Age of each slot's position, s (now less the send stamp; below 0 counts as 0).
    valid : array of bool, shape (*batch, N, W)
        The slot is a sensed neighbour. A valid slot whose position or age is NaN, or whose
        age is infinite, is a neighbour of unknown position: the robot stays.

    Returns
    -------
    u : array, shape (*batch, N, 3)
        Commands, m/s: ``|u| <= v_max``; every robot's halves hold; the saturated nominal
        command bitwise where none binds (``binding`` 0 and ``|u_nom| <= v_max``).
    signals : dict
        Each ``(*batch, N)`` (:data:`SIGNALS`):

        * ``binding`` (int): the sensed neighbours whose (linearised) half the saturated
          nominal command breaks;
        * ``clearance_m``: the smallest distance to a sensed neighbour the robot can prove,
          ``max(|y| - v_max age, 0)``, less ``d``, m (``inf`` with no neighbour sensed);
        * ``scale``: the factor in ``[0, 1]`` of the last step, which scales the programme's
          answer (or the fallback's command) so every exact half and the speed bound hold
          (1 where they hold as they are);
        * ``fallback`` (bool): no certified solution of the linearised programme (it has
          none, or, for a robot sensing more than :data:`CANDIDATES`, the candidates do not
          reach it): the command is the saturated nominal scaled by ``scale`` (False for a
          robot that stays for a neighbour of unknown position or its own lost position).

    Raises
    ------
    ShapeError
        Arrays whose trailing shapes do not match.
    """
    xp = common_namespace(u_nom, p, p_nb, age_s, valid)
    shapes = [tuple(np.shape(a)) for a in (u_nom, p, p_nb, age_s, valid)]
    if (len(shapes[0]) < 2 or shapes[0][-1] != 3 or shapes[1][-2:] != shapes[0][-2:] or len(shapes[2]) < 3
            or shapes[2][-1] != 3 or shapes[3][-2:] != shapes[2][-3:-1] or shapes[4][-2:] != shapes[2][-3:-1]
            or shapes[2][-3] != shapes[0][-2]):
        raise ShapeError(f"neighbour_filter: u_nom and p must be (*batch, N, 3), p_nb (*batch, N, W, 3), age_s and "
                         f"valid (*batch, N, W); got {shapes[0]}, {shapes[1]}, {shapes[2]}, {shapes[3]}, {shapes[4]}")
    try:
        lead = np.broadcast_shapes(shapes[0][:-2], shapes[1][:-2], shapes[2][:-3], shapes[3][:-2], shapes[4][:-2])
    except ValueError:
        raise ShapeError(f"neighbour_filter: batch axes {shapes[0][:-2]}, {shapes[1][:-2]}, {shapes[2][:-3]}, "
                         f"{shapes[3][:-2]}, {shapes[4][:-2]} do not broadcast") from None
    n, W = shapes[0][-2], shapes[2][-2]
    d, gam, v = barrier.min_separation_m, barrier.gamma, barrier.max_speed_m_s
    u_nom = xp.broadcast_to(xp.asarray(u_nom, dtype=xp.float64), lead + (n, 3))
    p = xp.broadcast_to(xp.asarray(p, dtype=xp.float64), lead + (n, 3))
    p_nb = xp.broadcast_to(xp.asarray(p_nb, dtype=xp.float64), lead + (n, W, 3))
    age_s = xp.broadcast_to(xp.asarray(age_s, dtype=xp.float64), lead + (n, W))
    valid = xp.broadcast_to(xp.asarray(valid, dtype=bool), lead + (n, W))
    # rows: the robots of every world along the last axis, components and slots in front
    R = math.prod(lead) * n
    u_r = xp.transpose(xp.reshape(u_nom, (R, 3)))
    p_r = xp.transpose(xp.reshape(p, (R, 3)))
    nb_r = xp.transpose(xp.reshape(p_nb, (R, W, 3)), (2, 1, 0))
    age_r = xp.transpose(xp.reshape(age_s, (R, W)))
    valid_r = xp.transpose(xp.reshape(valid, (R, W)))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # NumPy: candidates not taken
        u, signals = _filter(xp, d, gam, v, u_r, p_r, nb_r, age_r, valid_r)
    return (xp.reshape(xp.transpose(u), lead + (n, 3)),
            {k: xp.reshape(s, lead + (n,)) for k, s in signals.items()})


def _dot(a, b):
    """``a . b`` of vectors given as 3-tuples of arrays (broadcast)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _filter(xp, d, gam, v, u_nom, p, p_nb, age_s, valid):
    """:func:`neighbour_filter` on rows: ``u_nom``, ``p`` ``(3, R)``, ``p_nb`` ``(3, W, R)``,
    ``age_s``, ``valid`` ``(W, R)`` (one robot of one world per row ``R``); returns ``u``
    ``(3, R)`` and the signals, each ``(R,)``."""
    # -- the saturated nominal command; a robot lost (position not finite) stays
    own = xp.all(xp.isfinite(p), axis=0)
    go = own & xp.all(xp.isfinite(u_nom), axis=0)
    un = xp.where(go, u_nom, 0.0)
    speed = xp.sqrt(_dot(un, un))
    over = speed > v
    u0 = xp.where(over, un * (v / xp.where(over, speed, 1.0)), un)
    u0 = (u0[0], u0[1], u0[2])

    # -- each slot's half: 2 y.u - 2 r |u| + m >= 0 (docs/derivations.md)
    sensed = valid & own
    known = sensed & xp.all(xp.isfinite(p_nb), axis=0) & ~xp.isnan(age_s)
    y = xp.where(known, xp.where(own, p, 0.0)[:, None, :] - xp.where(known, p_nb, 0.0), 0.0)  # (3, W, R)
    ny = xp.sqrt(_dot(y, y))
    age = xp.where(known, xp.maximum(age_s, 0.0), xp.inf)  # unknown: infinitely old
    r = xp.where(sensed, xp.minimum(v * age, ny + d), 0.0)  # beyond |y| + d the half is u = 0 whatever r is
    lo = xp.maximum(ny - r, 0.0)  # the proven distance
    m = xp.where(sensed, 0.5 * gam * xp.maximum(lo * lo - d * d, 0.0), 0.0)
    a = (2.0 * y[0], 2.0 * y[1], 2.0 * y[2])
    # the programme's halfspace a.u >= b: |u| at its bound v, tightened by eta against rounding
    eta = _MARGIN * (2.0 * ny * v + m + 2.0 * r * v)
    b = xp.where(sensed, 2.0 * r * v - m + eta, 0.0)
    tol = -0.5 * eta  # a candidate's slack may be this short of b
    s0 = _dot(a, u0) - b  # (W, R): the slack of the nominal
    binding = sensed & (s0 < tol)

    # -- the K halfspaces nearest to being violated at u0 (all of them where W <= K)
    W = s0.shape[0]
    K = min(W, CANDIDATES)
    if K < W:
        key = xp.where(sensed, s0 / xp.maximum(2.0 * ny, 1e-300), xp.inf)
        idx = xp.argsort(key, axis=0, stable=True)[:K]  # (K, R), ties by slot
        aK = tuple(xp.take_along_axis(c, idx, axis=0) for c in a)
        bK, sK, tK = (xp.take_along_axis(x, idx, axis=0) for x in (b, s0, tol))
    else:
        aK, bK, sK, tK = a, b, s0, tol
    # -- the candidates: the projection of u0 on the planes of every subset S of at most three
    # of the K halfspaces, u = u0 + sum_l mu_l a_l with G_SS mu = -s0_S (G the Gram matrix). A
    # candidate whose mu are >= 0 is a dual-feasible point of value |u - u0|^2 = -mu . s0_S;
    # the solution of the programme over the K is the one of largest value (docs/derivations.md)
    zero = xp.zeros((1,) + s0.shape[1:], dtype=s0.dtype)
    groups = [((), zero)]  # (mu, value) of each group of candidates: first the empty set, u0
    if K >= 1:
        g = _dot(aK, aK)  # (K, R)
        ok = g > 0.0
        mu = -sK / xp.where(ok, g, 1.0)
        groups.append(((mu,), xp.where(ok & (mu >= 0.0), -mu * sK, -xp.inf)))
    if K >= 2:
        i1, i2 = _subsets(K, 2).T
        gp = _dot(tuple(c[i1] for c in aK), tuple(c[i2] for c in aK))  # (P, R): a_1 . a_2 of each pair
        g11, g22 = g[i1], g[i2]
        det2 = g11 * g22 - gp * gp  # |a_1 x a_2|^2
        ok = det2 > 1e-12 * g11 * g22
        s1, s2 = sK[i1], sK[i2]
        n1, n2 = gp * s2 - g22 * s1, gp * s1 - g11 * s2  # Cramer's rule
        den = xp.where(ok, det2, 1.0)
        mu1, mu2 = n1 / den, n2 / den
        groups.append(((mu1, mu2), xp.where(ok & (n1 >= 0.0) & (n2 >= 0.0), -(mu1 * s1 + mu2 * s2), -xp.inf)))
    if K >= 3:
        j1, j2, j3 = _subsets(K, 3).T
        q12, q13, q23 = _pairs_of_triples(K)
        g11, g22, g33, g12, g13, g23 = g[j1], g[j2], g[j3], gp[q12], gp[q13], gp[q23]
        c11, c22, c33 = det2[q23], det2[q13], det2[q12]  # the cofactors of G_SS
        c12, c13, c23 = g13 * g23 - g12 * g33, g12 * g23 - g13 * g22, g12 * g13 - g11 * g23
        det = g11 * c11 + g12 * c12 + g13 * c13  # (a_1 . a_2 x a_3)^2
        ok = det > 1e-18 * g11 * g22 * g33
        s1, s2, s3 = sK[j1], sK[j2], sK[j3]
        n1 = -(c11 * s1 + c12 * s2 + c13 * s3)
        n2 = -(c12 * s1 + c22 * s2 + c23 * s3)
        n3 = -(c13 * s1 + c23 * s2 + c33 * s3)
        den = xp.where(ok, det, 1.0)
        mu1, mu2, mu3 = n1 / den, n2 / den, n3 / den
        groups.append(((mu1, mu2, mu3), xp.where(ok & (n1 >= 0.0) & (n2 >= 0.0) & (n3 >= 0.0),
                                                 -(mu1 * s1 + mu2 * s2 + mu3 * s3), -xp.inf)))
    best = xp.argmax(xp.concatenate([value for _, value in groups], axis=0), axis=0)  # (R,): the first largest
    MU = [xp.zeros_like(u0[0])] * 3  # the best candidate's mu
    start = 0
    for mus, value in groups:
        size = value.shape[0]
        inside = (best >= start) & (best < start + size)
        at = xp.clip(best - start, 0, size - 1)[None]
        for q, m_q in enumerate(mus):
            MU[q] = xp.where(inside, xp.take_along_axis(m_q, at, axis=0)[0], MU[q])
        start += size
    L = xp.asarray(_sets(K))[:, best]  # (3, R): the best candidate's halfspaces
    if K:
        ub = tuple(u0[k] + sum(MU[q] * xp.take_along_axis(aK[k], L[q][None], axis=0)[0] for q in range(3))
                   for k in range(3))
    else:  # no slot (W = 0)
        ub = u0
    changed = xp.any(binding, axis=0)
    ub = tuple(xp.where(changed, c, c0) for c, c0 in zip(ub, u0))  # no halfspace broken: u0 bitwise
    # the solution over the K meets every halfspace: it is the programme's solution; where it
    # does not (a programme with no solution, or one the K do not span), the fallback's
    # direction is the saturated nominal
    solved = xp.all(_dot(a, ub) - b >= tol, axis=0)
    ub = tuple(xp.where(solved, c, c0) for c, c0 in zip(ub, u0))

    # -- the last step: the largest factor in [0, 1] that keeps every exact half and the bound
    nb = xp.sqrt(_dot(ub, ub))
    cw = _dot(a, ub) - 2.0 * r * nb  # the half at s ub: s cw + m >= 0
    short_ = sensed & (cw + m < 0.0)
    sw = xp.where(short_, m / xp.where(short_, -cw, 1.0), 1.0)
    fast = nb > v
    sb = xp.where(fast, v / xp.where(fast, nb, 1.0), 1.0)
    s = xp.min(xp.concatenate([sb[None], sw], axis=0), axis=0)
    u = xp.stack([xp.where(s < 1.0, s * c, c) for c in ub])

    none = xp.full((1,) + lo.shape[1:], xp.inf)
    clearance = xp.min(xp.concatenate([none, xp.where(sensed, lo - d, xp.inf)], axis=0), axis=0)
    # a robot that stays for a neighbour of unknown position (or its own lost) is no fallback:
    # its programme has no solution by construction, and its command is 0 on every namespace
    stays = ~own | xp.any(sensed & ~(known & (age < xp.inf)), axis=0)
    signals = {"binding": xp.sum(binding.astype(xp.int32), axis=0), "clearance_m": clearance,
               "scale": s, "fallback": ~solved & ~stays}
    return u, signals
