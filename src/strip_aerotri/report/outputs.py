"""The outputs of a run: CSVs, the machine-readable report and the HTML report.

:func:`build_outputs` turns a :class:`~strip_aerotri.pipeline.StripResult`
into the files of a result folder (name -> bytes), ready for
:class:`~strip_aerotri.io.ResultFolder`; :func:`build_report` gives the
content of ``report.json`` as plain Python (dict, list, str, int, float,
bool, None; never NaN).  Every file, column and key is described in
``docs/outputs.md``.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from collections.abc import Mapping, Sequence
from enum import Enum
from typing import Any

import numpy as np

from .. import __version__
from ..geometry.rotation import opk_from_matrix
from ..observations import ControlType
from .files import format_photos_csv, format_points_csv
from .tolerances import tolerance_verdicts

__all__ = [
    "REPORT_FORMAT",
    "REPORT_FORMAT_VERSION",
    "build_outputs",
    "build_report",
    "point_roles",
]

REPORT_FORMAT = "stripaero-report"
REPORT_FORMAT_VERSION = 1

_ROLE_OF_KIND = {
    ControlType.FULL: "control-full",
    ControlType.PLAN: "control-plan",
    ControlType.HEIGHT: "control-height",
    ControlType.CHECK: "check",
}


# --------------------------------------------------------------------------- helpers


def _clean(value: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, NaN/inf -> None."""
    if isinstance(value, Enum):
        return _clean(value.value)
    if isinstance(value, Mapping):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


def _f(value: Any) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _statistics(stats) -> dict[str, Any]:
    rmse = np.asarray(stats.rmse, dtype=np.float64)
    return {
        "n_plan": int(stats.n_plan),
        "n_height": int(stats.n_height),
        "rmse_e_m": _f(rmse[0]),
        "rmse_n_m": _f(rmse[1]),
        "rmse_h_m": _f(rmse[2]),
        "rmse_plan_m": _f(stats.rmse_plan),
        "mean_plan_m": _f(stats.mean_plan),
        "max_plan_m": _f(stats.max_plan),
        "max_height_m": _f(stats.max_height),
    }


def point_roles(result) -> np.ndarray:
    """Role of every point of ``result.point_ids`` (array of str, shape (P,)).

    ``control-full``, ``control-plan``, ``control-height``, ``check`` (from
    the control file), ``line`` (on a straight line), ``tie`` (determined in
    two or more models), ``model`` (in one model only), ``rays`` (in no
    model, intersected from its rays on photos that are not a pair, e.g.
    photos i and i + 2), ``none`` (not triangulated).
    """
    strip = result.strip
    n_det = np.asarray(strip.n_determinations)
    found = np.isfinite(np.asarray(result.points, dtype=np.float64)).all(axis=1)
    roles = np.where(
        n_det >= 2, "tie", np.where(n_det == 1, "model", np.where(found, "rays", "none"))
    ).astype(object)
    for index in result.ground.line_point_index:
        roles[np.asarray(index, dtype=np.intp)] = "line"
    lookup = {pid: i for i, pid in enumerate(result.point_ids)}
    for pid, kind in zip(result.control.point_ids, result.control.kind, strict=True):
        i = lookup.get(pid)
        if i is not None:
            roles[i] = _ROLE_OF_KIND[ControlType(kind)]
    return roles.astype(str)


def _control_rows(result) -> tuple[np.ndarray, np.ndarray]:
    """Point index (C,) of each row of ``ground.control_residuals`` and the residuals (C, 3)."""
    ground = result.ground
    lookup = {pid: i for i, pid in enumerate(result.point_ids)}
    rows = np.asarray(ground.control_index, dtype=np.intp)
    idx = np.array([lookup[result.control.point_ids[r]] for r in rows], dtype=np.intp)
    return idx, np.asarray(ground.control_residuals, dtype=np.float64).reshape(-1, 3)


def _residual_columns(result) -> np.ndarray:
    """(P, 3) given − adjusted E, N, H at control and check points, NaN elsewhere."""
    out = np.full((len(result.point_ids), 3), np.nan)
    idx, resid = _control_rows(result)
    out[idx] = resid
    return out


def _image_counts(result) -> tuple[np.ndarray, np.ndarray]:
    obs = result.strip.observations
    per_point = np.bincount(np.asarray(obs.point), minlength=obs.n_points)
    per_photo_all = np.bincount(np.asarray(obs.photo), minlength=obs.n_photos)
    return per_point, per_photo_all[np.asarray(result.strip.photo_index)]


# --------------------------------------------------------------------------- CSVs


def points_csv(result) -> str:
    """Text of ``points.csv`` (triangulated points only; see docs/outputs.md)."""
    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    ids = np.asarray(result.point_ids, dtype=str)
    roles = point_roles(result)
    n_det = np.asarray(result.strip.n_determinations, dtype=np.int64)
    n_img, _ = _image_counts(result)
    resid = _residual_columns(result)
    extra = {
        "role": roles[ok],
        "n_models": n_det[ok],
        "n_images": n_img[ok].astype(np.int64),
        "dE": resid[ok, 0],
        "dN": resid[ok, 1],
        "dH": resid[ok, 2],
    }
    return format_points_csv(
        ids[ok], points[ok], extra=extra, geographic=result.ground.crs.is_geographic
    )


def photos_csv(result) -> str:
    """Text of ``photos.csv`` (see docs/outputs.md)."""
    _, n_img = _image_counts(result)
    ids = np.asarray(result.photo_ids, dtype=str)
    extra = {
        "strip_index": np.arange(len(ids), dtype=np.int64),
        "n_points": n_img.astype(np.int64),
    }
    return format_photos_csv(
        ids,
        result.photo_centres,
        result.photo_opk,
        extra=extra,
        geographic=result.ground.crs.is_geographic,
    )


# --------------------------------------------------------------------------- report.json


def _element_names(method: str) -> tuple[list[str], list[str]]:
    if method == "base":
        return ["alpha1", "chi1", "alpha2", "omega2", "chi2"], ["deg"] * 5
    return ["b_y", "b_z", "a", "b", "c"], ["strip", "strip", "", "", ""]


def _pairs(result) -> list[dict[str, Any]]:
    strip = result.strip
    rel = strip.relative
    method = str(getattr(rel.method, "value", rel.method))
    names, _ = _element_names(method)
    elements = np.asarray(rel.elements, dtype=np.float64)
    if method == "base":
        elements = np.degrees(elements)
    ids = result.photo_ids
    return [
        {
            "index": m,
            "left": ids[m],
            "right": ids[m + 1],
            "n_points": int(rel.n_points[m]),
            "iterations": int(rel.iterations[m]),
            "sigma0_um": _f(rel.sigma0_um[m]),
            "rms_parallax_um": _f(rel.rms_parallax_um[m]),
            "max_parallax_um": _f(rel.max_parallax_um[m]),
            "elements": {n: _f(v) for n, v in zip(names, elements[m], strict=True)},
        }
        for m in range(rel.n_pairs)
    ]


def _models(result) -> list[dict[str, Any]]:
    strip = result.strip
    scale = float(result.ground.similarity.transform.scale)
    n_pts = np.bincount(np.asarray(strip.model), minlength=strip.n_models)
    tie_rms = np.asarray(strip.tie_rms, dtype=np.float64).reshape(-1, 3)
    ids = result.photo_ids
    out = []
    for m in range(strip.n_models):
        rms = tie_rms[m]
        plan = float(np.hypot(rms[0], rms[1]))
        out.append(
            {
                "index": m,
                "left": ids[m],
                "right": ids[m + 1],
                "n_points": int(n_pts[m]),
                "scale": _f(strip.scale[m]),
                "scale_ratio": _f(strip.scale_ratio[m]),
                "tie_points": int(strip.tie_count[m]),
                "tie_rms_strip": [_f(v) for v in rms],
                "tie_rms_m": [_f(v * scale) for v in rms],
                "tie_rms_plan_m": _f(plan * scale),
            }
        )
    return out


def _similarity(result) -> dict[str, Any]:
    sim = result.ground.similarity
    tr = sim.transform
    rotation = np.asarray(tr.rotation, dtype=np.float64)
    resid = np.asarray(sim.residuals, dtype=np.float64).reshape(-1, 3)
    return {
        "scale": _f(tr.scale),
        "rotation_opk_deg": [_f(v) for v in opk_from_matrix(rotation, degrees=True)],
        "rotation_matrix": rotation,
        "translation_m": np.asarray(tr.translation, dtype=np.float64),
        "sigma0": _f(sim.sigma0),
        "redundancy": int(sim.redundancy),
        "iterations": int(sim.iterations),
        "residuals": [
            {"point": pid, "dX_m": _f(r[0]), "dY_m": _f(r[1]), "dZ_m": _f(r[2])}
            for pid, r in zip(sim.point_ids, resid, strict=True)
        ],
    }


