"""Special sets of the team descriptions: robot states of N robots of any point kinds where a
formula divides by zero, takes an undefined angle or meets ``q`` versus ``-q`` (formations layer).

The generators here build robot states of a :class:`~.layout.RobotLayout` ``eps`` away from
a set (``eps = 0``: on it), from the robots' geometry only (no description), so every team
description of a layout is checked on the same states
(``formations.testing.check_formation`` through a description's ``special_sets()``). A
planar (``xy_yaw``) robot stays on the ground: where a set is a shape of the positions
(collinear robots) the generators keep the whole formation in ``z = 0`` for a layout with
planar robots; elsewhere the planar robots' ``z`` is dropped (the state is then near, not
on, a set that only concerns a reading, not the descriptions).
"""

from __future__ import annotations

import numpy as np

from . import geometry as g
from .layout import RobotLayout
from .team_chart import default_template

__all__ = ["team_collinear", "team_vertical", "team_anti_x", "team_half_turn_attitude", "team_half_turn_yaws",
           "team_wound_yaws", "team_states"]


def _has_planar(layout: RobotLayout) -> bool:
    return "xy_yaw" in layout.kinds


def _random_unit(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def team_states(layout: RobotLayout, rng, p, attitude=None, yaws=None):
    """The robot state of positions ``p`` (``(n, N, 3)`` m; planar robots' z dropped), yaws
    ``yaws`` (``(n, n_yaw)`` rad; default uniform in +-pi) and, for ``pose`` robots, random
    orientations (turned by ``attitude`` (``(n, 4)``) when given)."""
    n = p.shape[0]
    if yaws is None:
        yaws = rng.uniform(-np.pi, np.pi, (n, len(layout.yaw_indices)))
    m = len(layout.orientation_index)
    o = _random_unit(rng, (n, m))
    if attitude is not None and m:
        o = g.mul(attitude[:, None, :], o)
    return layout.compose(p, yaws, o)


def _formation(layout: RobotLayout, rng, n, q):
    """Robots at the layout's default template, scaled by 0.5-2 and turned by ``q`` (``(n, 4)``),
    about a random centre: ``(n, N, 3)``. Planar robots are put on the ground (``z = 0``),
    each moved horizontally by a random 0.3-0.6 m where the drop would bring two robots
    within 0.2 m of each other (a formation standing on edge projects robots onto one spot)."""
    t = default_template(layout)
    scale = rng.uniform(0.5, 2.0, (n, 1, 1))
    centre = rng.uniform(-2.0, 2.0, (n, 1, 3))
    p = centre + g.rotate(q[:, None, :], scale * t)
    planar = [i for i, k in enumerate(layout.kinds) if k == "xy_yaw"]
    if planar:
        p[:, planar, 2] = 0.0
        i, j = layout.pairs
        base = p[:, planar, :2].copy()
        for _ in range(100):
            d = np.linalg.norm(p[:, i] - p[:, j], axis=-1)
            close = np.any(d < 0.2, axis=-1)
            if not np.any(close):
                break
            a = rng.uniform(-np.pi, np.pi, (n, len(planar)))
            off = rng.uniform(0.3, 0.6, (n, len(planar)))[..., None] * np.stack([np.cos(a), np.sin(a)], -1)
            p[:, planar, :2] = np.where(close[:, None, None], base + off, p[:, planar, :2])
    return p


def team_collinear(layout: RobotLayout, rng, n, eps):
    """Every robot on one line, then each moved ``eps`` (relative to the formation's size) off
    it: Horn's matrix (Horn 1987 eq. (35)) has a double top eigenvalue on the set (the twist
    about the line is not a function of the positions). A horizontal line in ``z = 0`` for a
    layout with planar robots (offsets horizontal too), any line otherwise."""
    N = layout.n
    planar = _has_planar(layout)
    u = rng.normal(size=(n, 3))
    w = rng.normal(size=(n, N, 3))
    centre = rng.uniform(-2.0, 2.0, (n, 1, 3))
    if planar:
        u[:, 2] = 0.0
        w[..., 2] = 0.0
        centre[..., 2] = 0.0
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    w -= np.sum(w * u[:, None, :], axis=-1, keepdims=True) * u[:, None, :]  # perpendicular to the line
    w /= np.maximum(np.linalg.norm(w, axis=-1, keepdims=True), 1e-300)
    spacing = rng.uniform(0.3, 0.8, (n, N))
    t = np.cumsum(spacing, axis=-1)
    t -= t.mean(axis=-1, keepdims=True)
    t = t[:, rng.permutation(N)]  # robots in any order along the line
    size = np.max(np.abs(t), axis=-1)[:, None, None]
    p = centre + t[..., None] * u[:, None, :] + eps * size * w
    return team_states(layout, rng, p)


def team_vertical(layout: RobotLayout, rng, n, eps):
    """The formation's x axis ``eps`` rad from vertical: attitude ``q_z(psi) q_y(-+(pi/2 - eps))
    q_x(phi)`` (the z-y-x reading's gimbal lock, seed 000 eq. (5)'s ``|gamma_c| = pi/2`` for two
    robots: one straight above the other)."""
    sign = rng.choice([-1.0, 1.0], n)
    q = g.mul(g.mul(g.q_yaw(rng.uniform(-np.pi, np.pi, n)), g.q_pitch_y(-sign * (0.5 * np.pi - eps))),
              _q_roll(rng.uniform(-np.pi, np.pi, n)))
    return team_states(layout, rng, _formation(layout, rng, n, q), attitude=q)


def _q_roll(a):
    q = np.zeros(np.shape(a) + (4,))
    q[..., 0], q[..., 1] = np.cos(0.5 * a), np.sin(0.5 * a)
    return q


def team_anti_x(layout: RobotLayout, rng, n, eps):
    """``p_1 - p_2`` ``eps`` rad from ``-x``: seed 000 eqs. (14)-(15) (the minimal rotation
    from ``i``) are 0/0 there for two robots. With planar robots the formation is only yawed
    (about the vertical through its centroid), so ``p_1 - p_2``'s horizontal part is put
    there."""
    planar = _has_planar(layout)
    q0 = g.q_yaw(rng.uniform(-np.pi, np.pi, n)) if planar else _random_unit(rng, (n,))
    p = _formation(layout, rng, n, q0)
    d = p[:, 0] - p[:, 1]
    psi = rng.uniform(-np.pi, np.pi, n)
    if planar:
        turn = g.q_yaw(np.pi + eps * np.sign(np.cos(psi)) - np.arctan2(d[:, 1], d[:, 0]))
    else:
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        target = np.stack([-np.cos(eps) * np.ones(n), np.sin(eps) * np.cos(psi), np.sin(eps) * np.sin(psi)], -1)
        turn = g.swing(d, target, np.array([0.0, 0.0, 1.0]))
    c = p.mean(axis=1, keepdims=True)
    p = c + g.rotate(turn[:, None, :], p - c)
    return team_states(layout, rng, p, attitude=g.mul(turn, q0))


def team_half_turn_attitude(layout: RobotLayout, rng, n, eps):
    """The formation turned by ``pi - eps`` about a random axis from the template: ``q_c`` has
    ``w = sin(eps / 2)``, so without a hint its sign (nearest 1) flips across the set (``q``
    versus ``-q``: one attitude)."""
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * (np.pi - eps * rng.choice([-1.0, 1.0], n))
    q = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], axis=-1)
    return team_states(layout, rng, _formation(layout, rng, n, q), attitude=q)


