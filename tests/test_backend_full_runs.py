"""Every built-in scenario run to its end on the jax backend equals NumPy on every channel.

One full-length run per built-in scenario (``quatform.scenarios.builtin_scenarios``) with
its default choices: the kind's defaults, the scenario's own ``[controller]`` for teleop
(Euler parameters in every built-in one), and the ``quaternion`` controller for the pair
and team kinds, whose controller has no default; and the one known hard spot, the Euclidean
team chart of ``team-triangle-over-ugv`` (cluster space) past its vertical at t = 75 s.
Both backends run one experiment (one compilation, shared with the other jax tests where
their configuration is the same). Each channel of the finished log, derived ones included,
must agree within :data:`conftest.BACKEND_TOL` (NaN where NaN), with two rules that follow
what a value means:

* a chart's value near its singular set (the spherical ``alpha_c`` with the UAV a few
  nanometres off the vertical over the UGV, the Euclidean ``beta_c`` of a nearly vertical
  segment, and the Euler reading there) is ill-conditioned: its spread is the chart's
  :meth:`~quatform.formations.base.Formation.value_spread` of the positions' difference
  between the runs (plus their rounding, ``eps |r|``), a first-order bound from the chart's
  singularity measure (``docs/derivations.md``); on the singular set itself both runs take
  the chart's convention (the reference's value), tested in ``test_chart_singular_values.py``;
* the team's Euler reading follows the attitude through the vertical by the nearer of the
  frame's two triples (``EuclideanTeam.reading``); at a sample where the two are equally near
  the runs may read the frame by either, so a sample beyond its spread is compared as the
  other triple of the same frame, or the same triple, mod 2 pi;
* an attitude quaternion (``r_m``, ``r_s`` of the teleop kind) is one attitude with either
  sign; the ``w >= 0`` rule is a tie at half a turn (``w = 0``), where the runs' rounding picks
  either sign, so it is compared up to sign.

The chaotic runs recorded in ``docs/derivations.md`` are not default choices: the RPY
teleop law at gimbal lock (``--orientation-error rpy``; 1e-15 rad changes its run by radians)
and the pair cluster-space controller through the vertical of ``mas-kitts-helix`` (its
controller turns either way at the tie ``beta_c - beta_des = pi``), so no run here is compared
on what chaos changes.
"""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from conftest import BACKEND_TOL as TOL  # noqa: E402
from conftest import assert_metrics_equal  # noqa: E402

from quatform.formations import EuclideanTeam, UgvUavSpherical
from quatform.scenarios import builtin_scenarios, kind_of, load_scenario

EPS = np.finfo(float).eps
#: The choice of each kind whose compare option has no default.
REQUIRED = {"pair": {"controller": "quaternion"}, "team": {"controller": "quaternion"}}
#: Runs beyond the default choices: the known hard spot of the Euclidean team chart.
EXTRA = [("team-triangle-over-ugv", {"controller": "cluster-space"})]
#: Attitude quaternions (compared up to sign), by kind.
SIGN_FREE = {"teleop": ("r_m", "r_s")}


def _cases():
    out = []
    for name in sorted(builtin_scenarios()):
        kind = kind_of(load_scenario(name)).name
        out.append(pytest.param(name, REQUIRED.get(kind, {}), id=name))
    return out + [pytest.param(n, c, id=f"{n}-{c['controller']}") for n, c in EXTRA]


def _formation(controller):
    """The controller's description (through a safety filter)."""
    return getattr(getattr(controller, "inner", controller), "formation", None)


