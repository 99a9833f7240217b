"""EuclideanTeam: the minimal Santa Clara cluster space of N robots (the team baseline).

The formation contract for N = 2, 3, 4, 10, a mixed spatial layout and planar teams; N = 2 is
seed 000 eqs. (1)-(8) (``EuclideanPair``) and reproduces the pair cluster-space runs; every
singular set at the point and near it; a closed loop that tracks away from them and is lost
where the seed's baseline is; bad input in one line.
"""

import dataclasses

import numpy as np
import pytest

from quatform.control.base import Reference
from quatform.control.cluster_space import TABLE1, TABLE2
from quatform.control.team import TeamController
from quatform.errors import DegenerateInputError, InvalidInputError
from quatform.formations import EuclideanPair, RobotLayout
from quatform.formations.euclidean_team import EuclideanTeam
from quatform.formations.testing import SINGULAR, check_formation, robot_distance
from quatform.references.team_motion import template_positions
from quatform.robots import HolonomicRobot, Team
from quatform.scenarios import load_scenario
from quatform.scenarios.team import TEAM
from quatform.sim import simulate
from quatform.sim.metrics import singular_threshold
from quatform.sim.plants.kinematic import KinematicTeam

SPATIAL_MIX = RobotLayout(("xyz_yaw", "xyz", "xyz_yaw", "xyz_yaw", "xyz"))
PLANAR = RobotLayout.uniform("xy_yaw", 5)
#: seed 001's mix: a ground robot (robot 1) under three 4-DOF UAVs
GROUND_MIX = RobotLayout(("xy_yaw", "xyz_yaw", "xyz_yaw", "xyz_yaw"))


def _cases():
    return [EuclideanTeam(2), EuclideanTeam(3), EuclideanTeam(4), EuclideanTeam(10),
            EuclideanTeam(layout=SPATIAL_MIX), EuclideanTeam(layout=RobotLayout.uniform("xy_yaw", 2)),
            EuclideanTeam(layout=PLANAR), EuclideanTeam(2, chart="pair"),
            EuclideanTeam(layout=GROUND_MIX), EuclideanTeam(9, template=template_positions("grid", 9, 0.6, 3))]


@pytest.mark.parametrize("F", _cases(), ids=repr)
def test_the_formation_contract(F):
    check_formation(F, np.random.default_rng(14))
    assert F.n_c == F.n_r  # minimal: a square Jacobian
    (group,) = F.law_groups
    assert group.role == "variables" and np.array_equal(group.index[:, 0], np.arange(F.n_c))


def test_the_variables_are_the_seeds_and_kitts_mas():
    assert EuclideanTeam(2).names == ("x_c", "y_c", "z_c", "beta_c", "gamma_c", "d_c", "phi_1", "phi_2")
    assert EuclideanTeam(4).names == ("x_c", "y_c", "z_c", "beta_c", "gamma_c", "alpha_c", "d_c", "rho_3", "psi_3",
                                      "rho_4", "psi_4", "chi_4", "phi_1", "phi_2", "phi_3", "phi_4")
    assert EuclideanTeam(layout=RobotLayout.uniform("xy_yaw", 3)).names == (
        "x_c", "y_c", "beta_c", "d_c", "rho_3", "psi_3", "phi_1", "phi_2", "phi_3")
    assert "phi_2" not in EuclideanTeam(layout=SPATIAL_MIX).names  # an xyz robot has no heading


def test_three_robots_read_as_kitts_mas_p_q_beta():
    """Robot 3's rho_3, psi_3 are Kitts & Mas's q = |r1 - r3| and beta = the angle at robot 1 (law
    of cosines); d_c is half their p = |r1 - r2|; a flat triangle has no roll."""
    F = EuclideanTeam(3)
    p = np.array([[0.3, 1.2, 2.0], [-0.4, -0.1, 2.0], [1.1, 0.2, 2.0]])
    r = np.concatenate([p, np.array([[0.1], [0.2], [0.3]])], axis=1).ravel()
    c = dict(zip(F.names, F.forward(r)))
    P, Q, R = (np.linalg.norm(p[i] - p[j]) for i, j in ((0, 1), (0, 2), (1, 2)))
    assert c["d_c"] == pytest.approx(P / 2, rel=1e-13) and c["rho_3"] == pytest.approx(Q, rel=1e-13)
    assert c["psi_3"] == pytest.approx(np.arccos((P * P + Q * Q - R * R) / (2 * P * Q)), rel=1e-12)
    assert c["gamma_c"] == pytest.approx(0.0, abs=1e-15) and abs(c["alpha_c"]) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose([c["x_c"], c["y_c"], c["z_c"]], p.mean(axis=0), rtol=0, atol=1e-15)
    assert c["phi_3"] == pytest.approx(0.3 - c["beta_c"], abs=1e-15)


