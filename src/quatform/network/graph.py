"""The communication graph of a robot team: who hears whom, its Laplacian, λ₂ and the rate it predicts.

Formations and planning layer (imports errors and checks only).

Convention (Olfati-Saber & Murray 2004; Ren & Beard 2005): an edge ``(i, j)`` with
weight ``a_ij > 0`` means robot ``i`` receives robot ``j``'s messages (``j`` is an
in-neighbour of ``i``); information flows from ``j`` to ``i``. The Laplacian is
``L = D - A`` with ``A[i, j] = a_ij`` and ``D = diag(sum_j a_ij)``, so the consensus law
``x_dot = -k L x`` moves each robot towards the robots it hears. Robot indices are 0-based in
arrays and 1-based in messages ("robot 1" is index 0), as everywhere in quatform.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..checks import short
from ..errors import InvalidInputError, NonFiniteError, ShapeError, UnreachableError

__all__ = ["Graph", "positive", "robots_text", "switching_rate"]

#: Rows of the distance matrix that ``Graph.k_nearest`` and ``Graph.disk`` hold at once
#: (a block of ``ROWS x N`` distances: 2 MB at N = 1000).
ROWS = 256


def robots_text(indices, limit: int = 12) -> str:
    """``"4, 7"``: 0-based robot indices as the 1-based numbers messages use, at most ``limit``
    named (``"1, 2, ..., 12, ... (40 robots)"``)."""
    names = [str(int(i) + 1) for i in indices]
    if len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f", ... ({len(names)} robots)"


def positive(value, name: str, unit: str, where: str = "graph") -> float:
    """``value`` as a float, refused in one line (``where: name = value must be ...``) unless it
    is a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not (
            math.isfinite(value) and value > 0.0):
        raise InvalidInputError(f"{where}: {name} = {short(value)} must be a finite number > 0{unit}")
    return float(value)


