"""Pairwise separation barrier certificates: a safety filter any controller's commands pass through.

Control layer (above robots). The method of Wang, Ames and Egerstedt 2017 ("Safety barrier
certificates for collisions-free multirobot systems", IEEE T-RO 33(3)): change the nominal
inputs as little as possible, a quadratic programme, subject to one control-barrier-function
constraint ``h_dot >= -kappa(h)`` per pair of robots. The paper's barrier is that of
acceleration-bounded double integrators; for velocity-commanded points quatform uses the
single-integrator barrier of the Robotarium's ``create_single_integrator_barrier_certificate``
(and its unicycle version through a point ahead of the wheel axis),

    h_ij = |p_i - p_j|^2 - d_min^2                   (Robotarium single-integrator certificate)

of the points' positions ``p`` (m), with the linear class-K function ``kappa(h) = gamma h``
(the Robotarium's code uses ``gamma h^3``):

    2 (p_i - p_j) . (v_i - v_j) >= -gamma h_ij

    minimise sum_i |v_i - v_nom_i|^2  subject to every pair's constraint    (Wang et al. 2017's QP)

solved exactly: as the least-distance problem ``min |w|, G w >= c`` (``w = v - v_nom``) of
Lawson and Hanson ("Solving least squares problems", 1974, ch. 23), which is one
non-negative least-squares problem (``scipy.optimize.nnls``), per connected component of the
graph of the pairs whose constraint binds (found by adding the pairs the last solution
violates until none is), with the neighbours of each robot from a k-d tree. With no pair
binding the commands come back bitwise unchanged.

Point velocities: each robot model's :attr:`~quatform.robots.RobotModel.point_map`
(:mod:`quatform.robots.point_map`). The 4-DOF and planar holonomic robots' commands are
their velocities (yaw rates untouched), a free body's linear velocity (its angular velocity
untouched), the Pioneer's control point moves by seed 001 eq. (3.4) (``v = A_p (v, omega)``,
inverted by eq. (3.5)), as the Robotarium's unicycle certificate moves a point ahead of the
wheel axis. With ``dt_s`` given the Pioneer's point velocity is its exact mean velocity over
the held step (:meth:`~quatform.robots.Pioneer.mean_point_velocity`), so the sampled-time
argument below holds for it too. A planar robot's point moves at ``z = 0`` (or its platform
height): its z velocity is not a variable. A model without a point map (the Bebop with its
dynamic compensation) is refused. The maps' ``velocity``
runs on NumPy and on JAX arrays alike (the jax backend's test whether a pair binds).

Sampled time (``docs/derivations.md``, "Team robots and the separation barrier"): for points that move by ``dt v``
over a step, ``h_{k+1} = h_k + 2 dt dp.dv + dt^2 |dv|^2 >= (1 - gamma dt) h_k``, so with
``gamma dt <= 1`` every pair that starts at ``h >= 0`` keeps ``h >= 0`` at every sample.

Limits: the filtered commands are scaled by one factor ``s`` in ``(0, 1]`` (per connected
group of neighbouring robots; the whole team for a holonomic team, whose commands share one
factor anyway) so every robot is within its limits. That keeps every pair constraint: its
right side ``-gamma h`` is ``<= 0``; where ``2 dp.dv >= 0``, ``2 dp.(s dv) >= 0``; where it is
negative, ``2 dp.(s dv) >= 2 dp.dv >= -gamma h``.
"""

from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..algebra.kernels import array_namespace
from ..errors import DegenerateInputError, InvalidInputError, ShapeError
from ..formations.layout import POINT_KINDS, RobotLayout
from ..formations.team_chart import team_positions
from ..robots import ROBOT_MODELS, Team
from . import barrier as _barrier
from . import contract
from .barrier import HOST, pair_constraints, point_velocities, solves

__all__ = ["SeparationBarrier", "BarrierInfo", "SafeController", "SafeState", "components", "HOST",
           "start_floor"]

#: Teams of at most this many robots find their pairs by one dense comparison (cheaper than a tree).
_DENSE_PAIRS_MAX_ROBOTS = 48


def point_mapped() -> tuple[str, ...]:
    """The registered robot model classes the barrier moves (a :attr:`~quatform.robots.RobotModel.point_map`), by name."""
    return tuple(cls.__name__ for cls in ROBOT_MODELS.values() if cls.point_map is not None)


