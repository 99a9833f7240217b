"""Every key a short run of each kind writes into metrics.json, and every column of the run and
compare tables, is defined in docs/metrics.md with a unit; the compare table of the UGV-UAV
kind says how it treats the unreachable reference."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import re
from pathlib import Path

import pytest

from quatform.plan_runs import plan_case_to_dir, plan_to_dir
from quatform.runs import compare, run
from quatform.scenarios import KINDS, kind_aliases, load_scenario
from quatform.scenarios.team import TEAM_CHARTS

DOC = Path(__file__).resolve().parents[1] / "docs" / "metrics.md"


def _sections() -> dict:
    """``{heading: rows}`` of docs/metrics.md: each table row's cells, by its ``##``/``###`` heading."""
    out, head = {}, None
    for line in DOC.read_text(encoding="utf-8").splitlines():
        m = re.match(r"#{2,3} (.+)", line)
        if m:
            head = m.group(1).strip()
            out[head] = []
        elif head and line.startswith("|") and not line.startswith("|---"):
            out[head].append([c.strip() for c in line.strip().strip("|").split("|")])
    return out


def _keys(section: str) -> dict:
    """``{key: (unit, definition)}`` of a ``metrics.json`` section (header row left out)."""
    rows = _sections()[section][1:]
    return {r[0].strip("`"): (r[1], r[2]) for r in rows}


def _defined(kind: str) -> dict:
    """The keys defined for ``kind``: every run's and its own section's (the pair and the team
    kind share one, whose last column names the kinds of each key)."""
    if kind in ("pair", "team"):
        rows = _sections()["metrics.json: pair and team"][1:]
        own = {r[0].strip("`"): (r[1], r[2]) for r in rows if r[3] in ("both", kind)}
    else:
        own = _keys(f"metrics.json: {kind}")
    return {**_keys("metrics.json: every run"), **own}


def _short(name, **changes):
    sc = load_scenario(name)
    fields = {f.name for f in dataclasses.fields(sc)}
    kw = {"duration_s": 0.6}
    kw.update({k: v for k, v in (("metrics_from_s", 0.0), ("transient_s", 0.1)) if k in fields})
    return dataclasses.replace(sc, **{**kw, **changes})


def _written(tmp_path, sc, **options) -> set:
    out = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
    run(sc, out, plots=False, quiet=True, mcap=False, **options)
    return set(json.loads((out / "metrics.json").read_text()))


def _check(keys, kind):
    defined = _defined(kind)
    missing = sorted(set(keys) - set(defined))
    assert not missing, f"{kind}: metrics.json keys not defined in docs/metrics.md: {missing}"
    for key in keys:
        unit, definition = defined[key]
        assert unit and definition, f"{kind}: {key} needs a unit and a definition in docs/metrics.md"


def test_every_section_row_has_a_unit_and_a_definition():
    for head, rows in _sections().items():
        for r in rows[1:]:
            assert all(r), f"docs/metrics.md, {head}: an empty cell in {r}"
            assert len(r) == len(rows[0]), f"docs/metrics.md, {head}: {r} has not the header's {len(rows[0])} cells"


#: A short run of each kind (and of the options that add keys).
RUNS = [
    ("net-switching", "network", {}),
    ("mas-kitts-helix", "pair", {"controller": "quaternion"}),
    ("mas-kitts-helix", "pair", {"controller": "cluster-space"}),
    ("mas-kitts-helix", "pair", {"controller": "dual-quaternion", "min_separation": 0.5}),
    ("team-tetrahedron-helix", "team", {"controller": "quaternion"}),
    ("team-triangle-over-ugv", "team", {"controller": "robot-space"}),
    ("marciano-front-to-over", "ugv-uav", {"formation": "restricted"}),
    ("marciano-circle", "ugv-uav", {"formation": "quaternion"}),
    ("teleop-wall-contact", "teleop", {}),
    ("teleop-virtual-wall", "teleop", {}),
]


def test_every_kind_is_run_here():
    # the names the kinds' parts are registered under: a kind's own, or an alias it reads ("pair")
    assert {kind_aliases().get(kind, kind) for _, kind, _ in RUNS} == set(KINDS), \
        "add a short run of the new kind to RUNS"


