"""The self-calibrated camera in the outputs: report.json, camera.toml, the page.

``camera.toml`` holds the adjusted ``[camera]`` and ``[distortion]`` tables,
ready for the next project.  The adjustment estimated increments on
coordinates already corrected by the start ``[distortion]``, so the new
``[distortion]`` (always ``units = "mm"``, ``model = "correction"``) is the
Brown/Fraser polynomial fitted by least squares to the whole correction
(the start table's plus the increments) on a 21 x 21 grid over the area the
observations cover, measured coordinates reduced to the new principal point;
the RMS of that fit is written beside it (exact up to the increments'
evaluation point, below 0.01 µm for the start tables of practice).  Ebner's
parameters have no counterpart in ``[distortion]``: camera.toml then keeps the
start tables and lists the estimates as comments.  The page's section shows
the adjusted camera as camera.toml has it and names that file.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._typing import FloatArray
from ..interior import BrownDistortion, correct_distortion
from ..results import SelfCalibrationOutcome, VarianceComponents
from .values import json_float

__all__ = [
    "calibration_figures",
    "calibration_html",
    "calibration_outputs",
    "calibration_record",
    "camera_toml",
    "fitted_camera",
    "variance_html",
    "variance_record",
    "with_variance_html",
]

_DISTORTION_NAMES = ("k1", "k2", "k3", "p1", "p2", "b1", "b2")


def _increments(outcome: SelfCalibrationOutcome) -> dict[str, float]:
    est = outcome.estimate
    if est is None:
        return {}
    return {n: float(v) for n, v in zip(est.names, est.values, strict=True)}


def fitted_camera(
    outcome: SelfCalibrationOutcome,
    c_mm: float,
    principal_point_mm: FloatArray,
    start: BrownDistortion | None,
) -> tuple[float, FloatArray, BrownDistortion, float]:
    """The adjusted c (mm), principal point (mm), ``[distortion]`` and the RMS
    (µm) of the distortion's fit (module notes); Brown/Fraser only."""
    inc = _increments(outcome)
    c_new = c_mm + inc.get("c", 0.0)
    shift = np.array([inc.get("x0", 0.0), inc.get("y0", 0.0)])
    pp_new = np.asarray(principal_point_mm, dtype=np.float64) + shift
    cells = outcome.cells
    lo = (cells.x_edges[0], cells.y_edges[0]) if cells is not None else (-1.0, -1.0)
    hi = (cells.x_edges[-1], cells.y_edges[-1]) if cells is not None else (1.0, 1.0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 21), np.linspace(lo[1], hi[1], 21))
    new_reduced = np.column_stack([gx.ravel(), gy.ravel()])  # measured - new pp
    measured = new_reduced + shift  # measured - start pp
    corrected = measured if start is None else correct_distortion(measured, start, c_mm)
    # the increments' lens, affinity and shear terms at x̄ = corrected - shift
    from ..geometry.camera_model import BROWN_PARAMETERS, brown_correction

    values = np.array([inc.get(n, 0.0) if n in _DISTORTION_NAMES else 0.0 for n in BROWN_PARAMETERS])
    target = corrected - measured + brown_correction(corrected - shift, values, c_mm)
    x, y = new_reduced[:, 0], new_reduced[:, 1]
    r2 = x * x + y * y
    zero = np.zeros_like(x)
    design = np.stack(
        [
            np.column_stack([x * r2, y * r2]),
            np.column_stack([x * r2 * r2, y * r2 * r2]),
            np.column_stack([x * r2**3, y * r2**3]),
            np.column_stack([r2 + 2 * x * x, 2 * x * y]),
            np.column_stack([2 * x * y, r2 + 2 * y * y]),
            np.column_stack([x, zero]),
            np.column_stack([y, zero]),
        ],
        axis=-1,
    ).reshape(-1, 7)
    # only the terms estimated or given at the start (the others stay exactly 0)
    used = np.array(
        [
            n in inc or (start is not None and getattr(start, n) != 0.0)
            for n in _DISTORTION_NAMES
        ]
    )
    scale = np.maximum(np.sqrt(np.sum(design**2, axis=0)), 1e-300)
    coef = np.zeros(7)
    if used.any():
        sol, *_ = np.linalg.lstsq(design[:, used] / scale[used], target.ravel(), rcond=None)
        coef[used] = sol / scale[used]
    rms_um = float(np.sqrt(np.mean((design @ coef - target.ravel()) ** 2))) * 1000.0
    k1, k2, k3, p1, p2, b1, b2 = (float(v) for v in coef)
    fitted = BrownDistortion(k1=k1, k2=k2, k3=k3, p1=p1, p2=p2, b1=b1, b2=b2)
    return c_new, pp_new, fitted, rms_um


