"""Every option of the package, with its one default (method.md §3-8).

The project file's ``[adjustment]``, ``[images]``, ``[blunders]`` and
``[report]`` tables, the library calls and the command line all use these
enums and dataclasses; the key list of the project file
(:data:`strip_aerotri.project.schema.PROJECT_KEYS`) takes its defaults from
here, and the tests check that ``docs/project-file.md`` shows the same.

String options are :class:`OptionEnum` members (:mod:`.choices`, exported
here): they compare equal to their value (``Route.PROJECTED == "projected"``)
and are created from a member or a case-insensitive string.  This module
imports nothing heavy.

Each option is defined here once: its default (a ``DEFAULT_*`` constant, the
only place its literal is written; ``tests/test_options.py`` greps for it)
and its rule (a ``check_*`` function, an enum, or a rule of
:func:`adjustment_options` that ties keys together).  A rule raises
:class:`OptionError` naming the key; the loader only adds the file and the
table, and the library, the simulator's writer and ``stripaero check`` call
the same rules.  A run's result carries the :class:`AdjustmentOptions` it ran
with (``result.options``), and ``report.json`` writes them from there.

Adding an option to ``[adjustment]``: its default and field on
:class:`AdjustmentOptions`, its rule in ``_ADJUSTMENT_RULES`` (and in
:func:`adjustment_options` if it depends on other keys), its key in
``project/schema.py`` (type, unit, description for docs and messages), the
stage that uses it, :func:`strip_aerotri.report.values.options_record` and
docs/project-file.md.
"""

from __future__ import annotations

import difflib
import functools
import math
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from ._stats import chi_critical_value, critical_value
from ._text import shorten
from ._typing import BoolArray, FloatArray, IntArray
from .choices import (
    BlunderAction,
    Construction,
    DistortionModel,
    DistortionUnits,
    FiducialTransform,
    FlightDirection,
    ImageUnits,
    IntersectionMethod,
    ModelFormation,
    OptionEnum,
    Refine,
    RelativeOrientationMethod,
    Route,
    ScaleTransfer,
    Weights,
)

__all__ = [
    "SELF_CALIBRATION_CHOICES",
    "SELF_CALIBRATION_PARAMETERS",
    "DEFAULT_ALPHA",
    "DEFAULT_BLOCK_POLYNOMIAL",
    "DEFAULT_DIFFERENCE_TOLERANCE",
    "DEFAULT_DUPLICATE_TOL_MM",
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
    "DEFAULT_RO_TOLERANCE",
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
    "OptionError",
    "Refine",
    "SelfCalibration",
    "RelativeOrientationMethod",
    "ReportOptions",
    "Route",
    "ScaleTransfer",
    "Weights",
    "StripOptions",
    "adjustment_options",
    "check_alpha",
    "check_max_fraction",
    "check_max_iterations",
    "check_min_base_to_height",
    "check_photo_step",
    "check_self_calibration",
    "check_polynomial",
    "check_sections",
    "describe",
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
#: ``stripaero import uav-fc300x``: observations of one photo closer than this
#: (mm) are one point measured twice.
DEFAULT_DUPLICATE_TOL_MM = 0.005

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


# --------------------------------------------------------------------------- rules
#
# Each option's rule is one function here: it takes the value as given (a
# TOML value, a Python value, a command-line value), returns it converted
# and raises OptionError naming the key.  The loader turns an OptionError
# into a ConfigError naming the file and ``[table] key``; the dataclasses
# below call the same rules, so the library refuses what the project file
# refuses, in the same words.


class OptionError(ValueError):
    """An option's value breaks its rule.

    ``key`` is the option's key as written in the project file (``"alpha"``,
    ``"polynomial"``); ``rule`` the broken rule in words ("expected ...");
    ``str(error)`` is ``"key: rule"``.
    """

    def __init__(self, key: str, rule: str) -> None:
        super().__init__(f"{key}: {rule}")
        self.key = key
        self.rule = rule


def describe(value: object) -> str:
    """A value as written in a project file, for messages (``the number 4``)."""
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f'the string "{shorten(value)}"'
    if isinstance(value, int | float | np.integer | np.floating):
        return f"the number {shorten(repr(value))}"
    if isinstance(value, list | tuple):
        return "a list"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def _as_integer(value: object) -> int | None:
    """``value`` as an int if it is an integer (not a bool), else None."""
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        return int(value)
    return None


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool
    )


