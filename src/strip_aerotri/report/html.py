"""``report.html``: one self-contained page (tables, verdicts, figures) built
from ``report.json``'s content and the figures.
"""

from __future__ import annotations

import gc
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..options import DEFAULT_SECTIONS
from .aside import aside
from .calibration import calibration_figures, calibration_html, with_variance_html
from .figures import (
    StripFigureData,
    _fitted_png,
    figure_data,
    figure_layout,
    figure_parallax,
    figure_residuals,
    figure_ties,
)
from .html_parts import _esc, _figure, _fmt, _table, weak_check_sentence
from .restored import page_warnings
from .verdict import Verdict, criterion_label, overall_verdict

if TYPE_CHECKING:
    from ..results import StripResult

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
@page{size:A4;margin:14mm 12mm}
@media print{body{max-width:none;margin:0;padding:0}.scroll{max-height:none;overflow:visible;
display:block;border:none}thead{display:table-header-group}tr,figure{break-inside:avoid}
h2,h3{break-after:avoid}table{font-size:7.5pt}th,td{padding:1px 4px}th{white-space:normal}
figure img{border:none}}
"""


def _verdict_cell(passed: bool | None) -> tuple[str]:
    if passed is None:
        return ("<span class='na'>not judged</span>",)
    return ("<span class='pass'>PASS</span>",) if passed else ("<span class='fail'>FAIL</span>",)


@dataclass(frozen=True)
class StripFigures:
    """The figures of a strip's page (PNG as base64; None where not drawn)."""

    layout: str | None
    residuals: str | None
    parallax: str | None
    ties: str | None
    long_strip: bool = False
    #: the self-calibration's distortion field and cells; None: no such section
    calibration: tuple[str | None, str | None] | None = None


def build_html(result: StripResult, report: Mapping[str, Any]) -> str:
    """Text of ``report.html``: one self-contained page (inline PNG figures, no scripts).

    Parameters
    ----------
    result : StripResult
    report : mapping
        :func:`build_report` of the same result.
    """
    calibration = (report.get("bundle") or {}).get("self_calibration") is not None
    data = figure_data(result, report["models"], calibration=calibration)
    return html_page(report, draw_figures(data), warnings=result.warnings)


#: The figures' rc (no layout engine: each figure's axes are placed once by
#: figures_frame.fit, every label inside the canvas at any strip length,
#: tests/test_report_figures.py).
_STYLE: dict[str, Any] = {"font.size": 9, "axes.titlesize": 11}