def team_half_turn_yaws(layout: RobotLayout, rng, n, eps):
    """Headings half a turn (``+- pi + eps``) from the formation's yaw and from their neighbours':
    ``q_ci = q_c* q_i`` near a rotation by pi (``w`` near 0, the sign rule of eq. (20)'s error)."""
    psi = rng.uniform(-np.pi, np.pi, n)
    q = g.q_yaw(psi)
    k = np.arange(len(layout.yaw_indices))
    yaws = psi[:, None] + np.pi * (1 + k)[None, :] + eps
    m = len(layout.orientation_index)
    p = _formation(layout, rng, n, q)
    o = np.broadcast_to(g.mul(q, g.q_yaw(np.full(n, np.pi + eps)))[:, None, :], (n, m, 4))
    return layout.compose(p, yaws, o)


def team_wound_yaws(layout: RobotLayout, rng, n, eps):
    """Yaws wound by up to 50 turns either way, ``eps`` added to each."""
    q = _random_unit(rng, (n,))
    ny = len(layout.yaw_indices)
    yaws = rng.uniform(-np.pi, np.pi, (n, ny)) + 2.0 * np.pi * rng.integers(-50, 51, (n, ny)) + eps
    return team_states(layout, rng, _formation(layout, rng, n, q), attitude=q, yaws=yaws)
