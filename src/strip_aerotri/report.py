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
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import __version__
from .io import format_photos_csv, format_points_csv
from .observations import ControlType
from .quality import tolerance_verdicts
from .rotation import opk_from_matrix

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
_TERM_NAMES = ("1", "X", "Y", "XY", "X^2", "X^3")


# --------------------------------------------------------------------------- helpers


def _clean(value: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, NaN/inf -> None."""
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
    if hasattr(value, "value") and isinstance(value.value, str):  # Enum
        return value.value
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
    two or more models), ``model`` (in one model only), ``none`` (not
    triangulated).
    """
    strip = result.strip
    n_det = np.asarray(strip.n_determinations)
    roles = np.where(n_det >= 2, "tie", np.where(n_det == 1, "model", "none")).astype(object)
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
        result.ground.photo_opk,
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
        terms = list(_TERM_NAMES[: coef.shape[1]])
        out.update(
            {
                "kinds_xyz": [int(k) for k in deformation.kinds],
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
    for k in np.flatnonzero(is_check == check):
        r = resid[k]
        kind = result.control.kind[rows[k]]
        out.append(
            {
                "point": result.point_ids[idx[k]],
                "type": str(getattr(kind, "value", kind)),
                "dE_m": _f(r[0]),
                "dN_m": _f(r[1]),
                "dH_m": _f(r[2]),
                "plan_m": _f(np.hypot(r[0], r[1])),
            }
        )
    return out


def _options(result, project) -> dict[str, Any]:
    strip_opt = result.strip.options
    opts: dict[str, Any] = {
        "route": result.ground.route,
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
    return opts


def build_report(result, *, project=None, map_scale: float | None = None) -> dict[str, Any]:
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
        "warnings": list(result.warnings),
        "timings_s": dict(result.timings),
    }
    return _clean(report)


# --------------------------------------------------------------------------- all files


def build_outputs(result, *, project=None, map_scale: float | None = None) -> dict[str, bytes]:
    """Every file of a result folder, name -> content (UTF-8 bytes).

    Parameters
    ----------
    result : StripResult
    project : Project, optional
        Gives the report its name, files and options.
    map_scale : float, optional
        Map scale denominator for the tolerance verdicts (overrides the
        project's ``[report] map_scale``).

    Returns
    -------
    dict of str to bytes
        ``points.csv``, ``photos.csv``, ``report.json`` (see docs/outputs.md).
    """
    report = build_report(result, project=project, map_scale=map_scale)
    return {
        "points.csv": points_csv(result).encode("utf-8"),
        "photos.csv": photos_csv(result).encode("utf-8"),
        "report.json": (
            json.dumps(report, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
        ).encode("utf-8"),
    }
