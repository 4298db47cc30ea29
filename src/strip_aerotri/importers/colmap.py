"""COLMAP's text model: ``cameras.txt``, ``images.txt``, ``points3D.txt``.

The layout is COLMAP's documented text format (colmap.github.io, "Output
format"):

* ``cameras.txt``: ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]``;
* ``images.txt``: two lines per image, ``IMAGE_ID QW QX QY QZ TX TY TZ
  CAMERA_ID NAME`` and ``POINTS2D[] as (X, Y, POINT3D_ID)`` (the second line
  may be empty); the quaternion and translation map world to camera,
  ``X_cam = R X_world + t``, so the projection centre is ``-R^T t``;
* ``points3D.txt``: ``POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID,
  POINT2D_IDX)``.

Pixel coordinates have their origin at the top-left corner of the image
(the centre of the first pixel is (0.5, 0.5)), columns right, rows down; the
camera frame is x right, y down, z forward.

Every observation with a ``POINT3D_ID`` other than -1 becomes a tie point
``C<POINT3D_ID>``.  The camera is converted where a faithful conversion
exists (:func:`camera_from_colmap`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .common import (
    Camera,
    Distortion,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    PhotoPositions,
    assemble,
    line_floats,
    photo_id,
    read_text,
    split_rows,
    to_floats,
)
from .gcp_list import read_gcp_list

__all__ = [
    "TIE_PREFIX",
    "ColmapCamera",
    "ColmapModel",
    "camera_from_colmap",
    "import_colmap",
    "read_cameras",
    "read_images",
    "read_model",
    "read_points3d",
]

#: Prefix of the tie point ids (``C<POINT3D_ID>``).
TIE_PREFIX = "C"

#: Parameters of each model COLMAP defines, in its order.
_MODELS = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
    "FULL_OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
}
_OTHER_MODELS = (
    "SIMPLE_RADIAL_FISHEYE",
    "RADIAL_FISHEYE",
    "OPENCV_FISHEYE",
    "FOV",
    "THIN_PRISM_FISHEYE",
)


@dataclass(frozen=True)
class ColmapCamera:
    """One line of ``cameras.txt``."""

    camera_id: int
    model: str
    width: int
    height: int
    params: dict[str, float]
    where: str


@dataclass(frozen=True)
class ColmapModel:
    """What the importers use of a COLMAP text model.

    Attributes
    ----------
    camera : ColmapCamera
        The one camera of the photos.
    ties : ImageTable
        Pixel observations of the 3D points, ids ``C<POINT3D_ID>``.
    centres : PhotoPositions
        Projection centres in the model's world frame.
    files : tuple of Path
    """

    camera: ColmapCamera
    ties: ImageTable
    centres: PhotoPositions
    files: tuple[Path, ...]


def read_cameras(path: Path) -> dict[int, ColmapCamera]:
    """``cameras.txt``: every camera by its id.

    Raises
    ------
    ConfigError
        An unknown model, a wrong number of parameters, or a bad number.
    """
    rows = split_rows(path, read_text(path, "COLMAP cameras"))
    rows.require_fields(4, "CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]")
    cameras: dict[int, ColmapCamera] = {}
    for k, fields in enumerate(rows.fields):  # a loop over cameras (a handful)
        model = fields[1].upper()
        names = _MODELS.get(model)
        if names is None:
            known = ", ".join(_MODELS)
            extra = " (a fisheye model)" if model in _OTHER_MODELS else ""
            raise ConfigError(
                f"{rows.where(k)}: camera model {fields[1]}{extra} has no faithful conversion "
                f"to the project's camera; models read: {known}"
            )
        values = fields[4:]
        if len(values) != len(names):
            raise ConfigError(
                f"{rows.where(k)}: model {model} takes {len(names)} parameters "
                f"({' '.join(names)}), got {len(values)}"
            )
        numbers = line_floats(fields[:1] + fields[2:], rows.where(k), "camera")
        camera_id, width, height = int(numbers[0]), int(numbers[1]), int(numbers[2])
        params = dict(zip(names, numbers[3:].tolist(), strict=True))
        if camera_id in cameras:
            raise ConfigError(f"{rows.where(k)}: camera {camera_id} is listed twice")
        cameras[camera_id] = ColmapCamera(camera_id, model, width, height, params, rows.where(k))
    if not cameras:
        raise ConfigError(f"{path}: no camera")
    return cameras


def read_images(
    path: Path,
) -> tuple[list[str], list[int], np.ndarray, np.ndarray, ImageTable, dict[str, str]]:
    """``images.txt``: names, camera ids, poses and the observations of 3D points.

    Returns
    -------
    names : list of str
        Photo ids (file names without folder and extension).
    camera_ids : list of int
    quaternions : ndarray, shape (M, 4)
        QW QX QY QZ (world to camera).
    translations : ndarray, shape (M, 3)
    ties : ImageTable
        Observations whose POINT3D_ID is not -1, pixels, ids ``C<id>``.
    where : dict
        ``file:line`` of each photo's header line.
    """
    text = read_text(path, "COLMAP images")
    lines = text.splitlines()
    names: list[str] = []
    camera_ids: list[int] = []
    poses: list[np.ndarray] = []
    photo_parts: list[np.ndarray] = []
    point_parts: list[np.ndarray] = []
    xy_parts: list[np.ndarray] = []
    where: dict[str, str] = {}
    k = 0
    while k < len(lines):  # a loop over images; each image's points by arrays
        line = lines[k].strip()
        k += 1
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) < 10:
            raise ConfigError(
                f"{path}:{k}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got "
                f"{len(fields)} fields"
            )
        numbers = line_floats(fields[:9], f"{path}:{k}", "image pose")
        name = str(photo_id([" ".join(fields[9:])])[0])
        if name in where:
            raise ConfigError(
                f"{path}:{k}: photo '{name}' is listed twice (first at {where[name]})"
            )
        where[name] = f"{path}:{k}"
        names.append(name)
        camera_ids.append(int(numbers[8]))
        poses.append(numbers[1:8])
        points_line = lines[k] if k < len(lines) else ""
        k += 1
        values = points_line.split()
        if len(values) % 3:
            raise ConfigError(
                f"{path}:{k}: POINTS2D: expected triples X Y POINT3D_ID, got {len(values)} values"
            )
        if values:
            try:
                arr = np.asarray(values, dtype=np.float64).reshape(-1, 3)
            except ValueError:
                raise ConfigError(f"{path}:{k}: POINTS2D: expected numbers") from None
            if not np.isfinite(arr).all():
                raise ConfigError(f"{path}:{k}: POINTS2D: expected finite numbers")
            seen = arr[:, 2] != -1
            ids = np.char.add(TIE_PREFIX, arr[seen, 2].astype(np.int64).astype(str))
            photo_parts.append(np.full(ids.shape, name))
            point_parts.append(ids)
            xy_parts.append(arr[seen, :2])
    if not names:
        raise ConfigError(f"{path}: no image")
    ties = ImageTable(
        np.concatenate(photo_parts) if photo_parts else np.empty(0, str),
        np.concatenate(point_parts) if point_parts else np.empty(0, str),
        np.concatenate(xy_parts) if xy_parts else np.empty((0, 2)),
    )
    pose = np.asarray(poses)
    return names, camera_ids, pose[:, :4], pose[:, 4:], ties, where


def read_points3d(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``points3D.txt``: ids, reprojection errors (px) and track lengths."""
    rows = split_rows(path, read_text(path, "COLMAP 3D points"))
    rows.require_fields(8, "POINT3D_ID X Y Z R G B ERROR TRACK[]")
    counts = rows.counts()
    odd = np.flatnonzero((counts - 8) % 2)
    if odd.size:
        raise ConfigError(f"{rows.where(int(odd[0]))}: TRACK: expected pairs IMAGE_ID POINT2D_IDX")
    ids = to_floats(rows.column(0), rows, "POINT3D_ID").astype(np.int64)
    error = to_floats(rows.column(7), rows, "ERROR")
    return ids, error, (counts - 8) // 2


