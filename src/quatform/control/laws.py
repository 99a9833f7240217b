"""Feedback laws of the cluster-space controllers, each written once (control layer).

A law maps a cluster error (and the desired rate, for the feed-forward) to a commanded
cluster rate. Every law here is written on *components*: each argument is a Python float
or an array (a batch of formations, or a block of variables), and the same arithmetic
runs on both, so one formation stepped on floats and a batch stepped on arrays give the
same numbers.

* :func:`proportional`: ``-K e + c_dot_des``, seed 000 Fig. 2 (and the robot-space law
  of §3.1, the position and shape loops of §3.2).
* :func:`tanh_law`: ``c_dot_des - K tanh(e)``, seed 001 eqs. (4.43)-(4.44).
* :func:`quaternion_feedback`: seed 000 eq. (20) with the error order corrected (also
  seed 001 eq. (4.45)).
* :func:`dual_quaternion_feedback`: seed 000 eq. (28) with the error order corrected and
  the sign of the shape's rotation as its branch (``docs/derivations.md``).
* :class:`BlockLaw`: a per-variable-block feedback (positions, lengths, angles,
  quaternion blocks), each block one of the laws above.

Every law registers itself in :data:`LAWS` where it is defined (``@law(name)``; a law on a
whole block, with its own error, says its block size: ``@law(name, block=4)``), so a new law
is one module that a :class:`Block` names.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import concrete
from ..errors import InvalidInputError
from ..formations import pair_kernels as kern
from ..registry import Registry

__all__ = ["proportional", "tanh_law", "quaternion_feedback", "dual_quaternion_feedback", "Block",
           "BlockLaw", "LAWS", "law", "HALF_TURN_TIE"]

#: An error quaternion's scalar part within this of 0 is a half turn, whose two shortest ways
#: are a tie that ``sgn(0) = +1`` breaks (seed 000 eq. (20)): a 180 deg step gives ``qe_0 =
#: cos(pi/2) = 6e-17`` on NumPy and a few 1e-17 of either sign on JAX (its ``sin`` / ``cos`` and
#: fused products round apart), so the robots would turn opposite ways on the two backends
#: (``docs/derivations.md``, "A half turn's tie on every backend").
HALF_TURN_TIE = 1e-12


#: The laws a :class:`Block` may name, by name (filled by :func:`law` where each is defined):
#: component laws (per variable, ``fn(e, c_dot_des, k, feedforward)``) and whole-block laws
#: (``fn(q, q_des, q_des_dot, k, feedforward) -> (error, rate)``, ``fn.block_size`` variables:
#: quaternion blocks 4, dual-quaternion blocks 8).
LAWS = Registry("feedback law")


def law(name: str, block: int | None = None):
    """Register the decorated function as the feedback law ``name`` in :data:`LAWS`.

    Parameters
    ----------
    name : str
        The name a :class:`Block` gives.
    block : int or None
        None: a component law, called per variable. A number: a law on a whole block of that
        many variables with its own error, taking three gains (``K``'s diagonal).
    """
    def register(fn):
        fn.block_size = block
        return LAWS.add(name, fn)

    return register

@law("proportional")
def proportional(e, c_dot_des, k, feedforward=1.0):
    """``-k e + ff c_dot_des`` (seed 000 Fig. 2, ``c_dot_cmd = -K e + c_dot_des``).

    Parameters
    ----------
    e, c_dot_des, k : float or ndarray
        Error, desired rate and gain of one variable (or matching arrays of a block).
    feedforward : float
        1 to add the desired rate, 0 not to.
    """
    return -k * e + feedforward * c_dot_des


@law("tanh")
def tanh_law(e, c_dot_des, k, feedforward=1.0):
    """``ff c_dot_des - k tanh(e)``: seed 001 eqs. (4.43)-(4.44) (the rate saturated at ``k``)."""
    tanh = np.tanh if concrete(e) else kern.lib(e).tanh  # NumPy's tanh for floats too (its rounding)
    return feedforward * c_dot_des - k * tanh(e)


def _mul_pure(q, w1, w2, w3):
    """``q (0, w1, w2, w3)``: :func:`~quatform.algebra.kernels.qmul_components` with a zero
    scalar part dropped (the same floats for a finite ``q``)."""
    q0, q1, q2, q3 = q
    return (-q1 * w1 - q2 * w2 - q3 * w3,
            q0 * w1 + q2 * w3 - q3 * w2,
            q0 * w2 - q1 * w3 + q3 * w1,
            q0 * w3 + q1 * w2 - q2 * w1)


def _conj_mul(p, q):
    """``p* q`` on components: :func:`~quatform.algebra.kernels.qmul_components` of the
    conjugate with its signs folded in (negation is exact: the same floats)."""
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return (p0 * q0 + p1 * q1 + p2 * q2 + p3 * q3,
            p0 * q1 - p1 * q0 - p2 * q3 + p3 * q2,
            p0 * q2 + p1 * q3 - p2 * q0 - p3 * q1,
            p0 * q3 - p1 * q2 + p2 * q1 - p3 * q0)


@law("quaternion", block=4)
def quaternion_feedback(q, q_des, q_des_dot, k, feedforward=1.0):
    """Seed 000 eq. (20) with its error order corrected and a feed-forward, on components.

    ``qe = q_des* q`` (body frame), ``q_dot = 1/2 q (0, -sgn(qe_0) K qe_vec) + q_dot_des qe``
    with ``sgn(0) = +1``, ``qe_0`` within :data:`HALF_TURN_TIE` of 0 read as 0; ``q_dot_des qe = q_dot_des q_des* q`` keeps ``qe`` still when there
    is no feedback. Used by the two-robot and the UGV-UAV (seed 001 eq. (4.45)) controllers.

    Parameters
    ----------
    q, q_des, q_des_dot : sequences of 4 components (floats or arrays)
    k : sequence of 3 gains (diagonal of ``K``)
    feedforward : float
        1 to add the feed-forward, 0 not to.

    Returns
    -------
    qe, q_dot : tuples of 4 components
    """
    qe = _conj_mul(q_des, q)  # q_des* q
    h = -0.5 + 1.0 * (qe[0] < -HALF_TURN_TIE)  # -sgn(qe_0)/2, sgn(0) = +1 (a half turn's tie)
    q_dot = _mul_pure(q, h * k[0] * qe[1], h * k[1] * qe[2], h * k[2] * qe[3])  # 1/2 q (0, -sgn K qe_vec)
    if feedforward:
        q_dot = kern.qadd(q_dot, kern.qmul(*q_des_dot, *qe))
    return qe, q_dot


@law("dual-quaternion", block=8)
def dual_quaternion_feedback(q, q_des, q_des_dot, k, feedforward=1.0, signed_rotation=True):
    """Seed 000 eq. (28) with the error order corrected, on 8 components (floats or arrays).

    ``qe = qhat_des* qhat`` (body frame), ``qhat_dot = 1/2 qhat (0, -s K qe_p; 0, -sgn(qe_p0)
    K qe_d) + qhat_dot_des qe`` with ``sgn(0) = +1`` (``qe_p0`` within :data:`HALF_TURN_TIE`
    of 0 read as 0). ``s = sgn(qe_p0)`` (the seed's) where
    the sign of ``qhat`` means nothing (``signed_rotation=True``, the cluster pose); ``s =
    1`` where it is the branch of the half-way yaw (the shape ``qhat_s``: driven to
    ``+qhat_s_des``; ``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").

    Returns
    -------
    qe, q_dot : tuples of 8 components
    """
    qe = kern.dqmul(kern.dqconj(q_des), q)
    h = -0.5 + 1.0 * (qe[0] < -HALF_TURN_TIE)  # -sgn(qe_p0)/2, sgn(0) = +1 (a half turn's tie)
    hp = h if signed_rotation else -0.5
    w = (0.0, hp * k[0] * qe[1], hp * k[1] * qe[2], hp * k[2] * qe[3],
         0.0, h * k[0] * qe[5], h * k[1] * qe[6], h * k[2] * qe[7])
    q_dot = kern.dqmul(q, w)  # eq. (28): 1/2 qhat (0, -sgn K qe_p; 0, -sgn K qe_d)
    if feedforward:
        q_dot = kern.dqadd(q_dot, kern.dqmul(q_des_dot, qe))  # q_dot_des q_des* q = q_dot_des qe
    return qe, q_dot


@law("dual-quaternion-branch", block=8)
def _dual_quaternion_branch(q, q_des, q_des_dot, k, feedforward=1.0):
    """:func:`dual_quaternion_feedback` of a block whose sign is the branch (seed 000's
    shape ``qhat_s``: driven to ``+qhat_s_des``)."""
    return dual_quaternion_feedback(q, q_des, q_des_dot, k, feedforward, signed_rotation=False)




@dataclass(frozen=True)
class Block:
    """One block of a :class:`BlockLaw`: variables ``start .. start + size - 1``.

    ``law``: a :data:`LAWS` name, or ``"none"`` (the error is reported, the rate is 0: a
    variable the description holds constant); ``gains``: one per variable of a component
    law, three (``K``'s diagonal) for a quaternion block (``size`` 4).
    """

    law: str
    start: int
    size: int
    gains: tuple = ()

    def __post_init__(self):
        if self.law not in LAWS and self.law != "none":
            raise InvalidInputError(f"block law {self.law!r} unknown; choose {', '.join(LAWS)} or none")
        size = getattr(LAWS.get(self.law), "block_size", None)
        want = 3 if size else (0 if self.law == "none" else self.size)
        if size and self.size != size:
            raise InvalidInputError(f"a {self.law} block has {size} variables, got size {self.size}")
        if len(self.gains) != want:
            raise InvalidInputError(f"a {self.law} block of {self.size} variables takes {want} gains, "
                                    f"got {len(self.gains)}")


@dataclass(frozen=True)
class BlockLaw:
    """A per-variable-block feedback: each block of the cluster state its own law.

    Seed 001's UGV-UAV law (4.43)-(4.45) is ``tanh`` on the centroid and the length, a
    ``quaternion`` block on the orientation; seed 000's quaternion law (§3.2) is
    ``proportional`` on the centroid and ``d_c``, ``quaternion`` on ``q_c``, ``q_c1``, ``q_c2``.

    Parameters
    ----------
    blocks : tuple of Block
        Every variable in exactly one block.
    feedforward : bool
    """

    blocks: tuple
    feedforward: bool = True

    def __post_init__(self):
        covered = sorted(i for b in self.blocks for i in range(b.start, b.start + b.size))
        if covered != list(range(len(covered))):
            raise InvalidInputError("the blocks of a BlockLaw must cover the variables 0 .. n-1 once each")
        # per block: (slice, law or None, gains); quaternion blocks flagged by law
        plan = tuple((slice(b.start, b.start + b.size), LAWS.get(b.law), tuple(b.gains),
                      tuple(zip(range(b.start, b.start + b.size), b.gains or (None,) * b.size)),
                      getattr(LAWS.get(b.law), "block_size", None) is not None)
                     for b in self.blocks)
        object.__setattr__(self, "_plan", plan)
        object.__setattr__(self, "_n", len(covered))

    @property
    def n(self) -> int:
        return self._n

    def __call__(self, c, c_des, c_dot_des, e=None):
        """Errors and commanded rates, tuples of ``n`` components (floats or arrays).

        ``e``: the errors of the component blocks when the description wraps angles
        (``Formation.errors``); default ``c - c_des``. Quaternion blocks take their own
        body-frame error ``q_des* q``.
        """
        ff = 1.0 if self.feedforward else 0.0
        err, rate = [None] * self._n, [None] * self._n
        for s, law, k, pairs, whole in self._plan:
            if whole:  # a (dual) quaternion block: its own body-frame error
                err[s], rate[s] = law(c[s], c_des[s], c_dot_des[s], k, ff)
                continue
            for j, kj in pairs:
                ej = c[j] - c_des[j] if e is None else e[j]
                err[j] = ej
                rate[j] = 0.0 * ej if law is None else law(ej, c_dot_des[j], kj, ff)
        return tuple(err), tuple(rate)
