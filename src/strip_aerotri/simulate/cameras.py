"""Cameras and the physical parameters of a simulated flight.

:class:`StripPreset` holds every physical parameter of a simulated strip
(camera, flight, terrain, attitudes, points, noise); :data:`PRESETS` names
three of them and :func:`camera_preset` derives a consistent one from a
camera of :data:`CAMERAS` and a flight. Blocks use the same parameters for
each of their strips.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, NamedTuple

from ..options import DEFAULT_LINE_WEIGHT

__all__ = ["CAMERAS", "PRESETS", "Camera", "StripPreset", "camera_preset"]


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
    line_weight: float = DEFAULT_LINE_WEIGHT
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
    pixel_um = cam.pixel_size_um
    noise = (5.0 if pixel_um is None else 0.7 * pixel_um) if noise_um is None else float(noise_um)
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


def _resolve_preset(preset: str | StripPreset, overrides: dict[str, Any]) -> StripPreset:
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
