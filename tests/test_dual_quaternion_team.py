"""DualQuaternionTeam: seed 000 §3.3 for N robots of any point kinds."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import assert_metrics_equal
from quatform.control import TABLE1, DualQuaternionController
from quatform.control.base import Reference
from quatform.control.team import TeamController, team_lyapunov
from quatform.errors import (
    DegenerateInputError,
    InvalidInputError,
    NonUnitError,
    ShapeError,
    UnreachableError,
)
from quatform.formations import DualQuaternionPair, RobotLayout, RobotSpace
from quatform.formations.dual_quaternion_team import DualQuaternionTeam
from quatform.formations.testing import (
    check_formation,
    cluster_distance,
    robot_distance,
)
from quatform.robots import HolonomicRobot, Team

MIXED = RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw"))
MIXED2 = RobotLayout(("pose", "xyz", "pose", "xy_yaw", "xyz"))


def _dq_conj(a):
    return a * np.array([1.0, -1, -1, -1, 1, -1, -1, -1])


def _dqmul(a, b):
    from quatform.algebra import dqmul

    return dqmul(a, b)


# -- the formation contract -------------------------------------------------------------------------
@pytest.mark.parametrize("F", [DualQuaternionTeam(2), DualQuaternionTeam(3), DualQuaternionTeam(4),
                               DualQuaternionTeam(10), DualQuaternionTeam(layout=MIXED),
                               DualQuaternionTeam(layout=MIXED2), DualQuaternionTeam(layout=RobotLayout(("xyz",) * 3)),
                               DualQuaternionTeam(2, shape="relative")],
                         ids=["frame-2", "frame-3", "frame-4", "frame-10", "mixed", "mixed-pose", "xyz-3", "relative-2"])
def test_check_formation(F):
    check_formation(F, np.random.default_rng(14))


def test_default_is_n_four_dof_robots_and_the_frame_shape():
    F = DualQuaternionTeam(3)
    assert F.layout == RobotLayout.uniform("xyz_yaw", 3) and F.shape == "frame"
    assert F.n_c == 32 and F.n_r == 12
    assert [g.role for g in F.law_groups] == ["pose"] and F.law_groups[0].index.shape == (4, 8)
    assert len(F.sign_free) == 4
    R = DualQuaternionTeam(2, shape="relative")
    assert [g.role for g in R.law_groups] == ["pose", "relative-pose"] and R.sign_free == (slice(0, 8),)


# -- what the description computes -------------------------------------------------------------------
def test_frame_shape_is_the_pose_of_each_robot_in_the_formation_frame():
    rng = np.random.default_rng(1)
    F = DualQuaternionTeam(layout=MIXED)
    r = F.sample_robot_state(rng, (5,))
    c = F.forward(r)
    L = F.layout
    p = L.positions(r)
    from quatform.algebra import dq_from_pose, pose_from_dq

    qc, xc = pose_from_dq(c[..., :8])
    assert np.allclose(xc, p.mean(axis=-2), atol=1e-12)  # the centroid (seed 000 §5)
    assert np.allclose(np.abs(np.sum(qc * L.orientations(r)[..., 0, :], -1)), 1.0, atol=1e-12)  # first pose robot
    blocks = c[..., 8:].reshape(5, 4, 8)
    yaw = dict(zip((0, 1, 3), (r[:, i] for i in L.yaw_indices)))
    for i in range(4):
        q = L.orientations(r)[:, 0, :] if i == 2 else np.stack(
            [np.cos(yaw[i] / 2), 0 * yaw[i], 0 * yaw[i], np.sin(yaw[i] / 2)], -1)
        want = _dqmul(_dq_conj(c[..., :8]), dq_from_pose(q, p[:, i, :]))  # qhat_ci = qhat_c* qhat_i
        got = blocks[:, i]
        assert np.max(np.minimum(np.max(np.abs(want - got), -1), np.max(np.abs(want + got), -1))) < 1e-12


def test_yaw_mean_is_the_mean_of_the_real_yaws():
    F = DualQuaternionTeam(3)
    r = np.array([0.0, 0, 0, 3.0, 1, 0, 0, 3.2, 0, 1, 0, -3.0 + 2 * math.pi])  # wound: the real mean is used
    c = F.forward(r)
    th = (3.0 + 3.2 + (2 * math.pi - 3.0)) / 3
    assert np.allclose(c[:4], [math.cos(th / 2), 0, 0, math.sin(th / 2)], atol=1e-15)


# -- N = 2 is the seed ----------------------------------------------------------------------
def _pair_states(rng, n=200):
    r = DualQuaternionPair().sample_robot_state(rng, (n,))
    r[:, [3, 7]] += 2 * math.pi * rng.integers(-3, 4, (n, 2))
    return r


def test_the_pair_is_the_relative_shape_with_the_pair_chart():
    """DualQuaternionPair is DualQuaternionTeam(2, shape="relative", chart="pair"): one implementation,
    the seed's state and names; the relative shape is two xyz_yaw robots only."""
    P = DualQuaternionPair()
    assert isinstance(P, DualQuaternionTeam) and (P.shape, P.chart_kind, P.layout.kinds) == (
        "relative", "pair", ("xyz_yaw", "xyz_yaw"))
    assert P.names == DualQuaternionTeam(2, shape="relative").names and P.n_c == 16 and P.component_kernels
    assert P.names[8:10] == ("qhat_s_rw", "qhat_s_rx") and not P.team
    with pytest.raises(InvalidInputError, match="two xyz_yaw robots"):
        DualQuaternionTeam(layout=RobotLayout(("xy_yaw", "xyz_yaw")), shape="relative")


