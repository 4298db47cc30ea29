"""J's rules on the geometry of the control of a 3D similarity (J section
2.2, J(14)): enough plan and height points, plan points not coinciding,
height points not all in one vertical plane.

:func:`~strip_aerotri.geometry.similarity.fit_similarity` applies them;
``stripaero check`` and the ground stage call the same functions
(:func:`control_count_problems`, :func:`height_plane_verdict`,
:func:`cross_tilt`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from .._typing import BoolArray, FloatArray
from ..errors import GeometryError, StripAerotriWarning

__all__ = [
    "COINCIDENT_RTOL",
    "COLLINEAR_MAGNIFICATION",
    "COLLINEAR_RTOL",
    "WEAK_COLLINEAR_MAGNIFICATION",
    "WEAK_COLLINEAR_RTOL",
    "control_count_problems",
    "cross_tilt",
    "height_plane_verdict",
]

#: Relative size (against the extent of the control) below which plan points
#: are taken as coincident.
COINCIDENT_RTOL = 1e-6
#: Ratio of the smallest to the largest singular value of the centred plan
#: coordinates of the height points below which they are taken as collinear in
#: plan (all in one vertical plane): the tilt across that plane is undetermined.
COLLINEAR_RTOL = 1e-3
#: Same ratio below which the configuration is accepted but a warning is issued
#: (when the points served are not known, see ``WEAK_COLLINEAR_MAGNIFICATION``).
WEAK_COLLINEAR_RTOL = 1e-2
#: With the points the transformation serves known (``served``), the warning
#: instead asks how far the cross tilt carries the heights' errors: it is
#: determined to ``σ_h / s₁`` (s₁ the smaller singular value of the height
#: points' centred plan coordinates), so a height error reaches the served
#: point farthest from their best vertical plane (distance r) magnified
#: r / s₁ times.  The ratio above warns about every strip a few hundred
#: photos long, however well both its edges are controlled (r / s₁ 0.07-0.09
#: for the benchmarks' 1000-photo strips with control on both edges, 5600
#: for height control on one road).
WEAK_COLLINEAR_MAGNIFICATION = 10.0
#: With the points served known, height control in nearly one vertical plane
#: (singular value ratio below ``COLLINEAR_RTOL``) is refused only when its
#: errors reach them more than this many times magnified: a strip thousands
#: of photos long has the ratio of a line (7.7e-4 at 5000 photos with both
#: edges controlled) but a cross tilt as firm as a short one's (r / s₁ 0.1).
COLLINEAR_MAGNIFICATION = 100.0


def _quote(ids: Sequence[str], limit: int = 12) -> str:
    """``'A', 'B', 'C'`` (shortened with ``...`` beyond `limit` ids)."""
    quoted = [repr(str(i)) for i in ids]
    if len(quoted) > limit:
        quoted = [*quoted[:limit], "..."]
    return ", ".join(quoted)


def _validate_control_geometry(
    src: FloatArray,
    tgt: FloatArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    ids: tuple[str, ...],
    served: FloatArray | None = None,
) -> None:
    """Check J's rules for a 3D similarity; raise GeometryError naming the points."""
    used = use_xy | use_z
    bad_src = used & ~np.all(np.isfinite(src), axis=1)
    bad_xy = use_xy & ~np.all(np.isfinite(tgt[:, :2]), axis=1)
    bad_z = use_z & ~np.isfinite(tgt[:, 2])
    if np.any(bad_src):
        raise GeometryError(
            "control points have non-finite model coordinates: "
            f"{_quote([ids[i] for i in np.flatnonzero(bad_src)])}"
        )
    if np.any(bad_xy):
        raise GeometryError(
            "control points used for plan have non-finite target X or Y: "
            f"{_quote([ids[i] for i in np.flatnonzero(bad_xy)])}"
        )
    if np.any(bad_z):
        raise GeometryError(
            "control points used for height have non-finite target H: "
            f"{_quote([ids[i] for i in np.flatnonzero(bad_z)])}"
        )
    plan = np.flatnonzero(use_xy)
    height = np.flatnonzero(use_z)
    plan_ids = [ids[i] for i in plan]
    height_ids = [ids[i] for i in height]
    problems = control_count_problems(plan_ids, height_ids)
    if problems:
        raise GeometryError(problems[0])
    extent_src = float(np.max(np.ptp(src[used], axis=0)))
    ranges_tgt = [np.ptp(tgt[plan, 0]), np.ptp(tgt[plan, 1]), np.ptp(tgt[height, 2])]
    extent_tgt = float(max(ranges_tgt))
    for frame, xy, extent in (
        ("model", src[plan, :2], extent_src),
        ("control", tgt[plan, :2], extent_tgt),
    ):
        spread = float(np.max(np.ptp(xy, axis=0)))
        if spread == 0.0 or spread <= COINCIDENT_RTOL * extent:
            raise GeometryError(
                f"plan control points coincide in the {frame} (scale and azimuth are "
                f"undetermined): {_quote(plan_ids)}"
            )
    error, warning = height_plane_verdict(
        src[height, :2], None if served is None else served[:, :2], height_ids
    )
    if error is not None:
        raise GeometryError(error)
    if warning is not None:
        warnings.warn(warning, StripAerotriWarning, stacklevel=3)


