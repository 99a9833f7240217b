"""Bad input gets a clear exception from quatform.errors naming the value and the fix."""

from __future__ import annotations

import numpy as np
import pytest

import quatform.algebra as A
from quatform.errors import (
    DegenerateInputError,
    NonFiniteError,
    NonUnitError,
    NotARotationError,
    QuatformError,
    ShapeError,
)

Q = np.array([0.5, 0.5, 0.5, 0.5])
V = np.array([1.0, 2.0, 3.0])
DQ = A.dq_from_pose(Q, V)

# (function, args, index of the argument to corrupt, its kind: q=quaternion, u=unit quaternion, v=vector, d=dq, ud=unit dq)
CALLS = [
    (A.qmul, (Q, Q), 0, "q"),
    (A.qmul, (Q, Q), 1, "q"),
    (A.qconj, (Q,), 0, "q"),
    (A.qinv, (Q,), 0, "q"),
    (A.qnorm, (Q,), 0, "q"),
    (A.qnormalize, (Q,), 0, "q"),
    (A.qexp, (Q,), 0, "q"),
    (A.qlog, (Q,), 0, "q"),
    (A.qpow, (Q, 0.5), 0, "q"),
    (A.qslerp, (Q, Q, 0.5), 1, "u"),
    (A.qrotate, (Q, V), 0, "u"),
    (A.qrotate, (Q, V), 1, "v"),
    (A.q_from_axis_angle, (V, 1.0), 0, "v"),
    (A.axis_angle_from_q, (Q,), 0, "u"),
    (A.matrix_from_q, (Q,), 0, "u"),
    (A.qcanonical, (Q,), 0, "q"),
    (A.q_closest, (Q, Q), 1, "q"),
    (A.q_angle, (Q,), 0, "u"),
    (A.qplus, (Q,), 0, "q"),
    (A.qminus, (Q,), 0, "q"),
    (A.skew, (V,), 0, "v"),
    (A.jac_qrotate_vector, (Q,), 0, "q"),
    (A.jac_qrotate_quaternion, (Q, V), 1, "v"),
    (A.qdot_from_angular_velocity, (Q, V), 1, "v"),
    (A.angular_velocity_from_qdot, (Q, Q), 0, "u"),
    (A.integrate, (Q, V, 0.1), 0, "u"),
    (A.integrate, (Q, V, 0.1), 1, "v"),
    (A.dqmul, (DQ, DQ), 1, "d"),
    (A.dqconj, (DQ,), 0, "d"),
    (A.dqnorm, (DQ,), 0, "d"),
    (A.dqnormalize, (DQ,), 0, "d"),
    (A.dqinv, (DQ,), 0, "d"),
    (A.dqexp, (DQ,), 0, "d"),
    (A.dqlog, (DQ,), 0, "ud"),
    (A.dqpow, (DQ, 0.5), 0, "ud"),
    (A.dqpow_decoupled, (DQ, 0.5), 0, "ud"),
    (A.dqsqrt_decoupled, (DQ,), 0, "ud"),
    (A.dqsqrt_screw, (DQ,), 0, "ud"),
    (A.dq_from_pose, (Q, V), 0, "u"),
    (A.dq_from_pose, (Q, V), 1, "v"),
    (A.pose_from_dq, (DQ,), 0, "ud"),
    (A.dq_transform_point, (DQ, V), 1, "v"),
    (A.relative_euler_parameters, (Q, Q), 1, "u"),
    (A.w_matrix, (Q, Q), 0, "u"),
]


def _replace(args, i, value):
    args = list(args)
    args[i] = value
    return args


@pytest.mark.parametrize("fn,args,i,kind", CALLS, ids=lambda x: getattr(x, "__name__", None))
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_is_named(fn, args, i, kind, bad):
    x = np.array(args[i], dtype=float)
    x = np.stack([x, x])
    x[1, -1] = bad
    with pytest.raises(NonFiniteError, match=r"contains .*(nan|inf).* at index \(1, "):
        fn(*_replace([np.stack([np.asarray(a, float)] * 2) if np.ndim(a) else a for a in args], i, x))


@pytest.mark.parametrize("fn,args,i,kind", CALLS, ids=lambda x: getattr(x, "__name__", None))
def test_wrong_trailing_shape(fn, args, i, kind):
    x = np.asarray(args[i], dtype=float)
    with pytest.raises(ShapeError, match=r"must have shape \(\.\.\., \d\), got shape"):
        fn(*_replace(args, i, np.append(x, 0.0)))


@pytest.mark.parametrize("fn,args,i,kind", [c for c in CALLS if c[3] in ("u", "ud")], ids=lambda x: getattr(x, "__name__", None))
def test_non_unit_beyond_tolerance_raises_within_is_renormalised(fn, args, i, kind):
    x = np.asarray(args[i], dtype=float)
    with pytest.raises(NonUnitError, match="normalise it with"):
        fn(*_replace(args, i, 1.01 * x))
    near = (1 + 1e-8) * x
    out_near = fn(*_replace(args, i, near))
    out = fn(*args)
    for a, b in zip(out_near if isinstance(out_near, tuple) else (out_near,), out if isinstance(out, tuple) else (out,)):
        np.testing.assert_allclose(a, b, atol=1e-7)


def test_unit_dual_quaternion_needs_orthogonal_parts():
    bad = DQ.copy()
    bad[4:] += 0.1 * bad[:4]
    with pytest.raises(NonUnitError, match=r"primary \. dual"):
        A.pose_from_dq(bad)


def test_degenerate_inputs():
    with pytest.raises(DegenerateInputError, match="zero quaternion"):
        A.qinv([0.0, 0, 0, 0])
    with pytest.raises(DegenerateInputError, match="zero quaternion"):
        A.qlog([[1.0, 0, 0, 0], [0.0, 0, 0, 0]])
    with pytest.raises(DegenerateInputError, match="nonzero axis"):
        A.q_from_axis_angle([0.0, 0, 0], 0.5)
    np.testing.assert_array_equal(A.q_from_axis_angle([0.0, 0, 0], 0.0), [1, 0, 0, 0])
    with pytest.raises(DegenerateInputError, match="zero primary part"):
        A.dqnormalize(np.r_[np.zeros(4), 1.0, 0, 0, 0])


def test_not_a_rotation():
    with pytest.raises(NotARotationError, match="det = -1"):
        A.q_from_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(NotARotationError, match=r"index \(1,\)"):
        A.q_from_matrix(np.stack([np.eye(3), 1.1 * np.eye(3)]))


def test_non_numeric_and_hierarchy():
    with pytest.raises(ShapeError, match="numeric array"):
        A.qmul("abcd", Q)
    assert issubclass(NonFiniteError, QuatformError) and issubclass(NonFiniteError, ValueError)


def test_inputs_are_not_modified_and_outputs_are_new():
    q = Q.copy()
    out = A.qnormalize(q)
    out[0] = 9.0
    np.testing.assert_array_equal(q, Q)
    assert A.qconj(q) is not q