def calibration_record(
    outcome: SelfCalibrationOutcome | None,
    c_mm: float | None = None,
    principal_point_mm: FloatArray | None = None,
    start: BrownDistortion | None = None,
) -> dict[str, Any] | None:
    """``bundle.self_calibration`` of report.json (docs/outputs.md)."""
    if outcome is None:
        return None
    record: dict[str, Any] = {
        "choice": outcome.choice if isinstance(outcome.choice, str) else list(outcome.choice),
        "family": outcome.family,
        "kept": list(outcome.kept),
        "parameters": [
            {
                "name": p.name,
                "unit": p.unit,
                "estimate": json_float(p.value),
                "sd": json_float(p.std),
                "t": json_float(p.t),
                "kept": p.kept,
                "why_not": p.reason or None,
                "orientation_correlation": json_float(p.orientation_correlation),
            }
            for p in outcome.parameters
        ],
        "correlations_above_0_9": [
            {"a": a, "b": b, "r": json_float(r)} for a, b, r in outcome.correlations
        ],
        "sigma0": None if outcome.estimate is None else json_float(outcome.estimate.sigma0),
        "sigma0_without": json_float(outcome.sigma0_without),
        "notes": list(outcome.notes),
        "camera": None,
    }
    if c_mm is not None and outcome.family == "brown" and outcome.estimate is not None:
        pp = np.zeros(2) if principal_point_mm is None else principal_point_mm
        c_new, pp_new, dist, rms = fitted_camera(outcome, c_mm, pp, start)
        record["camera"] = {
            "principal_distance_mm": json_float(c_new),
            "principal_point_mm": [json_float(v) for v in pp_new],
            "distortion": {n: json_float(getattr(dist, n)) for n in _DISTORTION_NAMES},
            "distortion_fit_rms_um": json_float(rms),
        }
    return record


def camera_toml(
    outcome: SelfCalibrationOutcome | None,
    c_mm: float,
    principal_point_mm: FloatArray,
    start: BrownDistortion | None,
) -> str | None:
    """Text of ``camera.toml`` (None without self-calibration)."""
    if outcome is None:
        return None
    head = [
        "# The camera adjusted by the bundle's self-calibration; paste these tables",
        "# into the next project's strip.toml in place of its [camera] and [distortion].",
    ]
    if outcome.family == "ebner" or outcome.estimate is None:
        lines = head + [
            "# No parameter was kept: the camera is the start camera."
            if outcome.estimate is None
            else "# Ebner's parameters have no [distortion] counterpart; the tables are the"
            " start camera's, the estimates follow (estimate, sd).",
        ]
        lines += [
            f"#   {p.name} = {p.value:.6g} ({p.std:.2g})" + ("" if p.unit == "1" else f" {p.unit}")
            for p in outcome.parameters
            if p.kept
        ]
        return _tables(lines, c_mm, principal_point_mm, start or BrownDistortion())
    c_new, pp_new, dist, rms = fitted_camera(outcome, c_mm, principal_point_mm, start)
    lines = head + [
        f"# Estimated: {', '.join(outcome.kept)}; [distortion] fitted over the observed area "
        f"within {rms:.3f} µm RMS.",
    ]
    return _tables(lines, c_new, pp_new, dist)


def _tables(lines: list[str], c_mm: float, pp: FloatArray, dist: BrownDistortion) -> str:
    out = lines + [
        "",
        "[camera]",
        f"principal_distance_mm = {c_mm!r}",
        f"principal_point_mm = [{float(pp[0])!r}, {float(pp[1])!r}]",
        "",
        "[distortion]",
        f'units = "{dist.units.value}"',
        f'model = "{dist.model.value}"',
    ]
    out += [f"{n} = {float(getattr(dist, n))!r}" for n in _DISTORTION_NAMES]
    return "\n".join(out) + "\n"


