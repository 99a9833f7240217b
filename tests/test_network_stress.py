"""The stress matrix of a nominal configuration and Zhao's leader condition (quatform.network.stress)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from quatform.errors import DegenerateInputError, InvalidInputError, QuatformError, UnreachableError
from quatform.network import Graph
from quatform.network.stress import Stress, zhao2018_example


def _is_stress(S, nominal):
    """Ω 1 = 0, Ω P̄ = 0, symmetric, PSD of rank n - d - 1 (tolerances by the scale of Ω and P̄)."""
    Om = S.matrix()
    n, d = nominal.shape
    scale = np.max(np.abs(Om)) * max(1.0, np.max(np.abs(nominal)))
    assert np.allclose(Om, Om.T, atol=0.0)
    assert np.max(np.abs(Om @ np.ones(n))) <= 1e-12 * scale
    assert np.max(np.abs(Om @ nominal)) <= 1e-9 * scale
    ev = np.linalg.eigvalsh(Om)
    tiny = 1e-9 * ev[-1]
    assert np.all(np.abs(ev[: d + 1]) <= tiny)
    assert ev[d + 1] > tiny
    return ev


def _generic(seed, n, d):
    return np.random.default_rng(seed).normal(size=(n, d))


def _trilateration(n, d):
    """A (d+1)-clique, then each robot joined to the d + 1 robots before it (universally rigid
    on a generic configuration)."""
    e = [(i, j) for i in range(d + 1) for j in range(i + 1, d + 1)]
    e += [(k - m, k) for k in range(d + 1, n) for m in range(1, d + 2)]
    return np.array(e)


def test_zhao_example_has_the_papers_stress():
    ex = zhao2018_example()
    S = Stress(ex.nominal, ex.edges)
    ev = _is_stress(S, ex.nominal)
    assert S.iterations == 0  # one stress spans the solutions: its sign is the search
    # the one stress, in eighths of the largest weight (robots 1-based: 1-2, 1-3, 1-4, 1-5,
    # 2-4, 2-7, 3-5, 3-6, 4-5, 4-6, 5-7, 6-7)
    assert np.allclose(8.0 * S.weights, [4, 4, -2, -2, 8, -2, 8, -2, 1, 4, 4, 2], atol=1e-12)
    assert ev[3] > 0.5
    info = S.check_leaders(ex.leaders)
    assert info["omega_ff_min_eig"] > 0.04 and info["gamma_min"] > 0.0
    assert info["relay_step"] == pytest.approx(1.0) and 0.0 < info["relay_factor"] < 1.0
    assert info["relay_factor"] == pytest.approx(S.relay_factor(ex.leaders))  # 0.932
    g = S.graph()
    assert g.undirected and len(g.edges) == 2 * len(ex.edges)
    rows = S.rows()
    assert np.array_equal(rows, rows.T) and np.all(np.diag(rows) == 0.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.integers(1, 3), extra=st.integers(1, 9), tri=st.booleans())
def test_random_generic_configurations_have_a_psd_stress_of_full_rank(seed, d, extra, tri):
    n = d + 1 + extra
    p = _generic(seed, n, d)
    edges = _trilateration(n, d) if tri else np.argwhere(np.triu(np.ones((n, n)), 1))
    S = Stress(p, edges)
    _is_stress(S, p)
    assert np.max(np.abs(S.weights)) == pytest.approx(1.0)
    lead = np.random.default_rng(seed + 1).choice(n, size=d + 1, replace=False)
    # generic leaders: their simplex not flat (a nearly collinear draw makes Ω_ff nearly singular,
    # which check_leaders rightly refuses)
    centred = p[lead] - p[lead].mean(axis=0)
    assume(np.linalg.svd(centred, compute_uv=False)[-1] > 0.05 * np.linalg.norm(centred))
    info = S.check_leaders(lead)
    Off = np.delete(np.delete(S.matrix(), lead, 0), lead, 1)
    assert info["omega_ff_min_eig"] == pytest.approx(np.min(np.linalg.eigvalsh(Off)))
    assert info["omega_ff_min_eig"] > 0.0
    # the relay step contracts the followers' relayed velocities at least as fast as β = 1
    assert info["relay_factor"] < 1.0 and info["relay_factor"] <= S.relay_factor(lead) + 1e-12


def test_the_barrier_search_finds_the_stress_where_the_projection_of_the_identity_fails():
    """A 12-robot planar trilateration graph: nine independent stresses, the stress nearest to
    M = I is not positive definite on the complement, the barrier method's is."""
    p = _generic(11, 12, 2)
    S = Stress(p, _trilateration(12, 2))
    assert S.iterations > 0
    ev = _is_stress(S, p)
    assert ev[3] > 1e-9 * ev[-1]


