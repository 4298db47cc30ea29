"""The project file ``strip.toml`` and the CSV files it names.

This is the only module that reads TOML.  :func:`load_project` validates the
project strictly (every failure is one :class:`~strip_aerotri.errors.ConfigError`
line naming the file, the line or key, and the rule broken) and returns frozen
dataclasses already in library units: image millimetres, ground metres,
radians.  The option enums (:class:`Route`, :class:`RelativeOrientation`,
:class:`Intersection`, :class:`ScaleTransfer`) live here so that numerical
modules can import them without pulling in anything heavy.

The list of valid keys is :data:`PROJECT_KEYS` (with :data:`PROJECT_TABLES`,
:data:`IMAGE_COLUMNS`, :data:`CONTROL_COLUMNS`, :data:`GNSS_COLUMNS` and
:data:`IMU_COLUMNS`); validation, ``stripaero check`` and
``docs/project-file.md`` all follow it.
"""

from __future__ import annotations

import csv
import difflib
import itertools
import math
import re
import tomllib
import warnings as _warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConfigError, ConvergenceError, GeometryError, StripAerotriWarning
from ..interior import (
    BrownDistortion,
    FiducialFit,
    fit_fiducial_transforms,
    mm_from_pixel,
    reduce_image_coordinates,
)
from ..observations import (
    ControlPoints,
    ControlType,
    GnssCentres,
    ImageObservations,
    ImuAttitudes,
    LineSpec,
)
from ..options import (
    DEFAULT_DIFFERENCE_TOLERANCE,
    DEFAULT_GNSS_SIGMA_XY_M,
    DEFAULT_GNSS_SIGMA_Z_M,
    DEFAULT_IMAGE_SIGMA_MM,
    DEFAULT_IMU_SIGMA_DEG,
    DEFAULT_LINE_WEIGHT,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_MIN_BASE_TO_HEIGHT,
    DEFAULT_PHOTO_STEP,
    DEFAULT_POLYNOMIAL,
    DEFAULT_SCALE_TOLERANCE,
    DEFAULT_SECTIONS,
    DEFAULT_SIGMA_H_M,
    DEFAULT_SIGMA_XY_M,
    STAGES,
    AdjustmentOptions,
    BlunderAction,
    BlunderOptions,
    Construction,
    DistortionModel,
    DistortionUnits,
    FiducialTransform,
    FlightDirection,
    ImageOptions,
    ImageUnits,
    IntersectionMethod,
    OptionEnum,
    Refine,
    RelativeOrientationMethod,
    ReportOptions,
    Route,
    ScaleTransfer,
)
from ..plausibility import image_coordinate_problems

__all__ = [
    "CONTROL_COLUMNS",
    "FIDUCIAL_COLUMNS",
    "GNSS_COLUMNS",
    "IMAGE_COLUMNS",
    "IMU_COLUMNS",
    "PROJECT_KEYS",
    "PROJECT_TABLES",
    "AdjustmentOptions",
    "Block",
    "BlunderAction",
    "Camera",
    "ColumnSpec",
    "ImageOptions",
    "Intersection",
    "KeySpec",
    "Project",
    "Refine",
    "RelativeOrientation",
    "ReportOptions",
    "Route",
    "ScaleTransfer",
    "StraightLineSpec",
    "TableSpec",
    "check_output_directory",
    "load_project",
]


# The loader's former names of three option enums.
RelativeOrientation = RelativeOrientationMethod
Intersection = IntersectionMethod
Block = Construction
StraightLineSpec = LineSpec


# --------------------------------------------------------------------------- key list


@dataclass(frozen=True)
class TableSpec:
    """A table of ``strip.toml``.

    Attributes
    ----------
    name : str
        Table name as written in the file.
    required : bool
        Whether the table must be present.
    array : bool
        True for an array of tables (``[[name]]``).
    description : str
        One line for messages and docs.
    """

    name: str
    required: bool
    array: bool
    description: str


@dataclass(frozen=True)
class KeySpec:
    """A key of ``strip.toml``.

    Attributes
    ----------
    table : str
        Table the key belongs to.
    key : str
        Key name.
    kind : str
        Expected value, as named in messages and docs (e.g. ``"positive number"``).
    required : bool
        Whether the key must be given.
    default : object
        Value used when the key is absent (``None``: no value); for
        ``[strip] name`` and ``[[straight_line]] name`` a derived default, see
        ``default_text``.
    unit : str
        Unit of the value (empty when none).
    description : str
        Meaning, one or two sentences.
    contract : bool
        True for keys of the stable contract (formats.md), False for the
        backward-compatible extensions of this package.
    default_text : str
        The default as written in docs and ``stripaero check``.
    """

    table: str
    key: str
    kind: str
    required: bool
    default: object
    unit: str
    description: str
    contract: bool = True
    default_text: str = ""

    @property
    def default_display(self) -> str:
        """The default as shown to users (``"required"`` for required keys)."""
        if self.required:
            return "required"
        if self.default_text:
            return self.default_text
        if isinstance(self.default, tuple):
            return "[" + ", ".join(repr(v) for v in self.default) + "]"
        if isinstance(self.default, OptionEnum):
            return f'"{self.default.value}"'
        return "none" if self.default is None else repr(self.default)

    @property
    def qualified(self) -> str:
        """``[table] key`` (``[[table]] key`` for arrays of tables)."""
        table = _TABLES_BY_NAME[self.table]
        brackets = f"[[{self.table}]]" if table.array else f"[{self.table}]"
        return f"{brackets} {self.key}"


PROJECT_TABLES: tuple[TableSpec, ...] = (
    TableSpec("strip", True, False, "the strip: its name and photos in flight order"),
    TableSpec("camera", True, False, "interior orientation"),
    TableSpec("images", True, False, "measured image coordinates"),
    TableSpec("distortion", False, False, "lens distortion, Brown's polynomials"),
    TableSpec(
        "interior_orientation", False, False, "fiducial marks: comparator to calibrated system"
    ),
    TableSpec("control", True, False, "ground control and check points"),
    TableSpec(
        "straight_line", False, True, "points without ground coordinates on one straight line"
    ),
    TableSpec("adjustment", False, False, "choice of method variants"),
    TableSpec("output", False, False, "where results are written"),
    TableSpec("report", False, False, "report options"),
    TableSpec("blunders", False, False, "gross-error tests at every stage"),
    TableSpec("gnss", False, False, "observed projection centres for the bundle refinement"),
    TableSpec("imu", False, False, "observed photo attitudes for the bundle refinement"),
)
_TABLES_BY_NAME = {t.name: t for t in PROJECT_TABLES}


