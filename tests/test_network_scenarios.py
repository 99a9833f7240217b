"""The network scenario kind: files, runs, metrics, graph.json, figures, refusals.

Oracles: the periodic switching schedule's transition-matrix rate (one period's product of
``I - k dt L_s``), the documented failure of a schedule whose union has no spanning tree (the
disagreement between the parts that never hear each other stays), NumPy against JAX.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from quatform.errors import InvalidInputError
from quatform.runs import run
from quatform.scenarios import KINDS, builtin_scenarios, load_scenario
from quatform.tomlio import read_toml

NET = KINDS["network"]


def _data(**changes):
    data, _ = read_toml("net-switching", builtin_scenarios(), "scenario")
    data = json.loads(json.dumps(data))
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    return data


def test_switching_converges_at_the_period_rate(tmp_path):
    run("net-switching", tmp_path / "out", plots=True, quiet=True)
    out = tmp_path / "out"
    got = json.loads((out / "metrics.json").read_text())
    assert got["converged"] and got["nonfinite_commands"] == 0
    assert abs(got["measured_rate"] - got["predicted_rate"]) <= 0.05 * got["predicted_rate"]
    graph = json.loads((out / "graph.json").read_text())
    assert graph["graphs"][0]["edges"] == [[1, 2], [3, 4], [5, 6], [7, 8]]
    assert graph["graphs"][1]["start_s"] == 0.5 and graph["switching_period_s"] == 1.0 and len(graph["graphs"]) == 2
    for f in ("consensus_error.png", "message_age.png", "graph.png", "run.mcap", "timeseries.csv"):
        assert (out / f).is_file(), f
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert "consensus_error" in header and "messages_delivered" in header


def test_a_union_without_spanning_tree_is_refused_in_one_line():
    """Two halves that never hear each other reach no consensus (the failure is measured on SE(3)
    in tests/test_local_dq_laws.py): the file is refused, naming the robots robot 1 never reaches."""
    data = _data(switching=[{"start_s": 0.0, "kind": "edges", "edges": [[1, 2], [2, 3], [3, 4], [4, 1]]},
                            {"start_s": 0.5, "kind": "edges", "edges": [[5, 6], [6, 7], [7, 8], [8, 5]]}])
    with pytest.raises(InvalidInputError, match="union of the \\[\\[switching\\]\\] graphs: .*robots 5, 6, 7, 8") as err:
        NET.from_dict(data, "union-split")
    assert "\n" not in str(err.value)


def test_jax_equals_numpy():
    pytest.importorskip("jax")
    sc = dataclasses.replace(load_scenario("net-switching"), duration_s=2.0)
    ex = NET.experiment(sc)
    a = ex.run()
    b = ex.run(backend="jax")
    for name in ("state", "command", "network", "consensus_error"):
        np.testing.assert_allclose(b[name], a[name], rtol=1e-9, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("changes, match", [
    ({"law": "telepathy"}, "unknown law 'telepathy'"),
    ({"graph": {"kind": "ring"}}, "give \\[graph\\] or \\[\\[switching\\]\\], not both"),
    ({"switching": None}, "switching_period_s repeats"),
    ({"switching_period_s": 0.4}, "starts its first interval at 0 s and its last before"),
    ({"gains": {"gain": 1.0, "k": 2.0}}, "takes gain"),
    ({"switching": [{"start_s": 0.0, "kind": "edges", "edges": [[1, 9]]}]}, "edge \\[1, 9\\] must be two robot"),
    ({"robots": [{"model": "holonomic", "count": 4}, {"model": "free-body", "count": 4}]}, "one robot model"),
    ({"links": {"max_age_s": 0.0}}, "max_age_s"),
    ({"initial": {"antipodal": [0]}}, "antipodal must list robot numbers"),
    ({"initial": {"antipodal": [1]}}, "holonomic robots have none"),
    ({"links": {"drop": 1.0, "max_age_s": 0.01}}, "drop = 1 loses every message"),
    ({"links": {"delay_s": 0.5, "max_age_s": 0.1}}, "every message arrives stale"),
    ({"safety": {"min_separation_m": 0.1}}, "\\[safety\\] needs every pair .* the graph is directed"),
    ({"switching": None, "switching_period_s": None, "graph": {"kind": "complete"}, "duration_s": 1.0, "robots":
      [{"model": "holonomic", "count": 2000}]}, "edges, more than"),
])
def test_a_bad_file_is_one_line(changes, match):
    with pytest.raises(InvalidInputError, match=match) as err:
        NET.from_dict(_data(**changes), "bad.toml")
    assert "\n" not in str(err.value) and str(err.value).startswith("bad.toml")


def test_compare_over_law_leaves_out_the_laws_that_cannot_drive_the_robots():
    run_, skipped = NET.compare_choices(load_scenario("net-switching"), "law")
    assert "position-consensus" in run_
    for why in skipped.values():
        assert "\n" not in why


def test_a_sweep_trial_equals_its_run(tmp_path):
    """Trial i of a network sweep's cell is the run of its scenario with the links' seed
    ``seed + i``, the start drawn from the trial's stream and the cell's values."""
    from quatform.sweeps import load_sweep, plan_chunks
    from quatform.sweeps.trials import run_chunk, trial_stream

    spec_file = tmp_path / "s.toml"
    spec_file.write_text('name = "s"\nscenario = "net-switching"\ntrials = 2\nseed = 5\nduration_s = 3.0\n'
                         '[vary.link_drop]\nvalues = [0.3]\n[vary.link_delay_s]\nvalues = [0.02]\n'
                         '[vary.max_age_s]\nvalues = [0.1]\n')
    spec = load_sweep(spec_file)
    rows = [r for c in plan_chunks(spec) for r in run_chunk(c)]
    assert len(rows) == 2 and not any(r["failed"] for r in rows)
    sc = load_scenario("net-switching")
    for row in rows:
        i, point = row["trial"], row["point"]
        links = dataclasses.replace(sc.links, drop=0.3, delay_s=0.02, max_age_s=0.1, seed=5 + i)
        start = int(trial_stream(5, point, i).integers(2**63 - 1))
        one = dataclasses.replace(sc, duration_s=3.0, links=links, initial={**sc.initial, "seed": start})
        ex = NET.experiment(one)
        met = ex.metrics(ex.run())
        for key in ("consensus_error_final", "messages_dropped", "measured_rate", "min_separation_m"):
            assert row[key] == pytest.approx(met[key], rel=1e-9, abs=1e-12), key


def test_consensus_ring_reaches_the_poses_at_the_rate_lambda2_predicts():
    """12 free bodies on a directed ring from large, antipodal starts (robots 3, 7, 11 at -q):
    the pose consensus converges, its measured rate within 5 % of k lambda_2's discrete rate."""
    sc = load_scenario("net-consensus-ring")
    assert sc.initial["antipodal"] == (2, 6, 10)
    ex = NET.experiment(sc)
    plain = NET.experiment(dataclasses.replace(sc, initial={**sc.initial, "antipodal": ()}))
    q0, q1 = ex.x0.reshape(12, 7)[:, 3:7], plain.x0.reshape(12, 7)[:, 3:7]
    np.testing.assert_array_equal(q0[[2, 6, 10]], -q1[[2, 6, 10]])  # the same poses on the other sheet
    np.testing.assert_array_equal(np.delete(q0, [2, 6, 10], axis=0), np.delete(q1, [2, 6, 10], axis=0))
    log = ex.run()
    met = ex.metrics(log)
    assert met["converged"] and met["nonfinite_commands"] == 0
    assert abs(met["measured_rate"] - met["predicted_rate"]) <= 0.05 * met["predicted_rate"]
    assert met["graph_lambda2"] == pytest.approx(1.0 - np.cos(2 * np.pi / 12), rel=1e-12)


