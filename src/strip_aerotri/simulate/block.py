"""Simulated blocks of parallel strips with a known truth.

:func:`simulate_block` lays out ``n_strips`` parallel strips of
``n_photos_per_strip`` photos over one terrain, with the camera, attitudes,
points and noise of the single-strip simulator (:mod:`.strip`), and measures
every point on every photo of the block that sees it: a point id is one
ground point across the whole block, so the points of a side overlap are
observed on the photos of both strips.

Geometry
--------
* Strip axes are parallel to ``heading_deg`` and ``(1 - side_overlap) *
  format_mm[1] * scale`` metres apart (the ground footprint across the
  flight at the mean terrain); the block is centred on the local frame's
  origin. Strip 1 is the leftmost seen along ``heading_deg``, the next ones
  follow to its right.
* ``flight="serpentine"``: strips 2, 4, ... are flown the other way
  (``heading_deg + 180``, photo 1 at the far end of the block);
  ``flight="same"``: every strip is flown along ``heading_deg``. The planned
  nadirs of all strips lie on the same lines across the block ("stations",
  numbered 1 ... M along ``heading_deg``); centres, heights and attitudes
  wander about them as in a strip.

Points
------
Each strip gets the Gruber zones and the random model points of a strip
(:mod:`.strip`). Each side overlap also gets ``side_points_per_zone`` points
at every station, picked on the left strip's photo at the middle of its
triple overlap along the flight and at the middle of the side overlap
across it: seen on up to three photos of each strip, they are the common
points of the two strips (R4: the tie points of adjacent strips lie in
their side overlap), at least ``2 * side_points_per_zone`` in every model.
Points seen on fewer than two photos are dropped. Ids: strips ``"S1"``,
``"S2"``, ...; photos ``"S1_01"``, ... in each strip's flight order; points
``"P00001"``, ... across the block, strip by strip and side overlap by side
overlap, along ``heading_deg``.

Control
-------
Block layouts, on the "lanes" across the block (each strip's Gruber rows
and the middle of each side overlap):

* ``"perimeter"``: full points on the two outer lanes (the outer Gruber rows
  of the first and last strip) at every ``control_every``-th station and at
  the last, full points on every side overlap at the first and the last
  station (so the two ends of the block are controlled strip by strip), and
  height points on every side overlap at every ``control_every``-th station
  in between: chains of height points across the block.
* ``"corners"``: full points at the four corners and height points across
  the block at the middle station (outer lanes and side overlaps): about the
  least a block can be oriented with.

Without Gruber rows (``gruber_y_mm=()``) the outer lanes are the first and
the last side overlap.

Strip layouts (``"ends"``, ``"every_k_models"``, ``"dense"``, ``"fig4"``,
``"weak"``) give each strip the control it would have alone (:mod:`.strip`).
Every other Gruber or side-overlap point that is seen, except those of the
first and last station, is a check point. Noise and sigmas as for a strip.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray, IntArray
from ..observations import ControlPoints, ControlType, ImageObservations
from ._control import _CONTROL_LAYOUTS, _control_points, _strip_roles, _zone_points
from ._geodesy import _Geodesy
from ._scene import (
    _EXTRA,
    _GRUBER,
    _attitudes_about,
    _frozen,
    _image2terrain_plan,
    _matrix_from_opk,
    _projection_reach,
    _Terrain,
    _triple_overlap_centre_x,
    _visible_pairs,
)
from .cameras import StripPreset
from .strip import (
    SimulationTruth,
    _Arguments,
    _Blunders,
    _observe,
    _preset_and_errors,
    _seen_twice,
    _with_blunders_and_truth,
)
from .writer import write_block_project

__all__ = ["BlockStrip", "SimulatedBlock", "simulate_block"]

_FLIGHTS = ("serpentine", "same")
_BLOCK_LAYOUTS = ("perimeter", "corners")
_SIDE_OVERLAP = (0.2, 0.6)

# Point kind of the side-overlap zones (the strip's kinds are _GRUBER, _EXTRA).
_SIDE = 3


@dataclass(frozen=True, eq=False)
class BlockStrip:
    """One strip of a simulated block, with its true photo geometry.

    Attributes
    ----------
    name : str
        Strip name (``[[strips]] name``).
    photo_ids : tuple of str, length M
        Photos in the strip's flight order.
    heading_deg : float
        Azimuth of this strip's flight, degrees clockwise from north.
    reversed : bool
        Whether the strip is flown against the block's ``heading_deg``.
    offset_m : float
        Planned axis offset from the block's centre line, metres, positive to
        the right of the block's ``heading_deg``.
    photo_centres_local : ndarray, shape (M, 3)
        True projection centres in the local ENU frame, metres, flight order.
    photo_rotations_local : ndarray, shape (M, 3, 3)
        True rotations image -> local ENU (``l = R @ (x, y, -c)``).
    """

    name: str
    photo_ids: tuple[str, ...]
    heading_deg: float
    reversed: bool
    offset_m: float
    photo_centres_local: FloatArray
    photo_rotations_local: FloatArray


@dataclass(frozen=True, eq=False)
class SimulatedBlock:
    """A simulated block: strips, observations, control and truth.

    Attributes
    ----------
    preset : StripPreset
        The parameters of every strip (after overrides).
    side_overlap : float
        Planned side overlap of adjacent strips, a fraction.
    flight : {"serpentine", "same"}
        Flight pattern.
    strips : tuple of BlockStrip
        The strips, left to right across the block's heading.
    observations : ImageObservations
        Image coordinates in mm of the whole block; ``photo_ids`` are the
        strips' photos, strip after strip, each in flight order.
    control : ControlPoints
        Control (full, plan, height) and check points in ``crs``.
    crs : str
        The control CRS as given ("local" for the local ENU frame).
    truth : SimulationTruth
        True geometry of the whole block, photos in ``observations.photo_ids``
        order; ``heading_deg`` is the block's (the first strip's).
    """

    preset: StripPreset
    side_overlap: float
    flight: str
    strips: tuple[BlockStrip, ...]
    observations: ImageObservations
    control: ControlPoints
    crs: str
    truth: SimulationTruth

    @property
    def strip_photo_ids(self) -> tuple[tuple[str, ...], ...]:
        """Each strip's photo ids in flight order."""
        return tuple(s.photo_ids for s in self.strips)

    @property
    def photo_strip(self) -> IntArray:
        """Index into ``strips`` of each photo of ``observations.photo_ids``, shape (M,)."""
        return np.repeat(
            np.arange(len(self.strips)), [len(s.photo_ids) for s in self.strips]
        ).astype(np.intp)

    def common_points(self, first: int, second: int) -> tuple[str, ...]:
        """Ids of the points observed on photos of both strips (indices into ``strips``)."""
        seen = self._seen()
        both = seen[first] & seen[second]
        ids = np.asarray(self.observations.point_ids, dtype=object)
        return tuple(ids[both].tolist())

    def _seen(self) -> np.ndarray:
        """(strips, points) bool: the point is observed on a photo of the strip."""
        obs = self.observations
        seen = np.zeros((len(self.strips), obs.n_points), dtype=bool)
        seen[self.photo_strip[obs.photo], obs.point] = True
        return seen

    def write_project(
        self,
        directory: str | Path,
        *,
        block: str = "models",
        models: str | None = None,
        polynomial: int | str | None = None,
        route: str | None = None,
        name: str | None = None,
    ) -> Path:
        """Write ``strip.toml`` (``[[strips]]``), ``image_points.csv`` and ``control.csv``.

        The files follow the project format (docs/project-file.md,
        ``[[strips]]``). Existing files of those names in ``directory`` are
        overwritten; the folder is created if needed.

        Parameters
        ----------
        directory : str or Path
            Output folder.
        block : {"strips", "models"}
            ``[adjustment] block``.
        models : {"dependent", "independent"}, optional
            ``[adjustment] models``; omitted (the tool's default) when None.
        polynomial : {0, 1, 2, 3, "auto"}, optional
            ``[adjustment] polynomial``; omitted when None.
        route : {"geocentric", "projected"}, optional
            ``[adjustment] route``; omitted when None. Only "projected" is
            valid with ``crs = "local"``.
        name : str, optional
            Description in the file's first comment line; default describes
            the simulation.

        Returns
        -------
        Path
            Path of ``strip.toml``.

        Raises
        ------
        ValueError
            For a bad ``block``, ``models``, ``polynomial`` or ``route``.
        """
        if name is None:
            m = len(self.strips[0].photo_ids)
            name = (
                f"Simulated {self.preset.name} block, {len(self.strips)} strips x {m} photos, "
                f"{round(100 * self.side_overlap)} % side overlap, {self.flight} flight"
            )
        return write_block_project(
            directory,
            [(s.name, s.photo_ids) for s in self.strips],
            self.observations,
            self.control,
            self.crs,
            name=name,
            block=block,
            models=models,
            polynomial=polynomial,
            route=route,
        )


