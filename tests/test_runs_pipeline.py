"""The generic run / compare / CLI pipeline over a scenario kind: a small
fake kind (one integrator, a proportional law) registered in KINDS and FIGURES drives
quatform.runs and quatform.cli exactly as the real kinds do."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from quatform import cli, runs
from quatform.checks import check_keys, number, text
from quatform.control.contract import Controller, Step
from quatform.errors import InvalidInputError
from quatform.report import FIGURES, FigureSet, writers
from quatform.report.figures import new_figure, save
from quatform.scenarios import KINDS, Experiment, Option, ScenarioKind, kind_of, load_scenario
from quatform.report.writers import strict_json, write_columns
from quatform.sim import output
from quatform.sim.output import OUTPUT_MARKER, atomic_write_text, staged_dir

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


class FakeKind(ScenarioKind, register=False):
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


def test_cli_compare_names_options_as_its_flags_spell_them(tmp_path, capsys):
    """``quatform compare``'s refusals name the options as the command line spells them: the
    values of ``--over`` dashed (``orientation-error``), an option not to give as its flag."""
    for argv, words in ((["teleop-free-motion", "--over", "physics"],
                         "teleop-free-motion is a teleop scenario: it has no compare over 'physics'; "
                         "compare over one of orientation-error, preload"),
                        (["marciano-circle", "--over", "orientation-error"],
                         "it has no compare over 'orientation-error'; compare over one of formation, physics, profile"),
                        (["teleop-free-motion", "--over", "orientation-error", "--orientation-error", "rpy"],
                         "compare runs every orientation error (euler-parameters, rpy); "
                         "do not give --orientation-error")):
        assert cli.main(["compare", *argv, "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and words in err, err
    assert not (tmp_path / "o").exists()


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


# -- run outputs: strict JSON, staged (atomic) folders, Ctrl-C, --no-feedforward ---------------------

ROOT = Path(__file__).resolve().parents[1]


def _strict_loads(text):
    """json.loads that refuses NaN / Infinity (what a strict JSON reader does)."""
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=refuse)


def _lines(text):
    return [ln for ln in text.splitlines() if ln.strip()]


def _leftovers(folder: Path):
    return sorted(p.name for p in folder.iterdir() if ".partial-" in p.name or ".old-" in p.name
                  or ".tmp-" in p.name)


def test_metrics_json_is_strict_json_with_nonfinite_values_named(tmp_path):
    m = {"max_shape_error_m": float("inf"), "first_singular_time_s": None, "x": np.float64("nan"),
         "n": np.int64(3), "flag": np.bool_(True), "sub": {"v": [1.0, -np.inf]}, "arr": np.array([1.0, 2.0])}
    f = writers.write_metrics(m, tmp_path / "metrics.json")
    back = _strict_loads(f.read_text())
    assert back["max_shape_error_m"] is None and back["x"] is None and back["first_singular_time_s"] is None
    assert back["sub"]["v"] == [1.0, None] and back["n"] == 3 and back["flag"] is True and back["arr"] == [1.0, 2.0]
    assert back["nonfinite_values"] == {"max_shape_error_m": "inf", "x": "nan", "sub.v[1]": "-inf"}
    rows = _strict_loads(strict_json([{"a": 1.0}, {"a": float("nan")}]))
    assert rows == [{"a": 1.0}, {"a": None, "nonfinite_values": {"a": "nan"}}]


def test_a_csv_cut_off_while_written_leaves_no_file(tmp_path, monkeypatch):
    real = np.savetxt

    def half_then_ctrl_c(target, *a, **k):
        real(target, np.zeros((2, 2)), delimiter=",")  # part of the output, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(writers.np, "savetxt", half_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        write_columns(["t", "x"], np.ones((5, 2)), tmp_path / "timeseries.csv")
    assert list(tmp_path.iterdir()) == []


def test_an_atomic_write_keeps_the_old_file_when_cut_off(tmp_path, monkeypatch):
    f = tmp_path / "metrics.json"
    f.write_text("old")

    def ctrl_c(*a):
        raise KeyboardInterrupt

    monkeypatch.setattr(output.os, "replace", ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(f, "new")
    assert f.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["metrics.json"]


def _interrupt_at(monkeypatch, n_ok: int):
    """``Experiment.run`` (every kind's simulation) that runs ``n_ok`` times, then raises
    KeyboardInterrupt; returns the list of the runs' ``feedforward`` (from their meta)."""
    real, calls = Experiment.run, []

    def sim(self, progress=None):
        calls.append(self.meta.get("feedforward"))
        if len(calls) > n_ok:
            raise KeyboardInterrupt
        return real(self, progress)

    monkeypatch.setattr(Experiment, "run", sim)
    return calls


def test_ctrl_c_during_compare_leaves_nothing_and_exits_130(tmp_path, monkeypatch, capsys):
    _interrupt_at(monkeypatch, 1)  # the first controller's folder is complete, the second is cut off
    out = tmp_path / "new" / "cmp"
    assert cli.main(["compare", "mas-kitts-yaw-step", "--out", str(out)]) == 130
    err = [ln for ln in _lines(capsys.readouterr().err) if "quatform:" in ln]  # (and progress lines)
    assert len(err) == 1 and err[0].startswith("quatform: interrupted") and "Traceback" not in err[0]
    assert not (tmp_path / "new").exists()  # the parent made for the run is gone too
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_during_a_rerun_keeps_the_previous_run(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out), "--no-plots"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    _interrupt_at(monkeypatch, 0)
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "robot-space", "--out", str(out)]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _leftovers(tmp_path) == []