def components(n: int, i, j) -> np.ndarray:
    """Connected components of the graph on ``n`` robots with edges ``(i, j)``: each robot's
    label (the smallest robot number in its component), shape ``(n,)``.

    Label propagation with pointer jumping: every edge takes the smaller label of its ends,
    then every label its label's label, until nothing changes (a few NumPy calls per round,
    rounds about the logarithm of the components' diameter).
    """
    lab = np.arange(n)
    while True:
        m = np.minimum(lab[i], lab[j])
        new = lab.copy()
        np.minimum.at(new, i, m)
        np.minimum.at(new, j, m)
        new = new[new]
        if np.array_equal(new, lab):
            return lab
        lab = new


# -- the barrier ----------------------------------------------------------------------------

@dataclass(frozen=True)
class BarrierInfo:
    """What one filter call did, every array of the batch shape.

    Attributes
    ----------
    min_separation : ndarray
        Smallest distance between two robots' points, m (inf for one robot, NaN for a
        measurement that is not finite).
    active : ndarray of bool
        Whether the filter changed the commands.
    constraints : ndarray of int
        Pair constraints in the last programme solved (0 where inactive).
    factor : ndarray
        The smallest limit factor applied after the programme (1 where none was needed).
    """

    min_separation: np.ndarray
    active: np.ndarray
    constraints: np.ndarray
    factor: np.ndarray