def test_two_robots_are_the_seeds_pair():
    P, F = EuclideanPair(), EuclideanTeam(2)
    rng = np.random.default_rng(2)
    r = P.sample_robot_state(rng, (50,))
    c = P.forward(r)
    near = c + 0.1 * rng.normal(size=c.shape)
    np.testing.assert_allclose(F.forward(r), c, rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.forward(r, near_c=near), P.forward(r, near_c=near), rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.inverse(c), P.inverse(c), rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.jacobian(r), P.jacobian(r), rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.inverse_jacobian(r), P.inverse_jacobian(r), rtol=0, atol=1e-12)
    np.testing.assert_allclose(F.singularity_measure(r), P.singularity_measure(r), rtol=0, atol=1e-12)
    # the general O(N) rate map is the seed's closed form too (the pair applies the closed form)
    w = rng.normal(size=c.shape)
    np.testing.assert_allclose(F._rate_map(c, w), F.robot_rate(c, w), rtol=0, atol=1e-12)


@pytest.mark.parametrize(("name", "table"), [("mas-kitts-helix", TABLE2), ("mas-kitts-spiral", TABLE1)])
def test_the_team_controller_reproduces_the_pair_cluster_space_runs(name, table):
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration_s=32.0)  # past the seed's singular pose (27.5 s, 30 s)
    pair = TEAM.experiment(sc, controller="cluster-space")
    pair_log = pair.run()
    want = pair.metrics(pair_log)
    ctrl = TeamController(EuclideanTeam(2, chart="pair"), {"k": table["cluster-space"]["k"]}, pair.controller.team,
                          name="cluster-space")
    team = TEAM.experiment(sc, controller=ctrl)
    log = team.run()
    got = team.metrics(log)
    assert want["first_singular_time_s"] is not None  # the run meets the seed's singular pose
    for key, v in want.items():
        if key == "formation":
            assert got[key] == "euclidean-team"
        elif isinstance(v, float):
            assert got[key] == pytest.approx(v, rel=1e-9, abs=1e-15), key
        else:
            assert got[key] == v, key
    np.testing.assert_allclose(log["singularity"], pair_log["singularity"], rtol=0, atol=1e-12)


def _singular_sets(F):
    return [s for s in F.special_sets() if s.inverse_jacobian == "rank-deficient"]


@pytest.mark.parametrize("F", [EuclideanTeam(2), EuclideanTeam(3), EuclideanTeam(4), EuclideanTeam(10),
                               EuclideanTeam(layout=SPATIAL_MIX)], ids=repr)
def test_every_singular_set_at_the_point_and_near_it_batch_and_single(F):
    names = {s.name for s in _singular_sets(F)}
    assert "vertical" in names and (("collinear" in names) == (F.layout.n >= 3))
    assert ("spoke-pole" in names) == (F.layout.n >= 4)
    rng = np.random.default_rng(5)
    for s in _singular_sets(F):
        for eps in (0.0, 1e-9, 1e-6):
            r = s.states(rng, 6, eps)
            m = F.singularity_measure(r)
            single = np.array([F.singularity_measure(x) for x in r])
            np.testing.assert_allclose(m, single, rtol=1e-9, atol=1e-18)
            if eps == 0.0:
                assert np.all(m <= SINGULAR), (s.name, m)
                with pytest.raises(DegenerateInputError, match="undefined"):
                    F.jacobian(r)
                with pytest.raises(DegenerateInputError, match="undefined"):
                    F.cluster_rate(r[0], np.ones(F.n_r))
            else:  # the measure vanishes like the distance to the set
                assert np.all(m > 0.0) and np.all(m <= eps), (s.name, eps, m)
                assert np.all(np.isfinite(F.jacobian(r)))
            assert np.all(robot_distance(F, F.inverse(F.forward(r)), r) <= 1e-9)


def test_planar_teams_have_no_singular_set_but_coincidence():
    F = EuclideanTeam(layout=PLANAR)
    assert not _singular_sets(F)
    m = F.singularity_measure(F.sample_robot_state(np.random.default_rng(1), (200,)))
    assert np.all(m > 1e-3)


