"""UGV-UAV formation of seed 001: robots (Pioneer, Bebop) and the three descriptions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.errors import DegenerateInputError, InvalidInputError, UnreachableError
from quatform.formations import RobotLayout, UgvUavQuaternion, UgvUavRestricted, UgvUavSpherical
from quatform.robots import TABLE2_K, Bebop, Pioneer, yaw_matrix

ALL = [UgvUavSpherical(), UgvUavRestricted(), UgvUavQuaternion()]


def test_spherical_is_singular_with_the_uav_overhead():
    F = UgvUavSpherical()
    r = np.array([0.3, -0.2, 0.0, 0.3, -0.2, 1.5])
    with pytest.raises(DegenerateInputError, match="straight above"):
        F.jacobian(r)
    Ji = F.inverse_jacobian(r)
    assert np.all(np.isfinite(Ji)) and np.linalg.matrix_rank(Ji) == 5
    assert F.singularity_measure(r) < 1e-12
    for eps in (1e-3, 1e-6):
        near = r + np.array([0, 0, 0, eps, 0, 0])
        assert F.singularity_measure(near) < 2 * eps / 1.5
        assert np.abs(F.jacobian(near)[4]).max() > 0.5 / eps  # d alpha / d x_b ~ 1 / (rho cos beta)


def test_quaternion_is_regular_overhead_and_matches_eq_5_3():
    F = UgvUavQuaternion()
    e = np.array([0.0, 0.0, 0.0, 1.5, 0.0, np.pi / 2])
    c = F.from_euclidean(e)
    np.testing.assert_allclose(c[3:7], [np.sqrt(2) / 2, 0, -np.sqrt(2) / 2, 0], atol=1e-15)  # (5.3)
    r = UgvUavSpherical().inverse(e)
    for eps in (0.0, 1e-8, 1e-4):
        rr = r + np.array([0, 0, 0, eps, 0, 0])
        assert F.singularity_measure(rr, near_c=c) > 0.3
        np.testing.assert_allclose(F.inverse_jacobian(rr, near_c=c) @ F.jacobian(rr, near_c=c), np.eye(6), atol=1e-9)


def test_quaternion_seed_forward_behind_the_ugv():
    """(4.28)-(4.29) are 0/0 with the UAV behind the UGV along -x (eta = pi): the §5.3 path
    passes there. With a hint the description is regular."""
    F = UgvUavQuaternion()
    r = np.array([0.0, 0.0, 0.0, -0.75, 0.0, 0.0])
    c0 = F.forward(r)
    assert np.all(np.isfinite(c0))
    e = np.array([0.0, 0.0, 0.0, 0.75, np.pi, 0.0])
    hint = F.from_euclidean(e)
    for dy in (1e-7, -1e-7):
        c = F.forward(r + np.array([0, 0, 0, 0, dy, 0]), near_c=hint)
        np.testing.assert_allclose(np.abs(c[3:7] @ hint[3:7]), 1.0, atol=1e-12)


def test_quaternion_opposite_to_the_hint_and_the_seed_convention_near_minus_x():
    """Exactly opposite the desired segment: the half turn about the desired frame's z axis.
    And the continuity check of the runs is not vacuous: (4.26)-(4.29) without a hint jump
    by about pi between two states 2e-7 rad apart behind the UGV; continued, they do not."""
    from quatform.algebra import q_angle_between

    F = UgvUavQuaternion()
    hint = F.from_euclidean(np.array([0, 0, 0, 0.75, 0.0, 0.0]))  # UAV ahead along +x
    c = F.forward(np.array([0, 0, 0, -0.75, 0, 0.0]), near_c=hint)  # UAV behind
    qe = np.abs(np.array([hint[3], -hint[4], -hint[5], -hint[6]]) @ np.array([[c[3], c[4], c[5], c[6]]]).T)
    assert qe[0] < 1e-12  # a half turn
    a, b = np.array([0, 0, 0, -0.75, 1e-7, 0.0]), np.array([0, 0, 0, -0.75, 0.0, 1e-7])
    assert q_angle_between(F.forward(a)[3:7], F.forward(b)[3:7]) > 3.0
    ca = F.forward(a, near_c=hint)
    assert q_angle_between(ca[3:7], F.forward(b, near_c=ca)[3:7]) < 1e-6


def test_restricted_refuses_the_platform_level_front_configuration():
    F = UgvUavRestricted()
    front = np.array([0.0, 0.0, 0.0, 0.0, 0.75, 0.0])  # UAV ahead at platform level
    with pytest.raises(UnreachableError, match="beta_f = 90.0 deg"):  # forward refuses it too
        F.forward(front)
    c = np.array([0.0, 0.0, 0.0, 0.75, 0.0, math.pi / 2])  # what (4.13)-(4.18) give there
    with pytest.raises(UnreachableError, match="beta_f = 90.0 deg"):
        F.inverse(c)
    with pytest.raises(UnreachableError, match="outside the restricted"):
        F.from_euclidean(np.array([0, 0, 0, 0.75, np.pi / 2, 0.0]))
    # overhead is fine (alpha_f = beta_f = 0)
    over = F.from_euclidean(np.array([0, 0, 0, 1.5, 0.0, np.pi / 2]))
    np.testing.assert_allclose(over[4:], 0.0, atol=1e-12)
    assert np.all(np.isfinite(F.inverse(over)))


def test_descriptions_agree_on_the_robots():
    e = np.array([0.2, -0.1, 0.0, 1.2, 0.4, 1.1])
    r = UgvUavSpherical().inverse(e)
    for F in ALL:
        np.testing.assert_allclose(F.inverse(F.from_euclidean(e)), r, atol=1e-12)
        np.testing.assert_allclose(F.euclidean(F.from_euclidean(e), near_e=e), e, atol=1e-12)


def test_coincident_robots_refused():
    for F in ALL:
        with pytest.raises(DegenerateInputError, match="coincide"):
            F.forward(np.zeros(6))


def test_messages_name_the_ugv_and_the_uav_not_the_column_suffixes():
    for F in ALL:
        for call in (F.forward, F.singularity_measure):
            with pytest.raises(DegenerateInputError, match="robots UGV and UAV coincide") as info:
                call(np.zeros(6))
            assert "_p" not in str(info.value) and "_b" not in str(info.value)
    assert UgvUavSpherical().layout.names == ("x_p", "y_p", "z_p", "x_b", "y_b", "z_b")  # the columns keep theirs
    assert RobotLayout(("xyz", "xyz"), labels=("_p", "_b")).display_names == ("_p", "_b")  # default: the labels
    with pytest.raises(InvalidInputError, match="1 display names for 2 robots"):
        RobotLayout(("xyz", "xyz"), display_names=("UGV",))


# -- robots ------------------------------------------------------------------------------------

def test_pioneer_step_is_the_exact_unicycle():
    p = Pioneer()
    s0, u = np.array([0.2, -0.1, 0.3]), np.array([0.5, 0.8])
    x, n = s0.copy(), 20000
    for _ in range(n):  # fine Euler of eq. (3.4) with psi_dot = omega
        x = x + (1.0 / n) * np.r_[p.forward_matrix(x[2]) @ u, u[1]]
    np.testing.assert_allclose(p.step(s0, u, 1.0), x, atol=5e-5)
    straight = p.step(s0, np.array([0.5, 0.0]), 2.0)
    np.testing.assert_allclose(straight, s0 + np.array([np.cos(0.3), np.sin(0.3), 0]) * [1.0, 1.0, 0], atol=1e-12)


def test_pioneer_inverse_kinematics_eq_3_5():
    p = Pioneer()
    psi = np.linspace(-3, 3, 7)
    xy = np.stack([np.cos(psi * 2), np.sin(psi)], -1)
    vw = p.commands_from_velocity(psi, xy)
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", p.forward_matrix(psi), vw), xy, atol=1e-12)
    sat = p.saturate(np.array([3.0, 0.5]))
    assert abs(sat[0]) <= p.max_v + 1e-12 and sat[1] / sat[0] == pytest.approx(0.5 / 3.0)
    np.testing.assert_array_equal(p.saturate(np.array([np.nan, 1.0])), [0.0, 0.0])


def test_bebop_dynamics_table2():
    b = Bebop()
    assert b.k == TABLE2_K
    np.testing.assert_allclose(b.max_velocity, np.array(TABLE2_K[0::2]) / np.array(TABLE2_K[1::2]))
    s = np.zeros(8)
    u = np.array([0.2, -0.1, 0.3, 0.1])
    for _ in range(6000):
        s = b.step(s, u, 0.01)
    np.testing.assert_allclose(s[4:], b.k_u / b.k_v * u, rtol=1e-4)  # steady state of (3.11)
    slow = Bebop(max_fraction=0.4)
    np.testing.assert_allclose(slow.saturate(np.array([1.0, -1.0, 0.2, 0.5])), [0.4, -0.4, 0.2, 0.4])
    np.testing.assert_array_equal(b.saturate(np.array([np.inf, 0, 0, 0])), np.zeros(4))
    # world velocity = A_b body velocity (3.9)
    s = np.array([0, 0, 0, 0.7, 1.0, 0.0, 0.0, 0.0])
    s1 = Bebop(dynamic=False).step(s, np.array([b.k_v[0] / b.k_u[0], 0, 0, 0]), 0.01)
    np.testing.assert_allclose(s1[0:2] / 0.01, (yaw_matrix(0.7) @ [1.0, 0, 0, 0])[0:2], atol=1e-12)


# -- the restricted description refuses what it cannot express; huge finite positions ----------------

def test_restricted_refuses_the_uav_below_the_platform_single_and_batch():
    F = UgvUavRestricted()
    below = np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.966])  # 0.966 m below the platform
    with pytest.raises(UnreachableError, match=r"z_b - z_p = -0.966 m: the UAV is below the platform.*quaternion"):
        F.forward(below)
    above = below * np.array([1, 1, 1, 1, 1, -1])
    batch = np.stack([above, below, above])
    with pytest.raises(UnreachableError, match=r"-0.966 m at index \(1,\)"):
        F.forward(batch)
    np.testing.assert_allclose(F.inverse(F.forward(above)), above, atol=1e-12)
    np.testing.assert_array_equal(F.outside(batch), [False, True, False])
    # a cluster state whose (4.24) has no real root is refused, not clipped to platform level
    wide = UgvUavRestricted(range_deg=(-90.0, 90.0))
    with pytest.raises(UnreachableError, match="no real root"):
        wide.inverse(np.array([[0, 0, 0, 1.0, 0.2, 0.2], [0, 0, 0, 1.0, 1.0, 1.0]]))
    with pytest.raises(UnreachableError, match="below the platform"):
        F.from_euclidean(np.array([0, 0, 0, 1.0, 0.3, -0.2]))


@settings(max_examples=200, deadline=None)
@given(d=st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-2, 2)))
def test_restricted_forward_and_inverse_agree_on_their_domain(d):
    F = UgvUavRestricted()
    r = np.r_[0.1, -0.2, 0.0, np.array([0.1, -0.2, 0.0]) + np.array(d)]
    if np.linalg.norm(d) < 1e-3:
        return
    if F.outside(r):
        with pytest.raises(UnreachableError):
            F.forward(r)
    else:  # every state forward accepts comes back from inverse (to rho sqrt(eps) at platform
        # level, where the root of (4.24) amplifies round-off: 2e-8 m at the 45/45 deg corner)
        np.testing.assert_allclose(F.inverse(F.forward(r)), r, atol=1e-7)


@pytest.mark.parametrize("F", [UgvUavSpherical(), UgvUavRestricted(), UgvUavQuaternion()], ids=lambda f: f.name)
def test_huge_positions_are_refused_not_overflowed(F):
    r = np.array([0, 0, 0, 1e154, 1e154, 1e154])
    for f in (F.forward, F.jacobian, F.singularity_measure):
        with pytest.raises(InvalidInputError, match=r"r\[3\] = 1e\+154 is beyond the 1e\+150"):
            f(r)
    c = np.zeros(F.n_c)
    c[3] = 1.0 if F.name == "quaternion" else 1e154
    c[-3 if F.name == "quaternion" else 0] = 1e154
    with pytest.raises(InvalidInputError, match="beyond the 1e\\+150"):
        F.inverse(c)
    ok = np.array([0, 0, 0, 1e140, 1e140, 1e140]) * (1 if F.name != "restricted" else 1)
    if F.name != "restricted":
        assert np.all(np.isfinite(F.forward(ok)))


def test_restricted_rate_maps_refuse_what_forward_refuses():
    """jacobian([0, 0, 0, 0.5, 0.5, -0.966]) returned a 6 x 6 matrix (of the state mirrored
    above the platform) while forward refused it."""
    F = UgvUavRestricted()
    r = np.array([0, 0, 0, 0.5, 0.5, -0.966])
    for f in (F.forward, F.jacobian, F.inverse_jacobian, F.singularity_measure):
        with pytest.raises(UnreachableError, match=r"r: z_b - z_p = -0\.966 m: the UAV is below the platform"):
            f(r)
    c_up = F.forward(r * [1, 1, 1, 1, 1, -1])
    with pytest.raises(UnreachableError, match="below the platform"):
        F.inverse_jacobian_at(c_up, r=r)
    with pytest.raises(UnreachableError, match="alpha_f = 70.5 deg is outside"):
        F.inverse_jacobian_at(c_up + [0, 0, 0, 0, 0.8, 0])  # what inverse refuses
    assert F.inverse_jacobian_at(c_up, r=r * [1, 1, 1, 1, 1, -1]).shape == (6, 6)


robot_pair = st.tuples(*(st.floats(-2.0, 2.0) for _ in range(6))).map(np.array)


@settings(max_examples=150, deadline=None)
@given(r=robot_pair)
def test_restricted_rate_maps_exist_exactly_where_forward_does(r):
    """One check for all: on random robot pairs (UAV above and below, angles in and out of
    range), jacobian, inverse_jacobian and singularity_measure raise iff forward raises."""
    F = UgvUavRestricted()
    if np.linalg.norm(r[3:6] - r[0:3]) < 0.05:
        return  # robots on each other: refused by every map alike, not the point here

    def refused(f):
        try:
            f(r)
        except UnreachableError:
            return True
        return False

    expected = refused(F.forward)
    assert expected == bool(F.outside(r))
    assert refused(F.jacobian) == expected and refused(F.inverse_jacobian) == expected
    assert refused(F.singularity_measure) == expected
