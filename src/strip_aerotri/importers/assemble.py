""":func:`assemble`: an importer's arrays to an
:class:`~.tables.ImportedProject`, deciding and noting what the source does
not say.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._typing import FloatArray, StrArray
from ..errors import ConfigError
from ..geometry.rotation import opk_from_matrix
from ..interior import flight_matrix
from .control import split_control
from .strips import decide_flight_direction, strips_from_positions
from .tables import (
    Camera,
    ControlTable,
    Distortion,
    ImageFrame,
    ImageTable,
    ImportedProject,
    ImportOptions,
    PhotoAttitudes,
    PhotoPositions,
    Strip,
)
from .text import natural_key
from .writer import _is_geographic

__all__ = ["assemble"]


def _equirectangular(xyz: FloatArray) -> FloatArray:
    """Longitude, latitude (degrees) to metres on a sphere about their mean latitude."""
    lat0 = np.deg2rad(np.mean(xyz[:, 1]))
    metres = np.deg2rad(1.0) * 6371000.0
    return np.column_stack([xyz[:, 0] * metres * np.cos(lat0), xyz[:, 1] * metres, xyz[:, 2]])


def _check_ids(values: StrArray, what: str, source: str) -> None:
    empty = np.char.str_len(values) == 0 if values.size else np.zeros(0, bool)
    if empty.any():
        raise ConfigError(f"{source}: an empty {what} id")


def assemble(
    source: str,
    images: ImageTable,
    frame: ImageFrame,
    camera: Camera,
    control: ControlTable,
    crs: str,
    options: ImportOptions,
    *,
    inputs: Sequence[Path],
    default_name: str,
    distortion: Distortion | None = None,
    strips: Sequence[Strip] | None = None,
    track: PhotoPositions | None = None,
    track_crs: str | None = None,
    gnss: PhotoPositions | None = None,
    imu: PhotoAttitudes | None = None,
    notes: Sequence[str] = (),
    warnings: Sequence[str] = (),
) -> ImportedProject:
    """Decide strips, photo order, flight direction and control types; keep what they use.

    Parameters
    ----------
    source : str
        The format and its files, for messages and the header comment.
    images, frame, camera, control, crs
        What the importer read.
    options : ImportOptions
    inputs : sequence of Path
        Every file read.
    default_name : str
        Project name when ``options.name`` is None.
    distortion : Distortion, optional
    strips : sequence of Strip, optional
        Strips the source defines (else from ``options.photo_order``, else
        from ``track``, else one strip in photo-name order).
    track : PhotoPositions, optional
        Positions of the photos, to find the strips: in any Cartesian frame,
        or in ``track_crs``.
    track_crs : str, optional
        The CRS of ``track`` when it is the project's; longitude and latitude
        of a geographic CRS are scaled to metres first.
    gnss : PhotoPositions, optional
        Projection centres in ``crs`` (written as ``gnss.csv``).
    imu : PhotoAttitudes, optional
        Attitudes (written as ``imu.csv`` in the flight axes).

    Raises
    ------
    ConfigError
        Duplicated observations, unknown photo ids, nothing left to adjust,
        undecidable order or flight direction, or bad ``options``.
    """
    notes = list(notes)
    warnings = list(warnings)
    _check_unique(source, images, control)
    observed = np.unique(images.photo)
    strip_list, turn_photos = _find_strips(
        source, observed, options, strips, (track, track_crs), notes, warnings
    )
    strip_list = _chosen_strips(strip_list, observed, options, warnings)
    in_strips = np.asarray([p for s in strip_list for p in s.photos], dtype=str)
    left_out = np.setdiff1d(observed, in_strips)
    left_out = left_out[~np.isin(left_out, sorted(turn_photos))]
    if left_out.size and options.strips is None:
        warnings.append(
            f"observations of {left_out.size} photo(s) in no strip left out: "
            f"{', '.join(left_out[:10].tolist())}{', ...' if left_out.size > 10 else ''}"
        )
    images = images.take(np.isin(images.photo, in_strips))

    direction, strip_list, more_notes, more_warnings = decide_flight_direction(
        images, frame, strip_list, options.flight_direction
    )
    notes += more_notes
    warnings += more_warnings
    control = _observed_control(source, control, images, strip_list, options, notes)
    gnss, imu_opk = _gnss_and_imu(gnss, imu, in_strips, direction, notes, warnings)
    if options.sigma_mm is not None:
        frame = ImageFrame(
            frame.units, frame.pixel_size_mm, frame.principal_point_px, options.sigma_mm
        )
    return ImportedProject(
        source=source,
        name=options.name or default_name,
        strips=tuple(strip_list),
        camera=camera,
        frame=frame,
        flight_direction=direction,
        images=images,
        control=control,
        crs=crs,
        distortion=distortion,
        gnss=gnss,
        imu_opk_deg=imu_opk,
        notes=tuple(notes),
        warnings=tuple(warnings),
        inputs=tuple(Path(p) for p in inputs),
    )


def _check_unique(source: str, images: ImageTable, control: ControlTable) -> None:
    """No empty id, no point observed twice on a photo, no control point listed twice."""
    _check_ids(images.photo, "photo", source)
    _check_ids(images.point, "point", source)
    _check_ids(control.point, "control point", source)
    pair = np.char.add(np.char.add(images.photo, "\x00"), images.point)
    _, first, counts = np.unique(pair, return_index=True, return_counts=True)
    if (counts > 1).any():
        k = int(first[np.flatnonzero(counts > 1)[0]])
        raise ConfigError(
            f"{source}: point '{images.point[k]}' is observed twice on photo '{images.photo[k]}'"
        )
    names, counts = np.unique(control.point, return_counts=True)
    if (counts > 1).any():
        raise ConfigError(
            f"{source}: control point '{names[np.flatnonzero(counts > 1)[0]]}' is listed twice"
        )


def _find_strips(
    source: str,
    observed: StrArray,
    options: ImportOptions,
    strips: Sequence[Strip] | None,
    track: tuple[PhotoPositions | None, str | None],
    notes: list[str],
    warnings: list[str],
) -> tuple[list[Strip], set[str]]:
    """The strips and their photo order: ``--photo-order``, else the source's
    own ``strips``, else from the photo positions (``track`` and its CRS),
    else one strip in photo-name order; and the photos taken in turns.
    Notes and warnings are appended to the lists given."""
    positions, track_crs = track
    if options.photo_order is not None:
        listed = [p for s in options.photo_order for p in s]
        unknown = np.asarray(listed, dtype=str)[~np.isin(listed, observed)]
        if unknown.size:
            raise ConfigError(
                f"--photo-order: photo '{unknown[0]}' has no image observations in {source}"
            )
        notes.append("strips and photo order as given by --photo-order")
        return [Strip(str(k + 1), tuple(s)) for k, s in enumerate(options.photo_order)], set()
    if strips is not None:
        return list(strips), set()
    if positions is not None and np.isin(observed, positions.photo).all():
        rows = np.searchsorted(positions.photo, observed, sorter=np.argsort(positions.photo))
        xyz = positions.xyz[np.argsort(positions.photo)[rows]]
        if track_crs is not None and _is_geographic(track_crs):
            xyz = _equirectangular(xyz)
        found, dropped = strips_from_positions(observed.tolist(), xyz, turn_deg=options.turn_deg)
        notes.append(
            f"{len(found)} strip(s) from the photo positions: the track (photos in "
            f"name order) split where its heading turns by more than {options.turn_deg:g} deg"
        )
        if dropped:
            warnings.append(
                f"photo(s) taken in turns left out (a strip needs 2 photos): {', '.join(dropped)}"
            )
        return [Strip(str(k + 1), s) for k, s in enumerate(found)], set(dropped)
    if positions is not None:
        warnings.append("not every photo has a position: strips not found from positions")
    notes.append("one strip, photos in photo-name order (no positions to order them)")
    return [Strip("1", tuple(sorted(observed.tolist(), key=natural_key)))], set()


def _chosen_strips(
    strip_list: list[Strip], observed: StrArray, options: ImportOptions, warnings: list[str]
) -> list[Strip]:
    """The strips kept: each photo in one strip, the photos without
    observations left out (a warning), the strips ``--strips`` names, each
    with two photos or more."""
    seen: dict[str, str] = {}
    for strip in strip_list:
        for p in strip.photos:
            if p in seen:
                raise ConfigError(f"photo '{p}' is in strips {seen[p]} and {strip.name}")
            seen[p] = strip.name
    has_obs = set(observed.tolist())
    missing = [p for s in strip_list for p in s.photos if p not in has_obs]
    if missing:
        warnings.append(f"photo(s) without image observations left out: {', '.join(missing)}")
        strip_list = [
            Strip(s.name, tuple(p for p in s.photos if p in has_obs)) for s in strip_list
        ]
    if options.strips is not None:
        bad = [n for n in options.strips if not 1 <= n <= len(strip_list)]
        if bad:
            raise ConfigError(
                f"--strips: no strip {bad[0]}; the source has {len(strip_list)} strip(s) "
                f"({', '.join(s.name for s in strip_list)})"
            )
        strip_list = [strip_list[n - 1] for n in dict.fromkeys(options.strips)]
    short = [s.name for s in strip_list if len(s.photos) < 2]
    if short:
        raise ConfigError(f"strip {short[0]} has fewer than 2 photos with image observations")
    return strip_list


def _observed_control(
    source: str,
    control: ControlTable,
    images: ImageTable,
    strip_list: list[Strip],
    options: ImportOptions,
    notes: list[str],
) -> ControlTable:
    """The control points observed on the imported photos, split into
    control and check points (:func:`~.control.split_control`)."""
    observed_control = np.isin(control.point, np.unique(images.point))
    if not observed_control.any():
        raise ConfigError(
            f"{source}: none of the {len(control)} control point(s) is observed on the "
            "imported photos; a project needs control"
        )
    if (~observed_control).any():
        notes.append(
            f"{int((~observed_control).sum())} control point(s) not observed on the imported "
            "photos left out"
        )
    control = control.take(np.flatnonzero(observed_control))
    control, more_notes = split_control(
        control, images, strip_list, options.control_ids, options.check_ids
    )
    notes += more_notes
    n_full = int(np.sum(control.kind == "full"))
    if n_full < 4:
        notes.append(
            f"{n_full} full control point(s): the adjustment of every model at once (the "
            "default) needs two in plan and three in height and tests them only with more; "
            'J\'s polynomials (block = "strips") need more still (docs/ground.md)'
        )
    return control


def _gnss_and_imu(
    gnss: PhotoPositions | None,
    imu: PhotoAttitudes | None,
    in_strips: StrArray,
    direction: str,
    notes: list[str],
    warnings: list[str],
) -> tuple[PhotoPositions | None, tuple[StrArray, FloatArray] | None]:
    """The GNSS centres of the imported photos, and their IMU attitudes as
    ω, φ, κ (degrees) of the flight axes (None where none is left)."""
    if gnss is not None:
        gnss = gnss.take(np.isin(gnss.photo, in_strips))
        if len(gnss.photo) == 0:
            warnings.append("no GNSS centre belongs to an imported photo: gnss.csv not written")
            gnss = None
    if imu is None:
        return gnss, None
    imu = imu.take(np.isin(imu.photo, in_strips))
    if len(imu.photo) == 0:
        warnings.append("no attitude belongs to an imported photo: imu.csv not written")
        return gnss, None
    flight = flight_matrix(direction)
    notes.append(
        "IMU attitudes: R = Rx(omega) Ry(phi) Rz(kappa) mapping image vectors in the "
        "flight axes to local east-north-up (docs/conventions.md)"
    )
    return gnss, (imu.photo, opk_from_matrix(imu.matrix @ flight.T, degrees=True))
