"""Load ``strip.toml``: :func:`load_project` and the output folder's rules.

:func:`load_project` reads the TOML (:mod:`.schema` says what is valid), the
CSV tables (:mod:`.tables`) and returns a :class:`~.model.Project`; every
failure is one :class:`~strip_aerotri.errors.ConfigError` line naming the
file, the line or key, and the rule broken.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .._text import shorten
from .._typing import FloatArray, IntArray
from ..errors import ConfigError, ConvergenceError
from ..geometry.control_geometry import control_count_problems
from ..interior import (
    BrownDistortion,
    FiducialFit,
    reduce_image_coordinates,
)
from ..observations import (
    ControlPoints,
    ControlType,
    ImageObservations,
    LineSpec,
    StripSpec,
)
from ..options import (
    STAGES,
    AdjustmentOptions,
    BlunderAction,
    BlunderOptions,
    ImageOptions,
    OptionError,
    Refine,
    ReportOptions,
    Route,
    adjustment_options,
    describe,
)
from ..plausibility import image_coordinate_problems
from .camera_checks import (
    camera_problems,
    ebner_on_digital,
    measured_problems,
    principal_distance_problems,
)
from .csvfiles import MAX_TOML_BYTES, CsvTable, decode, read_bytes
from .model import Camera, Project, readonly
from .output import check_output
from .schema import (
    PROJECT_KEYS,
    PROJECT_TABLES,
    TABLES_BY_NAME,
    IdHints,
    check_table,
    suggest,
    suggest_id,
)
from .tables import (
    check_crs,
    load_control,
    load_fiducials,
    load_gnss,
    load_images,
    load_imu,
    read_image_options,
)

__all__ = ["load_project"]


# --------------------------------------------------------------------------- results


# --------------------------------------------------------------------------- helpers


_TOML_POSITION = re.compile(r"\s*\(at line (\d+), column (\d+)\)$")


#: Deepest nesting of tables and arrays in a project file: its deepest value
#: is a list in a table in an array of tables (``[[strips]] photos``).
MAX_TOML_DEPTH = 8
#: Most parts of a dotted key (``a.b.c = 1`` has three); a project's keys
#: have two at most (``camera.principal_distance_mm``).  tomllib takes time
#: quadratic in the parts (20 000 parts: 5 s), so they are counted first.
MAX_KEY_PARTS = 16
# a match starts at the beginning of a bare word or at a quote only, so that a
# long word is scanned once, not once from each of its characters
_KEY_PART = r"(?:(?<![A-Za-z0-9_-])[A-Za-z0-9_-]+|\"[^\"\n]*\"|'[^'\n]*')"
_DOTTED_KEY = re.compile(rf"{_KEY_PART}(?:[ \t]*\.[ \t]*{_KEY_PART}){{{MAX_KEY_PARTS},}}")


_BARE_WORD = re.compile(r"[^\s,\[\]{}\"'#=]+")


def _toml_hint(text: str, message: str, line: int, column: int) -> str:
    """The likely cause of tomllib's ``message`` at ``line``, ``column``
    (1-based) among the mistakes of users of spreadsheets and other formats:
    an id written as a number with leading zeros, a string without quotes, a
    decimal comma."""
    lines = text.splitlines()
    if not 1 <= line <= len(lines):
        return ""
    row = lines[line - 1]
    at = min(max(column - 1, 0), len(row))
    start = at
    while start > 0 and _BARE_WORD.fullmatch(row[start - 1]):
        start -= 1
    word = _BARE_WORD.match(row, start)
    token = word.group() if word else ""
    if re.fullmatch(r"0\d+", token):
        return f' (a TOML number cannot start with 0: write ids as strings, "{token}")'
    if message.startswith("Expected newline") and re.fullmatch(
        r"\d,\d", row[max(at - 1, 0) : at + 2]
    ):
        return " (a decimal comma: write numbers with a point, e.g. 152.87)"
    if message == "Invalid value" and token:
        in_array = row[:start].rstrip().endswith(("[", ","))
        value = token if in_array else row[start:].split("#")[0].strip()
        return f' (a string must be in quotes: "{shorten(value, 40)}")'
    return _twice_hint(lines, message, row)


def _twice_hint(lines: list[str], message: str, row: str) -> str:
    """A table declared twice (where first), or a key given twice in its table;
    a pasted camera.toml is the likely cause for [camera] and [distortion]."""
    table = re.fullmatch(r"Cannot declare \('([^']*)',\) twice", message)
    if table:
        name = table.group(1)
        header = re.compile(rf"\s*\[\s*{re.escape(name)}\s*\]\s*(#.*)?")
        first = next((k + 1 for k, ln in enumerate(lines) if header.fullmatch(ln)), None)
        where = f" (first at line {first})" if first else ""
        pasted = (
            "; the tables of a self-calibration's camera.toml replace the project's [camera] "
            "and [distortion], they are not added to them"
            if name in ("camera", "distortion")
            else ""
        )
        return f" (the table [{shorten(name, 40)}] is declared twice{where}: merge them{pasted})"
    if message == "Cannot overwrite a value" and "=" in row:
        key = row.split("=", 1)[0].strip()
        return f" (the key '{shorten(key, 40)}' is given twice in its table)"
    return ""


def _read_toml(path: Path) -> dict[str, Any]:
    text = decode(path, read_bytes(path, "project file", MAX_TOML_BYTES))
    dotted = _DOTTED_KEY.search(text)
    if dotted is not None:
        line = text.count("\n", 0, dotted.start()) + 1
        raise ConfigError(
            f"{path}:{line}: a dotted key of more than {MAX_KEY_PARTS} parts "
            f"({shorten(dotted.group(), 40)}); a project's keys have at most two "
            "(table.key)"
        )
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        match = _TOML_POSITION.search(message)
        if match:
            message = message[: match.start()]
            line, column = int(match.group(1)), int(match.group(2))
            raise ConfigError(
                f"{path}:{line}:{column}: TOML syntax error: {message}"
                f"{_toml_hint(text, message.strip(), line, column)}"
            ) from None
        raise ConfigError(f"{path}: TOML syntax error: {message}") from None
    except (RecursionError, MemoryError):
        doc = None  # nested too deep for the parser: told below
    depth, key = _deepest(doc)
    if doc is None or depth > MAX_TOML_DEPTH:
        at = f" (at {shorten(key, 60)})" if key else ""
        raise ConfigError(
            f"{path}: tables or arrays nested more than {MAX_TOML_DEPTH} deep{at}; a "
            "project nests a list in a table at most ([[strips]] photos)"
        )
    return doc


def _deepest(doc: object) -> tuple[int, str]:
    """The deepest nesting of tables and lists in ``doc`` and the dotted key of
    its first value that deep, without recursion (the depth is not known yet)."""
    stack: list[tuple[object, int, str]] = [(doc, 0, "")]
    deepest, where = 0, ""
    while stack:
        value, depth, key = stack.pop()
        if depth > deepest:
            deepest, where = depth, key
            if depth > MAX_TOML_DEPTH:
                break
        if isinstance(value, dict):
            stack.extend((v, depth + 1, f"{key}.{k}" if key else str(k)) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, depth + 1, f"{key}[{i}]") for i, v in enumerate(value))
    return deepest, where


# --------------------------------------------------------------------------- CSV


# --------------------------------------------------------------------------- images


# --------------------------------------------------------------------------- interior


# --------------------------------------------------------------------------- control


# --------------------------------------------------------------------------- GNSS, IMU


def _needs_bundle(toml_path: Path, name: str, what: str, refine: Refine) -> None:
    if refine is not Refine.BUNDLE:
        raise ConfigError(
            f"{toml_path}: [{name}]: {what} are observations of the bundle refinement only; "
            f'add refine = "bundle" to [adjustment], or remove [{name}]'
        )


# --------------------------------------------------------------------------- output


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
    _check_structure(toml_path, doc)

    def table(name: str) -> dict[str, object]:
        return check_table(str(toml_path), name, doc.get(name, {}), f"[{name}]")

    def optional(name: str) -> dict[str, object] | None:
        return table(name) if name in doc else None

    camera, images = table("camera"), table("images")
    control, adjustment = table("control"), table("adjustment")
    output, report = table("output"), table("report")
    blunders = _blunder_options(toml_path, table("blunders"))
    distortion_table, interior = optional("distortion"), optional("interior_orientation")
    gnss_table, imu_table = optional("gnss"), optional("imu")
    for key, what, given in (
        ("gnss", "GNSS centres", gnss_table),
        ("imu", "IMU attitudes", imu_table),
    ):
        if given is not None:
            _needs_bundle(toml_path, key, what, adjustment["refine"])  # type: ignore[arg-type]
    lines_raw = [
        check_table(str(toml_path), "straight_line", content, f"[[straight_line]] #{i}")
        for i, content in enumerate(doc.get("straight_line", []), start=1)
    ]

    strips, photo_ids, name = _photos(toml_path, doc)
    project_table = optional("project")
    if project_table is not None and project_table["name"] is not None:
        name = str(project_table["name"])
    crs = "local" if str(control["crs"]).lower() == "local" else str(control["crs"])
    principal_point: tuple[float, float] = camera["principal_point_mm"]  # type: ignore[assignment]
    principal_distance = float(camera["principal_distance_mm"])  # type: ignore[arg-type]
    if problems := principal_distance_problems(toml_path, principal_distance):
        raise ConfigError(problems[0])
    images_file = folder / str(images["file"])
    control_file = folder / str(control["file"])
    gnss_file, imu_file = (
        None if t is None else folder / str(t["file"]) for t in (gnss_table, imu_table)
    )
    fiducials_file = None if interior is None else folder / str(interior["fiducials_file"])
    inputs = (toml_path, images_file, control_file, fiducials_file, gnss_file, imu_file)
    output_directory = None
    if output["directory"] is not None:
        where = f"{toml_path}: [output] directory"
        kept = tuple(f for f in inputs if f is not None)
        output_directory = check_output(folder / str(output["directory"]), kept, where)

    image_options, distortion, fiducials, warnings = _interior(
        toml_path, images, distortion_table, interior, fiducials_file, photo_ids
    )
    reduce = _image_reduction(
        toml_path, principal_distance, principal_point, image_options, fiducials, distortion,
        images_file,
    )  # fmt: skip
    sigma_mm = float(images["sigma_mm"])  # type: ignore[arg-type]
    observations = load_images(
        images_file, photo_ids, principal_distance, reduce, sigma_mm, block=bool(strips)
    )
    table_c, ids, xyz, kinds, sigma_xy, sigma_h = load_control(
        control_file,
        float(control["sigma_xy_m"]),  # type: ignore[arg-type]
        float(control["sigma_h_m"]),  # type: ignore[arg-type]
    )
    given_route: Route | None = adjustment["route"]  # type: ignore[assignment]
    seen = frozenset(observations.point_ids)  # a set: np.isin would sort every id
    observed = np.fromiter(map(seen.__contains__, ids.tolist()), dtype=bool, count=len(ids))
    route, crs_warnings = check_crs(toml_path, crs, given_route, table_c, xyz, observed)
    warnings += crs_warnings
    gnss = (
        None
        if gnss_table is None
        else load_gnss(folder / str(gnss_table["file"]), photo_ids, gnss_table, crs, warnings)
    )
    imu = (
        None
        if imu_table is None
        else load_imu(folder / str(imu_table["file"]), photo_ids, imu_table, warnings)
    )

    control_points = _observed_control(
        table_c, ids, xyz, kinds, sigma_xy, sigma_h, observations, warnings
    )
    warnings += _single_ray_warnings(images_file, observations)
    straight_lines = _straight_lines(
        toml_path, lines_raw, observations, control_points, images_file, control_file
    )
    options = _adjustment_options(
        toml_path, adjustment, doc.get("adjustment", {}), route, block=bool(strips)
    )
    warnings += ebner_on_digital(toml_path, options, principal_distance, observations, fiducials)
    map_scale = report["map_scale"]
    return Project(
        path=toml_path,
        name=str(name),
        photo_ids=photo_ids,
        camera=Camera(principal_distance, readonly(np.asarray(principal_point, np.float64))),
        observations=observations,
        control=control_points,
        crs=crs,
        straight_lines=straight_lines,
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
        strips=strips,
    )


def _observed_control(
    table: CsvTable,
    ids: np.ndarray,
    xyz: FloatArray,
    kinds: np.ndarray,
    sigma_xy: FloatArray,
    sigma_h: FloatArray,
    observations: ImageObservations,
    warnings: list[str],
) -> ControlPoints:
    """The control rows whose point some photo observes; a warning naming each
    row left out (docs/project-file.md, "Errors": a warning, not an error)."""
    observed = set(observations.point_ids)
    is_observed = np.fromiter((i in observed for i in ids.tolist()), bool, count=ids.shape[0])
    missing = np.flatnonzero(~is_observed)
    hint = IdHints(observations.point_ids) if missing.size else None
    if ids.shape[0] and not is_observed.any() and hint is not None:
        raise ConfigError(
            f"{table.path}: none of its {ids.shape[0]} points is observed on any photo: the "
            f"point ids of the control and image files do not match (control '{ids[0]}'"
            f"{hint(str(ids[0]))}; the images name points such as "
            f"{', '.join(repr(p) for p in observations.point_ids[:3])})"
        )
    keep = np.flatnonzero(is_observed)
    lost = [int(r) for r in missing if kinds[r] is not ControlType.CHECK]
    if lost and hint is not None:
        plan = [str(ids[r]) for r in keep if kinds[r] in (ControlType.FULL, ControlType.PLAN)]
        height = [str(ids[r]) for r in keep if kinds[r] in (ControlType.FULL, ControlType.HEIGHT)]
        short = control_count_problems(plan, height)
        if short:
            raise ConfigError(
                f"{table.path}:{table.line[lost[0]]}: control point '{ids[lost[0]]}'"
                f"{hint(str(ids[lost[0]]))} and {len(lost) - 1} other(s) are not observed on "
                f"any photo, which leaves too little control ({short[0]}): check the ids "
                "against the image file's"
            )
    warnings.extend(
        f"{table.where(int(row))}: control point '{ids[row]}' ({kinds[row].value}) is "
        f"not observed on any photo{hint(str(ids[row])) if hint else ''}; left out"
        for row in missing
    )
    control_points = ControlPoints(
        point_ids=tuple(ids[keep].tolist()),
        xyz=readonly(xyz[keep]),
        kind=tuple(kinds[keep].tolist()),
        sigma_xy=readonly(sigma_xy[keep]),
        sigma_h=readonly(sigma_h[keep]),
        source_line=readonly(table.line[keep]),
    )
    return control_points


def _interior(
    toml_path: Path,
    images: dict[str, object],
    distortion_table: dict[str, object] | None,
    interior: dict[str, object] | None,
    fiducials_file: Path | None,
    photo_ids: tuple[str, ...],
) -> tuple[ImageOptions, BrownDistortion | None, tuple[FiducialFit, ...], list[str]]:
    """The image options, the distortion, the fiducial fits and their warnings."""
    image_options = read_image_options(toml_path, images)
    distortion = (
        None if distortion_table is None else BrownDistortion(**distortion_table)  # type: ignore[arg-type]
    )
    fiducials: tuple[FiducialFit, ...] = ()
    if interior is not None and fiducials_file is not None:
        fiducials = load_fiducials(fiducials_file, photo_ids, image_options, interior)
    warnings = [f"{fiducials_file}: {fit.message()}" for fit in fiducials if not fit.passed]
    return image_options, distortion, fiducials, warnings


def _photos(
    toml_path: Path, doc: dict[str, Any]
) -> tuple[tuple[StripSpec, ...], tuple[str, ...], str]:
    """The strips of a block (none for one strip), every photo id in order and
    the project's name."""
    if "strips" not in doc:
        table = check_table(str(toml_path), "strip", doc["strip"], "[strip]")
        photo_ids, name = _strip_photos(toml_path, table)
        return (), photo_ids, name
    tables = [
        check_table(str(toml_path), "strips", content, f"[[strips]] #{i}")
        for i, content in enumerate(doc["strips"], start=1)
    ]
    strips = _block_strips(toml_path, tables)
    return strips, tuple(p for s in strips for p in s.photo_ids), toml_path.parent.resolve().name


