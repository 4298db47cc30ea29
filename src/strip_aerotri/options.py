"""Every option of the package, with its one default (method.md §3-8).

The project file's ``[adjustment]``, ``[images]``, ``[blunders]`` and
``[report]`` tables, the library calls and the command line all use these
enums and dataclasses; the key list of the project file
(:data:`strip_aerotri.project.schema.PROJECT_KEYS`) takes its defaults from
here, and the tests check that ``docs/project-file.md`` shows the same.

String options are :class:`OptionEnum` members: they compare equal to their
value (``Route.PROJECTED == "projected"``) and are created from a member or a
case-insensitive string.  This module imports nothing heavy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Literal, Self

import numpy as np

from ._stats import chi_critical_value, critical_value
from ._typing import BoolArray, FloatArray

if TYPE_CHECKING:
    from .observations import ImageObservations

__all__ = [
    "SELF_CALIBRATION_CHOICES",
    "SELF_CALIBRATION_PARAMETERS",
    "DEFAULT_ALPHA",
    "DEFAULT_DIFFERENCE_TOLERANCE",
    "DEFAULT_GNSS_SIGMA_XY_M",
    "DEFAULT_GNSS_SIGMA_Z_M",
    "DEFAULT_IMAGE_SIGMA_MM",
    "DEFAULT_IMU_SIGMA_DEG",
    "DEFAULT_LINE_WEIGHT",
    "DEFAULT_MAX_FRACTION",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_MIN_BASE_TO_HEIGHT",
    "DEFAULT_PHOTO_STEP",
    "DEFAULT_POLYNOMIAL",
    "DEFAULT_SCALE_TOLERANCE",
    "DEFAULT_SECTIONS",
    "DEFAULT_SIGMA_H_M",
    "DEFAULT_SIGMA_XY_M",
    "STAGES",
    "AdjustmentOptions",
    "BlunderAction",
    "BlunderOptions",
    "Construction",
    "DistortionModel",
    "DistortionUnits",
    "FiducialTransform",
    "FlightDirection",
    "GroundOptions",
    "ImageOptions",
    "ImageUnits",
    "IntersectionMethod",
    "ModelFormation",
    "OptionEnum",
    "Refine",
    "SelfCalibration",
    "RelativeOrientationMethod",
    "ReportOptions",
    "Route",
    "ScaleTransfer",
    "StripOptions",
    "check_sections",
]

# --------------------------------------------------------------------------- defaults

#: Largest number of iterations of every iterative solution (relative
#: orientation, resection, similarity, simultaneous transformation, bundle).
DEFAULT_MAX_ITERATIONS = 50
#: Convergence of the relative orientation: largest parameter update (rad or
#: base units).
DEFAULT_RO_TOLERANCE = 1e-11
DEFAULT_IMAGE_SIGMA_MM = 0.005
DEFAULT_SIGMA_XY_M = 0.02
DEFAULT_SIGMA_H_M = 0.03
DEFAULT_LINE_WEIGHT = 100.0
#: J(16)'s polynomial type of the construction "strips".
DEFAULT_POLYNOMIAL = 3
#: The type of every strip's own polynomial in a block of independent strips
#: (``block = "strips"``): type 2 came closest to the bundle on simulated
#: film and drone blocks, type 3 over-fits strips of 8-15 photos
#: (docs/block.md).
DEFAULT_BLOCK_POLYNOMIAL = 2
DEFAULT_SECTIONS = 1
DEFAULT_PHOTO_STEP = 1
#: The Brown/Fraser parameters ``[adjustment] self_calibration`` may list
#: (method.md 6C), in their fixed order.
SELF_CALIBRATION_PARAMETERS = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1", "b2")
#: The named choices of ``[adjustment] self_calibration``.
SELF_CALIBRATION_CHOICES = ("none", "auto", "ebner12")
#: Smallest base-to-height ratio of a model for ``photo_step = "auto"``
#: (method.md §5.1).  0.3 is about the ratio of a normal-angle film camera at
#: 60 % overlap (B/H = 0.4 · 230 mm / 210 mm ≈ 0.44) reduced by a third:
#: below it the height error of a model point grows past ~3 times the plan
#: error (σ_Z / σ_XY ≈ H / B).
DEFAULT_MIN_BASE_TO_HEIGHT = 0.3
DEFAULT_GNSS_SIGMA_XY_M = 0.05
DEFAULT_GNSS_SIGMA_Z_M = 0.08
DEFAULT_IMU_SIGMA_DEG = 0.005
#: Family-wise false-alarm probability of each stage's blunder tests.
DEFAULT_ALPHA = 0.001
#: A stage that would reject more than this fraction of its observations stops.
DEFAULT_MAX_FRACTION = 0.2
#: R4 §1.7.7.1: a scale (deformation) coefficient of the fiducial fit may
#: differ from 1 by "a few units of the fourth decimal"; read as at most 5.
DEFAULT_SCALE_TOLERANCE = 5e-4
#: R4 §1.7.7.1: its x and y coefficients may differ by "a few units of the
#: fifth decimal"; read as at most 5.
DEFAULT_DIFFERENCE_TOLERANCE = 5e-5

#: The stages whose observations are tested for blunders (method.md §7).
STAGES = (
    "relative_orientation",
    "tie_points",
    "models",
    "control",
    "straight_line",
    "bundle",
    "gnss",
    "imu",
)


# --------------------------------------------------------------------------- enums


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


def check_sections(sections: object) -> int:
    """``sections`` as an int, ValueError unless it is an integer >= 1."""
    if (
        isinstance(sections, bool)
        or not isinstance(sections, int | np.integer)
        or int(sections) < 1
    ):
        raise ValueError(f"Expected sections to be an integer >= 1, got {sections!r}")
    return int(sections)


def _check_polynomial(poly: object) -> int | Literal["auto"]:
    if isinstance(poly, str):
        if poly.strip().lower() != "auto":
            raise ValueError(f"Expected polynomial 0, 1, 2, 3 or 'auto', got {poly!r}")
        return "auto"
    if (
        isinstance(poly, bool)
        or not isinstance(poly, int | np.integer)
        or int(poly) not in range(4)
    ):
        raise ValueError(f"Expected polynomial 0, 1, 2, 3 or 'auto', got {poly!r}")
    return int(poly)


def _check_iterations(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or int(value) < 1:
        raise ValueError(f"Expected max_iterations to be an integer >= 1, got {value!r}")
    return int(value)


# --------------------------------------------------------------------------- stages


@dataclass(frozen=True)
class StripOptions:
    """Choices of strip formation (each named after its source formula).

    Attributes
    ----------
    relative_orientation : RelativeOrientationMethod
        J(5)-(10) or B(125)-(136).
    intersection : IntersectionMethod
        J(12) or B(138).
    scale_transfer : ScaleTransfer
        J(15) or B(139)-(140).
    first_rotation : array_like, shape (3, 3), optional
        Image -> strip rotation of the first photo (identity: J).
    first_position : array_like, shape (3,), optional
        Projection centre of the first photo (origin: J).
    first_base_length : float, optional
        Length |b| of the first base (B's base length B, B(135)).  None (the
        default) is J's choice: the first base's component along the first
        photo's image x axis is 1 (``b_x = 1`` with ``R_1 = I``).
    max_iterations, tolerance
        Of the relative orientation.
    models : ModelFormation
        J's chain of dependent models (default) or independent models joined
        by 3D similarities (R4 2.2; the relative orientation is then B's
        base-system formulation whatever ``relative_orientation`` says).
    allow_breaks : bool
        A model that shares no tie point with the one before (no point on all
        three photos) is an error (False, J's chain), or a *break* (True): its
        scale cannot be transferred, it goes on with the same scale (equal
        bases), and a ground stage that transforms every model on its own
        (construction "models") takes the models after it from their own
        control.
    """

    relative_orientation: RelativeOrientationMethod = RelativeOrientationMethod.DEPENDENT
    intersection: IntersectionMethod = IntersectionMethod.MIDPOINT
    scale_transfer: ScaleTransfer = ScaleTransfer.Z
    first_rotation: FloatArray | None = None
    first_position: FloatArray | None = None
    first_base_length: float | None = None
    max_iterations: int = DEFAULT_MAX_ITERATIONS
    tolerance: float = DEFAULT_RO_TOLERANCE
    allow_breaks: bool = False
    models: ModelFormation = ModelFormation.DEPENDENT

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "relative_orientation",
            RelativeOrientationMethod.create(self.relative_orientation),
        )
        object.__setattr__(self, "models", ModelFormation.create(self.models))
        object.__setattr__(self, "intersection", IntersectionMethod.create(self.intersection))
        object.__setattr__(self, "scale_transfer", ScaleTransfer.create(self.scale_transfer))
        object.__setattr__(self, "max_iterations", _check_iterations(self.max_iterations))
        if self.first_base_length is not None and not (
            np.isfinite(self.first_base_length) and self.first_base_length > 0
        ):
            raise ValueError(f"Expected first_base_length > 0, got {self.first_base_length!r}")


@dataclass(frozen=True)
class GroundOptions:
    """Choices of the ground stage.

    Attributes
    ----------
    route : Route, optional
        Default: geocentric, projected when the CRS is "local".
    polynomial : int 0..3 or "auto", optional
        J(16) type of the deformation polynomials (0: similarity only) of
        the construction ``"strips"``; :data:`DEFAULT_POLYNOMIAL` when not
        given.
    sections : int >= 1
        Sections of equal length along the strip over which the polynomials
        become splines joined without steps (1: J(16)'s single polynomial;
        see :mod:`strip_aerotri.geometry.deformation`).  A long strip bends
        beyond one cubic (its error grows as a random walk along the chain);
        each section needs control of every coordinate.
    construction : Construction, optional
        ``"models"``: every model transformed at once (the default);
        ``"strips"``: the strip as one body with J's polynomials, the
        default when ``polynomial`` or ``sections`` is given.
    max_iterations : int
        Of the similarity and of the simultaneous transformation.
    """

    route: Route | None = None
    polynomial: int | Literal["auto"] | None = None
    sections: int = DEFAULT_SECTIONS
    construction: Construction | None = None
    max_iterations: int = DEFAULT_MAX_ITERATIONS

    def __post_init__(self) -> None:
        if self.route is not None:
            object.__setattr__(self, "route", Route.create(self.route))
        construction = self.construction
        if construction is None:
            named = self.polynomial is not None or self.sections != DEFAULT_SECTIONS
            construction = Construction.STRIPS if named else Construction.MODELS
        construction = Construction.create(construction)
        object.__setattr__(self, "construction", construction)
        if construction is Construction.MODELS and (
            self.polynomial not in (None, 0) or self.sections != DEFAULT_SECTIONS
        ):
            raise ValueError(
                "Expected no polynomial and no sections with construction 'models' (every "
                "model has its own similarity); use construction 'strips' for J's polynomials"
            )
        poly = DEFAULT_POLYNOMIAL if self.polynomial is None else self.polynomial
        poly = _check_polynomial(poly)
        object.__setattr__(self, "polynomial", poly)
        sections = check_sections(self.sections)
        if sections > 1 and poly == 0:
            raise ValueError("Expected polynomial 1, 2, 3 or 'auto' with sections > 1, got 0")
        object.__setattr__(self, "sections", sections)
        object.__setattr__(self, "max_iterations", _check_iterations(self.max_iterations))


@dataclass(frozen=True)
class BlunderOptions:
    """How gross errors are handled (``[blunders]``, method.md §7).

    Attributes
    ----------
    action : BlunderAction
        ``reject``: reject and re-solve (default); ``report``: compute the
        tests and report what would be rejected, change nothing; ``off``: no
        tests.
    alpha : float
        Family-wise false-alarm probability per stage (Bonferroni over the
        stage's tests).
    critical_values : dict
        Stage name (one of :data:`STAGES`) -> critical |w| overriding
        ``alpha`` for that stage.
    max_fraction : float
        Stop with an error when a stage would reject more than this fraction
        of its observations: the solution could not be trusted.
    exclude_points : tuple of str
        Point ids left out of every stage.
    exclude_observations : tuple of (photo, point)
        Image observations left out.
    """

    action: BlunderAction = BlunderAction.REJECT
    alpha: float = DEFAULT_ALPHA
    critical_values: dict[str, float] = field(default_factory=dict)
    max_fraction: float = DEFAULT_MAX_FRACTION
    exclude_points: tuple[str, ...] = ()
    exclude_observations: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "action", BlunderAction.create(self.action))
        except ValueError:
            raise ValueError(
                f"Expected action 'reject', 'report' or 'off', got {self.action!r}"
            ) from None
        if not 0.0 < float(self.alpha) < 1.0:
            raise ValueError(f"Expected 0 < alpha < 1, got {self.alpha!r}")
        for stage, value in self.critical_values.items():
            if stage not in STAGES:
                raise ValueError(f"Unknown stage {stage!r}; valid: {', '.join(STAGES)}")
            if not float(value) > 0:
                raise ValueError(f"Critical value of {stage!r} must be > 0, got {value!r}")
        if not 0.0 < float(self.max_fraction) <= 1.0:
            raise ValueError(f"Expected 0 < max_fraction <= 1, got {self.max_fraction!r}")

    @property
    def testing(self) -> bool:
        """Whether the tests are computed at all."""
        return self.action is not BlunderAction.OFF

    @property
    def rejecting(self) -> bool:
        """Whether failing observations are rejected."""
        return self.action is BlunderAction.REJECT

    def excluded(self, observations: ImageObservations) -> tuple[BoolArray, BoolArray]:
        """The user's exclusions as masks: points (P,) of ``exclude_points``
        and observations (K,) of those points or of ``exclude_observations``
        (ids not in the observations are ignored)."""
        points = np.zeros(observations.n_points, dtype=bool)
        if self.exclude_points:
            names = np.asarray(observations.point_ids)
            points = np.isin(names, list(self.exclude_points))
        drop = points[observations.point]
        if self.exclude_observations:
            photo_of = {pid: i for i, pid in enumerate(observations.photo_ids)}
            point_of = {pid: i for i, pid in enumerate(observations.point_ids)}
            n_pts = max(observations.n_points, 1)
            wanted = [
                photo_of[ph] * n_pts + point_of[pt]
                for ph, pt in self.exclude_observations
                if ph in photo_of and pt in point_of
            ]
            keys = observations.photo.astype(np.int64) * n_pts + observations.point
            drop |= np.isin(keys, wanted)
        return points, drop

    def critical(self, stage: str, n_tests: int, dof: int = 1) -> float:
        """Critical |w| of a stage with n tests; for a test of ``dof``
        components at once (``w = sqrt(vᵀ P v)``, chi-square) the square root
        of the chi-square quantile."""
        if stage in self.critical_values:
            return float(self.critical_values[stage])
        if dof == 1:
            return critical_value(n_tests, self.alpha)
        return chi_critical_value(n_tests, self.alpha, dof)


# --------------------------------------------------------------------------- project


@dataclass(frozen=True)
class SelfCalibration:
    """How the bundle calibrates the camera (``[adjustment] self_calibration``).

    Attributes
    ----------
    choice : str or tuple of str
        ``"auto"``, ``"ebner12"`` or Brown/Fraser names
        (:data:`strip_aerotri.options.SELF_CALIBRATION_PARAMETERS`).
    flight_direction : FlightDirection
        The sensor axis along the flight (``[images] flight_direction``): the
        corrections are defined in the sensor axes.
    """

    choice: str | tuple[str, ...]
    flight_direction: FlightDirection = FlightDirection.PLUS_X

    def __post_init__(self) -> None:
        object.__setattr__(self, "flight_direction", FlightDirection(self.flight_direction))
        if isinstance(self.choice, str):
            if self.choice not in ("auto", "ebner12"):
                raise ValueError(f'Expected "auto", "ebner12" or names, got {self.choice!r}')
        elif not self.choice or any(n not in SELF_CALIBRATION_PARAMETERS for n in self.choice):
            raise ValueError(
                f"Expected names from {SELF_CALIBRATION_PARAMETERS}, got {self.choice!r}"
            )

    @property
    def family(self) -> str:
        """``"ebner"`` for ebner12, else ``"brown"``."""
        return "ebner" if self.choice == "ebner12" else "brown"


@dataclass(frozen=True)
class AdjustmentOptions:
    """Method variants chosen in ``[adjustment]`` (method.md §3-6).

    Attributes
    ----------
    route : Route
    polynomial : int (0..3) or ``"auto"``
    sections : int
        Sections along the strip of the deformation polynomials (1: J(16)).
    block : Construction
        ``MODELS`` (every model at once) or ``STRIPS`` (J's polynomials);
        the loader resolves the default (``STRIPS`` when the project names a
        polynomial or sections).
    relative_orientation : RelativeOrientationMethod
    intersection : IntersectionMethod
    scale_transfer : ScaleTransfer
    max_iterations : int
        Of every iterative solution.
    photo_step : int or ``"auto"``
        Models on every k-th photo (:mod:`strip_aerotri.strip.densify`);
        1: every photo.
    min_base_to_height : float
        Target of ``photo_step = "auto"``.
    refine : Refine
    models : ModelFormation
        Dependent (J) or independent models (R4 2.2).
    self_calibration : str or tuple of str
        ``"none"``, ``"auto"``, ``"ebner12"`` or the Brown/Fraser parameters
        to estimate (:data:`SELF_CALIBRATION_PARAMETERS`); with ``refine =
        "bundle"`` only.
    """

    route: Route = Route.GEOCENTRIC
    polynomial: int | Literal["auto"] = DEFAULT_POLYNOMIAL
    sections: int = DEFAULT_SECTIONS
    relative_orientation: RelativeOrientationMethod = RelativeOrientationMethod.DEPENDENT
    intersection: IntersectionMethod = IntersectionMethod.MIDPOINT
    scale_transfer: ScaleTransfer = ScaleTransfer.Z
    max_iterations: int = DEFAULT_MAX_ITERATIONS
    photo_step: int | Literal["auto"] = DEFAULT_PHOTO_STEP
    min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT
    refine: Refine = Refine.NONE
    block: Construction = Construction.MODELS
    models: ModelFormation = ModelFormation.DEPENDENT
    self_calibration: str | tuple[str, ...] = "none"

    def calibration(self, flight_direction: FlightDirection | str) -> SelfCalibration | None:
        """The self-calibration asked for (None for "none")."""
        if self.self_calibration == "none":
            return None
        return SelfCalibration(self.self_calibration, FlightDirection(flight_direction))

    def strip_options(self) -> StripOptions:
        """The options of strip formation."""
        return StripOptions(
            relative_orientation=self.relative_orientation,
            intersection=self.intersection,
            scale_transfer=self.scale_transfer,
            max_iterations=self.max_iterations,
            # every model transformed on its own takes a model without tie
            # points to the one before from its own control
            allow_breaks=self.block is Construction.MODELS,
            models=self.models,
        )

    def ground_options(self) -> GroundOptions:
        """The options of the ground stage."""
        strips = self.block is Construction.STRIPS
        return GroundOptions(
            route=self.route,
            polynomial=self.polynomial if strips else None,
            sections=self.sections if strips else DEFAULT_SECTIONS,
            construction=self.block,
            max_iterations=self.max_iterations,
        )


@dataclass(frozen=True)
class ImageOptions:
    """How the measured image coordinates were given (``[images]``).

    Attributes
    ----------
    units : ImageUnits
        ``"mm"`` (x right, y up) or ``"pixel"`` (column, row; rows down).
    pixel_size_mm : float or None
    principal_point_px : ndarray, shape (2,), or None
        Column and row of the origin for ``"pixel"``.
    flight_direction : FlightDirection
        The image axis along the flight; the observations are turned so that
        x runs along it.
    """

    units: ImageUnits = ImageUnits.MM
    pixel_size_mm: float | None = None
    principal_point_px: FloatArray | None = None
    flight_direction: FlightDirection = FlightDirection.PLUS_X


@dataclass(frozen=True)
class ReportOptions:
    """Options of ``[report]``.

    Attributes
    ----------
    map_scale : float or None
        Map scale denominator (5000 for 1:5000) for tolerance verdicts.
    """

    map_scale: float | None = None
