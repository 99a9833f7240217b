"""Desired relative poses: consistent iff every cycle multiplies to ±1 (Qi & Cui, arXiv 2401.05132).

Oracles: schemes built from absolute poses are consistent; networkx's cycle basis has as many
cycles; a perturbed edge is reported on a cycle through it.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, strategies as st

from quatform.algebra import dq_from_pose, dqconj, dqmul, pose_from_dq, q_angle, q_from_axis_angle, qnormalize
from quatform.errors import InvalidInputError, NonUnitError, ShapeError, UnreachableError
from quatform.network import Graph, check_relative_poses, consistent_poses, cycle_basis
from quatform.network.consistency import TOL_M_PER_M


@st.composite
def graphs_and_poses(draw, max_n=9, scale=3.0):
    n = draw(st.integers(2, max_n))
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    chosen = draw(st.lists(st.sampled_from(pairs), unique=True, min_size=1, max_size=len(pairs)))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    poses = dq_from_pose(qnormalize(rng.normal(size=(n, 4))), rng.uniform(-scale, scale, (n, 3)))
    return Graph.from_edges(n, chosen), poses, rng


def _undirected(g: Graph) -> nx.Graph:
    G = nx.Graph()
    G.add_nodes_from(range(g.n))
    G.add_edges_from(map(tuple, g.edges.tolist()))
    return G


@given(graphs_and_poses())
def test_cycle_basis_is_a_basis_of_the_undirected_cycles(case):
    g, _, _ = case
    G = _undirected(g)
    cycles = cycle_basis(g)
    assert len(cycles) == len(nx.cycle_basis(G)) == G.number_of_edges() - g.n + nx.number_connected_components(G)
    for c in cycles:
        assert len(set(c)) == len(c) >= 3 and c[0] < c[1]
        assert all(G.has_edge(u, v) for u, v in zip(c, c[1:] + c[:1]))
    # independent: each cycle holds an edge no other one holds (its edge outside the forest)
    own = [{(min(c[0], c[1]), max(c[0], c[1]))} for c in cycles]
    assert len(set().union(*own)) == len(cycles) if cycles else True


@given(graphs_and_poses())
def test_schemes_from_absolute_poses_are_consistent_whatever_the_signs(case):
    g, poses, rng = case
    rel = consistent_poses(g, poses)
    check_relative_poses(g, rel)
    flipped = {e: (-q if rng.random() < 0.5 else q) for e, q in rel.items()}
    check_relative_poses(g, flipped)
    for (i, j), q in rel.items():  # the pose of robot j in robot i's frame
        np.testing.assert_allclose(dqmul(poses[i], q), poses[j], atol=1e-12)


@given(graphs_and_poses(), st.floats(1e-6, 0.5), st.floats(1e-6, 0.5))
def test_a_perturbed_edge_is_reported_on_a_cycle_through_it(case, angle, shift):
    g, poses, rng = case
    G = _undirected(g)
    rel = consistent_poses(g, poses)
    k = int(rng.integers(len(g.edges)))
    i, j = map(int, g.edges[k])
    bridges = {(min(u, v), max(u, v)) for u, v in nx.bridges(G)}
    on_cycle = (min(i, j), max(i, j)) not in bridges or (j, i) in rel
    axis = rng.normal(size=3)
    bump = dq_from_pose(q_from_axis_angle(axis / np.linalg.norm(axis), angle), rng.normal(size=3) * shift)
    rel[(i, j)] = dqmul(rel[(i, j)], bump)
    if not on_cycle:  # a bridge: any pose of it is consistent
        check_relative_poses(g, rel)
        return
    with pytest.raises(UnreachableError) as e:
        check_relative_poses(g, rel)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("relative poses: the cycle robots ")
    names = [int(r) - 1 for r in msg.split("the cycle robots ")[1].split(" multiplies")[0].split(" -> ")]
    steps = set(zip(names, names[1:]))
    assert (i, j) in steps or (j, i) in steps
    # the reported error is the product around the named cycle, started at its first robot
    # (a 2-cycle multiplies both given poses; a longer one the pose given from the lower index)
    product = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])
    for u, v in zip(names, names[1:]):
        lo, hi = min(u, v), max(u, v)
        up = rel[(lo, hi)] if (lo, hi) in rel else dqconj(rel[(hi, lo)])
        product = dqmul(product, rel[(u, v)] if len(names) == 3 else up if u < v else dqconj(up))
    q, t = pose_from_dq(product)
    rad, m = msg.split("multiplies to a ")[1].split(" m pose")[0].split(" rad, ")
    np.testing.assert_allclose([float(rad), float(m)], [q_angle(q), np.linalg.norm(t)], rtol=5e-3, atol=1e-12)


def test_the_worst_cycle_is_named_by_robot_numbers():
    g = Graph.from_edges(4, [(0, 2), (2, 3), (3, 0), (0, 1), (1, 2)])
    poses = dq_from_pose(np.tile([1.0, 0, 0, 0], (4, 1)), np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]))
    rel = consistent_poses(g, poses)
    rel[(2, 3)] = dqmul(rel[(2, 3)], dq_from_pose(q_from_axis_angle([0, 0, 1], 0.12), [0.05, 0, 0]))
    with pytest.raises(UnreachableError, match=r"^relative poses: the cycle robots 3 -> 4 -> 1 -> 3 multiplies to a "
                                               r"0\.12 rad, 0\.\d+ m pose, not the identity \(tolerance 1e-09 rad, "
                                               r"[\d.e-]+ m\); fix the desired poses on that cycle$"):
        check_relative_poses(g, rel)


def test_both_directions_must_be_mutual_inverses():
    g = Graph.ring(2)  # 1 hears 2 and 2 hears 1: a 2-cycle
    poses = dq_from_pose(np.tile([1.0, 0, 0, 0], (2, 1)), np.array([[0.0, 0, 0], [2, 0, 0]]))
    rel = consistent_poses(g, poses)
    check_relative_poses(g, {(0, 1): rel[(0, 1)], (1, 0): -rel[(1, 0)]})
    rel[(1, 0)] = dq_from_pose([1.0, 0, 0, 0], [-2.03, 0, 0])
    with pytest.raises(UnreachableError, match=r"cycle robots 1 -> 2 -> 1 multiplies to a 0 rad, 0\.03 m pose"):
        check_relative_poses(g, rel)


@pytest.mark.parametrize("scale", [1.0, 1e3, 1e6])
def test_the_translation_tolerance_follows_the_team_size(scale):
    # a chain of 40 robots around a loop of size `scale`: rounding of the products grows with the
    # lever arms; the default tolerance passes exact data at every scale and catches a slip of
    # 10x the tolerance
    n = 40
    rng = np.random.default_rng(7)
    g = Graph.ring(n, directed=False)
    poses = dq_from_pose(qnormalize(rng.normal(size=(n, 4))), rng.uniform(-scale, scale, (n, 3)))
    rel = consistent_poses(g, poses)
    check_relative_poses(g, rel)
    size = max(1.0, float(np.max(np.linalg.norm(pose_from_dq(poses)[1] - pose_from_dq(poses[0])[1], axis=-1))))
    rel[(5, 6)] = dqmul(rel[(5, 6)], dq_from_pose([1.0, 0, 0, 0], [0, 0, 10 * TOL_M_PER_M * 2 * size]))
    with pytest.raises(UnreachableError, match="cycle robots"):
        check_relative_poses(g, rel)
    check_relative_poses(g, rel, tol_m=1.0)  # a user's looser tolerance


def test_a_forest_without_cycles_is_always_consistent():
    g = Graph.from_edges(4, [(0, 1), (2, 3)])
    rel = {(0, 1): dq_from_pose([0.0, 1, 0, 0], [1, 2, 3]), (2, 3): dq_from_pose([1.0, 0, 0, 0], [0, 0, 5])}
    assert cycle_basis(g) == []
    check_relative_poses(g, rel)


@pytest.mark.parametrize("rel, error, text", [
    ({(0, 1): np.eye(8)[0]}, InvalidInputError, r"no desired pose for edge \(1, 2\) \(robot 3 in robot 2's frame\)"),
    ({(0, 1): np.eye(8)[0], (1, 2): np.eye(8)[0], (2, 0): np.eye(8)[0]}, InvalidInputError,
     r"\(2, 0\) is not an edge of the graph"),
    ({(0, 1): np.eye(8)[0], (1, 2): 2 * np.eye(8)[0]}, NonUnitError, r"relative\[\(1, 2\)\] must be a unit"),
    ({(0, 1): np.eye(8)[0], (1, 2): np.eye(4)[0]}, ShapeError, r"relative\[\(1, 2\)\] must be one unit dual"),
    ({(0, 1): np.eye(8)[0], "b": np.eye(8)[0]}, InvalidInputError, "key 'b' must be an edge"),
    ([np.eye(8)[0]], InvalidInputError, "must map each edge"),
])
def test_bad_relative_poses_are_one_line(rel, error, text):
    g = Graph.from_edges(3, [(0, 1), (1, 2)])
    with pytest.raises(error, match=text) as e:
        check_relative_poses(g, rel)
    assert "\n" not in str(e.value)


def test_bad_tolerances_and_root_poses_are_one_line():
    g = Graph.ring(3)
    rel = consistent_poses(g, np.tile(np.eye(8)[0], (3, 1)))
    for kwargs in ({"tol_rad": 0.0}, {"tol_m": -1.0}, {"tol_rad": float("nan")}):
        with pytest.raises(InvalidInputError, match="must be a finite number > 0"):
            check_relative_poses(g, rel, **kwargs)
    with pytest.raises(ShapeError, match=r"one pose per robot, shape \(3, 8\)"):
        consistent_poses(g, np.tile(np.eye(8)[0], (2, 1)))
