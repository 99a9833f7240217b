"""The team controller: any team description, its law groups and a team of N robots (control layer).

One control update (seed 000 Figs. 2, 6, 8 for N robots): the measured robot state ->
``formation.forward`` with the reference as hint -> the error and the commanded rate of
each of the description's law groups (:class:`~quatform.formations.team_chart.LawGroup`;
the laws of :mod:`.laws`, written once on components, here run on ``(..., M)`` arrays, one
call per group whatever the number of robots) -> ``formation.robot_rate`` (a directional
derivative, O(N), no matrix) -> the team's actuation and saturation. The object is
frozen and stateless, so it drives a simulation or real robots; wrap it in
:class:`~quatform.control.safety.SafeController` for the separation barrier.

:data:`TEAM_GAIN_KEYS` is the gain schema: the law and gain key each law-group role reads
(:func:`team_gain_sizes`: every key and how many numbers it takes); :func:`check_gain` is its
one check, which the controller and the team file reader both call. A team description says
its controller name and default gains (``Formation.controller``, ``Formation.gain_tables``);
:data:`TEAM_CONTROLLERS` follows the registered descriptions, and :func:`team_controller`
builds a controller by that name.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..algebra.angles import wrap_angle, wrap_entries
from ..algebra.kernels import array_namespace, hold
from ..algebra.validate import UNIT_TOLERANCE, as_array
from ..checks import MAX_NUMBER, short
from ..errors import DegenerateInputError, InvalidInputError, NonUnitError, ShapeError
from ..formations.base import Formation, check_magnitude
from ..registry import RegistryView
from ..robots import Team
from . import contract
from .base import FAILURE_REASONS, Reference, apart_robots, batch_shape, measured_codes
from .laws import dual_quaternion_feedback, proportional, quaternion_feedback

__all__ = ["TeamController", "TEAM_GAIN_KEYS", "TEAM_CONTROLLERS", "team_controller", "team_descriptions",
           "team_gain_sizes", "check_gain", "team_lyapunov"]

#: Law and gain key of each law-group role (``formations.team_chart.ROLE_WIDTHS``), and how
#: many gains the key takes (``None``: one per row of the group, or one for all).
TEAM_GAIN_KEYS = {
    "centroid": ("proportional", "k_x", 3),
    "shape": ("proportional", "k_d", 1),
    "separation": ("proportional", "k_d", 1),
    "attitude": ("quaternion", "k_w", 3),
    "orientation": ("quaternion", "k_w", 3),
    "pose": ("dual-quaternion", "k_dw", 3),
    "relative-pose": ("dual-quaternion-branch", "k_dw", 3),
    "position": ("proportional", "k_p", 3),
    "planar": ("proportional", "k_p", 3),
    "heading": ("proportional", "k_theta", 1),
    "variables": ("proportional", "k", None),
}


def team_gain_sizes() -> dict:
    """Every gain key of :data:`TEAM_GAIN_KEYS` and how many numbers a file gives it (3: three
    or one; 1: one), in the schema's order."""
    sizes = {}
    for _, key, n in TEAM_GAIN_KEYS.values():
        sizes.setdefault(key, n or 1)
    return sizes


def team_descriptions() -> dict:
    """The registered team descriptions that name a controller (``Formation.controller``), by
    that name, in ``controller_order``.

    A description names a controller in its own class body: a subclass that inherits its
    parent's ``controller`` (a preset, a user's variant) runs under the parent's controller,
    and names none of its own.

    Raises
    ------
    InvalidInputError
        Two descriptions set one controller name in their class bodies.
    """
    from ..formations import TEAM_FORMATIONS

    out = {}
    for c in sorted((c for c in TEAM_FORMATIONS.values() if vars(c).get("controller")),
                    key=lambda c: c.controller_order):
        if c.controller in out:
            raise InvalidInputError(
                f"team descriptions {out[c.controller].__name__} and {c.__name__} both set controller = "
                f"{c.controller!r}; give {c.__name__} its own controller name (or none, to run under its parent's)")
        out[c.controller] = c
    return out


#: The team description each controller name runs (``formations.TEAM_FORMATIONS`` keys),
#: read from the registered descriptions.
TEAM_CONTROLLERS = RegistryView(lambda: {name: c.key for name, c in team_descriptions().items()},
                                "TEAM_CONTROLLERS")


