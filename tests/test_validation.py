"""Bad input gets a clear exception from quatform.errors naming the value and the fix."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import quatform.algebra as A
from quatform.algebra import validate
from quatform.errors import (
    DegenerateInputError,
    InvalidInputError,
    NonFiniteError,
    NonUnitError,
    NotARotationError,
    QuatformError,
    ShapeError,
)
from quatform.tomlio import read_toml

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


# -- cheap messages, the TOML reader, number and budget checks ---------------------------------------

def test_validator_messages_are_cheap_to_build():
    """A NaN in a 4e6-entry array: the message names the first bad entry without allocating
    index lists or copies of the bad entries (argwhere and a[bad] would take 3x the array)."""
    a = np.full((1_000_000, 4), np.nan)
    a[0] = 1.0
    tracemalloc.start()
    try:
        with pytest.raises(NonFiniteError, match=r"contains nan at index \(1, 0\)"):
            validate.as_array(a, "q", 4)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.5 * a.nbytes
    q = np.ones((3, 5, 4))
    with pytest.raises(InvalidInputError, match=r"has norm 2 at index \(0, 0\)"):
        validate.as_unit_quaternion(q)
    with pytest.raises(InvalidInputError, match=r"primary \. dual = 1 \(tolerance"):
        validate.as_unit_dual_quaternion(np.r_[1.0, 0, 0, 0, 1.0, 0, 0, 0])


@pytest.mark.parametrize("make, needle", [
    (lambda p: p.write_bytes(b'name = "\xff\xfe"\n'), "not UTF-8 text (byte 0xff on line 1); save the file as UTF-8"),
    (lambda p: p.write_text("a = " + "[" * 100_000 + "]" * 100_000), "nested too deeply"),
    (lambda p: p.mkdir(), "is a folder, not a file"),
    (lambda p: p.write_text("# " + "x" * 1_100_000), "too large for a scenario file"),
    (lambda p: None, "no such file"),
])
def test_unreadable_toml_files_are_one_line_naming_the_file(tmp_path, make, needle):
    p = tmp_path / "s.toml"
    make(p)
    with pytest.raises(InvalidInputError) as e:
        read_toml(p, {}, "scenario")
    msg = str(e.value)
    assert str(p) in msg and needle in msg and "\n" not in msg


def test_a_device_and_an_unreadable_file_are_one_line(tmp_path, monkeypatch):
    with pytest.raises(InvalidInputError, match="not a regular file"):
        read_toml("/dev/null", {}, "scenario")
    p = tmp_path / "s.toml"
    p.write_text("x = 1\n")
    import quatform.tomlio as toml_module

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", str(p))

    monkeypatch.setattr(toml_module, "open", denied, raising=False)
    with pytest.raises(InvalidInputError, match="cannot read it .Permission denied.; check its permissions"):
        read_toml(p, {}, "plan spec")


def test_a_toml_file_with_a_byte_order_mark_reads(tmp_path):
    """Some editors start a UTF-8 file with a byte-order mark: the scenario reads as without it."""
    from quatform.scenarios import builtin_scenarios, load_scenario

    text = builtin_scenarios()["mas-kitts-spiral"].read_text(encoding="utf-8")
    f = tmp_path / "bom.toml"
    f.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert repr(load_scenario(f)) == repr(load_scenario("mas-kitts-spiral"))


@pytest.mark.parametrize("kind,line,key", [
    ("pair", "d_c = 1e200", "d_c"),
    ("ugv-uav", "r_x = 1e160", "r_x"),
    ("teleop", "duration_s = 1e300", "duration_s"),
    ("plan", "X = 1e300", "X"),
])
def test_huge_finite_numbers_are_refused_at_load_naming_the_key(tmp_path, kind, line, key):
    """A huge finite number in any file kind is refused by the reader, naming the key (not late,
    from an internal array, nor by overflowing into warnings)."""
    from quatform.checks import MAX_NUMBER, number
    from quatform.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match=rf"f.toml: {key} = .* is beyond \+-1e\+12"):
        number({key: float(line.split("=")[1])}, key, "f.toml")
    assert number({key: MAX_NUMBER}, key, "f.toml") == MAX_NUMBER


@pytest.mark.parametrize("name", ["QUATFORM_MAX_MEMORY_BYTES", "QUATFORM_MAX_WORK_S"])
@pytest.mark.parametrize("value", ["abc", "-5", "0", "nan", "inf"])
def test_a_budget_that_is_no_positive_number_is_one_line(monkeypatch, name, value):
    from quatform.checks import memory_budget_bytes, time_budget_s
    from quatform.errors import InvalidInputError

    monkeypatch.setenv(name, value)
    budget = memory_budget_bytes if "MEMORY" in name else time_budget_s
    with pytest.raises(InvalidInputError, match=name) as exc:
        budget()
    assert "\n" not in str(exc.value) and repr(value) in str(exc.value)
    monkeypatch.setenv(name, " 2.5e3 ")
    assert budget() == 2500.0