@pytest.mark.parametrize("name, kind, options", RUNS)
def test_every_metrics_key_of_a_run_is_defined(tmp_path, name, kind, options):
    _check(_written(tmp_path, _short(name), **options), kind)


@pytest.mark.parametrize("name, kind, options", [
    ("mas-kitts-helix", "pair", {"controller": "quaternion"}),
    ("team-triangle-over-ugv", "team", {"controller": "quaternion"}),
    ("marciano-circle", "ugv-uav", {"formation": "quaternion"}),
])
def test_every_metrics_key_of_a_physics_run_is_defined(tmp_path, name, kind, options):
    pytest.importorskip("mujoco")
    keys = _written(tmp_path, _short(name, duration_s=0.3), physics="mujoco", **options)
    assert {"collisions", "physics_timestep_s", "render"} <= keys
    _check(keys, kind)


def test_every_metrics_key_of_a_plan_is_defined(tmp_path):
    for spec in ("belta-kumar-2002-two-bodies", "vertical-pass-two-bodies"):
        _check(set(plan_to_dir(spec, tmp_path / spec, plots=False)[1]), "plan")
    _, m = plan_to_dir("belta-kumar-2002-two-bodies", tmp_path / "meet", alpha=0.2, plots=False)
    assert m["through_meeting"]
    _check(set(m), "plan")
    _check(set(plan_case_to_dir("belta-kumar-2001-airplanes", tmp_path / "air", "a", plots=False)[1]), "plan")


def test_every_metrics_key_of_a_replay_is_defined(tmp_path):
    helpers = Path(__file__).parent / "fake_rclpy" / "ros2_helpers.py"
    spec = importlib.util.spec_from_file_location("ros2_helpers", helpers)
    H = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(H)
    from quatform.ros2.replay import replay

    b = H.simulated_pair_bag(tmp_path, 0.3)
    bag, sc, robots = b["bag"], b["sc"], b["robots"]
    replay(bag, sc, robots, tmp_path / "out", controller="quaternion", plots=False)
    keys = set(json.loads((tmp_path / "out" / "metrics.json").read_text()))
    _check(keys, "replay")


def test_every_table_column_is_defined():
    sections = _sections()
    # each kind's table, and the team kind's table of each chart (seed 000's: "pair")
    tables = [(kind, kind.name, kind.table_columns) for kind in KINDS.values()]
    tables += [(KINDS["team"], name, parts.table_columns) for name, parts in TEAM_CHARTS.items() if name != "team"]
    for kind, name, own in tables:
        assert f"table: {name}" in sections, f"docs/metrics.md has no section 'table: {name}'"
        rows = {r[0]: r for r in sections[f"table: {name}"][1:]}
        axes = [o.name for o in kind.options if o.choices is not None]
        columns = set(own)
        keys = {key for key, _, _ in own}
        columns |= {(axis, axis.replace("_", " "), "{}") for axis in axes if axis not in keys}  # compare_columns
        defined = _defined(name)
        for key, header, _ in columns:
            assert header in rows, f"docs/metrics.md, table: {name}: no row for the column {header!r}"
            _, doc_key, unit, definition = rows[header]
            assert doc_key == f"`{key}`" and unit and definition, rows[header]
            assert key in defined, f"{name}: the column {header!r} reads {key}, not defined in metrics.json"


def test_the_ugv_uav_compare_table_states_the_unreachable_window(tmp_path):
    sc = _short("marciano-front-to-over", duration_s=2.0, transient_s=0.5)
    rows = compare(sc, tmp_path / "cmp", plots=False, quiet=True, mcap=False)
    table = (tmp_path / "cmp" / "comparison.md").read_text()
    head = [c.strip() for c in table.splitlines()[4].strip("|").split("|")]
    assert "unreachable ref. (s)" in head
    assert [h for h in head if "err" in h] == ["UGV err, reachable (m)", "UAV err, reachable (m)",
                                               "UAV yaw err, reachable (rad)"]
    restricted = next(r for r in rows if r["formation"] == "restricted")
    line = next(x for x in table.splitlines() if x.startswith("| restricted"))
    cells = dict(zip(head, [c.strip() for c in line.strip("|").split("|")]))
    assert restricted["unreachable_reference_s"] > 1.0
    assert cells["unreachable ref. (s)"] == f"{restricted['unreachable_reference_s']:.1f}"