def check_gain(value, key: str, n, rows: int | None = None, *, where: str | None = None,
               place: str | None = None) -> np.ndarray:
    """The gain ``key`` of :data:`TEAM_GAIN_KEYS` checked, as a flat float array: one number,
    or a list of ``n`` (``n`` None: of ``rows``, one per row of the law group), each a finite
    positive number within :data:`quatform.checks.MAX_NUMBER` (seed 000 Tables 1-2). The one
    check of a gain: the controller's (``gains['k_x']`` in its errors) and a team file's
    (``where`` the file, ``place`` its table, e.g. ``[gains.quaternion]``, in its errors).

    Raises
    ------
    InvalidInputError
        One line naming the file, the table and the key (or the controller's gain), the value
        and what it must be.
    """
    said = (f"{where}: {place} {key}" if where is not None else f"team controller: gains[{key!r}]") + \
        f" = {short(value)}"
    count = n if n is not None else (rows or 1)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    many = isinstance(value, (list, tuple, np.ndarray))
    vals = (value.tolist() if isinstance(value, np.ndarray) else list(value)) if many else [value]
    if many and (count == 1 or np.ndim(value) != 1 or len(vals) != count):
        raise InvalidInputError(f"{said} must be one number" + (f" or a list of {count}" if count > 1 else ""))
    if any(isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)) for v in vals):
        raise InvalidInputError(f"{said} must be {'numbers' if many else 'a number'}: a positive gain in 1/s, "
                                "e.g. 2.0 (seed 000 Tables 1-2)")
    k = np.array(vals, dtype=float)
    if not np.all(np.isfinite(k)):
        raise InvalidInputError(f"{said} must be finite: a positive gain in 1/s, e.g. 2.0 (seed 000 Tables 1-2)")
    if np.any(np.abs(k) > MAX_NUMBER):
        raise InvalidInputError(f"{said} is beyond +-{MAX_NUMBER:g}; give a physical gain (1/s)")
    if not np.all(k > 0):
        raise InvalidInputError(f"{said} must be positive (seed 000 Tables 1-2)")
    return k


def _gain(gains: Mapping, key: str, n, rows: int, role: str) -> np.ndarray:
    if key not in gains:
        raise InvalidInputError(f"team controller: the {role} law needs gains[{key!r}]; given {sorted(gains)}")
    return check_gain(gains[key], key, n, rows)


