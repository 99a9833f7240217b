"""Affine formation maneuvers with leaders (Zhao 2018): the position-only baseline on a stress matrix.

Control layer. The team tracks a target formation that is a time-varying affine image of a
nominal configuration, ``p*_i(t) = A(t) p̄_i + b(t)``; only the leaders know ``A(t), b(t)``.
The followers' law (Zhao 2018, IEEE TAC 63(12), Sec. IV, the single-integrator law for
leaders with time-varying velocities) uses the stress ``ω_ij`` of the nominal configuration
(:class:`quatform.network.stress.Stress`) and its neighbours' positions and velocities:

    p_dot_i = -(1 / γ_i) sum_j ω_ij (k (p_i - p_j) - p_dot_j),    γ_i = sum_j ω_ij

(Zhao's law is ``k = 1``). Stacked, ``Ω_ff p_dot_f + Ω_fl p_dot_l = -k (Ω_ff p_f + Ω_fl p_l)``:
``δ = Ω_ff p_f + Ω_fl p_l`` decays like ``exp(-k t)``, and with the leaders on their targets the
followers' error ``p_f - p*_f = Ω_ff^-1 δ`` follows, for any maneuver, where Zhao's condition
holds (``Ω`` PSD of rank ``n - d - 1``, leaders affinely spanning ``R^d``:
:meth:`quatform.network.stress.Stress.check_leaders`). A leader tracks its own target,
``p_dot_i = v*_i + k_l (p*_i - p_i)`` with ``v*_i = A_dot p̄_i + b_dot``.

On a network (:class:`~quatform.control.networked.NetworkedController`) each robot sends its
position and velocity; a leader's velocity is its command of the tick, a follower's its
command of the previous tick (the law's state). Zhao's law is an algebraic loop over the
followers' velocities; sampled, a follower moves its command by a step ``β`` (``relay``)
towards Zhao's, computed with the velocities last heard,

    u_i(k) = (1 - β) u_i(k - 1) + β (Zhao's p_dot_i with the neighbours' last velocities),

``β = 1`` one Jacobi sweep per tick. With perfect links the relayed velocities converge iff
:meth:`~quatform.network.stress.Stress.relay_factor` ``ρ(I - β Γ_f^-1 Ω_ff) < 1``;
:meth:`~quatform.network.stress.Stress.relay_step` gives the fastest ``β`` (1 on Zhao's example; a
generic stress often needs less). A neighbour's position is extrapolated over its message's age,
``p_j + (t - stamp_j) v_j`` (no change with perfect links). A follower that holds no valid
message of one of its stress neighbours (none arrived within the links' ``max_age_s``) holds
still (commands 0) until it does: its equation is not determined without every term, and
dropping a term with a signed weight would make the command depend on the frame's origin.
The links must carry every stress edge (:meth:`~quatform.network.stress.Stress.graph`); the
``missing`` signal counts a robot's stress neighbours without a valid message.
``docs/networks.md`` ("Affine formation maneuvers") has the measured errors,
``docs/derivations.md`` the deviations from the paper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...algebra.kernels import common_namespace
from ...checks import short
from ...errors import InvalidInputError, ShapeError
from ...network.graph import robots_text
from ...network.stress import AffineExample, Stress, zhao2018_example
from ..local import LocalController, LocalTick

__all__ = ["AffineManeuver", "affine_reference", "example_reference"]

#: The reference's entries: name -> (trailing shape given n, unit).
REFERENCE_KEYS = {"target": (3, "m"), "target_rate": (3, "m/s"), "leader": (1, "1 for a leader, 0 for a follower"),
                  "stress": (None, "the robot's row of ω_ij")}


def _gain(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not (np.isfinite(value)
                                                                                         and value > 0):
        raise InvalidInputError(f"affine-maneuver: {name} = {short(value)} must be a positive number in 1/s")
    return float(value)


@dataclass(frozen=True)
class AffineManeuver(LocalController):
    """Zhao 2018's followers and target-tracking leaders on one stress (module docstring).

    Parameters
    ----------
    gain : float
        ``k``, the followers' position gain, 1/s (Zhao's law: 1).
    leader_gain : float
        ``k_l``, the leaders' tracking gain, 1/s.
    relay : float
        ``β`` in (0, 1], the followers' relay step (:meth:`quatform.network.stress.Stress.relay_step`).

    Reference (per tick, row ``i`` robot ``i``'s): ``{"target": (*batch?, N, 3) m, "target_rate":
    (*batch?, N, 3) m/s, "leader": (*batch?, N, 1) 1 or 0, "stress": (*batch?, N, N)}``, the
    stress rows :meth:`quatform.network.stress.Stress.rows` (:func:`affine_reference` builds it).
    The followers' command does not read their target; the ``target_error`` signal does.
    """

    gain: float = 1.0
    leader_gain: float = 1.0
    relay: float = 1.0

    name = "affine-maneuver"
    message_columns = ("x", "y", "z", "v_x", "v_y", "v_z")
    own_columns = ("x", "y", "z")
    command_columns = ("v_x", "v_y", "v_z")

    def __post_init__(self):
        _gain(self.gain, "gain")
        _gain(self.leader_gain, "leader_gain")
        b = self.relay
        if isinstance(b, bool) or not isinstance(b, (int, float, np.number)) or not 0.0 < b <= 1.0:
            raise InvalidInputError(f"affine-maneuver: relay = {short(b)} must be a number in (0, 1] (the followers' "
                                    f"relay step; quatform.network.stress.Stress.relay_step gives one)")

    @classmethod
    def examples(cls) -> dict:
        return {cls.name: (cls(), 7)}

    def example(self, n, rng):
        ex = zhao2018_example()
        if n != len(ex.nominal):
            raise NotImplementedError("affine-maneuver's example is Zhao's 7 robots")
        reference, _ = example_reference(ex, np.array([3.0]), relay=self.relay)
        own = np.pad(ex.initial, ((0, 0), (0, 1))) + 0.1 * rng.normal(size=(n, 3))
        return own, reference(0)

    def consensus_error(self, own, desired):
        """The root mean square over the robots of ``|p_i - (A p̄_i + b)|``, m (the law's invariant:
        every robot on its target, the leaders pinning ``A`` and ``b``)."""
        d = np.asarray(own, dtype=float)[..., :3] - np.asarray(desired, dtype=float)[..., :3]
        return np.sqrt(np.mean(np.sum(d * d, axis=-1), axis=-1))

    def init(self, n: int, batch: tuple = ()):
        """Each robot's last command ``(*batch, n, 3)`` m/s (0 before the first tick)."""
        return np.zeros(tuple(batch) + (n, 3))

    def signal_columns(self):
        return {"target_error": ("target_error",), "missing": ("missing",)}

    def reference_arrays(self, reference, n: int):
        if isinstance(reference, dict) and "desired" in reference and "target" not in reference:
            reference = dict(reference, target=reference["desired"],  # the targets: the desired positions
                             target_rate=reference.get("desired_rate", np.zeros(np.shape(reference["desired"]))))
        out = {}
        for key, (width, unit) in REFERENCE_KEYS.items():
            try:
                a = np.asarray(reference[key], dtype=float)
            except (KeyError, TypeError, ValueError):
                raise InvalidInputError(f"affine-maneuver: the reference needs {key!r}, an array (N, "
                                        f"{width or 'N'}) ({unit}); affine_reference builds it (in a network "
                                        f"scenario file: an [affine] table with leaders and keyframes)") from None
            want = (n, width or n)
            if a.shape[-2:] != want:
                raise ShapeError(f"affine-maneuver: reference {key!r} must have shape (*batch, {want[0]}, {want[1]}), "
                                 f"got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise InvalidInputError(f"affine-maneuver: reference {key!r} holds NaN or infinity")
            out[key] = a
        lead = out["leader"][..., 0]
        if np.any((lead != 0.0) & (lead != 1.0)):
            raise InvalidInputError("affine-maneuver: reference 'leader' must be 1 (a leader) or 0 (a follower) per "
                                    "robot")
        w = out["stress"]
        if np.any(np.diagonal(w, axis1=-2, axis2=-1) != 0.0):
            raise InvalidInputError("affine-maneuver: reference 'stress' has a nonzero diagonal; give each robot's "
                                    "ω_ij with ω_ii = 0 (quatform.network.stress.Stress.rows())")
        gamma = np.sum(w, axis=-1)
        bad = (lead == 0.0) & (gamma <= 0.0)
        if np.any(bad):
            rows = np.unique(np.argwhere(bad)[:, -1])
            raise InvalidInputError(f"affine-maneuver: follower(s) {robots_text(rows)} have γ_i = sum_j ω_ij <= 0; "
                                    f"a positive semidefinite stress with Ω_ff positive definite has γ_i > 0 for "
                                    f"every follower: build the rows with quatform.network.stress.Stress and check the "
                                    f"leaders with Stress.check_leaders")
        return out

    def _leader_command(self, own, reference):
        return reference["target_rate"] + self.leader_gain * (reference["target"] - own)

    def message(self, state, own, reference, t):
        xp = common_namespace(own, state)
        leader = reference["leader"] > 0.5                                               # (*b, N, 1)
        v = xp.where(leader, self._leader_command(own, reference), state)
        return xp.concatenate([own, xp.broadcast_to(v, own.shape)], axis=-1)

    def tick(self, state, own, inbox, reference, t) -> LocalTick:
        xp = common_namespace(own, inbox["messages"], state)
        stress = xp.asarray(reference["stress"], dtype=own.dtype)                        # (*b, N, N)
        senders = np.asarray(inbox["senders"])                                           # (N, W)
        idx = xp.asarray(np.maximum(senders, 0))
        idx = xp.broadcast_to(idx, stress.shape[:-1] + senders.shape[-1:])
        w = xp.where(xp.asarray(senders >= 0), xp.take_along_axis(stress, idx, axis=-1), 0.0)  # (*b, N, W)
        valid = inbox["valid"]
        msg = inbox["messages"]
        age = xp.where(valid, xp.asarray(t)[..., None, None] - inbox["stamps"], 0.0)  # (*b, N, W); t: () or per world
        pj = msg[..., :3] + age[..., None] * msg[..., 3:]
        term = self.gain * (pj - own[..., None, :]) + msg[..., 3:]                       # (*b, N, W, 3)
        held = xp.where(valid, w, 0.0)
        total = xp.sum(held[..., None] * term, axis=-2)
        neighbours = xp.sum(xp.asarray(stress != 0.0, dtype=own.dtype), axis=-1)
        heard = xp.sum(xp.asarray(valid & (w != 0.0), dtype=own.dtype), axis=-1)
        missing = neighbours - heard                                                     # (*b, N)
        gamma = xp.sum(stress, axis=-1)
        safe = xp.where(gamma > 0.0, gamma, 1.0)
        zhao = (1.0 - self.relay) * state + self.relay * total / safe[..., None]
        follower = xp.where((missing < 0.5)[..., None], zhao, 0.0)
        leader = reference["leader"] > 0.5
        u = xp.where(leader, self._leader_command(own, reference), follower)
        u = xp.broadcast_to(u, own.shape)
        diff = own - reference["target"]
        err = xp.sqrt(xp.sum(diff * diff, axis=-1, keepdims=True))
        code = xp.zeros(own.shape[:-1], dtype=xp.int64)
        return LocalTick(u, u, {"target_error": err, "missing": missing[..., None]}, code)


def affine_reference(stress: Stress, leaders, targets, rates, relay: float = 1.0):
    """The per-tick reference of :class:`AffineManeuver`: ``reference(k)`` for tick ``k``.

    Parameters
    ----------
    stress : Stress
        The nominal configuration's stress (its rows travel in the reference).
    leaders : sequence of int
        0-based leader indices; Zhao's condition is checked (:meth:`Stress.check_leaders`).
    targets, rates : array_like, shape (T, n, d) or (T, *batch, n, d)
        ``p*_i(t_k) = A p̄_i + b`` (m) and ``v*_i = A_dot p̄_i + b_dot`` (m/s) of every robot at
        each tick, ``d <= 3`` (padded with zeros to ``x, y, z``).
    relay : float
        The law's ``relay`` step; refused in one line where the followers' relayed velocities
        do not contract (:meth:`Stress.relay_factor` ``>= 1``).
    """
    stress.check_leaders(leaders)
    rho = stress.relay_factor(leaders, relay)
    if rho >= 1.0:
        raise InvalidInputError(f"affine reference: at relay = {relay:.6g} the followers' relayed velocities do not "
                                f"contract (ρ(I - β Γ_f^-1 Ω_ff) = {rho:.6g} >= 1); give AffineManeuver(relay="
                                f"{stress.relay_step(leaders):.6g}) and the same relay here (Stress.relay_step)")
    lead = stress._leaders(leaders)
    n = stress.n
    targets = np.asarray(targets, dtype=float)
    rates = np.asarray(rates, dtype=float)
    if targets.shape != rates.shape or targets.ndim < 3 or targets.shape[-2] != n or targets.shape[-1] > 3:
        raise ShapeError(f"affine reference: targets and rates must both have shape (T, *batch, {n}, d), d <= 3; "
                         f"got {targets.shape} and {rates.shape}")
    pad = [(0, 0)] * (targets.ndim - 1) + [(0, 3 - targets.shape[-1])]
    targets, rates = np.pad(targets, pad), np.pad(rates, pad)
    flag = np.zeros((n, 1))
    flag[lead] = 1.0
    rows = stress.rows()
    return lambda k: {"target": targets[k], "target_rate": rates[k], "leader": flag, "stress": rows}


def example_reference(example: AffineExample, times, stress: Stress | None = None, relay: float = 1.0):
    """``(reference, stress)``: :func:`affine_reference` of ``example``'s maneuver at ``times`` (s)."""
    stress = Stress(example.nominal, example.edges) if stress is None else stress
    p, v = example.targets(np.asarray(times, dtype=float))
    return affine_reference(stress, example.leaders, p, v, relay), stress
