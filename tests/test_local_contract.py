"""The per-robot controller contract, run over every registered local controller.

Each law of :data:`quatform.control.local.LOCAL_CONTROLLERS` (its ``examples()``) is fed
random robots in general position and a random inbox (some slots stale or lost, some padded)
and must: give finite commands, messages and signals of the declared columns; compute each
robot's row from that robot's row of every input only (other robots' rows perturbed, the row
is bitwise the same); give one robot's node (``N = 1``, its rows only) the row the team call
gives; stay finite when nothing valid is held; and equal itself on JAX.
"""

from __future__ import annotations

import numpy as np
import pytest

import quatform.control.local_laws  # noqa: F401  (registers the laws)
from quatform.control.local import LOCAL_CONTROLLERS, LocalTick, robot_rows
from quatform.network import Graph, Links, inbox

CASES = [(label, ctrl, n) for cls in LOCAL_CONTROLLERS.values() for label, (ctrl, n) in cls.examples().items()]
IDS = [c[0] for c in CASES]


def _inputs(ctrl, n, seed=0, batch=()):
    """Own rows, reference, state and an inbox over a random graph (in-degree 1..3, padded)."""
    rng = np.random.default_rng(seed)
    own, ref = ctrl.example(n, rng)
    ref = ctrl.reference_arrays(ref, n)
    edges = sorted({(i, int(j)) for i in range(n) for j in rng.choice([k for k in range(n) if k != i],
                                                                       size=min(n - 1, 1 + i % 3), replace=False)})
    links = Links(Graph(n, edges, weights=rng.uniform(0.5, 2.0, size=len(edges))), max_age_s=1.0)
    state = ctrl.init(n, batch)
    msgs = ctrl.message(state, own, ref, 0.0)
    # each edge carries a message of its sender made from a randomly perturbed own state
    own_old, _ = ctrl.example(n, rng)
    sent = ctrl.message(state, own_old, ref, 0.0)
    E = len(links.edges)
    valid = rng.uniform(size=E) < 0.7
    received = (np.where(valid[:, None], sent[links.edges[:, 1]], 0.0), np.where(valid, -0.05, -np.inf), valid)
    box = inbox(received, links)
    w = np.zeros(box["senders"].shape)
    for i in range(n):
        for m, j in enumerate(box["senders"][i]):
            if j >= 0:
                w[i, m] = links.graph.weights[np.flatnonzero((links.edges[:, 0] == i) & (links.edges[:, 1] == j))[0]]
    box["weights"] = w
    return own, ref, state, box, msgs


def _finite(tree):
    leaves = tree.values() if isinstance(tree, dict) else [tree]
    return all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in leaves)


@pytest.mark.parametrize("label,ctrl,n", CASES, ids=IDS)
def test_columns_and_finite(label, ctrl, n):
    own, ref, state, box, msgs = _inputs(ctrl, n)
    assert own.shape == (n, len(ctrl.own_columns))
    assert msgs.shape == (n, len(ctrl.message_columns)) and _finite(msgs)
    out = ctrl.tick(state, own, box, ref, 0.1)
    assert isinstance(out, LocalTick)
    assert np.shape(out.u) == (n, len(ctrl.command_columns)) and _finite(out.u)
    cols = ctrl.signal_columns()
    assert set(out.signals) == set(cols)
    for k, v in out.signals.items():
        assert np.shape(v) == (n, len(cols[k])) and _finite(v), k
    assert np.shape(out.code) == (n,) and np.all(np.asarray(out.code) == 0)


