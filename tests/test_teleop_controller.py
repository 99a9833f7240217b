"""Seed 003's controller as one object: the fast single-configuration path against the
general functions, the RPY baseline and its singularity, registration, limits, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from quatform.algebra import matrix_from_q, q_from_axis_angle, q_from_matrix, qmul
from quatform.errors import InvalidInputError, NonFiniteError, ShapeError
from quatform.scenarios import load_scenario
from quatform.teleop import (
    KRAFT_MASTER,
    PANDA,
    PANDA_SLAVE,
    Registration,
    TeleopController,
    TeleopMeasurement,
    VirtualWall,
    rpy_from_q,
    rpy_task_jacobian,
    task_jacobian,
)
from quatform.teleop.kernels import cross, q_from_rotation
from quatform.control.stiffness import master_torque, redundancy_torque, slave_torque, task_error
from quatform.teleop.task import rpy_error, rpy_rate_from_angular_velocity, wrap_angle

Q_M0 = np.array([0.0, 0.3, -0.4, 0.2, 0.3, 0.0])
Q_S0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
REG = Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, Q_S0)
UNLIMITED = dict(master_limits=[1e9] * 5 + [0.0], slave_limits=[1e9] * 7)
small = st.floats(-0.6, 0.6)


def _measurement(dm, dmd, ds, dsd, F):
    return TeleopMeasurement(Q_M0 + dm, dmd, Q_S0 + ds, dsd, F)


vec = lambda n, lim=0.6: hnp.arrays(np.float64, n, elements=st.floats(-lim, lim))  # noqa: E731


@settings(max_examples=40, deadline=None)
@given(dm=vec(6, 2.5), dmd=vec(6, 1), ds=vec(7, 2.5), dsd=vec(7, 1), F=vec(6, 20),
       base=st.one_of(st.just(np.zeros(3)), vec(3, 2.0)), scale=st.one_of(st.just(1.0), st.floats(0.3, 3.0)))
def test_fast_path_equals_the_general_functions(dm, dmd, ds, dsd, F, base, scale):
    """compute() (frames shared, error from R_M^T R_S) = eqs. (12), (14a), (14b) written out
    with the general functions, for any registration (base rotation, scale) and either
    hemisphere of the two orientations."""
    angle = float(np.linalg.norm(base))
    q_base = q_from_axis_angle(base / angle, angle) if angle > 1e-6 else np.array([1.0, 0, 0, 0])
    reg = Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, Q_S0, scale=scale, base=q_base)
    c = TeleopController(reg, Q_S0, **UNLIMITED)
    meas = _measurement(dm, dmd, ds, dsd, F)
    J_sf = PANDA.jacobian(meas.q_s)
    if np.linalg.svd(J_sf, compute_uv=False)[-1] < 1e-3:
        return  # the slave at a kinematic singularity: tested separately
    cmd = c.compute(0.0, meas)
    p_m, r_m = KRAFT_MASTER.forward(meas.q_m)
    pm, rm, Jm = reg.apply(p_m, r_m, KRAFT_MASTER.jacobian(meas.q_m))
    p_s, r_s = PANDA.forward(meas.q_s)
    e = task_error(pm, rm, p_s, r_s)
    e_dot = task_jacobian(J_sf, rm, r_s) @ meas.qd_s - task_jacobian(Jm, rm, r_s) @ meas.qd_m
    tau_m = master_torque(Jm, rm, r_s, e, e_dot, c.gains_master, F_s=F, v=c.reflection)
    J_bar = PANDA_SLAVE.generalized_inverse(meas.q_s)
    tau_s = slave_torque(J_sf, rm, r_s, e, e_dot, c.gains_slave,
                         redundancy_torque(J_sf, J_bar, meas.q_s, meas.qd_s, Q_S0))
    np.testing.assert_allclose(cmd.e, e, atol=1e-12)
    np.testing.assert_allclose(cmd.tau_m[:5], tau_m[:5], rtol=1e-9, atol=1e-8)
    assert cmd.tau_m[5] == 0.0  # the wrist roll has no actuator
    np.testing.assert_allclose(cmd.tau_s, tau_s, rtol=1e-9, atol=1e-8)
    assert cmd.raw_finite and not cmd.saturated and cmd.null_space_ok
    tau_m2, tau_s2 = c.step(0.0, meas)  # the lean path sends the same torques
    np.testing.assert_array_equal(tau_m2, cmd.tau_m)
    np.testing.assert_array_equal(tau_s2, cmd.tau_s)


def test_slave_singularity_leaves_out_the_redundancy_torque():
    """At q_s = 0 the Panda's J M^-1 J^T is singular: the command stays finite, without tau_red."""
    c = TeleopController(REG, Q_S0)
    cmd = c.compute(0.0, TeleopMeasurement(Q_M0, np.zeros(6), np.zeros(7), np.zeros(7)))
    assert not cmd.null_space_ok and cmd.raw_finite
    assert np.all(np.isfinite(cmd.tau_s)) and np.abs(cmd.tau_s).max() > 0