def _block_strips(toml_path: Path, tables: list[dict[str, object]]) -> tuple[StripSpec, ...]:
    """The ``[[strips]]`` of a block: at least two, each of two or more photos,
    a photo in one strip only, names unique."""
    strips: list[StripSpec] = []
    owner: dict[str, str] = {}
    for i, table in enumerate(tables, start=1):
        where = f"{toml_path}: [[strips]] #{i}"
        name = str(table["name"]) if table["name"] is not None else str(i)
        photos: tuple[str, ...] = table["photos"]  # type: ignore[assignment]
        if len(photos) < 2:
            raise ConfigError(
                f"{where} photos: a strip needs at least two photos, got {len(photos)}"
            )
        if any(s.name == name for s in strips):
            raise ConfigError(f"{where} name: '{name}' is already the name of another strip")
        for photo in photos:
            if photo in owner:
                raise ConfigError(
                    f"{where} photos: photo '{photo}' is in strip '{owner[photo]}' and in strip "
                    f"'{name}'; a photo belongs to one strip only"
                )
            owner[photo] = name
        strips.append(StripSpec(name, photos))
    if len(strips) < 2:
        raise ConfigError(
            f"{toml_path}: [[strips]]: a block needs at least two strips, got {len(strips)}; "
            "write one strip as [strip]"
        )
    return tuple(strips)


