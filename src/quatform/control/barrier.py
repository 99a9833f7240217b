"""The separation barrier's programme at a fixed size, on any array namespace (control layer).

:class:`~quatform.control.safety.SeparationBarrier` solves Wang, Ames and Egerstedt 2017's
programme (``min sum_i |v_i - v_nom_i|^2`` subject to ``2 p_ij . (v_i - v_j) + gamma h_ij >= 0``
for every pair, the Robotarium single-integrator certificate ``h_ij = |p_ij|^2 - d_min^2``)
exactly on the host: Lawson and Hanson's least-distance programme (1974, ch. 23) as one
non-negative least-squares problem per connected component of a growing active set. The
programme is strictly convex and feasible, so its solution is unique: any exact solver gives
the same velocities to rounding. Here the solver has a fixed size and no branch on data, so
it runs on NumPy and under ``jax.jit`` alike (the array namespace of its operands,
:func:`quatform.algebra.kernels.array_namespace`), for a team of kinematic 4-DOF and planar
holonomic robots with one common limit factor (:func:`solves`):

* the ``K`` pairs of smallest ``g_ij = 2 p_ij . (v_i - v_j) + gamma h_ij`` (those within
  ``range_m`` when it is given) are the candidates (``K = min(pairs, CANDIDATES)``);
* their least-distance programme ``min |w|, G w >= c`` (``c = -g``) is Lawson and Hanson's
  NNLS ``min |E y - f|, y >= 0``, ``E = [G^T; c^T]``, ``f = e_last``, solved on its Gram
  matrix ``E^T E = G G^T + c c^T`` by their active-set algorithm (ch. 23, Algorithm NNLS) in
  a bounded loop with masks (``lax.while_loop`` on JAX, a Python loop on NumPy: the same
  steps); ``w = -r[:-1] / r[-1]``, ``r = E y - f``;
* every pair of the world (within ``range_m`` when it is given) is checked at ``v_nom + w``
  with the host solver's tolerance: the solution of a relaxation that satisfies every
  constraint is the programme's solution;
* the common limit factor ``s = min(1, team.limit_factor(u_new))`` scales the commands, as
  :meth:`~quatform.control.safety.SeparationBarrier.filter` scales a common-limit team's.

A world whose check fails (more binding pairs than ``K``, no convergence within the loop's
bound, an infeasible programme, a limit factor 0) is reported unsolved: the caller applies
the exact host solver there (:meth:`~quatform.control.safety.SafeController.tick` on NumPy)
or reports it with :data:`HOST` (under ``jax.jit``, where the driver reruns the world on the
host), so exactness is never traded. ``docs/derivations.md``, "The separation barrier on
JAX".
"""

from __future__ import annotations

import numpy as np

from ..algebra.kernels import array_namespace, small_matmul
from ..formations.team_chart import team_positions

__all__ = ["CANDIDATES", "HOST", "barrier_filter", "nnls_gram", "pair_constraints", "point_velocities", "solves"]

#: Most candidate pairs of one world's programme (the static size ``K``).
CANDIDATES = 32
#: Failure code of a world whose programme the array algorithm does not solve, or whose robots
#: start closer than the barrier's minimum: the world runs on the host (its exact solver, its
#: one-line refusal).
HOST = 3


def solves(team) -> bool:
    """Whether :func:`barrier_filter` runs the team: kinematic robots whose commands are their
    point rates (``team.passthrough``) with a point map (the 4-DOF and planar holonomic
    robots), with one common limit factor."""
    return bool(team.common_limit and team.passthrough and all(r.point_map is not None for r in team.robots))


def _while_loop(xp, cond, body, state):
    """``lax.while_loop`` on JAX; the same loop in Python on NumPy."""
    if xp is np:
        while cond(state):
            state = body(state)
        return state
    import jax

    return jax.lax.while_loop(cond, body, state)


