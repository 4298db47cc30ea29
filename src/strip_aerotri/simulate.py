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

import csv
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ._typing import ArrayLike, FloatArray, IntArray
from .observations import ControlPoints, ControlType, ImageObservations

if TYPE_CHECKING:
    from pyproj import CRS, Transformer

__all__ = [
    "CAMERAS",
    "PRESETS",
    "Camera",
    "LocalFrame",
    "SimulatedStrip",
    "SimulationTruth",
    "StripPreset",
    "camera_preset",
    "simulate_strip",
]

_LOCAL = "local"
_WGS84 = (6378137.0, 298.257223563)  # semi-major axis (m), inverse flattening
_DEFAULT_LOCAL_CENTRE = (21.0, 52.0)  # lon, lat (deg) used when crs = "local"
_CONTROL_LAYOUTS = ("ends", "every_k_models", "dense", "fig4", "weak")
_ROUTES = ("geocentric", "projected")
_POLYNOMIALS = (0, 1, 2, 3, "auto")

# Point kinds, internal.
_GRUBER, _EXTRA, _LINE = 0, 1, 2


@dataclass(frozen=True)
class StripPreset:
    """Every physical parameter of a simulated strip.

    Attributes
    ----------
    name : str
        Preset name.
    principal_distance_mm : float
        c in mm.
    format_mm : tuple of float
        Image format (along the flight x, across the flight y) in mm.
    flying_height_m : float
        Flying height above the mean terrain in metres.
    forward_overlap : float
        Forward overlap as a fraction (0.6 = 60 %); must be > 0.5 so that
        consecutive models share a triple overlap.
    terrain_height_m : float
        Mean ellipsoidal height of the terrain in metres.
    relief_m : float
        Amplitude of the smooth random terrain in metres (heights stay within
        ``terrain_height_m ± relief_m``).
    relief_wavelength_m : float
        Typical wavelength of the terrain undulations in metres.
    attitude_sigma_deg : float
        Standard deviation of omega and phi in degrees.
    kappa_sigma_deg : float
        Standard deviation of kappa about the heading in degrees.
    position_wander_m : float
        Photo centres wander uniformly within ± this, along and across the
        flight line, in metres.
    height_wander_m : float
        Photo heights wander uniformly within ± this, in metres.
    gruber_y_mm : tuple of float
        Image-scale y of the Gruber rows at each nadir in mm (left positive).
    gruber_points_per_zone : int
        Points per Gruber zone.
    gruber_spread_mm : float
        Points of a zone spread uniformly within ± this (x and y) in mm at
        image scale.
    extra_points_per_photo : int
        Random points per model (photo base) over the model area.
    image_noise_mm : float
        Standard deviation of the image coordinate noise in mm.
    control_noise_m : float
        Standard deviation of the control coordinate noise in metres.
    line : bool
        Whether to simulate a straight road along the strip.
    line_offset_mm : float
        Image-scale y offset of the road from the strip axis in mm.
    line_angle_deg : float
        Angle of the road against the heading in degrees.
    line_points_per_model : int
        Road points per model.
    line_weight : float
        Weight of the straight-line condition (J: about 100).
    pixel_size_um : float or None
        Pixel size of a digital camera (None for film); for reports only.
    """

    name: str
    principal_distance_mm: float
    format_mm: tuple[float, float]
    flying_height_m: float
    forward_overlap: float
    terrain_height_m: float
    relief_m: float
    relief_wavelength_m: float
    attitude_sigma_deg: float
    kappa_sigma_deg: float
    position_wander_m: float
    height_wander_m: float
    gruber_y_mm: tuple[float, ...]
    gruber_points_per_zone: int
    gruber_spread_mm: float
    extra_points_per_photo: int
    image_noise_mm: float
    control_noise_m: float
    line: bool = False
    line_offset_mm: float = -35.0
    line_angle_deg: float = 0.3
    line_points_per_model: int = 2
    line_weight: float = 100.0
    pixel_size_um: float | None = None

    @property
    def scale_m_per_mm(self) -> float:
        """Ground metres per image millimetre at the mean terrain."""
        return self.flying_height_m / self.principal_distance_mm

    @property
    def base_m(self) -> float:
        """Planned air base in metres."""
        return (1.0 - self.forward_overlap) * self.format_mm[0] * self.scale_m_per_mm


_FILM = StripPreset(
    name="film",
    principal_distance_mm=152.87,  # wide-angle film camera (RC/RMK class)
    format_mm=(230.0, 230.0),
    flying_height_m=152.87 * 8.0,  # photo scale 1:8000 -> 1222.96 m
    forward_overlap=0.60,
    terrain_height_m=150.0,
    relief_m=0.05 * 152.87 * 8.0,  # ~5 % of the flying height
    relief_wavelength_m=2500.0,
    attitude_sigma_deg=1.5,
    kappa_sigma_deg=2.0,
    position_wander_m=10.0,
    height_wander_m=10.0,
    gruber_y_mm=(75.0, 0.0, -75.0),
    gruber_points_per_zone=2,
    gruber_spread_mm=5.0,
    extra_points_per_photo=6,
    image_noise_mm=0.005,
    control_noise_m=0.02,
)