def _positive(value, name):
    if not (isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            and math.isfinite(value) and value > 0):
        raise InvalidInputError(f"SeparationBarrier {name} must be a positive finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class SeparationBarrier:
    """Pairwise separation barrier certificates (Wang, Ames, Egerstedt 2017), solved exactly.

    Parameters
    ----------
    min_separation_m : float
        Smallest distance ``d_min`` two robots' points may come to, m.
    gamma : float
        Barrier rate, 1/s: a pair may close in no faster than ``gamma h_ij / (2 |p_ij|)``.
        With ``dt_s`` given, ``gamma dt_s <= 1`` is required (the sampled-time guarantee).
    range_m : float or None
        Neighbour range, m. None (default): the range beyond which no pair's constraint can
        bind at the commanded speeds, ``(2 v + sqrt(4 v^2 + gamma^2 d_min^2)) / gamma`` with
        ``v`` the largest point speed (so the filter solves the programme over all pairs
        exactly). A number: a sensing range (pairs farther apart are not seen; the guarantee
        then needs ``range_m`` at least that automatic range).
    dt_s : float or None
        How long each filtered command is held, s (the control period). Given, the
        Pioneer's point velocity is its exact mean over the step and ``gamma dt_s <= 1`` is
        checked; None: instantaneous velocities (exact in sampled time for the holonomic
        robots, to ``O(dt^2)`` for the Pioneer).
    """

    min_separation_m: float
    gamma: float = 5.0
    range_m: float | None = None
    dt_s: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "min_separation_m", _positive(self.min_separation_m, "min_separation_m"))
        object.__setattr__(self, "gamma", _positive(self.gamma, "gamma"))
        if self.range_m is not None:
            object.__setattr__(self, "range_m", _positive(self.range_m, "range_m"))
            if self.range_m < self.min_separation_m:
                raise InvalidInputError(f"SeparationBarrier range_m = {self.range_m!r} m is below min_separation_m = "
                                        f"{self.min_separation_m!r} m; give a larger range or None (automatic)")
        if self.dt_s is not None:
            object.__setattr__(self, "dt_s", _positive(self.dt_s, "dt_s"))
            if self.gamma * self.dt_s > 1.0 + 1e-12:
                raise InvalidInputError(f"SeparationBarrier gamma * dt_s = {self.gamma * self.dt_s:.6g} > 1: the "
                                        f"sampled system may cross the barrier; give gamma <= {1.0 / self.dt_s:.6g} 1/s")

    # -- geometry of a team or layout -------------------------------------------------------
    def _plan(self, team):
        """``(layout, maps)`` for a team (one point map per group) or ``(layout, None)``."""
        if isinstance(team, Team):
            maps = []
            for g in team.groups:
                m = g.model.point_map
                if m is None:
                    raise InvalidInputError(
                        f"SeparationBarrier: a {type(g.model).__name__} robot's commands are not a map of its point "
                        f"velocity (known: {', '.join(point_mapped())}); filter its point rates through the layout "
                        "instead")
                maps.append(m)
            return team.layout, maps
        if isinstance(team, RobotLayout):
            return team, None
        raise InvalidInputError(f"SeparationBarrier.filter needs a Team or a RobotLayout, got {type(team).__name__}")

    @staticmethod
    def _layout_index(layout):
        """``(N, 3)`` indices of each robot's position entries in a layout vector (-1: planar z)."""
        idx = np.full((layout.n, 3), -1, dtype=np.intp)
        for i, (o, k) in enumerate(zip(layout.offsets, layout.kinds)):
            for j, p in enumerate(POINT_KINDS[k].position):
                idx[i, j] = o + p
        return idx

    def positions(self, team, x) -> np.ndarray:
        """The robots' point positions, m, shape ``(..., N, 3)`` (a team's state, or a layout's ``r``)."""
        layout, maps = self._plan(team)
        x = np.asarray(x, dtype=float)
        return layout.positions(team.point(x) if maps is not None else x)

    # -- the filter ---------------------------------------------------------------------------
    def filter(self, team, x, u):
        """Commands closest to ``u`` whose motion keeps every pair ``d_min`` apart, and what it did.

        Parameters
        ----------
        team : Team or RobotLayout
            A team (``x`` its stacked state, ``u`` its commands) or a layout (``x`` the robot
            state ``r``, ``u`` its rate ``r_dot``: single-integrator points, no limits).
        x : array_like, shape (..., n_state) or (..., layout.size)
            The measured state; leading axes are worlds (one programme per world).
        u : array_like, shape (..., n) or (..., layout.size)
            The nominal commands (within the robots' limits).

        Returns
        -------
        u_safe : ndarray, same shape as ``u`` broadcast with ``x``'s batch
            Bitwise ``u`` in every world where no pair constraint binds. A robot whose
            measurement is not finite (lost) is left out of its world's programme (its command
            passes; nothing is known of where it is), the others are still kept apart; a world
            with fewer than two robots measured passes its commands (``min_separation`` NaN).
        info : BarrierInfo
        """
        layout, maps = self._plan(team)
        width_x = team.n_state if maps is not None else layout.size
        width_u = team.n if maps is not None else layout.size
        x = np.asarray(x, dtype=float)
        u = u_in = np.asarray(u, dtype=float)
        if x.shape[-1:] != (width_x,) or u.shape[-1:] != (width_u,):
            raise ShapeError(f"SeparationBarrier.filter: x must have shape (..., {width_x}) and u (..., {width_u}), "
                             f"got {x.shape} and {u.shape}")
        if not np.all(np.isfinite(u)):
            raise InvalidInputError("SeparationBarrier.filter: u must be finite (saturate the commands first)")
        batch = np.broadcast_shapes(x.shape[:-1], u.shape[:-1])
        x = np.broadcast_to(x, batch + (width_x,))
        u = np.broadcast_to(u, batch + (width_u,))
        dt = self.dt_s
        n = layout.n
        if maps is not None:
            P = layout.positions(team.point(x))
            V = np.empty(batch + (n, 3))
            planar = np.zeros(n, dtype=bool)
            xg, ug = team.gather(x), team.gather(u, "command")
            for g, m, xs, us in zip(team.groups, maps, xg, ug):
                V[..., list(g.robots), :] = np.reshape(m.velocity(g.model, xs, us, dt), batch + (len(g.robots), 3))
                planar[list(g.robots)] = m.planar
        else:
            idx = self._layout_index(layout)
            P = layout.positions(x)
            V = layout.positions(u)
            planar = idx[:, 2] < 0
        flat_P, flat_V = P.reshape(-1, n, 3), V.reshape(-1, n, 3)
        B = flat_P.shape[0]
        min_sep = np.full(B, np.inf)
        active = np.zeros(B, dtype=bool)
        n_con = np.zeros(B, dtype=np.intp)
        factor = np.ones(B)
        out = None
        common = maps is not None and team.common_limit
        seen = np.all(np.isfinite(flat_P), axis=2) & np.all(np.isfinite(flat_V), axis=2)  # (B, n) robots
        flat_x, flat_u = x.reshape(B, width_x), u.reshape(B, width_u)
        for b in range(B):
            ok = seen[b]
            if ok.sum() < 2:  # fewer than two robots measured: no pair to filter on, the commands pass
                min_sep[b] = np.nan if not ok.all() else np.inf
                continue
            if ok.all():
                res = self._world(flat_P[b], flat_V[b], planar)
            else:  # a robot's measurement lost (NaN): the others are kept apart, its command passes
                res = self._world(flat_P[b][ok], flat_V[b][ok], planar[ok])
            min_sep[b] = res[0]
            if res[1] is None:
                continue
            V_new, changed, (pi, pj), k = res[1:]
            if not ok.all():
                keep = np.flatnonzero(ok)
                V_full, ch_full = np.array(flat_V[b]), np.zeros(n, dtype=bool)
                V_full[keep], ch_full[keep] = V_new, changed
                V_new, changed, pi, pj = V_full, ch_full, keep[pi], keep[pj]
            if out is None:
                out = np.array(flat_u, dtype=float)
            xb, ub = flat_x[b], flat_u[b]
            active[b] = True
            n_con[b] = k
            if maps is None:
                r = out[b]
                keep = idx >= 0
                r[idx[keep]] = V_new[keep]
                continue
            # new commands and each robot's limit factor, group by group
            news, facs = [], np.ones(n)
            for g, m, xs, us in zip(team.groups, maps, team.gather(xb), team.gather(ub, "command")):
                rob = list(g.robots)
                vg = V_new[rob] if g.axis else V_new[rob[0]]
                un = m.commands(g.model, xs, us, vg, dt)
                news.append((un, vg))
                facs[rob] = np.reshape(m.factor(g.model, xs, un, vg, dt), -1)
            if common or np.all(facs >= 1.0):
                s_rob = np.full(n, min(1.0, float(np.min(facs))))
            else:  # one factor per group of neighbours (the components of the pairs within range)
                comp = components(n, pi, pj)
                s_comp = np.ones(n)
                np.minimum.at(s_comp, comp, facs)
                s_rob = np.minimum(1.0, s_comp[comp])
            if np.any(s_rob <= 0):
                raise DegenerateInputError("SeparationBarrier: a robot's limits leave it no motion (limit factor 0); "
                                           "check the commands are finite and the limits positive")
            factor[b] = float(np.min(s_rob))
            write = changed | (s_rob < 1.0)
            parts = []
            for g, m, xs, us, (un, vg) in zip(team.groups, maps, team.gather(xb), team.gather(ub, "command"), news):
                rob = list(g.robots)
                s = s_rob[rob] if g.axis else np.float64(s_rob[rob[0]])
                uf = m.scaled(g.model, xs, un, vg, np.asarray(s), dt)
                w = write[rob][:, None] if g.axis else bool(write[rob[0]])
                parts.append(np.where(w, uf, us))
            out[b] = team.scatter(parts, "command", ())
        info = BarrierInfo(min_sep.reshape(batch), active.reshape(batch), n_con.reshape(batch), factor.reshape(batch))
        if out is None:
            return u_in if u_in.shape == u.shape else np.array(u), info
        return out.reshape(batch + (width_u,)), info

    # -- one world ------------------------------------------------------------------------------
    def _range(self, speed):
        if self.range_m is not None:
            return self.range_m
        d, g = self.min_separation_m, self.gamma
        return (2.0 * speed + math.sqrt(4.0 * speed * speed + g * g * d * d)) / g

    def _pairs(self, P, R):
        """Pairs ``(i, j)``, ``i < j``, no farther apart than ``R``, and the smallest separation."""
        from scipy.spatial import cKDTree  # scipy imported when used: the CLI's parsers stay light

        n = P.shape[0]
        if n < 2:
            return np.zeros(0, np.intp), np.zeros(0, np.intp), math.inf
        if n <= _DENSE_PAIRS_MAX_ROBOTS:
            i, j = np.triu_indices(n, 1)
            dist = np.linalg.norm(P[i] - P[j], axis=-1)
            near = dist <= R
            return i[near], j[near], float(dist.min())
        tree = cKDTree(P)
        pairs = tree.query_pairs(R, output_type="ndarray")
        i, j = pairs[:, 0].astype(np.intp), pairs[:, 1].astype(np.intp)
        if i.size:  # the closest pair is among them
            dmin = float(np.sqrt(np.min(np.einsum("ij,ij->i", P[i] - P[j], P[i] - P[j]))))
        else:
            dmin = float(tree.query(P, k=2)[0][:, 1].min())
        return i, j, dmin

    def _world(self, P, V, planar):
        """``(min_separation, V_new, changed, (i, j), constraints)`` of one world (``(i, j)``: the
        pairs within range, whose components a limit factor must span); ``V_new`` None where
        no constraint binds."""
        n = P.shape[0]
        d2, gam = self.min_separation_m ** 2, self.gamma
        speed = float(np.sqrt(np.max(np.einsum("ij,ij->i", V, V)))) if n else 0.0
        R = self._range(speed)
        i, j, dmin = self._pairs(P, R)
        if i.size == 0:
            return dmin, None
        pij = P[i] - P[j]
        h = np.einsum("ij,ij->i", pij, pij) - d2  # the single-integrator barrier (Robotarium certificate)
        g = 2.0 * np.einsum("ij,ij->i", pij, V[i] - V[j]) + gam * h  # h_dot + gamma h >= 0 (Wang et al. 2017)
        bind = g < 0.0
        if not np.any(bind):
            return dmin, None
        tol = 1e-12 * gam * d2
        while True:
            W = self._solve(P, V, planar, i[bind], j[bind], pij[bind], g[bind], n)
            Vn = V + W
            gn = 2.0 * np.einsum("ij,ij->i", pij, Vn[i] - Vn[j]) + gam * h
            new = ~bind & (gn < -tol)
            if np.any(new):
                bind |= new
                continue
            if self.range_m is None:  # the solution may be faster than the nominal: widen the range
                Rn = self._range(float(np.sqrt(np.max(np.einsum("ij,ij->i", Vn, Vn)))))
                if Rn > R * (1.0 + 1e-12):
                    keys = i[bind] * n + j[bind]
                    R = Rn
                    i, j, _ = self._pairs(P, R)
                    pij = P[i] - P[j]
                    h = np.einsum("ij,ij->i", pij, pij) - d2
                    g = 2.0 * np.einsum("ij,ij->i", pij, V[i] - V[j]) + gam * h
                    gn = 2.0 * np.einsum("ij,ij->i", pij, Vn[i] - Vn[j]) + gam * h
                    old = np.isin(i * n + j, keys)
                    bind = old | (gn < -tol)
                    if np.any(bind & ~old):
                        continue
            break
        changed = np.any(W != 0.0, axis=-1)
        return dmin, Vn, changed, (i, j), int(np.count_nonzero(bind))

    def _solve(self, P, V, planar, i, j, pij, g, n):
        """Velocity changes ``W`` (``(N, 3)``) of the programme over the pairs ``(i, j)``: one
        least-distance problem per connected component (Lawson and Hanson 1974, ch. 23)."""
        from scipy.optimize import nnls  # scipy imported when used: the CLI's parsers stay light

        W = np.zeros((n, 3))
        pair_comp = components(n, i, j)[i]
        order = np.argsort(pair_comp, kind="stable")
        bounds = np.flatnonzero(np.diff(pair_comp[order])) + 1
        for rows in np.split(order, bounds):
            robots = np.unique(np.concatenate([i[rows], j[rows]]))
            local = np.searchsorted(robots, np.stack([i[rows], j[rows]]))
            m, k = robots.size, rows.size
            G = np.zeros((k, m, 3))
            ar = np.arange(k)
            G[ar, local[0]] = 2.0 * pij[rows]
            G[ar, local[1]] = -2.0 * pij[rows]
            G[:, planar[robots], 2] = 0.0  # a planar point's z velocity is no variable
            G = G.reshape(k, 3 * m)
            c = -g[rows]  # G w >= c  <=>  the pair constraints at v_nom + w
            # LDP min |w| s.t. G w >= c: NNLS min |E y - f|, E = [G^T; c^T], f = e_{n+1};
            # w = -r[:n] / r[n], r = E y - f (Lawson and Hanson 1974, ch. 23, Algorithm LDP)
            E = np.vstack([G.T, c[None, :]])
            f = np.zeros(3 * m + 1)
            f[-1] = 1.0
            y, _ = nnls(E, f, maxiter=50 * (3 * m + k + 1))
            r = E @ y - f
            if abs(r[-1]) < 1e-14:
                a, b = int(i[rows][0]), int(j[rows][0])
                raise DegenerateInputError(
                    f"SeparationBarrier: no velocities keep robots {a + 1} and {b + 1} (and their neighbours) apart "
                    f"(separation {float(np.linalg.norm(P[a] - P[b])):.3g} m, at least {self.min_separation_m:g} m "
                    "needed); separate the robots")
            W[robots] = (-r[:-1] / r[-1]).reshape(m, 3)
        return W