def simulate_block(
    n_strips: int = 3,
    n_photos_per_strip: int = 8,
    *,
    preset: str | StripPreset = "film",
    side_overlap: float = 0.3,
    flight: str = "serpentine",
    crs: str = "EPSG:32634",
    centre_lonlat: tuple[float, float] | None = None,
    heading_deg: float = 75.0,
    seed: int = 0,
    image_noise_mm: float | None = None,
    control: str = "perimeter",
    control_every: int = 3,
    control_noise_m: float | None = None,
    n_check: int | None = None,
    side_points_per_zone: int = 2,
    systematic_k1: float = 0.0,
    film_shrink_y: float = 1.0,
    camera_errors: Mapping[str, float] | None = None,
    image_blunders: int = 0,
    image_blunder_mm: float | None = None,
    control_blunders: int = 0,
    control_blunder_m: tuple[float, float] = (0.5, 2.0),
    **overrides: object,
) -> SimulatedBlock:
    """Simulate a block of parallel strips of vertical photos with a known truth.

    Length: two dozen documented parameters; the code is the flight's steps
    in order (strips, photos, points, images, control, blunders).

    Parameters
    ----------
    n_strips : int
        Number of strips (>= 2).
    n_photos_per_strip : int
        Photos per strip M (>= 2).
    preset : {"film", "drone"} or StripPreset
        Physical parameters of every strip (see :data:`PRESETS`); a preset
        with a straight road (``line``) is refused: roads are for strips.
    side_overlap : float
        Planned side overlap of adjacent strips, a fraction in [0.2, 0.6].
    flight : {"serpentine", "same"}
        "serpentine": every other strip flown the other way; "same": all
        strips along ``heading_deg``.
    crs, centre_lonlat, seed, image_noise_mm, control_noise_m, n_check
        As for :func:`~strip_aerotri.simulate.simulate_strip` (the block's
        centre; equal arguments give equal blocks).
    heading_deg : float
        Azimuth of the first strip's flight, degrees clockwise from north.
    control : {"perimeter", "corners", "ends", "every_k_models", "dense", "fig4", "weak"}
        Control layout (module notes): a block layout, or a strip layout
        applied to every strip.
    control_every : int
        Spacing in stations (bases) of the perimeter's full points and
        height chains, or of a strip layout's "every_k_models" points.
    side_points_per_zone : int
        Common points per station in every side overlap (>= 1).
    systematic_k1, film_shrink_y, camera_errors
        Errors of the images not modelled by a plain adjustment, as for
        :func:`~strip_aerotri.simulate.simulate_strip`.
    image_blunders, image_blunder_mm, control_blunders, control_blunder_m
        Gross errors, as for :func:`~strip_aerotri.simulate.simulate_strip`
        (rows in ``truth.blunder_observations`` and ``truth.blunder_control``).
    **overrides
        Any :class:`StripPreset` field except ``name``.

    Returns
    -------
    SimulatedBlock

    Raises
    ------
    ValueError
        For bad arguments, unknown overrides, or a block in which too few
        points are seen or two adjacent strips share fewer than 3 points.

    Examples
    --------
    >>> block = simulate_block(3, 6, seed=1)
    >>> block.strip_photo_ids[1][:2]
    ('S2_01', 'S2_02')
    >>> block.strips[1].reversed, block.strips[1].heading_deg
    (True, 255.0)
    >>> len(block.common_points(0, 1)) >= 3 * 5
    True
    """
    n, m = (
        _check_count("n_strips", n_strips),
        _check_count("n_photos_per_strip", n_photos_per_strip),
    )
    side_overlap = _check_block_arguments(side_overlap, flight, control, side_points_per_zone)
    pre, errors = _preset_and_errors(
        preset,
        dict(overrides),
        _Arguments(
            crs, heading_deg, systematic_k1, film_shrink_y, control_every, n_check, camera_errors
        ),
        image_noise_mm,
        control_noise_m,
    )
    if pre.line:
        raise ValueError(
            f"preset {pre.name!r} has a straight road (line=True); a block has none: "
            "give a preset without one or line=False"
        )

    rng = np.random.default_rng(seed)
    geo = _Geodesy.build(crs, centre_lonlat, pre.terrain_height_m)
    terrain = _Terrain.random(rng, pre)
    lay = _Layout.plan(pre, n, m, side_overlap, flight, heading_deg)

    centre_plan, centres, rotations, opk = _photos(rng, geo, pre, lay)
    points = _points(rng, geo, terrain, pre, lay, centres, rotations, int(side_points_per_zone))

    ground = points.ground
    reach = _projection_reach(
        pre,
        geo,
        opk,
        centre_plan[:, 2],
        ground,
        centres,
        systematic_k1,
        film_shrink_y,
        margin=1.0 if errors is None else 1.05,
    )
    pairs = _block_pairs(
        ground, centres, rotations, pre, lay, reach, (systematic_k1, film_shrink_y, errors)
    )
    keep = _seen_twice(pairs[1], ground.shape[0])
    # Number the kept points strip by strip and side overlap by side overlap
    # (bands across the block), along the block's heading.
    kept = np.flatnonzero(keep)
    band = np.rint(2.0 * (points.cross[kept] - lay.offsets[0]) / lay.spacing)
    kept = kept[np.lexsort((points.along[kept], band))]
    photo_names = np.asarray(lay.photo_names)
    observations, kept = _observe(rng, pre, pairs, keep, kept, photo_names, min_width=5)
    _check_side_overlaps(observations, lay)

    points_local = ground[kept]
    points_crs = geo.local2crs(points_local)
    roles, check = _block_roles(points, kept, lay, pre, control, int(control_every))
    control_points = _control_points(
        rng,
        geo,
        pre,
        observations.point_ids,
        points_local,
        points_crs,
        roles,
        check,
        n_check,
    )

    observations, control_points, truth = _with_blunders_and_truth(
        _Blunders(seed, image_blunders, image_blunder_mm, control_blunders, control_blunder_m),
        observations,
        control_points,
        pre,
        geo,
        centres,
        rotations,
        (points_local, points_crs),
        heading_deg,
    )
    strips = tuple(
        BlockStrip(
            name=lay.strip_names[s],
            photo_ids=tuple(lay.photo_names[s * m : (s + 1) * m]),
            heading_deg=(float(heading_deg) + (180.0 if lay.reversed[s] else 0.0)) % 360.0,
            reversed=bool(lay.reversed[s]),
            offset_m=float(lay.offsets[s]),
            photo_centres_local=_frozen(centres[s * m : (s + 1) * m]),
            photo_rotations_local=_frozen(rotations[s * m : (s + 1) * m]),
        )
        for s in range(n)
    )
    return SimulatedBlock(
        preset=pre,
        side_overlap=side_overlap,
        flight=flight,
        strips=strips,
        observations=observations,
        control=control_points,
        crs=crs,
        truth=truth,
    )


