"""Every compute backend drives the one loop as NumPy does: each scenario kind on each backend.

:data:`quatform.sim.backends.SIM_BACKENDS` names the drivers of the loop's one tick
(:mod:`quatform.sim.loop`); NumPy is the reference, and every other backend must give its
channels within :data:`conftest.BACKEND_TOL`. The module runs, for each backend but NumPy:

* every built-in scenario to its end with its default choices (the kind's defaults, the
  scenario's own ``[controller]`` for teleop, the ``quaternion`` controller for the pair and
  team kinds, whose controller has no default), and the known hard spot of the Euclidean
  team chart (``team-triangle-over-ugv`` under cluster space past its vertical at t = 75 s);
  each channel of the finished log, derived ones included, within the tolerance (NaN where
  NaN), with three rules that follow what a value means:

  - a chart's value near its singular set (the spherical ``alpha_c`` with the UAV a few
    nanometres off the vertical over the UGV, the Euclidean ``beta_c`` of a nearly vertical
    segment, and the Euler reading there) is ill-conditioned: its spread is the chart's
    :meth:`~quatform.formations.base.Formation.value_spread` of the positions' difference
    between the runs (plus their rounding, ``eps |r|``), a first-order bound from the chart's
    singularity measure (``docs/derivations.md``); on the singular set itself both runs take
    the chart's convention, tested in ``test_chart_singular_values.py``;
  - the team's Euler reading follows the attitude through the vertical by the nearer of the
    frame's two triples (``EuclideanTeam.reading``); at a sample where the two are equally
    near the runs may read the frame by either, so a sample beyond its spread is compared as
    the other triple of the same frame, or the same triple, mod 2 pi;
  - an attitude quaternion (``r_m``, ``r_s`` of the teleop kind) is one attitude with either
    sign; the ``w >= 0`` rule is a tie at half a turn, where the runs' rounding picks either
    sign, so it is compared up to sign;

* the other choices on short pieces: the pair's four controllers (seed 000 Fig. 4's half
  turn, a tie both backends turn the same way), the team's four controllers on Pioneer and
  free-body teams, the ugv-uav kind's descriptions, lab profile and faulty motion capture,
  the teleop kind's roll-pitch-yaw law up to its lock;
* batches with per-world starts, TickMeasurement noise, latency and dropped frames (the
  ugv-uav kind with each world's own motion-capture streams), batch axes kept, progress in
  chunks that change nothing;
* failing worlds: robots on each other, a NaN start, a reading no arm makes (each fails
  alone with NumPy's one-line reason, frozen; one world raises NumPy's error), the
  separation barrier binding tick after tick (solved in the compiled tick), and a barrier
  programme the compiled tick does not solve (that world is NumPy's run,
  ``meta["numpy_worlds"]``);
* one-line refusals of what has no pure step (a MuJoCo plant, a controller with only
  ``update``, a measurement model without the contract), of an unknown backend and of a
  missing JAX;
* :func:`quatform.sim.jax_rollout.rollout_metrics`, the batched rollout reduced as it runs,
  against ``compute_metrics`` of a logged NumPy batch.

The chaotic runs recorded in ``docs/derivations.md`` are not compared past what chaos
changes: the RPY teleop law at gimbal lock (1e-15 rad changes its run by radians; its runs
stop before) and the pair cluster-space controller through the vertical of
``mas-kitts-helix`` (the tie ``beta_c - beta_des = pi``).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from conftest import BACKEND_TOL as TOL  # noqa: E402
from conftest import assert_logs_equal, assert_metrics_equal, noisy_batch, short_scenario  # noqa: E402

from quatform.errors import InvalidInputError, MissingDependencyError, NonFiniteError, ShapeError  # noqa: E402
from quatform.formations import EuclideanTeam, UgvUavSpherical  # noqa: E402
from quatform.robots import Pioneer  # noqa: E402
from quatform.scenarios import KINDS, builtin_scenarios, kind_of, load_scenario  # noqa: E402
from quatform.scenarios.team import TEAM  # noqa: E402
from quatform.scenarios.ugv_uav import ugv_uav_experiment, with_profile  # noqa: E402
from quatform.sim import loop  # noqa: E402
from quatform.sim.backends import SIM_BACKENDS, simulator  # noqa: E402
from quatform.sim.jax_rollout import ROLLOUT_METRICS, rollout_metrics  # noqa: E402
from quatform.sim.trial_measurement import TickMeasurement  # noqa: E402
from quatform.teleop.controller import MAX_JOINT_ANGLE  # noqa: E402
from quatform.tomlio import read_toml  # noqa: E402

#: Every backend but the reference.
BACKENDS = [b for b in SIM_BACKENDS if b != "numpy"]
TEAM, TELEOP = KINDS["team"], KINDS["teleop"]
PAIR_CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")
SAFETY = ("min_separation", "safety_active")


@pytest.fixture(params=BACKENDS)
def backend(request):
    """A compute backend other than NumPy."""
    return request.param


def _equal(a, b, channels=SAFETY):
    """The loop's channels (:func:`conftest.assert_logs_equal`) and ``channels`` within the tolerance."""
    assert_logs_equal(a, b)
    for key in channels:
        if key in a.channels:
            np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)