_DRONE = StripPreset(
    name="drone",
    principal_distance_mm=8.8,  # 1" sensor, 13.2 x 8.8 mm, long side across
    format_mm=(8.8, 13.2),
    flying_height_m=120.0,
    forward_overlap=0.80,
    terrain_height_m=150.0,
    relief_m=6.0,
    relief_wavelength_m=300.0,
    attitude_sigma_deg=3.0,
    kappa_sigma_deg=3.0,
    position_wander_m=2.0,
    height_wander_m=2.0,
    gruber_y_mm=(4.5, 0.0, -4.5),
    gruber_points_per_zone=1,
    gruber_spread_mm=0.3,
    extra_points_per_photo=4,  # with the Gruber points: ~30 points on each photo
    image_noise_mm=0.0015,  # ~0.6 pixel of 2.4 µm
    control_noise_m=0.01,
    line_offset_mm=-2.0,
)

#: Named presets: "film" (1:8000 wide-angle film, 60 % overlap), "drone"
#: (1" sensor at 120 m, 80 % overlap), "corridor" (film with a straight road).
PRESETS: Mapping[str, StripPreset] = MappingProxyType(
    {
        "film": _FILM,
        "drone": _DRONE,
        "corridor": dataclasses.replace(_FILM, name="corridor", line=True),
    }
)


class Camera(NamedTuple):
    """A camera of :data:`CAMERAS`: principal distance and format in mm,
    pixel size in um (None for film)."""

    principal_distance_mm: float
    format_long_mm: float
    format_short_mm: float
    pixel_size_um: float | None


#: Typical cameras of aerial projects: super-wide, wide and normal angle
#: film (230 x 230 mm), and the sensors of mapping drones.
CAMERAS: Mapping[str, Camera] = MappingProxyType(
    {
        "film88": Camera(88.5, 230.0, 230.0, None),  # super-wide angle film camera
        "film152": Camera(152.87, 230.0, 230.0, None),  # wide angle (RC30, RMK TOP 15 class)
        "film210": Camera(210.0, 230.0, 230.0, None),  # normal angle film camera
        "ff35": Camera(35.0, 36.0, 24.0, 4.4),  # full frame, 35 mm lens
        "apsc16": Camera(16.0, 23.5, 15.6, 3.9),  # APS-C, 16 mm lens
        "oneinch": Camera(8.8, 13.2, 8.8, 2.4),  # 1-inch sensor (Phantom 4 Pro class)
    }
)


def camera_preset(
    camera: str | Camera = "film152",
    *,
    long_side: str = "along",
    forward_overlap: float = 0.6,
    flying_height_m: float | None = None,
    tilt_deg: float = 1.5,
    kappa_deg: float = 2.0,
    relief_m: float | None = None,
    noise_um: float | None = None,
    line: bool = False,
) -> StripPreset:
    """A consistent :class:`StripPreset` for a camera and a flight.

    Parameters
    ----------
    camera : str or Camera
        A name of :data:`CAMERAS` or a Camera.
    long_side : {"along", "across"}
        Whether the format's long side runs along the flight or across it.
    forward_overlap : float
        Fraction, 0.5-0.95.
    flying_height_m : float, optional
        Above the mean terrain; default a photo scale of 1:8000 for film,
        120 m for drone cameras.
    tilt_deg, kappa_deg : float
        Standard deviations of omega and phi, and of kappa about the heading.
    relief_m : float, optional
        Default 5 % of the flying height.
    noise_um : float, optional
        Image noise; default 5 um on film, 0.7 pixel on sensors.
    line : bool
        A straight road along the strip (straight-line points).

    Returns
    -------
    StripPreset
        Gruber rows at 0 and about a third of the format across the flight
        from the axis, two points per zone, and enough random points per
        model that every pair shares 25-40 points (sensors) or 15-30 (film).
    """
    cam = CAMERAS[camera] if isinstance(camera, str) else camera
    if long_side not in ("along", "across"):
        raise ValueError(f'Expected `long_side` "along" or "across", got {long_side!r}')
    c = float(cam.principal_distance_mm)
    fmt = (
        (cam.format_long_mm, cam.format_short_mm)
        if long_side == "along"
        else (cam.format_short_mm, cam.format_long_mm)
    )
    film = cam.pixel_size_um is None
    height = (
        float(flying_height_m) if flying_height_m is not None else (8.0 * c if film else 120.0)
    )
    scale = height / c  # m per mm
    base = (1.0 - forward_overlap) * fmt[0] * scale
    relief = 0.05 * height if relief_m is None else float(relief_m)
    noise = (5.0 if film else 0.7 * cam.pixel_size_um) if noise_um is None else float(noise_um)
    gy = 0.33 * fmt[1]
    return StripPreset(
        name=f"{camera if isinstance(camera, str) else 'camera'}-{long_side}",
        principal_distance_mm=c,
        format_mm=fmt,
        flying_height_m=height,
        forward_overlap=float(forward_overlap),
        terrain_height_m=150.0,
        relief_m=relief,
        relief_wavelength_m=max(8.0 * base, 20.0 * relief),
        attitude_sigma_deg=float(tilt_deg),
        kappa_sigma_deg=float(kappa_deg),
        position_wander_m=0.02 * height,
        height_wander_m=0.02 * height,
        gruber_y_mm=(gy, 0.0, -gy),
        gruber_points_per_zone=2,
        gruber_spread_mm=0.04 * fmt[1],
        extra_points_per_photo=10 if film else 18,
        image_noise_mm=noise / 1000.0,
        control_noise_m=max(0.005, 0.25 * noise / 1000.0 * scale),
        line=bool(line),
        line_offset_mm=-0.15 * fmt[1],
        pixel_size_um=cam.pixel_size_um,
    )


