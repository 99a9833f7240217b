"""Pioneer 3-DX: a unicycle driven through a control point ahead of its wheel axis (seed 001 §3.1.1).

Robots layer. State ``(x, y, psi)``: the control point, a distance ``a`` ahead of the
middle of the wheel axis, and the heading. Commands ``(v, omega)``, eq. (3.1). The
control point moves by eq. (3.4), ``[x_dot, y_dot] = A_p [v, omega]`` with ``A_p`` of
eq. (3.2); the controller inverts it, eqs. (3.3), (3.5). A step integrates the unicycle
exactly for a command held over the step. As a robot model (:mod:`quatform.robots.model`)
it offers a formation its control point at the height ``z`` of its landing platform (point
kind ``xyz``, the default) or, with ``point_kind = "xy_yaw"``, its control point and heading
``(x, y, psi)`` as a planar point. The heading is then carried in the formation
but not commanded: the unicycle moves its control point with both of its inputs (eq. (3.5))
and its heading follows.

For a command held over a step of ``dt`` the control point's mean velocity is
``sinc(theta/2) R(psi + theta/2) (v, a omega)``, ``theta = omega dt``, and its inverse is
closed form (:meth:`Pioneer.mean_point_velocity`, :meth:`Pioneer.commands_from_mean_velocity`;
``docs/derivations.md``, "Robot models"): what a sampled-time safety filter needs.

Its actuation, point velocities, limits and step are written once on array components, so
they run on NumPy and on JAX arrays (under ``jax.jit``, the compute backend's loop) alike
(:func:`quatform.algebra.kernels.array_namespace`); on NumPy the step also checks its state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats as _floats
from ..algebra.kernels import concrete
from ..algebra.validate import as_array
from ..checks import number
from ..errors import InvalidInputError
from .model import RobotModel
from .point_map import PointMap
from .ros_io import RobotIO, pose_yaw, xy_vector, z_vector

__all__ = ["Pioneer", "UnicyclePointMap"]

#: Bisection steps of the sampled-time limit factor (relative accuracy 2^-48).
_BISECTION_STEPS = 48


# ROS 2 conversions (seed 001 §3.1.1): the control point (x, y, psi); commands (v, omega), eq. (3.1)
def _ros_state(model, pose, prev):
    psi = pose_yaw(pose, None if prev is None else prev[2])
    # the control point, a ahead of the middle of the wheel axis (the pose's origin), Fig. 10
    return np.array([pose.position[0] + model.a * np.cos(psi), pose.position[1] + model.a * np.sin(psi), psi])


def _ros_body(model, u, state, q):
    return xy_vector(u[..., 0], 0.0), z_vector(u[..., 1])



class UnicyclePointMap(PointMap):
    """The Pioneer's control point for the separation barrier: its velocity by seed 001 eq.
    (3.4), the commands of a velocity by eq. (3.5), as the Robotarium's unicycle certificate
    moves a point ahead of the wheel axis; with ``dt`` the exact mean velocity over the held
    step (:meth:`Pioneer.mean_point_velocity`) and its inverse, so the barrier's sampled-time
    argument holds for it too. The point moves at the platform height (planar)."""

    planar = True

    def velocity(self, model, x, u, dt):
        psi = x[..., 2]
        v = model.point_velocity(psi, u) if dt is None else model.mean_point_velocity(psi, u, dt)
        xp = namespace(v)
        return xp.concatenate([v, xp.zeros(v.shape[:-1] + (1,))], axis=-1)

    def commands(self, model, x, u, v, dt):
        psi = x[..., 2]
        if dt is None:
            return model.commands_from_velocity(psi, v[..., 0:2])  # eq. (3.5)
        return model.commands_from_mean_velocity(psi, v[..., 0:2], dt)

    def scaled(self, model, x, u_new, v, s, dt):
        if dt is None:  # eq. (3.5) is linear: scaling the commands scales the point velocity
            return s[..., None] * u_new
        return model.commands_from_mean_velocity(x[..., 2], s[..., None] * v[..., 0:2], dt)

    def factor(self, model, x, u_new, v, dt):
        if dt is None:
            return model.limit_factor(u_new)
        # sampled time: the largest s with commands_from_mean_velocity(s v) within the limits.
        # The turn: |tan(theta/2)| = |s V_l| / (2 a / dt + s V_f) <= tan(max_omega dt / 2), closed form;
        # the speed by bisection below that (|v| grows with s).
        psi = x[..., 2]
        c, sn = np.cos(psi), np.sin(psi)
        vf = c * v[..., 0] + sn * v[..., 1]
        vl = -sn * v[..., 0] + c * v[..., 1]
        tan_max = math.tan(min(0.5 * model.max_omega * dt, 0.5 * math.pi - 1e-9))
        den = np.abs(vl) - tan_max * vf
        with np.errstate(divide="ignore", invalid="ignore"):
            s_turn = np.where(den > 0, tan_max * 2.0 * model.a / dt / np.where(den > 0, den, 1.0), np.inf)
        hi = np.where(s_turn < 1.0, s_turn * (1.0 - 1e-12), 1.0)  # a hair inside a binding turn limit

        def speed_ok(s):
            u = model.commands_from_mean_velocity(psi, s[..., None] * v[..., 0:2], dt)
            return np.abs(u[..., 0]) <= model.max_v

        lo = np.where(speed_ok(hi), hi, 0.0)
        top = hi.copy()
        if np.any(lo < top):
            for _ in range(_BISECTION_STEPS):
                mid = 0.5 * (lo + top)
                ok = speed_ok(mid)
                lo, top = np.where(ok, mid, lo), np.where(ok, top, mid)
        return lo


@dataclass(frozen=True)
class Pioneer(RobotModel):
    """Unicycle with control point ahead of the axis.

    Parameters
    ----------
    a : float
        Distance from the middle of the wheel axis to the control point, m (seed 001:
        0.15 m).
    max_v : float
        Largest ``|v|``, m/s. The Pioneer 3-DX's rated top speed is 1.2 m/s; 0.75 m/s is a
        lab limit chosen here for a 6 x 4 m arena (the thesis does not give its own).
    max_omega : float
        Largest ``|omega|``, rad/s (100 deg/s, chosen likewise).
    z : float
        Height of the point it offers a formation (the landing platform), m.
    point_kind : str
        The point it offers a formation: ``"xyz"`` (control point at height ``z``, the
        default) or ``"xy_yaw"`` (control point and heading; the heading rate a formation
        asks for is not commanded, see the module docstring).
    """

    a: float = 0.15
    max_v: float = 0.75
    max_omega: float = 100.0 * math.pi / 180.0
    z: float = 0.0
    point_kind: str = "xyz"

    name = "pioneer"
    state_columns = ("x", "y", "psi")
    command_columns = ("v", "omega")
    column_units = {"x": "m", "y": "m", "psi": "rad", "v": "m/s", "omega": "rad/s"}
    #: Entries of the rate :meth:`actuate` takes: the point's (its z rate is ignored).
    n_rate = 3
    #: Its commands are not its point's rates (eq. (3.5) maps them).
    passthrough = False
    #: Not holonomic: it saturates on its own in a team (its point velocity turns with it).
    holonomic = False
    #: Team files: ``pioneer``, offering its control point and heading (``xy_yaw``): a
    #: unicycle whose heading follows its control point.
    file_names = ("pioneer",)
    limit_keys = ("a_m", "max_v_m_s", "max_omega_rad_s")
    ros_io = RobotIO("Pioneer 3-DX (v, omega)", "body", _ros_state, _ros_body)
    #: The separation barrier moves its control point (eqs. (3.4)-(3.5)).
    point_map = UnicyclePointMap()
    #: MuJoCo drives it as the Pioneer 3-DX-like differential-drive robot of the UGV-UAV plant.
    physics_kind = "diff-drive"

    @classmethod
    def from_file(cls, table, where, place, file_name="pioneer"):
        return cls(a=number(table, "a_m", where, 0.15, place=place, low=0.0, low_open=True),
                   max_v=number(table, "max_v_m_s", where, 0.75, place=place, low=0.0, low_open=True),
                   max_omega=number(table, "max_omega_rad_s", where, 100.0 * math.pi / 180.0, place=place, low=0.0,
                                    low_open=True),
                   point_kind="xy_yaw")

    def __post_init__(self):
        if self.point_kind not in ("xyz", "xy_yaw"):
            raise InvalidInputError(f"Pioneer point_kind must be 'xyz' or 'xy_yaw', got {self.point_kind!r}")
        if not np.isfinite(self.z):
            raise InvalidInputError(f"Pioneer z must be finite, got {self.z!r}")
        for name in ("a", "max_v", "max_omega"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInputError(f"Pioneer {name} must be positive and finite, got {v!r}")

    def point(self, x) -> np.ndarray:
        """``(x, y, z)``: the control point at the platform height, shape ``(..., 3)``; with
        ``point_kind = "xy_yaw"`` the state ``(x, y, psi)`` itself."""
        x = _floats(x)
        if self.point_kind == "xy_yaw":
            return x
        xp = namespace(x)
        return xp.stack([x[..., 0], x[..., 1], xp.full(x.shape[:-1], self.z)], axis=-1)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """``(v, omega)`` that move the control point at the world rate ``rate[..., 0:2]``,
        eq. (3.5) (:meth:`commands_from_velocity`), and ``memory`` unchanged. The third entry
        (the point's z rate, or the heading rate of an ``xy_yaw`` point) is not commanded."""
        x, rate = _floats(x), _floats(rate)
        return self.commands_from_velocity(x[..., 2], rate[..., 0:2]), memory

    def brake(self, x, memory=None):
        """Commands that stop the robot: zero, shape ``(..., 2)``."""
        return np.zeros(np.shape(x)[:-1] + (2,)), memory

    def forward_matrix(self, psi) -> np.ndarray:
        """``A_p`` of eq. (3.2): ``[x_dot, y_dot] = A_p [v, omega]``, shape ``(..., 2, 2)``."""
        c, s = np.cos(psi), np.sin(psi)
        return np.stack([np.stack([c, -self.a * s], -1), np.stack([s, self.a * c], -1)], -2)

    def commands_from_velocity(self, psi, xy_dot) -> np.ndarray:
        """``[v, omega] = A_p^-1 [x_dot, y_dot]``, eqs. (3.3), (3.5); shape ``(..., 2)``.

        ``A_p`` has determinant ``a``: invertible for every heading.
        """
        xy_dot = _floats(xy_dot)
        xp = namespace(xy_dot)
        c, s = xp.cos(psi), xp.sin(psi)
        v = c * xy_dot[..., 0] + s * xy_dot[..., 1]
        w = (-s * xy_dot[..., 0] + c * xy_dot[..., 1]) / self.a
        return xp.stack([v, w], axis=-1)

    def point_velocity(self, psi, u) -> np.ndarray:
        """World velocity of the control point for the commands ``u = (v, omega)``, eq. (3.4):
        ``A_p u``, shape ``(..., 2)``."""
        u = _floats(u)
        xp = namespace(u)
        c, s = xp.cos(psi), xp.sin(psi)
        fw, lat = u[..., 0], self.a * u[..., 1]
        return xp.stack([c * fw - s * lat, s * fw + c * lat], axis=-1)

    def mean_point_velocity(self, psi, u, dt: float) -> np.ndarray:
        """Mean world velocity of the control point over ``dt`` s of the held command ``u``.

        Integrating eq. (3.4) with ``psi(t) = psi + omega t``: the displacement over the step
        is ``dt sinc(theta/2) R(psi + theta/2) (v, a omega)``, ``theta = omega dt``
        (``docs/derivations.md``, "Robot models"); it tends to :meth:`point_velocity` as
        ``dt -> 0``.

        Parameters
        ----------
        psi : array_like, shape (...)
        u : array_like, shape (..., 2)
        dt : float
            s, positive.

        Returns
        -------
        ndarray, shape (..., 2)
        """
        u = _floats(u)
        xp = namespace(u)
        half = 0.5 * dt * u[..., 1]
        k = xp.sinc(half / np.pi)
        c, s = xp.cos(psi + half), xp.sin(psi + half)
        fw, lat = k * u[..., 0], k * self.a * u[..., 1]
        return xp.stack([c * fw - s * lat, s * fw + c * lat], axis=-1)

    def commands_from_mean_velocity(self, psi, mean, dt: float) -> np.ndarray:
        """``(v, omega)`` whose held step of ``dt`` s moves the control point by ``dt mean``.

        The inverse of :meth:`mean_point_velocity`, closed form: with ``(V_f, V_l) =
        R(-psi) mean``, ``tan(theta/2) = V_l / (2 a / dt + V_f)``, ``omega = theta / dt`` and
        ``v = (cos(theta/2) V_f + sin(theta/2) V_l) / sinc(theta/2)``
        (``docs/derivations.md``, "Robot models"); eq. (3.5) as ``dt -> 0``. Valid while
        ``V_f > -2 a / dt`` (a mean speed far beyond any Pioneer's).

        Parameters
        ----------
        psi : array_like, shape (...)
        mean : array_like, shape (..., 2)
            m/s.
        dt : float
            s, positive.

        Returns
        -------
        ndarray, shape (..., 2)
        """
        mean = np.asarray(mean, dtype=float)
        c, s = np.cos(psi), np.sin(psi)
        vf = c * mean[..., 0] + s * mean[..., 1]
        vl = -s * mean[..., 0] + c * mean[..., 1]
        half = np.arctan2(vl, 2.0 * self.a / dt + vf)
        v = (np.cos(half) * vf + np.sin(half) * vl) / np.sinc(half / np.pi)
        return np.stack([v, 2.0 * half / dt], axis=-1)

    def limit_factor(self, u) -> np.ndarray:
        """Largest ``s`` in ``[0, 1]`` with ``s u`` within the limits (0 for a non-finite ``u``),
        shape ``(...)``: the factor :meth:`saturate` applies."""
        u, finite, s = self._scale(u)
        return namespace(u).where(finite, s, 0.0)

    def saturate(self, u) -> np.ndarray:
        """``(v, omega)`` scaled as a whole into the limits (path curvature kept); NaN -> 0."""
        u, _, s = self._scale(u)
        return u * s[..., None]

    def _scale(self, u):
        """``(u0, finite, s)``: ``u`` with its non-finite commands zeroed, which are finite
        (shape ``(...)``), and the factor ``min(1, max_v / |v|, max_omega / |omega|)`` of
        ``u0`` (1 for a zeroed command)."""
        u = _floats(u)
        xp = namespace(u)
        finite = xp.all(xp.isfinite(u), axis=-1)
        u = xp.where(finite[..., None], u, 0.0)
        with np.errstate(divide="ignore", over="ignore"):
            s = xp.minimum(self.max_v / xp.abs(u[..., 0]), self.max_omega / xp.abs(u[..., 1]))
        return u, finite, xp.minimum(1.0, s)

    def step(self, state, u, dt: float) -> np.ndarray:
        """State ``(x, y, psi)`` after ``dt`` s of the saturated command ``(v, omega)`` (exact arc)."""
        state = as_array(state, "Pioneer state", 3) if concrete(state) else state
        u = self.saturate(u)
        xp = namespace(u)
        v, w = u[..., 0], u[..., 1]
        x, y, psi = state[..., 0], state[..., 1], state[..., 2]
        # middle of the wheel axis moves on an arc; the control point follows rigidly
        cx, cy = x - self.a * xp.cos(psi), y - self.a * xp.sin(psi)
        psi1 = psi + w * dt
        small = xp.abs(w * dt) < 1e-9
        with np.errstate(divide="ignore", invalid="ignore"):
            R = xp.where(small, 0.0, v / xp.where(small, 1.0, w))
        dx = xp.where(small, v * dt * xp.cos(psi + 0.5 * w * dt), R * (xp.sin(psi1) - xp.sin(psi)))
        dy = xp.where(small, v * dt * xp.sin(psi + 0.5 * w * dt), -R * (xp.cos(psi1) - xp.cos(psi)))
        cx, cy = cx + dx, cy + dy
        return xp.stack([cx + self.a * xp.cos(psi1), cy + self.a * xp.sin(psi1), psi1], axis=-1)
