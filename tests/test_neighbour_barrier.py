"""The decentralised separation barrier: each robot's filter against the neighbours it senses.

Per-robot locality, the exact programme (against Lawson and Hanson's least-distance
programme), the one-step guarantee on stale information, the promise in closed loop under
delay and loss (simulated directly and through ``quatform.network.Links``), degenerate
inputs, NumPy = JAX.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls

from quatform.control.neighbour_barrier import CANDIDATES, SIGNALS, NeighbourBarrier, neighbour_filter
from quatform.errors import InvalidInputError, ShapeError
from quatform.network import Graph, Links, inbox

#: Float rounding allowed below the minimum separation, m.
ROUNDING_M = 1e-12


def _random_inputs(rng, batch, n, w, spread=2.0):
    p = rng.uniform(-spread, spread, batch + (n, 3))
    p_nb = p[..., None, :] + rng.normal(size=batch + (n, w, 3))
    age = rng.uniform(0.0, 0.2, batch + (n, w))
    valid = rng.random(batch + (n, w)) < 0.8
    u = rng.normal(size=batch + (n, 3))
    return u, p, p_nb, age, valid


def _min_separation_over_step(p, u, dt):
    """The smallest distance between two robots moving from ``p`` at ``u`` for ``dt`` (the
    exact minimum over the step of each pair, which moves on a line)."""
    i, j = np.triu_indices(len(p), 1)
    x, dx = p[i] - p[j], dt * (u[i] - u[j])
    dd = np.einsum("ij,ij->i", dx, dx)
    s = np.clip(-np.einsum("ij,ij->i", x, dx) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
    return float(np.min(np.linalg.norm(x + s[:, None] * dx, axis=-1), initial=math.inf))


def _least_distance(u0, A, b):
    """``argmin |u - u0|`` subject to ``A u >= b`` by Lawson and Hanson's NNLS (1974, ch. 23)."""
    c = b - A @ u0
    E = np.vstack([A.T, c[None]])
    f = np.zeros(4)
    f[-1] = 1.0
    y, _ = nnls(E, f, maxiter=2000)
    r = E @ y - f
    return u0 - r[:3] / r[3]


# -- parameters --------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, words", [
    (dict(min_separation_m=0.0, max_speed_m_s=1.0), "min_separation_m = 0.0"),
    (dict(min_separation_m=math.nan, max_speed_m_s=1.0), "min_separation_m = nan"),
    (dict(min_separation_m=0.3, max_speed_m_s=-1.0), "max_speed_m_s = -1.0"),
    (dict(min_separation_m=0.3, max_speed_m_s=True), "max_speed_m_s = True"),
    (dict(min_separation_m=0.3, max_speed_m_s=1.0, gamma=math.inf), "gamma = inf"),
    (dict(min_separation_m=0.3, max_speed_m_s=1.0, gamma=20.0, dt_s=0.1), "give gamma <= 10 1/s"),
    (dict(min_separation_m=0.3, max_speed_m_s=1.0, dt_s="0.1"), "dt_s = '0.1'"),
])
def test_bad_parameters_are_one_line(kwargs, words):
    with pytest.raises(InvalidInputError) as err:
        NeighbourBarrier(**kwargs)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_mismatched_shapes_are_refused():
    bar = NeighbourBarrier(0.3, 1.0)
    u, p, p_nb, age, valid = _random_inputs(np.random.default_rng(0), (), 4, 3)
    with pytest.raises(ShapeError, match="p_nb"):
        bar.filter(u, p, p_nb[..., :2], age, valid)
    with pytest.raises(ShapeError, match="p_nb"):
        bar.filter(u, p, p_nb, age[:, :2], valid)
    with pytest.raises(ShapeError, match="do not broadcast"):
        bar.filter(np.zeros((2, 4, 3)), p, np.broadcast_to(p_nb, (3, 4, 3, 3)), age, valid)


# -- per robot ---------------------------------------------------------------------------------