def calibration_figures(outcome: SelfCalibrationOutcome | None) -> tuple[str | None, str | None]:
    """PNGs (base64): the distortion field (vectors on a grid and the radial
    profile) and the image residuals averaged in cells before and after."""
    if outcome is None or outcome.estimate is None or outcome.cells is None:
        return None, None
    from .figures_calibration import figure_cells, figure_distortion

    return figure_distortion(outcome), figure_cells(outcome.cells)


def _unit_cell(unit: str) -> str:
    """A unit for the page's tables (HTML): "–" for the dimensionless ("1",
    read as a number beside an estimate)."""
    from .html_parts import _esc

    return "–" if unit == "1" else _esc(unit)


def _camera_rows(camera: dict[str, Any], parameters: list[dict[str, Any]]) -> list[list[Any]]:
    """The adjusted camera's rows (term, value, sd, unit) as camera.toml has
    it: c, x0, y0, then the distortion terms kept or carried from the start;
    the sd is the estimate's (the start value is exact), "held" for a term
    held at its start value."""
    from .html_parts import _esc

    by_name = {p["name"]: p for p in parameters}

    def row(name: str, value: float | None, spec: str) -> list[Any]:
        p = by_name.get(name)
        sd = ("held",) if p is None or not p["kept"] or p["sd"] is None else (f"{p['sd']:.2g}",)
        unit = _unit_cell(p["unit"]) if p is not None else "mm"
        return [name, (_esc(format(value, spec)),) if value is not None else ("–",), sd, (unit,)]

    c, (x0, y0) = camera["principal_distance_mm"], camera["principal_point_mm"]
    rows = [row("c", c, ".4f"), row("x0", x0, ".4f"), row("y0", y0, ".4f")]
    for name, value in camera["distortion"].items():
        kept = name in by_name and by_name[name]["kept"]
        if kept or (value is not None and value != 0.0):
            rows.append(row(name, value, ".6g"))
    return rows


def _camera_html(record: dict[str, Any]) -> str:
    """The adjusted camera (c, the principal point and the distortion terms
    with their sd, as camera.toml has them) and the file that holds it."""
    from .html_parts import _fmt, _table

    camera = record.get("camera")
    paste = (
        "<code>camera.toml</code>, written beside this page, holds {what}: paste its "
        "[camera] and [distortion] tables into the next project's strip.toml in place of "
        "its own."
    )
    if camera is None:
        what = (
            "the start camera, Ebner's estimates as comments"
            if record.get("family") == "ebner" and record["kept"]
            else "the start camera"
        )
        return "<p>" + paste.format(what=what) + "</p>"
    return "\n".join(
        [
            "<h3>The adjusted camera</h3>",
            _table(["term", "value", "sd", "unit"], _camera_rows(camera, record["parameters"])),
            "<p>"
            + paste.format(what="these values")
            + " Principal distance and point in mm, as [camera] gives them; "
            "[distortion] in mm, model \"correction\", fitted over the observed area within "
            f"{_fmt(camera['distortion_fit_rms_um'])} µm RMS.</p>",
        ]
    )


def calibration_html(record: dict[str, Any] | None, figures: tuple[str | None, str | None]) -> str:
    """The page's section on the self-calibration ('' without one)."""
    if record is None:
        return ""
    from .html_parts import _esc, _figure, _fmt, _table

    rows = [
        [
            p["name"],
            (_unit_cell(p["unit"]),),
            (f"{p['estimate']:.4g}",) if p["estimate"] is not None else ("–",),
            (f"{p['sd']:.2g}",) if p["sd"] is not None else ("–",),
            _fmt(p["t"], 1),
            _fmt(p["orientation_correlation"], 4),
            "kept" if p["kept"] else (_esc(p["why_not"] or ""),),
        ]
        for p in record["parameters"]
    ]
    corr = record["correlations_above_0_9"]
    parts = [
        "<h2>Self-calibration of the camera</h2>",
        f"<p>Asked: {_esc(record['choice'])}; "
        + (
            f"kept: {_esc(', '.join(record['kept']))}. sigma0 {_fmt(record['sigma0'])} "
            f"(with the camera as given: {_fmt(record['sigma0_without'])}). "
            if record["kept"]
            else "no parameter kept: the camera is left as given (camera.toml holds it). "
            f"sigma0 {_fmt(record['sigma0_without'])}. "
        )
        + "Estimates are increments from the "
        "start camera; r(EO) is the multiple correlation with the photos' orientation and "
        "the points.</p>",
        _table(["parameter", "unit", "estimate", "sd", "t", "r(EO)", "kept / why not"], rows),
        "<p>Correlations above 0.9 between the kept parameters: "
        + (_esc(", ".join(f"{c['a']}-{c['b']} {c['r']:.3f}" for c in corr)) or "none")
        + "</p>",
        _camera_html(record),
        _figure(
            figures[0],
            "The camera's correction over the format (sensor axes), and its radial profile.",
            "distortion field",
        ),
        _figure(
            figures[1],
            "Image residuals averaged in cells over the format, at one scale: before, with "
            "the camera's correction added back (left), and after the self-calibration "
            "(right).",
            "residuals over the format",
        ),
    ]
    return "\n".join(parts)