# fmt: off
PROJECT_KEYS: tuple[KeySpec, ...] = (
    KeySpec(
        "strip", "name", "string", required=False, default=None, unit="",
        description="Name of the strip, used in reports.",
        default_text="name of the folder holding strip.toml",
    ),
    KeySpec(
        "strip", "photos", "list of ids", required=True, default=None, unit="",
        description="Photo ids (strings) in strip (flight) order; at least two, no "
        "duplicates; every photo must have observations.",
    ),
    KeySpec(
        "camera", "principal_distance_mm", "positive number", required=True, default=None,
        unit="mm", description="Principal distance c (calibrated focal length).",
    ),
    KeySpec(
        "camera", "principal_point_mm", "pair of numbers", required=False, default=(0.0, 0.0),
        unit="mm",
        description="Principal point x0, y0 in the image system; subtracted from every "
        "image x, y.",
        default_text="[0.0, 0.0]",
    ),
    KeySpec(
        "images", "file", "path", required=True, default=None, unit="",
        description="CSV of image coordinates, relative to the folder of strip.toml.",
    ),
    KeySpec(
        "images", "sigma_mm", "positive number", required=False,
        default=DEFAULT_IMAGE_SIGMA_MM, unit="mm",
        description="Standard deviation of an image coordinate, for rows without a sigma "
        "value.",
        contract=False,
    ),
    KeySpec(
        "images", "units", "choice", required=False, default=ImageUnits.MM, unit="",
        description='"mm" (x right, y up, in millimetres) or "pixel" (column, row with rows '
        "growing downwards; converted with pixel_size_mm and principal_point_px).",
        contract=False,
    ),
    KeySpec(
        "images", "pixel_size_mm", "positive number", required=False, default=None, unit="mm",
        description='Side of a square pixel; required with units = "pixel", refused '
        "otherwise.",
        contract=False,
        default_text="none",
    ),
    KeySpec(
        "images", "principal_point_px", "pair of numbers", required=False, default=None,
        unit="px",
        description="Column c0 and row r0 of the origin of the image coordinates (principal "
        'point or image centre): x = (col - c0) s, y = -(row - r0) s. Required with units = '
        '"pixel", refused otherwise.',
        contract=False,
        default_text="none",
    ),
    KeySpec(
        "images", "flight_direction", "choice", required=False,
        default=FlightDirection.PLUS_X, unit="",
        description='The image axis that points along the flight: "+x", "-x", "+y" or "-y"; '
        'the coordinates are turned so that x runs along the flight and y to its left '
        '(e.g. "+y": x\' = y, y\' = -x).',
        contract=False,
    ),
    KeySpec(
        "distortion", "k1", "number", required=False, default=0.0, unit="mm^-2",
        description="Radial coefficient of r^2 (unit for units = \"mm\"; none for "
        '"normalized").',
        contract=False,
    ),
    KeySpec(
        "distortion", "k2", "number", required=False, default=0.0, unit="mm^-4",
        description="Radial coefficient of r^4.", contract=False,
    ),
    KeySpec(
        "distortion", "k3", "number", required=False, default=0.0, unit="mm^-6",
        description="Radial coefficient of r^6.", contract=False,
    ),
    KeySpec(
        "distortion", "p1", "number", required=False, default=0.0, unit="mm^-1",
        description="Decentring coefficient paired with r^2 + 2x^2 (Brown 1966).",
        contract=False,
    ),
    KeySpec(
        "distortion", "p2", "number", required=False, default=0.0, unit="mm^-1",
        description="Decentring coefficient paired with r^2 + 2y^2 (Brown 1966).",
        contract=False,
    ),
    KeySpec(
        "distortion", "units", "choice", required=False, default=DistortionUnits.MM, unit="",
        description='"mm": r in millimetres; "normalized": r divided by the principal '
        "distance (OpenCV, Agisoft).",
        contract=False,
    ),
    KeySpec(
        "distortion", "model", "choice", required=False, default=DistortionModel.CORRECTION,
        unit="",
        description='"correction": corrected = measured + delta(measured) (Brown 1971); '
        '"projection": measured = ideal + delta(ideal) (OpenCV, Agisoft), inverted by '
        "iteration.",
        contract=False,
    ),
    KeySpec(
        "interior_orientation", "fiducials_file", "path", required=True, default=None,
        unit="",
        description="CSV photo,mark,x,y of the measured (comparator) coordinates of the "
        "fiducial marks, in [images] units, relative to the folder of strip.toml.",
        contract=False,
    ),
    KeySpec(
        "interior_orientation", "calibrated", "mark table", required=True, default=None,
        unit="mm",
        description='Calibrated coordinates of each mark, e.g. { "1" = [-106.0, -106.0], '
        '"2" = [106.0, 106.0] } (camera certificate, x right, y up).',
        contract=False,
    ),
    KeySpec(
        "interior_orientation", "transform", "choice", required=False,
        default=FiducialTransform.AFFINE, unit="",
        description='"similarity" (4 parameters, 2 marks at least) or "affine" (6 '
        "parameters, 3 marks at least), fitted per photo by least squares.",
        contract=False,
    ),
    KeySpec(
        "interior_orientation", "scale_tolerance", "positive number", required=False,
        default=DEFAULT_SCALE_TOLERANCE, unit="",
        description="R4 1.7.7.1: largest |s - 1| of a scale coefficient (\"a few units of "
        'the 4th decimal"); a photo over it is warned.',
        contract=False,
    ),
    KeySpec(
        "interior_orientation", "difference_tolerance", "positive number", required=False,
        default=DEFAULT_DIFFERENCE_TOLERANCE, unit="",
        description="R4 1.7.7.1: largest |sx - sy| (\"a few units of the 5th decimal\"); "
        "a photo over it is warned.",
        contract=False,
    ),
    KeySpec(
        "control", "file", "path", required=True, default=None, unit="",
        description="CSV of ground control and check points, relative to the folder of "
        "strip.toml.",
    ),
    KeySpec(
        "control", "crs", "string", required=True, default=None, unit="",
        description="CRS of control X, Y (anything pyproj understands: projected or "
        'geographic) or "local" for a local Cartesian site system in metres.',
    ),
    KeySpec(
        "control", "sigma_xy_m", "positive number", required=False,
        default=DEFAULT_SIGMA_XY_M, unit="m",
        description="Standard deviation of control X and Y, for rows without a sigma_xy "
        "value.",
        contract=False,
    ),
    KeySpec(
        "control", "sigma_h_m", "positive number", required=False,
        default=DEFAULT_SIGMA_H_M, unit="m",
        description="Standard deviation of control H, for rows without a sigma_h value.",
        contract=False,
    ),
    KeySpec(
        "straight_line", "points", "list of ids", required=True, default=None, unit="",
        description="Ids of at least three observed points without ground coordinates that "
        "lie on one straight vertical plane along the strip (J(18)).",
    ),
    KeySpec(
        "straight_line", "weight", "positive number", required=False,
        default=DEFAULT_LINE_WEIGHT, unit="",
        description="Weight of the line equations relative to control equations of "
        "weight 1.",
    ),
    KeySpec(
        "straight_line", "name", "string", required=False, default=None, unit="",
        description="Name of the line in reports; unique among the lines.",
        contract=False,
        default_text='"line <n>" (n = 1, 2, ... in file order)',
    ),
    KeySpec(
        "adjustment", "route", "choice", required=False, default=None, unit="",
        description='"geocentric" (local-tangent system, B(142)-(152)) or "projected" '
        "(map grid directly, J, with B(153)).",
        default_text='"geocentric"; "projected" when crs = "local"',
    ),
    KeySpec(
        "adjustment", "polynomial", "polynomial", required=False,
        default=DEFAULT_POLYNOMIAL, unit="",
        description="Deformation polynomial type: 0 (similarity only), 1, 2, 3 (J(16)) "
        'or "auto".',
    ),
    KeySpec(
        "adjustment", "sections", "positive integer", required=False,
        default=DEFAULT_SECTIONS, unit="",
        description="Sections of equal length along the strip over which the deformation "
        "polynomials become splines joined without steps (long strips, docs/ground.md); "
        "1: J(16)'s single polynomial. Every section needs control.",
        contract=False,
    ),
    KeySpec(
        "adjustment", "block", "choice", required=False, default=None, unit="",
        description='How the strip goes to the ground: "models" (every model its own 3D '
        "similarity, all transformed at once onto the control and onto each other on their "
        'common points and projection centres, R4 3) or "strips" (the strip as one body: '
        "J's similarity and deformation polynomials).",
        default_text='"models"; "strips" when polynomial or sections is given',
    ),
    KeySpec(
        "adjustment", "relative_orientation", "choice", required=False,
        default=RelativeOrientationMethod.DEPENDENT, unit="",
        description='"dependent" (b_y, b_z and Schut a, b, c; J) or "base" '
        "(B's five angles).",
        default_text='"dependent"',
    ),
    KeySpec(
        "adjustment", "intersection", "choice", required=False,
        default=IntersectionMethod.MIDPOINT, unit="",
        description='"midpoint" (J(12)) or "normal" (B(138)).',
        default_text='"midpoint"',
    ),
    KeySpec(
        "adjustment", "scale_transfer", "choice", required=False, default=ScaleTransfer.Z,
        unit="", description='"z" (J(15)) or "distance" (B(139)-(140)).',
        default_text='"z"',
    ),
    KeySpec(
        "adjustment", "max_iterations", "positive integer", required=False,
        default=DEFAULT_MAX_ITERATIONS, unit="",
        description="Largest number of iterations of each iterative solution (relative "
        "orientation); more is a convergence error.",
        contract=False,
    ),
    KeySpec(
        "adjustment", "photo_step", "photo step", required=False,
        default=DEFAULT_PHOTO_STEP, unit="",
        description="Models on every k-th photo (k >= 1), the photos between oriented by "
        'resection; "auto": the smallest k reaching min_base_to_height (high-overlap '
        "drone strips).",
        contract=False,
    ),
    KeySpec(
        "adjustment", "refine", "choice", required=False, default=Refine.NONE, unit="",
        description='"bundle": a rigorous bundle adjustment of all photos and points from '
        "the strip solution, in the local tangent frame (docs/bundle.md); points.csv and "
        "photos.csv then hold its results.",
        contract=False,
    ),
    KeySpec(
        "adjustment", "min_base_to_height", "positive number", required=False,
        default=DEFAULT_MIN_BASE_TO_HEIGHT, unit="",
        description='Smallest base-to-height ratio of a model for photo_step = "auto".',
        contract=False,
    ),
    KeySpec(
        "output", "directory", "path", required=False, default=None, unit="",
        description="Result folder, relative to the folder of strip.toml; the CLI's --out "
        "overrides it. Must not be the project folder nor contain input files.",
        default_text="none (the CLI then needs --out)",
    ),
    KeySpec(
        "report", "map_scale", "positive number", required=False, default=None, unit="",
        description="Map scale denominator (e.g. 5000 for 1:5000) for the tolerance "
        "verdicts of method.md section 7; without it no verdicts are given.",
        contract=False,
        default_text="none",
    ),
    KeySpec(
        "blunders", "action", "choice", required=False, default=BlunderAction.REJECT, unit="",
        description='"reject": test every stage, reject failing observations one at a time '
        'and re-solve; "report": test and report only; "off": no tests.',
        contract=False,
    ),
    KeySpec(
        "blunders", "alpha", "positive number", required=False, default=0.001, unit="",
        description="Family-wise false-alarm probability per stage (Bonferroni over the "
        "stage's tests), below 1.",
        contract=False,
    ),
    KeySpec(
        "blunders", "relative_orientation", "positive number", required=False, default=None,
        unit="", description="Critical |w| of the y-parallax tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "tie_points", "positive number", required=False, default=None, unit="",
        description="Critical |w| of the tie-point height tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "models", "positive number", required=False, default=None, unit="",
        description="Critical value of the tests of a point's determination in a model "
        'against the adjusted point (block = "models"; square root of a chi-square with 3 '
        "degrees of freedom; overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "control", "positive number", required=False, default=None, unit="",
        description="Critical |w| of the control tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "straight_line", "positive number", required=False, default=None,
        unit="", description="Critical |w| of the line-point tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "bundle", "positive number", required=False, default=None, unit="",
        description="Critical |w| of the bundle refinement's image and control tests "
        "(overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "gnss", "positive number", required=False, default=None, unit="",
        description="Critical |w| of the bundle's GNSS centre tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "imu", "positive number", required=False, default=None, unit="",
        description="Critical |w| of the bundle's IMU attitude tests (overrides alpha).",
        contract=False, default_text="from alpha",
    ),
    KeySpec(
        "blunders", "max_fraction", "positive number", required=False, default=0.2, unit="",
        description="Stop with an error when a stage would reject more than this fraction "
        "of its observations (at most 1).",
        contract=False,
    ),
    KeySpec(
        "blunders", "exclude_points", "list of ids", required=False, default=(), unit="",
        description="Point ids left out of every stage.",
        contract=False, default_text="none",
    ),
    KeySpec(
        "blunders", "exclude_observations", "list of ids", required=False, default=(), unit="",
        description='Image observations left out, each written "photo/point".',
        contract=False, default_text="none",
    ),
    KeySpec(
        "gnss", "file", "path", required=True, default=None, unit="",
        description="CSV photo,X,Y,Z[,sigma_xy,sigma_z] of the GNSS projection centres "
        "(control CRS, Z ellipsoidal height in metres), relative to the folder of "
        'strip.toml. The table needs [adjustment] refine = "bundle".',
        contract=False,
    ),
    KeySpec(
        "gnss", "sigma_xy", "positive number", required=False,
        default=DEFAULT_GNSS_SIGMA_XY_M, unit="m",
        description="Standard deviation of a centre's X and Y, for rows without a sigma_xy "
        "value.",
        contract=False,
    ),
    KeySpec(
        "gnss", "sigma_z", "positive number", required=False,
        default=DEFAULT_GNSS_SIGMA_Z_M, unit="m",
        description="Standard deviation of a centre's Z, for rows without a sigma_z value.",
        contract=False,
    ),
    KeySpec(
        "imu", "file", "path", required=True, default=None, unit="",
        description="CSV photo,omega,phi,kappa[,sigma_deg] of the IMU attitudes in degrees "
        "(image -> local east-north-up, the photos.csv convention), relative to the folder "
        'of strip.toml. The table needs [adjustment] refine = "bundle".',
        contract=False,
    ),
    KeySpec(
        "imu", "sigma_deg", "positive number", required=False,
        default=DEFAULT_IMU_SIGMA_DEG, unit="deg",
        description="Standard deviation of each attitude angle, for rows without a "
        "sigma_deg value.",
        contract=False,
    ),
)
# fmt: on