def _polynomial(result, requested: Any) -> dict[str, Any]:
    ground = result.ground
    deformation = ground.deformation
    out: dict[str, Any] = {"requested": requested, "kind": int(ground.polynomial_kind)}
    if deformation is not None:
        coef = np.asarray(deformation.coefficients, dtype=np.float64)
        terms = list(deformation.term_names)
        out.update(
            {
                "kinds_xyz": [int(k) for k in deformation.kinds],
                "sections": int(deformation.sections),
                "breakpoints_x_m": np.asarray(deformation.breakpoints_x, dtype=np.float64),
                "terms": terms,
                "coefficients_m": {axis: [_f(v) for v in coef[i]] for i, axis in enumerate("XYZ")},
                "normalization": {
                    "centre_m": np.asarray(deformation.normalization.centre, dtype=np.float64),
                    "half_extent_m": _f(deformation.normalization.half_extent),
                },
                "sigma0": _f(deformation.sigma0),
                "redundancy": int(deformation.redundancy),
                "sigma0_xyz": np.asarray(deformation.sigma0_xyz, dtype=np.float64),
                "redundancy_xyz": [int(v) for v in deformation.redundancy_xyz],
            }
        )
    selection = ground.kind_selection
    if selection is not None:
        out["auto"] = {
            "chosen": int(selection.kind),
            "table": [
                {
                    "kind": int(row.kind),
                    "feasible": bool(row.feasible),
                    "reason": str(row.reason),
                    "sigma0": _f(row.sigma0),
                    "redundancy": int(row.redundancy),
                    "sigma0_xyz": np.asarray(row.sigma0_xyz, dtype=np.float64),
                    "rms_xyz_m": np.asarray(row.rms_xyz, dtype=np.float64),
                    "statistic_xyz": np.asarray(row.statistic_xyz, dtype=np.float64),
                    "dof_xyz": np.asarray(row.dof_xyz, dtype=np.float64),
                    "critical_xyz": np.asarray(row.critical_xyz, dtype=np.float64),
                    "passed": bool(row.passed),
                }
                for row in selection.table
            ],
        }
    return out


def _lines(result, weights: Mapping[str, float]) -> list[dict[str, Any]]:
    ground = result.ground
    deformation = ground.deformation
    params = None
    if deformation is not None and len(deformation.line_names):
        params = {
            name: np.asarray(p, dtype=np.float64)
            for name, p in zip(deformation.line_names, deformation.line_parameters, strict=True)
        }
    out = []
    for name, index, resid in zip(
        ground.line_names, ground.line_point_index, ground.line_residuals, strict=True
    ):
        resid = np.asarray(resid, dtype=np.float64)
        ids = [result.point_ids[i] for i in np.asarray(index)]
        ab = None if params is None or name not in params else params[name]
        out.append(
            {
                "name": name,
                "weight": _f(weights[name]) if name in weights else None,
                "n_points": len(ids),
                "a_m": None if ab is None else _f(ab[0]),
                "b": None if ab is None else _f(ab[1]),
                "rms_m": _f(np.sqrt(np.mean(resid**2))) if resid.size else None,
                "max_abs_m": _f(np.max(np.abs(resid))) if resid.size else None,
                "residuals": [
                    {"point": p, "dY_m": _f(v)} for p, v in zip(ids, resid, strict=True)
                ],
            }
        )
    return out


def _control_points(result, check: bool) -> list[dict[str, Any]]:
    ground = result.ground
    idx, resid = _control_rows(result)
    is_check = np.asarray(ground.is_check, dtype=bool)
    rows = np.asarray(ground.control_index, dtype=np.intp)
    out = []
    red = np.asarray(getattr(ground, "control_redundancy", np.zeros((0, 3))), dtype=np.float64)
    mde = np.asarray(getattr(ground, "control_mde", np.zeros((0, 3))), dtype=np.float64)
    have = red.shape[0] == rows.shape[0]
    for k in np.flatnonzero(is_check == check):
        r = resid[k]
        kind = result.control.kind[rows[k]]
        row: dict[str, Any] = {
            "point": result.point_ids[idx[k]],
            "type": str(getattr(kind, "value", kind)),
            "dE_m": _f(r[0]),
            "dN_m": _f(r[1]),
            "dH_m": _f(r[2]),
            "plan_m": _f(np.hypot(r[0], r[1])),
        }
        if not check:
            used = [bool(ground.used_xy[k])] * 2 + [bool(ground.used_h[k])]
            row["redundancy"] = (
                [_f(v) if u else None for v, u in zip(red[k], used, strict=True)]
                if have
                else [None] * 3
            )
            row["mde_m"] = (
                [
                    _f(v) if u and np.isfinite(v) else None
                    for v, u in zip(mde[k], used, strict=True)
                ]
                if have
                else [None] * 3
            )
            row["detectable"] = (
                [bool(np.isfinite(v)) if u else None for v, u in zip(mde[k], used, strict=True)]
                if have
                else [None] * 3
            )
        out.append(row)
    return out


def _model_adjustment(result) -> dict[str, Any] | None:
    """The simultaneous transformation of the models (block = "models")."""
    models = getattr(result.ground, "models", None)
    if models is None:
        return None
    res = models.result
    labels = result.strip.model_labels
    rms = np.asarray(models.model_rms, dtype=np.float64)
    centres = np.asarray(models.centre_discrepancy, dtype=np.float64)
    disc = np.asarray(models.discrepancy, dtype=np.float64)
    return {
        "sigma0": _f(res.sigma0),
        "redundancy": int(res.redundancy),
        "iterations": int(res.iterations),
        "converged": bool(res.converged),
        "discrepancy_rms_m": [_f(v) for v in np.sqrt(np.nanmean(disc**2, axis=0))]
        if disc.size
        else [None] * 3,
        "models": [
            {
                "index": m,
                "label": labels[m] if m < len(labels) else str(m),
                "scale": _f(res.transforms.scale[m]),
                "discrepancy_rms_m": [_f(v) for v in rms[m]],
                "left_centre_m": [_f(v) for v in centres[m, 0]],
                "right_centre_m": [_f(v) for v in centres[m, 1]],
            }
            for m in range(rms.shape[0])
        ],
        "rejected": [{"model": m, "point": p} for m, p in models.rejected],
    }


def _options(result, project) -> dict[str, Any]:
    strip_opt = result.strip.options
    construction = getattr(result.ground, "construction", None)
    opts: dict[str, Any] = {
        "route": result.ground.route,
        "block": str(getattr(construction, "value", "strips")),
        "relative_orientation": strip_opt.relative_orientation,
        "intersection": strip_opt.intersection,
        "scale_transfer": strip_opt.scale_transfer,
        "max_iterations": int(strip_opt.max_iterations),
        "polynomial": int(result.ground.polynomial_kind)
        if result.ground.kind_selection is None
        else "auto",
    }
    if project is not None:
        adj = project.adjustment
        opts["polynomial"] = adj.polynomial if adj.polynomial == "auto" else int(adj.polynomial)
    if opts["block"] == "models":
        opts["polynomial"] = None  # every model its own similarity
    return opts


def build_report(
    result, *, project=None, map_scale: float | None = None, notes: Sequence[str] = ()
) -> dict[str, Any]:
    """Content of ``report.json`` (plain JSON types; NaN written as None).

    Parameters
    ----------
    result : StripResult
        The run's result (:func:`strip_aerotri.pipeline.triangulate`).
    project : Project, optional
        The loaded project (:func:`strip_aerotri.config.load_project`): name,
        files, options and its ``[report] map_scale``.
    map_scale : float, optional
        Map scale denominator S for the tolerance verdicts; overrides the
        project's.
    notes : sequence of str
        Further warnings (from writing the outputs), appended to ``warnings``.

    Returns
    -------
    dict
        Keys documented in ``docs/outputs.md``.
    """
    if map_scale is None and project is not None:
        report_opts = getattr(project, "report", None)
        map_scale = getattr(report_opts, "map_scale", None)
    ground = result.ground
    obs = result.strip.observations
    control = result.control
    kinds = [str(getattr(k, "value", k)) for k in control.kind]
    weights: dict[str, float] = {}
    if project is not None:
        weights = {spec.name: float(spec.weight) for spec in project.straight_lines}
    criteria = tolerance_verdicts(result, map_scale)
    judged = [c.passed for c in criteria if c.passed is not None]
    frame = ground.frame
    report: dict[str, Any] = {
        "format": REPORT_FORMAT,
        "format_version": REPORT_FORMAT_VERSION,
        "software": {"name": "strip_aerotri", "version": __version__},
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "project": {
            "name": None if project is None else project.name,
            "file": None if project is None else str(project.path),
            "images_file": None if project is None else str(project.images_file),
            "control_file": None if project is None else str(project.control_file),
            "crs": ground.crs.text or ground.crs.name,
            "crs_name": ground.crs.name,
        },
        "inputs": {
            "n_photos": len(result.photo_ids),
            "photos": list(result.photo_ids),
            "n_points": len(result.point_ids),
            "n_points_triangulated": int(np.count_nonzero(result.strip.triangulated)),
            "n_observations": len(obs.photo),
            "principal_distance_mm": _f(obs.principal_distance),
            "principal_point_mm": None
            if project is None
            else np.asarray(project.camera.principal_point_mm, dtype=np.float64),
            "control": {k.value: kinds.count(k.value) for k in ControlType},
            "control_left_out": list(ground.left_out),
            "straight_lines": [
                {"name": n, "n_points": len(i)}
                for n, i in zip(ground.line_names, ground.line_point_index, strict=True)
            ],
        },
        "options": _options(result, project),
        "relative_orientation": {
            "method": result.strip.relative.method,
            "element_names": _element_names(
                str(getattr(result.strip.relative.method, "value", result.strip.relative.method))
            )[0],
            "element_units": _element_names(
                str(getattr(result.strip.relative.method, "value", result.strip.relative.method))
            )[1],
            "max_parallax_history_um": np.asarray(result.strip.relative.history),
        },
        "pairs": _pairs(result),
        "models": _models(result),
        "ground": {
            "route": ground.route,
            "construction": str(getattr(getattr(ground, "construction", None), "value", "strips")),
            "azimuth_deg": _f(np.degrees(ground.azimuth)),
            "passes": int(ground.passes),
            "passes_converged": bool(ground.passes_converged),
            "image_scale_m_per_mm": _f(ground.image_scale),
            "expected_sigma_plan_m": _f(ground.expected_sigma_plan),
            "expected_sigma_height_m": _f(ground.expected_sigma_height),
            "tangent_frame": None
            if frame is None
            else {
                "origin_ecef_m": np.asarray(frame.origin_ecef, dtype=np.float64),
                "latitude_deg": _f(np.degrees(frame.latitude)),
                "longitude_deg": _f(np.degrees(frame.longitude)),
            },
        },
        "model_adjustment": _model_adjustment(result),
        "similarity": _similarity(result),
        "polynomial": _polynomial(result, _options(result, project)["polynomial"]),
        "straight_lines": _lines(result, weights),
        "control": {
            "statistics": _statistics(result.control_statistics),
            "points": _control_points(result, check=False),
        },
        "check": {
            "statistics": _statistics(result.check_statistics),
            "points": _control_points(result, check=True),
        },
        "tolerances": {
            "map_scale": None if map_scale is None else float(map_scale),
            "passed": None if not judged else all(judged),
            "criteria": [c.as_dict() for c in criteria],
        },
        "bundle": _bundle(result),
        "rejections": [
            {
                "stage": r.stage,
                "point": r.point,
                "photos": list(r.photos),
                "component": r.component,
                "residual": float(r.residual),
                "unit": r.unit,
                "w": float(r.w),
                "critical": float(r.critical),
                "applied": bool(r.applied),
                "effect": r.effect,
            }
            for r in getattr(result, "rejections", ())
        ],
        "warnings": [*result.warnings, *notes],
        "timings_s": dict(result.timings),
        "outputs": {
            "points.geojson": {
                "written": not ground.crs.is_local,
                "wgs84_operation": None,
            }
        },
    }
    return _clean(report)


