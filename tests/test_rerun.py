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
    return kind.parts_of(sc), kind.experiment(sc, **options).run(None)


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


def test_an_independent_mcap_reader_decodes_the_named_channels_by_their_embedded_schemas(tmp_path):
    """rerun-sdk's MCAP reader (its own Rust implementation, decoding ROS 2 messages from the
    ros2msg schemas in the file, as Foxglove and PlotJuggler do) reads the named fields and the
    poses back as the log holds them."""
    chunk = pytest.importorskip("rerun.chunk")
    if not hasattr(chunk, "McapReader"):
        pytest.skip("this rerun-sdk has no MCAP reader in Python")
    import numpy as np
    import pyarrow as pa

    from quatform.bags import write_mcap

    kind, log = _short_log("mas-kitts-helix", controller="quaternion")
    path = write_mcap(log, tmp_path / "run.mcap", kind=kind)
    reader = chunk.McapReader(path, decoders=["ros2_reflection"],
                              include_topic_regex=["/quatform/cluster$", "/robot_2/pose$"])
    info = reader.info()
    assert info.profile == "ros2" and info.summary_source == "embedded"
    assert {c.schema.encoding for c in info.channels} == {"ros2msg"}
    assert not info.chunks.has_overlapping_time_ranges  # written in time order
    parts = {}
    for c in reader.stream().to_chunks():
        batch = c.to_record_batch()
        names = [n for n in batch.schema.names if n.endswith(":message")]
        if names:
            parts.setdefault(c.entity_path, []).append((batch.column("message_log_time"), batch.column(names[0]).flatten()))
    for entity, rows in parts.items():
        order = np.argsort(np.concatenate([np.asarray(t.cast(pa.int64())) for t, _ in rows]), kind="stable")
        parts[entity] = pa.concat_arrays([m for _, m in rows]).take(pa.array(order))
    cluster, pose = parts["/quatform/cluster"], parts["/robot_2/pose"]
    cols = log.columns("cluster")
    for name in ("x_c", "q_c_w", "d_c", "q_c2_z"):
        np.testing.assert_array_equal(np.asarray(cluster.field(name)), log["cluster"][:, cols.index(name)])
    np.testing.assert_array_equal(np.asarray(pose.field("pose").field("position").field("z")), log["state"][:, 6])
    np.testing.assert_allclose(np.asarray(pose.field("pose").field("orientation").field("w")),
                               np.cos(log["state"][:, 7] / 2), atol=1e-15)


@pytest.mark.parametrize("bad, said", [("rx.txt", "FILE.rrd"),
                                       ("nonexist/dir/x.rrd", "does not exist or is not writable"),
                                       ("out/x.rrd", "inside the output folder")])
def test_a_bad_rerun_path_is_refused_before_the_run(tmp_path, monkeypatch, capsys, bad, said):
    """--rerun is checked before anything runs: a wrong suffix, a missing folder, a file inside --out."""
    pytest.importorskip("rerun")
    from quatform.scenarios import base

    ran = []
    monkeypatch.setattr(base.Experiment, "run", lambda self, *a, **k: ran.append(1))
    code = main(["run", "mas-kitts-helix", "--controller", "quaternion", "--out", str(tmp_path / "out"),
                 "--rerun", str(tmp_path / bad)])
    err = capsys.readouterr().err
    assert code == 2 and said in err and len(err.strip().splitlines()) == 1
    assert ran == [] and not (tmp_path / "out").exists()


def test_ctrl_c_during_the_rerun_write_leaves_neither_recording_nor_folder(tmp_path, monkeypatch, capsys):
    pytest.importorskip("rerun")
    from quatform.bags import rerun as qr

    def interrupted(rr, rec, root, log):
        raise KeyboardInterrupt

    from quatform.scenarios import base

    monkeypatch.setattr(qr, "_channels", interrupted)
    _, log = _short_log("mas-kitts-helix", controller="quaternion")
    monkeypatch.setattr(base.Experiment, "run", lambda self, *a, **k: log)
    code = main(["run", "mas-kitts-helix", "--controller", "quaternion", "--out", str(tmp_path / "out"), "--no-plots",
                 "--rerun", str(tmp_path / "k.rrd")])
    err = capsys.readouterr().err
    assert code == 130 and "left as it was" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []
