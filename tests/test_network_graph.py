"""The communication graph: builders, Laplacian, spanning tree, λ₂ and the rate it predicts.

Oracles: networkx (reachability, the Laplacian), λ₂ of graphs in closed form, and the linear
consensus ``x_dot = -k L x`` simulated exactly (``scipy.linalg.expm``) and in steps.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest
import scipy.linalg
import scipy.sparse
from hypothesis import given, strategies as st

from quatform.errors import InvalidInputError, NonFiniteError, ShapeError, UnreachableError
from quatform.network import Graph


@st.composite
def graphs(draw, max_n=9):
    n = draw(st.integers(2, max_n))
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    chosen = draw(st.lists(st.sampled_from(pairs), unique=True, max_size=len(pairs)))
    weights = draw(st.lists(st.floats(0.1, 10.0), min_size=len(chosen), max_size=len(chosen)))
    return Graph.from_edges(n, chosen, weights)


def _nx(g: Graph) -> nx.DiGraph:
    """networkx digraph with networkx's edge i -> j for quatform's edge (i, j) (i hears j)."""
    G = nx.DiGraph()
    G.add_nodes_from(range(g.n))
    G.add_weighted_edges_from((int(i), int(j), float(w)) for (i, j), w in zip(g.edges, g.weights))
    return G


@given(graphs())
def test_laplacian_is_networkx_out_degree_laplacian(g):
    # networkx: L = D_out - A with A[i, j] the weight of i -> j, which is quatform's D - A
    want = nx.laplacian_matrix(_nx(g), nodelist=range(g.n)).toarray()
    np.testing.assert_allclose(g.laplacian(), want, rtol=1e-15, atol=0)
    assert scipy.sparse.issparse(g.laplacian(sparse=True))
    np.testing.assert_array_equal(g.laplacian(sparse=True).toarray(), g.laplacian())
    np.testing.assert_allclose(g.laplacian().sum(axis=1), 0.0, atol=1e-12)


@given(graphs())
def test_reaches_and_roots_are_networkx_descendants(g):
    flow = _nx(g).reverse()  # messages travel j -> i along quatform's edge (i, j)
    for i in range(g.n):
        assert g.reaches(i).tolist() == sorted(nx.descendants(flow, i) | {i})
    roots = [r for r in range(g.n) if len(nx.descendants(flow, r)) == g.n - 1]
    assert g.spanning_tree_roots().tolist() == roots
    # a spanning arborescence of the flow exists iff there is a root
    has_tree = any(nx.is_arborescence(nx.bfs_tree(flow, r)) and len(nx.bfs_tree(flow, r)) == g.n for r in range(g.n))
    assert has_tree == bool(roots)
    if roots:
        g.check_spanning_tree()
    else:
        with pytest.raises(UnreachableError) as e:
            g.check_spanning_tree()
        assert "\n" not in str(e.value)


@given(graphs())
def test_in_neighbours_are_the_heard_robots(g):
    for i in range(g.n):
        assert g.in_neighbours(i).tolist() == sorted(_nx(g).successors(i))


def test_no_spanning_tree_names_the_robots_robot_1_does_not_reach():
    g = Graph.from_edges(8, [(1, 0), (2, 1), (4, 3), (5, 6)])
    with pytest.raises(UnreachableError, match=r"robot 1's reach .* not robots 4, 5, 6, 7, 8 \(directed"):
        g.check_spanning_tree()
    assert g.lambda2() == 0.0 and g.predicted_rate(2.0) == 0.0 and g.predicted_rate(2.0, 0.01) == 0.0
    np.testing.assert_allclose(g.largest_stable_gain(0.01), 200.0, rtol=1e-9)  # 2 / (dt λ), every λ 0 or 1
    with pytest.raises(InvalidInputError, match="diverge"):  # a mode that moves still diverges
        g.predicted_rate(201.0, 0.01)
    assert Graph(3, []).largest_stable_gain(0.1) == math.inf and Graph(3, []).predicted_rate(1.0, 0.1) == 0.0
    # two robots that hear nobody and a chain behind each: the best-connected is named
    two = Graph.from_edges(5, [(1, 0), (2, 1), (4, 3)])
    with pytest.raises(UnreachableError, match=r"robot 1's reach the most robots, yet not robots 4, 5 "):
        two.check_spanning_tree()


@pytest.mark.parametrize("n", [3, 5, 8, 13])
def test_lambda2_of_known_graphs_in_closed_form(n):
    tol = dict(rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Graph.ring(n, directed=False).lambda2(), 2 - 2 * math.cos(2 * math.pi / n), **tol)
    np.testing.assert_allclose(Graph.ring(n).lambda2(), 1 - math.cos(2 * math.pi / n), **tol)
    np.testing.assert_allclose(Graph.complete(n).lambda2(), n, **tol)
    path = Graph.from_edges(n, [(i, i + 1) for i in range(n - 1)], directed=False)
    np.testing.assert_allclose(path.lambda2(), 2 - 2 * math.cos(math.pi / n), **tol)
    # a directed path: the leader (robot n) is heard down the line; eigenvalues 0 and 1s
    chain = Graph.from_edges(n, [(i, i + 1) for i in range(n - 1)])
    assert chain.spanning_tree_roots().tolist() == [n - 1]
    np.testing.assert_allclose(chain.lambda2(), 1.0, rtol=1e-6)  # a defective eigenvalue: digits halve


@given(graphs())
def test_lambda2_undirected_is_networkx_algebraic_connectivity(g):
    u = Graph.from_edges(g.n, sorted({(min(i, j), max(i, j)) for i, j in g.edges.tolist()}), directed=False)
    G = nx.Graph(list(map(tuple, u.edges.tolist())))
    G.add_nodes_from(range(u.n))
    want = nx.laplacian_spectrum(G)[1] if nx.is_connected(G) else 0.0
    np.testing.assert_allclose(u.lambda2(), want, rtol=1e-9, atol=1e-9)


def _consensus_error(g: Graph, x0):
    """Initial error of ``x_dot = -L x`` from ``x0``: ``x0`` less its limit ``1 w^T x0`` (w the
    left null vector of L, ``w^T 1 = 1``)."""
    lam, W = scipy.linalg.eig(g.laplacian().T)
    w = np.real(W[:, np.argmin(np.abs(lam))])
    return x0 - (w @ x0) / w.sum()


def _graphs_for_rates():
    # a directed ring of robots 1-3 (weight 3) that robot 4 hears weakly (0.3), robots 4-7 hearing
    # each other with random weights: λ₂ well apart from the rest
    rng = np.random.default_rng(3)
    inner = [(i, j) for i in range(3, 7) for j in range(3, 7) if i != j]
    scattered = Graph.from_edges(7, [(0, 1), (1, 2), (2, 0), (3, 0)] + inner,
                                 weights=np.concatenate([[3.0, 3.0, 3.0, 0.3], rng.uniform(1.0, 2.0, len(inner))]))
    return {"undirected ring": Graph.ring(8, directed=False), "directed ring": Graph.ring(6),
            "complete": Graph.complete(5), "weighted directed": scattered}


@pytest.mark.parametrize("name", list(_graphs_for_rates()))
def test_predicted_rate_is_the_measured_decay_of_linear_consensus(name):
    g = _graphs_for_rates()[name]
    k = 1.7
    e0 = _consensus_error(g, np.random.default_rng(4).normal(size=g.n))
    lam = np.linalg.eigvals(g.laplacian())
    slow = lam[np.argsort(np.abs(lam))[1:]]
    slow = slow[np.argmin(slow.real)]
    # two times one period of the slowest mode apart (any period for a real one), late enough
    # for the faster modes to have faded
    period = 2 * math.pi / (k * abs(slow.imag)) if abs(slow.imag) > 1e-9 else 1.0
    t1 = 12.0 / (k * g.lambda2())
    t2 = t1 + period * max(1, math.ceil(2.0 / (k * g.lambda2() * period)))
    e1, e2 = (scipy.linalg.expm(-k * g.laplacian() * t) @ e0 for t in (t1, t2))
    measured = -math.log(np.linalg.norm(e2) / np.linalg.norm(e1)) / (t2 - t1)
    np.testing.assert_allclose(measured, g.predicted_rate(k), rtol=0.01)


@pytest.mark.parametrize("name, fraction", [("undirected ring", 0.5), ("undirected ring", 0.95),
                                            ("complete", 0.3), ("weighted directed", 0.5)])
def test_discrete_rate_is_the_measured_decay_of_the_stepped_loop(name, fraction):
    # at 0.5 of the largest stable gain the slowest mode sets the rate, at 0.95 the overshooting one
    g = _graphs_for_rates()[name]
    dt = 0.05
    k = fraction * g.largest_stable_gain(dt)
    per_step = g.predicted_rate(k, dt) * dt
    M = np.eye(g.n) - k * dt * g.laplacian()
    e = _consensus_error(g, np.random.default_rng(5).normal(size=g.n))
    for _ in range(math.ceil(15.0 / per_step)):  # the faster modes fade, the error stays far above rounding
        e = M @ e
    e1, steps = e.copy(), math.ceil(10.0 / per_step)
    for _ in range(steps):
        e = M @ e
    measured = -math.log(np.linalg.norm(e) / np.linalg.norm(e1)) / (steps * dt)
    np.testing.assert_allclose(measured, g.predicted_rate(k, dt), rtol=0.01)


def test_a_gain_past_the_largest_stable_one_is_refused_naming_it():
    g = Graph.ring(8, directed=False)
    dt = 0.1
    k_max = g.largest_stable_gain(dt)
    np.testing.assert_allclose(k_max, 2.0 / (dt * 4.0), rtol=1e-12)  # 2 / (dt λ_max), λ_max = 4
    assert g.predicted_rate(0.99 * k_max, dt) > 0.0
    with pytest.raises(InvalidInputError, match=r"diverge .* use a gain below 5 1/s"):
        g.predicted_rate(1.01 * k_max, dt)
    directed = Graph.ring(6)
    kd = directed.largest_stable_gain(dt)
    assert directed.predicted_rate(0.99 * kd, dt) > 0.0
    complete = Graph.complete(4)  # k dt λ = 1 on every mode: consensus in one step, up to rounding
    assert complete.predicted_rate(1.0 / (dt * 4), dt) >= 30.0 / dt
    with pytest.raises(InvalidInputError, match="diverge"):
        directed.predicted_rate(1.01 * kd, dt)


def test_k_nearest_hears_the_nearest_with_ties_by_index():
    p = np.array([[0.0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 2, 0], [5, 5, 5]])
    g = Graph.k_nearest(p, 2)
    assert g.in_neighbours(0).tolist() == [1, 2]  # 1 and 2 tie at 1 m
    assert g.in_neighbours(4).tolist() == [1, 3]
    assert len(g.edges) == 10


@given(st.integers(2, 40), st.integers(0, 2**32 - 1), st.data())
def test_k_nearest_and_disk_against_brute_force(n, seed, data):
    p = np.random.default_rng(seed).uniform(-3, 3, (n, 3))
    k = data.draw(st.integers(1, n - 1))
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    g = Graph.k_nearest(p, k)
    for i in range(n):
        order = sorted((d[i, j], j) for j in range(n) if j != i)
        assert g.in_neighbours(i).tolist() == sorted(j for _, j in order[:k])
    r = data.draw(st.floats(0.1, 6.0))
    disk = Graph.disk(p, r)
    want = {(i, j) for i in range(n) for j in range(n) if i != j and d[i, j] <= r}
    assert set(map(tuple, disk.edges.tolist())) == want
    assert disk.undirected


def test_disk_links_a_pair_exactly_at_the_radius():
    p = np.array([[0.0, 0, 0], [0.5, 0, 0], [3, 0, 0]])
    assert Graph.disk(p, 0.5).edges.tolist() == [[0, 1], [1, 0]]


def test_builders_and_value():
    assert Graph.ring(4).edges.tolist() == [[0, 1], [1, 2], [2, 3], [3, 0]]
    assert len(Graph.ring(4, directed=False).edges) == 8 and Graph.ring(4, directed=False).undirected
    assert not Graph.ring(4).undirected
    assert len(Graph.complete(4).edges) == 12
    g = Graph.from_edges(3, [(2, 0), (0, 1)], weights=[2.0, 3.0])
    assert g.edges.tolist() == [[0, 1], [2, 0]] and g.weights.tolist() == [3.0, 2.0]
    with pytest.raises(ValueError):
        g.edges[0, 0] = 1
    with pytest.raises(AttributeError):
        g.n = 4
    assert Graph.from_edges(3, []).edges.shape == (0, 2)
    assert Graph(3, [(0, 1)]).weights.tolist() == [1.0]


@pytest.mark.parametrize("call, error, text", [
    (lambda: Graph.from_edges(1, []), InvalidInputError, "n = 1 robots"),
    (lambda: Graph.from_edges(2.0, []), InvalidInputError, "n = 2.0"),
    (lambda: Graph.from_edges(3, [(0, 3)]), InvalidInputError, r"edge #1 \(0, 3\) names index 3, outside 0 .. 2"),
    (lambda: Graph.from_edges(3, [(0, -1)]), InvalidInputError, "outside 0 .. 2"),
    (lambda: Graph.from_edges(3, [(0, 1.5)]), InvalidInputError, r"edge #1 \(0, 1.5\) must be two whole robot"),
    (lambda: Graph(3, [(0.5, 1)]), InvalidInputError, r"edge #1 \(0.5, 1\) must be two whole robot"),
    (lambda: Graph.from_edges(3, [(0, 1, 2)]), ShapeError, r"shape \(E, 2\)"),
    (lambda: Graph.from_edges(3, [(1, 1)]), InvalidInputError, "edge #1, robot 2 hears robot 2, is a self-loop"),
    (lambda: Graph.from_edges(3, [(1, 2), (0, 1), (0, 1)]), InvalidInputError,
     r"edge #3, robot 1 hears robot 2, is given twice \(also as edge #2\)"),
    (lambda: Graph.from_edges(3, [(0, 1), (1, 0)], directed=False), InvalidInputError,
     r"edge #2, robots 2 and 1, is given twice \(also as edge #1;"),
    (lambda: Graph.from_edges(3, [(0, 1)], [np.nan]), NonFiniteError, "weight of edge #1 is nan"),
    (lambda: Graph.from_edges(3, [(0, 1)], [-1.0]), InvalidInputError, "must be > 0"),
    (lambda: Graph.from_edges(3, [(0, 1)], [0.0]), InvalidInputError, "must be > 0"),
    (lambda: Graph.from_edges(3, [(0, 1)], [1.0, 2.0]), ShapeError, r"shape \(1,\)"),
    (lambda: Graph.k_nearest(np.zeros((4, 2)), 1), ShapeError, r"\(N, 3\)"),
    (lambda: Graph.k_nearest([[0, 0, 0], [1, 0, np.inf]], 1), NonFiniteError, "robot 2"),
    (lambda: Graph.k_nearest(np.eye(3), 3), InvalidInputError, "k = 3 nearest neighbours must be an integer in 1 .. 2"),
    (lambda: Graph.k_nearest(np.eye(3), 0), InvalidInputError, "1 .. 2"),
    (lambda: Graph.disk(np.eye(3), 0.0), InvalidInputError, "radius_m = 0.0 must be a finite number > 0 m"),
    (lambda: Graph.disk(np.eye(3), -1.0), InvalidInputError, "radius_m"),
    (lambda: Graph.ring(3).in_neighbours(3), InvalidInputError, "robot index 3"),
    (lambda: Graph.ring(3).predicted_rate(0.0), InvalidInputError, "gain = 0.0"),
    (lambda: Graph.ring(3).predicted_rate(1.0, float("nan")), InvalidInputError, "dt_s = nan"),
])
def test_bad_input_is_one_line_naming_the_value(call, error, text):
    with pytest.raises(error, match=text) as e:
        call()
    assert "\n" not in str(e.value) and str(e.value).startswith("graph: ")
