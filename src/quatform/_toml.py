"""Reading the package's TOML files: built-in ones by name, or a user's by path (private).

Below every layer (like :mod:`quatform.errors`): the scenario loader (sim) and the plan-spec
loader (planning) resolve names and report unreadable files the same way.
"""

from __future__ import annotations

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


def read_toml(name_or_file, builtin: dict[str, Path], what: str) -> tuple[dict, Path]:
    """The parsed TOML of a built-in ``what`` (e.g. "scenario") by name, or of a file by path.

    An unknown name lists the built-in ones; a file that is not TOML is named with the
    parser's message. Both raise :class:`~quatform.errors.InvalidInputError`.
    """
    p = Path(name_or_file)
    if str(name_or_file) in builtin:
        p = builtin[str(name_or_file)]
    elif not (p.suffix == ".toml" or p.exists()):
        raise InvalidInputError(
            f"unknown {what} {str(name_or_file)!r}; built-in: {', '.join(sorted(builtin))}, "
            "or give the path of a .toml file"
        )
    try:
        return tomllib.loads(p.read_text()), p
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInputError(f"{p}: not valid TOML: {exc}") from None
