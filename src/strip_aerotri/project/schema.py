"""The schema of a project: its tables, keys and CSV columns.

:data:`PROJECT_TABLES` and :data:`PROJECT_KEYS` list every valid table and
key of ``strip.toml`` with its type, unit, default and rule;
:data:`IMAGE_COLUMNS`, :data:`FIDUCIAL_COLUMNS`, :data:`CONTROL_COLUMNS`,
:data:`GNSS_COLUMNS` and :data:`IMU_COLUMNS` the columns of the CSV files.
The loader validates against them, ``stripaero check`` lists them, and a
test holds ``docs/project-file.md`` to them.
"""

from __future__ import annotations

import difflib
import math
import re
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from .._text import MAX_ECHO, clean, shorten
from ..errors import ConfigError
from ..options import (
    ANGLE_SIGMA_RANGE_DEG,
    DEFAULT_ALPHA,
    DEFAULT_DIFFERENCE_TOLERANCE,
    DEFAULT_GNSS_SIGMA_XY_M,
    DEFAULT_GNSS_SIGMA_Z_M,
    DEFAULT_IMAGE_SIGMA_MM,
    DEFAULT_IMU_SIGMA_DEG,
    DEFAULT_LINE_WEIGHT,
    DEFAULT_MAX_FRACTION,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_MIN_BASE_TO_HEIGHT,
    DEFAULT_PHOTO_STEP,
    DEFAULT_POLYNOMIAL,
    DEFAULT_SCALE_TOLERANCE,
    DEFAULT_SECTIONS,
    DEFAULT_SIGMA_H_M,
    DEFAULT_SIGMA_XY_M,
    GROUND_SIGMA_RANGE_M,
    IMAGE_SIGMA_RANGE_MM,
    RULES,
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
    OptionError,
    Refine,
    RelativeOrientationMethod,
    Route,
    ScaleTransfer,
    Weights,
    describe,
)


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
        True for keys of the stable contract (docs/project-file.md), False for the
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
        table = TABLES_BY_NAME[self.table]
        brackets = f"[[{self.table}]]" if table.array else f"[{self.table}]"
        return f"{brackets} {self.key}"


