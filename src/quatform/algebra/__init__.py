"""Algebra layer: quaternions, dual quaternions, Euler parameters (bottom of quatform).

Quaternions are ``(..., 4)`` arrays ``(w, x, y, z)`` with the Hamilton product; dual
quaternions are ``(..., 8)`` arrays, primary part first, a pose being ``q + eps 1/2 t q``.
Every function broadcasts over leading axes, validates its input (shape, finiteness, unit
norm where required, see :mod:`quatform.errors`) and returns a new array.
"""

from .validate import UNIT_TOLERANCE
from .angles import wrap_angle
from .dual_quaternion import (
    DQ_IDENTITY,
    dq_closest,
    dq_from_pose,
    dq_transform_point,
    dqcanonical,
    dqconj,
    dqconj_combined,
    dqconj_dual,
    dqexp,
    dqexp_decoupled,
    dqinv,
    dqlog,
    dqlog_decoupled,
    dqmul,
    dqnorm,
    dqnormalize,
    dqpow,
    dqpow_decoupled,
    dqsqrt_decoupled,
    dqsqrt_screw,
    pose_from_dq,
)
from .euler_parameters import (
    euler_parameters_from_q,
    q_from_euler_parameters,
    relative_euler_parameters,
    w_matrix,
)
from .operators import (
    CONJ,
    dqminus,
    dqplus,
    jac_qrotate_quaternion,
    jac_qrotate_vector,
    qminus,
    qplus,
    skew,
)
from .quaternion import (
    IDENTITY,
    axis_angle_from_q,
    matrix_from_q,
    q_angle,
    q_angle_between,
    q_closest,
    q_continuous,
    q_from_axis_angle,
    q_from_matrix,
    qcanonical,
    qconj,
    qexp,
    qinv,
    qlog,
    qmul,
    qnorm,
    qnormalize,
    qpow,
    qrotate,
    qslerp,
)
from .rates import (
    INTEGRATORS,
    angular_acceleration_from_qddot,
    angular_velocity_from_qdot,
    integrate,
    qddot_from_angular_acceleration,
    qdot_from_angular_velocity,
    qdot_matrix,
)

__all__ = [
    "UNIT_TOLERANCE",
    "IDENTITY",
    "DQ_IDENTITY",
    "CONJ",
    # quaternions
    "qmul", "qconj", "qinv", "qnorm", "qnormalize", "qexp", "qlog", "qpow", "qslerp",
    "qrotate", "q_from_axis_angle", "axis_angle_from_q", "matrix_from_q", "q_from_matrix",
    "qcanonical", "q_closest", "q_continuous", "q_angle", "q_angle_between",
    # operators and derivatives
    "skew", "qplus", "qminus", "dqplus", "dqminus", "jac_qrotate_vector",
    "jac_qrotate_quaternion",
    # rates and integration
    "INTEGRATORS", "qdot_matrix", "qdot_from_angular_velocity", "angular_velocity_from_qdot",
    "qddot_from_angular_acceleration", "angular_acceleration_from_qddot", "integrate",
    # dual quaternions
    "dqmul", "dqconj", "dqconj_dual", "dqconj_combined", "dqnorm", "dqnormalize", "dqinv",
    "dqexp", "dqlog", "dqpow", "dqexp_decoupled", "dqlog_decoupled", "dqpow_decoupled",
    "dqsqrt_screw", "dqsqrt_decoupled", "dq_from_pose", "pose_from_dq", "dq_transform_point",
    "dqcanonical", "dq_closest",
    # Euler parameters (seed 003)
    "euler_parameters_from_q", "q_from_euler_parameters", "relative_euler_parameters",
    "w_matrix",
    # plane angles
    "wrap_angle",
]
