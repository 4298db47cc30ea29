"""Which GCPs are full control and which are check points
(:func:`split_control`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ConfigError
from .tables import ControlTable, ImageTable, Strip
from .text import natural_key

__all__ = ["split_control"]


def _default_full(
    control: ControlTable, images: ImageTable, photos: Sequence[str], per_place: int = 2
) -> list[str]:
    """GCPs nearest the start, the middle and the end of one strip, one per side.

    Candidates are the ``full`` points seen on at least 3 photos of the strip
    (2 when fewer than 6 qualify), two of them consecutive: a point the strip
    cannot triangulate is never chosen as control (the samples' strips of
    five photos chose GCPs seen on one photo, half their control lost).
    Their ground X, Y are projected on
    their principal axis, oriented with the photo order; at each of the three
    places the nearest candidate on each side of the axis is chosen.
    """
    strip_photos = np.asarray(photos, dtype=str)
    position = {p: k for k, p in enumerate(photos)}
    full = control.point[control.kind == "full"]
    rows = np.isin(images.photo, strip_photos) & np.isin(images.point, full)
    if not rows.any():
        return []
    pts, inverse, counts = np.unique(images.point[rows], return_inverse=True, return_counts=True)
    index = np.fromiter(
        (position[p] for p in images.photo[rows]), dtype=np.float64, count=int(rows.sum())
    )
    mean_index = np.bincount(inverse, weights=index) / counts
    # on two consecutive photos of the strip: a pair of it triangulates the point
    seen = np.zeros((pts.size, len(photos) + 1), dtype=bool)
    seen[inverse, index.astype(np.intp)] = True
    paired = (seen[:, :-1] & seen[:, 1:]).any(axis=1)
    for need in (3, 2):
        keep = (counts >= need) & paired
        if keep.sum() >= 3 * per_place:
            break
    pts, mean_index = pts[keep], mean_index[keep]
    if pts.size <= 3 * per_place:
        return [str(p) for p in pts]
    lookup = {p: k for k, p in enumerate(control.point)}
    xy = control.xyz[[lookup[p] for p in pts], :2]
    centred = xy - xy.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axis = vt[0]
    t = centred @ axis
    if np.ptp(mean_index) > 0 and np.ptp(t) > 0 and np.corrcoef(t, mean_index)[0, 1] < 0:
        t = -t  # the start of the strip is where its first photos see the ground
    side = centred @ np.array([-axis[1], axis[0]]) > 0
    chosen: list[int] = []
    free = np.ones(pts.size, dtype=bool)
    for place in (t.min(), 0.5 * (t.min() + t.max()), t.max()):
        for want in (True, False):
            pool = free & (side == want)
            if not pool.any():
                pool = free
            if not pool.any():
                break
            cand = np.flatnonzero(pool)
            pick = int(cand[np.argmin(np.abs(t[cand] - place))])
            chosen.append(pick)
            free[pick] = False
    return [str(pts[k]) for k in chosen]


def split_control(
    control: ControlTable,
    images: ImageTable,
    strips: Sequence[Strip],
    control_ids: Sequence[str] | None = None,
    check_ids: Sequence[str] | None = None,
) -> tuple[ControlTable, list[str]]:
    """The final type of every control point.

    * ``control_ids`` and ``check_ids`` both given: those types; every other
      point is left out.
    * ``control_ids`` alone: those keep their type (full, plan or height),
      every other point is a check point.
    * ``check_ids`` alone: those are check points, the others keep theirs.
    * neither: the source's own types when it has them (``typed``); else per
      strip the full points nearest its start, middle and end, one on each
      side of the strip axis (:func:`_default_full`), and every other point
      is a check point.

    Raises
    ------
    ConfigError
        An id that is not an observed control point, or an id in both lists.
    """
    notes: list[str] = []
    known = set(control.point.tolist())
    for option, ids in (("--control", control_ids), ("--check", check_ids)):
        for pid in ids or ():
            if pid not in known:
                listed = ", ".join(sorted(known, key=natural_key)[:12])
                raise ConfigError(
                    f"{option}: '{pid}' is not a control point observed on the imported "
                    f"photos (observed: {listed}{', ...' if len(known) > 12 else ''})"
                )
    both = set(control_ids or ()) & set(check_ids or ())
    if both:
        raise ConfigError(f"--control and --check both name {', '.join(sorted(both))}")
    assert control.kind is not None  # filled in by ControlTable
    kind = control.kind.copy()
    keep = np.ones(len(control), dtype=bool)
    if control_ids is not None or check_ids is not None:
        is_control = np.isin(control.point, list(control_ids or ()))
        is_check = np.isin(control.point, list(check_ids or ()))
        kind[is_control & (kind == "check")] = "full"
        kind[is_check] = "check"
        if control_ids is not None and check_ids is not None:
            keep = is_control | is_check
            if (~keep).any():
                notes.append(
                    f"{int((~keep).sum())} control point(s) in neither --control nor --check "
                    "left out"
                )
        elif control_ids is not None:
            kind[~is_control] = "check"
        notes.append("control and check points as given on the command line")
    elif control.typed:
        notes.append("control and check points as the source marks them")
    else:
        chosen: set[str] = set()
        for strip in strips:
            chosen.update(_default_full(control, images, strip.photos))
        is_full = np.isin(control.point, sorted(chosen))
        kind[(kind == "full") & ~is_full] = "check"
        listed = ", ".join(sorted(chosen, key=natural_key))
        notes.append(
            f"full control: {listed} (per strip the GCPs nearest its start, middle and end, "
            "one on each side of the strip axis, among those seen on 3 or more photos (2 "
            "when fewer qualify) of which two are consecutive); "
            "every other GCP is a check point (change with --control / --check)"
        )
    table = control.take(np.flatnonzero(keep))
    return ControlTable(
        table.point, table.xyz, kind[keep], True, table.sigma_xy, table.sigma_h
    ), notes
