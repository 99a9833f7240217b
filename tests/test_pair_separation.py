"""The two-robot formations keep robots apart where asked, and refuse robots on each other.

* The separation barrier of seed 000's files (``[safety] min_separation_m``, ``--min-separation``):
  the dual-quaternion law of seed 000 eq. (28) brings robots that start in place with their
  yaws off (by more than about 2 rad each) close together; with the barrier they never come
  within the set distance and still reach the reference.
* ``singularity_measure`` of coincident robots is a DegenerateInputError naming them; the robot
  spaces (pair and team: ``J = I``, nothing to divide by) give 1.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import pair_robot_error, pair_separation

from quatform import cli
from quatform.control import DualQuaternionController, Reference, SafeController, SeparationBarrier
from quatform.errors import DegenerateInputError, InvalidInputError
from quatform.formations import TEAM_FORMATIONS, DualQuaternionPair, EuclideanPair, QuaternionPair, RobotSpace
from quatform.formations import geometry as g
from quatform.scenarios import load_scenario
from quatform.scenarios.separation import separation_barrier
from quatform.scenarios.pair import run_pair
from quatform.scenarios.team import TEAM
from quatform.sim import compute_metrics

#: The reproducer's formation: robots 3.77 m apart (2 d_c), and its yaw-only start.
E = np.array([-2.494, 0.69, 0.491, 2.034, -0.253, 1.885, -0.864, 1.086])
YAWS = np.array([0, 0, 0, 2.811, 0, 0, 0, -2.849])
HALF = 0.5 * 2 * E[5]  # half the robots' separation, m




def scenario_file(tmp_path, safety="", offset=(2.811, -2.849), d_c=E[5], name="s"):
    """The reproducer as a pair scenario: the formation ``E`` held still, the robots starting
    with their yaws off by ``offset`` (phi_1, phi_2 move the yaws only)."""
    f = tmp_path / f"{name}.toml"
    f.write_text(f'name = "{name}"\nduration_s = 5.0\nmetrics_from_s = 4.0\ngains = "table1"\n'
                 '[robots]\nmax_speed_m_s = 3.0\nmax_yaw_rate_rad_s = 4.0\n'
                 f'[path]\ncentroid = "fixed"\ncenter = [{E[0]}, {E[1]}, {E[2]}]\nbeta_c = {E[3]}\n'
                 f'gamma_c = {E[4]}\nd_c = {d_c}\nphi_1 = {E[6]}\nphi_2 = {E[7]}\n'
                 f'[initial_offset]\nphi_1 = {offset[0]}\nphi_2 = {offset[1]}\n' + safety)
    return f


# -- the dual-quaternion pair's yaw-only starts ---------------------------------------------

def test_the_law_alone_brings_yaw_only_starts_together():
    """The reproducer without the barrier (what the barrier is for): 3.77 m -> 0.94 m."""
    C = DualQuaternionController()
    rd = RobotSpace().from_euclidean(E)
    c, cd = C.formation.from_euclidean(E, np.zeros(8))
    r, seps = rd + YAWS, []
    for _ in range(300):
        r = r + 0.01 * C.step(0, r, Reference(c, cd, rd))
        seps.append(pair_separation(r))
    assert pair_separation(rd) == pytest.approx(3.77)
    assert min(seps) == pytest.approx(0.944, abs=1e-3)


def test_the_reproducer_with_the_barrier_never_comes_within_the_set_distance(tmp_path):
    """The issue's loop, the controller in a SafeController with the run's barrier at
    half the separation: the robots stay 1.885 m apart or more and reach the reference."""
    sc = load_scenario(scenario_file(tmp_path))
    C = SafeController(DualQuaternionController(), separation_barrier(HALF, sc.dt_s))
    rd = RobotSpace().from_euclidean(E)
    c, cd = C.inner.formation.from_euclidean(E, np.zeros(8))
    r, seps = rd + YAWS, []
    for _ in range(600):
        r = r + 0.01 * C.step(0, r, Reference(c, cd, rd))
        seps.append(pair_separation(r))
    assert min(seps) >= HALF
    assert pair_robot_error(r, rd) < 1e-9


def test_scenario_safety_table_holds_the_reproducer_apart(tmp_path):
    """``[safety] min_separation_m`` in a pair scenario: the dual-quaternion run of the
    reproducer (in place, yaws off by 2.811 and -2.849 rad) came to 0.94 m; with the barrier
    at 1.885 m it stays there or farther and ends at the reference."""
    bare = run_pair(load_scenario(scenario_file(tmp_path, name="bare")), "dual-quaternion")
    assert compute_metrics(bare)["min_robot_separation_m"] < 1.0
    sc = load_scenario(scenario_file(tmp_path, f"[safety]\nmin_separation_m = {HALF}\n"))
    assert sc.safety == {"enabled": True, "min_separation_m": HALF}
    run = run_pair(sc, "dual-quaternion")
    m = TEAM.experiment(sc, controller="dual-quaternion").metrics(run)
    assert m["min_robot_separation_m"] >= HALF
    assert m["safety_min_separation_m"] == HALF and 0 < m["safety_active_time_s"] < 5
    assert pair_robot_error(run["state"][-1], run["r_des"][-1]) < 1e-6
    off = load_scenario(scenario_file(tmp_path, f"[safety]\nenabled = false\nmin_separation_m = {HALF}\n", name="o"))
    assert compute_metrics(run_pair(off, "dual-quaternion"))["min_robot_separation_m"] < 1.0


def test_random_yaw_only_starts_never_come_within_the_set_distance(tmp_path):
    """50 random yaw-only starts (each yaw off by up to pi, a batch of worlds) of the
    reproducer's formation with ``min_separation=1.885`` (half the separation): none comes
    closer, every one reaches the reference. Without the barrier some come within half (0.95 m)."""
    rng = np.random.default_rng(3)
    sc = load_scenario(scenario_file(tmp_path, offset=(0.0, 0.0)))
    rd = RobotSpace().from_euclidean(E)
    r0 = np.tile(rd, (50, 1))
    r0[:, [3, 7]] += rng.uniform(-np.pi, np.pi, (50, 2))
    bare = TEAM.experiment(sc, controller="dual-quaternion", r0=r0).run()
    assert np.count_nonzero(pair_separation(bare["state"]).min(axis=0) < HALF) >= 2
    run = TEAM.experiment(sc, controller="dual-quaternion", r0=r0, min_separation=HALF).run()
    assert pair_separation(run["state"]).min() >= HALF
    assert pair_robot_error(run["state"][-1], np.broadcast_to(rd, r0.shape)) < 1e-6


def test_cli_min_separation_option(tmp_path, capsys):
    """``quatform run FILE --controller dual-quaternion --min-separation 1.885``: the run's
    metrics say the barrier ran and the robots kept the distance; a negative value is one line."""
    f = scenario_file(tmp_path)
    out = tmp_path / "out"
    assert cli.main(["run", str(f), "--controller", "dual-quaternion", "--min-separation", str(HALF),
                     "--out", str(out), "--no-plots", "--no-mcap"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["min_robot_separation_m"] >= HALF and m["safety_min_separation_m"] == HALF
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[-2:] == ["min_separation", "safety_active"]
    capsys.readouterr()
    assert cli.main(["run", str(f), "--controller", "dual-quaternion", "--min-separation", "-1",
                     "--out", str(tmp_path / "bad"), "--no-plots", "--no-mcap"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "min_separation = -1" in err[0]


def test_a_minimum_equal_to_the_robots_separation_is_kept_not_refused(tmp_path):
    """``min_separation_m = 2 d_c`` (3.77 m, the robots' start and the reference's separation):
    the scenario's checks pass it, and SafeController refused the start, "robots 1 and 2
    start 3.77 m apart, closer than min_separation_m = 3.77 m" (their positions, built by
    trigonometry, are 3.7699999999999996 m apart). The run keeps the distance to rounding."""
    d = 2 * E[5]
    sc = load_scenario(scenario_file(tmp_path, f"[safety]\nmin_separation_m = {d}\n"))
    run = run_pair(sc, "dual-quaternion")
    assert pair_separation(run["state"]).min() >= d * (1 - 1e-12)
    C = SafeController(DualQuaternionController(), SeparationBarrier(d + 1e-4))
    c, cd = C.inner.formation.from_euclidean(E, np.zeros(8))
    rd = RobotSpace().from_euclidean(E)
    with pytest.raises(DegenerateInputError, match=r"start 3\.77 m apart, closer than min_separation_m = 3\.7701 m"):
        C.step(0.0, rd, Reference(c, cd, rd))  # beyond rounding: refused, the two numbers apart in the line


@pytest.mark.parametrize("scenario", ["mas-kitts-spiral", "mas-kitts-helix", "mas-kitts-yaw-step"])
def test_builtin_pair_scenarios_run_without_the_barrier(scenario):
    """The seed's scenarios show the robots' own paths: no barrier unless asked."""
    sc = load_scenario(scenario)
    assert sc.safety["enabled"] is False
    ex = TEAM.experiment(sc, controller="dual-quaternion")
    assert isinstance(ex.controller, DualQuaternionController) and "safety" not in ex.meta
    assert isinstance(TEAM.experiment(sc, controller="robot-space", min_separation=0.5).controller, SafeController)


def test_barrier_the_run_cannot_keep_is_refused(tmp_path):
    """A minimum above the robots' start or the reference's separation, an unknown [safety]
    key, a non-positive minimum: one line naming the setting."""
    with pytest.raises(InvalidInputError, match=r"start 3\.77 m apart.*\[safety\] min_separation_m = 4 m"):
        load_scenario(scenario_file(tmp_path, "[safety]\nmin_separation_m = 4.0\n"))
    sc = load_scenario(scenario_file(tmp_path))
    with pytest.raises(InvalidInputError, match=r"min_separation = 4 m"):
        TEAM.experiment(sc, controller="quaternion", min_separation=4.0)
    with pytest.raises(InvalidInputError, match=r"'min_sep' at \[safety\].*'min_separation_m'"):
        load_scenario(scenario_file(tmp_path, "[safety]\nmin_sep = 1.0\n"))
    with pytest.raises(InvalidInputError, match=r"\[safety\] min_separation_m"):
        load_scenario(scenario_file(tmp_path, "[safety]\nmin_separation_m = 0.0\n"))
    ramp = tmp_path / "ramp.toml"
    ramp.write_text(scenario_file(tmp_path, "[safety]\nmin_separation_m = 1.0\n").read_text()
                    + '[[path.ramps]]\nvariable = "d_c"\nstart_s = 1.0\nduration_s = 2.0\nchange = -1.6\n')
    with pytest.raises(InvalidInputError, match=r"reference brings the robots to 0\.57 m at t = 3 s"):
        load_scenario(ramp)


# -- coincident robots --------------------------------------------------------------------

@pytest.mark.parametrize("F", [EuclideanPair(), QuaternionPair(), DualQuaternionPair()], ids=lambda F: F.name)
def test_singularity_measure_of_coincident_robots_names_them(F):
    """It said "r contains nan ... check the measurement" for a finite input."""
    with pytest.raises(DegenerateInputError, match=r"^r: robots 1 and 2 coincide"):
        F.singularity_measure(np.zeros(8))
    r = np.array([[0, 0, 1, 0, 1, 0, 1, 0.3], [2, 2, 2, 0.1, 2, 2, 2, 0.2]])
    with pytest.raises(DegenerateInputError, match=r"robots 1 and 2 coincide.*at index \(1,\)"):
        F.singularity_measure(r)
    assert 0 < F.singularity_measure(r[0]) <= 1


def test_singularity_measure_of_robot_space_needs_no_separation():
    """The robot space has no special set and no length to divide by: 1 for any robots."""
    assert RobotSpace().singularity_measure(np.zeros(8)) == 1.0


@pytest.mark.parametrize("n", [2, 3])
def test_team_robot_space_measure_agrees_with_the_pair_on_robots_on_each_other(n):
    """The team's robot space, as the pair's: ``J = I``, no length to divide by, 1 for any robots."""
    F = TEAM_FORMATIONS["robot-space-team"](n)
    r = np.zeros((2, F.n_r))
    r[1, 4:] = np.arange(1.0, F.n_r - 3)  # robot 1 at the origin, the others apart
    np.testing.assert_array_equal(F.singularity_measure(r), [1.0, 1.0])
    if n == 2:
        assert F.singularity_measure(np.zeros(8)) == RobotSpace().singularity_measure(np.zeros(8)) == 1.0
    np.testing.assert_allclose(F.value_spread(np.zeros(F.n_r), 1e-3), np.sqrt(F.n_r) * 1e-3, rtol=1e-15)
    with pytest.raises(DegenerateInputError, match="robots 1 and 2 coincide"):
        F.forward(np.zeros(F.n_r))  # the description itself still needs its robots apart


@pytest.mark.parametrize("name", sorted(set(TEAM_FORMATIONS) - {"robot-space-team"}))
def test_team_singularity_measure_of_coincident_robots_names_them(name):
    F = TEAM_FORMATIONS[name](3)
    with pytest.raises(DegenerateInputError, match=r"^r: robots 1 and 2 coincide"):
        F.singularity_measure(np.zeros(F.n_r))