# --------------------------------------------------------------------------- points.geojson

GEOJSON_DECIMALS = 8
"""Decimals of longitude and latitude in points.geojson (1e-8 degree is about 1 mm)."""


def points_geojson(result) -> str | None:
    """Text of ``points.geojson``: RFC 7946 FeatureCollection in WGS 84 lon/lat.

    One Point feature per triangulated point, converted with
    :meth:`~strip_aerotri.geodesy.GroundCRS.to_wgs84_lonlat` (pyproj's best
    operation to WGS 84; display accuracy).  Properties: ``id``, ``role``,
    ``H`` (ellipsoidal height in metres on the control CRS's datum, as in
    points.csv), ``n_models``.  None for ``crs = "local"`` (no geodesy).
    """
    crs = result.ground.crs
    if crs.is_local:
        return None
    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    lonlat = np.round(crs.to_wgs84_lonlat(points[ok]), GEOJSON_DECIMALS)
    ids = np.asarray(result.point_ids, dtype=object)[ok]
    roles = point_roles(result)[ok]
    heights = np.round(points[ok, 2], 4)
    n_det = np.asarray(result.strip.n_determinations)[ok]
    features = [
        {
            "type": "Feature",
            "id": str(pid),
            "geometry": {"type": "Point", "coordinates": [float(lon), float(lat)]},
            "properties": {
                "id": str(pid),
                "role": str(role),
                "H": float(h),
                "n_models": int(n),
            },
        }
        for pid, (lon, lat), role, h, n in zip(
            ids, lonlat.tolist(), roles, heights.tolist(), n_det.tolist(), strict=True
        )
    ]
    collection = {"type": "FeatureCollection", "features": features}
    return json.dumps(collection, ensure_ascii=False, allow_nan=False, separators=(",", ":"))


# --------------------------------------------------------------------------- figures

_MAX_PLOT_POINTS = 20000
LONG_STRIP_RATIO = 8.0
"""A strip longer than this times its width is drawn along its axis, not to scale."""
_ROLE_STYLE = {
    # role: (label, marker, colour, size, zorder)
    "tie": ("tie points", ".", "#9a9a9a", 4, 2),
    "model": ("points in one model", ".", "#c8c8c8", 4, 2),
    "line": ("straight-line points", "x", "#e67e00", 22, 4),
    "check": ("check points", "s", "#8e44ad", 40, 6),
    "control-full": ("full control", "^", "#c0392b", 60, 7),
    "control-plan": ("plan control", ">", "#2471a3", 55, 7),
    "control-height": ("height control", "o", "#1e8449", 45, 7),
}


def _png(fig) -> str:
    import io as _bio

    buffer = _bio.BytesIO()
    # Fixed margins (rc "figure.subplot.*" in build_html) and fast PNG
    # compression: a layout engine or bbox_inches="tight" would draw every
    # figure twice, and they dominate the time of a run on large strips.
    fig.savefig(buffer, format="png", dpi=96, pil_kwargs={"compress_level": 1})
    import base64

    return base64.b64encode(buffer.getvalue()).decode("ascii")


class _Plan:
    """Plan coordinates for plotting: metres east and north (grid or local).

    Projected and local CRSs are plotted in their own X, Y; a geographic CRS
    in metres on a plane tangent at the strip's centre (display only).
    Directions from local east-north-up are turned into grid directions by the
    meridian convergence.
    """

    def __init__(self, result):
        crs = result.ground.crs
        self.crs = crs
        centres = np.asarray(result.photo_centres, dtype=np.float64)
        self.geographic = crs.is_geographic
        if self.geographic:
            ok = np.isfinite(centres).all(axis=1)
            self.lon0, self.lat0 = np.mean(centres[ok, :2], axis=0)
            ell = crs.ellipsoid
            self.radius = float(ell.semi_major_metre)
            self.unit = "m from the strip centre"
        else:
            self.unit = "m"
        self.centres = centres
        cxy = self.xy(centres)
        good = np.isfinite(cxy).all(axis=1)
        self.axis_start = cxy[good][0] if good.any() else np.zeros(2)
        self.axis_end = cxy[good][-1] if good.any() else np.array([1.0, 0.0])
        self.long = False

    def decide_long(self, xy: np.ndarray) -> None:
        """Use strip axes (not to scale) when the strip is much longer than wide."""
        sa = self.strip_axes(xy[np.isfinite(xy).all(axis=1)])
        if sa.size:
            length = float(np.ptp(sa[:, 0]))
            width = float(np.ptp(sa[:, 1]))
            self.long = length > LONG_STRIP_RATIO * max(width, 1e-9)

    def xy(self, xyh: np.ndarray) -> np.ndarray:
        xyh = np.asarray(xyh, dtype=np.float64)
        if not self.geographic:
            return xyh[:, :2]
        k = np.pi / 180.0 * self.radius
        return np.column_stack(
            [
                (xyh[:, 0] - self.lon0) * k * np.cos(np.radians(self.lat0)),
                (xyh[:, 1] - self.lat0) * k,
            ]
        )

    def strip_axes(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) plan xy -> (along, across): metres from the first photo along the
        line to the last one, and to its left."""
        d = self.axis_end - self.axis_start
        u = d / (np.hypot(d[0], d[1]) or 1.0)
        rel = np.asarray(xy, dtype=np.float64) - self.axis_start
        return np.stack([rel @ u, rel @ np.array([-u[1], u[0]])], axis=-1)

    def vectors_to_strip(self, de: np.ndarray, dn: np.ndarray) -> np.ndarray:
        """Plan vectors (grid east, north) -> (along, across) components."""
        d = self.axis_end - self.axis_start
        u = d / (np.hypot(d[0], d[1]) or 1.0)
        return np.stack([de * u[0] + dn * u[1], -de * u[1] + dn * u[0]], axis=-1)

    def convergence(self, xyh: np.ndarray) -> np.ndarray:
        if self.crs.is_local or self.geographic:
            return np.zeros(len(xyh))
        try:
            return np.asarray(self.crs.meridian_convergence(xyh), dtype=np.float64)
        except Exception:  # display only: fall back to true north
            return np.zeros(len(xyh))


def _footprints(result, plan: _Plan) -> np.ndarray | None:
    """(M, 4, 2) plan corners of each photo's footprint at the mean point height."""
    obs = result.strip.observations
    xy = np.asarray(obs.xy, dtype=np.float64)
    if xy.size == 0:
        return None
    half = np.max(np.abs(xy), axis=0)
    c = float(obs.principal_distance)
    corners = np.array(
        [
            [half[0], half[1], -c],
            [-half[0], half[1], -c],
            [-half[0], -half[1], -c],
            [half[0], -half[1], -c],
        ]
    )
    rot = np.asarray(result.ground.photo_rotations_enu, dtype=np.float64)
    rays = np.einsum("mij,kj->mki", rot, corners)  # (M, 4, 3) east, north, up
    centres = np.asarray(result.photo_centres, dtype=np.float64)
    points = np.asarray(result.points, dtype=np.float64)
    # mean height of the points seen on each photo (median of all where none)
    position = np.full(obs.n_photos, -1, dtype=np.intp)
    position[np.asarray(result.strip.photo_index)] = np.arange(len(centres))
    row_photo = position[np.asarray(obs.photo)]
    row_h = points[np.asarray(obs.point), 2]
    use = (row_photo >= 0) & np.isfinite(row_h)
    total = np.bincount(row_photo[use], weights=row_h[use], minlength=len(centres))
    count = np.bincount(row_photo[use], minlength=len(centres))
    fallback = float(np.nanmedian(points[:, 2])) if np.isfinite(points[:, 2]).any() else 0.0
    h = np.where(count > 0, total / np.maximum(count, 1), fallback)
    depth = centres[:, 2] - h
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -depth[:, None] / rays[:, :, 2]
    en = rays[:, :, :2] * t[:, :, None]
    gamma = plan.convergence(centres)
    cg, sg = np.cos(gamma)[:, None], np.sin(gamma)[:, None]
    # true azimuth alpha -> grid azimuth alpha - gamma: turn counter-clockwise by gamma
    e = cg * en[:, :, 0] - sg * en[:, :, 1]
    n = sg * en[:, :, 0] + cg * en[:, :, 1]
    grid = np.stack([e, n], axis=-1)
    # the grid scale factor (about 1) is ignored: display only
    out = plan.xy(centres)[:, None, :] + grid
    bad = ~np.isfinite(out).all(axis=(1, 2)) | (t <= 0).any(axis=1)
    return out[~bad]