def start_camera(
    project: Any, principal_distance_mm: float
) -> tuple[float, FloatArray, BrownDistortion | None]:
    """The start camera: the project's ``[camera]`` and ``[distortion]``, or
    ``principal_distance_mm`` with no principal point nor distortion."""
    if project is None:
        return principal_distance_mm, np.zeros(2), None
    cam = project.camera
    pp = np.asarray(cam.principal_point_mm, dtype=np.float64)
    return float(cam.principal_distance_mm), pp, project.distortion


def calibration_outputs(
    outcome: SelfCalibrationOutcome | None, project: Any, principal_distance_mm: float
) -> tuple[dict[str, Any] | None, bytes | None]:
    """report.json's ``bundle.self_calibration`` and camera.toml's bytes (None, None without)."""
    if outcome is None:
        return None, None
    c, pp, dist = start_camera(project, principal_distance_mm)
    text = camera_toml(outcome, c, pp, dist)
    return calibration_record(outcome, c, pp, dist), None if text is None else text.encode()


def variance_record(vc: VarianceComponents | None) -> dict[str, Any] | None:
    """``bundle.variance_components`` of report.json (docs/outputs.md): each
    observation group's a-priori and estimated sigma and its redundancy."""
    if vc is None:
        return None
    return {
        "applied": vc.applied,
        "iterations": vc.iterations,
        "converged": vc.converged,
        "sigma0_apriori": json_float(vc.sigma0_apriori),
        "groups": [
            {
                "group": g.name,
                "unit": g.unit,
                "n": g.n,
                "sigma_apriori": json_float(g.sigma_apriori),
                "sigma": json_float(g.sigma),
                "redundancy": json_float(g.redundancy),
                "factor": json_float(g.factor),
                "estimated": g.estimated,
            }
            for g in vc.groups
        ],
    }


def variance_html(record: dict[str, Any] | None) -> str:
    """The page's section on the observation groups' weights ('' without)."""
    if record is None:
        return ""
    from .html_parts import _esc, _fmt, _table

    rows = [
        [
            g["group"],
            (_esc(g["unit"]),),
            str(g["n"]),
            _fmt(g["sigma_apriori"], 4),
            _fmt(g["sigma"], 4),
            _fmt(g["redundancy"], 1),
            "estimated" if g["estimated"] else "as given (too little redundancy)",
        ]
        for g in record["groups"]
    ]
    how = (
        f"adjusted with the estimated weights ({record['iterations']} more adjustment(s), "
        + ("settled" if record["converged"] else "not settled")
        + ")"
        if record["applied"]
        else "estimated from the adjustment at the given weights, not applied"
    )
    return "\n".join(
        [
            "<h2>Observation weights from the data</h2>",
            "<p>Each group's sigma estimated from its residuals (variance components: "
            "v'Pv / r of the group, r the sum of its redundancy numbers); "
            f"{_esc(how)}. sigma0 at the given weights {_fmt(record['sigma0_apriori'])}.</p>",
            _table(
                ["group", "unit", "n", "sigma given", "sigma estimated", "redundancy", ""], rows
            ),
        ]
    )


def with_variance_html(calibration: str, report: dict[str, Any] | Any) -> str:
    """The page's self-calibration section followed by the weights' section of
    ``report`` (report.json's content), if it has one."""
    record = (report.get("bundle") or {}).get("variance_components")
    section = variance_html(record)
    return calibration if not section else (calibration + "\n" + section if calibration else section)
