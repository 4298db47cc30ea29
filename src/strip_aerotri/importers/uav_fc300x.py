"""The text files of the FC300X UAV block (DJI Phantom 3, 3 strips of 10 photos).

The layout of ``rashidyreza/Strip-Adjustment-with-Matlab`` (``src/*.txt`` and
``Calibration/cal.cal``), read from one folder:

* image point files, whitespace columns ``image Num x y n m`` with x, y in mm
  from the image centre, x right, y up (a header line ``image Num ...`` is
  skipped; ``n`` and ``m`` are not used):

  - ``GCP_ImageCs.txt``: the GCPs, ids kept as they are;
  - ``Tie_points_for_AO.txt``: tie points, ids prefixed ``T``;
  - ``Matching.txt``: matches, ids prefixed ``M``;
  - ``Matching<S>.txt`` (e.g. ``MatchingB2.txt``): matches numbered on their
    own, ids prefixed ``M<S>-``.

  The files number their points independently (the same number is a
  different point), hence the prefixes.  A point of a later file in this list
  with an observation within ``duplicate_tol_mm`` of an observation of an
  earlier file's point on the same photo is the same measurement under
  another id and is left out whole.
* ``GCP_UTM.txt``: ``id E N H`` in metres.
* ``cal.cal``: the Agisoft PhotoScan calibration in the CalCam layout (see
  :func:`read_calibration` for how it is converted).

Photos are ``B<strip>_<n>.JPG``: strip number and position in the strip.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..options import DEFAULT_DUPLICATE_TOL_MM
from .common import (
    Camera,
    ControlTable,
    Distortion,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    Rows,
    Strip,
    assemble,
    check_unique,
    natural_key,
    read_text,
    split_rows,
    to_floats,
)

__all__ = [
    "DEFAULT_CRS",
    "DEFAULT_DUPLICATE_TOL_MM",
    "CalCamCalibration",
    "import_uav_fc300x",
    "read_calibration",
    "read_gcp_file",
    "read_image_file",
]

#: The example script's choice (examples/uav_fc300x.py, docs/uav.md): the UTM
#: zone of GCP_UTM.txt is not stated, so E, N are used as a local site system.
DEFAULT_CRS = "local"
#: Observations closer than this on one photo are one measurement (mm; about 3 px).
#: Tangential, affinity and non-orthogonality terms of cal.cal larger than this
#: are refused: their definition in this layout is not documented.
NEGLIGIBLE = 1e-9

_PHOTO = re.compile(r"^B(\d+)_(\d+)$", re.IGNORECASE)
_FIXED_FILES = (("GCP_ImageCs.txt", ""), ("Tie_points_for_AO.txt", "T"), ("Matching.txt", "M"))


def read_image_file(path: Path, prefix: str) -> ImageTable:
    """One image point file: photo id (file name without ``.JPG``), ``prefix`` + Num, x, y.

    Raises
    ------
    ConfigError
        A record with fewer than 4 fields, an image name that is not a
        ``.JPG`` file, or a coordinate that is not a number (file and line).
    """
    rows = split_rows(path, read_text(path, "image points, columns image Num x y n m"))
    if len(rows) and rows.fields[0][0].lower() == "image":
        rows = rows.take(np.arange(1, len(rows)))  # the header line
    rows.require_fields(4, "image Num x y n m")
    names = rows.column(0)
    is_jpg = np.char.endswith(np.char.lower(names), ".jpg")
    if not is_jpg.all():
        k = int(np.flatnonzero(~is_jpg)[0])
        raise ConfigError(
            f"{rows.where(k)}: image: expected a .JPG file name, got {str(names[k])!r}"
        )
    photo = np.char.rstrip(np.asarray([n[:-4] for n in names], dtype=str))
    point = np.char.add(prefix, rows.column(1))
    xy = np.column_stack(
        [to_floats(rows.column(2), rows, "x"), to_floats(rows.column(3), rows, "y")]
    )
    return ImageTable(photo, point, xy)


def read_gcp_file(path: Path) -> ControlTable:
    """``GCP_UTM.txt``: ``id E N H`` per line (metres)."""
    rows = split_rows(path, read_text(path, "ground control, columns id E N H"))
    rows.require_fields(4, "id E N H")
    xyz = np.column_stack(
        [to_floats(rows.column(k), rows, c) for k, c in ((1, "E"), (2, "N"), (3, "H"))]
    )
    point = rows.column(0)
    check_unique(point, rows, "GCP")
    return ControlTable(point, xyz)


@dataclass(frozen=True)
class CalCamCalibration:
    """``cal.cal`` converted to the project's camera keys.

    Attributes
    ----------
    camera : Camera
        c = focal length (px) x pixel size; principal point from the image
        centre, x right and y up: ``((cx - W/2) s, -(cy - H/2) s)``.
    pixel_size_mm : float
        Sensor width in mm / width in pixels.
    distortion : Distortion
        The radial terms as ``units = "normalized"``, ``model = "projection"``.
    image_size_px : (float, float)
        Width and height in pixels (the image coordinates' origin is the
        image centre, half of them).
    """

    camera: Camera
    pixel_size_mm: float
    distortion: Distortion
    image_size_px: tuple[float, float] = (0.0, 0.0)


def read_calibration(path: Path) -> CalCamCalibration:
    """Read an Agisoft PhotoScan calibration exported in the CalCam layout.

    The file gives ``Focal_length``, ``Principal_point_x``, ``Principal_point_y``
    (pixels, from the top-left corner, rows down), ``General_scaling`` g,
    ``Radial_k1..k3``, ``Tangential_t1, t2``, ``Affinity``,
    ``Un-orthogonality`` and ``Sensor_width`` / ``Sensor_height`` (pixels, mm).

    Model of the radial terms: with pixel coordinates from the principal point
    scaled by g (x' = g x_px, r' = g r_px), the distortion in pixels is
    ``x' (k1 r'^2 + k2 r'^4 + k3 r'^6)``, applied to the ideal point (the
    projection form of Agisoft).  With the normalised radius rho = r_px / f,
    the coefficients of ``[distortion] units = "normalized"`` are therefore
    ``k1 g^3 f^2``, ``k2 g^5 f^4`` and ``k3 g^7 f^6``.  (Checked against the
    same calibration exported by PhotoScan in the 3DM CalibCam layout,
    ``Calibration/tex.txt`` of the same repository: K1 = 8.653781e-4 mm^-2 and
    K2 = -8.592621e-5 mm^-4 equal ``-k1 g^3 / s^2`` and ``-k2 g^5 / s^4`` to
    all printed digits, the sign being that of a correction-form program.)

    Raises
    ------
    ConfigError
        A missing or non-numeric key, non-square pixels, or tangential,
        affinity or non-orthogonality terms that are not negligible (their
        definition in this layout is not documented, so they are not converted).
    """
    rows = split_rows(path, read_text(path, "camera calibration (CalCam layout)"), comments=("%",))
    values: dict[str, tuple[int, list[str]]] = {}
    for k, fields in enumerate(rows.fields):
        values[fields[0].lower()] = (k, fields[1:])

    def number(key: str, index: int = 0) -> float:
        if key.lower() not in values:
            raise ConfigError(f"{path}: missing key '{key}' (camera calibration, CalCam layout)")
        k, rest = values[key.lower()]
        if len(rest) <= index:
            raise ConfigError(f"{rows.where(k)}: {key}: expected {index + 1} value(s)")
        return float(to_floats([rest[index]], Rows(rows.path, rows.lines[[k]], [rest]), key)[0])

    f_px = number("Focal_length")
    cx, cy = number("Principal_point_x"), number("Principal_point_y")
    g = number("General_scaling")
    k1, k2, k3 = (number(f"Radial_k{i}") for i in (1, 2, 3))
    width_px, width_mm = number("Sensor_width"), number("Sensor_width", 1)
    height_px, height_mm = number("Sensor_height"), number("Sensor_height", 1)
    if min(f_px, g, width_px, width_mm, height_px, height_mm) <= 0:
        raise ConfigError(
            f"{path}: focal length, General_scaling and sensor sizes must be positive"
        )
    for key in ("Tangential_t1", "Tangential_t2", "Affinity", "Un-orthogonality"):
        value = number(key)
        if abs(value) > NEGLIGIBLE:
            k, _ = values[key.lower()]
            raise ConfigError(
                f"{rows.where(k)}: {key} = {value!r}: tangential, affinity and "
                "non-orthogonality terms of this layout are not converted (their definition is "
                "not documented); only a calibration without them can be imported"
            )
    s = width_mm / width_px
    if abs(height_mm / height_px - s) > 1e-3 * s:
        raise ConfigError(
            f"{path}: pixels are not square ({s:.8f} x {height_mm / height_px:.8f} mm); the "
            "project has one pixel size"
        )
    camera = Camera(
        f_px * s,
        ((cx - width_px / 2.0) * s, -(cy - height_px / 2.0) * s),
    )
    distortion = Distortion(
        k1=k1 * g**3 * f_px**2,
        k2=k2 * g**5 * f_px**4,
        k3=k3 * g**7 * f_px**6,
        units="normalized",
        model="projection",
        comment=(
            f"{path.name}: radial k1..k3 with General_scaling {g:g} and f = {f_px:.4f} px, "
            "as k g^(2i+1) f^(2i) (docs/import.md)"
        ),
    )
    return CalCamCalibration(camera, s, distortion, (width_px, height_px))


def _drop_duplicates(
    tables: list[tuple[str, ImageTable]], tol_mm: float
) -> tuple[list[ImageTable], list[str]]:
    """Leave out points of later tables observed within ``tol_mm`` of an earlier one's."""
    from scipy.spatial import cKDTree

    kept: list[ImageTable] = []
    notes: list[str] = []
    for name, table in tables:
        if kept:
            earlier = ImageTable.concat(kept)
            before = earlier.rows_by_photo()
            duplicate: set[str] = set()
            for photo, rows in table.rows_by_photo().items():  # a loop over photos
                other = before.get(photo)
                if other is None:
                    continue
                dist, _ = cKDTree(earlier.xy[other]).query(table.xy[rows], k=1)
                duplicate.update(table.point[rows[dist < tol_mm]].tolist())
            if duplicate:
                table = table.take(~np.isin(table.point, sorted(duplicate)))
                notes.append(
                    f"{name}: {len(duplicate)} point(s) left out, each the same measurement as "
                    f"a point of an earlier file (within {tol_mm:g} mm on one photo)"
                )
        kept.append(table)
    return kept, notes