def test_affine_maneuver_reproduces_zhao_2018():
    """Zhao 2018's seven robots: the followers reach A p + b from his offsets and hold it through
    the maneuver; the leaders' condition and the stress come from the file's graph."""
    sc = load_scenario("net-affine-maneuver")
    assert sc.motion.leaders == (0, 1, 2)
    ex = NET.experiment(sc)
    log = ex.run()
    met = ex.metrics(log)
    err = np.asarray(log["consensus_error"])[:, 0]
    t = log.t
    assert met["converged"] and met["consensus_error_final"] < 1e-5
    assert np.max(err[t >= 10.0]) < 0.3  # bounded through both passages (the relay's one-tick lag)
    assert met["min_separation_m"] > 0.5


@pytest.mark.parametrize("changes, match", [
    ({"affine": {"leaders": [1, 2], "keyframes": [[0.0] + [0.0, 1.0, 1.0, 0.0, 0.0, 0.0]] * 2}}, "keyframes' times"),
    ({"affine": {"leaders": [1, 9]}}, "leaders must list robot numbers"),
])
def test_a_bad_affine_table_is_one_line(changes, match):
    data, _ = read_toml("net-affine-maneuver", builtin_scenarios(), "scenario")
    data = json.loads(json.dumps(data))
    data.update(changes)
    with pytest.raises(InvalidInputError, match=match) as err:
        NET.from_dict(data, "bad.toml")
    assert "\n" not in str(err.value)


def test_a_compare_draws_every_laws_consensus_error_on_one_figure(tmp_path):
    from quatform.report import figures_of
    from quatform.report.network_plots import write_network_compare_plots
    from quatform.runs import compare

    assert figures_of("network").compare is write_network_compare_plots
    compare(NET.from_dict(_data(duration_s=0.5), "short-switching"), tmp_path / "cmp", quiet=True, mcap=False)
    assert (tmp_path / "cmp" / "compare_consensus_error.png").is_file()

