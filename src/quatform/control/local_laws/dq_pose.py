"""The dual-quaternion local laws' unchecked kernels and their shared base (internal, not the user API).

Control layer. Pure and branch-free on any array namespace (NumPy, JAX under ``jax.jit``):
products and conjugates of ``(..., 8)`` dual quaternions (primary part first,
``docs/conventions.md``), a robot's pose point as a dual quaternion, the map between a world
twist and the robot's commands, the sign of a neighbour's dual quaternion nearest one's own
(decided on the double cover without a tie), and the host check of a dual-quaternion law's
reference. The public functions of :mod:`quatform.algebra.dual_quaternion` validate every
argument on the host; these only compute, so they trace under ``jax.jit``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...algebra import UNIT_TOLERANCE
from ...algebra.kernels import common_namespace, dot_last, dqmul_components, qmul_components
from ...errors import InvalidInputError, NonUnitError, ShapeError
from ...network.graph import switching_rate
from ..local import LocalController

#: What a robot of a dual-quaternion law measures of itself: its pose point.
POSE_COLUMNS = ("x", "y", "z", "q_w", "q_x", "q_y", "q_z")
#: The commands of a dual-quaternion law: world linear and angular velocity.
TWIST_COLUMNS = ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z")
#: The message of a dual-quaternion law: the sender's formation variable ``y = x x_d*``.
Y_COLUMNS = ("y_rw", "y_rx", "y_ry", "y_rz", "y_dw", "y_dx", "y_dy", "y_dz")

_CONJ8 = np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


def _stack(xp, parts):
    return xp.stack(xp.broadcast_arrays(*parts), axis=-1)


def dqmul(a, b):
    """``a b`` of broadcast ``(..., 8)`` dual quaternions."""
    xp = common_namespace(a, b)
    return _stack(xp, dqmul_components(*xp.moveaxis(a, -1, 0), *xp.moveaxis(b, -1, 0)))


def qmul(a, b):
    """``a b`` of broadcast ``(..., 4)`` quaternions."""
    xp = common_namespace(a, b)
    return _stack(xp, qmul_components(*xp.moveaxis(a, -1, 0), *xp.moveaxis(b, -1, 0)))


def dqconj(a):
    """``r* + eps d*``: the inverse of a unit dual quaternion."""
    return a * _CONJ8


def pure(a):
    """The vector parts of both halves of ``(..., 8)``, the scalar parts zeroed."""
    return a * np.array([0.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0])


def cross(a, b):
    """``a x b`` of broadcast ``(..., 3)`` vectors."""
    xp = common_namespace(a, b)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return _stack(xp, (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def _vector(xp, v):
    """``(0, v)`` of ``(..., 3)``."""
    return xp.concatenate([xp.zeros(v.shape[:-1] + (1,), dtype=v.dtype), v], axis=-1)


def pose_dq(own):
    """``q + eps 1/2 (0, t) q`` of pose points ``(..., 7)`` ``(x, y, z, q_w, q_x, q_y, q_z)``
    (seed 000 §3.3)."""
    xp = common_namespace(own)
    q = own[..., 3:7]
    return xp.concatenate([q, 0.5 * qmul(_vector(xp, own[..., 0:3]), q)], axis=-1)


def translation(x):
    """``t = 2 D(x) P(x)*`` of unit dual quaternions ``(..., 8)`` -> ``(..., 3)`` m."""
    return 2.0 * qmul(x[..., 4:8], x[..., 0:4] * _CONJ8[:4])[..., 1:4]


def twist_dq(v, w, t):
    """The world twist ``x_dot x* = 1/2 w + eps 1/2 (v + t x w)`` of a frame at ``t`` (m) moving
    at linear velocity ``v`` (m/s, of its origin) and angular velocity ``w`` (rad/s), both in
    the world frame (``x = q + eps 1/2 t q``, ``q_dot = 1/2 w q``)."""
    xp = common_namespace(v, w, t)
    return 0.5 * xp.concatenate([_vector(xp, w), _vector(xp, v + cross(t, w))], axis=-1)


def twist_commands(xi, t):
    """Inverse of :func:`twist_dq`: ``(v, w)`` ``(..., 6)`` of a frame at ``t`` whose twist is
    the pure ``xi`` ``(..., 8)``: ``w = 2 vec P(xi)``, ``v = 2 vec D(xi) - t x w``."""
    xp = common_namespace(xi, t)
    w = 2.0 * xi[..., 1:4]
    return xp.concatenate([2.0 * xi[..., 5:8] - cross(t, w), w], axis=-1)


def canonical_sign(y):
    """``+1`` or ``-1``: the sign making the primary part of ``y`` ``(..., 8)`` canonical (its
    first nonzero component of ``(w, x, y, z)`` positive; ``+1`` for a zero primary part)."""
    xp = common_namespace(y)
    w, a, b, c = y[..., 0], y[..., 1], y[..., 2], y[..., 3]
    lead = xp.where(w != 0.0, w, xp.where(a != 0.0, a, xp.where(b != 0.0, b, c)))
    return xp.where(lead < 0.0, -1.0, 1.0)


def aligned(y_j, y_i):
    """``y_j`` or ``-y_j``, whichever primary part is nearer ``y_i``'s, for broadcast ``(..., 8)``.

    Where the primary parts are orthogonal (the two rotations half a turn apart) both are
    equally near; the sign is then ``s(y_j) s(y_i)`` (:func:`canonical_sign`), so the result
    is the same for ``y_j`` and ``-y_j`` and changes sign with ``y_i``: a law written with it
    gives one command for every sign of every pose, at the tie included.
    """
    xp = common_namespace(y_j, y_i)
    d = dot_last(y_j[..., 0:4], y_i[..., 0:4])
    tie = canonical_sign(y_j) * canonical_sign(y_i)
    s = xp.where(d > 0.0, 1.0, xp.where(d < 0.0, -1.0, tie))
    return s[..., None] * y_j


def canonical(y):
    """``y`` or ``-y`` ``(..., 8)``, whichever has the canonical primary part (``w >= 0``)."""
    return canonical_sign(y)[..., None] * y


def formation_variable(x, x_d):
    """``y = x x_d*``: the displacement that carries the desired pose onto the pose, ``x = y x_d``."""
    return dqmul(x, dqconj(x_d))


def pose_twist_commands(zeta, y, x_d, desired_twist, t):
    """Each robot's ``(v, w)`` ``(..., 6)`` that moves its formation variable ``y = x x_d*`` with the
    twist ``zeta`` (``y_dot = zeta y``, ``(..., 8)`` pure) while its desired pose ``x_d`` moves with
    ``desired_twist`` (world ``(v_d, w_d)`` ``(..., 6)`` of ``x_d``'s frame); ``t`` is the robot's
    position (m). From ``x = y x_d``: ``x_dot x* = zeta + y xi_d y*`` with ``xi_d = x_d_dot x_d*``
    (:func:`twist_dq` at ``x_d``'s position)."""
    xi_d = twist_dq(desired_twist[..., 0:3], desired_twist[..., 3:6], translation(x_d))
    return twist_commands(zeta + dqmul(dqmul(y, xi_d), dqconj(y)), t)


def from_desired(law: str, reference: dict, n: int) -> dict:
    """``reference`` with each robot's desired pose point and its rate (``desired``,
    ``desired_rate`` ``(*batch?, n, 7)``: ``(x, y, z, q_w, q_x, q_y, q_z)`` and its rate, what
    :class:`~quatform.control.networked.NetworkedController` gives from the team's desired
    points) as ``pose`` (unit dual quaternions) and ``twist`` (world ``(v, w)``, ``w = 2 vec(q_dot
    q*)``, seed 001 eq. (2.32))."""
    out = dict(reference)
    rows = np.asarray(out.pop("desired"), dtype=float)
    rate = np.asarray(out.pop("desired_rate", np.zeros(rows.shape)), dtype=float)
    if rows.ndim < 2 or rows.shape[-2:] != (n, 7) or rate.shape[-2:] != (n, 7):
        raise ShapeError(f"{law}: reference 'desired' and 'desired_rate' must have shape (*batch, {n}, 7) (pose points "
                         f"x, y, z, q_w, q_x, q_y, q_z and their rates), got {rows.shape} and {rate.shape}")
    q = rows[..., 3:7]
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(rows)) or not np.all(np.isfinite(rate)) or np.any(np.abs(norm - 1.0) > UNIT_TOLERANCE):
        raise NonUnitError(f"{law}: reference 'desired' must hold finite poses with unit quaternions and finite "
                           f"rates; build the desired points of a pose robot with unit orientations")
    q = q / norm
    out["pose"] = pose_dq(np.concatenate([rows[..., 0:3], q], axis=-1))
    w = 2.0 * qmul(rate[..., 3:7], q * _CONJ8[:4])[..., 1:4]
    out["twist"] = np.concatenate([rate[..., 0:3], w], axis=-1)
    return out


def consensus_error(own, desired) -> np.ndarray:
    """The team's disagreement ``(...)`` of the dual-quaternion laws, from the robots' pose points
    and their desired ones (``(..., N, 7)`` each, NumPy): the root mean square over the robots of
    ``|y~_i - mean(y~)|``, ``y = x x_d*`` (8 components; the rotation part dimensionless, the
    dual part half a translation in m), each ``y_i`` signed nearest robot 1's: zero exactly where
    every ``x_i = c x_d_i`` for one ``c`` (the laws' invariant), whatever the signs of the poses."""
    q = np.asarray(desired, dtype=float)[..., 3:7]
    x_d = pose_dq(np.concatenate([np.asarray(desired, dtype=float)[..., 0:3],
                                  q / np.linalg.norm(q, axis=-1, keepdims=True)], axis=-1))
    y = formation_variable(pose_dq(np.asarray(own, dtype=float)), x_d)
    y = aligned(y, y[..., :1, :])
    dev = y - y.mean(axis=-2, keepdims=True)
    return np.sqrt(np.mean(np.sum(dev * dev, axis=-1), axis=-1))


def check_reference(law: str, reference, n: int, extra: dict | None = None) -> dict:
    """The reference of a dual-quaternion law as NumPy arrays, checked on the host.

    ``pose``: each robot's desired pose ``(*batch?, n, 8)``, unit dual quaternions (within
    :data:`~quatform.algebra.UNIT_TOLERANCE`); ``twist``: their world twists ``(v, w)``
    ``(*batch?, n, 6)`` m/s and rad/s (default 0: a fixed formation); ``extra``: ``{key:
    (shape after the batch, unit, default)}`` further per-robot arrays, nonnegative.
    """
    if not isinstance(reference, dict):
        raise InvalidInputError(f"{law}: the reference must be a dict with 'pose' (n, 8), each robot's desired pose "
                                f"as a unit dual quaternion, got {type(reference).__name__}")
    if "desired" in reference and "pose" not in reference:
        reference = from_desired(law, reference, n)
    out = {}
    try:
        pose = np.asarray(reference["pose"], dtype=float)
    except KeyError:
        raise InvalidInputError(f"{law}: the reference needs 'pose', each robot's desired pose as a unit dual "
                                f"quaternion, an array ({n}, 8)") from None
    except (TypeError, ValueError):
        raise InvalidInputError(f"{law}: reference 'pose' must be an array of numbers ({n}, 8)") from None
    if pose.ndim < 2 or pose.shape[-2:] != (n, 8):
        raise ShapeError(f"{law}: reference 'pose' must have shape (*batch, {n}, 8), got {pose.shape}")
    if not np.all(np.isfinite(pose)):
        raise InvalidInputError(f"{law}: reference 'pose' holds NaN or infinity")
    r, d = pose[..., :4], pose[..., 4:]
    bad = np.maximum(np.abs(np.sum(r * r, axis=-1) - 1.0), np.abs(np.sum(r * d, axis=-1)))
    if np.any(bad > UNIT_TOLERANCE):
        i = int(np.unravel_index(np.argmax(bad), bad.shape)[-1])
        raise NonUnitError(f"{law}: reference 'pose' of robot {i + 1} is not a unit dual quaternion (|r|^2 - 1 or "
                           f"r.d off by {np.max(bad):.3g} > {UNIT_TOLERANCE:g}); build it with "
                           f"quatform.algebra.dq_from_pose")
    out["pose"] = pose
    specs = {"twist": ((n, 6), "(m/s, rad/s)", 0.0, False)}
    specs.update({k: (shape, unit, default, True) for k, (shape, unit, default) in (extra or {}).items()})
    for key, (shape, unit, default, nonnegative) in specs.items():
        if key not in reference:
            out[key] = np.full(shape, float(default))
            continue
        try:
            a = np.asarray(reference[key], dtype=float)
        except (TypeError, ValueError):
            raise InvalidInputError(f"{law}: reference {key!r} must be an array of numbers {shape} in {unit}") from None
        if a.ndim < len(shape) or a.shape[a.ndim - len(shape):] != shape:
            raise ShapeError(f"{law}: reference {key!r} must have shape (*batch, {', '.join(map(str, shape))}), got "
                             f"{a.shape}")
        if not np.all(np.isfinite(a)):
            raise InvalidInputError(f"{law}: reference {key!r} holds NaN or infinity")
        if nonnegative and np.any(a < 0):
            raise InvalidInputError(f"{law}: reference {key!r} holds a negative value ({a.min():g}); give weights >= 0")
        out[key] = a
    return out


def check_gain(law: str, k) -> None:
    """A positive finite gain in 1/s, else one line."""
    if isinstance(k, bool) or not isinstance(k, (int, float, np.number)) or not np.isfinite(k) or k <= 0:
        raise InvalidInputError(f"{law}: gain = {k!r} must be a positive number in 1/s")


@dataclass(frozen=True)
class PoseLaw(LocalController):
    """The part the dual-quaternion laws share: each robot measures its pose point, commands its
    world twist and sends its formation variable ``y = x x_d*``; the reference is each robot's
    desired pose (:func:`check_reference`); the team's error is :func:`consensus_error` and the
    predicted rate that of the linearisation ``y <- (I - k dt L) y`` near consensus (no name: a
    base, not a law)."""

    gain: float = 1.0

    message_columns = Y_COLUMNS
    own_columns = POSE_COLUMNS
    command_columns = TWIST_COLUMNS

    def __post_init__(self):
        check_gain(self.name, self.gain)

    def example(self, n, rng):
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        desired = np.concatenate([rng.normal(size=(n, 3)), q], axis=-1)
        q2 = q + 0.3 * rng.normal(size=(n, 4))
        own = np.concatenate([rng.normal(size=(n, 3)), q2 / np.linalg.norm(q2, axis=-1, keepdims=True)], axis=-1)
        return own, {"desired": desired, "desired_rate": 0.1 * rng.normal(size=(n, 7))}

    def consensus_error(self, own, desired):
        """:func:`consensus_error`: zero where every ``x_i = c x_d_i``."""
        return consensus_error(own, desired)

    def predicted_rate(self, graph, period_s, switching_period_s=None):
        """The linearisation ``y <- (I - k dt L) y`` of ``y = x x_d*`` near consensus (leaderless):
        :meth:`Graph.predicted_rate` at the control period, or for a repeated switching schedule
        :func:`~quatform.network.graph.switching_rate`."""
        if switching_period_s is not None:
            return switching_rate(graph, switching_period_s, self.gain, period_s)
        return graph.predicted_rate(self.gain, dt_s=period_s)

    def message(self, state, own, reference, t):
        return formation_variable(pose_dq(own), reference["pose"])
