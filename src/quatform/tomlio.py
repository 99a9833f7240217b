"""Reading the package's TOML files: built-in ones by name, or a user's by path (internal: shared by quatform's layers, not part of the user API).

Below every layer (like :mod:`quatform.errors`): the scenario loader (sim) and the plan-spec
loader (planning) resolve names and report unreadable files the same way.
"""

from __future__ import annotations

import stat
import sys
from importlib import resources
from pathlib import Path

from .errors import InvalidInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["builtin_files", "read_toml"]


def builtin_files(folder: str) -> dict[str, Path]:
    """The ``*.toml`` files shipped in ``quatform/<folder>``, by name (file stem)."""
    root = resources.files("quatform") / folder
    return {Path(p.name).stem: Path(str(p)) for p in root.iterdir() if p.name.endswith(".toml")}


#: Largest TOML file read (scenario and plan files are a few kB; a bigger one is a mistake).
MAX_TOML_BYTES = 1_000_000


def _unknown(name, builtin, what) -> InvalidInputError:
    return InvalidInputError(
        f"unknown {what} {str(name)!r}; built-in: {', '.join(sorted(builtin))}, or give the path of a .toml file"
    )


def _read_text(p: Path, what: str) -> str:
    """The UTF-8 text of the regular file ``p``, at most :data:`MAX_TOML_BYTES` (one-line errors)."""
    fix = f"give a {what} .toml file"
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InvalidInputError(f"{p}: no such file; {fix} that exists, or a built-in name") from None
    except OSError as exc:
        raise InvalidInputError(f"{p}: cannot read it ({exc.strerror or exc}); {fix}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InvalidInputError(f"{p}: is a folder, not a file; {fix}")
    if not stat.S_ISREG(st.st_mode):
        raise InvalidInputError(f"{p}: is not a regular file (a device, pipe or socket); {fix}")
    if st.st_size > MAX_TOML_BYTES:
        raise InvalidInputError(f"{p}: {st.st_size:,} bytes is too large for a {what} file (at most "
                                f"{MAX_TOML_BYTES:,}); {fix} (a few kB)")
    try:
        with open(p, "rb") as f:
            raw = f.read(MAX_TOML_BYTES + 1)
    except OSError as exc:
        raise InvalidInputError(f"{p}: cannot read it ({exc.strerror or exc}); check its permissions or {fix}") from None
    if len(raw) > MAX_TOML_BYTES:  # grew since stat
        raise InvalidInputError(f"{p}: too large for a {what} file (at most {MAX_TOML_BYTES:,} bytes); {fix}")
    try:
        return raw.decode("utf-8-sig")  # a byte-order mark some editors write is no TOML statement
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InvalidInputError(f"{p}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line}); save the "
                                "file as UTF-8 (TOML files are UTF-8)") from None


def read_toml(name_or_file, builtin: dict[str, Path], what: str) -> tuple[dict, Path]:
    """The parsed TOML of a built-in ``what`` (e.g. "scenario") by name, or of a file by path.

    An unknown name lists the built-in ones; a missing, unreadable, non-UTF-8, oversized
    (over :data:`MAX_TOML_BYTES`) or too deeply nested file, or one that is not TOML, is
    named with the fix. All raise :class:`~quatform.errors.InvalidInputError` (one line).
    """
    name = str(name_or_file)
    if name in builtin:
        p = builtin[name]
    else:
        if not name or "\x00" in name:
            raise _unknown(name, builtin, what)
        p = Path(name_or_file)
        try:
            exists = p.exists()
        except (OSError, ValueError):  # e.g. a name too long for the file system
            exists = False
        if not (p.suffix == ".toml" or exists):
            raise _unknown(name, builtin, what)
    text_ = _read_text(p, what)
    try:
        return tomllib.loads(text_), p
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInputError(f"{p}: not valid TOML: {exc}") from None
    except RecursionError:
        raise InvalidInputError(f"{p}: arrays or tables nested too deeply to read; a {what} file needs a few "
                                "levels at most, flatten it") from None