def test_kernels_match_numpy():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(5, 4, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), atol=1e-14)
    for q in rng.normal(size=(200, 4)):
        q = q / np.linalg.norm(q)
        R = matrix_from_q(q)
        np.testing.assert_allclose(q_from_rotation(R), q_from_matrix(R), atol=1e-12)
    for angle in (0.0, np.pi, np.pi - 1e-9):  # the branches where w is 0 or small
        for axis in np.eye(3):
            R = matrix_from_q(q_from_axis_angle(axis, angle))
            np.testing.assert_allclose(matrix_from_q(np.array(q_from_rotation(R))), R, atol=1e-12)


def test_registration_makes_the_homes_coincide_and_keeps_base_axes():
    p_m0, r_m0 = KRAFT_MASTER.forward(Q_M0)
    p, r, _ = REG.apply(p_m0, r_m0, KRAFT_MASTER.jacobian(Q_M0))
    p_s0, r_s0 = PANDA.forward(Q_S0)
    np.testing.assert_allclose(p, p_s0, atol=1e-12)
    np.testing.assert_allclose(abs(r @ r_s0), 1.0, atol=1e-12)
    # a master rotation about a base axis is the same rotation of the registered frame
    turn = q_from_axis_angle([0.0, 0.6, 0.8], 0.4)
    _, r2, _ = REG.apply(p_m0 + [0.01, -0.02, 0.03], qmul(turn, r_m0), KRAFT_MASTER.jacobian(Q_M0))
    np.testing.assert_allclose(matrix_from_q(r2), matrix_from_q(turn) @ matrix_from_q(r_s0), atol=1e-12)
    with pytest.raises(InvalidInputError, match="scale"):
        Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, Q_S0, scale=0.0)


@settings(max_examples=30, deadline=None)
@given(q=vec(7, 2.5), qd=vec(7, 1))
def test_rpy_task_jacobian_against_finite_differences(q, qd):
    r = PANDA.forward(q)[1]
    if abs(np.cos(rpy_from_q(r)[1])) < 0.05:
        return  # the gimbal lock, tested below
    J = rpy_task_jacobian(PANDA.jacobian(q), r)
    h = 1e-6
    fd = wrap_angle(rpy_from_q(PANDA.forward(q + h * qd)[1]) - rpy_from_q(PANDA.forward(q - h * qd)[1])) / (2 * h)
    np.testing.assert_allclose(J[3:6] @ qd, fd, rtol=1e-4, atol=1e-5)


def test_rpy_rate_map_is_infinite_at_pitch_90_and_error_wraps():
    E = rpy_rate_from_angular_velocity([0.1, np.pi / 2, 0.3])
    assert not np.all(np.isfinite(E)) or np.abs(E).max() > 1e15
    E = rpy_rate_from_angular_velocity([0.1, np.pi / 2 - 1e-4, 0.3])
    assert np.abs(E).max() > 5e3  # 1/cos(pitch)
    # errors are wrapped: 179 deg and -179 deg of roll differ by 2 deg
    qa = q_from_axis_angle([1.0, 0, 0], np.radians(179))
    qb = q_from_axis_angle([1.0, 0, 0], np.radians(-179))
    np.testing.assert_allclose(rpy_error(qa, qb), [np.radians(2), 0, 0], atol=1e-9)


