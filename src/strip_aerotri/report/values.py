"""Shared pieces of the outputs: plain JSON values (never NaN), the roles of
the points, and the control rows and residuals in the result's order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from enum import Enum
from typing import Any

import numpy as np

from ..ground.common import index_of
from ..observations import ControlType
from ..options import AdjustmentOptions, Construction
from ..results import AccuracyStatistics, BlockResult, StripResult

_ROLE_OF_KIND = {
    ControlType.FULL: "control-full",
    ControlType.PLAN: "control-plan",
    ControlType.HEIGHT: "control-height",
    ControlType.CHECK: "check",
}


def clean(value: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, NaN/inf -> None."""
    kind = type(value)  # the exact built-in types first: most of a report's values
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is str or kind is int or value is None:
        return value
    if kind is dict:
        return {str(k): clean(v) for k, v in value.items()}
    if kind is list:
        return [clean(v) for v in value]
    if isinstance(value, Enum):
        return clean(value.value)
    if isinstance(value, Mapping):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean(value.tolist())
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


def delivered_points(result: StripResult | BlockResult) -> int:
    """The points delivered, one a row of points.csv: those with every
    coordinate of ``result.points`` finite (the refinement's when there is
    one), as the command line, report.json and the page count them."""
    return int(np.isfinite(np.asarray(result.points, dtype=np.float64)).all(axis=1).sum())


def json_float(value: Any) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def statistics(stats: AccuracyStatistics) -> dict[str, Any]:
    rmse = np.asarray(stats.rmse, dtype=np.float64)
    return {
        "n_plan": int(stats.n_plan),
        "n_height": int(stats.n_height),
        "rmse_e_m": json_float(rmse[0]),
        "rmse_n_m": json_float(rmse[1]),
        "rmse_h_m": json_float(rmse[2]),
        "rmse_plan_m": json_float(stats.rmse_plan),
        "mean_plan_m": json_float(stats.mean_plan),
        "max_plan_m": json_float(stats.max_plan),
        "max_height_m": json_float(stats.max_height),
    }


def point_roles(result: StripResult) -> np.ndarray:
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


def control_rows(result: StripResult) -> tuple[np.ndarray, np.ndarray]:
    """Point index (C,) of each row of ``ground.control_residuals`` and the residuals (C, 3)."""
    ground = result.ground
    rows = np.asarray(ground.control_index, dtype=np.intp)
    idx = index_of(result.point_ids, [result.control.point_ids[r] for r in rows])
    return idx, np.asarray(ground.control_residuals, dtype=np.float64).reshape(-1, 3)


def residual_columns(result: StripResult) -> np.ndarray:
    """(P, 3) given − adjusted E, N, H at control and check points, NaN
    elsewhere: of the points delivered (``result.points``), i.e. of the
    bundle refinement when it ran."""
    out = np.full((len(result.point_ids), 3), np.nan)
    refined = result.refined
    if refined is None:
        idx, resid = control_rows(result)
    else:
        lookup = {pid: i for i, pid in enumerate(result.point_ids)}
        rows = np.asarray(refined.control_index, dtype=np.intp)
        idx = np.array([lookup[result.control.point_ids[r]] for r in rows], dtype=np.intp)
        resid = np.asarray(refined.control_residuals, dtype=np.float64).reshape(-1, 3)
    out[idx] = resid
    return out


def image_counts(result: StripResult) -> tuple[np.ndarray, np.ndarray]:
    obs = result.strip.observations
    per_point = np.bincount(np.asarray(obs.point), minlength=obs.n_points)
    per_photo_all = np.bincount(np.asarray(obs.photo), minlength=obs.n_photos)
    return per_point, per_photo_all[np.asarray(result.strip.photo_index)]


def options_record(options: AdjustmentOptions | None) -> dict[str, Any] | None:
    """``report.json``'s ``options``: the options a strip or a block ran with
    (``result.options``), written the same way for both; None without them.
    ``polynomial`` is null with ``block = "models"`` (every model its own
    similarity)."""
    if options is None:
        return None
    models = options.block is Construction.MODELS
    return {
        "route": options.route.value,
        "block": options.block.value,
        "models": options.models.value,
        "relative_orientation": options.relative_orientation.value,
        "intersection": options.intersection.value,
        "scale_transfer": options.scale_transfer.value,
        "max_iterations": int(options.max_iterations),
        "photo_step": options.photo_step,
        "polynomial": None if models else options.polynomial,
        "refine": options.refine.value,
    }
