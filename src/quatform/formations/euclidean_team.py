"""The minimal Euclidean team description: the Santa Clara cluster space for N robots (formations layer).

The baseline whose singular poses the quaternion team descriptions remove. It
follows the cluster-space definitions of Kitts & Mas 2009 ("Cluster space specification and
control of mobile multirobot systems", IEEE/ASME Trans. Mechatronics 14(2): centroid,
cluster heading, the three-robot shape ``p, q, beta`` measured at robot 1, robot headings
relative to the cluster's) and of seed 000 §2 (Mas & Kitts 2017, eqs. (1)-(8): the pair in
space, yaw and pitch of the robot-2-to-robot-1 segment), for N robots:

* ``x_c, y_c, z_c`` (m): the centroid, eqs. (1)-(3) for N robots;
* ``beta_c, gamma_c`` (rad): yaw and pitch of the unit segment ``u`` from robot 2 to robot 1,
  eqs. (4)-(5), ``u = (-sin b cos g, cos b cos g, sin g)``: the formation's y axis (Kitts &
  Mas's heading axis);
* ``alpha_c`` (rad, N >= 3 in space): the roll about ``u`` that puts robot 3 in the
  formation's x-y plane, on its +x side. The formation frame is ``R = Rz(beta_c)
  Rx(gamma_c) Ry(alpha_c)`` (a z-x-y Euler sequence: singular at ``gamma_c = +-pi/2``);
* ``d_c`` (m): half the robot 1-2 distance, eq. (6) as the seed's text defines it;
* for robot 3 (``k = 3``): ``rho_3`` (m), its distance from robot 1 (Kitts & Mas's ``q``),
  and ``psi_3`` (rad), the angle at robot 1 from the side 1-2 to the side 1-3 (Kitts &
  Mas's ``beta``; in space in ``[0, pi]``, in the plane signed in ``(-pi, pi]``);
* for each further robot ``k >= 4``: ``rho_k`` (m, distance from robot 1), ``psi_k`` (rad,
  azimuth about the formation's z axis from the 1-to-2 direction ``-y``, towards ``+x``)
  and ``chi_k`` (rad, elevation towards ``+z``): robot ``k`` sits at ``p_1 + R rho_k (cos chi
  sin psi, -cos chi cos psi, sin chi)``;
* ``phi_i = theta_i - beta_c`` (rad) for every robot with a yaw, eqs. (7)-(8).

A planar team (every robot ``xy_yaw``) keeps the planar subset (Kitts & Mas's planar
clusters): ``x_c, y_c, beta_c, d_c``, ``rho_k, psi_k`` (``k >= 3``) and the ``phi_i``. With
two 4-DOF robots the variables are seed 000's, in its order; :class:`EuclideanPair`, seed
000's minimal baseline, is that team with the pair chart.

The chart is minimal (as many variables as the robots' DOF) and therefore singular:
``gamma_c = +-pi/2`` (``beta_c`` undefined, seed 000 §2), robots 1, 2, 3 collinear (roll
undefined), a spoke ``k >= 4`` along the formation's z axis (its azimuth undefined) and, as
a physical limit, coincident robots. Its ``special_sets`` list them;
``docs/derivations.md`` ("The Euclidean team baseline") derives the maps.
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra.kernels import array_namespace, as_floats, dot_last
from ..algebra.validate import as_array
from ..errors import DegenerateInputError, InvalidInputError
from . import geometry as g
from . import special_sets as sp
from .base import MIN_SEPARATION_M, Formation, Preset, Variable
from .layout import RobotLayout
from .special_sets import SpecialSet
from .team_chart import (
    LawGroup,
    TeamChart,
    check_template,
    pair_chart,
    team_compose,
    team_layout,
    team_positions,
)

__all__ = ["COLLINEAR_TOL", "POLE_TOL", "VERTICAL_TOL", "EUCLIDEAN_VARIABLES", "EuclideanTeam", "EuclideanPair",
           "segment_direction"]

#: Seed 000's Euclidean variables of a pair (§2, eqs. (1)-(8)): the cluster state of two
#: ``xyz_yaw`` robots and the pair chart of every description of them.
EUCLIDEAN_VARIABLES = (
    Variable("x_c", "m", "position"),
    Variable("y_c", "m", "position"),
    Variable("z_c", "m", "position"),
    Variable("beta_c", "rad", "angle"),
    Variable("gamma_c", "rad", "angle"),
    Variable("d_c", "m", "length"),
    Variable("phi_1", "rad", "angle"),
    Variable("phi_2", "rad", "angle"),
)

#: Below this ratio of the horizontal to the full robot 1-2 distance ``beta_c`` is taken as
#: undefined (the segment vertical).
VERTICAL_TOL = 1e-12
#: The pair chart's angles that wind by turns (``beta_c``, ``phi_1``, ``phi_2``).
_PAIR_WOUND = np.array([i for i, v in enumerate(EUCLIDEAN_VARIABLES) if v.name in ("beta_c", "phi_1", "phi_2")])

#: Below this ratio of robot 3's distance from the 1-2 line to its distance from robot 1 the
#: roll ``alpha_c`` is taken as undefined (robots 1, 2, 3 collinear).
COLLINEAR_TOL = 1e-12
#: Below this ratio of a spoke's distance from the formation's z axis to its length its
#: azimuth ``psi_k`` is taken as undefined (the spoke at a pole).
POLE_TOL = 1e-12

_SPATIAL = frozenset({"xyz_yaw", "xyz"})
_EZ = np.array([0.0, 0.0, 1.0])


def _dot(a, b):
    return dot_last(a, b)


def _set(a, idx, v):
    """``a`` with ``a[idx] = v``: in place for NumPy (as written), a functional update on
    another namespace (JAX's ``a.at[idx].set(v)``); the same entries either way."""
    if isinstance(a, np.ndarray):
        a[idx] = v
        return a
    return a.at[idx].set(v)


def segment_direction(beta, gamma):
    """Unit vector from robot 2 to robot 1 for cluster yaw ``beta`` and pitch ``gamma``.

    Inverse of seed 000 eqs. (4)-(5): ``(-sin b cos g, cos b cos g, sin g)``. Shape ``(..., 3)``.
    """
    xp = array_namespace(beta)
    cb, sb, cg, sg = xp.cos(beta), xp.sin(beta), xp.cos(gamma), xp.sin(gamma)
    return xp.stack([-sb * cg, cb * cg, sg], axis=-1)


def _pair_inverse_jacobian(c):
    """The dense derivative of the inverse of seed 000 eqs. (1)-(8) at the pair's cluster
    states ``c`` (``(..., 8)``, any array namespace), ``(..., 8, 8)``, in closed form:
    ``p1,2 = x_c +- d_c u`` with ``u`` the unit segment of eqs. (4)-(5) and ``u_beta``,
    ``u_gamma`` its partials, ``theta_i = beta_c + phi_i`` (eqs. (7)-(8)). The cluster-space
    controller of seed 000 Fig. 2 applies this matrix every step. Rank 7 at a vertical
    segment."""
    xp = array_namespace(c)
    cb, sb, cg, sg = xp.cos(c[..., 3]), xp.sin(c[..., 3]), xp.cos(c[..., 4]), xp.sin(c[..., 4])
    u = (-sb * cg, cb * cg, sg)
    d = c[..., 5]
    zero = xp.zeros_like(d)
    one = zero + 1.0
    u_b = (-cb * cg, -sb * cg, zero)
    u_g = (sb * sg, -cb * sg, cg)
    entries = []
    for s in (1.0, -1.0):  # p1, p2 = x_c +- d_c u
        sd = s * d
        for i in range(3):
            entries += [one if i == j else zero for j in range(3)] + [sd * u_b[i], sd * u_g[i], s * u[i], zero, zero]
        # theta_1 = beta_c + phi_1, theta_2 = beta_c + phi_2
        entries += [zero, zero, zero, one, zero, zero] + ([one, zero] if s > 0 else [zero, one])
    return xp.reshape(xp.stack(entries, axis=-1), d.shape + (8, 8))


def _spoke_direction(psi, chi):
    """Unit spoke of azimuth ``psi`` and elevation ``chi`` in the formation frame, ``(..., 3)``:
    ``(cos chi sin psi, -cos chi cos psi, sin chi)`` (``psi = 0``: from robot 1 towards robot 2)."""
    xp = array_namespace(psi)
    cc = xp.cos(chi)
    return xp.stack([cc * xp.sin(psi), -cc * xp.cos(psi), xp.sin(chi)], axis=-1)


def _frame(beta, gamma, alpha):
    """``(x0, u, z0, x_f, z_f)`` of ``R = Rz(beta) Rx(gamma) Ry(alpha)``: ``x0``, ``z0`` the frame
    before the roll (``x0`` horizontal), ``u`` the common y axis (seed 000 eqs. (4)-(5)
    inverted), ``x_f``, ``z_f`` the rolled axes. Each ``(..., 3)``."""
    xp = array_namespace(beta)
    cb, sb, cg, sg = xp.cos(beta), xp.sin(beta), xp.cos(gamma), xp.sin(gamma)
    zero = xp.zeros(np.shape(cb))
    x0 = xp.stack([cb, sb, zero], axis=-1)
    u = xp.stack([-sb * cg, cb * cg, sg], axis=-1)
    z0 = xp.stack([sb * sg, -cb * sg, cg], axis=-1)
    ca, sa = xp.cos(alpha)[..., None], xp.sin(alpha)[..., None]
    return x0, u, z0, ca * x0 - sa * z0, sa * x0 + ca * z0


def _frame_order(template, n, planar):
    """The robots in the chart's order: the layout's, except that in space the first robot of
    ``template`` off the line of its robots 1 and 2 plays robot 3 (a grid's first row is a line:
    the roll from robot 3 would be undefined from the start). A template whose robots are all
    on one line keeps the layout's order (its chart is singular: the formation is a line)."""
    order = np.arange(n)
    if template is None or planar or n < 4:
        return order
    t = np.asarray(template, dtype=float)
    u = t[1] - t[0]
    w = t[2:] - t[0]
    off = np.linalg.norm(np.cross(w, u), axis=-1) / max(float(np.linalg.norm(u)), 1e-300)
    size = max(float(np.max(np.linalg.norm(t - t.mean(axis=0), axis=-1))), 1e-300)
    if off[0] > 1e-6 * size:
        return order
    k = np.flatnonzero(off > 1e-6 * size)
    if not len(k):
        return order
    k = int(k[0]) + 2
    return np.concatenate([[0, 1, k], np.delete(np.arange(2, n), k - 2)])


class EuclideanTeam(Formation):
    """Minimal Euclidean cluster space of N robots (module docstring; Kitts & Mas 2009, seed 000 §2).

    Parameters
    ----------
    n : int, optional
        Number of 4-DOF robots (``xyz_yaw``).
    layout : RobotLayout, optional
        Instead of ``n``: robots of kinds ``xyz_yaw`` and ``xyz`` (a spatial team), all
        ``xy_yaw`` (a planar team) or a spatial team with one ``xy_yaw`` ground robot (its
        ``z = 0`` fixes ``z_c``, which leaves the chart: seed 001's UGV under UAVs).
    template : array_like, shape (N, 3), optional
        A shape (m) that :meth:`to_chart` fits the team chart's attitude to when no
        ``near_e`` is given; without one the team chart is this description's own frame.
        In space, when its robots 1, 2, 3 are on one line (a grid's first row), the first
        robot off that line plays the chart's robot 3 (:attr:`order`).
    chart : {"team", "pair"}
        The operator's chart: the team chart (:class:`~.team_chart.TeamChart`) or, for two
        ``xyz_yaw`` robots, seed 000's Euclidean variables (:data:`EUCLIDEAN_VARIABLES`:
        the cluster state itself; :class:`EuclideanPair`).

    Raises
    ------
    InvalidInputError
        A ``pose`` robot, more than one planar robot mixed with spatial ones, or
        ``chart="pair"`` for a team that is not two ``xyz_yaw`` robots.
    """

    name = "euclidean-team"
    key = "euclidean-team"
    singularity_on_arrays = True  # Formation.singularity_measure_arrays: robot_rate_arrays of the unit vectors
    team = True
    #: ``--controller cluster-space``.
    controller = "cluster-space"
    controller_order = 2
    #: Seed 000 Tables 1-2, ``K_CS``: its position gains on the centroid, its angle gain
    #: (``beta_c``) on angles and yaws, its ``d_c`` gain on shape variables.
    gain_tables = {
        "table1": {"k_x": [1.0, 1.0, 1.0], "k": 10.0, "k_d": 5.0, "k_w": [10.0, 10.0, 10.0], "k_theta": 10.0,
                   "k_p": [1.0, 1.0, 1.0]},
        "table2": {"k_x": [0.06, 0.06, 0.03], "k": 0.02, "k_d": 0.03, "k_w": [0.02, 0.02, 0.02], "k_theta": 0.03,
                   "k_p": [0.06, 0.06, 0.03]},
    }

    @classmethod
    def examples(cls) -> dict:
        """The contract test's instances: a mix of point kinds."""
        return {cls.key: cls(layout=RobotLayout(("xyz_yaw", "xyz", "xyz_yaw", "xyz_yaw", "xyz"))),
                # a ground robot under spatial ones, robots 1-3 of the template on a line (robot 4 plays robot 3)
                "euclidean-team-ground": cls(layout=RobotLayout(("xy_yaw", "xyz_yaw", "xyz_yaw", "xyz", "xyz_yaw")),
                                             template=[[0, 0, 0], [1, 0, 1], [2, 0, 2], [0, 1, 1], [1, 1, 1]])}

    def __init__(self, n=None, *, layout=None, template=None, chart="team"):
        L = team_layout(n, layout, "EuclideanTeam")
        kinds = set(L.kinds)
        if "pose" in kinds:
            raise InvalidInputError(
                f"EuclideanTeam: robot {L.display_names[L.kinds.index('pose')]} is a 'pose' robot (6 DOF): a minimal "
                "Euclidean chart would need Euler angles per robot; use QuaternionTeam or DualQuaternionTeam for "
                "pose robots")
        ground = [i for i, k in enumerate(L.kinds) if k == "xy_yaw"]
        if ground and kinds != {"xy_yaw"} and len(ground) > 1:
            raise InvalidInputError(
                f"EuclideanTeam: the layout mixes {len(ground)} planar (xy_yaw) robots with spatial ones {L.kinds}: "
                "the minimal chart of a mix drops z_c for one ground robot only (each further one would need "
                "another variable solved from its z = 0); give one ground robot, or use QuaternionTeam or "
                "RobotSpaceTeam for this mix")
        self._pair_chart = pair_chart(chart, L, "EuclideanTeam")
        self.layout = L
        self.planar = kinds == {"xy_yaw"}
        self.template = None if template is None else check_template(template, L.n)
        #: the robots in the chart's order: its robots 1, 2, 3 are ``order[0], order[1], order[2]``
        self.order = _frame_order(self.template, L.n, self.planar)
        self._unorder = None if np.array_equal(self.order, np.arange(L.n)) else np.argsort(self.order)
        #: the ground robot of a mixed team (chart order), whose z = 0 fixes z_c; None otherwise
        self._ground = None if self.planar or not ground else int(np.flatnonzero(self.order == ground[0])[0])
        self._nxc = 2 if self.planar or self._ground is not None else 3
        self.chart_kind = chart
        self.chart = TeamChart(L)
        #: seed 000's pair (two xyz_yaw robots): the inverse Jacobian in closed form
        self._seed = L.kinds == ("xyz_yaw", "xyz_yaw")
        self.chart_variables = EUCLIDEAN_VARIABLES if self._pair_chart else self.chart.variables
        self._build_index()

    def __repr__(self):
        return f"EuclideanTeam(layout={self.layout!r}, chart={self.chart_kind!r})"

    def _ordered(self, p):
        """Robot rows ``(..., N, 3)`` in the chart's order (:attr:`order`)."""
        return p if self._unorder is None else p[..., self.order, :]

    def _unordered(self, p):
        """Robot rows ``(..., N, 3)`` from the chart's order back to the layout's."""
        return p if self._unorder is None else p[..., self._unorder, :]

    # -- layout of the cluster state --------------------------------------------------------
    def _build_index(self):
        L, planar = self.layout, self.planar
        v = [Variable("x_c", "m", "position"), Variable("y_c", "m", "position")]
        if self._nxc == 3:
            v.append(Variable("z_c", "m", "position"))
        v.append(Variable("beta_c", "rad", "angle"))
        if not planar:
            v.append(Variable("gamma_c", "rad", "angle"))
        self._roll = not planar and L.n >= 3
        if self._roll:
            v.append(Variable("alpha_c", "rad", "angle"))
        self._i_beta = self._nxc
        self._i_gamma = None if planar else self._nxc + 1
        self._i_alpha = self._nxc + 2 if self._roll else None
        self._i_d = len(v)
        v.append(Variable("d_c", "m", "length"))
        rho, psi, chi = [], [], []
        for k in range(2, L.n):
            lab = L.labels[self.order[k]]
            rho.append(len(v))
            v.append(Variable(f"rho_{lab}", "m", "length"))
            psi.append(len(v))
            v.append(Variable(f"psi_{lab}", "rad", "angle"))
            if not planar and k >= 3:
                chi.append(len(v))
                v.append(Variable(f"chi_{lab}", "rad", "angle"))
        self._i_rho = np.array(rho, dtype=np.intp)
        self._i_psi = np.array(psi, dtype=np.intp)
        self._i_chi = np.array(chi, dtype=np.intp)
        self._yaw_robots = np.array([i for i, k in enumerate(L.kinds) if k != "xyz"], dtype=np.intp)
        self._i_phi = np.arange(len(v), len(v) + len(self._yaw_robots), dtype=np.intp)
        v += [Variable(f"phi_{L.labels[i]}", "rad", "angle") for i in self._yaw_robots]
        self.variables = tuple(v)
        owner = np.full(len(v), -1, dtype=np.intp)  # the robot whose spoke a variable is (-1: none)
        for idx in (self._i_rho, self._i_psi):
            owner[idx] = self.order[2:]
        owner[self._i_chi] = self.order[3:3 + len(self._i_chi)]
        self._spoke_owner = owner
        # the spokes whose azimuth wraps (all but robot 3's in space, every one in the plane)
        self._wrap_psi = np.arange(len(rho)) if planar else np.arange(1, len(rho))

    @functools.cached_property
    def law_groups(self) -> tuple[LawGroup, ...]:
        """One ``variables`` group: the proportional law on wrapped errors (seed 000 Fig. 2),
        gains ``k`` one per variable or one for all."""
        return (LawGroup("variables", np.arange(self.n_c, dtype=np.intp)[:, None]),)

    # -- checks -------------------------------------------------------------------------------
    def check_cluster_state(self, c, name="c"):
        """Finite ``(..., n_c)`` within the magnitude limit, ``d_c`` at least half and every
        ``rho_k`` at least :data:`~.base.MIN_SEPARATION_M` (else robots would coincide)."""
        c = super().check_cluster_state(c, name)
        if np.any(c[..., self._i_d] < 0.5 * MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"{name}: d_c must be at least {0.5 * MIN_SEPARATION_M:g} m (half the robot 1-2 distance), got "
                f"{float(np.min(c[..., self._i_d]))!r}; a smaller d_c puts robots 1 and 2 on each other")
        if len(self._i_rho):
            rho = c[..., self._i_rho]
            if np.any(rho < MIN_SEPARATION_M):
                k = int(np.argmin(np.min(rho.reshape(-1, rho.shape[-1]), axis=0)))
                raise DegenerateInputError(
                    f"{name}: {self.variables[self._i_rho[k]].name} = {float(np.min(rho)):.3g} m puts robot "
                    f"{self.layout.display_names[self.order[k + 2]]} on robot "
                    f"{self.layout.display_names[self.order[0]]} (at least {MIN_SEPARATION_M:g} m); give it a positive "
                    "distance from robot 1")
        return c

    # -- forward kinematics ---------------------------------------------------------------
    def _geometry(self, r, near_c=None, check=True):
        """Everything the forward map and its rate read: a dict of arrays (module docstring);
        ``check=False``: robots apart taken as given (any namespace)."""
        L = self.layout
        xp = array_namespace(r)
        p = self._ordered(team_positions(L, r))
        delta = p[..., 0, :] - p[..., 1, :]
        D = g.norm(delta)
        if check:
            self.check_apart(r, separations=D if L.n == 2 else None)
        dx, dy, dz = xp.moveaxis(delta, -1, 0)
        rho_h = xp.hypot(dx, dy)
        beta = xp.arctan2(-dx, dy)  # seed 000 eq. (4)
        if self.planar:
            gamma = xp.zeros_like(beta)
            vertical = xp.zeros(beta.shape, dtype=bool)
        else:
            gamma = xp.arctan2(dz, rho_h)  # eq. (5)
            vertical = rho_h <= VERTICAL_TOL * D
        if near_c is not None:  # beta_c held at the reference's where it is undefined
            nb = near_c[..., self._i_beta]
            beta = xp.where(vertical, nb, g.unwrap_near(beta, nb))
        G = {"p": p, "delta": delta, "D": D, "rho_h": rho_h, "beta": beta, "gamma": gamma, "vertical": vertical}
        if L.n < 3:  # no spokes: the frame is not read
            return G
        W = p[..., 2:, :] - p[..., :1, :]  # spokes from robot 1 (Kitts & Mas: p, q, beta at robot 1)
        x0, u, z0, _, _ = _frame(beta, gamma, xp.zeros_like(beta))
        if self._roll:
            w3 = W[..., 0, :]
            a, b = _dot(w3, x0), _dot(w3, z0)
            alpha = xp.arctan2(-b, a)  # robot 3 on the formation's +x side
            collinear = xp.hypot(a, b) <= COLLINEAR_TOL * g.norm(w3)
            if near_c is not None:
                na = near_c[..., self._i_alpha]
                alpha = xp.where(collinear, na, g.unwrap_near(alpha, na))
        else:
            alpha = xp.zeros_like(beta)
            collinear = xp.zeros(beta.shape, dtype=bool)
        x0, u, z0, xf, zf = _frame(beta, gamma, alpha)
        S = xp.stack([_dot(W, xf[..., None, :]), _dot(W, u[..., None, :]), _dot(W, zf[..., None, :])], axis=-1)
        if self._roll:
            S = _set(S, (..., 0, 2), 0.0)  # robot 3 lies in the formation's x-y plane by the roll's definition
        rho = g.norm(S)
        h = xp.hypot(S[..., 0], S[..., 1])
        psi = xp.arctan2(S[..., 0], -S[..., 1])
        chi = xp.arctan2(S[..., 2], h)
        pole = h <= POLE_TOL * rho
        if self._roll:
            pole = _set(pole, (..., 0), False)  # robot 3's azimuth is the collinear set, not a pole
        if self.planar:
            pole = _set(pole, Ellipsis, False)
        if near_c is not None and len(self._wrap_psi):
            npsi = near_c[..., self._i_psi]
            wp = self._wrap_psi
            psi = _set(psi, (..., wp), xp.where(pole[..., wp], npsi[..., wp], g.unwrap_near(psi[..., wp], npsi[..., wp])))
        G.update(x0=x0, u=u, z0=z0, xf=xf, zf=zf, alpha=alpha, collinear=collinear, S=S, rho=rho, h=h, psi=psi,
                 chi=chi, pole=pole)
        return G

    def forward(self, r, *, near_c=None):
        """Cluster state of the robots ``r`` (module docstring): centroid (seed 000 eqs. (1)-(3)),
        ``beta_c``, ``gamma_c`` (eqs. (4)-(5)), ``alpha_c``, ``d_c`` (eq. (6)), the spokes from
        robot 1 and ``phi_i`` (eqs. (7)-(8)).

        Parameters
        ----------
        r : array_like, shape (..., n_r)
        near_c : array_like, shape (..., n_c), optional
            Angles unwrapped to within pi of its; where an angle is undefined (``beta_c`` at a
            vertical segment, ``alpha_c`` with robots 1-3 collinear, ``psi_k`` at a pole) its
            value is held. Without it angles lie in ``[-pi, pi)`` / atan2's range.

        Returns
        -------
        ndarray, shape (..., n_c)

        Raises
        ------
        DegenerateInputError
            Two robots coincide.
        """
        r = self.check_robot_state(r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        return self._forward(r, near_c, True)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``, where the held angles are selects as on NumPy): the caller has checked
        ``r`` (finite, robots apart) and ``near_c``."""
        return self._forward(r, near_c, False)

    def _forward(self, r, near_c, check):
        xp = array_namespace(r)
        if near_c is not None:
            r = xp.broadcast_to(r, np.broadcast_shapes(r.shape[:-1], near_c.shape[:-1]) + r.shape[-1:])
        G = self._geometry(r, near_c, check)
        c = np.empty(r.shape[:-1] + (self.n_c,)) if xp is np else xp.zeros(r.shape[:-1] + (self.n_c,))
        nxc = self._nxc
        c = _set(c, (..., slice(0, nxc)), G["p"].mean(axis=-2)[..., :nxc])  # seed 000 eqs. (1)-(3), N robots
        c = _set(c, (..., self._i_beta), G["beta"])
        if not self.planar:
            c = _set(c, (..., self._i_gamma), G["gamma"])
        if self._roll:
            c = _set(c, (..., self._i_alpha), G["alpha"])
        c = _set(c, (..., self._i_d), 0.5 * G["D"])  # eq. (6), half the distance
        if self.layout.n >= 3:
            c = _set(c, (..., self._i_rho), G["rho"])
            c = _set(c, (..., self._i_psi), G["psi"])
            if len(self._i_chi):
                c = _set(c, (..., self._i_chi), G["chi"][..., 1:])
        if len(self._i_phi):
            th = self.layout.yaws(r)
            phi = th - G["beta"][..., None]  # eqs. (7)-(8)
            c = _set(c, (..., self._i_phi),
                     g.wrap(phi) if near_c is None else g.unwrap_near(phi, near_c[..., self._i_phi]))
        return c

    # -- inverse kinematics ---------------------------------------------------------------
    def _spokes(self, c):
        """Robot ``k``'s position from robot 1 in the formation frame, ``(..., N, 3)`` (robot 1: 0,
        robot 2: ``(0, -2 d_c, 0)``), and the spherical directions ``(..., N - 2, 3)``."""
        L = self.layout
        xp = array_namespace(c)
        shape = c.shape[:-1]
        S = xp.zeros(shape + (L.n, 3))
        S = _set(S, (..., 1, 1), -2.0 * c[..., self._i_d])
        if L.n < 3:
            return S, None, None, None
        psi = c[..., self._i_psi]
        chi = xp.zeros_like(psi)
        if len(self._i_chi):
            chi = _set(chi, (..., slice(1, None)), c[..., self._i_chi])
        dirs = _spoke_direction(psi, chi)
        rho = c[..., self._i_rho]
        S = _set(S, (..., slice(2, None), slice(None)), rho[..., None] * dirs)
        return S, dirs, psi, chi

    def _angles_of(self, c):
        beta = c[..., self._i_beta]
        xp = array_namespace(c)
        gamma = xp.zeros_like(beta) if self.planar else c[..., self._i_gamma]
        alpha = c[..., self._i_alpha] if self._roll else xp.zeros_like(beta)
        return beta, gamma, alpha

    def _place(self, c):
        """``(x_c (..., 3), frame, offsets (..., N, 3))``: ``p_i = x_c + R (s_i - mean s)``."""
        beta, gamma, alpha = self._angles_of(c)
        x0, u, z0, xf, zf = _frame(beta, gamma, alpha)
        S, dirs, psi, chi = self._spokes(c)
        Sc = S - S.mean(axis=-2, keepdims=True)
        off = (Sc[..., 0:1] * xf[..., None, :] + Sc[..., 1:2] * u[..., None, :] + Sc[..., 2:3] * zf[..., None, :])
        xc = array_namespace(c).zeros(c.shape[:-1] + (3,))
        nxc = self._nxc
        xc = _set(xc, (..., slice(None, nxc)), c[..., :nxc])
        if self._ground is not None:  # the ground robot at z = 0 fixes the centroid's height
            xc = _set(xc, (..., 2), -off[..., self._ground, 2])
        return xc, (x0, u, z0, xf, zf), off, (S, dirs, psi, chi)

    def inverse(self, c, *, near_r=None):
        """Robots of the cluster state ``c``: ``p_i = x_c + R(beta_c, gamma_c, alpha_c) (s_i -
        mean_j s_j)`` with ``s_i`` robot ``i``'s spoke from robot 1, ``theta_i = phi_i + beta_c``
        (eqs. (7)-(8)). Single-valued; at a singular set the positions do not depend on the
        undefined angle (``beta_c`` at ``gamma_c = +-pi/2`` only through ``beta_c + alpha_c``).
        Two robots: seed 000 eqs. (1)-(8) solved for them, ``x1,2 = x_c +- d_c u(beta_c,
        gamma_c)``; a pitch beyond ``[-pi/2, pi/2]`` gives the positions of ``(beta_c + pi,
        pi - gamma_c)`` (the fold of seed 000 §4.1), the yaws ``phi_i + beta_c`` as given.

        Parameters
        ----------
        c : array_like, shape (..., n_c)
            Two ``xyz_yaw`` robots: ``(..., 8)``, ``(x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1,
            phi_2)`` (m, rad).
        near_r : array_like, shape (..., n_r), optional
            Robot state whose yaws the result's are unwrapped near (within pi).

        Returns
        -------
        ndarray, shape (..., n_r)
            Two ``xyz_yaw`` robots: ``(..., 8)``, ``(x1, y1, z1, theta1, x2, y2, z2, theta2)``.

        Raises
        ------
        DegenerateInputError
            ``d_c`` or a ``rho_k`` too small (robots on robot 1).
        """
        c = self.check_cluster_state(c)
        xc, _, off, _ = self._place(c)
        p = self._unordered(xc[..., None, :] + off)
        th = c[..., self._i_phi] + c[..., self._i_beta][..., None]
        if near_r is not None and len(self._i_phi):
            th = g.unwrap_near(th, self.layout.yaws(self.check_robot_state(near_r, "near_r")))
        return self.layout.compose(p, th)

    # -- rate maps ------------------------------------------------------------------------
    def robot_rate(self, c, c_dot, *, r=None):
        """Derivative of :meth:`inverse` at ``c`` along ``c_dot``: ``p_i' = x_c' + w x R (s_i -
        m) + R (s_i' - m')`` with ``w = beta' e_z + gamma' x0 + alpha' u`` the frame's angular
        velocity (``R = Rz Rx Ry``), ``s_k' = rho_k' d_k + rho_k (psi_k' d_psi + chi_k' d_chi)``;
        ``theta_i' = beta_c' + phi_i'``. O(N); loses rank on the singular sets.

        Two ``xyz_yaw`` robots: the seed's 8 x 8 closed form (:meth:`inverse_jacobian_at`)
        applied to ``c_dot``, the floats of the pair cluster-space controller (seed 000 Fig. 2),
        so that a team controller reproduces its runs bit for bit (``docs/derivations.md``)."""
        return self.robot_rate_arrays(np.asarray(c, dtype=float), as_array(c_dot, "c_dot", self.n_c))

    def robot_rate_arrays(self, c, cd):
        """:meth:`robot_rate` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``)."""
        if self._seed:
            Ji = _pair_inverse_jacobian(c)
            if isinstance(Ji, np.ndarray) and isinstance(cd, np.ndarray):
                return np.einsum("...ij,...j->...i", Ji, cd)
            return (Ji * cd[..., None, :]).sum(axis=-1)  # the products' sums (as ClusterController on JAX)
        return self._rate_map(c, cd)

    def _rate_map(self, c, cd):
        """:meth:`robot_rate` for any team (the O(N) directional derivative)."""
        xp = array_namespace(cd)
        c, cd = xp.broadcast_arrays(c, cd)
        _, (x0, u, _, xf, zf), off, (S, dirs, psi, chi) = self._place(c)
        bd, gd, ad = self._angles_of(cd)
        w = bd[..., None] * _EZ + gd[..., None] * x0 + ad[..., None] * u
        Sd = xp.zeros(S.shape)
        Sd = _set(Sd, (..., 1, 1), -2.0 * cd[..., self._i_d])
        if self.layout.n >= 3:
            rho = c[..., self._i_rho][..., None]
            psid = cd[..., self._i_psi][..., None]
            chid = xp.zeros_like(psid)
            if len(self._i_chi):
                chid = _set(chid, (..., slice(1, None), slice(None)), cd[..., self._i_chi][..., None])
            cc, sc, cp, spsi = xp.cos(chi)[..., None], xp.sin(chi)[..., None], xp.cos(psi)[..., None], \
                xp.sin(psi)[..., None]
            d_psi = xp.concatenate([cc * cp, cc * spsi, xp.zeros_like(cc)], axis=-1)
            d_chi = xp.concatenate([-sc * spsi, sc * cp, cc], axis=-1)
            Sd = _set(Sd, (..., slice(2, None), slice(None)),
                      cd[..., self._i_rho][..., None] * dirs + rho * (psid * d_psi + chid * d_chi))
        Sdc = Sd - Sd.mean(axis=-2, keepdims=True)
        v = (Sdc[..., 0:1] * xf[..., None, :] + Sdc[..., 1:2] * u[..., None, :] + Sdc[..., 2:3] * zf[..., None, :])
        xcd = xp.zeros(cd.shape[:-1] + (3,))
        nxc = self._nxc
        xcd = _set(xcd, (..., slice(None, nxc)), cd[..., :nxc])
        v = xp.cross(w[..., None, :], off) + v
        if self._ground is not None:  # the ground robot stays at z = 0
            xcd = _set(xcd, (..., 2), -v[..., self._ground, 2])
        v = self._unordered(xcd[..., None, :] + v)
        if xp is not np:
            return team_compose(self.layout, v, cd[..., self._i_phi] + bd[..., None])
        return self.layout.compose(v, cd[..., self._i_phi] + bd[..., None])

    def inverse_jacobian_at(self, c, *, r=None):
        """The dense derivative of :meth:`inverse` at ``c``, ``(..., n_r, n_c)`` (NumPy, or another
        array namespace for two robots): for two ``xyz_yaw`` robots seed 000's closed form
        (rank 7 at a vertical segment), otherwise :meth:`robot_rate` on the unit vectors."""
        if self._seed:
            return _pair_inverse_jacobian(as_floats(c))
        return super().inverse_jacobian_at(c, r=r)

    def _rates(self, r, r_dot, near_c=None, strict=True):
        """Derivative of :meth:`forward` along ``r_dot``; ``strict``: raise where a rate is
        undefined, else report it as 0 (the held angle's rate)."""
        r = self.check_robot_state(r)
        rd = as_array(r_dot, "r_dot", self.n_r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        shape = np.broadcast_shapes(r.shape[:-1], rd.shape[:-1], () if near_c is None else near_c.shape[:-1])
        r, rd = (np.broadcast_to(a, shape + a.shape[-1:]) for a in (r, rd))
        G = self._geometry(r, near_c)
        L = self.layout
        v = self._ordered(L.positions(rd))
        dd = v[..., 0, :] - v[..., 1, :]
        delta, D, rho_h = G["delta"], G["D"], G["rho_h"]
        dx, dy, dz = np.moveaxis(delta, -1, 0)
        vert = G["vertical"]
        bad = {"gamma_c = +-pi/2 (robot 1 straight above or below robot 2: beta_c undefined)": vert}
        if L.n >= 3 and self._roll:
            bad["robots 1, 2, 3 collinear (alpha_c undefined)"] = G["collinear"]
        if L.n >= 4 and not self.planar:
            bad["a spoke k >= 4 along the formation's z axis (psi_k undefined)"] = np.any(G["pole"][..., 1:], axis=-1)
        if strict:
            for what, mask in bad.items():
                if np.any(mask):
                    raise DegenerateInputError(
                        f"the Euclidean {'pair' if L.n == 2 else 'team'} Jacobian is undefined at {what}; the minimal "
                        "chart is singular there: use " + ("QuaternionPair or DualQuaternionPair" if self._pair_chart
                                                           else "QuaternionTeam or DualQuaternionTeam"))
        rho2 = np.where(vert, 1.0, rho_h * rho_h)
        bd = np.where(vert, 0.0, (-dy * dd[..., 0] + dx * dd[..., 1]) / rho2)  # grad of eq. (4)
        if self.planar:
            gd = np.zeros_like(bd)
        else:
            rh = np.where(vert, 1.0, rho_h)
            gd = np.where(vert, 0.0, (-dz * (dx * dd[..., 0] + dy * dd[..., 1]) / rh + rho_h * dd[..., 2]) / (D * D))
        d_d = 0.5 * _dot(delta, dd) / D  # eq. (6)
        out = np.zeros(r.shape[:-1] + (self.n_c,))
        nxc = self._nxc
        out[..., :nxc] = v.mean(axis=-2)[..., :nxc]
        out[..., self._i_beta] = bd
        if not self.planar:
            out[..., self._i_gamma] = gd
        out[..., self._i_d] = d_d
        if L.n >= 3:
            x0, u, xf, zf, S = G["x0"], G["u"], G["xf"], G["zf"], G["S"]
            Wd = v[..., 2:, :] - v[..., :1, :]
            if self._roll:  # robot 3 stays in the x-y plane: w . (z_f x w3) = -z_f . w3'
                col = G["collinear"]
                sx3 = np.where(col, 1.0, S[..., 0, 0])
                w_xf = bd * xf[..., 2] + gd * np.cos(G["alpha"])  # (b' e_z + g' x0) . x_f
                w_u = np.where(col, bd * u[..., 2], (S[..., 0, 1] * w_xf - _dot(zf, Wd[..., 0, :])) / sx3)
                ad = w_u - bd * u[..., 2]
                out[..., self._i_alpha] = ad
            else:
                ad = np.zeros_like(bd)
            w = bd[..., None] * _EZ + gd[..., None] * x0 + ad[..., None] * u
            Om = np.stack([_dot(w, xf), _dot(w, u), _dot(w, zf)], axis=-1)  # R^T w
            Sd = np.stack([_dot(Wd, xf[..., None, :]), _dot(Wd, u[..., None, :]), _dot(Wd, zf[..., None, :])],
                          axis=-1) - np.cross(Om[..., None, :], S)
            if self._roll:
                Sd[..., 0, 2] = 0.0
            rho, h, pole = G["rho"], G["h"], G["pole"]
            out[..., self._i_rho] = _dot(S, Sd) / rho
            hs = np.where(pole, 1.0, h)
            psid = (-S[..., 1] * Sd[..., 0] + S[..., 0] * Sd[..., 1]) / (hs * hs)
            out[..., self._i_psi] = np.where(pole, 0.0, psid)
            if len(self._i_chi):
                hd = (S[..., 0] * Sd[..., 0] + S[..., 1] * Sd[..., 1]) / hs
                chid = np.where(pole, 0.0, (h * Sd[..., 2] - S[..., 2] * hd) / (rho * rho))
                out[..., self._i_chi] = chid[..., 1:]
        if len(self._i_phi):
            out[..., self._i_phi] = L.yaws(rd) - bd[..., None]  # eqs. (7)-(8)
        return out

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """Derivative of the forward map along ``r_dot`` (the gradients of eqs. (4)-(6), the roll
        from robot 3 staying in the formation's x-y plane, the spokes' spherical rates,
        ``phi_i' = theta_i' - beta_c'``); O(N). ``near_c`` changes no rate.

        Raises
        ------
        DegenerateInputError
            On a singular set (``gamma_c = +-pi/2``, robots 1-3 collinear, a spoke at a pole),
            where a rate is undefined.
        """
        return self._rates(r, r_dot, near_c, strict=True)

    # -- the Euler reading of the formation's attitude -------------------------------------------
    @property
    def reading_names(self) -> tuple[str, ...]:
        """Names of :meth:`reading`'s angles: ``beta_c``, and ``gamma_c`` and ``alpha_c`` in space."""
        return tuple(self.variables[i].name for i in self._reading_index)

    @property
    def _reading_index(self):
        return [i for i in (self._i_beta, self._i_gamma, self._i_alpha) if i is not None]

    def reading(self, r, *, near=None) -> np.ndarray:
        """The attitude angles ``(beta_c, gamma_c, alpha_c)`` (rad) of the robots ``r``.

        Without ``near``: the forward map's own values (seed 000 eqs. (4)-(5): ``gamma_c`` in
        ``[-pi/2, pi/2]``, ``beta_c`` and ``alpha_c`` in ``(-pi, pi]``), which is how robot space
        reads its formation (it keeps no formation state). With ``near`` (``(..., k)``), the
        one of the two Euler triples of the same frame, ``(beta, gamma, alpha)`` and
        ``(beta + pi, pi - gamma, alpha + pi)`` (``Rz Rx Ry`` is unchanged; for a pair without
        roll, ``(beta + pi, pi - gamma)`` gives the same segment), each wound to within pi of
        ``near``'s, that lies closer to it: the reading of a description that follows the
        attitude continuously through ``gamma_c = +-pi/2`` (``docs/derivations.md``).

        Parameters
        ----------
        r : array_like, shape (..., n_r)
        near : array_like, shape (..., k), optional

        Returns
        -------
        ndarray, shape (..., k)
            ``k = len(reading_names)``.
        """
        a = self.forward(r)[..., self._reading_index]
        return a if near is None else self._branch_near(a, np.asarray(near, dtype=float))

    def follow_reading(self, r) -> np.ndarray:
        """:meth:`reading` of the samples ``r`` ``(T, n_r)`` followed continuously in time: each
        sample's triple nearest the previous one's (the first: the forward map's), so that a
        formation pitching through the vertical reads ``gamma_c`` past ``pi/2``, as seed 000
        states its references. Shape ``(T, k)``."""
        a = self.reading(r)
        out = a.copy()
        for k in range(1, len(a)):  # sequential: each sample's branch depends on the last
            out[k] = self._branch_near(a[k], out[k - 1])
        return out

    def _branch_near(self, a, near):
        """The Euler triple of ``a``'s frame (``a`` or its flip) nearest ``near``, wound to it."""
        if self.planar:
            return g.unwrap_near(a, near)
        flip = a.copy()
        flip[..., 0] += np.pi
        flip[..., 1] = np.pi - a[..., 1]
        if a.shape[-1] > 2:
            flip[..., 2] += np.pi
        a, flip = g.unwrap_near(a, near), g.unwrap_near(flip, near)
        closer = np.sum((flip - near) ** 2, axis=-1) < np.sum((a - near) ** 2, axis=-1)
        return np.where(closer[..., None], flip, a)

    # -- the operator's chart ---------------------------------------------------------------
    @property
    def chart_on_arrays(self) -> bool:
        """The pair chart runs on any array namespace (:meth:`to_chart_arrays`); the team chart on NumPy."""
        return self._pair_chart

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of the pair chart on checked arrays of any namespace: ``c`` with
        ``beta_c``, ``phi_1``, ``phi_2`` wound to ``near_e``'s (a selection, no assignment)."""
        if near_e is None:
            return c.copy() if isinstance(c, np.ndarray) else c
        xp = array_namespace(c)
        wound = np.isin(np.arange(self.n_c), _PAIR_WOUND)
        return xp.where(wound, g.unwrap_near(c, near_e), c)

    def to_chart(self, c, *, near_e=None, r=None):
        """The operator's chart of ``c``.

        ``chart="pair"``: seed 000's variables (``c`` itself, angles unwrapped near
        ``near_e``'s). ``chart="team"``: the team chart; with ``near_e``, the robots read in
        ``near_e``'s frame (:meth:`TeamChart.from_robots`: its shape fitted, its attitude the
        hint); without it, with ``template`` fitted, else this description's own frame
        (``q_c`` of ``Rz(beta_c) Rx(gamma_c) Ry(alpha_c)``, ``s_i`` the centred spokes,
        ``theta_i = phi_i + beta_c``).
        """
        c = self.check_cluster_state(c)
        if self._pair_chart:  # beta_c, phi_1, phi_2 wound to near_e's (gamma_c in [-pi/2, pi/2])
            return self.to_chart_arrays(c, None if near_e is None else np.asarray(near_e, dtype=float))
        if near_e is not None or self.template is not None:
            return self.chart.from_robots(self.inverse(c), near_e=near_e, template=self.template)
        beta, gamma, alpha = self._angles_of(c)
        half = 0.5
        qz = np.stack([np.cos(half * beta), 0 * beta, 0 * beta, np.sin(half * beta)], axis=-1)
        qx = np.stack([np.cos(half * gamma), np.sin(half * gamma), 0 * gamma, 0 * gamma], axis=-1)
        qy = np.stack([np.cos(half * alpha), 0 * alpha, np.sin(half * alpha), 0 * alpha], axis=-1)
        q = g.mul(g.mul(qz, qx), qy)
        xc, _, off, _ = self._place(c)
        e = np.zeros(c.shape[:-1] + (self.chart.size,))
        e[..., 0:(2 if self.planar else 3)] = xc[..., 0:(2 if self.planar else 3)]
        e[..., 3:7] = q
        S, _, _, _ = self._spokes(c)
        e[..., self.chart.shape_index] = self._unordered(S - S.mean(axis=-2, keepdims=True))
        e[..., self.chart.yaw_index] = c[..., self._i_phi] + beta[..., None]
        return e

    def from_chart(self, e, e_dot=None):
        """Cluster state (and rate) of the chart values ``e`` (and ``e_dot``).

        ``chart="pair"``: seed 000's variables are the cluster state. ``chart="team"``: the
        forward map of the chart's robots (:meth:`TeamChart.robots`), with ``phi_i =
        theta_i - beta_c`` keeping ``e``'s winding; the rate is the forward map's derivative
        along :meth:`TeamChart.robot_rates`, where a rate is undefined (a singular set) the
        held angle's rate 0 (the reference stays finite; the Jacobian raises there).

        Raises
        ------
        DegenerateInputError
            The chart puts robots on each other (robot 1 and 2 at one point: no ``beta_c``).
        """
        if self._pair_chart:
            e = self.check_cluster_state(e, "e")
            return e.copy() if e_dot is None else (e.copy(), as_array(e_dot, "e_dot", 8).copy())
        e = self.chart.check(e)
        r = self.chart.robots(e)
        c = self.forward(r)
        if len(self._i_phi):
            c[..., self._i_phi] = e[..., self.chart.yaw_index] - c[..., self._i_beta][..., None]
        if e_dot is None:
            return c
        return c, self._rates(r, self.chart.robot_rates(e, e_dot), strict=False)

    # -- samples and special sets -----------------------------------------------------------
    def _random_cluster(self, rng, batch, overrides=None):
        """Cluster states inside the regular region (``|gamma_c| <= 1.1``, robot 3 at least 0.35 rad
        off the 1-2 line, spokes at least 0.45 rad from the poles, lengths 0.4-2 m), then
        ``overrides`` (pairs ``(variable index or index array, values)``)."""
        c = np.zeros(batch + (self.n_c,))
        L = self.layout
        nxc = self._nxc
        c[..., :nxc] = rng.uniform(-2.0, 2.0, batch + (nxc,))
        c[..., self._i_beta] = rng.uniform(-np.pi, np.pi, batch)
        if not self.planar:
            c[..., self._i_gamma] = rng.uniform(-1.1, 1.1, batch)
        if self._roll:
            c[..., self._i_alpha] = rng.uniform(-np.pi, np.pi, batch)
        c[..., self._i_d] = rng.uniform(0.3, 1.0, batch)
        m = len(self._i_rho)
        if m:
            reach = 2.0 * max(1.0, (L.n / 8.0) ** (1.0 / 3.0))  # room for N robots 0.3 m apart
            c[..., self._i_rho] = rng.uniform(0.6, reach, batch + (m,))
            c[..., self._i_psi] = rng.uniform(-np.pi, np.pi, batch + (m,))
            if self._roll:
                c[..., self._i_psi[0]] = rng.uniform(0.35, np.pi - 0.35, batch)
            if len(self._i_chi):
                c[..., self._i_chi] = rng.uniform(-1.1, 1.1, batch + (len(self._i_chi),))
        if len(self._i_phi):
            c[..., self._i_phi] = rng.uniform(-20.0, 20.0, batch + (len(self._i_phi),))
        for idx, val in overrides or ():
            c[..., idx] = val
        return c

    def _apart_states(self, rng, batch, overrides=None, min_m=0.3):
        """Robot states of :meth:`_random_cluster` with every two robots ``min_m`` apart: the spoke
        of the later robot of a close pair is drawn again (robots 1 and 2 are ``2 d_c >= 0.6`` m
        apart)."""
        c = self._random_cluster(rng, batch, overrides)
        L = self.layout
        j = L.pairs[1]
        for _ in range(500):
            r = self.inverse(c)
            close = L.separations(r) < min_m  # (..., pairs)
            if not np.any(close):
                return r
            redo = np.any(close[..., None] & (j[:, None] == np.arange(L.n)), axis=-2)  # (..., N)
            fresh = self._random_cluster(rng, batch, overrides)
            owner = self._spoke_owner
            mask = np.where(owner >= 0, redo[..., np.maximum(owner, 0)], False)
            c = np.where(mask, fresh, c)
        raise AssertionError(f"{self.name}: could not sample robots {min_m} m apart")  # pragma: no cover

    def sample_robot_state(self, rng, batch=()):
        """Random robot states away from the singular sets (``|gamma_c| <= 1.1``, robot 3 at least
        0.35 rad off the 1-2 line, spokes 0.45 rad from the poles), robots at least 0.3 m apart,
        yaws wound over several turns (+-20 rad); shape ``batch + (n_r,)``."""
        batch = (int(batch),) if isinstance(batch, (int, np.integer)) else tuple(batch)
        return self._apart_states(rng, batch)

    def _set(self, overrides_of_eps):
        def states(rng, n, eps):
            return self._apart_states(rng, (n,), overrides_of_eps(rng, n, eps), min_m=0.1)
        return states

    def special_sets(self) -> tuple[SpecialSet, ...]:
        """Every special set of the chart: ``vertical`` (``gamma_c = +-pi/2``), ``collinear``
        (robots 1-3 on a line, N >= 3 in space), ``spoke-pole`` (a spoke k >= 4 along the
        formation's z axis, N >= 4 in space): Jacobian undefined, inverse Jacobian rank
        deficient; ``angle-wraps`` (every wrapped angle at +-pi: atan2's branch cut) and
        ``wound-yaws`` (yaws wound by up to 50 turns): regular. (Coincident robots, the fourth
        singular set, are refused: ``forward`` raises.) A pair adds seed 000's ``anti-x`` and
        ``half-turn-yaws`` sets (regular here) through :func:`~.special_sets.pair_sets`."""
        out = []
        vertical_why = ("beta_c = atan2(-dx, dy) of seed 000 eq. (4) is atan2(0, 0) with robot 1 straight above or "
                        "below robot 2: held at near_c's; its rate is undefined and yaw and roll turn about one axis")
        if self.layout.kinds == ("xyz_yaw", "xyz_yaw"):
            out += list(sp.pair_sets(vertical_why, jacobian="raises", inverse_jacobian="rank-deficient"))
        elif not self.planar:
            def vertical(rng, n, eps):
                return [(self._i_gamma, rng.choice([-1.0, 1.0], n) * (0.5 * np.pi - eps))]
            out.append(SpecialSet("vertical", vertical_why, self._set(vertical), "raises", "rank-deficient"))
        if self._roll:
            def collinear(rng, n, eps):
                side = rng.choice([0.0, 1.0], n)
                return [(self._i_psi[0], side * np.pi + (1.0 - 2.0 * side) * eps)]
            out.append(SpecialSet(
                "collinear", "robots 1, 2, 3 on one line: the roll alpha_c = atan2(-w.z0, w.x0) of robot 3's offset "
                "from the line is atan2(0, 0); held at near_c's, its rate undefined (psi_3 = 0 or pi)",
                self._set(collinear), "raises", "rank-deficient"))
        if len(self._i_chi):
            def pole(rng, n, eps):  # one spoke k >= 4 per state, drawn at random
                m = len(self._i_chi)
                chi = rng.uniform(-1.1, 1.1, (n, m))
                chi[np.arange(n), rng.integers(0, m, n)] = rng.choice([-1.0, 1.0], n) * (0.5 * np.pi - eps)
                return [(self._i_chi, chi)]
            out.append(SpecialSet(
                "spoke-pole", "a spoke k >= 4 along the formation's z axis (chi_k = +-pi/2): its azimuth psi_k = "
                "atan2(s_x, -s_y) is atan2(0, 0); held at near_c's, its rate undefined",
                self._set(pole), "raises", "rank-deficient"))

        def wraps(rng, n, eps):
            sgn = rng.choice([-1.0, 1.0], n)
            ov = [(self._i_beta, sgn * (np.pi - eps))]
            if self._roll:
                ov.append((self._i_alpha, -sgn * (np.pi - eps)))
            if len(self._wrap_psi):
                ov.append((self._i_psi[self._wrap_psi], (sgn * (np.pi - eps))[:, None]))
            if len(self._i_phi):  # phi_i at +-pi too (wound by a few turns)
                ov.append((self._i_phi, (-sgn * (np.pi - eps))[:, None] + 2.0 * np.pi * rng.integers(-3, 4, (n, 1))))
            return ov
        out.append(SpecialSet("angle-wraps", "beta_c, alpha_c, the azimuths psi_k and phi_i at +-pi (atan2's branch "
                              "cut): unwrapped near near_c's, regular", self._set(wraps)))
        if len(self._i_phi) and self.layout.kinds != ("xyz_yaw", "xyz_yaw"):
            def wound(rng, n, eps):
                return [(self._i_phi, rng.uniform(-np.pi, np.pi, (n, len(self._i_phi)))
                         + 2.0 * np.pi * rng.integers(-50, 51, (n, len(self._i_phi))) + eps)]
            out.append(SpecialSet("wound-yaws", "yaws wound by up to 50 turns: phi_i = theta_i - beta_c unwrapped "
                                  "near near_c's, regular", self._set(wound)))
        return tuple(out)


class EuclideanPair(Preset, EuclideanTeam):
    """Seed 000 eqs. (1)-(8): ``EuclideanTeam(2, chart="pair")``, two 4-DOF robots in the
    variables ``(x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)`` (:data:`EUCLIDEAN_VARIABLES`).

    The minimal baseline of Mas & Kitts: singular where the segment between the robots is
    vertical (``|gamma_c| = pi/2``: ``beta_c`` undefined) and where the robots coincide. Eq. (6)
    is printed ``sqrt(dx^2 + dy^2 + dz^2/2)``; ``d_c`` is *half the distance* (text and Fig. 1),
    ``sqrt(dx^2 + dy^2 + dz^2) / 2`` (``docs/derivations.md``). ``gamma_c`` lies in ``[-pi/2,
    pi/2]`` (the range of eq. (5)); a pitch beyond it is read as ``beta_c + pi`` and ``pi -
    gamma_c``, the ambiguity of seed 000 §4.1.
    """

    name = "euclidean"
    key = "euclidean"
    arguments = {"n": 2, "chart": "pair"}