def test_frame_shape_at_n2_relates_to_eqs_26_27():
    """``qhat_c`` is the pair's; ``qhat_c2* qhat_c1 = qhat_2* qhat_1 = qhat_s`` (eq. (27)), the
    branch (sign) included, since both are built on the robots' real yaws."""
    rng = np.random.default_rng(3)
    F, P = DualQuaternionTeam(2), DualQuaternionPair()
    r = _pair_states(rng)
    c, cp = F.forward(r), P.forward(r)
    assert np.max(np.abs(c[:, :8] - cp[:, :8])) < 1e-12
    qs = _dqmul(_dq_conj(c[:, 16:24]), c[:, 8:16])
    assert np.max(np.abs(qs - cp[:, 8:16])) < 1e-12


def _pair_reference(name, duration=None):
    from quatform.scenarios import load_scenario

    sc = load_scenario(name)
    if duration is not None:
        sc = dataclasses.replace(sc, duration_s=duration)
    return sc


@pytest.mark.parametrize("name", ["mas-kitts-spiral", "mas-kitts-helix"])
def test_team_controller_commands_equal_the_pair_controllers_along_the_whole_reference(name):
    """Every reference sample of the scenario, measured robots displaced and wound: the team
    controller on DualQuaternionTeam(2, shape="relative") commands what the pair's
    dual-quaternion controller does (one batched call each; the closed loop is then equal step
    by step)."""
    sc = _pair_reference(name)
    e, ed = sc.path(sc.times)
    Fp = DualQuaternionTeam(2, shape="relative", chart="pair")
    c, cd = Fp.from_chart(e, ed)
    rng = np.random.default_rng(4)
    r = RobotSpace().from_chart(e) + 0.3 * rng.normal(size=(len(e), 8))
    r[:, [3, 7]] += 2 * math.pi * rng.integers(-2, 3, (len(e), 2))
    k_dw = sc.gains["dual-quaternion"]["k_dw"]
    team = TeamController(Fp, {"k_dw": k_dw}, sc.team, feedforward=sc.feedforward, name="dual-quaternion")
    pair = DualQuaternionController(k_dw=k_dw, team=sc.team, feedforward=sc.feedforward)
    a = team.update(0.0, r, Reference(c, cd))
    b = pair.update(0.0, r, Reference(c, cd), pair.init((len(e),)))
    assert np.max(np.abs(a.u - b.u)) < 1e-12
    assert np.max(np.abs(a.signals["cluster"] - b.signals["cluster"])) < 1e-12


def test_spiral_metrics_equal_the_pair_run():
    """The closed loop of the first 12 s of the spiral (the yaw turn): every metric within 1e-9 of its scale
    (the full spiral and helix: docs/derivations.md, "The dual-quaternion team")."""
    from quatform.scenarios.team import TEAM

    sc = _pair_reference("mas-kitts-spiral", 12.0)
    ref_exp = TEAM.experiment(sc, controller="dual-quaternion")
    m1 = ref_exp.metrics(ref_exp.run())
    ctrl = TeamController(DualQuaternionTeam(2, shape="relative", chart="pair"),
                          {"k_dw": TABLE1["dual-quaternion"]["k_dw"]}, sc.team, feedforward=sc.feedforward,
                          name="dual-quaternion")
    exp = TEAM.experiment(sc, controller=ctrl)
    m2 = exp.metrics(exp.run())
    assert (m1["formation"], m2["formation"]) == ("dual-quaternion", "dual-quaternion-team")
    assert_metrics_equal(m1, m2, skip=("formation",))


