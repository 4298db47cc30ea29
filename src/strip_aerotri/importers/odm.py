"""OpenDroneMap / WebODM ground control: ``gcp_list.txt``.

The layout of OpenDroneMap's documentation ("Ground Control Points", the GCP
file format): the first line is the CRS of the ground coordinates, a PROJ
string (``+proj=utm +zone=32 +datum=WGS84 +units=m +no_defs``), ``EPSG:nnnn``
or ``WGS84 UTM <zone><N|S>``; every following line is

    geo_x geo_y geo_z im_x im_y image_name [gcp_name [extra ...]]

separated by spaces or tabs, ``im_x``, ``im_y`` the pixel column and row of
the GCP on the image (origin top-left, rows down).  Without ``gcp_name`` the
lines with the same ``geo_x geo_y geo_z`` are one GCP (named ``gcp1``,
``gcp2``, ... in order of appearance).

The file holds no tie points: they come from another source, such as a
COLMAP model (``ties``, see :mod:`.colmap`).  Nor does it hold the camera:
its focal length and pixel size are given (:class:`PixelCamera`), or come
from the COLMAP model.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .common import (
    Camera,
    ControlTable,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    assemble,
    photo_id,
    read_text,
    split_rows,
    to_floats,
)

__all__ = ["GcpList", "PixelCamera", "crs_from_odm", "import_odm", "read_gcp_list"]

_UTM = re.compile(r"^\s*WGS\s*-?\s*84\s+UTM\s+(\d{1,2})\s*([NS])\s*$", re.IGNORECASE)


def crs_from_odm(text: str, where: str) -> str:
    """The CRS of a gcp_list.txt header line, as pyproj understands it.

    ``WGS84 UTM 32N`` becomes ``EPSG:32632`` (``32S``: ``EPSG:32732``);
    anything else (a PROJ string, ``EPSG:nnnn``, WKT) is passed on after
    pyproj has read it.
    """
    text = text.strip()
    m = _UTM.match(text)
    if m:
        zone = int(m.group(1))
        if not 1 <= zone <= 60:
            raise ConfigError(f"{where}: UTM zone {zone} is not 1..60")
        return f"EPSG:{32600 + zone if m.group(2).upper() == 'N' else 32700 + zone}"
    from pyproj import CRS

    try:
        CRS.from_user_input(text)
    except Exception:
        raise ConfigError(
            f"{where}: the first line must be the CRS (a PROJ string, EPSG:nnnn or "
            f"'WGS84 UTM 32N'), got {text!r}"
        ) from None
    return text


@dataclass(frozen=True)
class GcpList:
    """What a gcp_list.txt holds."""

    crs: str
    images: ImageTable
    control: ControlTable
    notes: list[str] = field(default_factory=list)


def read_gcp_list(path: Path) -> GcpList:
    """Read an OpenDroneMap ``gcp_list.txt``.

    Raises
    ------
    ConfigError
        A bad CRS line, a line with fewer than 6 fields or a bad number, or a
        GCP name given with two different ground coordinates.
    """
    text = read_text(path, "OpenDroneMap GCP list")
    lines = text.splitlines()
    head = next(
        (k for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")),
        None,
    )
    if head is None:
        raise ConfigError(f"{path}: empty (expected the CRS on the first line)")
    crs = crs_from_odm(lines[head], f"{path}:{head + 1}")
    rows = split_rows(path, "\n" * (head + 1) + "\n".join(lines[head + 1 :]))
    if not len(rows):
        raise ConfigError(f"{path}: no GCP observation after the CRS line")
    rows.require_fields(6, "geo_x geo_y geo_z im_x im_y image_name [gcp_name]")
    geo = np.column_stack(
        [
            to_floats(rows.column(k), rows, name)
            for k, name in enumerate(("geo_x", "geo_y", "geo_z"))
        ]
    )
    pix = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in ((3, "im_x"), (4, "im_y"))]
    )
    photos = photo_id(rows.column(5))
    counts = rows.counts()
    notes: list[str] = []
    if (counts >= 7).all():
        names = np.array([f[6] for f in rows.fields], dtype=str)
    elif (counts == 6).all():
        _, first, inverse = np.unique(geo, axis=0, return_index=True, return_inverse=True)
        rank = np.argsort(np.argsort(first))  # in order of appearance
        names = np.char.add("gcp", (rank[inverse.reshape(-1)] + 1).astype(str))
        notes.append(
            "GCPs without names: lines with equal coordinates are one GCP (gcp1, gcp2, ...)"
        )
    else:
        named = counts >= 7
        k = int(np.flatnonzero(named != named[0])[0])
        raise ConfigError(f"{rows.where(k)}: some lines name their GCP and some do not")
    uniq, first, inverse = np.unique(names, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    differ = np.any(
        np.abs(geo - geo[first][inverse]) > 1e-9 * np.maximum(1.0, np.abs(geo)), axis=1
    )
    if differ.any():
        k = int(np.flatnonzero(differ)[0])
        raise ConfigError(
            f"{rows.where(k)}: GCP '{names[k]}' has other coordinates than at line "
            f"{int(rows.lines[first[inverse[k]]])}"
        )
    images = ImageTable(photos, names, pix)
    control = ControlTable(uniq, geo[first])
    return GcpList(crs, images, control, notes)


@dataclass(frozen=True)
class PixelCamera:
    """A digital camera given by its focal length, pixel size and image size.

    Attributes
    ----------
    focal_mm : float
    pixel_size_mm : float
    image_size : (int, int)
        Width and height in pixels.
    principal_point_px : (float, float), optional
        Column and row; default the image centre ``(W/2, H/2)``.
    """

    focal_mm: float
    pixel_size_mm: float
    image_size: tuple[int, int]
    principal_point_px: tuple[float, float] | None = None

    @staticmethod
    def from_options(
        focal_mm: float | None,
        pixel_um: float | None,
        sensor_width_mm: float | None,
        image_size: tuple[int, int] | None,
        principal_point_px: tuple[float, float] | None = None,
    ) -> PixelCamera:
        """From the command-line options; each missing one is named."""
        if focal_mm is None:
            raise ConfigError("the camera needs --focal-mm (the calibrated focal length in mm)")
        if image_size is None:
            raise ConfigError("the camera needs --image-size W H (pixels)")
        if pixel_um is not None and sensor_width_mm is not None:
            raise ConfigError("give --pixel-um or --sensor-width-mm, not both")
        if pixel_um is not None:
            pixel = pixel_um / 1000.0
        elif sensor_width_mm is not None:
            pixel = sensor_width_mm / image_size[0]
        else:
            raise ConfigError("the camera needs --pixel-um or --sensor-width-mm")
        if not (focal_mm > 0 and pixel > 0 and min(image_size) > 0):
            raise ConfigError("focal length, pixel size and image size must be positive")
        return PixelCamera(focal_mm, pixel, image_size, principal_point_px)

    def check_marks(self, images: ImageTable, source: str) -> None:
        """Refuse an image size that contradicts the marked pixels.

        A mark outside the image (beyond half a pixel) is an error, naming
        the photo and point; so is marks whose mean column or row lies far
        from the centre the image size gives (more than a tenth of the size
        and more than four standard errors of a uniform spread), unless the
        principal point is given: the image size then sets the principal
        point wrongly (as a larger size with the marks of a smaller image).

        Raises
        ------
        ConfigError
            Naming ``source``, the image size and what contradicts it.
        """
        xy = np.asarray(images.xy, dtype=np.float64).reshape(-1, 2)
        size = np.asarray(self.image_size, dtype=np.float64)
        given = f"--image-size {self.image_size[0]} {self.image_size[1]}"
        outside = np.flatnonzero(((xy < -0.5) | (xy > size + 0.5)).any(axis=1))
        if outside.size:
            k = int(outside[0])
            raise ConfigError(
                f"{source}: photo {images.photo[k]}, point {images.point[k]}: the mark at "
                f"column {xy[k, 0]:g}, row {xy[k, 1]:g} lies outside the image of {given} "
                f"({outside.size} marks do; the largest column is {xy[:, 0].max():g}, row "
                f"{xy[:, 1].max():g}): check the image size"
            )
        if self.principal_point_px is not None or len(xy) < 8:
            return
        off = xy.mean(axis=0) - size / 2.0
        spread = size / np.sqrt(12.0 * len(xy))
        far = (np.abs(off) > 0.1 * size) & (np.abs(off) > 4.0 * spread)
        if far.any():
            fits = np.round(2.0 * xy.mean(axis=0) / 100.0) * 100.0
            raise ConfigError(
                f"{source}: the {len(xy)} marks centre on column {xy[:, 0].mean():.0f}, row "
                f"{xy[:, 1].mean():.0f}, far from the centre of an image of {given} "
                f"({size[0] / 2:g}, {size[1] / 2:g}); an image of about {fits[0]:.0f} x "
                f"{fits[1]:.0f} fits them: check the image size (or give "
                "--principal-point-px if the marks truly lie off the centre)"
            )

    def frame(self) -> ImageFrame:
        pp = self.principal_point_px or (self.image_size[0] / 2.0, self.image_size[1] / 2.0)
        return ImageFrame("pixel", self.pixel_size_mm, (float(pp[0]), float(pp[1])))


def import_odm(
    gcp_file: str | Path,
    options: ImportOptions | None = None,
    *,
    camera: PixelCamera | None = None,
    ties: str | Path | None = None,
    pixel_size_mm: float | None = None,
    crs: str | None = None,
    pose_crs: str | None = None,
) -> ImportedProject:
    """A project from an OpenDroneMap ``gcp_list.txt``, with tie points from COLMAP.

    Parameters
    ----------
    gcp_file : path
    options : ImportOptions, optional
    camera : PixelCamera, optional
        The camera; required without ``ties``, refused with it (the COLMAP
        model's camera is used, converted by :func:`.colmap.camera_from_colmap`).
    ties : path, optional
        A COLMAP text model of the same images (tie points, camera, and the
        photo positions that find the strips).
    pixel_size_mm : float, optional
        Required with ``ties``.
    crs : str, optional
        Overrides the CRS line of the file.
    pose_crs : str, optional
        With ``ties``: the model is geo-registered in this CRS; its projection
        centres become ``[gnss]``.
    """
    options = options or ImportOptions()
    path = Path(gcp_file)
    if ties is not None:
        if camera is not None:
            raise ConfigError(
                "with --ties the camera comes from the COLMAP model; leave out --focal-mm and "
                "--principal-point-px"
            )
        if pixel_size_mm is None:
            raise ConfigError(
                "with --ties the pixel size is needed: --pixel-um or --sensor-width-mm"
            )
        from .colmap import import_colmap

        project = import_colmap(
            ties, options, pixel_size_mm=pixel_size_mm, gcps=path, crs=crs, pose_crs=pose_crs
        )
        return project
    if camera is None:
        raise ConfigError(
            "gcp_list.txt holds no camera: give --focal-mm, --pixel-um (or --sensor-width-mm) "
            "and --image-size, or --ties with a COLMAP model"
        )
    gcp = read_gcp_list(path)
    camera.check_marks(gcp.images, str(path))
    frame = camera.frame()
    notes = [
        *gcp.notes,
        f"camera: f = {camera.focal_mm:g} mm, pixel {camera.pixel_size_mm:g} mm, principal "
        f"point ({frame.principal_point_px[0]:g}, {frame.principal_point_px[1]:g}) px "  # type: ignore[index]
        "(given); no distortion",
        "no tie points: gcp_list.txt has only GCPs (add --ties with a COLMAP model)",
    ]
    return assemble(
        f"the OpenDroneMap GCP list {path}",
        gcp.images,
        frame,
        Camera(camera.focal_mm),
        gcp.control,
        crs or gcp.crs,
        options,
        inputs=[path],
        default_name=path.resolve().parent.name,
        notes=notes,
    )
