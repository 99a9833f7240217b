"""One contract test over every registered controller (control.contract.Controller).

The pair registry ``CONTROLLERS`` (seed 000) and the UGV-UAV controller on each of its
formations (seed 001): ``step == update(init()).u``; B formations in one update equal B
updates (over several ticks, state threaded, for the UGV-UAV controller); no hidden state
(the same inputs from ``init()`` give the same outputs); signals with their declared
columns; a NaN or infinite measurement never reaches the commands.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.control import CONTROLLERS, Reference, UgvUavController
from quatform.control.contract import Controller, Step
from quatform.errors import QuatformError
from quatform.formations import EuclideanPair, UgvUavQuaternion, UgvUavRestricted, UgvUavSpherical

PAIRS = [cls() for cls in CONTROLLERS.values()]
UGV_UAV = [UgvUavController(F()) for F in (UgvUavQuaternion, UgvUavSpherical, UgvUavRestricted)]
E_PAIR = np.array([0.1, 0.2, 1.0, 0.3, 0.4, 1.0, 0.1, 0.2])
E_UAV = np.array([0.2, 0.1, 0.0, 1.5, 0.3, 1.2])


def _pair_inputs(ctrl, n=None, seed=0):
    rng = np.random.default_rng(seed)
    F = ctrl.formation
    c, cd = F.from_euclidean(E_PAIR, rng.normal(size=8) * 0.3)
    shape = () if n is None else (n,)
    r = EuclideanPair().inverse(E_PAIR) + 0.1 * rng.normal(size=shape + (8,))
    ref = Reference(np.broadcast_to(c, shape + c.shape).copy(), np.broadcast_to(cd, shape + cd.shape).copy())
    return r, ref


def _uav_inputs(ctrl, n=None, seed=0):
    rng = np.random.default_rng(seed)
    F = ctrl.formation
    c, cd = F.from_euclidean(E_UAV, 0.1 * rng.normal(size=6))
    r = F.inverse(c)
    m = np.r_[r[0:2], 0.3, r[3:6], 0.1, 0.05, 0.0, 0.0, 0.0]
    shape = () if n is None else (n,)
    m = m + 0.02 * rng.normal(size=shape + (11,))
    return m, Reference(c, cd)


def _check_signals(ctrl, step, batch):
    cols = ctrl.signal_columns()
    assert isinstance(step, Step) and set(step.signals) == set(cols)
    for k, v in step.signals.items():
        assert np.shape(v) == batch + (len(cols[k]),), k
    assert np.shape(step.u) == batch + (len(ctrl.command_names),)


ALL = PAIRS + UGV_UAV
IDS = [f"{c.name}-{type(c.formation).__name__}" for c in ALL]


@pytest.mark.parametrize("ctrl", ALL, ids=IDS)
def test_step_is_update_from_init_and_signals_have_their_columns(ctrl):
    assert isinstance(ctrl, Controller)
    inputs = _pair_inputs if ctrl in PAIRS else _uav_inputs
    m, ref = inputs(ctrl)
    s = ctrl.update(0.0, m, ref, ctrl.init())
    _check_signals(ctrl, s, ())
    np.testing.assert_array_equal(ctrl.step(0.0, m, ref), s.u)
    assert np.all(np.isfinite(s.u)) and s.signals["raw_finite"][0] == 1


@pytest.mark.parametrize("ctrl", PAIRS, ids=[c.name for c in PAIRS])
def test_pair_batch_equals_single_and_no_hidden_state(ctrl):
    r, ref = _pair_inputs(ctrl, 6)
    s = ctrl.update(0.0, r, ref, ctrl.init((6,)))
    _check_signals(ctrl, s, (6,))
    assert ctrl.init((6,)) is None  # stateless
    for i in range(6):
        one = ctrl.update(0.0, r[i], Reference(ref.c[i], ref.c_dot[i]), ctrl.init())
        np.testing.assert_allclose(s.u[i], one.u, rtol=1e-12, atol=1e-12)
        for k in s.signals:
            np.testing.assert_allclose(s.signals[k][i], one.signals[k], rtol=1e-12, atol=1e-12)
    again = ctrl.update(0.0, r, ref, ctrl.init((6,)))
    np.testing.assert_array_equal(again.u, s.u)


@pytest.mark.parametrize("ctrl", UGV_UAV, ids=[type(c.formation).__name__ for c in UGV_UAV])
def test_ugv_uav_batch_equals_single_over_ticks_and_no_hidden_state(ctrl):
    B, T, dt = 3, 5, 0.03
    m, ref = _uav_inputs(ctrl, B)
    m[1, 3:6] = np.nan  # a dropped frame in world 1 (held from tick 1 on)
    runs = []
    for trial in range(2):  # the same inputs from init() twice: the same outputs
        state, out = ctrl.init((B,)), []
        for k in range(T):
            mk = m if k == 0 else np.where(np.isnan(m), m, m + 0.001 * k)
            if k == 0:
                mk = np.where(np.isnan(mk), 0.5, mk)  # a good first frame everywhere
            s = ctrl.update(k * dt, mk, ref, state)
            _check_signals(ctrl, s, (B,))
            state = s.state
            out.append(s)
        runs.append(out)
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a.u, b.u)
    for i in range(B):
        state = ctrl.init()
        for k in range(T):
            mk = m[i] if k == 0 else np.where(np.isnan(m[i]), m[i], m[i] + 0.001 * k)
            if k == 0:
                mk = np.where(np.isnan(mk), 0.5, mk)
            s = ctrl.update(k * dt, mk, ref, state)
            state = s.state
            np.testing.assert_allclose(runs[0][k].u[i], s.u, rtol=1e-12, atol=1e-12)
            for key in s.signals:
                np.testing.assert_allclose(runs[0][k].signals[key][i], s.signals[key], rtol=1e-12, atol=1e-12)
    assert runs[0][-1].signals["held"][1, 0] == 1 and runs[0][-1].signals["held"][0, 0] == 0


@pytest.mark.parametrize("ctrl", ALL, ids=IDS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_measurement_never_reaches_the_commands(ctrl, bad):
    inputs = _pair_inputs if ctrl in PAIRS else _uav_inputs
    m, ref = inputs(ctrl)
    for j in range(m.shape[-1]):
        mj = m.copy()
        mj[j] = bad
        try:
            s = ctrl.update(0.0, mj, ref, ctrl.init())
        except QuatformError:
            continue  # refused in one line: nothing sent
        assert np.all(np.isfinite(s.u)), j


@pytest.mark.parametrize("ctrl", UGV_UAV, ids=[type(c.formation).__name__ for c in UGV_UAV])
def test_a_nan_reference_brakes_and_emergency_stop_is_data(ctrl):
    m, ref = _uav_inputs(ctrl)
    nan = np.full(ctrl.formation.n_c, np.nan)
    s = ctrl.update(0.0, m, Reference(nan, nan), ctrl.init())
    assert s.u[0] == 0 and s.u[1] == 0 and s.u[2] < 0  # the UGV stops, the UAV brakes (v_x > 0)
    assert np.all(np.isnan(s.signals["error"])) and s.signals["stopped"][0] == 0
    st0 = ctrl.init()
    stopped = ctrl.emergency_stop(st0, "joystick")
    assert not st0.stopped and stopped.stopped and stopped.stop_reason == "joystick"
    s = ctrl.update(0.0, m, ref, stopped)
    np.testing.assert_array_equal(s.u[0:2], 0.0)
    assert s.signals["stopped"][0] == 1 and s.state.stopped
    go = ctrl.update(0.0, m, ref, ctrl.release(s.state))
    np.testing.assert_array_equal(go.u, ctrl.step(0.0, m, ref))


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(0.0, 1.0), seed=st.integers(0, 1000))
def test_quaternion_pair_batch_of_random_formations_equals_single(scale, seed):
    ctrl = CONTROLLERS["quaternion"]()
    r, ref = _pair_inputs(ctrl, 4, seed)
    r = EuclideanPair().inverse(E_PAIR) + scale * (r - EuclideanPair().inverse(E_PAIR))
    u = ctrl.step(0.0, r, ref)
    for i in range(4):
        np.testing.assert_allclose(u[i], ctrl.step(0.0, r[i], Reference(ref.c[i], ref.c_dot[i])), atol=1e-12)


def test_cluster_controller_of_a_formation_law_and_team_is_the_cluster_space_controller():
    from quatform.control import ClusterController, ClusterSpaceController
    from quatform.control.laws import Block, BlockLaw
    from quatform.formations import EuclideanPair
    from quatform.errors import InvalidInputError

    k = (1.0, 1.0, 1.0, 10.0, 10.0, 5.0, 5.0, 10.0)
    generic = ClusterController(EuclideanPair(), BlockLaw((Block("proportional", 0, 8, k),)), feedforward=False)
    assert generic.law.feedforward is False  # the controller's setting
    ref_ctrl = ClusterSpaceController(k=k, feedforward=False)
    r, ref = _pair_inputs(ref_ctrl, 4)
    np.testing.assert_array_equal(generic.step(0.0, r, ref), ref_ctrl.step(0.0, r, ref))
    with pytest.raises(InvalidInputError, match="variables"):
        ClusterController(EuclideanPair(), BlockLaw((Block("proportional", 0, 3, k[:3]),)))


def test_ugv_uav_step_takes_a_batch_of_worlds():
    ctrl = UGV_UAV[0]
    m, ref = _uav_inputs(ctrl, 3)
    u = ctrl.step(0.0, m, ref)
    assert u.shape == (3, 6)
    for i in range(3):
        np.testing.assert_allclose(u[i], ctrl.step(0.0, m[i], ref), rtol=1e-12, atol=1e-12)


def test_step_gives_init_the_measurement_batch_whatever_the_command_width():
    """``Controller.step`` took the batch from the measured array only when its width was the
    command width; a controller measuring 3 values and commanding 1 got ``init(())`` for a
    batch of 2 (its state then had the wrong shape)."""
    from quatform.control.contract import Controller, Step

    seen = []

    class Narrow(Controller):
        name = "narrow"
        command_names = ("u",)

        def signal_columns(self):
            return {}

        def init(self, batch=()):
            seen.append(tuple(batch))
            return np.zeros(tuple(batch) + (1,))

        def update(self, t, measured, reference, state):
            return Step(state - np.asarray(measured)[..., :1], state, {})

    u = Narrow().step(0.0, np.ones((2, 3)))
    assert seen == [(2,)] and u.shape == (2, 1)
    Narrow().step(0.0, np.ones(3))
    assert seen[-1] == ()


# -- team controllers: every registered team description --------------------------------------

TEAM_GAINS = {"k_x": (1.0, 1.2, 0.8), "k_d": 2.0, "k_w": (3.0, 3.0, 3.0), "k_dw": (1.5, 1.5, 1.5), "k_p": 1.5,
              "k_theta": 2.0, "k": 1.0}


def _team_controllers():
    from quatform.control import TEAM_CONTROLLERS, team_controller
    from quatform.robots import HolonomicRobot, Team

    return [team_controller(name, Team((HolonomicRobot(),) * n), TEAM_GAINS) for name in TEAM_CONTROLLERS
            for n in (3, 7)]


TEAMS = _team_controllers()
TEAM_IDS = [f"{c.name}-{c.formation.layout.n}" for c in TEAMS]


def _team_inputs(ctrl, batch=(), seed=0):
    """A reference formation, its rate, and robots near it (``batch`` leading axes)."""
    rng = np.random.default_rng(seed)
    F = ctrl.formation
    r_des = F.sample_robot_state(rng)
    e = F.to_chart(F.forward(r_des), r=r_des)
    c, cd = F.from_chart(e, 0.2 * rng.normal(size=e.shape))
    r = F.inverse(c, near_r=r_des) + 0.05 * rng.normal(size=batch + (F.n_r,))
    return r, Reference(np.broadcast_to(c, batch + c.shape).copy(), np.broadcast_to(cd, batch + cd.shape).copy())


@pytest.mark.parametrize("ctrl", TEAMS, ids=TEAM_IDS)
def test_team_step_is_update_batch_equals_single_and_no_hidden_state(ctrl):
    assert isinstance(ctrl, Controller) and ctrl.init() is None
    r, ref = _team_inputs(ctrl)
    s = ctrl.update(0.0, r, ref, ctrl.init())
    _check_signals(ctrl, s, ())
    np.testing.assert_array_equal(ctrl.step(0.0, r, ref), s.u)
    assert np.all(np.isfinite(s.u)) and s.signals["raw_finite"][0] == 1
    rb, refb = _team_inputs(ctrl, (5,), seed=1)
    sb = ctrl.update(0.0, rb, refb, ctrl.init((5,)))
    _check_signals(ctrl, sb, (5,))
    for i in range(5):
        one = ctrl.update(0.0, rb[i], Reference(refb.c[i], refb.c_dot[i]), None)
        np.testing.assert_allclose(sb.u[i], one.u, rtol=1e-12, atol=1e-12)
        for k in sb.signals:
            np.testing.assert_allclose(sb.signals[k][i], one.signals[k], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(ctrl.update(0.0, rb, refb, None).u, sb.u)


@pytest.mark.parametrize("ctrl", TEAMS, ids=TEAM_IDS)
def test_team_zero_error_gives_the_feed_forward_and_errors_vanish(ctrl):
    """Robots exactly at the reference: every error is zero (quaternion errors the identity)
    and the command is the reference's own robot rate."""
    r, ref = _team_inputs(ctrl)
    F = ctrl.formation
    r0 = F.inverse(ref.c)
    s = ctrl.update(0.0, r0, ref, None)
    c_err = s.signals["error"]
    expected = np.zeros_like(c_err)
    for gr in F.law_groups:
        if gr.role in ("attitude", "orientation"):
            expected[gr.index[:, 0]] = np.sign(c_err[gr.index[:, 0]])
        elif gr.role in ("pose", "relative-pose"):
            expected[gr.index[:, 0]] = np.sign(c_err[gr.index[:, 0]])
    np.testing.assert_allclose(c_err, expected, atol=1e-9)
    np.testing.assert_allclose(s.u, ctrl.team.saturate(F.robot_rate(ref.c, ref.c_dot, r=r0)), atol=1e-9)