# -- relative shape for N >= 3: refused (one state would name N formations) -----------------------------
def test_relative_shape_is_the_pair_only():
    """For N robots eq. (27)'s relative shape names N formations turned by 4 pi j / N (a zero
    error at a turned twin), so it is refused beyond two robots."""
    for n in (3, 4, 10):
        with pytest.raises(InvalidInputError, match="shape='frame'"):
            DualQuaternionTeam(n, shape="relative")


# -- special sets at the point and near it, batch and single -----------------------------------
@pytest.mark.parametrize("F", [DualQuaternionTeam(3), DualQuaternionTeam(layout=MIXED2), DualQuaternionTeam(4)],
                         ids=["frame-3", "mixed-pose", "frame-4"])
def test_special_sets_regular_continuous_batch_equals_single(F):
    names = {s.name for s in F.special_sets()}
    assert {"vertical-axis", "collinear", "anti-x"} <= names
    if F.layout.n == 3:
        assert {"half-turn-yaws", "q-vs-minus-q", "wound-yaws"} <= names
    for sset in F.special_sets():
        states = {eps: sset.states(np.random.default_rng(7), 4, eps) for eps in (0.0, 1e-9, 1e-6)}
        c0 = F.forward(states[0.0])
        for eps, r in states.items():
            c = F.forward(r)
            assert np.all(np.isfinite(c))
            assert np.max(robot_distance(F, F.inverse(c), r)) < 1e-12, (sset.name, eps)
            # continuous: the same draw eps away moves the state by O(eps)
            assert np.max(np.abs(c - c0)) < 100 * eps + 1e-12, (sset.name, eps)
            v = np.linspace(-1, 1, r.size).reshape(r.shape)
            cd, J = F.cluster_rate(r, v), F.jacobian(r)
            assert np.all(np.isfinite(J)) and np.all(F.singularity_measure(r) > 1e-3), (sset.name, eps)
            assert np.max(np.abs(F.robot_rate(c, cd, r=r) - v)) < 1e-10
            for k in range(4):
                assert np.max(np.abs(F.forward(r[k]) - c[k])) < 1e-14
                assert np.max(np.abs(F.cluster_rate(r[k], v[k]) - cd[k])) < 1e-12
                assert np.max(robot_distance(F, F.inverse(c[k]), r[k])) < 1e-12


def test_q_versus_minus_q_of_every_block_is_the_same_robots():
    rng = np.random.default_rng(8)
    F = DualQuaternionTeam(layout=MIXED)
    r = F.sample_robot_state(rng, (10,))
    c = F.forward(r)
    signs = np.repeat(rng.choice([-1.0, 1.0], (10, 5)), 8, axis=-1)
    assert np.max(robot_distance(F, F.inverse(signs * c), r)) < 1e-12
    rows = F.layout.orientation_index
    flipped = r.copy()
    flipped[:, rows] *= -1  # the pose robot's quaternion data negated: the same robots
    assert np.max(cluster_distance(F, F.forward(flipped, near_c=c), c)) < 1e-12