def _strip_photos(toml_path: Path, strip: dict[str, object]) -> tuple[tuple[str, ...], str]:
    """The strip's photo ids (at least two) and its name (default: the project folder's)."""
    photo_ids: tuple[str, ...] = strip["photos"]  # type: ignore[assignment]
    if len(photo_ids) < 2:
        raise ConfigError(
            f"{toml_path}: [strip] photos: a strip needs at least two photos, got {len(photo_ids)}"
        )
    name = strip["name"] if strip["name"] is not None else toml_path.parent.resolve().name
    return photo_ids, str(name)


def _check_structure(toml_path: Path, doc: dict[str, Any]) -> None:
    """Every top-level name a known table of the right kind; the required ones present."""
    for name, content in doc.items():
        spec = TABLES_BY_NAME.get(name)
        if spec is None:
            owners = [s.qualified for s in PROJECT_KEYS if s.key == name]
            hint = (
                f" (keys belong in a table: did you mean {owners[0]}?)"
                if owners and not isinstance(content, dict)
                else suggest(name, list(TABLES_BY_NAME))
            )
            is_table = isinstance(content, dict) or (
                isinstance(content, list) and all(isinstance(c, dict) for c in content) and content
            )
            what = "table" if is_table else "top-level key"
            raise ConfigError(
                f"{toml_path}: unknown {what} '{shorten(name)}'{hint}; valid tables: "
                f"{', '.join(TABLES_BY_NAME)}"
            )
        if spec.array:
            if not isinstance(content, list) or not all(isinstance(c, dict) for c in content):
                raise ConfigError(
                    f"{toml_path}: '{name}' must be an array of tables, written [[{name}]]"
                )
        elif not isinstance(content, dict):
            raise ConfigError(
                f"{toml_path}: '{name}' must be a table, written [{name}], got {describe(content)}"
            )
    for spec in PROJECT_TABLES:
        if spec.required and spec.name not in doc:
            raise ConfigError(f"{toml_path}: missing required table [{spec.name}]")
    if "strip" in doc and "strips" in doc:
        raise ConfigError(
            f"{toml_path}: both [strip] and [[strips]]: a project is one strip ([strip]) or a "
            "block of strips ([[strips]], one table per strip), not both"
        )
    if "strips" in doc and "straight_line" in doc:
        raise ConfigError(
            f"{toml_path}: [[straight_line]]: the straight-line condition is not used in a block "
            "of strips yet; remove it (or adjust the strip with the line on its own)"
        )
    if "strip" not in doc and "strips" not in doc:
        raise ConfigError(
            f"{toml_path}: missing required table [strip] (or [[strips]] tables for a block)"
        )


