"""PX4 offboard messages (``px4_msgs``) for the ROS 2 bridge, on rosbags' type store.

ROS 2 bridge layer. ROS 2 Humble's type store (:func:`quatform.messages.typestore`) has no
``px4_msgs``; :func:`register_px4_types` adds the three this bridge uses, as PX4 v1.15 defines
them (``msg/TrajectorySetpoint.msg``, ``msg/OffboardControlMode.msg``,
``msg/VehicleOdometry.msg`` of PX4-Autopilot; v1.14's ``OffboardControlMode`` has ``actuator``
where v1.15 has ``thrust_and_torque`` and ``direct_actuator``: on a ROS machine the node uses
the user's own ``px4_msgs`` classes and sets only the fields named here).

PX4's frames are NED (world) and FRD (body) (:mod:`quatform.ros2.frames`); its timestamps are
microseconds. A velocity setpoint is a ``TrajectorySetpoint`` whose ``position``,
``acceleration``, ``jerk`` and ``yaw`` are NaN ("not controlled", the message's own comment),
sent with an ``OffboardControlMode`` whose ``velocity`` is true (PX4 User Guide, "Offboard
Mode": the mode message at 2 Hz or more keeps the vehicle in offboard).
"""

from __future__ import annotations

import math

import numpy as np

from .. import messages
from ..errors import InvalidInputError
from . import frames

__all__ = ["PX4_DEFINITIONS", "register_px4_types", "trajectory_setpoint", "offboard_control_mode",
           "vehicle_odometry_pose", "vehicle_odometry", "microseconds"]

#: The ``px4_msgs`` definitions (PX4 v1.15), by type name.
PX4_DEFINITIONS = {
    "px4_msgs/msg/TrajectorySetpoint": """
uint64 timestamp
float32[3] position
float32[3] velocity
float32[3] acceleration
float32[3] jerk
float32 yaw
float32 yawspeed
""",
    "px4_msgs/msg/OffboardControlMode": """
uint64 timestamp
bool position
bool velocity
bool acceleration
bool attitude
bool body_rate
bool thrust_and_torque
bool direct_actuator
""",
    "px4_msgs/msg/VehicleOdometry": """
uint64 timestamp
uint64 timestamp_sample
uint8 POSE_FRAME_UNKNOWN = 0
uint8 POSE_FRAME_NED = 1
uint8 POSE_FRAME_FRD = 2
uint8 pose_frame
float32[3] position
float32[4] q
uint8 VELOCITY_FRAME_UNKNOWN = 0
uint8 VELOCITY_FRAME_NED = 1
uint8 VELOCITY_FRAME_FRD = 2
uint8 VELOCITY_FRAME_BODY_FRD = 3
uint8 velocity_frame
float32[3] velocity
float32[3] angular_velocity
float32[3] position_variance
float32[3] orientation_variance
float32[3] velocity_variance
uint8 reset_counter
int8 quality
""",
}


def register_px4_types(store=None):
    """Register :data:`PX4_DEFINITIONS` in ``store`` (default: :func:`quatform.messages.typestore`)
    once; returns the store."""
    from rosbags.typesys import get_types_from_msg

    store = messages.typestore() if store is None else store
    missing = [name for name in PX4_DEFINITIONS if name not in store.types]
    if missing:
        types = {}
        for name in missing:
            types.update(get_types_from_msg(PX4_DEFINITIONS[name], name))
        store.register(types)
    return store


def _cls(name: str):
    register_px4_types()
    return messages.msg_type(name)


def microseconds(t: float) -> int:
    """PX4's ``timestamp`` (µs) of ``t`` s (finite, >= 0), or of a ``builtin_interfaces/msg/Time``
    (:func:`quatform.messages.stamp_ns`; rounded to the microsecond in integers)."""
    if hasattr(t, "sec") and hasattr(t, "nanosec"):
        return (messages.nanoseconds(t) + 500) // 1000
    if not (math.isfinite(t) and t >= 0):
        raise InvalidInputError(f"a PX4 timestamp must be finite and >= 0 s, got {t!r}")
    return int(round(t * 1e6))