def _rotation_from_quaternion(q: np.ndarray) -> np.ndarray:
    """World-to-camera matrices from unit quaternions QW QX QY QZ, shape (M, 4) -> (M, 3, 3)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    ).reshape(-1, 3, 3)


def read_model(
    folder: str | Path, *, min_track: int = 2, max_error_px: float | None = None
) -> tuple[ColmapModel, list[str]]:
    """Read a COLMAP text model from ``folder``.

    Parameters
    ----------
    min_track : int
        Leave out 3D points seen on fewer photos.
    max_error_px : float, optional
        Leave out 3D points whose mean reprojection error is larger.

    Raises
    ------
    ConfigError
        A missing file, an observation of a 3D point that points3D.txt does not
        list, or photos of more than one camera.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder}: not a folder (expected a COLMAP text model)")
    files = tuple(folder / n for n in ("cameras.txt", "images.txt", "points3D.txt"))
    for f in files:
        if not f.is_file():
            extra = " (a binary model? convert it with `colmap model_converter --output_type TXT`)"
            raise ConfigError(f"{f}: file not found (COLMAP text model){extra}")
    cameras = read_cameras(files[0])
    names, camera_ids, quat, trans, ties, where = read_images(files[1])
    ids, error, track = read_points3d(files[2])
    notes: list[str] = []
    used = sorted(set(camera_ids))
    unknown = [c for c in used if c not in cameras]
    if unknown:
        photo = names[camera_ids.index(unknown[0])]
        raise ConfigError(f"{where[photo]}: camera {unknown[0]} is not in {files[0]}")
    if len(used) > 1:
        raise ConfigError(
            f"{files[1]}: the photos use {len(used)} cameras ({', '.join(map(str, used))}); a "
            "project has one camera (re-run COLMAP with a single shared camera)"
        )
    camera = cameras[used[0]]
    tie_ids = np.char.add(TIE_PREFIX, ids.astype(str))
    missing = ~np.isin(ties.point, tie_ids)
    if missing.any():
        k = int(np.flatnonzero(missing)[0])
        raise ConfigError(
            f"{files[1]}: photo '{ties.photo[k]}' observes 3D point {ties.point[k][1:]}, which "
            f"{files[2].name} does not list"
        )
    bad = track < min_track
    if max_error_px is not None:
        bad |= error > max_error_px
    if bad.any():
        ties = ties.take(~np.isin(ties.point, tie_ids[bad]))
        notes.append(
            f"{int(bad.sum())} COLMAP 3D point(s) left out (track under {min_track} photos"
            + (f" or error over {max_error_px:g} px" if max_error_px is not None else "")
            + ")"
        )
    rot = _rotation_from_quaternion(quat)
    centres = -np.einsum("mji,mj->mi", rot, trans)
    model = ColmapModel(camera, ties, PhotoPositions(np.asarray(names, str), centres), files)
    return model, notes


