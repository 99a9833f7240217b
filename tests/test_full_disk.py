"""A full disk under run, compare, a team run and a sweep: one line naming the folder and the
file being written, exit status 1, and nothing half-written left.

The disk fills at the N-th write: ``open`` (builtins and io, which Path, NumPy, matplotlib,
Pillow and rosbags use) hands out files whose ``write`` raises ``OSError(ENOSPC)`` without a
file name, as the kernel's ``write(2)`` does, once N writes have been made."""

from __future__ import annotations

import builtins
import errno
import io
import os
import re

import pytest

from quatform import cli
from quatform.errors import OutputWriteError
from quatform.sim.output import atomic_write_text, staged_dir, write_failures

_REAL_OPEN = io.open


class _Disk:
    """Counts the writes to every file opened for writing whose path holds ``match``; the
    ``fail_at``-th such write and later ones fail."""

    def __init__(self, match: str, fail_at: int):
        self.match, self.fail_at, self.writes = match, fail_at, 0

    def open(self, file, mode="r", *args, **kwargs):
        f = _REAL_OPEN(file, mode, *args, **kwargs)
        writing = any(c in mode for c in "wax+") and self.match in str(file)
        return _FullFile(f, self) if writing else f


class _FullFile:
    def __init__(self, f, disk: _Disk):
        self._f, self._disk = f, disk

    def write(self, data):
        self._disk.writes += 1
        if self._disk.writes >= self._disk.fail_at:
            raise OSError(errno.ENOSPC, "No space left on device")
        return self._f.write(data)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()

    def __iter__(self):
        return iter(self._f)

    def __getattr__(self, name):
        return getattr(self._f, name)


@pytest.fixture
def full_disk(monkeypatch):
    def fill(match: str = "", fail_at: int = 1):
        disk = _Disk(match, fail_at)
        monkeypatch.setattr(builtins, "open", disk.open)
        monkeypatch.setattr(io, "open", disk.open)
        return disk

    return fill


def _entries(folder):
    return sorted(p.name for p in folder.iterdir())


def _refused(capsys, out):
    lines = capsys.readouterr().err.strip().splitlines()
    said = [line for line in lines if line.startswith("quatform:")]  # besides a run's progress lines
    assert not any("Traceback" in line for line in lines) and said == lines[-1:], lines
    err = said[0]
    m = re.fullmatch(rf"quatform: error: no space left on device writing (\S+) in {re.escape(str(out))}: free space "
                     r"or choose another --out", err)
    assert m, err
    assert m[1].startswith(str(out) + "/"), err  # the file by its final name in the user's folder
    return m[1]


SWEEP = """
name = "tiny"
scenario = "mas-kitts-yaw-step"
controllers = ["quaternion", "dual-quaternion"]
trials = 2
duration_s = 1.0
settle_s = 0.2
"""

COMMANDS = {
    "run": ["run", "mas-kitts-yaw-step", "--controller", "quaternion"],
    "compare": ["compare", "mas-kitts-yaw-step"],
    "team": ["run", "team-three-bodies", "--controller", "quaternion"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_full_disk_is_one_line_naming_the_folder_and_the_file(tmp_path, capsys, full_disk, command):
    """Guards against: "quatform: error: No space left on device", naming nothing."""
    out = tmp_path / "out"
    disk = full_disk("timeseries.csv")
    rc = cli.main([*COMMANDS[command], "--out", str(out), "--no-plots", "--no-mcap"])
    assert disk.writes >= 1, "the disk never filled"
    assert rc == 1
    assert _refused(capsys, out).endswith("timeseries.csv")
    assert _entries(tmp_path) == []  # no folder, no partial folder, no temporary file


@pytest.mark.parametrize("match, fail_at, named", [
    ("timeseries.csv", 1, "timeseries.csv"),
    (".png", 2, ".png"),  # the second figure: the first is whole, and goes with the folder
    ("run.mcap", 3, "run.mcap"),  # the bag's staging folder, some of its chunks written
    ("foxglove-layout.json", 1, "foxglove-layout.json"),
    ("metrics.json", 1, "metrics.json"),
    (".quatform-output.json", 1, ".quatform-output.json"),  # the last file, before the swap
])
def test_a_full_disk_names_each_file_of_a_run(tmp_path, capsys, full_disk, match, fail_at, named):
    out = tmp_path / "out"
    disk = full_disk(match, fail_at)
    plots = [] if match == ".png" else ["--no-plots"]
    rc = cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out), *plots])
    assert disk.writes >= fail_at and rc == 1
    assert _refused(capsys, out).endswith(named)
    assert _entries(tmp_path) == []