def _positive_integer(key: str, value: object) -> int:
    number = _as_integer(value)
    if number is None or number < 1:
        raise OptionError(key, f"expected a positive integer, got {describe(value)}")
    return number


def _positive_number(key: str, value: object) -> float:
    if not _is_number(value):
        raise OptionError(key, f"expected a positive number, got {describe(value)}")
    number = float(value)  # type: ignore[arg-type]
    if not math.isfinite(number) or number <= 0.0:
        raise OptionError(key, f"expected a positive finite number, got {shorten(repr(value))}")
    return number


#: Sane ranges (inclusive) of the standard deviations of a project, in its
#: key and in the CSV column that overrides it row by row: beyond them a
#: value is a typing error, or breaks the arithmetic (a weight 1/sigma² that
#: overflows, or a normal matrix that no longer inverts).  Image: a
#: nanometre to a centimetre, far around the micrometres of film and sensors.
IMAGE_SIGMA_RANGE_MM = (1e-6, 10.0)
#: Ground (control, GNSS centres): a micrometre to a thousand kilometres.
GROUND_SIGMA_RANGE_M = (1e-6, 1e6)
#: Attitude (IMU): 1e-7 degree (a micro-radian is 6e-5) to a half turn.
ANGLE_SIGMA_RANGE_DEG = (1e-7, 180.0)
#: Least family-wise false-alarm probability: below it the Bonferroni level
#: alpha / 2n of a large stage comes near the smallest float and the
#: critical value is lost.
MIN_ALPHA = 1e-12


def check_range(key: str, value: object, bounds: tuple[float, float], unit: str = "") -> float:
    """A positive number within ``bounds`` (inclusive), else an OptionError
    naming ``key``, the range and the value."""
    number = _positive_number(key, value)
    low, high = bounds
    if not low <= number <= high:
        unit = f" {unit}" if unit else ""
        raise OptionError(
            key,
            f"expected a number from {low:g} to {high:g}{unit}, got {number:g}{unit} (beyond "
            "any sane value: a typing error?)",
        )
    return number


def check_sections(sections: object) -> int:
    """``sections``: an integer >= 1."""
    return _positive_integer("sections", sections)


def check_max_iterations(value: object) -> int:
    """``max_iterations``: an integer >= 1."""
    return _positive_integer("max_iterations", value)


def check_polynomial(value: object) -> int | Literal["auto"]:
    """``polynomial``: J(16)'s type 0, 1, 2, 3 or ``"auto"`` (any case)."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    number = _as_integer(value)
    if number is not None and 0 <= number <= 3:
        return number
    raise OptionError("polynomial", f'expected 0, 1, 2, 3 or "auto", got {describe(value)}')


def check_photo_step(value: object) -> int | Literal["auto"]:
    """``photo_step``: an integer k >= 1 or ``"auto"`` (any case)."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    number = _as_integer(value)
    if number is not None and number >= 1:
        return number
    raise OptionError(
        "photo_step", f'expected a positive integer or "auto", got {describe(value)}'
    )


def check_min_base_to_height(value: object) -> float:
    """``min_base_to_height``: a positive number."""
    return _positive_number("min_base_to_height", value)