@dataclass(frozen=True, eq=False)
class TeamController(contract.Controller):
    """A stateless controller of a team description and a team of robots.

    Parameters
    ----------
    formation : Formation
        A description with :attr:`law_groups` (the team descriptions of
        :data:`quatform.formations.TEAM_FORMATIONS`).
    gains : Mapping
        The gains its roles read (:data:`TEAM_GAIN_KEYS`): ``k_x`` (3, 1/s) on the centroid,
        ``k_d`` (1/s) on the shape, ``k_w`` (3, 1/s) on quaternion errors (seed 000 eq. (20)),
        ``k_dw`` (3, 1/s) on dual-quaternion errors (eq. (28)), ``k_p`` / ``k_theta`` on robot
        positions and yaws, ``k`` (one per variable or one for all) on plain variables.
    team : Team
        The robots, whose layout must be the formation's (default: the kinematic model of each
        point kind). The measured values are the robots' points, which must be their states
        for a team that actuates (a Pioneer offering ``xy_yaw``: its control point and heading).
    feedforward : bool
        Add the reference's rate (seed 000's ``+ c_dot_des``).
    name : str
        Name in files and logs.
    """

    formation: Formation = None
    gains: Mapping = field(default_factory=dict)
    team: Team = None
    feedforward: bool = True
    name: str = "team"

    def __post_init__(self):
        F = self.formation
        if not isinstance(F, Formation):
            raise InvalidInputError(f"TeamController needs a team description, got {type(F).__name__}")
        team = Team(tuple(_default_model(k) for k in F.layout.kinds)) if self.team is None else self.team
        if not isinstance(team, Team):
            raise InvalidInputError(f"TeamController: team must be a robots.Team, got {type(team).__name__}")
        if team.layout.kinds != F.layout.kinds:
            raise InvalidInputError(f"TeamController: the team's robots offer points {team.layout.kinds}, the "
                                    f"formation describes {F.layout.kinds}; build both from one layout")
        object.__setattr__(self, "team", team)
        if not isinstance(self.gains, Mapping):
            raise InvalidInputError(f"TeamController: gains must be a mapping of gain names to values (e.g. "
                                    f"{{'k_x': 2.0, 'k_d': 20.0, 'k_w': 20.0}}), got {type(self.gains).__name__}")
        object.__setattr__(self, "gains", dict(self.gains))
        F.check_gains(self.gains)
        covered = np.sort(np.concatenate([gr.index.ravel() for gr in F.law_groups]))
        if not np.array_equal(covered, np.arange(F.n_c)):
            raise InvalidInputError(f"{type(F).__name__}.law_groups must cover its {F.n_c} variables once each")
        plan = []
        for gr in F.law_groups:
            law, key, n = TEAM_GAIN_KEYS[gr.role]
            k = _gain(self.gains, key, n, len(gr.index), gr.role)
            if gr.role == "planar":
                k = k[:2] if k.size == 3 else k
            elif law != "proportional":
                k = np.broadcast_to(k, (3,)).copy()  # the three gains of K's diagonal (eqs. (20), (28))
            elif law == "proportional" and n is None and k.size > 1:
                k = k[:, None]  # one gain per row
            plan.append((gr.role, law, gr.index, k))
        object.__setattr__(self, "_plan", tuple(plan))
        # each group read as a view where its variables are contiguous (no gather, no scatter);
        # the (dual) quaternion groups of one law and gains in one law call, their rows stacked
        merged = {}
        for _, law, idx, k in plan:
            if law != "proportional":
                merged.setdefault((law, tuple(k.tolist())), []).append(_block(idx))
        object.__setattr__(self, "_blocks", tuple((law, kk, tuple(blks)) for (law, kk), blks in merged.items()))
        object.__setattr__(self, "_linear", tuple((_block(idx), k) for _, law, idx, k in plan if law == "proportional"))

    # -- contract ---------------------------------------------------------------------------
    @property
    def command_names(self) -> tuple[str, ...]:
        return tuple(self.team.command_columns)

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        names = self.formation.names
        return {"cluster": names, "error": names, "raw_finite": ("raw_finite",)}

    pure = True
    failure_reasons = FAILURE_REASONS

    def update(self, t: float, measured, reference: Reference, state=None) -> contract.Step:
        """One control update: ``Step(u, None, {"cluster", "error", "raw_finite"})``.

        The host's checks (one-line errors), :meth:`reference_arrays` and :meth:`tick`; where
        the tick refuses a world (robots on each other), the checked forward kinematics raise
        its one-line error.

        Parameters
        ----------
        t : float
            Time, s (unused by the seed's laws).
        measured : array_like, shape (..., n_r)
            The robots' points (``team.point`` of their states).
        reference : Reference
            Desired cluster state and rate ``(..., n_c)``; ``robots`` (optional) the desired
            robot state whose yaws the measured ones are wound to.
        """
        F = self.formation
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        r = check_magnitude(as_array(measured, "measured robot state", F.n_r), "measured robot state")
        ref = self.reference_arrays(reference)
        c_des, c_dot = ref["c"], ref["c_dot"]
        try:
            batch_shape(r, c_des, c_dot)
        except ValueError:
            raise ShapeError(f"batch shapes differ: measured {r.shape}, reference.c {c_des.shape}, reference.c_dot "
                             f"{c_dot.shape}; give one reference per formation or one for all") from None
        out = self.tick(state, r, ref, t)
        if out.code.any():  # codes are >= 0  # the checked forward kinematics name the robots
            F.forward(F.align(r, ref["robots"]) if "robots" in ref else r, near_c=c_des)
            raise DegenerateInputError(f"{self.name} controller: {self.failure_reasons[int(np.max(out.code))]}")
        return contract.Step(out.u, None, dict(out.signals))

    def reference_arrays(self, reference):
        """``{"c", "c_dot"[, "robots"]}``: the reference's arrays, checked on the host (finite,
        within the magnitude limit, its (dual) quaternion groups unit: :attr:`checks`)."""
        F = self.formation
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        c_des = check_magnitude(as_array(reference.c, "reference.c", F.n_c), "reference.c")
        out = {"c": c_des, "c_dot": check_magnitude(as_array(reference.c_dot, "reference.c_dot", F.n_c),
                                                    "reference.c_dot")}
        if reference.robots is not None:
            out["robots"] = check_magnitude(as_array(reference.robots, "reference.robots", F.n_r), "reference.robots")
        self._check_reference(c_des)
        return out

    def tick(self, state, measured, reference, t) -> contract.Tick:
        """One pure control tick on any array namespace (seed 000 Figs. 2, 6, 8): the measured
        robots ``(..., n_r)`` wound onto ``reference["robots"]`` (when given), :meth:`chain`,
        the team's actuation (of a fresh memory), a non-finite command stopping its robot's
        group (``raw_finite`` 0), the saturation.

        ``code`` (:data:`~quatform.control.base.FAILURE_REASONS`): 1 where the measured state
        is not finite or beyond 1e150, 2 where two robots are closer than
        :data:`~quatform.formations.base.MIN_SEPARATION_M`; such a world's chain runs on
        :func:`~quatform.control.base.apart_robots` instead (its outputs are discarded).
        """
        F, team = self.formation, self.team
        xp = array_namespace(measured)
        c_des, c_dot = reference["c"], reference["c_dot"]
        lead = batch_shape(measured, c_des, c_dot)
        r = F.align(measured, reference["robots"]) if "robots" in reference else measured
        code = measured_codes(team.layout, measured, r)
        code = xp.broadcast_to(code, lead) if code.shape != lead else code
        r = hold(_lead(xp, xp.where(code[..., None] > 0, self._apart, r), lead))

        def stage(a):  # an array materialised once (hold; NumPy: itself)
            return hold(_lead(xp, a, lead))
        c, err, r_dot = (_lead(xp, v, lead) for v in self.chain(r, c_des, c_dot, stage=stage))
        r_dot = hold(r_dot)
        u = r_dot if team.passthrough else team.actuate(r, r_dot, t, team.initial_memory(lead))[0]
        finite = xp.all(xp.isfinite(u), axis=-1, keepdims=True)
        u = hold(team.saturate(xp.where(finite, u, 0.0)))
        return contract.Tick(None, u, {"cluster": c, "error": err, "raw_finite": finite.astype(u.dtype)}, code)

    @functools.cached_property
    def _apart(self):
        return apart_robots(self.formation.layout)

    def chain(self, r, c_des, c_dot_des, stage=None):
        """The control chain without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``, where no value can be tested): ``(c, err, r_dot)`` for the measured robots
        ``r`` (``(..., n_r)``, wound as :meth:`update` winds them) and the reference
        ``c_des``, ``c_dot_des`` (``(..., n_c)``), as :meth:`update` computes them (the same
        floats on NumPy), before the actuation and the saturation.

        As :meth:`quatform.control.cluster.ClusterController.chain`: the caller has run the
        reference checks (:attr:`checks`) and marks the worlds whose robots coincide or whose
        state is not finite, which :meth:`update` refuses. ``stage`` (optional) maps an array
        to an equal one (the jax loop computes it once there, ``algebra.kernels.hold``); it is
        applied to the cluster state and to the commanded cluster rate.
        """
        F = self.formation
        xp = array_namespace(r)
        c = F.forward_arrays(r, c_des)
        if stage is not None:
            c = stage(c)
        err = c - c_des
        if len(self._angles):  # the angles wrapped, the rest as it is (the floats of the in-place wrap)
            err = wrap_entries(err, self._angles)
        ff = 1.0 if self.feedforward else 0.0
        shape = np.broadcast_shapes(c.shape, c_dot_des.shape)
        rate_perm, keep, err_perm = self._chain_index
        errs, rates = [], []
        for blk, k in self._linear:
            v = proportional(_get(err, blk), _get(c_dot_des, blk), k, ff)
            rates.append(v.reshape(v.shape[:-2] + (-1,)))
        for law, kk, blks in self._blocks:  # eqs. (20), (28) on every row of one law at once
            comps = []
            for g in (_rows(c, blks), _rows(c_des, blks), _rows(c_dot_des, blks)):
                comps.append(tuple(g[..., j] for j in range(g.shape[-1])))
            if law == "quaternion":
                qe, qd = quaternion_feedback(*comps, kk, ff)
            else:
                qe, qd = dual_quaternion_feedback(*comps, kk, ff, signed_rotation=law == "dual-quaternion")
            q_err, q_rate = (xp.stack(xp.broadcast_arrays(*v), axis=-1) for v in (qe, qd))
            i = 0
            for b in blks:
                m = b.shape[0] if isinstance(b, np.ndarray) else b[1]
                errs.append(q_err[..., i:i + m, :].reshape(q_err.shape[:-2] + (-1,)))
                rates.append(q_rate[..., i:i + m, :].reshape(q_rate.shape[:-2] + (-1,)))
                i += m
        rate = _scatter(xp, rate_perm, rates, shape)
        if errs:  # the (dual) quaternion groups' errors replace c - c_des there (qe = q_des* q)
            err = _scatter(xp, err_perm, [err[..., keep]] + errs, np.broadcast_shapes(err.shape, shape))
        if stage is not None:
            rate = stage(rate)
        return c, err, F.robot_rate_arrays(c, rate)

    @functools.cached_property
    def _chain_index(self):
        """``(rate_perm, keep, err_perm)`` of :meth:`chain`: the gathers that put the groups'
        rates (proportional groups first, then each law's groups) and errors (the variables
        ``keep`` of ``c - c_des``, then the (dual) quaternion groups') in variable order
        (None: already in order)."""
        order = [_flat(blk) for blk, _ in self._linear]
        e_idx = [_flat(b) for _, _, blks in self._blocks for b in blks]
        keep = np.setdiff1d(np.arange(self.formation.n_c), np.concatenate(e_idx)) if e_idx else None
        return (_order(np.concatenate(order + e_idx)), keep,
                _order(np.concatenate([keep] + e_idx)) if e_idx else None)

    @property
    def checks(self) -> tuple:
        """What :meth:`update` checks of the reference every tick, as callables of the desired
        cluster state's components (:attr:`quatform.control.cluster.ClusterController.checks`):
        its (dual) quaternion groups are unit."""
        return (self._check_reference,)

    def _check_reference(self, comps):
        c_des = np.stack(np.broadcast_arrays(*comps), axis=-1) if isinstance(comps, tuple) else np.asarray(comps)
        for law, _, blks in self._blocks:
            self._check_units(_rows(c_des, blks), blks, law != "quaternion")

    @functools.cached_property
    def _angles(self) -> np.ndarray:
        """Indices of the description's angle variables (their errors wrapped to [-pi, pi))."""
        return np.array([i for i, v in enumerate(self.formation.variables) if v.kind == "angle"], dtype=np.intp)

    def _check_units(self, q, blks, dual):
        """Raise NonUnitError if a reference row ``q`` (``(..., M, 4 or 8)``, the rows of the
        groups ``blks``) is not a unit (dual) quaternion."""
        p = q[..., :4]
        n = np.sqrt(np.einsum("...i,...i->...", p, p))
        bad = np.abs(n - 1.0) > UNIT_TOLERANCE
        if dual:
            bad |= np.abs(np.einsum("...i,...i->...", p, q[..., 4:])) > UNIT_TOLERANCE
        if bad.any():
            idx = np.concatenate([b if isinstance(b, np.ndarray) else np.arange(b[0], b[0] + b[1] * b[2]).reshape(b[1:])
                                  for b in blks])
            names = self.formation.names
            row = int(np.argwhere(bad.reshape(-1, bad.shape[-1]))[0][-1])
            raise NonUnitError(f"reference {names[idx[row, 0]][:-2]} is not a unit {'dual ' if dual else ''}"
                               f"quaternion (norm {float(n.reshape(-1, n.shape[-1])[:, row].max()):.9g}); build "
                               "references with formation.from_chart or normalise them")


