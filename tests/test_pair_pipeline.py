"""The seed 000 pair runs on the one pipeline: kind, experiment, simulate, Log, metrics, CSV."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import pair_robot_error
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.control import CONTROLLERS
from quatform.errors import InvalidInputError, ShapeError
from quatform.formations import EuclideanPair, QuaternionPair, RobotSpace, RobotSpaceTeam
from quatform.robots import HolonomicRobot, Team
from quatform.scenarios import KINDS, kind_aliases, kind_of
from quatform.scenarios.pair import TABLE_COLUMNS, Scenario, pair_csv_channels, run_pair
from quatform.scenarios.team import TEAM, TeamScenario
from quatform.scenarios import load_scenario
from quatform.sim import compute_metrics
from quatform.report.writers import timeseries_table
from quatform.sim.plants import KinematicTeam

#: Offsets (Euclidean variables) of the batched worlds: m for x_c, y_c, z_c, d_c; rad else.
_SCALE = np.array([0.2, 0.2, 0.2, 0.3, 0.3, 0.1, 0.3, 0.3])


def _short_spiral(duration=1.5):
    return dataclasses.replace(load_scenario("mas-kitts-spiral"), duration_s=duration, metrics_from_s=0.0)


def _starts(sc, offsets):
    e0, _ = sc.path(np.zeros(1))
    return EuclideanPair().inverse(e0[0] + offsets)


def test_seed_000_files_read_into_the_team_kind_with_the_pair_chart():
    sc = load_scenario("mas-kitts-spiral")
    assert "pair" not in KINDS and kind_aliases()["pair"] == "team"
    assert isinstance(sc, Scenario) and isinstance(sc, TeamScenario) and kind_of(sc) is TEAM
    assert sc.chart == "pair" and TEAM.parts_of(sc) == "pair" and TEAM.columns_of(sc) == TABLE_COLUMNS
    assert TEAM.compare_choices(sc, "controller") == (tuple(CONTROLLERS), {})
    opts = {o.name: o for o in TEAM.options}
    assert set(opts["controller"].choices) == set(CONTROLLERS) and opts["controller"].default is None
    assert opts["physics"].choices == ("kinematic", "mujoco") and opts["physics"].default == "kinematic"
    assert "backend" not in opts  # the compute backend is Experiment.run(backend=...), --compute


def test_a_file_of_kind_pair_reads_into_the_team_kind_and_a_bad_key_is_one_line(tmp_path):
    good = tmp_path / "p.toml"
    good.write_text('kind = "pair"\nname = "p"\nduration_s = 2.0\n[path]\nd_c = 0.5\n')
    sc = load_scenario(good)
    assert isinstance(sc, Scenario) and kind_of(sc) is TEAM and sc.chart == "pair" and sc.metrics_from_s == 0.0
    bad = tmp_path / "q.toml"
    bad.write_text('kind = "pair"\nduration_s = 2.0\n[path]\nraduis = 1.0\n')
    with pytest.raises(InvalidInputError, match="raduis") as err:
        load_scenario(bad)
    assert "\n" not in str(err.value) and "radius" in str(err.value)


@pytest.mark.parametrize("controller", list(CONTROLLERS))
def test_a_batch_of_worlds_equals_the_worlds_run_one_by_one(controller):
    sc = _short_spiral()
    r0 = _starts(sc, np.random.default_rng(7).normal(scale=_SCALE, size=(3, 8)))
    batch = run_pair(sc, controller, r0=r0)
    assert batch.batch_shape == (3,) and batch["state"].shape == (sc.times.size, 3, 8)
    for i in range(3):
        one, world = run_pair(sc, controller, r0=r0[i]), batch.world(i)
        assert set(world.channels) == set(one.channels)
        for name in one.channels:
            np.testing.assert_allclose(world[name], one[name], rtol=0, atol=1e-12, err_msg=name)
        mb, ms = compute_metrics(world), compute_metrics(one)
        for key, v in ms.items():
            if isinstance(v, float):
                assert mb[key] == pytest.approx(v, rel=1e-12, abs=1e-12), key
            else:
                assert mb[key] == v, key


@settings(max_examples=5, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=8, max_size=8))
def test_a_batch_of_two_grid_worlds_equals_single_runs(unit):
    """Two worlds on a (2, 1) batch grid: any leading axes, each world its own start."""
    sc = _short_spiral(0.3)
    off = np.array(unit) * _SCALE
    r0 = _starts(sc, np.stack([off, -off]))[:, None, :]
    batch = run_pair(sc, "quaternion", r0=r0)
    assert batch.batch_shape == (2, 1)
    for i, sign in enumerate((1.0, -1.0)):
        one = run_pair(sc, "quaternion", r0=_starts(sc, sign * off))
        np.testing.assert_allclose(batch.world((i, 0))["state"], one["state"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch.world((i, 0))["singularity"], one["singularity"], rtol=0, atol=1e-12)


def test_metrics_of_a_batch_are_taken_one_world_at_a_time():
    sc = _short_spiral(0.2)
    log = run_pair(sc, "cluster-space", r0=_starts(sc, np.zeros((2, 8))))
    with pytest.raises(ShapeError, match=r"log.world\(i\)"):
        compute_metrics(log)
    assert compute_metrics(log.world(1))["scenario"] == "mas-kitts-spiral"


#: Recorded values (tools/metrics_regression.py baseline, `quatform run`).
_BASELINE = {
    ("mas-kitts-spiral", "cluster-space", 28.0): {  # the run is causal: its first 28 s are the full run's
        "first_singular_time_s": 27.44, "first_lost_time_s": 27.61},
    ("mas-kitts-spiral", "quaternion", None): {
        "first_singular_time_s": None, "first_lost_time_s": None,
        "min_singularity_measure": 0.31002897925504336, "max_cluster_position_error_m": 6.39694880374462e-05,
        "min_robot_separation_m": 2.005097172964871, "max_recovered_euclidean_error_rad": 4.396032626363677e-06},
    ("mas-kitts-yaw-step", "robot-space", None): {
        "first_singular_time_s": None, "min_singularity_measure": 1.0,
        "min_robot_separation_m": 0.011758843168274875, "max_recovered_euclidean_error_rad": 0.012923706860479278},
}


@pytest.mark.parametrize("case", list(_BASELINE))
def test_metrics_read_from_the_log_equal_todays_values(case):
    name, controller, duration = case
    sc = load_scenario(name)
    sc = sc if duration is None else dataclasses.replace(sc, duration_s=duration)
    m = compute_metrics(run_pair(sc, controller))
    for key, v in _BASELINE[case].items():
        assert m[key] == (None if v is None else pytest.approx(v, rel=1e-9, abs=1e-15)), key


_ROBOTS = "t,x1,x1_des,y1,y1_des,z1,z1_des,theta1,theta1_des,x2,x2_des,y2,y2_des,z2,z2_des,theta2,theta2_des"
_EUCLID = ",".join(f"euclid_{v},euclid_{v}_des" for v in ("x_c", "y_c", "z_c", "beta_c", "gamma_c", "d_c",
                                                             "phi_1", "phi_2"))
_TAIL = "u_x1,u_y1,u_z1,u_theta1,u_x2,u_y2,u_z2,u_theta2,singularity_measure"
_DQ = ",".join(f"qhat_{s}_{p}{c},qhat_{s}_{p}{c}_des" for s in "cs" for p in "rd" for c in "wxyz")


@pytest.mark.parametrize(("controller", "header"), [
    ("robot-space", f"{_ROBOTS},{_EUCLID},{_TAIL}"),  # the recorded yaw-step robot-space timeseries.csv
    ("dual-quaternion", f"{_ROBOTS},{_DQ},{_EUCLID},{_TAIL}"),
])
def test_the_csv_header_is_todays(controller, header):
    exp = TEAM.experiment(_short_spiral(0.05), controller=controller)
    assert exp.csv_channels == pair_csv_channels(exp.controller.formation)
    names, data = timeseries_table(exp.run(), exp.csv_channels)
    assert ",".join(names) == header and data.shape == (6, len(names))


def test_the_csv_columns_hold_the_log_channels():
    log = run_pair(_short_spiral(0.05), "quaternion")
    names, data = timeseries_table(log, pair_csv_channels(QuaternionPair()))
    np.testing.assert_array_equal(data[:, names.index("x2_des")], log["r_des"][:, 4])
    np.testing.assert_array_equal(data[:, names.index("q_c_z")], log["cluster"][:, 6])
    np.testing.assert_array_equal(data[:, names.index("singularity_measure")], log["singularity"][:, 0])


def test_the_kinematic_plant_is_the_team_step():
    team = Team((HolonomicRobot(1.0, 1.0), HolonomicRobot(2.0, 0.5)))
    plant = KinematicTeam(team)
    assert plant.state_columns == ("x1", "y1", "z1", "theta1", "x2", "y2", "z2", "theta2") and plant.batchable
    rng = np.random.default_rng(3)
    x, u = rng.normal(size=(4, 8)), 3.0 * rng.normal(size=(4, 8))
    np.testing.assert_array_equal(plant.step(x, u, 0.01, 0.0), team.step(x, u, 0.01))
    assert np.all(np.linalg.norm(plant.step(x, u, 1.0)[:, 0:3] - x[:, 0:3], axis=1) <= 1.0 + 1e-12)


def test_interleaved_csv_channels_must_have_one_width():
    log = run_pair(_short_spiral(0.05), "quaternion")
    with pytest.raises(InvalidInputError, match="different widths"):
        timeseries_table(log, [("state", "cluster")])


def test_the_experiment_refuses_a_bad_physics_and_options():
    sc = _short_spiral(0.05)
    with pytest.raises(InvalidInputError, match="give a controller"):
        TEAM.experiment(sc)
    with pytest.raises(InvalidInputError, match="unknown physics 'gazebo'"):
        TEAM.experiment(sc, controller="quaternion", physics="gazebo")
    with pytest.raises(InvalidInputError, match="physics = 'mujoco' only"):
        TEAM.experiment(sc, controller="quaternion", physics_options={"gains": {}})
    with pytest.raises(InvalidInputError, match="timestep"):
        TEAM.experiment(sc, controller="quaternion", physics="mujoco", physics_options={"timestep": 1e-3})
    with pytest.raises(InvalidInputError, match="must be a TeamScenario"):
        TEAM.experiment("mas-kitts-spiral", controller="quaternion")


def test_simulate_refuses_ticks_that_are_not_substeps_times_dt_apart():
    """The plant advanced ``substeps`` steps of ``dt`` between ticks whatever the ticks said:
    ticks 10 ms apart with dt = 0.1 ms logged t = 0.1 s for 1 ms of motion, silently."""
    from quatform.errors import InvalidInputError
    from quatform.scenarios import load_scenario
    from quatform.scenarios.team import TEAM
    from quatform.sim import simulate

    ex = TEAM.experiment(load_scenario("mas-kitts-yaw-step"), controller="quaternion")
    args = (ex.plant, ex.controller, ex.reference)
    with pytest.raises(InvalidInputError, match="evenly spaced"):
        simulate(*args, ex.times[:11], ex.x0, dt=0.0001)
    with pytest.raises(InvalidInputError, match="evenly spaced"):
        simulate(*args, np.array([0.0, 0.01, 0.02, 5.0]), ex.x0, dt=0.01)
    for bad in (float("nan"), 0.0, -0.01):
        with pytest.raises(InvalidInputError, match="dt"):
            simulate(*args, ex.times[:3], ex.x0, dt=bad)
    log = simulate(*args, ex.times[:11], ex.x0, dt=ex.dt)  # the experiment's own ticks run
    assert log.t.size == 11
    with pytest.raises(InvalidInputError, match="no channel"):
        log.table(["nosuch"])


# -- relative-yaw steps and offsets beyond pi on a fixed formation ----------------------

def fixed_scenario(tmp_path, extra):
    f = tmp_path / "s.toml"
    f.write_text('name = "s"\nduration_s = 8.0\nmetrics_from_s = 7.0\ngains = "table1"\n'
                 '[robots]\nmax_speed_m_s = 3.0\nmax_yaw_rate_rad_s = 4.0\n'
                 '[path]\ncentroid = "fixed"\ncenter = [0.0, 0.0, 1.0]\nd_c = 1.0\n' + extra)
    return load_scenario(f)


def test_a_reference_step_of_the_relative_yaw_keeps_the_robots_apart(tmp_path):
    """phi_1 + 1.6, phi_2 - 1.6 at t = 1 s (a CLI case that collides when the yaw
    error is not wrapped): all four controllers end at the new formation, none closer than 1.9 m."""
    sc = fixed_scenario(tmp_path, '[[path.steps]]\nvariable = "phi_1"\ntime_s = 1.0\nchange = 1.6\n'
                                  '[[path.steps]]\nvariable = "phi_2"\ntime_s = 1.0\nchange = -1.6\n')
    for name in ("cluster-space", "robot-space", "quaternion", "dual-quaternion"):
        run = run_pair(sc, name, feedforward=False)
        m = compute_metrics(run)
        assert m["min_robot_separation_m"] >= 1.9, name
        assert pair_robot_error(run["state"][-1], run["r_des"][-1]) < 1e-3, name


def test_a_yaw_initial_offset_does_not_end_with_the_robots_swapped(tmp_path):
    """[initial_offset] phi_1 = 2.0, phi_2 = -1.2 on a fixed formation ended with the robots
    swapped (3.8 m off) and the error reported zero."""
    sc = fixed_scenario(tmp_path, '[initial_offset]\nphi_1 = 2.0\nphi_2 = -1.2\n')
    run = run_pair(sc, "dual-quaternion")
    assert pair_robot_error(run["state"][-1], run["r_des"][-1]) < 1e-6
    assert compute_metrics(run)["min_robot_separation_m"] >= 1.9


# -- the pair's plots: angles drawn by their wrapped error, euclidean.png where it differs, titles --

@pytest.fixture(scope="module")
def yaw_step_runs():
    sc = load_scenario("mas-kitts-yaw-step")
    return {name: run_pair(sc, name) for name in ("cluster-space", "robot-space", "quaternion")}


def _figure_of(monkeypatch, draw, *args):
    """The matplotlib Figure a plotting function saves (its ``save`` intercepted)."""
    from quatform.report import plots

    got = []

    def keep(fig, path):
        got.append(fig)
        return path

    monkeypatch.setattr(plots, "save", keep)
    draw(*args, "unused.png")
    return got[0]


def _axes_named(fig, label):
    return next(ax for ax in fig.axes if ax.get_ylabel().startswith(label))


@pytest.mark.parametrize("name", ["cluster-space", "robot-space", "quaternion"])
def test_yaw_step_plot_draws_no_2pi_error(monkeypatch, yaw_step_runs, name):
    """beta_c steps to pi: wrapped, the desired would sit at -pi and the measured at +pi, a 2 pi
    gap that is no error. The drawn gap is the wrapped error (0 once settled)."""
    from quatform.report import plot_cluster_variables, plot_euclidean

    run = yaw_step_runs[name]
    draw = plot_euclidean if name == "quaternion" else plot_cluster_variables
    fig = _figure_of(monkeypatch, draw, run)
    ax = _axes_named(fig, "beta_c")
    meas, des = ax.lines[0], ax.lines[1]
    t = np.asarray(meas.get_xdata())
    ym, yd = np.asarray(meas.get_ydata(), float), np.asarray(des.get_ydata(), float)
    settled = t >= 5.0
    assert np.nanmax(np.abs(ym[settled] - yd[settled])) < 1e-2
    after = yd[t >= 1.0]  # the desired drawn flat at +pi or -pi (the same formation)
    assert np.all(np.abs(np.abs(after) - np.pi) < 1e-9) and np.ptp(after) < 1e-9
    ok = np.isfinite(ym)
    jumps = np.abs(np.diff(ym))[ok[1:] & ok[:-1]]
    assert jumps.max() <= np.pi + 1e-9  # no vertical line of a wrap
    plotted_err = np.abs(ym - yd)[ok]
    true_err = np.abs((run["e"][:, 3] - run["e_des"][:, 3] + np.pi) % (2 * np.pi) - np.pi)
    assert plotted_err.max() <= true_err.max() + 1e-9


def test_spiral_angle_traces_unwrapped(monkeypatch):
    """gamma_c runs 0 -> 2 pi: the desired trace is drawn as one continuous ramp."""
    from quatform.report import plot_euclidean

    sc = dataclasses.replace(load_scenario("mas-kitts-spiral"), duration_s=36.0)
    fig = _figure_of(monkeypatch, plot_euclidean, run_pair(sc, "dual-quaternion"))
    meas, des = _axes_named(fig, "gamma_c").lines[:2]
    t = np.asarray(meas.get_xdata())
    ym, yd = np.asarray(meas.get_ydata(), float), np.asarray(des.get_ydata(), float)
    assert np.all(np.isfinite(yd)) and np.abs(np.diff(yd)).max() < 0.1
    assert yd[-1] == pytest.approx(2 * np.pi, abs=1e-6)
    assert np.nanmax(np.abs(ym - yd)[t >= 5.0]) < 0.01  # the dual-quaternion run tracks it


def test_euclidean_png_only_where_it_differs(tmp_path, monkeypatch, yaw_step_runs):
    from quatform.report import plots, write_run_plots

    def quick_3d(run, path):  # the 3-D view is the slow one and not in question here
        path.write_bytes(b"x" * 2000)
        return path

    monkeypatch.setattr(plots, "plot_paths_3d", quick_3d)
    for name, run in yaw_step_runs.items():
        out = tmp_path / name
        out.mkdir()
        (out / "euclidean.png").write_bytes(b"stale")
        files = {p.name for p in write_run_plots(run, out)}
        dup = name in ("cluster-space", "robot-space")
        assert files == ({"cluster_variables.png", "paths_3d.png"} if dup
                         else {"cluster_variables.png", "euclidean.png", "paths_3d.png"}), name
        assert (out / "euclidean.png").exists() is not dup
        assert all((out / f).stat().st_size > 1000 for f in files)


def test_titles_name_the_paper(monkeypatch, yaw_step_runs):
    from quatform.report import plot_cluster_variables, plot_compare, plot_paths_3d, plot_separation

    run = yaw_step_runs["quaternion"]
    titles = [_figure_of(monkeypatch, plot_cluster_variables, run).get_suptitle(),
              _figure_of(monkeypatch, plot_compare, list(yaw_step_runs.values())).get_suptitle(),
              _figure_of(monkeypatch, plot_separation, list(yaw_step_runs.values())).axes[0].get_title(),
              _figure_of(monkeypatch, plot_paths_3d, run).axes[0].get_title()]
    for title in titles:
        assert "Mas & Kitts 2017" in title and "seed 000" not in title, title


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20)), min_size=2, max_size=60))
def test_drawn_angle_gap_is_the_wrapped_error(pairs):
    from quatform.report.plots import _angle_traces

    meas, des = (np.array(v, dtype=float) for v in zip(*pairs))
    ym, yd = _angle_traces(meas, des, np.arange(meas.size))
    true = np.abs((meas - des + np.pi) % (2 * np.pi) - np.pi)
    ok = np.isfinite(ym) & np.isfinite(yd)
    assert np.allclose(np.abs(ym - yd)[ok], true[ok], atol=1e-9)
    # every drawn value is the true angle modulo 2 pi
    for drawn, raw in ((ym, meas), (yd, des)):
        d = np.abs((drawn - raw + np.pi) % (2 * np.pi) - np.pi)[np.isfinite(drawn)]
        assert np.all(d < 1e-9)


def test_a_description_whose_cluster_is_the_robots_leaves_it_out_of_the_csv():
    """The description says so (``cluster_is_robot_state``), not its name."""
    for F in (RobotSpace(), RobotSpaceTeam(n=2)):
        assert F.cluster_is_robot_state and ("cluster", "c_des") not in pair_csv_channels(F)
    assert ("cluster", "c_des") in pair_csv_channels(QuaternionPair())


def test_a_shortened_experiment_is_finished_on_its_own_ticks():
    """``Experiment.times`` cut short (6 s, past metrics_from_s = 5 s): the finish reads the log's
    own ticks of the scenario's."""
    ex = TEAM.experiment(load_scenario("mas-kitts-helix"), controller="quaternion")
    short = dataclasses.replace(ex, times=ex.times[:600])
    log = short.run()
    assert log["e_des"].shape == (600, 8) and log["singularity"].shape == (600, 1)
    np.testing.assert_array_equal(log["r_des"], np.stack([ex.reference(k).robots for k in range(600)]))
    m = short.metrics(log)
    assert m["duration_s"] == pytest.approx(ex.times[599]) and m["singularity_samples"] == 600
    with pytest.raises(InvalidInputError, match="not the scenario's ticks"):
        dataclasses.replace(ex, times=ex.times[:600] + 0.003).run()