_ENUM_OF_KEY: dict[tuple[str, str], type[OptionEnum]] = {
    ("blunders", "action"): BlunderAction,
    ("adjustment", "refine"): Refine,
    ("adjustment", "route"): Route,
    ("adjustment", "block"): Construction,
    ("adjustment", "relative_orientation"): RelativeOrientationMethod,
    ("adjustment", "intersection"): IntersectionMethod,
    ("adjustment", "scale_transfer"): ScaleTransfer,
    ("images", "units"): ImageUnits,
    ("images", "flight_direction"): FlightDirection,
    ("distortion", "units"): DistortionUnits,
    ("distortion", "model"): DistortionModel,
    ("interior_orientation", "transform"): FiducialTransform,
}


@dataclass(frozen=True)
class ColumnSpec:
    """A column of an input CSV (names are matched case-insensitively)."""

    name: str
    required: bool
    unit: str
    description: str


IMAGE_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id, one of [strip] photos"),
    ColumnSpec("point", True, "", "point id; the same id is the same ground point on every photo"),
    ColumnSpec("x", True, "mm", "image x, along the flight"),
    ColumnSpec("y", True, "mm", "image y, to the left of the flight"),
    ColumnSpec("sigma", False, "mm", "standard deviation of x and y; empty: [images] sigma_mm"),
)

FIDUCIAL_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id, one of [strip] photos"),
    ColumnSpec("mark", True, "", "fiducial mark id, one of [interior_orientation] calibrated"),
    ColumnSpec("x", True, "mm or px", "measured x of the mark, in [images] units"),
    ColumnSpec("y", True, "mm or px", "measured y of the mark, in [images] units"),
)

CONTROL_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("point", True, "", "point id"),
    ColumnSpec("X", True, "CRS unit", "easting (or longitude in degrees); empty for height"),
    ColumnSpec("Y", True, "CRS unit", "northing (or latitude in degrees); empty for height"),
    ColumnSpec("H", True, "m", "ellipsoidal height; empty for plan"),
    ColumnSpec("type", True, "", "full, plan, height or check"),
    ColumnSpec(
        "sigma_xy", False, "m", "standard deviation of X and Y; empty: [control] sigma_xy_m"
    ),
    ColumnSpec("sigma_h", False, "m", "standard deviation of H; empty: [control] sigma_h_m"),
)

GNSS_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id; rows of photos not in [strip] photos are ignored"),
    ColumnSpec("X", True, "CRS unit", "projection centre easting (or longitude in degrees)"),
    ColumnSpec("Y", True, "CRS unit", "projection centre northing (or latitude in degrees)"),
    ColumnSpec("Z", True, "m", "projection centre ellipsoidal height"),
    ColumnSpec("sigma_xy", False, "m", "standard deviation of X and Y; empty: [gnss] sigma_xy"),
    ColumnSpec("sigma_z", False, "m", "standard deviation of Z; empty: [gnss] sigma_z"),
)

IMU_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id; rows of photos not in [strip] photos are ignored"),
    ColumnSpec("omega", True, "deg", "omega of image -> local east-north-up (photos.csv)"),
    ColumnSpec("phi", True, "deg", "phi of image -> local east-north-up (photos.csv)"),
    ColumnSpec("kappa", True, "deg", "kappa of image -> local east-north-up (photos.csv)"),
    ColumnSpec(
        "sigma_deg", False, "deg", "standard deviation of each angle; empty: [imu] sigma_deg"
    ),
)


# --------------------------------------------------------------------------- results


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Camera:
    """Interior orientation.

    Attributes
    ----------
    principal_distance_mm : float
        c in millimetres.
    principal_point_mm : ndarray, shape (2,)
        x0, y0 in millimetres (already subtracted from the observations).
    """

    principal_distance_mm: float
    principal_point_mm: FloatArray


@dataclass(frozen=True)
class Project:
    """A validated project: everything a run needs, in library units.

    Attributes
    ----------
    path : Path
        The project file, as given.
    name : str
    photo_ids : tuple of str
        Photos in strip (flight) order.
    camera : Camera
    observations : ImageObservations
        Image x, y in mm in the method's axes (x along the flight, y to its
        left), from pixels if so given, through the fiducial transformation,
        reduced by the principal point, corrected for distortion; sigma in mm.
    control : ControlPoints
        Control and check points observed on at least one photo.
    crs : str
        ``[control] crs`` as given (``"local"`` in lower case).
    straight_lines : tuple of LineSpec
    adjustment : AdjustmentOptions
    output_directory : Path or None
        ``[output] directory`` joined to the project folder.
    warnings : tuple of str
        Valid but doubtful things found while loading (each names its point or
        file); they are not emitted as Python warnings.
    images_file, control_file : Path
        The input CSVs, joined to the project folder.
    report : ReportOptions
    images : ImageOptions
    distortion : BrownDistortion or None
        ``[distortion]`` (None without the table).
    fiducials : tuple of FiducialFit
        Per-photo interior orientation from ``[interior_orientation]`` (empty
        without it), with the residuals at the marks and R4 §1.7.7.1's check.
    fiducials_file : Path or None
    blunders : BlunderOptions
    gnss : GnssCentres or None
        ``[gnss]``: observed projection centres in the control CRS (None
        without the table); rows of photos not in the strip are left out.
    imu : ImuAttitudes or None
        ``[imu]``: observed attitudes in radians (None without the table).
    gnss_file, imu_file : Path or None
        Their CSVs, joined to the project folder.
    """

    path: Path
    name: str
    photo_ids: tuple[str, ...]
    camera: Camera
    observations: ImageObservations
    control: ControlPoints
    crs: str
    straight_lines: tuple[LineSpec, ...]
    adjustment: AdjustmentOptions
    output_directory: Path | None
    warnings: tuple[str, ...]
    images_file: Path
    control_file: Path
    report: ReportOptions = field(default_factory=ReportOptions)
    images: ImageOptions = field(default_factory=ImageOptions)
    distortion: BrownDistortion | None = None
    fiducials: tuple[FiducialFit, ...] = ()
    fiducials_file: Path | None = None
    blunders: BlunderOptions = field(default_factory=BlunderOptions)
    gnss: GnssCentres | None = None
    imu: ImuAttitudes | None = None
    gnss_file: Path | None = None
    imu_file: Path | None = None

    @property
    def input_files(self) -> tuple[Path, ...]:
        """The project file and the CSVs it names."""
        extra = tuple(
            f for f in (self.fiducials_file, self.gnss_file, self.imu_file) if f is not None
        )
        return (self.path, self.images_file, self.control_file, *extra)

    @property
    def is_local(self) -> bool:
        """True for ``crs = "local"`` (no geodesy)."""
        return self.crs == "local"