def check_alpha(value: object) -> float:
    """``alpha``: a probability, :data:`MIN_ALPHA` <= alpha < 1."""
    alpha = check_range("alpha", value, (MIN_ALPHA, 1.0))
    if not alpha < 1.0:
        raise OptionError("alpha", f"expected a probability below 1, got {alpha!r}")
    return alpha


def check_max_fraction(value: object) -> float:
    """``max_fraction``: 0 < fraction <= 1."""
    fraction = _positive_number("max_fraction", value)
    if fraction > 1.0:
        raise OptionError("max_fraction", f"expected at most 1, got {fraction!r}")
    return fraction


def check_critical_value(stage: str, value: object) -> float:
    """A stage's critical |w| (``[blunders] <stage>``): a positive number."""
    if stage not in STAGES:
        raise OptionError(stage, f"unknown stage {stage!r}; valid: {', '.join(STAGES)}")
    return _positive_number(stage, value)


def check_exclude_observations(items: object) -> tuple[tuple[str, str], ...]:
    """``exclude_observations``: ``"photo/point"`` strings or (photo, point) pairs."""
    pairs = []
    for item in items if isinstance(items, list | tuple) else [items]:
        if isinstance(item, tuple) and len(item) == 2:
            photo, point = str(item[0]), str(item[1])
        else:
            photo, sep, point = str(item).partition("/")
            if not sep:
                photo = ""
        if not photo or not point:
            raise OptionError("exclude_observations", f'expected "photo/point", got {item!r}')
        pairs.append((photo, point))
    return tuple(pairs)


def check_self_calibration(value: object) -> str | tuple[str, ...]:
    """``self_calibration``: ``"none"``, ``"auto"``, ``"ebner12"`` (any case) or a
    non-empty list of distinct Brown/Fraser names, returned in their fixed order."""
    if isinstance(value, str) and value.strip().lower() in SELF_CALIBRATION_CHOICES:
        return value.strip().lower()
    if isinstance(value, list | tuple) and value and all(isinstance(v, str) for v in value):
        names = [str(v).strip().lower() for v in value]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise OptionError("self_calibration", f"{twice[0]!r} is listed twice")
        unknown = [n for n in names if n not in SELF_CALIBRATION_PARAMETERS]
        if unknown:
            raise OptionError(
                "self_calibration",
                f"unknown parameter {unknown[0]!r}; expected names from "
                f"{list(SELF_CALIBRATION_PARAMETERS)}",
            )
        return tuple(n for n in SELF_CALIBRATION_PARAMETERS if n in names)
    raise OptionError(
        "self_calibration",
        f'expected "none", "auto", "ebner12" or a non-empty list from '
        f"{list(SELF_CALIBRATION_PARAMETERS)}, got {_describe_self_calibration(value)}",
    )


def _describe_self_calibration(value: object) -> str:
    """A refused ``self_calibration`` and what was probably meant."""
    if isinstance(value, list | tuple):
        if not value:
            return 'an empty list (to estimate nothing: "none")'
        k = next(i for i, v in enumerate(value) if not isinstance(v, str))
        return (
            f"a list whose item {k + 1} is {describe(value[k])} (names in quotes, "
            'e.g. ["k1", "k2"])'
        )
    if isinstance(value, str):
        name = value.strip().lower()
        if name in SELF_CALIBRATION_PARAMETERS:
            return f'{describe(value)} (one parameter is a list too: ["{name}"])'
        close = difflib.get_close_matches(name, SELF_CALIBRATION_CHOICES, n=1, cutoff=0.6)
        if close:
            return f'{describe(value)} (did you mean "{close[0]}"?)'
    return describe(value)


