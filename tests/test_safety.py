"""The separation barrier certificates (Wang, Ames, Egerstedt 2017) and SafeController."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import BACKEND_TOL as TOL
from hypothesis import given, settings, strategies as st
from scipy.optimize import minimize, nnls

from quatform.control import DualQuaternionController, Reference
from quatform.control.safety import SafeController, SafeState, SeparationBarrier
from quatform.errors import DegenerateInputError, InvalidInputError
from quatform.formations import RobotSpace
from quatform.formations.layout import RobotLayout
from quatform.robots import Bebop, FreeBodyRobot, HolonomicRobot, Pioneer, PlanarHolonomicRobot, Team
from quatform.sim import simulate
from quatform.sim.plants import KinematicTeam

D_MIN = 0.3
DT = 0.02
GAMMA = 10.0  # gamma dt = 0.2
MODELS = {"holonomic": HolonomicRobot(1.0, 2.0), "planar": PlanarHolonomicRobot(1.0, 2.0),
          "pioneer": Pioneer(max_v=0.75)}


def start_state(model, n, rng, spread):
    """Robots at random, every pair at least 1.2 d_min apart."""
    pts = []
    while len(pts) < n:
        p = rng.uniform(-spread, spread, 3)
        if model.point_kind != "xyz_yaw":
            p[2] = 0.0
        if all(np.linalg.norm(p - q) >= 1.2 * D_MIN for q in pts):
            pts.append(p)
    pts = np.array(pts)
    yaw = rng.uniform(-np.pi, np.pi, n)
    if model.point_kind == "xyz_yaw":
        return np.concatenate([pts, yaw[:, None]], axis=1).ravel()
    return np.concatenate([pts[:, :2], yaw[:, None]], axis=1).ravel()


def nominal(team, x, kind, rng, goal=None):
    """Adversarial nominal commands, saturated by the team: every robot at full speed toward the
    centroid, toward its goal, or at random."""
    model = team.robots[0]
    n = len(team.robots)
    P = team.layout.positions(team.point(x))
    if kind == "random":
        V = rng.normal(size=(n, 3))
    else:
        target = P.mean(axis=0) if goal is None else goal
        V = target - P
    if model.point_kind != "xyz_yaw":
        V[:, 2] = 0.0
    V *= 5.0 / np.maximum(np.linalg.norm(V, axis=1, keepdims=True), 1e-12)  # beyond every limit
    yaw_rate = rng.uniform(-1, 1, n)
    if isinstance(model, Pioneer):
        u = model.commands_from_velocity(x.reshape(n, 3)[:, 2], V[:, :2])
    elif model.point_kind == "xyz_yaw":
        u = np.concatenate([V, yaw_rate[:, None]], axis=1)
    else:
        u = np.concatenate([V[:, :2], yaw_rate[:, None]], axis=1)
    return team.saturate(u.ravel())


def run(team, barrier, x, kind, steps, rng, goal=None):
    """Simulate with Team.step; the smallest separation over the run and the sampled-time check."""
    seps = []
    worst_ratio = np.inf
    layout = team.layout
    for _ in range(steps):
        u = nominal(team, x, kind, rng, goal)
        us, _ = barrier.filter(team, x, u)
        assert team.saturate(us) == pytest.approx(us, rel=1e-12, abs=1e-12)  # within the limits
        h0 = layout.separations(team.point(x)) ** 2 - D_MIN ** 2
        x = team.step(x, us, DT)
        h1 = layout.separations(team.point(x)) ** 2 - D_MIN ** 2
        seps.append(layout.min_separation(team.point(x)))
        # sampled time: h_{k+1} >= (1 - gamma dt) h_k for every pair
        worst_ratio = min(worst_ratio, float(np.min(h1 - (1 - GAMMA * DT) * h0)))
    return min(seps), worst_ratio, x


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("n", [2, 5, 30])
@pytest.mark.parametrize("kind", ["centroid", "random"])
def test_adversarial_commands_never_bring_two_robots_closer_than_the_minimum(name, n, kind):
    rng = np.random.default_rng(100 * n + len(name) + len(kind))
    model = MODELS[name]
    team = Team.uniform(model, n)
    barrier = SeparationBarrier(D_MIN, gamma=GAMMA, dt_s=DT)
    x = start_state(model, n, rng, spread=0.25 * np.sqrt(n) + 0.4)
    sep, ratio, _ = run(team, barrier, x, kind, 60 if n == 30 else 120, rng)
    assert sep >= D_MIN - 1e-9
    assert ratio >= -1e-9
    if kind == "centroid":
        assert sep < D_MIN + 0.01  # the commands did press the robots onto the barrier


@pytest.mark.parametrize("name", list(MODELS))
def test_two_robots_swapping_head_on_stop_apart(name):
    model = MODELS[name]
    team = Team.uniform(model, 2)
    p1, p2 = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    if model.point_kind == "xyz_yaw":
        x = np.r_[p1, 0.0, p2, np.pi]
    else:
        x = np.r_[p1[:2], 0.0, p2[:2], np.pi]
    goal = np.stack([p2, p1])
    barrier = SeparationBarrier(D_MIN, gamma=GAMMA, dt_s=DT)
    sep, ratio, x_end = run(team, barrier, x, "goal", 150, np.random.default_rng(1), goal=goal)
    assert sep >= D_MIN - 1e-9 and ratio >= -1e-9
    assert team.layout.min_separation(team.point(x_end)) < D_MIN + 0.05  # they did come close


def test_mixed_team_of_drones_free_bodies_and_ground_robots():
    rng = np.random.default_rng(3)
    team = Team((HolonomicRobot(1.0, 1.0), PlanarHolonomicRobot(1.0, 1.0), FreeBodyRobot(1.0, 1.0), Pioneer(),
                 Pioneer(point_kind="xy_yaw")) * 3)
    barrier = SeparationBarrier(D_MIN, gamma=GAMMA, dt_s=DT)
    parts = []
    for k, r in enumerate(team.robots):  # on a 5 x 3 grid 0.4 m apart, at heights within 5 cm
        xy = 0.4 * np.array([k % 5, k // 5], dtype=float) + rng.uniform(-0.02, 0.02, 2)
        parts.append({"xyz_yaw": np.r_[xy, 0.05, 0.0], "xy_yaw": np.r_[xy, 0.3], "xyz": np.r_[xy, 0.3],
                      "pose": np.r_[xy, 0.02, 1.0, 0, 0, 0]}[r.point_kind])
    x = np.concatenate(parts)
    assert team.layout.min_separation(team.point(x)) > D_MIN
    seps = []
    for _ in range(100):
        P = team.layout.positions(team.point(x))
        V = P.mean(axis=0) - P
        u_parts = []
        for r, xs, v in zip(team.robots, team.split(x), V):
            if isinstance(r, Pioneer):
                u_parts.append(r.commands_from_velocity(xs[2], v[:2]))
            elif isinstance(r, HolonomicRobot):
                u_parts.append(np.r_[v, 0.5])
            elif isinstance(r, PlanarHolonomicRobot):
                u_parts.append(np.r_[v[:2], 0.5])
            else:
                u_parts.append(np.r_[v, 0.3, -0.2, 0.1])
        u = team.saturate(5.0 * np.concatenate(u_parts))
        us, _ = barrier.filter(team, x, u)
        x = team.step(x, us, DT)
        seps.append(team.layout.min_separation(team.point(x)))
    assert D_MIN - 1e-9 <= min(seps) < D_MIN + 0.01
    q = x[team.state_slices[2]][3:]
    assert abs(np.linalg.norm(q) - 1) < 1e-12


def test_inactive_filter_returns_the_commands_bitwise():
    rng = np.random.default_rng(4)
    team = Team.uniform(HolonomicRobot(), 20)
    grid = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0)), -1).reshape(-1, 2) * 3.0
    x = np.concatenate([grid, np.ones((20, 1)), np.zeros((20, 1))], axis=1).ravel()
    u = team.saturate(rng.uniform(-1, 1, (3, team.n)))
    us, info = SeparationBarrier(0.5, gamma=2.0).filter(team, np.tile(x, (3, 1)), u)
    assert us is u and not info.active.any() and np.all(info.constraints == 0)
    np.testing.assert_allclose(info.min_separation, 3.0, rtol=1e-15)
    lost = np.tile(x, (2, 1))
    lost[0, 5] = np.nan
    close = team.saturate(np.tile(-np.sign(x) * 0.5, (2, 1)))
    lost[:, 4:6] = [[np.nan, 0.1], [0.0, 0.2]]  # world 0 lost, world 1: robot 2 beside robot 1
    us2, info2 = SeparationBarrier(0.5, gamma=2.0).filter(team, lost, close)
    np.testing.assert_array_equal(us2[0], close[0])  # robot 2 lost, the others far apart: nothing to do
    assert info2.min_separation[0] == pytest.approx(3.0) and info2.active.tolist() == [False, True]

    # far apart with a run through Team.step: the run is the unfiltered run, bitwise
    x1 = x.copy()
    x2 = x.copy()
    barrier = SeparationBarrier(0.5, gamma=5.0, dt_s=0.02)
    for _ in range(20):
        u = team.saturate(0.1 * np.sin(x1))
        x1 = team.step(x1, barrier.filter(team, x1, u)[0], 0.02)
        x2 = team.step(x2, team.saturate(0.1 * np.sin(x2)), 0.02)
    np.testing.assert_array_equal(x1, x2)


def brute_force(P, V, d, gamma, planar=None):
    """The programme by SLSQP over all pairs (small cases)."""
    n = P.shape[0]
    i, j = np.triu_indices(n, 1)
    pij = P[i] - P[j]
    h = np.sum(pij ** 2, axis=1) - d * d
    free = np.ones((n, 3), bool)
    if planar is not None:
        free[planar, 2] = False

    def full(w):
        out = V.copy()
        out[free] += w
        return out

    cons = [{"type": "ineq", "fun": lambda w, k=k: 2 * pij[k] @ (full(w)[i[k]] - full(w)[j[k]]) + gamma * h[k]}
            for k in range(i.size)]
    res = minimize(lambda w: np.sum(w ** 2), np.zeros(free.sum()), jac=lambda w: 2 * w, constraints=cons,
                   method="SLSQP", options={"ftol": 1e-14, "maxiter": 500})
    return full(res.x)


@pytest.mark.parametrize("seed", range(8))
def test_the_programme_is_solved_exactly(seed):
    """The filter's velocities equal a brute-force SLSQP solution within 1e-6 and satisfy KKT:
    every constraint holds and the change is a non-negative combination of the binding rows."""
    rng = np.random.default_rng(seed)
    n = 3 + seed % 3
    kinds = ("xyz_yaw",) * n if seed % 2 == 0 else ("xy_yaw",) * (n - 1) + ("xyz_yaw",)
    layout = RobotLayout(kinds)
    P = rng.uniform(-0.6, 0.6, (n, 3))
    planar = np.array([k == "xy_yaw" for k in kinds])
    P[planar, 2] = 0.0
    d = 0.25
    while np.min(layout.separations(layout.compose(P, np.zeros(n)))) < d * 1.05:
        P *= 1.2
    V = rng.normal(size=(n, 3)) * 2.0
    V[planar, 2] = 0.0
    V -= 0.8 * (P - P.mean(axis=0)) * 4  # toward the centroid
    V[planar, 2] = 0.0
    r = layout.compose(P, np.zeros(n))
    r_dot = layout.compose(V, rng.normal(size=n))
    barrier = SeparationBarrier(d, gamma=3.0)
    out, info = barrier.filter(layout, r, r_dot)
    Vf = layout.positions(out)
    np.testing.assert_array_equal(layout.yaws(out), layout.yaws(r_dot))  # yaw rates untouched
    ref = brute_force(P, V, d, 3.0, planar)
    np.testing.assert_allclose(Vf, ref, atol=1e-6)
    i, j = np.triu_indices(n, 1)
    pij = P[i] - P[j]
    g = 2 * np.sum(pij * (Vf[i] - Vf[j]), axis=1) + 3.0 * (np.sum(pij ** 2, axis=1) - d * d)
    assert np.all(g >= -1e-9)
    # stationarity: V_f - V = sum_k lambda_k grad_k, lambda >= 0, over the binding constraints
    bind = g < 1e-8
    rows = np.zeros((i.size, n, 3))
    rows[np.arange(i.size), i] = 2 * pij
    rows[np.arange(i.size), j] = -2 * pij
    rows[:, planar, 2] = 0.0
    A = rows[bind].reshape(int(bind.sum()), -1).T
    if A.size:
        _, rn = nnls(A, (Vf - V).ravel())
        assert rn < 1e-8
    assert info.active == bool(np.any(np.abs(Vf - V) > 0))


def test_batch_equals_single():
    rng = np.random.default_rng(9)
    team = Team.uniform(Pioneer(), 6)
    barrier = SeparationBarrier(D_MIN, gamma=GAMMA, dt_s=DT)
    X = np.stack([start_state(team.robots[0], 6, rng, 0.6) for _ in range(4)])
    U = np.stack([nominal(team, x, "centroid", rng) for x in X])
    out, info = barrier.filter(team, X, U)
    assert info.active.any()
    for b in range(4):
        o, inf = barrier.filter(team, X[b], U[b])
        np.testing.assert_array_equal(out[b], o)
        assert inf.active == info.active[b] and inf.min_separation == info.min_separation[b]
    out2, _ = barrier.filter(team, X.reshape(2, 2, -1), U.reshape(2, 2, -1))
    np.testing.assert_array_equal(out2.reshape(4, -1), out)


def test_dual_quaternion_pair_swapped_in_place_no_longer_collides():
    """Seed 000's pair started with its robots swapped: the dual-quaternion law drives them
    straight through each other (the formation refused coincident robots at t = 0.4 s). Through
    SafeController they stop min_separation apart and the log reports the filter."""
    e = np.array([0, 0, 1, 0, 0, 1, 0, 0.0])
    ctrl = DualQuaternionController()
    rd = RobotSpace().from_euclidean(e)
    c, cd = ctrl.formation.from_euclidean(e, np.zeros(8))
    r0 = np.r_[rd[4:7], rd[3], rd[0:3], rd[7]]
    times = np.arange(0, 3, 0.01)
    with pytest.raises(DegenerateInputError, match="coincide"):
        simulate(KinematicTeam(ctrl.team), ctrl, lambda k: Reference(c, cd, rd), times, r0)
    safe = SafeController(ctrl, SeparationBarrier(0.5, gamma=5.0, dt_s=0.01))
    log = simulate(KinematicTeam(ctrl.team), safe, lambda k: Reference(c, cd, rd), times, r0)
    x = log["state"]
    sep = np.linalg.norm(x[:, 0:3] - x[:, 4:7], axis=-1)
    assert sep.min() >= 0.5 - 1e-9
    np.testing.assert_allclose(log["min_separation"][:, 0], sep, rtol=1e-12)
    assert log["safety_active"].max() == 1.0 and sep[-1] < 0.5 + 1e-6  # pressed onto the barrier
    assert set(ctrl.signal_columns()) < set(safe.signal_columns())
    # a batch of two worlds equals the single runs
    logs = simulate(KinematicTeam(ctrl.team), safe, lambda k: Reference(c, cd, rd), times[:60], np.stack([r0, rd]))
    one = simulate(KinematicTeam(ctrl.team), safe, lambda k: Reference(c, cd, rd), times[:60], rd)
    np.testing.assert_allclose(logs["state"][:, 1], one["state"], rtol=1e-12, atol=1e-12)


def test_safe_controller_refuses_what_it_cannot_make_safe():
    ctrl = DualQuaternionController()
    safe = SafeController(ctrl, SeparationBarrier(0.5))
    e = np.array([0, 0, 1, 0, 0, 1, 0, 0.0])
    c, cd = ctrl.formation.from_euclidean(e, np.zeros(8))
    close = np.array([0, 0.2, 1, 0, 0, -0.1, 1, 0.0])
    with pytest.raises(DegenerateInputError, match=r"robots 1 and 2 start 0\.3 m apart") as err:
        safe.update(0.0, close, Reference(c, cd), safe.init())
    assert "\n" not in str(err.value)
    assert isinstance(safe.init(), SafeState)
    with pytest.raises(InvalidInputError, match="Bebop robot's commands are not a map.*known: .*Pioneer") as err:
        SeparationBarrier(0.5).filter(Team((Pioneer(), Bebop())), np.zeros(11), np.zeros(6))
    assert "\n" not in str(err.value)
    with pytest.raises(InvalidInputError, match="gamma"):
        SeparationBarrier(0.5, gamma=200.0, dt_s=0.01)
    with pytest.raises(InvalidInputError, match="min_separation_m"):
        SeparationBarrier(-1.0)
    with pytest.raises(InvalidInputError, match="range_m"):
        SeparationBarrier(0.5, range_m=0.1)


def test_limits_hold_and_a_common_factor_keeps_the_barrier():
    """Robots pushed apart faster than their limit: the filtered commands are scaled by one
    factor into the limits, and every pair constraint still holds."""
    team = Team.uniform(HolonomicRobot(0.5, 1.0), 3)
    x = np.array([0, 0, 0, 0, 0.31, 0, 0, 0, -0.31, 0, 0, 0.0])
    u = team.saturate(np.array([0, 0, 0, 0, -0.5, 0, 0, 0, 0.5, 0, 0, 0.0]))
    barrier = SeparationBarrier(0.3, gamma=50.0)
    us, info = barrier.filter(team, x, u)
    assert info.active and np.all(team.saturate(us) == pytest.approx(us, abs=1e-15))
    P = team.layout.positions(x)
    V = team.layout.positions(us)
    i, j = np.triu_indices(3, 1)
    pij = P[i] - P[j]
    g = 2 * np.sum(pij * (V[i] - V[j]), axis=1) + 50.0 * (np.sum(pij ** 2, axis=1) - 0.09)
    assert np.all(g >= -1e-12)


def test_large_team_uses_the_tree_and_agrees_with_dense_pairs():
    rng = np.random.default_rng(11)
    n = 120
    grid = np.stack(np.meshgrid(np.arange(12.0), np.arange(10.0)), -1).reshape(-1, 2)
    P = np.concatenate([grid, np.zeros((n, 1))], axis=1) * 0.5 + rng.uniform(-0.05, 0.05, (n, 3)) * [1, 1, 0]
    layout = RobotLayout(("xyz_yaw",) * n)
    r = layout.compose(P, np.zeros(n))
    V = rng.normal(size=(n, 3))
    r_dot = layout.compose(V, np.zeros(n))
    b = SeparationBarrier(0.3, gamma=4.0)
    out, info = b.filter(layout, r, r_dot)
    assert info.active and 0 < info.constraints < 400
    Vf = layout.positions(out)
    i, j = np.triu_indices(n, 1)
    pij = P[i] - P[j]
    g = 2 * np.sum(pij * (Vf[i] - Vf[j]), axis=1) + 4.0 * (np.sum(pij ** 2, axis=1) - 0.09)
    assert np.all(g >= -1e-9)  # every one of the 7140 pairs, not just the neighbours


def test_layout_points_of_every_kind_change_only_their_position_rates():
    layout = RobotLayout(("pose", "xy_yaw", "xyz", "xyz_yaw"))
    r = np.r_[0, 0, 0, 1, 0, 0, 0, 0.35, 0, 0.2, 0, 0.35, 0, -0.35, 0, 0, 0.0]
    r_dot = np.r_[0.5, 0, 0, 0.1, 0.2, 0.3, 0.4, -0.5, 0, 0.7, 0, -0.5, 0, 0.5, 0, 0, -0.2]
    out, info = SeparationBarrier(0.3, gamma=4.0).filter(layout, r, r_dot)
    assert info.active
    moved = np.flatnonzero(out != r_dot)
    position_entries = {0, 1, 2, 7, 8, 10, 11, 12, 13, 14, 15}
    assert set(moved.tolist()) <= position_entries and moved.size > 0
    P, V = layout.positions(r), layout.positions(out)
    i, j = layout.pairs
    pij = P[i] - P[j]
    g = 2 * np.sum(pij * (V[i] - V[j]), axis=1) + 4.0 * (np.sum(pij ** 2, axis=1) - 0.09)
    assert np.all(g >= -1e-9)


def test_a_lost_robot_does_not_switch_the_barrier_off_for_the_others():
    """Review finding: one NaN measurement let every other pair of its world collide."""
    team = Team.uniform(HolonomicRobot(), 3)
    x = np.array([0.0, 0, 1, 0, 0.6, 0, 1, 0, 7.0, 0, 1, 0])
    u = np.array([1.0, 0, 0, 0, -1.0, 0, 0, 0, 0, 0, 0, 0])  # robots 1 and 2 head-on at 1 m/s
    x[8] = np.nan  # robot 3's measurement lost
    barrier = SeparationBarrier(0.5, gamma=5.0, dt_s=0.02)
    us, info = barrier.filter(team, x, u)
    assert info.active and info.min_separation == pytest.approx(0.6)
    np.testing.assert_array_equal(us[8:], u[8:])  # the lost robot's command passes
    for _ in range(100):  # the two measured robots never come closer than 0.5 m
        us, info = barrier.filter(team, x, u)
        x = x + 0.02 * us
        assert abs(x[4] - x[0]) >= 0.5 - 1e-9
    one = np.array(x)
    one[0] = np.nan
    _, info1 = barrier.filter(team, one, u)  # two robots lost: no pair left
    assert np.isnan(info1.min_separation)


# -- the barrier's array algorithm (control.barrier) against SeparationBarrier.filter ------------------------------------------------------

TEAMS = {"two 4-DOF": (HolonomicRobot(), HolonomicRobot()),
         "four mixed": (HolonomicRobot(), PlanarHolonomicRobot(), HolonomicRobot(), PlanarHolonomicRobot()),
         "six planar": (PlanarHolonomicRobot(),) * 6}
_KERNELS = {}


def _kernel(name, barrier):
    import jax
    import jax.numpy as jnp

    from quatform.control.barrier import barrier_filter

    key = (name, barrier)
    if key not in _KERNELS:
        team = Team(TEAMS[name])
        _KERNELS[key] = team, jax.jit(lambda m, u: barrier_filter(barrier, team, m, u, jnp.ones(m.shape[0], dtype=bool)))
    return _KERNELS[key]


@pytest.mark.parametrize("name", list(TEAMS))
@pytest.mark.parametrize("range_m", [None, 0.8])
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_kernel_equals_the_exact_programme(name, range_m, seed):
    jax = pytest.importorskip("jax")
    barrier = SeparationBarrier(0.3, gamma=5.0, range_m=range_m)
    team, kernel = _kernel(name, barrier)
    rng = np.random.default_rng(seed)
    B = 4
    x = np.empty((B, team.n_state))
    for w in range(B):  # robots within 1.2 m of each other, at least the barrier's 0.3 m apart
        while True:
            p = rng.uniform(-0.6, 0.6, (len(team.robots), 3))
            p[:, 2] = np.where([isinstance(r, PlanarHolonomicRobot) for r in team.robots], 0.0, p[:, 2])
            d = np.linalg.norm(p[:, None] - p[None], axis=-1) + 9.0 * np.eye(len(p))
            if d.min() >= 0.31:
                break
        x[w] = np.concatenate([np.append(pk[:2 if isinstance(r, PlanarHolonomicRobot) else 3], rng.uniform(-3, 3))
                               for pk, r in zip(p, team.robots)])
    u = team.saturate(rng.uniform(-2.0, 2.0, (B, team.n)))
    expected, info = barrier.filter(team, x, u)
    with jax.enable_x64(True):
        got, sep, active, solved = (np.asarray(v) for v in kernel(x, u))
    assert np.all(solved)
    np.testing.assert_array_equal(active, info.active)
    np.testing.assert_allclose(got, expected, rtol=0, atol=TOL)
    np.testing.assert_array_equal(got[~active], u[~active])  # no pair binds: the commands bitwise
    np.testing.assert_allclose(sep.min(axis=-1), info.min_separation, rtol=0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), P=st.sampled_from([33, 64, 65, 200, 4950]), levels=st.integers(1, 40))
def test_candidate_selection_is_top_k_without_its_sort(seed, P, levels):
    """The barrier's K smallest keys on JAX: the indices (and order) of ``lax.top_k(-key, K)``,
    ties by index, ``-0.0`` before ``0.0``, ``inf`` (pairs out of range) last; NumPy's stable
    sort gives the same indices where no zero is signed."""
    jax = pytest.importorskip("jax")
    from quatform.control.barrier import CANDIDATES, _smallest

    rng = np.random.default_rng(seed)
    key = rng.integers(-levels, levels + 1, (3, P)).astype(float) * 0.25  # many ties
    key[rng.random(key.shape) < 0.3] = np.inf
    key[rng.random(key.shape) < 0.05] = -0.0
    K = min(CANDIDATES, P)
    with jax.enable_x64(True):
        got = np.asarray(jax.jit(lambda k: _smallest(jax.numpy, k, K))(key))
        want = np.asarray(jax.lax.top_k(-jax.numpy.asarray(key), K)[1])
    np.testing.assert_array_equal(got, want)
    unsigned = key + 0.0  # -0.0 -> 0.0: the float order NumPy's sort uses
    with jax.enable_x64(True):
        got_u = np.asarray(jax.jit(lambda k: _smallest(jax.numpy, k, K))(unsigned))
    np.testing.assert_array_equal(got_u, _smallest(np, unsigned, K))
