"""quatform.bags.rerun: a run as a headless Rerun recording (extra ``rerun``)."""

import dataclasses
import re
import sys

import pytest

from quatform.cli import main
from quatform.errors import MissingDependencyError
from quatform.scenarios import kind_of, load_scenario


def _short_log(name, **options):
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration_s=0.5, metrics_from_s=0.0)
    kind = kind_of(sc)
    return kind.name, kind.experiment(sc, **options).run(None)


def _entities(path):
    """Entity paths of a recording, read back by rerun-sdk (skipped where it cannot read files)."""
    chunk = pytest.importorskip("rerun.chunk")
    if not hasattr(chunk, "RrdReader"):
        pytest.skip("this rerun-sdk cannot read recordings back in Python")
    return set(chunk.RrdReader(path).store().schema().entity_paths())


def test_a_missing_rerun_sdk_names_its_pip_install(monkeypatch, tmp_path):
    from quatform.bags import rerun as qr

    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[rerun\]"'):
        qr.require_rerun()
    kind, log = _short_log("mas-kitts-helix", controller="quaternion")
    with pytest.raises(MissingDependencyError):
        qr.write_rerun(log, tmp_path / "x.rrd", kind=kind)


def test_write_rerun_holds_the_scene_and_every_channel(tmp_path):
    pytest.importorskip("rerun")
    from quatform.bags.rerun import write_rerun

    kind, log = _short_log("mas-kitts-helix", controller="quaternion")
    path = write_rerun(log, tmp_path / "helix.rrd", kind=kind)
    assert path.is_file() and path.stat().st_size > 1000
    assert not (tmp_path / "helix.rrd.partial").exists()
    entities = _entities(path)
    for e in ("/world/robot_1", "/world/robot_2", "/world/robots", "/world/robots_desired", "/world/edges",
              "/world/paths", "/world/paths_desired", "/channels/cluster", "/channels/error", "/channels/singularity"):
        assert e in entities, (e, sorted(entities))
    from rerun.chunk import RrdReader

    schema = RrdReader(path).store().schema()
    assert any("Transform3D:quaternion" in c for c in schema.column_names())


def test_cli_rerun_writes_one_recording_of_a_run_and_of_a_compare(tmp_path):
    pytest.importorskip("rerun")
    rrd = tmp_path / "teleop.rrd"
    # a short teleoperation run (joint states and the wrench have no Rerun entity; the hands' poses
    # and every channel do)
    from quatform.scenarios import builtin_scenarios

    text = builtin_scenarios()["teleop-free-motion"].read_text()
    text = re.sub(r"(?m)^duration_s = .*$", "duration_s = 0.05", text, count=1)
    text = re.sub(r"(?ms)^keys = \[.*?^\]", "keys = [{ t_s = 0.0 }]", text, count=1)
    toml = tmp_path / "free.toml"
    toml.write_text(text)
    assert main(["teleop", str(toml), "--out", str(tmp_path / "t"), "--no-plots", "--no-mcap", "--rerun", str(rrd)]) == 0
    entities = _entities(rrd)
    assert {"/world/master_hand", "/world/slave_hand", "/channels/F_s"} <= entities
    both = tmp_path / "both.rrd"
    assert main(["compare", str(toml), "--out", str(tmp_path / "c"), "--no-plots", "--rerun", str(both)]) == 0
    entities = _entities(both)
    assert {"/euler-parameters/world/slave_hand", "/rpy/world/slave_hand"} <= entities
    assert (tmp_path / "c" / "rpy" / "run.mcap").is_file()


def test_a_recording_is_a_rrd_file(tmp_path):
    pytest.importorskip("rerun")
    from quatform.bags.rerun import write_rerun
    from quatform.errors import InvalidInputError

    kind, log = _short_log("mas-kitts-helix", controller="quaternion")
    with pytest.raises(InvalidInputError, match="FILE.rrd"):
        write_rerun(log, tmp_path / "x.mcap", kind=kind)
    assert not (tmp_path / "x.mcap").exists()
