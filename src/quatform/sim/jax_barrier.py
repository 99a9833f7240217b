"""The separation barrier's quadratic programme solved inside the compiled tick (sim layer, JAX).

:class:`~quatform.control.safety.SeparationBarrier` solves Wang, Ames and Egerstedt 2017's
programme (``min sum_i |v_i - v_nom_i|^2`` subject to ``2 p_ij . (v_i - v_j) + gamma h_ij >= 0``
for every pair, the Robotarium single-integrator certificate ``h_ij = |p_ij|^2 - d_min^2``)
exactly on the host: Lawson and Hanson's least-distance programme (1974, ch. 23) as one
non-negative least-squares problem per connected component of a growing active set. The
programme is strictly convex and feasible, so its solution is unique: any exact solver gives
the same velocities to rounding. Here the solver has a fixed size, for a team of kinematic
4-DOF and planar holonomic robots with one common limit factor (what the jax backend runs):

* the ``K`` pairs of smallest ``g_ij = 2 p_ij . (v_i - v_j) + gamma h_ij`` (those within
  ``range_m`` when it is given) are the candidates (``K = min(pairs, CANDIDATES)``);
* their least-distance programme ``min |w|, G w >= c`` (``c = -g``) is Lawson and Hanson's
  NNLS ``min |E y - f|, y >= 0``, ``E = [G^T; c^T]``, ``f = e_last``, solved on its Gram
  matrix ``E^T E = G G^T + c c^T`` by their active-set algorithm (ch. 23, Algorithm NNLS) in
  a bounded ``lax.while_loop`` with masks; ``w = -r[:-1] / r[-1]``, ``r = E y - f``;
* every pair of the world (within ``range_m`` when it is given) is checked at ``v_nom + w``
  with NumPy's tolerance: the solution of a relaxation that satisfies every constraint is
  the programme's solution;
* the common limit factor ``s = min(1, team.limit_factor(u_new))`` scales the commands, as
  :meth:`~quatform.control.safety.SeparationBarrier.filter` scales a common-limit team's.

A world whose check fails (more binding pairs than ``K``, no convergence within the loop's
bound, an infeasible programme, a limit factor 0) is reported unsolved: the jax loop reruns
it on NumPy (:mod:`.jax_loop`), so exactness is never traded. ``docs/derivations.md``,
"The separation barrier on JAX".
"""

from __future__ import annotations

from ..formations.team_chart import team_positions
from ..robots import HolonomicRobot, PlanarHolonomicRobot

__all__ = ["CANDIDATES", "barrier_filter", "nnls_gram", "pair_constraints", "solves"]

#: Most candidate pairs of one world's programme on JAX (the static size ``K``).
CANDIDATES = 32


def solves(team) -> bool:
    """Whether :func:`barrier_filter` runs the team: kinematic 4-DOF and planar holonomic
    robots whose commands are their point rates, with one common limit factor."""
    return bool(team.common_limit and team.passthrough
                and all(type(r) in (HolonomicRobot, PlanarHolonomicRobot) for r in team.robots))


