"""The values of the string options (:mod:`.options` defines the options, their
defaults and rules, and exports these): each an :class:`OptionEnum` whose
members compare equal to their value (``Route.PROJECTED == "projected"``)
and are created from a member or a case-insensitive string, with errors that
list the valid values.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Self

__all__ = [
    "BlunderAction",
    "Construction",
    "DistortionModel",
    "DistortionUnits",
    "FiducialTransform",
    "FlightDirection",
    "ImageUnits",
    "IntersectionMethod",
    "ModelFormation",
    "OptionEnum",
    "Refine",
    "RelativeOrientationMethod",
    "Route",
    "ScaleTransfer",
    "Weights",
]


class OptionEnum(StrEnum):
    """A string option, matched case-insensitively."""

    @classmethod
    def create(cls, value: object) -> Self:
        """Member for ``value`` (a member or a case-insensitive string).

        Raises
        ------
        ValueError
            If ``value`` names no member; the message lists the valid values.
        """
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            member = cls._missing_(value)
            if member is not None:
                return member
        raise ValueError(f"invalid value {value!r}; valid values: {cls.valid_values()}")

    @classmethod
    def _missing_(cls, value: object) -> Self | None:
        if isinstance(value, str):
            wanted = value.strip().lower()
            for member in cls:
                if member.value == wanted:
                    return member
        return None

    @classmethod
    def valid_values(cls) -> str:
        """The valid values as ``"a", "b"`` for messages."""
        return ", ".join(f'"{m.value}"' for m in cls)


class RelativeOrientationMethod(OptionEnum):
    """Parametrisation of the dependent relative orientation (method.md §3)."""

    DEPENDENT = "dependent"
    """Base components b_y, b_z and Schut's a, b, c of the right photo (J(5)-(10))."""
    BASE = "base"
    """B's rotation-only elements alpha'1, chi'1, alpha'2, omega'2, chi'2 (B(125)-(135))."""


class IntersectionMethod(OptionEnum):
    """Model point formation (method.md §4)."""

    MIDPOINT = "midpoint"
    """Middle of the shortest y-parallel vector between the rays (J(11)-(12))."""
    NORMAL = "normal"
    """Normal-case reduction to horizontal photos (B(137)-(138))."""


class ScaleTransfer(OptionEnum):
    """Scaling of each new model to the previous one (method.md §5)."""

    Z = "z"
    """Least squares on the Z components of the tie points (J(15))."""
    DISTANCE = "distance"
    """Ratio of distances from the common projection centre (B(139)-(140))."""


class ModelFormation(OptionEnum):
    """How a strip is formed from its pairs (``[adjustment] models``)."""

    DEPENDENT = "dependent"
    """J's chain: each pair oriented to the previous photo, scale transferred
    on the tie points (partially dependent models)."""
    INDEPENDENT = "independent"
    """R4 2.2: each pair oriented on its own (B's base system, both photos
    rotate), its model joined to the strip by a 3D similarity on its tie
    points and the shared projection centre; doubly determined points
    compared and averaged."""


class Route(OptionEnum):
    """How the strip reaches the ground system (method.md §6.2)."""

    GEOCENTRIC = "geocentric"
    """Intermediate local-tangent system at the control centroid, B(142)-(152)."""
    PROJECTED = "projected"
    """Similarity directly to the map grid with the earth-curvature term B(153) (J)."""


class Construction(OptionEnum):
    """How the strip goes to the ground (``[adjustment] block``, method.md §6A)."""

    MODELS = "models"
    """Every model its own similarity, all at once, tied on common points and
    projection centres (R4 §3, PAT-M)."""
    STRIPS = "strips"
    """The strip as one body: J's similarity and deformation polynomials (J(16)-(18))."""


class Refine(OptionEnum):
    """Optional final step (``[adjustment] refine``)."""

    NONE = "none"
    BUNDLE = "bundle"
    """A rigorous bundle adjustment started from the strip solution."""


class BlunderAction(OptionEnum):
    """What the gross-error tests do (``[blunders] action``)."""

    REJECT = "reject"
    """Reject the worst failing observation and solve again, until none fails."""
    REPORT = "report"
    """Compute the tests and report what would be rejected; change nothing."""
    OFF = "off"
    """No tests."""


class ImageUnits(OptionEnum):
    """Unit of the measured image coordinates (``[images] units``)."""

    MM = "mm"
    """Millimetres, x right and y up (a comparator or a reduced file)."""
    PIXEL = "pixel"
    """Pixel column and row of a digital image, rows growing downwards."""


class FlightDirection(OptionEnum):
    """The sensor axis that points along the flight (``[images] flight_direction``)."""

    PLUS_X = "+x"
    MINUS_X = "-x"
    PLUS_Y = "+y"
    MINUS_Y = "-y"


class DistortionUnits(OptionEnum):
    """In which units the radius r of the distortion polynomials is taken."""

    MM = "mm"
    """r in millimetres: k1 in mm^-2, k2 in mm^-4, k3 in mm^-6, p1, p2 in mm^-1."""
    NORMALIZED = "normalized"
    """r divided by the principal distance c (dimensionless coefficients, the
    form of OpenCV and Agisoft)."""


class DistortionModel(OptionEnum):
    """Direction in which the Brown polynomials are applied."""

    CORRECTION = "correction"
    """Brown (1971): corrected = measured + Δ(measured)."""
    PROJECTION = "projection"
    """OpenCV / Agisoft: distorted = ideal + Δ(ideal); inverted by iteration."""


class FiducialTransform(OptionEnum):
    """Transformation from comparator to calibrated fiducial coordinates."""

    SIMILARITY = "similarity"
    """4 parameters: shift, rotation, one scale (2 marks at least)."""
    AFFINE = "affine"
    """6 parameters: shift, rotation, two scales, non-orthogonality (3 marks at least)."""


class Weights(OptionEnum):
    """The observation weights of the bundle refinement (``[adjustment] weights``)."""

    GIVEN = "given"
    """The stated sigmas of the image coordinates, control, GNSS and IMU."""
    ESTIMATED = "estimated"
    """Each group's sigma estimated from its residuals (variance components,
    :mod:`strip_aerotri.bundle.variance`)."""