def _decimate(index: np.ndarray, limit: int) -> np.ndarray:
    if index.size <= limit:
        return index
    return index[np.linspace(0, index.size - 1, limit).astype(np.intp)]


def _figure_layout(result, plan: _Plan, roles: np.ndarray) -> str:
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    pxy = np.full((len(points), 2), np.nan)
    pxy[ok] = plan.xy(points[ok])
    cxy = plan.xy(plan.centres)
    feet = _footprints(result, plan)
    if plan.long:
        pxy = plan.strip_axes(pxy)
        cxy = plan.strip_axes(cxy)
        if feet is not None and len(feet):
            feet = plan.strip_axes(feet.reshape(-1, 2)).reshape(feet.shape)
    fig = Figure(figsize=(10, 4.5 if plan.long else 6.5))
    ax = fig.subplots()
    if feet is not None and len(feet):
        step = max(1, len(feet) // 400)
        ax.add_collection(
            PolyCollection(
                feet[::step],
                facecolors="#5dade2",
                edgecolors="#2e86c1",
                alpha=0.08,
                linewidths=0.6,
                zorder=1,
                label="photo footprints",
            )
        )
    ax.plot(cxy[:, 0], cxy[:, 1], "-", color="#2e86c1", lw=0.8, zorder=3)
    ax.plot(
        cxy[:, 0], cxy[:, 1], "o", ms=3.5, color="#1b4f72", zorder=3, label="projection centres"
    )
    ax.annotate(
        result.photo_ids[0],
        cxy[0],
        textcoords="offset points",
        xytext=(4, 4),
        fontsize=8,
        color="#1b4f72",
    )
    ax.annotate(
        result.photo_ids[-1],
        cxy[-1],
        textcoords="offset points",
        xytext=(4, 4),
        fontsize=8,
        color="#1b4f72",
    )
    for role, (label, marker, colour, size, z) in _ROLE_STYLE.items():
        sel = np.flatnonzero(ok & (roles == role))
        if sel.size == 0:
            continue
        sel = _decimate(sel, _MAX_PLOT_POINTS)
        crowded = sel.size > 400 and marker not in (".", "x")
        ax.scatter(
            pxy[sel, 0],
            pxy[sel, 1],
            s=size / 4 if crowded else size,
            marker=marker,
            c=colour,
            zorder=z,
            label=f"{label} ({int(np.count_nonzero(ok & (roles == role)))})",
            linewidths=1.0 if marker == "x" else 0.4,
            **({} if marker in (".", "x") or crowded else {"edgecolors": "black"}),
        )
    ax.autoscale_view()
    _plan_axes(ax, plan)
    if plan.long:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    else:
        ax.legend(loc="best", fontsize=8, framealpha=0.85)
    ax.set_title(
        "Strip layout along the strip axis (not to scale)" if plan.long else "Strip layout"
    )
    return _png(fig)


def _plan_axes(ax, plan: _Plan) -> None:
    if plan.long:
        ax.set_xlabel(f"along the strip from the first photo [{plan.unit}]")
        ax.set_ylabel("across the strip, left positive [m]")
    else:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"X (east) [{plan.unit}]")
        ax.set_ylabel(f"Y (north) [{plan.unit}]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.grid(True, lw=0.3, alpha=0.5)


def _nice(value: float) -> float:
    """1, 2 or 5 times a power of ten, not above ``value``."""
    if not (np.isfinite(value) and value > 0):
        return 1.0
    exp = np.floor(np.log10(value))
    base = value / 10**exp
    step = 5.0 if base >= 5 else 2.0 if base >= 2 else 1.0
    return float(step * 10**exp)


def _figure_residuals(result, plan: _Plan) -> str | None:
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure

    idx, resid = _control_rows(result)
    if idx.size == 0:
        return None
    is_check = np.asarray(result.ground.is_check, dtype=bool)
    pxy = plan.xy(np.asarray(result.points, dtype=np.float64)[idx])
    cxy = plan.xy(plan.centres)
    # residuals are along east/north; turn them to the grid like the footprints
    gamma = plan.convergence(np.asarray(result.points, dtype=np.float64)[idx])
    de = np.cos(gamma) * resid[:, 0] - np.sin(gamma) * resid[:, 1]
    dn = np.sin(gamma) * resid[:, 0] + np.cos(gamma) * resid[:, 1]
    plan_len = np.hypot(de, dn)
    if plan.long:
        return _figure_residuals_along(result, plan, idx, resid, pxy, de, dn, is_check)
    fig = Figure(figsize=(10, 6.5))
    ax = fig.subplots()
    ax.plot(
        cxy[:, 0], cxy[:, 1], "-", color="#aab7b8", lw=1.0, zorder=1, label="projection centres"
    )
    extent = float(np.nanmax(np.ptp(np.vstack([cxy, pxy]), axis=0))) or 1.0
    largest = float(np.nanmax(plan_len)) if np.isfinite(plan_len).any() else 0.0
    key = _nice(largest) if largest > 0 else 0.1
    # arrow of the largest residual: 8 % of the extent
    scale = (largest if largest > 0 else key) / (0.08 * extent)
    has_plan = np.isfinite(plan_len)
    for sel, colour, label in ((~is_check, "#c0392b", "control"), (is_check, "#8e44ad", "check")):
        sel = sel & has_plan
        if sel.any():
            q = ax.quiver(
                pxy[sel, 0],
                pxy[sel, 1],
                de[sel],
                dn[sel],
                angles="xy",
                scale_units="xy",
                scale=scale,
                color=colour,
                width=0.0025,
                zorder=4,
                label=f"plan residual, {label}",
            )
    if has_plan.any():
        ax.quiverkey(
            q, 0.85, 0.04, key, f"{key:g} m", labelpos="E", coordinates="axes", color="black"
        )
    dh = resid[:, 2]
    has_h = np.isfinite(dh)
    if has_h.any():
        lim = float(np.nanmax(np.abs(dh))) or 1.0
        norm = TwoSlopeNorm(vcenter=0.0, vmin=-lim, vmax=lim)
        for sel, marker in ((~is_check, "^"), (is_check, "s")):
            sel = sel & has_h
            if sel.any():
                sc = ax.scatter(
                    pxy[sel, 0],
                    pxy[sel, 1],
                    c=dh[sel],
                    cmap="RdBu_r",
                    norm=norm,
                    marker=marker,
                    s=70,
                    edgecolors="black",
                    linewidths=0.5,
                    zorder=5,
                )
        bar = fig.colorbar(sc, ax=ax, shrink=0.8, pad=0.02)
        bar.set_label("height residual dH [m] (given − adjusted)")
    no_h = ~has_h
    if no_h.any():
        ax.scatter(
            pxy[no_h, 0],
            pxy[no_h, 1],
            facecolors="white",
            edgecolors="black",
            marker="o",
            s=30,
            zorder=5,
            label="no height residual",
        )
    names = np.asarray(result.point_ids, dtype=object)[idx]
    if idx.size <= 60:
        for (x, y), name in zip(pxy, names, strict=True):
            ax.annotate(
                str(name),
                (x, y),
                textcoords="offset points",
                xytext=(5, -10),
                fontsize=7,
                color="#333333",
            )
    _plan_axes(ax, plan)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)
    ax.set_title("Residuals at control (▲) and check (■) points: arrows plan, colour height")
    return _png(fig)


