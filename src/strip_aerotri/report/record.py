"""``report.json``: :func:`build_report` gives every stage's figures as plain
Python (dict, list, str, int, float, bool, None; never NaN), described in
``docs/outputs.md``.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .._version import __version__
from ..geometry.rotation import opk_from_matrix
from ..observations import ControlType
from ..results import AccuracyStatistics, StripResult
from .tolerances import plan_drift_warning, tolerance_verdicts
from .values import (
    clean,
    control_rows,
    delivered_points,
    json_float,
    options_record,
    statistics,
)
from .verdict import with_verdict

if TYPE_CHECKING:
    from ..project import Project

REPORT_FORMAT = "stripaero-report"


REPORT_FORMAT_VERSION = 1


def _element_names(method: str) -> tuple[list[str], list[str]]:
    if method == "base":
        return ["alpha1", "chi1", "alpha2", "omega2", "chi2"], ["deg"] * 5
    return ["b_y", "b_z", "a", "b", "c"], ["strip", "strip", "", "", ""]


def _model_photos(result: StripResult) -> tuple[list[str], list[str]]:
    """The left and the right photo of every pair (model): consecutive photos,
    or every k-th one when the strip was formed with a photo step k."""
    strip = result.strip
    ids = strip.photo_ids
    pos = strip.model_photo_positions
    return [ids[i] for i in pos[:-1]], [ids[i] for i in pos[1:]]


def _pairs(result: StripResult) -> list[dict[str, Any]]:
    strip = result.strip
    rel = strip.relative
    method = str(getattr(rel.method, "value", rel.method))
    names, _ = _element_names(method)
    elements = np.asarray(rel.elements, dtype=np.float64)
    if method == "base":
        elements = np.degrees(elements)
    left, right = _model_photos(result)
    n_points = np.asarray(rel.n_points).astype(np.int64).tolist()
    iterations = np.asarray(rel.iterations).astype(np.int64).tolist()
    sigma0 = _json_floats(rel.sigma0_um)
    rms = _json_floats(rel.rms_parallax_um)
    largest = _json_floats(rel.max_parallax_um)
    values = _json_floats(elements.reshape(-1, len(names)))
    return [
        {
            "index": m,
            "left": left[m],
            "right": right[m],
            "n_points": n_points[m],
            "iterations": iterations[m],
            "sigma0_um": sigma0[m],
            "rms_parallax_um": rms[m],
            "max_parallax_um": largest[m],
            "elements": dict(zip(names, values[m], strict=True)),
        }
        for m in range(rel.n_pairs)
    ]


def model_records(result: StripResult) -> list[dict[str, Any]]:
    """report.json's ``models``: each model's photos, points, scale and tie differences."""
    strip = result.strip
    scale = float(result.ground.similarity.transform.scale)
    n_pts = np.bincount(np.asarray(strip.model), minlength=strip.n_models)
    tie_rms = np.asarray(strip.tie_rms, dtype=np.float64).reshape(-1, 3)
    left, right = _model_photos(result)
    plan = np.hypot(tie_rms[:, 0], tie_rms[:, 1]) * scale
    columns = zip(
        n_pts.tolist(),
        _json_floats(strip.scale),
        _json_floats(strip.scale_ratio),
        np.asarray(strip.tie_count).astype(np.int64).tolist(),
        _json_floats(tie_rms),
        _json_floats(tie_rms * scale),
        _json_floats(plan),
        strict=True,
    )
    return [
        {
            "index": m,
            "left": left[m],
            "right": right[m],
            "n_points": points,
            "scale": model_scale,
            "scale_ratio": ratio,
            "tie_points": ties,
            "tie_rms_strip": rms_strip,
            "tie_rms_m": rms_m,
            "tie_rms_plan_m": plan_m,
        }
        for m, (points, model_scale, ratio, ties, rms_strip, rms_m, plan_m) in enumerate(columns)
    ]


def _similarity(result: StripResult) -> dict[str, Any]:
    sim = result.ground.similarity
    tr = sim.transform
    rotation = np.asarray(tr.rotation, dtype=np.float64)
    resid = np.asarray(sim.residuals, dtype=np.float64).reshape(-1, 3)
    return {
        "scale": json_float(tr.scale),
        "rotation_opk_deg": [json_float(v) for v in opk_from_matrix(rotation, degrees=True)],
        "rotation_matrix": rotation,
        "translation_m": np.asarray(tr.translation, dtype=np.float64),
        "sigma0": json_float(sim.sigma0),
        "redundancy": int(sim.redundancy),
        "iterations": int(sim.iterations),
        "residuals": [
            {
                "point": pid,
                "dX_m": json_float(r[0]),
                "dY_m": json_float(r[1]),
                "dZ_m": json_float(r[2]),
            }
            for pid, r in zip(sim.point_ids, resid, strict=True)
        ],
    }


def _polynomial(result: StripResult, requested: Any) -> dict[str, Any]:
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
                "coefficients_m": {
                    axis: [json_float(v) for v in coef[i]] for i, axis in enumerate("XYZ")
                },
                "normalization": {
                    "centre_m": np.asarray(deformation.normalization.centre, dtype=np.float64),
                    "half_extent_m": json_float(deformation.normalization.half_extent),
                },
                "sigma0": json_float(deformation.sigma0),
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
                    "sigma0": json_float(row.sigma0),
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


def _lines(result: StripResult, weights: Mapping[str, float]) -> list[dict[str, Any]]:
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
                "weight": json_float(weights[name]) if name in weights else None,
                "n_points": len(ids),
                "a_m": None if ab is None else json_float(ab[0]),
                "b": None if ab is None else json_float(ab[1]),
                "rms_m": json_float(np.sqrt(np.mean(resid**2))) if resid.size else None,
                "max_abs_m": json_float(np.max(np.abs(resid))) if resid.size else None,
                "residuals": [
                    {"point": p, "dY_m": json_float(v)} for p, v in zip(ids, resid, strict=True)
                ],
            }
        )
    return out


def _all_check_statistics(result: StripResult) -> AccuracyStatistics:
    """The check statistics over every check point determined, the weakly
    determined ones included (``statistics`` leaves them out)."""
    _, resid = control_rows(result)
    return AccuracyStatistics.from_residuals(resid[np.asarray(result.ground.is_check, dtype=bool)])


def _json_floats(values: np.ndarray) -> list[Any]:
    """:func:`.values.json_float` of every value of a column (N,) or table (N, k)."""
    table = np.asarray(values, dtype=np.float64)
    finite = math.isfinite
    if table.ndim == 1:
        return [v if finite(v) else None for v in table.tolist()]
    return [[v if finite(v) else None for v in row] for row in table.tolist()]


def _control_points(result: StripResult, check: bool) -> list[dict[str, Any]]:
    """report.json's control or check points: every row's columns at once."""
    ground = result.ground
    idx, resid = control_rows(result)
    is_check = np.asarray(ground.is_check, dtype=bool)
    rows = np.asarray(ground.control_index, dtype=np.intp)
    red = np.asarray(getattr(ground, "control_redundancy", np.zeros((0, 3))), dtype=np.float64)
    mde = np.asarray(getattr(ground, "control_mde", np.zeros((0, 3))), dtype=np.float64)
    have = red.shape[0] == rows.shape[0]
    ks = np.flatnonzero(is_check == check)
    kinds = [result.control.kind[r] for r in rows[ks].tolist()]
    columns: dict[str, list[Any]] = {
        "point": [result.point_ids[i] for i in idx[ks].tolist()],
        "type": [str(getattr(kind, "value", kind)) for kind in kinds],
        "dE_m": _json_floats(resid[ks, 0]),
        "dN_m": _json_floats(resid[ks, 1]),
        "dH_m": _json_floats(resid[ks, 2]),
        "plan_m": _json_floats(np.hypot(resid[ks, 0], resid[ks, 1])),
    }
    if not check:
        xy = np.asarray(ground.used_xy, dtype=bool)[ks]
        used = np.column_stack([xy, xy, np.asarray(ground.used_h, dtype=bool)[ks]])
        if have:
            off = ~used
            columns["redundancy"] = _json_floats(np.where(off, np.nan, red[ks]))
            columns["mde_m"] = _json_floats(np.where(off, np.nan, mde[ks]))
            detectable = np.isfinite(mde[ks]).tolist()
            columns["detectable"] = [
                [d if u else None for d, u in zip(row, use, strict=True)]
                for row, use in zip(detectable, used.tolist(), strict=True)
            ]
        else:
            for name in ("redundancy", "mde_m", "detectable"):
                columns[name] = [[None] * 3 for _ in range(ks.size)]
    names = list(columns)
    records = zip(*columns.values(), strict=True)
    return [dict(zip(names, values, strict=True)) for values in records]


def _model_adjustment(result: StripResult) -> dict[str, Any] | None:
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
        "sigma0": json_float(res.sigma0),
        "redundancy": int(res.redundancy),
        "iterations": int(res.iterations),
        "converged": bool(res.converged),
        "discrepancy_rms_m": [json_float(v) for v in np.sqrt(np.nanmean(disc**2, axis=0))]
        if disc.size
        else [None] * 3,
        "models": [
            {
                "index": m,
                "label": labels[m] if m < len(labels) else str(m),
                "scale": model_scale,
                "discrepancy_rms_m": model_rms,
                "left_centre_m": left,
                "right_centre_m": right,
            }
            for m, (model_scale, model_rms, left, right) in enumerate(
                zip(
                    _json_floats(np.asarray(res.transforms.scale)[: rms.shape[0]]),
                    _json_floats(rms),
                    _json_floats(centres[:, 0]),
                    _json_floats(centres[:, 1]),
                    strict=True,
                )
            )
        ],
        "rejected": [{"model": m, "point": p} for m, p in models.rejected],
    }


def tolerances_record(result: StripResult, map_scale: float | None) -> dict[str, Any]:
    """report.json's ``tolerances``: the criteria, their verdicts and the words
    (the run's summary takes its verdict from here too)."""
    criteria = tolerance_verdicts(result, map_scale)
    judged = [c.passed for c in criteria if c.passed is not None]
    return with_verdict(
        {
            "map_scale": None if map_scale is None else float(map_scale),
            "passed": None if not judged else all(judged),
            "criteria": [c.as_dict() for c in criteria],
        }
    )


def drift_warnings(result: StripResult, map_scale: float | None) -> list[str]:
    """The warnings the report adds at the map scale (the plan drift between
    the control, :func:`~.tolerances.plan_drift_warning`)."""
    return [w for w in (plan_drift_warning(result, map_scale),) if w is not None]


def build_report(
    result: StripResult,
    *,
    project: Project | None = None,
    map_scale: float | None = None,
    notes: Sequence[str] = (),
) -> dict[str, Any]:
    """Content of ``report.json`` (plain JSON types; NaN written as None).

    Parameters
    ----------
    result : StripResult
        The run's result (:func:`strip_aerotri.pipeline.triangulate`).
    project : Project, optional
        The loaded project (:func:`strip_aerotri.project.load_project`): name,
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
    frame = ground.frame
    options = options_record(result.options)
    if options is None:
        raise ValueError("Expected a result of triangulate(), which carries its options")
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
            "n_points_triangulated": delivered_points(result),
            "n_observations": len(obs.photo),
            "principal_distance_mm": json_float(obs.principal_distance),
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
        "options": options,
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
        "models": model_records(result),
        "ground": {
            "route": ground.route,
            "construction": str(getattr(getattr(ground, "construction", None), "value", "strips")),
            "azimuth_deg": json_float(np.degrees(ground.azimuth)),
            "passes": int(ground.passes),
            "passes_converged": bool(ground.passes_converged),
            "image_scale_m_per_mm": json_float(ground.image_scale),
            "expected_sigma_plan_m": json_float(ground.expected_sigma_plan),
            "expected_sigma_height_m": json_float(ground.expected_sigma_height),
            "tangent_frame": None
            if frame is None
            else {
                "origin_ecef_m": np.asarray(frame.origin_ecef, dtype=np.float64),
                "latitude_deg": json_float(np.degrees(frame.latitude)),
                "longitude_deg": json_float(np.degrees(frame.longitude)),
            },
        },
        "model_adjustment": _model_adjustment(result),
        "similarity": _similarity(result),
        "polynomial": _polynomial(result, options["polynomial"]),
        "straight_lines": _lines(result, weights),
        "control": {
            "statistics": statistics(result.control_statistics),
            "points": _control_points(result, check=False),
        },
        "check": {
            "statistics": statistics(result.check_statistics),
            "points": _control_points(result, check=True),
            "weakly_determined": list(getattr(result, "weak_checks", ())),
            "statistics_with_weak": statistics(_all_check_statistics(result)),
        },
        "tolerances": tolerances_record(result, map_scale),
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
        # plain strings (a PointWarning is a str with its point's id as data)
        "warnings": [
            str(w) for w in (*result.warnings, *notes, *drift_warnings(result, map_scale))
        ],
        "timings_s": dict(result.timings),
        "outputs": {
            "points.geojson": {
                "written": not ground.crs.is_local,
                "wgs84_operation": None,
            }
        },
    }
    cleaned: dict[str, Any] = clean(report)
    return cleaned


def _bundle(result: StripResult) -> dict[str, Any] | None:
    """The bundle refinement's figures, when it was run (docs/bundle.md)."""
    refined = getattr(result, "refined", None)
    if refined is None:
        return None
    return {
        "frame": refined.frame_description,
        "sigma0": json_float(refined.sigma0) if hasattr(refined, "sigma0") else None,
        "redundancy": int(refined.redundancy),
        "iterations": int(refined.iterations),
        "converged": bool(refined.converged),
        "n_observations": int(refined.n_observations),
        "control": statistics(refined.control_statistics),
        "check": statistics(refined.check_statistics),
        "check_with_weak": statistics(
            AccuracyStatistics.from_residuals(
                np.asarray(refined.control_residuals)[np.asarray(refined.is_check, dtype=bool)]
            )
        ),
        "point_std_median_m": _column_medians(refined.point_std),
        "centre_std_median_m": _column_medians(refined.centre_std),
        "rejections": [r.describe() for r in refined.rejections],
        "strip_method_check": statistics(result.check_statistics),
        "gnss": _bundle_gnss(getattr(refined, "gnss", None)),
        "imu": _bundle_imu(getattr(refined, "imu", None)),
        "restored_points": list(result.restored_points),
    }


def _column_medians(values: Any) -> list[float | None]:
    """Median of the finite values of each column (None for a column without any)."""
    a = np.asarray(values, dtype=np.float64)
    out: list[float | None] = []
    for col in a.T:
        col = col[np.isfinite(col)]
        out.append(json_float(np.median(col)) if col.size else None)
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
        "redundancy_sum": json_float(np.sum(redundancy)) if redundancy.size else None,
        "critical_w": json_float(out.critical),
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
    tested = np.asarray(np.isfinite(np.asarray(out.w, dtype=np.float64)).any(axis=1), dtype=bool)
    failed = np.asarray(out.failed, dtype=bool)
    return [bool(f) if t else None for f, t in zip(failed, tested, strict=True)]


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
        "sigma_xy_m": json_float(np.median(out.sigma_xy)) if out.n_used else None,
        "sigma_z_m": json_float(np.median(out.sigma_z)) if out.n_used else None,
        "rms_e_m": json_float(rms[0]),
        "rms_n_m": json_float(rms[1]),
        "rms_u_m": json_float(rms[2]),
        "rms_plan_m": json_float(out.rms_plan),
        "max_plan_m": json_float(out.max_plan),
        "max_u_m": json_float(out.max_up),
        **_test_summary(out),
        "photos": [
            {
                "photo": pid,
                "dE_m": json_float(v[i, 0]),
                "dN_m": json_float(v[i, 1]),
                "dU_m": json_float(v[i, 2]),
                "plan_m": json_float(out.plan[i]),
                "sigma_xy_m": json_float(out.sigma_xy[i]),
                "sigma_z_m": json_float(out.sigma_z[i]),
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
        "sigma_deg": json_float(np.degrees(np.median(out.sigma))) if out.n_used else None,
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
                "rx_deg": json_float(v[i, 0]),
                "ry_deg": json_float(v[i, 1]),
                "rz_deg": json_float(v[i, 2]),
                "d_omega_deg": json_float(d_opk[i, 0]),
                "d_phi_deg": json_float(d_opk[i, 1]),
                "d_kappa_deg": json_float(d_opk[i, 2]),
                "sigma_deg": json_float(np.degrees(out.sigma[i])),
                "redundancy": np.asarray(out.redundancy[i], dtype=np.float64),
                "w": np.asarray(out.w[i], dtype=np.float64),
                "failed": failed[i],
                "rejected": bool(out.rejected[i]),
            }
            for i, pid in enumerate(out.photo_ids)
        ],
    }
