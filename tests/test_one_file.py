"""A new formation, team description, robot model, law, local law, scenario kind, writer and sweep parameter is one file.

Each toy below is the text of one module, written to a temporary folder and imported as a
user would import their own file; nothing else changes. The test checks that its registry
picked it up and that it runs where a user would use it: the formation passes the contract
test, the team description is a controller of the team kind with its own gains, the robot model is read from a team file and moves in a run, the law steps a block, the local law runs a network scenario,
the kind runs and compares through ``quatform.runs``, the writer writes its file in a run
(and the CLI offers its flag), the sweep parameter is varied in a sweep.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import sys
import textwrap

import numpy as np
import pytest

from quatform.formations import FORMATION_TYPES, FORMATIONS
from quatform.formations.testing import check_formation
from quatform.outputs import WRITERS, add_output_flags, output_choices
from quatform.robots import ROBOT_MODELS, file_models
from quatform.robots.testing import check_robot_model
from quatform.scenarios import KINDS, kind_of, load_scenario
from quatform.scenarios.team import TEAM_CHARTS
from quatform.sweeps import PARAMETERS

TOY_FORMATION = '''
"""A toy two-robot description: the midpoint and half the separation of two points."""
import numpy as np

from quatform.formations import Formation, RobotLayout
from quatform.formations.layout import Variable

_VARS = tuple(Variable(n, "m", "position") for n in ("m_x", "m_y", "m_z", "h_x", "h_y", "h_z"))
_T = np.array([[0.5, 0, 0, 0.5, 0, 0], [0, 0.5, 0, 0, 0.5, 0], [0, 0, 0.5, 0, 0, 0.5],
               [0.5, 0, 0, -0.5, 0, 0], [0, 0.5, 0, 0, -0.5, 0], [0, 0, 0.5, 0, 0, -0.5]])
_TI = np.linalg.inv(_T)


class ToyMidpoint(Formation):
    name = "toy-midpoint"
    key = "toy-midpoint"
    variables = _VARS
    chart_variables = _VARS
    layout = RobotLayout.uniform("xyz", 2)

    def forward(self, r, *, near_c=None):
        return np.asarray(r, dtype=float) @ _T.T

    def inverse(self, c, *, near_r=None):
        return np.asarray(c, dtype=float) @ _TI.T

    def cluster_rate(self, r, r_dot, *, near_c=None):
        return np.broadcast_to(np.asarray(r_dot, dtype=float) @ _T.T,
                               np.broadcast_shapes(np.shape(r)[:-1], np.shape(r_dot)[:-1]) + (6,)).copy()

    def robot_rate(self, c, c_dot, *, r=None):
        return np.broadcast_to(np.asarray(c_dot, dtype=float) @ _TI.T,
                               np.broadcast_shapes(np.shape(c)[:-1], np.shape(c_dot)[:-1]) + (6,)).copy()

    def to_chart(self, c, *, near_e=None, r=None):
        return np.asarray(c, dtype=float)

    def from_chart(self, e, e_dot=None):
        e = np.asarray(e, dtype=float)
        return e if e_dot is None else (e, np.asarray(e_dot, dtype=float))
'''

TOY_TEAM = '''
"""A toy team description: seed 000's robot space for N robots, offered as its own controller."""
from quatform.formations import RobotSpaceTeam


class ToyRobotSpace(RobotSpaceTeam):
    name = "toy-robot-space"
    key = "toy-robot-space"
    controller = "toy-robot-space"
    gain_tables = {"table1": {"k_p": [1.0, 1.0, 1.0], "k_theta": 4.0},
                   "table2": {"k_p": [0.05, 0.05, 0.05], "k_theta": 0.02}}
'''

TOY_ROBOT = '''
"""A toy robot: a point under world velocity commands, its speed limited."""
from dataclasses import dataclass

import numpy as np

from quatform.checks import number
from quatform.robots import RobotModel
from quatform.robots.point_map import VelocityCommands
from quatform.robots.ros_io import RobotIO


def _ros_state(model, pose, prev):
    return np.asarray(pose.position, dtype=float)


