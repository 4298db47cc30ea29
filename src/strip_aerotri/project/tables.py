"""The project's CSV tables: image points (with fiducials and pixel
units), control, GNSS centres and IMU attitudes, each read, checked and
converted to library units.
"""

from __future__ import annotations

import warnings as _warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .._text import shorten
from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConfigError, GeometryError, StripAerotriWarning
from ..interior import (
    FiducialFit,
    fit_fiducial_transforms,
    mm_from_pixel,
)
from ..observations import (
    ControlType,
    GnssCentres,
    ImageObservations,
    ImuAttitudes,
)
from ..options import (
    FiducialTransform,
    ImageOptions,
    ImageUnits,
    Route,
)
from ..plausibility import image_coordinate_problems
from .csvfiles import CsvTable, float_column, id_column, optional_sigma, read_csv
from .model import readonly
from .schema import (
    CONTROL_COLUMNS,
    FIDUCIAL_COLUMNS,
    GNSS_COLUMNS,
    IMAGE_COLUMNS,
    IMU_COLUMNS,
    suggest,
    suggest_id,
)


def load_images(
    path: Path,
    photo_ids: tuple[str, ...],
    principal_distance: float,
    reduce: Callable[[FloatArray, IntArray], FloatArray],
    default_sigma: float,
    *,
    block: bool = False,
) -> ImageObservations:
    """The image observations of the project's photos (``block``: the photos
    are listed in ``[[strips]]``, not ``[strip]``)."""
    photos_key = "[[strips]] photos" if block else "[strip] photos"
    table = read_csv(path, IMAGE_COLUMNS, "[images] file")
    photo = id_column(table, "photo")
    point = id_column(table, "point")
    x, _ = float_column(table, "x")
    y, _ = float_column(table, "y")
    if "sigma" in table.columns:
        sigma, empty = float_column(table, "sigma", allow_empty=True, positive=True)
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
            f"{table.where(row)}: photo '{photo[row]}' is not in "
            f"{'any ' if block else ''}{photos_key} of the project file"
            f"{suggest_id(str(photo[row]), photo_ids)}"
        )
    present = set(name_index.tolist())
    for i, pid in enumerate(photo_ids):
        if i not in present:
            raise ConfigError(
                f"{path}: photo '{pid}' (listed in {photos_key}) has no observations"
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
        photo=readonly(photo_index[order]),
        point=readonly(point_index[order]),
        xy=readonly(xy),
        sigma=readonly(sigma[order]),
        principal_distance=float(principal_distance),
        source_line=readonly(table.line[order]),
    )


def read_image_options(toml_path: Path, images: dict[str, object]) -> ImageOptions:
    """``[images]`` units, pixel keys and flight direction, checked together."""
    units: ImageUnits = images["units"]  # type: ignore[assignment]
    pixel_keys = ("pixel_size_mm", "principal_point_px")
    if units is ImageUnits.PIXEL:
        for key in pixel_keys:
            if images[key] is None:
                raise ConfigError(f'{toml_path}: [images] {key}: required with units = "pixel"')
    elif (images["pixel_size_mm"] is None) != (images["principal_point_px"] is None):
        # with units = "mm" the two keys together only say where the mm origin
        # lies in the image's pixels, for exports that need pixels (export odm)
        given, missing = pixel_keys if images["pixel_size_mm"] is not None else pixel_keys[::-1]
        raise ConfigError(
            f'{toml_path}: [images] {given}: with units = "mm" give {missing} too (the pixel '
            "column and row of the origin of the mm coordinates, for pixel exports), or neither"
        )
    pp = images["principal_point_px"]
    return ImageOptions(
        units=units,
        pixel_size_mm=None if images["pixel_size_mm"] is None else float(images["pixel_size_mm"]),  # type: ignore[arg-type]
        principal_point_px=None if pp is None else readonly(np.asarray(pp, dtype=np.float64)),
        flight_direction=images["flight_direction"],  # type: ignore[arg-type]
    )