PROJECT_TABLES: tuple[TableSpec, ...] = (
    TableSpec("project", False, False, "the project's name, for the report's title"),
    TableSpec("strip", False, False, "the strip: its name and photos in flight order"),
    TableSpec(
        "strips", False, True, "a block: one table per strip, its name and photos in flight order"
    ),
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


TABLES_BY_NAME = {t.name: t for t in PROJECT_TABLES}

#: Longest id (photo, point, mark) in characters; ids are kept as arrays of
#: fixed-width strings, whose size is rows x the longest id.
MAX_ID_LENGTH = 128
#: Longest name (of a strip, a line) in characters, as drawn in figures.
MAX_NAME_LENGTH = 200
#: Largest magnitude of a distortion coefficient (the keys of kind "number"):
#: real ones are below 1 (normalised) or 1e-3 (mm); far beyond, the
#: polynomials overflow.
MAX_COEFFICIENT = 1e6
#: Longest other string value (a CRS may be given as WKT) and path.
MAX_STRING_LENGTH = 65536
MAX_PATH_LENGTH = 4096


# fmt: off
PROJECT_KEYS: tuple[KeySpec, ...] = (
    KeySpec(
        "project", "name", "string", required=False, default=None, unit="",
        description="Name of the project (the client's job), the title of the report and "
        "of the run's summary; overrides [strip] name there.",
        contract=False,
        default_text="[strip] name; for a block the name of the folder holding strip.toml",
    ),
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
        "strips", "name", "string", required=False, default=None, unit="",
        description="Name of the strip of a block, used in reports.",
        default_text='"1", "2", ... in file order',
    ),
    KeySpec(
        "strips", "photos", "list of ids", required=True, default=None, unit="",
        description="Photo ids of the strip in its flight order; at least two; a photo in "
        "one strip only.",
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
        description='Side of a square pixel; required with units = "pixel". With units = '
        '"mm" (an extension) it may be given together with principal_point_px: they then '
        "only tell the exports that need pixels (export odm) how to convert.",
        contract=False,
        default_text="none",
    ),
    KeySpec(
        "images", "principal_point_px", "pair of numbers", required=False, default=None,
        unit="px",
        description="Column c0 and row r0 of the origin of the image coordinates (principal "
        'point or image centre): x = (col - c0) s, y = -(row - r0) s. Required with units = '
        '"pixel"; with units = "mm" only together with pixel_size_mm (see there).',
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
        "distortion", "b1", "number", required=False, default=0.0, unit="",
        description="Affinity: b1 x added to x (Fraser 1997).", contract=False,
    ),
    KeySpec(
        "distortion", "b2", "number", required=False, default=0.0, unit="",
        description="Shear: b2 y added to x (Fraser 1997).", contract=False,
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
        "adjustment", "models", "choice", required=False,
        default=ModelFormation.DEPENDENT, unit="",
        description='How the strip is formed: "dependent" (J: chained pairs with scale '
        'transfer) or "independent" (R4 2.2: each pair its own model in B\'s base system, '
        "joined to the strip by a 3D similarity on its tie points and the common projection "
        "centre; the doubly determined points compared and averaged).",
        default_text='"dependent"',
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
        "adjustment", "self_calibration", "self calibration", required=False, default="none",
        unit="",
        description='With refine = "bundle" only: "none"; "auto" (the parameters the data '
        "determine and that are significant, chosen by t values and correlations); a list "
        'from ["c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1", "b2"] (Brown/Fraser, '
        'estimated as given); or "ebner12" (film: Ebner\'s 12 parameters). One camera '
        "shared by all photos, starting from [camera] and [distortion]; the adjusted camera "
        "is written to camera.toml.",
        default_text='"none"',
    ),
    KeySpec(
        "adjustment", "weights", "choice", required=False, default=Weights.GIVEN, unit="",
        description='With refine = "bundle" only: "given" (the stated sigmas of the image '
        'coordinates, control, GNSS and IMU) or "estimated" (each group\'s sigma estimated '
        "from its residuals by variance components and the bundle adjusted with them; "
        "report.json bundle.variance_components).",
        default_text='"given"',
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
        "blunders", "alpha", "positive number", required=False, default=DEFAULT_ALPHA, unit="",
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
        "blunders", "max_fraction", "positive number", required=False,
        default=DEFAULT_MAX_FRACTION, unit="",
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


_ENUM_OF_KEY: dict[tuple[str, str], type[OptionEnum]] = {
    ("blunders", "action"): BlunderAction,
    ("adjustment", "refine"): Refine,
    ("adjustment", "route"): Route,
    ("adjustment", "block"): Construction,
    ("adjustment", "models"): ModelFormation,
    ("adjustment", "relative_orientation"): RelativeOrientationMethod,
    ("adjustment", "intersection"): IntersectionMethod,
    ("adjustment", "scale_transfer"): ScaleTransfer,
    ("adjustment", "weights"): Weights,
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
    bounds: tuple[float, float] | None = None


IMAGE_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id, one of [strip] photos"),
    ColumnSpec("point", True, "", "point id; the same id is the same ground point on every photo"),
    ColumnSpec("x", True, "mm", "image x, along the flight"),
    ColumnSpec("y", True, "mm", "image y, to the left of the flight"),
    ColumnSpec(
        "sigma",
        False,
        "mm",
        "standard deviation of x and y; empty: [images] sigma_mm",
        IMAGE_SIGMA_RANGE_MM,
    ),
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
        "sigma_xy",
        False,
        "m",
        "standard deviation of X and Y; empty: [control] sigma_xy_m",
        GROUND_SIGMA_RANGE_M,
    ),
    ColumnSpec(
        "sigma_h",
        False,
        "m",
        "standard deviation of H; empty: [control] sigma_h_m",
        GROUND_SIGMA_RANGE_M,
    ),
)


GNSS_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id; rows of photos not in [strip] photos are ignored"),
    ColumnSpec("X", True, "CRS unit", "projection centre easting (or longitude in degrees)"),
    ColumnSpec("Y", True, "CRS unit", "projection centre northing (or latitude in degrees)"),
    ColumnSpec("Z", True, "m", "projection centre ellipsoidal height"),
    ColumnSpec(
        "sigma_xy",
        False,
        "m",
        "standard deviation of X and Y; empty: [gnss] sigma_xy",
        GROUND_SIGMA_RANGE_M,
    ),
    ColumnSpec(
        "sigma_z",
        False,
        "m",
        "standard deviation of Z; empty: [gnss] sigma_z",
        GROUND_SIGMA_RANGE_M,
    ),
)