def test_a_failed_run_leaves_no_folder(tmp_path, monkeypatch, capsys):
    def fails(*a, **k):
        raise InvalidInputError("bad reference")

    monkeypatch.setattr(Experiment, "run", fails)
    out = tmp_path / "a" / "b"
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out)]) == 2
    assert list(tmp_path.iterdir()) == []


def test_a_rerun_replaces_the_old_plots_and_keeps_user_files_safe(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out)]
    assert cli.main(argv) == 0
    assert list(out.glob("*.png"))
    assert cli.main(argv + ["--no-plots"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted([OUTPUT_MARKER, "metrics.json", "timeseries.csv",
                                                            "run.mcap", "foxglove-layout.json"])
    # a file the user put there: the folder is no longer quatform's alone, so it is not replaced
    (out / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert cli.main(argv) == 2
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and "notes.txt" in err[0] and "did not write" in err[0]
    assert (out / "notes.txt").read_text() == "mine"
    # a folder of the user's (not made by quatform, not empty) is refused before any work
    user = tmp_path / "mine"
    user.mkdir()
    (user / "data.csv").write_text("1,2\n")
    assert cli.main(argv[:-1] + [str(user)]) == 2
    assert [p.name for p in user.iterdir()] == ["data.csv"] and _leftovers(tmp_path) == []


def test_out_dot_and_a_file_are_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for out, needle in ((".", "current folder"), (str(tmp_path), "current folder")):
        assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", out]) == 2
        assert needle in capsys.readouterr().err
    (tmp_path / "f").write_text("x")
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", "f"]) == 2
    assert "is a file" in capsys.readouterr().err
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", "a\x00b"]) == 2
    assert "NUL" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_an_empty_folder_is_used_and_stale_partials_of_dead_runs_are_removed(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".o.partial-{int(dead.stdout)}"
    stale.mkdir()
    (stale / "timeseries.csv").write_text("cut")
    with staged_dir(out) as tmp:
        assert tmp.parent == tmp_path and not stale.exists()
        (tmp / "a.txt").write_text("a")
    assert sorted(p.name for p in out.iterdir()) == [OUTPUT_MARKER, "a.txt"]
    assert json.loads((out / OUTPUT_MARKER).read_text())["entries"] == ["a.txt"]


def test_plan_and_teleop_write_through_the_staged_folder(tmp_path, monkeypatch, capsys):
    import quatform.plan_runs as plan_runs

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plan_runs, "make_plan", ctrl_c)
    assert cli.main(["plan", "belta-kumar-2002-two-bodies", "--out", str(tmp_path / "p"), "--alpha", "0.5",
                     "--alpha", "0.9"]) == 130
    monkeypatch.setattr(Experiment, "run", ctrl_c)
    assert cli.main(["teleop", "teleop-preload", "--out", str(tmp_path / "t")]) == 130
    assert list(tmp_path.iterdir()) == []


def test_sigint_to_a_real_run_exits_130_with_one_line_and_no_files(tmp_path):
    """Ctrl-C (SIGINT) sent to a real `quatform run` while it works: one line, status 130, no folder."""
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "quatform.cli", "run", "mas-kitts-spiral", "--controller",
                             "dual-quaternion", "--out", str(out)], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not any(".partial-" in p.name for p in tmp_path.iterdir()):  # the run has started writing
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    err = _lines(err)
    assert len(err) == 1 and err[0].startswith("quatform: interrupted") and "left as it was" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_a_second_ctrl_c_while_reporting_the_first_is_ignored(tmp_path, monkeypatch):
    """Guards against: a second Ctrl-C while the first was being reported ended the process by the
    signal (exit -2); SIGINT is ignored while the one line is written, restored after."""
    import signal

    seen = []
    monkeypatch.setattr(cli, "_say", lambda text: seen.append((text, signal.getsignal(signal.SIGINT))))
    _interrupt_at(monkeypatch, 0)
    before = signal.getsignal(signal.SIGINT)
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(tmp_path / "r")]) == 130
    assert seen and seen[-1][0].startswith("interrupted") and seen[-1][1] is signal.SIG_IGN
    assert signal.getsignal(signal.SIGINT) is before