def load_fiducials(
    path: Path,
    photo_ids: tuple[str, ...],
    images: ImageOptions,
    interior: dict[str, object],
) -> tuple[FiducialFit, ...]:
    """Read the fiducial CSV and fit each photo's comparator -> calibrated transformation."""
    calibrated: dict[str, tuple[float, float]] = interior["calibrated"]  # type: ignore[assignment]
    kind: FiducialTransform = interior["transform"]  # type: ignore[assignment]
    table = read_csv(path, FIDUCIAL_COLUMNS, "[interior_orientation] fiducials_file")
    photo = id_column(table, "photo")
    mark = id_column(table, "mark")
    x, _ = float_column(table, "x")
    y, _ = float_column(table, "y")
    order_of = {pid: i for i, pid in enumerate(photo_ids)}
    photo_index = np.empty(table.n_rows, dtype=np.intp)
    seen: dict[tuple[str, str], int] = {}
    for row, (pid, mid) in enumerate(zip(photo.tolist(), mark.tolist(), strict=True)):
        if pid not in order_of:
            raise ConfigError(
                f"{table.where(row)}: photo '{pid}' is not in [strip] photos"
                f"{suggest_id(pid, photo_ids)}"
            )
        if mid not in calibrated:
            raise ConfigError(
                f"{table.where(row)}: mark '{mid}' is not in [interior_orientation] calibrated"
                f"{suggest(mid, list(calibrated))}"
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


def load_control(
    path: Path, default_sigma_xy: float, default_sigma_h: float
) -> tuple[CsvTable, np.ndarray, FloatArray, np.ndarray, FloatArray, FloatArray]:
    """Parse and check control.csv; returns table, ids, xyz, kinds, sigma_xy, sigma_h."""
    table = read_csv(path, CONTROL_COLUMNS, "[control] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no control points (only a header)")
    ids = id_column(table, "point")
    xyz = np.empty((table.n_rows, 3))
    given = np.empty((table.n_rows, 3), dtype=bool)
    for j, name in enumerate(("X", "Y", "H")):
        values, empty = float_column(table, name, allow_empty=True)
        xyz[:, j] = values
        given[:, j] = ~empty

    type_strings = np.asarray([t.lower() for t in id_column(table, "type").tolist()], dtype=str)
    valid = [t.value for t in ControlType]
    type_names, type_first, type_inverse = np.unique(
        type_strings.reshape(-1), return_index=True, return_inverse=True
    )
    bad_types = [i for i, t in enumerate(type_names) if t not in valid]
    if bad_types:
        row = int(min(type_first[i] for i in bad_types))
        got = table.columns["type"][row].strip()
        raise ConfigError(
            f"{table.where(row)}: column 'type': unknown type '{got}'{suggest(got, valid)}; "
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
            values, empty = float_column(table, name, allow_empty=True, positive=True)
            values[empty] = default
        else:
            values = np.full(table.n_rows, default)
        sigmas.append(values)
    kinds = np.array([ControlType(v) for v in valid], dtype=object)[kind_codes]
    return table, ids, xyz, kinds, sigmas[0], sigmas[1]


def check_crs(
    toml_name: Path,
    crs: str,
    route: Route | None,
    table: CsvTable,
    xyz: FloatArray,
    observed: BoolArray | None = None,
) -> tuple[Route, list[str]]:
    """Validate ``crs`` with pyproj, choose the route and check geographic
    ranges and, on the ``observed`` rows, plausible coordinates."""
    warnings: list[str] = []
    if crs == "local":
        if route is Route.GEOCENTRIC:
            raise ConfigError(
                f'{toml_name}: [adjustment] route: "geocentric" needs a geodetic CRS; '
                f'with crs = "local" only "projected" applies'
            )
        check_plausible_extent(None, table, xyz, observed)
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
    check_plausible_extent(crs_obj, table, xyz, observed)
    if not crs_obj.is_geographic:
        unit = crs_obj.axis_info[0].unit_name if crs_obj.axis_info else "metre"
        if unit not in ("metre", "meter") and chosen is Route.PROJECTED:
            warnings.append(
                f"{toml_name}: [control] crs: '{crs}' has X, Y in {unit}, but H is in metres; "
                "the projected route mixes the two"
            )
    return chosen, warnings


def _check_geographic_ranges(crs: str, table: CsvTable, xyz: FloatArray) -> None:
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


#: No ellipsoidal height of a ground point, nor of a site system's H, is
#: beyond 100 km; no projected coordinate beyond 1e8 (the earth's
#: circumference is 4e7 m, 1.3e8 US feet).
MAX_ABS_HEIGHT_M = 1e5
MAX_ABS_PROJECTED = 1e8
#: A point farther from the median of the plan control than this many times
#: the control's own median distance from it (and at least 1 km) lies far
#: outside the project; heights farther than this from the median height.
EXTENT_FACTOR = 1000.0
MAX_HEIGHT_SPREAD_M = 20_000.0
#: Degrees around a CRS's area of use still taken as plausible.
AREA_MARGIN_DEG = 20.0


def check_plausible_extent(
    crs: Any,
    table: CsvTable,
    xyz: FloatArray,
    judged: BoolArray | None = None,
    names: tuple[str, str] = ("point", "H"),
) -> None:
    """Refuse control coordinates no project can have, naming the first row.

    ``crs`` is the pyproj CRS of ``[control] crs`` (None for "local"); only
    the rows ``judged`` are looked at (default all: a control point no photo
    observes is left out with a warning, whatever its coordinates), and NaN
    cells (a plan or height point's empty ones) pass; ``names`` are those of
    the id and the height column (GNSS centres: photo, Z).  Implausible are: a
    height beyond :data:`MAX_ABS_HEIGHT_M` or :data:`MAX_HEIGHT_SPREAD_M` from
    the median height; a projected or local X, Y beyond
    :data:`MAX_ABS_PROJECTED`, or far outside the extent of the other points
    (:data:`EXTENT_FACTOR`); a projected point that its CRS cannot take to
    longitude and latitude, or that lies more than :data:`AREA_MARGIN_DEG`
    outside the CRS's area of use.  Such a value is a typing or export error,
    and adjusting with it gives a "result" in the thousands of kilometres.
    """
    if judged is not None:
        xyz = np.where(judged[:, None], xyz, np.nan)
    xy, h = xyz[:, :2], xyz[:, 2]
    h_name = names[1]
    with np.errstate(over="ignore", invalid="ignore"):
        h_median = np.nanmedian(h) if np.isfinite(h).any() else 0.0
        rules = [
            (np.abs(h) > MAX_ABS_HEIGHT_M, f"{h_name} beyond {MAX_ABS_HEIGHT_M:g} m"),
            (
                np.abs(h - h_median) > MAX_HEIGHT_SPREAD_M,
                f"{h_name} more than {MAX_HEIGHT_SPREAD_M:g} m from the median height "
                f"{h_median:.1f} m of the file",
            ),
        ]
        geographic = crs is not None and crs.is_geographic
        if not geographic:
            rules.append(
                (
                    np.abs(xy).max(axis=1) > MAX_ABS_PROJECTED,
                    f"X or Y beyond {MAX_ABS_PROJECTED:g}",
                )
            )
            plan = np.isfinite(xy).all(axis=1)
            if plan.sum() >= 3:
                centre = np.median(xy[plan], axis=0)
                distance = np.hypot(*(xy - centre).T)
                reach = max(float(np.median(distance[plan])), 1.0) * EXTENT_FACTOR
                rules.append(
                    (
                        distance > max(reach, 1000.0),
                        f"more than {max(reach, 1000.0):.3g} from the median of the plan "
                        f"coordinates ({centre[0]:.1f}, {centre[1]:.1f}), {EXTENT_FACTOR:g} "
                        "times their median distance from it",
                    )
                )
    for bad, text in rules:
        if bad.any():
            _raise_implausible(table, xyz, int(np.flatnonzero(bad)[0]), text, names)
    if crs is not None and not geographic:
        _check_area_of_use(crs, table, xyz, names)


def _raise_implausible(
    table: CsvTable, xyz: FloatArray, row: int, text: str, names: tuple[str, str]
) -> None:
    values = ", ".join("" if v != v else f"{v:.6g}" for v in xyz[row])
    raise ConfigError(
        f"{table.where(row)}: {names[0]} '{shorten(table.columns[names[0]][row].strip())}' at "
        f"X, Y, {names[1]} = {values}: implausible coordinates ({text}); a typing or export "
        "error?"
    )


def _check_area_of_use(crs: Any, table: CsvTable, xyz: FloatArray, names: tuple[str, str]) -> None:
    """Projected X, Y that the CRS cannot take to longitude and latitude, or
    far outside its area of use (unless swapping X and Y brings them inside:
    then the mirrored-control check names the cause)."""
    import pyproj

    plan = np.flatnonzero(np.isfinite(xyz[:, :2]).all(axis=1))
    if not plan.size:
        return
    try:
        to_lonlat = pyproj.Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True)
    except (pyproj.exceptions.ProjError, pyproj.exceptions.CRSError):  # no inverse: no test
        return
    xy = xyz[plan, :2]

    def lonlat(a: FloatArray, b: FloatArray) -> FloatArray:
        with np.errstate(all="ignore"):
            out = to_lonlat.transform(a, b, errcheck=False)
        return np.column_stack([np.asarray(v, dtype=np.float64) for v in out])

    given = lonlat(xy[:, 0], xy[:, 1])
    bad = ~np.isfinite(given).all(axis=1)
    text = f"outside the domain of crs {shorten(crs.name)}"
    area = crs.area_of_use
    if area is not None and not bad.any():
        outside = ~_within_area(given, area) & ~_within_area(lonlat(xy[:, 1], xy[:, 0]), area)
        if outside.any():
            bad = outside
            k = int(np.flatnonzero(bad)[0])
            text = (
                f"at longitude, latitude {given[k, 0]:.2f}, {given[k, 1]:.2f}, more than "
                f"{AREA_MARGIN_DEG:g} degrees outside the area of use of crs "
                f"{shorten(crs.name)} ({shorten(area.name.rstrip('.'), 40)})"
            )
    if bad.any():
        _raise_implausible(table, xyz, int(plan[int(np.flatnonzero(bad)[0])]), text, names)


def _within_area(lonlat: FloatArray, area: Any) -> BoolArray:
    """Longitude, latitude within ``area`` (a pyproj AreaOfUse) and its margin."""
    m = AREA_MARGIN_DEG
    lon, lat = lonlat[:, 0], lonlat[:, 1]
    west, east = area.west - m, area.east + m
    with np.errstate(invalid="ignore"):
        in_lon = (
            (lon >= west) & (lon <= east)
            if area.west <= area.east
            else (lon >= west) | (lon <= east)
        )  # an area across the antimeridian
        inside = in_lon & (lat >= area.south - m) & (lat <= area.north + m)
    return np.asarray(inside, dtype=bool)


def _crs_object(crs: str) -> Any:
    """The pyproj CRS of ``crs`` (already validated by :func:`check_crs`), None for "local"."""
    if crs == "local":
        return None
    import pyproj

    return pyproj.CRS.from_user_input(crs)


def _is_geographic(crs: str) -> bool:
    """True for a geographic CRS (already validated by :func:`check_crs`)."""
    crs_object = _crs_object(crs)
    return crs_object is not None and bool(crs_object.is_geographic)


def _strip_rows(
    table: CsvTable, photo: np.ndarray, photo_ids: tuple[str, ...], notes: list[str]
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
        # _strip_rows <- load_gnss / load_imu <- load_project <- caller
        _warnings.warn(text, StripAerotriWarning, stacklevel=4)
    known = np.flatnonzero(index >= 0)
    return known[np.argsort(index[known], kind="stable")]


def load_gnss(
    path: Path,
    photo_ids: tuple[str, ...],
    gnss: dict[str, object],
    crs: str,
    notes: list[str],
) -> GnssCentres:
    """Read the GNSS centres CSV (``[gnss] file``)."""

    table = read_csv(path, GNSS_COLUMNS, "[gnss] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no GNSS centres (only a header)")
    photo = id_column(table, "photo")
    xyz = np.column_stack([float_column(table, name)[0] for name in ("X", "Y", "Z")])
    sigma_xy = optional_sigma(table, "sigma_xy", float(gnss["sigma_xy"]))  # type: ignore[arg-type]
    sigma_z = optional_sigma(table, "sigma_z", float(gnss["sigma_z"]))  # type: ignore[arg-type]
    if _is_geographic(crs):
        _check_geographic_ranges(crs, table, xyz)
    rows = _strip_rows(table, photo, photo_ids, notes)
    in_strip = np.zeros(table.n_rows, dtype=bool)
    in_strip[rows] = True
    check_plausible_extent(_crs_object(crs), table, xyz, in_strip, names=("photo", "Z"))
    return GnssCentres(tuple(photo[rows].tolist()), xyz[rows], sigma_xy[rows], sigma_z[rows])


def load_imu(
    path: Path, photo_ids: tuple[str, ...], imu: dict[str, object], notes: list[str]
) -> ImuAttitudes:
    """Read the IMU attitudes CSV (``[imu] file``), degrees in the file, radians out."""

    table = read_csv(path, IMU_COLUMNS, "[imu] file")
    if table.n_rows == 0:
        raise ConfigError(f"{path}: no IMU attitudes (only a header)")
    photo = id_column(table, "photo")
    opk = np.column_stack([float_column(table, n)[0] for n in ("omega", "phi", "kappa")])
    sigma = optional_sigma(table, "sigma_deg", float(imu["sigma_deg"]))  # type: ignore[arg-type]
    rows = _strip_rows(table, photo, photo_ids, notes)
    return ImuAttitudes.from_degrees(tuple(photo[rows].tolist()), opk[rows], sigma[rows])