def _figure_residuals_along(result, plan, idx, resid, pxy, de, dn, is_check) -> str:
    """Residual components against the distance along a long strip (three panels)."""
    from matplotlib.figure import Figure

    along = plan.strip_axes(pxy)[:, 0]
    comp = plan.vectors_to_strip(de, dn)
    fig = Figure(figsize=(10, 7.5))
    axes = fig.subplots(3, 1, sharex=True)
    few = len(idx) <= 300
    panels = (
        (comp[:, 0], "along-strip residual [m]"),
        (comp[:, 1], "across-strip residual [m]"),
        (resid[:, 2], "height residual dH [m]"),
    )
    for ax, (values, label) in zip(axes, panels, strict=True):
        for sel, marker, colour, name in (
            (~is_check, "^", "#c0392b", "control"),
            (is_check, "s", "#8e44ad", "check"),
        ):
            sel = sel & np.isfinite(values)
            if sel.any():
                ax.scatter(
                    along[sel],
                    values[sel],
                    marker=marker,
                    c=colour,
                    s=28 if few else 6,
                    label=name,
                    linewidths=0.3 if few else 0.0,
                    **({"edgecolors": "black"} if few else {}),
                )
        ax.axhline(0.0, color="black", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"along the strip from the first photo [{plan.unit}]")
    axes[0].set_title("Residuals (given − adjusted) at control and check points along the strip")
    return _png(fig)


def _bars_or_lines(ax, x, values, labels, colours, width=0.4):
    many = len(x) > 120
    for k, (v, label, colour) in enumerate(zip(values, labels, colours, strict=True)):
        if many:
            ax.plot(x, v, "-", lw=0.9, color=colour, label=label)
        else:
            offset = (k - (len(values) - 1) / 2) * width
            ax.bar(x + offset, v, width=width, color=colour, label=label)


