"""Atomic files and staged run folders (sim layer; the writers of :mod:`quatform.report.writers` use them).

Every file is written to a temporary name and renamed into place (:func:`atomic_write_text`),
so a run cut off by Ctrl-C never leaves a truncated file under its final name. A whole run
folder is built by :func:`staged_dir` in a hidden sibling folder and swapped into place only
when the run has finished: an interrupted or failed run leaves the previous folder (or none)
as it was.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import threading
from pathlib import Path


__all__ = ["atomic_write_text", "atomic_write_bytes", "staged_dir", "check_inputs_outside", "OUTPUT_MARKER"]


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


def check_inputs_outside(out, *inputs, flag: str = "--out") -> None:
    """Refuse an output folder that is, or holds, one of the run's input files (one line naming both).

    :func:`staged_dir` replaces ``out`` as a whole, so an input inside it (a bag, a plan, a
    spec) would be deleted by the run that reads it. Links are followed (the real paths are
    compared); ``None``, what is not path-like (a loaded scenario) and what is not a file or
    folder (a built-in name) are skipped. An ``out`` holding a NUL character is refused too.

    Parameters
    ----------
    out : str or path-like
        The output folder.
    *inputs : str, path-like or None
        The files or folders the run reads.
    flag : str
        How the output folder is named in the message (the CLI's flag).
    """
    from ..errors import InvalidInputError

    if "\x00" in str(out):
        raise InvalidInputError(f"output folder {str(out)!r} holds a NUL character; give a folder name without it")
    final = Path(os.path.realpath(out))
    for given in inputs:
        if not isinstance(given, (str, os.PathLike)) or "\x00" in str(given):
            continue
        path = Path(given)
        if not path.exists():  # a built-in name, not a file
            continue
        real = Path(os.path.realpath(path))
        if real == final or final in real.parents:
            outside = os.path.join(os.path.dirname(os.path.abspath(out)) or ".", f"{final.name}-out")
            raise InvalidInputError(
                f"input {str(given)!r} is inside the output folder {flag} {str(out)!r}, which quatform replaces "
                f"whole (the input would be deleted); give an {flag} outside it (e.g. {flag} {outside}) or move "
                "the input out first")


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
def staged_dir(out, inputs=()):
    """Build an output folder in a hidden sibling and swap it into place when the block succeeds.

    Yields the temporary folder ``<parent>/.<name>.partial-<pid>``; write every file of the
    run there. When the block ends normally, :data:`OUTPUT_MARKER` (the names written) is added
    and the folder is renamed to ``out``; a previous ``out`` (made by quatform, or empty) is
    removed. On any exception, KeyboardInterrupt included, the temporary folder and any parent
    folders made for it are removed and ``out`` is left as it was. Refused up front (one line):
    an ``out`` that is a file, a symbolic link, the current folder or one holding it, or a
    folder holding entries quatform did not write (user files are never deleted), and an
    ``out`` that holds one of ``inputs`` (:func:`check_inputs_outside`).

    Parameters
    ----------
    out : str or path-like
        The final output folder.
    inputs : sequence of str, path-like or None
        The files the run reads; none may lie inside ``out``.

    Yields
    ------
    pathlib.Path
        The temporary folder to write into.
    """
    check_inputs_outside(out, *inputs)  # refuses a NUL in out too
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