def _image_reduction(
    toml_path: Path,
    principal_distance: float,
    principal_point: tuple[float, float],
    image_options: ImageOptions,
    fiducials: tuple[FiducialFit, ...],
    distortion: BrownDistortion | None,
    images_file: Path,
) -> Callable[[FloatArray, IntArray], FloatArray]:
    """The reduction of raw image coordinates to the photo system (mm) of this
    project.  When the distortion cannot be removed, coordinates that no
    camera gives (far outside the format, from its corner) are named as the
    cause before the coefficients are; when the reduced coordinates are
    implausible but the measurements are not, the principal point or the
    distortion is named (:mod:`.camera_checks`)."""

    def reduce(
        xy: FloatArray,
        photo: IntArray,
        lens: BrownDistortion | None,
        centre: tuple[float, float] = principal_point,
    ) -> FloatArray:
        return reduce_image_coordinates(
            xy,
            photo,
            principal_distance,
            units=image_options.units,
            pixel_size_mm=image_options.pixel_size_mm,
            principal_point_px=image_options.principal_point_px,
            fiducials=fiducials or None,
            principal_point_mm=centre,
            distortion=lens,
            flight_direction=image_options.flight_direction,
        )

    no_lens = distortion is None or distortion.is_zero

    def reduce_all(xy: FloatArray, photo: IntArray) -> FloatArray:
        measured = reduce(xy, photo, None, (0.0, 0.0))  # as measured: no camera applied
        first = measured_problems(
            toml_path, measured, principal_point, image_options.flight_direction,
            principal_distance,
        )  # fmt: skip
        if first:
            raise ConfigError(first[0])
        if no_lens and not any(principal_point):
            return measured
        try:
            corrected = reduce(xy, photo, distortion)
        except ConvergenceError as exc:
            plain = reduce(xy, photo, None)
            problems = image_coordinate_problems(plain, principal_distance, file=str(images_file))
            raise ConfigError(
                f"{problems[0]} (the [distortion] could not be removed from them)"
                if problems
                else f"{toml_path}: [distortion]: {exc}"
            ) from None
        problems = camera_problems(
            toml_path, corrected, measured, lambda lens, centre: reduce(xy, photo, lens, centre),
            principal_point, distortion, principal_distance,
        )  # fmt: skip
        if problems:
            raise ConfigError(problems[0])
        return corrected

    return reduce_all


