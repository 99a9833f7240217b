"""Seed 003 kinematics: modified DH chains, the Kraft master, Euler-parameter task Jacobians."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from quatform.algebra import (
    angular_velocity_from_qdot,
    matrix_from_q,
    q_from_axis_angle,
    qmul,
)
from quatform.errors import ShapeError
from quatform.teleop import KRAFT_MASTER, orientation_error, task_jacobian

joints = hnp.arrays(np.float64, 6, elements=st.floats(-math.pi, math.pi))


def _frames_by_oracle(q, arm=None):
    """The same chain composed with pytransform3d's elementary rotations (independent code)."""
    from pytransform3d.rotations import active_matrix_from_angle
    from pytransform3d.transformations import transform_from

    arm = KRAFT_MASTER if arm is None else arm
    T = np.eye(4)
    for L, qi in zip(arm.links, q, strict=True):
        Rx = transform_from(active_matrix_from_angle(0, L.alpha_prev), np.zeros(3))
        Tx = transform_from(np.eye(3), [L.a_prev, 0, 0])
        Rz = transform_from(active_matrix_from_angle(2, qi + L.offset), np.zeros(3))
        Tz = transform_from(np.eye(3), [0, 0, L.d])
        T = T @ Rx @ Tx @ Rz @ Tz
    return T @ transform_from(np.eye(3), [0, 0, arm.tool_d])


@given(q=joints)
def test_kraft_forward_kinematics_against_pytransform3d(q):
    p, quat = KRAFT_MASTER.forward(q)
    T = _frames_by_oracle(q)
    np.testing.assert_allclose(p, T[0:3, 3], atol=1e-12)
    np.testing.assert_allclose(matrix_from_q(quat), T[0:3, 0:3], atol=1e-12)


def test_kraft_table_values():
    assert [L.d for L in KRAFT_MASTER.links] == [0, 0.073, 0, 0.084, 0, 0.114]
    assert [L.a_prev for L in KRAFT_MASTER.links] == [0, 0, 0.178, 0.203, 0, 0]
    assert KRAFT_MASTER.actuated == (True,) * 5 + (False,)
    # at the pictured pose: reach = a2 + a3 + d6 along the arm, d2 - d4 sideways (eq. check by hand)
    p, _ = KRAFT_MASTER.forward(np.zeros(6))
    np.testing.assert_allclose(p, [0.203 + 0.114, -0.073, 0.178 + 0.084], atol=1e-12)


@given(q=joints, qd=hnp.arrays(np.float64, 6, elements=st.floats(-1, 1)))
def test_force_reflecting_jacobian_eq_15(q, qd):
    """J_mf q_dot = [p_dot; omega], omega in the base frame, against central differences."""
    h = 1e-6
    (p1, r1), (p0, r0) = KRAFT_MASTER.forward(q + h * qd), KRAFT_MASTER.forward(q - h * qd)
    r1 = r1 if r1 @ r0 >= 0 else -r1
    v = KRAFT_MASTER.jacobian(q) @ qd
    np.testing.assert_allclose(v[0:3], (p1 - p0) / (2 * h), atol=1e-7)
    _, r = KRAFT_MASTER.forward(q)
    r = r if r @ r0 >= 0 else -r
    w = angular_velocity_from_qdot(r, (r1 - r0) / (2 * h), frame="world")
    np.testing.assert_allclose(v[3:6], w, atol=1e-7)


@given(q_m=joints, q_s=joints, qd=hnp.arrays(np.float64, 6, elements=st.floats(-1, 1)))
def test_task_jacobians_eqs_16_18(q_m, q_s, qd):
    """diag(I, W) J_f maps the slave's joint rates to the rate of delta_eps (master still),
    and minus it the master's (slave still)."""
    arm = KRAFT_MASTER  # any arm: the slave role only needs a chain
    _, rm = arm.forward(q_m)
    _, rs = arm.forward(q_s)
    if abs(rm @ rs) < 0.05:  # near a 180 deg error the short-way sign flips
        return
    h = 1e-6
    num = (orientation_error(rm, arm.forward(q_s + h * qd)[1]) - orientation_error(rm, arm.forward(q_s - h * qd)[1])) / (2 * h)
    num_m = (orientation_error(arm.forward(q_m + h * qd)[1], rs) - orientation_error(arm.forward(q_m - h * qd)[1], rs)) / (2 * h)
    for r in (rs, -rs):  # either sign of either quaternion: W takes the short way itself
        Js = task_jacobian(arm.jacobian(q_s), rm, r)
        np.testing.assert_allclose(num, (Js @ qd)[3:6], atol=2e-6)
        Jm = task_jacobian(arm.jacobian(q_m), rm, r)
        np.testing.assert_allclose(num_m, -(Jm @ qd)[3:6], atol=2e-6)


@pytest.mark.parametrize("angle", [1e-6, 1e-3, 0.1, 1.0, 2.5, math.pi])
def test_orientation_error_is_half_angle_then_saturates(angle):
    """Seed 003 conclusion: |delta_eps| ~ angle/2 for small errors, sin(angle/2) for large."""
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    rm = q_from_axis_angle([0, 1, 0], 0.4)
    rs = qmul(rm, q_from_axis_angle(axis, angle))
    e = orientation_error(rm, rs)
    assert np.linalg.norm(e) == pytest.approx(math.sin(angle / 2), rel=1e-9, abs=1e-15)
    np.testing.assert_allclose(e / np.linalg.norm(e), axis, atol=1e-9)  # in {M}
    if angle < 1e-2:
        assert np.linalg.norm(e) == pytest.approx(angle / 2, rel=1e-4)
    np.testing.assert_allclose(orientation_error(rm, -rs), e, atol=1e-12)  # q vs -q


