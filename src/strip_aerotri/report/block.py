"""The result folder of a block of strips: the tables, ``report.json`` and
``report.html`` (docs/outputs.md, "A block of strips")."""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping, Sequence
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from .._text import shorten
from .._version import __version__
from ..observations import ControlType
from ..results import AccuracyStatistics
from . import json_text
from .aside import aside
from .block_page import block_html
from .calibration import (
    calibration_figures,
    calibration_html,
    calibration_outputs,
    variance_record,
    with_variance_html,
)
from .files import format_photos_csv, format_points_csv
from .record import REPORT_FORMAT, REPORT_FORMAT_VERSION, _bundle_gnss, _bundle_imu
from .tolerances import TRANSFER_UM, transfer_passed
from .values import clean, delivered_points, json_float, options_record, statistics
from .verdict import with_verdict

if TYPE_CHECKING:
    from ..project import Project
    from ..results import BlockResult

__all__ = [
    "JOIN_PLAN_MM",
    "TRANSFER_UM",
    "block_outputs",
    "block_tolerances_record",
    "build_block_outputs",
    "build_block_report",
    "joins_record",
]

JOIN_PLAN_MM = 0.5
"""Mean plan discrepancy of the common points of two strips, mm at the map
scale (R4 1.7.7.7)."""

_ROLE = {
    ControlType.FULL: "control-full",
    ControlType.PLAN: "control-plan",
    ControlType.HEIGHT: "control-height",
    ControlType.CHECK: "check",
}


def _roles_and_strips(result: BlockResult) -> tuple[np.ndarray, np.ndarray]:
    """Each point's role (control kind, ``common`` to two or more strips,
    ``strip`` in one) and the number of strips that determine it."""
    n_strips = np.zeros(result.observations.n_points, dtype=np.int64)
    for strip in result.strips:
        n_strips += np.isfinite(strip.points).all(axis=1)
    roles = np.where(n_strips >= 2, "common", "strip").astype(object)
    lookup = {pid: i for i, pid in enumerate(result.point_ids)}
    for pid, kind in zip(result.control.point_ids, result.control.kind, strict=True):
        i = lookup.get(pid)
        if i is not None:
            roles[i] = _ROLE[ControlType(kind)]
    return roles.astype(str), n_strips


def _residuals(result: BlockResult) -> np.ndarray:
    """dE, dN, dH (given − adjusted) per point, NaN where none."""
    out = np.full((result.observations.n_points, 3), np.nan)
    lookup = {pid: i for i, pid in enumerate(result.point_ids)}
    for row, resid in zip(result.control_index, result.control_residuals, strict=True):
        out[lookup[result.control.point_ids[row]]] = resid
    return out


def _check_rows(result: BlockResult, residuals: np.ndarray) -> AccuracyStatistics:
    """The statistics of ``residuals`` (rows of ``result.control_index``) at
    every check point determined, the weakly determined ones included."""
    return AccuracyStatistics.from_residuals(
        np.asarray(residuals)[np.asarray(result.is_check, dtype=bool)]
    )