def test_a_full_disk_leaves_a_previous_run_as_it_was(tmp_path, capsys, full_disk):
    out = tmp_path / "out"
    argv = ["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out), "--no-plots", "--no-mcap"]
    assert cli.main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    full_disk("metrics.json")
    assert cli.main(argv) == 1
    _refused(capsys, out)
    assert _entries(tmp_path) == ["out"] and {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.parametrize("match, named", [("sweep.json", "sweep.json"), ("results.csv", "results.csv"),
                                           (".png", ".png"), ("part-", "part-00000-000000.parquet")])
def test_a_sweep_on_a_full_disk_names_the_folder_and_keeps_only_whole_files(tmp_path, capsys, full_disk, match,
                                                                            named):
    spec = tmp_path / "tiny.toml"
    spec.write_text(SWEEP)
    out = tmp_path / "out"
    full_disk(match)
    plots = [] if match == ".png" else ["--no-plots"]
    shards = ["--results", "parquet"] if match == "part-" else []  # a Parquet shard (pyarrow)
    if shards:
        pytest.importorskip("pyarrow")
    assert cli.main(["sweep", str(spec), "--out", str(out), "--quiet", *plots, *shards]) == 1
    assert _refused(capsys, out).endswith(named)
    left = [p for p in tmp_path.rglob("*") if ".tmp-" in p.name or ".partial" in p.name]
    assert left == []  # finished chunks may stay (a rerun resumes them), never a half-written file


def test_the_api_raises_one_output_write_error(tmp_path, full_disk):
    out = tmp_path / "o"
    full_disk()
    with pytest.raises(OutputWriteError, match=rf"no space left on device writing {re.escape(str(out))}/a\.json in "
                       rf"{re.escape(str(out))}: free space") as info:
        with staged_dir(out) as tmp:
            atomic_write_text(tmp / "a.json", "{}")
    assert info.value.errno == errno.ENOSPC and isinstance(info.value, OSError)
    assert _entries(tmp_path) == []


def test_a_file_the_run_reads_keeps_its_own_error(tmp_path):
    """A permission error on a file outside the output folder (an input) is not a write failure."""
    with pytest.raises(PermissionError):
        with write_failures(tmp_path / "o"):
            raise PermissionError(errno.EACCES, "Permission denied", "/etc/shadow")
    with pytest.raises(OutputWriteError, match="permission denied writing .*/o/x in"):
        with write_failures(tmp_path / "o"):
            raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "o" / "x"))


def test_a_plan_on_a_full_disk_names_its_file(tmp_path, capsys, full_disk):
    out = tmp_path / "out"
    full_disk("plan.npz")
    assert cli.main(["plan", "vertical-pass-two-bodies", "--out", str(out), "--no-plots"]) == 1
    assert _refused(capsys, out) == f"{out}/plan.npz"
    assert _entries(tmp_path) == []


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc (no folder can be made in it)")
def test_an_out_where_no_folder_can_be_made_is_one_line_naming_it(tmp_path):
    """Guards against: ``--out /proc/x`` reporting the hidden staging folder's name
    (``/proc/.x.partial-<pid>``) instead of the user's folder and the fix."""
    from quatform import runs

    with pytest.raises(OutputWriteError) as err:
        runs.run("mas-kitts-helix", "/proc/quatform-out", quiet=True, plots=False, mcap=False, controller="quaternion")
    assert "/proc/quatform-out" in str(err.value) and "--out" in str(err.value) and ".partial" not in str(err.value)
