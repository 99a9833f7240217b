"""The generic run / compare / CLI pipeline over a scenario kind: a small
fake kind (one integrator, a proportional law) registered in KINDS and FIGURES drives
quatform.runs and quatform.cli exactly as the real kinds do."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass

import numpy as np
import pytest

from quatform import cli, runs
from quatform.checks import check_keys, number, text
from quatform.control.contract import Controller, Step
from quatform.errors import InvalidInputError
from quatform.report import FIGURES, FigureSet
from quatform.report.figures import new_figure, save
from quatform.scenarios import KINDS, Experiment, Option, ScenarioKind, kind_of, load_scenario
from quatform.sim.output import OUTPUT_MARKER

GAINS = {"slow": 0.5, "fast": 2.0}


@dataclass(frozen=True)
class FakeScenario:
    name: str
    title: str
    source: str
    x0: float
    duration_s: float
    dt_s: float


class Integrator:
    """Plant x' = u (one state), exact Euler step."""

    state_columns = ("x",)
    output_columns = ("x",)
    batchable = True

    def output(self, x):
        return x

    def step(self, x, u, dt, t):
        return x + dt * u


@dataclass(frozen=True)
class Proportional(Controller):
    k: float
    name: str = "proportional"

    @property
    def command_names(self):
        return ("u",)

    def signal_columns(self):
        return {"error": ("e",)}

    def update(self, t, measured, reference, state):
        e = -np.asarray(measured, dtype=float)
        return Step(self.k * e, state, {"error": e})


class FakeKind(ScenarioKind):
    name = "fake"
    scenario_type = FakeScenario
    options = (Option("gain", "the gain", choices=tuple(GAINS), default="slow"),
               Option("damped", "a switch on by default", type=bool, default=None),
               Option("offset_m", "an initial offset, m", type=float),
               Option("scale", "the gain's scale", choices=("full", "half"), default="full"))
    compare_over = "gain"
    table_columns = (("gain", "gain", "{}"), ("final_abs_x", "|x(T)|", "{:.4f}"))

    def from_dict(self, data, where):
        check_keys(data, ("kind", "name", "title", "source", "x0", "duration_s", "dt_s"), where)
        text(data, "kind", where, "fake", choices=("fake",))
        return FakeScenario(text(data, "name", where, "fake"), text(data, "title", where, "a fake"),
                            text(data, "source", where, "seed 000"), number(data, "x0", where, 1.0),
                            number(data, "duration_s", where, 1.0), number(data, "dt_s", where, 0.01))

    def experiment(self, scenario, gain="slow", damped=None, offset_m=None, scale="full"):
        if gain not in GAINS:
            raise InvalidInputError(f"unknown gain {gain!r}")
        on = (True if damped is None else damped) and scale == "full"
        times = np.arange(0.0, scenario.duration_s + 1e-12, scenario.dt_s)

        def metrics(log):
            return {"scenario": scenario.name, "gain": gain, "final_abs_x": float(abs(log["state"][-1, 0]))}

        return Experiment(scenario, gain, Integrator(), Proportional(GAINS[gain] * (1.0 if on else 0.5)),
                          lambda k: None, times, np.array([scenario.x0 + (offset_m or 0.0)]), scenario.dt_s,
                          metrics=metrics, csv_channels=("state", "command"), meta={"damped": on})


def _figure(log, out):
    fig = new_figure((3, 2))
    fig.add_subplot().plot(log.t, log["state"][:, 0])
    return [save(fig, out / "x.png")]


def _compare_figure(logs, out):
    fig = new_figure((3, 2))
    ax = fig.add_subplot()
    for log in logs:
        ax.plot(log.t, log["state"][:, 0])
    return [save(fig, out / "compare_x.png")]


@pytest.fixture
def fake(monkeypatch, tmp_path):
    monkeypatch.setitem(KINDS, "fake", FakeKind())
    monkeypatch.setitem(FIGURES, "fake", FigureSet(_figure, _compare_figure))
    f = tmp_path / "fake.toml"
    f.write_text('kind = "fake"\nname = "f1"\nx0 = 2.0\nduration_s = 1.0\ndt_s = 0.01\n')
    return f


def test_the_loader_dispatches_on_kind_and_kind_of_maps_back(fake, tmp_path):
    sc = load_scenario(fake)
    assert isinstance(sc, FakeScenario) and sc.x0 == 2.0 and kind_of(sc) is KINDS["fake"]
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "fak"\n')
    with pytest.raises(InvalidInputError, match=r"kind = 'fak' is not one of .*fake.*did you mean 'fake'"):
        load_scenario(bad)
    with pytest.raises(InvalidInputError, match="not the scenario of a registered kind"):
        kind_of(object())