#: metrics.json of mas-kitts-spiral under the robot-space controller as the pair's own metrics
#: function wrote it (arccos of the segments' dot product for the orientation error).
SPIRAL_ROBOT_SPACE = {
    "duration_s": 60.0, "max_cluster_position_error_m": 0.0005117428516231187,
    "max_command_speed_m_s": 3.0000000000000004, "max_orientation_error_rad": 0.0006037117798673698,
    "max_recovered_euclidean_error_rad": 3.141570883344336, "max_robot_position_error_m": 0.0015935204040797804,
    "max_robot_yaw_error_rad": 5.231375166614427e-05, "max_shape_error_m": 0.0014320223180099845,
    "min_robot_separation_m": 2.0395553852503214, "min_singularity_measure": 1.0, "nonfinite_commands": 0,
    "reference_lost": False, "singularity_detected": False, "first_lost_time_s": None, "first_singular_time_s": None,
}


def test_the_one_metrics_function_keeps_the_pairs_values():
    """compute_metrics (the team definitions, N = 2) on a pair log: the values the pair's own
    definitions gave, within 1e-9 relative (an absolute floor of 1e-9 near zero)."""
    m = compute_metrics(run_pair(load_scenario("mas-kitts-spiral"), "robot-space"))
    for key, want in SPIRAL_ROBOT_SPACE.items():
        if isinstance(want, float):
            assert m[key] == pytest.approx(want, rel=1e-9, abs=1e-9), key
        else:
            assert m[key] == want, key
    assert m["n_robots"] == 2 and m["singularity_samples"] == 6001 and m["max_reading_error_rad"] is None
