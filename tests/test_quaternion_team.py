"""QuaternionTeam: seed 000 §3.2 for N robots of any point kinds.

The formation contract (``formations.testing.check_formation``) for N = 2, 3, 4, 10 and a
mixed layout; N = 2 against :class:`QuaternionPair` (maps and the seed's spiral and helix
runs); the special sets at and near each point, batch and single; the fit's properties
that make the shape law work (stationarity, the envelope rate); zero error only at the
reference; the team controller's Lyapunov function; bad input.
"""

from __future__ import annotations

import numpy as np
import pytest

from quatform.errors import DegenerateInputError, InvalidInputError, NonUnitError, ShapeError, UnreachableError
from quatform.formations import QuaternionPair, RobotLayout
from quatform.formations import geometry as g
from quatform.formations.quaternion_team import QuaternionTeam
from quatform.formations.testing import check_formation, cluster_distance, robot_distance

MIXED = RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz"))
TETRAHEDRON = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])


def _teams():
    return {"2": QuaternionTeam(2), "3": QuaternionTeam(3), "4": QuaternionTeam(4), "10": QuaternionTeam(10),
            "mixed": QuaternionTeam(layout=MIXED), "pair-chart": QuaternionTeam(2, chart="pair"),
            "tetrahedron": QuaternionTeam(4, template=TETRAHEDRON),
            "mixed-6": QuaternionTeam(layout=RobotLayout(("pose", "xy_yaw", "xy_yaw", "xyz", "xyz_yaw", "pose")))}


TEAMS = _teams()