def test_rpy_controller_at_gimbal_lock_sends_finite_saturated_torques():
    """Put the slave's tool at pitch -90 deg (to 1e-5 rad): the RPY law's rate map is ~1e5;
    the command is still finite and within the limits, and the saturation is reported."""
    from scipy.optimize import minimize_scalar

    qs = np.array([0.0, -0.2446, 0.0, -2.6831, 0.0, 3.5392, 0.0])

    def tilt(a):  # distance of the tool's x axis from vertical, turning joint 6
        q = np.r_[qs[:5], a, qs[6]]
        return np.linalg.norm(matrix_from_q(PANDA.forward(q)[1])[:, 0] - [0.0, 0.0, 1.0])

    qs[5] = minimize_scalar(tilt, bounds=(2.5, 4.5), method="bounded", options={"xatol": 1e-12}).x
    pitch = rpy_from_q(PANDA.forward(qs)[1])[1]
    assert abs(pitch + np.pi / 2) < 1e-5
    reg = Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, qs)
    ctrl = TeleopController(reg, qs, orientation_error="rpy")
    meas = TeleopMeasurement(Q_M0 + 0.01, np.full(6, 0.2), qs, np.full(7, -0.2))
    cmd = ctrl.compute(0.0, meas)
    assert np.all(np.isfinite(cmd.tau_m)) and np.all(np.isfinite(cmd.tau_s))
    assert np.all(np.abs(cmd.tau_s) <= ctrl.slave_limits) and np.all(np.abs(cmd.tau_m) <= ctrl.master_limits)
    ep = TeleopController(reg, qs).compute(0.0, meas)
    assert ep.raw_finite and np.abs(ep.tau_s).max() < 5.0  # the Euler-parameter law: nothing special
    assert cmd.saturated and np.abs(cmd.tau_s).max() > 10 * np.abs(ep.tau_s).max()


def test_limits_preload_and_walls():
    c = TeleopController(REG, Q_S0)
    meas = _measurement(np.full(6, 0.4), np.zeros(6), np.zeros(7), np.zeros(7), np.zeros(6))
    cmd = c.compute(0.0, meas)
    assert cmd.saturated and np.all(np.abs(cmd.tau_m) <= c.master_limits + 1e-12)
    assert cmd.tau_m[5] == 0.0
    # preload adds its offset in the direction of the command
    small_meas = _measurement(np.full(6, 0.01), np.zeros(6), np.zeros(7), np.zeros(7), np.zeros(6))
    off = TeleopController(REG, Q_S0).compute(0.0, small_meas).tau_m
    on = TeleopController(REG, Q_S0, preload_nm=TeleopController.default_preload()).compute(0.0, small_meas).tau_m
    big = np.abs(off) > TeleopController.default_preload()
    np.testing.assert_allclose(on[big], off[big] + np.sign(off[big]) * TeleopController.default_preload()[big])
    from quatform.control.stiffness import preload

    pre = TeleopController.default_preload()
    for scale in (0.001, 0.01, 0.1):  # inside the ramp, across it, beyond it: the general function
        meas = _measurement(np.full(6, scale), np.zeros(6), np.zeros(7), np.zeros(7), np.zeros(6))
        raw = TeleopController(REG, Q_S0, **UNLIMITED).compute(0.0, meas).tau_m
        fast = TeleopController(REG, Q_S0, preload_nm=pre, **UNLIMITED).compute(0.0, meas).tau_m
        np.testing.assert_allclose(fast, preload(raw, pre), atol=1e-12)
    # a virtual wall the master's tool is inside pushes it out along -normal
    p_master = KRAFT_MASTER.forward(Q_M0)[0]
    wall = VirtualWall(normal=(0.0, 0.0, -1.0), offset=-(p_master[2] + 0.01), resist_force_n=8.0, thickness_m=0.02)
    assert wall.depth(p_master) == pytest.approx(0.01)
    still = _measurement(*(np.zeros(n) for n in (6, 6, 7, 7, 6)))
    cw = TeleopController(REG, Q_S0, walls=(wall,), **UNLIMITED).compute(0.0, still)
    np.testing.assert_allclose(cw.wall_force, [0.0, 0.0, 4.0], atol=1e-9)  # 400 N/m x 1 cm, upward
    J = KRAFT_MASTER.jacobian(Q_M0)  # ... and it reaches the master's joints as J^T F
    np.testing.assert_allclose(cw.tau_m[:5], (J[0:3].T @ cw.wall_force)[:5], atol=1e-9)
    with pytest.raises(InvalidInputError, match="normal"):
        VirtualWall(normal=(0.0, 0.0, 0.0), offset=0.0)