def _figure_parallax(result) -> str:
    from matplotlib.figure import Figure

    rel = result.strip.relative
    x = np.arange(rel.n_pairs)
    fig = Figure(figsize=(11, 3.8))
    (ax, hx) = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2.3, 1]})
    _bars_or_lines(
        ax,
        x,
        [np.asarray(rel.sigma0_um), np.asarray(rel.max_parallax_um)],
        ["σ0 (one image coordinate)", "max |y-parallax|"],
        ["#2e86c1", "#e67e22"],
    )
    ax.set_xlabel("pair (left photo's position in the strip)")
    ax.set_ylabel("µm at image scale")
    ax.set_title("Relative orientation: residual y-parallax per pair")
    ax.grid(True, axis="y", lw=0.3)
    ax.legend(fontsize=8)
    q = np.asarray(rel.parallax_um, dtype=np.float64)
    q = q[np.isfinite(q)]
    if q.size:
        rms = float(np.sqrt(np.mean(q**2)))
        hx.hist(q, bins=min(60, max(10, q.size // 20)), color="#5d6d7e")
        for sign in (-1, 1):
            hx.axvline(sign * 3 * rms, color="#c0392b", lw=1.0, ls="--")
        hx.set_title(f"All {q.size} y-parallaxes; ±3 RMS dashed", fontsize=10)
        hx.set_xlabel("µm")
    return _png(fig)


def _figure_ties(result, models: list[dict[str, Any]]) -> str | None:
    from matplotlib.figure import Figure

    if len(models) < 2:
        return None
    x = np.array([m["index"] for m in models], dtype=np.float64)
    rms = np.array(
        [[np.nan if v is None else v for v in m["tie_rms_m"]] for m in models], dtype=np.float64
    )
    plan = np.hypot(rms[:, 0], rms[:, 1])
    fig = Figure(figsize=(11, 3.6))
    ax = fig.subplots()
    _bars_or_lines(
        ax,
        x[1:],
        [plan[1:], np.abs(rms[1:, 2])],
        ["plan (X, Y)", "height (Z)"],
        ["#16a085", "#8e44ad"],
    )
    ax.set_xlabel("model (left photo's position in the strip)")
    ax.set_ylabel("RMS difference [m]")
    ax.set_title("Differences between the two determinations of tie points, per model")
    ax.grid(True, axis="y", lw=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


# --------------------------------------------------------------------------- report.html

_CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;color:#1c2833;
max-width:1150px;margin:24px auto;padding:0 18px;line-height:1.4}
h1{font-size:1.7em;margin-bottom:0.1em}h2{border-bottom:2px solid #d5d8dc;padding-bottom:3px;
margin-top:1.6em;font-size:1.3em}h3{font-size:1.05em;margin-bottom:0.3em}
.sub{color:#5d6d7e;margin-top:0}
table{border-collapse:collapse;margin:0.4em 0 1em 0;font-size:0.88em}
th,td{border:1px solid #d5d8dc;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#eaf2f8;text-align:center}td.l,th.l{text-align:left}
tr:nth-child(even) td{background:#fbfcfc}
.pass{color:#196f3d;font-weight:bold}.fail{color:#b03a2e;font-weight:bold}
.na{color:#7f8c8d}.verdict{font-size:1.15em;padding:6px 10px;display:inline-block;
border-radius:4px;margin:0.3em 0}
.verdict.pass{background:#d5f5e3}.verdict.fail{background:#fadbd8}.verdict.na{background:#eaeded}
figure{margin:0.6em 0 1.2em 0}figure img{max-width:100%;height:auto;border:1px solid #eaeded}
figcaption{color:#5d6d7e;font-size:0.88em}
.scroll{max-height:420px;overflow-y:auto;display:inline-block;border:1px solid #eaeded}
.scroll table{margin:0}
ul.warn li{color:#7e5109}
footer{margin-top:2em;color:#7f8c8d;font-size:0.8em}
"""


def _esc(value: Any) -> str:
    import html

    return html.escape(str(value), quote=True)


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(float(value)):
            return "–"
        return f"{float(value):.{digits}f}"
    return _esc(value)


def _table(
    header: list[str],
    rows: list[list[Any]],
    *,
    left: int = 1,
    left_columns: tuple[int, ...] = (),
    scroll: bool = False,
    digits: list[int] | int = 3,
) -> str:
    if not rows:
        return "<p class='na'>none</p>"
    if isinstance(digits, int):
        digits = [digits] * len(header)
    head = "".join(
        ("<th class='l'>" if i < left else "<th>") + f"{_esc(h)}</th>"
        for i, h in enumerate(header)
    )
    body = []
    for row in rows:
        cells = []
        for i, v in enumerate(row):
            text = v[0] if isinstance(v, tuple) else _fmt(v, digits[i])
            cls = " class='l'" if i < left or i in left_columns else ""
            cells.append(f"<td{cls}>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    html_table = f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    return f"<div class='scroll'>{html_table}</div>" if scroll and len(rows) > 25 else html_table


def _verdict_cell(passed: bool | None) -> tuple[str]:
    if passed is None:
        return ("<span class='na'>not judged</span>",)
    return ("<span class='pass'>PASS</span>",) if passed else ("<span class='fail'>FAIL</span>",)


def _figure(b64: str | None, caption: str, alt: str) -> str:
    if b64 is None:
        return f"<p class='na'>{_esc(caption)}: nothing to show.</p>"
    return (
        f"<figure><img alt='{_esc(alt)}' src='data:image/png;base64,{b64}'>"
        f"<figcaption>{_esc(caption)}</figcaption></figure>"
    )


def build_html(result, report: Mapping[str, Any]) -> str:
    """Text of ``report.html``: one self-contained page (inline PNG figures, no scripts).

    Parameters
    ----------
    result : StripResult
    report : mapping
        :func:`build_report` of the same result.
    """
    import matplotlib

    style = {
        "font.size": 9,
        "axes.titlesize": 11,
        "figure.subplot.left": 0.07,
        "figure.subplot.right": 0.97,
        "figure.subplot.bottom": 0.11,
        "figure.subplot.top": 0.91,
        "figure.subplot.hspace": 0.3,
        "figure.subplot.wspace": 0.18,
    }
    with matplotlib.rc_context(style):
        plan = _Plan(result)
        points = np.asarray(result.points, dtype=np.float64)
        finite = np.isfinite(points).all(axis=1)
        plan.decide_long(np.vstack([plan.xy(plan.centres), plan.xy(points[finite])]))
        roles = point_roles(result)
        fig_layout = _figure_layout(result, plan, roles)
        fig_resid = _figure_residuals(result, plan)
        fig_par = _figure_parallax(result)
        fig_ties = _figure_ties(result, report["models"])
    return _html_page(report, fig_layout, fig_resid, fig_par, fig_ties)


def _stat_rows(report: Mapping[str, Any]) -> list[list[Any]]:
    rows = []
    for key, label in (("control", "control (used)"), ("check", "check (not used)")):
        st = report[key]["statistics"]
        rows.append(
            [
                label,
                st["n_plan"],
                st["n_height"],
                st["rmse_e_m"],
                st["rmse_n_m"],
                st["rmse_h_m"],
                st["rmse_plan_m"],
                st["mean_plan_m"],
                st["max_plan_m"],
                st["max_height_m"],
            ]
        )
    return rows


def _html_page(report, fig_layout, fig_resid, fig_par, fig_ties) -> str:
    proj = report["project"]
    inp = report["inputs"]
    tol = report["tolerances"]
    name = proj["name"] or "Strip aerotriangulation"
    ctrl = inp["control"]
    overall = tol["passed"]
    overall_cls = "na" if overall is None else "pass" if overall else "fail"
    overall_text = (
        "not judged"
        if overall is None
        else "all judged criteria pass"
        if overall
        else "at least one criterion fails"
    )
    chk = report["check"]["statistics"]
    pairs = report["pairs"]
    sig = [p["sigma0_um"] for p in pairs if p["sigma0_um"] is not None]
    mx = [p["max_parallax_um"] for p in pairs if p["max_parallax_um"] is not None]
    opt = report["options"]
    summary = [
        ["CRS", (_esc(f"{proj['crs_name']}"),)],
        ["route to the ground", (_esc(report["ground"]["route"]),)],
        ["photos", inp["n_photos"]],
        [
            "points triangulated / measured",
            (f"{inp['n_points_triangulated']} / {inp['n_points']}",),
        ],
        ["image observations", inp["n_observations"]],
        [
            "control full / plan / height / check (given)",
            (f"{ctrl['full']} / {ctrl['plan']} / {ctrl['height']} / {ctrl['check']}",),
        ],
        [
            "control / check points compared",
            (f"{len(report['control']['points'])} / {len(report['check']['points'])}",),
        ],
        [
            "polynomial (requested → used)",
            (f"{_esc(opt['polynomial'])} → {report['polynomial']['kind']}",),
        ],
        ["image scale [m per mm]", report["ground"]["image_scale_m_per_mm"]],
        ["y-parallax σ0, median of pairs [µm]", float(np.median(sig)) if sig else None],
        ["largest y-parallax [µm]", float(np.max(mx)) if mx else None],
        [
            "check RMSE E / N / H [m]",
            (" / ".join(_fmt(chk[k]) for k in ("rmse_e_m", "rmse_n_m", "rmse_h_m")),),
        ],
        [
            "check RMSE plan / mean plan [m]",
            (f"{_fmt(chk['rmse_plan_m'])} / {_fmt(chk['mean_plan_m'])}",),
        ],
        [
            "map scale for the verdicts",
            ("–" if tol["map_scale"] is None else f"1:{tol['map_scale']:g}",),
        ],
        ["R4 §1.7.7 verdict", (f"<span class='{overall_cls}'>{_esc(overall_text)}</span>",)],
    ]
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        f"<title>{_esc(name)} – strip aerotriangulation report</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>{_esc(name)}</h1>",
        "<p class='sub'>Analytical strip aerotriangulation by partially dependent models"
        f" · strip_aerotri {_esc(report['software']['version'])}"
        f" · {_esc(report['created_utc'])}</p>",
        f"<div class='verdict {overall_cls}'>Tolerances (R4 §1.7.7): {_esc(overall_text)}</div>",
        "<h2>Summary</h2>",
        _table(["item", "value"], summary, left=1),
        "<h3>Accuracy at control and check points (given − adjusted, metres)</h3>",
        _table(
            [
                "set",
                "n plan",
                "n height",
                "RMSE E",
                "RMSE N",
                "RMSE H",
                "RMSE plan",
                "mean plan",
                "max plan",
                "max |dH|",
            ],
            _stat_rows(report),
            digits=3,
        ),
        "<h2>Figures</h2>",
        _figure(
            fig_layout,
            "Figure 1. Strip layout: projection centres, photo footprints at "
            "the mean height of its points, all points by role.",
            "strip layout",
        ),
        _figure(
            fig_resid,
            "Figure 2. Residuals (given − adjusted) at control and check "
            "points: plan as arrows (scale in the key), height as colour.",
            "residual vectors",
        ),
        _figure(
            fig_par,
            "Figure 3. Residual y-parallax of the relative orientation per pair "
            "(left) and of all points (right), µm at image scale.",
            "y-parallax",
        ),
        _figure(
            fig_ties,
            "Figure 4. RMS of the differences between the two determinations of "
            "the tie points of each model and the previous one, in metres.",
            "tie-point differences",
        ),
        "<h2>Tolerance verdicts (R4 §1.7.7)</h2>",
        _table(
            ["criterion", "source", "n", "value", "limit", "unit", "verdict", "explanation"],
            [
                [
                    c["name"],
                    c["source"],
                    c["n"],
                    c["value"],
                    c["limit"],
                    c["unit"],
                    _verdict_cell(c["passed"]),
                    (f"<span style='white-space:normal'>{_esc(c['explanation'])}</span>",),
                ]
                for c in tol["criteria"]
            ],
            left=2,
            left_columns=(7,),
            digits=[0, 0, 0, 4, 4, 0, 0, 0],
        ),
    ]
    parts += _html_tables(report)
    parts.append(
        "<footer>Residuals and discrepancies are given minus adjusted, along local east, "
        "north and up. photos.csv angles: R = Rx(ω)·Ry(φ)·Rz(κ) maps image vectors to local "
        "east-north-up. See docs/outputs.md for every figure of this report.</footer>"
        "</body></html>"
    )
    return "\n".join(parts)


def _plan_of(values, pick):
    """One plan figure from [E, N, H] values (``pick`` of the two), or None."""
    if not values:
        return None
    plan = [v for v in values[:2] if v is not None]
    return pick(plan) if plan else None


def _html_tables(report: Mapping[str, Any]) -> list[str]:
    out = ["<h2>Relative orientation per pair</h2>"]
    ro = report["relative_orientation"]
    names = ro["element_names"]
    units = ro["element_units"]
    el_head = [f"{n} [{u}]" if u else n for n, u in zip(names, units, strict=True)]
    out.append(
        _table(
            [
                "pair",
                "left",
                "right",
                "points",
                "iterations",
                "σ0 [µm]",
                "RMS q [µm]",
                "max q [µm]",
                *el_head,
            ],
            [
                [
                    p["index"],
                    p["left"],
                    p["right"],
                    p["n_points"],
                    p["iterations"],
                    p["sigma0_um"],
                    p["rms_parallax_um"],
                    p["max_parallax_um"],
                    *[p["elements"][n] for n in names],
                ]
                for p in report["pairs"]
            ],
            left=0,
            scroll=True,
            digits=[0, 0, 0, 0, 0, 2, 2, 2, 6, 6, 6, 6, 6],
        )
    )
    out.append("<h2>Models</h2>")
    out.append(
        _table(
            [
                "model",
                "left",
                "right",
                "points",
                "scale λ",
                "λ ratio",
                "tie points",
                "tie RMS X [m]",
                "tie RMS Y [m]",
                "tie RMS Z [m]",
            ],
            [
                [
                    m["index"],
                    m["left"],
                    m["right"],
                    m["n_points"],
                    m["scale"],
                    m["scale_ratio"],
                    m["tie_points"],
                    *m["tie_rms_m"],
                ]
                for m in report["models"]
            ],
            left=0,
            scroll=True,
            digits=[0, 0, 0, 0, 5, 5, 0, 3, 3, 3],
        )
    )
    sim = report["similarity"]
    out.append("<h2>Similarity transformation (strip system → work frame)</h2>")
    out.append(
        _table(
            [
                "scale",
                "ω [°]",
                "φ [°]",
                "κ [°]",
                "tX [m]",
                "tY [m]",
                "tZ [m]",
                "σ0",
                "redundancy",
                "iterations",
            ],
            [
                [
                    sim["scale"],
                    *sim["rotation_opk_deg"],
                    *sim["translation_m"],
                    sim["sigma0"],
                    sim["redundancy"],
                    sim["iterations"],
                ]
            ],
            left=0,
            digits=[4, 5, 5, 5, 3, 3, 3, 3, 0, 0],
        )
    )
    out.append("<h2>Control residuals (given − adjusted, m)</h2>")
    out.append(
        "<p>r: redundancy number of the component (the share of an error in it that shows "
        "in its residual); MDE: the smallest error the blunder test finds with 80 % "
        "probability (Baarda), m. <em>undetectable</em>: the component has no redundancy "
        "and an error in it cannot be found by any test; only more control can show it.</p>"
    )

    def mde_cell(p, k):
        if p.get("detectable", [None] * 3)[k] is False:
            return ("<em>undetectable</em>",)
        return p.get("mde_m", [None] * 3)[k]

    out.append(
        _table(
            ["point", "type", "dE", "dN", "dH", "plan", "r plan", "r H", "MDE plan", "MDE H"],
            [
                [
                    p["point"],
                    p["type"],
                    p["dE_m"],
                    p["dN_m"],
                    p["dH_m"],
                    p["plan_m"],
                    _plan_of(p.get("redundancy"), min),
                    (p.get("redundancy") or [None] * 3)[2],
                    mde_cell(p, 0)
                    if p.get("detectable", [None] * 3)[0] is False
                    else _plan_of(p.get("mde_m"), max),
                    mde_cell(p, 2),
                ]
                for p in report["control"]["points"]
            ],
            left=2,
            scroll=True,
            digits=[0, 0, 3, 3, 3, 3, 3, 3, 2, 2],
        )
    )
    out.append("<h2>Check-point discrepancies (given − adjusted, m)</h2>")
    out.append(
        _table(
            ["point", "type", "dE", "dN", "dH", "plan"],
            [
                [p["point"], p["type"], p["dE_m"], p["dN_m"], p["dH_m"], p["plan_m"]]
                for p in report["check"]["points"]
            ],
            left=2,
            scroll=True,
        )
    )
    adj = report.get("model_adjustment")
    if adj:
        out.append("<h2>Every model at once (block = models, R4 §3)</h2>")
        out.append(
            f"<p>Each model transformed by its own 3D similarity onto the control and onto "
            f"the other models on their common points and projection centres: σ0 = "
            f"{_fmt(adj['sigma0'])}, redundancy {adj['redundancy']}, {adj['iterations']} "
            f"iteration(s). The discrepancies are each model's determination of a point "
            f"minus the adjusted point (R4 §2.2's differences between determinations), "
            f"along the strip (X), across it (Y) and in height (Z); RMS over all "
            f"{'X, Y, Z'}: {', '.join(_fmt(v) for v in adj['discrepancy_rms_m'])} m.</p>"
        )
        out.append(
            _table(
                ["model", "pair", "scale", "RMS X [m]", "RMS Y [m]", "RMS Z [m]"],
                [
                    [m["index"], m["label"], m["scale"], *m["discrepancy_rms_m"]]
                    for m in adj["models"]
                ],
                left=2,
                scroll=True,
                digits=[0, 0, 6, 3, 3, 3],
            )
        )
    poly = report["polynomial"]
    out.append("<h2>Deformation polynomials (J(16))</h2>")
    if adj:
        out.append(
            "<p class='na'>Not used: every model has its own similarity (block = models); "
            'J\'s polynomials are block = "strips".</p>'
        )
    elif poly.get("coefficients_m"):
        terms = poly["terms"]
        sections = int(poly.get("sections", 1))
        spline_text = ""
        if sections > 1:
            breaks = ", ".join(_fmt(x, 1) for x in poly["breakpoints_x_m"])
            spline_text = (
                f" In {sections} sections along the strip (breakpoints at X = {breaks} m of the "
                "work frame): each polynomial is f(u) + v g(u) with f a spline of the type's "
                "degree and g piecewise linear, joined without steps; f0… and Y·g0… are their "
                "B-spline coefficients."
            )
        out.append(
            f"<p>Type {poly['kind']} (X, Y, Z types {poly['kinds_xyz']}); normalised "
            f"variables u = (X − X0)/h, v = (Y − Y0)/h with h = "
            f"{_fmt(poly['normalization']['half_extent_m'], 1)} m; σ0 = "
            f"{_fmt(poly['sigma0'])}, redundancy {poly['redundancy']}. Coefficients in metres."
            f"{spline_text}</p>"
        )
        out.append(
            _table(
                ["coordinate", *terms],
                [[axis, *poly["coefficients_m"][axis]] for axis in "XYZ"],
                left=1,
                digits=4,
                scroll=sections > 1,
            )
        )
    else:
        out.append("<p class='na'>Similarity only (type 0).</p>")
    if poly.get("auto"):
        out.append("<h3>Automatic choice of the type</h3>")
        out.append(
            _table(
                [
                    "type",
                    "feasible",
                    "σ0",
                    "redundancy",
                    "RMS X [m]",
                    "RMS Y [m]",
                    "RMS Z [m]",
                    "accepted",
                    "note",
                ],
                [
                    [
                        r["kind"],
                        r["feasible"],
                        r["sigma0"],
                        r["redundancy"],
                        *r["rms_xyz_m"],
                        r["passed"],
                        r["reason"],
                    ]
                    for r in poly["auto"]["table"]
                ],
                left=1,
                digits=[0, 0, 3, 0, 3, 3, 3, 0, 0],
            )
        )
    if report["straight_lines"]:
        out.append("<h2>Straight lines (J(18))</h2>")
        out.append(
            _table(
                ["line", "weight", "points", "a [m]", "b", "RMS [m]", "max |dY| [m]"],
                [
                    [
                        ln["name"],
                        ln["weight"],
                        ln["n_points"],
                        ln["a_m"],
                        ln["b"],
                        ln["rms_m"],
                        ln["max_abs_m"],
                    ]
                    for ln in report["straight_lines"]
                ],
                left=1,
                digits=[0, 1, 0, 3, 6, 3, 3],
            )
        )
    out += _html_gnss_imu(report)
    out.append("<h2>Gross errors (data snooping, method.md §7)</h2>")
    out.append(
        _table(
            [
                "stage",
                "point",
                "photos / line",
                "tested",
                "residual",
                "unit",
                "w",
                "critical",
                "rejected",
                "effect",
            ],
            [
                [
                    r["stage"],
                    r["point"],
                    "-".join(r["photos"]),
                    r["component"],
                    r["residual"],
                    r["unit"],
                    r["w"],
                    r["critical"],
                    "yes"
                    if r["applied"]
                    else (
                        "no (kept)" if str(r["effect"]).startswith("kept") else "no (report only)"
                    ),
                    r["effect"],
                ]
                for r in report.get("rejections", [])
            ],
            left=4,
            left_columns=(5, 8, 9),
            digits=[0, 0, 0, 0, 4, 0, 2, 2, 0, 0],
        )
    )
    out.append("<h2>Warnings</h2>")
    if report["warnings"]:
        out.append(
            "<ul class='warn'>"
            + "".join(f"<li>{_esc(w)}</li>" for w in report["warnings"])
            + "</ul>"
        )
    else:
        out.append("<p class='na'>none</p>")
    out.append("<h2>Options and timings</h2>")
    out.append(
        _table(["option", "value"], [[k, (_esc(v),)] for k, v in report["options"].items()])
    )
    out.append(
        _table(["stage", "seconds"], [[k, v] for k, v in report["timings_s"].items()], digits=3)
    )
    return out


def _html_gnss_imu(report: Mapping[str, Any]) -> list[str]:
    """Section on the GNSS centres and IMU attitudes of the bundle refinement (or nothing)."""
    bundle = report.get("bundle") or {}
    gnss, imu = bundle.get("gnss"), bundle.get("imu")
    if gnss is None and imu is None:
        return []
    out = [
        "<h2>Bundle refinement: GNSS centres and IMU attitudes</h2>",
        "<p>Residuals are observed − adjusted: GNSS projection centres in metres along "
        "local east, north, up at the adjusted centre; IMU attitudes in degrees as the "
        "small rotation about the photo's image axes x (along the flight), y (to its "
        "left), z (up). r: redundancy numbers; w: Baarda's test at the a-priori σ, "
        "critical value by Bonferroni over the components. A failing centre or attitude "
        "is rejected as a whole by the bundle's data snooping (stages gnss, imu: see "
        "the warnings); rejected ones stay listed with their residuals.</p>",
    ]

    def largest(sec: Mapping[str, Any]) -> tuple[str]:
        if sec["max_abs_w"] is None:
            return ("– (precision not computed)",)
        return (f"{sec['max_abs_w']:.2f} (photo {_esc(sec['max_abs_w_photo'])})",)

    def counts(sec: Mapping[str, Any]) -> tuple[str]:
        text = f"{sec['n_used']} / {sec['n_given']}"
        if sec["n_unmatched"]:
            text += f" ({sec['n_unmatched']} not in the strip: " + ", ".join(
                _esc(p) for p in sec["unmatched_photos"][:10]
            )
            text += " …)" if sec["n_unmatched"] > 10 else ")"
        return (text,)

    rows: list[list[Any]] = []
    if gnss is not None:
        rows += [
            ["GNSS centres used / given", counts(gnss)],
            [
                "GNSS σ a-priori plan / height [m] (median)",
                (f"{_fmt(gnss['sigma_xy_m'])} / {_fmt(gnss['sigma_z_m'])}",),
            ],
            [
                "GNSS RMS E / N / U [m]",
                (" / ".join(_fmt(gnss[k]) for k in ("rms_e_m", "rms_n_m", "rms_u_m")),),
            ],
            [
                "GNSS largest plan / |U| [m]",
                (f"{_fmt(gnss['max_plan_m'])} / {_fmt(gnss['max_u_m'])}",),
            ],
            [
                "GNSS largest |w| / critical",
                (f"{largest(gnss)[0]} / {_fmt(gnss['critical_w'], 2)}",),
            ],
            ["GNSS centres failing the test", gnss["n_failed"]],
        ]
    if imu is not None:
        rows += [
            ["IMU attitudes used / given", counts(imu)],
            ["IMU σ a-priori [°] (median)", (_fmt(imu["sigma_deg"], 4),)],
            ["IMU RMS x / y / z [°]", (" / ".join(_fmt(v, 4) for v in imu["rms_deg"]),)],
            [
                "IMU largest |x| / |y| / |z| [°]",
                (" / ".join(_fmt(v, 4) for v in imu["max_abs_deg"]),),
            ],
            ["IMU largest |w| / critical", (f"{largest(imu)[0]} / {_fmt(imu['critical_w'], 2)}",)],
            ["IMU attitudes failing the test", imu["n_failed"]],
        ]
    out.append(_table(["item", "value"], rows, left=1))

    def failed_cell(value: bool | None, rejected: bool = False) -> tuple[str]:
        if rejected:
            return ("<span class='fail'>rejected</span>",)
        if value is None:
            return ("<span class='na'>–</span>",)
        return ("<span class='fail'>FAIL</span>",) if value else ("<span class='pass'>ok</span>",)

    if gnss is not None and gnss["photos"]:
        out.append("<h3>GNSS centres (observed − adjusted, m)</h3>")
        out.append(
            _table(
                ["photo", "dE", "dN", "dU", "plan", "σ plan", "σ height", "r E", "r N", "r U",
                 "w E", "w N", "w U", "test"],
                [
                    [ph["photo"], ph["dE_m"], ph["dN_m"], ph["dU_m"], ph["plan_m"],
                     ph["sigma_xy_m"], ph["sigma_z_m"], *ph["redundancy"], *ph["w"],
                     failed_cell(ph["failed"], ph.get("rejected", False))]
                    for ph in gnss["photos"]
                ],
                left=1,
                scroll=True,
                digits=[0, 3, 3, 3, 3, 3, 3, 2, 2, 2, 2, 2, 2, 0],
            )
        )  # fmt: skip
    if imu is not None and imu["photos"]:
        out.append("<h3>IMU attitudes (observed − adjusted, degrees)</h3>")
        out.append(
            _table(
                ["photo", "about x", "about y", "about z", "dω", "dφ", "dκ", "σ", "r x", "r y",
                 "r z", "w x", "w y", "w z", "test"],
                [
                    [ph["photo"], ph["rx_deg"], ph["ry_deg"], ph["rz_deg"], ph["d_omega_deg"],
                     ph["d_phi_deg"], ph["d_kappa_deg"], ph["sigma_deg"], *ph["redundancy"],
                     *ph["w"], failed_cell(ph["failed"], ph.get("rejected", False))]
                    for ph in imu["photos"]
                ],
                left=1,
                scroll=True,
                digits=[0, 4, 4, 4, 4, 4, 4, 4, 2, 2, 2, 2, 2, 2, 0],
            )
        )  # fmt: skip
    return out


# --------------------------------------------------------------------------- all files


def build_outputs(
    result, *, project=None, map_scale: float | None = None, html: bool = True
) -> dict[str, bytes]:
    """Every file of a result folder, name -> content (UTF-8 bytes).

    Parameters
    ----------
    result : StripResult
    project : Project, optional
        Gives the report its name, files and options.
    map_scale : float, optional
        Map scale denominator for the tolerance verdicts (overrides the
        project's ``[report] map_scale``).
    html : bool
        Also build ``report.html`` (matplotlib figures; the slowest part).

    Returns
    -------
    dict of str to bytes
        ``points.csv``, ``photos.csv``, ``report.json``, ``report.html`` and,
        unless the CRS is ``"local"``, ``points.geojson`` (see
        docs/outputs.md).  When the GeoJSON is left out, ``report.json``
        says so under ``warnings``.
    """
    notes: list[str] = []
    geojson = points_geojson(result)
    if geojson is None:
        notes.append('points.geojson not written: crs is "local" (no geodesy to WGS 84)')
    report = build_report(result, project=project, map_scale=map_scale, notes=notes)
    if geojson is not None:
        report["outputs"]["points.geojson"] = {
            "written": True,
            "wgs84_operation": result.ground.crs.wgs84_operation,
        }
    files = {
        "points.csv": points_csv(result).encode("utf-8"),
        "photos.csv": photos_csv(result).encode("utf-8"),
    }
    if geojson is not None:
        files["points.geojson"] = (geojson + "\n").encode("utf-8")
    if html:
        files["report.html"] = build_html(result, report).encode("utf-8")
    files["report.json"] = (
        json.dumps(report, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
    ).encode("utf-8")
    return files


def _bundle(result: Any) -> dict[str, Any] | None:
    """The bundle refinement's figures, when it was run (docs/bundle.md)."""
    refined = getattr(result, "refined", None)
    if refined is None:
        return None
    return {
        "frame": refined.frame_description,
        "sigma0": _f(refined.sigma0) if hasattr(refined, "sigma0") else None,
        "redundancy": int(refined.redundancy),
        "iterations": int(refined.iterations),
        "converged": bool(refined.converged),
        "n_observations": int(refined.n_observations),
        "control": _statistics(refined.control_statistics),
        "check": _statistics(refined.check_statistics),
        "point_std_median_m": _column_medians(refined.point_std),
        "centre_std_median_m": _column_medians(refined.centre_std),
        "rejections": [r.describe() for r in refined.rejections],
        "strip_method_check": _statistics(result.check_statistics),
        "gnss": _bundle_gnss(getattr(refined, "gnss", None)),
        "imu": _bundle_imu(getattr(refined, "imu", None)),
    }


def _column_medians(values: Any) -> list[float | None]:
    """Median of the finite values of each column (None for a column without any)."""
    a = np.asarray(values, dtype=np.float64)
    out: list[float | None] = []
    for col in a.T:
        col = col[np.isfinite(col)]
        out.append(_f(np.median(col)) if col.size else None)
    return out


def _largest_w(photo_ids: Sequence[str], w: np.ndarray) -> tuple[float | None, str | None]:
    """Largest |w| over the photos and the photo it belongs to (None, None if none)."""
    a = np.abs(np.asarray(w, dtype=np.float64))
    if a.size == 0 or not np.isfinite(a).any():
        return None, None
    row_max = np.max(np.where(np.isfinite(a), a, -np.inf), axis=1)
    i = int(np.argmax(row_max))
    return float(row_max[i]), photo_ids[i]


def _test_summary(out: Any) -> dict[str, Any]:
    rejected = np.asarray(out.rejected, dtype=bool)
    redundancy = np.asarray(out.redundancy, dtype=np.float64)[~rejected]
    max_w, max_w_photo = _largest_w(out.photo_ids, out.w)
    tested = bool(np.isfinite(np.asarray(out.w, dtype=np.float64)).any())
    return {
        "redundancy_sum": _f(np.sum(redundancy)) if redundancy.size else None,
        "critical_w": _f(out.critical),
        "max_abs_w": max_w,
        "max_abs_w_photo": max_w_photo,
        "n_failed": int(np.count_nonzero(out.failed)) if tested else None,
        "n_rejected": int(np.count_nonzero(rejected)),
    }


def _counts(out: Any) -> dict[str, Any]:
    """Observations given, used and not in the strip (GNSS centres or IMU attitudes)."""
    return {
        "n_given": int(out.n_given),
        "n_used": int(out.n_used),
        "n_unmatched": len(out.unmatched),
        "unmatched_photos": list(out.unmatched),
    }


def _photo_failed(out: Any) -> list[bool | None]:
    """Per photo: some component failed its test; None where none was tested."""
    tested = np.isfinite(np.asarray(out.w, dtype=np.float64)).any(axis=1)
    return [bool(f) if t else None for f, t in zip(np.asarray(out.failed), tested, strict=True)]


def _bundle_gnss(out: Any) -> dict[str, Any] | None:
    """GNSS centres in the bundle refinement: counts, residuals, tests (docs/outputs.md)."""
    if out is None:
        return None
    v = np.asarray(out.residuals, dtype=np.float64)
    rms = out.rms
    failed = _photo_failed(out)
    return {
        "residual": "observed - adjusted",
        "axes": "east, north, up at the adjusted projection centre (ground metres)",
        **_counts(out),
        "sigma_xy_m": _f(np.median(out.sigma_xy)) if out.n_used else None,
        "sigma_z_m": _f(np.median(out.sigma_z)) if out.n_used else None,
        "rms_e_m": _f(rms[0]),
        "rms_n_m": _f(rms[1]),
        "rms_u_m": _f(rms[2]),
        "rms_plan_m": _f(out.rms_plan),
        "max_plan_m": _f(out.max_plan),
        "max_u_m": _f(out.max_up),
        **_test_summary(out),
        "photos": [
            {
                "photo": pid,
                "dE_m": _f(v[i, 0]),
                "dN_m": _f(v[i, 1]),
                "dU_m": _f(v[i, 2]),
                "plan_m": _f(out.plan[i]),
                "sigma_xy_m": _f(out.sigma_xy[i]),
                "sigma_z_m": _f(out.sigma_z[i]),
                "redundancy": np.asarray(out.redundancy[i], dtype=np.float64),
                "w": np.asarray(out.w[i], dtype=np.float64),
                "failed": failed[i],
                "rejected": bool(out.rejected[i]),
            }
            for i, pid in enumerate(out.photo_ids)
        ],
    }


def _bundle_imu(out: Any) -> dict[str, Any] | None:
    """IMU attitudes in the bundle refinement: counts, residuals, tests (docs/outputs.md)."""
    if out is None:
        return None
    v = np.degrees(np.asarray(out.residuals, dtype=np.float64))
    d_opk = np.degrees(np.asarray(out.opk_differences, dtype=np.float64))
    failed = _photo_failed(out)
    return {
        "residual": "observed - adjusted",
        "axes": "rotation vector about the photo's image axes x, y, z (x along the flight)",
        **_counts(out),
        "sigma_deg": _f(np.degrees(np.median(out.sigma))) if out.n_used else None,
        "rms_deg": np.degrees(out.rms),
        "max_abs_deg": np.degrees(out.max_abs),
        "rms_opk_deg": (
            np.sqrt(np.mean(d_opk[~np.asarray(out.rejected)] ** 2, axis=0))
            if out.n_used
            else [None] * 3
        ),
        **_test_summary(out),
        "photos": [
            {
                "photo": pid,
                "rx_deg": _f(v[i, 0]),
                "ry_deg": _f(v[i, 1]),
                "rz_deg": _f(v[i, 2]),
                "d_omega_deg": _f(d_opk[i, 0]),
                "d_phi_deg": _f(d_opk[i, 1]),
                "d_kappa_deg": _f(d_opk[i, 2]),
                "sigma_deg": _f(np.degrees(out.sigma[i])),
                "redundancy": np.asarray(out.redundancy[i], dtype=np.float64),
                "w": np.asarray(out.w[i], dtype=np.float64),
                "failed": failed[i],
                "rejected": bool(out.rejected[i]),
            }
            for i, pid in enumerate(out.photo_ids)
        ],
    }