def build_block_report(
    result: BlockResult, *, project: Project | None = None, map_scale: float | None = None
) -> dict[str, Any]:
    """Content of a block's ``report.json`` (plain JSON types, NaN as None)."""
    joins = joins_record(result, map_scale)
    created = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    report = {
        "format": REPORT_FORMAT,
        "format_version": REPORT_FORMAT_VERSION,
        "software": {"name": "strip_aerotri", "version": __version__},
        "created": created,
        "created_utc": created,  # the key of a strip's report.json
        "project": {
            "name": None if project is None else project.name,
            "file": None if project is None else str(project.path),
            "crs": None if project is None else project.crs,
        },
        "inputs": _inputs(result),
        "options": options_record(result.options),
        "block": {
            "construction": None if result.options is None else result.options.block.value,
            "polynomial": result.polynomial,
            "strips": [
                {
                    "name": spec.name,
                    "photos": list(spec.photo_ids),
                    "n_models": strip.n_models,
                    "scale": json_float(scale),
                    "rejections": [r.describe() for r in strip.rejections],
                    "polynomial_terms": (
                        result.polynomial_terms[k] if result.polynomial_terms else None
                    ),
                }
                for k, (spec, strip, scale) in enumerate(
                    zip(result.specs, result.strips, result.scale, strict=True)
                )
            ],
            "sigma0": json_float(result.sigma0),
            "refined": result.refined,
            "refined_sigma0": json_float(result.refined_sigma0),
            "redundancy": result.redundancy,
            "iterations": result.iterations,
            "joins": joins,
            "join_criterion": f"mean plan discrepancy <= {JOIN_PLAN_MM} mm at the map scale "
            "(R4 1.7.7.7)",
            "transfer_criterion": f"mean transfer error <= {TRANSFER_UM:.0f} um in the image, "
            "free block, digital identification (R4 1.7.7.3)",
        },
        "control": {
            "statistics": statistics(result.control_statistics),
            "fit_statistics": None
            if result.control_fit_statistics is None
            else statistics(result.control_fit_statistics),
            "points": _control_points(result, check=False),
        },
        "check": {
            "statistics": statistics(result.check_statistics),
            "points": _control_points(result, check=True),
            "weakly_determined": list(getattr(result, "weak_checks", ())),
            "statistics_with_weak": statistics(_check_rows(result, result.control_residuals)),
        },
        "bundle": (
            {
                "sigma0": json_float(result.refined_sigma0),
                "block_check": None
                if result.block_check_statistics is None
                else statistics(result.block_check_statistics),
                "block_check_with_weak": None
                if result.block_control_residuals is None
                else statistics(_check_rows(result, result.block_control_residuals)),
                "gnss": _bundle_gnss(result.gnss),
                "imu": _bundle_imu(result.imu),
                "restored_points": list(result.restored_points),
            }
            if result.refined
            else None
        ),
        "tolerances": block_tolerances_record(result, map_scale, joins),
        "rejections": [r.describe() for r in result.rejections],
        "warnings": [str(w) for w in result.warnings],  # plain strings
        "timings_s": dict(result.timings),
    }
    cleaned: dict[str, Any] = clean(report)
    return cleaned


def joins_record(result: BlockResult, map_scale: float | None) -> list[dict[str, Any]]:
    """report.json's ``block.joins``: every two strips' common points, their
    discrepancies and transfer errors against R4's limits."""
    limit = None if map_scale is None else JOIN_PLAN_MM * 1e-3 * map_scale
    return [
        {
            "strips": [result.specs[i].name, result.specs[j].name],
            "n_points": join.n_points,
            "mean_plan_m": json_float(join.mean_plan_m),
            "max_plan_m": json_float(join.max_plan_m),
            "mean_height_m": json_float(join.mean_height_m),
            "max_height_m": json_float(join.max_height_m),
            "plan_limit_m": limit,
            "passed": None if limit is None else bool(join.mean_plan_m <= limit),
            "mean_transfer_um": json_float(join.mean_transfer_um),
            "max_transfer_um": json_float(join.max_transfer_um),
            "transfer_limit_um": TRANSFER_UM,
            "transfer_passed": transfer_passed(join.mean_transfer_um),
        }
        for join in result.joins
        for i, j in [join.strips]
    ]


def block_tolerances_record(
    result: BlockResult, map_scale: float | None, joins: Sequence[Mapping[str, Any]]
) -> dict[str, Any]:
    """report.json's ``tolerances`` of a block, with its verdict over the
    check points and the ``joins`` (:func:`joins_record`; the run's summary
    takes its verdict from here too)."""
    return with_verdict(_tolerances(result, map_scale), joins)


def _tolerances(result: BlockResult, map_scale: float | None) -> dict[str, Any]:
    """R4 §1.7.7's check-point criteria for the block, as a strip's (the
    mean plan discrepancy at the map scale, and the distribution of dE, dN);
    the joins carry the criteria of the common points."""
    from ..ground.check_precision import strong_checks
    from .tolerances import check_mean_plan, residual_distribution

    resid = np.asarray(result.control_residuals, dtype=np.float64).reshape(-1, 3)
    # the check points of the statistics: without the weakly determined ones
    check = strong_checks(result, result.control, result.weak_checks)
    criteria = (
        check_mean_plan(np.hypot(resid[check, 0], resid[check, 1]), map_scale),
        *residual_distribution(
            resid[check, :2].reshape(-1),
            prefix="check_en",
            what="check-point discrepancies dE, dN",
            unit="m",
        ),
    )
    judged = [c.passed for c in criteria if c.passed is not None]
    return {
        "map_scale": map_scale,
        "criteria": [c.as_dict() for c in criteria],
        "passed": None if not judged else all(judged),
    }