def _lead(xp, a, lead):
    """``a`` (``(..., k)``) with the leading axes ``lead`` (as it is when it has them)."""
    return a if a.shape[:-1] == lead else xp.broadcast_to(a, lead + a.shape[-1:])


def _block(idx):
    """A group's index as ``(start, M, k)`` where its variables are contiguous, else the index."""
    M, k = idx.shape
    if np.array_equal(idx, idx[0, 0] + np.arange(M * k).reshape(M, k)):
        return (int(idx[0, 0]), M, k)
    return idx


def _get(a, blk):
    """``a``'s variables of a group as ``(..., M, k)`` (a view where they are contiguous)."""
    if isinstance(blk, np.ndarray):
        return a[..., blk]
    start, M, k = blk
    return a[..., start:start + M * k].reshape(a.shape[:-1] + (M, k))


def _flat(blk) -> np.ndarray:
    """A group's variable indices, flat in row order."""
    if isinstance(blk, np.ndarray):
        return blk.ravel()
    start, M, k = blk
    return np.arange(start, start + M * k)


def _order(order):
    """The gather that puts entries given in ``order`` (variable indices) in variable order;
    None where ``order`` is ``0 .. n - 1``."""
    return None if np.array_equal(order, np.arange(order.size)) else np.argsort(order, kind="stable")