@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), w=st.sampled_from([0, 1, 4, CANDIDATES + 3]))
def test_each_row_depends_only_on_its_own_inputs(seed, w):
    rng = np.random.default_rng(seed)
    bar = NeighbourBarrier(0.5, 1.0, gamma=5.0)
    inputs = _random_inputs(rng, (2,), 5, w)
    u, sig = bar.filter(*inputs)
    i = int(rng.integers(5))
    others = np.arange(5) != i
    moved = [np.array(x, dtype=float) for x in inputs]
    for x in moved[:4]:
        x[:, others] += rng.normal(size=x[:, others].shape) * 3.0
    moved[4] = rng.random(inputs[4].shape) < 0.5
    moved[4][:, i] = inputs[4][:, i]
    u2, sig2 = bar.filter(*moved)
    np.testing.assert_array_equal(u2[:, i], u[:, i])
    for k in SIGNALS:
        np.testing.assert_array_equal(sig2[k][:, i], sig[k][:, i])
    alone, sig1 = bar.filter(*(x[:, i:i + 1] for x in inputs))  # the same function on one robot's node
    np.testing.assert_array_equal(alone[:, 0], u[:, i])
    for k in SIGNALS:
        np.testing.assert_array_equal(sig1[k][:, 0], sig[k][:, i])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), w=st.integers(1, 2 * CANDIDATES))
def test_fresh_information_solves_the_programme_exactly(seed, w):
    """Ages 0 and a speed bound that does not bind: the command is the solution of ``min |u -
    u_nom|^2`` subject to each sensed neighbour's half ``2 y.u >= -gamma h / 2`` (to the
    filter's tightening, 1e-12 of ``2 |y| v_max``)."""
    rng = np.random.default_rng(seed)
    d, gamma = 0.5, 5.0
    bar = NeighbourBarrier(d, 50.0, gamma=gamma)
    u, p, p_nb, _, valid = _random_inputs(rng, (), 1, w, spread=1.0)
    u = 3.0 * u
    y = p[:, None] - p_nb
    dist = np.linalg.norm(y, axis=-1)
    valid &= dist >= d
    got, sig = bar.filter(u, p, p_nb, np.zeros_like(dist), valid)
    keep = valid[0]
    if not keep.any():
        np.testing.assert_array_equal(got, u)
        return
    A, b = 2.0 * y[0, keep], -0.5 * gamma * (dist[0, keep] ** 2 - d * d)
    expected = _least_distance(u[0], A, b)
    if w <= CANDIDATES or not sig["fallback"][0]:  # beyond K neighbours: exact where certified
        assert not sig["fallback"][0]
        scale = 1.0 + np.abs(expected).max()
        np.testing.assert_allclose(got[0], expected, rtol=0, atol=1e-9 * scale)
    assert np.all(A @ got[0] >= b - 1e-9 * (1.0 + np.abs(b)))


def test_nothing_binds_gives_the_nominal_command_bitwise():
    rng = np.random.default_rng(4)
    bar = NeighbourBarrier(0.3, 2.0, gamma=5.0)
    p = rng.uniform(-1, 1, (3, 8, 3))
    p_nb = p[..., None, :] + 50.0 * rng.normal(size=(3, 8, 5, 3))  # far away
    u = rng.uniform(-1.0, 1.0, (3, 8, 3))
    got, sig = bar.filter(u, p, p_nb, rng.uniform(0, 0.5, (3, 8, 5)), np.ones((3, 8, 5), bool))
    np.testing.assert_array_equal(got, u)
    np.testing.assert_array_equal(sig["binding"], 0)
    np.testing.assert_array_equal(sig["scale"], 1.0)
    assert not sig["fallback"].any()
    # no valid neighbour: the nominal command, saturated
    fast = 5.0 * u
    got, sig = bar.filter(fast, p, p_nb, np.zeros((3, 8, 5)), np.zeros((3, 8, 5), bool))
    speed = np.linalg.norm(fast, axis=-1, keepdims=True)
    np.testing.assert_allclose(got, np.where(speed > 2.0, fast * 2.0 / speed, fast), rtol=1e-15)
    np.testing.assert_array_equal(sig["clearance_m"], math.inf)


