"""A two-robot spatial plan as the reference of the seed 000 pair controllers.

Planning layer (uses formations). :class:`PlanPairPath` turns a plan of N = 2 robots in
space into the Euclidean cluster variables of seed 000 eqs. (1)-(8),
``e = (x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)``, and their exact rates, with the
interface of :class:`~quatform.references.EuclideanPath` (``path(t) -> (e, e_dot)``), so
every controller receives the plan through its description's ``from_euclidean``.

The plan gives positions only; the robots' yaws are held constant (``yaws``, default 0).
Angles are continuous along the plan: the pitch runs through ``±pi/2`` (no fold), and
where the segment is vertical ``beta_c`` is held (its rate set to 0): the same convention
as ``EuclideanPair.forward`` with a hint. The plan must not turn about the vertical while
passing through it (``beta_c`` would jump); the error says so.
"""

from __future__ import annotations

import numpy as np

from ..errors import DegenerateInputError, InvalidInputError
from .plan import Plan

__all__ = ["PlanPairPath"]

#: Below this ``|cos gamma_c|`` the segment counts as vertical: ``beta_c`` held.
VERTICAL_COS = 1e-6


def _angles(u):
    beta = np.arctan2(-u[..., 0], u[..., 1])  # seed 000 eq. (4)
    gamma = np.arctan2(u[..., 2], np.hypot(u[..., 0], u[..., 1]))  # eq. (5)
    return beta, gamma


def _partials(beta, gamma):
    """``d u / d beta`` and ``d u / d gamma`` of ``u = segment_direction(beta, gamma)``."""
    cb, sb, cg, sg = np.cos(beta), np.sin(beta), np.cos(gamma), np.sin(gamma)
    return (np.stack([-cb * cg, -sb * cg, np.zeros_like(cb)], axis=-1),
            np.stack([sb * sg, -cb * sg, cg], axis=-1))


def _near(a, ref):
    return a + 2.0 * np.pi * np.round((ref - a) / (2.0 * np.pi))


class PlanPairPath:
    """Euclidean cluster path of a two-robot spatial plan.

    Parameters
    ----------
    plan : Plan
        N = 2 robots, d = 3.
    yaws : (float, float)
        Constant yaws of robots 1 and 2, rad.
    """

    def __init__(self, plan: Plan, yaws=(0.0, 0.0)):
        if plan.n_robots != 2 or plan.dim != 3:
            raise InvalidInputError(
                f"a pair-controller reference needs a plan of 2 robots in space (d = 3), got N = "
                f"{plan.n_robots}, d = {plan.dim}; plan the pair with 3-D start and goal positions"
            )
        self.plan = plan
        self.yaws = np.asarray(yaws, dtype=float)
        grid = np.linspace(plan.times[0], plan.times[-1], 8 * plan.times.size)
        self._grid = grid
        self._beta, self._gamma = self._continuous(grid)

    def _continuous(self, t):
        """Sequentially continuous ``(beta_c, gamma_c)`` on the sorted times ``t``."""
        p, _, _ = self.plan.sample(t)
        u = self._unit(p)
        b0, g0 = _angles(u)
        beta, gamma = b0.copy(), g0.copy()
        for k in range(1, t.size):
            cands = ((b0[k], g0[k]), (b0[k] + np.pi, np.pi - g0[k]))
            best = None
            for b, g in cands:
                g = _near(g, gamma[k - 1])
                b = beta[k - 1] if abs(np.cos(g)) < VERTICAL_COS else _near(b, beta[k - 1])
                cost = abs(b - beta[k - 1]) + abs(g - gamma[k - 1])
                if best is None or cost < best[0]:
                    best = (cost, b, g)
            beta[k], gamma[k] = best[1], best[2]
            if abs(beta[k] - beta[k - 1]) > 0.5 * np.pi:
                raise InvalidInputError(
                    f"the plan turns the pair about the vertical while passing through it (beta_c jumps "
                    f"at t = {t[k]:.3f} s): its Euclidean cluster variables are discontinuous there"
                )
        return beta, gamma

    @staticmethod
    def _unit(p):
        delta = p[..., 0, :] - p[..., 1, :]
        D = np.linalg.norm(delta, axis=-1)
        if np.any(D <= 1e-9):
            raise DegenerateInputError(
                f"the plan's robots meet (separation {float(D.min()):.3g} m); a pair formation is "
                "undefined there - plan with a larger alpha"
            )
        return delta / D[..., None]

    def __call__(self, t):
        """``e(t)`` and ``e_dot(t)``, each shape ``t.shape + (8,)``."""
        t = np.asarray(t, dtype=float)
        p, v, _ = self.plan.sample(t)
        delta, ddelta = p[..., 0, :] - p[..., 1, :], v[..., 0, :] - v[..., 1, :]
        u = self._unit(p)
        D = np.linalg.norm(delta, axis=-1)
        b0, g0 = _angles(u)
        bref = np.interp(t, self._grid, self._beta)
        gref = np.interp(t, self._grid, self._gamma)
        # the branch of (beta, gamma) nearest the continuous one: (b, g) or (b + pi, pi - g)
        g1, g2 = _near(g0, gref), _near(np.pi - g0, gref)
        other = np.abs(g2 - gref) < np.abs(g1 - gref)
        gamma = np.where(other, g2, g1)
        beta = _near(np.where(other, b0 + np.pi, b0), bref)
        vertical = np.abs(np.cos(gamma)) < VERTICAL_COS
        beta = np.where(vertical, bref, beta)
        u_b, u_g = _partials(beta, gamma)
        u_dot = (ddelta - u * np.einsum("...i,...i->...", u, ddelta)[..., None]) / D[..., None]
        cg2 = np.cos(gamma) ** 2
        beta_dot = np.where(vertical, 0.0, np.einsum("...i,...i->...", u_dot, u_b) / np.where(vertical, 1.0, cg2))
        e = np.empty(t.shape + (8,))
        ed = np.empty(t.shape + (8,))
        e[..., 0:3] = 0.5 * (p[..., 0, :] + p[..., 1, :])  # seed 000 eqs. (1)-(3): the midpoint
        ed[..., 0:3] = 0.5 * (v[..., 0, :] + v[..., 1, :])
        e[..., 3], ed[..., 3] = beta, beta_dot
        e[..., 4], ed[..., 4] = gamma, np.einsum("...i,...i->...", u_dot, u_g)
        e[..., 5] = 0.5 * D  # eq. (6): half the distance
        ed[..., 5] = 0.5 * np.einsum("...i,...i->...", u, ddelta)
        e[..., 6], ed[..., 6] = self.yaws[0] - beta, -beta_dot  # eqs. (7)-(8), constant yaws
        e[..., 7], ed[..., 7] = self.yaws[1] - beta, -beta_dot
        return e, ed