@pytest.mark.parametrize("label,ctrl,n", CASES, ids=IDS)
def test_rows_are_local(label, ctrl, n):
    """Robot i's outputs do not change when every other robot's inputs do."""
    own, ref, state, box, _ = _inputs(ctrl, n, seed=1)
    base = ctrl.tick(state, own, box, ref, 0.1)
    other_own, other_ref, _, other_box, _ = _inputs(ctrl, n, seed=2)
    i = n // 2
    keep = np.arange(n) == i

    def mix(a, b, axis_from_end):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return a
        shape = [1] * a.ndim
        shape[a.ndim - axis_from_end] = n
        return np.where(keep.reshape(shape), a, b)

    own2 = mix(own, other_own, 2)
    ref2 = {k: mix(v, other_ref[k], 2) if np.ndim(v) >= 2 and np.shape(v)[-2] == n else v for k, v in ref.items()}
    box2 = dict(box)
    for key, axis in (("messages", 3), ("stamps", 2), ("valid", 2), ("weights", 2)):
        if box[key].shape == other_box[key].shape:
            box2[key] = mix(box[key], other_box[key], axis)
    out = ctrl.tick(state, own2, box2, ref2, 0.1)
    np.testing.assert_array_equal(np.asarray(out.u)[i], np.asarray(base.u)[i])
    for k in base.signals:
        np.testing.assert_array_equal(np.asarray(out.signals[k])[i], np.asarray(base.signals[k])[i])
    np.testing.assert_array_equal(np.asarray(ctrl.message(state, own2, ref2, 0.1))[i],
                                  np.asarray(ctrl.message(state, own, ref, 0.1))[i])


@pytest.mark.parametrize("label,ctrl,n", CASES, ids=IDS)
def test_one_robot_node(label, ctrl, n):
    """One robot's node (its rows only, N = 1) computes what the team call gives its row."""
    own, ref, state, box, _ = _inputs(ctrl, n, seed=3)
    team = ctrl.tick(state, own, box, ref, 0.1)
    for i in range(n):
        rows = [i]
        one = ctrl.tick(robot_rows(state, rows, 2), own[rows],
                        {k: (v[rows] if k == "senders" else robot_rows(v, rows, 3 if k == "messages" else 2))
                         for k, v in box.items()},
                        {k: robot_rows(v, rows, 2) for k, v in ref.items()}, 0.1)
        np.testing.assert_allclose(np.asarray(one.u)[0], np.asarray(team.u)[i], rtol=0, atol=1e-12)


@pytest.mark.parametrize("label,ctrl,n", CASES, ids=IDS)
def test_nothing_held(label, ctrl, n):
    """An inbox with no valid message (all lost or stale) still gives finite outputs."""
    own, ref, state, box, _ = _inputs(ctrl, n, seed=4)
    box = dict(box, valid=np.zeros_like(box["valid"]), messages=np.zeros_like(box["messages"]),
               stamps=np.full(box["stamps"].shape, -np.inf))
    out = ctrl.tick(state, own, box, ref, 0.1)
    assert _finite(out.u) and all(_finite(v) for v in out.signals.values())


@pytest.mark.parametrize("label,ctrl,n", CASES, ids=IDS)
def test_jax_equals_numpy(label, ctrl, n):
    jax = pytest.importorskip("jax")
    own, ref, state, box, _ = _inputs(ctrl, n, seed=5)
    ref_np = ctrl.tick(state, own, box, ref, 0.1)
    with jax.enable_x64(True):
        to = (lambda tree: jax.tree_util.tree_map(jax.numpy.asarray, tree))
        box_j = {k: v for k, v in box.items() if k != "senders"}

        def run(s, o, b, r):
            out = ctrl.tick(s, o, dict(b, senders=box["senders"]), r, 0.1)
            return out.u, dict(out.signals), ctrl.message(s, o, r, 0.1)

        u, signals, msgs = jax.jit(run)(to(state), to(own), to(box_j), to(ref))
    np.testing.assert_allclose(np.asarray(u), np.asarray(ref_np.u), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.asarray(msgs), np.asarray(ctrl.message(state, own, ref, 0.1)), rtol=1e-9, atol=1e-12)
    for k in ref_np.signals:
        np.testing.assert_allclose(np.asarray(signals[k]), np.asarray(ref_np.signals[k]), rtol=1e-9, atol=1e-12)


def test_every_law_is_enrolled():
    assert "position-consensus" in LOCAL_CONTROLLERS
    assert len(CASES) >= len(LOCAL_CONTROLLERS)
