"""An operator's goal for the formation's pose, followed within rate limits (references layer).

A live run (``quatform run --live``) lets an operator send the formation a goal pose: the
reference's centroid ``x_c`` and attitude ``q_c`` then move toward it tick by tick, the
rest of the reference (shape, headings) staying the scenario's. :func:`approach_pose` is the
pure step of that motion, written once on the array namespace of its operands (NumPy or
JAX, any leading batch axes, branch-free): the centroid moves along the straight line to the
goal at most ``max_speed * dt`` per tick, the attitude along the shortest great arc
(spherical linear interpolation, Shoemake 1985, "Animating rotation with quaternion
curves", SIGGRAPH '85, eq. for ``slerp(q, p; s) = q (q* p)^s``) at most ``max_rate * dt``
radians per tick, so the reference's speed and angular rate stay within the bounds and it
lands on the goal exactly once it is within one step. The goal's sign is taken nearer the
current attitude (``q`` and ``-q`` are one rotation: the arc is never the long way round),
and a goal equal to the current pose (or its negative) is a step of zero, never a NaN.

Given the velocities of the tick before and acceleration bounds, the step also bounds how fast
its velocity changes: the velocity goes toward the one the motion asks for (toward the goal, at
most the speed bound and at most the speed from which steps of ``max_accel dt`` less each stop
on the goal, :func:`_stopping_speed`) by at most ``max_accel dt`` per tick, and likewise the
angular velocity by ``max_ang_accel dt``, so the reference's velocity never jumps when a goal
arrives or changes, and it still lands on the goal.

:func:`goal_limits` gives the bounds of a team from its robots' own limits.
"""

from __future__ import annotations

from ..algebra.kernels import array_namespace, dot_last, qmul_components
from ..errors import InvalidInputError

__all__ = ["approach_pose", "goal_limits", "GOAL_SHARE", "GOAL_RAMP_S"]

#: The share of the slowest robot's speed limit ``v_min`` the goal motion may take
#: (:func:`goal_limits`), half in translation and half in rotation: a robot at distance
#: ``rho <= radius`` from the centroid moves at most ``v + w rho <= GOAL_SHARE v_min``, so the
#: reference leaves every robot ``(1 - GOAL_SHARE) v_min`` of its limit for the controller's
#: corrections.
GOAL_SHARE = 0.8

#: The time the goal motion takes to reach its speed bound from rest, s: its acceleration
#: bounds are ``max_speed / GOAL_RAMP_S`` and ``max_rate / GOAL_RAMP_S`` (a live run's).
GOAL_RAMP_S = 0.5

#: Below this (m, rad) a step is taken as arrived (the direction of a zero vector is not used).
_TINY = 1e-12


def _qmul(xp, q, p):
    return xp.stack(qmul_components(*(q[..., i] for i in range(4)), *(p[..., i] for i in range(4))), axis=-1)


def _stopping_speed(xp, dist, accel, dt):
    """The largest speed from which ticks that each take ``accel dt`` off the speed (and move
    ``speed dt``) stop within ``dist``: ``n accel dt`` with ``dist = accel dt^2 n (n + 1) / 2``."""
    h = accel * dt * dt
    return accel * dt * (xp.sqrt(0.25 + 2.0 * dist / h) - 0.5)


def _toward(xp, current, wanted, most):
    """``current`` moved toward ``wanted`` (``(..., 3)``) by at most ``most`` (norm)."""
    change = wanted - current
    size = xp.sqrt(dot_last(change, change))
    scale = xp.where(size > most, most / xp.where(size > most, size, 1.0), 1.0)
    return current + scale[..., None] * change