@pytest.mark.parametrize("F", [EuclideanTeam(2), EuclideanTeam(4), EuclideanTeam(layout=PLANAR)], ids=repr)
@pytest.mark.parametrize("k", [1, 2])
def test_robots_closing_on_robot_1_take_the_measure_to_zero(F, k):
    """Zero side lengths (robot 2 or 3 on robot 1): refused at the point, the measure ~ the gap near it
    (a pair's measure is taken on the formation scaled to unit size, so there only the refusal)."""
    if k >= F.layout.n:
        pytest.skip("no such robot")
    rng = np.random.default_rng(9)
    r = F.sample_robot_state(rng, (6,))
    p = F.layout.positions(r).copy()
    direction = rng.normal(size=(6, 3))
    if F.planar:
        direction[:, 2] = 0.0
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    scale = F.length_scale(r)[:, None]
    for gap in (0.0, 1e-8, 1e-6):
        p[:, k] = p[:, 0] + gap * scale * direction
        rr = F.layout.compose(p, F.layout.yaws(r))
        if gap == 0.0:
            with pytest.raises(DegenerateInputError, match="coincide"):
                F.forward(rr)
            continue
        m = F.singularity_measure(rr)
        np.testing.assert_allclose(m, [F.singularity_measure(x) for x in rr], rtol=1e-9, atol=1e-18)
        assert np.all(m > 0.0)
        if F.layout.n > 2:
            assert np.all(m <= 10 * gap), (gap, m)


def test_the_team_chart_round_trips():
    rng = np.random.default_rng(4)
    for F in (EuclideanTeam(4), EuclideanTeam(layout=SPATIAL_MIX), EuclideanTeam(layout=PLANAR)):
        r = F.sample_robot_state(rng, (12,))
        c = F.forward(r)
        e = F.to_chart(c)
        assert np.all(robot_distance(F, F.chart.robots(e), r) <= 1e-12)
        back = F.from_chart(e)
        np.testing.assert_allclose(F.errors(back, c), 0.0, rtol=0, atol=1e-11)
        # read in another chart's frame: the same robots
        other = F.chart.from_robots(r)
        e2 = F.to_chart(c, near_e=other)
        assert np.all(robot_distance(F, F.chart.robots(e2), r) <= 1e-12)
        np.testing.assert_allclose(e2[..., 3:7], other[..., 3:7], rtol=0, atol=1e-9)


def test_from_chart_stays_finite_on_the_vertical():
    """A reference through the vertical (the held angles' rates reported 0; the Jacobian raises)."""
    F = EuclideanTeam(4)
    e = F.to_chart(F.forward(F.sample_robot_state(np.random.default_rng(3))))
    e[3:7] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]  # the formation's y axis (robots 2 -> 1) vertical
    e[F.chart.shape_index] = [[0, 0.5, 0], [0, -0.5, 0], [0.8, 0, 0], [-0.8, 0.0, 0.6]]
    c, cd = F.from_chart(e, np.ones(F.chart.size))
    assert abs(c[F._i_gamma]) == pytest.approx(np.pi / 2, abs=1e-12)
    assert np.all(np.isfinite(cd)) and cd[F._i_beta] == 0.0
    with pytest.raises(DegenerateInputError, match="gamma_c"):
        F.jacobian(F.chart.robots(e))


# -- closed loop ---------------------------------------------------------------------------------

_SHAPE = np.array([[0.0, 0.5, 0.0], [0.0, -0.5, 0.0], [0.8, 0.0, 0.0], [0.3, 0.0, 0.7]])


def _run(F, c, cd, t):
    team = Team((HolonomicRobot(),) * 4)
    ctrl = TeamController(F, {"k": 1.0}, team)
    r_des = F.inverse(c)
    log = simulate(KinematicTeam(team), ctrl, lambda k: Reference(c[k], cd[k], r_des[k]), t, r_des[0])
    x = log["state"]
    err = np.max(np.linalg.norm(F.layout.positions(x) - F.layout.positions(r_des), axis=-1), axis=-1)
    return err, log, x


def _yawing_chart(F, t):
    e = np.zeros((len(t), F.chart.size))
    ed = np.zeros_like(e)
    e[:, 0], ed[:, 0], e[:, 2] = 0.05 * t, 0.05, 1.0
    a, w = 0.1 * t, 0.1
    e[:, 3], e[:, 6], ed[:, 3], ed[:, 6] = np.cos(a / 2), np.sin(a / 2), -w / 2 * np.sin(a / 2), w / 2 * np.cos(a / 2)
    e[:, F.chart.shape_index] = _SHAPE - _SHAPE.mean(axis=0)
    e[:, F.chart.yaw_index], ed[:, F.chart.yaw_index] = 0.3 + 0.02 * t[:, None], 0.02
    return e, ed


