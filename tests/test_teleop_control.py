"""Seed 003 control laws: stiffness torques (14a)/(14b), force reflection, redundancy, preload, walls."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from quatform.errors import InvalidInputError
from quatform.teleop import KRAFT_MASTER, PANDA, PANDA_SLAVE
from quatform.control.stiffness import (
    StiffnessGains,
    deadband,
    explicit_stiffness_limit,
    force_stability_term,
    master_torque,
    preload,
    redundancy_torque,
    slave_torque,
    task_error,
    virtual_wall_force,
)

G = StiffnessGains(kp_pos=300.0, kp_rot=10.0, kv_pos=0.0, kv_rot=0.0)
qm_s = hnp.arrays(np.float64, 6, elements=st.floats(-2.5, 2.5))
qs_s = hnp.arrays(np.float64, 7, elements=st.floats(-2.5, 2.5))


def energy(qm, qs):
    pm, rm = KRAFT_MASTER.forward(qm)
    ps, rs = PANDA.forward(qs)
    e = task_error(pm, rm, ps, rs)
    return 0.5 * e @ (G.kp * e), e, rm, rs


@given(qm=qm_s, qs=qs_s)
def test_torques_are_the_springs_generalized_forces(qm, qs):
    """tau_m = -dU/dq_m and tau_s = -dU/dq_s for U = 1/2 e^T K_p e: the signs of (14a), (14b)
    and the W of (19) are right (the short-way sign included)."""
    U, e, rm, rs = energy(qm, qs)
    if abs(rm @ rs) < 0.05:
        return  # a 180 deg error: the short way is about to switch sides
    h = 1e-6
    tm = master_torque(KRAFT_MASTER.jacobian(qm), rm, rs, e, np.zeros(6), G)
    ts = slave_torque(PANDA.jacobian(qs), rm, rs, e, np.zeros(6), G)
    grad_m = np.array([(energy(qm + h * d, qs)[0] - energy(qm - h * d, qs)[0]) / (2 * h) for d in np.eye(6)])
    grad_s = np.array([(energy(qm, qs + h * d)[0] - energy(qm, qs - h * d)[0]) / (2 * h) for d in np.eye(7)])
    np.testing.assert_allclose(tm, -grad_m, atol=1e-5 * max(1, np.abs(tm).max()))
    np.testing.assert_allclose(ts, -grad_s, atol=1e-5 * max(1, np.abs(ts).max()))


def test_force_reflection_pushes_the_operator_back():
    qm = np.array([0.1, -0.2, 0.3, 0.1, 0.2, 0.0])
    pm, rm = KRAFT_MASTER.forward(qm)
    F_s = np.array([5.0, 0, 0, 0, 0, 0])  # the slave pushes on its environment along +x
    v = force_stability_term()
    tau = master_torque(KRAFT_MASTER.jacobian(qm), rm, rm, np.zeros(6), np.zeros(6), G, F_s, v)
    J = KRAFT_MASTER.jacobian(qm)
    # the master's tool is pushed along -x: the torque does negative work on +x motion
    qd_plus_x = np.linalg.lstsq(J[0:3], np.array([1.0, 0, 0]), rcond=None)[0]
    assert tau @ qd_plus_x < 0
    assert force_stability_term(np.array([1.0, 0, 0, 0, 0, 0]), F_s, k_for=0.1) == pytest.approx(-0.5)
    with pytest.raises(InvalidInputError, match="negative"):
        force_stability_term(constant=0.3)


@given(qs=qs_s, qd=hnp.arrays(np.float64, 7, elements=st.floats(-1, 1)))
def test_redundancy_torque_makes_no_task_force_eq_13(qs, qd):
    J = PANDA.jacobian(qs)
    if np.linalg.svd(J, compute_uv=False)[-1] < 1e-2:
        return
    Jb = PANDA_SLAVE.generalized_inverse(qs)
    tau = redundancy_torque(J, Jb, qs, qd, np.zeros(7))
    np.testing.assert_allclose(Jb.T @ tau, 0.0, atol=1e-9 * max(1, np.abs(tau).max()))
    # static balance seen in the task space: J_bar^T J_sf^T = I, so the slave's contact
    # wrench equals the stiffness times the error (eq. (13), position part)
    np.testing.assert_allclose(Jb.T @ J.T, np.eye(6), atol=1e-8)


def test_preload_inverts_the_deadband():
    width = np.array([0.15, 0.15, 0.1, 0.05, 0.05, 0.0])
    tau = np.array([0.5, -0.3, 0.2, -0.1, 0.04, 0.7])
    out = deadband(preload(tau, width), width)
    big = np.abs(tau) >= width / 2
    np.testing.assert_allclose(out[big], tau[big], atol=1e-12)
    np.testing.assert_array_equal(deadband(np.array([0.1, -0.1]), 0.15), [0.0, 0.0])
    # continuous through zero (no switching chatter)
    ts = np.linspace(-0.01, 0.01, 201)
    assert np.abs(np.diff(preload(ts, 0.1))).max() < 0.02


def test_virtual_wall_repels_only_inside():
    n, off, k, b = np.array([0, 0, 1.0]), 0.2, 1000.0, 20.0
    assert np.all(virtual_wall_force([0, 0, 0.1], [0, 0, 1.0], n, off, k, b) == 0)
    f = virtual_wall_force([0, 0, 0.21], [0, 0, 0.5], n, off, k, b)
    np.testing.assert_allclose(f, [0, 0, -(k * 0.01 + b * 0.5)])
    f_out = virtual_wall_force([0, 0, 0.21], [0, 0, -0.5], n, off, k, b)
    np.testing.assert_allclose(f_out, [0, 0, -k * 0.01])  # moving out: no damping pull


# -- springs beyond the explicit integrator's stability limit; the moments of the two laws --

@pytest.mark.parametrize("factor, stable", [(0.98, True), (1.02, False)])
@pytest.mark.parametrize("m, c", [(2.9, 0.0), (2.9, 160.0), (0.061, 60.0)])
def test_stiffness_limit_is_the_semi_implicit_euler_boundary(m, c, factor, stable):
    """k dt^2 + 2 c dt < 4 m: below it the sampled mass-spring-damper decays, above it grows."""
    dt = 1e-3
    k = factor * float(explicit_stiffness_limit(m, c, dt))
    x, v, peak = 1e-3, 0.0, 0.0
    for _ in range(4000):  # the simulator's step: force at the start, velocity first
        v = v + dt * (-k * x - c * v) / m
        x = x + dt * v
        peak = max(peak, abs(x))
    assert (peak < 0.1) == stable  # bounded (undamped: it neither grows nor decays) or blown up
    if not stable:
        assert peak > 1e3


def test_euler_parameter_moment_is_k_over_4_sin_theta_zero_at_180_deg():
    """W^T K delta_eps about the error axis is (K/4) sin(theta): largest at 90 deg, 0 at 180."""
    from quatform.algebra import matrix_from_q, q_from_axis_angle, qmul
    from quatform.teleop import orientation_error, task_jacobian

    k, axis = 10.0, np.array([0.0, 0.6, 0.8])
    q_m = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.4)
    for theta in np.radians([10.0, 60.0, 90.0, 150.0, 179.0, 180.0]):
        q_s = qmul(q_m, q_from_axis_angle(axis, theta))  # theta from the master, about its axis
        W = task_jacobian(np.eye(6), q_m, q_s)[3:6, 3:6]
        moment = W.T @ (k * orientation_error(q_m, q_s))  # base frame
        along = moment @ (matrix_from_q(q_m) @ axis)
        assert along == pytest.approx(k / 4 * np.sin(theta), abs=1e-12)


@pytest.mark.parametrize("pitch_deg", [0.0, -30.0, -63.0654, -80.0])
def test_rpy_small_angle_stiffness_equals_euler_parameters_only_at_pitch_0(pitch_deg):
    """The RPY law's moment per radian is (kp/4) E^-T E^-1: eigenvalues 1/(1 + |sin p|), 1,
    1/(1 - |sin p|) times the Euler-parameter law's (x0.53, x1, x9.2 at the -63 deg start)."""
    from quatform.algebra import q_from_axis_angle, qmul
    from quatform.teleop import rpy_error
    from quatform.teleop.task import rpy_from_q, rpy_rate_from_angular_velocity

    p = np.radians(pitch_deg)
    q_m = qmul(q_from_axis_angle(np.array([0.0, 1.0, 0.0]), p), q_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi))
    E_inv = rpy_rate_from_angular_velocity(rpy_from_q(q_m))
    K = np.empty((3, 3))  # moment per radian over kp/4, by small rotations about the base axes
    h = 1e-6
    for j in range(3):
        q_s = qmul(q_from_axis_angle(np.eye(3)[j], h), q_m)
        K[:, j] = E_inv.T @ rpy_error(q_m, q_s) / h
    eig = np.linalg.eigvalsh(0.5 * (K + K.T))
    s = abs(np.sin(p))
    np.testing.assert_allclose(eig, sorted([1 / (1 + s), 1.0, 1 / (1 - s)]), rtol=1e-4)
    if pitch_deg == -63.0654:
        np.testing.assert_allclose(eig, [0.53, 1.0, 9.2], atol=0.02)
