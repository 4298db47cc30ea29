"""PATB input files: image coordinates (``.im``) and control points (``.con``).

PATB (the bundle block adjustment program of Ackermann's Stuttgart group)
reads free-format, whitespace-separated records; what is read here (see
docs/import.md for the sources and what is not certain):

* ``.im``: for each photo a header record whose first field is the photo
  number (further fields, such as a camera number, are not used), then one
  record ``point x y`` per measured point, then the record ``-99`` that ends
  the photo.  x right, y up, reduced to the principal point of the film or
  sensor system, in millimetres or micrometres (the units a PATB project file
  ``.pro`` states; ``units`` here).
* ``.con``: records ``point X Y Z`` (full control), ended by ``-99`` (also
  accepted: the end of the file).  Records of another length are refused:
  PATB's plan-only and height-only control records are not read.
* ``.ori`` (optional, a PATB result): per photo the records ``photo X0 Y0 Z0``,
  ``a11 a12 a13 a21 a22`` and ``a23 a31 a32 a33`` (the layout PCI Geomatics'
  OrthoEngine documents for PATB exterior orientation); only the projection
  centres are used, as ``[gnss]`` positions and to find the strips.  The
  rotation matrix is not imported (its direction, image to ground or ground
  to image, is not documented there).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._typing import IntArray
from ..errors import ConfigError
from .common import (
    Camera,
    ControlTable,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    PhotoPositions,
    assemble,
    check_unique,
    line_floats,
    read_text,
    split_rows,
    to_floats,
)

__all__ = ["UNITS", "import_patb", "read_con", "read_im", "read_ori"]

#: Units of .im coordinates and their size in mm.
UNITS = {"mm": 1.0, "um": 1e-3}
#: Larger |x| or |y| in "mm" is refused (no frame camera has a 1 m format).
_MAX_MM = 500.0


def _is_end(field: str) -> bool:
    try:
        return float(field) == -99.0
    except ValueError:
        return False


def read_im(path: Path, units: str = "mm") -> ImageTable:
    """A PATB image coordinate file, coordinates converted to mm.

    Raises
    ------
    ConfigError
        A point record with fewer than 3 fields, a bad number, a point measured
        twice on one photo, or coordinates too large for ``units = "mm"``.
    """
    if units not in UNITS:
        raise ValueError(f"Expected units in {tuple(UNITS)}, got {units!r}")
    rows = split_rows(path, read_text(path, "PATB image coordinates"), comments=("#", "*"))
    photos: list[str] = []
    point_rows: list[int] = []
    photo = None
    for k, fields in enumerate(rows.fields):  # a loop over records (splitting lines)
        if _is_end(fields[0]) and len(fields) == 1:
            photo = None
        elif photo is None:
            photo = fields[0]
        else:
            if len(fields) < 3:
                raise ConfigError(
                    f"{rows.where(k)}: expected a point record 'point x y' (or -99 to end "
                    f"photo {photo}), got {len(fields)} field(s)"
                )
            photos.append(photo)
            point_rows.append(k)
    if not point_rows:
        raise ConfigError(f"{path}: no point record (expected photo, point x y ..., -99)")
    pts = rows.take(point_rows)
    xy = np.column_stack([to_floats(pts.column(1), pts, "x"), to_floats(pts.column(2), pts, "y")])
    limit: IntArray | list[int] = (
        np.flatnonzero(np.abs(xy).max(axis=1) > _MAX_MM) if units == "mm" else []
    )
    if len(limit):
        k = int(limit[0])
        raise ConfigError(
            f"{pts.where(k)}: image coordinate {xy[k].max():g} is too large for mm; are the "
            "coordinates in micrometres (--units um, see the .pro file)?"
        )
    table = ImageTable(np.asarray(photos, str), pts.column(0), xy * UNITS[units])
    pair = np.char.add(np.char.add(table.photo, "\x00"), table.point)
    _, inverse, counts = np.unique(pair, return_inverse=True, return_counts=True)
    if (counts > 1).any():
        dup = np.flatnonzero(counts[inverse.reshape(-1)] > 1)
        k = int(dup[1])
        raise ConfigError(
            f"{pts.where(k)}: point '{table.point[k]}' is measured twice on photo "
            f"'{table.photo[k]}' (first at line {int(pts.lines[dup[0]])})"
        )
    return table


def read_con(path: Path) -> ControlTable:
    """A PATB control point file: ``point X Y Z`` records up to ``-99``."""
    rows = split_rows(path, read_text(path, "PATB control points"), comments=("#", "*"))
    keep: list[int] = []
    for k, fields in enumerate(rows.fields):
        if _is_end(fields[0]) and len(fields) == 1:
            break
        if len(fields) != 4:
            raise ConfigError(
                f"{rows.where(k)}: expected a control record 'point X Y Z', got {len(fields)} "
                "field(s) (plan-only and height-only records are not read)"
            )
        keep.append(k)
    if not keep:
        raise ConfigError(f"{path}: no control record (expected point X Y Z)")
    pts = rows.take(keep)
    xyz = np.column_stack(
        [to_floats(pts.column(k), pts, n) for k, n in ((1, "X"), (2, "Y"), (3, "Z"))]
    )
    ids = pts.column(0)
    check_unique(ids, pts, "control point")
    return ControlTable(ids, xyz)


def read_ori(path: Path) -> PhotoPositions:
    """Projection centres of a PATB ``.ori`` file (three records per photo)."""
    rows = split_rows(path, read_text(path, "PATB exterior orientation"), comments=("#", "*"))
    records = [k for k, f in enumerate(rows.fields) if not (_is_end(f[0]) and len(f) == 1)]
    if not records or len(records) % 3:
        raise ConfigError(
            f"{path}: expected three records per photo (photo X Y Z; a11..a22; a23..a33), got "
            f"{len(records)} record(s)"
        )
    heads = records[0::3]
    photos, xyz = [], []
    for k, m1, m2 in zip(heads, records[1::3], records[2::3], strict=True):
        fields = rows.fields[k]
        if len(fields) < 4 or len(rows.fields[m1]) != 5 or len(rows.fields[m2]) != 4:
            raise ConfigError(
                f"{rows.where(k)}: expected 'photo X Y Z' then 5 and 4 matrix elements"
            )
        photos.append(fields[0])
        xyz.append(line_floats(fields[1:4], rows.where(k), "X Y Z"))
        line_floats(rows.fields[m1] + rows.fields[m2], rows.where(m1), "rotation matrix")
    return PhotoPositions(np.asarray(photos, str), np.asarray(xyz))


def import_patb(
    im_file: str | Path,
    con_file: str | Path,
    options: ImportOptions | None = None,
    *,
    focal_mm: float,
    crs: str,
    principal_point_mm: tuple[float, float] | None = None,
    units: str = "mm",
    ori_file: str | Path | None = None,
) -> ImportedProject:
    """A project from PATB ``.im`` and ``.con`` files (and optionally ``.ori``).

    Parameters
    ----------
    focal_mm : float
        Calibrated principal distance (the PATB camera file, not read here).
    crs : str
        CRS of the ``.con`` coordinates (PATB does not store it).
    principal_point_mm : (float, float), optional
        x0, y0 when the ``.im`` coordinates are not reduced to the principal point.
    units : {"mm", "um"}
        Units of the ``.im`` coordinates.
    ori_file : path, optional
        Projection centres, written as ``[gnss]`` and used to find the strips.
    """
    options = options or ImportOptions()
    im_path, con_path = Path(im_file), Path(con_file)
    images = read_im(im_path, units)
    control = read_con(con_path)
    inputs = [im_path, con_path]
    notes = [
        f"image coordinates from {im_path.name} in {units}, x right, y up"
        + (", written in mm" if units != "mm" else ""),
        f"camera: c = {focal_mm:g} mm (given)",
    ]
    gnss = None
    if ori_file is not None:
        gnss = read_ori(Path(ori_file))
        inputs.append(Path(ori_file))
        notes.append(f"GNSS centres: the projection centres of {Path(ori_file).name}")
    return assemble(
        f"the PATB files {im_path} and {con_path}",
        images,
        ImageFrame("mm"),
        Camera(focal_mm, principal_point_mm),
        control,
        crs,
        options,
        inputs=inputs,
        default_name=im_path.stem,
        track=gnss,
        track_crs=crs,
        gnss=gnss,
        notes=notes,
    )