def test_bad_joint_vectors():
    with pytest.raises(ShapeError, match="Kraft master"):
        KRAFT_MASTER.forward(np.zeros(5))
    batch = np.random.default_rng(0).normal(size=(4, 6))
    p, r = KRAFT_MASTER.forward(batch)
    assert p.shape == (4, 3) and r.shape == (4, 4)
    assert KRAFT_MASTER.jacobian(batch).shape == (4, 6, 6)


# -- the 7-DOF slave ----------------------------------------------------------------------------

from quatform.teleop import PANDA, PANDA_SLAVE  # noqa: E402

joints7 = hnp.arrays(np.float64, 7, elements=st.floats(-2.5, 2.5))


@given(q=joints7)
def test_slave_kinematics_against_pytransform3d_and_jacobian(q):
    p, quat = PANDA.forward(q)
    T = _frames_by_oracle(q, PANDA)
    np.testing.assert_allclose(p, T[0:3, 3], atol=1e-12)
    np.testing.assert_allclose(matrix_from_q(quat), T[0:3, 0:3], atol=1e-12)
    h, qd = 1e-6, np.linspace(-1, 1, 7)
    v = PANDA.jacobian(q) @ qd
    np.testing.assert_allclose(v[0:3], (PANDA.forward(q + h * qd)[0] - PANDA.forward(q - h * qd)[0]) / (2 * h),
                               atol=1e-7)


@given(q=joints7, qd=hnp.arrays(np.float64, 7, elements=st.floats(-1, 1)))
def test_mass_matrix_is_the_kinetic_energy(q, qd):
    """1/2 qd^T M qd equals the rods' and rotors' kinetic energy from finite-difference motion."""
    M = PANDA_SLAVE.mass_matrix(q)
    np.testing.assert_allclose(M, M.T, atol=1e-12)
    assert np.linalg.eigvalsh(M).min() > 0
    h = 1e-6
    Fp, cp, up, Lp = PANDA_SLAVE._coms(q + h * qd)
    Fm, cm, um, Lm = PANDA_SLAVE._coms(q - h * qd)
    F0, c0, u0, L0 = PANDA_SLAVE._coms(q)
    energy = 0.5 * PANDA_SLAVE.armature * qd @ qd
    assert PANDA_SLAVE.armature > 0
    for i, m in enumerate(PANDA_SLAVE.masses):
        v = (cp[i] - cm[i]) / (2 * h)
        Rd = (Fp[i, 0:3, 0:3] - Fm[i, 0:3, 0:3]) / (2 * h)
        W = Rd @ F0[i, 0:3, 0:3].T  # [omega]x in the base frame
        w = np.array([W[2, 1], W[0, 2], W[1, 0]])
        across, along = m * L0[i] ** 2 / 12, m * PANDA_SLAVE.radius ** 2 / 2
        I = across * (np.eye(3) - np.outer(u0[i], u0[i])) + along * np.outer(u0[i], u0[i])
        energy += 0.5 * m * v @ v + 0.5 * w @ I @ w
    assert 0.5 * qd @ M @ qd == pytest.approx(energy, rel=1e-6, abs=1e-12)


@given(q=joints7, xd=hnp.arrays(np.float64, 6, elements=st.floats(-1, 1)))
def test_generalized_inverse_eq_13_minimises_kinetic_energy(q, xd):
    J = PANDA.jacobian(q)
    if np.linalg.svd(J, compute_uv=False)[-1] < 1e-2:
        return  # near a kinematic singularity of the slave
    Jb = PANDA_SLAVE.generalized_inverse(q)
    np.testing.assert_allclose(J @ Jb, np.eye(6), atol=1e-9)
    M = PANDA_SLAVE.mass_matrix(q)
    best = Jb @ xd
    null = np.linalg.svd(J)[2][-1]  # the redundant direction
    for s in (-0.3, 0.1, 0.5):
        other = best + s * null
        np.testing.assert_allclose(J @ other, J @ best, atol=1e-9)
        assert other @ M @ other >= best @ M @ best - 1e-12


def test_shepperd_selection_on_jax_is_the_float_branch():
    """``q_from_rotation`` on JAX computes all four branches and selects: each of them taken
    (turns of pi about x, y, z take branches 1-3) gives the float path's quaternion."""
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    from quatform.algebra import matrix_from_q
    from quatform.teleop.kernels import q_from_rotation

    rng = np.random.default_rng(5)
    q = rng.standard_normal((40, 4))
    q = np.vstack([q / np.linalg.norm(q, axis=1, keepdims=True), np.eye(4), [[0.0, 1.0, 1e-9, 0.0]]])
    R = matrix_from_q(q)
    with jax.enable_x64(True):
        got = np.stack(jax.jit(q_from_rotation)(jnp.asarray(R)), axis=-1)
    want = np.array([q_from_rotation(r) for r in R])
    assert {int(np.argmax(np.abs(w))) for w in want} == {0, 1, 2, 3}
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
