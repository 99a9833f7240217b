"""The communication model: delay, jitter, loss, send rates, switching and stale messages.

Oracles: closed forms (perfect links, a pure delay, total loss, rate gating, the age
boundary), a plain-Python event-by-event simulation of the documented draws (each edge's
list of (arrival, send) events), the binomial law of the losses, and NumPy against JAX.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.errors import InvalidInputError, NonFiniteError, ShapeError
from quatform.network import Graph, Links, delivered_edges, inbox

DT = 0.01


def _times(T, dt=DT):
    return np.arange(T) * dt


def _tick(schedule, k):
    return {key: value[k] for key, value in schedule.items()}


def _run(links, schedule, times, outgoing):
    """``(messages, stamps, valid)`` at every tick of a write-then-read loop; ``outgoing``
    ``(T, *batch, N, d)``."""
    batch = schedule["lag"].shape[1:-1]
    state = links.init(outgoing[0], batch, schedule)
    out = []
    for k, t in enumerate(times):
        state = links.write(state, outgoing[k], t)
        out.append(links.read(state, _tick(schedule, k)))
    return [np.stack(a) for a in zip(*out)]


def _reference(links, times, dt, world=0):
    """``(lag (T, E), new (T, E), sent (T,), dropped (T,))`` of one world, event by event from the
    documented rules and draw order, in plain Python."""
    T, E = len(times), len(links.edges)
    rng = np.random.default_rng(links.seed + world)
    horizon = math.inf if math.isinf(links.max_age_s) else math.floor(links.max_age_s / dt + 1e-9)
    events = [[] for _ in range(E)]
    sent, dropped = [0] * T, [0] * T
    for s in range(T):
        u = rng.random(2 * E)
        interval = 0
        for m, start in enumerate(links.starts):
            if times[s] + 1e-9 * dt >= start:
                interval = m
        for e in range(E):
            j = int(links.edges[e, 1])
            if links.rate_hz is None or s == 0:
                sends = True
            else:
                r = float(links.rate_hz[j])
                sends = math.floor(times[s] * r + 1e-9) > math.floor(times[s - 1] * r + 1e-9)
            if not (sends and links.active[interval, e]):
                continue
            sent[s] += 1
            if u[e] < links.drop[e]:
                dropped[s] += 1
                continue
            delay = max(0, math.ceil((links.delay_s[e] + links.jitter_s[e] * u[E + e]) / dt - 1e-9))
            events[e].append((s + delay, s))
    lag = np.full((T, E), -1)
    new = np.zeros((T, E), dtype=bool)
    for e in range(E):
        before = -1
        for k in range(T):
            arrived = [s for a, s in events[e] if a <= k]
            newest = max(arrived, default=-1)
            if newest >= 0 and k - newest <= horizon:
                lag[k, e] = k - newest
                new[k, e] = newest > before
            before = newest
    return lag, new, np.array(sent), np.array(dropped)


@st.composite
def links_cases(draw):
    n = draw(st.integers(2, 4))
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    first = draw(st.lists(st.sampled_from(pairs), unique=True, min_size=1, max_size=len(pairs)))
    graph = Graph(n, first)
    if draw(st.booleans()):
        second = draw(st.lists(st.sampled_from(pairs), unique=True, max_size=len(pairs)))
        graph = [(0.0, graph), (draw(st.integers(1, 20)) * DT, Graph(n, second))]
    E = len(Links(graph).edges)
    per_edge = st.one_of(st.floats(0.0, 0.06), st.lists(st.floats(0.0, 0.06), min_size=E, max_size=E))
    rate = st.one_of(st.none(), st.sampled_from([100.0, 50.0, 30.0, 10.0]),
                     st.lists(st.sampled_from([100.0, 40.0, 25.0]), min_size=n, max_size=n))
    links = Links(graph, delay_s=draw(per_edge), jitter_s=draw(per_edge), drop=draw(st.sampled_from([0.0, 0.3, 1.0])),
                  rate_hz=draw(rate), max_age_s=draw(st.sampled_from([math.inf, 0.03, 0.07, 0.2])),
                  seed=draw(st.integers(0, 2**32)))
    return links, draw(st.integers(1, 40))


@settings(max_examples=40)
@given(links_cases())
def test_schedule_equals_event_by_event_reference(case):
    links, T = case
    times = _times(T)
    s = links.schedule(times, DT)
    lag, new, sent, dropped = _reference(links, times, DT)
    np.testing.assert_array_equal(s["lag"], lag)
    np.testing.assert_array_equal(s["new"], new)
    np.testing.assert_array_equal(s["messages_sent"], sent)
    np.testing.assert_array_equal(s["messages_dropped"], dropped)
    np.testing.assert_array_equal(delivered_edges(_tick(s, T - 1)), new[-1])


@settings(max_examples=25)
@given(links_cases(), st.data())
def test_chunked_schedule_equals_one_call(case, data):
    links, T = case
    times = _times(T)
    whole = links.schedule(times, DT, (2,))
    cuts = sorted(data.draw(st.lists(st.integers(0, T), max_size=4)))
    bounds = [0, *cuts, T]
    parts = [links.schedule(times, DT, (2,), ticks=(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]
    for key in whole:
        np.testing.assert_array_equal(np.concatenate([p[key] for p in parts]), whole[key])
        assert all(p[key].dtype == whole[key].dtype for p in parts)


def test_world_b_of_a_batch_is_a_batch_of_one_with_seed_plus_b():
    graph = Graph.complete(3)
    links = Links(graph, delay_s=0.01, jitter_s=0.05, drop=0.4, rate_hz=[100.0, 50.0, 20.0], max_age_s=0.1, seed=11)
    times = _times(60)
    batch = links.schedule(times, DT, (2, 3))
    for b in range(6):
        alone = Links(graph, delay_s=0.01, jitter_s=0.05, drop=0.4, rate_hz=[100.0, 50.0, 20.0], max_age_s=0.1,
                      seed=11 + b).schedule(times, DT)
        for key in batch:
            np.testing.assert_array_equal(batch[key][:, b // 3, b % 3], alone[key])


def test_perfect_links_deliver_every_message_the_tick_it_is_sent():
    links = Links(Graph.complete(4), rate_hz=1.0 / DT)
    T, times = 30, _times(30)
    s = links.schedule(times, DT, (2,))
    assert np.all(s["lag"] == 0) and np.all(s["new"])
    assert np.all(s["messages_sent"] == 12) and np.all(s["messages_dropped"] == 0)
    out = np.random.default_rng(0).normal(size=(T, 2, 4, 3))
    messages, stamps, valid = _run(links, s, times, out)
    np.testing.assert_array_equal(messages, out[:, :, links.edges[:, 1]])
    np.testing.assert_array_equal(stamps, np.broadcast_to(times[:, None, None], stamps.shape))
    assert np.all(valid)


@pytest.mark.parametrize("d", [1, 3, 7])
def test_a_pure_delay_of_d_ticks_delivers_the_message_sent_d_ticks_before(d):
    links = Links(Graph.ring(5, directed=False), delay_s=d * DT)
    T, times = 25, _times(25)
    s = links.schedule(times, DT)
    out = np.arange(T, dtype=float)[:, None, None] * 10.0 + np.arange(5.0)[None, :, None]  # (T, N, 1)
    messages, stamps, valid = _run(links, s, times, out)
    assert not np.any(valid[:d]) and np.all(valid[d:])
    np.testing.assert_array_equal(messages[d:, :, 0], out[:-d, links.edges[:, 1], 0])
    np.testing.assert_array_equal(stamps[d:], np.broadcast_to(times[:-d, None], stamps[d:].shape))
    assert np.all(messages[:d] == 0.0) and np.all(stamps[:d] == -np.inf)


def test_total_loss_delivers_nothing():
    links = Links(Graph.complete(3), delay_s=0.02, drop=1.0)
    T, times = 20, _times(20)
    s = links.schedule(times, DT, (3,))
    assert np.all(s["lag"] == -1) and not np.any(s["new"])
    np.testing.assert_array_equal(s["messages_dropped"], s["messages_sent"])
    messages, stamps, valid = _run(links, s, times, np.ones((T, 3, 3, 2)))
    assert not np.any(valid) and np.all(messages == 0.0) and np.all(stamps == -np.inf)


def test_with_jitter_the_stamp_at_a_receiver_never_goes_back():
    links = Links(Graph.complete(3), delay_s=0.01, jitter_s=0.08, drop=0.2, seed=5)
    T, times = 200, _times(200)
    s = links.schedule(times, DT, (2,))
    delays = []
    _, stamps, valid = _run(links, s, times, np.zeros((T, 2, 3, 1)))
    for k in range(1, T):
        both = valid[k] & valid[k - 1]
        assert np.all(stamps[k][both] >= stamps[k - 1][both])
        delays.append(s["lag"][k][s["new"][k]])
    assert np.ptp(np.concatenate(delays)) >= 5  # the jitter spans ticks: messages cross


def test_a_message_exactly_max_age_old_is_valid_one_tick_more_is_stale():
    for dt, period_ticks, age_ticks in ((0.01, 10, 5), (0.1, 10, 3), (0.02, 5, 3)):
        links = Links(Graph.ring(3), rate_hz=1.0 / (period_ticks * dt), max_age_s=age_ticks * dt)
        times = _times(4 * period_ticks, dt)
        lag = links.schedule(times, dt)["lag"][:, 0]
        expected = np.arange(len(times)) % period_ticks
        np.testing.assert_array_equal(lag, np.where(expected <= age_ticks, expected, -1))
        assert links.horizon_ticks(dt, len(times)) == age_ticks


def test_rate_gating_a_10_hz_robot_in_a_100_hz_loop_sends_every_10th_tick():
    links = Links(Graph.complete(3), rate_hz=[100.0, 10.0, 25.0])
    times = _times(100)
    s = links.schedule(times, DT)
    k = np.arange(100)
    for e, (i, j) in enumerate(links.edges):
        period = {0: 1, 1: 10, 2: 4}[int(j)]
        np.testing.assert_array_equal(s["new"][:, e], k % period == 0)
        np.testing.assert_array_equal(s["lag"][:, e], k % period)
    np.testing.assert_array_equal(s["messages_sent"], 2 * (1 + (k % 10 == 0) + (k % 4 == 0)))


def test_switching_an_inactive_edge_delivers_nothing_sent_then():
    ring, path = Graph.ring(3), Graph(3, [(0, 1), (1, 2)])  # the ring's (2, 0) is off from 0.2 s to 0.5 s
    links = Links([(0.0, ring), (0.2, path), (0.5, ring)], delay_s=0.05)
    assert links.starts.tolist() == [0.0, 0.2, 0.5]
    times = _times(80)
    s = links.schedule(times, DT)
    e = int(np.flatnonzero((links.edges[:, 0] == 2) & (links.edges[:, 1] == 0))[0])
    newest = np.arange(80) - s["lag"][:, e]
    sent_off = (newest >= 20) & (newest < 50)
    assert not np.any(sent_off & (s["lag"][:, e] >= 0))
    np.testing.assert_array_equal(newest[24:25], [19])  # sent at 0.19 s, in flight at the switch: it arrives
    np.testing.assert_array_equal(newest[55:56], [50])
    np.testing.assert_array_equal(s["messages_sent"][[19, 20, 49, 50]], [3, 2, 2, 3])


def test_losses_follow_the_drop_probability_within_a_binomial_bound():
    links = Links(Graph.complete(6), drop=0.3, seed=2)
    s = links.schedule(_times(500), DT, (4,))
    sent, dropped = s["messages_sent"].sum(axis=0), s["messages_dropped"].sum(axis=0)
    assert np.all(sent == 500 * 30)
    assert np.all(np.abs(dropped - 0.3 * sent) <= 5.0 * np.sqrt(sent * 0.3 * 0.7))


@given(links_cases())
@settings(max_examples=20)
def test_inbox_groups_each_robots_in_neighbours(case):
    links, T = case
    s = links.schedule(_times(T), DT)
    rng = np.random.default_rng(0)
    messages, stamps, valid = _run(links, s, _times(T), rng.normal(size=(T, links.n, 2)))
    box = inbox((messages[-1], stamps[-1], valid[-1]), links)
    for i in range(links.n):
        mine = np.flatnonzero(links.edges[:, 0] == i)
        m = len(mine)
        np.testing.assert_array_equal(box["senders"][i, :m], links.edges[mine, 1])
        assert np.all(box["senders"][i, m:] == -1) and not np.any(box["valid"][i, m:])
        np.testing.assert_array_equal(box["messages"][i, :m], messages[-1][mine])
        np.testing.assert_array_equal(box["stamps"][i, :m], stamps[-1][mine])
        np.testing.assert_array_equal(box["valid"][i, :m], valid[-1][mine])
    assert box["messages"].shape == (links.n, np.bincount(links.edges[:, 0], minlength=links.n).max(), 2)


def test_numpy_and_jax_read_write_equal_bitwise():
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    links = Links(Graph.complete(4), delay_s=0.02, jitter_s=0.06, drop=0.25, rate_hz=[100.0, 50.0, 20.0, 100.0],
                  max_age_s=0.08, seed=9)
    T, times = 60, _times(60)
    s = links.schedule(times, DT, (3,))
    out = np.random.default_rng(1).normal(size=(T, 3, 4, 8))
    expected = _run(links, s, times, out)

    def tick(state, x):
        state = links.write(state, x["out"], x["t"])
        got = links.read(state, x)
        box = inbox(got, links)
        return state, (*got, box["messages"], box["valid"])

    with jax.enable_x64(True):
        state = jax.tree_util.tree_map(jnp.asarray, links.init(out[0], (3,), s))
        xs = {key: jnp.asarray(v) for key, v in s.items()} | {"out": jnp.asarray(out), "t": jnp.asarray(times)}
        _, got = jax.jit(lambda st, x: jax.lax.scan(tick, st, x))(state, xs)
    for a, b in zip(got[:3], expected):
        np.testing.assert_array_equal(np.asarray(a), b)
    box = [inbox((m, st, v), links) for m, st, v in zip(*expected)]
    np.testing.assert_array_equal(np.asarray(got[3]), np.stack([b["messages"] for b in box]))
    np.testing.assert_array_equal(np.asarray(got[4]), np.stack([b["valid"] for b in box]))


def test_memory_lags_are_int16_and_the_ring_holds_the_longest_lag():
    links = Links(Graph.ring(4), delay_s=0.03, jitter_s=0.02, max_age_s=0.5)
    s = links.schedule(_times(50), DT, (2,))
    assert s["lag"].dtype == np.int16 and s["new"].dtype == np.bool_
    state = links.init(np.zeros((4, 8)), (2,), s)
    assert state["ring"].shape == (2, int(s["lag"].max()) + 1, 4, 8)
    with pytest.raises(InvalidInputError, match="ring length 2 must be an integer of at least"):
        links.init(np.zeros((4, 8)), (2,), s, length=2)
    assert Links(Graph.ring(4)).schedule(_times(40000), 1e-3, ticks=(0, 2))["lag"].dtype == np.int32


@pytest.mark.parametrize("kwargs, error, match", [
    ({"delay_s": -0.01}, InvalidInputError, r"delay_s = -0.01 must be a finite number >= 0 s"),
    ({"delay_s": [0.0, 0.1]}, ShapeError, r"delay_s must be a number or one per candidate edge, shape \(3,\)"),
    ({"jitter_s": [0.0, -1.0, 0.0]}, InvalidInputError, r"jitter_s of candidate edge #2 = -1.0 must be"),
    ({"drop": 1.5}, InvalidInputError, r"drop = 1.5 must be a finite number in \[0, 1\] \(a probability\)"),
    ({"drop": math.nan}, InvalidInputError, r"drop = nan must be a finite number"),
    ({"rate_hz": 0.0}, InvalidInputError, r"rate_hz = 0.0 must be a finite number > 0 Hz \(None: every tick\)"),
    ({"rate_hz": [10.0, -1.0, 10.0]}, InvalidInputError, r"rate_hz of robot #2 = -1.0"),
    ({"rate_hz": [10.0, 10.0]}, ShapeError, r"rate_hz must be a number or one per robot, shape \(3,\)"),
    ({"max_age_s": 0.0}, InvalidInputError, r"max_age_s = 0.0 must be a number > 0 s"),
    ({"seed": -1}, InvalidInputError, r"seed = -1 must be an integer >= 0"),
])
def test_bad_settings_are_one_line_naming_the_value(kwargs, error, match):
    with pytest.raises(error, match=match) as info:
        Links(Graph.ring(3), **kwargs)
    assert "\n" not in str(info.value)


def test_bad_switching_schedules_batches_and_runs_are_one_line():
    ring3, ring4 = Graph.ring(3), Graph.ring(4)
    with pytest.raises(InvalidInputError, match=r"switching starts must increase, yet interval #2 starts at 0 s"):
        Links([(0.0, ring3), (0.0, ring3)])
    with pytest.raises(InvalidInputError, match=r"interval #2 has 4 robots, the first has 3"):
        Links([(0.0, ring3), (1.0, ring4)])
    with pytest.raises(NonFiniteError, match=r"start_s = nan of switching interval #1"):
        Links([(math.nan, ring3)])
    with pytest.raises(InvalidInputError, match=r"must be a Graph or a non-empty sequence"):
        Links([])
    links = Links(ring3, rate_hz=[100.0, 200.0, 50.0])
    with pytest.raises(InvalidInputError, match=r"rate_hz = 200 Hz of robot 2 is above the loop's 1/dt = 100 Hz "
                                                r"\(a robot cannot send faster than the loop ticks\)"):
        links.schedule(_times(5), DT)
    with pytest.raises(ShapeError, match=r"batch \(0,\) must be a tuple of positive integers"):
        Links(ring3).schedule(_times(5), DT, (0,))
    with pytest.raises(InvalidInputError, match=r"ticks \(3, 9\) must be a range"):
        Links(ring3).schedule(_times(5), DT, ticks=(3, 9))
    with pytest.raises(InvalidInputError, match=r"dt = 0 must be a finite number > 0 s"):
        Links(ring3).schedule(_times(5), 0)
    with pytest.raises(ShapeError, match=r"outgoing0 must be \(N, d\) or \(\*batch, N, d\) with N = 3"):
        Links(ring3).init(np.zeros((4, 2)))
    with pytest.raises(ShapeError, match=r"schedule lags of shape \(5, 2, 3\) for batch \(3,\)"):
        Links(ring3).init(np.zeros((3, 2)), (3,), Links(ring3).schedule(_times(5), DT, (2,)))


def test_write_and_inbox_refuse_wrong_shapes_in_one_line():
    links = Links(Graph.ring(3))
    state = links.init(np.zeros((2, 3, 4)), (2,))
    for bad, seen in ((np.zeros((3, 4)), r"shape \(3, 4\)"), (np.zeros((2, 3, 5)), r"shape \(2, 3, 5\)"),
                      (None, "None")):
        with pytest.raises(ShapeError, match=r"outgoing messages must be \(\*batch, N, d\) = \(2, 3, 4\) .*got "
                                             + seen) as info:
            links.write(state, bad, 0.0)
        assert "\n" not in str(info.value)
    got = links.read(links.write(state, np.ones((2, 3, 4)), 0.0), {"lag": np.zeros((2, 3), dtype=np.int16)})
    assert inbox(got, links)["valid"].shape == (2, 3, 1)
    for bad in (None, got[:2], (got[0], got[1][..., :1], got[2]), (np.zeros(3), got[1], got[2])):
        with pytest.raises(ShapeError, match=r"received must be Links.read's \(messages \(\*batch, E, d\), "
                                             r"stamps \(\*batch, E\), valid \(\*batch, E\)\), got ") as info:
            inbox(bad, links)
        assert "\n" not in str(info.value)


def test_a_loop_drawing_chunk_by_chunk_reads_what_one_schedule_reads():
    links = Links(Graph.complete(3), delay_s=0.02, jitter_s=0.05, drop=0.3, rate_hz=50.0, max_age_s=0.09, seed=4)
    T, times = 90, _times(90)
    out = np.random.default_rng(3).normal(size=(T, 2, 3, 4))
    expected = _run(links, links.schedule(times, DT, (2,)), times, out)
    state = links.init(out[0], (2,), length=links.horizon_ticks(DT, T) + 1)
    got = []
    for k0 in range(0, T, 25):
        chunk = links.schedule(times, DT, (2,), ticks=(k0, min(k0 + 25, T)))
        for k in range(k0, min(k0 + 25, T)):
            state = links.write(state, out[k], times[k])
            got.append(links.read(state, _tick(chunk, k - k0)))
    for a, b in zip(zip(*got), expected):
        np.testing.assert_array_equal(np.stack(a), b)


def test_a_lag_the_ring_does_not_hold_reads_as_not_valid():
    links = Links(Graph.ring(3), delay_s=0.05)
    state = links.write(links.init(np.ones((3, 2)), length=3), np.ones((3, 2)), 0.0)
    messages, stamps, valid = links.read(state, {"lag": np.array([5, 2, -1], dtype=np.int16)})
    np.testing.assert_array_equal(valid, [False, True, False])
    assert np.all(messages[[0, 2]] == 0.0) and np.all(stamps[[0, 2]] == -np.inf)
