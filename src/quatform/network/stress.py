"""The stress matrix of a nominal configuration on a graph, and the leaders that fix its affine image.

Formations and planning layer (imports errors, checks and the graph).

A *stress* of a configuration ``P̄ = [p̄_1 ... p̄_n]^T`` (``(n, d)``, m) on an undirected graph
is a weight ``ω_ij = ω_ji`` on every edge with each robot in equilibrium,
``sum_j ω_ij (p̄_j - p̄_i) = 0``. Its stress matrix ``Ω`` (``Ω_ij = -ω_ij`` on an edge, 0 off
the graph, ``Ω_ii = sum_j ω_ij``) is a Laplacian with signed weights: ``Ω 1 = 0`` and
``Ω P̄ = 0``, so ``Ω (P̄ A^T + 1 b^T) = 0`` for every affine image of ``P̄``: the configurations
that the law ``Ω p = 0`` holds are the affine images of the nominal one (Lin, Wang, Han & Fu
2016, IEEE TAC 61(10), "Necessary and sufficient graphical conditions for affine formation
control"; Zhao 2018, IEEE TAC 63(12), "Affine formation maneuver control of multiagent
systems", Sec. II–III). They are exactly those when ``Ω`` is positive semidefinite of rank
``n - d - 1`` (its kernel is then ``span[1, P̄]``), which :class:`Stress` finds.

**Method** (Zhao 2018, Sec. III, and the procedure of its released code): the equilibrium
equations are linear in the edge weights, ``E ω = 0`` (``E``: ``(d n, m)``); their null space
(SVD) is spanned by ``b_1 ... b_s``. With ``Q`` ``(n, n - d - 1)`` an orthonormal basis of the
complement of ``span[1, P̄]``, every stress has ``Ω = Q M Q^T``, ``M = sum_k x_k M_k``,
``M_k = Q^T H^T diag(b_k) H Q`` (``H`` the incidence matrix), and ``Ω`` is PSD of rank
``n - d - 1`` iff ``M`` is positive definite, the linear matrix inequality Zhao solves with an
LMI solver. Here: with one stress (``s = 1``) its sign decides; otherwise the stress nearest
to ``M = I`` (a least-squares projection) is taken where it is positive definite, and else
a barrier method (Boyd & Vandenberghe 2004, Convex Optimization, Sec. 11.6) maximises the
least eigenvalue ``t`` of ``M`` over ``||x|| <= 1`` (``||x|| = ||ω||``: the basis is
orthonormal), the semidefinite programme ``max t`` s.t. ``M(x) - t I ⪰ 0``: Newton steps on
``-c t - log det(M(x) - t I) - log(1 - ||x||^2)`` for ``c = 1, 8, 64, ...``. On the central
path the optimum is at most ``(n - d) / c`` above ``t`` (the barrier's degree over ``c``), so the
method stops with ``t`` within ``tol`` of the optimum, or as soon as the optimum is below
``tol``: then no stress of rank ``n - d - 1`` exists (within ``tol``, relative to the largest
``||M_k||_F``) and the call raises one line. Cost: ``O(m s r^2)`` to form the ``M_k``
(``r = n - d - 1``), ``O(s^2 r^2)`` per Newton step (60 robots in the plane: a trilateration
graph 0.3 s, the complete graph 2 s).

Zhao's condition for leaders (2018, Sec. III, affine localizability): with such a stress, the
followers' positions are fixed by the leaders' (``Ω_ff`` nonsingular, then positive
definite) iff the leaders' nominal positions affinely span ``R^d`` (at least ``d + 1`` of them,
not on one hyperplane). :meth:`Stress.check_leaders` checks both, one line per failure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..checks import short
from ..errors import DegenerateInputError, InvalidInputError, NonFiniteError, ShapeError, UnreachableError
from .graph import Graph, robots_text

__all__ = ["Stress", "AffineExample", "zhao2018_example", "TOL", "MAX_ITERATIONS"]

#: Relative tolerance of a rank decision (singular values and eigenvalues below ``TOL`` times
#: the largest count as zero).
TOL = 1e-9
#: Largest number of Newton steps while searching a positive definite combination.
MAX_ITERATIONS = 5000


def _nominal(nominal) -> np.ndarray:
    try:
        p = np.asarray(nominal, dtype=float)
    except (TypeError, ValueError):
        raise ShapeError(f"stress: nominal {short(nominal)} must be an array (n, d) of positions in m") from None
    if p.ndim != 2 or not 1 <= p.shape[1] <= 3:
        raise ShapeError(f"stress: nominal must have shape (n, d), d in 1 .. 3, positions in m; got shape {p.shape}")
    n, d = p.shape
    if n < d + 2:
        raise InvalidInputError(f"stress: {n} robots in R^{d}: a stress of rank n - d - 1 needs at least d + 2 = "
                                f"{d + 2} robots (with n = d + 1 every robot is a leader); add robots")
    if not np.all(np.isfinite(p)):
        k = int(np.argmax(~np.isfinite(p).all(axis=1)))
        raise NonFiniteError(f"stress: nominal position of robot {k + 1} is {short(p[k].tolist())}; give finite "
                             f"positions")
    return p


def _affine_rank(p: np.ndarray, tol: float) -> int:
    """Dimension of the affine hull of the rows of ``p``: the singular values of the centred rows
    above ``tol`` times the largest (0 where all rows coincide)."""
    s = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    return int(np.sum(s > tol * s[0])) if len(s) and s[0] > 0.0 else 0


def _complement(p: np.ndarray) -> np.ndarray:
    """``(n, n - d - 1)``: an orthonormal basis of the complement of ``span[1, P̄]``."""
    n, d = p.shape
    u, _, _ = np.linalg.svd(np.column_stack([np.ones(n), p]), full_matrices=True)
    return u[:, d + 1:]


@dataclass(frozen=True, eq=False)
class Stress:
    """The positive semidefinite stress of rank ``n - d - 1`` of ``nominal`` on ``edges`` (module docstring).

    Parameters
    ----------
    nominal : array_like, shape (n, d)
        The nominal configuration ``P̄``, m (``d`` in 1 .. 3; a planar team gives ``d = 2``).
    edges : array_like of int, shape (m, 2)
        Undirected pairs ``(i, j)``, 0-based, each once.
    tol : float
        Relative tolerance of the rank decisions (:data:`TOL`).

    Attributes
    ----------
    edges : ndarray, shape (m, 2)
        The pairs, ``i < j``, sorted.
    weights : ndarray, shape (m,)
        ``ω_ij`` of each pair, scaled so the largest ``|ω_ij|`` is 1 (the law divides by
        ``γ_i = sum_j ω_ij``, so the scale does not matter).
    iterations : int
        Newton steps the search took (0 where one stress spans the solutions, or the stress
        nearest to ``M = I`` is positive definite).

    Raises
    ------
    ShapeError, NonFiniteError, InvalidInputError
        Malformed positions or edges (one line each).
    DegenerateInputError
        The nominal configuration does not affinely span ``R^d`` (e.g. collinear in the plane).
    UnreachableError
        A robot with fewer than ``d + 1`` neighbours, a graph with no stress, or no positive
        semidefinite combination of rank ``n - d - 1`` found.
    """

    nominal: np.ndarray
    edges: np.ndarray
    tol: float = TOL
    weights: np.ndarray = field(init=False)
    iterations: int = field(init=False)

    def __post_init__(self):
        p = _nominal(self.nominal)
        n, d = p.shape
        tol = self.tol
        if isinstance(tol, bool) or not isinstance(tol, (int, float, np.number)) or not 0.0 < tol < 1e-2:
            raise InvalidInputError(f"stress: tol = {short(tol)} must be a number in (0, 0.01), a relative tolerance")
        if _affine_rank(p, tol) < d:
            raise DegenerateInputError(
                f"stress: the {n} nominal positions span an affine space of dimension {_affine_rank(p, tol)}, not "
                f"R^{d} (collinear or coplanar); give nominal positions that span R^{d}, or give them in "
                f"d = {_affine_rank(p, tol)}")
        e = np.sort(Graph.from_edges(n, self.edges, directed=False).edges, axis=1)
        e = np.unique(e, axis=0)
        degree = np.bincount(e.ravel(), minlength=n)
        # A robot with at most d neighbours in independent directions carries no stress (its
        # equilibrium forces its weights to 0), so Ω's rank falls short: name it.
        low = [i for i in np.flatnonzero(degree < d + 1)
               if _affine_rank(np.vstack([p[i], p[e[e[:, 0] == i, 1]], p[e[e[:, 1] == i, 0]]]), tol) == degree[i]]
        if low:
            counts = sorted({int(degree[i]) for i in low})
            many = len(low) > 1
            held = (f"{counts[0]} neighbour{'s' if counts[0] != 1 else ''}" if len(counts) == 1
                    else f"{counts[0]} to {counts[-1]} neighbours")
            raise UnreachableError(
                f"stress: robot{'s' if many else ''} {robots_text(low)} {'have' if many else 'has'} {held} "
                f"in independent directions{' each' if many and len(counts) == 1 else ''}, so no stress reaches "
                f"{'them' if many else 'it'}; a stress of rank n - d - 1 needs every robot to have at least "
                f"d + 1 = {d + 1} (Zhao 2018, universal rigidity); add edges to {'them' if many else 'it'}")
        m = len(e)
        H = np.zeros((m, n))
        H[np.arange(m), e[:, 0]] = -1.0
        H[np.arange(m), e[:, 1]] = 1.0
        # E ω = 0: robot i's equilibrium sum_j ω_ij (p̄_j - p̄_i) = 0, d rows per robot.
        diff = p[e[:, 1]] - p[e[:, 0]]                                   # (m, d)
        E = np.zeros((n, d, m))
        E[e[:, 0], :, np.arange(m)] += diff
        E[e[:, 1], :, np.arange(m)] -= diff
        E = E.reshape(n * d, m)
        _, s, vt = np.linalg.svd(E, full_matrices=True)
        rank = int(np.sum(s > tol * max(float(s[0]), 1e-300)))
        basis = vt[rank:].T                                              # (m, s)
        if basis.shape[1] == 0:
            raise UnreachableError(
                f"stress: the {m} edges carry no stress on the nominal configuration (the equilibrium equations "
                f"have full rank {rank}); add edges until the framework is universally rigid (e.g. each new "
                f"robot joined to d + 1 = {d + 1} robots already placed)")
        Q = _complement(p)
        HQ = H @ Q
        r = HQ.shape[1]                                                 # M_k = (HQ)^T diag(b_k) HQ
        Mk = (basis.T @ (HQ[:, :, None] * HQ[:, None, :]).reshape(m, r * r)).reshape(-1, r, r)
        x, iterations, lam = _positive_combination(Mk, tol)
        if lam <= tol:
            raise UnreachableError(
                f"stress: no positive semidefinite stress of rank n - d - 1 = {n - d - 1} on these {m} edges "
                f"({basis.shape[1]} independent stresses; the largest least eigenvalue on the complement of "
                f"span[1, P̄] is {lam:.3g}, relative); add edges (a universally rigid "
                f"framework has one) or move the nominal positions off special positions")
        w = basis @ x
        w = w / np.max(np.abs(w))
        e.setflags(write=False)
        w.setflags(write=False)
        p = p.copy()
        p.setflags(write=False)
        object.__setattr__(self, "nominal", p)
        object.__setattr__(self, "edges", e)
        object.__setattr__(self, "tol", float(tol))
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "iterations", iterations)

    # ------------------------------------------------------------------ views
    @property
    def n(self) -> int:
        """Number of robots."""
        return self.nominal.shape[0]

    @property
    def d(self) -> int:
        """Dimension of the nominal configuration."""
        return self.nominal.shape[1]

    def matrix(self) -> np.ndarray:
        """``Ω`` ``(n, n)``: ``Ω_ij = -ω_ij`` on an edge, ``Ω_ii = γ_i = sum_j ω_ij``; PSD, rank
        ``n - d - 1``, ``Ω 1 = 0``, ``Ω P̄ = 0``."""
        w = self.rows()
        return np.diag(w.sum(axis=1)) - w

    def rows(self) -> np.ndarray:
        """``(n, n)``: row ``i`` holds robot ``i``'s ``ω_ij`` (0 off the graph and on the diagonal),
        what robot ``i`` knows of the stress (the reference of :mod:`quatform.control.local_laws.affine`)."""
        w = np.zeros((self.n, self.n))
        w[self.edges[:, 0], self.edges[:, 1]] = self.weights
        w[self.edges[:, 1], self.edges[:, 0]] = self.weights
        return w

    def graph(self) -> Graph:
        """The links' graph: each robot hears its stress neighbours (undirected, weights 1; the
        stress weights may be negative, which a :class:`Graph` refuses, so they travel in
        :meth:`rows`)."""
        return Graph.from_edges(self.n, self.edges, directed=False)

    # ------------------------------------------------------------------ leaders
    def _leaders(self, leaders) -> np.ndarray:
        try:
            a = np.asarray(leaders)
        except (TypeError, ValueError):
            a = np.array([None])
        if a.ndim != 1 or not (a.size == 0 or np.issubdtype(a.dtype, np.integer)):
            raise InvalidInputError(f"stress: leaders {short(leaders)} must be a sequence of robot indices "
                                    f"0 .. {self.n - 1} (0-based: robot 1 is index 0)")
        a = a.astype(np.int64)
        if np.any((a < 0) | (a >= self.n)):
            raise InvalidInputError(f"stress: leader index {int(a[(a < 0) | (a >= self.n)][0])} is outside "
                                    f"0 .. {self.n - 1} ({self.n} robots, 0-based: robot 1 is index 0); "
                                    f"renumber it")
        values, counts = np.unique(a, return_counts=True)
        if np.any(counts > 1):
            raise InvalidInputError(f"stress: the leaders name robot{'s' if np.sum(counts > 1) > 1 else ''} "
                                    f"{robots_text(values[counts > 1])} more than once; name each leader once")
        return np.sort(a)

    def check_leaders(self, leaders) -> dict:
        """Zhao's condition: ``leaders``' nominal positions affinely span ``R^d``, and ``Ω_ff`` is
        positive definite (Zhao 2018, Sec. III).

        Parameters
        ----------
        leaders : sequence of int
            0-based indices of the robots that know the maneuver.

        Returns
        -------
        dict
            ``omega_ff_min_eig`` (the least eigenvalue of ``Ω_ff``, ``Ω`` scaled as
            :attr:`weights`), ``gamma_min`` (the least ``γ_i`` of a follower), ``relay_step``
            (:meth:`relay_step`) and ``relay_factor`` (:meth:`relay_factor` at that step).

        Raises
        ------
        UnreachableError
            Fewer than ``d + 1`` leaders, leaders on one hyperplane, or ``Ω_ff`` singular.
        """
        lead = self._leaders(leaders)
        d = self.d
        if len(lead) < d + 1:
            raise UnreachableError(
                f"stress: {len(lead)} leader(s) cannot fix an affine image in R^{d}: Zhao's condition needs at "
                f"least d + 1 = {d + 1} leaders whose nominal positions affinely span R^{d}; add "
                f"{d + 1 - len(lead)} leader(s) off the affine hull of robots {robots_text(lead) or '(none)'}")
        r = _affine_rank(self.nominal[lead], self.tol)
        if r < d:
            raise UnreachableError(
                f"stress: the nominal positions of leaders {robots_text(lead)} span an affine space of dimension "
                f"{r}, not R^{d} (collinear or coplanar), so the followers' affine image is not fixed; choose a "
                f"leader off that {'line' if r == 1 else 'plane' if r == 2 else 'point'}")
        follow = np.setdiff1d(np.arange(self.n), lead)
        Om = self.matrix()
        off = Om[np.ix_(follow, follow)]
        lam = float(np.min(np.linalg.eigvalsh(off))) if len(follow) else math.inf
        if len(follow) and lam <= self.tol * float(np.max(np.abs(np.linalg.eigvalsh(Om)))):
            raise UnreachableError(
                f"stress: Ω_ff of followers {robots_text(follow)} is singular (least eigenvalue {lam:.3g}) although "
                f"the leaders span R^{d}; the stress is not of rank n - d - 1 within tolerance, so add edges")
        return {"omega_ff_min_eig": lam, "gamma_min": float(np.min(np.diag(off))) if len(follow) else math.inf,
                "relay_step": self.relay_step(lead), "relay_factor": self.relay_factor(lead, self.relay_step(lead))}

    def _relay_spectrum(self, leaders) -> np.ndarray:
        """Eigenvalues of ``Γ_f^-1 Ω_ff`` (real, positive where Zhao's condition holds: it is
        similar to ``Γ_f^-1/2 Ω_ff Γ_f^-1/2``), ascending; empty without followers."""
        lead = self._leaders(leaders)
        follow = np.setdiff1d(np.arange(self.n), lead)
        if not len(follow):
            return np.zeros(0)
        Om = self.matrix()[np.ix_(follow, follow)]
        g = 1.0 / np.sqrt(np.diag(Om))
        return np.linalg.eigvalsh(g[:, None] * Om * g[None, :])

    def relay_step(self, leaders) -> float:
        """The relay step ``β`` that contracts the followers' relayed velocities fastest:
        ``min(1, 2 / (λ_min + λ_max))`` over the eigenvalues of ``Γ_f^-1 Ω_ff`` (1 without
        followers). :class:`~quatform.control.local_laws.affine.AffineManeuver`'s ``relay``."""
        lam = self._relay_spectrum(leaders)
        return float(min(1.0, 2.0 / (lam[0] + lam[-1]))) if len(lam) else 1.0

    def relay_factor(self, leaders, step: float = 1.0) -> float:
        """``ρ(I - β Γ_f^-1 Ω_ff)``: the contraction per tick of the followers' relayed velocities.

        A follower of the sampled law moves its velocity by ``β`` towards Zhao's, computed
        with its neighbours' velocities as last received (``β = 1``: a Jacobi sweep on
        ``Ω_ff v_f = ...`` per tick). With perfect links the relayed velocities converge iff
        this is below 1, at this rate per tick; ``Γ_f`` is the followers' ``γ_i``.

        Parameters
        ----------
        leaders : sequence of int
            0-based leader indices.
        step : float
            ``β`` in (0, 1].
        """
        if isinstance(step, bool) or not isinstance(step, (int, float, np.number)) or not 0.0 < step <= 1.0:
            raise InvalidInputError(f"stress: relay step = {short(step)} must be a number in (0, 1]")
        lam = self._relay_spectrum(leaders)
        return float(np.max(np.abs(1.0 - step * lam))) if len(lam) else 0.0