# -- the controller -----------------------------------------------------------------------------

def _flat(xp, a, lead, B):
    """``a`` (``(..., k)``) broadcast to the leading axes ``lead`` and flattened to ``(B, k)``."""
    if a.shape[:-1] != lead:
        a = xp.broadcast_to(a, lead + a.shape[-1:])
    return a if a.ndim == 2 and a.shape[0] == B else xp.reshape(a, (B, a.shape[-1]))


class SafeState(NamedTuple):
    """State of a :class:`SafeController`: the inner controller's and whether it has started
    (a tuple, so a pytree of arrays for :meth:`SafeController.tick` under ``jax.jit``).

    Attributes
    ----------
    inner : object
        The inner controller's state.
    started : bool or array of bool, shape (*batch)
        False before a world's first update (which refuses robots already too close).
    """

    inner: object = None
    started: object = False


#: Relative rounding of the robots' points a start may carry below the barrier's minimum
#: (a few ulps of the larger of their coordinates and the minimum).
_START_ROUNDING = 16 * np.finfo(float).eps


def start_floor(positions, min_separation_m: float):
    """The smallest separation a start may have under a barrier of ``min_separation_m``: the
    minimum less the rounding of the robots' points (a start exactly at the minimum, robots
    ``2 d_c`` apart with ``d = 2 d_c`` and their points built by trigonometry, is kept: ``h`` a
    few ulps below 0 asks them only not to close). ``positions`` ``(..., N, 3)`` m (NumPy or
    JAX); returns ``(..., 1)`` m, to compare with the separations ``(..., pairs)``."""
    xp = array_namespace(positions)
    scale = xp.max(xp.abs(positions), axis=(-2, -1))[..., None]
    return min_separation_m - _START_ROUNDING * xp.maximum(scale, min_separation_m)