# --------------------------------------------------------------------------- helpers


def _describe(value: object) -> str:
    """A TOML value as written, for messages."""
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f'the string "{value}"'
    if isinstance(value, int | float):
        return f"the number {value!r}"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def _suggest(word: str, candidates: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` or empty."""
    lower = {c.lower(): c for c in candidates}
    if word.lower() in lower:
        return f" (did you mean '{lower[word.lower()]}'?)"
    match = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean '{match[0]}'?)" if match else ""


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _parse_value(spec: KeySpec, value: object, where: str) -> object:
    """Convert one TOML value after checking it against ``spec.kind``."""
    kind = spec.kind
    if kind in ("string", "path"):
        if not isinstance(value, str) or not value.strip():
            raise ConfigError(f"{where}: expected a non-empty string, got {_describe(value)}")
        return value.strip() if kind == "string" else value
    if kind == "positive number":
        if not _is_number(value):
            raise ConfigError(f"{where}: expected a positive number, got {_describe(value)}")
        number = float(value)  # type: ignore[arg-type]
        if not math.isfinite(number) or number <= 0.0:
            raise ConfigError(f"{where}: expected a positive finite number, got {value!r}")
        return number
    if kind == "positive integer":
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ConfigError(f"{where}: expected a positive integer, got {_describe(value)}")
        return value
    if kind == "pair of numbers":
        if (
            not isinstance(value, list)
            or len(value) != 2
            or not all(_is_number(v) and math.isfinite(v) for v in value)
        ):
            raise ConfigError(
                f"{where}: expected a list of two finite numbers like [0.0, 0.0], got {value!r}"
            )
        return (float(value[0]), float(value[1]))
    if kind == "list of ids":
        if not isinstance(value, list):
            raise ConfigError(
                f'{where}: expected a list of id strings like ["1201", "1202"], '
                f"got {_describe(value)}"
            )
        for item in value:
            if not isinstance(item, str):
                hint = f' (write "{item}")' if _is_number(item) else ""
                raise ConfigError(f"{where}: ids must be strings, got {_describe(item)}{hint}")
            if not item.strip():
                raise ConfigError(f"{where}: ids must not be empty")
        ids = [item.strip() for item in value]
        seen: set[str] = set()
        for item in ids:
            if item in seen:
                raise ConfigError(f"{where}: id '{item}' is listed twice")
            seen.add(item)
        return tuple(ids)
    if kind == "choice":
        enum = _ENUM_OF_KEY[(spec.table, spec.key)]
        if isinstance(value, str):
            member = enum._missing_(value)
            if member is not None:
                return member
        raise ConfigError(
            f"{where}: expected one of {enum.valid_values()} (any case), got {_describe(value)}"
        )
    if kind == "number":
        if not _is_number(value) or not math.isfinite(value):  # type: ignore[arg-type]
            raise ConfigError(f"{where}: expected a finite number, got {_describe(value)}")
        return float(value)  # type: ignore[arg-type]
    if kind == "photo step":
        if isinstance(value, str) and value.strip().lower() == "auto":
            return "auto"
        if isinstance(value, int) and not isinstance(value, bool) and value >= 1:
            return value
        raise ConfigError(
            f'{where}: expected a positive integer or "auto", got {_describe(value)}'
        )
    if kind == "mark table":
        if not isinstance(value, dict) or len(value) < 2:
            raise ConfigError(
                f'{where}: expected a table of at least two marks like {{ "1" = [-106.0, '
                f'-106.0], "2" = [106.0, 106.0] }}, got {_describe(value)}'
            )
        marks: dict[str, tuple[float, float]] = {}
        for mark, xy in value.items():
            if (
                not isinstance(xy, list)
                or len(xy) != 2
                or not all(_is_number(v) and math.isfinite(v) for v in xy)
            ):
                raise ConfigError(
                    f"{where}: mark '{mark}': expected a list of two finite numbers (x, y in "
                    f"mm), got {xy!r}"
                )
            marks[str(mark).strip()] = (float(xy[0]), float(xy[1]))
        return marks
    if kind == "polynomial":
        if isinstance(value, str) and value.strip().lower() == "auto":
            return "auto"
        if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 3:
            return value
        raise ConfigError(f'{where}: expected 0, 1, 2, 3 or "auto", got {_describe(value)}')
    raise AssertionError(f"unhandled kind {kind!r}")  # pragma: no cover


def _check_table(
    toml_name: str, table: str, content: dict[str, Any], label: str
) -> dict[str, object]:
    """Validate one table's keys and convert its values (defaults filled in)."""
    specs = {s.key: s for s in PROJECT_KEYS if s.table == table}
    for key in content:
        if key not in specs:
            elsewhere = [s.qualified for s in PROJECT_KEYS if s.key == key and s.table != table]
            hint = f" (it belongs in {elsewhere[0]})" if elsewhere else _suggest(key, list(specs))
            raise ConfigError(
                f"{toml_name}: unknown key '{key}' in {label}{hint}; "
                f"valid keys: {', '.join(specs)}"
            )
    out: dict[str, object] = {}
    for key, spec in specs.items():
        where = f"{toml_name}: {label} {key}"
        if key in content:
            out[key] = _parse_value(spec, content[key], where)
        elif spec.required:
            raise ConfigError(f"{toml_name}: {label}: missing required key '{key}'")
        else:
            out[key] = spec.default
    return out


_TOML_POSITION = re.compile(r"\s*\(at line (\d+), column (\d+)\)$")


def _read_bytes(path: Path, what: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: {what} is a folder, not a file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None


def _decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ConfigError(
            f"{path}:{line}: not valid UTF-8 (byte 0x{data[exc.start]:02x}); "
            "save the file as UTF-8"
        ) from None


def _read_toml(path: Path) -> dict[str, Any]:
    text = _decode(path, _read_bytes(path, "project file"))
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        match = _TOML_POSITION.search(message)
        if match:
            message = message[: match.start()]
            raise ConfigError(
                f"{path}:{match.group(1)}:{match.group(2)}: TOML syntax error: {message}"
            ) from None
        raise ConfigError(f"{path}: TOML syntax error: {message}") from None


# --------------------------------------------------------------------------- CSV


@dataclass
class _CsvTable:
    """Columns of a CSV as stripped strings, with the file line of each row."""

    path: Path
    columns: dict[str, Sequence[str]]
    line: IntArray
    header_line: int

    @property
    def n_rows(self) -> int:
        return int(self.line.shape[0])

    def where(self, row: int) -> str:
        return f"{self.path}:{int(self.line[row])}"


_SKIPPED_LINE = re.compile(r"\n[ \t\f\v]*(?:#[^\n]*)?(?=\n|\Z)")


def _split_lines(text: str) -> tuple[list[str], IntArray]:
    """Data lines of ``text`` (no comments, no blank lines) and their 1-based numbers."""
    lines = text.split("\n")
    skipped: list[int] = []
    index, position = 0, 0
    text = "\n" + text  # so that every line, the first too, starts after a newline
    for match in _SKIPPED_LINE.finditer(text):
        index += text.count("\n", position, match.start())
        position = match.start()
        skipped.append(index)
    if not skipped:
        return lines, np.arange(1, len(lines) + 1, dtype=np.intp)
    kept: list[str] = []
    start = 0
    for i in skipped:
        kept.extend(lines[start:i])
        start = i + 1
    kept.extend(lines[start:])
    numbers = np.delete(np.arange(1, len(lines) + 1, dtype=np.intp), skipped)
    return kept, numbers


def _split_fields(path: Path, lines: list[str], numbers: IntArray) -> list[list[str]]:
    """Fields of each line by the csv module (quotes allowed, one line per record)."""
    reader = csv.reader(lines, strict=True)
    try:
        rows = list(reader)
        failure = None if len(rows) == len(lines) else "a quoted field is not closed on its line"
    except csv.Error as exc:
        failure = str(exc)
    if failure is None:
        return rows
    # a record may not span lines: the culprit is the first line with an odd number of quotes
    odd = [i for i, item in enumerate(lines) if item.count('"') % 2]
    index = odd[0] if odd else min(max(reader.line_num - 1, 0), len(lines) - 1)
    raise ConfigError(f"{path}:{numbers[index]}: malformed CSV: {failure}")


def _read_csv(path: Path, columns: Sequence[ColumnSpec], named_by: str) -> _CsvTable:
    """Read a comma-separated file into string columns (cells not yet stripped).

    Comment lines (first non-blank character ``#``) and blank lines are
    skipped; UTF-8 with or without BOM; LF or CRLF line ends.  Header names
    are matched case-insensitively against ``columns``; unknown columns are
    an error.
    """
    data = _read_bytes(path, f"file named by {named_by}")
    text = _decode(path, data)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    kept, numbers = _split_lines(text)
    if not kept:
        raise ConfigError(f"{path}: no header line (the file is empty or all comments)")
    header_line = int(numbers[0])
    header = [name.strip() for name in _split_fields(path, kept[:1], numbers[:1])[0]]
    canonical = {c.name.lower(): c.name for c in columns}
    names: list[str] = []
    for name in header:
        if not name:
            raise ConfigError(f"{path}:{header_line}: empty column name in the header")
        if name.lower() not in canonical:
            allowed = ", ".join(c.name for c in columns)
            raise ConfigError(
                f"{path}:{header_line}: unknown column '{name}'"
                f"{_suggest(name, [c.name for c in columns])}; allowed columns: {allowed}"
            )
        if canonical[name.lower()] in names:
            raise ConfigError(f"{path}:{header_line}: column '{name}' appears twice")
        names.append(canonical[name.lower()])
    missing = [c.name for c in columns if c.required and c.name not in names]
    if missing:
        raise ConfigError(
            f"{path}:{header_line}: missing required column(s) {', '.join(missing)} "
            f"(header is: {','.join(header)})"
        )
    body = kept[1:]
    line = numbers[1:]
    n_col = len(names)
    if '"' in text:
        rows = _split_fields(path, body, line)
        lengths = np.fromiter(map(len, rows), dtype=np.intp, count=len(rows))
    else:  # fast path without quoting: one split of the whole body
        rows = []
        lengths = 1 + np.fromiter(
            map(str.count, body, itertools.repeat(",")), dtype=np.intp, count=len(body)
        )
    bad = np.flatnonzero(lengths != n_col)
    if bad.size:
        row = int(bad[0])
        hint = " (decimal commas? use a point)" if lengths[row] > n_col else ""
        raise ConfigError(
            f"{path}:{line[row]}: expected {n_col} fields ({','.join(names)}), "
            f"got {lengths[row]}{hint}"
        )
    if rows:
        cells: Sequence[Sequence[str]] = list(zip(*rows, strict=True))
    elif body:
        flat = ",".join(body).split(",")
        cells = [flat[j::n_col] for j in range(n_col)]
    else:
        cells = [[] for _ in names]
    return _CsvTable(path, dict(zip(names, cells, strict=True)), line, header_line)


def _float_column(
    table: _CsvTable, name: str, *, allow_empty: bool = False, positive: bool = False
) -> tuple[FloatArray, BoolArray]:
    """Column ``name`` as float64 (NaN where empty) and the mask of empty cells.

    Raises ConfigError naming the line and column of the first value that is
    not a number, not finite, or (``positive``) not > 0, and of the first
    empty cell unless ``allow_empty``.
    """
    strings = table.columns[name]
    n = len(strings)
    empty = np.zeros(n, dtype=bool)
    try:  # fast path: float() accepts surrounding white space, not empty cells
        values = np.asarray(strings, dtype=np.float64).reshape(n)
    except ValueError:
        stripped = [s.strip() for s in strings]
        empty = np.fromiter((not s for s in stripped), dtype=bool, count=n)
        if empty.any() and not allow_empty:
            row = int(np.flatnonzero(empty)[0])
            raise ConfigError(f"{table.where(row)}: column '{name}' is empty") from None
        filled = [s or "nan" for s in stripped]
        try:
            values = np.asarray(filled, dtype=np.float64).reshape(n)
        except ValueError:
            row = next(i for i, s in enumerate(filled) if not _is_float(s))
            raise ConfigError(
                f"{table.where(row)}: column '{name}': expected a number, got '{stripped[row]}'"
            ) from None
    bad = ~np.isfinite(values) & ~empty
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ConfigError(
            f"{table.where(row)}: column '{name}': expected a finite number, "
            f"got '{strings[row].strip()}'"
        )
    if positive:
        bad = (values <= 0.0) & ~empty
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ConfigError(
                f"{table.where(row)}: column '{name}': expected a positive number, "
                f"got '{strings[row].strip()}'"
            )
    return values, empty


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _id_column(table: _CsvTable, name: str) -> np.ndarray:
    """Column ``name`` as a str array with white space stripped; an empty id is an error."""
    strings = table.columns[name]
    arr = np.char.strip(np.asarray(strings, dtype=str).reshape(len(strings)))
    empty = arr == ""
    if empty.any():
        row = int(np.flatnonzero(empty)[0])
        raise ConfigError(f"{table.where(row)}: column '{name}': empty id")
    return arr


# --------------------------------------------------------------------------- images


def _load_images(
    path: Path,
    photo_ids: tuple[str, ...],
    principal_distance: float,
    reduce: Callable[[FloatArray, IntArray], FloatArray],
    default_sigma: float,
) -> ImageObservations:
    table = _read_csv(path, IMAGE_COLUMNS, "[images] file")
    photo = _id_column(table, "photo")
    point = _id_column(table, "point")
    x, _ = _float_column(table, "x")
    y, _ = _float_column(table, "y")
    if "sigma" in table.columns:
        sigma, empty = _float_column(table, "sigma", allow_empty=True, positive=True)
        sigma[empty] = default_sigma
    else:
        sigma = np.full(table.n_rows, default_sigma)

    photo_names, photo_first, photo_inverse = np.unique(
        photo, return_index=True, return_inverse=True
    )
    order_of = {pid: i for i, pid in enumerate(photo_ids)}
    name_index = np.array([order_of.get(str(n), -1) for n in photo_names], dtype=np.intp)
    unknown = np.flatnonzero(name_index < 0)
    if unknown.size:
        row = int(photo_first[unknown].min())
        raise ConfigError(
            f"{table.where(row)}: photo '{photo[row]}' is not in [strip] photos "
            f"of the project file"
        )
    present = set(name_index.tolist())
    for i, pid in enumerate(photo_ids):
        if i not in present:
            raise ConfigError(
                f"{path}: photo '{pid}' (listed in [strip] photos) has no observations"
            )
    photo_index = name_index[photo_inverse.reshape(-1)]
    point_names, point_index = np.unique(point, return_inverse=True)
    point_index = point_index.reshape(-1).astype(np.intp)

    key = photo_index.astype(np.int64) * max(len(point_names), 1) + point_index
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    dup = np.flatnonzero(sorted_key[1:] == sorted_key[:-1])
    if dup.size:
        later = order[dup + 1]
        d = int(np.argmin(table.line[later]))
        first, second = int(order[dup[d]]), int(later[d])
        raise ConfigError(
            f"{table.where(second)}: duplicate observation of point '{point[second]}' on "
            f"photo '{photo[second]}' (first at line {table.line[first]})"
        )

    xy = reduce(np.column_stack([x, y])[order], photo_index[order])
    lines = table.line[order]
    problems = image_coordinate_problems(
        xy, principal_distance, where=lambda k: f"{path}:{int(lines[k])}", file=str(path)
    )
    if problems:
        raise ConfigError(problems[0])
    return ImageObservations(
        photo_ids=photo_ids,
        point_ids=tuple(point_names.tolist()),
        photo=_readonly(photo_index[order]),
        point=_readonly(point_index[order]),
        xy=_readonly(xy),
        sigma=_readonly(sigma[order]),
        principal_distance=float(principal_distance),
        source_line=_readonly(table.line[order]),
    )


# --------------------------------------------------------------------------- interior


def _image_options(toml_path: Path, images: dict[str, object]) -> ImageOptions:
    """``[images]`` units, pixel keys and flight direction, checked together."""
    units: ImageUnits = images["units"]  # type: ignore[assignment]
    pixel_keys = ("pixel_size_mm", "principal_point_px")
    if units is ImageUnits.PIXEL:
        for key in pixel_keys:
            if images[key] is None:
                raise ConfigError(f'{toml_path}: [images] {key}: required with units = "pixel"')
    else:
        for key in pixel_keys:
            if images[key] is not None:
                raise ConfigError(
                    f'{toml_path}: [images] {key}: only used with units = "pixel" (units is "mm")'
                )
    pp = images["principal_point_px"]
    return ImageOptions(
        units=units,
        pixel_size_mm=None if images["pixel_size_mm"] is None else float(images["pixel_size_mm"]),  # type: ignore[arg-type]
        principal_point_px=None if pp is None else _readonly(np.asarray(pp, dtype=np.float64)),
        flight_direction=images["flight_direction"],  # type: ignore[arg-type]
    )


def _load_fiducials(
    path: Path,
    photo_ids: tuple[str, ...],
    images: ImageOptions,
    interior: dict[str, object],
) -> tuple[FiducialFit, ...]:
    """Read the fiducial CSV and fit each photo's comparator -> calibrated transformation."""
    calibrated: dict[str, tuple[float, float]] = interior["calibrated"]  # type: ignore[assignment]
    kind: FiducialTransform = interior["transform"]  # type: ignore[assignment]
    table = _read_csv(path, FIDUCIAL_COLUMNS, "[interior_orientation] fiducials_file")
    photo = _id_column(table, "photo")
    mark = _id_column(table, "mark")
    x, _ = _float_column(table, "x")
    y, _ = _float_column(table, "y")
    order_of = {pid: i for i, pid in enumerate(photo_ids)}
    photo_index = np.empty(table.n_rows, dtype=np.intp)
    seen: dict[tuple[str, str], int] = {}
    for row, (pid, mid) in enumerate(zip(photo.tolist(), mark.tolist(), strict=True)):
        if pid not in order_of:
            raise ConfigError(f"{table.where(row)}: photo '{pid}' is not in [strip] photos")
        if mid not in calibrated:
            raise ConfigError(
                f"{table.where(row)}: mark '{mid}' is not in [interior_orientation] calibrated"
                f"{_suggest(mid, list(calibrated))}"
            )
        if (pid, mid) in seen:
            raise ConfigError(
                f"{table.where(row)}: mark '{mid}' of photo '{pid}' is listed twice "
                f"(first at line {seen[(pid, mid)]})"
            )
        seen[(pid, mid)] = int(table.line[row])
        photo_index[row] = order_of[pid]
    need = 2 if kind is FiducialTransform.SIMILARITY else 3
    counts = np.bincount(photo_index, minlength=len(photo_ids))
    for i, pid in enumerate(photo_ids):
        if counts[i] < need:
            raise ConfigError(
                f"{path}: photo '{pid}' has {counts[i]} fiducial mark(s); a {kind.value} "
                f"transformation needs at least {need}"
            )
    measured = np.column_stack([x, y])
    if images.units is ImageUnits.PIXEL:
        measured = mm_from_pixel(measured, images.pixel_size_mm, images.principal_point_px)  # type: ignore[arg-type]
    target = np.array([calibrated[m] for m in mark.tolist()], dtype=np.float64).reshape(-1, 2)
    try:
        return fit_fiducial_transforms(
            photo_index,
            measured,
            target,
            photo_ids,
            kind,
            marks=tuple(mark.tolist()),
            scale_tolerance=float(interior["scale_tolerance"]),  # type: ignore[arg-type]
            difference_tolerance=float(interior["difference_tolerance"]),  # type: ignore[arg-type]
        )
    except GeometryError as exc:
        raise ConfigError(f"{path}: {exc}") from None


# --------------------------------------------------------------------------- control


def _load_control(
    path: Path, default_sigma_xy: float, default_sigma_h: float
) -> tuple[_CsvTable, np.ndarray, FloatArray, np.ndarray, FloatArray, FloatArray]:
    """Parse and check control.csv; returns table, ids, xyz, kinds, sigma_xy, sigma_h."""
    table = _read_csv(path, CONTROL_COLUMNS, "[control] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no control points (only a header)")
    ids = _id_column(table, "point")
    xyz = np.empty((table.n_rows, 3))
    given = np.empty((table.n_rows, 3), dtype=bool)
    for j, name in enumerate(("X", "Y", "H")):
        values, empty = _float_column(table, name, allow_empty=True)
        xyz[:, j] = values
        given[:, j] = ~empty

    type_strings = np.char.lower(_id_column(table, "type"))
    valid = [t.value for t in ControlType]
    type_names, type_first, type_inverse = np.unique(
        type_strings.reshape(-1), return_index=True, return_inverse=True
    )
    bad_types = [i for i, t in enumerate(type_names) if t not in valid]
    if bad_types:
        row = int(min(type_first[i] for i in bad_types))
        got = table.columns["type"][row].strip()
        raise ConfigError(
            f"{table.where(row)}: column 'type': unknown type '{got}'{_suggest(got, valid)}; "
            f"valid types: {', '.join(valid)}"
        )
    kind_codes = np.array([valid.index(t) for t in type_names], dtype=np.intp)[
        type_inverse.reshape(-1)
    ]
    full, plan, height, check = (kind_codes == i for i in range(4))
    gx, gy, gh = given.T
    rules = (
        (full & ~(gx & gy & gh), "a full point needs X, Y and H"),
        (plan & ~(gx & gy), "a plan point needs X and Y"),
        (plan & gh, "a plan point leaves H empty"),
        (height & ~gh, "a height point needs H"),
        (height & (gx | gy), "a height point leaves X and Y empty"),
        (check & (gx != gy), "a check point gives both X and Y or neither"),
        (check & ~gx & ~gh, "a check point needs X and Y, or H, or all three"),
    )
    found = [(int(np.flatnonzero(mask)[0]), text) for mask, text in rules if mask.any()]
    if found:
        row, text = min(found)
        raise ConfigError(
            f"{table.where(row)}: point '{ids[row]}' of type '{valid[kind_codes[row]]}': {text}"
        )

    _, first, inverse, counts = np.unique(
        ids, return_index=True, return_inverse=True, return_counts=True
    )
    if (counts > 1).any():
        inverse = inverse.reshape(-1)
        is_repeat = (counts[inverse] > 1) & (np.arange(ids.shape[0]) != first[inverse])
        row = int(np.flatnonzero(is_repeat)[0])
        raise ConfigError(
            f"{table.where(row)}: point '{ids[row]}' is listed twice "
            f"(first at line {table.line[first[inverse[row]]]})"
        )

    sigmas = []
    for name, default in (("sigma_xy", default_sigma_xy), ("sigma_h", default_sigma_h)):
        if name in table.columns:
            values, empty = _float_column(table, name, allow_empty=True, positive=True)
            values[empty] = default
        else:
            values = np.full(table.n_rows, default)
        sigmas.append(values)
    kinds = np.array([ControlType(v) for v in valid], dtype=object)[kind_codes]
    return table, ids, xyz, kinds, sigmas[0], sigmas[1]


def _check_crs(
    toml_name: Path, crs: str, route: Route | None, table: _CsvTable, xyz: FloatArray
) -> tuple[Route, list[str]]:
    """Validate ``crs`` with pyproj, choose the route and check geographic ranges."""
    warnings: list[str] = []
    if crs == "local":
        if route is Route.GEOCENTRIC:
            raise ConfigError(
                f'{toml_name}: [adjustment] route: "geocentric" needs a geodetic CRS; '
                f'with crs = "local" only "projected" applies'
            )
        return Route.PROJECTED, warnings
    import pyproj  # deferred: only loading a geodetic project needs it

    try:
        crs_obj = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as exc:
        detail = str(exc).split(": (", 1)[0]
        raise ConfigError(
            f"{toml_name}: [control] crs: not a CRS pyproj understands: '{crs}' ({detail})"
        ) from None
    if crs_obj.is_geocentric:
        raise ConfigError(
            f"{toml_name}: [control] crs: '{crs}' is geocentric; give a horizontal "
            "(projected or geographic) CRS"
        )
    if crs_obj.is_vertical:
        raise ConfigError(
            f"{toml_name}: [control] crs: '{crs}' has a vertical component, but H must be "
            "the ellipsoidal height; give the horizontal CRS only"
        )
    if not (crs_obj.is_projected or crs_obj.is_geographic):
        raise ConfigError(
            f"{toml_name}: [control] crs: '{crs}' is neither projected nor geographic"
        )
    chosen = Route.GEOCENTRIC if route is None else route
    if crs_obj.is_geographic:
        if chosen is Route.PROJECTED:
            raise ConfigError(
                f'{toml_name}: [adjustment] route: "projected" needs a projected CRS or '
                f"\"local\"; '{crs}' is geographic (longitude, latitude)"
            )
        _check_geographic_ranges(crs, table, xyz)
    else:
        unit = crs_obj.axis_info[0].unit_name if crs_obj.axis_info else "metre"
        if unit not in ("metre", "meter") and chosen is Route.PROJECTED:
            warnings.append(
                f"{toml_name}: [control] crs: '{crs}' has X, Y in {unit}, but H is in metres; "
                "the projected route mixes the two"
            )
    return chosen, warnings


def _check_geographic_ranges(crs: str, table: _CsvTable, xyz: FloatArray) -> None:
    """Longitude X and latitude Y in range (NaN cells pass), for a geographic ``crs``."""
    lon, lat = xyz[:, 0], xyz[:, 1]
    for bad, text in (
        (np.abs(lat) > 90.0, "latitude Y outside -90..90 degrees"),
        (np.abs(lon) > 360.0, "longitude X outside -360..360 degrees"),
    ):
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ConfigError(
                f"{table.where(row)}: {text} (crs '{crs}' is geographic: X is the "
                "longitude and Y the latitude, in degrees)"
            )


def _is_geographic(crs: str) -> bool:
    """True for a geographic CRS (already validated by :func:`_check_crs`)."""
    if crs == "local":
        return False
    import pyproj

    return bool(pyproj.CRS.from_user_input(crs).is_geographic)


# --------------------------------------------------------------------------- GNSS, IMU


def _strip_rows(
    table: _CsvTable, photo: np.ndarray, photo_ids: tuple[str, ...], notes: list[str]
) -> IntArray:
    """Rows of ``table`` whose photo is in the strip, in strip order.

    A photo listed twice is an error naming both lines.  Rows of photos that
    are not in ``[strip] photos`` are left out with one warning naming the
    first of them, appended to ``notes`` and emitted as
    :class:`~strip_aerotri.errors.StripAerotriWarning` at the caller of
    :func:`load_project`.
    """
    _, first, inverse, counts = np.unique(
        photo, return_index=True, return_inverse=True, return_counts=True
    )
    if (counts > 1).any():
        inverse = inverse.reshape(-1)
        is_repeat = (counts[inverse] > 1) & (np.arange(photo.shape[0]) != first[inverse])
        row = int(np.flatnonzero(is_repeat)[0])
        raise ConfigError(
            f"{table.where(row)}: photo '{photo[row]}' is listed twice "
            f"(first at line {table.line[first[inverse[row]]]})"
        )
    order_of = {pid: i for i, pid in enumerate(photo_ids)}
    index = np.array([order_of.get(pid, -1) for pid in photo.tolist()], dtype=np.intp)
    unknown = np.flatnonzero(index < 0)
    if unknown.size:
        shown = ", ".join(f"'{photo[i]}'" for i in unknown[:5])
        more = f" and {unknown.size - 5} more" if unknown.size > 5 else ""
        text = (
            f"{table.where(int(unknown[0]))}: {unknown.size} row(s) of photo(s) not in "
            f"[strip] photos ignored: {shown}{more}"
        )
        notes.append(text)
        # _strip_rows <- _load_gnss / _load_imu <- load_project <- caller
        _warnings.warn(text, StripAerotriWarning, stacklevel=4)
    known = np.flatnonzero(index >= 0)
    return known[np.argsort(index[known], kind="stable")]


def _optional_sigma(table: _CsvTable, name: str, default: float) -> FloatArray:
    """Positive column ``name`` with ``default`` where absent or empty."""
    if name not in table.columns:
        return np.full(table.n_rows, default)
    values, empty = _float_column(table, name, allow_empty=True, positive=True)
    values[empty] = default
    return values


def _load_gnss(
    path: Path,
    photo_ids: tuple[str, ...],
    gnss: dict[str, object],
    crs: str,
    notes: list[str],
) -> GnssCentres:
    """Read the GNSS centres CSV (``[gnss] file``)."""

    table = _read_csv(path, GNSS_COLUMNS, "[gnss] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no GNSS centres (only a header)")
    photo = _id_column(table, "photo")
    xyz = np.column_stack([_float_column(table, name)[0] for name in ("X", "Y", "Z")])
    sigma_xy = _optional_sigma(table, "sigma_xy", float(gnss["sigma_xy"]))  # type: ignore[arg-type]
    sigma_z = _optional_sigma(table, "sigma_z", float(gnss["sigma_z"]))  # type: ignore[arg-type]
    if _is_geographic(crs):
        _check_geographic_ranges(crs, table, xyz)
    rows = _strip_rows(table, photo, photo_ids, notes)
    return GnssCentres(tuple(photo[rows].tolist()), xyz[rows], sigma_xy[rows], sigma_z[rows])


def _load_imu(
    path: Path, photo_ids: tuple[str, ...], imu: dict[str, object], notes: list[str]
) -> ImuAttitudes:
    """Read the IMU attitudes CSV (``[imu] file``), degrees in the file, radians out."""

    table = _read_csv(path, IMU_COLUMNS, "[imu] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no IMU attitudes (only a header)")
    photo = _id_column(table, "photo")
    opk = np.column_stack([_float_column(table, n)[0] for n in ("omega", "phi", "kappa")])
    sigma = _optional_sigma(table, "sigma_deg", float(imu["sigma_deg"]))  # type: ignore[arg-type]
    rows = _strip_rows(table, photo, photo_ids, notes)
    return ImuAttitudes.from_degrees(tuple(photo[rows].tolist()), opk[rows], sigma[rows])


def _needs_bundle(toml_path: Path, name: str, what: str, refine: Refine) -> None:
    if refine is not Refine.BUNDLE:
        raise ConfigError(
            f"{toml_path}: [{name}]: {what} are observations of the bundle refinement only; "
            f'add refine = "bundle" to [adjustment], or remove [{name}]'
        )


# --------------------------------------------------------------------------- output


def _is_within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_directory(
    directory: str | Path, project: Project, *, source: str = "--out"
) -> Path:
    """Check that results may be written to ``directory``.

    Parameters
    ----------
    directory : str or Path
        The result folder (relative paths are relative to the current folder,
        as for a command-line option).
    project : Project
        The loaded project, whose input files are protected.
    source : str
        Where the folder came from, for messages (e.g. ``"--out"``).

    Returns
    -------
    Path
        ``directory`` as a Path.

    Raises
    ------
    ConfigError
        If the folder is the project folder, contains an input file, or is a file.
    """
    return _check_output(Path(directory), project.input_files, source)


def _check_output(directory: Path, inputs: Sequence[Path], source: str) -> Path:
    target = directory.resolve()
    if target.exists() and not target.is_dir():
        raise ConfigError(f"{source}: output folder '{directory}' is a file")
    project_dir = inputs[0].resolve().parent
    if target == project_dir:
        raise ConfigError(
            f"{source}: output folder '{directory}' is the project folder; "
            'choose a folder of its own (e.g. "out")'
        )
    for item in inputs:
        if _is_within(item.resolve(), target):
            raise ConfigError(
                f"{source}: output folder '{directory}' contains the input file '{item}'; "
                "results replace the whole folder"
            )
    return directory


# --------------------------------------------------------------------------- project


def load_project(path: str | Path) -> Project:
    """Read and validate a project file and the CSVs it names.

    Parameters
    ----------
    path : str or Path
        The project file (``strip.toml``); paths inside are relative to its folder.

    Returns
    -------
    Project
        Image coordinates in mm reduced to the principal point, ground in the
        control CRS (metres for heights), options as enums.  Control points
        that no photo observes are left out and named in ``Project.warnings``.

    Raises
    ------
    ConfigError
        On the first rule broken, with a one-line message naming the file and
        the line (CSV) or key (TOML), see ``docs/project-file.md``.

    Notes
    -----
    Input files are only read, never written.
    """
    toml_path = Path(path)
    folder = toml_path.parent
    doc = _read_toml(toml_path)

    for name, content in doc.items():
        spec = _TABLES_BY_NAME.get(name)
        if spec is None:
            owners = [s.qualified for s in PROJECT_KEYS if s.key == name]
            hint = (
                f" (keys belong in a table: did you mean {owners[0]}?)"
                if owners and not isinstance(content, dict)
                else _suggest(name, list(_TABLES_BY_NAME))
            )
            is_table = isinstance(content, dict) or (
                isinstance(content, list) and all(isinstance(c, dict) for c in content) and content
            )
            what = "table" if is_table else "top-level key"
            raise ConfigError(
                f"{toml_path}: unknown {what} '{name}'{hint}; valid tables: "
                f"{', '.join(_TABLES_BY_NAME)}"
            )
        if spec.array:
            if not isinstance(content, list) or not all(isinstance(c, dict) for c in content):
                raise ConfigError(
                    f"{toml_path}: '{name}' must be an array of tables, written [[{name}]]"
                )
        elif not isinstance(content, dict):
            raise ConfigError(
                f"{toml_path}: '{name}' must be a table, written [{name}], "
                f"got {_describe(content)}"
            )
    for spec in PROJECT_TABLES:
        if spec.required and spec.name not in doc:
            raise ConfigError(f"{toml_path}: missing required table [{spec.name}]")

    def table(name: str) -> dict[str, object]:
        return _check_table(str(toml_path), name, doc.get(name, {}), f"[{name}]")

    strip, camera, images = table("strip"), table("camera"), table("images")
    control, adjustment = table("control"), table("adjustment")
    output, report = table("output"), table("report")
    blunders = _blunder_options(toml_path, table("blunders"))
    distortion_table = table("distortion") if "distortion" in doc else None
    interior = table("interior_orientation") if "interior_orientation" in doc else None
    gnss_table = table("gnss") if "gnss" in doc else None
    imu_table = table("imu") if "imu" in doc else None
    if gnss_table is not None:
        _needs_bundle(toml_path, "gnss", "GNSS centres", adjustment["refine"])  # type: ignore[arg-type]
    if imu_table is not None:
        _needs_bundle(toml_path, "imu", "IMU attitudes", adjustment["refine"])  # type: ignore[arg-type]
    lines_raw = [
        _check_table(str(toml_path), "straight_line", content, f"[[straight_line]] #{i}")
        for i, content in enumerate(doc.get("straight_line", []), start=1)
    ]

    photo_ids: tuple[str, ...] = strip["photos"]  # type: ignore[assignment]
    if len(photo_ids) < 2:
        raise ConfigError(
            f"{toml_path}: [strip] photos: a strip needs at least two photos, got {len(photo_ids)}"
        )
    name = strip["name"] if strip["name"] is not None else folder.resolve().name
    crs = str(control["crs"])
    if crs.lower() == "local":
        crs = "local"

    principal_point: tuple[float, float] = camera["principal_point_mm"]  # type: ignore[assignment]
    principal_distance = float(camera["principal_distance_mm"])  # type: ignore[arg-type]
    images_file = folder / str(images["file"])
    control_file = folder / str(control["file"])
    gnss_file = None if gnss_table is None else folder / str(gnss_table["file"])
    imu_file = None if imu_table is None else folder / str(imu_table["file"])
    output_directory = None
    if output["directory"] is not None:
        extra = (
            None if interior is None else folder / str(interior["fiducials_file"]),
            gnss_file,
            imu_file,
        )
        output_directory = _check_output(
            folder / str(output["directory"]),
            (toml_path, images_file, control_file, *(f for f in extra if f is not None)),
            f"{toml_path}: [output] directory",
        )

    image_options = _image_options(toml_path, images)
    distortion = None
    if distortion_table is not None:
        distortion = BrownDistortion(**distortion_table)  # type: ignore[arg-type]
    fiducials: tuple[FiducialFit, ...] = ()
    fiducials_file = None
    warnings: list[str] = []
    if interior is not None:
        fiducials_file = folder / str(interior["fiducials_file"])
        fiducials = _load_fiducials(fiducials_file, photo_ids, image_options, interior)
        warnings += [f"{fiducials_file}: {fit.message()}" for fit in fiducials if not fit.passed]

    def reduce(xy: FloatArray, photo: IntArray) -> FloatArray:
        try:
            return reduce_image_coordinates(
                xy,
                photo,
                principal_distance,
                units=image_options.units,
                pixel_size_mm=image_options.pixel_size_mm,
                principal_point_px=image_options.principal_point_px,
                fiducials=fiducials or None,
                principal_point_mm=principal_point,
                distortion=distortion,
                flight_direction=image_options.flight_direction,
            )
        except ConvergenceError as exc:
            raise ConfigError(f"{toml_path}: [distortion]: {exc}") from None

    observations = _load_images(
        images_file,
        photo_ids,
        principal_distance,
        reduce,
        float(images["sigma_mm"]),  # type: ignore[arg-type]
    )
    table_c, ids, xyz, kinds, sigma_xy, sigma_h = _load_control(
        control_file,
        float(control["sigma_xy_m"]),  # type: ignore[arg-type]
        float(control["sigma_h_m"]),  # type: ignore[arg-type]
    )
    route, crs_warnings = _check_crs(
        toml_path,
        crs,
        adjustment["route"],  # type: ignore[arg-type]
        table_c,
        xyz,
    )
    warnings += crs_warnings
    gnss = (
        None if gnss_file is None else _load_gnss(gnss_file, photo_ids, gnss_table, crs, warnings)
    )  # type: ignore[arg-type]
    imu = None if imu_file is None else _load_imu(imu_file, photo_ids, imu_table, warnings)  # type: ignore[arg-type]

    observed = set(observations.point_ids)
    is_observed = np.fromiter((i in observed for i in ids.tolist()), bool, count=ids.shape[0])
    for row in np.flatnonzero(~is_observed):
        warnings.append(
            f"{table_c.where(int(row))}: control point '{ids[row]}' ({kinds[row].value}) is "
            "not observed on any photo; left out"
        )
    keep = np.flatnonzero(is_observed)
    control_points = ControlPoints(
        point_ids=tuple(ids[keep].tolist()),
        xyz=_readonly(xyz[keep]),
        kind=tuple(kinds[keep].tolist()),
        sigma_xy=_readonly(sigma_xy[keep]),
        sigma_h=_readonly(sigma_h[keep]),
        source_line=_readonly(table_c.line[keep]),
    )

    rays = np.bincount(observations.point, minlength=observations.n_points)
    single = np.flatnonzero(rays < 2)
    if single.size:
        shown = ", ".join(f"'{observations.point_ids[i]}'" for i in single[:5])
        more = f" and {single.size - 5} more" if single.size > 5 else ""
        warnings.append(
            f"{images_file}: {single.size} point(s) observed on one photo only cannot be "
            f"triangulated: {shown}{more}"
        )

    control_ids = {
        pid
        for pid, kind in zip(control_points.point_ids, control_points.kind, strict=True)
        if kind is not ControlType.CHECK
    }
    straight_lines = []
    names_seen: dict[str, int] = {}
    for i, raw in enumerate(lines_raw, start=1):
        label = f"{toml_path}: [[straight_line]] #{i}"
        points: tuple[str, ...] = raw["points"]  # type: ignore[assignment]
        if len(points) < 3:
            raise ConfigError(
                f"{label} points: a straight line needs at least three points "
                f"(two fix the line alone), got {len(points)}"
            )
        for pid in points:
            if pid not in observed:
                raise ConfigError(
                    f"{label} points: point '{pid}' is not observed on any photo in {images_file}"
                )
            if pid in control_ids:
                raise ConfigError(
                    f"{label} points: point '{pid}' is a control point in {control_file}; "
                    "line points have no ground coordinates"
                )
        line_name = str(raw["name"]) if raw["name"] is not None else f"line {i}"
        if line_name in names_seen:
            raise ConfigError(
                f"{label} name: '{line_name}' is already the name of line #{names_seen[line_name]}"
            )
        names_seen[line_name] = i
        straight_lines.append(
            LineSpec(points, float(raw["weight"]), line_name)  # type: ignore[arg-type]
        )

    polynomial: int | Literal["auto"] = adjustment["polynomial"]  # type: ignore[assignment]
    sections = int(adjustment["sections"])  # type: ignore[call-overload]
    if sections > 1 and polynomial == 0:
        raise ConfigError(
            f"{toml_path}: [adjustment] sections: {sections} sections need a polynomial type "
            '1, 2, 3 or "auto", got polynomial = 0'
        )
    raw_adjustment = doc.get("adjustment", {})
    named = [key for key in ("polynomial", "sections") if key in raw_adjustment]
    block = adjustment["block"]
    if block is None:
        block = Construction.STRIPS if named else Construction.MODELS
    elif block is Construction.MODELS and named:
        raise ConfigError(
            f'{toml_path}: [adjustment] {named[0]}: applies to block = "strips" (J\'s '
            'polynomials); with block = "models" every model has its own similarity. Remove '
            f'{named[0]} or set block = "strips"'
        )
    options = AdjustmentOptions(
        route=route,
        polynomial=polynomial,
        sections=sections,
        relative_orientation=adjustment["relative_orientation"],  # type: ignore[arg-type]
        intersection=adjustment["intersection"],  # type: ignore[arg-type]
        scale_transfer=adjustment["scale_transfer"],  # type: ignore[arg-type]
        max_iterations=int(adjustment["max_iterations"]),  # type: ignore[call-overload]
        photo_step=adjustment["photo_step"],  # type: ignore[arg-type]
        min_base_to_height=float(adjustment["min_base_to_height"]),  # type: ignore[arg-type]
        refine=adjustment["refine"],  # type: ignore[arg-type]
        block=block,  # type: ignore[arg-type]
    )
    map_scale = report["map_scale"]
    return Project(
        path=toml_path,
        name=str(name),
        photo_ids=photo_ids,
        camera=Camera(principal_distance, _readonly(np.asarray(principal_point, np.float64))),
        observations=observations,
        control=control_points,
        crs=crs,
        straight_lines=tuple(straight_lines),
        adjustment=options,
        output_directory=output_directory,
        warnings=tuple(warnings),
        images_file=images_file,
        control_file=control_file,
        report=ReportOptions(None if map_scale is None else float(map_scale)),  # type: ignore[arg-type]
        images=image_options,
        distortion=distortion,
        fiducials=fiducials,
        fiducials_file=fiducials_file,
        blunders=blunders,
        gnss=gnss,
        imu=imu,
        gnss_file=gnss_file,
        imu_file=imu_file,
    )


def _blunder_options(toml_path: Path, table: dict[str, object]) -> BlunderOptions:
    """``[blunders]`` as :class:`~strip_aerotri.blunders.BlunderOptions`."""
    where = f"{toml_path}: [blunders]"
    alpha = float(table["alpha"])  # type: ignore[arg-type]
    if not alpha < 1.0:
        raise ConfigError(f"{where} alpha: expected a probability below 1, got {alpha!r}")
    fraction = float(table["max_fraction"])  # type: ignore[arg-type]
    if fraction > 1.0:
        raise ConfigError(f"{where} max_fraction: expected at most 1, got {fraction!r}")
    pairs = []
    for item in table["exclude_observations"]:  # type: ignore[union-attr]
        photo, sep, point = str(item).partition("/")
        if not sep or not photo or not point:
            raise ConfigError(
                f'{where} exclude_observations: expected "photo/point", got {item!r}'
            )
        pairs.append((photo, point))
    critical = {
        stage: float(table[stage])  # type: ignore[arg-type]
        for stage in STAGES
        if table[stage] is not None
    }
    return BlunderOptions(
        action=BlunderAction.create(table["action"]),
        alpha=alpha,
        critical_values=critical,
        max_fraction=fraction,
        exclude_points=tuple(table["exclude_points"]),  # type: ignore[arg-type]
        exclude_observations=tuple(pairs),
    )