def height_plane_verdict(
    height_xy: FloatArray, served_xy: FloatArray | None, height_ids: Sequence[str]
) -> tuple[str | None, str | None]:
    """J's rule on height control nearly in one vertical plane: (error, warning).

    The error when the points are collinear in plan (singular value ratio
    below :data:`COLLINEAR_RTOL`) and an error of their heights reaches the
    farthest served point more than :data:`COLLINEAR_MAGNIFICATION` times
    magnified (:func:`cross_tilt`; always without served points); else a
    warning when the tilt across is weak.  Plan coordinates of the height
    points and of the served points in any one Cartesian frame (the strip
    model's too: the ratio and the magnification do not depend on scale).
    The similarity applies it, and ``stripaero check`` on the formed strip.
    """
    ratio, magnified = cross_tilt(height_xy, served_xy)
    if ratio < COLLINEAR_RTOL and (magnified is None or magnified > COLLINEAR_MAGNIFICATION):
        reach = (
            ""
            if magnified is None
            else f"; an error of their heights reaches the farthest point {magnified:.0f} "
            "times magnified"
        )
        return (
            "height control points all lie in one vertical plane (collinear in plan, "
            f"singular value ratio {ratio:.1e}{reach}); the tilt across it is undetermined: "
            f"{_quote(height_ids)}",
            None,
        )
    if magnified is not None:
        if magnified > WEAK_COLLINEAR_MAGNIFICATION:
            return None, (
                "height control points lie nearly in one vertical plane (an error of their "
                f"heights reaches the farthest point {magnified:.0f} times magnified); the "
                f"cross tilt is weak: {_quote(height_ids)}"
            )
    elif ratio < WEAK_COLLINEAR_RTOL:
        return None, (
            "height control points lie nearly in one vertical plane (singular value ratio "
            f"{ratio:.1e}); the cross tilt is weak: {_quote(height_ids)}"
        )
    return None, None


def cross_tilt(
    height_xy: FloatArray, served_xy: FloatArray | None = None, margin: float = 0.0
) -> tuple[float, float | None]:
    """How well height control points fix the tilt across their best vertical plane.

    Parameters
    ----------
    height_xy : ndarray, shape (N, 2)
        Plan coordinates of the height control points (any Cartesian unit).
    served_xy : ndarray, shape (M, 2), optional
        Plan coordinates of the points the transformation serves, same unit.
    margin : float
        Distance added to the farthest served point's, same unit (an estimate
        of how far beyond `served_xy` the points served reach).

    Returns
    -------
    ratio : float
        Smaller over larger singular value of the centred ``height_xy`` (0 when
        they coincide or lie on one line).
    magnified : float or None
        ``r / s₁``: r the distance of the served point farthest from the
        height points' best vertical plane, s₁ the smaller singular value.
        The tilt is determined to ``σ_h / s₁``, so an error of the heights
        reaches that point magnified this many times (inf when s₁ is 0, None
        without served points).
    """
    centre = height_xy.mean(axis=0)
    _, sv, vt = np.linalg.svd(height_xy - centre, full_matrices=False)
    ratio = 0.0 if sv[0] == 0.0 else float(sv[1] / sv[0])
    if served_xy is None or served_xy.shape[0] == 0:
        return ratio, None
    reach = float(np.max(np.abs((served_xy - centre) @ vt[1]))) + margin
    return ratio, (np.inf if sv[1] == 0.0 else reach / float(sv[1]))


def control_count_problems(plan_ids: Sequence[str], height_ids: Sequence[str]) -> list[str]:
    """J's counting rule for the similarity (J(14)), one line per shortfall.

    At least two full or plan points (``plan_ids``) and three full or height
    points (``height_ids``); :func:`fit_similarity` raises the first line,
    ``stripaero check`` lists them all.
    """
    problems = []
    if len(plan_ids) < 2:
        problems.append(
            "similarity transformation needs at least two full or plan control points, "
            f"got {len(plan_ids)}" + (f": {_quote(plan_ids)}" if plan_ids else "")
        )
    if len(height_ids) < 3:
        problems.append(
            "similarity transformation needs at least three full or height control points, "
            f"got {len(height_ids)}" + (f": {_quote(height_ids)}" if height_ids else "")
        )
    return problems
