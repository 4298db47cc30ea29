"""Control layouts and gross errors of the simulator."""

from __future__ import annotations

import dataclasses

import numpy as np

from .._typing import FloatArray, IntArray
from ..observations import ControlPoints, ControlType, ImageObservations
from ._geodesy import _Geodesy
from ._scene import _GRUBER
from .cameras import StripPreset

_CONTROL_LAYOUTS = ("ends", "every_k_models", "dense", "fig4", "weak")


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
    gruber = np.flatnonzero(kind == _GRUBER)
    roles = _strip_roles(
        _zone_points(gruber, nadir, row, rank), pre.gruber_y_mm, m, layout, every, {}
    )
    last = m - 1
    check = [int(p) for p in gruber if int(p) not in roles and 0 < nadir[p] < last]
    return _control_points(
        rng, geo, pre, point_ids, points_local, points_crs, roles, check, n_check
    )


def _zone_points(
    points: IntArray, nadir: IntArray, row: IntArray, rank: IntArray
) -> dict[tuple[int, int], int]:
    """The first seen point (lowest rank) of each zone (nadir, row) among ``points``."""
    zone_point: dict[tuple[int, int], int] = {}
    for p in points[np.lexsort((rank[points], row[points], nadir[points]))]:
        zone_point.setdefault((int(nadir[p]), int(row[p])), int(p))
    return zone_point


def _strip_roles(
    zone_point: dict[tuple[int, int], int],
    gruber_y_mm: tuple[float, ...],
    m: int,
    layout: str,
    every: int,
    roles: dict[int, ControlType],
) -> dict[int, ControlType]:
    """Add the roles of a strip layout (module notes of ``strip``) to ``roles``.

    ``zone_point`` maps (nadir, Gruber row) to a point; a point that already
    has a role keeps it. Returns ``roles``.
    """
    gy = np.asarray(gruber_y_mm, dtype=np.float64)
    sides = sorted({int(np.argmax(gy)), int(np.argmin(gy))}) if gy.size else []
    axis_row = int(np.argmin(np.abs(gy))) if gy.size else -1

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
    return roles


def _control_points(
    rng: np.random.Generator,
    geo: _Geodesy,
    pre: StripPreset,
    point_ids: tuple[str, ...],
    points_local: FloatArray,
    points_crs: FloatArray,
    roles: dict[int, ControlType],
    check: list[int],
    n_check: int | None,
) -> ControlPoints:
    """Control with ``roles`` and check points among ``check`` (all, or
    ``n_check`` of them at random), sorted by point id.

    Control is the truth plus N(0, ``control_noise_m``) per coordinate in
    the local frame; check points carry the exact truth.
    """
    roles = dict(roles)
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


def _blunders(
    rng: np.random.Generator,
    observations: ImageObservations,
    control: ControlPoints,
    pre: StripPreset,
    n_image: int,
    size_mm: float | None,
    n_control: int,
    size_m: tuple[float, float],
) -> tuple[ImageObservations, ControlPoints, tuple[int, ...], tuple[int, ...]]:
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
