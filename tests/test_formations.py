"""Formations (seed 000 eqs. (1)-(19), (26)-(27)): the seeds' numbers, branch choices, singular points.

The properties every description shares (round trips, rate maps against differences, batch =
single, sign and wrap invariance) are checked once for all in test_formation_contract.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import pair_robot_error, pair_separation
from hypothesis import assume, given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from quatform.algebra import dq_from_pose, dqconj, dqmul, dqsqrt_decoupled, q_angle_between
from quatform.errors import (
    DegenerateInputError,
    InvalidInputError,
    NonFiniteError,
    NonUnitError,
    ShapeError,
    UnreachableError,
)
from quatform.formations import (
    DualQuaternionPair,
    EuclideanPair,
    QuaternionPair,
    RobotSpace,
    segment_direction,
)
from quatform.formations import geometry as g

ALL = [EuclideanPair(), RobotSpace(), QuaternionPair(), DualQuaternionPair()]

coord = st.floats(-3, 3, allow_nan=False)
angle = st.floats(-12, 12, allow_nan=False)


@st.composite
def robot_states(draw, min_sep=0.05, min_cos_pitch=0.0):
    r = np.array([draw(coord), draw(coord), draw(coord), draw(angle),
                  draw(coord), draw(coord), draw(coord), draw(angle)])
    delta = r[0:3] - r[4:7]
    D = np.linalg.norm(delta)
    if D < min_sep:
        r[4:7] = r[0:3] - np.array([min_sep, 0.3, 0.1])
        delta = r[0:3] - r[4:7]
        D = np.linalg.norm(delta)
    if np.hypot(delta[0], delta[1]) < min_cos_pitch * D:
        r[4] = r[0] - D  # tilt it back from the vertical
    return r


@st.composite
def euclidean_states(draw, full_pitch=True):
    lim = 7.0 if full_pitch else 1.5
    return np.array([draw(coord), draw(coord), draw(coord), draw(angle),
                     draw(st.floats(-lim, lim)), draw(st.floats(0.1, 3.0)), draw(angle), draw(angle)])


@pytest.mark.parametrize("F", ALL, ids=lambda f: f.name)
@given(e=euclidean_states(), e_dot=hnp.arrays(np.float64, 8, elements=st.floats(-2, 2)))
def test_from_euclidean_is_consistent(F, e, e_dot):
    """One motion, every description: c(e) maps to the same robots, and c_dot to the same robot
    rates (each description's own rates against differences: test_formation_contract)."""
    c, cd = F.from_euclidean(e, e_dot)
    r = EuclideanPair().inverse(e)
    np.testing.assert_allclose(F.inverse(c, near_r=r), r, atol=1e-9)
    # c_dot is the cluster image of the robots' rate: J^-1 c_dot = r_dot
    r_dot = EuclideanPair().inverse_jacobian_at(e) @ e_dot
    np.testing.assert_allclose(F.inverse_jacobian_at(c, r=r) @ cd, r_dot, atol=1e-8)


@pytest.mark.parametrize("F", [QuaternionPair(), DualQuaternionPair()], ids=lambda f: f.name)
@given(e=euclidean_states())
def test_monitoring_recovers_full_pitch(F, e):
    """Quaternion descriptions give back beta_c, gamma_c on the whole circle (no fold)."""
    back = F.euclidean(F.from_euclidean(e), near_e=e)
    np.testing.assert_allclose(back, e, atol=1e-8)


@pytest.mark.parametrize("F", [QuaternionPair(), DualQuaternionPair()], ids=lambda f: f.name)
@given(r=robot_states(), e_hint=euclidean_states())
def test_monitoring_is_the_measured_formation_for_any_hint(F, r, e_hint):
    """Whatever the desired state, the Euclidean variables read back give the measured robots
    (exactly, away from the vertical; near it the yaw comes from the cluster frame)."""
    delta = r[0:3] - r[4:7]
    assume(np.hypot(delta[0], delta[1]) > 0.02 * np.linalg.norm(delta))
    c = F.forward(r, near_c=F.from_euclidean(e_hint))
    back = EuclideanPair().inverse(F.euclidean(c, near_e=e_hint, r=r))
    np.testing.assert_allclose(g.wrap(back - r), 0, atol=1e-8)


@pytest.mark.parametrize("F", [EuclideanPair(), QuaternionPair(), DualQuaternionPair()], ids=lambda f: f.name)
def test_singularity_measure_ignores_place_and_size(F):
    e = np.array([0, 0, 1, 0.3, 0.4, 1.0, 0.1, 0.2])
    ref = F.singularity_measure(EuclideanPair().inverse(e), near_c=F.from_euclidean(e))
    for x, d in ((1e3, 1.0), (0.0, 1e-2), (-50.0, 1e2)):
        e2 = e.copy()
        e2[0], e2[5] = x, d
        assert F.singularity_measure(EuclideanPair().inverse(e2), near_c=F.from_euclidean(e2)) == pytest.approx(ref, rel=1e-6)


@given(e=euclidean_states())
def test_euclidean_folds_past_vertical(e):
    """Eqs. (1)-(8) read gamma_c beyond pi/2 as beta_c + pi, pi - gamma_c (seed 000 §4.1)."""
    E = EuclideanPair()
    back = E.forward(E.inverse(e))
    gam = g.wrap(e[4])
    if abs(np.cos(gam)) < 1e-6:
        return
    folded = np.cos(gam) < 0
    want_gamma = np.pi - gam if folded else gam
    np.testing.assert_allclose(g.wrap(back[4] - want_gamma), 0, atol=1e-8)
    np.testing.assert_allclose(g.wrap(back[3] - e[3] - (np.pi if folded else 0.0)), 0, atol=1e-8)
    np.testing.assert_allclose(back[5], e[5], atol=1e-12)


def test_seed_eq6_is_half_the_distance():
    r = np.array([1.0, 2.0, 3.0, 0, -1.0, 0.0, 1.0, 0])
    assert EuclideanPair().forward(r)[5] == pytest.approx(np.linalg.norm(r[0:3] - r[4:7]) / 2)


# -- singular and ambiguous points -------------------------------------------------------

def vertical_pair(eps=0.0, beta=0.3):
    """Robot 1 above robot 2, tilted by eps rad in the direction of yaw beta."""
    e = np.array([0.5, -0.2, 2.0, beta, np.pi / 2 - eps, 1.0, 0.4, -0.7])
    return EuclideanPair().inverse(e), e


def test_euclidean_at_vertical_is_singular_but_never_nan():
    E = EuclideanPair()
    r, e = vertical_pair(0.0)
    with pytest.raises(DegenerateInputError, match="straight above"):
        E.jacobian(r)
    c = E.forward(r)
    assert np.all(np.isfinite(c))
    assert E.singularity_measure(r) < 1e-12  # the inverse Jacobian lost rank
    Ji = E.inverse_jacobian(r)
    assert np.all(np.isfinite(Ji)) and np.linalg.matrix_rank(Ji) == 7
    # with a hint, beta_c is held at the hint's value where it is undefined
    assert E.forward(r, near_c=e)[3] == pytest.approx(e[3])


@pytest.mark.parametrize("eps", [1e-2, 1e-4, 1e-6, 1e-8])
def test_euclidean_near_vertical_condition_grows(eps):
    E = EuclideanPair()
    r, _ = vertical_pair(eps)
    m = E.singularity_measure(r)
    assert 0 < m < 2 * eps  # ~ |cos gamma_c|: the distance to the singular pose
    J = E.jacobian(r)
    # |d beta / d p1| = 1 / (D cos gamma_c), D = 2 d_c = 2 m
    assert np.linalg.norm(J[3, 0:3]) == pytest.approx(1.0 / (2.0 * np.sin(eps)), rel=1e-6)


@pytest.mark.parametrize("F", [QuaternionPair(), DualQuaternionPair()], ids=lambda f: f.name)
@pytest.mark.parametrize("eps", [0.0, 1e-8, 1e-4])
def test_quaternion_descriptions_regular_at_vertical(F, eps):
    r, e = vertical_pair(eps)
    hint = F.from_euclidean(e)
    c = F.forward(r, near_c=hint)
    J, Ji = F.jacobian(r, near_c=hint), F.inverse_jacobian(r, near_c=hint)
    assert np.all(np.isfinite(J)) and np.all(np.isfinite(Ji))
    np.testing.assert_allclose(Ji @ J, np.eye(8), atol=1e-9)
    assert F.singularity_measure(r, near_c=hint) > 0.05
    np.testing.assert_allclose(F.euclidean(c, near_e=e), e, atol=1e-7)


def test_seed_quaternion_forward_at_minus_i():
    """Eqs. (14)-(15) divide 0/0 where x1 - x2 points along -i; the hinted forward does not."""
    Q = QuaternionPair()
    r = np.array([-1.0, 0, 1, 0.2, 1.0, 0, 1, -0.3])  # x1 - x2 = -2 i
    c = Q.forward(r)  # the seed's convention: half turn about z chosen there
    assert np.all(np.isfinite(c))
    np.testing.assert_allclose(np.linalg.norm(c[3:7]), 1.0)
    np.testing.assert_allclose(Q.inverse(c, near_r=r), r, atol=1e-12)
    # just off -i the seed's q_c swings by up to pi in twist between nearby states ...
    a = Q.forward(r + np.array([0, 1e-7, 0, 0, 0, 0, 0, 0]))
    b = Q.forward(r + np.array([0, 0, 1e-7, 0, 0, 0, 0, 0]))
    assert q_angle_between(a[3:7], b[3:7]) > 1.0
    # ... while the hinted one moves by the motion's size only
    ha = Q.forward(r + np.array([0, 1e-7, 0, 0, 0, 0, 0, 0]), near_c=c)
    hb = Q.forward(r + np.array([0, 0, 1e-7, 0, 0, 0, 0, 0]), near_c=c)
    assert q_angle_between(ha[3:7], hb[3:7]) < 1e-6


def test_quaternion_hint_opposite_segment_is_half_turn_about_hint_z():
    Q = QuaternionPair()
    e = np.array([0, 0, 1, 0.0, 0.0, 1.0, 0, 0])
    hint = Q.from_euclidean(e)
    e_flip = e.copy()
    e_flip[3] = np.pi  # segment reversed: a 180 deg formation error
    r = EuclideanPair().inverse(e_flip)
    c = Q.forward(r, near_c=hint)
    qe = g.mul(g.conj(hint[3:7]), c[3:7])
    np.testing.assert_allclose(np.abs(qe), [0, 0, 0, 1], atol=1e-12)  # half turn about body z


def test_dual_quaternion_closed_form_is_eq26_with_decoupled_root():
    D = DualQuaternionPair()
    rng = np.random.default_rng(3)
    for _ in range(50):
        r = rng.normal(size=8) * np.array([2, 2, 2, 3, 2, 2, 2, 3])
        c = D.forward(r)
        dq1 = dq_from_pose(g.q_yaw(r[3]), r[0:3])
        dq2 = dq_from_pose(g.q_yaw(r[7]), r[4:7])
        qs = dqmul(dqconj(dq2), dq1)  # eq. (27)
        assert min(np.abs(c[8:] - qs).max(), np.abs(c[8:] + qs).max()) < 1e-12
        qc = dqmul(dq2, dqsqrt_decoupled(qs))  # eq. (26), short root
        same = min(np.abs(c[:8] - qc).max(), np.abs(c[:8] + qc).max()) < 1e-12
        rel = g.wrap(r[3] - r[7])
        # the short root is the branch of the continuous yaws unless they wound past pi
        assert same == (abs(g.wrap(0.5 * (r[3] + r[7]) - (r[7] + 0.5 * rel))) < 1e-9)


def test_dual_quaternion_pair_tells_the_branch_by_the_sign_of_qhat_s():
    """A formation and the same formation turned half a turn about the cluster z axis (yaws
    wound by +-pi) have the same pair up to the sign of qhat_s; that sign tells them apart,
    so the inverse needs no hint (without the sign it would return the turned one)."""
    D = DualQuaternionPair()
    r = np.array([1.0, 0.5, 1.0, 0.3, -1.0, -0.5, 1.2, -0.4])
    c = D.forward(r)
    mid = 0.5 * (r[0:3] + r[4:7])
    turned = r.copy()
    for k in (0, 4):
        turned[k:k + 2] = 2 * mid[:2] - r[k:k + 2]
    turned[[3, 7]] = r[[3, 7]] + np.array([np.pi, -np.pi])
    c2 = D.forward(turned)
    np.testing.assert_allclose(c2[0:8], c[0:8], atol=1e-12)
    np.testing.assert_allclose(c2[8:16], -c[8:16], atol=1e-12)
    np.testing.assert_allclose(g.wrap(D.inverse(c) - r), 0, atol=1e-12)
    np.testing.assert_allclose(g.wrap(D.inverse(c2) - turned), 0, atol=1e-12)
    # a hint only unwraps the yaws: the turned formation's robots as hint give r back
    np.testing.assert_allclose(D.inverse(c, near_r=turned)[[0, 1, 2, 4, 5, 6]], r[[0, 1, 2, 4, 5, 6]], atol=1e-12)
    # monitoring with the turned formation's Euclidean state as the hint: the measured robots
    got = EuclideanPair().inverse(D.euclidean(c, near_e=EuclideanPair().forward(turned), r=r))
    np.testing.assert_allclose(g.wrap(got - r), 0, atol=1e-9)


def test_dual_quaternion_half_turn_relative_yaw_is_continuous():
    """The short root jumps where the relative yaw crosses pi; the description does not."""
    D = DualQuaternionPair()
    rel = np.linspace(np.pi - 1e-3, np.pi + 1e-3, 201)
    r = np.zeros((rel.size, 8))
    r[:, 0], r[:, 4] = 1.0, -1.0
    r[:, 3], r[:, 7] = 0.5 * rel, -0.5 * rel
    c = D.forward(r, near_c=np.tile(D.forward(r[0]), (rel.size, 1)))
    assert np.abs(np.diff(c, axis=0)).max() < 1e-4


@pytest.mark.parametrize("F", [EuclideanPair(), QuaternionPair(), DualQuaternionPair()], ids=lambda f: f.name)
def test_coincident_robots_are_refused(F):
    r = np.array([1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0, 1.0])
    with pytest.raises(DegenerateInputError, match="coincide"):
        F.forward(r)


@pytest.mark.parametrize("F", ALL, ids=lambda f: f.name)
def test_bad_robot_states(F):
    with pytest.raises(ShapeError):
        F.forward(np.zeros(7))
    with pytest.raises(NonFiniteError):
        F.forward(np.array([0, 0, 0, np.nan, 1, 0, 0, 0.0]))


def test_unreachable_and_non_unit_cluster_states():
    Q = QuaternionPair()
    c = Q.from_euclidean(np.array([0, 0, 1, 0.1, 0.2, 1.0, 0.3, 0.4]))
    bad = c.copy()
    bad[8:12] = [np.cos(0.2), np.sin(0.2), 0, 0]  # robot 1 would roll
    with pytest.raises(UnreachableError, match="tilts robot 1.*only yaws"):
        Q.inverse(bad)
    bad = c.copy()
    bad[3:7] *= 1.1
    with pytest.raises(NonUnitError):
        Q.inverse(bad)
    D = DualQuaternionPair()
    cd = D.from_euclidean(np.array([0, 0, 1, 0.1, 0.2, 1.0, 0.3, 0.4]))
    bad = cd.copy()
    bad[0:8] = dq_from_pose([np.cos(0.1), 0, np.sin(0.1), 0], [0, 0, 1])
    with pytest.raises(UnreachableError):
        D.inverse(bad)


def test_segment_direction_matches_eqs_4_5():
    u = segment_direction(0.3, 0.2)
    r = np.r_[u, 0, 0, 0, 0, 0]
    c = EuclideanPair().forward(r)
    assert c[3] == pytest.approx(0.3) and c[4] == pytest.approx(0.2)


# -- inverse(forward(r)) without a hint; huge positions --------------------------------

def random_states(rng, n, wind=40.0):
    r = rng.uniform(-5, 5, (n, 8))
    r[:, [3, 7]] = rng.uniform(-wind, wind, (n, 2))  # wound yaws
    return r


@pytest.mark.parametrize("F", ALL, ids=lambda f: f.name)
def test_round_trip_without_a_hint_10000_states(F):
    """DualQuaternionPair returned another formation for 23 % of random states."""
    r = random_states(np.random.default_rng(3), 10_000)
    back = F.inverse(F.forward(r))
    d = back - r
    d[:, [3, 7]] = g.wrap(d[:, [3, 7]])
    assert np.abs(d).max() < 1e-9


def test_round_trip_without_a_hint_of_opposite_wound_yaws():
    r = np.array([0, 1, 0, 2, 0, -1, 0, -2.0])
    D = DualQuaternionPair()
    assert pair_robot_error(D.inverse(D.forward(r)), r) < 1e-12


@settings(max_examples=60, deadline=None)
@given(r=st.tuples(*(st.floats(-1e3, 1e3) for _ in range(3)), st.floats(-1e3, 1e3),
                   *(st.floats(-1e3, 1e3) for _ in range(3)), st.floats(-1e3, 1e3)).map(np.array))
def test_round_trip_without_a_hint_property(r):
    if pair_separation(r) < 1e-3:
        r[4] += 1.0
    for F in ALL:
        back = F.inverse(F.forward(r))
        assert pair_robot_error(back, r) < 1e-9 * max(1.0, np.abs(r).max()), F.name


def test_quaternion_round_trip_beside_the_minus_i_direction():
    """Segment 1.75e-6 rad from -i (the seed's n_12 = 0/0 point, eqs. (14)-(15)): 1 + a.u
    cancelled and the round trip was 6e-8 m off at 46 m (found by the property test)."""
    r = np.array([-46.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.7520607149571205e-06, 0.0])
    Q = QuaternionPair()
    assert pair_robot_error(Q.inverse(Q.forward(r)), r) < 1e-12 * 46


def test_forward_hint_does_not_change_the_formation():
    """forward with any hint (the formation turned, yaws wound) is an encoding of r itself."""
    D = DualQuaternionPair()
    rng = np.random.default_rng(4)
    r = random_states(rng, 500)
    hint = D.forward(random_states(rng, 500))
    hint[::2, 8:] *= -1  # the other branch
    assert pair_robot_error(D.inverse(D.forward(r, near_c=hint)), r) < 1e-9


@pytest.mark.parametrize("F", ALL, ids=lambda f: f.name)
def test_huge_positions_are_refused_by_name(F):
    """A separation of 2e154 m gave d_c = inf (a wrong frame) or a bare OverflowError."""
    r = np.array([0, 0, 0, 0, 2e154, 0, 0, 0.0])
    with pytest.raises(InvalidInputError, match=r"r\[4\] = 2e\+154"):
        F.forward(r)


def test_euclidean_inverse_has_a_numpydoc_docstring():
    """EuclideanPair.inverse had none."""
    doc = EuclideanPair.inverse.__doc__ or ""
    for section in ("Parameters", "Returns", "Raises", "(..., 8)", "eqs. (1)-(8)"):
        assert section in doc
