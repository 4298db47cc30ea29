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


class PhotoOrderError(GeometryError):
    """A strip's photos are listed against the flight: the rays of most of its
    pairs meet behind the photos.

    Attributes
    ----------
    n_wrong, n_pairs : int
        Pairs whose rays meet behind the photos, and all pairs of the strip.
    strip : str or None
        The strip of a block, when known.
    """

    def __init__(
        self, message: str, *, n_wrong: int = 0, n_pairs: int = 0, strip: str | None = None
    ) -> None:
        super().__init__(message)
        self.n_wrong, self.n_pairs, self.strip = n_wrong, n_pairs, strip


class HeightUnitError(GeometryError):
    """The control heights are in another unit than the plan control (feet or
    decimetres with X, Y in metres): the strip scaled to the plan control
    sees them change by the unit's factor
    (:func:`strip_aerotri.ground.height_units.height_unit_problems`).

    Attributes
    ----------
    detail : str
        The message without the control's name (``"control: "`` before it).
    """

    def __init__(self, name: str, detail: str | None = None) -> None:
        # one argument: the whole message (as ``type(exc)(message)`` rewraps it)
        super().__init__(name if detail is None else f"{name}: {detail}")
        self.detail = name if detail is None else detail


class FlightAxisError(GeometryError):
    """Image x does not point along the flight: the photos of a pair move
    along another image axis.

    Attributes
    ----------
    pair : str
        The pair that shows it.
    along : str
        The axis of the image coordinates as given to the orientation that
        the flight runs along (``"+y"``, ``"-y"``, ``"-x"``), or "" when unknown.
    strip : str or None
        The strip of a block, when known.
    """

    def __init__(
        self, message: str, *, pair: str = "", along: str = "", strip: str | None = None
    ) -> None:
        super().__init__(message)
        self.pair, self.along, self.strip = pair, along, strip


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
    "FlightAxisError",
    "GeometryError",
    "HeightUnitError",
    "MissingExtraError",
    "PhotoOrderError",
    "StripAerotriError",
    "StripAerotriWarning",
]
