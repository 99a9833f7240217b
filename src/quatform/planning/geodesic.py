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
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp

from ..algebra._validate import as_array
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
        ``"continuation"`` (from the straight lines at alpha = 0.5) or ``"energy
        minimisation"`` (where the continuation stalled: a minimiser of the discretised
        path energy, which may break the formation's symmetry).
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
    """Geodesic of the shaped metric from ``q0`` (s = 0) to ``q1`` (s = 1).

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

    s = np.linspace(0.0, 1.0, 21)
    y = np.concatenate([qa[:, None] + np.outer(qb - qa, s), np.repeat((qb - qa)[:, None], s.size, 1)])
    if target != 0.5:
        y = y + _side_step(a0, b0, m, s, scale)

    def bc(ya, yb):
        return np.concatenate([ya[:n] - qa, yb[:n] - qb])

    def bc_jac(ya, yb):
        sel = np.hstack([np.eye(n), np.zeros((n, n))])
        zero = np.zeros_like(sel)
        return np.vstack([sel, zero]), np.vstack([zero, sel])

    cur, step, done, sol, guess = 0.5, 0.1 * np.sign(target - 0.5), [], None, "continuation"
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
                break
            step *= 1.5
        else:
            step /= 2.0
            if abs(step) < min_step:
                where = (f"the continuation from alpha = 0.5 stalled at alpha = {cur:.4g}"
                         if done else "no geodesic was found")
                # the continuation keeps the start's symmetry; the geodesic may break it: start
                # again from a minimiser of the discretised path energy (three or more robots)
                sol = _solve_from_energy_guess(a0, b0, m, target, bc, bc_jac, tol, max_nodes) if N >= 3 else None
                if sol is None:
                    raise ConvergenceError(
                        f"no geodesic of the shaped metric for alpha = {target:g}: {where} "
                        f"(last attempt: {why}). For small alpha the "
                        "energy-minimising motion may pass through robots meeting, where the metric is "
                        "singular (docs/planning.md); try an alpha closer to 0.5"
                    )
                done, guess = [target], "energy minimisation"
                break
    f = _fun(m, target, n)
    ivp = solve_ivp(f, (0.0, 1.0), sol.y[:, 0], method="DOP853", rtol=1e-11, atol=1e-12 * max(scale, 1.0),
                    vectorized=True)
    miss = float(np.max(np.abs(ivp.y[:n, -1] - qb))) if ivp.success else float("inf")
    grid = np.linspace(0.0, 1.0, 401)
    yy = sol.sol(grid)
    E = metric_energy(yy[:n].T, yy[n:].T, m, target)
    drift = float(np.max(np.abs(E - E[0])) / max(E[0], 1e-300))
    if not (miss <= ENDPOINT_TOLERANCE * max(scale, 1e-9)) or not (drift <= ENERGY_TOLERANCE):
        raise ConvergenceError(
            f"the boundary-value solution for alpha = {target:g} is not an accurate geodesic: integrating "
            f"its initial velocity misses the goal by {miss:.3g} m and the energy drifts by {drift:.2g} "
            "(relative); the geodesic flow is too sensitive here - try an alpha closer to 0.5"
        )
    return GeodesicSolution(target, m, d, sol.x, sol.y[:n].T, sol.y[n:].T, miss, drift, tuple(done),
                            time.perf_counter() - t_start, sol.sol, guess)


#: Most unknowns of the discretised path-energy minimisation (it uses numerical gradients).
ENERGY_GUESS_MAX_UNKNOWNS = 400


def _solve_from_energy_guess(a0, b0, m, alpha, bc, bc_jac, tol, max_nodes, segments: int = 32):
    """A geodesic from a minimiser of the discretised path energy, or None.

    The centre of mass moves on its straight line (flat, decoupled); the robots' offsets
    from it are free at ``segments - 1`` interior times and minimise ``sum E_k / K`` with
    ``E_k`` the metric energy of segment ``k`` (L-BFGS, numerical gradient). The start is
    the similar-shape path (shrinking mid-way, turning uniformly in the plane) with a fixed
    seeded perturbation that breaks its symmetry. ``solve_bvp`` then refines it, first at a
    loose tolerance, then at ``tol``.
    """
    from scipy.optimize import minimize

    N, d = a0.shape
    K = segments
    if (K - 1) * N * d > ENERGY_GUESS_MAX_UNKNOWNS:
        return None
    w = m / m.sum()
    c0, c1 = w @ a0, w @ b0
    r0, r1 = a0 - c0, b0 - c1
    s = np.linspace(0.0, 1.0, K + 1)
    ss = s[1:-1, None, None]
    rho = float(np.sqrt(np.sum(m * np.sum(r0 * r0, axis=1))) / np.sqrt(m.sum()))
    if d == 2:
        z0, z1 = r0[:, 0] + 1j * r0[:, 1], r1[:, 0] + 1j * r1[:, 1]
        turn = float(np.angle(np.sum(m * z1 * np.conj(z0))))
        z = z0 * np.exp(1j * turn * ss[..., 0]) * (1.0 - 0.8 * np.sin(np.pi * ss[..., 0]))
        X = np.stack([z.real, z.imag], axis=-1)
    else:
        X = (r0 + ss * (r1 - r0)) * (1.0 - 0.8 * np.sin(np.pi * ss))
    X = X + 0.3 * rho * np.random.default_rng(0).normal(size=X.shape) * np.sin(np.pi * ss)

    def offsets(x):
        Y = np.concatenate([r0[None], x.reshape(K - 1, N, d), r1[None]])
        return Y - np.einsum("i,kij->kj", w, Y)[:, None, :]

    def energy(x):
        Y = offsets(x)
        mid, vel = 0.5 * (Y[1:] + Y[:-1]), (Y[1:] - Y[:-1]) * K
        return float(np.sum(metric_energy(mid.reshape(K, -1), vel.reshape(K, -1), m, alpha)) / K)

    try:
        res = minimize(energy, X.ravel(), method="L-BFGS-B", options={"maxiter": 3000, "maxfun": 10**7})
    except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError, ValueError):
        return None
    q = (offsets(res.x) + c0 + s[:, None, None] * (c1 - c0)).reshape(K + 1, -1).T
    y = np.vstack([q, np.gradient(q, s, axis=1)])
    n = N * d
    sol = None
    for t in (max(tol, 1e-4), tol):
        try:
            r = solve_bvp(_fun(m, alpha, n), bc, s if sol is None else sol.x, y if sol is None else sol.y,
                          tol=t, max_nodes=max(max_nodes, 30000), fun_jac=_fun_jac(m, alpha, n), bc_jac=bc_jac)
        except (DegenerateInputError, FloatingPointError, np.linalg.LinAlgError):
            return None
        if r.status != 0 or not np.all(np.isfinite(r.y)):
            return None
        sol = r
    return sol


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
    from .plan import Plan

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
    vel = np.stack([(c1 - c0) + w[1] * rel_dot, (c1 - c0) - w[0] * rel_dot], axis=1) / T
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
    from .plan import Plan

    T = float(duration_s)
    if not (np.isfinite(T) and T > 0):
        raise InvalidInputError(f"duration_s must be a positive number of seconds, got {duration_s!r}")
    if int(knots) < 2:
        raise InvalidInputError(f"knots must be at least 2, got {knots!r}")
    s = np.linspace(0.0, 1.0, int(knots))
    q, qd = sol.state(s)
    qdd = sol.acceleration(q, qd)
    N, d = sol.masses.size, sol.dim
    shape = (s.size, N, d)
    return Plan(s * T, q.reshape(shape), (qd / T).reshape(shape), (qdd / (T * T)).reshape(shape), sol.masses,
                dict(info or {}))