def _photo_key(photo: str) -> tuple[int, int] | None:
    m = _PHOTO.match(photo)
    return (int(m.group(1)), int(m.group(2))) if m else None


def import_uav_fc300x(
    data_dir: str | Path,
    options: ImportOptions | None = None,
    *,
    crs: str = DEFAULT_CRS,
    duplicate_tol_mm: float = DEFAULT_DUPLICATE_TOL_MM,
    distortion: bool = True,
) -> ImportedProject:
    """Import the FC300X block (or some of its strips) from ``data_dir``.

    Parameters
    ----------
    data_dir : path
        Folder with the image point files, ``GCP_UTM.txt`` and ``cal.cal``.
    options : ImportOptions, optional
        ``options.strips`` are strip numbers (the ``<strip>`` of
        ``B<strip>_<n>``); the duplicates are looked for among their photos only.
    crs : str
        ``[control] crs`` of GCP_UTM.txt's E, N (default ``"local"``: the UTM
        zone is not stated in the data).
    duplicate_tol_mm : float
    distortion : bool
        Write cal.cal's radial distortion (``[distortion]``).

    Returns
    -------
    ImportedProject
        Strips ``B1``, ``B2``, ... in photo order ``n``; flight direction from
        the image shifts; GCPs split into full control and check points.
    """
    options = options or ImportOptions()
    folder = Path(data_dir)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: not a folder (expected the FC300X data folder)")
    files = [(folder / name, prefix) for name, prefix in _FIXED_FILES]
    for extra in sorted(folder.glob("Matching?*.txt"), key=lambda p: natural_key(p.name)):
        suffix = extra.stem[len("Matching") :]
        files.append((extra, f"M{suffix}-"))
    for path, _ in files[:2]:
        if not path.is_file():
            raise ConfigError(f"{path}: file not found (FC300X image points)")
    files = [(p, prefix) for p, prefix in files if p.is_file()]
    tables = [(p.name, read_image_file(p, prefix)) for p, prefix in files]

    photos = np.unique(np.concatenate([t.photo for _, t in tables]))
    keys = {str(p): _photo_key(str(p)) for p in photos}
    bad = [p for p, k in keys.items() if k is None]
    if bad:
        raise ConfigError(
            f"{folder}: photo '{bad[0]}' is not named B<strip>_<n> (the strip and the photo's "
            "place in it)"
        )
    numbers = sorted({k[0] for k in keys.values() if k is not None})
    wanted = numbers if options.strips is None else list(dict.fromkeys(options.strips))
    missing = [n for n in wanted if n not in numbers]
    if missing:
        raise ConfigError(
            f"--strips: no strip {missing[0]} in {folder} (strips: "
            f"{', '.join(str(n) for n in numbers)})"
        )
    strips = []
    for number in wanted:
        members = sorted((k[1], p) for p, k in keys.items() if k is not None and k[0] == number)
        strips.append(Strip(f"B{number}", tuple(p for _, p in members)))
    selected = [p for s in strips for p in s.photos]
    tables = [(name, t.take(np.isin(t.photo, selected))) for name, t in tables]
    kept, notes = _drop_duplicates(tables, duplicate_tol_mm)
    images = ImageTable.concat(kept)

    gcp_path = folder / "GCP_UTM.txt"
    control = read_gcp_file(gcp_path)
    cal_path = folder / "cal.cal"
    cal = read_calibration(cal_path)
    notes.insert(
        0,
        "ids: GCPs as numbered; T<n> Tie_points_for_AO.txt, M<n> Matching.txt, "
        "M<S>-<n> Matching<S>.txt (the files number their points independently)",
    )
    notes.append(
        f"camera from {cal_path.name}: c = {cal.camera.principal_distance_mm:.6f} mm, "
        f"pixel {cal.pixel_size_mm:.8f} mm"
    )
    if not distortion:
        notes.append(
            f"no [distortion]: {cal_path.name}'s radial distortion left out (--no-distortion), "
            "so the coordinates are taken as free of it; to estimate the lens from these "
            'photos: [adjustment] refine = "bundle" and self_calibration = "auto"'
        )
    if crs.strip().lower() == "local":
        notes.append(
            'crs = "local": GCP_UTM.txt gives UTM E, N without the zone, so they serve as a '
            "local site system; give --crs EPSG:326zz when the zone is known"
        )
    opts = ImportOptions(
        strips=None,
        control_ids=options.control_ids,
        check_ids=options.check_ids,
        flight_direction=options.flight_direction,
        photo_order=options.photo_order,
        name=options.name,
        sigma_mm=options.sigma_mm,
        turn_deg=options.turn_deg,
    )
    inputs = [p for p, _ in files] + [gcp_path, cal_path]
    name = (
        "FC300X "
        + ("strip " if len(strips) == 1 else "strips ")
        + ", ".join(s.name for s in strips)
    )
    return assemble(
        f"the FC300X UAV block in {folder}",
        images,
        # the mm coordinates start at the image centre: where that is in pixels
        # (pixel_size_mm and principal_point_px), for exports in pixels
        ImageFrame(
            "mm",
            cal.pixel_size_mm,
            (cal.image_size_px[0] / 2.0, cal.image_size_px[1] / 2.0),
        ),
        cal.camera,
        control,
        crs,
        opts,
        inputs=inputs,
        default_name=name,
        distortion=cal.distortion if distortion else None,
        strips=strips,
        notes=notes,
    )
