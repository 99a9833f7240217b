"""Zhao 2018's affine formation maneuver as a local law (quatform.control.local_laws.affine)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.control.local import LOCAL_CONTROLLERS, robot_rows
from quatform.control.local_laws.affine import AffineManeuver, affine_reference, example_reference
from quatform.control.networked import NetworkedController
from quatform.errors import InvalidInputError, ShapeError
from quatform.network import Links
from quatform.network.stress import Stress, zhao2018_example
from quatform.robots import HolonomicRobot, Team
from quatform.sim import simulate
from quatform.sim.plants.kinematic import KinematicTeam

DT = 0.01
EX = zhao2018_example()
S = Stress(EX.nominal, EX.edges)
N = 7
FOLLOWERS = [3, 4, 5, 6]
TEAM = Team.uniform(HolonomicRobot(max_speed=100.0), N, common_limit=False)


def _x0(batch=()):
    x = np.zeros((N, 4))
    x[:, :2] = EX.initial
    return np.broadcast_to(x.reshape(-1), tuple(batch) + (4 * N,)).copy()


def _run(links, times, batch=(), backend=simulate):
    ref, _ = example_reference(EX, times, S)
    ctrl = NetworkedController(AffineManeuver(), TEAM, links, DT)
    log = backend(KinematicTeam(TEAM), ctrl, ref, times, _x0(batch))
    return log


def _errors(log, times):
    """Stacked followers' error to A(t) p̄ + b(t) ``(T,)``, m, and the z excursion."""
    x = np.asarray(log.channels["state"].data).reshape(len(times), N, 4)
    p, _ = EX.targets(times)
    return np.linalg.norm(x[:, FOLLOWERS, :2] - p[:, FOLLOWERS], axis=(1, 2)), np.max(np.abs(x[..., 2]))


def test_registered():
    assert LOCAL_CONTROLLERS["affine-maneuver"] is AffineManeuver


def test_zhao_example_converges_through_the_maneuver_with_perfect_links():
    times = np.arange(int(round(EX.duration_s / DT)) + 1) * DT
    log = _run(Links(S.graph(), max_age_s=0.5), times)
    err, z = _errors(log, times)
    assert err[0] == pytest.approx(np.sqrt(10.0))      # Zhao's offsets of the followers
    assert np.max(err) <= err[0] + 1e-9                 # the peak is the start
    assert np.max(err[times >= 10.0]) < 0.3             # measured 0.261 m during the maneuver
    assert err[-1] < 1e-5                               # measured 1.5e-6 m after the 10 s hold
    assert z == 0.0
    assert np.all(np.asarray(log.channels["missing"].data) == 0.0)
    te = np.asarray(log.channels["target_error"].data)[-1].reshape(N)
    assert np.max(te) < 1e-5


def test_zhao_example_stays_bounded_with_delay_and_loss():
    times = np.arange(int(round(EX.duration_s / DT)) + 1) * DT
    log = _run(Links(S.graph(), delay_s=0.05, drop=0.1, max_age_s=0.5, seed=1), times)
    err, _ = _errors(log, times)
    assert np.all(np.isfinite(err))
    assert np.max(err[times >= 10.0]) < 2.5             # measured 1.93 m
    assert err[-1] < 0.01                               # measured 1.7e-3 m
    net = np.asarray(log.channels["network"].data).sum(axis=0)
    assert net[1] > 0.05 * net[0]                       # about 10 % of the messages lost


def _inbox(rng, batch=(), drop=0.3):
    """A random inbox of the example's graph: every stress neighbour a slot, some invalid."""
    rows = S.rows()
    W = int(np.max(np.sum(rows != 0, axis=1))) + 1
    senders = -np.ones((N, W), dtype=np.int64)
    for i in range(N):
        nb = np.flatnonzero(rows[i])
        senders[i, :len(nb)] = nb
    shape = tuple(batch) + (N, W)
    valid = (senders >= 0) & (rng.random(shape) > drop)
    return {"senders": senders, "messages": np.where(valid[..., None], rng.normal(size=shape + (6,)), 0.0),
            "stamps": np.where(valid, -rng.random(shape) * 0.1, -np.inf), "valid": valid,
            "weights": (senders >= 0).astype(float)}