def test_a_collinear_nominal_configuration_is_one_line():
    p = np.c_[np.arange(6.0), 2.0 * np.arange(6.0)]
    with pytest.raises(DegenerateInputError, match=r"span an affine space of dimension 1, not R\^2") as e:
        Stress(p, np.argwhere(np.triu(np.ones((6, 6)), 1)))
    assert "\n" not in str(e.value)


def test_too_few_and_collinear_leaders_are_one_line():
    ex = zhao2018_example()
    S = Stress(ex.nominal, ex.edges)
    with pytest.raises(UnreachableError, match=r"2 leader\(s\) cannot fix an affine image in R\^2.*add 1 leader"):
        S.check_leaders([0, 1])
    # robots 2, 4, 6 lie on the line y = 2
    with pytest.raises(UnreachableError, match=r"leaders 2, 4, 6 span an affine space of dimension 1.*off that line"):
        S.check_leaders([1, 3, 5])
    with pytest.raises(InvalidInputError, match="the leaders name robot 1 more than once; name each leader once"):
        S.check_leaders([0, 0, 1, 2])
    with pytest.raises(InvalidInputError, match="outside 0 .. 6"):
        S.check_leaders([0, 1, 9])


def test_graphs_without_the_stress_are_one_line():
    p = _generic(3, 6, 2)
    with pytest.raises(UnreachableError, match=r"robot 6 has 2 neighbours in independent directions, .*at least "
                                               r"d \+ 1 = 3"):
        Stress(p, [(0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (2, 3), (0, 4), (1, 4), (2, 4), (3, 4), (4, 5), (3, 5)])
    with pytest.raises(UnreachableError, match=r"robots 5, 6 have 2 neighbours in independent directions each, so "
                                               r"no stress reaches them"):
        Stress(p, [(0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (2, 3), (0, 4), (4, 5), (3, 5)])
    # a robot midway between its two neighbours carries a stress: no refusal by its degree
    mid = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.0], [0.0, 2.0], [2.0, 2.0]])
    edges = [(0, 2), (1, 2), (0, 1), (0, 3), (1, 3), (0, 4), (1, 4), (3, 4)]
    _is_stress(Stress(mid, edges), mid)
    prism = [(0, 1), (1, 2), (0, 2), (3, 4), (4, 5), (3, 5), (0, 3), (1, 4), (2, 5)]
    with pytest.raises(UnreachableError, match="carry no stress"):
        Stress(p, prism)
    # two K4 sharing the edge (0, 1): each carries a stress, yet they fold about the shared
    # edge (not universally rigid), so no combination has rank n - d - 1 = 3
    k4 = lambda v: [(a, b) for i, a in enumerate(v) for b in v[i + 1:]]  # noqa: E731
    edges = sorted(set(k4([0, 1, 2, 3]) + k4([0, 1, 4, 5])))
    with pytest.raises(UnreachableError, match="no positive semidefinite stress of rank n - d - 1 = 3 on these 11 edges"):
        Stress(p, edges)


@pytest.mark.parametrize("bad, kind, text", [
    (np.zeros((3, 2)), InvalidInputError, "at least d \\+ 2 = 4 robots"),
    (np.zeros((5, 4)), QuatformError, "d in 1 .. 3"),
    (np.array([[0.0, 0], [1, 0], [0, 1], [np.nan, 1]]), QuatformError, "robot 4"),
])
def test_malformed_nominal_is_one_line(bad, kind, text):
    with pytest.raises(kind, match=text) as e:
        Stress(bad, [(0, 1)])
    assert "\n" not in str(e.value)


def test_edges_are_checked_by_the_graph():
    p = _generic(0, 5, 2)
    with pytest.raises(InvalidInputError, match="given twice"):
        Stress(p, [(0, 1), (1, 0)])
    with pytest.raises(InvalidInputError, match="self-loop"):
        Stress(p, [(0, 0)])


def test_the_example_maneuver_is_an_affine_image_with_consistent_rates():
    ex = zhao2018_example()
    t = np.linspace(0.0, ex.duration_s, 7001)
    A, b, dA, db = ex.maneuver(t)
    p, v = ex.targets(t)
    assert np.allclose(p[0], ex.nominal) and np.allclose(v[[0, -1]], 0.0)
    fd = np.gradient(p, t, axis=0)[1:-1]
    assert np.max(np.abs(fd - v[1:-1])) <= 1e-3 * np.max(np.abs(v))
    Om = Stress(ex.nominal, ex.edges).matrix()
    assert np.max(np.abs(np.einsum("ij,tjk->tik", Om, p))) <= 1e-12 * np.max(np.abs(p))
    # the second passage lays the formation on one line, robots at least 1 m apart
    line = p[np.argmin(np.abs(t - 50.0))]
    assert np.ptp(line[:, 0]) <= 1e-12 and np.min(np.diff(np.sort(line[:, 1]))) >= 1.0 - 1e-12
    assert Graph.from_edges(7, ex.edges, directed=False).lambda2() > 0.0