def _block_pairs(
    ground: FloatArray,
    centres: FloatArray,
    rotations: FloatArray,
    pre: StripPreset,
    lay: _Layout,
    reach: float,
    camera: tuple[float, float, FloatArray | None],
) -> tuple[IntArray, IntArray, FloatArray]:
    """Collinearity and visibility, strip by strip: the (photo, point, xy)
    of every point a photo sees; each strip's photos see only the points
    within ``reach`` across the flight of its axis.  ``camera``: the
    simulated radial distortion, film shrinkage and camera errors."""
    systematic_k1, film_shrink_y, errors = camera
    right_local = np.array([lay.right[0], lay.right[1], 0.0])
    ahead_local = np.array([lay.ahead[0], lay.ahead[1], 0.0])
    point_cross = ground @ right_local
    n, m = len(lay.strip_names), centres.shape[0] // len(lay.strip_names)
    pairs = []
    for s in range(n):
        rows = slice(s * m, (s + 1) * m)
        if math.isfinite(reach):
            photo_cross = centres[rows] @ right_local
            near = (point_cross >= photo_cross.min() - reach) & (
                point_cross <= photo_cross.max() + reach
            )
            candidates = np.flatnonzero(near)
        else:
            candidates = np.arange(ground.shape[0])
        photo, point, xy = _visible_pairs(
            ground[candidates],
            centres[rows],
            rotations[rows],
            pre,
            reach,
            ahead_local,
            systematic_k1,
            film_shrink_y,
            errors,
        )
        pairs.append((photo + s * m, candidates[point], xy))
    return (
        np.concatenate([p[0] for p in pairs]),
        np.concatenate([p[1] for p in pairs]),
        np.concatenate([p[2] for p in pairs]),
    )


