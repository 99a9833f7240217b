"""The formation interface: one contract for every cluster-space representation.

Second layer of quatform (above :mod:`quatform.algebra`). A formation maps the stacked
robot state ``r`` (shape ``(..., n_r)``) to the cluster state ``c`` (shape ``(..., n_c)``)
and back, gives the rate maps the controllers need (``cluster_rate``: ``c_dot = J(r)
r_dot``; ``robot_rate``: ``r_dot = dINVKIN(c) c_dot``, the primitive; the dense Jacobians
are derived from them), says how close a state is to a singular pose, and converts its
state to the operator's chart (Euclidean variables for pairs, spherical ones for UGV-UAV).
The robot state is laid out by a :class:`~.layout.RobotLayout` (N robots, each of a point
kind), which computes slices, separations and yaw winding. The controllers, the
references and the simulator only use this interface, so an N-robot representation
plugs in by subclassing :class:`Formation`; ``formations.testing.check_formation`` is its
contract test.

Choices that a representation leaves open (the sign of a quaternion, the branch of a
square root, the 2 pi of an angle, the twist of a segment's frame) are resolved by typed
keyword arguments, one meaning each: ``near_c`` (a cluster state to stay closest to),
``near_r`` (a robot state whose yaws to unwrap near), ``near_e`` (chart variables to stay
closest to) and ``r`` (the robots of a cluster state, where the state alone does not fix
the branch). Controllers pass the desired state as ``near_c``, so the measured state is
expressed on the same sheet as the reference; without one the seed's printed convention
is used.
"""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod
from collections.abc import Mapping

import numpy as np

from ..algebra import wrap_angle
from ..algebra.angles import wrap_entries
from ..algebra.kernels import array_namespace, concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError
from ..registry import Registry, RegistryView
from .layout import POINT_KINDS, RobotLayout, Variable
from .special_sets import SpecialSet
from .team_chart import team_compose, team_positions

__all__ = ["Variable", "Formation", "Preset", "SpecialSet", "FORMATION_TYPES", "FORMATIONS", "TEAM_FORMATIONS", "ROBOT_PAIR_VARIABLES", "PAIR_LAYOUT", "MIN_SEPARATION_M",
           "MAX_MAGNITUDE"]

#: Closest two robots may be (m); below it a two-robot formation is undefined.
MIN_SEPARATION_M = 1e-9
#: Teams up to this size measure their length scale over all pairs (O(N^2)); larger ones from
#: the centroid (:meth:`Formation.length_scale`).
_ALL_PAIRS_UP_TO = 16
#: Largest magnitude of a state entry (m, rad, m/s ...). The formations square lengths
#: (norms, Lyapunov functions) and multiply them by gains and rates; below 1e150 every such
#: product of two or three of them is finite in float64, above about 1.3e154 a squared
#: separation overflows to infinity.
MAX_MAGNITUDE = 1e150


def check_magnitude(a, name):
    """Raise InvalidInputError if an entry of the finite array ``a`` exceeds :data:`MAX_MAGNITUDE`."""
    # one ufunc reduction of |a| (np.max and np.min each cost a Python-level wrapper)
    if a.size and not np.maximum.reduce(np.abs(a), axis=None) <= MAX_MAGNITUDE:
        idx = np.unravel_index(int(np.argmax(np.abs(a))), a.shape)
        raise InvalidInputError(
            f"{name}{list(int(i) for i in idx)} = {float(a[idx]):.6g} is beyond the {MAX_MAGNITUDE:g} "
            "quatform accepts (squared lengths would overflow); express the state in larger units "
            "or nearer the origin"
        )
    return a


#: Two 4-DOF robots (seed 000): ``r = (x1, y1, z1, theta1, x2, y2, z2, theta2)``.
PAIR_LAYOUT = RobotLayout.uniform("xyz_yaw", 2)
#: The pair layout's variables.
ROBOT_PAIR_VARIABLES = PAIR_LAYOUT.variables


def quaternion_variables(prefix: str):
    return tuple(Variable(f"{prefix}_{c}", "1", "quaternion") for c in "wxyz")


