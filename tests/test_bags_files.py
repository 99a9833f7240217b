"""The files the bags layer writes and reads: corrupt MCAP files are one line, the rosbag2
metadata names the file, /tf_static is transient-local, the Foxglove layout's panel titles,
CSV times to the nanosecond.

Oracles: rosbags' reader (the metadata and QoS it reads back), the MCAP record layout of the
specification (a length field patched by hand), Foxglove's layout format (panel settings read
``foxglovePanelTitle``), Python's own float parsing.
"""

import dataclasses
import functools
import struct

import numpy as np
import pytest

from quatform.bags import foxglove_layout, read_log, read_poses, scene_of, write_mcap
from quatform.cli import main
from quatform.errors import InvalidInputError
from quatform.report.writers import write_columns, write_timeseries
from quatform.scenarios import kind_of, load_scenario
from quatform.sim.log import Channel, Log

HUGE = 2 ** 62


@functools.cache
def _short_run():
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=0.2, metrics_from_s=0.0)
    kind = kind_of(sc)
    return kind.parts_of(sc), kind.experiment(sc, controller="quaternion").run(None)


@pytest.fixture
def run_mcap(tmp_path):
    kind, log = _short_run()
    return write_mcap(log, tmp_path / "run.mcap", kind=kind)


def _records(data: bytes):
    """``[(offset, opcode, length)]`` of the top-level records (MCAP spec: opcode u8, length u64)."""
    out, pos = [], 8
    while pos < len(data) - 8:
        op, (n,) = data[pos], struct.unpack_from("<Q", data, pos + 1)
        out.append((pos, op, n))
        pos += 9 + n
        if op == 0x02:
            break
    return out


def _patched(path, offset: int, value: int, name: str):
    data = bytearray(path.read_bytes())
    struct.pack_into("<Q", data, offset, value)
    out = path.with_name(name)
    out.write_bytes(bytes(data))
    return out


def _chunk_index_compressed_size_offset(data: bytes, offset: int) -> int:
    """Byte offset of a ChunkIndex record's ``compressed_size`` (times, chunk offset and length,
    message index offsets (u32 + bytes), message index length, compression (u32 + bytes))."""
    b = offset + 9 + 32
    b += 4 + struct.unpack_from("<I", data, b)[0] + 8
    return b + 4 + struct.unpack_from("<I", data, b)[0]


def test_a_huge_declared_record_length_is_one_line_naming_the_file_and_the_record(run_mcap):
    """A record (here the header) declaring 2^62 bytes: read_log and read_poses said MemoryError."""
    left = run_mcap.stat().st_size - 8 - 9 - 8  # after the start magic, the record's header; before the end magic
    bad = _patched(run_mcap, 9, HUGE, "header.mcap")  # the Header record at byte 8: its length field
    want = (rf"bag .*header\.mcap is truncated or corrupt: record at byte 8 \(opcode 0x01\) declares "
            rf"{HUGE} bytes \(2\^62\), the file has {left} left; copy or record the file again")
    for read in (read_log, read_poses):
        with pytest.raises(InvalidInputError, match=want):
            read(bad)


def test_a_chunk_index_pointing_past_the_file_is_one_line(run_mcap):
    data = run_mcap.read_bytes()
    index = next(p for p, op, _ in _records(data) if op == 0x08)
    bad = _patched(run_mcap, _chunk_index_compressed_size_offset(data, index), HUGE, "index.mcap")
    for read in (read_log, read_poses):
        with pytest.raises(InvalidInputError, match=rf"record at byte {index} \(opcode 0x08\) declares a compressed "
                                                    rf"chunk of {HUGE} bytes"):
            read(bad)


def test_a_chunks_sizes_are_checked_against_its_record_and_the_bound(run_mcap):
    from quatform.bags.mcap_check import MAX_CHUNK_BYTES, check_mcap

    data = run_mcap.read_bytes()
    chunk = next(p for p, op, _ in _records(data) if op == 0x06)
    with pytest.raises(InvalidInputError, match=rf"record at byte {chunk} \(opcode 0x06\) declares {HUGE} bytes"):
        check_mcap(_patched(run_mcap, chunk + 1, HUGE, "chunk.mcap"))
    with pytest.raises(InvalidInputError, match=rf"uncompressed chunk of {HUGE} bytes \(2\^62\), more than the "
                                                rf"{MAX_CHUNK_BYTES} bytes"):
        check_mcap(_patched(run_mcap, chunk + 9 + 16, HUGE, "unc.mcap"))  # after the two times


def test_a_truncated_file_is_one_line(run_mcap):
    from quatform.bags.mcap_check import check_mcap

    data = run_mcap.read_bytes()
    cut = run_mcap.with_name("cut.mcap")
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InvalidInputError, match=r"cut\.mcap is truncated or corrupt: record at byte \d+ .*declares"):
        read_log(cut)
    check_mcap(run_mcap)  # the file as written passes


def test_a_chunk_whose_compressed_bytes_are_damaged_is_one_line(run_mcap):
    """Bytes of a chunk's zstd data overwritten (the record lengths intact): read_log and
    read_poses said 'internal error: ZstdError: ... Data corruption detected'."""
    data = bytearray(run_mcap.read_bytes())
    chunk, _, n = next(r for r in _records(bytes(data)) if r[1] == 0x06)
    mid = chunk + 9 + n // 2  # inside the chunk's compressed records
    data[mid:mid + 64] = bytes(b ^ 0xFF for b in data[mid:mid + 64])
    bad = run_mcap.with_name("damaged.mcap")
    bad.write_bytes(bytes(data))
    for read in (read_log, read_poses):
        with pytest.raises(InvalidInputError, match=r"bag .*damaged\.mcap is truncated or corrupt \(.*\); copy or "
                                                    r"record the file again"):
            read(bad)