class LocalFrame(NamedTuple):
    """The local ENU tangent frame of a simulation, in geocentric terms.

    ``local = ecef2enu @ (ecef - origin_ecef)`` (rows: east, north, up unit
    vectors in ECEF), both in metres on the datum of the simulation's CRS.

    Attributes
    ----------
    origin_ecef : ndarray, shape (3,)
        Geocentric coordinates of the origin in metres.
    ecef2enu : ndarray, shape (3, 3)
        Rotation ECEF -> local ENU.
    """

    origin_ecef: FloatArray
    ecef2enu: FloatArray

    def ecef2local(self, xyz: ArrayLike) -> FloatArray:
        """Geocentric (N, 3) m -> local ENU (N, 3) m."""
        xyz = np.asarray(xyz, dtype=np.float64)
        return (xyz - self.origin_ecef) @ self.ecef2enu.T

    def local2ecef(self, enu: ArrayLike) -> FloatArray:
        """Local ENU (N, 3) m -> geocentric (N, 3) m."""
        enu = np.asarray(enu, dtype=np.float64)
        return enu @ self.ecef2enu + self.origin_ecef


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

        The files follow the project format (formats.md). Existing files of
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
        from pyproj import CRS

        if polynomial is not None and (
            isinstance(polynomial, bool) or polynomial not in _POLYNOMIALS
        ):
            raise ValueError(
                f"Expected `polynomial` to be one of {_POLYNOMIALS}, got {polynomial!r}"
            )
        if route is not None and route not in _ROUTES:
            raise ValueError(f"Expected `route` to be one of {_ROUTES} or None, got {route!r}")
        if route == "geocentric" and self.crs == _LOCAL:
            raise ValueError('`route="geocentric"` needs a real CRS, not crs="local"')
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        obs = self.observations
        if name is None:
            name = f"Simulated {self.preset.name} strip, {obs.n_photos} photos"

        lines = [
            "# Simulated strip (strip_aerotri.simulate); truth is not in these files.",
            "[strip]",
            f"name = {_toml_str(name)}",
            f"photos = {_toml_list(obs.photo_ids)}",
            "",
            "[camera]",
            f"principal_distance_mm = {obs.principal_distance!r}",
            "",
            "[images]",
            'file = "image_points.csv"',
            "",
            "[control]",
            'file = "control.csv"',
            f"crs = {_toml_str(self.crs)}",
        ]
        for ids, weight in self.lines:
            lines += ["", "[[straight_line]]", f"points = {_toml_list(ids)}"]
            lines.append(f"weight = {float(weight)!r}")
        lines += ["", "[adjustment]"]
        if route is not None:
            lines.append(f"route = {_toml_str(route)}")
        if polynomial is not None:
            poly = _toml_str(polynomial) if isinstance(polynomial, str) else str(polynomial)
            lines.append(f"polynomial = {poly}")
        toml_path = directory / "strip.toml"
        toml_path.write_text("\n".join(lines) + "\n", encoding="utf-8")

        with (directory / "image_points.csv").open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(["photo", "point", "x", "y", "sigma"])
            photo_names = np.asarray(obs.photo_ids, dtype=object)[obs.photo]
            point_names = np.asarray(obs.point_ids, dtype=object)[obs.point]
            writer.writerows(
                [p, q, f"{x:.6f}", f"{y:.6f}", f"{s:.6f}"]
                for p, q, (x, y), s in zip(
                    photo_names, point_names, obs.xy.tolist(), obs.sigma.tolist(), strict=True
                )
            )

        geographic = self.crs != _LOCAL and CRS.from_user_input(self.crs).is_geographic
        xy_fmt = "{:.10f}" if geographic else "{:.4f}"
        ctrl = self.control
        with (directory / "control.csv").open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(["point", "X", "Y", "H", "type", "sigma_xy", "sigma_h"])
            for pid, (x, y, h), kind, sxy, sh in zip(
                ctrl.point_ids,
                ctrl.xyz.tolist(),
                ctrl.kind,
                ctrl.sigma_xy.tolist(),
                ctrl.sigma_h.tolist(),
                strict=True,
            ):
                writer.writerow(
                    [
                        pid,
                        "" if math.isnan(x) else xy_fmt.format(x),
                        "" if math.isnan(y) else xy_fmt.format(y),
                        "" if math.isnan(h) else f"{h:.4f}",
                        kind.value,
                        f"{sxy:.4f}",
                        f"{sh:.4f}",
                    ]
                )
        return toml_path


