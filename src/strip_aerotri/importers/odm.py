"""OpenDroneMap / WebODM ground control: ``gcp_list.txt`` (its layout and
reader in :mod:`.gcp_list`) imported as a project.

The file holds no tie points: they come from another source, such as a
COLMAP model (``ties``, see :mod:`.colmap`).  Nor does it hold the camera:
its focal length and pixel size are given (:class:`PixelCamera`), or come
from the COLMAP model.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .common import (
    Camera,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    assemble,
)
from .gcp_list import GcpList, crs_from_odm, read_gcp_list

__all__ = ["GcpList", "PixelCamera", "crs_from_odm", "import_odm", "read_gcp_list"]

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
