"""Geodesics of the shaped metric between two formations: seed 002 eqs. (14)-(15).

Planning layer. :func:`solve_geodesic` solves the two-point boundary-value problem
``q̈ = -Gamma(q)[q̇, q̇]``, ``q(0) = q^0``, ``q(1) = q^1`` with
:func:`scipy.integrate.solve_bvp` and a continuation in ``alpha``: at ``alpha = 0.5`` the
geodesic is the uniform straight line (exact start), and each next ``alpha`` starts from the
previous solution; a failed step is halved. The result is then *checked*: the initial
state is integrated forward as an initial-value problem (DOP853) and must land on ``q^1``,
and the energy ``q̇^T M_alpha q̇`` must stay constant. Anything else raises
:class:`~quatform.errors.ConvergenceError`; a wrong path is never returned.

Geodesics may not exist: the shaped metric of two bodies is a cone in the relative
coordinates (``docs/derivations.md``, seed 002 item 3), and when ``alpha`` is small enough
the only energy-minimising curve passes through the robots meeting, where the metric is
singular. For two robots that bound is checked before solving (:func:`meeting_bound`), and
:func:`plan_through_meeting` gives the minimising motion through the meeting instead. For
three or more robots no such bound holds (their shapes can deform, and a geodesic may
exist that breaks the formation's symmetry); where the continuation stalls, the error says
how far it got.

Between the same ends there may be several geodesics: two robots take the closed-form one
(:func:`_cone_geodesic`); for three or more the second variation of the discretised path
energy is checked (:func:`_second_variation`, Morse index theorem) and where it is negative
the solver restarts and returns the geodesic of lower energy (Fig. 4's symmetric
geodesic is a saddle below alpha ~ 0.425).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp

from ..algebra.validate import as_array
from ..errors import (
    ConvergenceError,
    DegenerateInputError,
    InvalidInputError,
    ShapeError,
)
from .shaping import (
    check_alpha,
    check_masses,
    geodesic_acceleration,
    geodesic_jacobian,
    metric_energy,
)

__all__ = ["GeodesicSolution", "meeting_bound", "plan_from_geodesic", "plan_through_meeting", "solve_geodesic"]

#: Largest accepted miss of the forward-integrated end point, as a fraction of the travel.
ENDPOINT_TOLERANCE = 1e-5
#: Largest accepted relative drift of ``q̇^T M_alpha q̇`` along the returned geodesic.
ENERGY_TOLERANCE = 1e-4


@dataclass(frozen=True)
class GeodesicSolution:
    """A verified geodesic of ``M_alpha`` on ``s in [0, 1]``.

    Attributes
    ----------
    alpha : float
    masses : ndarray, shape (N,)
    dim : int
        2 (plane) or 3 (space).
    s : ndarray, shape (K,)
        Collocation mesh of ``solve_bvp`` on ``[0, 1]``.
    q, q_dot : ndarray, shape (K, N*d)
        Configuration and its derivative with respect to ``s`` on the mesh.
    endpoint_error_m : float
        Distance between ``q^1`` and the forward integration of the initial state.
    energy_drift : float
        ``max |E - E(0)| / E(0)`` of ``E = q̇^T M_alpha q̇`` on a fine grid.
    continuation : tuple of float
        The ``alpha`` values solved on the way, in order.
    solve_time_s : float
        Wall time of the continuation, the check included.
    guess : str
        ``"continuation"`` (from the straight lines at alpha = 0.5), ``"closed form
        (cone)"`` (two robots: the exact geodesic, refined), ``"energy minimisation"``
        (where the continuation stalled: a minimiser of the discretised path energy, which
        may break the formation's symmetry) or ``"second-variation restart"`` (the
        continuation's geodesic was not a minimiser: see ``alternatives``).
    energy : float
        ``int_0^1 q'^T M_alpha q' ds`` (seed 002 eq. (12), ``M = diag(m_i I_d)``), in
        mass x length^2 units; constant integrand along a geodesic.
    alternatives : tuple of (str, float)
        Geodesics found and rejected for a higher energy, as ``(guess, energy)``.
    second_variation : float or None
        Smallest eigenvalue of the discretised second variation at the returned geodesic
        over the flat metric's (``_PathEnergy.floor``): positive for a local energy
        minimiser. None where it was not checked (two robots, ``alpha = 0.5``, more than
        ``ENERGY_GUESS_MAX_UNKNOWNS`` unknowns, or a geodesic reached by a restart).
    """

    alpha: float
    masses: np.ndarray
    dim: int
    s: np.ndarray
    q: np.ndarray
    q_dot: np.ndarray
    endpoint_error_m: float
    energy_drift: float
    continuation: tuple
    solve_time_s: float
    _spline: object = None
    guess: str = "continuation"
    energy: float = float("nan")
    alternatives: tuple = ()
    second_variation: float | None = None

    def state(self, s):
        """``(q, q')`` at parameters ``s`` (shape ``(K,)``), each shape ``(K, N*d)``: the
        collocation polynomial of ``solve_bvp``."""
        y = self._spline(np.asarray(s, dtype=float))
        n = self.q.shape[-1]
        return y[:n].T, y[n:].T

    def acceleration(self, q, q_dot):
        """``q''`` from the geodesic equation (seed 002 eq. (15))."""
        return geodesic_acceleration(q, q_dot, self.masses, self.alpha)


def _check_ends(q0, q1, masses):
    m = check_masses(masses)
    a = as_array(q0, "start positions", None)
    b = as_array(q1, "goal positions", None)
    if a.ndim != 2 or a.shape[0] != m.size or a.shape[1] not in (2, 3) or b.shape != a.shape:
        raise ShapeError(
            f"start and goal positions must both have shape (N, d) with N = {m.size} (len(masses)) and "
            f"d = 2 or 3; got {a.shape} and {b.shape}"
        )
    for name, p in (("start", a), ("goal", b)):
        X = p - p.mean(axis=0)
        if np.max(np.linalg.norm(X, axis=1)) <= 1e-12 * max(1.0, np.abs(p).max()):
            raise DegenerateInputError(f"all robots coincide in the {name} configuration; separate them")
        sv = np.linalg.svd(X, compute_uv=False)
        if p.shape[1] == 3 and p.shape[0] >= 3 and sv[1] <= 1e-6 * sv[0]:
            raise DegenerateInputError(
                f"the {name} robots are collinear: for three or more robots in space the shaped metric "
                "jumps there (the spin about their line moves no mass, docs/planning.md); move one robot "
                "off the line or plan in the plane (d = 2)"
            )
    return a, b, m


def _two_body_bound(a, b, masses, alpha):
    """Seed 002 item 3 of docs/derivations.md: two bodies have a geodesic only if the relative
    direction turns by less than ``pi / k``, ``k = sqrt((1 - alpha) / alpha)`` (a cone)."""
    _, turn = meeting_bound(a, b, masses)
    k = np.sqrt((1.0 - alpha) / alpha)
    if alpha != 0.5 and k * turn >= np.pi * (1.0 - 1e-9):
        raise ConvergenceError(
            f"no geodesic of the shaped metric for alpha = {alpha:g}: the two robots' relative direction "
            f"turns by {turn:.4g} rad, and a geodesic exists only for alpha > {1.0 / (1.0 + (np.pi / turn) ** 2):.4g} "
            "(the shaped metric is a cone in the relative position, docs/planning.md); below, the "
            "energy-minimising motion passes through the robots meeting - raise alpha"
        )


def _side_step(a, b, m, s, scale):
    """Initial-guess correction where the straight lines make two robots meet.

    Off ``alpha = 0.5`` the metric is singular where robots meet, and the straight line
    through such a point is symmetric (a swap can turn either way): the guess is bent
    sideways by 0.2 of the formation's size for the closest pair, centre of mass kept.
    Returns the change of ``(q, q')``, shape ``(2 N d, K)``; zero when no pair comes
    within 5 % of the size.
    """
    N, d = a.shape
    fine = np.linspace(0.0, 1.0, 201)[:, None, None]
    lines = (1.0 - fine) * a + fine * b
    D = np.where(np.eye(N, dtype=bool), np.inf, np.linalg.norm(lines[:, :, None] - lines[:, None], axis=-1))
    k, i, j = np.unravel_index(int(np.argmin(D)), D.shape)
    out = np.zeros((2 * N * d, s.size))
    if D[k, i, j] >= 0.05 * scale:
        return out
    w = (b[i] - a[i]) - (b[j] - a[j])
    if d == 2:
        nrm = np.array([-w[1], w[0]])
    else:
        nrm = np.cross(w, np.eye(3)[int(np.argmin(np.abs(w)))])
    nrm = nrm / max(np.linalg.norm(nrm), 1e-300)
    bump, rate = 0.2 * scale * np.sin(np.pi * s), 0.2 * scale * np.pi * np.cos(np.pi * s)
    for r, share in ((i, m[j] / (m[i] + m[j])), (j, -m[i] / (m[i] + m[j]))):
        out[r * d:(r + 1) * d] += share * np.outer(nrm, bump)
        out[N * d + r * d:N * d + (r + 1) * d] += share * np.outer(nrm, rate)
    return out


def _fun(masses, alpha, n):
    def f(s, y):
        q, qd = y[:n].T, y[n:].T
        return np.concatenate([y[n:], geodesic_acceleration(q, qd, masses, alpha).T], axis=0)
    return f


def _fun_jac(masses, alpha, n):
    """``d f / d y`` of the first-order system ``y = (q, q̇)``, shape ``(2n, 2n, m)``."""
    def jac(s, y):
        Jq, Jv = geodesic_jacobian(y[:n].T, y[n:].T, masses, alpha)
        out = np.zeros((2 * n, 2 * n, y.shape[1]))
        out[:n, n:] = np.eye(n)[:, :, None]
        out[n:, :n] = np.moveaxis(Jq, 0, -1)
        out[n:, n:] = np.moveaxis(Jv, 0, -1)
        return out
    return jac


def solve_geodesic(q0, q1, masses, alpha, *, tol: float = 1e-6, max_nodes: int = 2000,
                   min_step: float = 1e-2) -> GeodesicSolution:
    """Geodesic of the shaped metric from ``q0`` (s = 0) to ``q1`` (s = 1), the energy minimiser
    among those found.

    Parameters
    ----------
    q0, q1 : array_like, shape (N, d)
        Start and goal positions of the N robots, m (``d = 2`` or 3).
    masses : array_like, shape (N,)
        Only their ratios matter (seed 002 §5).
    alpha : float
        Shaping weight in ``(0, 1)``: 0.5 straight lines, towards 1 rigid, towards 0 clustering.
    tol : float
        ``solve_bvp`` residual tolerance.
    max_nodes : int
        ``solve_bvp`` mesh limit.
    min_step : float
        Smallest continuation step in ``alpha`` before giving up.

    Notes
    -----
    Two robots start from the closed-form cone geodesic (:func:`_cone_guess`), refined by
    ``solve_bvp``. Three or more start from the continuation in ``alpha``; the geodesic it
    returns keeps the start's symmetry and need not minimise the energy: the second
    variation of the discretised path energy at it is checked (:func:`_second_variation`),
    and where it is not positive the solver restarts along its most negative direction and
    returns the geodesic of lower energy (the other is kept in ``alternatives``).

    Raises
    ------
    ConvergenceError
        No geodesic found, or the one found fails the forward-integration or energy check.
    """
    a0, b0, m = _check_ends(q0, q1, masses)
    target = check_alpha(alpha)
    if m.size == 2:
        _two_body_bound(a0, b0, m, target)
    N, d = a0.shape
    n = N * d
    qa, qb = a0.reshape(-1), b0.reshape(-1)
    travel = float(np.max(np.linalg.norm(b0 - a0, axis=1)))
    scale = max(travel, float(np.max(np.linalg.norm(a0 - a0.mean(axis=0), axis=1))))
    t_start = time.perf_counter()

    def bc(ya, yb):
        return np.concatenate([ya[:n] - qa, yb[:n] - qb])

    def bc_jac(ya, yb):
        sel = np.hstack([np.eye(n), np.zeros((n, n))])
        zero = np.zeros_like(sel)
        return np.vstack([sel, zero]), np.vstack([zero, sel])

    sol, done, guess = None, [], "continuation"
    if N == 2 and target != 0.5:
        cone = _cone_geodesic(a0, b0, m, target)
        if cone is not None:  # exact; checked below like any other
            mesh = np.linspace(0.0, 1.0, 401)
            sol = SimpleNamespace(x=mesh, y=cone(mesh), sol=cone)
            done, guess = [target], "closed form (cone)"
    def branch(res, a):
        """At an intermediate alpha: the lower-energy geodesic where ``res`` is not a minimiser."""
        checked = _verify(res, m, a, qb, scale)
        if checked is None:
            return None
        out = _lowest_energy(res, "continuation", *checked, m, a, qa, qb, bc, bc_jac, tol, scale)
        return out[0] if out[5] else None

    def leap(res):
        """From a geodesic at another alpha: a minimiser of the discretised path energy at
        ``target`` started from it, refined (or None)."""
        return _minimise_and_refine(m, target, qa, qb, scale, lambda s: res.sol(s)[:n, 1:-1].T, bc, bc_jac, tol)

    if sol is None:
        sol, done, guess = _continuation(a0, b0, m, target, bc, bc_jac, tol, max_nodes, min_step, scale,
                                         branch if N >= 3 else None, leap)
    checked = _verify(sol, m, target, qb, scale)
    if checked is None:
        miss, drift = _miss_and_drift(sol, m, target, qb, scale)
        raise ConvergenceError(
            f"the boundary-value solution for alpha = {target:g} is not an accurate geodesic: integrating "
            f"its initial velocity misses the goal by {miss:.3g} m and the energy drifts by {drift:.2g} "
            "(relative); the geodesic flow is too sensitive here - try an alpha closer to 0.5"
        )
    miss, drift, energy = checked
    alternatives, lowest = (), None
    if N >= 3 and target != 0.5:
        sol, guess, miss, drift, energy, alternatives, lowest = _lowest_energy(
            sol, guess, miss, drift, energy, m, target, qa, qb, bc, bc_jac, tol, scale)
    return GeodesicSolution(target, m, d, sol.x, sol.y[:n].T, sol.y[n:].T, miss, drift, tuple(done),
                            time.perf_counter() - t_start, sol.sol, guess, energy, alternatives, lowest)


def _continuation(a0, b0, m, target, bc, bc_jac, tol, max_nodes, min_step, scale, branch=None, leap=None):
    """Continuation in alpha from the straight lines at 0.5: ``(solve_bvp result, alphas, guess)``.

    Each next alpha starts from the last solution; steps grow by 1.5 after a success and
    halve after a failure. ``branch(res, alpha)``, when given, is asked at each intermediate
    alpha for a lower-energy geodesic (the continuation keeps the start's symmetry, the
    minimiser may break it); from the first it returns, ``leap(res)`` tries to reach the
    target alpha at once (a path-energy minimiser started from that branch), else the
    continuation follows that branch. Where a step falls below ``min_step`` three or more robots start again from a
    minimiser of the discretised path energy; otherwise ConvergenceError.
    """
    N, d = a0.shape
    n = N * d
    qa, qb = a0.reshape(-1), b0.reshape(-1)
    s = np.linspace(0.0, 1.0, 21)
    y = np.concatenate([qa[:, None] + np.outer(qb - qa, s), np.repeat((qb - qa)[:, None], s.size, 1)])
    if target != 0.5:
        y = y + _side_step(a0, b0, m, s, scale)
    cur, step, done, sol, label = 0.5, 0.1 * np.sign(target - 0.5), [], None, "continuation"
    while True:
        nxt = target if abs(target - cur) <= abs(step) else cur + step
        try:
            res = solve_bvp(_fun(m, nxt, n), bc, s, y, tol=tol, max_nodes=max_nodes,
                            fun_jac=_fun_jac(m, nxt, n), bc_jac=bc_jac)
            ok = res.status == 0 and np.all(np.isfinite(res.y))
            why = res.message
        except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError) as exc:
            ok, why = False, f"{type(exc).__name__}: {exc}"
        if ok:
            cur, sol = nxt, res
            done.append(float(cur))
            s, y = res.x, res.y
            if cur == target:
                return sol, done, label
            if branch is not None and label == "continuation":
                other = branch(res, cur)
                if other is not None:
                    sol, s, y = other, other.x, other.y
                    label = f"second-variation restart at alpha = {cur:.4g}"
                    jump = None if leap is None else leap(other)
                    if jump is not None:
                        return jump, done + [float(target)], label
            step *= 1.5
            continue
        step /= 2.0
        if abs(step) >= min_step:
            continue
        where = (f"the continuation from alpha = 0.5 stalled at alpha = {cur:.4g}" if done
                 else "no geodesic was found")
        # the continuation keeps the start's symmetry; the geodesic may break it: start
        # again from a minimiser of the discretised path energy (three or more robots)
        sol = _solve_from_energy_guess(a0, b0, m, target, bc, bc_jac, tol, scale) if N >= 3 else None
        if sol is None:
            raise ConvergenceError(
                f"no geodesic of the shaped metric for alpha = {target:g}: {where} "
                f"(last attempt: {why}). For small alpha the "
                "energy-minimising motion may pass through robots meeting, where the metric is "
                "singular (docs/planning.md); try an alpha closer to 0.5"
            )
        return sol, [target], "energy minimisation"


def _miss_and_drift(sol, m, alpha, qb, scale):
    """Forward-integration miss of the goal (m) and relative drift of ``q̇^T M_alpha q̇``."""
    n = qb.size
    f = _fun(m, alpha, n)
    try:
        ivp = solve_ivp(f, (0.0, 1.0), sol.y[:, 0], method="DOP853", rtol=1e-11,
                        atol=1e-12 * max(scale, 1.0), vectorized=True)
        miss = float(np.max(np.abs(ivp.y[:n, -1] - qb))) if ivp.success else float("inf")
    except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError):
        miss = float("inf")
    yy = sol.sol(np.linspace(0.0, 1.0, 401))
    E = metric_energy(yy[:n].T, yy[n:].T, m, alpha)
    return miss, float(np.max(np.abs(E - E[0])) / max(E[0], 1e-300))


def _verify(sol, m, alpha, qb, scale):
    """``(miss, drift, energy)`` of a solve_bvp result that passes the geodesic checks, else None.

    ``energy`` is ``int_0^1 q̇^T M_alpha q̇ ds`` (seed 002 eq. (12); constant along a geodesic,
    so its mean on the check grid)."""
    miss, drift = _miss_and_drift(sol, m, alpha, qb, scale)
    if not (miss <= ENDPOINT_TOLERANCE * max(scale, 1e-9)) or not (drift <= ENERGY_TOLERANCE):
        return None
    n = qb.size
    yy = sol.sol(np.linspace(0.0, 1.0, 401))
    return miss, drift, float(np.mean(metric_energy(yy[:n].T, yy[n:].T, m, alpha)))


def _refine(m, alpha, bc, bc_jac, s, y, tols, max_nodes):
    """``solve_bvp`` from the guess ``(s, y)`` at each tolerance of ``tols`` in turn, or None."""
    n = y.shape[0] // 2
    sol = None
    for t in tols:
        try:
            r = solve_bvp(_fun(m, alpha, n), bc, s if sol is None else sol.x, y if sol is None else sol.y,
                          tol=t, max_nodes=max_nodes, fun_jac=_fun_jac(m, alpha, n), bc_jac=bc_jac)
        except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError):
            return None
        if r.status != 0 or not np.all(np.isfinite(r.y)):
            return None
        sol = r
    return sol


def _cone_geodesic(a0, b0, m, alpha):
    """Two robots: the closed-form geodesic, as ``y(s) -> (q, q')`` stacked, shape ``(2 n, K)``.

    docs/derivations.md, seed 002 item 3: the centre of mass moves uniformly on its line and
    the relative vector ``d = x1 - x2`` on the cone ``alpha dr^2 + (1 - alpha) r^2 dtheta^2``,
    which unrolls with ``phi = k theta``, ``k = sqrt((1 - alpha) / alpha)``, to a plane where
    the geodesic is the uniform straight line ``z(s) = (1 - s) r0 + s r1 exp(i k turn)``. It
    lies in the plane of ``d0`` and ``d1``; None where that plane is not defined (``d0``
    parallel to ``d1``: no turn, or a half turn, where the side is a choice) or beyond the
    bound ``k turn < pi``.
    """
    d0, d1 = a0[0] - a0[1], b0[0] - b0[1]
    r0, r1 = float(np.linalg.norm(d0)), float(np.linalg.norm(d1))
    e1 = d0 / r0
    perp = d1 - e1 * (e1 @ d1)
    if np.linalg.norm(perp) <= 1e-9 * r1:
        return None
    e2 = perp / np.linalg.norm(perp)
    turn = float(np.arctan2(d1 @ e2, d1 @ e1))  # in (0, pi)
    k = np.sqrt((1.0 - alpha) / alpha)
    if not k * turn < np.pi:
        return None
    w = m / m.sum()
    c0, c1 = w @ a0, w @ b0
    end = r1 * np.exp(1j * k * turn)

    def y(s):
        s = np.asarray(s, dtype=float)
        z = (1.0 - s) * r0 + s * end
        dz = end - r0
        r, th = np.abs(z), np.angle(z) / k  # arg z in [0, k turn] within (-pi, pi): no wrap
        r_dot = (dz * np.conj(z)).real / r
        th_dot = (dz * np.conj(z)).imag / (r * r * k)
        u = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
        u_perp = -np.sin(th)[:, None] * e1 + np.cos(th)[:, None] * e2
        rel, rel_dot = r[:, None] * u, r_dot[:, None] * u + (r * th_dot)[:, None] * u_perp
        com = c0 + s[:, None] * (c1 - c0)
        q = np.concatenate([com + w[1] * rel, com - w[0] * rel], axis=1)
        q_dot = np.concatenate([(c1 - c0) + w[1] * rel_dot, (c1 - c0) - w[0] * rel_dot], axis=1)
        return np.vstack([q.T, q_dot.T])

    return y


#: Most unknowns of the discretised path energy (its Hessian is checked densely).
ENERGY_GUESS_MAX_UNKNOWNS = 400
#: Segments of the discretised path energy.
ENERGY_SEGMENTS = 32


class _PathEnergy:
    """The discretised path energy ``sum_k e(mid_k, K (Y_{k+1} - Y_k)) / K``, ``K`` segments.

    ``e = q̇^T M_alpha q̇`` (seed 002 eq. (12)) at the segment's midpoint; ``Y_0 = q^0`` and
    ``Y_K = q^1`` are fixed, the ``K - 1`` interior configurations ``x`` are free. Each
    segment depends on its two ends only, so the gradient (central differences) and the
    Hessian (second differences, block tridiagonal) come from one batched metric evaluation
    per segment and variable (pair) instead of one path evaluation per unknown.
    """

    def __init__(self, qa, qb, m, alpha, K, scale):
        self.qa, self.qb, self.m, self.alpha, self.K = qa, qb, m, alpha, K
        self.n = qa.size
        self.h1, self.h2 = 1e-6 * scale, 1e-4 * scale

    def full(self, x):
        return np.concatenate([self.qa[None], np.reshape(x, (self.K - 1, self.n)), self.qb[None]])

    def _segments(self, Z):
        n = self.n
        Y0, Y1 = Z[..., :n], Z[..., n:]
        return metric_energy(0.5 * (Y0 + Y1), (Y1 - Y0) * self.K, self.m, self.alpha) / self.K

    def _pairs(self, x):
        Y = self.full(x)
        return np.concatenate([Y[:-1], Y[1:]], axis=1)  # (K, 2n): each segment's two ends

    def value_and_grad(self, x):
        n, Z = self.n, self._pairs(x)
        E = np.eye(2 * n) * self.h1
        f = self._segments(np.stack([Z[:, None] + E, Z[:, None] - E]))
        g = (f[0] - f[1]) / (2.0 * self.h1)  # (K, 2n)
        G = np.zeros((self.K + 1, n))
        G[:-1] += g[:, :n]
        G[1:] += g[:, n:]
        return float(self._segments(Z).sum()), G[1:-1].ravel()

    def hessian(self, x):
        n, K, h, Z = self.n, self.K, self.h2, self._pairs(x)
        E = np.eye(2 * n) * h
        pp, pm = E[:, None] + E[None], E[:, None] - E[None]
        Zc = Z[:, None, None]
        f = self._segments(np.stack([Zc + pp, Zc + pm, Zc - pm, Zc - pp]))
        Hs = (f[0] - f[1] - f[2] + f[3]) / (4.0 * h * h)  # (K, 2n, 2n)
        H = np.zeros(((K + 1) * n, (K + 1) * n))
        for k in range(K):
            H[k * n:(k + 2) * n, k * n:(k + 2) * n] += Hs[k]
        H = H[n:-n, n:-n]
        return 0.5 * (H + H.T)

    def floor(self):
        """Smallest Hessian eigenvalue of the flat metric ``min(alpha, 1 - alpha) min(m)``:
        ``2 K (2 - 2 cos(pi / K)) w``, the scale a second variation is judged against."""
        w = min(self.alpha, 1.0 - self.alpha) * float(np.min(self.m))
        return 2.0 * self.K * (2.0 - 2.0 * np.cos(np.pi / self.K)) * w

    def minimise(self, x0):
        from scipy.optimize import minimize

        res = minimize(self.value_and_grad, x0, jac=True, method="L-BFGS-B", options={"maxiter": 5000})
        return res.x


#: Most unknowns of the second-variation check (its Hessian is dense).
SECOND_VARIATION_MAX_UNKNOWNS = 800


def _second_variation(sol, m, alpha, qa, qb, scale):
    """Smallest eigenvalue of the second variation of the path energy at ``sol`` over its
    floor, with the ``(K - 1) * n`` direction and the ``_PathEnergy`` and knots ``(K + 1, n)``
    of the coarse discretisation; None when there are too many unknowns to check.

    A geodesic whose second variation has a negative direction (a conjugate point before
    ``s = 1``, Morse index theorem) is not an energy minimiser: nearby curves cost less.
    The discretised Hessian at the geodesic's samples is off by ``O(1/K^2)``, and minimisers
    that break Fig. 4's symmetry have an (almost) flat direction whose discretised
    eigenvalue comes out ``-0.28`` (K = 32), ``-0.07`` (64), ``-0.03`` (96) of the floor at
    alpha = 0.3: the eigenvalue is extrapolated from K = 32 and 64 (Richardson,
    ``(4 l_64 - l_32) / 3``; ``-0.001`` there, ``-2.13`` at the symmetric geodesic of alpha = 0.4).
    """
    n = qa.size
    out = []
    for K in (ENERGY_SEGMENTS, 2 * ENERGY_SEGMENTS):
        if (K - 1) * n > SECOND_VARIATION_MAX_UNKNOWNS:
            return None
        P = _PathEnergy(qa, qb, m, alpha, K, scale)
        q = sol.sol(np.linspace(0.0, 1.0, K + 1))[:n].T
        try:
            w, V = np.linalg.eigh(P.hessian(q[1:-1].ravel()))
        except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError):
            return None
        out.append((float(w[0] / P.floor()), V[:, 0], P, q))
    (l1, v, P, q), (l2, *_) = out
    return (4.0 * l2 - l1) / 3.0, v, P, q


#: A second variation below ``-SECOND_VARIATION_TOLERANCE`` times its floor counts as negative.
SECOND_VARIATION_TOLERANCE = 0.05


def _lowest_energy(sol, guess, miss, drift, energy, m, alpha, qa, qb, bc, bc_jac, tol, scale,
                   restarts: int = 3):
    """The lower-energy geodesic: restart where the second variation at ``sol`` is negative.

    The restart perturbs the geodesic along the most negative direction (0.1 of ``scale``),
    minimises the discretised path energy from there, refines with ``solve_bvp`` and checks
    it; the geodesic of lower energy is kept, the other is listed in the returned
    ``alternatives`` as ``(guess, energy)``. Returns the chosen geodesic's
    ``(sol, guess, miss, drift, energy, alternatives, lowest)``, ``lowest`` the smallest
    eigenvalue of its second variation over its floor (None where not checked).
    """
    alternatives = []
    lowest = None
    for _ in range(restarts):
        sv = _second_variation(sol, m, alpha, qa, qb, scale)
        if sv is None:
            break
        lowest, v, P, q = sv
        if lowest >= -SECOND_VARIATION_TOLERANCE:
            break
        v = v / np.max(np.abs(v))
        new = None
        V = np.vstack([np.zeros(qa.size), v.reshape(P.K - 1, -1), np.zeros(qa.size)])
        for sign in (1.0, -1.0):
            def start(s, sign=sign):  # the geodesic bent along the negative direction
                bend = np.stack([np.interp(s, np.linspace(0.0, 1.0, P.K + 1), c) for c in V.T], axis=-1)
                return (sol.sol(s)[:qa.size].T + sign * 0.1 * scale * bend)[1:-1]
            cand = _minimise_and_refine(m, alpha, qa, qb, scale, start, bc, bc_jac, tol)
            checked = None if cand is None else _verify(cand, m, alpha, qb, scale)
            if checked is not None and checked[2] < energy * (1.0 - 1e-9):
                new = (cand, checked)
                break
        if new is None:
            break  # no cheaper geodesic found: keep this one (its second variation says so)
        alternatives.append((guess, energy))
        sol, (miss, drift, energy) = new[0], new[1]
        guess = "second-variation restart"
        lowest = None
    return sol, guess, miss, drift, energy, tuple(alternatives), lowest


def _solve_from_energy_guess(a0, b0, m, alpha, bc, bc_jac, tol, scale, segments: int = ENERGY_SEGMENTS):
    """A geodesic from a minimiser of the discretised path energy, or None.

    The start is the similar-shape path (shrinking mid-way, turning uniformly in the plane)
    with a fixed seeded perturbation that breaks its symmetry (:func:`_minimise_and_refine`).
    """
    N, d = a0.shape
    K = segments
    if (K - 1) * N * d > ENERGY_GUESS_MAX_UNKNOWNS:
        return None
    w = m / m.sum()
    c0, c1 = w @ a0, w @ b0
    r0, r1 = a0 - c0, b0 - c1
    grid = np.linspace(0.0, 1.0, K + 1)
    ss = grid[1:-1, None, None]
    rho = float(np.sqrt(np.sum(m * np.sum(r0 * r0, axis=1))) / np.sqrt(m.sum()))
    if d == 2:
        z0, z1 = r0[:, 0] + 1j * r0[:, 1], r1[:, 0] + 1j * r1[:, 1]
        turn = float(np.angle(np.sum(m * z1 * np.conj(z0))))
        z = z0 * np.exp(1j * turn * ss[..., 0]) * (1.0 - 0.8 * np.sin(np.pi * ss[..., 0]))
        X = np.stack([z.real, z.imag], axis=-1)
    else:
        X = (r0 + ss * (r1 - r0)) * (1.0 - 0.8 * np.sin(np.pi * ss))
    X = X + 0.3 * rho * np.random.default_rng(0).normal(size=X.shape) * np.sin(np.pi * ss)
    X = X + c0 + ss * (c1 - c0)

    def start(t):  # the guess above, interpolated to the segments' knots
        flat = np.vstack([a0.reshape(1, -1), X.reshape(K - 1, -1), b0.reshape(1, -1)])
        return np.stack([np.interp(t, grid, c) for c in flat.T], axis=-1)[1:-1]

    return _minimise_and_refine(m, alpha, a0.reshape(-1), b0.reshape(-1), scale, start, bc, bc_jac, tol)


def _minimise_and_refine(m, alpha, qa, qb, scale, start, bc, bc_jac, tol, segments=(ENERGY_SEGMENTS, 48),
                         max_nodes: int = 5000):
    """A geodesic from a minimiser of the discretised path energy, or None.

    For each number of segments ``K`` in turn, :class:`_PathEnergy` is minimised (L-BFGS)
    from ``start(s)`` (the interior configurations at ``s = k / K``, shape ``(K - 1, n)``),
    and ``solve_bvp`` refines it at tolerances 1e-4, 1e-5 and ``tol`` (each from the last);
    the first that converges within ``max_nodes`` nodes is returned. (A 32-segment guess
    sometimes sends the 1e-6 refinement past 20000 nodes where 48 segments need 600.)
    """
    n = qa.size
    tols = tuple(t for t in (1e-4, 1e-5) if t > tol) + (tol,)
    for K in segments:
        if (K - 1) * n > ENERGY_GUESS_MAX_UNKNOWNS:
            continue
        s = np.linspace(0.0, 1.0, K + 1)
        P = _PathEnergy(qa, qb, m, alpha, K, scale)
        try:
            Q = P.full(P.minimise(np.asarray(start(s), dtype=float).ravel())).T
        except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError, ValueError):
            continue
        sol = _refine(m, alpha, bc, bc_jac, s, np.vstack([Q, np.gradient(Q, s, axis=1)]), tols, max_nodes)
        if sol is not None:
            return sol
    return None


def meeting_bound(q0, q1, masses):
    """For two robots: the smallest ``alpha`` with a geodesic between ``q0`` and ``q1``.

    The relative position lives on a cone, ``mu (alpha dr^2 + (1 - alpha) r^2 dOmega^2)``
    (plus the flat centre of mass); geodesics lie in planes through the apex, and a straight
    line on the unrolled cone joins the ends only if ``sqrt((1 - alpha) / alpha)`` times the
    turn of the relative direction is below ``pi`` (docs/derivations.md, seed 002 item 3).
    Returns ``(bound, turn)``; ``None`` for three or more robots, where no such bound holds:
    their shapes can deform, and the minimiser need not pass through a meeting.
    """
    a, b, m = _check_ends(q0, q1, masses)
    if m.size != 2:
        return None
    d0, d1 = a[0] - a[1], b[0] - b[1]
    turn = float(np.arccos(np.clip(d0 @ d1 / (np.linalg.norm(d0) * np.linalg.norm(d1)), -1.0, 1.0)))
    return (0.0 if turn == 0.0 else 1.0 / (1.0 + (np.pi / turn) ** 2)), turn


def plan_through_meeting(q0, q1, masses, alpha, duration_s: float, knots: int = 201, info: dict | None = None):
    """Two robots at or below :func:`meeting_bound`: the energy minimiser, through their meeting.

    In the metric's completion the shortest curve between the ends runs through the cone's
    apex: the centre of mass moves uniformly on its straight line (the rigid part of the
    metric is flat), and the relative position shrinks along its start direction to zero and
    grows along its goal direction at a constant rate (``r0 + r1`` in all). Its metric
    energy is constant on both halves: ``alpha mu (r0 + r1)^2 + (1 - alpha) M |c1 - c0|^2``
    (times ``1/T^2``), stored as ``info["energy"]``. The robots *meet* at
    ``s* = r0 / (r0 + r1)``: the plan says so. There the relative velocity reverses; the
    :class:`Plan` knot at the meeting has zero velocity, so the sampled motion slows to rest
    over the knot interval before it and speeds up over the one after (accelerations of
    about ``3 |v| / h`` there, ``h = T / (knots - 1)``: a physical stop at contact, where the
    ideal path has a velocity jump).
    """
    from .plan import Plan, check_plan_rates

    a, b, m = _check_ends(q0, q1, masses)
    alpha = check_alpha(alpha)
    known = meeting_bound(a, b, m)
    if known is None:
        raise InvalidInputError(f"a path through the robots' meeting is defined for two robots, got {m.size}")
    if alpha > known[0] and alpha != 0.5:
        raise InvalidInputError(f"alpha = {alpha:g} is above the bound {known[0]:.4g}: a geodesic exists, use "
                                "solve_geodesic")
    T = float(duration_s)
    if not (np.isfinite(T) and T > 0) or int(knots) < 2:
        raise InvalidInputError(f"need duration_s > 0 and knots >= 2, got {duration_s!r}, {knots!r}")
    w = m / m.sum()
    c0, c1 = w @ a, w @ b
    d0, d1 = a[0] - a[1], b[0] - b[1]
    r0, r1 = float(np.linalg.norm(d0)), float(np.linalg.norm(d1))
    s_meet = r0 / (r0 + r1)
    s = np.union1d(np.linspace(0.0, 1.0, int(knots)), [s_meet])
    before = s <= s_meet
    rel = np.where(before[:, None], (1.0 - s / s_meet)[:, None] * d0,
                   ((s - s_meet) / (1.0 - s_meet))[:, None] * d1)
    rel_dot = np.where(before[:, None], -d0 / s_meet, d1 / (1.0 - s_meet))
    rel_dot[np.isclose(s, s_meet, rtol=0.0, atol=1e-12)] = 0.0
    com = c0 + s[:, None] * (c1 - c0)
    pos = np.stack([com + w[1] * rel, com - w[0] * rel], axis=1)
    rate = np.stack([(c1 - c0) + w[1] * rel_dot, (c1 - c0) - w[0] * rel_dot], axis=1)
    check_plan_rates(T, rate, 0.0, (info or {}).get("name"))
    vel = rate / T
    info = {**(info or {}), "through_meeting": True, "meeting_time_s": s_meet * T,
            "energy": float((alpha * (m[0] * m[1] / m.sum()) * (r0 + r1) ** 2
                             + (1.0 - alpha) * m.sum() * float((c1 - c0) @ (c1 - c0))) / (T * T))}
    return Plan(s * T, pos, vel, np.zeros_like(pos), m, info)


def plan_from_geodesic(sol: GeodesicSolution, duration_s: float, knots: int = 201, info: dict | None = None):
    """The geodesic as a :class:`~quatform.planning.plan.Plan` over ``[0, duration_s]``.

    A geodesic keeps its shape under ``t = s T`` (constant speed): positions from the
    collocation solution at ``knots`` uniform times, velocities ``q'/T`` and accelerations
    ``q''/T^2`` with ``q''`` from the geodesic equation (seed 002 eq. (15)).
    """
    from .plan import Plan, check_plan_rates

    T = float(duration_s)
    if not (np.isfinite(T) and T > 0):
        raise InvalidInputError(f"duration_s must be a positive number of seconds, got {duration_s!r}")
    if int(knots) < 2:
        raise InvalidInputError(f"knots must be at least 2, got {knots!r}")
    s = np.linspace(0.0, 1.0, int(knots))
    q, qd = sol.state(s)
    qdd = sol.acceleration(q, qd)
    # velocities qd / T and accelerations qdd / T^2 within the plan's bound
    check_plan_rates(T, qd, qdd, (info or {}).get("name"))
    N, d = sol.masses.size, sol.dim
    shape = (s.size, N, d)
    return Plan(s * T, q.reshape(shape), (qd / T).reshape(shape), (qdd / (T * T)).reshape(shape), sol.masses,
                dict(info or {}))