# -- the guarantee -------------------------------------------------------------------------------

def _apart(rng, n, d, box):
    """``n`` points in a cube of side ``box`` at least ``d`` apart (rejection)."""
    pts = []
    while len(pts) < n:
        q = rng.uniform(0.0, box, 3)
        if all(np.linalg.norm(q - x) >= d for x in pts):
            pts.append(q)
    return np.array(pts)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(2, 7), stale=st.sampled_from([0.0, 0.05, 0.3]))
def test_one_step_keeps_every_pair_apart_on_stale_information(seed, n, stale):
    """Robots at least ``d`` apart, each knowing the others' positions up to ``v_max age`` old
    (any past position the speed bound allows), every robot filtering: after the step, and
    during it, every pair is at least ``d`` apart."""
    rng = np.random.default_rng(seed)
    d, v, dt = 0.4, 1.5, 0.1
    bar = NeighbourBarrier(d, v, gamma=1.0 / dt, dt_s=dt)
    p = _apart(rng, n, d, box=1.2 * n ** (1 / 3))
    off = rng.normal(size=3)
    touching = p[0] + d * off / np.linalg.norm(off)
    if rng.random() < 0.5 and np.all(np.linalg.norm(p[2:] - touching, axis=-1) >= d):
        p[1] = touching  # a pair exactly at the minimum
    assert _min_separation_over_step(p, np.zeros_like(p), dt) >= d - ROUNDING_M
    others = np.array([[j for j in range(n) if j != i] for i in range(n)]).reshape(n, n - 1)
    age = rng.uniform(0.0, stale, (n, n - 1))
    step = rng.normal(size=(n, n - 1, 3))
    step *= (v * age * rng.uniform(0, 1, (n, n - 1)) ** (1 / 3) / np.linalg.norm(step, axis=-1))[..., None]
    p_nb = p[others] - step  # where each neighbour was, within v_max age of where it is
    u_nom = 3.0 * v * rng.normal(size=(n, 3)) + (p.mean(axis=0) - p)  # towards each other, fast
    u, sig = bar.filter(u_nom, p, p_nb, age, np.ones((n, n - 1), bool))
    assert np.all(np.isfinite(u))
    assert np.all(np.linalg.norm(u, axis=-1) <= v * (1.0 + 1e-15))
    assert _min_separation_over_step(p, u, dt) >= d - ROUNDING_M