def chart_spreads(kind, exp, a, b) -> dict:
    """``{channel: spread(rows) -> (len(rows), k)}``: the first-order bound on how far each
    chart-valued channel's entries can differ between the logs ``a`` and ``b`` at the samples
    ``rows`` (:meth:`Formation.value_spread` of the chart at ``a``'s robots, for their largest
    difference between the runs plus rounding). Evaluated only where the entries differ by
    more than :data:`TOL` (a singular value decomposition per sample: a 100-robot chart's
    costs 0.3 s)."""

    def delta(p_a, p_b):
        return np.abs(p_a - p_b).max(axis=-1) + EPS * np.abs(p_a).max(axis=-1)

    if kind == "ugv-uav":
        r_a, r_b = a["r_true"], b["r_true"]

        def e(rows):  # to_chart: the spherical variables
            return UgvUavSpherical().value_spread(r_a[rows], delta(r_a[rows], r_b[rows]))

        def ts(rows):  # euclid_v, euclid_v_des (the reference: exact)
            s = e(rows)
            return np.repeat(s, 2, axis=-1) * np.tile([1.0, 0.0], s.shape[-1])

        return {"e": e, "ts_chart": ts}
    if kind == "team":
        p_a, p_b = a["points"], b["points"]
        F = _formation(exp.controller)
        out = {}
        if isinstance(F, EuclideanTeam):  # the controller's own chart: its cluster state and error
            def own(rows):
                return F.value_spread(p_a[rows], delta(p_a[rows], p_b[rows]), near_c=a["c_des"][rows])

            out["cluster"] = out["error"] = own
            reader = F
        else:
            reader = EuclideanTeam(layout=exp.meta["layout"], template=exp.scenario.template)
        if "reading" in a.channels:
            idx = [reader.names.index(n) for n in reader.reading_names]

            def reading(rows):
                return reader.value_spread(p_a[rows], delta(p_a[rows], p_b[rows]))[:, idx]

            out["reading"] = reading
        return out
    return {}


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _euler_twin(a):
    """The other Euler triple of the same frame, ``(beta + pi, pi - gamma, alpha + pi)``
    (:meth:`EuclideanTeam.reading`): the reading follows the attitude through the vertical by
    the triple nearer the last sample's, and within one sample of the vertical the two are
    equally near, so each run's rounding picks either (one frame, read twice)."""
    return np.stack([a[..., 0] + np.pi, np.pi - a[..., 1], a[..., 2] + np.pi], axis=-1)


def assert_runs_agree(kind, exp, a, b):
    """Every channel of ``a`` and ``b`` within :data:`TOL` (NaN where NaN), chart values within
    :func:`chart_spreads`, attitude quaternions up to sign; the metrics equal."""
    assert list(a.channels) == list(b.channels)
    spreads = chart_spreads(kind, exp, a, b)
    for name in a.channels:
        x, y = np.asarray(a[name], dtype=float), np.asarray(b[name], dtype=float)
        assert x.shape == y.shape and a.columns(name) == b.columns(name), name
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        if name in SIGN_FREE.get(kind, ()):
            flip = np.sum((x + y) ** 2, axis=-1) < np.sum((x - y) ** 2, axis=-1)
            y = np.where(flip[:, None], -y, y)
        diff = np.where(np.isnan(x), 0.0, np.abs(y - x))
        bad = diff > TOL
        if name in spreads and bad.any():
            rows = np.flatnonzero(bad.reshape(len(bad), -1).any(axis=-1))
            allowed = TOL + np.nan_to_num(spreads[name](rows), nan=0.0)
            bad[rows] = diff[rows] > allowed
            if name == "reading" and bad.any() and x.shape[-1] == 3:
                rows = np.flatnonzero(bad.any(axis=-1))
                allowed = TOL + np.nan_to_num(spreads[name](rows), nan=0.0)
                same = np.abs(_wrap(y[rows] - x[rows])) <= allowed
                twin = np.abs(_wrap(_euler_twin(y[rows]) - x[rows])) <= allowed
                bad[rows] = ~(same.all(axis=-1) | twin.all(axis=-1))[:, None]
        assert not bad.any(), (f"{name}: {int(bad.sum())} entries differ beyond the tolerance; the first at "
                               f"t = {a.t[np.argmax(bad.reshape(len(bad), -1).any(axis=-1))]:.3f} s by "
                               f"{diff[bad][0]:.3g}")
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))


@pytest.mark.parametrize(("name", "choice"), _cases())
def test_builtin_scenario_to_its_end_equals_numpy(name, choice):
    sc = load_scenario(name)
    kind = kind_of(sc)
    exp = kind.experiment(sc, **choice)
    a, b = exp.run(), exp.run(backend="jax")
    assert a.t[-1] >= sc.duration_s - exp.dt * exp.substeps - 1e-9  # to its end
    assert_runs_agree(kind.name, exp, a, b)