def _inputs(result: BlockResult) -> dict[str, Any]:
    """What the block was given, as a strip's ``inputs`` (docs/outputs.md)."""
    obs = result.observations
    kinds = [str(getattr(k, "value", k)) for k in result.control.kind]
    return {
        "n_strips": len(result.specs),
        "n_photos": len(result.photo_ids),
        "n_points": len(result.point_ids),
        "n_points_triangulated": delivered_points(result),
        "n_observations": len(obs.photo),
        "principal_distance_mm": json_float(obs.principal_distance),
        "control": {k.value: kinds.count(k.value) for k in ControlType},
    }


def _control_points(result: BlockResult, *, check: bool) -> list[dict[str, Any]]:
    """The control (or check) points the block determined: type and residuals
    (given − adjusted, E, N, H metres; null where not given or not used)."""
    out = []
    for row, resid, is_check in zip(
        result.control_index, result.control_residuals, result.is_check, strict=True
    ):
        if bool(is_check) != check:
            continue
        kind = result.control.kind[row]
        out.append(
            {
                "point": result.control.point_ids[row],
                "type": str(getattr(kind, "value", kind)),
                "dE_m": json_float(resid[0]),
                "dN_m": json_float(resid[1]),
                "dH_m": json_float(resid[2]),
                "plan_m": json_float(np.hypot(resid[0], resid[1])),
            }
        )
    return out


def build_block_outputs(
    result: BlockResult, *, project: Project | None = None, map_scale: float | None = None
) -> dict[str, bytes]:
    """Every file of a block's result folder, name -> UTF-8 bytes."""
    report = build_block_report(result, project=project, map_scale=map_scale)
    return block_outputs(result, report, project=project)


def block_outputs(
    result: BlockResult, report: dict[str, Any], *, project: Project | None = None
) -> dict[str, bytes]:
    """:func:`build_block_outputs` with the ``report.json`` content already built."""
    geographic = result.control is not None and bool(
        project is not None and not project.is_local and _geographic(project.crs)
    )
    # the figures drawn in a second process while this one writes the tables
    with aside(partial(_block_figures, result, geographic)) as drawing:
        points_text, photos_text = _block_tables(result, geographic)
        cal_record, cal_toml = calibration_outputs(
            result.self_calibration, project, float(result.observations.principal_distance)
        )
        if cal_record is not None:
            report["bundle"]["self_calibration"] = cal_record
        weights = variance_record(result.variance_components)
        if weights is not None:
            report["bundle"]["variance_components"] = weights
        text = json_text.dumps(report, indent=2, ensure_ascii=True) + "\n"
        figure, calibration = drawing.result()
    section = "" if cal_record is None else calibration_html(cal_record, calibration)
    section = with_variance_html(section, report)
    files = {
        "points.csv": points_text.encode("utf-8"),
        "photos.csv": photos_text.encode("utf-8"),
        "report.json": text.encode("utf-8"),
        "report.html": block_html(
            report, figure, calibration=section, warnings=result.warnings
        ).encode("utf-8"),
    }
    if cal_toml is not None:
        files["camera.toml"] = cal_toml
    return files


def _block_figures(
    result: BlockResult, geographic: bool
) -> tuple[str | None, tuple[str | None, str | None]]:
    """The block's figure and the self-calibration's two (None without)."""
    return block_figure(result, geographic=geographic), calibration_figures(
        result.self_calibration
    )


