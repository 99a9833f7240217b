"""The ugv-uav and teleop kinds in a sweep: a cell's trials run as one batch (NumPy, JAX) and
each trial's metrics equal the run of its world alone within 1e-9; the built-in sweeps of
both kinds through ``quatform sweep``."""

import dataclasses
import json
import math

import numpy as np
import pytest

from quatform.cli import main
from quatform.errors import InvalidInputError
from quatform.scenarios import KINDS
from quatform.sweeps import builtin_sweeps, estimate, load_sweep
from quatform.sweeps.spec import sweep_from_dict
from quatform.sweeps.teleop import OFFSET_COLUMNS as TELEOP_OFFSETS
from quatform.sweeps.trials import Chunk, cell_scenario, run_chunk, trial_stream
from quatform.sweeps.ugv_uav import OFFSET_COLUMNS as UGV_UAV_OFFSETS

UGV_UAV = {
    "scenario": "marciano-circle", "formations": ["quaternion", "restricted"], "trials": 3, "chunk_trials": 2,
    "seed": 4, "duration_s": 3.0, "settle_s": 1.0,
    "vary": {"noise_m": {"values": [0.01]}, "noise_rad": {"values": [0.02]}, "latency_s": {"values": [0.02]},
             "dropout_rate": {"values": [0.1]}, "glitch_rate": {"values": [0.05]},
             "gain_scale": {"values": [1.5], "gain": "k_x"}, "initial_offset_m": {"values": [0.05]},
             "initial_offset_rad": {"values": [0.1]}},
}
TELEOP = {
    "scenario": "teleop-free-motion", "orientation_errors": ["euler-parameters"], "trials": 2, "seed": 2,
    "duration_s": 0.4,
    "vary": {"preload": {"values": [1]}, "gain_scale": {"values": [1.2]}, "initial_offset_rad": {"values": [0.02]}},
}


def _offsets(seed, point, trial, columns, moved):
    """The start a trial's draws give: the first uniforms of its stream, one per moved column."""
    u = trial_stream(seed, point, trial).uniform(-1.0, 1.0, sum(len(c) for c, _ in moved))
    x, j = np.zeros(len(columns)), 0
    for names, a in moved:
        for c in names:
            x[columns.index(c)] = a * u[j]
            j += 1
    return x


def _alone(spec, cell, trial):
    """The metrics of one trial's world run alone: the cell's scenario (a ugv-uav trial: its
    motion capture's seed the spec's + the trial), its start, no batch."""
    point, choice, values = spec.cells()[cell]
    sc = cell_scenario(spec, values, choice)
    kind = KINDS[spec.data["kind"]]
    if spec.data["kind"] == "ugv-uav":
        sc = dataclasses.replace(sc, seed=spec.seed + trial)
        moved = [(UGV_UAV_OFFSETS["m"], values["initial_offset_m"]),
                 (UGV_UAV_OFFSETS["rad"], values["initial_offset_rad"])]
    else:
        moved = [(TELEOP_OFFSETS, values["initial_offset_rad"])]
    exp = kind.experiment(sc, **{spec.compare_key: choice})
    x0 = np.asarray(exp.x0, float) + _offsets(spec.seed, point, trial, tuple(exp.plant.state_columns), moved)
    return exp.metrics(dataclasses.replace(exp, x0=x0).run())


def _assert_rows_equal_runs(spec, backend):
    for cell in range(len(spec.cells())):
        cut = min(2, spec.trials - 1)  # two chunks: a trial's numbers do not depend on its chunk
        rows = run_chunk(Chunk(spec, cell, 0, cut, backend)) + run_chunk(Chunk(spec, cell, cut, spec.trials, backend))
        assert [r["trial"] for r in rows] == list(range(spec.trials))
        for r in rows:
            assert not r["failed"], r["failure"]
            alone = _alone(spec, cell, r["trial"])
            for k, v in alone.items():
                if isinstance(v, float) and not math.isnan(v):
                    assert r[k] == pytest.approx(v, rel=1e-9, abs=1e-9), (cell, r["trial"], k)
                elif isinstance(v, (bool, int, str)) and k in r and k not in spec.data.get("vary", {}):
                    assert r[k] == v, (cell, r["trial"], k)
        # the trials differ (their own streams and starts)
        assert len({r["max_ugv_position_error_m" if spec.data["kind"] == "ugv-uav" else "peak_position_error_m"]
                    for r in rows}) == len(rows)


@pytest.fixture(scope="module")
def ugv_uav_spec():
    return sweep_from_dict(dict(UGV_UAV), "ugv-uav-test")


@pytest.fixture(scope="module")
def teleop_spec():
    return sweep_from_dict(dict(TELEOP, chunk_trials=2), "teleop-test")


def test_a_ugv_uav_cell_equals_its_worlds_run_alone(ugv_uav_spec):
    _assert_rows_equal_runs(ugv_uav_spec, "numpy")


def test_a_teleop_cell_equals_its_worlds_run_alone(teleop_spec):
    _assert_rows_equal_runs(teleop_spec, "numpy")


@pytest.mark.parametrize("which", ["ugv-uav", "teleop"])
def test_on_jax_a_cell_equals_its_worlds_run_alone(which, ugv_uav_spec, teleop_spec):
    pytest.importorskip("jax")
    _assert_rows_equal_runs(ugv_uav_spec if which == "ugv-uav" else teleop_spec, "jax")


