"""Parrot Bebop 2 as a 4-DOF velocity-commanded vehicle with its identified dynamics (seed 001 §3.1.2).

Robots layer. Commands ``u = (u_x, u_y, u_z, u_psi)`` in the body frame, each a fraction
of the vehicle's full command range ``[-1, 1]`` (eq. (3.6)). Kinematics, eqs. (3.7)-(3.10):
``X_dot = A_b v`` with ``v`` the body-frame velocity ``(v_x, v_y, z_dot, psi_dot)`` and
``A_b`` the yaw rotation. Dynamics (Santana et al., Pinto et al.), eqs. (3.11)-(3.13):
``v_dot = K_u u - K_v v`` in the body frame, ``K_u = diag(K1, K3, K5, K7)``,
``K_v = diag(K2, K4, K6, K8)`` (Table 2). The thesis prints it in the world frame as
``X_ddot = A_b K_u u - A_b K_v X_dot``, which applies the body-frame drag to world-frame
velocities; the dynamic compensation (4.47) it uses is the body-frame law, so quatform
integrates that one (``docs/derivations.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..algebra.validate import as_array
from ..errors import InvalidInputError

__all__ = ["Bebop", "TABLE2_K"]

#: Seed 001 Table 2: K1 ... K8 of the identified model.
TABLE2_K = (0.8417, 0.1823, 0.8354, 0.1710, 3.966, 4.001, 9.8524, 4.7295)


def yaw_matrix(psi) -> np.ndarray:
    """``A_b`` of eq. (3.7), shape ``(..., 4, 4)``."""
    psi = np.asarray(psi, dtype=float)
    c, s = np.cos(psi), np.sin(psi)
    A = np.zeros(psi.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 1, 0], A[..., 1, 1] = c, -s, s, c
    A[..., 2, 2] = A[..., 3, 3] = 1.0
    return A


@dataclass(frozen=True)
class Bebop:
    """The identified high-level model of a Bebop 2.

    Parameters
    ----------
    k : tuple of 8 floats
        ``K1 ... K8`` (Table 2).
    max_fraction : float
        Largest ``|u_i|`` as a fraction of the full command (1.0; 0.4 in seed 001 §5.3).
    dynamic : bool
        ``True``: the dynamic model; ``False``: the kinematic model (velocities follow the
        command at once, ``v = (K_u/K_v) u``).
    """

    k: tuple = field(default=TABLE2_K)
    max_fraction: float = 1.0
    dynamic: bool = True

    def __post_init__(self):
        k = np.asarray(self.k, dtype=float)
        if k.shape != (8,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise InvalidInputError(f"Bebop k must be 8 positive numbers K1..K8, got {self.k!r}")
        if not (0 < self.max_fraction <= 1):
            raise InvalidInputError(f"max_fraction must be in (0, 1], got {self.max_fraction!r}")
        object.__setattr__(self, "k", tuple(float(x) for x in k))

    @property
    def k_u(self) -> np.ndarray:
        return np.array(self.k[0::2])

    @property
    def k_v(self) -> np.ndarray:
        return np.array(self.k[1::2])

    @property
    def max_velocity(self) -> np.ndarray:
        """Steady body velocities at ``max_fraction``: ``(K_u/K_v) max_fraction``, (m/s, m/s, m/s, rad/s)."""
        return self.k_u / self.k_v * self.max_fraction

    def saturate(self, u) -> np.ndarray:
        """Commands clipped to ``+-max_fraction``; non-finite commands become zero."""
        u = np.asarray(u, dtype=float)
        u = np.where(np.all(np.isfinite(u), axis=-1, keepdims=True), u, 0.0)
        return np.clip(u, -self.max_fraction, self.max_fraction)

    def step(self, state, u, dt: float) -> np.ndarray:
        """State ``(x, y, z, psi, v_x, v_y, z_dot, psi_dot)`` (body velocities) after ``dt`` s.

        The body velocity relaxes exactly (first-order lag, command held); the pose is
        integrated with the mean velocity over the step and the mid-step yaw.
        """
        state = as_array(state, "Bebop state", 8)
        u = self.saturate(u)
        pose, v0 = state[..., :4], state[..., 4:]
        v_inf = self.k_u / self.k_v * u
        if self.dynamic:
            decay = np.exp(-self.k_v * dt)
            v1 = v_inf + (v0 - v_inf) * decay
            mean = v_inf + (v0 - v_inf) * (1.0 - decay) / (self.k_v * dt)
        else:
            v1 = mean = v_inf
        psi_mid = pose[..., 3] + 0.5 * dt * mean[..., 3]
        world = np.einsum("...ij,...j->...i", yaw_matrix(psi_mid), mean)
        return np.concatenate([pose + dt * world, v1], axis=-1)