def nnls_gram(A, b, valid, tol, max_iter, skip):
    """Lawson and Hanson's NNLS (1974, ch. 23, Algorithm NNLS) on its normal equations,
    batched: ``min_y>=0 |E y - f|`` given ``A = E^T E`` and ``b = E^T f``.

    Parameters
    ----------
    A : jax array, shape (B, K, K)
    b : jax array, shape (B, K)
    valid : jax array of bool, shape (B, K)
        Columns that may enter the passive set (the others stay 0).
    tol : float or jax array of shape (B,)
        A column enters while its gradient ``b - A y`` exceeds ``tol``.
    max_iter : int
        Bound of the loop (each step adds or drops one column).
    skip : jax array of bool, shape (B,)
        Worlds not solved (their ``y`` stays 0, not converged).

    Returns
    -------
    y : jax array, shape (B, K)
    converged : jax array of bool, shape (B,)
    """
    import jax
    import jax.numpy as jnp

    B, K = b.shape
    eye = jnp.eye(K, dtype=A.dtype)
    tol = jnp.broadcast_to(jnp.asarray(tol, dtype=A.dtype), (B,))

    def solve(passive):  # z_P = A_PP^-1 b_P, z_Z = 0 (the other rows and columns the identity)
        Am = jnp.where(passive[:, :, None] & passive[:, None, :], A, eye)
        z = jnp.linalg.solve(Am, jnp.where(passive, b, 0.0)[..., None])[..., 0]
        return jnp.where(passive, z, 0.0)

    def body(state):
        y, passive, done, it = state
        z = solve(passive)
        accept = jnp.all(~passive | (z > 0.0), axis=-1)
        # z feasible: y = z, then the column of largest positive gradient enters (or y is optimal)
        grad = b - jnp.einsum("bkl,bl->bk", A, z)
        enter = ~passive & valid & (grad > tol[:, None])
        t = jnp.argmax(jnp.where(enter, grad, -jnp.inf), axis=-1)
        more = jnp.any(enter, axis=-1)
        passive_a = passive | ((jnp.arange(K) == t[:, None]) & more[:, None])
        # z not feasible: move from y towards z until a passive entry reaches 0, which leaves
        neg = passive & (z <= 0.0)
        gap = y - z  # > 0 on a passive entry with y > 0 >= z
        ratio = jnp.where(neg, jnp.where(gap > 0.0, y / jnp.where(gap > 0.0, gap, 1.0), 0.0), jnp.inf)
        q = jnp.argmin(ratio, axis=-1)
        alpha = jnp.min(ratio, axis=-1, keepdims=True)
        y_s = y + alpha * (z - y)
        passive_s = passive & (y_s > 0.0) & (jnp.arange(K) != q[:, None])
        y_s = jnp.where(passive_s, y_s, 0.0)
        keep = done[:, None]
        y = jnp.where(keep, y, jnp.where(accept[:, None], z, y_s))
        passive = jnp.where(keep, passive, jnp.where(accept[:, None], passive_a, passive_s))
        done = done | (accept & ~more)
        return y, passive, done, it + 1

    def cond(state):
        return (state[3] < max_iter) & ~jnp.all(state[2])

    zero = jnp.zeros((B, K), dtype=A.dtype)
    y, _, done, _ = jax.lax.while_loop(cond, body, (zero, jnp.zeros((B, K), dtype=bool), skip, jnp.asarray(0)))
    return y, done & ~skip


def pair_constraints(barrier, L, P, V):
    """Every pair's constraint of :class:`~quatform.control.safety.SeparationBarrier` at the
    points ``P`` moving at ``V`` (``(B, n, 3)``, JAX arrays): ``(pij, sep, R, h, g, active)``,
    the pairs' offsets ``(B, pairs, 3)`` and separations, the range (``range_m`` or
    ``SeparationBarrier._range`` of the largest point speed, ``(B, 1)``), ``h`` and ``g`` (``(B,
    pairs)``) and whether some pair within range binds (``(B,)``)."""
    import jax.numpy as jnp

    i, j = L.pairs
    pij = P[:, i, :] - P[:, j, :]
    sep = jnp.sqrt(jnp.sum(pij * pij, axis=-1))  # (B, pairs)
    d2, gam = barrier.min_separation_m ** 2, barrier.gamma
    if barrier.range_m is None:  # SeparationBarrier._range of the largest point speed
        speed = jnp.sqrt(jnp.max(jnp.sum(V * V, axis=-1), axis=-1, keepdims=True))
        R = (2.0 * speed + jnp.sqrt(4.0 * speed * speed + gam * gam * d2)) / gam
    else:
        R = barrier.range_m
    h = jnp.sum(pij * pij, axis=-1) - d2  # the single-integrator barrier (Robotarium certificate)
    g = 2.0 * jnp.sum(pij * (V[:, i, :] - V[:, j, :]), axis=-1) + gam * h  # Wang et al. 2017
    active = jnp.any((sep <= R) & (g < 0.0), axis=-1)
    return pij, sep, R, h, g, active