def _scatter(xp, perm, parts, shape):
    """The ``shape`` array of ``parts`` (each ``(..., m)``, concatenated in order) gathered by
    ``perm`` (:func:`_order`; None: as they are); no arithmetic: the same floats."""
    lead = shape[:-1]
    flat = [v if v.shape[:-1] == lead else xp.broadcast_to(v, lead + v.shape[-1:]) for v in parts]
    a = xp.concatenate(flat, axis=-1) if len(flat) > 1 else flat[0]
    return a if perm is None else a[..., perm]


def _rows(a, blks):
    """The rows of several groups stacked, ``(..., sum M, k)``."""
    if len(blks) == 1:
        return _get(a, blks[0])
    parts = [_get(a, b) for b in blks]
    return array_namespace(a).concatenate(parts, axis=-2)


def _default_model(kind):
    """The kinematic model of a point kind: a 4-DOF holonomic robot, a planar holonomic robot,
    a free body; a position-only point has no default (its heading is someone else's)."""
    from ..robots import FreeBodyRobot, HolonomicRobot, PlanarHolonomicRobot

    models = {"xyz_yaw": HolonomicRobot, "xy_yaw": PlanarHolonomicRobot, "pose": FreeBodyRobot}
    if kind not in models:
        raise InvalidInputError(f"TeamController: give a robots.Team for robots of point kind {kind!r} "
                                f"(defaults exist for {', '.join(models)})")
    return models[kind]()


