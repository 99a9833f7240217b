"""One contract test per base class over every registered type, enrolled from the registries.

Each registry fills itself when a type is defined (``quatform.registry``); these tests read
the registries, never a hand-kept list, so a new scenario kind, writer, sweep parameter, pose
reader, command writer, feedback law or team description is checked as soon as its module is
imported. Formations (``test_formation_contract.py``), robot models (``test_robot_models.py``)
and controllers (``test_controller_contract.py``, every team controller by name) have their own
contract files, over ``FORMATIONS``, ``ROBOT_MODELS`` and ``TEAM_CONTROLLERS``.
"""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from quatform.errors import InvalidInputError
from quatform.outputs import WRITERS, RunFiles, Writer, add_output_flags, output_choices, writer_choices
from quatform.registry import Registry
from quatform.report import FigureSet, figures_of
from quatform.scenarios import KINDS, ScenarioKind, builtin_scenarios, kind_of, load_scenario
from quatform.sim.log import Channel, Log
from quatform.sweeps import PARAMETERS
from quatform.sweeps.trials import NOT_SWEEPABLE, SWEEP_KINDS

_BUILTIN = {name: load_scenario(name) for name in sorted(builtin_scenarios())}


def test_a_key_registered_twice_is_one_line():
    reg = Registry("thing")
    reg.add("a", int)
    reg.add("a", int)  # the same entry again (a module imported twice) replaces it
    with pytest.raises(InvalidInputError, match=r"thing 'a' is registered twice: by int .* and by float"):
        reg.add("a", float)


# --------------------------------------------------------------------------- scenario kinds

@pytest.mark.parametrize("name", list(KINDS))
def test_scenario_kind_contract(name):
    kind = KINDS[name]
    assert isinstance(kind, ScenarioKind) and kind.name == name and isinstance(kind.scenario_type, type)
    own = {o.name: o for o in kind.options}
    assert len(own) == len(kind.options), "option names are unique"
    for o in kind.options:
        assert o.choices is None or o.default is None or o.default in o.choices, o.name
    assert kind.compare_over is None or own[kind.compare_over].choices, "compare_over is an option with choices"
    assert all(len(c) == 3 for c in kind.table_columns)
    # its sweepability: an adapter, or the reason a sweep refuses it
    assert (name in SWEEP_KINDS) != (name in NOT_SWEEPABLE)
    assert isinstance(figures_of(name), FigureSet)
    mine = [sc for sc in _BUILTIN.values() if type(sc) is kind.scenario_type]
    for sc in mine:  # its built-in scenarios map back to it
        assert kind_of(sc) is kind


def test_every_builtin_scenario_has_a_registered_kind():
    assert {kind_of(sc).name for sc in _BUILTIN.values()} <= set(KINDS)


# --------------------------------------------------------------------------- writers

def _log():
    t = np.linspace(0.0, 0.2, 3)
    return Log(t, [Channel("state", ("x",), t[:, None]), Channel("command", ("u",), -t[:, None])], {"kind": "none"})


class _Kind:
    name = "no-scene"  # a kind without a bag scene: run.mcap holds its channels only


@pytest.mark.parametrize("name", list(WRITERS))
def test_writer_contract(name, tmp_path):
    w = WRITERS[name]
    assert isinstance(w, Writer) and w.name == name and isinstance(w.files, tuple) and w.files
    if w.records:  # a recording: off unless a file is named, checked before any work
        assert w.optional and not w.default
        return
    if not w.optional:
        with pytest.raises(InvalidInputError, match="always written"):
            writer_choices(writers={name: False})
    run = RunFiles(_log(), tmp_path, _Kind(), ("state", "command"), {"final": 1.0})
    w.write(run)
    assert (tmp_path / w.files[0]).is_file() == w.applies(run)  # a writer writes what a run has


def test_the_output_flags_are_the_optional_writers():
    p = argparse.ArgumentParser()
    add_output_flags(p)
    flags = {a.dest: a for a in p._actions if a.dest.startswith("writer_")}
    assert set(flags) == {f"writer_{n}" for n, w in WRITERS.items() if w.optional}
    defaults = output_choices(p.parse_args([]))
    assert defaults == {n: (None if w.records else w.default) for n, w in WRITERS.items() if w.optional}
    assert p.parse_args(["--no-mcap"]).writer_mcap is False  # the flags the CLI always had
    assert p.parse_args(["--rerun", "x.rrd"]).writer_rerun == "x.rrd"