def _reference(rng, batch=()):
    p, v = EX.targets(3.0)
    ref = affine_reference(S, EX.leaders, p[None], v[None])(0)
    ref["target"] = ref["target"] + rng.normal(size=tuple(batch) + (N, 3))
    return ref


def test_rows_depend_on_their_own_row_only():
    rng = np.random.default_rng(4)
    law = AffineManeuver(gain=1.5, leader_gain=2.0, relay=0.7)
    own, state = rng.normal(size=(2, N, 3)), rng.normal(size=(2, N, 3))
    box, ref = _inbox(rng, (2,)), law.reference_arrays(_reference(rng, (2,)), N)
    full = law.tick(state, own, box, ref, 0.0)
    msg = law.message(state, own, ref, 0.0)
    for rows in ([0], [4], [6, 1]):
        r = np.array(rows)
        sub_box = {k: robot_rows(v, r, 3 if k == "messages" else 2) for k, v in box.items()}
        sub = law.tick(robot_rows(state, r, 2), robot_rows(own, r, 2), sub_box, robot_rows(ref, r, 2), 0.0)
        assert np.array_equal(sub.u, full.u[:, r])
        assert np.array_equal(sub.signals["missing"], full.signals["missing"][:, r])
        assert np.array_equal(law.message(robot_rows(state, r, 2), robot_rows(own, r, 2), robot_rows(ref, r, 2), 0.0),
                              msg[:, r])


def test_missing_messages_give_finite_commands_and_a_follower_holds_still():
    rng = np.random.default_rng(5)
    law = AffineManeuver()
    ref = law.reference_arrays(_reference(rng), N)
    box = _inbox(rng, drop=0.0)
    own, state = rng.normal(size=(N, 3)), rng.normal(size=(N, 3))
    box["valid"] = box["valid"].copy()
    box["valid"][4, 0] = False                           # follower 5 lost a neighbour
    box["valid"][0, :] = False                           # leader 1 hears nobody
    out = law.tick(state, own, box, ref, 0.0)
    assert np.all(np.isfinite(out.u)) and np.all(out.code == 0)
    assert np.array_equal(out.u[4], np.zeros(3))
    assert np.allclose(out.u[0], ref["target_rate"][0] + (ref["target"][0] - own[0]))
    missing = out.signals["missing"][:, 0]
    assert missing[4] == 1.0 and missing[0] == np.count_nonzero(S.rows()[0])
    assert np.all(missing[[3, 5, 6]] == 0.0) and np.all(np.linalg.norm(out.u[[3, 5, 6]], axis=1) > 0.0)
    nothing = dict(box, valid=np.zeros_like(box["valid"]))
    out = law.tick(state, own, nothing, ref, 0.0)
    assert np.all(np.isfinite(out.u)) and np.all(out.u[FOLLOWERS] == 0.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), shift=st.lists(st.floats(-50, 50), min_size=3, max_size=3))
def test_followers_commands_do_not_depend_on_the_frames_origin(seed, shift):
    """Zhao's law uses relative positions only: translating every robot and message leaves a
    follower's command (tolerance by the positions' size)."""
    rng = np.random.default_rng(seed)
    law = AffineManeuver()
    ref = law.reference_arrays(_reference(rng), N)
    box = _inbox(rng)
    own, state = rng.normal(size=(N, 3)), rng.normal(size=(N, 3))
    c = np.array(shift)
    moved = dict(box, messages=np.where(box["valid"][..., None], box["messages"] + np.r_[c, 0, 0, 0], 0.0))
    a = law.tick(state, own, box, ref, 0.0).u[FOLLOWERS]
    b = law.tick(state, own + c, moved, ref, 0.0).u[FOLLOWERS]
    assert np.allclose(a, b, rtol=0.0, atol=1e-12 * (1.0 + np.max(np.abs(c))) * 10)