def prepare_drawing() -> None:
    """Load what :func:`draw_figures` needs, so that a process waiting to
    draw has it ready (:class:`.aside.Standby`): matplotlib with its Agg
    canvas, and what its first figure loads (the font, the PNG writer),
    by drawing a small figure of the same kinds of artists and throwing it
    away (about 0.3 s in all; nothing of it reaches the page)."""
    import matplotlib
    from matplotlib.figure import Figure

    with matplotlib.rc_context(_STYLE):  # type: ignore[arg-type]  # typed as literal keys
        fig = Figure(figsize=(3, 2))
        ax = fig.subplots()
        ax.plot([0.0, 1.0], [0.0, 1.0], "-", label="a")
        ax.scatter([0.5], [0.5], c=[0.5], cmap="RdBu_r", marker="^", label="b")
        ax.quiver([0.2], [0.2], [0.1], [0.1], angles="xy", scale_units="xy", scale=1.0)
        ax.annotate("0", (0.5, 0.5), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.set_title("σ0 µm ±")
        ax.set_xlabel("x")
        _fitted_png(fig, best=ax.legend(loc="best", fontsize=8))


def draw_figures(data: StripFigureData) -> StripFigures:
    """The page's figures of :func:`.figures.figure_data`'s inputs.

    The layout and the residuals are drawn here, the parallaxes and the ties
    meanwhile by a process forked for them (:func:`.aside.aside`; where
    forking is not allowed, here afterwards, in the order of the page): the
    figures are the costliest part of the report, and the run that waits
    for them has its own writing to do on the other core (docs/scaling.md).
    """
    import matplotlib

    with _no_collection(), matplotlib.rc_context(_STYLE):  # type: ignore[arg-type]  # literal keys
        with aside(partial(_parallax_and_ties, data)) as other:
            layout, residuals = figure_layout(data), figure_residuals(data)
            parallax, ties = other.result()
        calibration = None if data.calibration is None else calibration_figures(data.calibration)
        return StripFigures(layout, residuals, parallax, ties, data.plan.long, calibration)


@contextmanager
def _no_collection() -> Iterator[None]:
    """Python's garbage collector paused while the figures are drawn: they
    make some 50 000 objects, and each collection of the oldest generation
    would walk the run's whole heap (the result) as well; what they leave
    is collected afterwards, as usual."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _parallax_and_ties(data: StripFigureData) -> tuple[str, str | None]:
    """The figures of :func:`draw_figures` drawn by its second process."""
    return figure_parallax(data), figure_ties(data)


def html_page(
    report: Mapping[str, Any], figures: StripFigures, *, warnings: Iterable[str]
) -> str:
    """The page of ``report`` (report.json's content) with its ``figures``;
    ``warnings``, the result's own (with their points), let the page list the
    points the refinement restored as restored (:func:`.restored.page_warnings`):
    required, since without them a restored point is listed as left out."""
    record = (report.get("bundle") or {}).get("self_calibration")
    return _html_page(
        {**report, "warnings": page_warnings(report, warnings)},
        figures.layout,
        figures.residuals,
        figures.parallax,
        figures.ties,
        long_strip=figures.long_strip,
        calibration=with_variance_html(
            ""
            if figures.calibration is None or record is None
            else calibration_html(record, figures.calibration),
            report,
        ),
    )


#: The columns of an accuracy row (:func:`stat_row`).
STAT_HEADER = [
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
]


def stat_row(label: str, st: Mapping[str, Any]) -> list[Any]:
    """One accuracy row of ``statistics`` (report.json) under ``label``."""
    keys = ("n_plan", "n_height", "rmse_e_m", "rmse_n_m", "rmse_h_m", "rmse_plan_m")
    return [label, *(st[k] for k in keys), st["mean_plan_m"], st["max_plan_m"], st["max_height_m"]]


def _stat_rows(report: Mapping[str, Any]) -> list[list[Any]]:
    """The accuracy rows: control and check points of the strip method and,
    after a bundle refinement, of the refinement (the coordinates delivered)."""
    sets: list[tuple[str, Mapping[str, Any]]] = [
        ("control (used)", report["control"]["statistics"]),
        ("check (not used)", report["check"]["statistics"]),
    ]
    bundle = report.get("bundle")
    if bundle is not None:
        sets = [(f"strip method: {label}", st) for label, st in sets] + [
            ("bundle refinement (delivered): control", bundle["control"]),
            ("bundle refinement (delivered): check", bundle["check"]),
        ]
    return [stat_row(label, st) for label, st in sets]


def criteria_table(criteria: list[Mapping[str, Any]]) -> str:
    """The R4 criteria of report.json's ``tolerances`` as a table."""
    return _table(
        ["criterion", "source", "n", "value", "limit", "unit", "verdict", "explanation"],
        [
            [
                (
                    f"<span style='white-space:normal'>"
                    f"{_esc(c.get('label') or criterion_label(c['name']))}</span>",
                ),
                c["source"],
                c["n"],
                c["value"],
                c["limit"],
                c["unit"],
                _verdict_cell(c["passed"]),
                (f"<span style='white-space:normal'>{_esc(c['explanation'])}</span>",),
            ]
            for c in criteria
        ],
        left=2,
        left_columns=(7,),
        digits=[0, 0, 0, 4, 4, 0, 0, 0],
    )


def _plain_summary(report: Mapping[str, Any], verdict: str) -> str:
    """The result in two sentences for a reader who is not a photogrammetrist."""
    inp, chk = report["inputs"], report["check"]["statistics"]
    ctrl = inp["control"]
    used = report["control"]["statistics"]
    text = (
        f"{inp['n_photos']} photos were oriented and {inp['n_points_triangulated']} points "
        f"measured on them were given ground coordinates, fitted to "
        f"{used['n_plan']} control points in plan and {used['n_height']} in height "
        f"({report['project']['crs_name']}). "
    )
    bundle = report.get("bundle")
    if bundle is not None:  # the delivered coordinates are the refinement's
        chk = bundle["check"]
    compared = max(chk["n_plan"], chk["n_height"])
    if compared:
        weak = len(report["check"].get("weakly_determined") or ())
        given = ctrl["check"] - weak
        at = (
            f"At {compared} independent check points"
            if compared >= given
            else f"At {compared} of the {given} independent check points (the other "
            f"{given - compared} could not be triangulated or compared)"
        )
        text += (
            f"{at}, which the adjustment did not use, the computed positions differ from "
            f"the surveyed ones by {_fmt(chk['rmse_plan_m'])} m in plan and "
            f"{_fmt(chk['rmse_h_m'])} m in height (root mean square"
            + (
                ", after the rigorous bundle refinement; the strip method alone: "
                f"{_fmt(bundle['strip_method_check']['rmse_plan_m'])} m and "
                f"{_fmt(bundle['strip_method_check']['rmse_h_m'])} m"
                if bundle is not None
                else ""
            )
            + "). "
        )
        text += weak_check_sentence(report["check"])
    else:
        text += "There were no independent check points, so the accuracy is not proven. "
    text += f"Against the tolerances of the production rules: {verdict}."
    return f"<p class='plain'>{_esc(text)}</p>"


_VERDICT_WORD = {"pass": "met", "fail": "not met", "na": "not fully judged"}


def verdict_banner(verdict: Verdict) -> str:
    """The verdict first on the page, in the words of the plain summary and the CLI."""
    return (
        f"<div class='verdict {verdict.status}'>Tolerances of the production rules (R4 "
        f"§1.7.7): {_esc(verdict.text)}</div>"
    )


def _html_page(
    report: Mapping[str, Any],
    fig_layout: str | None,
    fig_resid: str | None,
    fig_par: str | None,
    fig_ties: str | None,
    *,
    long_strip: bool = False,
    calibration: str = "",
) -> str:
    """The page: head, summary, verdicts, figures, then the tables.

    Length: a template read top to bottom as the page reads; its parts are
    strings in page order, and cutting it would scatter that order.
    """
    proj = report["project"]
    inp = report["inputs"]
    tol = report["tolerances"]
    name = proj["name"] or "Strip aerotriangulation"
    ctrl = inp["control"]
    verdict = overall_verdict(tol)
    overall_cls, overall_text = verdict.status, verdict.text
    # the delivered solution's check points: the refinement's when there is one
    chk = report["bundle"]["check"] if report.get("bundle") else report["check"]["statistics"]
    of = " (bundle refinement)" if report.get("bundle") else ""
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
            "construction",
            (
                "every model its own similarity, all at once"
                if opt.get("block") == "models"
                else f"one transformation of the whole strip and polynomials (Janiszewski; "
                f"requested {_esc(opt['polynomial'])}, "
                f"used {report['polynomial']['kind']})",
            ),
        ],
        ["image scale [m per mm]", report["ground"]["image_scale_m_per_mm"]],
        ["y-parallax σ0, median of pairs [µm]", float(np.median(sig)) if sig else None],
        ["largest y-parallax [µm]", float(np.max(mx)) if mx else None],
        [
            f"check RMSE E / N / H [m]{of}",
            (" / ".join(_fmt(chk[k]) for k in ("rmse_e_m", "rmse_n_m", "rmse_h_m")),),
        ],
        [
            f"check RMSE plan / mean plan [m]{of}",
            (f"{_fmt(chk['rmse_plan_m'])} / {_fmt(chk['mean_plan_m'])}",),
        ],
        [
            "map scale for the verdicts",
            ("–" if tol["map_scale"] is None else f"1:{tol['map_scale']:g}",),
        ],
        [
            "tolerance verdict",
            (f"<span class='{overall_cls}'>{_esc(_VERDICT_WORD[overall_cls])}</span>",),
        ],
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
        verdict_banner(verdict),
        "<p class='sub'>The tolerances are those of the Russian production rules for "
        "analytical phototriangulation (called R4 below; §1.7.7: the check points at the "
        "map scale, the relative orientation, the joins of the models). J below is "
        "Janiszewski's description of the strip method, whose formulas the report cites "
        "(his transformation of the whole strip bent by polynomials is formula 16; the "
        "construction used is in the summary).</p>",
        _plain_summary(report, overall_text),
        "<h2>Summary</h2>",
        _table(["item", "value"], summary, left=1),
        "<h3>Accuracy at control and check points (given − adjusted, metres)</h3>",
        _table(
            STAT_HEADER,
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
            "Figure 2. Residuals (given − adjusted) at control and check points "
            + (
                "against the distance along the strip: along, across and height."
                if long_strip
                else "in plan: plan as arrows (scale in the key), height as colour."
            ),
            "residual vectors",
        ),
        _figure(
            fig_par,
            "Figure 3. Residual y-parallax of the relative orientation per pair of photos, "
            "named by its left photo (left), and of all points (right), µm at image scale.",
            "y-parallax",
        ),
        _figure(
            fig_ties,
            "Figure 4. RMS of the differences between the two determinations of "
            "the tie points of each model (named by its left photo) and the previous one, "
            "in metres.",
            "tie-point differences",
        ),
        "<h2>Tolerance verdicts (R4 §1.7.7)</h2>",
        criteria_table(tol["criteria"]),
    ]
    if calibration:
        parts.append(calibration)
    parts += _html_tables(report)
    parts.append(
        "<footer>Residuals and discrepancies are given minus adjusted, along local east, "
        "north and up. photos.csv angles: R = Rx(ω)·Ry(φ)·Rz(κ) maps image vectors to local "
        "east-north-up. Every figure of this report is described in the documentation "
        "installed with the program (stripaero docs outputs).</footer>"
        "</body></html>"
    )
    return "\n".join(parts)