def _random_unit(rng, shape=()):
    q = rng.normal(size=tuple(shape) + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# -- the formation contract -----------------------------------------------------------------------

@pytest.mark.parametrize("key", sorted(TEAMS))
@pytest.mark.parametrize("seed", [0, 1])
def test_contract(key, seed):
    check_formation(TEAMS[key], np.random.default_rng(seed), n=24)


class _GroundSampled(QuaternionTeam):
    """QuaternionTeam whose random states put planar robots on the ground before pushing robots
    apart (Formation.sample_robot_state pushes them apart in 3-D and then drops the planar z, so
    two ground robots can land within the contract test's 0.1 m)."""

    def sample_robot_state(self, rng, batch=()):
        batch = (int(batch),) if isinstance(batch, (int, np.integer)) else tuple(batch)
        L = self.layout
        ground = [i for i, k in enumerate(L.kinds) if k == "xy_yaw"]
        p = rng.uniform(-2.0, 2.0, batch + (L.n, 3))
        p[..., ground, 2] = 0.0
        i, j = L.pairs
        for _ in range(200):
            close = np.any(np.linalg.norm(p[..., i, :] - p[..., j, :], axis=-1) < 0.3, axis=-1)
            if not np.any(close):
                break
            fresh = rng.uniform(-2.0, 2.0, p.shape)
            fresh[..., ground, 2] = 0.0
            p = np.where(close[..., None, None], fresh, p)
        q = rng.normal(size=batch + (len(L.orientation_index), 4))
        return L.compose(p, rng.uniform(-20.0, 20.0, batch + (len(L.yaw_indices),)),
                         q / np.linalg.norm(q, axis=-1, keepdims=True))


@pytest.mark.parametrize("kinds", [("xy_yaw",) * 2, ("xy_yaw",) * 5, ("pose", "xy_yaw", "xy_yaw", "xyz", "xyz_yaw")])
def test_contract_ground_teams(kinds):
    for seed in (0, 1, 2):
        check_formation(_GroundSampled(layout=RobotLayout(kinds)), np.random.default_rng(seed), n=24)


def test_variables_and_groups():
    F = QuaternionTeam(layout=MIXED)
    names = F.names
    assert names[:7] == ("x_c", "y_c", "z_c", "q_c_w", "q_c_x", "q_c_y", "q_c_z")
    assert names[7:10] == ("s1_x", "s1_y", "s1_z") and names[16:19] == ("s4_x", "s4_y", "s4_z")
    assert names[19:] == tuple(f"q_c{i}_{a}" for i in (1, 2, 3) for a in "wxyz")  # no heading for the xyz robot
    assert F.n_c == 7 + 3 * 4 + 4 * 3
    roles = {gr.role: gr.index.shape for gr in F.law_groups}
    assert roles == {"centroid": (1, 3), "attitude": (1, 4), "shape": (4, 3), "orientation": (3, 4)}
    covered = np.sort(np.concatenate([gr.index.ravel() for gr in F.law_groups]))
    np.testing.assert_array_equal(covered, np.arange(F.n_c))
    assert F.sign_free == (slice(3, 7), slice(19, 23), slice(23, 27), slice(27, 31))
    assert QuaternionTeam(3).layout == RobotLayout.uniform("xyz_yaw", 3)
    assert F.chart_variables == F.chart.variables


# -- N = 2 is the seed -----------------------------------------------------------------------------

def _tangent(c, w, blocks=(slice(3, 7), slice(8, 12), slice(12, 16))):
    w = np.array(w)
    for sl in blocks:
        q = c[..., sl]
        w[..., sl] -= q * np.sum(q * w[..., sl], axis=-1, keepdims=True)
    return w


def test_the_pair_is_the_separation_shape_with_the_pair_chart():
    """QuaternionPair is QuaternionTeam(2, shape="separation", chart="pair"): seed 000's state
    (x_c, q_c, d_c, q_c1, q_c2) and names, one implementation; the shape is two xyz_yaw robots'
    and is read in the pair chart."""
    P = QuaternionPair()
    assert isinstance(P, QuaternionTeam) and (P.shape, P.chart_name) == ("separation", "pair")
    assert P.n_c == 16 and P.names[7] == "d_c" and P.component_kernels and not P.team
    assert [grp.role for grp in P.law_groups] == ["centroid", "attitude", "separation", "orientation"]
    with pytest.raises(InvalidInputError, match="two xyz_yaw robots"):
        QuaternionTeam(3, shape="separation", chart="pair")
    with pytest.raises(InvalidInputError, match="give chart='pair'"):
        QuaternionTeam(2, shape="separation")
    with pytest.raises(InvalidInputError, match="shape 'ring' unknown"):
        QuaternionTeam(2, shape="ring")
    with pytest.raises(InvalidInputError, match="frame state"):
        P.to_pair(P.forward(P.sample_robot_state(np.random.default_rng(0))))


def test_two_robots_are_the_quaternion_pair():
    """Forward (with and without a hint), inverse, the rates on the state's own branch and the
    inverse's rate along unit-preserving directions equal QuaternionPair's, within 1e-12."""
    P, T = QuaternionPair(), QuaternionTeam(2)
    rng = np.random.default_rng(5)
    r = P.sample_robot_state(rng, (200,))
    cp_near = P.forward(P.sample_robot_state(rng, (200,)))
    for near in (None, cp_near):
        a = T.forward(r, near_c=None if near is None else T.from_pair(near))
        np.testing.assert_allclose(a, T.from_pair(P.forward(r, near_c=near)), rtol=0, atol=1e-12)
    cp = P.forward(r, near_c=cp_near)
    np.testing.assert_allclose(T.inverse(T.from_pair(cp), near_r=r), P.inverse(cp, near_r=r), rtol=0, atol=1e-12)
    np.testing.assert_allclose(T.to_pair(T.from_pair(cp)), cp, rtol=0, atol=1e-12)
    v = rng.normal(size=r.shape)
    cp0 = P.forward(r)
    a = T.cluster_rate(r, v, near_c=T.from_pair(cp0))
    np.testing.assert_allclose(a, T.from_pair(cp0, P.cluster_rate(r, v, near_c=cp0))[1], rtol=0, atol=1e-12)
    w = _tangent(cp, rng.normal(size=cp.shape))
    np.testing.assert_allclose(T.robot_rate(T.from_pair(cp), T.from_pair(cp, w)[1]), P.robot_rate(cp, w),
                               rtol=0, atol=1e-12)


def test_team_cluster_rate_is_the_derivative_for_any_hint():
    """With a hint on another branch than the state's, the fit's twist moves with the segment;
    the team's cluster_rate includes that (central differences agree)."""
    T = QuaternionTeam(2)
    rng = np.random.default_rng(6)
    r = T.sample_robot_state(rng, (50,))
    near = T.forward(T.sample_robot_state(rng, (50,)))
    v, h = rng.normal(size=r.shape), 1e-6
    fd = (T.forward(r + h * v, near_c=near) - T.forward(r - h * v, near_c=near)) / (2 * h)
    np.testing.assert_allclose(T.cluster_rate(r, v, near_c=near), fd, rtol=0, atol=1e-7)


def test_pair_chart_round_trip_and_rates():
    """chart='pair': seed 000's Euclidean variables through QuaternionPair's chart."""
    P, T = QuaternionPair(), QuaternionTeam(2, chart="pair")
    rng = np.random.default_rng(7)
    e = np.concatenate([rng.uniform(-1, 1, (20, 5)), rng.uniform(0.3, 2, (20, 1)), rng.uniform(-3, 3, (20, 2))], -1)
    e_dot = rng.normal(size=e.shape)
    c, cd = T.from_chart(e, e_dot)
    cp, cpd = P.from_chart(e, e_dot)
    np.testing.assert_allclose(c, T.from_pair(cp), rtol=0, atol=1e-14)
    np.testing.assert_allclose(cd, T.from_pair(cp, cpd)[1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(T.to_chart(c, near_e=e), P.to_chart(cp, near_e=e), rtol=0, atol=1e-12)
    assert T.chart_variables == P.chart_variables


# -- the fit -----------------------------------------------------------------------------------------

def test_fit_is_stationary_and_the_shape_residual_has_the_envelope_rate():
    """At c = forward(r, near_c=ref): sum s_des,i x s_i = 0 (the fit's stationarity), so the
    rate of sum |s_i - s_des,i|^2 is 2 sum (s - s_des) . R^T (v_i - mean v), the fit's rate
    dropping out (docs/derivations.md, "The quaternion team")."""
    T = QuaternionTeam(4, template=TETRAHEDRON)
    rng = np.random.default_rng(8)
    r = T.sample_robot_state(rng, (30,))
    ref = T.forward(T.sample_robot_state(rng, (30,)))
    c = T.forward(r, near_c=ref)
    s, sd = c[:, T.shape_index], ref[:, T.shape_index]
    np.testing.assert_allclose(np.sum(np.cross(sd, s), axis=1), 0.0, atol=1e-12)
    v = rng.normal(size=r.shape)
    cd = T.cluster_rate(r, v, near_c=ref)
    rate = 2 * np.sum((s - sd) * cd[:, T.shape_index], axis=(1, 2))
    p_dot = T.layout.positions(v)
    cen_dot = p_dot - p_dot.mean(axis=1, keepdims=True)
    q = c[:, 3:7]
    envelope = 2 * np.sum((s - sd) * g.rotate(g.conj(q)[:, None, :], cen_dot), axis=(1, 2))
    np.testing.assert_allclose(rate, envelope, rtol=1e-9, atol=1e-9)


def test_shape_law_turns_the_fit_with_the_commanded_rate():
    """Robots moved by robot_rate(c, c_dot) with s_dot = -k (s - s_des) and any omega: the fit's
    attitude moves at exactly the commanded q_c_dot (the fit is unique here) and the shape at s_dot."""
    T = QuaternionTeam(4, template=TETRAHEDRON)
    rng = np.random.default_rng(9)
    ref = T.forward(T.sample_robot_state(rng, (20,)))
    r = T.inverse(ref) + 0.1 * rng.normal(size=(20, T.n_r))
    c = T.forward(r, near_c=ref)
    cd = np.zeros_like(c)
    q = c[:, 3:7]
    omega = rng.normal(size=(20, 3))
    cd[:, 3:7] = 0.5 * g.mul(q, np.concatenate([np.zeros((20, 1)), omega], -1))
    cd[:, T.shape_index] = -3.0 * (c[:, T.shape_index] - ref[:, T.shape_index])
    realised = T.cluster_rate(r, T.robot_rate(c, cd), near_c=ref)
    np.testing.assert_allclose(realised[:, :T.orientation_index[0, 0]], cd[:, :T.orientation_index[0, 0]],
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize("key", ["3", "4", "10", "tetrahedron", "mixed", "mixed-6"])
def test_zero_error_only_at_the_reference(key):
    """Robots at the reference formation read zero error; a half-turn twin (the formation
    turned by pi) and a mirror twin do not."""
    T = TEAMS[key]
    rng = np.random.default_rng(10)
    n = 40
    c_des = T.forward(T.sample_robot_state(rng, (n,)))
    r = T.inverse(c_des)
    assert np.max(cluster_distance(T, T.forward(r, near_c=c_des), c_des)) < 1e-12
    # the half-turn twin: the formation turned by pi about a random axis through its centroid
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    half = np.concatenate([np.zeros((n, 1)), axis], -1)
    twin = np.array(c_des)
    twin[:, 3:7] = g.mul(c_des[:, 3:7], half)
    if T.layout.kinds.count("xy_yaw") == 0:
        rt = T.inverse(T.from_chart(T.to_chart(twin)))
        ct = T.forward(rt, near_c=c_des)
        assert np.min(cluster_distance(T, ct, c_des)) > 1e-3
    # a mirror twin: the shape reflected in the formation's x-y plane
    mirror = np.array(c_des)
    s = mirror[:, T.shape_index]
    s[..., 2] *= -1
    mirror[:, T.shape_index] = s
    planar = np.max(np.abs(c_des[:, T.shape_index][..., 2]), axis=-1) > 1e-6  # a mirror that is a rotation
    if T.layout.kinds.count("xy_yaw") == 0:
        cm = T.forward(T.inverse(mirror), near_c=c_des)
        assert np.all(cluster_distance(T, cm, c_des)[planar] > 1e-3)


def test_collinear_robots_take_the_twist_from_the_hint():
    """Collinear robots, non-collinear reference shape: every attitude turning the line's
    best-fitting direction onto the robots' line fits equally; the one nearest the hint is taken,
    and the forward map is continuous through the line with the hint held."""
    T = QuaternionTeam(4, template=TETRAHEDRON)
    rng = np.random.default_rng(11)
    u = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    line = np.array([-1.5, -0.4, 0.6, 1.3])
    p = 0.2 + line[:, None] * u
    r = T.layout.compose(p, rng.uniform(-3, 3, 4))
    ref = T.forward(T.inverse(T.from_chart(np.concatenate([[0, 0, 0], _random_unit(rng),
                                                           (TETRAHEDRON - TETRAHEDRON.mean(0)).ravel(),
                                                           rng.uniform(-3, 3, 4)]))))
    c = T.forward(r, near_c=ref)
    q = c[3:7]
    # the fit's attitude maps some template direction onto the line; every twist about the line fits
    # as well; the hint's is the one nearest it: q is the hint's projection on that circle
    for t in np.linspace(-np.pi, np.pi, 9):
        twist = np.concatenate([[np.cos(t / 2)], np.sin(t / 2) * u])
        other = g.mul(twist, q)
        assert np.dot(other, ref[3:7]) <= np.dot(q, ref[3:7]) + 1e-12
        s_other = g.rotate(g.conj(other)[None, :], p - p.mean(0))
        s_q = g.rotate(g.conj(q)[None, :], p - p.mean(0))
        score = np.sum(s_other * ref[T.shape_index]), np.sum(s_q * ref[T.shape_index])
        assert abs(score[0] - score[1]) < 1e-12
    # through the line (offsets t w, t from -2e-8 to 2e-8 of the size): continuous, the hint's
    # projection on the line, the best fit off it (a half turn of the twist apart on the two sides,
    # the template's mirror image being fitted by a half turn), turning within the fit's tie window
    w = rng.normal(size=p.shape)
    w -= np.sum(w * u, axis=-1, keepdims=True) * u
    size = np.max(np.abs(line))
    ts = np.linspace(-2e-8, 2e-8, 4001) * size
    path = T.forward(T.layout.compose(p + ts[:, None, None] * w, np.broadcast_to(T.layout.yaws(r), (4001, 4))),
                     near_c=ref)
    assert np.max(cluster_distance(T, path[1:], path[:-1])) < 0.02  # q_ci may change sign: q vs -q
    np.testing.assert_allclose(path[2000], c, atol=1e-12)
    for k in (0, -1):  # the best fit: Horn's top eigenvector, a better score than the hint's projection
        rk = T.layout.compose(p + ts[k] * w, T.layout.yaws(r))
        assert cluster_distance(T, path[k], T.forward(rk, near_c=np.concatenate([ref[:3], path[k][3:]]))) < 1e-9


def test_mirror_tie_is_broken_by_the_hint():
    """Robots at the mirror image of an isotropic template (a regular tetrahedron: the best
    proper rotations of a mirror image tie): the fit is the hint's projection on the tied
    eigenvectors of Horn's matrix, and continuous along a path through the tie (turning to the
    best fit of each side within the tie window)."""
    from quatform.formations.team_chart import horn_matrix

    T = QuaternionTeam(4, template=TETRAHEDRON)
    rng = np.random.default_rng(12)
    t = TETRAHEDRON - TETRAHEDRON.mean(0)
    p = t * np.array([1.0, 1.0, -1.0])
    lam, V = np.linalg.eigh(horn_matrix(t, p))
    top = V[:, lam > lam[-1] - 1e-9]
    assert top.shape[1] >= 2  # a tie
    base = T.forward(T.layout.compose(t, np.zeros(4)))
    w = rng.normal(size=p.shape)
    ts = np.linspace(-2e-8, 2e-8, 2001)
    for _ in range(3):
        hint = np.array(base)
        hint[3:7] = _random_unit(rng)
        c = T.forward(T.layout.compose(p + 1.0, np.zeros(4)), near_c=hint)
        proj = top @ (top.T @ hint[3:7])
        np.testing.assert_allclose(c[3:7], proj / np.linalg.norm(proj), atol=1e-9)
        path = T.forward(T.layout.compose(p + 1.0 + ts[:, None, None] * w, np.zeros((2001, 4))), near_c=hint)
        assert np.all(np.isfinite(path))
        assert np.max(cluster_distance(T, path[1:], path[:-1])) < 0.02


# -- the special sets: at and near each, batch and single ---------------------------------------------

@pytest.mark.parametrize("key", ["2", "3", "10", "mixed", "tetrahedron"])
def test_special_sets_continuous_batch_and_single(key):
    """Each declared special set at eps = 0 and 1e-9, 1e-6 from it (the same draws): forward
    finite and continuous with the hint held (the on-set state's own cluster state), the
    round trip without a hint exact (yaws mod 2 pi), and a batch equal to a loop."""
    T = TEAMS[key]
    for sset in T.special_sets():
        r0 = sset.states(np.random.default_rng(3), 6, 0.0)
        c0 = T.forward(r0)
        # near collinear robots with a non-collinear template the twist turns within the fit's
        # tie window (test_collinear_robots_take_the_twist_from_the_hint): continuous, not Lipschitz
        lipschitz = sset.name != "collinear" or T.layout.n == 2 or key == "tetrahedron-line"
        for eps in (0.0, 1e-9, 1e-6):
            r = sset.states(np.random.default_rng(3), 6, eps)
            c = T.forward(r, near_c=c0)
            assert np.all(np.isfinite(c)), sset.name
            if lipschitz:
                assert np.max(cluster_distance(T, c, c0)) < 1e4 * eps + 1e-9, (sset.name, eps)
            free = T.forward(r)
            assert np.max(robot_distance(T, T.inverse(free), r)) < sset.round_trip_tol, (sset.name, eps)
            rates = T.cluster_rate(r, np.ones_like(r), near_c=c0)
            inv = T.inverse(free)
            for i in (0, 3, 5):
                np.testing.assert_allclose(T.forward(r[i], near_c=c0[i]), c[i], rtol=0, atol=1e-12)
                np.testing.assert_allclose(T.inverse(free[i]), inv[i], rtol=0, atol=1e-12)
                np.testing.assert_allclose(T.cluster_rate(r[i], np.ones_like(r[i]), near_c=c0[i]), rates[i],
                                           rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(rates[i]))))


def test_pair_anti_x_without_hint_takes_the_half_turn():
    """Two robots with x1 - x2 along -x, no hint: seed 000 eqs. (14)-(15) are 0/0; the fit takes
    the half turn about z (QuaternionPair's rule), q_c = (0, 0, 0, 1)."""
    T = QuaternionTeam(2)
    r = np.array([-1.0, 0.0, 0.5, 0.3, 1.0, 0.0, 0.5, -0.2])
    c = T.forward(r)
    np.testing.assert_allclose(np.abs(c[3:7]), [0, 0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(c, T.from_pair(QuaternionPair().forward(r)), atol=1e-14)


# -- bad input --------------------------------------------------------------------------------------

def _one_line(exc):
    msg = str(exc.value)
    assert "\n" not in msg and len(msg) < 400
    return msg


def test_bad_input_is_one_line_naming_the_value_and_the_fix():
    with pytest.raises(ShapeError) as e:
        QuaternionTeam(3, template=np.zeros((4, 3)))
    assert "(..., 3, 3)" in _one_line(e)
    with pytest.raises(DegenerateInputError) as e:
        QuaternionTeam(3, template=[[0, 0, 0], [0, 0, 0], [1, 0, 0]])
    assert "robots 1 and 2" in _one_line(e)
    with pytest.raises(InvalidInputError) as e:
        QuaternionTeam(3, template=[[0, 0, np.nan], [0, 1, 0], [1, 0, 0]])
    assert "NaN" in _one_line(e)
    with pytest.raises(InvalidInputError) as e:
        QuaternionTeam(layout=MIXED, chart="pair")
    assert "chart='team'" in _one_line(e)
    with pytest.raises(InvalidInputError) as e:
        QuaternionTeam(3, chart="euclid")
    assert "team, pair" in _one_line(e)
    with pytest.raises(InvalidInputError) as e:
        QuaternionTeam(layout=RobotLayout(("xyz_yaw",)))
    assert "at least 2 robots" in _one_line(e)
    with pytest.raises(InvalidInputError):
        QuaternionTeam(3, layout=MIXED)
    T = QuaternionTeam(3)
    r = T.sample_robot_state(np.random.default_rng(0), (2,))
    bad = np.array(r)
    bad[1, 4:7] = bad[1, 0:3]
    with pytest.raises(DegenerateInputError) as e:
        T.forward(bad)
    assert "robots 1 and 2 coincide" in _one_line(e)
    bad = np.array(r)
    bad[0, 5] = np.nan
    with pytest.raises(InvalidInputError) as e:
        T.forward(bad)
    assert "NaN" in _one_line(e) or "nan" in _one_line(e).lower()
    c = T.forward(r)
    c2 = np.array(c)
    c2[0, 3:7] *= 1.1
    with pytest.raises(NonUnitError) as e:
        T.inverse(c2)
    assert "q_c" in _one_line(e)
    tilted = np.array(c)
    tilted[0, T.orientation_index[1]] = g.mul(tilted[0, T.orientation_index[1]], [np.cos(0.1), np.sin(0.1), 0, 0])
    with pytest.raises(UnreachableError) as e:
        T.inverse(tilted)
    assert "robot 2" in _one_line(e)
    c3 = np.array(c)
    c3[0, T.shape_index[2]] = c3[0, T.shape_index[0]]
    with pytest.raises(DegenerateInputError) as e:
        T.inverse(c3)
    assert "s_i" in _one_line(e)
    M = QuaternionTeam(layout=MIXED)
    cm = M.forward(M.sample_robot_state(np.random.default_rng(1)))
    cm[M.shape_index[1, 2]] += 0.5
    with pytest.raises(UnreachableError) as e:
        M.inverse(cm)
    assert "planar robot 2" in _one_line(e)


def test_fit_rate_uses_fit_attitudes_weights():
    """The fit's rate differentiates fit_attitude's eigenvector weights: its attitude equals
    fit_attitude's across the tie window (robots 1e-10 .. 1e-5 of their size off a line, a
    non-collinear template), and its rate equals central differences there."""
    from quatform.formations.team_chart import fit_attitude

    T = QuaternionTeam(4, template=TETRAHEDRON)
    rng = np.random.default_rng(14)
    u = np.array([0.6, 0.0, 0.8])
    base = np.array([-1.5, -0.4, 0.6, 1.3])[:, None] * u
    w = rng.normal(size=base.shape)
    w -= np.sum(w * u, axis=-1, keepdims=True) * u
    hint = _random_unit(rng)
    tmpl = T.template
    for eps in (1e-10, 1e-9, 3e-9, 1e-8, 1e-7, 1e-5):
        cen = base + eps * w
        cen = cen - cen.mean(0)
        v = rng.normal(size=cen.shape)
        v -= v.mean(0)
        q, q_dot = T._fit_rate(tmpl, cen, v, hint)
        np.testing.assert_allclose(q, fit_attitude(tmpl, cen, hint), rtol=0, atol=1e-14)
        h = 1e-3 * eps  # within the window the weights change over a gap of 1e-9 of the size
        fd = (fit_attitude(tmpl, cen + h * v, hint) - fit_attitude(tmpl, cen - h * v, hint)) / (2 * h)
        # central differences: truncation ~1e-6, rounding ~1e-16 / h
        assert np.max(np.abs(q_dot - fd)) <= (1e-4 + 1e-15 / h) * max(1.0, np.max(np.abs(fd))), eps


@pytest.mark.parametrize("key", ["2", "3", "10", "tetrahedron", "mixed", "mixed-6", "pair-chart"])
def test_singularity_measure_is_the_dense_one(key):
    """The O(N) singularity measure (J J^T = D + U U^T on an invariant subspace of at most 14
    dimensions) equals Formation's, sigma_min / sigma_max of the dense inverse Jacobian."""
    from quatform.formations.base import Formation

    T = TEAMS[key]
    rng = np.random.default_rng(15)
    r = T.sample_robot_state(rng, (2, 10))
    near = T.forward(T.sample_robot_state(rng, (2, 10)))
    for nc in (None, near):
        np.testing.assert_allclose(T.singularity_measure(r, near_c=nc), Formation.singularity_measure(T, r, near_c=nc),
                                   rtol=0, atol=1e-12)
