"""Atomic files and staged run folders (sim layer; the writers of :mod:`quatform.report.writers` use them).

Every file is written to a temporary name and renamed into place (:func:`atomic_write_text`),
so a run cut off by Ctrl-C never leaves a truncated file under its final name. A whole run
folder is built by :func:`staged_dir` in a hidden sibling folder and swapped into place only
when the run has finished: an interrupted or failed run leaves the previous folder (or none)
as it was.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import signal
import threading
from pathlib import Path

from ..errors import OutputWriteError

__all__ = ["atomic_file", "remove_dead_temporaries", "atomic_write_text", "atomic_write_bytes", "staged_dir",
           "check_inputs_outside", "OUTPUT_MARKER", "WRITE_FAILURES", "writing", "write_failures"]


# --------------------------------------------------------------------------- write failures

#: The ``errno`` of a write that fails for lack of room or rights, what it says and its fix.
WRITE_FAILURES = {
    errno.ENOSPC: ("no space left on device", "free space or choose another --out"),
    errno.EDQUOT: ("disk quota exceeded", "free space or choose another --out"),
    errno.EFBIG: ("file too large (the file system's or the process's size limit)",
                  "choose another --out or raise the limit (ulimit -f)"),
    errno.EROFS: ("read-only file system", "choose a writable --out"),
    errno.EACCES: ("permission denied", "choose a folder you may write to as --out"),
    errno.EPERM: ("operation not permitted", "choose a folder you may write to as --out"),
    errno.ENOENT: ("no folder can be made there (a file system such as /proc)",
                   "choose a folder you may write to as --out"),
}


@contextlib.contextmanager
def writing(path):
    """Name ``path`` (the file being written, by its final name) on a :data:`WRITE_FAILURES`
    error raised in the block: a full disk's ``write()`` names no file, a temporary file's
    ``open()`` names the temporary one."""
    try:
        yield
    except OSError as exc:
        if exc.errno in WRITE_FAILURES and not isinstance(exc, OutputWriteError):
            exc.filename = os.fspath(path)
        raise


_outer = threading.local()
#: The errors of :data:`WRITE_FAILURES` that a file read raises too: converted only for files
#: in the output folder.
_RIGHTS = {errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOENT}  # also what a read outside out raises


def _within(name, folder) -> bool:
    """Whether the path ``name`` is ``folder`` or lies inside it."""
    rel = os.path.relpath(os.path.abspath(name), os.path.abspath(folder))
    return rel == os.curdir or not (rel == os.pardir or rel.startswith(os.pardir + os.sep))


@contextlib.contextmanager
def write_failures(folder, staged=None):
    """Turn a :data:`WRITE_FAILURES` error raised in the block into one
    :class:`~quatform.errors.OutputWriteError` line naming ``folder`` and the file being written
    (``no space left on device writing out/x/run.mcap in out/x: free space or choose another
    --out``). ``staged``: the temporary folder the block writes in place of ``folder``
    (:func:`staged_dir`), whose files are named by their final path. Nested blocks leave the
    conversion to the outermost, which names the user's folder."""
    depth = getattr(_outer, "depth", 0)
    _outer.depth = depth + 1
    try:
        yield
    except OSError as exc:
        why = WRITE_FAILURES.get(exc.errno)
        if why is None or isinstance(exc, OutputWriteError):
            raise
        name = exc.filename if isinstance(exc.filename, (str, os.PathLike)) else None
        inside = name is None or _within(name, folder)
        if name is not None and staged is not None and _within(name, staged):
            rel = os.path.relpath(os.path.abspath(name), os.path.abspath(staged))
            name = os.fspath(folder) if rel == os.curdir else os.path.join(os.fspath(folder), rel)
            inside = True
        if not inside and exc.errno in _RIGHTS:  # a file the run reads, not one it writes
            raise
        if depth:  # an enclosing block names its own folder
            exc.filename = name
            raise
        file = f"writing {name}" if name is not None else "writing a file"
        err = OutputWriteError(f"{why[0]} {file} in {os.fspath(folder)}: {why[1]}")
        err.errno = exc.errno
        raise err from None
    finally:
        _outer.depth = depth


# --------------------------------------------------------------------------- atomic files

@contextlib.contextmanager
def atomic_file(path, mode: str = "wb"):
    """Open a temporary sibling of ``path`` for writing (``mode``: ``"wb"``, or ``"w"``: UTF-8
    text, no newline translation) and rename it into place when the block ends.

    A reader (or a run cut off half-way) sees the old file or the whole new one, never a
    truncated one; the temporary file (``.NAME.tmp-PID``, hidden) is removed on any error,
    KeyboardInterrupt included.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    text = "b" not in mode
    try:
        with writing(path), open(tmp, mode, **({"encoding": "utf-8", "newline": ""} if text else {})) as f:
            yield f
        with writing(path):
            os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def remove_dead_temporaries(folder, stem: str = "*") -> None:
    """Remove the temporary files :func:`atomic_file` left in ``folder`` for files named
    ``stem`` (a glob) by processes no longer running (a run killed with no clean-up)."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    for p in folder.glob(f".{stem}.tmp-*"):
        pid = p.name.rsplit("-", 1)[-1]
        if pid.isdigit() and int(pid) != os.getpid() and not _pid_alive(int(pid)):
            with contextlib.suppress(OSError):
                p.unlink()


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through :func:`atomic_file`."""
    with atomic_file(path) as f:
        f.write(data)
    return Path(path)


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
    tmp = parent / f".{final.name}.partial-{os.getpid()}"
    with write_failures(out, tmp):
        yield from _staged(out, final, parent, tmp)


def _staged(out: Path, final: Path, parent: Path, tmp: Path):
    """The body of :func:`staged_dir` (its write failures made one line there)."""
    made = []
    for p in reversed([parent, *parent.parents]):
        if not p.exists():
            made.append(p)
    parent.mkdir(parents=True, exist_ok=True)
    _remove_stale(parent, final.name)
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
