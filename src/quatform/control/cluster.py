"""The cluster-space controller: formation, law and team, stateless (control layer).

One control update (seed 000 Fig. 2): the measured robot state -> forward kinematics with
the reference as hint -> the cluster error (``Formation.errors``: angles wrapped) -> the
law (:mod:`quatform.control.laws`, here a :class:`~quatform.control.laws.BlockLaw`) ->
robot rates through the description's rate map at the measured state -> the team's
actuation and saturation (:class:`~quatform.robots.Team`). It runs on components (Python
floats for one formation, arrays for a batch; ``Formation.forward_components``,
``robot_rate_components``): the quaternion and dual-quaternion pairs apply their inverse
kinematics as a directional derivative (no matrix), the Euclidean descriptions the dense
inverse Jacobian of seed 000 Fig. 2. The four controllers of seed 000 are instances
(``ClusterSpaceController``, ``RobotSpaceController``, ``QuaternionController``,
``DualQuaternionController``): a formation, a :class:`~quatform.control.laws.BlockLaw` and
the reference checks that refuse a reference that is no formation.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np

from ..algebra.kernels import array_namespace, hold
from ..errors import InvalidInputError
from ..formations import pair_kernels as kern
from ..formations.base import Formation
from ..robots import Team
from . import contract
from .base import Controller, apart_robots, batch_shape, measured_codes
from .laws import BlockLaw

__all__ = ["ClusterController"]


@dataclass(frozen=True)
class ClusterController(Controller):
    """A stateless cluster-space controller of a formation, a law and a team.

    Parameters
    ----------
    formation : Formation
        The description the law acts in.
    law : BlockLaw
        Errors and commanded cluster rates from ``(c, c_des, c_dot_des, e)`` components.
    team : Team
        The robots: actuation (identity for holonomic robots) and saturation.
    feedforward : bool
        Whether the law adds the desired rate (the law's own setting is replaced by it).
    checks : tuple of callables
        Each called with the desired cluster state's components before anything is
        computed; raises (one line) where the reference is no formation of the team.
    filters : tuple
        What a lab puts around the chain (:mod:`quatform.control.filters`: the
        motion-capture screen, arena walls, a heading law), as data; a controller that
        uses them keeps their memory in its state (seed 001's
        :class:`~quatform.control.ugv_uav.UgvUavController`). The seed-000 controllers
        have none.
    """

    formation: Formation = field(default=None)
    law: BlockLaw = field(default=None)
    team: Team = Team()
    feedforward: bool = True
    checks: tuple = ()
    filters: tuple = ()
    name = "cluster"

    def __post_init__(self):
        if not isinstance(self.formation, Formation) or not isinstance(self.law, BlockLaw):
            raise InvalidInputError("ClusterController needs a Formation and a BlockLaw (control.laws), got "
                                    f"{type(self.formation).__name__} and {type(self.law).__name__}")
        if self.law.n != self.formation.n_c:
            raise InvalidInputError(f"the law has {self.law.n} variables, the formation {self.formation.n_c}")
        if self.law.feedforward != self.feedforward:
            object.__setattr__(self, "law", replace(self.law, feedforward=self.feedforward))

    def tick(self, state, measured, reference, t) -> contract.Tick:
        """One pure control tick on any array namespace (seed 000 Fig. 2): the measured robots
        ``(..., n_r)`` wound onto ``reference["robots"]`` (when given), :meth:`chain`, the
        team's saturation; ``raw_finite`` 0 where the unsaturated command was not finite.

        ``code`` (:data:`~quatform.control.base.FAILURE_REASONS`): 1 where the measured state
        is not finite or beyond 1e150, 2 where the robots are within
        :data:`~quatform.formations.base.MIN_SEPARATION_M` and the formation's
        ``robots_apart`` (not seed 000's robot space, defined there); such a world's chain runs
        on :func:`~quatform.control.base.apart_robots` instead (its outputs are discarded). A
        controller with :attr:`filters` runs its :meth:`update` (NumPy).
        """
        if self.filters:
            return super().tick(state, measured, reference, t)
        F, team = self.formation, self.team
        xp = array_namespace(measured)
        c_des, c_dot_des = reference["c"], reference["c_dot"]
        lead = batch_shape(measured, c_des, c_dot_des)
        r = F.align(measured, reference["robots"]) if "robots" in reference else measured
        code = measured_codes(team.layout, measured, r, apart=F.robots_apart, inclusive=True)
        code = xp.broadcast_to(code, lead) if code.shape != lead else code
        r = hold(xp.where(code[..., None] > 0, self._apart, r))
        stage = None
        if xp is not np:  # each stage's components materialised once (hold; NumPy needs none)
            def stage(comps):
                a = hold(xp.stack([xp.broadcast_to(v, lead) for v in comps], axis=-1))
                return tuple(a[..., q] for q in range(a.shape[-1]))
        c, err, r_dot = (_lead(xp, kern.pack(v), lead) for v in self.chain(r, c_des, c_dot_des, stage=stage))
        r_dot = hold(r_dot)
        finite = xp.all(xp.isfinite(r_dot), axis=-1, keepdims=True)
        u = hold(team.saturate(r_dot))
        return contract.Tick(None, u, {"cluster": c, "error": err, "raw_finite": finite.astype(u.dtype)}, code)

    @functools.cached_property
    def _apart(self):
        return apart_robots(self.team.layout)

    def _control(self, r, c_des, c_dot_des, aligned):
        F = self.formation
        if not F.component_kernels:
            return self._control_arrays(r, c_des, c_dot_des)
        rc, cd, cdd = _comps(r), _comps(c_des), _comps(c_dot_des)
        for check in self.checks:
            check(cd)
        return self._chain_components(rc, cd, cdd)

    def chain(self, r, c_des, c_dot_des, stage=None):
        """The control chain without the checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``, where no value can be tested): ``(c, err, r_dot)`` (tuples of components
        or arrays; ``kern.pack`` them) for the measured robots ``r`` (``(..., n_r)``, aligned
        as :meth:`update` aligns them) and the reference ``c_des``, ``c_dot_des``.

        The caller has run the reference checks (:attr:`checks`, on the whole reference at
        once) and marks the worlds whose robots coincide or whose state is not finite, which
        :meth:`update` refuses. The team must be passthrough or have no actuation memory.
        ``stage`` (optional) maps the component tuples that the forward kinematics and the law
        return to equal ones (the jax loop computes them once there, ``algebra.kernels.hold``).
        """
        F = self.formation
        if F.component_kernels:
            return self._chain_components(kern.unpack(r), kern.unpack(c_des), kern.unpack(c_dot_des), stage)
        return self._chain_arrays(r, F.forward_arrays(r, c_des), c_des, c_dot_des, stage)

    def _chain_components(self, rc, cd, cdd, stage=None):
        F = self.formation
        c, rc = F.forward_components(rc, cd, stage=stage)  # the reference's branch (near_c)
        if stage is not None:
            c, rc = stage(c), stage(rc)
        err, rate = self.law(c, cd, cdd, F.error_components(c, cd) if F.wraps_angles else None)
        if stage is not None:
            err, rate = stage(err), stage(rate)
        r_dot = F.robot_rate_components(c, rate, rc)
        return c, err, self._actuate(rc, r_dot)

    def _control_arrays(self, r, c_des, c_dot_des):
        """The chain on arrays, for a description without component kernels (the Euclidean
        ones: forward kinematics and the dense inverse Jacobian of seed 000 Fig. 2)."""
        r, c_des, c_dot_des = (np.asarray(a, dtype=float) for a in (r, c_des, c_dot_des))
        for check in self.checks:
            check(kern.unpack(c_des))
        return self._chain_arrays(r, self.formation.forward(r, near_c=c_des), c_des, c_dot_des)

    def _chain_arrays(self, r, c, c_des, c_dot_des, stage=None):
        """Errors, the law and the dense inverse Jacobian (seed 000 Fig. 2) at the measured
        cluster state ``c`` (arrays of any namespace)."""
        F = self.formation
        if stage is not None:
            c = kern.pack(stage(kern.unpack(c)))
        e = kern.unpack(F.errors(c, c_des)) if F.wraps_angles else None
        err, rate = self.law(kern.unpack(c), kern.unpack(c_des), kern.unpack(c_dot_des), e)
        if stage is not None:
            err, rate = stage(err), stage(rate)
        Ji, rate = F.inverse_jacobian_at(c, r=r), kern.pack(rate)
        if isinstance(Ji, np.ndarray):
            r_dot = np.einsum("...ij,...j->...i", Ji, rate)
        else:  # another namespace (JAX): the products' sums (XLA runs a batched einsum row by row)
            r_dot = (Ji * rate[..., None, :]).sum(axis=-1)
        return c, err, self._actuate(r, r_dot)

    def _actuate(self, r, r_dot):
        """The team's commands for the robot rates (the rates themselves for holonomic robots)."""
        if self.team.passthrough:
            return r_dot
        r_arr = kern.pack(r)
        u, _ = self.team.actuate(r_arr, kern.pack(r_dot), 0.0, self.team.initial_memory(np.shape(r_arr)[:-1]))
        return u


def _lead(xp, a, lead):
    """``a`` (``(..., k)``) with the leading axes ``lead`` (as it is when it has them)."""
    return a if a.shape[:-1] == lead else xp.broadcast_to(a, lead + a.shape[-1:])


def _comps(a):
    """Components of ``a``: a tuple of floats as it is, an array by ``pair_kernels.unpack``."""
    return a if isinstance(a, tuple) else kern.unpack(a)