def _check_block_arguments(
    side_overlap: float, flight: str, control: str, side_points_per_zone: int
) -> float:
    """The arguments only a block has, checked; the side overlap as a float."""
    side_overlap = float(side_overlap)
    if not _SIDE_OVERLAP[0] <= side_overlap <= _SIDE_OVERLAP[1]:
        raise ValueError(
            f"Expected `side_overlap` within {list(_SIDE_OVERLAP)}, got {side_overlap!r}"
        )
    if flight not in _FLIGHTS:
        raise ValueError(f"Expected `flight` to be one of {_FLIGHTS}, got {flight!r}")
    layouts = _BLOCK_LAYOUTS + _CONTROL_LAYOUTS
    if control not in layouts:
        raise ValueError(f"Expected `control` to be one of {layouts}, got {control!r}")
    if isinstance(side_points_per_zone, bool) or int(side_points_per_zone) < 1:
        raise ValueError(f"Expected `side_points_per_zone` >= 1, got {side_points_per_zone!r}")
    return side_overlap


def _check_count(name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2:
        raise ValueError(f"Expected `{name}` to be an integer >= 2, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class _Layout:
    """The planned block: strips, stations and photo order (plan metres)."""

    n: int
    m: int
    heading: float  # radians, the block's
    ahead: FloatArray  # plan (east, north) unit vector along the heading
    right: FloatArray  # plan unit vector to the right of the heading
    base: float  # m
    spacing: float  # m between strip axes
    stations: FloatArray  # (m,) planned nadirs along the heading, m
    offsets: FloatArray  # (n,) strip axes to the right of the centre line, m
    reversed: np.ndarray  # (n,) bool
    photo_strip: IntArray  # (n*m,) strip of each block photo
    photo_station: IntArray  # (n*m,) station of each block photo
    strip_names: tuple[str, ...]
    photo_names: tuple[str, ...]

    @classmethod
    def plan(
        cls, pre: StripPreset, n: int, m: int, side_overlap: float, flight: str, heading_deg: float
    ) -> _Layout:
        heading = math.radians(float(heading_deg))
        spacing = (1.0 - side_overlap) * pre.format_mm[1] * pre.scale_m_per_mm
        reversed_ = (np.arange(n) % 2 == 1) & (flight == "serpentine")
        j = np.arange(m)
        station = np.where(reversed_[:, None], m - 1 - j, j).ravel()
        strip_names = tuple(f"S{s + 1:0{len(str(n))}d}" for s in range(n))
        width = max(2, len(str(m)))
        photo_names = tuple(f"{name}_{k + 1:0{width}d}" for name in strip_names for k in range(m))
        return cls(
            n=n,
            m=m,
            heading=heading,
            ahead=np.array([math.sin(heading), math.cos(heading)]),
            right=np.array([math.cos(heading), -math.sin(heading)]),
            base=pre.base_m,
            spacing=spacing,
            stations=np.asarray((j - 0.5 * (m - 1)) * pre.base_m, dtype=np.float64),
            offsets=np.asarray((np.arange(n) - 0.5 * (n - 1)) * spacing, dtype=np.float64),
            reversed=reversed_,
            photo_strip=np.repeat(np.arange(n), m),
            photo_station=station,
            strip_names=strip_names,
            photo_names=photo_names,
        )

    def photo_at(self, strip: IntArray, station: IntArray) -> IntArray:
        """Block photo index of a strip's photo at a station."""
        j = np.where(self.reversed[strip], self.m - 1 - station, station)
        return strip * self.m + j


def _photos(
    rng: np.random.Generator, geo: _Geodesy, pre: StripPreset, lay: _Layout
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Photo centres (plan with heights, and local) and rotations of the block.

    As in a strip: centres wander about the planned nadirs, omega, phi and
    kappa about each strip's own heading are truncated normals. Returns
    plan (N, 3), local centres (N, 3), rotations (N, 3, 3), opk (N, 3).
    """
    count = lay.n * lay.m
    w = pre.position_wander_m
    along = lay.stations[lay.photo_station] + rng.uniform(-w, w, count)
    across = lay.offsets[lay.photo_strip] + rng.uniform(-w, w, count)
    centre_plan, centres, opk, tilt = _attitudes_about(
        rng, geo, pre, along[:, None] * lay.ahead + across[:, None] * lay.right
    )
    swing = math.pi / 2.0 - lay.heading - math.pi * lay.reversed[lay.photo_strip]
    cos, sin = np.cos(swing), np.sin(swing)
    zero, one = np.zeros(count), np.ones(count)
    rz = np.stack(
        [
            np.stack([cos, -sin, zero], axis=-1),
            np.stack([sin, cos, zero], axis=-1),
            np.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )
    rotations = tilt @ rz @ _matrix_from_opk(opk)
    return centre_plan, centres, rotations, opk


@dataclass(frozen=True)
class _Points:
    """Every simulated ground point of the block, before visibility."""

    ground: FloatArray  # (P, 3) local ENU, m
    along: FloatArray  # (P,) planned plan position along the heading, m
    cross: FloatArray  # (P,) to the right of the heading, m
    kind: IntArray  # _GRUBER, _EXTRA or _SIDE
    strip: IntArray  # owner strip (the left strip of a side overlap)
    nadir: IntArray  # photo index in the owner's flight order (zones), else -1
    station: IntArray  # station of the zone, else -1
    row: IntArray  # Gruber row (zones of a strip), else -1
    lane: IntArray  # Gruber row s * rows + r, side overlap n * rows + s; else -1
    rank: IntArray  # rank in its zone, else -1


def _points(
    rng: np.random.Generator,
    geo: _Geodesy,
    terrain: _Terrain,
    pre: StripPreset,
    lay: _Layout,
    centres: FloatArray,
    rotations: FloatArray,
    per_side_zone: int,
) -> _Points:
    """Gruber zones and model points of each strip, and side-overlap zones."""
    n, m, c = lay.n, lay.m, pre.principal_distance_mm
    zone_x = np.concatenate(
        [
            _triple_overlap_centre_x(
                geo, terrain, centres[s * m : (s + 1) * m], rotations[s * m : (s + 1) * m], c
            )
            for s in range(n)
        ]
    )
    spread = pre.gruber_spread_mm

    # Gruber zones of every photo, as in a strip.
    gy = np.asarray(pre.gruber_y_mm, dtype=np.float64)
    n_rows, per_zone = gy.size, pre.gruber_points_per_zone
    g_photo = np.repeat(np.arange(n * m), n_rows * per_zone)
    g_row = np.tile(np.repeat(np.arange(n_rows), per_zone), n * m)
    g_rank = np.tile(np.arange(per_zone), n * m * n_rows)
    k_g = g_photo.size
    g_xy = np.column_stack(
        [
            zone_x[g_photo] + rng.uniform(-spread, spread, k_g),
            gy[g_row] + rng.uniform(-spread, spread, k_g),
        ]
    )

    # Side-overlap zones: at each station, on the left strip's photo, at the
    # middle of the side overlap (image y to the right of that photo's flight).
    s_strip = np.repeat(np.arange(n - 1), m * per_side_zone)
    s_station = np.tile(np.repeat(np.arange(m), per_side_zone), n - 1)
    s_rank = np.tile(np.arange(per_side_zone), (n - 1) * m)
    s_photo = lay.photo_at(s_strip, s_station)
    k_s = s_photo.size
    middle_mm = 0.5 * lay.spacing / pre.scale_m_per_mm
    band_mm = pre.format_mm[1] - 2.0 * middle_mm  # side overlap width in the image
    s_spread = min(spread, 0.25 * band_mm)
    s_xy = np.column_stack(
        [
            zone_x[s_photo] + rng.uniform(-spread, spread, k_s),
            np.where(lay.reversed[s_strip], middle_mm, -middle_mm)
            + rng.uniform(-s_spread, s_spread, k_s),
        ]
    )
    zone_plan = _image2terrain_plan(
        geo,
        terrain,
        centres,
        rotations,
        np.concatenate([g_photo, s_photo]),
        np.vstack([g_xy, s_xy]),
        c,
    )

    # Random points per model of each strip, over the strip's width.
    per_model = pre.extra_points_per_photo
    k_e = n * (m - 1) * per_model
    e_strip = np.repeat(np.arange(n), (m - 1) * per_model)
    e_model = np.tile(np.repeat(np.arange(m - 1), per_model), n)
    half_width = 0.45 * pre.format_mm[1] * pre.scale_m_per_mm
    e_along = lay.stations[e_model] + rng.uniform(0.0, lay.base, k_e)
    e_across = lay.offsets[e_strip] + rng.uniform(-half_width, half_width, k_e)
    e_plan = e_along[:, None] * lay.ahead + e_across[:, None] * lay.right

    plan = np.vstack([zone_plan, e_plan])
    ground = geo.plan2local(np.column_stack([plan, terrain.height(plan)]))
    g_strip = lay.photo_strip[g_photo]
    none_e = np.full(k_e, -1)
    return _Points(
        ground=ground,
        along=plan @ lay.ahead,
        cross=plan @ lay.right,
        kind=np.concatenate([np.full(k_g, _GRUBER), np.full(k_s, _SIDE), np.full(k_e, _EXTRA)]),
        strip=np.concatenate([g_strip, s_strip, e_strip]),
        nadir=np.concatenate([g_photo - g_strip * m, s_photo - s_strip * m, none_e]),
        station=np.concatenate([lay.photo_station[g_photo], s_station, none_e]),
        row=np.concatenate([g_row, np.full(k_s, -1), none_e]),
        lane=np.concatenate([g_strip * n_rows + g_row, n * n_rows + s_strip, none_e]),
        rank=np.concatenate([g_rank, s_rank, none_e]),
    )


def _check_side_overlaps(observations: ImageObservations, lay: _Layout) -> None:
    """Every pair of adjacent strips must share at least 3 observed points."""
    seen = np.zeros((lay.n, observations.n_points), dtype=bool)
    seen[lay.photo_strip[observations.photo], observations.point] = True
    common = (seen[:-1] & seen[1:]).sum(axis=1)
    for s in np.flatnonzero(common < 3):
        raise ValueError(
            f"Strips {lay.strip_names[s]} and {lay.strip_names[s + 1]} share only "
            f"{int(common[s])} observed point(s); check `side_overlap` and the attitudes"
        )


def _block_roles(
    points: _Points,
    kept: IntArray,
    lay: _Layout,
    pre: StripPreset,
    layout: str,
    every: int,
) -> tuple[dict[int, ControlType], list[int]]:
    """Control roles and check candidates, as indices into the kept points."""
    kind, station = points.kind[kept], points.station[kept]
    zones = np.flatnonzero((kind == _GRUBER) | (kind == _SIDE))
    roles: dict[int, ControlType] = {}
    last = lay.m - 1
    if layout in _BLOCK_LAYOUTS:
        zone_point = _zone_points(zones, station, points.lane[kept], points.rank[kept])

        def assign(stations: list[int], lanes: list[int], role: ControlType) -> None:
            for t in stations:
                for lane in lanes:
                    p = zone_point.get((t, lane))
                    if p is not None and p not in roles:
                        roles[p] = role

        gy = np.asarray(pre.gruber_y_mm, dtype=np.float64)
        n_rows = gy.size
        sides = [lay.n * n_rows + s for s in range(lay.n - 1)]
        outer = [sides[0], sides[-1]]  # without Gruber rows: the outer side overlaps
        if n_rows:
            # Plan position of each Gruber row across the block: image y is to
            # the left of each strip's own flight.
            sign = np.where(lay.reversed, 1.0, -1.0)
            cross = lay.offsets[:, None] + sign[:, None] * gy[None, :] * pre.scale_m_per_mm
            outer = [int(np.argmin(cross[0])), (lay.n - 1) * n_rows + int(np.argmax(cross[-1]))]
        if layout == "perimeter":
            assign(sorted({*range(0, lay.m, every), last}), outer, ControlType.FULL)
            assign([0, last], sides, ControlType.FULL)
            assign(list(range(every, last, every)), sides, ControlType.HEIGHT)
        else:  # "corners"
            assign([0, last], outer, ControlType.FULL)
            assign([last // 2], outer + sides, ControlType.HEIGHT)
    else:
        strip = points.strip[kept]
        gruber = np.flatnonzero(kind == _GRUBER)
        for s in range(lay.n):
            own = gruber[strip[gruber] == s]
            zone_point = _zone_points(own, points.nadir[kept], points.row[kept], points.rank[kept])
            _strip_roles(zone_point, pre.gruber_y_mm, lay.m, layout, every, roles)
    check = [int(p) for p in zones if int(p) not in roles and 0 < station[p] < last]
    return roles, check