def trajectory_setpoint(t: float, velocity_enu, yaw_rate_enu: float):
    """A PX4 velocity setpoint: ``velocity_enu`` (3,) m/s in the world (ENU) and the yaw rate
    about ENU's up axis, rad/s, as ``TrajectorySetpoint`` in NED (yawspeed about down: the
    negated rate); position, acceleration, jerk and yaw NaN (not controlled)."""
    v = np.asarray(velocity_enu, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or not math.isfinite(yaw_rate_enu):
        raise InvalidInputError(f"a PX4 velocity setpoint needs a finite velocity (3,) and yaw rate, got "
                                f"{v.tolist()} and {yaw_rate_enu!r}")
    nan3 = np.full(3, np.nan, dtype=np.float32)
    return _cls("px4_msgs/msg/TrajectorySetpoint")(
        timestamp=microseconds(t), position=nan3, velocity=frames.ned_from_enu(v).astype(np.float32),
        acceleration=nan3.copy(), jerk=nan3.copy(), yaw=float("nan"), yawspeed=float(-yaw_rate_enu))


def offboard_control_mode(t: float):
    """``OffboardControlMode`` selecting velocity control (PX4 "Offboard Mode")."""
    return _cls("px4_msgs/msg/OffboardControlMode")(
        timestamp=microseconds(t), position=False, velocity=True, acceleration=False, attitude=False,
        body_rate=False, thrust_and_torque=False, direct_actuator=False)


def vehicle_odometry(t: float, position_enu, q_enu_flu, velocity_enu=(0.0, 0.0, 0.0),
                     angular_velocity_flu=(0.0, 0.0, 0.0)):
    """The ``VehicleOdometry`` PX4 would publish for a REP-103 pose (for tests and recordings):
    NED position, FRD-to-NED quaternion, NED velocity, FRD body rates."""
    f32 = np.float32
    return _cls("px4_msgs/msg/VehicleOdometry")(
        timestamp=microseconds(t), timestamp_sample=microseconds(t), pose_frame=1,
        position=frames.ned_from_enu(position_enu).astype(f32),
        q=frames.q_ned_frd_from_enu_flu(q_enu_flu).astype(f32), velocity_frame=1,
        velocity=frames.ned_from_enu(velocity_enu).astype(f32),
        angular_velocity=frames.frd_from_flu(angular_velocity_flu).astype(f32),
        position_variance=np.zeros(3, f32), orientation_variance=np.zeros(3, f32),
        velocity_variance=np.zeros(3, f32), reset_counter=0, quality=0)


def vehicle_odometry_pose(msg):
    """``(t, position ENU (3,), quaternion FLU->ENU (w, x, y, z) (4,), body twist or None)`` of a
    ``VehicleOdometry`` in the NED frame (``pose_frame`` 1); the twist ``(linear FLU, angular
    FLU)`` when its velocity is given in NED (``velocity_frame`` 1) or body FRD (3). Another
    pose frame is one line (FRD world frames have an arbitrary heading)."""
    if int(msg.pose_frame) != 1:
        raise InvalidInputError(f"px4 VehicleOdometry pose_frame = {int(msg.pose_frame)}: the bridge reads NED poses "
                                "(pose_frame 1); set PX4's EKF2 to a NED local frame")
    p = frames.enu_from_ned(np.asarray(msg.position, dtype=float))
    q = frames.q_enu_flu_from_ned_frd(np.asarray(msg.q, dtype=float))
    q = q / np.linalg.norm(q)
    twist = None
    vel = np.asarray(msg.velocity, dtype=float)
    w_flu = frames.flu_from_frd(np.asarray(msg.angular_velocity, dtype=float))
    if int(msg.velocity_frame) == 1 and np.all(np.isfinite(vel)):
        from ..formations import geometry as g

        twist = (g.rotate(g.conj(q), frames.enu_from_ned(vel)), w_flu)  # world velocity into the body frame
    elif int(msg.velocity_frame) == 3 and np.all(np.isfinite(vel)):
        twist = (frames.flu_from_frd(vel), w_flu)
    return msg.timestamp * 1e-6, p, q, twist