def _cond(xp, pred, yes, no):
    """``lax.cond(pred, yes, no)`` on JAX; the branch ``pred`` picks on NumPy (both give the
    same values: ``no`` is what ``yes`` gives where nothing is to be solved)."""
    if xp is np:
        return yes(None) if bool(pred) else no(None)
    import jax

    return jax.lax.cond(pred, yes, no, None)


#: Entries per block of :func:`_smallest`'s selection on JAX.
_BLOCK = 64


def _smallest(xp, key, K):
    """Indices of the ``K`` smallest entries of each row of ``key`` (``(B, P)``, no NaN),
    smallest first, ties by index: a stable sort on NumPy; on JAX the same indices as
    ``lax.top_k(-key, K)`` (IEEE total order: ``-0.0`` before ``0.0``) without its sort.

    ``lax.top_k`` of float64 sorts the whole row on the CPU (the library's fast top-k is
    float32 only; 4 950 pairs x 32 candidates: 36 x this selection's time, ``docs/performance.md``).
    Here the row is cut into blocks of :data:`_BLOCK` entries with their minima held; each of
    the ``K`` rounds takes the smallest block minimum (the first block on a tie), that block's
    smallest entry (the first on a tie), and replaces it by the largest key: ``P + K (P /
    _BLOCK + 2 _BLOCK)`` comparisons instead of ``K P``. The keys compared are the floats' bit
    patterns as integers, sign-folded (the total order: ``int64`` ``b`` or ``b ^ (2^63 - 1)``
    where negative), so equal floats compare equal and ``argmin``'s first index is the tie rule.
    """
    if xp is np:
        return np.argsort(key, axis=-1, kind="stable")[..., :K]
    import jax

    jnp = jax.numpy
    B, P = key.shape
    nb = -(-P // _BLOCK)
    top = jnp.iinfo(jnp.int64).max
    bits = jax.lax.bitcast_convert_type(key.astype(jnp.float64), jnp.int64)
    order = jnp.where(bits < 0, bits ^ jnp.int64(top), bits)
    blocks = jnp.concatenate([order, jnp.full((B, nb * _BLOCK - P), top)], axis=-1).reshape(B, nb, _BLOCK)
    least = jnp.min(blocks, axis=-1)  # (B, nb)
    rows, within = jnp.arange(B), jnp.arange(_BLOCK)
    out = []
    for _ in range(K):
        b = jnp.argmin(least, axis=-1)
        block = blocks[rows, b]  # (B, _BLOCK)
        j = jnp.argmin(block, axis=-1)
        out.append(b * _BLOCK + j)
        block = jnp.where(within == j[:, None], top, block)
        blocks = blocks.at[rows, b].set(block)
        least = least.at[rows, b].set(jnp.min(block, axis=-1))
    return jnp.stack(out, axis=-1)


def _solve(xp, A, b):
    """Batched ``A z = b`` (``(B, K, K)``, ``(B, K)``); a singular world's ``z`` NaN on NumPy
    (JAX's LU gives non-finite values there)."""
    if xp is not np:
        return xp.linalg.solve(A, b[..., None])[..., 0]
    try:
        return np.linalg.solve(A, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        z = np.full(b.shape, np.nan)
        for w in range(b.shape[0]):
            try:
                z[w] = np.linalg.solve(A[w], b[w])
            except np.linalg.LinAlgError:
                pass
        return z


def nnls_gram(A, b, valid, tol, max_iter, skip):
    """Lawson and Hanson's NNLS (1974, ch. 23, Algorithm NNLS) on its normal equations,
    batched: ``min_y>=0 |E y - f|`` given ``A = E^T E`` and ``b = E^T f``.

    Parameters
    ----------
    A : array, shape (B, K, K)
    b : array, shape (B, K)
    valid : array of bool, shape (B, K)
        Columns that may enter the passive set (the others stay 0).
    tol : float or array of shape (B,)
        A column enters while its gradient ``b - A y`` exceeds ``tol``.
    max_iter : int
        Bound of the loop (each step adds or drops one column).
    skip : array of bool, shape (B,)
        Worlds not solved (their ``y`` stays 0, not converged).

    Returns
    -------
    y : array, shape (B, K)
    converged : array of bool, shape (B,)
    """
    xp = array_namespace(A)
    B, K = b.shape
    eye = xp.eye(K, dtype=A.dtype)
    tol = xp.broadcast_to(xp.asarray(tol, dtype=A.dtype), (B,))
    cols = xp.arange(K)

    def solve(passive):  # z_P = A_PP^-1 b_P, z_Z = 0 (the other rows and columns the identity)
        Am = xp.where(passive[:, :, None] & passive[:, None, :], A, eye)
        z = _solve(xp, Am, xp.where(passive, b, 0.0))
        return xp.where(passive, z, 0.0)

    def body(state):
        y, passive, done, it = state
        z = solve(passive)
        accept = xp.all(~passive | (z > 0.0), axis=-1)
        # z feasible: y = z, then the column of largest positive gradient enters (or y is optimal)
        grad = b - small_matmul(A, z[..., None])[..., 0]
        enter = ~passive & valid & (grad > tol[:, None])
        t = xp.argmax(xp.where(enter, grad, -xp.inf), axis=-1)
        more = xp.any(enter, axis=-1)
        passive_a = passive | ((cols == t[:, None]) & more[:, None])
        # z not feasible: move from y towards z until a passive entry reaches 0, which leaves
        neg = passive & (z <= 0.0)
        gap = y - z  # > 0 on a passive entry with y > 0 >= z
        ratio = xp.where(neg, xp.where(gap > 0.0, y / xp.where(gap > 0.0, gap, 1.0), 0.0), xp.inf)
        q = xp.argmin(ratio, axis=-1)
        alpha = xp.min(ratio, axis=-1, keepdims=True)
        y_s = y + alpha * (z - y)
        passive_s = passive & (y_s > 0.0) & (cols != q[:, None])
        y_s = xp.where(passive_s, y_s, 0.0)
        keep = done[:, None]
        y = xp.where(keep, y, xp.where(accept[:, None], z, y_s))
        passive = xp.where(keep, passive, xp.where(accept[:, None], passive_a, passive_s))
        done = done | (accept & ~more)
        return y, passive, done, it + 1

    def cond(state):
        return (state[3] < max_iter) & ~xp.all(state[2])

    zero = xp.zeros((B, K), dtype=A.dtype)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # NumPy: the step not taken
        y, _, done, _ = _while_loop(xp, cond, body, (zero, xp.zeros((B, K), dtype=bool), skip, xp.asarray(0)))
    return y, done & ~skip


def pair_constraints(barrier, L, P, V):
    """Every pair's constraint of :class:`~quatform.control.safety.SeparationBarrier` at the
    points ``P`` moving at ``V`` (``(..., n, 3)``, any namespace): ``(pij, sep, R, h, g,
    active)``, the pairs' offsets ``(..., pairs, 3)`` and separations, the range (``range_m``
    or ``SeparationBarrier._range`` of the largest point speed, ``(..., 1)``), ``h`` and ``g``
    (``(..., pairs)``) and whether some pair within range binds (``(...)``)."""
    xp = array_namespace(P)
    i, j = L.pairs
    pij = P[..., i, :] - P[..., j, :]
    sep2 = xp.sum(pij * pij, axis=-1)
    sep = xp.sqrt(sep2)  # (..., pairs)
    d2, gam = barrier.min_separation_m ** 2, barrier.gamma
    if barrier.range_m is None:  # SeparationBarrier._range of the largest point speed
        speed = xp.sqrt(xp.max(xp.sum(V * V, axis=-1), axis=-1, keepdims=True))
        R = (2.0 * speed + xp.sqrt(4.0 * speed * speed + gam * gam * d2)) / gam
    else:
        R = barrier.range_m
    h = sep2 - d2  # the single-integrator barrier (Robotarium certificate)
    g = 2.0 * xp.sum(pij * (V[..., i, :] - V[..., j, :]), axis=-1) + gam * h  # Wang et al. 2017
    active = xp.any((sep <= R) & (g < 0.0), axis=-1)
    return pij, sep, R, h, g, active


def point_velocities(barrier, team, x, u):
    """The robots' point velocities, m/s, ``(..., N, 3)``, at the measured state ``x`` for the
    team's commands ``u`` (``(..., n_state)`` and ``(..., n)``, any namespace), as
    :meth:`~quatform.control.safety.SeparationBarrier.filter` reads them
    (each model's :attr:`~quatform.robots.RobotModel.point_map`: a Pioneer's mean control-point
    velocity over the barrier's ``dt_s``, seed 001 eq. (3.4); a free body's linear velocity)."""
    xp = array_namespace(u)
    parts, robots = [], []
    for g, xg, ug in zip(team.groups, team.gather(x), team.gather(u, "command")):
        v = g.model.point_map.velocity(g.model, xg, ug, barrier.dt_s)
        parts.append(v if g.axis else v[..., None, :])
        robots.extend(g.robots)
    V = xp.concatenate(parts, axis=-2) if len(parts) > 1 else parts[0]
    return V if robots == sorted(robots) else V[..., np.argsort(robots), :]


def barrier_filter(barrier, team, m, u, live):
    """:meth:`~quatform.control.safety.SeparationBarrier.filter` of a common-limit team of
    4-DOF and planar holonomic robots (:func:`solves`) for a batch of worlds, on any array
    namespace.

    Parameters
    ----------
    barrier : SeparationBarrier
    team : Team
        Kinematic holonomic robots whose commands are their point rates (``team.passthrough``)
        with one common limit factor.
    m : array, shape (B, n_state)
        Measured states (the robots' points).
    u : array, shape (B, n)
        Nominal (saturated) commands.
    live : array of bool, shape (B,)
        Worlds whose programme is wanted (a failed or frozen world's is not solved).

    Returns
    -------
    u_safe : array, shape (B, n)
        ``u`` bitwise where no pair binds; the programme's commands scaled by the common
        limit factor where one does and the world is solved.
    separations : array, shape (B, pairs)
        Distance between the points of each pair of robots (``team.layout.pairs``), m.
    active : array of bool, shape (B,)
        Whether some pair within range binds (the filter changes the commands).
    solved : array of bool, shape (B,)
        False where the fixed-size programme could not be shown to be the exact one, or
        was not tried (more pairs binding at ``u`` than ``K``, a world not ``live``): the
        world must be filtered on the host.
    """
    xp = array_namespace(u)
    L = team.layout
    i, j = L.pairs
    n, n_pairs = L.n, len(i)
    K = min(n_pairs, CANDIDATES)
    P = team_positions(L, m)
    V = team_positions(L, u)
    with np.errstate(invalid="ignore", over="ignore"):  # NumPy: a refused world's (not live) values
        pij, sep, R, h, g, active = pair_constraints(barrier, L, P, V)
    d2, gam = barrier.min_separation_m ** 2, barrier.gamma
    if barrier.range_m is None:
        # every pair: the host solver widens its range to that of the solution's speed, beyond
        # which no pair can bind (SeparationBarrier._range), so its solution satisfies every pair
        seen = xp.isfinite(g)
    else:  # a sensing range: the pairs beyond it are not in the programme
        seen = (sep <= R) & xp.isfinite(g)
    tol = 1e-12 * gam * d2  # SeparationBarrier._world's tolerance of a new violation
    planar = L.position_index[:, 2] == L.size  # a planar point's z velocity is no variable
    zmask = np.where(planar[:, None], np.array([1.0, 1.0, 0.0]), 1.0)  # (n, 3)
    # each command entry that is a point velocity: its (robot, axis) in V's flat (n * 3) entries
    src = np.zeros(u.shape[-1], dtype=np.intp)
    is_v = np.zeros(u.shape[-1], dtype=bool)
    for a in range(n):
        for d in range(3):
            e = L.position_index[a, d]
            if e < L.size:
                src[e], is_v[e] = 3 * a + d, True
    ia, ib = xp.asarray(i), xp.asarray(j)

    # more pairs binding at u than candidates: the check would fail, the loop is not run
    tried = active & live & (xp.sum(seen & (g < 0.0), axis=-1) <= K)

    def solve(_):
        key = xp.where(seen, g, xp.inf)
        if K < n_pairs:
            idx = _smallest(xp, key, K)  # the K smallest g: the most violated or nearest pairs
            a, bb = ia[idx], ib[idx]  # (B, K) robots of each candidate
            key_c, g_c = xp.take_along_axis(key, idx, axis=-1), xp.take_along_axis(g, idx, axis=-1)
            pc = xp.take_along_axis(pij, idx[..., None], axis=1)
            za, zb = xp.asarray(zmask)[a], xp.asarray(zmask)[bb]
        else:  # every pair a candidate, in pair order: the robots and their masks are constants
            a, bb = i[None, :], j[None, :]
            key_c, g_c, pc, za, zb = key, g, pij, zmask[a], zmask[bb]
        valid = xp.isfinite(key_c)
        c = xp.where(valid, -g_c, 0.0)  # G w >= c
        # the candidates' rows of G: +2 p_ij at robot i, -2 p_ij at robot j (planar z zeroed)
        va = xp.where(valid[..., None], 2.0 * pc * za, 0.0)
        vb = xp.where(valid[..., None], -2.0 * pc * zb, 0.0)
        # G G^T: two candidates share at most one robot, where their rows meet as +-4 p_k . p_l on
        # its axes (a constant pattern C when every pair is a candidate)
        def meet(ra, rb, z):
            return (ra[:, :, None] == rb[:, None, :])[..., None] * z[:, :, None, :]

        C = 4.0 * (meet(a, a, za) - meet(a, bb, za) - meet(bb, a, zb) + meet(bb, bb, zb))  # (B, K, K, 3)
        both = valid[:, :, None] & valid[:, None, :]
        Q = xp.where(both, xp.sum(pc[:, :, None, :] * pc[:, None, :, :] * C, axis=-1), 0.0)
        A = Q + c[:, :, None] * c[:, None, :]  # E^T E, E = [G^T; c^T]
        scale = 1.0 + xp.max(xp.abs(c), axis=-1)
        y, converged = nnls_gram(A, c, valid, 1e-14 * scale, 4 * K + 8, ~tried)
        onehot = np.arange(n)
        Gy = (small_matmul(xp.swapaxes((a[..., None] == onehot).astype(u.dtype), -1, -2), y[..., None] * va)
              + small_matmul(xp.swapaxes((bb[..., None] == onehot).astype(u.dtype), -1, -2), y[..., None] * vb))
        den = xp.sum(c * y, axis=-1) - 1.0  # r[-1]
        feasible = xp.abs(den) >= 1e-14  # SeparationBarrier._solve's infeasibility test
        W = -Gy / xp.where(feasible, den, 1.0)[:, None, None]  # w = -r[:-1] / r[-1]
        Vn = V + W
        gn = 2.0 * xp.sum(pij * (Vn[:, i, :] - Vn[:, j, :]), axis=-1) + gam * h
        kept = xp.all(~seen | (gn >= -tol), axis=-1)
        u_new = xp.where(xp.asarray(is_v), Vn.reshape(Vn.shape[0], 3 * n)[:, src], u)
        s = xp.minimum(1.0, team.limit_factor(u_new))  # the common limit factor (SeparationBarrier.filter)
        out = xp.where(active[:, None], s[:, None] * u_new, u)
        return out, ~active | (converged & feasible & kept & (s > 0.0))

    def skip(_):
        return u, ~active

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # NumPy: a world not solved
        u_safe, solved = _cond(xp, xp.any(tried), solve, skip)
    return u_safe, sep, active, solved