def _positive_combination(Mk: np.ndarray, tol: float):
    """``(x (s,), newton_steps, λ)``: ``x`` with ``sum_k x_k M_k`` positive definite and its least
    eigenvalue ``λ`` per unit ``||x||`` (relative to the largest ``||M_k||_F``): the sign of one
    stress, the projection of ``I``, or the barrier method's maximiser over ``||x|| <= 1``
    (module docstring); ``λ <= tol`` where no positive definite combination exists."""
    s, r = Mk.shape[0], Mk.shape[1]
    scale = max(float(np.max(np.sqrt(np.sum(Mk * Mk, axis=(1, 2))))), 1e-300)       # the largest ||M_k||_F
    M = Mk / scale
    if s == 1:
        lam = float(np.linalg.eigvalsh(M[0])[0]), float(np.linalg.eigvalsh(-M[0])[0])
        return (np.ones(1), 0, lam[0]) if lam[0] >= lam[1] else (-np.ones(1), 0, lam[1])
    flat = M.reshape(s, r * r)
    # the Gram matrix is positive definite: Ω determines ω, so the M_k are independent
    import scipy.linalg  # imported where used: the CLI's --help stays light

    x = scipy.linalg.solve(flat @ flat.T, np.einsum("kaa->k", M), assume_a="pos")
    if np.any(x):                                                      # the stress nearest to Q^T Q = I
        x = x / np.linalg.norm(x)
        lam = float(np.linalg.eigvalsh(np.tensordot(x, M, 1))[0])
        if lam > tol:
            return x, 0, lam
        x = 0.5 * x
    else:
        x = np.full(s, 0.5 / math.sqrt(s))
    A = np.concatenate([M, -np.eye(r)[None]])                          # F(z) = sum_a z_a A_a, z = (x, t)
    z = np.append(x, np.linalg.eigvalsh(np.tensordot(x, M, 1))[0] - 1.0)
    theta = r + 1.0                                                    # the barrier's degree

    def terms(z):
        """(psi's barrier part, L^-1 A_a L^-T (s+1, r, r)) or None outside the domain."""
        F = np.tensordot(z, A, 1)
        room = 1.0 - float(z[:-1] @ z[:-1])
        try:
            L = np.linalg.cholesky(F)
        except np.linalg.LinAlgError:
            return None
        if room <= 0.0:
            return None
        Li = np.linalg.inv(L)
        return -2.0 * float(np.sum(np.log(np.diag(L)))) - math.log(room), Li @ A @ Li.T, room

    steps, c = 0, 1.0
    while theta / c > tol and steps < MAX_ITERATIONS:
        for _ in range(100):                                           # centring: Newton on -c t + barrier
            phi, B, room = terms(z)
            x = z[:-1]
            g = -np.einsum("aii->a", B)
            g[-1] -= c
            g[:-1] += 2.0 * x / room
            Bf = B.reshape(s + 1, r * r)
            H = Bf @ Bf.T
            H[:-1, :-1] += 2.0 * np.eye(s) / room + 4.0 * np.outer(x, x) / room ** 2
            dz = -np.linalg.solve(H, g)
            dec = -float(g @ dz)
            if dec / 2.0 <= 1e-10:
                break
            value, step = -c * z[-1] + phi, 1.0
            while True:                                                # backtracking, staying inside
                new = terms(z + step * dz)
                if new is not None and -c * (z[-1] + step * dz[-1]) + new[0] <= value - 0.25 * step * dec:
                    break
                step *= 0.5
            z = z + step * dz
            steps += 1
        if z[-1] + theta / c <= tol:                                   # the optimum is below tol: none exists
            break
        c *= 8.0
    x = z[:-1]
    return x, steps, float(np.linalg.eigvalsh(np.tensordot(x, M, 1))[0]) / max(float(np.linalg.norm(x)), 1e-300)