def test_metrics_json_is_written_last():
    order = sorted(WRITERS.values(), key=lambda w: w.order)
    assert order[-1].name == "metrics" and order[0].name == "csv"


# --------------------------------------------------------------------------- sweep parameters

@pytest.mark.parametrize("name", list(PARAMETERS))
def test_sweep_parameter_contract(name):
    p = PARAMETERS[name]
    assert p.name == name and p.unit and p.help
    assert p.low is None or p.high is None or p.low < p.high
    # some sweepable kind can vary it, and it says where
    assert any(name in SWEEP_KINDS[k].parameters for k in SWEEP_KINDS)
    assert p.kinds is None or set(p.kinds) <= set(KINDS)


# --------------------------------------------------------------------------- ROS 2 endpoints

def test_pose_readers_and_command_writers():
    from quatform.ros2.endpoints import COMMAND_WRITERS, POSE_READERS

    for name, r in POSE_READERS.items():
        assert r.msg_type.count("/") == 2 and callable(r.read) and callable(r.stamp_ns), name
    for name, w in COMMAND_WRITERS.items():
        assert callable(w.topics) and callable(w.build) and w.default_topic, name


# --------------------------------------------------------------------------- feedback laws

def _laws():
    from quatform.control.laws import LAWS

    return list(LAWS)


@pytest.mark.parametrize("name", _laws())
def test_law_contract(name):
    """A component law runs on floats and arrays alike and passes the desired rate at zero
    error; a whole-block law keeps a block at its reference still, through a Block."""
    from quatform.control.laws import LAWS, Block, BlockLaw

    fn = LAWS[name]
    size = fn.block_size
    if size is None:
        e, cd = np.array([0.3, -0.2, 0.0]), np.array([0.1, 0.0, -0.4])
        arr = fn(e, cd, 1.5, 1.0)
        assert [fn(float(a), float(b), 1.5, 1.0) for a, b in zip(e, cd)] == pytest.approx(list(arr), rel=1e-15)
        assert fn(0.0, 0.25, 1.5, 1.0) == pytest.approx(0.25) and fn(0.0, 0.25, 1.5, 0.0) == 0.0
        law = BlockLaw((Block(name, 0, 2, (1.0, 2.0)),))
    else:
        assert size in (4, 8)
        law = BlockLaw((Block(name, 0, size, (1.0, 1.0, 1.0)),))
    c = (1.0,) + (0.0,) * (law.n - 1)
    err, rate = law(c, c, (0.0,) * law.n)
    assert len(err) == len(rate) == law.n and all(r == 0.0 for r in rate)


# --------------------------------------------------------------------------- team descriptions

def _descriptions():
    from quatform.control.team import team_descriptions

    return list(team_descriptions())


@pytest.mark.parametrize("name", _descriptions())
def test_team_description_contract(name):
    """Its controller name and gain tables fit the one gain schema (control.TEAM_GAIN_KEYS),
    its table-1 gains drive a three-robot team of its default robots, and a scenario file's
    [gains.<name>] takes it."""
    from quatform.control import TEAM_CONTROLLERS, TEAM_GAIN_KEYS, Reference, TeamController
    from quatform.control.team import team_descriptions, team_gain_sizes
    from quatform.formations import TEAM_FORMATIONS

    cls = team_descriptions()[name]
    assert TEAM_FORMATIONS[TEAM_CONTROLLERS[name]] is cls and cls.team
    sizes = team_gain_sizes()
    assert set(cls.gain_tables) >= {"table1", "table2"}
    for table, gains in cls.gain_tables.items():
        assert set(gains) <= set(sizes), (table, set(gains) - set(sizes))
        for key, v in gains.items():
            assert np.size(v) in (1, sizes[key]) and np.all(np.asarray(v) > 0), (table, key)
    F = cls(3)
    read = {TEAM_GAIN_KEYS[g.role][1] for g in F.law_groups}
    assert read <= set(cls.gain_tables["table1"]), read - set(cls.gain_tables["table1"])
    ctrl = TeamController(F, cls.gain_tables["table1"], name=name)
    r = F.sample_robot_state(np.random.default_rng(0))
    c = F.forward(r)
    u = ctrl.step(0.0, r, Reference(c, np.zeros_like(c)))
    assert np.shape(u) == (ctrl.team.n,) and np.all(np.isfinite(u))