def _ros_world(model, u, state):
    return np.asarray(u, dtype=float), np.zeros(np.shape(u))


@dataclass(frozen=True)
class ToyPoint(RobotModel):
    max_speed: float = 1.0

    name = "toy-point"
    point_kind = "xyz"
    state_columns = ("x", "y", "z")
    command_columns = ("v_x", "v_y", "v_z")
    column_units = {"x": "m", "y": "m", "z": "m", "v_x": "m/s", "v_y": "m/s", "v_z": "m/s"}
    n_rate = 3
    passthrough = True
    holonomic = False
    file_names = ("toy-point",)
    limit_keys = ("max_speed_m_s",)
    ros_io = RobotIO("toy point", "world", _ros_state, lambda m, u, x, q: _ros_world(m, u, x), _ros_world,
                     setpoint=True)
    point_map = VelocityCommands()  # the separation barrier moves its point through its commands

    @classmethod
    def from_file(cls, table, where, place, file_name="toy-point"):
        return cls(max_speed=number(table, "max_speed_m_s", where, 1.0, place=place, low=0.0, low_open=True))

    def point(self, x):
        return np.asarray(x, dtype=float)

    def initial_memory(self, batch=()):
        return None

    def actuate(self, x, rate, t, memory=None):
        return np.asarray(rate, dtype=float), memory

    def brake(self, x, memory=None):
        return np.zeros(np.shape(x)[:-1] + (3,)), memory

    def limit_factor(self, u):
        speed = np.linalg.norm(np.asarray(u, dtype=float), axis=-1)
        return np.minimum(1.0, self.max_speed / np.maximum(speed, 1e-300))

    def saturate(self, u):
        u = np.asarray(u, dtype=float)
        u = np.where(np.all(np.isfinite(u), axis=-1, keepdims=True), u, 0.0)
        return u * self.limit_factor(u)[..., None]

    def step(self, x, u, dt):
        return np.asarray(x, dtype=float) + dt * self.saturate(u)
'''

TOY_LAW = '''
"""A toy component law: a proportional law whose rate is clipped at its gain."""
import numpy as np

from quatform.control.laws import law


@law("toy-clipped")
def clipped(e, c_dot_des, k, feedforward=1.0):
    return feedforward * c_dot_des - np.clip(k * e, -k, k)
'''

TOY_KIND = '''
"""A toy scenario kind: one integrator under a proportional law, with figures and a bag scene."""
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from quatform.bags.scene import SCENES, Scene, SceneKind
from quatform.checks import check_keys, number, text
from quatform.control.contract import Controller, Step, Tick
from quatform.report import FIGURES, FigureSet
from quatform.report.figures import new_figure, save
from quatform.scenarios import Experiment, Option, ScenarioKind


@dataclass(frozen=True)
class ToyScenario:
    name: str
    title: str
    source: str
    x0: float
    duration_s: float


class Integrator:
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
    pure: ClassVar[bool] = True

    @property
    def command_names(self):
        return ("u",)

    def signal_columns(self):
        return {"error": ("e",)}

    def tick(self, state, measured, reference, t):
        e = -measured
        return Tick(state, self.k * e, {"error": e}, 0 * e[..., 0].astype(int))

    def update(self, t, measured, reference, state):
        out = self.tick(state, np.asarray(measured, dtype=float), reference, t)
        return Step(out.u, out.state, out.signals)


GAINS = {"slow": 0.5, "fast": 2.0}


class ToyKind(ScenarioKind):
    name = "toy-integrator"
    scenario_type = ToyScenario
    options = (Option("gain", "the gain", choices=tuple(GAINS), default="slow"),)
    compare_over = "gain"
    table_columns = (("gain", "gain", "{}"), ("final_abs_x", "|x(T)|", "{:.4f}"))
    not_sweepable = "a toy"

    def from_dict(self, data, where):
        check_keys(data, ("kind", "name", "title", "source", "x0", "duration_s"), where)
        return ToyScenario(text(data, "name", where, "toy"), text(data, "title", where, "a toy"),
                           text(data, "source", where, "none"), number(data, "x0", where, 1.0),
                           number(data, "duration_s", where, 0.5))

    def experiment(self, scenario, gain="slow"):
        times = np.arange(0.0, scenario.duration_s + 1e-12, 0.01)

        def metrics(log):
            return {"scenario": scenario.name, "gain": gain, "final_abs_x": float(abs(log["state"][-1, 0]))}

        return Experiment(scenario, gain, Integrator(), Proportional(GAINS[gain]), lambda k: None, times,
                          np.array([scenario.x0]), 0.01, metrics=metrics, csv_channels=("state", "command"))