#: Every description class by its :attr:`Formation.key` (filled when a subclass with a key is defined).
FORMATION_TYPES = Registry("formation")


class Formation(ABC):
    """Cluster-space representation of a team of robots.

    Subclasses set :attr:`name`, :attr:`variables`, :attr:`layout`,
    :attr:`chart_variables` and implement the abstract methods. Every method accepts
    leading batch axes. A subclass that sets :attr:`key` registers itself in
    :data:`FORMATION_TYPES` when it is defined; :data:`FORMATIONS` then holds its
    :meth:`examples`, over which ``tests/test_formation_contract.py`` runs
    :func:`~quatform.formations.testing.check_formation`.
    """

    #: Short name used on the command line and in files.
    name: str = ""
    #: Unique key of the class in :data:`FORMATION_TYPES` (None: not registered, e.g. a shared base).
    key: str | None = None
    #: An N-robot team description, built as ``cls(n=None, *, layout=None, template=None)``
    #: (:data:`TEAM_FORMATIONS`); False for a :class:`Preset` of one.
    team: bool = False
    #: A team description's controller: the name the team scenario kind (``--controller``, a
    #: file's ``[gains.<name>]``) and ``control.team_controller`` know it by (None: none).
    controller: str | None = None
    #: Where that controller comes among the team controllers offered (``--controller``,
    #: ``compare``): seed 000's order, then by the order defined.
    controller_order: float = float("inf")
    #: Its default gains by table (``"table1"``, ``"table2"``: seed 000 Tables 1-2 adapted to
    #: teams), each ``{gain key: number or list}``, the keys of ``control.TEAM_GAIN_KEYS``.
    gain_tables: Mapping = {}
    #: Layout of the cluster state vector.
    variables: tuple[Variable, ...] = ()
    #: The robots and their points; :attr:`robot_variables` is its variables.
    layout: RobotLayout = PAIR_LAYOUT
    #: The operator's chart: the variables :meth:`to_chart` gives and :meth:`from_chart`
    #: takes (the seed-000 Euclidean variables for pairs, the spherical ones for UGV-UAV).
    chart_variables: tuple[Variable, ...] = ()
    #: Blocks of the cluster state whose sign means nothing (``q`` and ``-q`` are one state).
    sign_free: tuple[slice, ...] = ()
    #: Whether :meth:`forward` refuses robots on each other (closer than
    #: :data:`MIN_SEPARATION_M`); a controller marks such a measurement refused (code 2).
    robots_apart: bool = True
    #: Its cluster state is the robot state itself (robot space, ``c = r``): a file that
    #: writes the robots leaves its cluster variables out.
    cluster_is_robot_state: bool = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("key"):
            FORMATION_TYPES.add(cls.key, cls)

    def check_gains(self, gains: Mapping) -> None:
        """Refuse ``gains`` (``{gain key: value}``, :attr:`gain_tables`' keys) its controller
        cannot drive these robots with, in the description's own words (one line). Default:
        nothing; the team controller checks each law group's gain itself."""

    @classmethod
    def examples(cls) -> dict:
        """The instances the contract test runs over, by a unique key (default: ``{key: cls()}``)."""
        return {cls.key: cls()}

    @property
    def robot_variables(self) -> tuple[Variable, ...]:
        """Layout of the robot state vector (:attr:`layout`'s variables)."""
        return self.layout.variables

    @property
    def n_c(self) -> int:
        return len(self.variables)

    @property
    def n_r(self) -> int:
        return self.layout.size

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables)

    # -- input checks ---------------------------------------------------------------
    def check_robot_state(self, r, name: str = "r") -> np.ndarray:
        """Finite ``(..., n_r)`` array, entries within :data:`MAX_MAGNITUDE`."""
        return check_magnitude(as_array(r, name, self.n_r), name)

    def check_cluster_state(self, c, name: str = "c") -> np.ndarray:
        """Finite ``(..., n_c)`` array, entries within :data:`MAX_MAGNITUDE`."""
        return check_magnitude(as_array(c, name, self.n_c), name)

    def check_apart(self, r, name: str = "r", separations=None) -> None:
        """Raise DegenerateInputError (naming the robots) if two robots of ``r`` are closer than
        :data:`MIN_SEPARATION_M`; ``separations`` (m, any shape), if the caller has them, make
        the check one comparison where every robot is apart."""
        if separations is not None and not np.any(np.asarray(separations) < MIN_SEPARATION_M):
            return
        self.layout.check_apart(r, MIN_SEPARATION_M, name)

    # -- the contract -----------------------------------------------------------------
    @abstractmethod
    def forward(self, r, *, near_c=None) -> np.ndarray:
        """Cluster state of robot state ``r``: ``c = KIN(r)``, shape ``(..., n_c)``.

        ``near_c`` (a cluster state, ``(..., n_c)``) picks the branch (sign, twist, 2 pi)
        closest to it where the description leaves one open.
        """

    @abstractmethod
    def inverse(self, c, *, near_r=None) -> np.ndarray:
        """Robot state of cluster state ``c``: ``r = INVKIN(c)``, shape ``(..., n_r)``.

        ``near_r`` (a robot state, ``(..., n_r)``) picks the branch where the inverse is not
        unique (the robots' yaws are unwrapped to within pi of its).
        """

    @abstractmethod
    def cluster_rate(self, r, r_dot, *, near_c=None) -> np.ndarray:
        """``c_dot = J(r) r_dot`` at ``c = forward(r, near_c=near_c)``: the rate of the cluster
        state as the robots move at ``r_dot``.

        Parameters
        ----------
        r : array_like, shape (..., n_r)
        r_dot : array_like, shape (..., n_r)
            Robot rates (m/s, rad/s); broadcast against ``r``.
        near_c : array_like, shape (..., n_c), optional
            As in :meth:`forward`.

        Returns
        -------
        ndarray, shape (broadcast of the batch axes) + (n_c,)
        """

    @abstractmethod
    def robot_rate(self, c, c_dot, *, r=None) -> np.ndarray:
        """``r_dot = dINVKIN(c) c_dot``: the robots' rates of the cluster rate ``c_dot``.

        Finite for every reachable state; where the representation is singular the map
        loses rank instead of blowing up.

        Parameters
        ----------
        c : array_like, shape (..., n_c)
        c_dot : array_like, shape (..., n_c)
            Broadcast against ``c``.
        r : array_like, shape (..., n_r), optional
            The robots of ``c``, for a description whose inverse has several branches.

        Returns
        -------
        ndarray, shape (broadcast of the batch axes) + (n_r,)
        """

    @staticmethod
    def _basis(n, batch_ndim):
        """The ``n`` unit vectors on a leading axis, ``(n, 1, ..., 1, n)``, to broadcast against a batch."""
        return np.eye(n).reshape((n,) + (1,) * batch_ndim + (n,))

    def jacobian(self, r, *, near_c=None) -> np.ndarray:
        """``J`` with ``c_dot = J(r) r_dot`` at ``c = forward(r, near_c=near_c)``, shape ``(..., n_c, n_r)``.

        :meth:`cluster_rate` applied to the unit vectors (one batched call).
        """
        r = self.check_robot_state(r)
        cols = self.cluster_rate(r, self._basis(self.n_r, r.ndim - 1), near_c=near_c)
        return np.ascontiguousarray(np.moveaxis(cols, 0, -1))

    def inverse_jacobian_at(self, c, *, r=None) -> np.ndarray:
        """Derivative of ``INVKIN`` at the cluster state ``c``; ``r``, the robots of ``c``,
        picks the branch where ``INVKIN`` has several (shape ``(..., n_r, n_c)``).

        :meth:`robot_rate` applied to the unit vectors (one batched call).
        """
        c = np.asarray(c, dtype=float)
        cols = self.robot_rate(c, self._basis(self.n_c, c.ndim - 1), r=r)
        return np.ascontiguousarray(np.moveaxis(cols, 0, -1))

    def inverse_jacobian(self, r, *, near_c=None) -> np.ndarray:
        """Derivative of ``INVKIN`` at ``c = forward(r, near_c=near_c)``, shape ``(..., n_r, n_c)``.

        The matrix the seed's controllers use to turn cluster rates into robot rates:
        ``r_dot = J^-1 c_dot``. It is finite for every reachable state; where the
        representation is singular it loses rank instead of blowing up.
        """
        r = self.check_robot_state(r)
        return self.inverse_jacobian_at(self.forward(r, near_c=near_c), r=r)

    @abstractmethod
    def to_chart(self, c, *, near_e=None, r=None) -> np.ndarray:
        """The operator's chart variables (:attr:`chart_variables`) of the cluster state ``c``,
        shape ``(..., len(chart_variables))``.

        ``near_e``: chart variables to stay closest to (the desired ones, for monitoring);
        ``r``: the robots of ``c``, for a description whose state does not fix them.
        """

    @abstractmethod
    def from_chart(self, e, e_dot=None):
        """Cluster state (and rate) of chart variables ``e`` (and rates ``e_dot``).

        The one place where a motion stated in the operator's variables becomes a motion
        of this representation. Angles in ``e`` may be unwrapped (``gamma_c`` from 0 to
        ``2 pi``); the result is continuous wherever ``e`` is.

        Returns
        -------
        c : ndarray, shape (..., n_c)
            If ``e_dot`` is None.
        (c, c_dot) : tuple of ndarray
            Otherwise.
        """

    def euclidean(self, c, *, near_e=None, r=None) -> np.ndarray:
        """Alias of :meth:`to_chart` (the name of the README and of seed 000's variables)."""
        return self.to_chart(c, near_e=near_e, r=r)

    def from_euclidean(self, e, e_dot=None):
        """Alias of :meth:`from_chart` (the name of the README and of seed 000's variables)."""
        return self.from_chart(e, e_dot)

    # -- reachable set, samples, special sets -----------------------------------------
    def reachable(self, r) -> np.ndarray:
        """Where the robot state ``r`` (..., n_r) is inside the description (its forward map
        exists): a bool array (...). Raises nothing. Every state, unless a subclass says
        otherwise."""
        return np.ones(np.shape(r)[:-1], dtype=bool)

    def sample_robot_state(self, rng, batch=()) -> np.ndarray:
        """Random valid robot states, shape ``batch + (n_r,)``: positions within a few metres,
        robots at least 0.3 m apart, yaws wound over several turns (+-20 rad); inside
        :meth:`reachable` where a description has a reachable set."""
        batch = (int(batch),) if isinstance(batch, (int, np.integer)) else tuple(batch)
        L = self.layout
        flat = np.array([POINT_KINDS[k].position == (0, 1) for k in L.kinds])  # planar robots: z = 0

        def draw(shape):
            q = rng.uniform(-2.0, 2.0, shape)
            q[..., flat, 2] = 0.0
            return q

        p = draw(batch + (L.n, 3))
        i, j = L.pairs
        for _ in range(100):  # push apart robots closer than 0.3 m (rare)
            d = np.linalg.norm(p[..., i, :] - p[..., j, :], axis=-1)
            close = d < 0.3
            if not np.any(close):
                break
            p = np.where(np.any(close, axis=-1)[..., None, None], draw(p.shape), p)
        yaws = rng.uniform(-20.0, 20.0, batch + (len(L.yaw_indices),))
        q = rng.normal(size=batch + (len(L.orientation_index), 4))
        return L.compose(p, yaws, q / np.linalg.norm(q, axis=-1, keepdims=True))

    def special_sets(self) -> tuple[SpecialSet, ...]:
        """The description's special sets (:class:`SpecialSet`): where its formulas divide by
        zero, take an undefined angle or meet ``q`` versus ``-q``, and what it does there."""
        return ()

    # -- the controllers' component path ---------------------------------------------------
    #: Whether the description overrides :meth:`forward_components` and
    #: :meth:`robot_rate_components` with component kernels (then a controller runs on
    #: floats for one formation); otherwise a controller runs on arrays.
    component_kernels = False

    def forward_components(self, rc, near_c, stage=None):
        """Measured cluster state for a controller: ``(c, rc)`` as tuples of components
        (Python floats for one formation, arrays for a batch), with ``rc`` the robot state
        the cluster state is of (a description may wind its yaws onto ``near_c``'s branch).
        ``stage`` (optional): a compiled loop's hold of intermediate components
        (:meth:`~quatform.control.cluster.ClusterController.chain`). Only a description with
        :attr:`component_kernels` offers it."""
        raise NotImplementedError(f"{type(self).__name__} has no component kernels (component_kernels = False): "
                                  "a controller runs it on arrays")

    def error_components(self, c, c_des):
        """The error components a law reads where the description wraps angles
        (:meth:`errors`), or None where ``c - c_des`` is the error of every non-quaternion
        variable (no angle among them)."""
        from .pair_kernels import pack, unpack

        if not self.wraps_angles:
            return None
        return unpack(self.errors(np.asarray(pack(c), dtype=float), np.asarray(pack(c_des), dtype=float)))

    @functools.cached_property
    def wraps_angles(self) -> bool:
        """Whether a cluster variable is an angle (its error is wrapped, :meth:`errors`)."""
        return any(v.kind == "angle" for v in self.variables)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` of checked arrays of any namespace (NumPy, JAX), for a controller of a
        description without component kernels; no check. Only a description that runs on
        another array namespace offers it."""
        raise NotImplementedError(f"{type(self).__name__} has no forward_arrays: it runs on NumPy arrays only")

    def robot_rate_components(self, c, c_dot, rc):
        """:meth:`robot_rate` on components, for a controller (the robot rates that move the
        cluster state ``c`` of the robots ``rc`` at ``c_dot``). Only a description with
        :attr:`component_kernels` offers it."""
        raise NotImplementedError(f"{type(self).__name__} has no component kernels (component_kernels = False): "
                                  "a controller runs it on arrays")

    def align(self, r, r_ref) -> np.ndarray:
        """``r`` with each robot yaw moved by whole turns to within pi of ``r_ref``'s
        (:meth:`RobotLayout.wind`).

        The robots' physical state is unchanged; the descriptions that read yaws as real
        numbers (the dual-quaternion half-way yaw) then see the same sheet as the
        reference. Fast path for one state (Python floats).
        """
        return self.layout.wind(r, r_ref)

    def errors(self, c, c_des) -> np.ndarray:
        """Per-variable error ``c - c_des`` with angles wrapped to ``[-pi, pi)``."""
        if not concrete(c):  # another array namespace (JAX): the same rule, selected
            return wrap_entries(c - c_des, np.flatnonzero(self._angle_mask))
        e = np.asarray(c) - np.asarray(c_des)
        ang = [i for i, v in enumerate(self.variables) if v.kind == "angle"]
        if ang:
            e[..., ang] = wrap_angle(e[..., ang])
        return e

    @functools.cached_property
    def _angle_mask(self) -> np.ndarray:
        return np.array([v.kind == "angle" for v in self.variables], dtype=bool)

    def length_scale(self, r) -> np.ndarray:
        """Size of the formation (m), used to make Jacobians dimensionless: half the largest
        separation of two robots (``d_c`` of a pair); for more than :data:`_ALL_PAIRS_UP_TO`
        robots the largest distance from the centroid (O(N), within a factor 2 of it).
        Shape ``(...)``; any array namespace."""
        xp = array_namespace(r)
        p = team_positions(self.layout, r)
        if self.layout.n > _ALL_PAIRS_UP_TO:  # O(N): the largest distance from the centroid
            return xp.max(xp.linalg.norm(p - xp.mean(p, axis=-2, keepdims=True), axis=-1), axis=-1)
        i, j = self.layout.pairs
        return 0.5 * xp.max(xp.linalg.norm(p[..., i, :] - p[..., j, :], axis=-1), axis=-1)

    #: Whether :meth:`to_chart_arrays` runs on any array namespace (NumPy, JAX under ``jax.jit``).
    chart_on_arrays = False

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of checked arrays of any namespace, for a description with
        :attr:`chart_on_arrays`."""
        raise NotImplementedError(f"{type(self).__name__} has no to_chart_arrays: its chart runs on NumPy arrays only")

    #: Whether :meth:`singularity_measure_arrays` runs on any array namespace (NumPy, JAX under
    #: ``jax.jit``): the description's :meth:`forward_arrays` and :meth:`inverse_jacobian_arrays` do.
    singularity_on_arrays = False

    def singularity_measure(self, r, *, near_c=None) -> np.ndarray:
        """Reciprocal condition number of the inverse Jacobian, in ``[0, 1]``; 0 at a singular pose.

        Taken on the normalised formation: robot positions moved so that their centroid is
        at the origin and divided by :meth:`length_scale`, so the value depends on the
        formation's shape and attitude only, not on where it is, how big, or the unit
        (:meth:`normalised`). :meth:`singularity_measure_arrays` is the same measure on any
        array namespace (equal within rounding).

        Returns
        -------
        ndarray, shape (...)
        """
        s = np.linalg.svd(self.inverse_jacobian(self.normalised(r), near_c=near_c), compute_uv=False)
        return s[..., -1] / s[..., 0]

    def singularity_measure_arrays(self, r, near_c=None):
        """:meth:`singularity_measure` of checked robots ``r`` on any array namespace, for a
        description with :attr:`singularity_on_arrays`: the singular values of
        :meth:`inverse_jacobian_arrays` at ``forward_arrays(normalised_arrays(r), near_c)``."""
        rn = self.normalised_arrays(r)
        J = self.inverse_jacobian_arrays(self.forward_arrays(rn, near_c), rn)
        s = array_namespace(J).linalg.svd(J, compute_uv=False)
        return s[..., -1] / s[..., 0]

    def inverse_jacobian_arrays(self, c, r=None):
        """:meth:`inverse_jacobian_at` (``(..., n_r, n_c)``) of checked arrays of any namespace
        (``r``: the robots of ``c``, for a description whose rates read them): its
        ``robot_rate_arrays`` (:meth:`robot_rate` without its checks, on NumPy or JAX arrays)
        on the unit vectors."""
        rate = getattr(self, "robot_rate_arrays", None)
        if rate is None:
            raise NotImplementedError(f"{type(self).__name__} has no inverse_jacobian_arrays: its singularity measure "
                                      "runs on NumPy arrays only")
        xp = array_namespace(c)
        basis = xp.asarray(self._basis(self.n_c, c.ndim - 1))
        cols = rate(c, basis, r=r) if self.rates_read_robots else rate(c, basis)
        return xp.moveaxis(cols, 0, -1)

    #: Whether ``robot_rate_arrays`` takes the robots ``r`` of ``c`` (``r=``).
    rates_read_robots = False

    def value_spread(self, r, delta, *, near_c=None) -> np.ndarray:
        """How far :meth:`forward`'s values at ``r`` can move when every entry of ``r`` moves by at
        most ``delta``: the first-order bound of the conditioning (``docs/derivations.md``,
        Formations: how many digits a chart's value carries).

        On the normalised formation (:meth:`normalised`: positions over ``L =``
        :meth:`length_scale`, angles kept) ``|dc| <= |dr| / sigma_min(J^-1)`` and
        ``sigma_min(J^-1) = s sigma_max(J^-1) >= s``, ``s`` the :meth:`singularity_measure`
        (``sigma_max >= 1``: the cluster's position moves every robot's point with it). With
        ``|dr| <= sqrt(n_r) delta max(1, 1 / L)``, each value moves by at most ``sqrt(n_r) delta
        max(1, 1 / L) / s``, times ``L`` for those in metres. Near a singular set (``s -> 0``)
        the bound grows as ``1 / s``: an angle that a singular pose leaves undefined (the
        spherical ``alpha_c`` over the UGV, ``beta_c`` of a vertical segment) carries fewer
        digits the closer the robots are to it; on the set itself its value is the
        description's convention (the reference's, ``near_c`` / ``near_e``). First order:
        valid while ``delta`` is small against the distance to the set, ``s L``.

        Parameters
        ----------
        r : array_like, shape (..., n_r)
        delta : float or array_like, shape (...)
            Largest change of an entry of ``r`` (m for positions, rad for angles).
        near_c : array_like, shape (..., n_c), optional
            As for :meth:`singularity_measure`.

        Returns
        -------
        ndarray, shape (..., n_c)
            In each variable's unit (m or rad); ``inf`` where ``s = 0``, beyond a turn for an
            undefined angle on a singular set (``s`` there is rounding).
        """
        r = self.check_robot_state(r)
        delta = np.asarray(delta, dtype=float)
        if not np.all(np.isfinite(delta)) or np.any(delta < 0):
            raise InvalidInputError(f"value_spread: delta must be finite and >= 0, got {delta!r}")
        L = self.length_scale(r)
        s = self.singularity_measure(r, near_c=near_c)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(s > 0, np.sqrt(self.n_r) * delta * np.maximum(1.0, 1.0 / L) / s, np.inf)
        metres = np.array([v.unit == "m" for v in self.variables])
        return step[..., None] * np.where(metres, L[..., None], 1.0)

    def normalised(self, r) -> np.ndarray:
        """The robots ``r`` with their centroid at the origin and positions divided by
        :meth:`length_scale` (yaws and orientations kept): the formation on which
        :meth:`singularity_measure` is taken. A team with planar (``xy_yaw``) robots is moved
        horizontally only: they stay on the ground (``z = 0``), which scaling keeps.

        Robots on each other (a length scale below :data:`MIN_SEPARATION_M`, nothing to divide
        by) are refused as :meth:`forward` refuses them: :meth:`check_apart` names them.
        """
        return self.normalised_arrays(self._checked_apart(r))

    def _checked_apart(self, r) -> np.ndarray:
        """``r`` checked, robots on each other refused (a length scale below :data:`MIN_SEPARATION_M`)."""
        r = self.check_robot_state(r)
        if np.any(self.length_scale(r) < MIN_SEPARATION_M):
            self.check_apart(r)
        return r

    def normalised_arrays(self, r):
        """:meth:`normalised` of checked robots on any array namespace (no check)."""
        xp, L = array_namespace(r), self.layout
        p = team_positions(L, r)
        centre = xp.mean(p, axis=-2, keepdims=True)
        if "xy_yaw" in L.kinds:  # planar robots stay on the ground
            centre = centre * np.array([1.0, 1.0, 0.0])
        compose = L.compose if xp is np else functools.partial(team_compose, L)  # NumPy's in C order
        return compose((p - centre) / self.length_scale(r)[..., None, None], r[..., list(L.yaw_indices)],
                       r[..., L.orientation_index])


class Preset:
    """A team description with fixed constructor arguments, e.g. ``class EuclideanPair(Preset,
    EuclideanTeam)`` with ``arguments = {"n": 2, "chart": "pair"}``: built without arguments,
    its one example that instance, a formation of its own :attr:`~Formation.key` in
    :data:`FORMATION_TYPES` (so the contract test runs it) but no team description of
    :data:`TEAM_FORMATIONS` (``team = False``) and so no second team controller. Put it first
    among the bases."""

    team = False
    #: The keyword arguments of the team description's constructor.
    arguments: Mapping = {}

    def __init__(self):
        super().__init__(**self.arguments)

    @classmethod
    def examples(cls) -> dict:
        return {cls.key: cls()}

    def __repr__(self):
        return f"{type(self).__name__}()"


_EXAMPLES: dict[type, dict] = {}


def _examples() -> dict:
    """Every registered description's :meth:`Formation.examples` by key (each class's built once)."""
    out = {}
    for cls in list(FORMATION_TYPES.values()):
        if cls not in _EXAMPLES:
            _EXAMPLES[cls] = cls.examples()
        out.update(_EXAMPLES[cls])
    return out


#: Every description by a unique key (the examples of :data:`FORMATION_TYPES`): the two-robot
#: ones of seed 000 by their name (``euclidean``, ``robot``, ``quaternion``,
#: ``dual-quaternion``), the UGV-UAV ones of seed 001 as ``ugv-uav-<name>``, the team ones
#: on a mixed layout each.
FORMATIONS: Mapping = RegistryView(_examples, "FORMATIONS")
#: The team descriptions (N robots of any point kinds) by key, as classes:
#: ``TEAM_FORMATIONS[key](n=None, *, layout=None, template=None)``.
TEAM_FORMATIONS: Mapping = RegistryView(lambda: {k: c for k, c in FORMATION_TYPES.items() if c.team},
                                          "TEAM_FORMATIONS")