# ----------------------------------------------------------------------------
# TOML writing helpers (tomllib only reads)


def _toml_str(text: str) -> str:
    """A TOML basic string."""
    out = []
    for ch in str(text):
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_list(items: tuple[str, ...]) -> str:
    return "[" + ", ".join(_toml_str(s) for s in items) + "]"


# ----------------------------------------------------------------------------
# Geodesy (pyproj), private


def _ecef2enu_matrix(lon_deg: ArrayLike, lat_deg: ArrayLike) -> FloatArray:
    """Rotation(s) ECEF -> ENU at geodetic longitude/latitude, shape (..., 3, 3)."""
    lam = np.radians(np.asarray(lon_deg, dtype=np.float64))
    phi = np.radians(np.asarray(lat_deg, dtype=np.float64))
    sl, cl, sp, cp = np.sin(lam), np.cos(lam), np.sin(phi), np.cos(phi)
    zero = np.zeros_like(sl)
    return np.stack(
        [
            np.stack([-sl, cl, zero], axis=-1),
            np.stack([-sp * cl, -sp * sl, cp], axis=-1),
            np.stack([cp * cl, cp * sl, sp], axis=-1),
        ],
        axis=-2,
    )


@dataclass(frozen=True)
class _Geodesy:
    """Transformers between plan (tmerc), geodetic, geocentric, local and CRS."""

    crs: CRS | None
    ellipsoid: tuple[float, float]
    centre_lonlat: tuple[float, float]
    plan2ecef: Transformer  # tmerc (e, n, h) <-> ECEF
    ecef2geodetic: Transformer  # ECEF <-> lon, lat (deg), h
    geodetic2crs: Transformer | None  # lon, lat (deg) <-> CRS X, Y
    frame: LocalFrame

    @classmethod
    def build(cls, crs_text: str, centre_lonlat: tuple[float, float] | None, h0: float):
        from pyproj import CRS, Transformer

        if crs_text == _LOCAL:
            crs = None
            ellipsoid = _WGS84
            geodetic2crs = None
            centre = _DEFAULT_LOCAL_CENTRE if centre_lonlat is None else centre_lonlat
        else:
            try:
                crs = CRS.from_user_input(crs_text)
            except Exception as exc:  # pyproj raises CRSError
                raise ValueError(
                    f"Expected `crs` to be a CRS pyproj knows, got {crs_text!r}"
                ) from exc
            if not (crs.is_projected or crs.is_geographic) or crs.is_compound:
                raise ValueError(
                    "Expected `crs` to be a horizontal projected or geographic CRS, "
                    f"got {crs_text!r}"
                )
            ell = crs.ellipsoid
            ellipsoid = (float(ell.semi_major_metre), float(ell.inverse_flattening))
            geodetic2crs = Transformer.from_crs(crs.geodetic_crs, crs, always_xy=True)
            centre = _area_centre(crs) if centre_lonlat is None else centre_lonlat
        lon0, lat0 = (float(v) for v in centre)
        if not (-180.0 <= lon0 <= 360.0 and -89.0 <= lat0 <= 89.0):
            raise ValueError(
                f"Expected `centre_lonlat` within longitude [-180, 360] and latitude "
                f"[-89, 89] degrees, got {centre!r}"
            )
        a, rf = ellipsoid
        ell_txt = f"+a={a!r} +rf={rf!r}"
        plan2ecef = Transformer.from_pipeline(
            f"+proj=pipeline +step +inv +proj=tmerc +lat_0={lat0!r} +lon_0={lon0!r} +k=1 "
            f"+x_0=0 +y_0=0 {ell_txt} +step +proj=cart {ell_txt}"
        )
        ecef2geodetic = Transformer.from_pipeline(
            f"+proj=pipeline +step +inv +proj=cart {ell_txt} "
            "+step +proj=unitconvert +xy_in=rad +xy_out=deg"
        )
        ox, oy, oz = ecef2geodetic.transform(lon0, lat0, h0, direction="INVERSE")
        frame = LocalFrame(
            origin_ecef=np.array([ox, oy, oz], dtype=np.float64),
            ecef2enu=_ecef2enu_matrix(lon0, lat0),
        )
        return cls(crs, ellipsoid, (lon0, lat0), plan2ecef, ecef2geodetic, geodetic2crs, frame)

    def plan2local(self, enh: FloatArray) -> FloatArray:
        """Plan (tmerc east, north) + ellipsoidal height (N, 3) -> local ENU (N, 3)."""
        x, y, z = self.plan2ecef.transform(enh[:, 0], enh[:, 1], enh[:, 2])
        return self.frame.ecef2local(np.column_stack([x, y, z]))

    def local2plan(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> plan (tmerc east, north) + ellipsoidal height (N, 3)."""
        ecef = self.frame.local2ecef(enu)
        e, n, h = self.plan2ecef.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2], direction="INVERSE")
        return np.column_stack([e, n, h])

    def local2geodetic(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> longitude, latitude (deg), ellipsoidal height (m)."""
        ecef = self.frame.local2ecef(enu)
        lon, lat, h = self.ecef2geodetic.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lon, lat, h])

    def local2crs(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> CRS X, Y (always_xy) and ellipsoidal height H."""
        if self.geodetic2crs is None:
            return np.array(enu, dtype=np.float64, copy=True)
        llh = self.local2geodetic(enu)
        x, y = self.geodetic2crs.transform(llh[:, 0], llh[:, 1])
        return np.column_stack([x, y, llh[:, 2]])


def _area_centre(crs: CRS) -> tuple[float, float]:
    """Centre (lon, lat) of a CRS's area of use, in degrees."""
    area = crs.area_of_use
    if area is None:
        raise ValueError(f"CRS {crs.name!r} has no area of use: give `centre_lonlat`")
    west, south, east, north = area.bounds
    if east < west:  # crosses the antimeridian
        east += 360.0
    lon = 0.5 * (west + east)
    if lon > 180.0:
        lon -= 360.0
    return lon, 0.5 * (south + north)


# ----------------------------------------------------------------------------
# Terrain and attitudes


@dataclass(frozen=True)
class _Terrain:
    """Smooth random terrain: a sum of plane waves, |h - mean| <= amplitude."""

    mean: float
    amplitude: float
    wave: FloatArray  # (K, 2) wave vectors, rad/m
    phase: FloatArray  # (K,)
    weight: FloatArray  # (K,), sum 1

    @classmethod
    def random(cls, rng: np.random.Generator, preset: StripPreset, n_waves: int = 6):
        direction = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        wavelength = preset.relief_wavelength_m * rng.uniform(0.5, 1.5, n_waves)
        k = 2.0 * np.pi / wavelength
        wave = np.column_stack([k * np.cos(direction), k * np.sin(direction)])
        phase = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        weight = rng.uniform(0.5, 1.0, n_waves)
        return cls(preset.terrain_height_m, preset.relief_m, wave, phase, weight / weight.sum())

    def height(self, plan: FloatArray) -> FloatArray:
        """Ellipsoidal height (N,) at plan (east, north) (N, 2), metres."""
        return self.mean + self.amplitude * (np.cos(plan @ self.wave.T + self.phase) @ self.weight)


def _projection_reach(
    pre: StripPreset,
    geo: _Geodesy,
    opk: FloatArray,
    camera_h: FloatArray,
    ground: FloatArray,
    centres: FloatArray,
    systematic_k1: float,
    film_shrink_y: float,
) -> float:
    """Distance (m) beyond which no photo can see a point; inf when unknown.

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
    half = math.hypot(0.5 * pre.format_mm[0], 0.5 * pre.format_mm[1] / film_shrink_y)
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
) -> tuple[IntArray, IntArray, FloatArray]:
    """The (photo, point) pairs in which a point is seen, with its image xy.

    Each point (P, 3) is projected into the photos (M) whose centres lie within
    ``reach`` metres of it along the unit vector ``ahead`` (a distance along
    one direction never exceeds the distance itself). Returns photo and point
    indices, shape (K,), and image x, y in mm, shape (K, 2), of the pairs in
    which the point is in front of the camera and inside the format.
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
    visible = (
        (v[:, 2] < 0.0)
        & (np.abs(x) <= 0.5 * pre.format_mm[0])
        & (np.abs(y) <= 0.5 * pre.format_mm[1])
    )
    return pair_photo[visible], pair_point[visible], np.column_stack([x[visible], y[visible]])


def _matrix_from_opk(opk: FloatArray) -> FloatArray:
    """Rx(omega) Ry(phi) Rz(kappa), radians, (..., 3) -> (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("XYZ", opk.reshape(-1, 3)).as_matrix().reshape(*opk.shape, 3)


def _rz(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ----------------------------------------------------------------------------
# The simulator


def _resolve_preset(preset: str | StripPreset, overrides: dict) -> StripPreset:
    if isinstance(preset, StripPreset):
        base = preset
    elif isinstance(preset, str) and preset in PRESETS:
        base = PRESETS[preset]
    else:
        raise ValueError(
            f"Expected `preset` to be one of {sorted(PRESETS)} or a StripPreset, got {preset!r}"
        )
    names = {f.name for f in dataclasses.fields(StripPreset)} - {"name"}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise ValueError(
            f"Unknown simulation parameter(s) {unknown}; valid overrides are {sorted(names)}"
        )
    out = dataclasses.replace(base, **overrides) if overrides else base
    checks = [
        ("principal_distance_mm", out.principal_distance_mm > 0),
        ("format_mm", len(out.format_mm) == 2 and min(out.format_mm) > 0),
        ("flying_height_m", out.flying_height_m > 0),
        ("forward_overlap", 0.5 < out.forward_overlap < 1.0),
        ("relief_m", out.relief_m >= 0 and out.relief_m < out.flying_height_m),
        ("relief_wavelength_m", out.relief_wavelength_m > 0),
        ("gruber_points_per_zone", out.gruber_points_per_zone >= 0),
        ("extra_points_per_photo", out.extra_points_per_photo >= 0),
        ("line_points_per_model", out.line_points_per_model >= 0),
        ("image_noise_mm", out.image_noise_mm >= 0),
        ("control_noise_m", out.control_noise_m >= 0),
    ]
    for key, ok in checks:
        if not ok:
            raise ValueError(f"Invalid simulation parameter {key}={getattr(out, key)!r}")
    return out


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
    image_blunders: int = 0,
    image_blunder_mm: float | None = None,
    control_blunders: int = 0,
    control_blunder_m: tuple[float, float] = (0.5, 2.0),
    **overrides: object,
) -> SimulatedStrip:
    """Simulate one strip of vertical photos with a known truth.

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
        0.005 mm.
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
    image_blunders : int
        Observations of points seen on three or more photos given a gross
        error: a shift in a random direction of ``image_blunder_mm`` (default
        15-40 times the image noise, at least 0.05 mm); their rows are in
        ``truth.blunder_observations``.
    image_blunder_mm : float, optional
    control_blunders : int
        Control rows (full, plan or height) given a gross error of one given
        coordinate, a random size in ``control_blunder_m`` with a random
        sign; their rows are in ``truth.blunder_control``.
    control_blunder_m : (float, float)
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
    if int(control_every) < 1:
        raise ValueError(f"Expected `control_every` >= 1, got {control_every!r}")
    if n_check is not None and int(n_check) < 0:
        raise ValueError(f"Expected `n_check` >= 0 or None, got {n_check!r}")
    if not isinstance(crs, str):
        raise ValueError(f"Expected `crs` to be a string, got {type(crs).__name__}")
    if not (math.isfinite(heading_deg) and math.isfinite(systematic_k1)) or film_shrink_y <= 0:
        raise ValueError("Expected finite `heading_deg`, `systematic_k1` and `film_shrink_y` > 0")
    extra: dict[str, object] = dict(overrides)
    if image_noise_mm is not None:
        extra["image_noise_mm"] = float(image_noise_mm)
    if control_noise_m is not None:
        extra["control_noise_m"] = float(control_noise_m)
    if line is not None:
        extra["line"] = bool(line)
    pre = _resolve_preset(preset, extra)

    m = int(n_photos)
    rng = np.random.default_rng(seed)
    geo = _Geodesy.build(crs, centre_lonlat, pre.terrain_height_m)
    terrain = _Terrain.random(rng, pre)

    heading = math.radians(float(heading_deg))
    ahead = np.array([math.sin(heading), math.cos(heading)])  # plan (east, north)
    left = np.array([-math.cos(heading), math.sin(heading)])
    scale = pre.scale_m_per_mm
    base = pre.base_m
    along = (np.arange(m) - 0.5 * (m - 1)) * base  # planned nadirs, metres

    # Photo centres and rotations.
    w, hw = pre.position_wander_m, pre.height_wander_m
    d_along = along + rng.uniform(-w, w, m)
    d_across = rng.uniform(-w, w, m)
    centre_plan = np.column_stack(
        [
            d_along[:, None] * ahead + d_across[:, None] * left,
            pre.terrain_height_m + pre.flying_height_m + rng.uniform(-hw, hw, m),
        ]
    )
    centres = geo.plan2local(centre_plan)
    opk = np.column_stack(
        [
            _truncated_normal(rng, math.radians(pre.attitude_sigma_deg), (m, 2)),
            _truncated_normal(rng, math.radians(pre.kappa_sigma_deg), (m, 1)),
        ]
    )
    llh = geo.local2geodetic(centres)
    tilt = geo.frame.ecef2enu @ np.swapaxes(_ecef2enu_matrix(llh[:, 0], llh[:, 1]), -1, -2)
    rotations = tilt @ _rz(math.pi / 2.0 - heading) @ _matrix_from_opk(opk)

    # Ground points: Gruber zones picked on each photo's image near its
    # principal point (so they lie in the triple overlap whatever the photo's
    # tilt), then random points per model.
    c = pre.principal_distance_mm
    n_rows, per_zone = len(pre.gruber_y_mm), pre.gruber_points_per_zone
    zone_nadir = np.repeat(np.arange(m), n_rows * per_zone)
    zone_row = np.tile(np.repeat(np.arange(n_rows), per_zone), m)
    zone_rank = np.tile(np.arange(per_zone), m * n_rows)
    spread = pre.gruber_spread_mm
    k_g = zone_nadir.size
    zone_x = _triple_overlap_centre_x(geo, terrain, centres, rotations, c)
    zone_xy = np.column_stack(
        [
            zone_x[zone_nadir] + rng.uniform(-spread, spread, k_g),
            np.asarray(pre.gruber_y_mm, dtype=np.float64)[zone_row]
            + rng.uniform(-spread, spread, k_g),
        ]
    )
    g_plan = _image2terrain_plan(geo, terrain, centres, rotations, zone_nadir, zone_xy, c)
    n_extra = pre.extra_points_per_photo * (m - 1)
    half_width = 0.45 * pre.format_mm[1] * scale
    e_model = np.repeat(np.arange(m - 1), pre.extra_points_per_photo)
    e_along = along[e_model] + rng.uniform(0.0, base, n_extra)
    e_across = rng.uniform(-half_width, half_width, n_extra)
    e_plan = e_along[:, None] * ahead + e_across[:, None] * left
    plan = np.vstack([g_plan, e_plan])
    ground = geo.plan2local(np.column_stack([plan, terrain.height(plan)]))
    kind = np.concatenate([np.full(k_g, _GRUBER), np.full(n_extra, _EXTRA)])
    nadir = np.concatenate([zone_nadir, np.full(n_extra, -1)])
    row = np.concatenate([zone_row, np.full(n_extra, -1)])
    rank = np.concatenate([zone_rank, np.full(n_extra, -1)])

    if pre.line and pre.line_points_per_model > 0:
        road = _road_points(geo, terrain, pre, heading, along)
        ground = np.vstack([ground, road])
        n_road = road.shape[0]
        kind = np.concatenate([kind, np.full(n_road, _LINE)])
        nadir, row, rank = (np.concatenate([a, np.full(n_road, -1)]) for a in (nadir, row, rank))

    # Collinearity and visibility, each point only in the photos that can
    # reach it (a dense (photos, points) projection is quadratic in the strip).
    ahead_local = np.array([ahead[0], ahead[1], 0.0])
    reach = _projection_reach(
        pre, geo, opk, centre_plan[:, 2], ground, centres, systematic_k1, film_shrink_y
    )
    pair_photo, pair_point, pair_xy = _visible_pairs(
        ground, centres, rotations, pre, reach, ahead_local, systematic_k1, film_shrink_y
    )
    keep = np.bincount(pair_point, minlength=ground.shape[0]) >= 2
    if keep.sum() < 3:
        raise ValueError("Too few points are seen on two or more photos; check the parameters")

    # Number the kept points along the flight.
    kept = np.flatnonzero(keep)
    kept = kept[np.argsort(ground[kept] @ ahead_local, kind="stable")]
    width = max(4, len(str(kept.size)))
    point_names = np.char.add("P", np.char.zfill(np.arange(1, kept.size + 1).astype(str), width))
    photo_names = np.arange(1001, 1001 + m).astype(str)

    # Observations photo by photo, each photo's points in numbering order.
    number = np.full(ground.shape[0], -1)
    number[kept] = np.arange(kept.size)
    seen = keep[pair_point]
    obs_photo, obs_point, xy = pair_photo[seen], number[pair_point[seen]], pair_xy[seen]
    order = np.lexsort((obs_point, obs_photo))
    obs_photo, obs_point, xy = obs_photo[order], obs_point[order], xy[order]
    if pre.image_noise_mm > 0:
        xy = xy + rng.normal(0.0, pre.image_noise_mm, xy.shape)
    sigma = pre.image_noise_mm if pre.image_noise_mm > 0 else 0.005
    observations = ImageObservations.from_ids(
        photo_names[obs_photo],
        point_names[obs_point],
        xy,
        c,
        photo_ids=photo_names,
        sigma=sigma,
    )
    # ``from_ids`` orders points by id; the ids (sorted, zero-padded) were
    # assigned in ``kept`` order.
    kept = kept[np.searchsorted(point_names, np.asarray(observations.point_ids))]

    points_local = ground[kept]
    points_crs = geo.local2crs(points_local)

    control_points = _control(
        rng,
        geo,
        pre,
        observations.point_ids,
        points_local,
        points_crs,
        kind=kind[kept],
        nadir=nadir[kept],
        row=row[kept],
        rank=rank[kept],
        m=m,
        layout=control,
        every=int(control_every),
        n_check=n_check,
    )

    line_ids = tuple(
        p for p, k in zip(observations.point_ids, kind[kept], strict=True) if k == _LINE
    )
    lines = ((line_ids, float(pre.line_weight)),) if len(line_ids) >= 3 else ()

    blunder_obs: tuple[int, ...] = ()
    blunder_ctrl: tuple[int, ...] = ()
    if image_blunders or control_blunders:
        observations, control_points, blunder_obs, blunder_ctrl = _blunders(
            np.random.default_rng([seed, 7]),
            observations,
            control_points,
            pre,
            int(image_blunders),
            image_blunder_mm,
            int(control_blunders),
            control_blunder_m,
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
    return SimulatedStrip(
        preset=pre,
        observations=observations,
        control=control_points,
        crs=crs,
        lines=lines,
        truth=truth,
    )


def _blunders(rng, observations, control, pre, n_image, size_mm, n_control, size_m):
    """Gross errors added to the observations and the control (module notes);
    returns both and the rows changed."""
    obs = observations
    rays = np.bincount(obs.point, minlength=obs.n_points)
    candidates = np.flatnonzero(rays[obs.point] >= 3)
    rows = np.sort(rng.choice(candidates, size=min(n_image, candidates.size), replace=False))
    if size_mm is None:
        size = np.maximum(0.05, pre.image_noise_mm * rng.uniform(15.0, 40.0, rows.size))
    else:
        size = np.full(rows.size, float(size_mm))
    angle = rng.uniform(0.0, 2.0 * np.pi, rows.size)
    xy = obs.xy.copy()
    xy[rows] += size[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    kinds = np.array([k.value for k in control.kind])
    used = np.flatnonzero(kinds != "check")
    bad = np.sort(rng.choice(used, size=min(n_control, used.size), replace=False))
    xyz = np.array(control.xyz, dtype=np.float64, copy=True)
    lo, hi = size_m
    for row in bad:
        given = np.flatnonzero(np.isfinite(xyz[row]))
        xyz[row, rng.choice(given)] += rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi)
    return (
        dataclasses.replace(obs, xy=xy),
        dataclasses.replace(control, xyz=xyz),
        tuple(int(r) for r in rows),
        tuple(int(r) for r in bad),
    )


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
    enu = offset + s[:, None] * direction
    for _ in range(5):  # dh/dU ~ 1: converges to far below a micrometre
        enh = geo.local2plan(enu)
        enu[:, 2] += terrain.height(enh[:, :2]) - enh[:, 2]
    return enu


def _control(
    rng: np.random.Generator,
    geo: _Geodesy,
    pre: StripPreset,
    point_ids: tuple[str, ...],
    points_local: FloatArray,
    points_crs: FloatArray,
    *,
    kind: IntArray,
    nadir: IntArray,
    row: IntArray,
    rank: IntArray,
    m: int,
    layout: str,
    every: int,
    n_check: int | None,
) -> ControlPoints:
    """Pick control and check points among the seen Gruber-zone points."""
    gy = np.asarray(pre.gruber_y_mm, dtype=np.float64)
    sides = sorted({int(np.argmax(gy)), int(np.argmin(gy))}) if gy.size else []
    axis_row = int(np.argmin(np.abs(gy))) if gy.size else -1

    # First seen point (lowest rank) of each Gruber zone.
    zone_point: dict[tuple[int, int], int] = {}
    gruber = np.flatnonzero(kind == _GRUBER)
    for p in gruber[np.lexsort((rank[gruber], row[gruber], nadir[gruber]))]:
        zone_point.setdefault((int(nadir[p]), int(row[p])), int(p))

    roles: dict[int, ControlType] = {}

    def assign(nadirs: list[int], rows: list[int], role: ControlType) -> None:
        for i in nadirs:
            for r in rows:
                p = zone_point.get((i, r))
                if p is not None and p not in roles:
                    roles[p] = role

    last = m - 1
    if layout == "dense":
        assign(list(range(m)), sides, ControlType.FULL)
    elif layout == "every_k_models":
        assign(sorted({*range(0, m, every), last}), sides, ControlType.FULL)
    elif layout == "fig4":
        every_row = list(range(gy.size))
        assign([0, last], every_row, ControlType.FULL)
        assign(list(range(3, last, 3)), sides, ControlType.HEIGHT)
    elif layout == "weak":
        assign([0, last], sides, ControlType.FULL)
        middle = [axis_row] if axis_row >= 0 else sides[:1]
        assign([last // 2], middle, ControlType.HEIGHT)
    else:  # "ends"
        full = sorted({0, last, last // 2})
        assign(full, sides, ControlType.FULL)
        assign([i for i in range(3, last, 3) if i not in full], sides, ControlType.HEIGHT)
        quarter = sorted({round(last / 4), round(3 * last / 4)} - {0, last})
        assign(quarter, [axis_row] if axis_row >= 0 else [], ControlType.PLAN)

    check = [int(p) for p in gruber if int(p) not in roles and 0 < nadir[p] < last]
    if n_check is not None and int(n_check) < len(check):
        check = sorted(rng.choice(check, size=int(n_check), replace=False).tolist())
    for p in check:
        roles[p] = ControlType.CHECK

    index = np.array(sorted(roles, key=lambda p: point_ids[p]), dtype=np.intp)
    n = index.size
    role = [roles[int(p)] for p in index]
    is_control = np.array([r is not ControlType.CHECK for r in role], dtype=bool)
    noisy = np.array(points_local[index], dtype=np.float64, copy=True)
    if pre.control_noise_m > 0 and n:
        noise = rng.normal(0.0, pre.control_noise_m, (n, 3))
        noisy[is_control] += noise[is_control]
    xyz = geo.local2crs(noisy) if n else np.zeros((0, 3))
    xyz[~is_control] = points_crs[index[~is_control]]
    plan_given = np.array(
        [r in (ControlType.FULL, ControlType.PLAN, ControlType.CHECK) for r in role]
    )
    h_given = np.array(
        [r in (ControlType.FULL, ControlType.HEIGHT, ControlType.CHECK) for r in role]
    )
    xyz[~plan_given, :2] = np.nan
    xyz[~h_given, 2] = np.nan
    sigma = pre.control_noise_m if pre.control_noise_m > 0 else 0.01
    return ControlPoints(
        point_ids=tuple(point_ids[p] for p in index),
        xyz=xyz,
        kind=tuple(role),
        sigma_xy=np.full(n, sigma),
        sigma_h=np.full(n, sigma),
        source_line=np.zeros(n, dtype=np.intp),
    )
