"""strip_aerotri: analytical strip aerotriangulation by partially dependent models."""

from __future__ import annotations

from .errors import (
    ConfigError,
    ConvergenceError,
    GeometryError,
    StripAerotriError,
    StripAerotriWarning,
)

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "ConvergenceError",
    "GeometryError",
    "StripAerotriError",
    "StripAerotriWarning",
    "__version__",
]