def test_a_trial_without_changes_is_quatform_run():
    """Trial 0 of a spec of seed 0 with nothing varied is the scenario's own run (its seed 0)."""
    spec = sweep_from_dict({"scenario": "marciano-circle", "formations": ["quaternion"], "trials": 1,
                            "duration_s": 2.0, "settle_s": 1.0}, "plain")
    row = run_chunk(Chunk(spec, 0, 0, 1))[0]
    sc = dataclasses.replace(cell_scenario(spec, {}, "quaternion"))
    exp = KINDS["ugv-uav"].experiment(sc, formation="quaternion")
    assert sc.seed == 0
    for k, v in exp.metrics(exp.run()).items():
        if isinstance(v, float):
            assert row[k] == pytest.approx(v, rel=1e-12, abs=1e-12), k


def test_the_kinds_parameters_and_refusals():
    from quatform.sweeps.trials import SWEEP_KINDS

    assert {"noise_m", "latency_s", "dropout_rate", "glitch_rate", "gain_scale", "seed", "initial_offset_m"} <= \
        set(SWEEP_KINDS["ugv-uav"].parameters)
    assert {"gain_scale", "preload", "initial_offset_rad", "seed"} == set(SWEEP_KINDS["teleop"].parameters)
    bad = [({**TELEOP, "vary": {"noise_m": {"values": [0.01]}}}, "cannot vary noise_m; it can vary gain_scale"),
           ({**TELEOP, "settle_s": 0.1}, "has no settling time"),
           ({**TELEOP, "vary": {"gain_scale": {"values": [2.0], "gain": "kp_pos"}}},
            "not a gain of the euler-parameters controller; it has gains_master.kp_pos"),
           ({**UGV_UAV, "vary": {"gain_scale": {"values": [2.0], "gain": "k_q"}}}, "it has k_x, k_d, k_w, k_psi"),
           ({**TELEOP, "vary": {"glitch_rate": {"values": [0.1]}}}, "cannot vary glitch_rate"),
           ({**UGV_UAV, "vary": {"noise_m": {"values": [2.0]}}}, "mocap_noise_m = 2.0 must be <= 1"),
           ({**TELEOP, "vary": {"gain_scale": {"values": [1e4]}}}, "stability limit")]
    for data, match in bad:
        with pytest.raises(InvalidInputError, match=match) as err:
            spec = sweep_from_dict(data, "bad")
            estimate(spec)  # the up-front checks build every cell's scenario
        assert "\n" not in str(err.value)


@pytest.mark.parametrize("name", ["ugv-uav-mocap-sweep", "teleop-preload-sweep"])
def test_the_builtin_sweeps_through_the_cli(name, tmp_path, capsys):
    """Each built-in (shortened here: its own keys, a shorter duration_s) writes its tables and figures."""
    assert name in builtin_sweeps()
    spec = load_sweep(name)
    assert estimate(spec, workers=1).seconds < 120
    text = builtin_sweeps()[name].read_text(encoding="utf-8")
    short = {"ugv-uav-mocap-sweep": "duration_s = 1.5\nsettle_s = 1.0\n", "teleop-preload-sweep": "duration_s = 0.3\n"}
    body = "\n".join(line for line in text.splitlines() if not line.startswith(("duration_s", "settle_s")))
    toml = tmp_path / f"{name}.toml"
    toml.write_text(body.replace("seed = 0\n", "seed = 0\n" + short[name]), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(toml), "--out", str(out), "--trials", "1", "--quiet"]) == 0
    for f in ("results.csv", "results.json", "summary.csv", "summary.json", "sweep.json"):
        assert (out / f).is_file(), f
    rows = json.loads((out / "results.json").read_text())
    rows = rows if isinstance(rows, list) else rows["rows"]
    assert len(rows) == len(spec.cells()) and not any(r["failed"] for r in rows)
    assert list((out / "figures").glob("*.png"))


def test_a_batch_of_one_ugv_uav_world_is_the_run_alone():
    """x0 of shape (1, 11): the finished world's metrics are the one-world run's, exactly."""
    sc = dataclasses.replace(KINDS["ugv-uav"].from_dict({"kind": "ugv-uav", "name": "c", "duration_s": 3.0,
                                                         "transient_s": 1.0, "mocap_noise_m": 0.01,
                                                         "mocap_dropout_rate": 0.2}, "c"))
    exp = KINDS["ugv-uav"].experiment(sc, formation="quaternion")
    one, batch = exp.run(), dataclasses.replace(exp, x0=np.asarray(exp.x0)[None]).run()
    assert batch["r_true"].shape[1] == 1
    assert exp.metrics(batch.world(0)) == exp.metrics(one)


@pytest.mark.parametrize("formation", ["spherical", "quaternion"])
def test_a_finished_ugv_uav_batch_holds_each_worlds_own_finish(formation):
    """The finish of a batch (the formation's continuation computed for every world at once)
    gives each world exactly the channels and metrics of that world finished alone; a world
    whose first frames are lost has no recovered description there (NaN), not an error."""
    sc = KINDS["ugv-uav"].from_dict({"kind": "ugv-uav", "name": "c", "duration_s": 4.0, "transient_s": 1.0,
                                     "mocap_noise_m": 0.01, "mocap_noise_rad": 0.02, "mocap_dropout_rate": 0.3,
                                     "mocap_glitch_rate": 0.1, "seed": 2}, "c")
    exp = KINDS["ugv-uav"].experiment(sc, formation=formation)
    x0 = np.repeat(np.asarray(exp.x0)[None], 3, axis=0)
    x0[:, 0] += [-0.05, 0.0, 0.05]
    raw = dataclasses.replace(exp, x0=x0, finish=lambda log: log).run()
    batch = exp.finish(raw)
    for b in range(3):
        alone = exp.finish(raw.world(b))
        for name in alone.channels:
            np.testing.assert_array_equal(batch.world(b)[name], alone[name], err_msg=name)
        assert json.dumps(exp.metrics(batch.world(b))) == json.dumps(exp.metrics(alone))