# -- every built-in scenario to its end -------------------------------------------------------------

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
def test_builtin_scenario_to_its_end_equals_numpy(name, choice, backend):
    sc = load_scenario(name)
    kind = kind_of(sc)
    exp = kind.experiment(sc, **choice)
    a, b = exp.run(), exp.run(backend=backend)
    assert a.t[-1] >= sc.duration_s - exp.dt * exp.substeps - 1e-9  # to its end
    assert_runs_agree(kind.parts_of(sc), exp, a, b)


# -- the other choices, on short pieces ---------------------------------------------------------------

@pytest.mark.parametrize("controller", PAIR_CONTROLLERS)
def test_pair_half_turn_step_turns_the_same_way(controller, backend):
    """Seed 000 Fig. 4's 180 deg yaw step (t = 1 s) is a tie between the two ways round: a
    backend that rounds ``d / 2 pi`` or ``atan2`` apart would turn the other way; the tie rule
    (algebra.angles.TIE_TURNS) turns both the same way. Metrics equal."""
    ex = TEAM.experiment(short_scenario("mas-kitts-yaw-step", 1.3), controller=controller)
    a, b = ex.run(backend="numpy"), ex.run(backend=backend)
    assert_logs_equal(a, b)
    assert_metrics_equal(ex.metrics(a), ex.metrics(b))


def _ugv_team(duration_s=0.6, move_start_s=0.1, move_s=0.4):
    """``team-triangle-over-ugv`` cut to ``duration_s``, its shape move (robot 2 to hover over
    the UGV) starting at ``move_start_s`` and lasting ``move_s``."""
    data, where = read_toml("team-triangle-over-ugv", builtin_scenarios(), "scenario")
    data = dict(data, duration_s=duration_s, metrics_from_s=0.0,
                shape=dict(data["shape"], moves=[dict(data["shape"]["moves"][0], start_s=move_start_s,
                                                      duration_s=move_s)]))
    return TEAM.from_dict(data, str(where))


def _bodies(robots, name="free-bodies"):
    """A short team scenario of ``robots`` (``[[robots]]`` entries) around free bodies: a
    tetrahedron moving and turning about a tilted axis, robot space given an orientation gain."""
    data = {"kind": "team", "name": name, "duration_s": 0.6, "dt_s": 0.02,
            "gains": {"base": "table1", "robot-space": {"k_w": 6.0}}, "robots": robots,
            "shape": {"template": "tetrahedron", "edge": 1.2},
            "path": {"kind": "line", "center": [0.0, 0.0, 1.0], "velocity": [0.3, 0.1, 0.0]},
            "attitude": {"turns": [{"axis": [0.3, 0.2, 1.0], "angle": 1.0, "start_s": 0.0, "duration_s": 0.6}]},
            "headings": {"mode": "path"}, "safety": {"min_separation_m": 0.3}}
    return TEAM.from_dict(data, name)


BODY_TEAMS = {
    "free-bodies": [{"model": "free-body", "count": 4}],  # one common limit factor
    "mixed": [{"model": "free-body", "count": 2}, {"model": "pioneer", "count": 1},
              {"model": "quadrotor", "count": 1}],  # each robot on its own
}
@pytest.mark.parametrize("team", BODY_TEAMS)
def test_the_descriptions_that_take_free_bodies(team):
    """The pose descriptions run a free-body team (robot space with its orientation gain);
    cluster space, whose chart takes no attitude of a robot, is skipped."""
    run, skipped = TEAM.compare_choices(_bodies(BODY_TEAMS[team]), "controller")
    assert run == ("quaternion", "dual-quaternion", "robot-space") and list(skipped) == ["cluster-space"]


#: Each team controller once over the team shapes: built-in teams, the Pioneer team (its
#: unicycle, each robot's own limit, robot 2's move over the UGV), free bodies.
TEAM_CASES = [("team-tetrahedron-helix", "quaternion"), ("team-ring-flip", "dual-quaternion"),
              ("team-three-bodies", "cluster-space"), ("ugv", "robot-space"), ("ugv", "cluster-space"),
              ("free-bodies", "robot-space"), ("mixed", "quaternion"), ("mixed", "dual-quaternion")]


def _team_scenario(name):
    if name == "ugv":
        return _ugv_team()
    if name in BODY_TEAMS:
        return _bodies(BODY_TEAMS[name])
    return short_scenario(name, 0.4)


@pytest.mark.parametrize("scenario, controller", TEAM_CASES)
def test_team_batch_equals_numpy(scenario, controller, backend):
    """A noisy, late, lossy batch (:func:`conftest.noisy_batch`): every world on the backend."""
    batch = noisy_batch(TEAM.experiment(_team_scenario(scenario), controller=controller))
    a, b = batch.run(backend="numpy"), batch.run(backend=backend)
    _equal(a, b)
    assert "failed" not in b.meta and "numpy_worlds" not in b.meta
    if scenario == "ugv":  # the unicycle turning within its limit, robot 2 at its own
        u = b["command"]
        assert np.abs(u[..., 1]).max() > 0.3 and np.all(np.abs(u[..., 1]) <= Pioneer().max_omega + 1e-12)
        assert abs(np.linalg.norm(u[..., 2:5], axis=-1).max() - batch.scenario.team.robots[1].max_speed) < 1e-12
    if scenario in BODY_TEAMS:  # robot 1 (a free body) turned, its quaternion unit
        q = b["state"][1:, :, 3:7]
        turn = 2.0 * np.arccos(np.minimum(1.0, np.abs(np.sum(q[-1] * q[0], axis=-1))))
        assert turn.min() > 0.02 and np.allclose(np.linalg.norm(q, axis=-1), 1.0, rtol=0, atol=1e-12), turn