#: The rule of every option of ``[adjustment]`` and ``[blunders]`` that is not
#: a choice of an enum (those are :meth:`OptionEnum.create`), by (table, key).
RULES: dict[tuple[str, str], Callable[[object], object]] = {
    ("adjustment", "polynomial"): check_polynomial,
    ("adjustment", "sections"): check_sections,
    ("adjustment", "max_iterations"): check_max_iterations,
    ("adjustment", "photo_step"): check_photo_step,
    ("adjustment", "min_base_to_height"): check_min_base_to_height,
    ("adjustment", "self_calibration"): check_self_calibration,
    ("blunders", "alpha"): check_alpha,
    ("blunders", "max_fraction"): check_max_fraction,
    **{("blunders", stage): functools.partial(check_critical_value, stage) for stage in STAGES},
    ("images", "sigma_mm"): functools.partial(
        check_range, "sigma_mm", bounds=IMAGE_SIGMA_RANGE_MM, unit="mm"
    ),
    **{
        (table, key): functools.partial(check_range, key, bounds=GROUND_SIGMA_RANGE_M, unit="m")
        for table, key in (
            ("control", "sigma_xy_m"),
            ("control", "sigma_h_m"),
            ("gnss", "sigma_xy"),
            ("gnss", "sigma_z"),
        )
    },
    ("imu", "sigma_deg"): functools.partial(
        check_range, "sigma_deg", bounds=ANGLE_SIGMA_RANGE_DEG, unit="deg"
    ),
}


_MODELS_TAKE_NO = (
    'applies to block = "strips" (J\'s polynomials); with block = "models" every model has its '
    'own similarity. Remove {key} or set block = "strips"'
)


def _sections_with(sections: int, polynomial: int | Literal["auto"]) -> int:
    """Sections need a polynomial to join (type 0 has nothing to join)."""
    if sections > 1 and polynomial == 0:
        raise OptionError(
            "sections",
            f'{sections} sections need a polynomial type 1, 2, 3 or "auto", got polynomial = 0',
        )
    return sections


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
        object.__setattr__(self, "max_iterations", check_max_iterations(self.max_iterations))
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
            key = "polynomial" if self.polynomial not in (None, 0) else "sections"
            raise OptionError(key, _MODELS_TAKE_NO.format(key=key))
        poly = check_polynomial(DEFAULT_POLYNOMIAL if self.polynomial is None else self.polynomial)
        object.__setattr__(self, "polynomial", poly)
        sections = _sections_with(check_sections(self.sections), poly)
        object.__setattr__(self, "sections", sections)
        object.__setattr__(self, "max_iterations", check_max_iterations(self.max_iterations))