def camera_from_colmap(
    camera: ColmapCamera, pixel_size_mm: float
) -> tuple[Camera, ImageFrame, Distortion | None, list[str]]:
    """The project's camera keys from a COLMAP camera.

    With f the focal length in pixels and s the pixel size: c = f s;
    ``[images] units = "pixel"`` with ``principal_point_px = [cx, cy]`` (the
    same pixel convention as the observations); distortion as ``units =
    "normalized"``, ``model = "projection"`` (COLMAP distorts the ideal
    normalised point): k1, k2 (and FULL_OPENCV's k3) unchanged, and OpenCV's
    y-down tangential terms as p1 = OpenCV p2, p2 = -OpenCV p1
    (docs/project-file.md, ``[distortion]``).

    Raises
    ------
    ConfigError
        fx and fy differ (the project has square pixels and no affinity), or
        FULL_OPENCV's rational terms k4..k6 are not zero.
    """
    p = camera.params
    notes: list[str] = []
    if "f" in p:
        f = p["f"]
    else:
        fx, fy = p["fx"], p["fy"]
        if abs(fx - fy) > 1e-6 * max(abs(fx), abs(fy)):
            raise ConfigError(
                f"{camera.where}: fx = {fx!r} and fy = {fy!r} differ; the project's camera has "
                "one principal distance (no affinity), so this camera cannot be converted"
            )
        f = 0.5 * (fx + fy)
    for key in ("k4", "k5", "k6"):
        if p.get(key, 0.0) != 0.0:
            raise ConfigError(
                f"{camera.where}: {key} = {p[key]!r}: FULL_OPENCV's rational terms have no "
                "counterpart in the project's distortion; refit with OPENCV"
            )
    if not (f > 0 and pixel_size_mm > 0):
        raise ConfigError(f"{camera.where}: focal length and pixel size must be positive")
    frame = ImageFrame("pixel", pixel_size_mm, (p["cx"], p["cy"]))
    distortion = Distortion(
        k1=p.get("k", p.get("k1", 0.0)),
        k2=p.get("k2", 0.0),
        k3=p.get("k3", 0.0),
        p1=p.get("p2", 0.0),
        p2=-p.get("p1", 0.0),
        units="normalized",
        model="projection",
        comment=(
            f"COLMAP {camera.model} camera {camera.camera_id}: OpenCV's (k1, k2, k3, p1, p2) "
            "as (k1, k2, k3, p2, -p1) in x right, y up"
        ),
    )
    notes.append(
        f"camera: COLMAP {camera.model}, f = {f:.4f} px x {pixel_size_mm:g} mm = "
        f"{f * pixel_size_mm:.6f} mm, principal point ({p['cx']:.3f}, {p['cy']:.3f}) px"
    )
    return Camera(f * pixel_size_mm), frame, (None if distortion.is_zero else distortion), notes