# -- zero formation error <=> robots at the reference ----------------------------------------
@pytest.mark.parametrize("layout", [RobotLayout.uniform("xyz_yaw", 4), MIXED], ids=["4", "mixed"])
def test_zero_formation_error_iff_robots_at_the_reference(layout):
    rng = np.random.default_rng(9)
    F = DualQuaternionTeam(layout=layout)
    team = Team(tuple(HolonomicRobot() if k == "xyz_yaw" else None for k in layout.kinds)) \
        if set(layout.kinds) == {"xyz_yaw"} else None
    ctrl = TeamController(F, {"k_dw": [1.0, 1.0, 1.0]}, team) if team else None
    r_des = F.sample_robot_state(rng, (50,))
    c_des = F.forward(r_des)
    yi = list(F.layout.yaw_indices)
    wound = r_des.copy()
    wound[:, yi] += 2 * math.pi * rng.integers(-5, 6, (50, len(yi)))
    c = F.forward(wound, near_c=c_des)
    assert np.max(cluster_distance(F, c, c_des)) < 1e-12  # at the reference, any lift: zero error
    if ctrl is not None:
        assert np.max(team_lyapunov(ctrl, c, c_des)) < 1e-12
    # the half-turn twin (formation turned pi about the vertical through its centroid, yaws + pi)
    # and small displacements are not zero error
    L = F.layout
    p = L.positions(r_des)
    xc = p.mean(axis=1, keepdims=True)
    twin_p = xc + (p - xc) * np.array([-1.0, -1.0, 1.0])
    q = L.orientations(r_des)
    half = np.array([0.0, 0.0, 0.0, 1.0])
    from quatform.formations import geometry as g

    twin = L.compose(twin_p, L.yaws(r_des) + math.pi, g.mul(half, q) if len(q[0]) else None)
    moved = r_des + 1e-3 * rng.normal(size=r_des.shape)
    rows = L.orientation_index
    moved[:, rows] /= np.linalg.norm(moved[:, rows], axis=-1, keepdims=True)
    for other in (twin, moved):
        ct = F.forward(other, near_c=c_des)
        assert np.min(cluster_distance(F, ct, c_des)) > 1e-5
        assert np.min(robot_distance(F, F.inverse(ct), r_des)) > 1e-5


# -- the controller ----------------------------------------------------------------------------
def _closed_loop(N, rng, steps, B=16, k=2.0, dt=2e-3, yaw_spread=3.1):
    F = DualQuaternionTeam(N)
    team = Team(tuple(HolonomicRobot(max_speed=1e6, max_yaw_rate=1e6) for _ in range(N)))
    ctrl = TeamController(F, {"k_dw": [k, k, k]}, team, feedforward=False)
    r_des = F.sample_robot_state(rng, (B,))
    c_des = F.forward(r_des)
    yi = list(F.layout.yaw_indices)
    r = r_des.copy()
    r[:, yi] += rng.uniform(-yaw_spread, yaw_spread, (B, N))
    r += 0.3 * rng.normal(size=r.shape)
    ref = Reference(c_des, np.zeros_like(c_des))
    V, switch = [], []
    err_prev = None
    for _ in range(steps):
        step = ctrl.update(0.0, r, ref)
        V.append(team_lyapunov(ctrl, step.signals["cluster"], c_des))
        err = (r[:, yi] - r_des[:, yi] + math.pi) % (2 * math.pi) - math.pi
        switch.append(np.zeros(B, bool) if err_prev is None else np.any(np.abs(err - err_prev) > math.pi, axis=-1))
        err_prev = err
        r = r + dt * step.u
    return F, ctrl, np.array(V), np.array(switch), r, r_des


@pytest.mark.parametrize("N", [3, 4, 10])
def test_lyapunov_29_decreases_along_the_closed_loop_except_at_branch_switches(N):
    """Eq. (29) summed over the N + 1 blocks (control.team.team_lyapunov), constant reference, no
    feed-forward, Euler steps of 2 ms (k dt = 0.01): it never rises in a step, except in the step where a
    robot's yaw error passes pi (the measured state moves to the other lift: the formation yaw
    jumps by 2 pi / N); every run approaches the reference."""
    _, _, V, switch, _, _ = _closed_loop(N, np.random.default_rng(10 + N), 700, k=5.0)
    rise = np.diff(V, axis=0) > 1e-13
    assert not np.any(rise & ~switch[1:])
    assert np.all(V[-1] < 0.01 * V[0])


def test_controller_batch_equals_single():
    rng = np.random.default_rng(11)
    F = DualQuaternionTeam(4)
    ctrl = TeamController(F, {"k_dw": TABLE1["dual-quaternion"]["k_dw"]}, None)
    r = F.sample_robot_state(rng, (6,))
    c_des, cd = F.forward(F.sample_robot_state(rng, (6,))), 0.1 * rng.normal(size=(6, F.n_c))
    batch = ctrl.update(0.0, r, Reference(c_des, cd))
    for k in range(6):
        one = ctrl.update(0.0, r[k], Reference(c_des[k], cd[k]))
        assert np.max(np.abs(one.u - batch.u[k])) < 1e-12


