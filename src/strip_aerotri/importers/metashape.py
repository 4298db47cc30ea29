"""Agisoft Metashape exports: markers XML and the Omega Phi Kappa camera text.

* **Markers / cameras XML** (File > Export > Export Markers, or Export
  Cameras in the Agisoft XML format): ``document/chunk`` with

  - ``cameras/camera`` (also inside ``group``): ``id`` and ``label`` (the
    photo; its file name without extension);
  - ``markers/marker``: ``id``, ``label`` and an optional ``reference``
    element ``x y z enabled`` (the ground coordinates in the chunk CRS; a
    marker whose reference is disabled is a check point in Metashape, one
    without a reference is a tie point);
  - ``frames/frame/markers/marker marker_id`` with ``location camera_id x y``:
    the marker's pixel column and row on a photo (origin top-left, rows down);
  - ``reference``: the chunk CRS as WKT;
  - optionally ``sensors/sensor`` with ``resolution``, the ``pixel_width``
    property (mm) and a ``calibration`` (f, cx, cy, k1..k4, p1, p2, b1, b2 in
    pixels, cx, cy from the image centre).

* **Omega Phi Kappa text** (File > Export > Export Cameras > Omega Phi
  Kappa): a row per photo ``label X Y Z omega phi kappa [r11 .. r33]``
  (tabs or spaces), comment lines ``#``.  The angles are read in the PATB
  convention (``R = Rx(omega) Ry(phi) Rz(kappa)`` from the camera x right, y
  up, z back to the grid of the projected chunk CRS); docs/import.md says
  what is checked of this reading and what is not.

The camera model of Metashape's Appendix C ("Camera models", frame camera):
``x' = x(1 + K1 r^2 + K2 r^4 + K3 r^6 + K4 r^8) + P1 (r^2 + 2x^2) + 2 P2 x y``,
``y' = y(...) + P2 (r^2 + 2y^2) + 2 P1 x y`` on the normalised camera
coordinates (x right, y down), ``u = W/2 + cx + x' f + x' B1 + y' B2``,
``v = H/2 + cy + y' f``.  In the project's axes (x right, y up) these are
p1 = P1 and p2 = -P2, with ``units = "normalized"``, ``model =
"projection"``; K4, B1 and B2 have no counterpart and must be zero.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..geometry.rotation import matrix_from_opk
from .common import (
    Camera,
    ControlTable,
    Distortion,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    PhotoPositions,
    assemble,
    attitudes_from_opk,
    check_unique,
    line_floats,
    photo_id,
    read_text,
    split_rows,
    to_floats,
)
from .odm import PixelCamera

__all__ = ["MarkersXml", "import_metashape", "read_markers_xml", "read_opk_text"]

_EPSG = re.compile(r"EPSG:{1,2}(\d{4,6})")


def _crs_from_wkt(wkt: str, where: str) -> str:
    """The chunk CRS: ``local`` for a LOCAL_CS, ``EPSG:n`` when pyproj knows it, else the WKT."""
    if wkt.upper().startswith(("LOCAL_CS", "ENGCRS", "ENGINEERINGCRS")):
        return "local"
    from pyproj import CRS

    try:
        crs = CRS.from_wkt(wkt)
    except Exception:
        raise ConfigError(f"{where}: not a CRS pyproj can read; give --crs") from None
    if crs.is_compound or crs.is_vertical:
        raise ConfigError(
            f"{where}: the chunk CRS has a vertical datum (heights above a geoid, not the "
            "ellipsoid); give --crs with its horizontal CRS and make sure the marker heights "
            "are ellipsoidal"
        )
    code = crs.to_epsg(min_confidence=90)
    return f"EPSG:{code}" if code else wkt


def read_opk_text(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
    """Metashape's Omega Phi Kappa text: labels, X Y Z, angles (degrees) and the CRS.

    Returns
    -------
    photo : ndarray of str, shape (M,)
    xyz, opk : ndarray, shape (M, 3)
    crs : str or None
        ``EPSG:nnnn`` when a comment line names one.

    Raises
    ------
    ConfigError
        A row with too few fields or bad numbers, or a rotation matrix that
        is neither ``Rx Ry Rz`` of the row's angles nor its transpose.
    """
    text = read_text(path, "Metashape Omega Phi Kappa cameras")
    crs = None
    for line in text.splitlines():
        if line.lstrip().startswith("#"):
            match = _EPSG.search(line)
            if match:
                crs = f"EPSG:{match.group(1)}"
    delimiter = "\t" if "\t" in text else ("," if "," in text.split("\n", 5)[-1] else None)
    rows = split_rows(path, text, delimiter=delimiter)
    rows.require_fields(7, "label X Y Z omega phi kappa")
    photo = photo_id(rows.column(0))
    xyz = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in ((1, "X"), (2, "Y"), (3, "Z"))]
    )
    opk = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in ((4, "omega"), (5, "phi"), (6, "kappa"))]
    )
    counts = rows.counts()
    if (counts >= 16).all():
        r = np.stack(
            [line_floats(f[7:16], rows.where(k), "r11..r33") for k, f in enumerate(rows.fields)]
        )
        r = r.reshape(-1, 3, 3)
        m = matrix_from_opk(opk, degrees=True)
        same = np.abs(r - m).max(axis=(1, 2)) < 1e-5
        transposed = np.abs(r - np.swapaxes(m, 1, 2)).max(axis=(1, 2)) < 1e-5
        bad = np.flatnonzero(~(same | transposed))
        if bad.size:
            raise ConfigError(
                f"{rows.where(int(bad[0]))}: the matrix r11..r33 is neither Rx(omega) Ry(phi) "
                "Rz(kappa) of the row's angles nor its transpose: the angles follow another "
                "convention and are not converted"
            )
    check_unique(photo, rows, "photo")
    return photo, xyz, opk, crs


class MarkersXml:
    """What a Metashape markers (or cameras) XML holds.

    Attributes
    ----------
    images : ImageTable
        Marker observations in pixels, ids = marker labels.
    control : ControlTable
        Markers with a reference: ``full`` when enabled, ``check`` when not.
    crs : str or None
        The chunk's WKT.
    camera, frame, distortion : optional
        From the chunk's one sensor when it carries a calibration and a pixel size.
    notes : list of str
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        text = read_text(path, "Metashape markers XML")
        try:
            root = ET.fromstring(text)
        except ET.ParseError as exc:
            line = exc.position[0] if exc.position else 0
            raise ConfigError(f"{path}:{line}: not well-formed XML ({exc})") from None
        chunks = root.findall("chunk") if root.tag != "chunk" else [root]
        if not chunks:
            raise ConfigError(f"{path}: no <chunk> element (expected a Metashape XML export)")
        self.notes: list[str] = []
        if len(chunks) > 1:
            self.notes.append(f"{path.name}: {len(chunks)} chunks, the first one read")
        chunk = chunks[0]
        cams = {c.get("id"): c.get("label") for c in chunk.iter("camera") if c.get("label")}
        # marker id -> label; looked up by the optional marker_id of a location
        markers: dict[str | None, str] = {}
        refs = []
        label: str | None  # a marker's label; below, the label a location refers to
        for m in self._find_all(chunk, "markers", "marker"):
            mid, label = m.get("id"), (m.get("label") or "").strip()
            if mid is None or not label:
                continue
            markers[mid] = label
            ref = m.find("reference")
            if ref is not None and ref.get("x") is not None:
                refs.append(
                    (label, ref.get("x"), ref.get("y"), ref.get("z"), ref.get("enabled", "true"))
                )
        photos: list[str] = []
        points: list[str] = []
        xy: list[tuple[str | None, str | None]] = []
        for frame_markers in chunk.iter("frame"):
            for m in frame_markers.iter("marker"):
                label = markers.get(m.get("marker_id"))
                if label is None:
                    continue
                for loc in m.iter("location"):
                    cam = cams.get(loc.get("camera_id"))
                    if cam is None or loc.get("x") is None or loc.get("valid") == "false":
                        continue
                    photos.append(cam)
                    points.append(label)
                    xy.append((loc.get("x"), loc.get("y")))
        if not xy:
            raise ConfigError(f"{path}: no marker location on a photo (frames/frame/markers)")
        where = f"{path}: marker location"
        self.images = ImageTable(
            photo_id(photos),
            np.asarray(points, str),
            # line_floats reports a missing (None) value as not a number
            line_floats(
                [v for pair in xy for v in pair],  # type: ignore[misc]
                where,
                "x y",
            ).reshape(-1, 2),
        )
        if not refs:
            raise ConfigError(f"{path}: no marker has a <reference> (ground coordinates)")
        partial = [r[0] for r in refs if r[2] is None or r[3] is None]
        if partial:
            raise ConfigError(
                f"{path}: marker '{partial[0]}': <reference> without y or z (plan or height "
                "control from this file is not read)"
            )
        labels = np.asarray([r[0] for r in refs], str)
        values = line_floats(
            [v for r in refs for v in r[1:4]],  # type: ignore[misc]  # as the locations' x y
            f"{path}: marker reference",
            "x y z",
        ).reshape(-1, 3)
        kind = np.where([r[4].lower() in ("true", "1") for r in refs], "full", "check")
        self.control = ControlTable(labels, values, kind, typed=True)
        ref = chunk.find("reference")
        wkt = ref.text.strip() if ref is not None and ref.text and ref.text.strip() else None
        self.crs = None if wkt is None else _crs_from_wkt(wkt, f"{path}: chunk <reference>")
        self.camera, self.frame, self.distortion = self._sensor(chunk)

    @staticmethod
    def _find_all(chunk: ET.Element, parent: str, tag: str) -> list[ET.Element]:
        out = []
        for holder in chunk.findall(parent):
            out += list(holder.iter(tag))
        return out

    def _sensor(
        self, chunk: ET.Element
    ) -> tuple[Camera | None, ImageFrame | None, Distortion | None]:
        sensors = self._find_all(chunk, "sensors", "sensor")
        if len(sensors) != 1:
            if sensors:
                self.notes.append(f"{self.path.name}: {len(sensors)} sensors, none read")
            return None, None, None
        sensor = sensors[0]
        pixel = None
        for prop in sensor.iter("property"):
            if prop.get("name") == "pixel_width":
                pixel = float(prop.get("value", "nan"))
        calibration = sensor.find("calibration")
        resolution = sensor.find("resolution")
        if calibration is None or pixel is None or not np.isfinite(pixel) or pixel <= 0:
            return None, None, None
        res = (
            calibration.find("resolution")
            if calibration.find("resolution") is not None
            else resolution
        )
        if res is None:
            return None, None, None
        where = f"{self.path}: sensor calibration"
        width, height = line_floats(
            [res.get("width", "nan"), res.get("height", "nan")], where, "resolution"
        )

        def value(tag: str) -> float:
            el = calibration.find(tag)
            return (
                0.0
                if el is None or el.text is None
                else float(line_floats([el.text], where, tag)[0])
            )

        f = value("f")
        for tag in ("k4", "b1", "b2", "p3", "p4"):
            if value(tag) != 0.0:
                raise ConfigError(
                    f"{where}: {tag} = {value(tag)!r} has no counterpart in the project's camera "
                    "(fit the camera without it, or give the camera with --focal-mm ...)"
                )
        if not f > 0:
            raise ConfigError(f"{where}: f must be positive")
        frame = ImageFrame("pixel", pixel, (width / 2.0 + value("cx"), height / 2.0 + value("cy")))
        distortion = Distortion(
            k1=value("k1"),
            k2=value("k2"),
            k3=value("k3"),
            p1=value("p1"),
            p2=-value("p2"),
            units="normalized",
            model="projection",
            comment=(
                "Metashape calibration: (k1, k2, k3, p1, p2) as (k1, k2, k3, p1, -p2) in "
                "x right, y up"
            ),
        )
        self.notes.append(
            f"camera from {self.path.name}: f = {f:.4f} px x {pixel:g} mm = {f * pixel:.6f} mm"
        )
        return Camera(f * pixel), frame, (None if distortion.is_zero else distortion)