def approach_pose(p, q, p_goal, q_goal, max_speed, max_rate, dt, v=None, w=None, max_accel=None,
                  max_ang_accel=None):
    """One tick of the pose ``(p, q)`` toward ``(p_goal, q_goal)`` within rate limits (and, given
    the velocities ``v``, ``w`` of the tick before, acceleration limits).

    Parameters
    ----------
    p, p_goal : array_like, shape (..., 3)
        The current and the goal position, m (world).
    q, q_goal : array_like, shape (..., 4)
        The current and the goal attitude, unit quaternions ``(w, x, y, z)`` (world from
        body); ``q_goal`` of either sign.
    max_speed : float or array_like, shape (...)
        Largest speed of the position, m/s (> 0).
    max_rate : float or array_like, shape (...)
        Largest angular rate of the attitude, rad/s (> 0).
    dt : float
        The tick, s (> 0).
    v, w : array_like, shape (..., 3), optional
        The velocity (m/s) and world angular velocity (rad/s) of the tick before, each given
        with its acceleration bound.
    max_accel, max_ang_accel : float or array_like, shape (...), optional
        Largest change of ``v`` per second, m/s^2, and of ``w``, rad/s^2 (> 0); without them
        the velocities follow the goal at once.

    Returns
    -------
    p_next : ndarray, shape (..., 3)
        The position one tick later, m: ``p + v dt``.
    q_next : ndarray, shape (..., 4)
        The attitude one tick later (unit, the sign continuing ``q``'s): ``exp(w dt / 2) q``.
    v : ndarray, shape (..., 3)
        The position's velocity over the tick, m/s (``|v| <= max_speed``; within ``max_accel dt``
        of the ``v`` given).
    w : ndarray, shape (..., 3)
        The attitude's angular velocity over the tick, rad/s, world frame (``|w| <= max_rate``;
        within ``max_ang_accel dt`` of the ``w`` given); the attitude's rate is ``q_dot = (0, w) q / 2``.
    """
    xp = array_namespace(p)
    p, q, p_goal, q_goal = (xp.asarray(a, dtype=float) for a in (p, q, p_goal, q_goal))
    # position: along the straight line, at most max_speed dt (and, bounded, stopping in time)
    d = p_goal - p
    dist = xp.sqrt(dot_last(d, d))
    step = xp.minimum(dist, max_speed * dt)
    if max_accel is not None:
        step = xp.minimum(step, _stopping_speed(xp, dist, max_accel, dt) * dt)
    frac = xp.where(dist > _TINY, step / xp.where(dist > _TINY, dist, 1.0), 1.0)
    move = frac[..., None] * d
    if max_accel is not None:
        move = _toward(xp, xp.asarray(v, dtype=float), move / dt, max_accel * dt) * dt
    p_next = p + move
    v = move / dt
    # attitude: the goal's sign nearer q (shortest arc), then the world-frame rotation q_goal q*
    q_goal = xp.where((dot_last(q, q_goal) < 0.0)[..., None], -q_goal, q_goal)
    conj = xp.asarray([1.0, -1.0, -1.0, -1.0])
    rel = _qmul(xp, q_goal, q * conj)
    s = xp.sqrt(dot_last(rel[..., 1:], rel[..., 1:]))
    angle = 2.0 * xp.arctan2(s, xp.abs(rel[..., 0]))  # in [0, pi]: rel's scalar part is q . q_goal >= 0
    axis = rel[..., 1:] / xp.where(s > _TINY, s, 1.0)[..., None]
    axis = xp.where((s > _TINY)[..., None], axis, 0.0)
    turn = xp.minimum(angle, max_rate * dt)
    if max_ang_accel is not None:
        turn = xp.minimum(turn, _stopping_speed(xp, angle, max_ang_accel, dt) * dt)
        wanted = _toward(xp, xp.asarray(w, dtype=float), axis * (turn / dt)[..., None], max_ang_accel * dt)
        rate = xp.sqrt(dot_last(wanted, wanted))
        axis = wanted / xp.where(rate > _TINY, rate, 1.0)[..., None]
        axis = xp.where((rate > _TINY)[..., None], axis, 0.0)
        turn = rate * dt
    half = 0.5 * turn
    rot = xp.concatenate([xp.cos(half)[..., None], xp.sin(half)[..., None] * axis], axis=-1)
    q_next = _qmul(xp, rot, q)
    q_next = q_next / xp.sqrt(dot_last(q_next, q_next))[..., None]
    w = axis * (turn / dt)[..., None]
    return p_next, q_next, v, w


def _speed_limit(robot) -> float:
    """The speed a robot's point can move at, m/s: its ``max_speed`` (holonomic, planar, free-body
    robots, the Bebop), else its forward speed ``max_v`` (a Pioneer's control point moves at
    ``max_v`` along its heading)."""
    for name in ("max_speed", "max_v"):
        value = getattr(robot, name, None)
        if value is not None:
            return float(value)
    raise InvalidInputError(f"robot model {type(robot).__name__} declares no speed limit (max_speed or max_v); "
                            "the live goal's speed cannot be bounded")


def goal_limits(robots, radius: float) -> tuple[float, float]:
    """``(max_speed m/s, max_rate rad/s)`` of a goal's motion for a team of ``robots`` whose
    farthest robot is ``radius`` m from the centroid: half of :data:`GOAL_SHARE` of the slowest
    robot's speed limit ``v_min`` in translation, ``v = GOAL_SHARE v_min / 2``, and the angular
    rate that moves the farthest robot at that speed, ``w = v / radius``; a robot at distance
    ``rho <= radius`` then moves at most ``v + w rho <= GOAL_SHARE v_min < v_min`` with both.
    None of the built-in scenarios or robots declares a limit for the formation as a whole, so
    the robots' own limits bound it."""
    half = 0.5 * GOAL_SHARE * min(_speed_limit(r) for r in robots)
    return half, half / max(float(radius), _TINY)

