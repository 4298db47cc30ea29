"""Pix4D exports: image marks, GCP coordinates and calibrated external camera parameters.

* **Marks** (GCP/MTP Manager > Export Marks, "PIX4D marks files"): a record
  per mark ``image name, point label, x, y[, accuracy[, zoom]]`` separated by
  commas (or semicolons, tabs, spaces), x and y the pixel column and row from
  the upper-left corner of the image (Pix4D, "How to import and export Tie
  Points marks"); the accuracy (pixels) becomes the observation's sigma.
* **GCP coordinates** (the file Pix4D imports): ``label, c1, c2, z[,
  accuracy horizontal, accuracy vertical]`` with c1, c2 in the axis order of
  the CRS definition (Pix4D, "Tie points (GCPs, CPs) import format"): for
  EPSG:4326 latitude then longitude.  They are written in pyproj's
  ``always_xy`` order (longitude, latitude; easting, northing).
* **Calibrated external camera parameters**
  (``<project>_calibrated_external_camera_parameters.txt``): a header line
  ``imageName X Y Z Omega Phi Kappa`` and a row per photo, the projection
  centre in the output CRS and the angles (degrees) of Pix4D's documented
  PATB convention ("How are the internal and external camera parameters
  defined"): ``R = Rx(omega) Ry(phi) Rz(kappa)``, camera x right, y up, z
  back, ``X_cam = R^T (X - T)``, world X east, Y north, Z up on the map grid.

The camera is given on the command line (focal length, pixel size, image
size, principal point); Pix4D's distortion is not imported.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .common import (
    Camera,
    ControlTable,
    ImageTable,
    ImportedProject,
    ImportOptions,
    PhotoPositions,
    Rows,
    assemble,
    attitudes_from_opk,
    check_unique,
    photo_id,
    read_text,
    split_rows,
    to_floats,
)
from .odm import PixelCamera

__all__ = ["import_pix4d", "read_external", "read_gcp_coordinates", "read_marks"]


def _sniff(text: str) -> str | None:
    sample = "\n".join(
        line for line in text.splitlines()[:20] if not line.lstrip().startswith("#")
    )
    for delimiter in (",", ";", "\t"):
        if delimiter in sample:
            return delimiter
    return None


def _numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _drop_header(rows: Rows, column: int) -> Rows:
    if len(rows) and len(rows.fields[0]) > column and not _numeric(rows.fields[0][column]):
        return rows.take(np.arange(1, len(rows)))
    return rows


def read_marks(path: Path) -> ImageTable:
    """Pix4D marks: observations in pixels; sigma = accuracy when given (px, see import_pix4d)."""
    text = read_text(path, "Pix4D marks")
    rows = _drop_header(split_rows(path, text, delimiter=_sniff(text)), 2)
    rows.require_fields(4, "image name, point label, x, y[, accuracy]")
    xy = np.column_stack(
        [to_floats(rows.column(2), rows, "x"), to_floats(rows.column(3), rows, "y")]
    )
    counts = rows.counts()
    sigma = None
    if (counts >= 5).all():
        sigma = to_floats(rows.column(4), rows, "accuracy")
        bad = np.flatnonzero(sigma <= 0)
        if bad.size:
            raise ConfigError(f"{rows.where(int(bad[0]))}: accuracy must be positive")
    return ImageTable(photo_id(rows.column(0)), rows.column(1), xy, sigma)


def _first_axis_is_north(crs: str) -> bool:
    if crs.strip().lower() == "local":
        return False
    from pyproj import CRS

    axes = CRS.from_user_input(crs).axis_info
    return bool(axes) and axes[0].direction.lower() in ("north", "south")


def read_gcp_coordinates(path: Path, crs: str, order: str = "auto") -> tuple[ControlTable, str]:
    """Pix4D GCP coordinates as ``always_xy`` X, Y and H.

    Parameters
    ----------
    order : {"auto", "xy", "yx"}
        Order of c1, c2 in the file: ``auto`` takes the CRS definition's
        axis order (as Pix4D does), ``xy`` easting/longitude first, ``yx``
        northing/latitude first.
    """
    text = read_text(path, "Pix4D GCP coordinates")
    rows = _drop_header(split_rows(path, text, delimiter=_sniff(text)), 1)
    rows.require_fields(4, "label, c1, c2, z[, accuracy horizontal, accuracy vertical]")
    c = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in ((1, "c1"), (2, "c2"), (3, "z"))]
    )
    swap = order == "yx" or (order == "auto" and _first_axis_is_north(crs))
    if swap:
        c = c[:, [1, 0, 2]]
    counts = rows.counts()
    sxy = sh = None
    if (counts >= 6).all():
        sxy = to_floats(rows.column(4), rows, "accuracy horizontal")
        sh = to_floats(rows.column(5), rows, "accuracy vertical")
    label = rows.column(0)
    check_unique(label, rows, "GCP")
    note = (
        f"{path.name}: c1, c2 read as "
        + (
            "northing/latitude, easting/longitude"
            if swap
            else "easting/longitude, northing/latitude"
        )
        + (" (the CRS's axis order)" if order == "auto" else " (--gcp-axis-order)")
    )
    return ControlTable(label, c, sigma_xy=sxy, sigma_h=sh), note


def read_external(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Calibrated external camera parameters: photo ids, X Y Z, omega phi kappa (degrees)."""
    text = read_text(path, "Pix4D calibrated external camera parameters")
    rows = split_rows(path, text)
    if not len(rows):
        raise ConfigError(f"{path}: no row")
    names = ["imagename", "x", "y", "z", "omega", "phi", "kappa"]
    columns = list(range(7))
    if not _numeric(rows.fields[0][1] if len(rows.fields[0]) > 1 else "x"):
        header = [h.lower() for h in rows.fields[0]]
        missing = [n for n in names if n not in header]
        if missing:
            raise ConfigError(f"{rows.where(0)}: header without column '{missing[0]}'")
        columns = [header.index(n) for n in names]
        rows = rows.take(np.arange(1, len(rows)))
    rows.require_fields(max(columns) + 1, "imageName X Y Z Omega Phi Kappa")
    photo = photo_id(rows.column(columns[0]))
    values = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in zip(columns[1:], names[1:], strict=True)]
    )
    check_unique(photo, rows, "photo")
    return photo, values[:, :3], values[:, 3:]