def test_an_out_holding_an_input_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """Review finding 2: ``--out`` set to the folder of its own input would delete the input."""
    from quatform.planning import builtin_plan_specs
    from quatform.scenarios import builtin_scenarios

    def no_work(*a, **k):
        raise AssertionError("work started")

    monkeypatch.setattr(Experiment, "run", no_work)
    prev = tmp_path / "prev"
    prev.mkdir()
    files = {"plan.npz": b"npz", "run.mcap": b"mcap", "robots.toml": b"",
             "spec.toml": builtin_plan_specs()["belta-kumar-2002-two-bodies"].read_bytes(),
             "sc.toml": builtin_scenarios()["mas-kitts-helix"].read_bytes(), "sweep.toml": b""}
    for name, data in files.items():
        (prev / name).write_bytes(data)
    (prev / OUTPUT_MARKER).write_text(json.dumps({"written_by": "quatform", "entries": sorted(files)}))
    monkeypatch.chdir(tmp_path)
    commands = [
        (["run", "team-three-bodies", "--reference", "prev/plan.npz", "--out", "prev"], "prev/plan.npz"),
        (["compare", "team-three-bodies", "--reference", "prev/plan.npz", "--out", "prev"], "prev/plan.npz"),
        (["run", "prev/sc.toml", "--controller", "quaternion", "--out", "prev"], "prev/sc.toml"),
        (["compare", "prev/sc.toml", "--out", "./prev/"], "prev/sc.toml"),
        (["plan", "prev/spec.toml", "--out", "prev"], "prev/spec.toml"),
        (["plan", "prev/spec.toml", "--case", "a", "--out", "prev"], "prev/spec.toml"),
        (["plan", "prev/spec.toml", "--alpha", "0.5", "--alpha", "0.9", "--out", "prev"], "prev/spec.toml"),
        (["replay", "prev/run.mcap", "--scenario", "mas-kitts-helix", "--controller", "quaternion", "--robots",
          "prev/robots.toml", "--out", "prev"], "prev/run.mcap"),
        (["replay", "prev", "--scenario", "mas-kitts-helix", "--controller", "quaternion", "--robots",
          "prev/robots.toml", "--out", str(prev)], "'prev'"),
        (["sweep", "prev/sweep.toml", "--out", "prev"], "prev/sweep.toml"),
    ]
    for argv, named in commands:
        assert cli.main(argv) == 2, argv
        err = _lines(capsys.readouterr().err)
        assert len(err) == 1 and "inside the output folder" in err[0] and named in err[0], (argv, err)
        assert "--out" in err[0] and "outside it" in err[0]
    assert sorted(p.name for p in prev.iterdir()) == sorted([*files, OUTPUT_MARKER])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["prev"]


def test_check_inputs_outside_follows_links_and_skips_names(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "bag.mcap").write_text("x")
    (tmp_path / "link").symlink_to(tmp_path / "out")
    with pytest.raises(InvalidInputError, match="bag.mcap"):
        output.check_inputs_outside(tmp_path / "link", tmp_path / "out" / "bag.mcap")
    with pytest.raises(InvalidInputError, match="inside the output folder"):
        with staged_dir(tmp_path / "out", inputs=[str(tmp_path / "link" / "bag.mcap")]):
            raise AssertionError("entered")
    output.check_inputs_outside(tmp_path / "out", None, "mas-kitts-helix", tmp_path / "bag.mcap", object())
    output.check_inputs_outside(tmp_path / "out2", tmp_path / "out" / "bag.mcap")
    assert (tmp_path / "out" / "bag.mcap").read_text() == "x"


def test_no_feedforward_gives_seed_000_fig13_steady_state_errors(tmp_path, capsys):
    """Seed 000 Fig. 13 (no feedforward): steady-state cluster position errors about 0.236 m
    (robot space), 0.108 m (quaternion), 0.029 m (dual quaternion)."""
    fig13 = {"robot-space": 0.236, "quaternion": 0.108, "dual-quaternion": 0.029}
    for c, expected in fig13.items():
        out = tmp_path / c
        assert cli.main(["run", "mas-kitts-spiral", "--controller", c, "--no-feedforward", "--no-plots",
                         "--out", str(out)]) == 0
        m = json.loads((out / "metrics.json").read_text())
        assert m["feedforward"] is False
        assert m["max_cluster_position_error_m"] == pytest.approx(expected, rel=0.05)
    assert "feedforward: off" in capsys.readouterr().out


def test_compare_passes_no_feedforward_and_ugv_uav_refuses_it(tmp_path, monkeypatch, capsys):
    calls = _interrupt_at(monkeypatch, 0)
    assert cli.main(["compare", "mas-kitts-yaw-step", "--no-feedforward", "--out", str(tmp_path / "c")]) == 130
    assert calls == [False]
    for argv in (["compare", "marciano-circle"], ["run", "marciano-circle"]):
        assert cli.main([*argv, "--no-feedforward", "--out", str(tmp_path / "u")]) == 2
        err = capsys.readouterr().err
        assert "marciano-circle is a ugv-uav scenario: --no-feedforward does not apply to it" in err
