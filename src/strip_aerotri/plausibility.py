"""Checks that the input is plausible before it is adjusted.

Input that is readable but wrong in a systematic way (wrong units, axes,
order or handedness) can still run to an "answer"; these checks stop it with
one line naming the likely cause.  Each returns the problems it finds as
messages (``stripaero check`` lists them all; a run stops at the first):

* :func:`image_coordinate_problems` — image coordinates far outside any
  film or sensor format (micrometres or pixels taken for millimetres), far
  inside it (metres), or not centred on the principal point (measured from
  a corner of the format; along the flight alone: a principal point outside
  the format);
* :func:`ray_direction_problems` — photos listed against the flight, or a
  pair in the wrong order: after the relative orientation, the rays of such
  pairs meet behind the photos (a negative x-parallax); image x across the
  flight is the relative orientation's own check (the base runs across it);
* :func:`control_handedness_problems` — control mirrored against the photos
  (easting and northing, or longitude and latitude, swapped): on each photo
  that shows three or more plan control points not on one line, a 2D
  similarity from the image to the control fits far better with a
  reflection than without.  A near-vertical photo maps its image (x along
  the flight, y to the left, right-handed with z up) onto east-north-up by
  a rotation, never by a reflection;
* :func:`control_relief_problems` — plan coordinates and heights in
  different units (X, Y in km with H in m): the control heights on a photo
  span more than the flying height the plan control's scale gives;
* :func:`strip_aerotri.ground.height_units.height_unit_problems` (the
  ground stage's, on the formed strip) — heights in feet (or decimetres)
  with X, Y in metres, or X, Y in feet with H in metres, which the span
  cannot see: once the strip is formed and scaled to the plan control (the
  ground stage), the control heights' gradient over the strip model has a
  norm near the unit factor times the plan coordinates' instead of 1,
  whatever the model's tilt;
* :func:`control_coverage_problems` — a warning, not a stop: strip ends
  beyond the outermost plan or height control, where the strip is
  extrapolated;
* :func:`image_sigma_problems` — a warning, not a stop: an image sigma
  far from the scatter of the pairs' own y-parallaxes (micrometres or
  pixels written where millimetres are read);
* :func:`control_degree_problems` — control given in degrees (longitude,
  latitude) under a projected CRS: every plan coordinate within ±180, ±90,
  spanning less than a few units (a few metres: no strip's control), and
  either the degrees fall inside the CRS's area of use or the numbers, taken
  as metres, fall outside it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ._text import shorten
from ._typing import ArrayLike, BoolArray, FloatArray, IntArray
from .errors import GeometryError, PhotoOrderError
from .interior import corrected_flight_direction
from .observations import ControlPoints, ImageObservations
from .options import FlightDirection

if TYPE_CHECKING:
    from .geodesy import GroundCRS

__all__ = [
    "MAX_IMAGE_RADIUS_MM",
    "MIN_SPAN_OVER_C",
    "control_coverage_problems",
    "control_degree_problems",
    "control_distance_problems",
    "control_handedness_problems",
    "control_relief_problems",
    "flight_axis_message",
    "image_coordinate_problems",
    "image_sigma_problems",
    "photo_order_hint",
    "photo_order_message",
    "ray_direction_problems",
]

#: No film or sensor format reaches beyond this radius from the principal
#: point (230 x 230 mm film: 163 mm at the corners).
MAX_IMAGE_RADIUS_MM = 250.0
#: An image radius beyond this many principal distances is a field of view
#: wider than 157 deg, which no mapping camera has (super-wide film: 1.85).
_MAX_RADIUS_OVER_C = 5.0
#: Image points all within this fraction of c: a field of view narrower
#: than 2.3 deg (a 610 mm lens on 230 mm film still spans 0.27).
MIN_SPAN_OVER_C = 0.02
#: A photo votes "mirrored" when the reflected fit leaves less than this
#: fraction of the rotated fit's residual (and the other way round).
_MIRROR_RATIO = 0.1


def image_coordinate_problems(
    xy_mm: ArrayLike,
    principal_distance: float,
    where: Callable[[int], str] | None = None,
    file: str = "image coordinates",
) -> list[str]:
    """Image coordinates no camera can produce.

    Parameters
    ----------
    xy_mm : array_like, shape (n, 2)
        Image coordinates in mm, reduced to the principal point.
    principal_distance : float
        c in mm.
    where : callable, optional
        ``where(k)`` says where row k comes from ("file:line").
    file : str
        The file, for messages about all rows.

    Returns
    -------
    list of str
        One message per problem (empty when plausible).
    """
    xy = np.asarray(xy_mm, dtype=np.float64).reshape(-1, 2)
    if xy.shape[0] == 0:
        return []
    c = float(principal_distance)
    radius = np.hypot(xy[:, 0], xy[:, 1])
    limit = min(MAX_IMAGE_RADIUS_MM, _MAX_RADIUS_OVER_C * c)
    outside = np.flatnonzero(radius > limit)
    problems = []
    if outside.size:
        k = int(outside[np.argmax(radius[outside])])
        at = where(k) if where is not None else file
        share = outside.size / xy.shape[0]
        if share > 0.5:
            cause = (
                f"{outside.size} of the {xy.shape[0]} points ({share:.0%}) lie that far out, so "
                "the coordinates are not in millimetres (micrometres? pixels? then [images] "
                'units = "pixel" with pixel_size_mm)'
            )
        else:
            cause = (
                f"{outside.size} of the {xy.shape[0]} points lie that far out: a typing error "
                "in the coordinates?"
            )
        problems.append(
            f"{at}: image point ({xy[k, 0]:.6g}, {xy[k, 1]:.6g}) mm lies {radius[k]:.4g} mm "
            f"from the principal point, beyond any film or sensor format with c = {c:g} mm "
            f"(at most {limit:.4g} mm); {cause}"
        )
    span = float(np.max(np.ptp(xy, axis=0)))
    if xy.shape[0] >= 3 and span < MIN_SPAN_OVER_C * c:
        problems.append(
            f"{file}: all image points lie within {span:.3g} mm of each other, less than "
            f"{MIN_SPAN_OVER_C:g} of the principal distance c = {c:g} mm: are the "
            "coordinates in metres instead of millimetres?"
        )
    # from a corner of the format, some points also lie beyond the radius:
    # the origin is the cause, unless most do (then the unit is)
    off = _off_centre_problems(xy, file)
    most_out = outside.size > 0.5 * xy.shape[0]
    return problems + off if most_out else off + problems


#: Image points, measured over the whole format of every photo, lie about
#: as far on each side of the principal point: their middle (half-way from
#: the least to the greatest) beyond this fraction of their half range, on
#: both axes, means another origin (a corner of the format).  Real projects
#: stay under 0.04 (the examples, the external strips, the FC300X block,
#: the import samples, tests/data).  Across the flight (y) alone it says
#: nothing (a strip along a coast sees land on one side); along it (x) alone
#: it is a principal point outside the format or an origin at its edge (the
#: forward overlap spreads the points on both sides: 0.000-0.026 above).
_OFF_CENTRE = 0.5
#: Fewer image points than this say nothing about the format's middle.
_OFF_CENTRE_MIN_POINTS = 20


def _off_centre_problems(xy: FloatArray, file: str) -> list[str]:
    """Image coordinates whose origin is not the principal point (a corner
    of the format: pixels' columns and rows scaled to mm)."""
    if xy.shape[0] < _OFF_CENTRE_MIN_POINTS:
        return []
    low, high = xy.min(axis=0), xy.max(axis=0)
    middle, half = 0.5 * (low + high), 0.5 * (high - low)
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.abs(middle) / half
    beyond = [bool(half[a] > 0.0 and off[a] > _OFF_CENTRE) for a in (0, 1)]
    if not beyond[0]:
        return []
    ranges = ", ".join(f"{'xy'[a]} from {low[a]:.4g} to {high[a]:.4g} mm" for a in (0, 1))
    if beyond[1]:
        return [
            f"{file}: the image points are not centred on the principal point ({ranges}, after "
            "[camera] principal_point_mm): are they measured from a corner of the format? "
            "Give the principal point's position in that system as principal_point_mm (or "
            '[images] units = "pixel" with pixel_size_mm and principal_point_px)'
        ]
    return [
        f"{file}: the image points are not centred on the principal point along the flight "
        f"({ranges}, x along the flight after [camera] principal_point_mm and [images] "
        "flight_direction), which the forward overlap spreads them on both sides of: is the "
        "principal point outside the format, or x measured from an edge of it?"
    ]


def ray_direction_problems(
    rotation_left: ArrayLike,
    rotation_right: ArrayLike,
    base: ArrayLike,
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    labels: Sequence[str],
    *,
    strict: bool = False,
) -> list[str]:
    """Pairs whose rays meet behind the photos, after relative orientation.

    The y-parallax equation does not see the sign of the base (J(5) is
    linear in b), so a pair whose photos are in the wrong order is oriented
    with its base pointing forward and its rays meeting behind both photos:
    the intersection scales ``k_l = j·(b × p) / j·(l × p)`` and
    ``k_r = j·(b × l) / j·(l × p)`` (J(12)) are negative.  All or most pairs
    so: the photos are listed against the flight (or image x points against
    it); a few: those pairs' photos are out of order.

    Parameters
    ----------
    rotation_left, rotation_right : array_like, shape (n_pairs, 3, 3)
        Image -> strip rotations of each pair's photos.
    base : array_like, shape (n_pairs, 3)
        Each pair's base in the strip system.
    left, right : array_like, shape (n, 3)
        Image vectors of each point on the left and right photo.
    pair : array_like of int, shape (n,)
    labels : sequence of str
        Names of the pairs.
    strict : bool
        Raise the first problem instead of returning it.

    Returns
    -------
    list of str

    Raises
    ------
    PhotoOrderError
        With ``strict``, when most pairs' rays meet behind the photos.
    GeometryError
        With ``strict``, when a few pairs' do.
    """
    rot_l = np.asarray(rotation_left, dtype=np.float64)
    rot_r = np.asarray(rotation_right, dtype=np.float64)
    b = np.asarray(base, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    n_pairs = b.shape[0]
    l = np.einsum("nij,nj->ni", rot_l[pair], np.asarray(left, dtype=np.float64))
    p = np.einsum("nij,nj->ni", rot_r[pair], np.asarray(right, dtype=np.float64))
    j = rot_l[pair][:, :, 1]
    d = np.einsum("ni,ni->n", j, np.cross(l, p))
    with np.errstate(invalid="ignore", divide="ignore"):
        k_l = np.einsum("ni,ni->n", j, np.cross(b[pair], p)) / d
        k_r = np.einsum("ni,ni->n", j, np.cross(b[pair], l)) / d
    behind = ~((k_l > 0) & (k_r > 0))
    counts = np.bincount(pair, minlength=n_pairs)
    share = np.bincount(pair, behind, minlength=n_pairs) / np.maximum(counts, 1)
    wrong = share > 0.5
    if not wrong.any():
        return []
    if wrong.sum() > n_pairs / 2:
        message = photo_order_message(int(wrong.sum()), n_pairs)
        if strict:
            raise PhotoOrderError(message, n_wrong=int(wrong.sum()), n_pairs=n_pairs)
        return [message]
    problems = [
        f"{labels[int(m)]}: the rays of {share[m]:.0%} of its points meet behind the photos (a "
        "negative x-parallax, while the strip's other pairs have a positive one): are these "
        "two photos in flight order in the strip's photos ([strip] photos, or its [[strips]] "
        "entry in a block)?"
        for m in np.flatnonzero(wrong)
    ]
    if strict:
        raise GeometryError(problems[0])
    return problems


def photo_order_message(
    n_wrong: int,
    n_pairs: int,
    *,
    flight_direction: FlightDirection | str = FlightDirection.PLUS_X,
    strip: str | None = None,
) -> str:
    """The message for a strip whose photos are listed against the flight.

    Parameters
    ----------
    n_wrong, n_pairs : int
        Pairs whose rays meet behind the photos, and all pairs.
    flight_direction : {"+x", "-x", "+y", "-y"}
        The project's ``[images] flight_direction``: the hint names its
        opposite.
    strip : str, optional
        The strip of a block: the hint names its ``[[strips]]`` entry and
        leaves the flight direction (common to every strip) alone.
    """
    head = (
        "the photos appear to be listed against the flight direction: the rays of "
        f"{n_wrong} of {n_pairs} pairs meet behind the photos (a consistent negative "
        "x-parallax); "
    )
    current = FlightDirection(flight_direction)
    if strip is not None:
        return head + (
            f"list [[strips]] '{strip}' photos in flight order (reverse that strip's list "
            f'only: [images] flight_direction = "{current.value}" holds for every strip of '
            "the block, and its strips may be flown in opposite directions)"
        )
    opposite = corrected_flight_direction(current, "-x")
    return head + (
        f"list [strip] photos in flight order, or, if image {current.value} points against "
        f'the flight, set [images] flight_direction = "{opposite.value}"'
    )


#: Above this many photos in a strip the order is not inferred (a dense
#: eigen-decomposition of their n x n graph: 0.2 s at 1000).
_ORDER_MAX_PHOTOS = 1000


def consecutive_common(row: IntArray, point: IntArray, n: int) -> IntArray:
    """Points observed on both photos of each consecutive pair.

    Parameters
    ----------
    row : array_like of int, shape (m,)
        Each observation's photo, by its position 0 .. n-1 in the strip.
    point : array_like of int, shape (m,)
        Each observation's point; a (row, point) pair may repeat (counted once).
    n : int
        The strip's photos.

    Returns
    -------
    ndarray of int, shape (n - 1,)
        Entry ``k``: the points observed on both photos ``k`` and ``k + 1``.
    """
    row = np.asarray(row, dtype=np.int64)
    key = np.sort(np.asarray(point, dtype=np.int64) * n + row)  # point-major, then row
    # the same point on the next photo: the next key, within the point's keys (a
    # repeated key meets its successor once, at the end of its run)
    on_next = (key[1:] == key[:-1] + 1) & (key[:-1] % n < n - 1)
    left = (key[:-1] % n)[on_next]
    return np.bincount(left, minlength=max(n - 1, 0))[: max(n - 1, 0)].astype(np.intp)


def photo_order_hint(
    observations: ImageObservations,
    sequence: ArrayLike,
    failing: ArrayLike | None,
    min_common: int,
) -> tuple[int, str]:
    """A strip's photos listed out of flight order, told by their common points.

    The photos are put in order by their common points alone: the spectral
    seriation of the graph whose edges weigh the points two photos share
    (the Fiedler vector of its Laplacian; Atkins, Boman and Hendrickson
    1998, SIAM J. Comput. 28(1), 297-310, doi:10.1137/S0097539795285771).
    Along a strip the overlap falls with the distance between photos, so
    that order is the flight's, or its reverse.  A pair that fails (too few
    common points, no tie point with its neighbour) whose two photos are not
    next to each other in that order is listed out of order; the hint names
    the photos each belongs next to.  Nothing is said when the failing
    pair's photos are neighbours by their points too (a photo with few
    points), when the inferred order has a pair with too few common points
    as well (the points cannot tell the order), when the photos fall apart
    into groups that share no point, or for more than
    :data:`_ORDER_MAX_PHOTOS` photos.

    Parameters
    ----------
    observations : ImageObservations
    sequence : array_like of int, shape (n,)
        The strip's photos (indices into ``observations.photo_ids``) in the
        listed order.
    failing : array_like of int, or None
        The failing pairs, each by its left photo's position in ``sequence``;
        None: the consecutive photos with fewer than ``min_common`` common
        points.
    min_common : int
        The fewest common points a pair needs.

    Returns
    -------
    pair : int
        The first failing pair so explained, -1 when none.
    hint : str
        The sentence naming where its photos belong, or "".
    """
    seq = np.asarray(sequence, dtype=np.intp)
    n = seq.shape[0]
    if n < 3 or n > _ORDER_MAX_PHOTOS:
        return -1, ""
    position = np.full(observations.n_photos, -1, dtype=np.intp)
    position[seq] = np.arange(n)
    row = position[observations.photo]
    keep = row >= 0
    if failing is None:
        consecutive = consecutive_common(row[keep], observations.point[keep], n)
        failing = np.flatnonzero(consecutive < min_common)
    pairs = np.unique(np.asarray(failing, dtype=np.intp))
    pairs = pairs[(pairs >= 0) & (pairs < n - 1)]
    if not pairs.size:
        return -1, ""
    # scipy.sparse only for a pair that fails (about 0.045 s to import, with
    # csgraph: a run whose consecutive photos share their points never needs it)
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components, laplacian

    incidence = sparse.csr_matrix(
        (np.ones(int(keep.sum())), (row[keep], observations.point[keep])),
        shape=(n, max(observations.n_points, 1)),
    )
    common = (incidence @ incidence.T).toarray()
    np.fill_diagonal(common, 0.0)
    if connected_components(sparse.csr_matrix(common > 0), directed=False)[0] != 1:
        return -1, ""
    _, vectors = np.linalg.eigh(laplacian(common))
    inferred = np.argsort(vectors[:, 1], kind="stable")  # photos in the inferred order
    if (common[inferred[:-1], inferred[1:]] < min_common).any():
        return -1, ""  # a weak pair in the inferred order too: the points cannot tell
    rank = np.empty(n, dtype=np.intp)
    rank[inferred] = np.arange(n)
    ids = [observations.photo_ids[i] for i in seq]
    for m in pairs.tolist():
        if abs(int(rank[m]) - int(rank[m + 1])) <= 1:
            continue
        belongs = "; ".join(
            f"'{ids[e]}' next to "
            + " and ".join(
                f"'{ids[k]}' ({int(common[e, k])})"
                for k in inferred[max(rank[e] - 1, 0) : rank[e] + 2]
                if k != e
            )
            for e in (m, m + 1)
        )
        return m, (
            f"the photos seem listed out of flight order: by their common points (in "
            f"brackets) {belongs}; list them in flight order ([strip] photos, or the "
            "strip's [[strips]] photos)"
        )
    return -1, ""


def flight_axis_message(
    pair: str,
    along: str,
    *,
    flight_direction: FlightDirection | str = FlightDirection.PLUS_X,
) -> str:
    """The message for a pair whose base runs across the image x axis.

    Parameters
    ----------
    pair : str
        The pair's name.
    along : {"+y", "-y", "-x", ""}
        The axis of the image coordinates (after ``flight_direction``) that
        the photos move along; "" when the points do not tell.
    flight_direction : {"+x", "-x", "+y", "-y"}
        The project's ``[images] flight_direction``.
    """
    current = FlightDirection(flight_direction)
    head = f"{pair}: the base runs across the image x axis"
    if not along:
        return head + (
            "; image x must point along the flight: set [images] flight_direction to the "
            "sensor axis the photos move along"
        )
    right = corrected_flight_direction(current, along)
    back = ("-" if along[0] == "+" else "+") + along[1]
    turned = (
        ""
        if current is FlightDirection.PLUS_X
        else f' (x, y as turned by [images] flight_direction = "{current.value}")'
    )
    return head + (
        f": the photos move along image {along}{turned}, the pair's points shift along "
        f"{back} from the left photo to the right one; image x must point along the flight: "
        f'set [images] flight_direction = "{right.value}"'
    )


def _group_sums(group: IntArray, n: int, *values: FloatArray) -> list[FloatArray]:
    """Sum of each value over the rows of each group (``np.bincount``)."""
    return [np.bincount(group, weights=v, minlength=n).astype(np.float64) for v in values]


def _plan_fit_residuals(
    group: IntArray, n: int, image: FloatArray, ground: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The best 2D similarity image -> ground of every group of rows (a photo),
    without and with a reflection of the image: each fit's sum of squared
    residuals relative to the ground spread, and the ground's smaller over
    larger principal variance (0: the points on one line).

    ``group`` numbers the rows' groups 0..n-1.  In complex numbers z = x + iy
    of the centred coordinates the similarity is z_ground = s z_image with
    s = Σ conj(z_image) z_ground / Σ |z_image|²; the reflected image is
    conj(z_image).
    """
    count = np.bincount(group, minlength=n).astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        means = np.stack(_group_sums(group, n, *image.T, *ground.T), axis=1) / count[:, None]
    a = image - means[group, :2]
    b = ground - means[group, 2:]
    za = a[:, 0] + 1j * a[:, 1]
    zb = b[:, 0] + 1j * b[:, 1]
    saa, sbb, bxx, byy, bxy = _group_sums(
        group,
        n,
        (za * za.conj()).real,
        (zb * zb.conj()).real,
        b[:, 0] ** 2,
        b[:, 1] ** 2,
        b[:, 0] * b[:, 1],
    )
    fits = []
    for image_z in (za, za.conj()):  # proper, mirrored
        cross = image_z.conj() * zb
        re, im = _group_sums(group, n, cross.real, cross.imag)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = (re + 1j * im) / saa
            resid = zb - scale[group] * image_z
            (ss,) = _group_sums(group, n, (resid * resid.conj()).real)
            fits.append(ss / np.maximum(sbb, 1e-300))
    half_trace = 0.5 * (bxx + byy)
    root = np.hypot(0.5 * (bxx - byy), bxy)
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = (half_trace - root) / (half_trace + root)
    return fits[0], fits[1], spread


def control_handedness_problems(
    observations: ImageObservations,
    control_point: IntArray,
    control_xy: ArrayLike,
    *,
    geographic: bool = False,
    file: str = "control",
) -> list[str]:
    """Control mirrored against the photos (plan axes swapped).

    Parameters
    ----------
    observations : ImageObservations
    control_point : array_like of int, shape (C,)
        The observations' point index of each plan control point (−1: not
        observed).
    control_xy : array_like, shape (C, 2)
        Their plan coordinates in the CRS's axis order (always_xy).
    geographic : bool
        True when X, Y are longitude and latitude (degrees): longitudes are
        shrunk by cos(latitude) for the fit.
    file : str
        The control file, for the message.

    Returns
    -------
    list of str
        One message when the photos that can tell vote "mirrored".
    """
    obs = observations
    control_point = np.asarray(control_point, dtype=np.intp)
    xy = np.asarray(control_xy, dtype=np.float64).reshape(-1, 2)
    ok = (control_point >= 0) & np.isfinite(xy).all(axis=1)
    if ok.sum() < 3:
        return []
    xy = xy[ok]
    if geographic:
        xy = np.column_stack([xy[:, 0] * np.cos(np.radians(xy[:, 1].mean())), xy[:, 1]])
    row_of = np.full(obs.n_points, -1, dtype=np.intp)
    row_of[control_point[ok]] = np.arange(int(ok.sum()))
    rows = row_of[obs.point]
    on = np.flatnonzero(rows >= 0)
    photos, group = np.unique(obs.photo[on], return_inverse=True)
    proper, mirrored, spread = _plan_fit_residuals(
        group, photos.size, np.asarray(obs.xy, dtype=np.float64)[on], xy[rows[on]]
    )
    # three points or more, not on one line (singular values 10:1, variances
    # 100:1): a reflection about the line fits as well
    tells = (np.bincount(group, minlength=photos.size) >= 3) & (spread > 0.01)
    mirror = tells & (mirrored < _MIRROR_RATIO * proper)
    votes_mirror = int(np.count_nonzero(mirror))
    votes_proper = int(np.count_nonzero(tells & ~mirror & (proper < _MIRROR_RATIO * mirrored)))
    ratios = proper[mirror] / np.maximum(mirrored[mirror], 1e-300)
    if votes_mirror > votes_proper:
        return [
            f"{file}: the control is mirrored against the photos: on {votes_mirror} of "
            f"{votes_mirror + votes_proper} photos showing three or more plan control points, "
            "the image maps onto the control by a reflection (the fit with one is "
            f"{np.median(ratios):.0f} times closer); are the X and Y columns swapped "
            "(easting and northing, or longitude and latitude), or, if the control is right, "
            "one image axis reversed (y down, as pixel rows run)?"
        ]
    return []


def control_problems(
    observations: ImageObservations,
    control: ControlPoints,
    crs: str | GroundCRS,
    file: str = "control",
) -> list[str]:
    """:func:`control_degree_problems`, :func:`control_distance_problems`,
    :func:`control_relief_problems` (a projected or local CRS), then
    :func:`control_handedness_problems`, for a project's control.

    Every control and check point with plan coordinates takes part (check
    points are measured like control and tell the handedness as well).
    """
    from .geodesy import GroundCRS

    crs = crs if isinstance(crs, GroundCRS) else GroundCRS.from_user_input(crs)
    degrees = control_degree_problems(control, crs, file=file)
    if degrees:
        return degrees
    lookup = {pid: i for i, pid in enumerate(observations.point_ids)}
    point = np.array([lookup.get(p, -1) for p in control.point_ids], dtype=np.intp)
    xy = np.asarray(control.xyz, dtype=np.float64)[:, :2]
    distant = control_distance_problems(observations, point, xy, control.point_ids, file=file)
    if distant:
        return distant
    if not crs.is_geographic:
        units = control_relief_problems(observations, point, control.xyz, file=file)
        if units:
            return units
    return control_handedness_problems(
        observations, point, xy, geographic=crs.is_geographic, file=file
    )


#: A plan point farther from every plan point it shares a photo with than
#: this many times their distance on the photo at the strip's scale cannot
#: lie where its coordinates say (tilt and relief change distances by tens
#: of per cent, not by this factor).
_DISTANCE_FACTOR = 20.0


def _pairs_within_runs(labels: IntArray) -> tuple[IntArray, IntArray]:
    """Every pair of rows (i < j) with the same label, the labels in runs:
    run by run, in the order of ``np.triu_indices`` (0-1, 0-2, ..., 1-2, ...)."""
    n = labels.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    run_end = np.flatnonzero(np.r_[labels[1:] != labels[:-1], True]) + 1
    sizes = np.diff(np.r_[0, run_end])
    partners = np.repeat(run_end, sizes) - np.arange(n) - 1  # rows after each in its run
    first = np.repeat(np.arange(n), partners)
    offset = np.arange(first.shape[0]) - np.repeat(np.cumsum(partners) - partners, partners)
    return first, first + 1 + offset


def _plan_pairs(
    observations: ImageObservations, point: IntArray, plan: FloatArray
) -> tuple[IntArray, IntArray, IntArray, FloatArray, FloatArray]:
    """Every pair of plan control points on each photo: the control row of
    each observation kept, the pairs' two observations ``a``, ``b`` (into
    the kept ones), their distance on the photo (mm, at least 5 % of the
    median) and on the ground (plan units)."""
    row_of = np.full(observations.n_points, -1, dtype=np.intp)
    usable = (np.asarray(point) >= 0) & np.isfinite(plan).all(axis=1)
    row_of[np.asarray(point)[usable]] = np.flatnonzero(usable)
    row = row_of[observations.point]
    keep = np.flatnonzero(row >= 0)  # observations of plan points, sorted by photo
    photo, row, image = observations.photo[keep], row[keep], observations.xy[keep]
    a, b = _pairs_within_runs(photo)  # every pair of plan points on each photo
    if not a.size:
        empty = np.zeros(0, dtype=np.float64)
        return row, a, b, empty, empty
    with np.errstate(all="ignore"):
        on_photo = np.hypot(*(image[a] - image[b]).T)
        on_photo = np.maximum(on_photo, 0.05 * float(np.median(on_photo)))
        ground = np.hypot(*(plan[row[a]] - plan[row[b]]).T)
    return row, a, b, on_photo, ground


def control_distance_problems(
    observations: ImageObservations,
    point: IntArray,
    xy: ArrayLike,
    ids: Sequence[str],
    file: str = "control",
) -> list[str]:
    """Control or check points far from where the photos show them.

    Two plan points on one photo are as far apart on the ground as on the
    photo times the photo scale (within what tilt and relief change).  The
    scale is the median ratio of ground to image distance over every pair of
    plan points that share a photo; a point whose every such pair is more
    than :data:`_DISTANCE_FACTOR` times too long lies far outside the
    project (a typing or export error in its coordinates).

    Parameters
    ----------
    observations : ImageObservations
    point : ndarray of int, shape (m,)
        Observation point index of each control row (-1: not observed).
    xy : array_like, shape (m, 2)
        Plan coordinates of the control rows (NaN for height points).
    ids : sequence of str
        The control rows' ids, for the message.
    file : str
        The control file, for the message.

    Returns
    -------
    list of str
        One message naming the farthest such point (empty when none).
    """
    plan = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    row, a, b, on_photo, ground = _plan_pairs(observations, point, plan)
    if not a.size:
        return []
    with np.errstate(all="ignore"):
        scale = float(np.median(ground / on_photo))
        ratio = ground / (scale * on_photo)
    if not np.isfinite(scale) or scale <= 0.0:
        return []
    best = np.full(plan.shape[0], np.inf)
    np.minimum.at(best, row[a], ratio)
    np.minimum.at(best, row[b], ratio)
    bad = np.flatnonzero(np.isfinite(best) & (best > _DISTANCE_FACTOR))
    if not bad.size:
        return []
    k = int(bad[np.argmax(best[bad])])
    return [
        f"{file}: point '{ids[k]}' at X, Y = {plan[k, 0]:.6g}, {plan[k, 1]:.6g}: implausible "
        f"coordinates: it lies at least {best[k]:.3g} times farther from every plan point it "
        f"shares a photo with than the photos show at the strip's scale ({bad.size} such "
        "point(s)); a typing or export error in its X or Y?"
    ]


#: The control heights on one photo span less than twice the flying height
#: above the mean ground (every point lies below the camera, the lowest at
#: most as far below the mean as the camera is above it); the median photo
#: spanning more than this many flying heights, as the plan control's scale
#: gives it, means plan and heights in different units.  Real projects
#: span 0.03-0.06 of it, the real FC300X block (steep ground at 45 m) 0.37.
_RELIEF_FACTOR = 2.0


def control_relief_problems(
    observations: ImageObservations,
    point: IntArray,
    xyz: ArrayLike,
    file: str = "control",
) -> list[str]:
    """Plan coordinates and heights of the control in different units.

    The plan control gives the photo scale: the median ratio of ground to
    image distance over every pair of plan points on a photo, s (plan units
    per mm); the camera is then about s c above the mean ground.  Every
    point a photo shows lies below its camera, so the heights of the control
    points on one photo span less than twice that.  When, on the median
    photo with two or more height points, they span more than
    :data:`_RELIEF_FACTOR` times s c, X, Y and H are not in one unit (X, Y
    in km with H in m, or H in mm with X, Y in m; heights in feet stay
    within the bound unless the ground is as steep as the flight is low).
    Units are only comparable in a projected or local CRS: nothing is found
    when the plan coordinates are degrees (the caller leaves a geographic
    CRS out).

    Parameters
    ----------
    observations : ImageObservations
    point : ndarray of int, shape (m,)
        Observation point index of each control row (-1: not observed).
    xyz : array_like, shape (m, 3)
        X, Y, H of the control rows (NaN where a row has none).
    file : str
        The control file, for the message.

    Returns
    -------
    list of str
        One message when the units disagree (empty otherwise).
    """
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    _, a, _, on_photo, ground = _plan_pairs(observations, point, xyz[:, :2])
    if not a.size:
        return []
    with np.errstate(all="ignore"):
        scale = float(np.median(ground / on_photo))  # plan units per mm
    height_above = scale * observations.principal_distance
    if not np.isfinite(height_above) or height_above <= 0.0:
        return []
    row_of = np.full(observations.n_points, -1, dtype=np.intp)
    usable = (np.asarray(point) >= 0) & np.isfinite(xyz[:, 2])
    row_of[np.asarray(point)[usable]] = np.flatnonzero(usable)
    row = row_of[observations.point]
    keep = row >= 0
    photo, height = observations.photo[keep], xyz[row[keep], 2]
    n = observations.n_photos
    low, high = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(low, photo, height)
    np.maximum.at(high, photo, height)
    shown = np.bincount(photo, minlength=n) >= 2
    if not shown.any():
        return []
    span = float(np.median((high - low)[shown]))
    if span <= _RELIEF_FACTOR * height_above:
        return []
    return [
        f"{file}: the control heights on a photo span {span:.4g} in H's unit (the median of "
        f"{int(shown.sum())} photos) while the plan control puts the camera about "
        f"{height_above:.4g} in X, Y's unit above the ground (the photos' scale with c = "
        f"{observations.principal_distance:.6g} mm); every point lies below the camera: "
        "are X, Y and H in different units (X, Y in km, or H in mm or feet)?"
    ]


#: Plan control spanning less than this in a projected CRS's unit (metres)
#: cannot be the control of a photo strip; in degrees it is up to ~500 km.
_DEGREE_SPAN = 5.0
#: Margin around a CRS's area of use, degrees.
_AREA_MARGIN_DEG = 1.0


def _inside(lonlat: FloatArray, bounds: tuple[float, float, float, float]) -> BoolArray:
    west, south, east, north = bounds
    m = _AREA_MARGIN_DEG
    lon, lat = lonlat[:, 0], lonlat[:, 1]
    in_lon = (
        (lon >= west - m) & (lon <= east + m)
        if west <= east
        else (lon >= west - m) | (lon <= east + m)
    )  # an area across the antimeridian
    return np.asarray(in_lon & (lat >= south - m) & (lat <= north + m), dtype=bool)


def control_degree_problems(
    control: ControlPoints, crs: str | GroundCRS, file: str = "control"
) -> list[str]:
    """Control in degrees (longitude, latitude) under a projected CRS.

    Parameters
    ----------
    control : ControlPoints
    crs : str or GroundCRS
        ``[control] crs``; nothing is found for "local" or a geographic CRS.
    file : str
        The control file, for the message.

    Returns
    -------
    list of str
        One message when the plan coordinates look like degrees.
    """
    from .geodesy import GroundCRS

    crs = crs if isinstance(crs, GroundCRS) else GroundCRS.from_user_input(crs)
    if crs.crs is None or crs.is_geographic:
        return []
    xy = np.asarray(control.xyz, dtype=np.float64)[:, :2]
    rows = np.flatnonzero(np.isfinite(xy).all(axis=1))
    if rows.size == 0:
        return []
    xy = xy[rows]
    span = float(np.max(np.ptp(xy, axis=0)))
    if not ((np.abs(xy[:, 0]) <= 180.0).all() and (np.abs(xy[:, 1]) <= 90.0).all()):
        return []
    if span >= _DEGREE_SPAN:
        return []
    area = crs.crs.area_of_use
    where = ""
    if area is not None:
        bounds = (area.west, area.south, area.east, area.north)
        degrees_inside = bool(_inside(xy, bounds).all())
        try:
            lonlat = crs.to_wgs84_lonlat(xy)
            metres_inside = bool(np.isfinite(lonlat).all() and _inside(lonlat, bounds).all())
        except GeometryError:  # pyproj cannot place them at all
            metres_inside = False
        if metres_inside and not degrees_inside:
            return []  # small metres near the CRS's origin, inside its area
        if not metres_inside:
            where = f" and lies outside its area of use ({shorten(area.name.rstrip('.'), 30)})"
    k = 0
    given = crs.text or crs.name
    return [
        f"{file}: point '{control.point_ids[int(rows[k])]}': coordinates {xy[k, 0]:.8g}, "
        f"{xy[k, 1]:.8g} look like degrees (longitude, latitude) but crs = {given} is "
        f"projected, in metres: as metres the plan control spans {span:.3g} m{where}; give "
        f"X, Y as {given} eastings and northings, or set [control] crs to the geographic "
        'CRS of the degrees (e.g. "EPSG:4326", WGS 84 longitude and latitude)'
    ]


#: A strip may run this many photos, or this fraction of its photos, beyond
#: its outermost plan or height control before the run warns (R4's layout
#: has full points in the first and the last model).
_END_PHOTOS = 2
_END_FRACTION = 0.1


def control_coverage_problems(
    observations: ImageObservations, control: ControlPoints, file: str = "control"
) -> list[str]:
    """Warnings for a strip's ends that its plan or its height control does
    not reach (photos in flight order, ``observations.photo_ids``).

    A control point reaches the photos it is measured on; an end is
    extrapolated when more than ``max(_END_PHOTOS, _END_FRACTION (M - 1))``
    photos lie beyond the outermost control of a kind.  Errors grow fast
    beyond the last control (with the square to the cube of the distance
    along a strip), which a check point there shows but nothing else does.
    """
    m = observations.n_photos
    lookup = {pid: i for i, pid in enumerate(observations.point_ids)}
    point = np.array([lookup.get(p, -1) for p in control.point_ids], dtype=np.intp)
    first = np.full(observations.n_points, m, dtype=np.intp)
    last = np.full(observations.n_points, -1, dtype=np.intp)
    np.minimum.at(first, observations.point, observations.photo)
    np.maximum.at(last, observations.point, observations.photo)
    seen = point >= 0
    seen[seen] = first[point[seen]] < last[point[seen]]  # on two photos at least
    slack = max(_END_PHOTOS, _END_FRACTION * (m - 1))
    reach: dict[tuple[int, int], list[str]] = {}
    for kind, uses in (("plan", control.uses_xy), ("height", control.uses_h)):
        rows = point[seen & uses]
        if rows.size == 0:
            continue  # no control of this kind at all: the adjustment says so
        lo, hi = int(first[rows].min()), int(last[rows].max())
        if lo > slack or m - 1 - hi > slack:
            reach.setdefault((lo, hi), []).append(kind)
    ids = observations.photo_ids
    return [
        f"{file}: the {' and '.join(kinds)} control "
        f"{'reach' if len(kinds) > 1 else 'reaches'} photos {ids[lo]} to {ids[hi]} "
        f"of the strip's {ids[0]} to {ids[-1]}: the {lo + m - 1 - hi} photos beyond are "
        "extrapolated, and a strip's errors grow fast beyond its last control; add full "
        "control points at both ends of the strip (R4: in the first and the last model)"
        for (lo, hi), kinds in reach.items()
    ]


#: The image sigma given may be this many times the scatter of the pairs'
#: y-parallaxes, or this many times smaller, before the run warns: the
#: weights, sigma0 and every blunder test rest on it.
_SIGMA_FACTOR = 5.0


def image_sigma_problems(pair_sigma_um: ArrayLike, sigma_mm: ArrayLike) -> list[str]:
    """A warning when the image sigma given (``sigma_mm``, every
    observation's, mm) is far from what the relative orientations measured
    (``pair_sigma_um``: each pair's a-posteriori sigma of an image coordinate
    from its residual y-parallaxes, µm), medians against each other.

    Given far too large (e.g. 5 written for 5 µm, or a sigma in pixels with
    ``units = "pixel"``: the column is millimetres whatever the units), the
    images weigh nothing against the control and no blunder test can fail;
    far too small, the tests reject good observations.
    """
    measured = np.asarray(pair_sigma_um, dtype=np.float64)
    measured = measured[np.isfinite(measured) & (measured > 0)]
    given_mm = np.asarray(sigma_mm, dtype=np.float64)
    if measured.size == 0 or given_mm.size == 0:
        return []
    scatter, given = float(np.median(measured)), 1000.0 * float(np.median(given_mm))
    ratio = given / scatter
    if 1.0 / _SIGMA_FACTOR <= ratio <= _SIGMA_FACTOR:
        return []
    times = f"{ratio:.0f} times" if ratio >= 1.0 else f"1/{1.0 / ratio:.0f} of"
    head = (
        f"image sigma: the sigma given to the image coordinates ({given:.4g} µm, median) is "
        f"{times} the scatter of the pairs' own y-parallaxes ({scatter:.3g} µm, median of "
        "the relative orientations' sigma0): "
    )
    if ratio > _SIGMA_FACTOR:
        return [
            head + "the images weigh too little against the control and the blunder tests "
            "cannot find their errors; the sigma column and [images] sigma_mm are in "
            "millimetres whatever [images] units (micrometres or pixels written there?)"
        ]
    return [
        head + "the blunder tests will reject good observations; the sigma column and "
        "[images] sigma_mm are in millimetres (metres written there?)"
    ]

