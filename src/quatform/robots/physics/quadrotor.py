"""An IRIS-like quadrotor for MuJoCo physics: its numbers, its MJCF, its autopilot.

Robots layer (physical models; no MuJoCo import). The vehicle is one free rigid body
with four rotor actuators; each rotor pushes along the body z axis and twists the body
about it by its drag moment (``k_m`` times its thrust, against its spin), with a
first-order motor lag. The numbers are those of the PX4 SITL ``iris`` model
(PX4-SITL_gazebo ``models/iris/iris.sdf``, the RotorS multirotor plug-in): they are the
vehicles seed 000 §4.2 flies in Gazebo (3DR IRIS under PX4).

:class:`QuadrotorCascade` is a PX4-style cascaded low-level controller:

* velocity mode (PX4 ``OFFBOARD`` velocity set points, what seed 000's formation
  controllers send): world velocity error -> desired acceleration (PI, PX4 defaults
  ``MPC_XY_VEL_P/I_ACC``, ``MPC_Z_VEL_P/I_ACC``) -> thrust vector with tilt limit ->
  attitude (body z along the thrust, heading kept) and collective thrust -> body-rate set
  point -> rate loop -> torques -> rotor forces by the mixer (:meth:`QuadrotorCascade.mix`:
  roll and pitch first, then the collective thrust, then as much yaw as fits);
* Bebop-like attitude mode (what seed 001's controller sends, eq. (3.6)): body-frame
  ``(u_x, u_y)`` in ``[-1, 1]`` are pitch and roll as fractions of a small tilt limit
  (seed 001 §3.1.2: +-5 deg), ``u_z`` a climb-rate and ``u_psi`` a yaw-rate fraction.
  A vehicle so driven behaves like eq. (3.11): ``x_ddot ~ g tan(5 deg) u_x - (rotor drag)
  x_dot``, which is why ``K1 ... K8`` can be identified from it.

The attitude error is the geometric one of Lee, Leok & McClamroch (2010),
``e_R = 1/2 vee(R_d^T R - R^T R_d)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import DegenerateInputError, InvalidInputError, NonFiniteError

__all__ = ["GRAVITY", "IRIS", "QuadrotorCascade", "QuadrotorParams", "quadrotor_mjcf"]

#: Standard gravity, m/s^2 (MuJoCo's default too).
GRAVITY = 9.81


@dataclass(frozen=True)
class QuadrotorParams:
    """Physical numbers of a quadrotor (SI units).

    Attributes
    ----------
    mass : float
        kg (iris.sdf ``base_link``: 1.5).
    inertia : tuple of 3 floats
        Principal moments about body x, y, z, kg m^2 (iris.sdf: 0.029125, 0.029125, 0.055225).
    rotors : tuple of 4 (x, y) pairs
        Rotor hub positions in the body frame, m (iris.sdf ``rotor_0..3``: (0.13, -0.22),
        (-0.13, 0.20), (0.13, 0.22), (-0.13, -0.20); "arm length" ~0.25 m).
    spin : tuple of 4 ints
        +1 for a rotor spinning counter-clockwise seen from above (iris: rotors 0, 1), -1
        clockwise (2, 3). Its drag moment on the body is ``-spin k_m f``.
    motor_constant : float
        Thrust per squared rotor speed, N s^2 (iris.sdf ``motorConstant``: 5.84e-6).
    moment_constant : float
        Drag moment per unit thrust, m (iris.sdf ``momentConstant``: 0.06).
    max_rotor_speed : float
        rad/s (iris.sdf ``maxRotVelocity``: 1100), so ``f_max = 5.84e-6 * 1100^2 = 7.07 N``
        per rotor, thrust-to-weight 1.9.
    motor_time_constant : float
        First-order motor lag, s (iris.sdf ``timeConstantUp``: 0.0125; its slower
        ``timeConstantDown`` 0.025 is not modelled: MuJoCo's filter has one constant).
    rotor_drag_coefficient : float
        In-plane rotor drag per rotor speed, N s / (m rad) (iris.sdf
        ``rotorDragCoefficient``: 8.06428e-5): ``F = -c sum_i(omega_i) v_perp``, linear in
        the body's in-plane velocity; at hover it is ~0.26 N s/m, a drag rate of 0.17 1/s,
        close to seed 001 Table 2's ``K2, K4`` (0.18, 0.17).
    rotor_radius : float
        m (the iris's 10-inch propellers: 0.127).
    leg_height : float
        Height of the body origin above the ground when landed, m.
    """

    mass: float = 1.5
    inertia: tuple = (0.029125, 0.029125, 0.055225)
    rotors: tuple = ((0.13, -0.22), (-0.13, 0.20), (0.13, 0.22), (-0.13, -0.20))
    spin: tuple = (1, 1, -1, -1)
    motor_constant: float = 5.84e-6
    moment_constant: float = 0.06
    max_rotor_speed: float = 1100.0
    motor_time_constant: float = 0.0125
    rotor_drag_coefficient: float = 8.06428e-5
    rotor_radius: float = 0.127
    leg_height: float = 0.12

    def __post_init__(self):
        for name in ("mass", "motor_constant", "moment_constant", "max_rotor_speed", "motor_time_constant",
                     "rotor_drag_coefficient", "rotor_radius", "leg_height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise InvalidInputError(f"QuadrotorParams {name} must be positive and finite, got {v!r}")
        try:
            inertia = np.asarray(self.inertia, dtype=float)
            rotors = np.asarray(self.rotors, dtype=float)
        except (TypeError, ValueError):
            raise InvalidInputError(f"QuadrotorParams inertia must be 3 numbers and rotors 4 (x, y) pairs, "
                                    f"got {self.inertia!r} and {self.rotors!r}") from None
        if inertia.shape != (3,) or not np.all(np.isfinite(inertia)) or np.any(inertia <= 0):
            raise InvalidInputError(f"QuadrotorParams inertia must be 3 positive moments, kg m^2, got {self.inertia!r}")
        if rotors.shape != (4, 2) or not np.all(np.isfinite(rotors)):
            raise InvalidInputError(f"QuadrotorParams rotors must be 4 finite (x, y) pairs, m, got {self.rotors!r}")
        if len(self.spin) != 4 or any(s not in (1, -1) for s in self.spin):
            raise InvalidInputError(f"QuadrotorParams spin must be 4 values of +1 or -1, got {self.spin!r}")
        if abs(np.linalg.det(self.mixer())) < 1e-9:
            raise DegenerateInputError(f"QuadrotorParams: rotors {self.rotors!r} with spins {self.spin!r} cannot "
                                       "give independent thrust, roll, pitch and yaw (singular mixer); place "
                                       "the rotors around the centre with two spinning each way")

    @property
    def max_thrust(self) -> float:
        """Largest thrust of one rotor, N."""
        return self.motor_constant * self.max_rotor_speed ** 2

    def mixer(self) -> np.ndarray:
        """``A`` with ``(T, tau_x, tau_y, tau_z) = A f`` for rotor forces ``f``, shape (4, 4).

        A force ``f`` along body z at ``(x, y, 0)`` has moment ``(y f, -x f, 0)``; the rotor's
        drag moment is ``-spin k_m f`` about z.
        """
        r = np.asarray(self.rotors, dtype=float)
        return np.array([np.ones(4), r[:, 1], -r[:, 0], -np.asarray(self.spin) * self.moment_constant])


#: The PX4 SITL iris (see :class:`QuadrotorParams`).
IRIS = QuadrotorParams()


def _floats(x) -> list:
    """A flat list of Python floats (rows first) from a list or an array."""
    return x if type(x) is list else np.ravel(x).tolist()


@dataclass
class QuadrotorCascade:
    """PX4-style cascaded low-level controller of one quadrotor (stateful: the velocity
    integrator). Its numbers are read once, when it is made (the loops run at the physics
    rate on each vehicle): for other numbers make another (``dataclasses.replace``), do not
    assign its fields.

    Parameters
    ----------
    params : QuadrotorParams
    vel_p, vel_i : (3,) gains, 1/s and 1/s^2
        Velocity PI (PX4 defaults: xy 1.8 / 0.4, z 4 / 2).
    tilt_max : float
        Largest tilt in velocity mode, rad (PX4 ``MPC_TILTMAX_AIR`` is 45 deg; 35 deg here).
    att_p : float
        Attitude gain, 1/s (PX4 ``MC_ROLL_P`` 6.5).
    rate_p : (3,) gains, 1/s
        Body-rate loop bandwidths (roll, pitch, yaw); torques are ``J rate_p (w_sp - w)``
        plus the gyroscopic term.
    bebop_tilt_max, bebop_climb_max, bebop_yaw_rate_max : float
        Full-scale commands of the Bebop-like attitude mode: tilt (rad; seed 001 §3.1.2:
        5 deg), climb rate (m/s) and yaw rate (rad/s).
    bebop_climb_p : float
        Climb-rate loop gain of the attitude mode, 1/s (PX4's ``MPC_Z_VEL_P_ACC`` = 4).
    yaw_rate_max : float
        Largest yaw-rate set point, rad/s (PX4 ``MC_YAWRATE_MAX``: 200 deg/s = 3.49 rad/s).
    thrust_headroom : float
        The collective thrust is capped at this fraction of the most the four rotors give
        together (0.85 of 4 f_max = 24.0 N for the iris, 1.63 m g), so roll and pitch keep
        at least 15 % of each rotor's range (PX4 likewise caps ``MPC_THR_MAX`` below full).
    thrust_xy_margin : float
        Velocity mode: the fraction of that cap kept for the horizontal demand when the
        vertical one would take it all (PX4 ``MPC_THR_XY_MARG``: 0.3).
    """

    params: QuadrotorParams = field(default_factory=QuadrotorParams)
    vel_p: tuple = (1.8, 1.8, 4.0)
    vel_i: tuple = (0.4, 0.4, 2.0)
    vel_i_limit: float = 3.0
    tilt_max: float = math.radians(35.0)
    att_p: float = 6.5
    rate_p: tuple = (25.0, 25.0, 5.0)
    bebop_tilt_max: float = math.radians(5.0)
    bebop_climb_max: float = 1.0
    bebop_yaw_rate_max: float = 2.0
    bebop_climb_p: float = 4.0
    yaw_rate_max: float = math.radians(200.0)
    thrust_headroom: float = 0.85
    thrust_xy_margin: float = 0.3

    def __post_init__(self):
        for name in ("vel_p", "vel_i", "rate_p"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise InvalidInputError(f"QuadrotorCascade {name} must be 3 non-negative gains, got {getattr(self, name)!r}")
        for name in ("tilt_max", "att_p", "bebop_tilt_max", "bebop_climb_max", "bebop_yaw_rate_max",
                     "bebop_climb_p", "vel_i_limit", "yaw_rate_max", "thrust_headroom"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise InvalidInputError(f"QuadrotorCascade {name} must be positive and finite, got {v!r}")
        if not self.tilt_max < 0.5 * math.pi:
            raise InvalidInputError(f"tilt_max must be below pi/2, got {self.tilt_max!r}")
        if not self.thrust_headroom < 1.0:
            raise InvalidInputError(f"thrust_headroom must be below 1 (roll and pitch need room), "
                                    f"got {self.thrust_headroom!r}")
        if not (isinstance(self.thrust_xy_margin, (int, float)) and 0.0 <= self.thrust_xy_margin < 1.0):
            raise InvalidInputError(f"thrust_xy_margin must be in [0, 1), got {self.thrust_xy_margin!r}")
        # the loops run every physics step on one vehicle: Python floats, not 3-vectors of
        # NumPy (each NumPy call on a 3-vector costs about a microsecond)
        self._vp = [float(x) for x in self.vel_p]
        self._vi = [float(x) for x in self.vel_i]
        self._J = [float(x) for x in self.params.inertia]
        self._kJ = [j * float(k) for j, k in zip(self._J, self.rate_p)]
        self._mix_inv = np.linalg.inv(self.params.mixer()).tolist()
        self._fmax = self.params.max_thrust
        # the largest collective thrust every rotor can share (f_i = M_i0 T), with headroom
        self._thrust_max = self.thrust_headroom * min(self._fmax / r[0] for r in self._mix_inv)
        self._tan_tilt = math.tan(self.tilt_max)
        # the constants of the loops, computed once: the same floats as the expressions of
        # the loops they stand for (t_max * t_max, margin * t_max, -0.7 g, ...), read with one
        # attribute lookup per call (the loops run at the physics rate on every vehicle)
        t_max = self._thrust_max
        self._outer = (float(self.params.mass), t_max, t_max * t_max, self.thrust_xy_margin * t_max,
                       self._tan_tilt, -0.7 * GRAVITY, float(self.vel_i_limit), *self._vp, *self._vi)
        self._inner = (-self.att_p, self.yaw_rate_max, t_max, *self._J, *self._kJ)
        self._mix_rows = tuple(x for r in self._mix_inv for x in r)  # (M_00, M_01, ..., M_33)
        self._drag = (-self.params.rotor_drag_coefficient, float(self.params.motor_constant))
        self.reset()

    def reset(self):
        """Clear the velocity integrator."""
        self._integral = [0.0, 0.0, 0.0]

    # -- the physics loop's entries (Python floats, no conversion) --------------------
    def step_velocity(self, u, vw, R, forces, dt: float) -> tuple[list, tuple]:
        """One physics step of velocity mode: ``(rotor forces, rotor drag)``.

        :meth:`velocity_mode` and :meth:`rotor_drag` (the same floats) on the plain Python
        values the physics loop holds, without their conversions.

        Parameters
        ----------
        u : sequence of 4 floats
            World-frame velocity set point (m/s) and yaw rate (rad/s); a non-finite entry is
            zero (the velocity) or no yaw rate.
        vw : sequence of 6 floats
            World-frame velocity (m/s), then body-frame angular velocity (rad/s): the free
            joint's ``qvel``.
        R : sequence of 9 floats
            Body-to-world rotation, rows first.
        forces : sequence of 4 floats
            The rotors' present forces, N (for the drag).
        dt : float
            The integrator's step, s.

        Returns
        -------
        (list of 4 floats, tuple of 3 floats)
            Rotor force commands (N) and the world-frame in-plane rotor drag (N).
        """
        return self._velocity_chain(u, vw, R, dt), self._rotor_drag(forces, vw, R)

    def step_attitude(self, u, vw, R, forces, dt: float | None = None) -> tuple[list, tuple]:
        """One physics step of the Bebop-like attitude mode: ``(rotor forces, rotor drag)``
        (:meth:`attitude_mode` and :meth:`rotor_drag`; arguments as :meth:`step_velocity`,
        ``u`` the command ``(u_x, u_y, u_z, u_psi)``; ``dt`` unused: this mode keeps no
        integrator, it is there so that a loop calls both modes alike)."""
        return self._attitude_list(u, vw[2], R, vw[3:6]), self._rotor_drag(forces, vw, R)

    # -- outer loops ------------------------------------------------------------------
    def velocity_mode(self, v_cmd, yaw_rate_cmd: float, v, R, omega, dt: float) -> np.ndarray:
        """Rotor forces (4,) for a world-frame velocity and yaw-rate set point.

        Parameters
        ----------
        v_cmd : (3,) m/s, world frame
        yaw_rate_cmd : float, rad/s
        v : (3,) world-frame velocity, m/s
        R : (3, 3) body-to-world rotation
        omega : (3,) body-frame angular velocity, rad/s
        dt : float, s (the integrator's step)
        """
        u = [*_floats(v_cmd), float(yaw_rate_cmd)]
        return np.array(self._velocity_chain(u, [*_floats(v), *_floats(omega)], _floats(R), dt))

    def _velocity_chain(self, u, vw, R, dt) -> list:
        """:meth:`velocity_mode` on Python floats: ``u`` (4,), ``vw`` (6,) velocity and body
        rates, ``R`` the rotation's 9 entries row by row. Each ``min(max(x, lo), hi)`` of
        floats is written as the comparisons Python's ``min`` and ``max`` make (``max(x, lo)``
        is ``lo if lo > x else x``): the same values, NaN included."""
        v0, v1, v2, w0, w1, w2 = vw
        # a non-finite state is an error (it would poison the integrator for good): x - x is
        # 0 exactly for every finite x, NaN otherwise
        s = v0 + v1 + v2 + R[0] + R[1] + R[2] + R[3] + R[4] + R[5] + R[6] + R[7] + R[8] + w0 + w1 + w2
        if not s - s == 0.0:
            raise NonFiniteError(f"velocity_mode: the vehicle's state is not finite (v = {[v0, v1, v2]!r}); "
                                 "check the physics step")
        m, t_max, t_max2, xy_margin, tan_tilt, az_min, lim_i, p0, p1, p2, i0, i1, i2 = self._outer
        c0, c1, c2, yaw_rate = u
        # a non-finite set point component means "hold" (0), as in attitude_mode
        c0 = c0 if c0 - c0 == 0.0 else 0.0
        c1 = c1 if c1 - c1 == 0.0 else 0.0
        c2 = c2 if c2 - c2 == 0.0 else 0.0
        nlim = -lim_i
        I = self._integral
        # velocity PI, the integrator clamped to +-lim_i: x = min(max(x, -lim), lim)
        e0, e1, e2 = c0 - v0, c1 - v1, c2 - v2
        x = I[0] + i0 * e0 * dt
        x = nlim if nlim > x else x
        x = lim_i if lim_i < x else x
        I[0] = x
        a0 = p0 * e0 + x
        x = I[1] + i1 * e1 * dt
        x = nlim if nlim > x else x
        x = lim_i if lim_i < x else x
        I[1] = x
        a1 = p1 * e1 + x
        x = I[2] + i2 * e2 * dt
        x = nlim if nlim > x else x
        x = lim_i if lim_i < x else x
        I[2] = x
        a2 = p2 * e2 + x
        g = GRAVITY
        fx, fy = m * a0, m * a1
        nxy = math.hypot(fx, fy)
        # the thrust vector within the rotors' reach (PX4 PositionControl::_accelerationControl
        # and MPC_THR_XY_MARG): vertical first, less a margin kept for the horizontal demand,
        # then the horizontal within what is left and the tilt limit
        margin = xy_margin if xy_margin < nxy else nxy  # min(nxy, margin t_max)
        a2 = az_min if az_min > a2 else a2  # min(max(a_z, -0.7 g), g)
        a2 = g if g < a2 else a2
        fz = m * (g + a2)
        x = math.sqrt(t_max2 - margin * margin)
        fz = x if x < fz else fz
        x = t_max2 - fz * fz
        x = math.sqrt(0.0 if 0.0 > x else x)
        lim = fz * tan_tilt  # min(fz tan(tilt_max), sqrt(max(t_max^2 - fz^2, 0)))
        lim = x if x < lim else lim
        if nxy > lim:
            fx, fy = fx * lim / nxy, fy * lim / nxy
        return self._attitude_chain(fx, fy, fz, yaw_rate, R, (w0, w1, w2))

    def attitude_mode(self, u, v, R, omega) -> np.ndarray:
        """Rotor forces (4,) for a Bebop-like command ``(u_x, u_y, u_z, u_psi)`` in [-1, 1]
        (seed 001 eq. (3.6)): pitch and roll fractions of ``bebop_tilt_max`` in the heading
        frame, climb-rate and yaw-rate fractions."""
        return np.array(self._attitude_list(u, v[2], _floats(R), _floats(omega)))

    def _attitude_list(self, u, vz, R, w) -> list:
        """:meth:`attitude_mode` (4 floats): ``vz`` the climb rate, ``R`` the rotation's 9
        entries row by row, ``w`` the body rates (Python floats)."""
        u = [min(max(float(x), -1.0), 1.0) if math.isfinite(x) else 0.0 for x in u]
        m, g = self.params.mass, GRAVITY
        az = self.bebop_climb_p * (u[2] * self.bebop_climb_max - float(vz))
        fz = min(m * (g + min(max(az, -0.7 * g), g)), self._thrust_max * math.cos(self.bebop_tilt_max))
        tx, ty = math.tan(u[0] * self.bebop_tilt_max), math.tan(u[1] * self.bebop_tilt_max)
        c, s = R[0], R[3]
        h = math.hypot(c, s) or 1.0
        c, s = c / h, s / h
        return self._attitude_chain(fz * (c * tx - s * ty), fz * (s * tx + c * ty), fz,
                                    u[3] * self.bebop_yaw_rate_max, R, w)

    # -- inner loops ------------------------------------------------------------------
    def _attitude_chain(self, fx, fy, fz, yaw_rate, R, w) -> list:
        """Thrust vector -> attitude set point (heading kept) -> rates -> torques -> forces.

        ``R``: the rotation's 9 entries row by row; ``w``: body rates; all Python floats.
        """
        R0, R1, R2, R3, R4, R5, R6, R7, R8 = R
        w0, w1, w2 = w
        n = math.sqrt(fx * fx + fy * fy + fz * fz)
        b30, b31, b32 = fx / n, fy / n, fz / n
        if R0 * R0 + R3 * R3 > 1e-12:  # the heading
            x0, x1, x2 = R0, R3, 0.0
        else:
            x0, x1, x2 = 1.0, 0.0, 0.0
        b20, b21, b22 = b31 * x2 - b32 * x1, b32 * x0 - b30 * x2, b30 * x1 - b31 * x0  # b3 x heading
        nb = math.sqrt(b20 * b20 + b21 * b21 + b22 * b22)
        b20, b21, b22 = b20 / nb, b21 / nb, b22 / nb
        b10, b11, b12 = b21 * b32 - b22 * b31, b22 * b30 - b20 * b32, b20 * b31 - b21 * b30  # b2 x b3
        # e_R = 1/2 vee(Rd^T R - R^T Rd), (Rd^T R)_ij = (column i of Rd) . (column j of R)
        # (Rd^T R)_ij written out: column i of Rd is b1, b2, b3, column j of R is (R[j], R[3 + j], R[6 + j])
        e0 = 0.5 * ((b30 * R1 + b31 * R4 + b32 * R7) - (b20 * R2 + b21 * R5 + b22 * R8))
        e1 = 0.5 * ((b10 * R2 + b11 * R5 + b12 * R8) - (b30 * R0 + b31 * R3 + b32 * R6))
        # rate set point: attitude P on roll and pitch; the yaw rate (world z) in body axes
        nkp, lim, t_max, J0, J1, J2, k0, k1, k2 = self._inner
        if yaw_rate - yaw_rate == 0.0:  # finite: within PX4 MC_YAWRATE_MAX, min(max(r, -lim), lim)
            x = -lim
            yaw_rate = x if x > yaw_rate else yaw_rate
            yaw_rate = lim if lim < yaw_rate else yaw_rate
        else:
            yaw_rate = 0.0
        s0, s1, s2 = nkp * e0 + yaw_rate * R6, nkp * e1 + yaw_rate * R7, yaw_rate * R8
        thrust = fx * R2 + fy * R5 + fz * R8  # min(max(thrust, 0), t_max)
        thrust = 0.0 if 0.0 > thrust else thrust
        thrust = t_max if t_max < thrust else thrust
        Jw0, Jw1, Jw2 = J0 * w0, J1 * w1, J2 * w2
        # torques: J rate_p (w_sp - w) + w x J w
        return self._mix(thrust, k0 * (s0 - w0) + (w1 * Jw2 - w2 * Jw1), k1 * (s1 - w1) + (w2 * Jw0 - w0 * Jw2),
                         k2 * (s2 - w2) + (w0 * Jw1 - w1 * Jw0))

    def mix(self, thrust: float, tau) -> list:
        """Rotor forces (4 floats) for collective thrust and body torques, within ``[0, f_max]``.

        Where the wrench is out of the rotors' reach, PX4's priorities (its mixer's
        desaturation, ``ControlAllocationSequentialDesaturation``): roll and pitch first,
        kept whole by moving the collective thrust as far as needed (scaled down together
        only where no thrust fits them); then the yaw torque, scaled by the largest
        ``s`` in ``[0, 1]`` that keeps every rotor in range. The thrust is first capped at
        the headroom's limit, so a thrust alone always fits.
        """
        t0 = min(max(float(thrust), 0.0), self._thrust_max)
        return self._mix(t0, float(tau[0]), float(tau[1]), float(tau[2]))

    def _mix(self, t0, t1, t2, t3) -> list:
        """:meth:`mix` of a thrust ``t0`` already within ``[0, thrust cap]`` (Python floats)."""
        M = self._mix_rows
        f0 = M[0] * t0 + M[1] * t1 + M[2] * t2 + M[3] * t3
        f1 = M[4] * t0 + M[5] * t1 + M[6] * t2 + M[7] * t3
        f2 = M[8] * t0 + M[9] * t1 + M[10] * t2 + M[11] * t3
        f3 = M[12] * t0 + M[13] * t1 + M[14] * t2 + M[15] * t3
        # min(f) >= 0 and max(f) <= f_max, with the comparisons min() and max() make
        lo = f0
        if f1 < lo:
            lo = f1
        if f2 < lo:
            lo = f2
        if f3 < lo:
            lo = f3
        if lo >= 0.0:
            hi = f0
            if f1 > hi:
                hi = f1
            if f2 > hi:
                hi = f2
            if f3 > hi:
                hi = f3
            if hi <= self._fmax:
                return [f0, f1, f2, f3]
        return self._desaturate(t0, t1, t2, t3)

    def _desaturate(self, t0, t1, t2, t3) -> list:
        """:meth:`mix` where the wrench is out of the rotors' reach (PX4's priorities)."""
        M, fmax = self._mix_inv, self._fmax
        # rotor i: 0 <= m_i (T + dT) + k rp_i <= fmax, i.e. -T - k a_i <= dT <= u_i - T - k a_i
        # with a_i = rp_i / m_i, u_i = fmax / m_i; some dT fits iff k (a_j - a_i) <= u_j, all i, j
        m0 = [r[0] for r in M]
        rp = [r[1] * t1 + r[2] * t2 for r in M]
        a = [rp[i] / m0[i] for i in range(4)]
        u = [fmax / m0[i] for i in range(4)]
        k = 1.0
        for j in range(4):
            for i in range(4):
                if a[j] - a[i] > u[j] * k:
                    k = u[j] / (a[j] - a[i])
        lo = max(-t0 - k * a[i] for i in range(4))
        hi = min(u[i] - t0 - k * a[i] for i in range(4))
        d = min(max(0.0, lo), hi)  # the least change of the collective thrust
        f = [m0[i] * (t0 + d) + k * rp[i] for i in range(4)]
        # yaw: the largest s in [0, 1] with 0 <= f_i + s y_i <= fmax for every rotor
        y = [r[3] * t3 for r in M]
        s = 1.0
        for fi, yi in zip(f, y):
            if yi > 0.0:
                s = min(s, (fmax - fi) / yi)
            elif yi < 0.0:
                s = min(s, fi / -yi)
        s = max(s, 0.0)
        return [min(max(fi + s * yi, 0.0), fmax) for fi, yi in zip(f, y)]

    def rotor_drag(self, forces, v, R) -> tuple:
        """World-frame in-plane rotor drag, N: ``-c sum_i(omega_i) v_perp`` (RotorS motor model).

        ``R``: the rotation (3, 3) or its 9 entries row by row.
        """
        return self._rotor_drag([float(f) for f in forces], _floats(v), _floats(R))

    def _rotor_drag(self, forces, v, R) -> tuple:
        """:meth:`rotor_drag` on Python floats (``v``: the velocity first, 3 or more entries)."""
        nc, c = self._drag
        f0, f1, f2, f3 = forces
        # sum_i omega_i, omega_i = sqrt(max(f_i, 0) / k_f), in the rotors' order (the same
        # floats as a sum() over them)
        speed = 0.0 + math.sqrt((0.0 if 0.0 > f0 else f0) / c)
        speed += math.sqrt((0.0 if 0.0 > f1 else f1) / c)
        speed += math.sqrt((0.0 if 0.0 > f2 else f2) / c)
        speed += math.sqrt((0.0 if 0.0 > f3 else f3) / c)
        R0, R1, _, R3, R4, _, R6, R7, _ = R
        vx, vy, vz = v[0], v[1], v[2]
        bx = R0 * vx + R3 * vy + R6 * vz  # body x, y components (R^T v)
        by = R1 * vx + R4 * vy + R7 * vz
        k = nc * speed
        return (k * (R0 * bx + R1 * by), k * (R3 * bx + R4 * by), k * (R6 * bx + R7 * by))


def quadrotor_mjcf(name: str, pos, yaw: float = 0.0, rgba=(0.2, 0.3, 0.8, 1.0),
                   params: QuadrotorParams = IRIS) -> tuple[str, str]:
    """MJCF of one quadrotor: ``(body, actuators)`` fragments for :func:`world_mjcf`.

    The body carries the iris's mass and inertia explicitly (its geoms only collide and
    show); its collision shape is the hull, two arms, four rotor discs and two skids. Rotor
    ``i`` is a ``general`` actuator on site ``{name}_rotor{i}`` with gear
    ``(0, 0, 1, 0, 0, -spin k_m)``: thrust along body z and the drag moment, control in
    ``[0, f_max]`` N, filtered by the motor lag.
    """
    p = params
    x, y, z = (float(a) for a in pos)
    cr, sr = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    col = " ".join(f"{c:g}" for c in rgba)
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = p.rotors
    h = p.leg_height
    lines = [
        f'<body name="{name}" pos="{x:.6g} {y:.6g} {z:.6g}" quat="{cr:.9g} 0 0 {sr:.9g}">',
        f'  <freejoint name="{name}_root"/>',
        f'  <inertial pos="0 0 0" mass="{p.mass:g}" diaginertia="{p.inertia[0]:g} {p.inertia[1]:g} {p.inertia[2]:g}"/>',
        f'  <geom name="{name}_hull" type="box" size="0.1 0.07 0.04" rgba="{col}"/>',
        f'  <geom name="{name}_arm0" type="capsule" size="0.012" fromto="{x0:g} {y0:g} 0.02 {x1:g} {y1:g} 0.02" rgba="0.15 0.15 0.15 1"/>',
        f'  <geom name="{name}_arm1" type="capsule" size="0.012" fromto="{x2:g} {y2:g} 0.02 {x3:g} {y3:g} 0.02" rgba="0.15 0.15 0.15 1"/>',
    ]
    for i, (rx, ry) in enumerate(p.rotors):
        shade = "0.9 0.3 0.2 0.6" if i in (0, 2) else "0.7 0.7 0.7 0.6"  # front rotors red
        lines.append(f'  <geom name="{name}_prop{i}" type="cylinder" size="{p.rotor_radius:g} 0.004" '
                     f'pos="{rx:g} {ry:g} 0.035" rgba="{shade}"/>')
        lines.append(f'  <site name="{name}_rotor{i}" pos="{rx:g} {ry:g} 0.02"/>')
    for side in (-1, 1):
        lines.append(f'  <geom name="{name}_skid{(side + 1) // 2}" type="capsule" size="0.008" '
                     f'fromto="-0.1 {0.1 * side:g} {-h + 0.008:g} 0.1 {0.1 * side:g} {-h + 0.008:g}" rgba="0.1 0.1 0.1 1"/>')
        for sx in (-1, 1):
            lines.append(f'  <geom type="capsule" size="0.006" fromto="{0.05 * sx:g} {0.06 * side:g} -0.04 '
                         f'{0.05 * sx:g} {0.1 * side:g} {-h + 0.008:g}" rgba="0.1 0.1 0.1 1" contype="0" conaffinity="0"/>')
    lines.append("</body>")
    acts = [f'<general name="{name}_motor{i}" site="{name}_rotor{i}" gear="0 0 1 0 0 {-s * p.moment_constant:g}" '
            f'ctrllimited="true" ctrlrange="0 {p.max_thrust:.6g}" dyntype="filter" dynprm="{p.motor_time_constant:g}"/>'
            for i, s in enumerate(p.spin)]
    return "\n".join(lines), "\n".join(acts)