def _single_ray_warnings(images_file: Path, observations: ImageObservations) -> list[str]:
    """A warning naming the points observed on one photo only (none can be intersected)."""
    rays = np.bincount(observations.point, minlength=observations.n_points)
    single = np.flatnonzero(rays < 2)
    if not single.size:
        return []
    shown = ", ".join(f"'{observations.point_ids[i]}'" for i in single[:5])
    more = f" and {single.size - 5} more" if single.size > 5 else ""
    return [
        f"{images_file}: {single.size} point(s) observed on one photo only cannot be "
        f"triangulated: {shown}{more}"
    ]


def _straight_lines(
    toml_path: Path,
    lines_raw: list[dict[str, object]],
    observations: ImageObservations,
    control: ControlPoints,
    images_file: Path,
    control_file: Path,
) -> tuple[LineSpec, ...]:
    """The ``[[straight_line]]`` tables checked against the observations and the control."""
    if not lines_raw:  # the sets of the ids below take a 1000-photo strip 5-10 ms
        return ()
    observed = set(observations.point_ids)
    control_ids = {
        pid
        for pid, kind in zip(control.point_ids, control.kind, strict=True)
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
                    f"{suggest_id(pid, observations.point_ids)}"
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
    return tuple(straight_lines)


def _adjustment_options(
    toml_path: Path,
    adjustment: dict[str, object],
    raw_adjustment: dict[str, object],
    route: Route,
    *,
    block: bool = False,
) -> AdjustmentOptions:
    """``[adjustment]`` as options (:func:`strip_aerotri.options.adjustment_options`
    holds every rule; ``block``: a project of ``[[strips]]``)."""
    given = {key: adjustment[key] for key in raw_adjustment}
    try:
        return adjustment_options(given, route=route, block=block)
    except OptionError as exc:
        raise ConfigError(f"{toml_path}: [adjustment] {exc}") from None



def _blunder_options(toml_path: Path, table: dict[str, object]) -> BlunderOptions:
    """``[blunders]`` as :class:`~strip_aerotri.options.BlunderOptions`."""
    try:
        return BlunderOptions(
            action=BlunderAction.create(table["action"]),
            alpha=table["alpha"],  # type: ignore[arg-type]
            critical_values={
                stage: table[stage]  # type: ignore[misc]
                for stage in STAGES
                if table[stage] is not None
            },
            max_fraction=table["max_fraction"],  # type: ignore[arg-type]
            exclude_points=tuple(table["exclude_points"]),  # type: ignore[arg-type]
            exclude_observations=table["exclude_observations"],  # type: ignore[arg-type]
        )
    except OptionError as exc:
        raise ConfigError(f"{toml_path}: [blunders] {exc}") from None