@pytest.mark.parametrize("ctrl", TEAMS, ids=TEAM_IDS)
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_team_non_finite_measurement_never_reaches_the_commands(ctrl, bad):
    r, ref = _team_inputs(ctrl)
    for j in (0, 3, r.shape[-1] - 1):
        rj = r.copy()
        rj[j] = bad
        try:
            s = ctrl.update(0.0, rj, ref, None)
        except QuatformError:
            continue  # refused in one line: nothing sent
        assert np.all(np.isfinite(s.u)), j


def test_team_controller_bad_arguments_are_one_line():
    from quatform.control import team_controller
    from quatform.errors import InvalidInputError
    from quatform.robots import HolonomicRobot, Team

    team = Team.uniform(HolonomicRobot(), 3)
    for args, match in ((("quaternion", team, [1, 2, 3]), "gains must be a mapping"),
                        (("quaternion", "team", TEAM_GAINS), "must be a robots.Team"),
                        (("quaternon", team, TEAM_GAINS), "did you mean 'quaternion'"),
                        (("quaternion", team, {"k_x": 1.0}), "law needs gains"),
                        (("quaternion", team, {**TEAM_GAINS, "k_w": -1.0}), "must be positive")):
        with pytest.raises(InvalidInputError, match=match):
            team_controller(*args)