IMU_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("photo", True, "", "photo id; rows of photos not in [strip] photos are ignored"),
    ColumnSpec("omega", True, "deg", "omega of image -> local east-north-up (photos.csv)"),
    ColumnSpec("phi", True, "deg", "phi of image -> local east-north-up (photos.csv)"),
    ColumnSpec("kappa", True, "deg", "kappa of image -> local east-north-up (photos.csv)"),
    ColumnSpec(
        "sigma_deg",
        False,
        "deg",
        "standard deviation of each angle; empty: [imu] sigma_deg",
        ANGLE_SIGMA_RANGE_DEG,
    ),
)


def suggest(word: str, candidates: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` or empty."""
    if len(word) > 2 * MAX_ECHO:  # no key is that long, and difflib would take its time
        return ""
    lower = {c.lower(): c for c in candidates}
    if word.lower() in lower:
        return f" (did you mean '{lower[word.lower()]}'?)"
    match = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean '{match[0]}'?)" if match else ""


def _id_forms(word: str) -> tuple[str, str]:
    """(Unicode NFC form, the form a spreadsheet leaves: NFC, stripped, no
    leading zeros, no ``.0`` tail) of an id."""
    nfc = unicodedata.normalize("NFC", word)
    number = re.fullmatch(r"0*(\d+?)(?:\.0+)?", nfc.strip())
    return nfc, number.group(1) if number else nfc.strip()


class IdHints:
    """For an id not found among ``candidates``, the candidate it differs
    from only in a way the eye does not see or a spreadsheet makes (the
    Unicode form, NFD against NFC; leading zeros dropped, or ``.0`` added to
    a number) or in case, as `` (...)`` naming the cause, or empty.  The
    candidates' forms are computed once, so that many ids can be asked
    about."""

    def __init__(self, candidates: Sequence[str]) -> None:
        self._nfc: dict[str, str] = {}
        self._bare: dict[str, str] = {}
        self._folded: dict[str, str] = {}
        for c in candidates:
            nfc, bare = _id_forms(c)
            self._nfc.setdefault(nfc, c)
            self._bare.setdefault(bare, c)
            self._folded.setdefault(bare.casefold(), c)

    def __call__(self, word: str) -> str:
        if len(word) > 2 * MAX_ECHO:
            return ""
        nfc, bare = _id_forms(word)
        c = self._nfc.get(nfc)
        if c is not None and c != word:
            return (
                f" (it differs from '{c}' only in its Unicode form, decomposed against "
                "composed: save the files with the same normalization, NFC)"
            )
        c = self._bare.get(bare)
        if c is not None and c != word:
            return (
                f" (did you mean '{c}'? a spreadsheet drops leading zeros or writes ids as "
                "numbers: format the id column as text)"
            )
        c = self._folded.get(bare.casefold())
        if c is not None and c != word:
            return f" (did you mean '{c}'? ids are case-sensitive)"
        return ""


def suggest_id(word: str, candidates: Sequence[str]) -> str:
    """:class:`IdHints` for one id, else :func:`suggest`."""
    return IdHints(candidates)(word) or suggest(word, candidates)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _parse_value(spec: KeySpec, value: object, where: str) -> object:
    """Convert one TOML value after checking it against its option's rule
    (:data:`strip_aerotri.options.RULES`) or ``spec.kind``."""
    rule = RULES.get((spec.table, spec.key))
    if rule is not None:
        try:
            return rule(value)
        except OptionError as exc:
            raise ConfigError(f"{where}: {exc.rule}") from None
    kind = spec.kind
    if kind in ("string", "path"):
        if not isinstance(value, str) or not value.strip():
            raise ConfigError(f"{where}: expected a non-empty string, got {describe(value)}")
        what = "a path" if kind == "path" else "a name" if spec.key == "name" else "text"
        _check_text(value, where, _max_length(spec), what)
        return value.strip() if kind == "string" else value
    if kind == "positive number":
        if not _is_number(value):
            raise ConfigError(f"{where}: expected a positive number, got {describe(value)}")
        number = float(value)  # type: ignore[arg-type]
        if not math.isfinite(number) or number <= 0.0:
            raise ConfigError(
                f"{where}: expected a positive finite number, got {shorten(repr(value))}"
            )
        return number
    if kind == "positive integer":
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ConfigError(f"{where}: expected a positive integer, got {describe(value)}")
        return value
    if kind == "pair of numbers":
        if (
            not isinstance(value, list)
            or len(value) != 2
            or not all(_is_number(v) and math.isfinite(v) for v in value)
        ):
            raise ConfigError(
                f"{where}: expected a list of two finite numbers like [0.0, 0.0], got "
                f"{shorten(repr(value))}"
            )
        return (float(value[0]), float(value[1]))
    if kind == "list of ids":
        if not isinstance(value, list):
            raise ConfigError(
                f'{where}: expected a list of id strings like ["1201", "1202"], '
                f"got {describe(value)}"
            )
        for item in value:
            if not isinstance(item, str):
                hint = f' (write "{item}")' if _is_number(item) else ""
                raise ConfigError(f"{where}: ids must be strings, got {describe(item)}{hint}")
            if not item.strip():
                raise ConfigError(f"{where}: ids must not be empty")
            _check_text(item, where, MAX_ID_LENGTH, "an id")
        ids = [item.strip() for item in value]
        seen: set[str] = set()
        for item in ids:
            if item in seen:
                raise ConfigError(f"{where}: id '{shorten(item)}' is listed twice")
            seen.add(item)
        return tuple(ids)
    if kind == "choice":
        enum = _ENUM_OF_KEY[(spec.table, spec.key)]
        if isinstance(value, str):
            member = enum._missing_(value)
            if member is not None:
                return member
        raise ConfigError(
            f"{where}: expected one of {enum.valid_values()} (any case), got {describe(value)}"
        )
    if kind == "number":
        if not _is_number(value) or not math.isfinite(value):  # type: ignore[arg-type]
            raise ConfigError(f"{where}: expected a finite number, got {describe(value)}")
        if abs(float(value)) > MAX_COEFFICIENT:  # type: ignore[arg-type]
            raise ConfigError(
                f"{where}: expected a number from -{MAX_COEFFICIENT:g} to {MAX_COEFFICIENT:g}, "
                f"got {float(value):g} (beyond any lens: a typing error?)"  # type: ignore[arg-type]
            )
        return float(value)  # type: ignore[arg-type]
    if kind == "mark table":
        if not isinstance(value, dict) or len(value) < 2:
            raise ConfigError(
                f'{where}: expected a table of at least two marks like {{ "1" = [-106.0, '
                f'-106.0], "2" = [106.0, 106.0] }}, got {describe(value)}'
            )
        marks: dict[str, tuple[float, float]] = {}
        for mark, xy in value.items():
            if (
                not isinstance(xy, list)
                or len(xy) != 2
                or not all(_is_number(v) and math.isfinite(v) for v in xy)
            ):
                raise ConfigError(
                    f"{where}: mark '{shorten(mark)}': expected a list of two finite numbers "
                    f"(x, y in mm), got {shorten(repr(xy))}"
                )
            marks[str(mark).strip()] = (float(xy[0]), float(xy[1]))
        return marks
    raise AssertionError(f"unhandled kind {kind!r}")  # pragma: no cover


def _max_length(spec: KeySpec) -> int:
    if spec.kind == "path":
        return MAX_PATH_LENGTH
    return MAX_NAME_LENGTH if spec.key == "name" else MAX_STRING_LENGTH


def _check_text(value: str, where: str, limit: int, what: str) -> None:
    """Refuse a string longer than ``limit`` characters or holding control
    characters (a NUL byte, an escape sequence): no name, id or path has them,
    nor a line break or tab (other text, a CRS's WKT, may span lines)."""
    if len(value) > limit:
        raise ConfigError(
            f"{where}: {what} of {len(value)} characters ({shorten(value, 40)}); at most "
            f"{limit} are allowed"
        )
    breaks = what != "text" and any(c in value for c in "\n\r\t")
    if breaks or clean(value) != value:
        raise ConfigError(
            f"{where}: {what} holding a control character (a NUL byte or a terminal escape "
            f"sequence): {shorten(value, 40)!r} as read without them; retype it"
        )


def check_table(
    toml_name: str, table: str, content: dict[str, Any], label: str
) -> dict[str, object]:
    """Validate one table's keys and convert its values (defaults filled in)."""
    specs = {s.key: s for s in PROJECT_KEYS if s.table == table}
    for key in content:
        if key not in specs:
            elsewhere = [s.qualified for s in PROJECT_KEYS if s.key == key and s.table != table]
            hint = f" (it belongs in {elsewhere[0]})" if elsewhere else suggest(key, list(specs))
            raise ConfigError(
                f"{toml_name}: unknown key '{shorten(key)}' in {label}{hint}; "
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