class _Observed(Protocol):
    """What :meth:`BlunderOptions.excluded` reads of the image observations
    (:class:`strip_aerotri.observations.ImageObservations`)."""

    @property
    def n_points(self) -> int: ...
    @property
    def point_ids(self) -> tuple[str, ...]: ...
    @property
    def photo_ids(self) -> tuple[str, ...]: ...
    @property
    def point(self) -> IntArray: ...
    @property
    def photo(self) -> IntArray: ...


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
        object.__setattr__(self, "action", BlunderAction.create(self.action))
        object.__setattr__(self, "alpha", check_alpha(self.alpha))
        object.__setattr__(
            self,
            "critical_values",
            {s: check_critical_value(s, v) for s, v in self.critical_values.items()},
        )
        object.__setattr__(self, "max_fraction", check_max_fraction(self.max_fraction))
        object.__setattr__(
            self, "exclude_observations", check_exclude_observations(self.exclude_observations)
        )

    @property
    def testing(self) -> bool:
        """Whether the tests are computed at all."""
        return self.action is not BlunderAction.OFF

    @property
    def rejecting(self) -> bool:
        """Whether failing observations are rejected."""
        return self.action is BlunderAction.REJECT

    def excluded(self, observations: _Observed) -> tuple[BoolArray, BoolArray]:
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
        choice = check_self_calibration(self.choice)
        if choice == "none":
            raise OptionError("self_calibration", 'a SelfCalibration is not "none"')
        object.__setattr__(self, "choice", choice)

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
    weights : Weights
        The bundle refinement's observation weights: as given, or estimated
        by group from the residuals (variance components); with ``refine =
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
    weights: Weights = Weights.GIVEN

    def calibration(self, flight_direction: FlightDirection | str) -> SelfCalibration | None:
        """The self-calibration asked for (None for "none")."""
        if self.self_calibration == "none":
            return None
        return SelfCalibration(self.self_calibration, FlightDirection(flight_direction))

    def __post_init__(self) -> None:
        for key, value in vars(self).items():
            object.__setattr__(self, key, _adjustment_value(key, value))
        _sections_with(self.sections, self.polynomial)

    @property
    def allow_breaks(self) -> bool:
        """Whether a model sharing no tie point with the one before is a break
        (:class:`StripOptions`): every model transformed on its own
        (``block = "models"``) takes it from its own control."""
        return self.block is Construction.MODELS

    def strip_options(self) -> StripOptions:
        """The options of strip formation."""
        return StripOptions(
            relative_orientation=self.relative_orientation,
            intersection=self.intersection,
            scale_transfer=self.scale_transfer,
            max_iterations=self.max_iterations,
            allow_breaks=self.allow_breaks,
            models=self.models,
        )

    @classmethod
    def of_stages(
        cls,
        strip: StripOptions,
        ground: GroundOptions,
        *,
        route: Route | str,
        photo_step: int | Literal["auto"] = DEFAULT_PHOTO_STEP,
        min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT,
        refine: Refine | str = Refine.NONE,
    ) -> AdjustmentOptions:
        """The options of a run given as the stages' options (the library's
        :func:`~strip_aerotri.pipeline.triangulate` call)."""
        return cls(
            route=Route.create(route),
            polynomial=DEFAULT_POLYNOMIAL if ground.polynomial is None else ground.polynomial,
            sections=ground.sections,
            relative_orientation=strip.relative_orientation,
            intersection=strip.intersection,
            scale_transfer=strip.scale_transfer,
            max_iterations=strip.max_iterations,
            photo_step=photo_step,
            min_base_to_height=min_base_to_height,
            refine=Refine.create(refine),
            block=Construction.MODELS if ground.construction is None else ground.construction,
            models=strip.models,
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


_ADJUSTMENT_RULES: dict[str, Callable[[object], object]] = {
    "route": Route.create,
    "polynomial": check_polynomial,
    "sections": check_sections,
    "relative_orientation": RelativeOrientationMethod.create,
    "intersection": IntersectionMethod.create,
    "scale_transfer": ScaleTransfer.create,
    "max_iterations": check_max_iterations,
    "photo_step": check_photo_step,
    "min_base_to_height": check_min_base_to_height,
    "refine": Refine.create,
    "block": Construction.create,
    "models": ModelFormation.create,
    "self_calibration": check_self_calibration,
    "weights": Weights.create,
}


def _adjustment_value(key: str, value: object) -> object:
    """One ``[adjustment]`` value converted by its rule (OptionError naming ``key``)."""
    rule = _ADJUSTMENT_RULES.get(key)
    if rule is None:
        raise OptionError(key, f"unknown option; valid: {', '.join(_ADJUSTMENT_RULES)}")
    try:
        return rule(value)
    except OptionError:
        raise
    except ValueError as exc:
        raise OptionError(key, str(exc)) from None


def adjustment_options(
    given: Mapping[str, object], *, route: Route | str | None = None, block: bool = False
) -> AdjustmentOptions:
    """The options of ``[adjustment]`` from the keys a project gives.

    Every value is checked by its option's rule, then the rules that tie
    keys together: ``self_calibration`` needs ``refine = "bundle"``;
    sections need a polynomial; independent models are not
    oriented by ``"dependent"``; ``block`` defaults to ``"models"``, or to
    ``"strips"`` when one strip names ``polynomial`` or ``sections``;
    ``polynomial`` and ``sections`` apply to ``block = "strips"`` only; and
    a block of strips (``block=True``) takes no sections, no ``"auto"``
    polynomial (its default is :data:`DEFAULT_BLOCK_POLYNOMIAL`) and no
    photo step.

    Parameters
    ----------
    given : mapping
        The keys given (absent keys take their default), as written or
        already converted.
    route : Route or str, optional
        The route resolved for the project's CRS; overrides ``given``.
    block : bool
        Whether the project is a block of ``[[strips]]``.

    Raises
    ------
    OptionError
        On the first rule broken; its ``key`` names the key to mend.
    """
    values = {key: _adjustment_value(key, value) for key, value in given.items()}
    named = [key for key in ("polynomial", "sections") if key in values]
    polynomial = values.get("polynomial", DEFAULT_POLYNOMIAL)
    sections = _sections_with(
        values.get("sections", DEFAULT_SECTIONS),  # type: ignore[arg-type]
        polynomial,  # type: ignore[arg-type]
    )
    models = values.get("models", ModelFormation.DEPENDENT)
    if (
        models is ModelFormation.INDEPENDENT
        and values.get("relative_orientation") is RelativeOrientationMethod.DEPENDENT
    ):
        raise OptionError(
            "relative_orientation",
            '"dependent" orients each pair to the previous photo, which independent models do '
            'not; with models = "independent" every pair is oriented on its own in B\'s base '
            'system: remove relative_orientation or set models = "dependent"',
        )
    default = Construction.STRIPS if named and not block else Construction.MODELS
    construction = values.get("block", default)
    if block:
        polynomial = _block_polynomial(values, named, construction)  # type: ignore[arg-type]
    elif construction is Construction.MODELS and named:
        raise OptionError(named[0], _MODELS_TAKE_NO.format(key=named[0]))
    if values.get("self_calibration", "none") != "none" and values.get("refine") is not (
        Refine.BUNDLE
    ):
        raise OptionError(
            "self_calibration",
            'the camera is calibrated in the bundle refinement only; add refine = "bundle" '
            "to [adjustment], or remove self_calibration",
        )
    if values.get("weights", Weights.GIVEN) is not Weights.GIVEN and values.get(
        "refine"
    ) is not Refine.BUNDLE:
        raise OptionError(
            "weights",
            'the weights are estimated in the bundle refinement only; add refine = "bundle" '
            "to [adjustment], or remove weights",
        )
    if route is not None:
        values["route"] = route
    values.update(polynomial=polynomial, sections=sections, block=construction)
    return AdjustmentOptions(**values)  # type: ignore[arg-type]


def _block_polynomial(
    values: Mapping[str, object], named: Collection[str], construction: Construction
) -> int:
    """The type of every strip's own polynomial in a block (0 with
    ``block = "models"``), and the keys a block refuses."""
    if "sections" in named:
        raise OptionError(
            "sections",
            'a block has no sections (with block = "strips" every strip has one polynomial); '
            "remove it",
        )
    if construction is Construction.MODELS and named:
        raise OptionError(
            "polynomial",
            'applies to block = "strips" (every strip its own polynomial); with block = '
            '"models" every model has its own similarity. Remove polynomial or set block = '
            '"strips"',
        )
    polynomial = values.get("polynomial", DEFAULT_BLOCK_POLYNOMIAL)
    if polynomial == "auto":
        raise OptionError(
            "polynomial",
            "\"auto\" chooses a type from one strip's own control, and in a block the strips "
            f"share the control: give 0, 1, 2 or 3 (default {DEFAULT_BLOCK_POLYNOMIAL})",
        )
    if values.get("photo_step", DEFAULT_PHOTO_STEP) != DEFAULT_PHOTO_STEP:
        raise OptionError("photo_step", "a block forms its models on every photo; remove it")
    if construction is Construction.MODELS:
        return 0
    kind = check_polynomial(polynomial)  # an int here: "auto" is refused above
    return 0 if kind == "auto" else kind


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
