"""Whether a team's desired relative poses can all hold at once: every cycle multiplies to 1.

Formations and planning layer (imports algebra, errors and checks).

``relative[(i, j)]`` is the desired pose of robot ``j`` in robot ``i``'s frame, a unit dual
quaternion ``(8,)``, for each edge ``(i, j)`` of a :class:`~quatform.network.graph.Graph`.
Qi & Cui (arXiv 2401.05132): such a scheme is consistent (some absolute poses
realise it) iff the product of the relative configurations around every cycle of the graph
is the identity; on the double cover, ``+1`` or ``-1`` (``q`` and ``-q`` are one pose). An
edge used against its direction contributes the inverse (the conjugate of a unit dual
quaternion); both directions of a pair given must be mutual inverses (their 2-cycle; the
longer cycles use the pose given from the lower-indexed robot). A cycle basis suffices: the
fundamental cycles of a breadth-first spanning forest of the undirected graph.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..algebra.dual_quaternion import DQ_IDENTITY, dqconj, dqmul, pose_from_dq
from ..algebra.quaternion import q_angle
from ..algebra.validate import as_unit_dual_quaternion
from ..checks import short
from ..errors import InvalidInputError, ShapeError, UnreachableError
from .graph import Graph, positive

__all__ = ["check_relative_poses", "consistent_poses", "cycle_basis"]

#: Default rotation tolerance of a cycle's product, rad (rounding of a few hundred products).
TOL_RAD = 1e-9
#: Default translation tolerance per metre of the team's size (the largest distance of a robot
#: from its tree's root, at least 1 m): rounding grows with the lever arms.
TOL_M_PER_M = 1e-9


def _forest(graph: Graph):
    """``(pairs (P, 2) with a < b, predecessor (n,), depth (n,), tree (P,) bool)``: the undirected
    pairs and a breadth-first spanning forest (each component rooted at its lowest index)."""
    e = graph.edges
    pairs = np.unique(np.sort(e, axis=1), axis=0) if len(e) else np.zeros((0, 2), dtype=np.int64)
    U = graph.laplacian(sparse=True) != 0
    from scipy.sparse import csgraph  # imported where used: the CLI's --help stays light

    count, label = csgraph.connected_components(U, directed=False)
    pred = np.full(graph.n, -1)
    depth = np.zeros(graph.n, dtype=np.int64)
    for c in range(count):
        order, p = csgraph.breadth_first_order(U, int(np.argmax(label == c)), directed=False)
        pred[order[1:]] = p[order[1:]]
        for v in order[1:]:
            depth[v] = depth[p[v]] + 1
    tree = (pred[pairs[:, 1]] == pairs[:, 0]) | (pred[pairs[:, 0]] == pairs[:, 1])
    return pairs, pred, depth, tree


def _tree_path(pred, depth, a: int, b: int) -> list[int]:
    """Robots on the tree path from ``b`` to ``a`` (both included)."""
    up_b, up_a = [b], [a]
    while depth[up_b[-1]] > depth[up_a[-1]]:
        up_b.append(int(pred[up_b[-1]]))
    while depth[up_a[-1]] > depth[up_b[-1]]:
        up_a.append(int(pred[up_a[-1]]))
    while up_a[-1] != up_b[-1]:
        up_a.append(int(pred[up_a[-1]]))
        up_b.append(int(pred[up_b[-1]]))
    return up_b + up_a[-2::-1]


def cycle_basis(graph: Graph) -> list[list[int]]:
    """Fundamental cycles of the undirected graph under ``graph``: one per pair of robots linked
    in either direction outside a breadth-first spanning forest (``E_u - n + components`` of
    them), each as its robots in order, ``[a, b, ..., ]`` with ``a < b`` the pair's robots
    (0-based; the cycle closes back to ``a``)."""
    pairs, pred, depth, tree = _forest(graph)
    return [[int(a)] + _tree_path(pred, depth, int(a), int(b))[:-1] for a, b in pairs[~tree]]


def _key(key, n: int) -> tuple[int, int]:
    if not (isinstance(key, tuple) and len(key) == 2 and all(
            isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in key)):
        raise InvalidInputError(f"relative poses: key {short(key)} must be an edge (i, j) of two robot "
                                f"indices 0 .. {n - 1}")
    return int(key[0]), int(key[1])


def _relative(graph: Graph, relative) -> np.ndarray:
    """The poses of ``relative`` in the order of ``graph.edges``, shape (E, 8), checked."""
    if not isinstance(relative, Mapping):
        raise InvalidInputError(f"relative poses: {short(relative)} must map each edge (i, j) to the pose of "
                                f"robot j in robot i's frame (a unit dual quaternion, shape (8,))")
    given = {_key(k, graph.n): v for k, v in relative.items()}
    edges = {(int(i), int(j)) for i, j in graph.edges}
    extra = sorted(set(given) - edges)
    if extra:
        i, j = extra[0]
        raise InvalidInputError(f"relative poses: ({i}, {j}) is not an edge of the graph (robot {i + 1} does not "
                                f"hear robot {j + 1}); add the edge to the graph or remove the pose")
    out = np.empty((len(graph.edges), 8))
    for k, (i, j) in enumerate(graph.edges.tolist()):
        if (i, j) not in given:
            raise InvalidInputError(f"relative poses: no desired pose for edge ({i}, {j}) (robot {j + 1} in robot "
                                    f"{i + 1}'s frame); give relative[({i}, {j})]")
        v = np.asarray(given[(i, j)], dtype=float)
        if v.shape != (8,):
            raise ShapeError(f"relative poses: relative[({i}, {j})] must be one unit dual quaternion, shape (8,), "
                             f"got shape {v.shape}")
        out[k] = as_unit_dual_quaternion(v, f"relative[({i}, {j})]")
    return out


def _cycle_text(cycle: list[int], limit: int = 12) -> str:
    names = [str(r + 1) for r in cycle] + [str(cycle[0] + 1)]
    if len(names) > limit + 1:
        names = names[:limit // 2] + ["..."] + names[-(limit // 2):]
    return " -> ".join(names) + ("" if len(cycle) <= limit else f" ({len(cycle)} robots)")


def check_relative_poses(graph: Graph, relative, tol_rad: float = TOL_RAD, tol_m: float | None = None) -> None:
    """Raise one line naming the worst cycle whose product of desired relative poses is not 1.

    Parameters
    ----------
    graph : Graph
    relative : mapping (i, j) -> array_like, shape (8,)
        For every edge ``(i, j)`` of ``graph`` (and nothing else), the desired pose of robot
        ``j`` in robot ``i``'s frame, a unit dual quaternion (either sign).
    tol_rad : float
        Largest rotation angle of a cycle's product, rad.
    tol_m : float, optional
        Largest translation of a cycle's product, m; default ``TOL_M_PER_M`` times the team's
        size (the largest distance of a robot from its spanning tree's root, at least 1 m).

    Raises
    ------
    UnreachableError
        A cycle (a fundamental cycle, or an edge given in both directions) multiplies to a
        pose beyond the tolerances: no absolute poses realise the scheme (Qi & Cui,
        arXiv 2401.05132). The worst cycle (largest ratio to its tolerance) is named
        by its robots, starting where its product is measured.
    InvalidInputError
        A missing edge, a key that is not an edge, a pose that is not a unit dual quaternion.
    """
    tol_rad = positive(tol_rad, "tol_rad", " rad", "relative poses")
    T = _relative(graph, relative)
    row = {(int(i), int(j)): k for k, (i, j) in enumerate(graph.edges.tolist())}
    pairs, pred, depth, tree = _forest(graph)

    def pose(a, b):
        """``T_ab`` (robot b in robot a's frame) of each pair, from the pose given for (lower
        index, higher index), or the inverse of the other one; the inverse for ``a > b``."""
        if not len(a):
            return np.zeros((0, 8))
        lo, hi = np.minimum(a, b).tolist(), np.maximum(a, b).tolist()
        fwd = np.array([row.get((i, j), -1) for i, j in zip(lo, hi)], dtype=np.int64)
        back = np.array([row.get((j, i), -1) for i, j in zip(lo, hi)], dtype=np.int64)
        up = np.where((fwd >= 0)[:, None], T[fwd], dqconj(T[back]))
        return np.where((a < b)[:, None], up, dqconj(up))

    P = np.tile(DQ_IDENTITY, (graph.n, 1))  # pose of each robot in its tree root's frame
    for d in range(1, int(depth.max()) + 1):
        v = np.flatnonzero(depth == d)
        P[v] = dqmul(P[pred[v]], pose(pred[v], v))
    if tol_m is None:
        tol_m = TOL_M_PER_M * max(1.0, float(np.max(np.linalg.norm(pose_from_dq(P)[1], axis=-1))))
    tol_m = positive(tol_m, "tol_m", " m", "relative poses")

    a, b = pairs[~tree, 0], pairs[~tree, 1]
    e = graph.edges
    both = (e[:, 0] < e[:, 1]) & np.array([(j, i) in row for i, j in e.tolist()], dtype=bool)
    i2, j2 = e[both, 0], e[both, 1]
    back = [row[(j, i)] for i, j in zip(i2.tolist(), j2.tolist())]
    products = np.concatenate([dqmul(pose(a, b), dqmul(dqconj(P[b]), P[a])),  # a -> b -> tree path -> a
                               dqmul(T[both], T[back])])  # i -> j -> i, both poses as given
    if not len(products):
        return
    q, t = pose_from_dq(products)
    angle, shift = q_angle(q), np.linalg.norm(t, axis=-1)
    score = np.maximum(angle / tol_rad, shift / tol_m)
    w = int(np.argmax(score))
    if angle[w] <= tol_rad and shift[w] <= tol_m:
        return
    if w < len(a):
        cycle = [int(a[w])] + _tree_path(pred, depth, int(a[w]), int(b[w]))[:-1]
    else:
        cycle = [int(i2[w - len(a)]), int(j2[w - len(a)])]
    raise UnreachableError(
        f"relative poses: the cycle robots {_cycle_text(cycle)} multiplies to a {angle[w]:.3g} rad, "
        f"{shift[w]:.3g} m pose, not the identity (tolerance {tol_rad:.3g} rad, {tol_m:.3g} m); fix the "
        f"desired poses on that cycle")


def consistent_poses(graph: Graph, root_poses) -> dict[tuple[int, int], np.ndarray]:
    """Relative poses ``{(i, j): P_i* P_j}`` of every edge from absolute poses: consistent by
    construction.

    Parameters
    ----------
    graph : Graph
    root_poses : array_like, shape (n, 8)
        Each robot's pose in one common frame, unit dual quaternions.

    Returns
    -------
    dict
        ``(i, j) -> ndarray (8,)``, the pose of robot ``j`` in robot ``i``'s frame.
    """
    P = as_unit_dual_quaternion(root_poses, "root_poses")
    if P.shape != (graph.n, 8):
        raise ShapeError(f"relative poses: root_poses must hold one pose per robot, shape ({graph.n}, 8), got "
                         f"shape {P.shape}")
    e = graph.edges
    rel = dqmul(dqconj(P[e[:, 0]]), P[e[:, 1]])
    return {(int(i), int(j)): r for (i, j), r in zip(e.tolist(), rel)}
