"""Terrain, attitudes and imaging of the simulator: where points are, which
photos see them and at which image coordinates."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._typing import FloatArray, IntArray
from ._geodesy import _ecef2enu_matrix, _Geodesy
from .cameras import StripPreset

if TYPE_CHECKING:
    pass

# Point kinds, internal.
_GRUBER, _EXTRA, _LINE = 0, 1, 2


@dataclass(frozen=True)
class _Terrain:
    """Smooth random terrain: a sum of plane waves, |h - mean| <= amplitude."""

    mean: float
    amplitude: float
    wave: FloatArray  # (K, 2) wave vectors, rad/m
    phase: FloatArray  # (K,)
    weight: FloatArray  # (K,), sum 1

    @classmethod
    def random(cls, rng: np.random.Generator, preset: StripPreset, n_waves: int = 6) -> _Terrain:
        direction = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        wavelength = preset.relief_wavelength_m * rng.uniform(0.5, 1.5, n_waves)
        k = 2.0 * np.pi / wavelength
        wave = np.column_stack([k * np.cos(direction), k * np.sin(direction)])
        phase = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        weight = rng.uniform(0.5, 1.0, n_waves)
        return cls(preset.terrain_height_m, preset.relief_m, wave, phase, weight / weight.sum())

    def height(self, plan: FloatArray) -> FloatArray:
        """Ellipsoidal height (N,) at plan (east, north) (N, 2), metres."""
        heights: FloatArray = self.mean + self.amplitude * (
            np.cos(plan @ self.wave.T + self.phase) @ self.weight
        )
        return heights


def _projection_reach(
    pre: StripPreset,
    geo: _Geodesy,
    opk: FloatArray,
    camera_h: FloatArray,
    ground: FloatArray,
    centres: FloatArray,
    systematic_k1: float,
    film_shrink_y: float,
    margin: float = 1.0,
) -> float:
    """Distance (m) beyond which no photo can see a point; inf when unknown.

    ``margin`` (>= 1) enlarges the format's half-diagonal (for camera errors
    that move points into the format).

    A point seen inside the format lies on a ray within ``theta = atan(r / c)
    + tilt`` of the photo's vertical (``r`` the half-diagonal of the format
    before the systematic errors, ``tilt`` the largest angle of a camera axis
    from its own vertical); on the terrain it is no lower than
    ``terrain_height_m - relief_m``. On a sphere of the ellipsoid's smallest
    radius of curvature (the surface falls away fastest), the ray from the
    highest camera at ``theta`` meets that height at the distance returned
    (with 1 % and 10 m to spare), unless it comes back up beyond the far root;
    so the bound holds when the whole strip is shorter than that root. Radial
    distortion ``k1 < 0`` can bring far points into the format: no bound then.
    """
    if systematic_k1 < 0:
        return math.inf
    c = pre.principal_distance_mm
    half = margin * math.hypot(0.5 * pre.format_mm[0], 0.5 * pre.format_mm[1] / film_shrink_y)
    cam_tilt = float(np.arccos(np.clip(np.cos(opk[:, 0]) * np.cos(opk[:, 1]), -1.0, 1.0)).max())
    theta = math.atan(half / c) + cam_tilt
    if theta >= math.radians(85.0):
        return math.inf
    a, rf = geo.ellipsoid
    e2 = (2.0 - 1.0 / rf) / rf
    radius = a * (1.0 - e2)  # meridian radius at the equator: the smallest
    r_cam = radius + float(camera_h.max())
    r_low = radius + pre.terrain_height_m - pre.relief_m
    cos_t = math.cos(theta)
    disc = (r_cam * cos_t) ** 2 - (r_cam**2 - r_low**2)
    if r_low <= 0 or disc <= 0:
        return math.inf
    near, far = r_cam * cos_t - math.sqrt(disc), r_cam * cos_t + math.sqrt(disc)
    low = np.minimum(ground.min(axis=0), centres.min(axis=0))
    high = np.maximum(ground.max(axis=0), centres.max(axis=0))
    if float(np.linalg.norm(high - low)) >= far:
        return math.inf
    return 1.01 * near + 10.0


def _visible_pairs(
    ground: FloatArray,
    centres: FloatArray,
    rotations: FloatArray,
    pre: StripPreset,
    reach: float,
    ahead: FloatArray,
    systematic_k1: float,
    film_shrink_y: float,
    camera_errors: FloatArray | None = None,
) -> tuple[IntArray, IntArray, FloatArray]:
    """The (photo, point) pairs in which a point is seen, with its image xy.

    Each point (P, 3) is projected into the photos (M) whose centres lie within
    ``reach`` metres of it along the unit vector ``ahead`` (a distance along
    one direction never exceeds the distance itself). Returns photo and point
    indices, shape (K,), and image x, y in mm, shape (K, 2), of the pairs in
    which the point is in front of the camera and inside the format.
    ``camera_errors`` (10,) are the Brown/Fraser corrections
    (:func:`with_camera_errors`) that the measured coordinates need.
    """
    n_points = ground.shape[0]
    if math.isfinite(reach):
        photo_along = centres @ ahead
        by_along = np.argsort(photo_along, kind="stable")
        sorted_along = photo_along[by_along]
        point_along = ground @ ahead
        lo = np.searchsorted(sorted_along, point_along - reach, side="left")
        hi = np.searchsorted(sorted_along, point_along + reach, side="right")
        count = hi - lo
        pair_point = np.repeat(np.arange(n_points), count)
        offset = np.arange(pair_point.size) - np.repeat(np.cumsum(count) - count, count)
        pair_photo = by_along[np.repeat(lo, count) + offset]
    else:
        pair_photo = np.repeat(np.arange(centres.shape[0]), n_points)
        pair_point = np.tile(np.arange(n_points), centres.shape[0])
    # v = R.T (X - S), summed in the order of einsum("mji,mpj->mpi")
    d = ground[pair_point] - centres[pair_photo]
    rot = rotations[pair_photo]
    v = (rot[:, 0, :] * d[:, 0:1] + rot[:, 1, :] * d[:, 1:2]) + rot[:, 2, :] * d[:, 2:3]
    c = pre.principal_distance_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        x = -c * v[:, 0] / v[:, 2]
        y = -c * v[:, 1] / v[:, 2]
    radial = 1.0 + systematic_k1 * (x * x + y * y)
    x = x * radial
    y = y * radial * film_shrink_y
    if camera_errors is not None:
        x, y = with_camera_errors(x, y, camera_errors, c)
    visible = (
        (v[:, 2] < 0.0)
        & (np.abs(x) <= 0.5 * pre.format_mm[0])
        & (np.abs(y) <= 0.5 * pre.format_mm[1])
    )
    return pair_photo[visible], pair_point[visible], np.column_stack([x[visible], y[visible]])


def camera_error_values(errors: Mapping[str, float] | None) -> FloatArray | None:
    """Brown/Fraser values by name -> the (10,) vector (None for none or all zero)."""
    from ..geometry.camera_model import BROWN_PARAMETERS

    if not errors:
        return None
    unknown = sorted(set(errors) - set(BROWN_PARAMETERS))
    if unknown:
        raise ValueError(f"Unknown camera error(s) {unknown}; expected {BROWN_PARAMETERS}")
    values = np.array([float(errors.get(n, 0.0)) for n in BROWN_PARAMETERS])
    if not np.all(np.isfinite(values)):
        raise ValueError("Expected finite camera errors")
    return values if np.any(values) else None


def with_camera_errors(
    x: FloatArray, y: FloatArray, values: FloatArray, c_mm: float
) -> tuple[FloatArray, FloatArray]:
    """Measured coordinates m whose Brown/Fraser correction takes them to the
    ideal (x, y): ``m + Δ(m; values) = ideal`` (fixed-point iteration, exact to
    1e-12 mm for errors of a few hundred µm), NaN where the ideal is NaN."""
    from ..geometry.camera_model import brown_correction

    ideal = np.column_stack([x, y])
    good = np.all(np.isfinite(ideal), axis=1)
    m = ideal.copy()
    for _ in range(30):
        step = ideal[good] - brown_correction(m[good], values, c_mm) - m[good]
        m[good] += step
        if not step.size or float(np.max(np.abs(step))) < 1e-12:
            break
    return m[:, 0], m[:, 1]


def _matrix_from_opk(opk: FloatArray) -> FloatArray:
    """Rx(omega) Ry(phi) Rz(kappa), radians, (..., 3) -> (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    matrices: FloatArray = (
        Rotation.from_euler("XYZ", opk.reshape(-1, 3)).as_matrix().reshape(*opk.shape, 3)
    )
    return matrices


def _rz(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _truncated_normal(
    rng: np.random.Generator, sigma: float, shape: tuple[int, ...], limit: float = 2.0
) -> FloatArray:
    """N(0, sigma) truncated at ``limit`` sigma (values beyond are redrawn)."""
    out = rng.normal(0.0, sigma, shape)
    bad = np.abs(out) > limit * sigma
    while bad.any():
        out[bad] = rng.normal(0.0, sigma, int(bad.sum()))
        bad = np.abs(out) > limit * sigma
    return out


def _frozen(a: FloatArray) -> FloatArray:
    out = np.array(a, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _triple_overlap_centre_x(
    geo: _Geodesy, terrain: _Terrain, centres: FloatArray, rotations: FloatArray, c: float
) -> FloatArray:
    """Image x (mm) on each photo midway between its neighbours' principal points.

    That is the middle of the triple overlap along the flight, where the
    Gruber tie zones belong; 0 for the first and last photo. Shape (M,).
    """
    m = centres.shape[0]
    out = np.zeros(m)
    if m < 3:
        return out
    photo = np.arange(m)
    plan = _image2terrain_plan(geo, terrain, centres, rotations, photo, np.zeros((m, 2)), c)
    ground = geo.plan2local(np.column_stack([plan, terrain.height(plan)]))
    inner = photo[1:-1]
    v_prev = np.einsum("nji,nj->ni", rotations[inner], ground[inner - 1] - centres[inner])
    v_next = np.einsum("nji,nj->ni", rotations[inner], ground[inner + 1] - centres[inner])
    out[inner] = -0.5 * c * (v_prev[:, 0] / v_prev[:, 2] + v_next[:, 0] / v_next[:, 2])
    return out


def _image2terrain_plan(
    geo: _Geodesy,
    terrain: _Terrain,
    centres: FloatArray,
    rotations: FloatArray,
    photo: IntArray,
    xy: FloatArray,
    c: float,
) -> FloatArray:
    """Plan (east, north) where image rays of the given photos meet the terrain.

    Fixed-point iteration along each ray on the ellipsoidal height; it
    contracts by about (terrain slope) x (ray inclination), well below 1 for
    the presets' smooth terrain. Returns shape (N, 2).
    """
    rays = np.einsum("nij,nj->ni", rotations[photo], np.column_stack([xy, np.full(len(xy), -c)]))
    start = centres[photo]
    t = -start[:, 2] / rays[:, 2]  # to the local frame's origin height
    for _ in range(12):
        enh = geo.local2plan(start + t[:, None] * rays)
        t = t + (terrain.height(enh[:, :2]) - enh[:, 2]) / rays[:, 2]
    return geo.local2plan(start + t[:, None] * rays)[:, :2]


def _road_points(
    geo: _Geodesy, terrain: _Terrain, pre: StripPreset, heading: float, along: FloatArray
) -> FloatArray:
    """Points exactly on one vertical plane of the local frame, on the terrain.

    The plane contains the local up axis direction; its trace in plan is a
    straight line at ``line_angle_deg`` to the heading, offset across the
    strip by ``line_offset_mm`` at image scale. Heights are solved so that
    each point lies on the terrain (ellipsoidal height = terrain height).
    """
    k = pre.line_points_per_model
    az = heading + math.radians(pre.line_angle_deg)
    direction = np.array([math.sin(az), math.cos(az), 0.0])
    offset = (
        pre.line_offset_mm
        * pre.scale_m_per_mm
        * np.array([-math.cos(heading), math.sin(heading), 0.0])
    )
    steps = ((np.arange(k) + 0.5) / k) * pre.base_m
    s = (along[:-1, None] + steps[None, :]).ravel()
    enu: FloatArray = offset + s[:, None] * direction
    for _ in range(5):  # dh/dU ~ 1: converges to far below a micrometre
        enh = geo.local2plan(enu)
        enu[:, 2] += terrain.height(enh[:, :2]) - enh[:, 2]
    return enu


def _attitudes_about(
    rng: np.random.Generator, geo: _Geodesy, pre: StripPreset, plan_xy: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Photos over the plan positions ``plan_xy`` (N, 2): the flying height
    wandering, ω and φ, κ as truncated normals.  Returns the centres in plan
    with heights (N, 3), in the local frame (N, 3), ω-φ-κ (N, 3, radians)
    and the rotations (N, 3, 3) from each centre's east-north-up to the
    local frame."""
    count = plan_xy.shape[0]
    hw = pre.height_wander_m
    centre_plan = np.column_stack(
        [plan_xy, pre.terrain_height_m + pre.flying_height_m + rng.uniform(-hw, hw, count)]
    )
    centres = geo.plan2local(centre_plan)
    opk = np.column_stack(
        [
            _truncated_normal(rng, math.radians(pre.attitude_sigma_deg), (count, 2)),
            _truncated_normal(rng, math.radians(pre.kappa_sigma_deg), (count, 1)),
        ]
    )
    llh = geo.local2geodetic(centres)
    tilt = geo.frame.ecef2enu @ np.swapaxes(_ecef2enu_matrix(llh[:, 0], llh[:, 1]), -1, -2)
    return centre_plan, centres, opk, tilt
