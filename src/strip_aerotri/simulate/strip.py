"""Simulated strips of vertical photos with a known truth.

:func:`simulate_strip` builds one strip of near-vertical photos over a smooth
random terrain on the curved earth, measures image coordinates by the
collinearity equations, picks ground control in a J/R4-style layout and
returns everything together with the true geometry. It lets users try the
tool without data, and it is the ground truth of the package's tests.

Geometry
--------
* The strip is built in a local east-north-up (ENU) Cartesian tangent frame
  with its origin on the ellipsoid normal through the strip centre, at the
  mean terrain height (ellipsoidal), on the ellipsoid of the datum of the
  chosen CRS (geodetic <-> geocentric of the same datum, no datum shift).
* Ground points and photo centres are first laid out in plan as (east,
  north) metres of a transverse Mercator projection centred on the strip
  centre (scale 1 on its central meridian) with an ellipsoidal height from
  the terrain function, and then converted exactly, through geodetic and
  geocentric coordinates, into the local ENU frame. The earth's curvature is
  therefore in the data (about ``D**2 / (2 R)`` of height drop at a distance
  D from the centre).
* Image system (method.md section 2): x along the flight, y to its left, z
  up; image vector ``(x, y, -c)`` in mm. A photo's rotation ``R`` maps image
  vectors to the local ENU frame: ``R = T @ Rz(90° - heading) @ Rx(omega) @
  Ry(phi) @ Rz(dkappa)``, where ``T`` rotates the ENU frame at the photo's
  nadir into the ENU frame at the strip centre (tilt of the local vertical).
* omega, phi and dkappa are normal, truncated at two standard deviations
  (film: tilts within 3°, the usual limit for vertical photography), so that
  every triple overlap keeps its tie zones.
* Collinearity: ``v = R.T @ (X - S)``, ``x = -c v_x / v_z``,
  ``y = -c v_y / v_z``; then optional systematic errors, then noise.

Points
------
Per photo, ``len(gruber_y_mm)`` "Gruber" zones across the strip (film:
y = +75, 0, -75 mm), each with ``gruber_points_per_zone`` points spread by
``gruber_spread_mm``, are picked on that photo's image at the x midway
between the images of its neighbours' principal points (the middle of the
triple overlap) and intersected with the terrain; they are the tie points.
Each model (photo base) gets ``extra_points_per_photo`` more points at
random over its area. With ``line=True`` a straight road runs
along the strip axis: ``line_points_per_model`` points per model lie exactly
on one vertical plane of the local ENU frame (heights follow the terrain);
they have no ground coordinates and are returned in ``lines``. Every point is
kept only if at least two photos see it (inside the format, in front of the
camera). Ids: photos ``"1001"``, ``"1002"``, ...; points ``"P0001"``, ... in
order along the flight.

Control
-------
``control="ends"``: full (X, Y, H) points on both sides of the strip at the
first nadir, the last nadir and the middle nadir; height-only points on both
sides at every third nadir in between; plan-only points on the strip axis at
the quarter nadirs. ``"every_k_models"``: full points on both sides every
``control_every`` models and at the last nadir. ``"dense"``: full points on
both sides at every nadir. ``"fig4"`` (R4's strip layout): three full points
(both sides and the axis) at the first and at the last nadir, height-only
points on both sides at every third nadir in between. ``"weak"``: two full
points (both sides) at the first and at the last nadir and one height point
on the axis at the middle nadir: about the least a strip can be oriented
and deformed with. Every other Gruber-zone point that is seen (except
those of the first and last nadir) is a check point. Control coordinates are
the truth plus N(0, ``control_noise_m``) per coordinate in metres (added in
the local ENU frame, so also for geographic CRSs); check points carry the
exact truth. The ``sigma_xy`` and ``sigma_h`` written for control equal
``control_noise_m`` (or 0.01 m when it is 0).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..observations import ControlPoints, ImageObservations
from ..options import DEFAULT_IMAGE_SIGMA_MM
from ._control import _CONTROL_LAYOUTS, _blunders, _control
from ._geodesy import LocalFrame, _Geodesy
from ._scene import (
    _EXTRA,
    _GRUBER,
    _LINE,
    _attitudes_about,
    _frozen,
    _image2terrain_plan,
    _matrix_from_opk,
    _projection_reach,
    _road_points,
    _rz,
    _Terrain,
    _triple_overlap_centre_x,
    _visible_pairs,
    camera_error_values,
)
from .cameras import StripPreset, _resolve_preset
from .writer import write_strip_project

__all__ = ["SimulatedStrip", "SimulationTruth", "simulate_strip"]


@dataclass(frozen=True, eq=False)
class SimulationTruth:
    """The true geometry of a simulated strip (arrays are read-only).

    Attributes
    ----------
    photo_centres_local : ndarray, shape (M, 3)
        Projection centres in the local ENU frame, metres, photo order.
    photo_rotations_local : ndarray, shape (M, 3, 3)
        Rotations image -> local ENU (``l = R @ (x, y, -c)``).
    points_local : ndarray, shape (P, 3)
        Ground points in the local ENU frame, in the order of
        ``observations.point_ids``.
    points_crs : ndarray, shape (P, 3)
        The same in the CRS (X, Y in always_xy order, H ellipsoidal height of
        the CRS's datum in metres); the local ENU coordinates for "local".
    photo_centres_crs : ndarray, shape (M, 3)
        Projection centres in the CRS, as ``points_crs``.
    origin_lonlat_h : tuple of float
        Longitude, latitude (deg) and ellipsoidal height (m) of the local
        frame's origin.
    local_to_ecef : LocalFrame
        Origin and rotation linking the local frame to geocentric coordinates.
    ellipsoid : tuple of float
        Semi-major axis (m) and inverse flattening of the datum's ellipsoid.
    heading_deg : float
        Azimuth of the flight line, degrees clockwise from north.
    flying_height_m : float
        Planned flying height above the mean terrain, metres.
    blunder_observations : tuple of int
        Rows of the observations given a gross error (``image_blunders``).
    blunder_control : tuple of int
        Rows of the control given a gross error (``control_blunders``).
    """

    photo_centres_local: FloatArray
    photo_rotations_local: FloatArray
    points_local: FloatArray
    points_crs: FloatArray
    photo_centres_crs: FloatArray
    origin_lonlat_h: tuple[float, float, float]
    local_to_ecef: LocalFrame
    ellipsoid: tuple[float, float]
    heading_deg: float
    flying_height_m: float
    blunder_observations: tuple[int, ...] = ()
    blunder_control: tuple[int, ...] = ()


@dataclass(frozen=True, eq=False)
class SimulatedStrip:
    """A simulated strip: observations, control, straight lines and truth.

    Attributes
    ----------
    preset : StripPreset
        The parameters used (after overrides).
    observations : ImageObservations
        Image coordinates in mm (noise and systematic errors included).
    control : ControlPoints
        Control (full, plan, height) and check points in ``crs``.
    crs : str
        The control CRS as given ("local" for the local ENU frame).
    lines : tuple of (tuple of str, float)
        Straight lines: point ids and weight.
    truth : SimulationTruth
        True geometry.
    """

    preset: StripPreset
    observations: ImageObservations
    control: ControlPoints
    crs: str
    lines: tuple[tuple[tuple[str, ...], float], ...]
    truth: SimulationTruth

    def write_project(
        self,
        directory: str | Path,
        *,
        polynomial: int | str | None = None,
        route: str | None = None,
        name: str | None = None,
    ) -> Path:
        """Write ``strip.toml``, ``image_points.csv`` and ``control.csv``.

        The files follow the project format (docs/project-file.md). Existing files of
        those names in ``directory`` are overwritten; the folder is created if
        needed.

        Parameters
        ----------
        directory : str or Path
            Output folder.
        polynomial : {0, 1, 2, 3, "auto"}, optional
            ``[adjustment] polynomial`` (J's construction, ``block =
            "strips"``); None (the default) writes none: every model at once.
        route : {"geocentric", "projected"}, optional
            ``[adjustment] route``; omitted (the tool's default) when None.
            Only "projected" is valid with ``crs = "local"``.
        name : str, optional
            ``[strip] name``; default describes the simulation.

        Returns
        -------
        Path
            Path of ``strip.toml``.

        Raises
        ------
        ValueError
            For a bad ``polynomial`` or ``route``.
        """
        obs = self.observations
        if name is None:
            name = f"Simulated {self.preset.name} strip, {obs.n_photos} photos"
        return write_strip_project(
            directory,
            obs,
            self.control,
            self.crs,
            name=name,
            lines=self.lines,
            polynomial=polynomial,
            route=route,
        )


def simulate_strip(
    n_photos: int = 12,
    *,
    preset: str | StripPreset = "film",
    crs: str = "EPSG:32634",
    centre_lonlat: tuple[float, float] | None = None,
    heading_deg: float = 75.0,
    seed: int = 0,
    image_noise_mm: float | None = None,
    control: str = "ends",
    control_every: int = 3,
    control_noise_m: float | None = None,
    n_check: int | None = None,
    line: bool | None = None,
    systematic_k1: float = 0.0,
    film_shrink_y: float = 1.0,
    camera_errors: Mapping[str, float] | None = None,
    image_blunders: int = 0,
    image_blunder_mm: float | None = None,
    control_blunders: int = 0,
    control_blunder_m: tuple[float, float] = (0.5, 2.0),
    **overrides: object,
) -> SimulatedStrip:
    """Simulate one strip of vertical photos with a known truth.

    Length: twenty documented parameters; the code is the flight's steps
    in order (photos, points, images, control, blunders).

    Parameters
    ----------
    n_photos : int
        Number of photos M (>= 2).
    preset : {"film", "drone", "corridor"} or StripPreset
        Physical parameters (see :data:`PRESETS`).
    crs : str
        CRS of the control (any horizontal projected or geographic CRS
        pyproj understands), or "local" for the local ENU frame itself
        (X = east, Y = north, H = up, metres, WGS 84 ellipsoid).
    centre_lonlat : (float, float), optional
        Strip centre, longitude and latitude in degrees on the CRS's datum;
        default: the centre of the CRS's area of use ((21, 52) for "local").
    heading_deg : float
        Azimuth of the flight, degrees clockwise from (geodetic) north.
    seed : int
        Seed of ``np.random.default_rng``; equal arguments give equal strips.
    image_noise_mm : float, optional
        Image noise standard deviation in mm; default: the preset's (film
        5 µm). With 0 the observations are exact; their ``sigma`` is then
        the default image sigma (``DEFAULT_IMAGE_SIGMA_MM``).
    control : {"ends", "every_k_models", "dense", "fig4", "weak"}
        Control layout (see the module notes).
    control_every : int
        Spacing in models of the full control for "every_k_models".
    control_noise_m : float, optional
        Control noise standard deviation in metres; default the preset's
        (film 0.02 m).
    n_check : int, optional
        Number of check points (a random subset); default all candidates.
    line : bool, optional
        Simulate a straight road; default the preset's ("corridor": True).
    systematic_k1 : float
        Radial distortion added to the images and not modelled by the
        adjustment, in mm^-2: ``x' = x (1 + k1 r**2)``, ``y' = y (1 + k1 r**2)``.
    film_shrink_y : float
        Scale applied to the image y coordinates (film shrinkage; 1 = none).
    camera_errors : mapping of str to float, optional
        Uncorrected camera errors: Brown/Fraser values by name (``c, x0, y0,
        k1, k2, k3, p1, p2, b1, b2``; units and formula in
        :mod:`strip_aerotri.geometry.camera_model`), given as the correction
        that the simulated measurements need: measured ``m`` with ``m +
        Δ(m) = ideal``.  A self-calibration estimating them finds these
        values.  Default none (the images are unchanged).
    image_blunders, image_blunder_mm : int, float or None
        Observations of points seen on three or more photos given a gross
        error: a shift in a random direction of ``image_blunder_mm`` (default
        15-40 times the image noise, at least 0.05 mm); their rows are in
        ``truth.blunder_observations``.
    control_blunders, control_blunder_m : int, (float, float)
        Control rows (full, plan or height) given a gross error of one given
        coordinate, a random size in ``control_blunder_m`` with a random
        sign; their rows are in ``truth.blunder_control``.
    **overrides
        Any :class:`StripPreset` field except ``name``, e.g.
        ``extra_points_per_photo=10``.

    Returns
    -------
    SimulatedStrip

    Raises
    ------
    ValueError
        For bad arguments, unknown overrides or a strip in which too few
        points are seen.

    Examples
    --------
    >>> strip = simulate_strip(5, seed=1)
    >>> strip.observations.photo_ids
    ('1001', '1002', '1003', '1004', '1005')
    >>> strip.truth.points_local.shape == (strip.observations.n_points, 3)
    True
    """
    if isinstance(n_photos, bool) or not isinstance(n_photos, (int, np.integer)) or n_photos < 2:
        raise ValueError(f"Expected `n_photos` to be an integer >= 2, got {n_photos!r}")
    if control not in _CONTROL_LAYOUTS:
        raise ValueError(f"Expected `control` to be one of {_CONTROL_LAYOUTS}, got {control!r}")
    extra: dict[str, object] = {**overrides, **({} if line is None else {"line": bool(line)})}
    pre, errors = _preset_and_errors(
        preset,
        extra,
        _Arguments(
            crs, heading_deg, systematic_k1, film_shrink_y, control_every, n_check, camera_errors
        ),
        image_noise_mm,
        control_noise_m,
    )

    m = int(n_photos)
    rng = np.random.default_rng(seed)
    geo = _Geodesy.build(crs, centre_lonlat, pre.terrain_height_m)
    terrain = _Terrain.random(rng, pre)
    flight = _Flight.fly(rng, geo, pre, m, math.radians(float(heading_deg)))
    scene = _scene_points(rng, geo, terrain, pre, flight)

    # Collinearity and visibility, each point only in the photos that can
    # reach it (a dense (photos, points) projection is quadratic in the strip).
    ground = scene.ground
    reach = _projection_reach(
        pre,
        geo,
        flight.opk,
        flight.centre_plan[:, 2],
        ground,
        flight.centres,
        systematic_k1,
        film_shrink_y,
        margin=1.0 if errors is None else 1.05,
    )
    pairs = _visible_pairs(
        ground,
        flight.centres,
        flight.rotations,
        pre,
        reach,
        flight.ahead_local,
        systematic_k1,
        film_shrink_y,
        errors,
    )
    keep = _seen_twice(pairs[1], ground.shape[0])
    # Number the kept points along the flight.
    kept = np.flatnonzero(keep)
    kept = kept[np.argsort(ground[kept] @ flight.ahead_local, kind="stable")]
    photo_names = np.arange(1001, 1001 + m).astype(str)
    observations, kept = _observe(rng, pre, pairs, keep, kept, photo_names, min_width=4)

    points_local = ground[kept]
    points_crs = geo.local2crs(points_local)
    control_points = _control(
        rng,
        geo,
        pre,
        observations.point_ids,
        points_local,
        points_crs,
        kind=scene.kind[kept],
        nadir=scene.nadir[kept],
        row=scene.row[kept],
        rank=scene.rank[kept],
        m=m,
        layout=control,
        every=int(control_every),
        n_check=n_check,
    )

    line_ids = tuple(
        p for p, k in zip(observations.point_ids, scene.kind[kept], strict=True) if k == _LINE
    )
    lines = ((line_ids, float(pre.line_weight)),) if len(line_ids) >= 3 else ()
    observations, control_points, truth = _with_blunders_and_truth(
        _Blunders(seed, image_blunders, image_blunder_mm, control_blunders, control_blunder_m),
        observations,
        control_points,
        pre,
        geo,
        flight.centres,
        flight.rotations,
        (points_local, points_crs),
        heading_deg,
    )
    return SimulatedStrip(
        preset=pre,
        observations=observations,
        control=control_points,
        crs=crs,
        lines=lines,
        truth=truth,
    )


class _Arguments(NamedTuple):
    """The arguments a strip and a block check alike."""

    crs: object
    heading_deg: float
    systematic_k1: float
    film_shrink_y: float
    control_every: int
    n_check: int | None
    camera_errors: Mapping[str, float] | None


def _preset_and_errors(
    preset: str | StripPreset,
    extra: dict[str, object],
    args: _Arguments,
    image_noise_mm: float | None,
    control_noise_m: float | None,
) -> tuple[StripPreset, FloatArray | None]:
    """The arguments of a strip or a block checked, the preset with the
    noises and ``extra`` fields given, and the camera errors' values."""
    if int(args.control_every) < 1:
        raise ValueError(f"Expected `control_every` >= 1, got {args.control_every!r}")
    if args.n_check is not None and int(args.n_check) < 0:
        raise ValueError(f"Expected `n_check` >= 0 or None, got {args.n_check!r}")
    if not isinstance(args.crs, str):
        raise ValueError(f"Expected `crs` to be a string, got {type(args.crs).__name__}")
    finite = math.isfinite(args.heading_deg) and math.isfinite(args.systematic_k1)
    if not finite or args.film_shrink_y <= 0:
        raise ValueError("Expected finite `heading_deg`, `systematic_k1` and `film_shrink_y` > 0")
    errors = camera_error_values(args.camera_errors)
    if image_noise_mm is not None:
        extra["image_noise_mm"] = float(image_noise_mm)
    if control_noise_m is not None:
        extra["control_noise_m"] = float(control_noise_m)
    return _resolve_preset(preset, extra), errors


@dataclass(frozen=True)
class _Flight:
    """A strip's photos: the flight axes in plan (east, north), the nadirs
    along the axis (m), the centres in plan and height, in the local frame,
    and the attitudes (ω, φ, κ and image -> local rotations); ``heading``
    the azimuth of the axis, radians."""

    heading: float
    ahead: FloatArray
    left: FloatArray
    along: FloatArray
    centre_plan: FloatArray
    centres: FloatArray
    opk: FloatArray
    rotations: FloatArray

    @property
    def ahead_local(self) -> FloatArray:
        return np.array([self.ahead[0], self.ahead[1], 0.0])

    @classmethod
    def fly(
        cls, rng: np.random.Generator, geo: _Geodesy, pre: StripPreset, m: int, heading: float
    ) -> _Flight:
        """``m`` photos on the axis of azimuth ``heading`` (radians), one base
        apart, wandering in position, height and attitude."""
        ahead = np.array([math.sin(heading), math.cos(heading)])  # plan (east, north)
        left = np.array([-math.cos(heading), math.sin(heading)])
        along = np.asarray((np.arange(m) - 0.5 * (m - 1)) * pre.base_m, dtype=np.float64)
        w = pre.position_wander_m
        d_along = along + rng.uniform(-w, w, m)
        d_across = rng.uniform(-w, w, m)
        centre_plan, centres, opk, tilt = _attitudes_about(
            rng, geo, pre, d_along[:, None] * ahead + d_across[:, None] * left
        )
        rotations = tilt @ _rz(math.pi / 2.0 - heading) @ _matrix_from_opk(opk)
        return cls(heading, ahead, left, along, centre_plan, centres, opk, rotations)


class _ScenePoints(NamedTuple):
    """The ground points (local frame) and what each is: its kind, and for a
    Gruber point its photo (nadir), zone row and rank in the zone (-1 else)."""

    ground: FloatArray
    kind: IntArray
    nadir: IntArray
    row: IntArray
    rank: IntArray


def _scene_points(
    rng: np.random.Generator,
    geo: _Geodesy,
    terrain: _Terrain,
    pre: StripPreset,
    flight: _Flight,
) -> _ScenePoints:
    """Gruber zones picked on each photo's image near its principal point (so
    they lie in the triple overlap whatever the photo's tilt), random points
    per model, and the road's points when the preset has one."""
    m = flight.centres.shape[0]
    c = pre.principal_distance_mm
    n_rows, per_zone = len(pre.gruber_y_mm), pre.gruber_points_per_zone
    zone_nadir = np.repeat(np.arange(m), n_rows * per_zone)
    zone_row = np.tile(np.repeat(np.arange(n_rows), per_zone), m)
    zone_rank = np.tile(np.arange(per_zone), m * n_rows)
    spread = pre.gruber_spread_mm
    k_g = zone_nadir.size
    zone_x = _triple_overlap_centre_x(geo, terrain, flight.centres, flight.rotations, c)
    zone_xy = np.column_stack(
        [
            zone_x[zone_nadir] + rng.uniform(-spread, spread, k_g),
            np.asarray(pre.gruber_y_mm, dtype=np.float64)[zone_row]
            + rng.uniform(-spread, spread, k_g),
        ]
    )
    g_plan = _image2terrain_plan(
        geo, terrain, flight.centres, flight.rotations, zone_nadir, zone_xy, c
    )
    n_extra = pre.extra_points_per_photo * (m - 1)
    half_width = 0.45 * pre.format_mm[1] * pre.scale_m_per_mm
    e_model = np.repeat(np.arange(m - 1), pre.extra_points_per_photo)
    e_along = flight.along[e_model] + rng.uniform(0.0, pre.base_m, n_extra)
    e_across = rng.uniform(-half_width, half_width, n_extra)
    e_plan = e_along[:, None] * flight.ahead + e_across[:, None] * flight.left
    plan = np.vstack([g_plan, e_plan])
    ground = geo.plan2local(np.column_stack([plan, terrain.height(plan)]))
    kind = np.concatenate([np.full(k_g, _GRUBER), np.full(n_extra, _EXTRA)])
    nadir = np.concatenate([zone_nadir, np.full(n_extra, -1)])
    row = np.concatenate([zone_row, np.full(n_extra, -1)])
    rank = np.concatenate([zone_rank, np.full(n_extra, -1)])
    if pre.line and pre.line_points_per_model > 0:
        road = _road_points(geo, terrain, pre, flight.heading, flight.along)
        ground = np.vstack([ground, road])
        n_road = road.shape[0]
        kind = np.concatenate([kind, np.full(n_road, _LINE)])
        nadir, row, rank = (np.concatenate([a, np.full(n_road, -1)]) for a in (nadir, row, rank))
    return _ScenePoints(ground, kind, nadir, row, rank)


def _seen_twice(pair_point: IntArray, n_points: int) -> BoolArray:
    """The points seen on two or more photos (an error when fewer than three are)."""
    keep = np.bincount(pair_point, minlength=n_points) >= 2
    if keep.sum() < 3:
        raise ValueError("Too few points are seen on two or more photos; check the parameters")
    return np.asarray(keep, dtype=bool)


def _observe(
    rng: np.random.Generator,
    pre: StripPreset,
    pairs: tuple[IntArray, IntArray, FloatArray],
    keep: BoolArray,
    kept: IntArray,
    photo_names: np.ndarray,
    *,
    min_width: int,
) -> tuple[ImageObservations, IntArray]:
    """The image observations of the visible (photo, point, xy) ``pairs`` of
    the points ``keep``: the points named ``P0001``... in the order ``kept``
    (zero-padded to ``min_width`` digits at least), photo by photo, with the
    preset's image noise; and ``kept`` in the observations' point order."""
    pair_photo, pair_point, pair_xy = pairs
    width = max(min_width, len(str(kept.size)))
    point_names = np.char.add("P", np.char.zfill(np.arange(1, kept.size + 1).astype(str), width))
    # Observations photo by photo, each photo's points in numbering order.
    number = np.full(keep.size, -1)
    number[kept] = np.arange(kept.size)
    seen = keep[pair_point]
    obs_photo, obs_point, xy = pair_photo[seen], number[pair_point[seen]], pair_xy[seen]
    order = np.lexsort((obs_point, obs_photo))
    obs_photo, obs_point, xy = obs_photo[order], obs_point[order], xy[order]
    if pre.image_noise_mm > 0:
        xy = xy + rng.normal(0.0, pre.image_noise_mm, xy.shape)
    sigma = pre.image_noise_mm if pre.image_noise_mm > 0 else DEFAULT_IMAGE_SIGMA_MM
    observations = ImageObservations.from_ids(
        photo_names[obs_photo],
        point_names[obs_point],
        xy,
        pre.principal_distance_mm,
        photo_ids=photo_names,
        sigma=sigma,
    )
    # ``from_ids`` orders points by id; the ids (sorted, zero-padded) were
    # assigned in ``kept`` order.
    return observations, kept[np.searchsorted(point_names, np.asarray(observations.point_ids))]


class _Blunders(NamedTuple):
    """The gross errors asked for (``simulate_strip``'s arguments)."""

    seed: int
    image: int
    image_mm: float | None
    control: int
    control_m: tuple[float, float]


def _with_blunders_and_truth(
    blunders: _Blunders,
    observations: ImageObservations,
    control_points: ControlPoints,
    pre: StripPreset,
    geo: _Geodesy,
    centres: FloatArray,
    rotations: FloatArray,
    points: tuple[FloatArray, FloatArray],
    heading_deg: float,
) -> tuple[ImageObservations, ControlPoints, SimulationTruth]:
    """The observations and control with their gross errors (drawn from a
    generator of their own, so that the rest is the same with and without
    them), and the truth (``points``: in the local frame and in the CRS)."""
    points_local, points_crs = points
    blunder_obs: tuple[int, ...] = ()
    blunder_ctrl: tuple[int, ...] = ()
    if blunders.image or blunders.control:
        observations, control_points, blunder_obs, blunder_ctrl = _blunders(
            np.random.default_rng([blunders.seed, 7]),
            observations,
            control_points,
            pre,
            int(blunders.image),
            blunders.image_mm,
            int(blunders.control),
            blunders.control_m,
        )
    truth = SimulationTruth(
        photo_centres_local=_frozen(centres),
        photo_rotations_local=_frozen(rotations),
        points_local=_frozen(points_local),
        points_crs=_frozen(points_crs),
        photo_centres_crs=_frozen(geo.local2crs(centres)),
        origin_lonlat_h=(geo.centre_lonlat[0], geo.centre_lonlat[1], pre.terrain_height_m),
        local_to_ecef=LocalFrame(_frozen(geo.frame.origin_ecef), _frozen(geo.frame.ecef2enu)),
        ellipsoid=geo.ellipsoid,
        heading_deg=float(heading_deg),
        flying_height_m=pre.flying_height_m,
        blunder_observations=blunder_obs,
        blunder_control=blunder_ctrl,
    )
    return observations, control_points, truth