def read_markers_xml(path: Path) -> MarkersXml:
    """Read a Metashape markers or cameras XML (see :class:`MarkersXml`)."""
    return MarkersXml(Path(path))


def import_metashape(
    markers_file: str | Path,
    options: ImportOptions | None = None,
    *,
    cameras_file: str | Path | None = None,
    camera: PixelCamera | None = None,
    crs: str | None = None,
    attitudes: bool = True,
    source_types: bool = False,
) -> ImportedProject:
    """A project from Metashape's markers XML and, optionally, its OPK camera text.

    Parameters
    ----------
    markers_file : path
        The markers (or cameras) XML: marker observations and references.
    cameras_file : path, optional
        The Omega Phi Kappa text: projection centres (``[gnss]``, and the
        strips) and attitudes (``[imu]``).
    camera : PixelCamera, optional
        Overrides (or replaces a missing) sensor calibration of the XML.
    crs : str, optional
        Overrides the chunk CRS.
    attitudes : bool
        Write the attitudes of ``cameras_file`` (``[imu]``).
    source_types : bool
        Take the markers' reference flags as the control types (enabled: full
        control, disabled: check point). By default the control is chosen as
        for every other format (:func:`.common.split_control`), because a
        Metashape project usually has every reference enabled.
    """
    options = options or ImportOptions()
    path = Path(markers_file)
    xml = read_markers_xml(path)
    notes = list(xml.notes)
    control = xml.control
    if not source_types:
        kinds = control.kind if control.kind is not None else np.array([], str)
        n_on, n_off = int(np.sum(kinds == "full")), int(np.sum(kinds == "check"))
        control = ControlTable(
            control.point,
            control.xyz,
            np.full(len(control), "full"),
            False,
            control.sigma_xy,
            control.sigma_h,
        )
        notes.append(
            f"the markers' reference flags ({n_on} enabled, {n_off} disabled) are not used as "
            "control types (--source-types uses them)"
        )
    if camera is not None:
        camera.check_marks(xml.images, str(path))
        frame, cam, distortion = camera.frame(), Camera(camera.focal_mm), None
        notes.append("camera as given on the command line; no distortion")
    elif xml.camera is not None:
        assert xml.frame is not None  # _sensor gives the camera and its frame together
        frame, cam, distortion = xml.frame, xml.camera, xml.distortion
    else:
        raise ConfigError(
            f"{path}: no sensor calibration with a pixel size; give the camera with --focal-mm, "
            "--pixel-um (or --sensor-width-mm) and --image-size"
        )
    inputs = [path]
    gnss = imu = None
    if cameras_file is not None:
        cpath = Path(cameras_file)
        inputs.append(cpath)
        photo, xyz, opk, opk_crs = read_opk_text(cpath)
        crs = crs or xml.crs or opk_crs
        gnss = PhotoPositions(photo, xyz)
        notes.append(f"GNSS centres: X Y Z of {cpath.name}")
        if attitudes:
            if crs is None:
                raise ConfigError(f"{cpath}: the CRS is not known; give --crs")
            imu = attitudes_from_opk(photo, opk, xyz[:, :2], crs, str(cpath))
            notes.append(
                f"attitudes of {cpath.name} read as PATB omega, phi, kappa on the map grid, "
                "turned by the meridian convergence to east-north-up"
            )
    crs = crs or xml.crs
    if crs is None:
        raise ConfigError(f"{path}: the chunk has no <reference> CRS; give --crs")
    return assemble(
        f"the Metashape export {path}" + (f" with {cameras_file}" if cameras_file else ""),
        xml.images,
        frame,
        cam,
        control,
        crs,
        options,
        inputs=inputs,
        default_name=path.stem,
        distortion=distortion,
        track=gnss,
        track_crs=crs,
        gnss=gnss,
        imu=imu,
        notes=notes,
    )
