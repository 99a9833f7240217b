"""Registries that fill themselves when a type is defined (below every layer).

A :class:`Registry` is a ``dict`` by key (so ``REG[key]``, ``key in REG`` and iteration work
as on any mapping) whose entries are added by the code that defines them: a base class's
``__init_subclass__`` (``FORMATION_TYPES``, ``ROBOT_MODELS``, ``KINDS``, ``WRITERS``), or one
call beside the definition (``FIGURES.add(...)``, ``PARAMETERS.add(...)``,
``@POSE_READERS.register("pose")``). No table lists the entries by hand: a new one is one
file that defines it, and the contract tests read the registries.

A key given twice to different entries is one line naming both (a redefinition of the same
entry, a module imported again, replaces it).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from .errors import InvalidInputError

__all__ = ["Registry", "RegistryView", "import_package_modules"]


def _origin(value) -> tuple:
    """Where ``value`` was defined: ``(module, qualified name)`` of it or of its type."""
    obj = value if isinstance(value, type) or callable(value) and hasattr(value, "__qualname__") else type(value)
    return getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)


class Registry(dict):
    """Entries by key, added where they are defined (see the module docstring).

    Parameters
    ----------
    what : str
        What an entry is, in words (messages: ``"formation"``, ``"robot model"``).
    """

    def __init__(self, what: str, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.what = what

    def add(self, key: str, value):
        """Register ``value`` under ``key`` and return it.

        Raises
        ------
        InvalidInputError
            ``key`` holds an entry defined elsewhere (another module or name).
        """
        old = self.get(key)
        if old is not None and old is not value and _origin(old) != _origin(value):
            module, name = _origin(old)
            raise InvalidInputError(f"{self.what} {key!r} is registered twice: by {name} ({module}) and by "
                                    f"{_origin(value)[1]} ({_origin(value)[0]}); give the new one another name")
        self[key] = value
        return value

    def register(self, key: str) -> Callable:
        """The decorator form of :meth:`add`: ``@REG.register("name")`` above a class or function."""
        def decorate(value):
            return self.add(key, value)

        return decorate


class RegistryView(Mapping):
    """A read-only mapping derived from registries, computed on each use (so it follows them).

    Parameters
    ----------
    build : callable ``() -> dict``
        The mapping as it is now (e.g. the team classes among the formation types).
    what : str
        Its name, for ``repr``.
    """

    def __init__(self, build: Callable[[], dict], what: str):
        self._build = build
        self.what = what

    def __getitem__(self, key):
        return self._build()[key]

    def __iter__(self):
        return iter(self._build())

    def __len__(self):
        return len(self._build())

    def __repr__(self):
        return f"{self.what}({', '.join(map(str, self._build()))})"


def import_package_modules(package: str, path, skip: tuple = (), suffix: str = "") -> None:
    """Import every module of ``package`` (its ``__path__`` ``path``) whose name ends with
    ``suffix``, but ``skip``, so the entries its modules define register themselves (a new
    module needs no import list)."""
    import importlib
    import pkgutil

    for info in sorted(pkgutil.iter_modules(path), key=lambda i: i.name):
        if info.name not in skip and not info.name.startswith("_") and info.name.endswith(suffix):
            importlib.import_module(f"{package}.{info.name}")