def test_rate_maps_cost_a_constant_number_of_numpy_calls():
    """O(N): the rate maps on 10 and on 1000 robots make the same NumPy calls (no Python loop
    over robots), and no dense matrix: the cost per robot at N = 1000 is not above that at 10."""
    import time

    out = {}
    for N in (10, 1000):
        F = DualQuaternionTeam(N)
        rng = np.random.default_rng(12)
        grid = np.stack(np.meshgrid(np.arange(10.0), np.arange(N // 10), [0.0], indexing="ij"), -1).reshape(-1, 3)
        r = F.layout.compose(grid + 0.1 * rng.normal(size=(N, 3)), rng.uniform(-20, 20, N))
        c = F.forward(r)
        v = rng.normal(size=r.shape)
        cd = F.cluster_rate(r, v, near_c=c)
        best = []
        for _ in range(20):
            t0 = time.perf_counter()
            F.forward(r, near_c=c)
            F.robot_rate(c, cd, r=r)
            best.append(time.perf_counter() - t0)
        out[N] = min(best)
    assert out[1000] / 1000 < out[10] / 10


# -- bad input ---------------------------------------------------------------------------------
def test_bad_input_one_line_each():
    with pytest.raises(InvalidInputError, match="exactly one"):
        DualQuaternionTeam()
    with pytest.raises(InvalidInputError, match="n >= 2"):
        DualQuaternionTeam(1)
    with pytest.raises(InvalidInputError, match="shape 'ring' unknown"):
        DualQuaternionTeam(3, shape="ring")
    with pytest.raises(InvalidInputError, match="xyz_yaw, pose.*shape='frame'"):
        DualQuaternionTeam(layout=RobotLayout(("xyz_yaw", "pose")), shape="relative")
    with pytest.raises(InvalidInputError, match="chart='pair'"):
        DualQuaternionTeam(3, chart="pair")
    with pytest.raises(ShapeError, match="shape \\(..., 3, 3\\)"):
        DualQuaternionTeam(3, template=np.zeros((4, 3)))
    with pytest.raises(DegenerateInputError, match="robots 1 and 2 on each other"):
        DualQuaternionTeam(3, template=[[0, 0, 0], [0, 0, 0], [1, 0, 0]])
    F = DualQuaternionTeam(3)
    r = np.array([0.0, 0, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0])
    with pytest.raises(DegenerateInputError, match="robots 1 and 2 coincide"):
        F.forward(r)
    c = F.forward(np.array([0.0, 0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0]))
    bad = c.copy()
    bad[8:16] = c[16:24]  # robot 1's pose in the frame := robot 2's: the two coincide
    with pytest.raises(DegenerateInputError, match="coincide"):
        F.inverse(bad)
    tilted = c.copy()
    tilted[:4] = [math.cos(0.1), math.sin(0.1), 0, 0]
    tilted[4:8] = 0.0
    with pytest.raises(UnreachableError, match="tilts"):
        F.inverse(tilted)
    with pytest.raises(NonUnitError, match="unit dual quaternion"):
        F.inverse(2 * c)
    with pytest.raises(InvalidInputError, match="shape"):
        F.forward(np.zeros(8))
    for err in (DegenerateInputError, UnreachableError, NonUnitError):
        try:
            {DegenerateInputError: lambda: F.forward(r), UnreachableError: lambda: F.inverse(tilted),
             NonUnitError: lambda: F.inverse(2 * c)}[err]()
        except err as e:
            assert "\n" not in str(e)


def test_lyapunov_29_rises_where_eq_33_drops_its_term_as_for_the_pair():
    """Seed 000 eq. (33) drops the scalar ``d0`` of the error's dual part: for a rotation error
    beyond 90 deg with a translation error along its axis above 2 sqrt 2 m, eq. (29) rises at
    first (the pair's counterexample, docs/derivations.md, "The two-robot formations and controllers (seed 000)" item 4, on the team's qhat_c: a rigid
    turn of 166 deg about the vertical and 4 m up, Table 1 gains: 2.030 -> 2.264), and the loop
    still converges; 2 m up it falls in every step."""
    F = DualQuaternionTeam(3)
    team = Team(tuple(HolonomicRobot(max_speed=1e6, max_yaw_rate=1e6) for _ in range(3)))
    ctrl = TeamController(F, {"k_dw": TABLE1["dual-quaternion"]["k_dw"]}, team, feedforward=False)
    r_des = np.array([1.0, 0, 0, 0, -0.5, 0.866, 0, 0, -0.5, -0.866, 0, 0])
    c_des = F.forward(r_des)
    L = F.layout
    p = L.positions(r_des)
    a = math.radians(166.0)
    R = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    out = {}
    for dz in (4.0, 2.0):
        r = L.compose((p - p.mean(0)) @ R.T + p.mean(0) + [0, 0, dz], L.yaws(r_des) + a)
        V = []
        for _ in range(300):
            s = ctrl.update(0.0, r, Reference(c_des, np.zeros_like(c_des)))
            V.append(float(team_lyapunov(ctrl, s.signals["cluster"], c_des)))
            r = r + 1e-3 * s.u
        out[dz] = np.array(V)
    assert abs(out[4.0][0] - 2.0297) < 1e-3 and abs(out[4.0].max() - 2.2636) < 1e-3
    assert out[4.0][-1] < 0.15 * out[4.0][0]
    assert not np.any(np.diff(out[2.0]) > 1e-13) and out[2.0][-1] < 0.1 * out[2.0][0]


@settings(max_examples=25, deadline=None)
@given(kinds=st.lists(st.sampled_from(["xy_yaw", "xyz_yaw", "pose", "xyz"]), min_size=2, max_size=6),
       seed=st.integers(0, 2**31 - 1))
def test_any_mix_round_trips_and_rates_invert(kinds, seed):
    """Any mix of point kinds: ``inverse(forward(r)) = r`` without a hint (yaws mod 2 pi, wound by up
    to 40 rad), ``forward(r wound, near_c=c) = c`` up to block signs, and ``robot_rate`` inverts
    ``cluster_rate`` (the inverse Jacobian has full rank everywhere)."""
    rng = np.random.default_rng(seed)
    F = DualQuaternionTeam(layout=RobotLayout(tuple(kinds)))
    r = F.sample_robot_state(rng, (4,))
    c = F.forward(r)
    assert np.max(robot_distance(F, F.inverse(c), r)) < 1e-10
    wound = r.copy()
    yi = list(F.layout.yaw_indices)
    wound[:, yi] += 2 * math.pi * rng.integers(-6, 7, (4, len(yi)))
    assert np.max(cluster_distance(F, F.forward(wound, near_c=c), c)) < 1e-10
    v = rng.normal(size=r.shape)
    cd = F.cluster_rate(wound, v, near_c=c)
    assert np.max(np.abs(F.robot_rate(F.forward(wound, near_c=c), cd, r=wound) - v)) < 1e-9


def test_a_chart_whose_robots_coincide_is_refused():
    F = DualQuaternionTeam(3)
    e = F.chart.from_robots(np.array([0.0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0]))
    e[F.chart.shape_index[1]] = e[F.chart.shape_index[0]]
    with pytest.raises(DegenerateInputError, match="robots 1 and 2 coincide"):
        F.from_chart(e)


def test_another_lift_at_the_reference_is_an_equilibrium_so_forward_winds_onto_the_reference():
    """Robots at the reference with one yaw wound a turn: ``forward`` of those real yaws is another
    state (``q_c`` turned by 2 pi / N), and eq. (28) on it with ``K = k I`` commands robot rates
    that cancel exactly (docs/derivations.md, "The dual-quaternion team" item 5); ``forward(r, near_c=c_des)``
    takes the reference's lift, whose error is zero."""
    from quatform.control.laws import dual_quaternion_feedback

    F = DualQuaternionTeam(3)
    r = F.sample_robot_state(np.random.default_rng(15), ())
    c_des = F.forward(r)
    wound = r.copy()
    wound[3] += 2 * math.pi
    c = F.forward(wound)
    assert np.min(cluster_distance(F, c, c_des)) > 0.1
    B, Bd = c.reshape(4, 8), c_des.reshape(4, 8)
    rate = np.concatenate([dual_quaternion_feedback(tuple(B[k]), tuple(Bd[k]), (0.0,) * 8, (2.0,) * 3, 0.0)[1]
                           for k in range(4)])
    assert np.max(np.abs(F.robot_rate(c, rate, r=wound))) < 1e-12
    assert np.max(cluster_distance(F, F.forward(wound, near_c=c_des), c_des)) < 1e-12