def team_lyapunov(controller: TeamController, c, c_des) -> np.ndarray:
    """Seed 000 eqs. (21) and (29) for a team: the sum over the law groups of
    ``1/2 |e|^2`` (proportional groups, angles wrapped), ``1 - qe_0^2 + |qe_vec|^2 = 2
    |qe_vec|^2`` (quaternion groups, eq. (21)) and ``1 - qe_p0^2 + |qe_p|^2 + |qe_d|^2``
    (dual-quaternion groups, eq. (29)). Shape ``(...)``."""
    from ..formations import pair_kernels as kern

    c, c_des = np.asarray(c, float), np.asarray(c_des, float)
    err = c - c_des
    idx_ang = controller._angles
    if len(idx_ang):
        err[..., idx_ang] = wrap_angle(err[..., idx_ang])
    V = np.zeros(np.broadcast_shapes(c.shape, c_des.shape)[:-1])
    for role, law, idx, _ in controller._plan:
        if law == "proportional":
            V = V + 0.5 * np.sum(err[..., idx] ** 2, axis=(-2, -1))
            continue
        a, b = (tuple(np.moveaxis(x[..., idx], -1, 0)) for x in (c, c_des))
        if law == "quaternion":
            qe = kern.qmul(*kern.qconj(b), *a)
            V = V + 0.5 * np.sum(1.0 - qe[0] ** 2 + qe[1] ** 2 + qe[2] ** 2 + qe[3] ** 2, axis=-1)
        else:
            qe = kern.dqmul(kern.dqconj(b), a)
            V = V + np.sum(1.0 - qe[0] ** 2 + sum(x ** 2 for x in qe[1:4]) + sum(x ** 2 for x in qe[5:8]), axis=-1)
    return V


def team_controller(name: str, team: Team, gains: Mapping, *, template=None, feedforward: bool = True,
                    **options) -> TeamController:
    """The seed-000 controller ``name`` (a :data:`TEAM_CONTROLLERS` key) for ``team``.

    Builds the team description whose ``controller`` is ``name`` (:func:`team_descriptions`) on
    the team's layout (with ``template`` and ``options``) and a :class:`TeamController`.
    """
    from ..checks import nearest

    if name not in TEAM_CONTROLLERS:
        raise InvalidInputError(f"unknown team controller {name!r}{nearest(name, TEAM_CONTROLLERS)}; choose one of "
                                f"{', '.join(TEAM_CONTROLLERS)}")
    if not isinstance(team, Team):
        raise InvalidInputError(f"team_controller: team must be a robots.Team (e.g. Team.uniform(HolonomicRobot(), 4)), "
                                f"got {type(team).__name__}")
    cls = team_descriptions()[name]
    F = cls(layout=team.layout, template=template, **options)
    return TeamController(F, gains, team, feedforward, name)
