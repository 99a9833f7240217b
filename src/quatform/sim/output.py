"""Run files: ``timeseries.csv`` and ``metrics.json``, written atomically into staged folders.

Sim layer. The time series holds, for every logged variable, the measured value ``v``
and the desired ``v_des`` side by side: the robots (``x1 ... theta2``), the controller's
own cluster variables (quaternion components ``q_c_w, q_c_x, ...``), the Euclidean
variables recovered from the measurements (prefix ``euclid_``), the commands
(``u_x1 ...``) and the singularity measure.

Every file is written to a temporary name and renamed into place (:func:`atomic_write_text`),
so a run cut off by Ctrl-C never leaves a truncated file under its final name. A whole run
folder is built by :func:`staged_dir` in a hidden sibling folder and swapped into place only
when the run has finished: an interrupted or failed run leaves the previous folder (or none)
as it was. ``metrics.json`` is strict JSON (:func:`strict_json`): a NaN or infinite value is
written as ``null`` and named under ``nonfinite_values``.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import shutil
import signal
import threading
from pathlib import Path

import numpy as np


__all__ = ["timeseries_columns", "write_columns", "write_timeseries", "write_metrics", "write_json",
           "strict_json", "atomic_write_text", "atomic_write_bytes", "staged_dir", "OUTPUT_MARKER"]


def timeseries_columns(log, channels) -> tuple[list[str], np.ndarray]:
    """Column names (``t`` first) and the ``(T, n)`` array of one world's log, for a CSV file.

    Parameters
    ----------
    log : Log
        One world (``log.world(i)`` of a batched log).
    channels : sequence
        File order (a kind's ``Experiment.csv_channels``, e.g.
        :data:`quatform.scenarios.pair.PAIR_CSV_CHANNELS`): each item a channel name (its
        columns as they are) or a tuple of channels of one width whose columns are
        interleaved (``("state", "r_des")`` -> ``x1, x1_des, y1, y1_des, ...``).
    """
    names, cols = ["t"], [log.t[:, None]]
    for item in channels:
        group = (item,) if isinstance(item, str) else tuple(item)
        widths = {len(log.columns(name)) for name in group}
        if len(widths) != 1:
            from ..errors import InvalidInputError

            raise InvalidInputError(f"timeseries: interleaved channels {group} have different widths "
                                    f"{[len(log.columns(n)) for n in group]}; interleave channels of one width")
        for i in range(widths.pop()):
            for name in group:
                names.append(log.columns(name)[i])
                cols.append(np.asarray(log[name], dtype=float)[:, i:i + 1])
    return names, np.hstack(cols)


def write_columns(names, data, path) -> Path:
    """A CSV file with a header row ``names`` and the ``(T, n)`` array ``data`` (9 digits).

    Written atomically (a temporary file renamed into place).
    """
    buf = io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    return atomic_write_text(path, buf.getvalue())


def write_timeseries(log, path, channels) -> Path:
    """``timeseries.csv`` of one world's log: the columns of :func:`timeseries_columns`."""
    return write_columns(*timeseries_columns(log, channels), path)


# --------------------------------------------------------------------------- strict JSON

def _finite(obj, where: str, bad: dict):
    """``obj`` with numpy values made plain and every NaN/inf replaced by ``None`` (noted in ``bad``)."""
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        if math.isfinite(obj):
            return obj
        bad[where or "value"] = "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
        return None
    if isinstance(obj, dict):
        return {str(k): _finite(v, f"{where}.{k}" if where else str(k), bad) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v, f"{where}[{i}]", bad) for i, v in enumerate(obj)]
    return obj


def strict_json(obj) -> str:
    """``obj`` as strict JSON text (RFC 8259: no ``NaN``, ``Infinity``), indented, one trailing newline.

    A NaN or infinite number becomes ``null``. In a dict (a ``metrics.json``) the replaced
    values are named under the added key ``nonfinite_values``, ``{"key.sub[0]": "inf" | "-inf" |
    "nan"}``, so a ``null`` that means "did not happen" (e.g. ``first_singular_time_s``) is
    told apart from one that was not finite. In a list of dicts (``comparison.json``) each
    dict gets its own ``nonfinite_values``. NumPy scalars and arrays are written as numbers and
    lists.
    """
    def one(d):
        bad: dict = {}
        clean = _finite(d, "", bad)
        if bad and isinstance(clean, dict):
            clean["nonfinite_values"] = {**clean.get("nonfinite_values", {}), **bad}
        return clean

    clean = [one(d) for d in obj] if isinstance(obj, (list, tuple)) else one(obj)
    return json.dumps(clean, indent=2, allow_nan=False) + "\n"


def write_json(obj, path) -> Path:
    """:func:`strict_json` of ``obj`` written atomically to ``path``."""
    return atomic_write_text(path, strict_json(obj))


def write_metrics(metrics: dict, path) -> Path:
    """``metrics.json``: strict JSON (non-finite values as ``null``, see :func:`strict_json`), atomic."""
    return write_json(metrics, path)


# --------------------------------------------------------------------------- atomic files