def _block_tables(result: BlockResult, geographic: bool) -> tuple[str, str]:
    """The text of points.csv and photos.csv of a block."""
    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    roles, n_strips = _roles_and_strips(result)
    resid = _residuals(result)
    ids = np.asarray(result.point_ids, dtype=str)
    points_text = format_points_csv(
        ids[ok],
        points[ok],
        extra={
            "role": roles[ok],
            "n_strips": n_strips[ok],
            "dE": resid[ok, 0],
            "dN": resid[ok, 1],
            "dH": resid[ok, 2],
        },
        geographic=geographic,
    )
    strip_names = np.array([result.specs[k].name for k in result.photo_strip], dtype=str)
    photos_text = format_photos_csv(
        np.asarray(result.photo_ids, dtype=str),
        result.photo_centres,
        result.photo_opk,
        extra={"strip": strip_names},
        geographic=geographic,
    )
    return points_text, photos_text


def _geographic(crs: str) -> bool:
    import pyproj

    return bool(pyproj.CRS.from_user_input(crs).is_geographic)


def block_figure(result: BlockResult, *, geographic: bool = False) -> str | None:
    """The block in plan as a PNG (base64): photo centres coloured by strip,
    control and check points, and the check points' plan residuals as
    arrows (scaled so that the largest is a tenth of the block's extent, the
    scale written in the legend)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    from .figures import _fitted_png, _nice

    centres = np.asarray(result.photo_centres, dtype=np.float64)
    if not np.isfinite(centres).all():
        return None
    origin = centres[:, :2].mean(axis=0)
    if geographic:  # degrees to metres about the centre, for a figure only
        lat = np.radians(origin[1])
        factor = np.array([111_320.0 * np.cos(lat), 110_540.0])
    else:
        factor = np.ones(2)

    def plan(xyh: np.ndarray) -> np.ndarray:
        out: np.ndarray = (xyh[:, :2] - origin) * factor
        return out

    fig = Figure(figsize=(10.5, 6.5))
    ax = fig.subplots()
    for k, spec in enumerate(result.specs):
        xy = plan(centres[result.photo_strip == k])
        ax.plot(
            xy[:, 0], xy[:, 1], "o-", ms=3, lw=0.8, label=f"strip {shorten(spec.name, 40)} photos"
        )
    lookup = {pid: i for i, pid in enumerate(result.point_ids)}
    rows = np.asarray(result.control_index)
    index = np.array([lookup[result.control.point_ids[r]] for r in rows], dtype=np.intp)
    points = np.asarray(result.points, dtype=np.float64)[index]
    ok = np.isfinite(points).all(axis=1)
    check = np.asarray(result.is_check) & ok
    control = ~np.asarray(result.is_check) & ok
    xy = plan(points)
    ax.scatter(
        xy[control, 0], xy[control, 1], marker="^", s=50, c="#c0392b", label="control", zorder=4
    )
    ax.scatter(
        xy[check, 0], xy[check, 1], marker="s", s=25, c="#8e44ad", label="check points", zorder=4
    )
    resid = np.asarray(result.control_residuals, dtype=np.float64)[:, :2]
    vec = check & np.isfinite(resid).all(axis=1)
    if vec.any():
        extent = float(np.ptp(plan(centres), axis=0).max()) or 1.0
        largest = float(np.hypot(*resid[vec].T).max()) or 1.0
        scale = 0.1 * extent / largest
        arrows = ax.quiver(
            xy[vec, 0],
            xy[vec, 1],
            resid[vec, 0],
            resid[vec, 1],
            angles="xy",
            scale_units="xy",
            scale=1.0 / scale,
            width=0.003,
            color="#1f618d",
            zorder=5,  # above the point markers (4)
            label=f"check point plan residual (x {scale:.0f})",
        )
        key = _nice(largest)
        ax.quiverkey(
            arrows, 0.86, 0.04, key, f"{key:g} m", labelpos="E", coordinates="axes", color="black"
        )
        # the arrows' tips inside the axes: quiver does not widen the limits
        tips = xy[vec] + resid[vec] * scale
        ax.update_datalim(tips)
        ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east from the block centre (m)")
    ax.set_ylabel("north from the block centre (m)")
    ax.grid(alpha=0.3)
    # beside the axes, not over the points (figures_frame.fit makes room)
    beside = ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    return _fitted_png(fig, beside=beside)
