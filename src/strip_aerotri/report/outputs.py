"""The outputs of a run: the files of a result folder.

:func:`build_outputs` turns a :class:`~strip_aerotri.results.StripResult`
into the files of a result folder (name -> bytes), ready for
:class:`~strip_aerotri.report.files.ResultFolder`: the tables
(:mod:`.tables`), ``report.json`` (:mod:`.record`) and ``report.html``
(:mod:`.html` with :mod:`.figures`).  Every file, column and key is
described in ``docs/outputs.md``.
"""

from __future__ import annotations

from contextlib import AbstractContextManager, nullcontext
from functools import partial
from typing import TYPE_CHECKING, Any

from . import json_text
from .aside import Aside, Standby, aside
from .calibration import calibration_outputs, variance_record
from .figures import figure_data
from .html import StripFigures, build_html, draw_figures, html_page
from .record import REPORT_FORMAT, REPORT_FORMAT_VERSION, build_report, model_records
from .tables import photos_csv, points_csv, points_geojson
from .values import point_roles

if TYPE_CHECKING:
    from ..project import Project
    from ..results import StripResult

__all__ = [
    "GEOJSON_LOCAL_NOTE",
    "REPORT_FORMAT",
    "REPORT_FORMAT_VERSION",
    "build_html",
    "build_outputs",
    "build_report",
    "point_roles",
    "strip_outputs",
]

#: The note of report.json's ``warnings`` when points.geojson is not written.
GEOJSON_LOCAL_NOTE = 'points.geojson not written: crs is "local" (no geodesy to WGS 84)'


def build_outputs(
    result: StripResult,
    *,
    project: Project | None = None,
    map_scale: float | None = None,
    html: bool = True,
    standby: Standby | None = None,
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
    standby : Standby, optional
        A process started before the adjustment (:class:`.aside.Standby`
        with :func:`.html.prepare_drawing`) that draws the figures; without
        one they are drawn in a process forked now (:func:`.aside.aside`).

    Returns
    -------
    dict of str to bytes
        ``points.csv``, ``photos.csv``, ``report.json``, ``report.html`` and,
        unless the CRS is ``"local"``, ``points.geojson`` (see
        docs/outputs.md).  When the GeoJSON is left out, ``report.json``
        says so under ``warnings``.
    """
    return strip_outputs(result, project=project, map_scale=map_scale, html=html, standby=standby)[
        0
    ]


def strip_outputs(
    result: StripResult,
    *,
    project: Project | None = None,
    map_scale: float | None = None,
    html: bool = True,
    standby: Standby | None = None,
) -> tuple[dict[str, bytes], dict[str, Any]]:
    """:func:`build_outputs` and the content of ``report.json`` it wrote.

    The page's figures are drawn in a second process (:mod:`.aside`) while
    this one makes report.json and the tables.
    """
    refined = getattr(result, "refined", None)
    outcome = None if refined is None else refined.self_calibration
    drawing: AbstractContextManager[Aside[StripFigures] | None] = nullcontext()
    roles = point_roles(result)
    if html:  # calibration: the outcome's figures if the refinement has one
        data = figure_data(result, model_records(result), calibration=True, roles=roles)
        drawing = (
            aside(partial(draw_figures, data))
            if standby is None
            else standby.submit(draw_figures, data)
        )
    with drawing as figures:
        notes: list[str] = []
        geojson = points_geojson(result, roles=roles)
        if geojson is None:
            notes.append(GEOJSON_LOCAL_NOTE)
        report = build_report(result, project=project, map_scale=map_scale, notes=notes)
        cal_record, cal_toml = calibration_outputs(
            outcome, project, float(result.strip.observations.principal_distance)
        )
        if cal_record is not None:
            report["bundle"]["self_calibration"] = cal_record
        weights = variance_record(None if refined is None else refined.variance_components)
        if weights is not None:
            report["bundle"]["variance_components"] = weights
        if geojson is not None:
            report["outputs"]["points.geojson"] = {
                "written": True,
                "wgs84_operation": result.ground.crs.wgs84_operation,
            }
        files = {
            "points.csv": points_csv(result, roles=roles).encode("utf-8"),
            "photos.csv": photos_csv(result).encode("utf-8"),
        }
        if geojson is not None:
            files["points.geojson"] = (geojson + "\n").encode("utf-8")
        if cal_toml is not None:
            files["camera.toml"] = cal_toml
        text = json_text.dumps(report, indent=1) + "\n"
        if figures is not None:
            page = html_page(report, figures.result(), warnings=result.warnings)
            files["report.html"] = page.encode("utf-8")
    files["report.json"] = text.encode("utf-8")
    return files, report