@dataclass(frozen=True)
class SafeController(contract.Controller):
    """Any controller whose commands pass through a :class:`SeparationBarrier`.

    Parameters
    ----------
    inner : Controller
        The controller whose commands are filtered (its ``measured`` input must be the
        team's stacked state).
    barrier : SeparationBarrier
    team : Team, optional
        The robots (default: the inner controller's ``team`` field, as every quatform
        controller of a team has).

    Signals: the inner controller's, plus ``min_separation`` (m, the smallest distance
    between two robots' points as measured) and ``safety_active`` (1 where the filter
    changed the command, else 0).
    """

    inner: contract.Controller
    barrier: SeparationBarrier
    team: Team | None = field(default=None)

    def __post_init__(self):
        if not isinstance(self.inner, contract.Controller):
            raise InvalidInputError(f"SafeController: inner must be a Controller, got {type(self.inner).__name__}")
        if not isinstance(self.barrier, SeparationBarrier):
            raise InvalidInputError(f"SafeController: barrier must be a SeparationBarrier, got "
                                    f"{type(self.barrier).__name__}")
        if self.team is None:  # the inner controller's configured team (a dataclass field)
            names = {f.name for f in dataclasses.fields(self.inner)} if dataclasses.is_dataclass(self.inner) else ()
            if "team" not in names:
                raise InvalidInputError(f"SafeController: give team= (the robots of the {type(self.inner).__name__})")
            object.__setattr__(self, "team", self.inner.team)
        if not isinstance(self.team, Team):
            raise InvalidInputError(f"SafeController: team must be a Team, got {type(self.team).__name__}")
        self.barrier._plan(self.team)  # refuses a model without a point-velocity map
        if len(self.inner.command_names) != self.team.n:
            raise InvalidInputError(f"SafeController: the inner controller commands {len(self.inner.command_names)} "
                                    f"values, the team takes {self.team.n}")

    @property
    def name(self) -> str:
        return self.inner.name

    @property
    def command_names(self) -> tuple[str, ...]:
        return self.inner.command_names

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """The inner controller's signals, ``min_separation`` and ``safety_active``."""
        return {**self.inner.signal_columns(), "min_separation": ("min_separation",),
                "safety_active": ("safety_active",)}

    @property
    def pure(self) -> bool:
        """The inner controller's (the barrier's array algorithm is pure)."""
        return self.inner.pure

    @property
    def failure_reasons(self):
        """The inner controller's, and :data:`~quatform.control.barrier.HOST`."""
        return {**self.inner.failure_reasons,
                HOST: "the separation barrier's programme is not solved by the array algorithm, or the robots "
                      "start closer than its minimum (the world runs on the host)"}

    def init(self, batch: tuple = ()):
        """:class:`SafeState` of the inner controller's initial state, no world started."""
        return SafeState(self.inner.init(batch), np.zeros(batch, dtype=bool))

    def reference_arrays(self, reference):
        """The inner controller's."""
        return self.inner.reference_arrays(reference)

    def tick(self, state, measured, reference, t) -> contract.Tick:
        """The inner controller's tick with its commands through the separation barrier.

        One filter per namespace, chosen by the arrays, not by the data: under ``jax.jit``
        (any namespace but NumPy) the barrier's array algorithm
        (:func:`~quatform.control.barrier.barrier_filter`, fixed size, branch-free), with code
        :data:`~quatform.control.barrier.HOST` where it does not solve a binding programme (a
        team it does not run, :func:`~quatform.control.barrier.solves`; more binding pairs than
        its candidates; no convergence ...): the driver reruns that world on the host. On
        NumPy the exact host solver (:meth:`SeparationBarrier.filter`) for every live world:
        the array algorithm's answer, where it has one, is that solver's to rounding
        (``docs/derivations.md``, "The separation barrier on JAX"), and on the host the exact
        solver is the cheaper of the two (its pairs from a k-d tree, nothing solved where no
        pair binds), so NumPy's numbers are exactly today's. ``HOST`` also marks a world whose
        robots start closer than the barrier's minimum (:func:`start_floor`; :meth:`update`
        raises its one-line error), and on NumPy a world the host solver refuses.
        """
        return self.shield(state, measured, self.inner.tick(state.inner, measured, reference, t))

    def shield(self, state, measured, nominal: contract.Tick) -> contract.Tick:
        """The tick of the nominal tick ``nominal`` (the inner controller's, its commands
        ``(*batch, n_u)`` possibly changed by a caller, e.g. a learning env's residual) through
        the separation barrier: :meth:`tick`'s second half, so that a caller that changes the
        nominal commands has them filtered too."""
        u, signals, code = self._filter(measured, nominal.u, nominal.code, state.started)
        xp = array_namespace(u)
        return contract.Tick(SafeState(nominal.state, xp.ones(code.shape, dtype=bool)), u,
                             {**nominal.signals, **signals}, code)

    def _filter(self, measured, u, code, started, raise_host=False):
        """``(u_safe, {"min_separation", "safety_active"}, code)`` of the nominal commands ``u``
        at the measured team state, for the worlds whose ``code`` is 0 (see :meth:`tick`):
        :meth:`_filter_host` on NumPy, :meth:`_filter_arrays` on another namespace."""
        xp = array_namespace(u)
        lead = np.broadcast_shapes(tuple(code.shape), tuple(measured.shape[:-1]), tuple(u.shape[:-1]))
        B = math.prod(lead)
        m, u = _flat(xp, measured, lead, B), _flat(xp, u, lead, B)
        code = xp.reshape(xp.broadcast_to(code, lead), (B,))
        started = xp.reshape(xp.broadcast_to(xp.asarray(started, dtype=bool), lead), (B,))
        if xp is np:
            u_safe, min_sep, active, code = self._filter_host(m, u, code, started, raise_host)
        else:
            u_safe, min_sep, active, code = self._filter_arrays(m, u, code, started)
        signals = {"min_separation": xp.reshape(min_sep, lead + (1,)),
                   "safety_active": xp.reshape(active.astype(u.dtype), lead + (1,))}
        return xp.reshape(u_safe, lead + u.shape[-1:]), signals, xp.reshape(code, lead)

    def _filter_arrays(self, m, u, code, started):
        """The barrier's array algorithm (:func:`~quatform.control.barrier.barrier_filter`) on
        ``(B, ...)`` arrays of any namespace: ``(u_safe, min_separation, active, code)``, code
        :data:`~quatform.control.barrier.HOST` where a live world's binding programme is not
        solved (a team the algorithm does not run: where any pair binds) or its robots start
        closer than the minimum. The measured states are the robots' points (the teams the
        jax backend runs)."""
        xp = array_namespace(u)
        team, L, barrier = self.team, self.team.layout, self.barrier
        B = code.shape[0]
        live = code == 0
        if solves(team):
            u_safe, sep, active, solved = _barrier.barrier_filter(barrier, team, m, u, live)
        else:  # the array algorithm runs no such team: a world where a pair binds is the host's
            P = team_positions(L, m)
            V = team_positions(L, u) if team.passthrough else point_velocities(barrier, team, m, u)
            with np.errstate(invalid="ignore", over="ignore"):
                _, sep, _, _, _, active = pair_constraints(barrier, L, P, V)
            u_safe, solved = u, ~active
        if sep.shape[-1]:
            min_sep = xp.min(sep, axis=-1)
            with np.errstate(invalid="ignore"):
                floor = start_floor(team_positions(L, m), barrier.min_separation_m)
            start = ~started & xp.any(sep < floor, axis=-1)
        else:  # one robot: no pair
            min_sep = xp.full((B,), xp.inf)
            start = xp.zeros((B,), dtype=bool)
        code = xp.where(start, HOST, xp.where(code > 0, code, xp.where(solved, 0, HOST)))
        return u_safe, min_sep, active, code

    def _filter_host(self, m, u, code, started, raise_host):
        """The exact host solver (:meth:`SeparationBarrier.filter`) on ``(B, ...)`` NumPy arrays
        for every live world: ``(u_safe, min_separation, active, code)``, code
        :data:`~quatform.control.barrier.HOST` where a world's robots start closer than the
        minimum or the solver refuses it (``raise_host``: its error is raised)."""
        team, layout, barrier = self.team, self.team.layout, self.barrier
        B = code.shape[0]
        start = np.zeros(B, dtype=bool)
        if not np.all(started) and layout.n > 1:
            p = team.point(m[~started])
            with np.errstate(invalid="ignore", over="ignore"):
                close = layout.separations(p) < start_floor(layout.positions(p), barrier.min_separation_m)
            start[~started] = np.any(close, axis=-1)
        host = (code == 0) & ~start
        if host.all():  # every world the host's (the common case): the solver's answer as it is
            try:
                u_safe, info = barrier.filter(team, m, u)
                return u_safe, info.min_separation, info.active, code
            except DegenerateInputError:
                if raise_host:
                    raise
        u_safe, min_sep = np.array(u), np.full(B, np.nan)
        active, solved = np.zeros(B, dtype=bool), np.zeros(B, dtype=bool)
        every = bool(np.all(host))
        if not np.any(host):
            return u_safe, min_sep, active, np.where(start, HOST, code)
        try:  # every live world at once, world by world where the solver refuses one
            worlds = slice(None) if every else np.flatnonzero(host)
            runs = [(worlds, *barrier.filter(team, m if every else m[worlds], u if every else u[worlds]))]
        except DegenerateInputError:
            if raise_host:
                raise
            runs = []
            for b in np.flatnonzero(host):
                try:
                    runs.append(([b], *barrier.filter(team, m[[b]], u[[b]])))
                except DegenerateInputError:
                    pass
        for worlds, ub, info in runs:
            u_safe[worlds], min_sep[worlds], active[worlds], solved[worlds] = ub, info.min_separation, info.active, True
        code = np.where(start, HOST, np.where(code > 0, code, np.where(solved, 0, HOST)))
        return u_safe, min_sep, active, code

    def update(self, t: float, measured, reference, state) -> contract.Step:
        """The inner controller's update with its commands filtered on ``measured``.

        The first update of a world refuses robots already closer than ``min_separation_m``
        (no command can make that safe), naming the pair and the separation. The filter is
        :meth:`tick`'s: the barrier's array algorithm, the exact host solver
        (:meth:`SeparationBarrier.filter`) for the worlds it does not solve (whose refusal,
        such as robots no velocity keeps apart, is raised).
        """
        if not isinstance(state, SafeState):
            raise InvalidInputError(f"SafeController.update: state must be a SafeState (from init), got "
                                    f"{type(state).__name__}")
        m = np.asarray(measured, dtype=float)
        if m.shape[-1:] != (self.team.n_state,):
            raise ShapeError(f"SafeController: measured must be the team's state, shape (..., {self.team.n_state}), "
                             f"got {m.shape}")
        started = np.asarray(state.started, dtype=bool)
        if not np.all(started):
            self._check_start(m, started)
        step = self.inner.update(t, measured, reference, state.inner)
        ok = np.zeros(np.broadcast_shapes(m.shape[:-1], np.shape(step.u)[:-1]), dtype=np.int64)
        u, signals, code = self._filter(m, np.asarray(step.u, dtype=float), ok, True, raise_host=True)
        if np.any(code > 0):  # not reached: the host solver raises where the array algorithm fails
            raise DegenerateInputError(f"SafeController: {self.failure_reasons[int(np.max(code))]}")
        return contract.Step(u, SafeState(step.state, np.ones(code.shape, dtype=bool)), {**step.signals, **signals})

    def _check_start(self, m, started=False):
        """Refuse robots closer than :func:`start_floor` (the minimum less their points' rounding)
        in the worlds not ``started``."""
        layout = self.team.layout
        p = self.team.point(m)
        sep = layout.separations(p)
        if sep.shape[-1] == 0:
            return
        d = self.barrier.min_separation_m
        close = (sep < start_floor(layout.positions(p), d)) & ~np.asarray(started, dtype=bool)[..., None]
        if np.any(close):
            at = np.argwhere(close)[0]
            a, b = (int(p[at[-1]]) for p in layout.pairs)
            where = f" in world {tuple(int(k) for k in at[:-1])}" if len(at) > 1 else ""
            raise DegenerateInputError(
                f"SafeController: robots {layout.display_names[a]} and {layout.display_names[b]} start "
                f"{float(sep[tuple(at)]):.6g} m apart{where}, closer than min_separation_m = {d:.6g} m; start them "
                "farther apart or lower the minimum")
