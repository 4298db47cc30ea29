"""The strips of an import and the photo order in each, and the image axis
along the flight (:func:`strips_from_positions`,
:func:`decide_flight_direction`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from .._typing import FloatArray, IntArray, StrArray
from ..errors import ConfigError
from .tables import DEFAULT_TURN_DEG, ImageFrame, ImageTable, Strip
from .text import natural_key

__all__ = ["decide_flight_direction", "strips_from_positions"]


def strips_from_positions(
    photos: Sequence[str],
    xyz: FloatArray,
    *,
    turn_deg: float = DEFAULT_TURN_DEG,
) -> tuple[list[tuple[str, ...]], list[str]]:
    """Split a photo track into strips at its turns.

    The photos, in photo-name order (:func:`natural_key`, taken as the order
    of capture), make a track of steps.  Consecutive steps whose headings stay
    within ``turn_deg`` of the mean heading of their run form one run; each
    run of two or more steps is a strip (a run of one step is a turn, unless
    no run is longer).  A photo at the corner of two runs stays in the first.

    Parameters
    ----------
    photos : sequence of str, length M
    xyz : array_like, shape (M, 3)
        Positions in any Cartesian frame (a projected CRS, a site or a model
        frame); only X, Y are used.
    turn_deg : float

    Returns
    -------
    strips : list of tuple of str
        Each strip's photos ordered along its direction of travel.
    dropped : list of str
        Photos in no strip (taken in a turn).

    Raises
    ------
    ConfigError
        When the positions cannot order the photos (all at one place).
    """
    order = sorted(range(len(photos)), key=lambda i: natural_key(photos[i]))
    names = [str(photos[i]) for i in order]
    xy = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)[order, :2]
    if len(names) < 2:
        raise ConfigError(f"cannot form a strip from {len(names)} photo(s)")
    step = np.diff(xy, axis=0)
    length = np.hypot(step[:, 0], step[:, 1])
    extent = float(np.max(np.hypot(*(xy - xy.mean(axis=0)).T)))
    if extent <= 1e-9 * max(1.0, float(np.max(np.abs(xy)))):
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: their positions all lie at "
            "one place; give the order with --photo-order FILE"
        )
    moving = length > 1e-6 * extent
    unit = np.zeros_like(step)
    unit[moving] = step[moving] / length[moving, None]
    cos_turn = math.cos(math.radians(turn_deg))
    runs: list[list[int]] = []  # [first step, last step, number of moving steps]
    heading = np.zeros(2)
    for i in range(step.shape[0]):  # a loop over the steps of the track: sequential
        if not moving[i]:
            if runs:
                runs[-1][1] = i
            continue
        if (
            runs
            and np.any(heading)
            and float(unit[i] @ (heading / np.linalg.norm(heading))) >= cos_turn
        ):
            runs[-1][1] = i
            runs[-1][2] += 1
            heading = heading + unit[i]
        else:
            runs.append([i if runs else 0, i, 1])  # standing photos before the first run join it
            heading = unit[i].copy()
    if not runs:
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: they do not move; give the "
            "order with --photo-order FILE"
        )
    min_steps = 2 if any(r[2] >= 2 for r in runs) else 1
    used: set[int] = set()
    strips: list[tuple[str, ...]] = []
    for first, last, count in runs:
        if count < min_steps:
            continue
        piece = [k for k in range(first, last + 2) if k not in used]
        if len(piece) < 2:
            continue
        used.update(piece)
        pts = xy[piece]
        direction = pts[-1] - pts[0]
        along = pts @ direction if np.any(direction) else np.arange(len(piece), dtype=float)
        strips.append(tuple(names[piece[k]] for k in np.argsort(along, kind="stable")))
    dropped = [names[k] for k in range(len(names)) if k not in used]
    if not strips:
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: the track turns by more than "
            f"{turn_deg:g} deg at every photo; give the order with --photo-order FILE"
        )
    return strips, dropped


def _strip_motion(
    sensor: FloatArray, by_photo: dict[str, IntArray], point: StrArray, photos: Sequence[str]
) -> FloatArray | None:
    """Mean motion of the camera in the sensor axes between consecutive photos.

    The points move in the image opposite to the camera, so the motion is
    minus the median shift of the common points of each pair, averaged over
    the pairs; None when no pair shares a point.
    """
    shifts = []
    for a, b in pairwise(photos):  # a loop over pairs, not points
        ia, ib = by_photo.get(a), by_photo.get(b)
        if ia is None or ib is None:
            continue
        _, ka, kb = np.intersect1d(point[ia], point[ib], assume_unique=True, return_indices=True)
        if ka.size:
            shifts.append(np.median(sensor[ib[kb]] - sensor[ia[ka]], axis=0))
    if not shifts:
        return None
    mean: FloatArray = -np.mean(shifts, axis=0)
    return mean


def decide_flight_direction(
    images: ImageTable,
    frame: ImageFrame,
    strips: Sequence[Strip],
    given: str | None = None,
) -> tuple[str, list[Strip], list[str], list[str]]:
    """The image axis along the flight, and the strips in the order it implies.

    The camera moves between consecutive photos by minus the mean shift of
    their common points in the image.  The axis (x or y) with the larger
    motion is the flight axis, its sign the direction; every strip must move
    along the same axis.  A strip whose photos move the other way along it
    (a strip flown back with the camera's heading kept) is listed in reverse,
    so that x points to the next photo in every strip.

    Parameters
    ----------
    given : {"+x", "-x", "+y", "-y"}, optional
        Use this direction instead of deciding it; strips that move against
        it are still reversed.

    Returns
    -------
    direction, strips, notes, warnings

    Raises
    ------
    ConfigError
        When nothing decides it (no point on two consecutive photos) and it is
        not given, or when strips move along different image axes.
    """
    notes: list[str] = []
    warnings: list[str] = []
    sensor = frame.sensor_mm(images.xy)
    by_photo = images.rows_by_photo()
    motions = [_strip_motion(sensor, by_photo, images.point, s.photos) for s in strips]
    known = [(s, m) for s, m in zip(strips, motions, strict=True) if m is not None]
    if given is None:
        if not known:
            raise ConfigError(
                "cannot decide the flight direction in the image: no point is observed on "
                "two consecutive photos of any strip; give --flight-direction"
            )
        axes = {s.name: int(np.argmax(np.abs(m))) for s, m in known}
        if len(set(axes.values())) > 1:
            along = ", ".join(f"{name}: image {'xy'[a]}" for name, a in axes.items())
            raise ConfigError(
                f"the strips move along different image axes ({along}); a project has one "
                "[images] flight_direction: import those strips separately (--strips)"
            )
        axis = next(iter(axes.values()))
        votes = sum(1 if m[axis] > 0 else -1 for _, m in known)
        sign = "+" if votes > 0 or (votes == 0 and known[0][1][axis] > 0) else "-"
        direction = f"{sign}{'xy'[axis]}"
        notes.append(
            f"flight direction {direction}: the photos move along image {direction} "
            "(minus the mean shift of the points common to consecutive photos)"
        )
    else:
        direction = given
        notes.append(f"flight direction {direction} (given)")
    axis = 0 if direction[1] == "x" else 1
    positive = direction[0] == "+"
    out: list[Strip] = []
    for strip, motion in zip(strips, motions, strict=True):
        if motion is None:
            warnings.append(
                f"strip {strip.name}: no point is seen on two consecutive photos; its photo "
                "order is kept as found"
            )
            out.append(strip)
            continue
        major, minor = abs(motion[axis]), abs(motion[1 - axis])
        if major <= minor:
            warnings.append(
                f"strip {strip.name}: its photos move along image {'xy'[1 - axis]} more than "
                f"along image {'xy'[axis]} (flight direction {direction})"
            )
        elif minor > math.tan(math.radians(30.0)) * major:
            angle = math.degrees(math.atan2(minor, major))
            warnings.append(
                f"strip {strip.name}: its photos move at {angle:.0f} deg to image axis "
                f"{'xy'[axis]}; the flight direction {direction} is the nearest axis"
            )
        if (motion[axis] > 0) != positive:
            out.append(Strip(strip.name, tuple(reversed(strip.photos))))
            notes.append(
                f"strip {strip.name}: photos listed in reverse order, so that image "
                f"{direction} points to the next photo"
            )
        else:
            out.append(strip)
    return direction, out, notes, warnings