# ---------------------------------------------------------------------- Zhao 2018's example
@dataclass(frozen=True)
class AffineExample:
    """A planar affine maneuver: the nominal configuration, its graph, the leaders, the start and
    the target formation ``p*_i(t) = A(t) p̄_i + b(t)``.

    Attributes
    ----------
    nominal : ndarray, shape (n, 2)
        ``P̄``, m.
    edges : ndarray, shape (m, 2)
        Undirected pairs, 0-based.
    leaders : tuple of int
        0-based indices of the leaders.
    initial : ndarray, shape (n, 2)
        Positions at ``t = 0``, m.
    keyframes : ndarray, shape (K, 7)
        ``(t_s, θ_rad, s_x, s_y, h, b_x_m, b_y_m)``: at ``t_s``, ``A = R(θ) [[s_x, h], [0, s_y]]``,
        ``b = (b_x, b_y)``; between two keyframes each parameter moves by the quintic
        ``10 τ^3 - 15 τ^4 + 6 τ^5`` (zero rate and acceleration at both ends); held after the last.
    """

    nominal: np.ndarray
    edges: np.ndarray
    leaders: tuple
    initial: np.ndarray
    keyframes: np.ndarray

    @property
    def duration_s(self) -> float:
        """Time of the last keyframe, s."""
        return float(self.keyframes[-1, 0])

    def maneuver(self, t):
        """``(A, b, A_dot, b_dot)`` at times ``t`` (``(*T,)`` s): ``(*T, 2, 2)``, ``(*T, 2)`` m,
        ``(*T, 2, 2)`` 1/s, ``(*T, 2)`` m/s."""
        t = np.asarray(t, dtype=float)
        kf = self.keyframes
        k = np.clip(np.searchsorted(kf[:, 0], t, side="right") - 1, 0, len(kf) - 2)
        t0, t1 = kf[k, 0], kf[k + 1, 0]
        tau = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)
        ds = np.where((tau > 0.0) & (tau < 1.0), 30.0 * tau ** 2 * (1.0 - tau) ** 2 / (t1 - t0), 0.0)
        q = kf[k, 1:] + s[..., None] * (kf[k + 1, 1:] - kf[k, 1:])
        dq = ds[..., None] * (kf[k + 1, 1:] - kf[k, 1:])
        th, sx, sy, h, bx, by = np.moveaxis(q, -1, 0)
        dth, dsx, dsy, dh, dbx, dby = np.moveaxis(dq, -1, 0)
        c, sn = np.cos(th), np.sin(th)
        R = np.stack([np.stack([c, -sn], -1), np.stack([sn, c], -1)], -2)
        dR = np.stack([np.stack([-sn, -c], -1), np.stack([c, -sn], -1)], -2) * dth[..., None, None]
        z = np.zeros_like(sx)
        S = np.stack([np.stack([sx, h], -1), np.stack([z, sy], -1)], -2)
        dS = np.stack([np.stack([dsx, dh], -1), np.stack([z, dsy], -1)], -2)
        return R @ S, np.stack([bx, by], -1), dR @ S + R @ dS, np.stack([dbx, dby], -1)

    def targets(self, t):
        """``(p*, v*)`` of every robot at ``t``: ``A p̄_i + b`` ``(*T, n, 2)`` m and ``A_dot p̄_i +
        b_dot`` ``(*T, n, 2)`` m/s."""
        A, b, dA, db = self.maneuver(t)
        p = self.nominal
        return (np.einsum("...ab,nb->...na", A, p) + b[..., None, :],
                np.einsum("...ab,nb->...na", dA, p) + db[..., None, :])