def test_a_follower_with_no_positive_gamma_and_other_bad_references_are_one_line():
    rng = np.random.default_rng(6)
    law = AffineManeuver()
    ref = _reference(rng)
    bad = dict(ref, stress=-ref["stress"])
    with pytest.raises(InvalidInputError, match=r"follower\(s\) 4, 5, 6, 7 have γ_i = sum_j ω_ij <= 0") as e:
        law.reference_arrays(bad, N)
    assert "\n" not in str(e.value)
    with pytest.raises(ShapeError, match="'target' must have shape"):
        law.reference_arrays(dict(ref, target=np.zeros((N, 2))), N)
    with pytest.raises(InvalidInputError, match="needs 'stress'"):
        law.reference_arrays({k: v for k, v in ref.items() if k != "stress"}, N)
    with pytest.raises(InvalidInputError, match="1 \\(a leader\\) or 0"):
        law.reference_arrays(dict(ref, leader=np.full((N, 1), 0.5)), N)
    with pytest.raises(InvalidInputError, match="NaN"):
        law.reference_arrays(dict(ref, target_rate=np.full((N, 3), np.nan)), N)
    with pytest.raises(InvalidInputError, match="gain = 0 must be a positive number"):
        AffineManeuver(gain=0)
    with pytest.raises(InvalidInputError, match="relay = 1.5 must be a number in"):
        AffineManeuver(relay=1.5)
    with pytest.raises(InvalidInputError, match="leaders"):
        affine_reference(S, [0, 1], np.zeros((1, N, 2)), np.zeros((1, N, 2)))


def test_a_generic_stress_needs_the_relay_step_and_converges_with_it():
    """On a generic configuration the followers' Jacobi relay (β = 1) may not contract; the
    reference refuses it in one line, and the step of Stress.relay_step converges."""
    p = np.random.default_rng(0).normal(size=(8, 2))
    stress = Stress(p, np.argwhere(np.triu(np.ones((8, 8)), 1)))
    lead = [0, 1, 2]
    beta = stress.relay_step(lead)
    assert stress.relay_factor(lead) > 1.0 > stress.relay_factor(lead, beta)     # 1.062 and 0.976
    dt, times = 0.01, np.arange(2001) * 0.01
    targets = np.broadcast_to(p, (len(times), 8, 2))
    with pytest.raises(InvalidInputError, match=r"relayed velocities do not contract .* give AffineManeuver\(relay="):
        affine_reference(stress, lead, targets, 0.0 * targets)
    team = Team.uniform(HolonomicRobot(max_speed=100.0), 8, common_limit=False)
    x0 = np.zeros((8, 4))
    x0[:, :2] = p + np.r_[np.zeros((3, 2)), np.random.default_rng(9).normal(size=(5, 2))]
    ctrl = NetworkedController(AffineManeuver(relay=beta), team, Links(stress.graph(), max_age_s=0.5), dt)
    log = simulate(KinematicTeam(team), ctrl, affine_reference(stress, lead, targets, 0.0 * targets, beta), times,
                   x0.reshape(-1))
    x = np.asarray(log.channels["state"].data).reshape(len(times), 8, 4)[..., :2]
    err = np.linalg.norm(x[:, 3:] - p[3:], axis=(1, 2))
    assert err[-1] < 1e-6 * err[0]                                               # measured 1.6e-9 relative


def test_jax_equals_numpy_batched_with_delay_and_loss():
    pytest.importorskip("jax")
    from quatform.sim.loop import simulate_jax

    times = np.arange(150) * DT
    links = Links(S.graph(), delay_s=0.03, jitter_s=0.02, drop=0.2, max_age_s=0.2, seed=2)
    a = _run(links, times, batch=(2,))
    b = _run(links, times, batch=(2,), backend=simulate_jax)
    for k in a.channels:
        x, y = np.asarray(a.channels[k].data, dtype=float), np.asarray(b.channels[k].data, dtype=float)
        assert np.allclose(x, y, rtol=0.0, atol=1e-9 * (1.0 + np.max(np.abs(x)))), k