def test_bad_measurements_and_settings_are_refused():
    c = TeleopController(REG, Q_S0)
    with pytest.raises(NonFiniteError, match="q_s"):
        c.step(0.0, TeleopMeasurement(Q_M0, np.zeros(6), np.r_[Q_S0[:6], np.nan], np.zeros(7)))
    with pytest.raises(ShapeError, match=r"qd_m must have shape \(6,\)"):
        c.step(0.0, TeleopMeasurement(Q_M0, np.zeros(5), Q_S0, np.zeros(7)))
    with pytest.raises(InvalidInputError, match="orientation_error"):
        TeleopController(REG, Q_S0, orientation_error="euler-angles")
    with pytest.raises(InvalidInputError, match="negative"):
        TeleopController(REG, Q_S0, reflection=0.2)
    with pytest.raises(InvalidInputError, match="master_limits"):
        TeleopController(REG, Q_S0, master_limits=[1.0, -1.0, 1, 1, 1, 0])
    for bad in (dict(reflection=-np.inf), dict(k_for=np.nan), dict(k_for=-1.0), dict(k_null=np.nan),
                dict(d_null=-1.0)):
        with pytest.raises(InvalidInputError):
            TeleopController(REG, Q_S0, **bad)
    with pytest.raises(InvalidInputError, match="scale"):
        Registration(REG.base, REG.tool, REG.p_master0, REG.p_slave0, scale=np.nan)
    with pytest.raises(InvalidInputError, match="offset"):
        VirtualWall(normal=(0.0, 0.0, 1.0), offset=np.nan)
    with pytest.raises(InvalidInputError, match="damping"):
        VirtualWall(normal=(0.0, 0.0, 1.0), offset=0.0, damping=-5.0)
    tau_m, tau_s = c.step(0.0, TeleopMeasurement(Q_M0, np.zeros(6), Q_S0, np.zeros(7)))
    np.testing.assert_allclose(tau_m, 0.0, atol=1e-12)  # at the registered homes: nothing to do
    np.testing.assert_allclose(tau_s, 0.0, atol=1e-12)


# -- virtual walls beyond reach, measurements not numbers or physically impossible ---------

@pytest.mark.parametrize("kw, match", [
    ({"resist_force_n": 1e300, "thickness_m": 1e-300}, "resist_force_n / thickness_m"),
    ({"resist_force_n": 1e12, "thickness_m": 1.0}, "resist_force_n / thickness_m"),
    ({"resist_force_n": "8"}, "resist_force_n = '8' must be a number"),
    ({"thickness_m": math.inf}, "thickness_m = inf must be finite"),
    ({"damping": math.nan}, "damping = nan must be finite"),
    ({"normal": ("a", 0, 1)}, "normal must be a nonzero 3-vector"),
])
def test_virtual_walls_beyond_reach_or_not_numbers_are_refused_at_construction(kw, match):
    with pytest.raises(InvalidInputError, match=match):
        VirtualWall(**{"normal": (0.0, 0.0, -1.0), "offset": -0.2, **kw})


@pytest.mark.parametrize("field", ["q_m", "qd_m", "q_s", "qd_s", "F_s"])
def test_non_numeric_measurements_name_the_field(field):
    sc = load_scenario("teleop-free-motion")
    ctrl = sc.controller()
    good = {"q_m": np.array(sc.q_m0), "qd_m": np.zeros(6), "q_s": np.array(sc.q_s0), "qd_s": np.zeros(7),
            "F_s": np.zeros(6)}
    good[field] = ["x"] * len(good[field])
    with pytest.raises(InvalidInputError, match=f"measurement {field} = "):
        ctrl.compute(0.0, TeleopMeasurement(**good))


@pytest.mark.parametrize("field, entry, value, match", [
    ("q_m", None, 1e300, r"measurement q_m\[0\] = 1e\+300 rad is beyond \+-1000 rad"),
    ("q_s", 3, -2e3, r"measurement q_s\[3\] = -2000 rad is beyond \+-1000 rad"),
    ("qd_m", 1, 1e5, r"measurement qd_m\[1\] = 100000 rad/s is beyond \+-100 rad/s"),
    ("qd_s", 6, -150.0, r"measurement qd_s\[6\] = -150 rad/s is beyond \+-100 rad/s"),
    ("F_s", 2, 1e6, r"measurement F_s\[2\] = 1e\+06 N is beyond \+-8700 N.*MAX_WRIST_FORCE"),
    ("F_s", 4, 1e4, r"measurement F_s\[4\] = 10000 N m is beyond \+-870 N m.*MAX_WRIST_MOMENT"),
])
def test_impossible_measurements_are_refused_not_saturated(field, entry, value, match):
    """q_m = 1e300 gets one line naming the field and value, not saturated torques."""
    sc = load_scenario("teleop-free-motion")
    ctrl = sc.controller()
    good = {"q_m": np.array(sc.q_m0), "qd_m": np.zeros(6), "q_s": np.array(sc.q_s0), "qd_s": np.zeros(7),
            "F_s": np.zeros(6)}
    bad = good[field].copy()
    if entry is None:
        bad[:] = value
    else:
        bad[entry] = value
    with pytest.raises(InvalidInputError, match=match) as exc:
        ctrl.step(0.0, TeleopMeasurement(**{**good, field: bad}))
    assert "\n" not in str(exc.value)