def test_the_baseline_tracks_away_from_its_singular_sets_and_is_lost_past_the_vertical():
    F = EuclideanTeam(4)
    t = np.arange(0.0, 30.0, 0.05)
    c, cd = F.from_chart(*_yawing_chart(F, t))
    err, log, x = _run(F, c, cd, t)
    assert np.all(log["raw_finite"] == 1.0)
    regular_err, regular_measure = err.max(), F.singularity_measure(x).min()
    assert regular_err < 1e-3 and regular_measure > 0.05
    # the seed's experiment (Fig. 9) for four robots: gamma_c ramped through pi/2 in the baseline's variables
    c_des = np.repeat(c[:1], len(t), axis=0)
    cd_des = np.zeros_like(c_des)
    ramp = (t > 5.0) & (t < 45.0)
    c_des[:, F._i_gamma] = np.clip((t - 5.0) / 40.0, 0.0, 1.0) * 2.0 * np.pi
    cd_des[ramp, F._i_gamma] = 2.0 * np.pi / 40.0
    err, log, x = _run(F, c_des, cd_des, t)
    crossing = t < 15.0  # gamma_des = pi/2 at t = 15 s
    assert err[crossing].max() < 100 * max(regular_err, 1e-5)  # tracked up to the vertical
    size = 2.0 * c[0, F._i_d]
    assert err[~crossing].max() > 0.3 * size  # then lost: the formation does not follow past pi/2
    m = F.singularity_measure(x)
    assert m.min() < 1e-3 * regular_measure  # stuck at the singular pose on the way (2e-7 at t = 15 s)
    assert np.all(m[t < 12.0] > 1e-3)


# -- bad input ----------------------------------------------------------------------------------

@pytest.mark.parametrize(("kwargs", "match"), [
    ({"layout": RobotLayout(("xyz_yaw", "pose", "xyz_yaw"))}, "robot 2 is a 'pose' robot"),
    ({"layout": RobotLayout(("xyz_yaw", "xy_yaw", "xy_yaw"))}, "mixes 2 planar"),
    ({"n": 3, "chart": "pair"}, "needs two xyz_yaw robots"),
    ({"n": 2, "chart": "euler"}, "chart must be 'team' or 'pair'"),
    ({"n": 1}, "n >= 2"),
    ({"n": 3, "template": np.zeros((2, 3))}, "shape"),
])
def test_unrepresentable_teams_are_refused_in_one_line(kwargs, match):
    with pytest.raises(InvalidInputError, match=match) as info:
        EuclideanTeam(**kwargs)
    assert "\n" not in str(info.value)


def test_bad_states_are_refused_in_one_line():
    F = EuclideanTeam(4)
    r = F.sample_robot_state(np.random.default_rng(0))
    c = F.forward(r)
    bad = r.copy()
    bad[4:7] = bad[8:11]  # robots 2 and 3 on each other
    cases = [(DegenerateInputError, "robots 2 and 3 coincide", lambda: F.forward(bad)),
             (InvalidInputError, "nan at index", lambda: F.forward(np.where(np.arange(F.n_r) == 5, np.nan, r))),
             (DegenerateInputError, "d_c must be", lambda: F.inverse(np.where(np.arange(F.n_c) == F._i_d, 0.0, c))),
             (DegenerateInputError, "puts robot 4 on robot 1",
              lambda: F.inverse(np.where(np.arange(F.n_c) == F._i_rho[1], -1.0, c)))]
    e = F.to_chart(c)
    e[F.chart.shape_index[1]] = e[F.chart.shape_index[0]]  # a chart whose robots 1 and 2 coincide
    cases.append((DegenerateInputError, "robots 1 and 2 coincide", lambda: F.from_chart(e)))
    cases.append((DegenerateInputError, "d_c must be",
                  lambda: EuclideanTeam(2, chart="pair").from_chart([0, 0, 0, 0, 0, -0.5, 0, 0])))
    for cls, match, call in cases:
        with pytest.raises(cls, match=match) as info:
            call()
        assert "\n" not in str(info.value)