def _plot(log, out):
    fig = new_figure((3, 2))
    fig.add_subplot().plot(log.t, log["state"][:, 0])
    return [save(fig, out / "toy_x.png")]


FIGURES.add("toy-integrator", FigureSet(_plot))


def _scene(log):
    x = np.asarray(log["state"])[:, 0]
    return Scene(bodies=("body",), parents=("world",), position=np.stack([x, 0 * x, 0 * x], axis=-1)[:, None],
                 quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (x.size, 1, 1)))


SCENES.add("toy-integrator", SceneKind(_scene, lambda scene: ()))
'''

TOY_CHART = '''
"""A chart of the team kind: the team chart, its robots starting on the reference whatever
the scenario's initial offset."""
from dataclasses import dataclass

from quatform.scenarios.team import TeamChartParts, TeamScenario


class OnReference(TeamChartParts):
    name = "toy-on-reference"

    def start(self, sc, e_des):
        return self.robots(sc, e_des[:1])[0]


@dataclass(frozen=True, eq=False)
class OnReferenceScenario(TeamScenario):
    chart = "toy-on-reference"
'''

TOY_WRITER = '''
"""A toy writer: the final state of a run as a text file, off unless asked for."""
from quatform.outputs import Writer


class FinalStateWriter(Writer):
    name = "final_state"
    files = ("final_state.txt",)
    optional = True
    default = False
    help = "also write final_state.txt (the last state)"

    def write(self, run):
        (run.folder / self.files[0]).write_text(" ".join(f"{v:.17g}" for v in run.log["state"][-1]) + "\\n")
'''

TOY_PARAMETER = '''
"""A toy sweep parameter: the settling time after which a trial's metrics are measured."""
import dataclasses

from quatform.sweeps import sweep_parameter
from quatform.sweeps.spec import Parameter


def _settle(sc, value, spec, choice):
    return dataclasses.replace(sc, metrics_from_s=float(value))


sweep_parameter(Parameter("toy_settle_s", "s", "when the metrics start (replaces the scenario's metrics_from_s)",
                          kinds=("pair",), apply=_settle))
'''

TOY_LOCAL_LAW = '''
"""A toy local law: each robot moves towards the mean of what its neighbours send (no offsets)."""
from dataclasses import dataclass

import numpy as np

from quatform.algebra.kernels import common_namespace
from quatform.control.local import LocalController, LocalTick


@dataclass(frozen=True)
class ToyHerd(LocalController):
    gain: float = 0.5

    name = "toy-herd"
    message_columns = ("x", "y", "z")
    own_columns = ("x", "y", "z")
    command_columns = ("v_x", "v_y", "v_z")

    def example(self, n, rng):
        return rng.normal(size=(n, 3)), {}

    def signal_columns(self):
        return {"held": ("held",)}

    def message(self, state, own, reference, t):
        return own

    def tick(self, state, own, inbox, reference, t):
        xp = common_namespace(own, inbox["messages"])
        w = xp.where(inbox["valid"], 1.0, 0.0)
        count = xp.sum(w, axis=-1)
        pull = xp.sum(w[..., None] * (inbox["messages"] - own[..., None, :]), axis=-2)
        u = self.gain * pull / xp.maximum(count, 1.0)[..., None]
        return LocalTick(None, u, {"held": count[..., None]}, xp.zeros(own.shape[:-1], dtype=xp.int64))