def test_replay_of_a_corrupt_bag_is_one_line_and_exit_2(run_mcap, tmp_path, capsys):
    bad = _patched(run_mcap, 9, HUGE, "header.mcap")
    robots = tmp_path / "robots.toml"
    robots.write_text("".join(f'[[robots]]\nname = "r{i}"\npose_topic = "/robot_{i}/pose"\n' for i in (1, 2)))
    rc = main(["replay", str(bad), "--scenario", "mas-kitts-helix", "--controller", "quaternion", "--robots",
               str(robots), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and "Traceback" not in err and "out of memory" not in err
    assert "header.mcap is truncated or corrupt: record at byte 8 (opcode 0x01) declares 4611686018427387904" in err


def _rosbag2_metadata(path):
    """The rosbag2 metadata record the MCAP file carries (``name`` rosbag2), parsed YAML."""
    from ruamel.yaml import YAML

    data = path.read_bytes()
    for pos, op, n in _records(data):
        if op == 0x0C:  # Metadata: name (u32 + bytes), map<string, string> (u32 byte length + pairs)
            b = pos + 9
            k = struct.unpack_from("<I", data, b)[0]
            if data[b + 4:b + 4 + k] != b"rosbag2":
                continue
            b += 4 + k + 4
            key_len = struct.unpack_from("<I", data, b)[0]
            b += 4 + key_len
            value_len = struct.unpack_from("<I", data, b)[0]
            return YAML(typ="safe").load(data[b + 4:b + 4 + value_len].decode())
    raise AssertionError("no rosbag2 metadata record")


def test_the_rosbag2_metadata_names_the_file_it_is_in(run_mcap):
    meta = _rosbag2_metadata(run_mcap)
    assert meta["relative_file_paths"] == ["run.mcap"]
    assert [f["path"] for f in meta["files"]] == ["run.mcap"]
    assert not any(p.name.startswith(".run.mcap") for p in run_mcap.parent.iterdir())  # no staging left


def test_tf_static_is_offered_transient_local():
    """A teleoperation run's /tf_static (the arms' bases): the QoS tf2's static broadcaster
    offers, which a late subscriber of ros2 bag play needs; rosbags reads it back."""
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosDurability, QosHistory, QosReliability

    sc = dataclasses.replace(load_scenario("teleop-wall-contact"), duration_s=0.05)
    kind = kind_of(sc)
    log = kind.experiment(sc).run(None)
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        path = write_mcap(log, Path(d) / "run.mcap", kind=kind.parts_of(sc))
        with AnyReader([path]) as reader:
            qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    (static,) = qos["/tf_static"]
    assert static.durability == QosDurability.TRANSIENT_LOCAL
    assert static.reliability == QosReliability.RELIABLE
    assert (static.history, static.depth) == (QosHistory.KEEP_LAST, 1)
    assert qos["/tf"] == []  # the others: the player's default (volatile)


def test_the_foxglove_layouts_panel_titles_are_under_foxglove_panel_title():
    kind, log = _short_run()
    configs = foxglove_layout(kind, scene_of(log, kind))["configById"]
    plots = {k: c for k, c in configs.items() if k.startswith("Plot!")}
    assert plots and all("title" not in c for c in configs.values())
    assert all(c["foxglovePanelTitle"] for c in plots.values())
    assert "(m)" in plots["Plot!position"]["foxglovePanelTitle"]  # the position plot's unit


def test_csv_times_survive_to_the_nanosecond(tmp_path):
    """timeseries.csv of an epoch-stamped log: every t reads back as the same float (so the
    stamp round(t * 1e9) that run.mcap holds); integer-ns times as nine decimals, exactly."""
    from quatform.report.writers import ns_text

    t = 1.7e9 + np.arange(8001) * 0.01
    log = Log(t, [Channel("state", ("x",), np.sin(t - 1.7e9)[:, None])], {})
    path = write_timeseries(log, tmp_path / "timeseries.csv")
    rows = [line.split(",") for line in path.read_text().splitlines()[1:]]
    back = np.array([float(r[0]) for r in rows])
    np.testing.assert_array_equal(back, t)
    assert np.unique(back).size == t.size
    np.testing.assert_array_equal(np.round(back * 1e9).astype(np.int64), np.round(t * 1e9).astype(np.int64))
    ns = 1_700_000_000_000_000_000 + np.arange(3, dtype=np.int64) * 10_000_001
    assert ns_text(ns) == ["1700000000.000000000", "1700000000.010000001", "1700000000.020000002"]
    assert ns_text([-1_500_000_000]) == ["-1.500000000"]
    f = write_columns(["t", "x"], np.c_[ns * 1e-9, [1.0, 2.0, 1 / 3]], tmp_path / "c.csv", ns={"t": ns})
    lines = f.read_text().splitlines()
    assert lines[1:] == ["1700000000.000000000,1", "1700000000.010000001,2", "1700000000.020000002,0.333333333"]
    with pytest.raises(InvalidInputError, match="lacks"):
        write_columns(["t"], np.zeros((3, 1)), tmp_path / "d.csv", ns={"time": ns})