def test_team_without_the_barrier_and_its_metrics_equal_numpy(backend):
    exp = TEAM.experiment(_bodies(BODY_TEAMS["mixed"]), controller="dual-quaternion")
    a, b = exp.run(backend="numpy"), exp.run(backend=backend)
    for key in a.channels:  # every channel of the finished log (the chart, the singularity measure, ...)
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=TOL, err_msg=key)
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))
    bare = dataclasses.replace(noisy_batch(exp), controller=exp.controller.inner)
    _equal(bare.run(backend="numpy"), bare.run(backend=backend), ())


#: Short runs of the ugv-uav kind: (scenario, formation, changes); front-to-over switches at 4 s.
UGV_UAV_CASES = [
    ("marciano-front-to-over", "restricted", dict(duration_s=8.0, uav_front_until_s=4.0, transient_s=1.0,
                                                   switch_transient_s=1.0)),
    ("marciano-lemniscate", "spherical", dict(duration_s=5.0)),
]
#: A lossy lab: noise on positions and orientations, latency, lost and glitched frames.
FAULTS = dict(duration_s=6.0, mocap_noise_m=0.003, mocap_noise_rad=0.01, mocap_latency_s=0.013,
              mocap_dropout_rate=0.5, mocap_glitch_rate=0.2, transient_s=1.0)


def _ugv_uav_equal(exp, backend):
    """Every channel of the finished logs, the controller's final state and the metrics equal;
    NumPy's log."""
    a, b = exp.run(), exp.run(backend=backend)
    assert list(a.channels) == list(b.channels)
    for name in a.channels:
        x, y = np.asarray(a[name], dtype=float), np.asarray(b[name], dtype=float)
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(y, x, rtol=0, atol=TOL, equal_nan=True, err_msg=name)
    sa, sb = a.meta["controller_state"], b.meta["controller_state"]
    assert (bool(np.all(sa.stopped)), sa.stop_reason) == (bool(np.all(sb.stopped)), sb.stop_reason)
    assert a.meta["stop_reason"] == b.meta["stop_reason"] and a.meta["stopped_at"] == b.meta["stopped_at"]
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))
    return a


@pytest.mark.parametrize("name, formation, changes", UGV_UAV_CASES)
def test_ugv_uav_descriptions_equal_numpy(name, formation, changes, backend):
    log = _ugv_uav_equal(ugv_uav_experiment(dataclasses.replace(load_scenario(name), **changes), formation), backend)
    if formation == "restricted":  # in front at platform level the restricted description holds: both branches ran
        reach = log["reachable"][:, 0]
        assert 0 < reach.sum() < reach.size


def test_ugv_uav_lab_profile_and_faulty_motion_capture_equal_numpy(backend):
    """The lab's world (motion-capture rate, latency, noise; the Pioneer's acceleration limits,
    two more state columns); noise, latency, dropped and glitched frames: the screen rejects,
    holds and finally stops."""
    sc = with_profile(dataclasses.replace(load_scenario("marciano-circle"), duration_s=5.0), "lab")
    log = _ugv_uav_equal(ugv_uav_experiment(sc, "quaternion"), backend)
    assert log["state"].shape[1] == 13 and np.any(log["state"][1:, 11] != log["command"][:-1, 0])  # ramping
    sc = dataclasses.replace(load_scenario("marciano-circle"), **FAULTS)
    log = _ugv_uav_equal(ugv_uav_experiment(sc, "restricted", max_hold_s=0.1), backend)
    assert np.all(np.bincount(log["frame"][:, 0].astype(int), minlength=3) > 0)  # good, dropped, rejected
    assert log["held"].sum() > 0
    assert log["stopped"][-1, 0] == 1.0 and log.meta["stop_reason"].startswith("motion capture")


def test_ugv_uav_batch_reads_each_worlds_streams(backend):
    """A batch of the ugv-uav kind: each world its own motion-capture streams, the same on both
    backends; world 0 of the batch is the run of one world."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), **dict(FAULTS, duration_s=2.0))
    exp = dataclasses.replace(ugv_uav_experiment(sc, "quaternion"), finish=lambda log: log)
    batch = dataclasses.replace(exp, x0=np.stack([exp.x0, exp.x0]))
    a, b = batch.run(backend="numpy"), batch.run(backend=backend)
    for name in a.channels:
        np.testing.assert_allclose(b[name], a[name], rtol=0, atol=TOL, equal_nan=True, err_msg=name)
    one = exp.run(backend="numpy")
    np.testing.assert_allclose(a["state"][:, 0], one["state"], rtol=0, atol=TOL)
    assert not np.array_equal(a["measured"][:, 0], a["measured"][:, 1])


#: Teleop cuts of the RPY law: (scenario, preload, duration_s), stopping before its lock.
TELEOP_RPY = [("teleop-pitch-through-90", False, 1.85), ("teleop-preload", True, 1.0),
              ("teleop-wall-contact", False, 1.4)]
#: Column prefixes of rates, forces and torques (compared relative to the column's peak).
SCALED = ("qd_", "F_", "M_", "tau_", "wall_force")


def _teleop(name, oe="euler-parameters", duration_s=0.3, preload=False):
    sc = dataclasses.replace(load_scenario(name), duration_s=duration_s)
    return TELEOP.experiment(sc, oe, preload)


def _teleop_equal(a, b):
    """Angles, positions and quaternions within the tolerance (a quaternion up to its sign);
    rates, forces and torques within it relative to the column's peak (absolute below 1)."""
    assert set(a.channels) == set(b.channels)
    for ch in a.channels:
        x, y = a[ch], b[ch]
        assert x.shape == y.shape, ch
        if ch in ("r_m", "r_s"):  # q and -q: the same orientation
            y = np.where(np.sum(x * y, axis=-1, keepdims=True) < 0, -y, y)
        for c, col in enumerate(a.columns(ch)):
            scale = max(1.0, float(np.max(np.abs(x[..., c])))) if col.startswith(SCALED) else 1.0
            np.testing.assert_allclose(y[..., c], x[..., c], rtol=0, atol=TOL * scale, err_msg=f"{ch}.{col}")


@pytest.mark.parametrize("name, preload, duration_s", TELEOP_RPY)
def test_teleop_rpy_law_equals_numpy(name, preload, duration_s, backend):
    exp = _teleop(name, "rpy", duration_s, preload)
    a, b = exp.run(backend="numpy"), exp.run(backend=backend)
    _teleop_equal(a, b)
    assert_metrics_equal(exp.metrics(a), exp.metrics(b))


# -- batches and progress ---------------------------------------------------------------------------

@pytest.mark.parametrize("controller", PAIR_CONTROLLERS)
def test_pair_batch_with_tick_measurement_equals_numpy(controller, backend):
    """Three worlds from offset starts, with noise, two ticks of latency and dropped frames."""
    ex = TEAM.experiment(short_scenario("mas-kitts-spiral", 0.5), controller=controller)
    T = ex.times.size
    rng = np.random.default_rng(7)
    x0 = ex.x0 + rng.normal(0.0, 0.2, (3, 8))
    meas = TickMeasurement(rng.normal(0.0, 0.01, (T, 3, 8)), 2, rng.random((T, 3)) < 0.2)
    ex = dataclasses.replace(ex, x0=x0, measurement=meas)
    a, b = ex.run(backend="numpy"), ex.run(backend=backend)
    assert_logs_equal(a, b)
    assert "failed" not in b.meta