'''


def _import(tmp_path, name: str, source: str):
    """Write ``source`` to ``tmp_path/name.py`` and import it as a user's module."""
    path = tmp_path / f"{name}.py"
    path.write_text(textwrap.dedent(source))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def registries():
    """Every registry as it was before the test (the toys leave them when it ends)."""
    from quatform.bags.scene import SCENES
    from quatform.control.laws import LAWS
    from quatform.control.local import LOCAL_CONTROLLERS
    from quatform.report import FIGURES

    saved = [(reg, dict(reg)) for reg in (FORMATION_TYPES, ROBOT_MODELS, KINDS, WRITERS, PARAMETERS, FIGURES,
                                          SCENES, LAWS, LOCAL_CONTROLLERS, TEAM_CHARTS)]
    yield
    for reg, before in saved:
        reg.clear()
        reg.update(before)
    for name in ("toy_formation", "toy_team", "toy_robot", "toy_law", "toy_local_law", "toy_kind", "toy_writer",
                 "toy_parameter", "toy_chart"):
        sys.modules.pop(name, None)


def test_a_formation_is_one_file(tmp_path, registries):
    module = _import(tmp_path, "toy_formation", TOY_FORMATION)
    assert FORMATION_TYPES["toy-midpoint"] is module.ToyMidpoint
    F = FORMATIONS["toy-midpoint"]  # its examples, built on first use
    assert isinstance(F, module.ToyMidpoint)
    check_formation(F, np.random.default_rng(0), n=12)


def test_a_team_description_is_one_file(tmp_path, registries):
    from quatform import runs
    from quatform.control import TEAM_CONTROLLERS
    from quatform.scenarios.team import TEAM_TABLES, available_controllers

    module = _import(tmp_path, "toy_team", TOY_TEAM)
    assert FORMATION_TYPES["toy-robot-space"] is module.ToyRobotSpace
    assert TEAM_CONTROLLERS["toy-robot-space"] == "toy-robot-space" and available_controllers()[-1] == "toy-robot-space"
    assert TEAM_TABLES["table2"]["toy-robot-space"]["k_theta"] == 0.02
    f = tmp_path / "toy-team.toml"
    f.write_text(textwrap.dedent('''
        kind = "team"
        name = "toy-description"
        duration_s = 1.0
        dt_s = 0.02

        [[robots]]
        model = "holonomic"
        count = 3

        [shape]
        template = "triangle"
        side = 1.0

        [path]
        kind = "line"
        center = [0.0, 0.0, 1.0]
        velocity = [0.2, 0.0, 0.0]

        [gains.toy-robot-space]
        k_p = 2.0
    '''))
    sc = load_scenario(f)
    assert sc.gains["toy-robot-space"] == {"k_p": 2.0, "k_theta": 4.0}  # the file's gain over the table's
    log, metrics = runs.run(sc, tmp_path / "out", quiet=True, plots=False, mcap=False, controller="toy-robot-space")
    assert metrics["controller"] == "toy-robot-space" and np.all(np.isfinite(log["state"]))
    assert metrics["max_cluster_position_error_m"] < 0.05


def test_a_robot_model_is_one_file(tmp_path, registries):
    from quatform import runs
    from quatform.report.replay_plots import column_unit
    from quatform.ros2.robot_io import PoseSample, robot_io

    module = _import(tmp_path, "toy_robot", TOY_ROBOT)
    assert ROBOT_MODELS["toy-point"] is module.ToyPoint and file_models()["toy-point"] is module.ToyPoint
    # the ROS 2 bridge's conversions and the replay figure's units come with it
    model = module.ToyPoint()
    check_robot_model(model)  # the contract every registered model passes
    assert robot_io(model).kind == "toy point"
    pose = PoseSample(0.0, np.array([1.0, 2.0, 3.0]), np.array([1.0, 0.0, 0.0, 0.0]))
    assert robot_io(model).state(model, pose, None).tolist() == [1.0, 2.0, 3.0]
    assert column_unit("v_z", model) == "m/s"
    # a team file names it, and a run moves three of them in formation
    f = tmp_path / "toy-team.toml"
    f.write_text(textwrap.dedent('''
        kind = "team"
        name = "toy-team"
        duration_s = 1.0
        dt_s = 0.02

        [[robots]]
        model = "toy-point"
        count = 3
        max_speed_m_s = 2.0

        [shape]
        template = "triangle"
        side = 1.0

        [path]
        kind = "line"
        center = [0.0, 0.0, 1.0]
        velocity = [0.2, 0.0, 0.0]

        [safety]
        min_separation_m = 0.5
    '''))
    sc = load_scenario(f)
    assert [type(r) for r in sc.team.robots] == [module.ToyPoint] * 3 and sc.team.robots[0].max_speed == 2.0
    assert sc.safety["enabled"]  # the separation barrier reads the model's point map
    log, metrics = runs.run(sc, tmp_path / "out", quiet=True, plots=False, mcap=False, controller="quaternion")
    assert np.all(np.isfinite(log["state"])) and metrics["max_cluster_position_error_m"] < 0.05
    # two of them head-on: the barrier slows them so they stay apart
    from quatform.control.safety import SeparationBarrier
    from quatform.robots import Team

    team = Team((model, model))
    x = np.array([0.0, 0.0, 1.0, 0.6, 0.0, 1.0])
    u_safe, info = SeparationBarrier(0.5, gamma=5.0).filter(team, x, np.array([0.5, 0.0, 0.0, -0.5, 0.0, 0.0]))
    assert info.active and u_safe[0] - u_safe[3] < 1.0
    assert 2 * 0.6 * (u_safe[3] - u_safe[0]) >= -5.0 * (0.6 ** 2 - 0.5 ** 2) - 1e-9  # Wang et al. 2017


def test_a_law_is_one_file(tmp_path, registries):
    from quatform.control.laws import LAWS, Block, BlockLaw

    module = _import(tmp_path, "toy_law", TOY_LAW)
    assert LAWS["toy-clipped"] is module.clipped
    law = BlockLaw((Block("toy-clipped", 0, 2, (1.0, 1.0)),))
    err, rate = law((3.0, 0.5), (0.0, 0.0), (0.1, 0.0))
    assert err == (3.0, 0.5) and rate == (pytest.approx(0.1 - 1.0), pytest.approx(-0.5))


def test_a_local_law_is_one_file(tmp_path, registries):
    from quatform import runs
    from quatform.control.local import LOCAL_CONTROLLERS

    module = _import(tmp_path, "toy_local_law", TOY_LOCAL_LAW)
    assert LOCAL_CONTROLLERS["toy-herd"] is module.ToyHerd
    sc = dataclasses.replace(load_scenario("net-switching"), duration_s=1.0)
    assert "toy-herd" in KINDS["network"].options[0].choices  # --law offers it
    runs.run(sc, tmp_path / "out", plots=False, quiet=True, mcap=False, law="toy-herd")
    assert json.loads((tmp_path / "out" / "metrics.json").read_text())["law"] == "toy-herd"


def test_a_scenario_kind_is_one_file(tmp_path, registries):
    from quatform import runs
    from quatform.sweeps.trials import NOT_SWEEPABLE

    module = _import(tmp_path, "toy_kind", TOY_KIND)
    assert isinstance(KINDS["toy-integrator"], module.ToyKind)
    assert NOT_SWEEPABLE["toy-integrator"] == "a toy"
    f = tmp_path / "toy.toml"
    f.write_text('kind = "toy-integrator"\nname = "t1"\nx0 = 2.0\n')
    log, m = runs.run(f, tmp_path / "run", quiet=True, gain="fast")
    names = {p.name for p in (tmp_path / "run").iterdir()}
    assert {"metrics.json", "timeseries.csv", "toy_x.png", "run.mcap", "foxglove-layout.json"} <= names
    assert m["final_abs_x"] == pytest.approx(2.0 * (1 - 0.02) ** (log.t.size - 1), rel=1e-12)
    rows = runs.compare(f, tmp_path / "cmp", quiet=True, mcap=False)
    assert [r["gain"] for r in rows] == ["slow", "fast"]
    pytest.importorskip("jax")  # its plant and pure controller, one file, run on every compute backend
    _, mj = runs.run(f, tmp_path / "run-jax", quiet=True, mcap=False, plots=False, compute="jax", gain="fast")
    assert mj["final_abs_x"] == pytest.approx(m["final_abs_x"], rel=1e-12)


def test_a_chart_of_the_team_kind_is_one_file(tmp_path, registries):
    from quatform import runs
    from quatform.scenarios import load_scenario
    from quatform.scenarios.team import TEAM

    module = _import(tmp_path, "toy_chart", TOY_CHART)
    assert isinstance(TEAM_CHARTS["toy-on-reference"], module.OnReference)
    sc = load_scenario("team-tetrahedron-helix")
    fields = {f.name: getattr(sc, f.name) for f in dataclasses.fields(sc) if f.init}
    toy = module.OnReferenceScenario(**{**fields, "duration_s": 0.3, "metrics_from_s": 0.0,
                                        "initial_offset": {"position": (0.2, 0.0, 0.0), "yaw": 0.1, "scale": 1.0}})
    assert kind_of(toy) is TEAM and TEAM.parts_of(toy) == "toy-on-reference"
    exp = TEAM.experiment(toy, controller="quaternion")
    np.testing.assert_array_equal(exp.x0, exp.reference(0).robots)  # its own start, the rest the team kind's
    assert exp.meta["kind"] == "toy-on-reference"
    _, m = runs.run(toy, tmp_path / "run", quiet=True, controller="quaternion")
    names = {p.name for p in (tmp_path / "run").iterdir()}
    assert {"metrics.json", "timeseries.csv", "run.mcap"} <= names
    assert m["max_robot_position_error_m"] < 1e-9


def test_a_writer_is_one_file(tmp_path, registries):
    from quatform import runs

    _import(tmp_path, "toy_kind", TOY_KIND)
    module = _import(tmp_path, "toy_writer", TOY_WRITER)
    assert isinstance(WRITERS["final_state"], module.FinalStateWriter)
    # the CLI's output flags come from the registry
    p = argparse.ArgumentParser()
    add_output_flags(p)
    args = p.parse_args(["--final-state", "--no-mcap"])
    assert output_choices(args) == {"mcap": False, "rerun": None, "final_state": True}
    f = tmp_path / "toy.toml"
    f.write_text('kind = "toy-integrator"\nname = "t1"\nx0 = 2.0\n')
    log, _ = runs.run(f, tmp_path / "off", quiet=True, plots=False)
    assert not (tmp_path / "off" / "final_state.txt").exists()  # off unless asked for
    log, _ = runs.run(f, tmp_path / "on", quiet=True, plots=False, writers=output_choices(args))
    names = {p.name for p in (tmp_path / "on").iterdir()}
    assert "final_state.txt" in names and "run.mcap" not in names
    assert float((tmp_path / "on" / "final_state.txt").read_text()) == log["state"][-1, 0]


def test_a_sweep_parameter_is_one_file(tmp_path, registries):
    from quatform.sweeps import load_sweep, run_sweep

    _import(tmp_path, "toy_parameter", TOY_PARAMETER)
    assert PARAMETERS["toy_settle_s"].kinds == ("pair",)
    spec = tmp_path / "toy-sweep.toml"
    spec.write_text(textwrap.dedent('''
        name = "toy-sweep"
        scenario = "mas-kitts-helix"
        controllers = ["robot-space"]
        trials = 2
        seed = 3
        duration_s = 1.0
        settle_s = 0.0

        [vary.toy_settle_s]
        values = [0.0, 0.9]
    '''))
    out = tmp_path / "out"
    run_sweep(load_sweep(spec), out, quiet=True, plots=False)
    rows = json.loads((out / "results.json").read_text())
    rows = rows["rows"] if isinstance(rows, dict) else rows
    assert sorted({r["toy_settle_s"] for r in rows}) == [0.0, 0.9] and len(rows) == 4
    # the parameter reached each cell's scenario: its metrics are measured from it
    assert all(r["metrics_from_s"] == r["toy_settle_s"] for r in rows)