def _loop(n, ticks, dt, delay, loss, d, v, gamma, seed, goals="swap"):
    """Single integrators ``p <- p + dt u`` under the filter, every robot sensing every other,
    each holding the newest message that arrived (sent ``delay`` ticks before it arrives,
    lost with probability ``loss``); the smallest separation over the run (between ticks
    included) and the median distance to the goals at the end."""
    rng = np.random.default_rng(seed)
    bar = NeighbourBarrier(d, v, gamma=gamma, dt_s=dt)
    ang = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    p = np.stack([3.0 * np.cos(ang), 3.0 * np.sin(ang), 0.05 * rng.normal(size=n)], axis=-1)
    if goals == "swap":  # head-on swaps through the centre, half the team to random goals
        goal = -p.copy()
        goal[n // 2:] = rng.uniform(-3.0, 3.0, (n - n // 2, 3))
    else:  # everyone to a small ball: a crowd the filter holds at the minimum
        goal = rng.uniform(-0.3, 0.3, (n, 3))
    others = np.array([[j for j in range(n) if j != i] for i in range(n)])
    history = np.empty((ticks + 1, n, 3))
    history[0] = p
    newest = np.zeros((n, n - 1), dtype=np.int64)  # the send tick of the message held (tick 0: known)
    low = math.inf
    for k in range(ticks):
        if k >= delay:
            arrived = rng.random((n, n - 1)) >= loss
            newest = np.where(arrived, np.maximum(newest, k - delay), newest)
        u, sig = bar.filter(goal - p, p, history[newest, others], (k - newest) * dt, np.ones((n, n - 1), bool))
        assert np.all(np.isfinite(u))
        low = min(low, _min_separation_over_step(p, u, dt))
        p = p + dt * u
        history[k + 1] = p
    return low, float(np.median(np.linalg.norm(p - goal, axis=-1)))


@pytest.mark.parametrize("delay, loss, goals", [(0, 0.0, "crowd"), (3, 0.1, "swap"), (5, 0.3, "crowd"),
                                                (8, 0.2, "swap")])
def test_closed_loop_never_closer_than_the_minimum(delay, loss, goals):
    d = 0.3
    low, _ = _loop(30, 200, 0.05, delay, loss, d, 1.0, 10.0, seed=delay, goals=goals)
    assert low >= d - ROUNDING_M
    if delay == 0:  # fresh information: the crowd is held at the minimum itself
        assert low <= d + 1e-9


def test_closed_loop_through_links_and_the_inbox():
    """The radio of ``quatform.network``: a complete graph, 0.1 s delay with 0.05 s jitter, 20 %
    loss; robots hold until a neighbour's first message arrives (``hold_unheard``)."""
    n, ticks, dt, d, v = 20, 300, 0.05, 0.3, 1.0
    rng = np.random.default_rng(0)
    ang = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    p = np.stack([2.5 * np.cos(ang), 2.5 * np.sin(ang), 0.05 * rng.normal(size=n)], axis=-1)
    goal = -p + 0.05 * rng.normal(size=p.shape)
    links = Links(Graph.complete(n), delay_s=0.1, jitter_s=0.05, drop=0.2, seed=3)
    times = np.arange(ticks) * dt
    xs = links.schedule(times, dt)
    def message(p):  # the sender's position first, then anything else
        return np.concatenate([p, np.ones((n, 1))], axis=-1)

    state = links.init(message(p), (), xs)
    bar = NeighbourBarrier(d, v, gamma=10.0, dt_s=dt)
    low, held = math.inf, 0
    for k, t in enumerate(times):
        state = links.write(state, message(p), t)
        box = inbox(links.read(state, {key: x[k] for key, x in xs.items()}), links)
        u, sig = bar.filter_inbox(goal - p, p, box, t, hold_unheard=True)
        if k == 0:  # nothing has arrived: every robot stays
            np.testing.assert_array_equal(u, 0.0)
        held += int(np.sum(~np.any(box["valid"], axis=-1)))
        low = min(low, _min_separation_over_step(p, u, dt))
        p = p + dt * u
    assert low >= d - ROUNDING_M
    assert held > 0
    assert np.median(np.linalg.norm(p - goal, axis=-1)) < 0.5  # and the swap gets through


# -- degenerate inputs -----------------------------------------------------------------------------

def test_degenerate_inputs_give_finite_commands():
    bar = NeighbourBarrier(0.3, 1.0, gamma=5.0)
    rng = np.random.default_rng(1)
    u, p, p_nb, age, valid = _random_inputs(rng, (), 6, 4)
    p_nb[0] = p[0]  # coincident with every neighbour
    age[1] = 0.0
    valid[2] = False  # no neighbour
    p_nb[2] = np.nan  # ... and garbage in the invalid slots
    age[2] = np.nan
    valid[3] = True
    age[3, 0] = math.inf  # a neighbour of unknown position: the robot stays
    p_nb[4, 1] = np.nan  # likewise
    valid[4, 1] = True
    age[5] = -1.0  # a stamp ahead of the clock counts as age 0
    got, sig = bar.filter(u, p, p_nb, age, valid)
    assert np.all(np.isfinite(got)) and all(np.all(np.isfinite(sig[k]) | (k == "clearance_m")) for k in SIGNALS)
    assert np.all(np.linalg.norm(got, axis=-1) <= 1.0 * (1 + 1e-15))
    np.testing.assert_array_equal(got[[3, 4]], 0.0)
    speed = np.linalg.norm(u[2])
    np.testing.assert_allclose(got[2], u[2] * min(1.0, 1.0 / speed), rtol=1e-15)
    clipped = age.copy()
    clipped[5] = 0.0
    again, _ = bar.filter(u, p, p_nb, clipped, valid)
    np.testing.assert_array_equal(again[5], got[5])
    # a lost own position or a nominal command that is not finite: the robot stays
    p[0, 1], u[1, 2] = np.nan, np.inf
    got, sig = bar.filter(u, p, p_nb, age, valid)
    np.testing.assert_array_equal(got[:2], 0.0)
    assert np.all(np.isfinite(got))


@pytest.mark.parametrize("batch, n, w", [((0,), 5, 3), ((2,), 0, 3), ((2,), 4, 0), ((), 1, 0)])
def test_empty_shapes(batch, n, w):
    bar = NeighbourBarrier(0.3, 1.0)
    inputs = _random_inputs(np.random.default_rng(0), batch, n, w)
    got, sig = bar.filter(*inputs)
    assert got.shape == batch + (n, 3)
    assert all(sig[k].shape == batch + (n,) for k in SIGNALS)
    if w == 0:
        speed = np.linalg.norm(inputs[0], axis=-1, keepdims=True)
        np.testing.assert_allclose(got, inputs[0] * np.minimum(1.0, 1.0 / speed), rtol=1e-15)


def test_inbox_helper_reads_positions_and_ages():
    bar = NeighbourBarrier(0.3, 1.0, gamma=5.0)
    rng = np.random.default_rng(2)
    u, p, p_nb, age, valid = _random_inputs(rng, (2,), 4, 3)
    t = 7.5
    box = {"senders": np.array([[1, 2, -1], [0, 2, 3], [0, -1, -1], [0, 1, 2]]),
           "messages": np.concatenate([p_nb, rng.normal(size=(2, 4, 3, 5))], axis=-1),
           "stamps": np.where(valid, t - age, -math.inf), "valid": valid}
    got, sig = bar.filter_inbox(u, p, box, t)
    expected, sig_e = neighbour_filter(bar, u, p, p_nb, age, valid)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    held, _ = bar.filter_inbox(u, p, box, t, hold_unheard=True)
    unheard = np.any((box["senders"] >= 0) & ~valid, axis=-1)
    np.testing.assert_array_equal(held[unheard], 0.0)
    np.testing.assert_array_equal(held[~unheard], got[~unheard])
    with pytest.raises(ShapeError, match="first 3"):
        bar.filter_inbox(u, p, {**box, "messages": box["messages"][..., :2]}, t)


# -- NumPy and JAX -------------------------------------------------------------------------------

@pytest.mark.parametrize("w", [0, 3, CANDIDATES + 4])
def test_numpy_equals_jax(w):
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    bar = NeighbourBarrier(0.5, 1.0, gamma=5.0)
    rng = np.random.default_rng(w)
    inputs = list(_random_inputs(rng, (3,), 12, w, spread=1.5))
    if w:
        inputs[1][0, 0] = inputs[2][0, 0, 0]  # coincident
        inputs[3][1, 2, 0] = math.inf  # unknown position
    expected, sig = bar.filter(*inputs)
    with jax.enable_x64(True):
        got, sig_j = jax.jit(bar.filter)(*(jnp.asarray(x) for x in inputs))
        got, sig_j = np.asarray(got), {k: np.asarray(s) for k, s in sig_j.items()}
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    for k in SIGNALS:
        np.testing.assert_allclose(sig_j[k].astype(float), sig[k].astype(float), rtol=0, atol=1e-9)
