"""The formation interface: one contract for every cluster-space representation.

Second layer of quatform (above :mod:`quatform.algebra`). A formation maps the stacked
robot state ``r`` (shape ``(..., n_r)``) to the cluster state ``c`` (shape ``(..., n_c)``)
and back, gives the Jacobians the controllers need, says how close a state is to a
singular pose, and converts its state to operator-friendly Euclidean variables. The
controllers, the references and the simulator only use this interface, so an N-robot
representation plugs in by subclassing :class:`Formation`.

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
import math
from abc import ABC, abstractmethod

import numpy as np

from ..algebra import wrap_angle
from ..algebra.validate import as_array
from ..errors import DegenerateInputError, InvalidInputError
from .layout import RobotLayout, Variable

__all__ = ["Variable", "Formation", "ROBOT_PAIR_VARIABLES", "MIN_SEPARATION_M", "MAX_MAGNITUDE"]

_TWO_PI = 2.0 * math.pi

#: Closest two robots may be (m); below it a two-robot formation is undefined.
MIN_SEPARATION_M = 1e-9
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


def _robot_pair_variables():
    out = []
    for i in (1, 2):
        out += [Variable(f"x{i}", "m", "position"), Variable(f"y{i}", "m", "position"),
                Variable(f"z{i}", "m", "position"), Variable(f"theta{i}", "rad", "angle")]
    return tuple(out)


#: Robot space of two 4-DOF robots: ``r = (x1, y1, z1, theta1, x2, y2, z2, theta2)``.
ROBOT_PAIR_VARIABLES = _robot_pair_variables()


@functools.lru_cache(maxsize=None)
def _angle_indices(variables):
    return tuple(i for i, v in enumerate(variables) if v.kind == "angle")


def quaternion_variables(prefix: str):
    return tuple(Variable(f"{prefix}_{c}", "1", "quaternion") for c in "wxyz")


class Formation(ABC):
    """Cluster-space representation of a team of robots.

    Subclasses set :attr:`name`, :attr:`variables` and implement the abstract methods.
    Every method accepts leading batch axes.
    """

    #: Short name used on the command line and in files.
    name: str = ""
    #: Layout of the cluster state vector.
    variables: tuple[Variable, ...] = ()
    #: Layout of the robot state vector.
    robot_variables: tuple[Variable, ...] = ROBOT_PAIR_VARIABLES

    @property
    def n_c(self) -> int:
        return len(self.variables)

    @property
    def n_r(self) -> int:
        return len(self.robot_variables)

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

    @staticmethod
    def _check_separation(delta, name="r"):
        d = np.sqrt(np.einsum("...i,...i->...", delta, delta))
        if np.any(d < MIN_SEPARATION_M):
            idx = np.argwhere(np.atleast_1d(d < MIN_SEPARATION_M))[0]
            raise DegenerateInputError(
                f"{name}: the two robots coincide (separation {float(np.atleast_1d(d)[tuple(idx)]):.3g} m"
                f" at index {tuple(int(i) for i in idx)}); a formation of two robots needs them apart"
            )
        return d

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
    def jacobian(self, r, *, near_c=None) -> np.ndarray:
        """``J`` with ``c_dot = J(r) r_dot`` at ``c = forward(r, near_c=near_c)``, shape ``(..., n_c, n_r)``."""

    def inverse_jacobian(self, r, *, near_c=None) -> np.ndarray:
        """Derivative of ``INVKIN`` at ``c = forward(r, near_c=near_c)``, shape ``(..., n_r, n_c)``.

        The matrix the seed's controllers use to turn cluster rates into robot rates:
        ``r_dot = J^-1 c_dot``. It is finite for every reachable state; where the
        representation is singular it loses rank instead of blowing up.
        """
        r = self.check_robot_state(r)
        return self.inverse_jacobian_at(self.forward(r, near_c=near_c), r=r)

    @abstractmethod
    def inverse_jacobian_at(self, c, *, r=None) -> np.ndarray:
        """Derivative of ``INVKIN`` at the cluster state ``c``; ``r``, the robots of ``c``,
        picks the branch where ``INVKIN`` has several (shape ``(..., n_r, n_c)``)."""

    #: The operator's chart: the variables :meth:`to_chart` gives and :meth:`from_chart`
    #: takes (the seed-000 Euclidean variables for pairs, the spherical ones for UGV-UAV).
    chart_variables: tuple[Variable, ...] = ()

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

    def align(self, r, r_ref) -> np.ndarray:
        """``r`` with each robot yaw moved by whole turns to within pi of ``r_ref``'s.

        The robots' physical state is unchanged; the descriptions that read yaws as real
        numbers (the dual-quaternion half-way yaw) then see the same sheet as the
        reference. Fast path for one state (Python floats).
        """
        idx = _angle_indices(self.robot_variables)
        if r.ndim == 1 and r_ref.ndim == 1:
            out = r.tolist()
            ref = r_ref.tolist()
            for i in idx:
                out[i] += _TWO_PI * math.floor((ref[i] - out[i]) / _TWO_PI + 0.5)
            return np.array(out)
        out = np.array(np.broadcast_to(r, np.broadcast_shapes(r.shape, r_ref.shape)), dtype=float)
        for i in idx:
            out[..., i] += _TWO_PI * np.floor((r_ref[..., i] - out[..., i]) / _TWO_PI + 0.5)
        return out

    def errors(self, c, c_des) -> np.ndarray:
        """Per-variable error ``c - c_des`` with angles wrapped to ``[-pi, pi)``."""
        e = np.asarray(c) - np.asarray(c_des)
        ang = [i for i, v in enumerate(self.variables) if v.kind == "angle"]
        if ang:
            e[..., ang] = wrap_angle(e[..., ang])
        return e

    def length_scale(self, r) -> np.ndarray:
        """Size of the formation (m), used to make Jacobians dimensionless. Shape ``(...)``."""
        r = np.asarray(r)
        return 0.5 * np.linalg.norm(r[..., 0:3] - r[..., 4:7], axis=-1)

    def singularity_measure(self, r, *, near_c=None) -> np.ndarray:
        """Reciprocal condition number of the inverse Jacobian, in ``[0, 1]``; 0 at a singular pose.

        Taken on the normalised formation: robot positions moved so that their centroid is
        at the origin and divided by :meth:`length_scale`, so the value depends on the
        formation's shape and attitude only, not on where it is, how big, or the unit.

        Returns
        -------
        ndarray, shape (...)
        """
        r = self.check_robot_state(r)
        pos = [i for i, v in enumerate(self.robot_variables) if v.kind == "position"]
        rn = np.array(r, dtype=float)
        if pos:
            L = self.length_scale(r)[..., None]
            p = rn[..., pos].reshape(r.shape[:-1] + (-1, 3))
            p = (p - p.mean(axis=-2, keepdims=True)) / L[..., None]
            rn[..., pos] = p.reshape(r.shape[:-1] + (len(pos),))
        s = np.linalg.svd(self.inverse_jacobian(rn, near_c=near_c), compute_uv=False)
        return s[..., -1] / s[..., 0]