def test_measurements_within_each_bound_are_accepted():
    """Entries each within reach pass, though their norm is beyond the bound (per entry, not norm)."""
    from quatform.teleop.controller import (MAX_JOINT_ANGLE, MAX_JOINT_RATE, MAX_WRIST_FORCE, MAX_WRIST_MOMENT,
                                            _measured)

    np.testing.assert_array_equal(_measured(np.full(6, 0.99 * MAX_JOINT_ANGLE), "q_m", 6), 0.99 * MAX_JOINT_ANGLE)
    np.testing.assert_array_equal(_measured(np.full(7, -0.99 * MAX_JOINT_RATE), "qd_s", 7), -0.99 * MAX_JOINT_RATE)
    w = np.r_[np.full(3, 0.99 * MAX_WRIST_FORCE), np.full(3, 0.99 * MAX_WRIST_MOMENT)]
    np.testing.assert_array_equal(_measured(w, "F_s", 6), w)
    with pytest.raises(InvalidInputError, match="not finite"):
        _measured(np.r_[np.inf, 0.0, 0.0, 0.0, 0.0, 0.0], "qd_m", 6)


@pytest.mark.parametrize("orientation_error", ["euler-parameters", "rpy"])
def test_update_and_step_take_leading_batch_axes(orientation_error):
    """A batch of three worlds equals three single calls bitwise (commands and signals, update
    and step); a bad world's error names its index."""
    c = TeleopController(REG, Q_S0, orientation_error=orientation_error, walls=(VirtualWall((0.0, 0.0, 1.0), -0.2),))
    rng = np.random.default_rng(3)
    worlds = [np.r_[Q_M0 + rng.uniform(-0.3, 0.3, 6), rng.uniform(-1, 1, 6), Q_S0 + rng.uniform(-0.3, 0.3, 7),
                    rng.uniform(-1, 1, 7), rng.uniform(-5, 5, 6)] for _ in range(3)]
    batch = np.stack(worlds)
    out = c.update(0.1, batch)
    singles = [c.update(0.1, w) for w in worlds]
    assert out.u.shape == (3, 13)
    np.testing.assert_array_equal(out.u, np.stack([s.u for s in singles]))
    for name, v in out.signals.items():
        np.testing.assert_array_equal(v, np.stack([s.signals[name] for s in singles]), err_msg=name)
    tau_m, tau_s = c.step(0.1, batch)
    for k, w in enumerate(worlds):
        one_m, one_s = c.step(0.1, w)
        np.testing.assert_array_equal(tau_m[k], one_m)
        np.testing.assert_array_equal(tau_s[k], one_s)
    np.testing.assert_array_equal(c.update(0.1, batch.reshape(3, 1, 32)).u[:, 0], out.u)
    bad = batch.copy()
    bad[2, 12 + 3] = np.nan  # q_s4 of the third world
    with pytest.raises(NonFiniteError, match=r"^measurement q_s in world \(2,\) = .* is not finite"):
        c.update(0.1, bad)
    bad[2, 12 + 3] = 1e6
    with pytest.raises(InvalidInputError, match=r"^measurement q_s\[3\] in world \(2,\) = 1e\+06 rad is beyond"):
        c.step(0.1, bad)


def test_a_batch_of_no_worlds_gives_no_torques():
    """Zero worlds: every output has its leading axis of 0 (no traceback)."""
    c = TeleopController(REG, Q_S0)
    out = c.update(0.0, np.zeros((0, 32)))
    assert out.u.shape == (0, 13) and all(v.shape[0] == 0 for v in out.signals.values())
    tau_m, tau_s = c.step(0.0, np.zeros((0, 32)))
    assert tau_m.shape == (0, 6) and tau_s.shape == (0, 7)