def import_pix4d(
    marks_file: str | Path,
    gcp_file: str | Path,
    options: ImportOptions | None = None,
    *,
    camera: PixelCamera,
    crs: str,
    external_file: str | Path | None = None,
    gcp_axis_order: str = "auto",
    attitudes: bool = True,
) -> ImportedProject:
    """A project from Pix4D marks, GCP coordinates and (optionally) external parameters.

    Parameters
    ----------
    camera : PixelCamera
        Focal length, pixel size, image size (and principal point).
    crs : str
        The CRS of the GCPs and of the external parameters (Pix4D's output
        coordinate system).
    external_file : path, optional
        ``*_calibrated_external_camera_parameters.txt``: ``[gnss]``, the strips,
        and ``[imu]`` (unless ``attitudes`` is False).
    gcp_axis_order : {"auto", "xy", "yx"}
    """
    options = options or ImportOptions()
    marks_path, gcp_path = Path(marks_file), Path(gcp_file)
    images = read_marks(marks_path)
    camera.check_marks(images, str(marks_path))
    if images.sigma_mm is not None:
        images = ImageTable(
            images.photo, images.point, images.xy, images.sigma_mm * camera.pixel_size_mm
        )
    control, note = read_gcp_coordinates(gcp_path, crs, gcp_axis_order)
    notes = [
        note,
        f"camera: f = {camera.focal_mm:g} mm, pixel {camera.pixel_size_mm:g} mm (given); "
        "Pix4D's distortion is not imported",
    ]
    inputs = [marks_path, gcp_path]
    gnss = imu = None
    if external_file is not None:
        epath = Path(external_file)
        inputs.append(epath)
        photo, xyz, opk = read_external(epath)
        gnss = PhotoPositions(photo, xyz)
        notes.append(f"GNSS centres: X Y Z of {epath.name}")
        if attitudes:
            imu = attitudes_from_opk(photo, opk, xyz[:, :2], crs, str(epath))
            notes.append(
                f"attitudes of {epath.name}: Pix4D's PATB omega, phi, kappa on the map grid, "
                "turned by the meridian convergence to east-north-up"
            )
    return assemble(
        f"the Pix4D files {marks_path} and {gcp_path}"
        + (f" with {external_file}" if external_file else ""),
        images,
        camera.frame(),
        Camera(camera.focal_mm),
        control,
        crs,
        options,
        inputs=inputs,
        default_name=marks_path.stem,
        track=gnss,
        track_crs=crs,
        gnss=gnss,
        imu=imu,
        notes=notes,
    )