def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary sibling file renamed into place.

    A reader (or a run cut off half-way) sees the old file or the whole new one, never a
    truncated one; the temporary file is removed on any error, KeyboardInterrupt included.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` encoded as UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


# --------------------------------------------------------------------------- staged folders

#: File quatform writes into every output folder it makes: the names of the entries it wrote.
#: A folder without it (or holding other entries) is the user's, and is never replaced.
OUTPUT_MARKER = ".quatform-output.json"


def _entries(folder: Path) -> list[str]:
    return sorted(n for n in os.listdir(folder) if n != OUTPUT_MARKER)


def _check_out(out: Path, final: Path) -> None:
    """Refuse an output folder that quatform may not replace (one line naming it and the fix)."""
    from ..errors import InvalidInputError

    cwd = Path(os.getcwd())
    if final == cwd or final in cwd.parents:
        raise InvalidInputError(
            f"output folder {str(out)!r} is the current folder or holds it; quatform builds a run in a new "
            f"folder and swaps it in whole, so give a sub-folder (e.g. --out {os.path.join(str(out), 'run')})")
    if final.is_symlink():
        raise InvalidInputError(f"output folder {str(out)!r} is a symbolic link; give the folder it points to")
    if not final.exists():
        return
    if not final.is_dir():
        raise InvalidInputError(f"output folder {str(out)!r} is a file; give a folder name (--out DIR)")
    entries = _entries(final)
    if not entries:
        return
    owned: set = set()
    marker = final / OUTPUT_MARKER
    if marker.is_file():
        try:
            listed = json.loads(marker.read_text(encoding="utf-8")).get("entries", [])
            owned = {n for n in listed if isinstance(n, str)} if isinstance(listed, list) else set()
        except (OSError, ValueError, AttributeError):
            owned = set()
    foreign = [n for n in entries if n not in owned]
    if foreign:
        raise InvalidInputError(
            f"output folder {str(out)!r} holds files quatform did not write (e.g. {foreign[0]!r}); quatform "
            "replaces its output folder as a whole, so give a new or empty folder, or move those files away")


_STALE = re.compile(r"\.(?P<name>.+)\.(?:partial|old)-(?P<pid>\d+)$")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def _remove_stale(parent: Path, name: str) -> None:
    """Remove ``.<name>.partial-<pid>`` / ``.<name>.old-<pid>`` folders of processes that died (SIGKILL)."""
    with contextlib.suppress(OSError):
        for entry in os.listdir(parent):
            m = _STALE.match(entry)
            if m and m["name"] == name and int(m["pid"]) != os.getpid() and not _pid_alive(int(m["pid"])):
                shutil.rmtree(parent / entry, ignore_errors=True)


@contextlib.contextmanager
def _no_sigint():
    """Hold back SIGINT (Ctrl-C) for the few system calls that swap a folder into place."""
    main = threading.current_thread() is threading.main_thread() and hasattr(signal, "pthread_sigmask")
    if main:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if main:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@contextlib.contextmanager
def staged_dir(out):
    """Build an output folder in a hidden sibling and swap it into place when the block succeeds.

    Yields the temporary folder ``<parent>/.<name>.partial-<pid>``; write every file of the
    run there. When the block ends normally, :data:`OUTPUT_MARKER` (the names written) is added
    and the folder is renamed to ``out``; a previous ``out`` (made by quatform, or empty) is
    removed. On any exception, KeyboardInterrupt included, the temporary folder and any parent
    folders made for it are removed and ``out`` is left as it was. Refused up front (one line):
    an ``out`` that is a file, a symbolic link, the current folder or one holding it, or a
    folder holding entries quatform did not write (user files are never deleted).

    Parameters
    ----------
    out : str or path-like
        The final output folder.

    Yields
    ------
    pathlib.Path
        The temporary folder to write into.
    """
    if "\x00" in str(out):
        from ..errors import InvalidInputError

        raise InvalidInputError(f"output folder {str(out)!r} holds a NUL character; give a folder name without it")
    out = Path(out)
    final = Path(os.path.abspath(out))
    _check_out(out, final)
    parent = final.parent
    made = []
    for p in reversed([parent, *parent.parents]):
        if not p.exists():
            made.append(p)
    parent.mkdir(parents=True, exist_ok=True)
    _remove_stale(parent, final.name)
    tmp = parent / f".{final.name}.partial-{os.getpid()}"
    try:
        if tmp.exists():
            shutil.rmtree(tmp)
        tmp.mkdir()
        yield tmp
        _check_out(out, final)  # the user may have put files there meanwhile
        atomic_write_text(tmp / OUTPUT_MARKER, json.dumps({"written_by": "quatform", "entries": _entries(tmp)},
                                                          indent=2) + "\n")
        old = parent / f".{final.name}.old-{os.getpid()}"
        with _no_sigint():
            if final.exists():
                os.rename(final, old)
                try:
                    os.rename(tmp, final)
                except BaseException:
                    os.rename(old, final)
                    raise
            else:
                os.rename(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        with _no_sigint():  # a second Ctrl-C waits until the partial folder is gone
            shutil.rmtree(tmp, ignore_errors=True)
            for p in reversed(made):
                with contextlib.suppress(OSError):
                    p.rmdir()
        raise
