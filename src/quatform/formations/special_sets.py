"""Special sets of the formation descriptions: robot states where a formula divides by zero,
takes an undefined angle, or meets ``q`` versus ``-q``, and what the description does there.

Formations layer (beside :mod:`.base`). Each description lists its sets in
``special_sets()``; ``formations.testing.check_formation`` checks the declared behaviour at
and near each one. The generators here build robot states of the two robot layouts of
seeds 000 and 001 ``eps`` away from a set (``eps = 0``: on it); they use only the robots'
geometry, not a description, so every description of a layout is checked on the same states.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["SpecialSet", "pair_states", "pair_vertical", "pair_anti_x", "pair_half_turn_yaws", "pair_wound_yaws",
           "ugv_uav_states", "ugv_uav_overhead", "ugv_uav_behind", "ugv_uav_restricted_overhead",
           "ugv_uav_restricted_corner"]


@dataclass(frozen=True)
class SpecialSet:
    """A special set of a description and its behaviour there.

    Attributes
    ----------
    name : str
        Short name (``vertical``, ``anti-x``, ...).
    why : str
        The formula and what goes wrong in it.
    states : callable
        ``states(rng, n, eps) -> ndarray (n, n_r)``: robot states ``eps`` (rad) away from
        the set; ``eps = 0`` on it.
    jacobian : str
        At ``eps = 0``: ``"finite"``, or ``"raises"`` (DegenerateInputError: the rate of a
        variable is undefined there).
    inverse_jacobian : str
        At ``eps = 0``: ``"full-rank"``, or ``"rank-deficient"`` (finite, singularity
        measure 0: a direction of the cluster state moves no robot).
    round_trip_tol : float
        Relative accuracy of ``inverse(forward(r))`` on and near the set (1e-9; larger where
        a formula loses digits there, e.g. a square root of a rounding error).
    """

    name: str
    why: str
    states: Callable
    jacobian: str = "finite"
    inverse_jacobian: str = "full-rank"
    round_trip_tol: float = 1e-9


# -- two 4-DOF robots (seed 000), r = (x1, y1, z1, theta1, x2, y2, z2, theta2) -------------

def pair_states(centre, beta, gamma, d, theta1, theta2):
    """Robots at ``centre +- d u(beta, gamma)`` with ``u = (-sin b cos g, cos b cos g, sin g)``
    (seed 000 eqs. (1)-(6) solved for the positions) and yaws ``theta1``, ``theta2``."""
    u = np.stack([-np.sin(beta) * np.cos(gamma), np.cos(beta) * np.cos(gamma), np.sin(gamma)], axis=-1)
    half = np.asarray(d)[..., None] * u
    return np.concatenate([centre + half, np.asarray(theta1)[..., None], centre - half,
                           np.asarray(theta2)[..., None]], axis=-1)


def _pair_random(rng, n):
    return (rng.uniform(-2, 2, (n, 3)), rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.2, 1.2, n),
            rng.uniform(0.3, 2.0, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n))


def pair_vertical(rng, n, eps):
    """One robot ``eps`` rad from straight above (or below) the other: ``gamma_c = +-(pi/2 - eps)``
    (eq. (4)'s ``atan2(0, 0)`` on the set)."""
    x, b, _, d, t1, t2 = _pair_random(rng, n)
    sign = rng.choice([-1.0, 1.0], n)
    return pair_states(x, b, sign * (0.5 * np.pi - eps), d, t1, t2)


def pair_anti_x(rng, n, eps):
    """``x1 - x2`` ``eps`` rad from ``-i`` (the seed's minimal rotation from ``i``, eqs. (14)-(15),
    is 0/0 on the set)."""
    x, _, _, d, t1, t2 = _pair_random(rng, n)
    psi = rng.uniform(-np.pi, np.pi, n)
    return pair_states(x, 0.5 * np.pi + eps * np.cos(psi), eps * np.sin(psi), d, t1, t2)


def pair_half_turn_yaws(rng, n, eps):
    """Relative yaw ``theta1 - theta2 = +-pi + eps`` (the short square root of ``qhat_s``, eq. (26),
    jumps there; ``q_c1`` and ``q_c2`` half a turn apart)."""
    x, b, gam, d, t1, _ = _pair_random(rng, n)
    return pair_states(x, b, gam, d, t1, t1 - rng.choice([-1.0, 1.0], n) * (np.pi + eps))


def pair_wound_yaws(rng, n, eps):
    """Yaws wound by up to 50 turns either way (read as real numbers by the half-way yaw of
    eq. (26)); ``eps`` is added to both."""
    x, b, gam, d, t1, t2 = _pair_random(rng, n)
    k = rng.integers(-50, 51, (2, n))
    return pair_states(x, b, gam, d, t1 + 2 * np.pi * k[0] + eps, t2 + 2 * np.pi * k[1] + eps)


# -- UGV control point and UAV (seed 001), r = (x_p, y_p, z_p, x_b, y_b, z_b) ---------------

def ugv_uav_states(x_p, rho, alpha, beta):
    """UAV at ``x_p + rho (cos a cos b, sin a cos b, sin b)`` (seed 001 eqs. (4.10)-(4.12))."""
    u = np.stack([np.cos(alpha) * np.cos(beta), np.sin(alpha) * np.cos(beta), np.sin(beta)], axis=-1)
    return np.concatenate([x_p, x_p + np.asarray(rho)[..., None] * u], axis=-1)


def ugv_uav_overhead(rng, n, eps):
    """The UAV ``eps`` rad from straight above or below the UGV (eq. (4.5)'s ``alpha_c`` is
    ``atan2(0, 0)`` on the set)."""
    sign = rng.choice([-1.0, 1.0], n)
    return ugv_uav_states(rng.uniform(-2, 2, (n, 3)), rng.uniform(0.5, 2.0, n), rng.uniform(-np.pi, np.pi, n),
                          sign * (0.5 * np.pi - eps))


def ugv_uav_behind(rng, n, eps):
    """The UAV ``eps`` rad from straight behind the UGV, along ``-x`` (eq. (4.5)'s branch cut
    ``alpha_c = +-pi``; the minimal rotation from ``i`` of eqs. (4.26)-(4.29) is 0/0 on it)."""
    psi = rng.uniform(-np.pi, np.pi, n)
    return ugv_uav_states(rng.uniform(-2, 2, (n, 3)), rng.uniform(0.5, 2.0, n), np.pi + eps * np.cos(psi),
                          eps * np.sin(psi))


def _restricted_states(rng, n, a, b):
    """UAV at ``alpha_f = a``, ``beta_f = b`` (eqs. (4.22)-(4.24))."""
    x_p = rng.uniform(-2, 2, (n, 3))
    rho = rng.uniform(0.5, 2.0, n)
    sa, sb = np.sin(a), np.sin(b)
    w = np.sqrt(np.maximum(0.0, 1.0 - sa * sa - sb * sb))
    return np.concatenate([x_p, x_p + rho[:, None] * np.stack([sa, sb, w], axis=-1)], axis=-1)


def ugv_uav_restricted_overhead(rng, n, eps):
    """The UAV ``eps`` rad (in ``alpha_f`` and ``beta_f``) from overhead: the lower edge of the
    restricted description's operating range."""
    return _restricted_states(rng, n, np.full(n, eps), np.full(n, eps) * rng.uniform(0, 1, n))


def ugv_uav_restricted_corner(rng, n, eps):
    """``alpha_f = beta_f = 45 deg - eps``: the UAV near platform level, where (4.24)'s root
    ``sqrt(1 - sin^2 alpha_f - sin^2 beta_f)`` is 0 and its derivative infinite."""
    a = np.full(n, np.radians(45.0) - eps)
    return _restricted_states(rng, n, a, a)


def pair_sets(vertical_why, jacobian="finite", inverse_jacobian="full-rank"):
    """The special sets of a two-robot description: the vertical segment (its behaviour
    given), ``x1 - x2`` along ``-i``, half-turn relative yaws and yaws wound by many turns."""
    return (
        SpecialSet("vertical", vertical_why, pair_vertical, jacobian, inverse_jacobian),
        SpecialSet("anti-x", "x1 - x2 along -i: the seed's minimal rotation from i (eqs. (14)-(15)) is 0/0",
                   pair_anti_x),
        SpecialSet("half-turn-yaws", "theta1 - theta2 = +-pi: the short root of qhat_s (eq. (26)) jumps, q_c1 and "
                   "q_c2 half a turn apart", pair_half_turn_yaws),
        SpecialSet("wound-yaws", "yaws wound by up to 50 turns (read as real numbers by eq. (26)'s half-way yaw)",
                   pair_wound_yaws),
    )