def test_batch_axes_broadcast():
    F = EuclideanTeam(4)
    rng = np.random.default_rng(6)
    r = F.sample_robot_state(rng)
    c = F.forward(F.sample_robot_state(rng, (3,)))
    v = rng.normal(size=F.n_r)
    assert F.forward(r, near_c=c).shape == (3, F.n_c) and F.cluster_rate(r, v, near_c=c).shape == (3, F.n_c)
    assert F.robot_rate(c, rng.normal(size=(2, 1, F.n_c))).shape == (2, 3, F.n_r)
    np.testing.assert_allclose(F.forward(r, near_c=c)[1], F.forward(r, near_c=c[1]), rtol=0, atol=0)


# -- a ground robot under spatial ones; the chart's robot 3 off the 1-2 line -------------------

def test_a_ground_robot_fixes_z_c_and_the_chart_stays_minimal():
    F = EuclideanTeam(layout=GROUND_MIX)
    names = [v.name for v in F.variables]
    assert "z_c" not in names and F.n_c == F.n_r == 3 + 3 * 4
    r = F.sample_robot_state(np.random.default_rng(3), 50)
    np.testing.assert_allclose(F.inverse(F.forward(r), near_r=r), r, atol=1e-10)
    c = F.forward(r)
    rate = F.robot_rate(c, np.random.default_rng(4).normal(size=c.shape))
    c2 = F.forward(F.inverse(c + 1e-7 * np.eye(F.n_c)[5]))  # d_c moved: robot 1 stays on the ground
    assert np.all(np.isfinite(rate)) and np.all(np.isfinite(c2))
    # robot 2 straight over the ground robot: gamma_c = -pi/2, the Euclidean chart's singular pose
    over = r[0].copy()
    over[3:6] = [over[0], over[1], 1.5]
    with pytest.raises(DegenerateInputError, match="gamma_c"):
        F.cluster_rate(over, np.zeros(F.n_r))
    assert F.singularity_measure(over) < 1e-9


def test_the_grid_plays_its_first_robot_off_row_one_as_robot_3():
    t = template_positions("grid", 100, 0.6, 10)
    F = EuclideanTeam(100, template=t)
    assert list(F.order[:4]) == [0, 1, 10, 2] and sorted(F.order) == list(range(100))
    assert [v.name for v in F.variables][7:9] == ["rho_11", "psi_11"]
    r = F.layout.compose(t + [0.0, 0.0, 8.0], np.zeros(100))
    # regular on the template (above the team metrics' "singular" line); robots 1, 2, 3 of a row: 0
    assert F.singularity_measure(r) > 1.5 * singular_threshold(100)
    assert EuclideanTeam(100).singularity_measure(r) < 1e-9
    np.testing.assert_allclose(F.inverse(F.forward(r)), r, atol=1e-10)
    line = template_positions("line", 5, 1.0)
    np.testing.assert_array_equal(EuclideanTeam(5, template=line).order, np.arange(5))  # a line stays a line


def test_the_euler_reading_folds_past_the_vertical_unless_followed():
    """A tetrahedron pitching 2 pi about y: the forward map's own angles fold at gamma_c = -pi/2
    to (beta_c + pi, pi - gamma_c, alpha_c + pi) (seed 000's robot-space reading); followed in
    time the reading is continuous; both triples are one frame (the same robots)."""
    from quatform.formations import geometry as g

    E = EuclideanTeam(4)
    t = template_positions("tetrahedron", 4, 1.0)
    ang = np.linspace(0.0, 2.0 * np.pi, 401)
    q = np.stack([np.cos(ang / 2), 0 * ang, np.sin(ang / 2), 0 * ang], -1)
    r = E.layout.compose(g.rotate(q[:, None, :], t[None]) + [0.0, 0.0, 5.0], np.zeros((401, 4)))
    follow, own = E.follow_reading(r), E.reading(r)
    assert np.max(np.abs(np.diff(follow, axis=0))) < 0.02  # continuous: 2 pi / 400 per sample
    np.testing.assert_allclose(follow[-1, 1] - follow[0, 1], -2.0 * np.pi, atol=1e-9)
    assert np.all(np.abs(own[:, 1]) <= 0.5 * np.pi + 1e-12)
    mid = (ang > 0.6 * np.pi) & (ang < 1.4 * np.pi)  # past the vertical: folded
    np.testing.assert_allclose(np.abs(g.wrap(own[mid, 0] - follow[mid, 0])), np.pi, atol=1e-9)
    # the reading near the followed one is the followed one (same robots, same frame)
    np.testing.assert_allclose(E.reading(r, near=follow), follow, atol=1e-9)
