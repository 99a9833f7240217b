"""Linear consensus on positions with formation offsets: the position-only baseline.

Control layer. Each robot ``i`` at ``p_i`` (m) holds its desired offset ``r_i`` (m) in the
team's frame and sends ``xi_i = p_i - r_i``, its estimate of the team's common point. It
moves towards the estimates it holds of its in-neighbours (Olfati-Saber & Murray 2004, IEEE
TAC 49(9), eq. (2); Ren & Beard 2005, IEEE TAC 50(5)):

    u_i = r_dot_i + k sum_j a_ij valid_ij (xi_j - xi_i)

with ``a_ij`` the edge's weight and ``valid_ij`` whether robot ``i`` holds a message of ``j``
no older than the links' ``max_age_s`` (a missing one counts as absent, not as zero). With
perfect links the stacked ``xi`` obeys ``xi_dot = -k L xi``: with a directed spanning tree it
reaches consensus at the rate ``k Re lambda_2(L)`` (continuous time;
:meth:`quatform.network.Graph.predicted_rate`), so the robots reach the offsets ``r_i``
around a common point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...algebra.kernels import common_namespace
from ...errors import InvalidInputError, ShapeError
from ...network.graph import switching_rate
from ..local import LocalController, LocalTick

__all__ = ["PositionConsensus"]


@dataclass(frozen=True)
class PositionConsensus(LocalController):
    """Each robot: ``u_i = r_dot_i + k sum_j a_ij (xi_j - xi_i)``, ``xi = p - r`` (module docstring).

    Parameters
    ----------
    gain : float
        ``k``, 1/s, > 0.

    Reference (per tick): ``{"desired": (*batch?, N, 3) m, "desired_rate": (*batch?, N, 3) m/s}``,
    each robot's desired position ``r_i`` and its rate.
    """

    gain: float = 1.0

    name = "position-consensus"
    message_columns = ("xi_x", "xi_y", "xi_z")
    own_columns = ("x", "y", "z")
    command_columns = ("v_x", "v_y", "v_z")

    def __post_init__(self):
        k = self.gain
        if isinstance(k, bool) or not isinstance(k, (int, float, np.number)) or not np.isfinite(k) or k <= 0:
            raise InvalidInputError(f"position-consensus: gain = {k!r} must be a positive number in 1/s")

    def signal_columns(self):
        return {"disagreement": ("disagreement",), "neighbours": ("neighbours",)}

    def reference_arrays(self, reference, n: int):
        out = {}
        for key in ("desired", "desired_rate"):
            try:
                a = np.asarray(reference[key], dtype=float)
            except (KeyError, TypeError, ValueError):
                raise InvalidInputError(f"position-consensus: the reference needs {key!r}, an array (N, 3) in m"
                                        f"{'/s' if key == 'desired_rate' else ''}") from None
            if a.shape[-2:] != (n, 3):
                raise ShapeError(f"position-consensus: reference {key!r} must have shape (*batch, {n}, 3), got "
                                 f"{a.shape}")
            if not np.all(np.isfinite(a)):
                raise InvalidInputError(f"position-consensus: reference {key!r} holds NaN or infinity")
            out[key] = a
        return out

    def example(self, n, rng):
        offset = rng.normal(size=(n, 3))
        return rng.normal(size=(n, 3)), {"desired": offset, "desired_rate": rng.normal(size=(n, 3))}

    def predicted_rate(self, graph, period_s, switching_period_s=None):
        """The decay rate of the disagreement with perfect links, 1/s.

        One graph: the discrete loop's ``-log(max |1 - k dt lambda|) / dt``
        (:meth:`Graph.predicted_rate`). A schedule ``[(start_s, Graph), ...]`` repeated every
        ``switching_period_s``: the rate of one period's transition matrix
        (:func:`~quatform.network.graph.switching_rate`; 0 where the union over a period has
        no spanning tree).
        """
        if switching_period_s is None:
            return graph.predicted_rate(self.gain, dt_s=period_s)
        return switching_rate(graph, switching_period_s, self.gain, period_s)

    def message(self, state, own, reference, t):
        return own - reference["desired"]

    def tick(self, state, own, inbox, reference, t) -> LocalTick:
        xp = common_namespace(own, inbox["messages"])
        xi = own - reference["desired"]
        w = xp.where(inbox["valid"], xp.asarray(inbox["weights"], dtype=own.dtype), 0.0)  # (*b, N, W)
        diff = inbox["messages"] - xi[..., None, :]                                      # (*b, N, W, 3)
        pull = xp.sum(w[..., None] * diff, axis=-2)
        u = reference["desired_rate"] + self.gain * pull
        dis = xp.sum(w * xp.sqrt(xp.sum(diff * diff, axis=-1)), axis=-1)
        count = xp.sum(xp.asarray(inbox["valid"], dtype=own.dtype), axis=-1)
        code = xp.zeros(own.shape[:-1], dtype=xp.int64)
        return LocalTick(None, u, {"disagreement": dis[..., None], "neighbours": count[..., None]}, code)