def zhao2018_example() -> AffineExample:
    """Zhao 2018's 7-robot, 3-leader planar example, with a maneuver through two narrow passages.

    The nominal configuration, the 12 edges and the leaders (robots 1, 2, 3) are Zhao's (2018,
    Fig. 3, and the simulation of the author's released code: ``P̄ = 2 [(2, 0), (1, 1),
    (1, -1), (0, 1), (0, -1), (-1, 1), (-1, -1)]`` m); the start puts the leaders on their
    targets and the followers off them by Zhao's offsets ``(1, 1), (0, 1), (-1, 1), (-2, -1)``
    m. The maneuver follows the paper's sequence for single integrators as keyframes of
    ``A(t), b(t)`` (Zhao drives double-integrator leaders by accelerations): a translation, a
    scaling in ``y`` to pass a narrow passage and back, a rotation by -90° while turning
    downwards, a shear that lays the formation on one line (``s_y = 0``, robots at least 1 m apart) to
    pass a second passage, and back to the nominal shape, held from 60 s to 70 s.
    """
    r = np.array([[2.0, 0.0], [1.0, 1.0], [1.0, -1.0], [0.0, 1.0], [0.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    nominal = 2.0 * r
    edges = np.array([(1, 2), (1, 3), (1, 4), (1, 5), (2, 4), (3, 5), (3, 6), (4, 5), (4, 6), (2, 7), (5, 7),
                      (6, 7)]) - 1
    offsets = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [-1.0, 1.0], [-2.0, -1.0]])
    q = -0.5 * math.pi
    keyframes = np.array([
        # t_s   θ     s_x  s_y  h     b_x   b_y
        [0.0,  0.0,  1.0, 1.0, 0.0,  0.0,   0.0],    # start (followers converge)
        [10.0, 0.0,  1.0, 1.0, 0.0,  10.0,  0.0],    # translation
        [15.0, 0.0,  1.0, 0.5, 0.0,  15.0,  0.0],    # scale down in y before the passage
        [20.0, 0.0,  1.0, 0.5, 0.0,  20.0,  0.0],    # through the passage
        [25.0, 0.0,  1.0, 1.0, 0.0,  25.0,  0.0],    # scale back up
        [35.0, q,    1.0, 1.0, 0.0,  30.0,  -5.0],   # rotate by -90° while turning downwards
        [40.0, q,    1.0, 1.0, 0.0,  30.0,  -10.0],  # translation
        [45.0, q,    1.0, 0.0, 0.25, 30.0,  -15.0],  # shear onto one line
        [55.0, q,    1.0, 0.0, 0.25, 30.0,  -25.0],  # through the second passage, collinear
        [60.0, q,    1.0, 1.0, 0.0,  30.0,  -30.0],  # back to the nominal shape
        [70.0, q,    1.0, 1.0, 0.0,  30.0,  -30.0],  # hold
    ])
    for a in (nominal, edges, offsets, keyframes):
        a.setflags(write=False)
    initial = nominal + offsets
    initial.setflags(write=False)
    return AffineExample(nominal, edges, (0, 1, 2), initial, keyframes)