def _plan_of(
    values: Sequence[float | None] | None, pick: Callable[[list[float]], float]
) -> float | None:
    """One plan figure from [E, N, H] values (``pick`` of the two), or None."""
    if not values:
        return None
    plan = [v for v in values[:2] if v is not None]
    return pick(plan) if plan else None


def _html_tables(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
    out += _relative_section(report)
    out += _models_section(report)
    out += _similarity_section(report)
    out += _control_section(report)
    out += _ground_section(report)
    out += _lines_section(report)
    out += _html_gnss_imu(report)
    out += _snooping_section(report)
    out += _closing_section(report)
    return out


def _relative_section(report: Mapping[str, Any]) -> list[str]:
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
    if "b_y" in names:
        out.append(
            "<p class='sub'>q: the residual y-parallax, the vertical mismatch of a point "
            "between the two photos. b_y, b_z: the base from the left to the right photo, "
            "across and up, in units of its length along the strip; a, b, c (no unit): the "
            "turn of the right photo against the left (the rotation axis times tan(angle/2), "
            "about x, y, z).</p>"
        )
    return out


def _models_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
    return out


def _similarity_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
    return out


def _control_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
    out.append("<h2>Control residuals (given − adjusted, m)</h2>")
    out.append(
        "<p>r: redundancy number of the component (the share of an error in it that shows "
        "in its residual); MDE: the smallest error the blunder test finds with 80 % "
        "probability (Baarda), m. <em>undetectable</em>: the component has no redundancy "
        "and an error in it cannot be found by any test; only more control can show it.</p>"
    )

    def mde_cell(p: Mapping[str, Any], k: int) -> Any:
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
    return out


def _ground_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
        sections = int(poly.get("sections", DEFAULT_SECTIONS))
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
    return out


def _lines_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
    return out


def _snooping_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
    return out


def _closing_section(report: Mapping[str, Any]) -> list[str]:
    out: list[str] = []
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