def _count(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InvalidInputError(f"graph: n = {short(n)} robots must be an integer of at least 2 "
                                f"(a network needs two robots)")
    return int(n)


def _pair(row) -> str:
    """``"(0, 1.5)"``: an edge as given, its numbers printed plainly."""
    return "(" + ", ".join(f"{float(v):g}" for v in row) + ")"


def _edge_array(n: int, edges) -> np.ndarray:
    try:
        e = np.asarray(edges, dtype=float)
    except (TypeError, ValueError):
        raise ShapeError(f"graph: edges {short(edges)} must be pairs (i, j) of robot indices, shape (E, 2)") from None
    if e.size == 0:
        e = np.zeros((0, 2))
    if e.ndim != 2 or e.shape[1] != 2:
        raise ShapeError(f"graph: edges must be pairs (i, j) of robot indices, shape (E, 2), got shape "
                         f"{e.shape}")
    bad = ~np.isfinite(e) | (e != np.round(e))
    if np.any(bad):
        k = int(np.argmax(bad.any(axis=1)))
        raise InvalidInputError(f"graph: edge #{k + 1} {_pair(e[k])} must be two whole robot indices in "
                                f"0 .. {n - 1} (0-based: robot 1 is index 0)")
    out = (e < 0) | (e > n - 1)
    if np.any(out):
        k = int(np.argmax(out.any(axis=1)))
        raise InvalidInputError(f"graph: edge #{k + 1} {_pair(e[k])} names index {e[k][out[k]][0]:g}, outside "
                                f"0 .. {n - 1} ({n} robots, 0-based: robot 1 is index 0); renumber it or raise n")
    e = e.astype(np.int64)
    loop = e[:, 0] == e[:, 1]
    if np.any(loop):
        k = int(np.argmax(loop))
        raise InvalidInputError(f"graph: edge #{k + 1}, robot {e[k, 0] + 1} hears robot {e[k, 1] + 1}, is a "
                                f"self-loop (a robot hearing itself); remove it")
    return e


def _given_once(e: np.ndarray, undirected: bool) -> None:
    """Refuse, in one line, the first edge of ``e`` (in the order given) that repeats an earlier
    one (``undirected``: ``(j, i)`` repeats ``(i, j)``)."""
    keys = np.sort(e, axis=1) if undirected else e
    if not len(keys):
        return
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    earlier = first[inverse.reshape(-1)]
    twice = earlier != np.arange(len(e))
    if np.any(twice):
        k = int(np.argmax(twice))
        i, j = e[k] + 1
        if undirected:
            raise InvalidInputError(f"graph: edge #{k + 1}, robots {i} and {j}, is given twice (also as edge "
                                    f"#{earlier[k] + 1}; an undirected edge links both ways); give each pair once")
        raise InvalidInputError(f"graph: edge #{k + 1}, robot {i} hears robot {j}, is given twice (also as edge "
                                f"#{earlier[k] + 1}); give it once with the summed weight")


def _weight_array(weights, count: int) -> np.ndarray:
    w = np.ones(count) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (count,):
        raise ShapeError(f"graph: weights must have one entry per edge, shape ({count},), got shape {w.shape}")
    if not np.all(np.isfinite(w)):
        k = int(np.argmax(~np.isfinite(w)))
        raise NonFiniteError(f"graph: weight of edge #{k + 1} is {w[k]:g}; give a finite positive weight")
    if np.any(w <= 0.0):
        k = int(np.argmax(w <= 0.0))
        raise InvalidInputError(f"graph: weight of edge #{k + 1} is {w[k]:.6g}, must be > 0 (a_ij > 0; leave "
                                f"the edge out for no link)")
    return w


def _positions(positions) -> np.ndarray:
    p = np.asarray(positions, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 2:
        raise ShapeError(f"graph: positions must be (N, 3) in metres with N >= 2 robots, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        k = int(np.argmax(~np.isfinite(p).all(axis=1)))
        raise NonFiniteError(f"graph: position of robot {k + 1} is {short(p[k].tolist())}; give finite positions")
    return p


def _distance_blocks(p: np.ndarray):
    """``(rows, d)``: blocks of robot indices and their distances ``(len(rows), N)`` to every robot
    (from coordinate differences, as a user measures a separation), the robot's own entry ``inf``."""
    for start in range(0, len(p), ROWS):
        rows = np.arange(start, min(start + ROWS, len(p)))
        d = np.linalg.norm(p[rows, None, :] - p[None, :, :], axis=-1)
        d[np.arange(len(rows)), rows] = np.inf
        yield rows, d


@dataclass(frozen=True, eq=False)
class Graph:
    """Directed weighted graph of ``n`` robots (a frozen value; its arrays are read-only).

    Parameters
    ----------
    n : int
        Number of robots, at least 2.
    edges : array_like of int, shape (E, 2)
        Edge ``(i, j)``: robot ``i`` receives robot ``j``'s messages (0-based). Stored sorted;
        no self-loops, no edge twice.
    weights : array_like, shape (E,), optional
        ``a_ij > 0`` of each edge (the edge order given); default 1.
    """

    n: int
    edges: np.ndarray
    weights: np.ndarray | None = None

    def __post_init__(self):
        n = _count(self.n)
        e = _edge_array(n, self.edges)
        w = _weight_array(self.weights, len(e))
        _given_once(e, undirected=False)
        order = np.lexsort((e[:, 1], e[:, 0]))
        e, w = e[order], w[order]
        e.setflags(write=False)
        w.setflags(write=False)
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "edges", e)
        object.__setattr__(self, "weights", w)

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_edges(cls, n: int, edges, weights=None, directed: bool = True) -> Graph:
        """The graph of ``edges`` (pairs ``(i, j)``, 0-based: ``i`` hears ``j``), weights 1 unless
        given; ``directed=False`` adds ``(j, i)`` with the same weight for every pair."""
        n = _count(n)
        e = _edge_array(n, edges)
        w = _weight_array(weights, len(e))
        if not directed:
            _given_once(e, undirected=True)
            e, w = np.concatenate([e, e[:, ::-1]]), np.concatenate([w, w])
        return cls(n, e, w)

    @classmethod
    def complete(cls, n: int) -> Graph:
        """Every robot hears every other robot (weights 1); λ₂ = n."""
        n = _count(n)
        i, j = np.nonzero(~np.eye(n, dtype=bool))
        return cls(n, np.stack([i, j], axis=1), np.ones(len(i)))

    @classmethod
    def ring(cls, n: int, directed: bool = True) -> Graph:
        """Robot ``i`` hears robot ``i + 1`` (mod n); undirected: also ``i - 1``. λ₂ is
        ``1 - cos(2π/n)`` directed, ``2 - 2 cos(2π/n)`` undirected."""
        n = _count(n)
        i = np.arange(n)
        return cls.from_edges(n, np.stack([i, (i + 1) % n], axis=1), directed=directed or n == 2)

    @classmethod
    def k_nearest(cls, positions, k: int) -> Graph:
        """Each robot hears its ``k`` nearest robots (weights 1; equal distances: lower index first).

        Parameters
        ----------
        positions : array_like, shape (N, 3)
            Robot positions, m.
        k : int
            Neighbours per robot, ``1 <= k <= N - 1``.
        """
        p = _positions(positions)
        n = len(p)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= n - 1:
            raise InvalidInputError(f"graph: k = {short(k)} nearest neighbours must be an integer in 1 .. {n - 1} "
                                    f"(N = {n} robots, each hears at most the N - 1 others)")
        parts = [np.stack([np.repeat(rows, k), np.argsort(d, axis=1, kind="stable")[:, :k].reshape(-1)], axis=1)
                 for rows, d in _distance_blocks(p)]
        return cls(n, np.concatenate(parts), np.ones(n * k))

    @classmethod
    def disk(cls, positions, radius_m: float) -> Graph:
        """Undirected graph of the robots at most ``radius_m`` apart (weights 1).

        Parameters
        ----------
        positions : array_like, shape (N, 3)
            Robot positions, m.
        radius_m : float
            Communication range, m, > 0; a pair exactly ``radius_m`` apart is linked.
        """
        p = _positions(positions)
        radius_m = positive(radius_m, "radius_m", " m")
        parts = [np.argwhere(d <= radius_m) + np.array([rows[0], 0]) for rows, d in _distance_blocks(p)]
        e = np.concatenate(parts)
        return cls(len(p), e, np.ones(len(e)))

    # ------------------------------------------------------------------ structure
    @property
    def undirected(self) -> bool:
        """True when every edge's reverse is an edge of the same weight (``A = A^T``)."""
        L = self.laplacian(sparse=True)
        return (L != L.T).nnz == 0

    def laplacian(self, sparse: bool = False):
        """``L = D - A`` (``A[i, j] = a_ij``, ``D = diag(sum_j a_ij)``).

        Returns
        -------
        ndarray, shape (n, n), or scipy.sparse.csr_array with ``sparse=True`` (large n)
        """
        import scipy.sparse  # imported where used: the CLI's --help stays light

        A = scipy.sparse.csr_array((self.weights, (self.edges[:, 0], self.edges[:, 1])), shape=(self.n, self.n))
        L = scipy.sparse.diags_array(np.asarray(A.sum(axis=1)).reshape(-1)).tocsr() - A
        return L if sparse else L.toarray()

    def in_neighbours(self, i: int) -> np.ndarray:
        """Indices of the robots robot ``i`` hears (sorted)."""
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < self.n:
            raise InvalidInputError(f"graph: robot index {short(i)} must be an integer in 0 .. {self.n - 1} "
                                    f"(0-based: robot 1 is index 0)")
        lo, hi = np.searchsorted(self.edges[:, 0], [i, i + 1])
        return self.edges[lo:hi, 1].copy()

    def _flow(self):
        """Sparse ``F[j, i] = 1`` for each edge ``(i, j)``: the direction messages travel."""
        import scipy.sparse

        return scipy.sparse.csr_array((np.ones(len(self.edges)), (self.edges[:, 1], self.edges[:, 0])),
                                      shape=(self.n, self.n))

    def reaches(self, i: int) -> np.ndarray:
        """Indices of the robots whose messages depend on robot ``i``'s: those that hear it
        directly or through others, ``i`` included (sorted)."""
        self.in_neighbours(i)
        from scipy.sparse import csgraph

        return np.sort(csgraph.breadth_first_order(self._flow(), int(i), directed=True,
                                                   return_predecessors=False))

    @functools.cached_property
    def _sources(self) -> list[np.ndarray]:
        """The robots of each strongly connected component of the information flow that no edge
        enters, in order of their lowest index."""
        from scipy.sparse import csgraph

        count, label = csgraph.connected_components(self._flow(), directed=True, connection="strong")
        e = self.edges
        entered = np.zeros(count, dtype=bool)
        entered[label[e[:, 0]][label[e[:, 0]] != label[e[:, 1]]]] = True
        return sorted((np.flatnonzero(label == c) for c in np.flatnonzero(~entered)), key=lambda m: m[0])

    @property
    def _roots(self) -> np.ndarray:
        return self._sources[0] if len(self._sources) == 1 else np.zeros(0, dtype=np.int64)

    def spanning_tree_roots(self) -> np.ndarray:
        """Indices of the robots every robot hears, directly or through others.

        A directed spanning tree exists iff this is non-empty (Ren & Beard 2005: then
        zero is a simple eigenvalue of ``L`` and consensus is reached); the roots are the
        strongly connected component that no edge enters, when it is the only one.
        """
        return self._roots.copy()

    def check_spanning_tree(self) -> None:
        """Raise one line naming the robots that no root reaches, if no spanning tree exists.

        The best-connected robot (the one reaching most robots; lowest index on a tie) is named
        with what it does not reach. It is in a component no edge enters (every robot is reached
        from one, and reaches no more than it), so one search from each such component finds it.

        Raises
        ------
        UnreachableError
        """
        if len(self._roots):
            return
        reach = [self.reaches(int(members[0])) for members in self._sources]
        k = int(np.argmax([len(r) for r in reach]))
        best = int(self._sources[k][0])
        missing = np.setdiff1d(np.arange(self.n), reach[k])
        raise UnreachableError(
            f"graph: no robot's messages reach every robot: robot {best + 1}'s reach the most robots, yet not "
            f"robots {robots_text(missing)} (directed: a spanning tree needs one robot every other robot "
            f"hears, directly or through others); add an edge into them from a robot that robot {best + 1} "
            f"reaches")

    # ------------------------------------------------------------------ spectrum
    @functools.cached_property
    def _spectrum(self) -> np.ndarray:
        """Eigenvalues of ``L`` other than zero: all but the simple zero when a spanning tree
        exists, else all but those within rounding of zero (``1e-9`` of the largest)."""
        L = self.laplacian()
        lam = np.linalg.eigvalsh(L).astype(complex) if self.undirected else np.linalg.eigvals(L)
        if len(self._roots):
            lam = np.delete(lam, int(np.argmin(np.abs(lam))))
        else:
            lam = lam[np.abs(lam) > 1e-9 * max(1.0, float(np.max(np.abs(lam))))]
        lam.setflags(write=False)
        return lam

    def lambda2(self) -> float:
        """λ₂: the smallest real part among the eigenvalues of ``L`` other than the simple zero.

        Undirected, it is the algebraic connectivity (Fiedler 1973); directed, the real part
        that sets the rate of ``x_dot = -L x`` (Olfati-Saber & Murray 2004; Cui, Qi,
        Chen & Wang 2025, arXiv 2508.10519, the R-linear rate). 0 when no spanning tree
        exists (zero is then a repeated eigenvalue, Ren & Beard 2005). Dense
        eigenvalues: O(n³).
        """
        if not len(self._roots):
            return 0.0
        return float(np.min(self._spectrum.real))

    def largest_stable_gain(self, dt_s: float) -> float:
        """Largest ``k`` below which ``x <- (I - k dt L) x`` contracts on every mode that moves: the
        least ``2 Re λ / (dt |λ|²)`` over the nonzero eigenvalues (``|1 - k dt λ| < 1``); ``inf``
        without edges."""
        dt = positive(dt_s, "dt_s", " s")
        lam = self._spectrum
        return float(np.min(2.0 * lam.real / (dt * np.abs(lam) ** 2))) if len(lam) else math.inf

    def predicted_rate(self, gain: float, dt_s: float | None = None) -> float:
        """Rate (1/s) at which the consensus error of ``x_dot = -k L x`` decays.

        Continuous: ``k Re λ₂`` (the error decays like ``exp(-k Re λ₂ t)``). With a step
        ``dt_s``, the map ``x <- (I - k dt L) x``: ``-log(max |1 - k dt λ|) / dt`` over the
        eigenvalues other than the simple zero (``inf`` where every ``k dt λ`` is 1: the error
        vanishes in finitely many steps). 0 when no spanning tree exists (the loop is still
        refused where a mode diverges).

        Raises
        ------
        InvalidInputError
            A gain or step that is not finite and > 0, or a discrete loop that does not
            contract (``max |1 - k dt λ| >= 1`` over the nonzero eigenvalues; the message names
            the largest stable gain).
        """
        k = positive(gain, "gain", " 1/s")
        if dt_s is None:
            return k * self.lambda2()
        dt = positive(dt_s, "dt_s", " s")
        lam = self._spectrum
        rho = float(np.max(np.abs(1.0 - k * dt * lam))) if len(lam) else 0.0
        if rho >= 1.0:
            raise InvalidInputError(
                f"graph: gain {k:.6g} 1/s with dt_s = {dt:.6g} s makes x <- (I - k dt L) x diverge "
                f"(max |1 - k dt λ| = {rho:.6g} >= 1); use a gain below {self.largest_stable_gain(dt):.6g} 1/s "
                f"or a shorter step")
        if not len(self._roots):
            return 0.0
        return -math.log(rho) / dt if rho > 0.0 else math.inf


def switching_rate(pattern, period_s: float, gain: float, dt_s: float) -> float:
    """Rate (1/s) at which the consensus error of ``x <- (I - k dt L(t)) x`` decays under a
    switching schedule repeated every ``period_s``: ``-log rho / period_s``, ``rho`` the largest
    eigenvalue modulus, after the consensus mode (the eigenvalue 1 of ``Phi 1 = 1``), of one
    period's transition matrix ``Phi = prod_s (I - k dt L_s)^(n_s)`` (``n_s``: the ticks of
    ``dt_s`` graph ``s`` holds). 0 where ``rho`` is 1: the union over a period has no spanning
    tree and the parts that never hear each other keep their disagreement (Jadbabaie, Lin &
    Morse 2003, IEEE TAC 48(6); Ren & Beard 2005).

    Parameters
    ----------
    pattern : sequence of (float, Graph)
        One period's intervals: start, s (the first at 0, increasing, each before ``period_s``)
        and the graph that holds from then.
    period_s, gain, dt_s : float
        The period, s; ``k``, 1/s; the tick, s.
    """
    k, dt, T = positive(gain, "gain", " 1/s"), positive(dt_s, "dt_s", " s"), positive(period_s, "period_s", " s")
    n = pattern[0][1].n
    ends = [float(s) for s, _ in pattern[1:]] + [T]
    phi = np.eye(n)
    for (start, g), end in zip(pattern, ends):
        ticks = int(round((end - float(start)) / dt))
        phi = np.linalg.matrix_power(np.eye(n) - k * dt * g.laplacian(), ticks) @ phi
    lam = np.linalg.eigvals(phi)
    lam = np.delete(lam, int(np.argmin(np.abs(lam - 1.0))))
    rho = float(np.max(np.abs(lam), initial=0.0))
    if rho >= 1.0 - 1e-12:
        return 0.0
    return -math.log(rho) / T if rho > 0.0 else math.inf
