"""Exception types that quatform raises for bad input.

This module sits below every layer: all of quatform imports it, it imports nothing of
quatform. Every exception names the offending value and says how to fix it.
Input errors also derive from :class:`ValueError`, so code written against the standard
library's conventions catches them too.
"""

from __future__ import annotations

__all__ = [
    "QuatformError",
    "InvalidInputError",
    "ShapeError",
    "NonFiniteError",
    "NonUnitError",
    "DegenerateInputError",
    "NotARotationError",
    "UnreachableError",
    "ConvergenceError",
    "ResourceLimitError",
    "MissingDependencyError",
    "OutputWriteError",
    "Terminated",
]


#: Longest message an error keeps; the rest is cut (a 2e5-element array quoted in a message
#: would otherwise print 600 kB).
MAX_MESSAGE_CHARS = 500


class QuatformError(Exception):
    """Base class of every error quatform raises on purpose.

    Its message is one line (newlines and runs of spaces collapse to one space) of at most
    :data:`MAX_MESSAGE_CHARS` characters.
    """

    def __init__(self, *args):
        if len(args) == 1 and isinstance(args[0], str):
            msg = " ".join(args[0].split())
            if len(msg) > MAX_MESSAGE_CHARS:
                msg = msg[: MAX_MESSAGE_CHARS - 5] + " ..."
            args = (msg,)
        super().__init__(*args)


class InvalidInputError(QuatformError, ValueError):
    """An argument is not acceptable: wrong shape, not finite, out of its domain."""


class ShapeError(InvalidInputError):
    """An array does not have the trailing shape a function needs (e.g. ``(..., 4)``)."""


class NonFiniteError(InvalidInputError):
    """An array holds NaN or infinity."""


class NonUnitError(InvalidInputError):
    """A quaternion or dual quaternion that must be unit is not, beyond the tolerance."""


class DegenerateInputError(InvalidInputError):
    """An input sits where the requested quantity is undefined (zero quaternion, zero axis)."""


class NotARotationError(InvalidInputError):
    """A matrix that must be a rotation (orthonormal, det = +1) is not, beyond the tolerance."""


class UnreachableError(InvalidInputError):
    """A state or reference that the robots or the chosen description cannot reach."""


class ConvergenceError(QuatformError, RuntimeError):
    """A numerical solver (e.g. a geodesic boundary-value problem) found no acceptable solution."""


class ResourceLimitError(InvalidInputError):
    """The requested work cannot fit in this machine's memory or the time budget (estimated
    up front; the message names the key that sets the amount of work and the limit)."""


class MissingDependencyError(QuatformError, ImportError):
    """An optional package that the requested feature needs is not installed (the message
    names the ``pip install`` command)."""


class OutputWriteError(QuatformError, OSError):
    """An output file could not be written: the disk is full, a quota is reached, the folder is
    read-only or not the user's (the message names the folder, the file and the fix; ``errno``
    is the system's). Nothing half-written is left under the file's name."""


class Terminated(KeyboardInterrupt):
    """SIGTERM asked the process to stop: raised where a command stops on it as on Ctrl-C (the
    ROS 2 bridge's node), so the same clean-up runs; the command line says ``terminated
    (SIGTERM)`` and exits with 143 (128 + 15, as a shell reports a process ended by SIGTERM)."""
