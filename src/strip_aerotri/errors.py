"""Exceptions and warnings of strip_aerotri.

Every domain failure derives from :class:`StripAerotriError`; the command line
turns these into one line on stderr and exit code 1.  Classes also inherit a
builtin where that helps callers who catch builtins.
"""

from __future__ import annotations


class StripAerotriError(Exception):
    """Base class of every error raised by strip_aerotri for a bad project or an
    adjustment that cannot be done."""


class ConfigError(StripAerotriError, ValueError):
    """The project file or an input CSV breaks the contract (file, line, key named)."""


class GeometryError(StripAerotriError, ValueError):
    """Too few or degenerate points for a step (pair, model, control, polynomial)."""


class ConvergenceError(StripAerotriError, RuntimeError):
    """An iterative solution did not converge."""


class MissingExtraError(StripAerotriError, ImportError):
    """An optional feature needs a package that is not installed; the message
    names the extra to install (``pip install 'strip_aerotri[gpkg]'``)."""


class StripAerotriWarning(UserWarning):
    """A result that is valid but weak or degenerate (gimbal lock, near-singular normals)."""


__all__ = [
    "ConfigError",
    "ConvergenceError",
    "GeometryError",
    "MissingExtraError",
    "StripAerotriError",
    "StripAerotriWarning",
]