def georeferenced_centres(centres: PhotoPositions, pose_crs: str, crs: str) -> PhotoPositions:
    """Projection centres of a geo-registered model in the project CRS.

    ``pose_crs`` is the CRS of the model's world frame (for example
    ``EPSG:4978`` after ``colmap model_aligner --alignment_type ecef``, or the
    project's projected CRS); the centres are transformed with pyproj
    (``always_xy``).  With ``crs = "local"`` only ``pose_crs = "local"`` is
    accepted.
    """
    if crs.strip().lower() == "local" or pose_crs.strip().lower() == "local":
        if crs.strip().lower() != pose_crs.strip().lower():
            raise ConfigError(
                f"--pose-crs {pose_crs!r} and crs {crs!r}: a local site system cannot be "
                "transformed to or from a CRS"
            )
        return centres
    from pyproj import CRS, Transformer

    try:
        src, dst = CRS.from_user_input(pose_crs), CRS.from_user_input(crs)
    except Exception as exc:
        raise ConfigError(f"--pose-crs {pose_crs!r} or crs {crs!r}: {exc}") from None
    if src == dst:
        return centres
    t = Transformer.from_crs(src, dst, always_xy=True)
    x, y, z = t.transform(centres.xyz[:, 0], centres.xyz[:, 1], centres.xyz[:, 2])
    return PhotoPositions(centres.photo, np.column_stack([x, y, z]))


def import_colmap(
    model_dir: str | Path,
    options: ImportOptions | None = None,
    *,
    pixel_size_mm: float,
    gcps: str | Path,
    crs: str | None = None,
    pose_crs: str | None = None,
    min_track: int = 2,
    max_error_px: float | None = None,
) -> ImportedProject:
    """A project from a COLMAP text model (tie points, camera) and an ODM GCP file.

    Parameters
    ----------
    model_dir : path
        Folder with cameras.txt, images.txt, points3D.txt.
    pixel_size_mm : float
        Side of a pixel (COLMAP works in pixels only).
    gcps : path
        The control: an OpenDroneMap ``gcp_list.txt`` (ground coordinates and
        their pixel observations on the same images).
    crs : str, optional
        Overrides the CRS of the GCP file.
    pose_crs : str, optional
        The model is geo-registered in this CRS: its projection centres are
        written as ``[gnss]`` observations.  Without it the centres are used
        only to find the strips (their frame is arbitrary).
    min_track, max_error_px
        See :func:`read_model`.
    """
    options = options or ImportOptions()
    model, notes = read_model(model_dir, min_track=min_track, max_error_px=max_error_px)
    camera, frame, distortion, more = camera_from_colmap(model.camera, pixel_size_mm)
    notes += more
    gcp = read_gcp_list(Path(gcps))
    crs = crs or gcp.crs
    clash = np.intersect1d(gcp.control.point, np.unique(model.ties.point))
    if clash.size:
        raise ConfigError(f"{gcps}: GCP name '{clash[0]}' is also a COLMAP tie point id")
    images = ImageTable.concat([gcp.images, model.ties])
    gnss = None
    if pose_crs is not None:
        gnss = georeferenced_centres(model.centres, pose_crs, crs)
        notes.append(f"GNSS centres: the COLMAP projection centres, model frame {pose_crs}")
    return assemble(
        f"the COLMAP model in {model_dir} with the GCPs of {gcps}",
        images,
        frame,
        camera,
        gcp.control,
        crs,
        options,
        inputs=[*model.files, Path(gcps)],
        default_name=Path(model_dir).resolve().name,
        distortion=distortion,
        track=gnss if gnss is not None else model.centres,
        track_crs=crs if gnss is not None else None,
        gnss=gnss,
        notes=[*notes, *gcp.notes],
    )