def barrier_filter(barrier, team, m, u, live):
    """:meth:`~quatform.control.safety.SeparationBarrier.filter` of a common-limit team of
    4-DOF and planar holonomic robots on JAX arrays, for a batch of worlds.

    Parameters
    ----------
    barrier : SeparationBarrier
    team : Team
        Kinematic holonomic robots whose commands are their point rates (``team.passthrough``)
        with one common limit factor.
    m : jax array, shape (B, n_state)
        Measured states.
    u : jax array, shape (B, n)
        Nominal (saturated) commands.
    live : jax array of bool, shape (B,)
        Worlds whose programme is wanted (a failed or frozen world's is not solved).

    Returns
    -------
    u_safe : jax array, shape (B, n)
        ``u`` bitwise where no pair binds; the programme's commands scaled by the common
        limit factor where one does and the world is solved.
    separations : jax array, shape (B, pairs)
        Distance between the points of each pair of robots (``team.layout.pairs``), m.
    active : jax array of bool, shape (B,)
        Whether some pair within range binds (the filter changes the commands).
    solved : jax array of bool, shape (B,)
        False where the fixed-size programme could not be shown to be the exact one, or
        was not tried (more pairs binding at ``u`` than ``K``, a world not ``live``): the
        world must be filtered on the host.
    """
    import jax
    import jax.numpy as jnp

    L = team.layout
    i, j = L.pairs
    n, n_pairs = L.n, len(i)
    K = min(n_pairs, CANDIDATES)
    P = team_positions(L, m)
    V = team_positions(L, u)
    pij, sep, R, h, g, active = pair_constraints(barrier, L, P, V)
    d2, gam = barrier.min_separation_m ** 2, barrier.gamma
    if barrier.range_m is None:
        # every pair: NumPy widens its range to that of the solution's speed, beyond which no
        # pair can bind (SeparationBarrier._range), so its solution satisfies every pair
        seen = jnp.isfinite(g)
    else:  # a sensing range: the pairs beyond it are not in the programme
        seen = (sep <= R) & jnp.isfinite(g)
    tol = 1e-12 * gam * d2  # SeparationBarrier._world's tolerance of a new violation
    planar = L.position_index[:, 2] == L.size  # a planar point's z velocity is no variable
    zmask = jnp.where(jnp.asarray(planar)[:, None], jnp.array([1.0, 1.0, 0.0]), 1.0)  # (n, 3)
    flat = L.position_index[L.position_index < L.size]  # the point velocities' entries of u
    ia, ib = jnp.asarray(i), jnp.asarray(j)

    # more pairs binding at u than candidates: the check would fail, the loop is not run
    tried = active & live & (jnp.sum(seen & (g < 0.0), axis=-1) <= K)

    def solve(_):
        key = jnp.where(seen, g, jnp.inf)
        if K < n_pairs:
            _, idx = jax.lax.top_k(-key, K)  # the K smallest g: the most violated or nearest pairs
        else:
            idx = jnp.broadcast_to(jnp.arange(n_pairs), key.shape)
        valid = jnp.isfinite(jnp.take_along_axis(key, idx, axis=-1))
        a, bb = ia[idx], ib[idx]  # (B, K) robots of each candidate
        pc = jnp.take_along_axis(pij, idx[..., None], axis=1)
        c = jnp.where(valid, -jnp.take_along_axis(g, idx, axis=-1), 0.0)  # G w >= c
        # the candidates' rows of G: +2 p_ij at robot i, -2 p_ij at robot j (planar z zeroed)
        va = jnp.where(valid[..., None], 2.0 * pc * zmask[a], 0.0)
        vb = jnp.where(valid[..., None], -2.0 * pc * zmask[bb], 0.0)
        Q = 0.0
        for ra, wa in ((a, va), (bb, vb)):
            for rb, wb in ((a, va), (bb, vb)):
                Q = Q + jnp.where(ra[:, :, None] == rb[:, None, :], jnp.einsum("bkd,bld->bkl", wa, wb), 0.0)
        A = Q + c[:, :, None] * c[:, None, :]  # E^T E, E = [G^T; c^T]
        scale = 1.0 + jnp.max(jnp.abs(c), axis=-1)
        y, converged = nnls_gram(A, c, valid, 1e-14 * scale, 4 * K + 8, ~tried)
        onehot = jnp.arange(n)
        Gy = (jnp.einsum("bkn,bkd->bnd", (a[..., None] == onehot).astype(u.dtype), y[..., None] * va)
              + jnp.einsum("bkn,bkd->bnd", (bb[..., None] == onehot).astype(u.dtype), y[..., None] * vb))
        den = jnp.sum(c * y, axis=-1) - 1.0  # r[-1]
        feasible = jnp.abs(den) >= 1e-14  # SeparationBarrier._solve's infeasibility test
        W = -Gy / jnp.where(feasible, den, 1.0)[:, None, None]  # w = -r[:-1] / r[-1]
        Vn = V + W
        gn = 2.0 * jnp.sum(pij * (Vn[:, i, :] - Vn[:, j, :]), axis=-1) + gam * h
        kept = jnp.all(~seen | (gn >= -tol), axis=-1)
        u_new = u.at[:, flat].set(Vn.reshape(Vn.shape[0], -1)[:, (L.position_index < L.size).reshape(-1)])
        s = jnp.minimum(1.0, team.limit_factor(u_new))  # the common limit factor (SeparationBarrier.filter)
        out = jnp.where(active[:, None], s[:, None] * u_new, u)
        return out, ~active | (converged & feasible & kept & (s > 0.0))

    def skip(_):
        return u, ~active

    u_safe, solved = jax.lax.cond(jnp.any(tried), solve, skip, None)
    return u_safe, sep, active, solved