def test_batch_axes_kept_and_progress_in_chunks(backend):
    ex = TEAM.experiment(short_scenario("mas-kitts-helix", 0.33), controller="quaternion", feedforward=False)
    x0 = np.broadcast_to(ex.x0, (2, 2, 8)) + np.arange(4.0).reshape(2, 2, 1) * 0.05
    ex = dataclasses.replace(ex, x0=x0)
    seen = []
    a, b = ex.run(backend="numpy"), ex.run(progress=seen.append, backend=backend)
    assert b["state"].shape == (ex.times.size, 2, 2, 8)
    assert_logs_equal(a, b)
    T = ex.times.size
    assert len(seen) == -(-T // -(-T // 10))  # chunks of ceil(T / 10) ticks
    assert seen[-1] == pytest.approx(1.0) and np.all(np.diff(seen) > 0)
    assert_logs_equal(b, ex.run(backend=backend))  # the same run in one piece


def test_teleop_batch_a_failed_world_frozen_and_chunks(backend):
    """A teleop batch: each world its own run, a reading no arm makes fails that world alone
    (frozen, NumPy's reason), the same batch on NumPy, and in ten chunks the same run."""
    exp = _teleop("teleop-wall-contact")
    rng = np.random.default_rng(3)
    x0 = np.repeat(exp.x0[None], 3, axis=0)
    x0[:, :26] += 0.02 * rng.standard_normal((3, 26))  # the joints' angles and rates; the wrist sensor at 0
    x0[2, 0] = 2.0 * MAX_JOINT_ANGLE
    run = simulator(backend)
    batch = run(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt)
    raw = dataclasses.replace(exp, finish=lambda log: log)
    _teleop_equal(dataclasses.replace(raw, x0=x0[0]).run(backend="numpy"), batch.world(0))
    assert batch.meta["failed"].tolist() == [False, False, True]
    assert "t = 0 s: measurement q_m[0] = 2000 rad is beyond" in batch.meta["failure"][(2,)]
    assert np.all(batch["state"][:, 2] == x0[2]) and np.all(batch["command"][:, 2] == 0.0)
    assert np.all(np.isnan(batch["e"][:, 2]))
    on_numpy = simulator("numpy")(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt)
    _teleop_equal(on_numpy, batch)
    assert on_numpy.meta["failure"] == batch.meta["failure"]
    told = []
    chunked = run(exp.plant, exp.controller, exp.reference, exp.times, x0, dt=exp.dt, progress=told.append)
    assert told[-1] == 1.0 and len(told) == 10
    _teleop_equal(batch, chunked)
    delayed = [sim(exp.plant, exp.controller, exp.reference, exp.times[:5], x0[:2], dt=exp.dt,
                   measurement=TickMeasurement(delay_ticks=1)) for sim in (simulator("numpy"), run)]
    _teleop_equal(*delayed)  # any measurement model with the contract
    np.testing.assert_array_equal(delayed[0]["measured"][1], delayed[0]["state"][0])


# -- failing worlds ---------------------------------------------------------------------------------

def test_pair_failures_are_numpys_and_fail_alone(backend):
    """A world starting with NaN and one with its robots on each other fail with NumPy's own
    reasons, frozen; robot space (defined with robots on each other) goes on as on NumPy; one
    world raises NumPy's error."""
    for controller in ("quaternion", "robot-space"):
        ex = TEAM.experiment(short_scenario("mas-kitts-helix", 0.1), controller=controller)
        x0 = np.repeat(ex.x0[None], 3, axis=0)
        x0[1, 0] = np.nan
        x0[2, 4:7] = x0[2, 0:3]
        raw = dataclasses.replace(ex, x0=x0, finish=lambda log: log)
        a, b = raw.run(backend="numpy"), raw.run(backend=backend)
        assert np.array_equal(a.meta["failed"], b.meta["failed"]) and a.meta["failure"] == b.meta["failure"]
        assert b.meta["failed"].tolist() == [False, True, controller != "robot-space"]
        _equal(a, b, ())
        if controller == "quaternion":
            assert "coincide" in b.meta["failure"][(2,)]
            np.testing.assert_array_equal(b["state"][:, 2], np.broadcast_to(x0[2], b["state"][:, 2].shape))
            assert np.all(b["command"][:, 2] == 0.0) and np.all(np.isnan(b["cluster"][:, 2]))
    with pytest.raises(InvalidInputError, match="coincide"):
        dataclasses.replace(TEAM.experiment(short_scenario("mas-kitts-spiral", 0.2), controller="dual-quaternion"),
                            x0=x0[2]).run(backend=backend)


def test_one_teleop_world_raises_numpys_error(backend):
    exp = _teleop("teleop-free-motion", duration_s=0.05)
    x0 = exp.x0.copy()
    x0[7] = np.nan
    with pytest.raises(NonFiniteError, match="measurement qd_m") as numpy_error:
        dataclasses.replace(exp, x0=x0).run(backend="numpy")
    with pytest.raises(NonFiniteError, match="measurement qd_m") as other:
        dataclasses.replace(exp, x0=x0).run(backend=backend)
    assert str(other.value) == str(numpy_error.value)


def test_a_team_world_with_robots_on_each_other_fails_alone(backend):
    exp = TEAM.experiment(short_scenario("team-tetrahedron-helix", 0.3), controller="quaternion")
    batch = noisy_batch(exp, B=3, spread=0.0, sigma=0.0)
    x0 = np.array(batch.x0)
    x0[1, 4:7] = x0[1, 0:3]  # robot 2 on robot 1 in world 1
    for ctrl in (exp.controller.inner, exp.controller):  # bare and with the barrier
        run = dataclasses.replace(batch, x0=x0, controller=ctrl)
        a, b = run.run(backend="numpy"), run.run(backend=backend)
        assert b.meta["failed"].tolist() == [False, True, False] == a.meta["failed"].tolist()
        assert list(b.meta["failure"]) == [(1,)] and b.meta["failure"][(1,)].startswith("t = 0 s: ")
        assert np.all(b["command"][:, 1] == 0.0) and np.all(np.isnan(b["cluster"][:, 1]))
        for w in (0, 2):  # the rest go on, as on NumPy
            for key in ("state", "command", "cluster", "error"):
                np.testing.assert_allclose(b[key][:, w], a[key][:, w], rtol=0, atol=TOL, err_msg=key)


def _crossing(scenario, controller, duration_s, cycles=(2, 2, 2, 2), seed=3):
    """``scenario`` as a batch of worlds, world ``w`` with robots ``1 ... cycles[w]`` started
    each in the next one's slot (moved by 2 cm), so their ways home cross: its barrier binds;
    noise and one tick of latency."""
    exp = TEAM.experiment(short_scenario(scenario, duration_s), controller=controller)
    slots = exp.controller.team.state_slices
    B, T = len(cycles), len(exp.times)
    x0 = np.repeat(exp.x0[None], B, axis=0)
    for w, cycle in enumerate(cycles):
        for k in range(cycle):
            x0[w, slots[k]] = exp.x0[slots[(k + 1) % cycle]]
    rng = np.random.default_rng(seed)
    x0 = x0 + 0.02 * rng.standard_normal(x0.shape)
    noise = 0.002 * rng.standard_normal((T, B, x0.shape[-1]))
    return dataclasses.replace(exp, x0=x0, measurement=TickMeasurement(noise, 1), finish=lambda log: log)


@pytest.mark.parametrize("scenario, controller", [("team-three-bodies", "robot-space"),
                                                  ("team-ring-flip", "quaternion")])
def test_a_binding_barrier_is_solved_in_the_tick(scenario, controller, backend):
    run = _crossing(scenario, controller, 1.2 if scenario == "team-three-bodies" else 2.0)
    a, b = run.run(backend="numpy"), run.run(backend=backend)
    active = a["safety_active"][..., 0]
    assert np.all(np.sum(active, axis=0) >= 5), np.sum(active, axis=0)  # every world binds, tick after tick
    assert "numpy_worlds" not in b.meta and "failed" not in b.meta  # every world solved in the tick
    _equal(a, b)


def test_more_binding_pairs_than_candidates_are_numpys_run(monkeypatch, backend):
    from quatform.control import barrier

    monkeypatch.setattr(barrier, "CANDIDATES", 1)  # one candidate: a world where two pairs bind is NumPy's
    monkeypatch.setattr(loop, "_CACHE", {})  # no compiled tick of more candidates
    run = _crossing("team-ring-flip", "quaternion", 2.0, cycles=(2, 3, 0))  # one pair, three pairs, none
    a, b = run.run(backend="numpy"), run.run(backend=backend)
    assert np.sum(a["safety_active"][..., 0], axis=0).tolist()[2] == 0
    assert b.meta["numpy_worlds"].tolist() == [False, True, False]
    _equal(a, b)


def test_a_barrier_the_tick_does_not_solve_is_numpys_run(monkeypatch, backend):
    """As if the compiled tick solved no binding programme: those worlds (a Pioneer team's, a
    free-body team's) are NumPy's runs, reported in ``numpy_worlds``; progress reaches 1 once
    they are done; one world is NumPy's run as it is."""
    from quatform.control import barrier

    solve = barrier.barrier_filter
    monkeypatch.setattr(barrier, "barrier_filter", lambda *a: (lambda r: r[:3] + (~r[2],))(solve(*a)))
    monkeypatch.setattr(loop, "_CACHE", {})  # no compiled tick of the real filter
    exp = TEAM.experiment(short_scenario("team-three-bodies", 0.4), controller="robot-space")
    batch = noisy_batch(exp, B=3, spread=0.0)
    x0 = np.array(batch.x0)
    p1, p2 = x0[2, 0:2], x0[2, 3:5]  # world 2: robot 1 behind robot 2 (0.35 m, barrier 0.3 m), its way through it
    x0[2, 0:2] = p2 + 0.35 * (p2 - p1) / np.linalg.norm(p2 - p1)
    run = dataclasses.replace(batch, x0=x0)
    seen = []
    a, b = run.run(backend="numpy"), run.run(backend=backend, progress=seen.append)
    assert np.nanmax(a["safety_active"][:, 2]) == 1.0 and np.nanmax(a["safety_active"][:, :2]) == 0.0
    assert b.meta["numpy_worlds"].tolist() == [False, False, True]
    _equal(a, b)
    assert seen[-1] == 1.0 and all(f < 1.0 for f in seen[:-1]) and len(seen) <= 10
    one = dataclasses.replace(exp, x0=x0[2], finish=lambda log: log)
    a, b = one.run(backend="numpy"), one.run(backend=backend)
    assert b.meta["numpy_worlds"] == np.True_
    _equal(a, b)
    ugv = TEAM.experiment(_ugv_team(0.4), controller="robot-space")  # a Pioneer team, its barrier binding
    batch = noisy_batch(ugv, B=3, spread=0.0)
    x0 = np.array(batch.x0)
    x0[2, 3:6] = [x0[2, 0], x0[2, 1], -0.55]  # world 2: robot 2 starts 0.55 m under the UGV, its way up through it
    run = dataclasses.replace(batch, x0=x0)
    a, b = run.run(backend="numpy"), run.run(backend=backend)
    assert np.nanmax(a["safety_active"][:, 2]) == 1.0 and np.nanmax(a["safety_active"][:, :2]) == 0.0
    assert b.meta["numpy_worlds"].tolist() == [False, False, True]
    _equal(a, b)


def test_a_start_at_the_minimum_to_rounding_is_kept_as_on_numpy(backend):
    """A barrier's minimum a few ulps above the robots' start separation: NumPy's
    SafeController keeps the start (:func:`~quatform.control.safety.start_floor`), and the
    compiled tick reads the same floor, so no world is rerun on NumPy."""
    from quatform.control.safety import start_floor

    exp = TEAM.experiment(short_scenario("team-ring-flip", 0.3), controller="quaternion")
    C = exp.controller
    P = C.team.layout.positions(C.team.point(exp.x0))
    sep = C.team.layout.separations(C.team.point(exp.x0)).min()
    d = np.nextafter(np.nextafter(sep, np.inf), np.inf)  # two ulps above the start
    assert sep < d and sep >= start_floor(P, d)[0]
    exp = dataclasses.replace(exp, controller=dataclasses.replace(C, barrier=dataclasses.replace(C.barrier,
                                                                                                 min_separation_m=d)))
    a, b = exp.run(backend="numpy"), exp.run(backend=backend)
    assert "numpy_worlds" not in b.meta and "failed" not in b.meta
    _equal(a, b)


# -- refusals ---------------------------------------------------------------------------------------

class UpdateOnly:
    """A user's controller with only ``update`` (``pure = False``): it runs on NumPy."""

    def __new__(cls, inner):
        from quatform.control.contract import Controller

        class _Update(Controller):
            name = "update-only"
            command_names = inner.command_names

            def signal_columns(self):
                return inner.signal_columns()

            def update(self, t, measured, reference, state):
                return inner.update(t, measured, reference, state)

        return _Update()


def test_refuses_what_has_no_pure_step_in_one_line(backend):
    """Decided from what the parts declare: a controller's ``pure``, a plant's ``batchable``,
    a measurement model's contract."""
    ex = TEAM.experiment(short_scenario("mas-kitts-spiral", 0.1), controller="quaternion")
    user = dataclasses.replace(ex, controller=UpdateOnly(ex.controller))
    np.testing.assert_allclose(user.run(backend="numpy")["state"], ex.run(backend="numpy")["state"], rtol=0, atol=0)

    class Once:  # a measurement model without schedule / init / observe / read
        columns = None

    class OneAtATime(type(ex.plant)):
        batchable = False

    cases = [(user, "the controller _Update has no pure tick"),
             (dataclasses.replace(ex, measurement=Once()), "the measurement model Once lacks schedule/init/observe/read"),
             (dataclasses.replace(ex, plant=OneAtATime(ex.plant.team)), "the plant OneAtATime has no pure step")]
    for run, what in cases:
        with pytest.raises(InvalidInputError) as err:
            run.run(backend=backend)
        msg = str(err.value)
        assert "\n" not in msg and what in msg and "runs pure controllers" in msg and "--compute numpy" in msg


@pytest.mark.parametrize("scenario, choice", [
    ("marciano-circle", {"formation": "quaternion", "physics": "mujoco"}),
    ("team-triangle-over-ugv", {"controller": "quaternion", "physics": "mujoco"}),
])
def test_mujoco_physics_is_refused_in_one_line(scenario, choice, backend):
    pytest.importorskip("mujoco")
    sc = load_scenario(scenario)
    sc = dataclasses.replace(sc, duration_s=0.1, **({"metrics_from_s": 0.0} if hasattr(sc, "metrics_from_s") else {}))
    with pytest.raises(InvalidInputError) as err:
        kind_of(sc).experiment(sc, **choice).run(backend=backend)
    assert "\n" not in str(err.value) and "has no pure step (batchable = False)" in str(err.value)


def test_unknown_backend_missing_jax_and_bad_shapes_in_one_line(monkeypatch):
    with pytest.raises(InvalidInputError, match="unknown compute backend 'jaks'.*jax"):
        simulator("jaks")
    ex = TEAM.experiment(short_scenario("mas-kitts-spiral", 0.2), controller="quaternion")
    with pytest.raises(ShapeError, match="holds no world"):
        dataclasses.replace(ex, x0=np.zeros((0, 8))).run(backend="jax")
    with pytest.raises(ShapeError, match=r"noise of shape \(3, 8\) for 21 ticks"):
        dataclasses.replace(ex, measurement=TickMeasurement(np.zeros((3, 8)), 0)).run(backend="jax")
    import builtins

    real = builtins.__import__

    def no_jax(name, *args, **kwargs):
        if name == "jax" or name.startswith("jax."):
            raise ImportError("No module named 'jax'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_jax)
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[jax\]"'):
        ex.run(backend="jax")


# -- the JAX driver's own ---------------------------------------------------------------------------

def test_global_x64_left_alone_and_equal_configurations_compile_once():
    before = jax.config.jax_enable_x64
    sc = short_scenario("mas-kitts-helix", 0.1)
    a, b = (TEAM.experiment(sc, controller="quaternion") for _ in range(2))
    assert a.run(backend="jax")["state"].dtype == np.float64
    assert jax.config.jax_enable_x64 == before
    assert a.controller is not b.controller
    assert loop.config_key(a.plant, a.controller, None) == loop.config_key(b.plant, b.controller, None)
    other = TEAM.experiment(dataclasses.replace(sc, gains={"quaternion": {"k_x": [1, 1, 1]}}), controller="quaternion")
    assert loop.config_key(other.plant, other.controller, None) != loop.config_key(a.plant, a.controller, None)


def test_team_sweep_equals_numpy(tmp_path, backend):
    from quatform.sweeps import run_sweep
    from quatform.sweeps.spec import sweep_from_dict

    data = {"name": "tiny-team", "scenario": "team-grid-100", "trials": 2, "seed": 0, "duration_s": 0.5,
            "settle_s": 0.0, "controllers": ["quaternion"],
            "vary": {"team_size": {"values": [4]}, "noise_m": {"values": [0.005]}, "noise_rad": {"values": [0.005]},
                     "initial_offset_m": {"values": [0.1]}, "initial_offset_rad": {"values": [0.1]}}}
    spec = sweep_from_dict(data, "tiny-team")
    rows = {}
    for name in ("numpy", backend):
        run_sweep(spec, tmp_path / name, backend=name, plots=False, quiet=True)
        rows[name] = json.loads((tmp_path / name / "results.json").read_text())["rows"]
    assert len(rows[backend]) == len(rows["numpy"]) == 2
    for a, b in zip(rows["numpy"], rows[backend]):
        assert a.keys() == b.keys()
        for key, value in a.items():
            if isinstance(value, float) and np.isfinite(value):
                assert abs(b[key] - value) <= TOL, key
            elif not isinstance(value, float):
                assert b[key] == value, key


# -- the batched rollout reduced as it runs ----------------------------------------------------------

def _assert_rollout_is_compute_metrics(res, ex, logged, worlds):
    """Every key the rollout returns equals ``ex.metrics`` of each healthy logged world."""
    assert {"reference_lost", "max_orientation_error_rad", "robot_position_error_median_m"} <= set(res)
    for i in worlds:
        want = ex.metrics(logged.world(i))
        for key in set(ROLLOUT_METRICS) & set(res):
            got, exp = res[key][i], want[key]
            if exp is None:
                assert np.isnan(got), key
            elif isinstance(exp, bool):
                assert bool(got) == exp, key
            else:
                assert float(got) == pytest.approx(float(exp), rel=1e-9, abs=TOL), key


@pytest.mark.parametrize("controller", ["quaternion", "dual-quaternion", "robot-space"])
def test_rollout_metrics_equal_compute_metrics(controller):
    """The reduced rollout's metrics equal compute_metrics of each world of a logged NumPy batch,
    the singularity measure and the recovered Euclidean error included."""
    ex = TEAM.experiment(short_scenario("mas-kitts-helix", 0.8), controller=controller)
    ex = dataclasses.replace(ex, meta={**ex.meta, "metrics_from_s": 0.3})
    T = ex.times.size
    rng = np.random.default_rng(3)
    x0 = ex.x0 + rng.normal(0.0, 0.08, (5, 8))
    x0[4, 0] = np.nan  # world 4 starts with a NaN
    meas = TickMeasurement(rng.normal(0.0, 0.004, (T, 5, 8)), 1, rng.random((T, 5)) < 0.05)
    res = rollout_metrics(ex, x0, meas, trials_per_call=2)  # chunks of 2, the last one padded
    assert {"min_singularity_measure", "max_recovered_euclidean_error_rad"} <= set(res)
    log = TEAM.experiment(dataclasses.replace(short_scenario("mas-kitts-helix", 0.8), metrics_from_s=0.3),
                          controller=controller)
    log = dataclasses.replace(log, x0=x0, measurement=meas, finish=lambda log: log)
    raw = log.run(backend="numpy")
    assert res["failed"].tolist() == raw.meta["failed"].tolist() == [False] * 4 + [True]
    assert res["failure"] == raw.meta["failure"]
    healthy = TickMeasurement(meas.noise[:, :4], 1, meas.dropped[:, :4])
    ex = dataclasses.replace(TEAM.experiment(dataclasses.replace(short_scenario("mas-kitts-helix", 0.8),
                                                                 metrics_from_s=0.3), controller=controller),
                             x0=x0[:4], measurement=healthy)
    _assert_rollout_is_compute_metrics(res, ex, ex.run(backend="numpy"), range(4))


@pytest.mark.parametrize("scenario, controller, barrier", [
    ("team-tetrahedron-helix", "cluster-space", False),  # four robots, the barrier off
    ("team-ring-flip", "quaternion", True),  # ten robots under the separation barrier
])
def test_rollout_metrics_of_a_team_equal_compute_metrics(scenario, controller, barrier):
    """Any N, with or without the barrier: the same keys and values as compute_metrics of the
    logged NumPy run; without the description's metrics only the errors from the robots."""
    ex = TEAM.experiment(dataclasses.replace(short_scenario(scenario, 0.5), metrics_from_s=0.2), controller=controller,
                         min_separation=None if barrier else 0.0)
    assert ex.meta["safety"]["applied"] == barrier
    x0 = ex.x0 + np.random.default_rng(5).normal(0.0, 0.01, (3,) + ex.x0.shape)
    ex = dataclasses.replace(ex, x0=x0)
    res = rollout_metrics(ex, x0, trials_per_call=2)
    assert ("safety_active_time_s" in res) == barrier and "min_singularity_measure" in res
    logged = ex.run(backend="numpy")
    _assert_rollout_is_compute_metrics(res, ex, logged, range(3))
    bare = rollout_metrics(ex, x0, formation_metrics=False)
    assert "min_singularity_measure" not in bare and "max_recovered_attitude_error_rad" not in bare
    _assert_rollout_is_compute_metrics(bare, ex, logged, range(3))


@pytest.mark.parametrize("bad", [0, -1, 0.5, "3", True, float("nan")])
def test_rollout_refusals_are_one_line(bad):
    ex = TEAM.experiment(short_scenario("mas-kitts-helix", 0.05), controller="quaternion")
    with pytest.raises(InvalidInputError, match="trials_per_call"):
        rollout_metrics(ex, np.broadcast_to(ex.x0, (2, 8)), trials_per_call=bad)
    with pytest.raises(ShapeError, match="at least one world"):
        rollout_metrics(ex, np.zeros((0, 8)))
    user = dataclasses.replace(ex, controller=UpdateOnly(ex.controller))
    with pytest.raises(InvalidInputError, match="rollout_metrics reduces batched experiments of kinematic robots") as e:
        rollout_metrics(user)
    assert "\n" not in str(e.value)