def test_run_writes_the_log_metrics_and_figures(fake, tmp_path):
    out = tmp_path / "run"
    log, m = runs.run(fake, out, quiet=True, gain="fast")
    k, dt = GAINS["fast"], 0.01
    n = log.t.size
    assert n == 101 and m["final_abs_x"] == pytest.approx(2.0 * (1 - k * dt) ** (n - 1), rel=1e-12)
    assert m["damped"] is True and m["gain"] == "fast" and m["wall_time_s"] >= 0.0
    # a kind without a scene (quatform.bags.SCENES): its channels in run.mcap, no Foxglove layout
    assert sorted(p.name for p in out.iterdir()) == sorted([OUTPUT_MARKER, "metrics.json", "run.mcap",
                                                           "timeseries.csv", "x.png"])
    with open(out / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["t", "x", "u"] and len(rows) == n + 1
    assert float(rows[-1][1]) == pytest.approx(log["state"][-1, 0], rel=1e-8)
    assert json.loads((out / "metrics.json").read_text()) == pytest.approx(m)
    _, m2 = runs.run(fake, out, quiet=True, plots=False, damped=False, offset_m=1.0)
    assert m2["damped"] is False and m2["final_abs_x"] == pytest.approx(3.0 * (1 - 0.25 * dt) ** (n - 1), rel=1e-12)
    assert "x.png" not in {p.name for p in out.iterdir()}


def test_run_refuses_an_option_of_another_kind_and_a_bad_choice(fake, tmp_path):
    with pytest.raises(InvalidInputError, match=r"f1 is a fake scenario: controller does not apply to it; "
                                                r"it takes gain, damped, offset_m, scale"):
        runs.run(fake, tmp_path / "o", quiet=True, controller="quaternion")
    with pytest.raises(InvalidInputError, match=r"gain = 'fats' is not one of slow, fast \(did you mean 'fast'\?\)"):
        runs.run(fake, tmp_path / "o", quiet=True, gain="fats")
    assert list(tmp_path.iterdir()) == [fake]


def test_compare_runs_every_choice_into_its_folder(fake, tmp_path):
    out = tmp_path / "cmp"
    rows = runs.compare(fake, out, quiet=True, damped=False)
    assert [r["gain"] for r in rows] == ["slow", "fast"]
    assert rows[0]["final_abs_x"] > rows[1]["final_abs_x"]
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted([OUTPUT_MARKER, "slow", "fast", "compare_x.png", "comparison.md", "comparison.json"])
    assert json.loads((out / "fast" / "metrics.json").read_text())["final_abs_x"] == pytest.approx(rows[1]["final_abs_x"])
    md = (out / "comparison.md").read_text()
    assert md.startswith("# f1: a fake (no damped)\n") and "| slow |" in md and "| fast |" in md
    assert [r["gain"] for r in json.loads((out / "comparison.json").read_text())] == ["slow", "fast"]
    over = runs.compare(fake, tmp_path / "c4", over="scale", quiet=True, gain="fast")
    assert [(r["scale"], r["gain"]) for r in over] == [("full", "fast"), ("half", "fast")]
    assert over[0]["final_abs_x"] == pytest.approx(2.0 * (1 - 0.02) ** 100, rel=1e-12)
    assert over[1]["final_abs_x"] == pytest.approx(rows[1]["final_abs_x"], rel=1e-12)  # half: the gain halved
    assert "| scale |" in (tmp_path / "c4" / "comparison.md").read_text()  # the axis as the first column
    with pytest.raises(InvalidInputError, match="no compare over 'offset_m'"):
        runs.compare(fake, tmp_path / "c2", over="offset_m", quiet=True)
    with pytest.raises(InvalidInputError, match=r"compare runs every gain \(slow, fast\); do not give gain"):
        runs.compare(fake, tmp_path / "c3", quiet=True, gain="fast")


def test_a_compare_cut_off_in_its_second_run_leaves_nothing(fake, tmp_path, monkeypatch):
    real, calls = Experiment.run, []

    def run_then_ctrl_c(self, progress=None):
        calls.append(self.label)
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(self, progress)

    monkeypatch.setattr(Experiment, "run", run_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        runs.compare(fake, tmp_path / "new" / "cmp", quiet=True)
    assert calls == ["slow", "fast"] and list(tmp_path.iterdir()) == [fake]


def test_the_cli_reads_the_kinds_options_from_the_registry(fake, tmp_path, capsys):
    out = tmp_path / "o"
    assert cli.main(["run", str(fake), "--gain", "fast", "--no-damped", "--offset-m", "0.5", "--out", str(out)]) == 0
    text_out = capsys.readouterr().out
    assert "damped: off (--no-damped)" in text_out and "| fast |" in text_out
    assert json.loads((out / "metrics.json").read_text())["damped"] is False
    with pytest.raises(SystemExit):
        cli.main(["run", "--help"])
    assert "--gain {" in capsys.readouterr().out
    assert cli.main(["compare", str(fake), "--out", str(tmp_path / "c")]) == 0
    assert "| slow |" in capsys.readouterr().out and (tmp_path / "c" / "compare_x.png").exists()
    assert cli.main(["teleop", str(fake), "--out", str(tmp_path / "t")]) == 2
    assert "not a teleoperation scenario" in capsys.readouterr().err


def test_the_csv_writer_interleaves_a_value_and_its_desired_one(tmp_path):
    from quatform.report.writers import timeseries_table, write_timeseries
    from quatform.sim.log import Log

    t = np.linspace(0.0, 1.0, 5)
    log = (Log(t, []).add("state", ("a", "b"), np.stack([t, 2 * t], -1)).add("des", ("a_des", "b_des"), np.stack([-t, -2 * t], -1))
           .add("u", ("u",), t[:, None] ** 2))
    names, data = timeseries_table(log, (("state", "des"), "u"))
    assert names == ["t", "a", "a_des", "b", "b_des", "u"]
    np.testing.assert_allclose(data[:, 1:], np.stack([t, -t, 2 * t, -2 * t, t ** 2], -1), rtol=0, atol=0)
    assert timeseries_table(log)[0] == ["t", "a", "b", "a_des", "b_des", "u"]
    with pytest.raises(InvalidInputError, match="different widths"):
        timeseries_table(log, (("state", "u"),))
    f = write_timeseries(log, tmp_path / "ts.csv", (("state", "des"), "u"))
    back = np.loadtxt(f, delimiter=",", skiprows=1)
    assert f.read_text().splitlines()[0] == "t,a,a_des,b,b_des,u"
    np.testing.assert_allclose(back, data, rtol=1e-8)
