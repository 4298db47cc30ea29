"""``report.html`` of a block of strips, from its ``report.json`` content.

The page reads as the strip report does: the result in plain words first
(photos, control, the check points' accuracy, how well the strips fit
together), then the accuracy, the block in plan, the strips, their joins
with R4's two criteria, the bundle refinement with its GNSS and IMU
observations, every control and check point, and the rejections.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from .html import (
    _CSS,
    STAT_HEADER,
    _verdict_cell,
    criteria_table,
    stat_row,
    verdict_banner,
)
from .html_parts import _esc, _figure, _fmt, _table, weak_check_sentence
from .restored import page_warnings
from .verdict import overall_verdict

__all__ = ["block_html"]


def _plain(report: Mapping[str, Any]) -> str:
    """The result in a few sentences for a reader who is not a photogrammetrist."""
    block = report["block"]
    check, control = report["check"]["statistics"], report["control"]["statistics"]
    n_photos = sum(len(s["photos"]) for s in block["strips"])
    text = (
        f"{n_photos} photos in {len(block['strips'])} parallel strips were oriented as one "
        f"block and the points measured on them given ground coordinates, fitted to "
        f"{control['n_plan']} control points in plan and {control['n_height']} in height"
        + (f" ({report['project']['crs']})" if report["project"].get("crs") else "")
        + ". "
    )
    compared = max(check["n_plan"], check["n_height"])
    if compared:
        text += (
            f"At {compared} independent check points, which the adjustment did not use, "
            f"the computed positions differ from the surveyed ones by "
            f"{_fmt(check['rmse_plan_m'])} m in plan and {_fmt(check['rmse_h_m'])} m in "
            "height (root mean square"
            + (
                ", after the rigorous bundle refinement of the whole block"
                if block["refined"]
                else ""
            )
            + "). "
        )
        text += weak_check_sentence(report["check"])
    else:
        text += "There were no independent check points, so the accuracy is not proven. "
    joins = block["joins"]
    if joins:
        means = [j["mean_plan_m"] for j in joins if j["mean_plan_m"] is not None]
        transfer = [j["mean_transfer_um"] for j in joins if j["mean_transfer_um"] is not None]
        if means:
            low, high = _fmt(min(means)), _fmt(max(means))
            spread = low if low == high else f"{low}-{high}"
            text += (
                f"On the points two strips share, the strips agree to {spread} m in plan "
                "on average"
            )
            if transfer:
                failing = sum(1 for j in joins if j["transfer_passed"] is False)
                pairs = "pair" if len(joins) == 1 else "pairs"
                text += (
                    f"; their transfer errors in the image are {max(transfer):.0f} µm at most "
                    f"on average ({failing} of {len(joins)} {pairs} of strips above R4's "
                    f"{joins[0]['transfer_limit_um']:.0f} µm)"
                )
            text += ". "
    verdict = overall_verdict(report["tolerances"], joins)
    text += f"Against the tolerances of the production rules: {verdict.text}."
    return f"<p class='plain'>{_esc(text)}</p>"


def _verdict_banner(report: Mapping[str, Any]) -> str:
    """R4's verdict at the check points and on the joins, first on the page."""
    return verdict_banner(overall_verdict(report["tolerances"], report["block"]["joins"]))


def _readable(criterion: str) -> str:
    """report.json's plain-ASCII criterion with the signs a reader expects."""
    return criterion.replace("<=", "≤").replace(" um ", " µm ")


def _joins(report: Mapping[str, Any]) -> str:
    block = report["block"]
    rows = [
        [
            " / ".join(j["strips"]),
            j["n_points"],
            j["mean_plan_m"],
            j["max_plan_m"],
            j["mean_height_m"],
            j["max_height_m"],
            _verdict_cell(j["passed"]),
            j["mean_transfer_um"],
            j["max_transfer_um"],
            _verdict_cell(j["transfer_passed"]),
        ]
        for j in block["joins"]
    ]
    header = [
        "strips",
        "points",
        "mean plan [m]",
        "max plan [m]",
        "mean |dH| [m]",
        "max |dH| [m]",
        "agree within 0.5 mm at map scale (R4 1.7.7.7)",
        "mean transfer [µm]",
        "max transfer [µm]",
        "transfer within 40 µm (R4 1.7.7.3)",
    ]
    digits = [0, 0, 3, 3, 3, 3, 0, 1, 1, 0]
    return (
        "<h2>How well the strips fit together (R4 1.7.7.3, 1.7.7.7)</h2>"
        f"<p>{_esc(_readable(block['join_criterion']))}; "
        f"{_esc(_readable(block['transfer_criterion']))}. "
        "A point two strips share is placed by each strip; the table compares the two "
        "places, on the ground in the adjusted block and, as transfer errors in the image, "
        "in the free block (the block transformed onto itself only, the control holding "
        "the datum). A largest discrepancy far above the mean is usually one weak tie "
        "point (seen at the image edge by few photos); the blunder tests leave out the "
        "determinations that fail.</p>" + _table(header, rows, left=1, digits=digits)
    )


def _points(report: Mapping[str, Any], key: str, title: str) -> str:
    rows = [
        [p["point"], p["type"], p["dE_m"], p["dN_m"], p["dH_m"], p["plan_m"]]
        for p in report[key].get("points", [])
    ]
    header = ["point", "type", "dE [m]", "dN [m]", "dH [m]", "plan [m]"]
    return f"<h3>{_esc(title)}</h3>" + _table(header, rows, left=2, digits=3)


def _bundle(report: Mapping[str, Any]) -> str:
    block = report["block"]
    if not block["refined"]:
        return ""
    bundle = report.get("bundle") or {}
    out = [
        "<h2>Bundle refinement of the whole block (R4 4)</h2>",
        "<p>Every photo and point of the block adjusted by the collinearity equations, "
        f"started from the block's solution: sigma0 {_fmt(block['refined_sigma0'])} "
        f"(the block's transformation: {_fmt(block['sigma0'])}). The accuracy above, the "
        "coordinates of points.csv and photos.csv are the refinement's; the joins are "
        "those of the block's transformation.</p>",
    ]
    own = bundle.get("block_check")
    if own is not None:
        out.append(
            f"<p>The block's own solution at the same check points: "
            f"{_fmt(own['rmse_plan_m'])} m in plan, {_fmt(own['rmse_h_m'])} m in height "
            f"(the refinement: {_fmt(report['check']['statistics']['rmse_plan_m'])} m and "
            f"{_fmt(report['check']['statistics']['rmse_h_m'])} m).</p>"
        )
    gnss, imu = bundle.get("gnss"), bundle.get("imu")
    if gnss is not None:
        out.append(
            "<h3>GNSS projection centres (observed − adjusted, east / north / up)</h3>"
            + _table(
                ["photos used", "rejected", "RMS E", "RMS N", "RMS up", "max plan", "max |up|"],
                [
                    [
                        gnss["n_used"],
                        gnss["n_rejected"],
                        gnss["rms_e_m"],
                        gnss["rms_n_m"],
                        gnss["rms_u_m"],
                        gnss["max_plan_m"],
                        gnss["max_u_m"],
                    ]
                ],
                left=0,
                digits=[0, 0, 3, 3, 3, 3, 3],
            )
        )
    if imu is not None:
        rms = imu["rms_opk_deg"]
        out.append(
            "<h3>IMU attitudes (observed − adjusted, degrees)</h3>"
            + _table(
                ["photos used", "rejected", "RMS omega", "RMS phi", "RMS kappa"],
                [[imu["n_used"], imu["n_rejected"], rms[0], rms[1], rms[2]]],
                left=0,
                digits=[0, 0, 4, 4, 4],
            )
        )
    return "".join(out)


_STAGES = {
    "relative_orientation": "y-parallaxes of the relative orientations",
    "tie_points": "tie-point determinations (the scale transfer's test)",
    "models": "point determinations in the block's transformation",
    "control": "control coordinates",
    "bundle": "image observations of the bundle refinement",
}


def _rejections(rejections: list[str]) -> str:
    """How many each test rejected, then every one (a stage's name leads
    each description)."""
    if not rejections:
        return "<p class='na'>none</p>"
    counts: dict[str, int] = {}
    for text in rejections:
        stage = text.split(":", 1)[0]
        counts[stage] = counts.get(stage, 0) + 1
    summary = _table(
        ["test", "rejected"],
        [[_STAGES.get(stage, stage), n] for stage, n in counts.items()],
        digits=0,
    )
    items = "".join(f"<li>{_esc(r)}</li>" for r in rejections)
    return f"{summary}<ul class='small'>{items}</ul>"


def block_html(
    report: Mapping[str, Any],
    figure: str | None = None,
    calibration: str = "",
    *,
    warnings: Iterable[str],
) -> str:
    """The page of a block's ``report.json`` content and its figure (PNG, base64);
    ``warnings``, the result's own (with their points), let the page list the
    points the refinement restored as restored (:func:`.restored.page_warnings`):
    required, since without them a restored point is listed as left out."""
    block = report["block"]
    project = report["project"]
    name = project["name"] or "Block"
    deformation = ""
    if block.get("polynomial"):
        n_terms = 3 * int(block["polynomial"])
        kept = ", ".join(
            f"{s['name']} {s['polynomial_terms']} of {n_terms}"
            for s in block["strips"]
            if s.get("polynomial_terms") is not None
        )
        deformation = (
            f"; every strip with its own polynomial of type {block['polynomial']}, "
            f"terms kept: {kept}"
        )
    strips = [
        [s["name"], len(s["photos"]), s["n_models"], s["scale"], len(s["rejections"])]
        for s in block["strips"]
    ]
    rejections = [r for s in block["strips"] for r in s["rejections"]] + list(report["rejections"])
    others = [w for w in page_warnings(report, warnings) if w not in set(rejections)]
    stats = [stat_row("control (used)", report["control"]["statistics"])]
    if report["control"].get("fit_statistics") is not None:
        units = str(block["construction"] or "units")
        units = units if units.endswith("s") else f"{units}s"
        label = f"control: the {units}' own determinations"
        stats.append(stat_row(label, report["control"]["fit_statistics"]))
    stats.append(stat_row("check (not used)", report["check"]["statistics"]))
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        f"<title>{_esc(name)}: block report</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>{_esc(name)}: aerotriangulation of a block of {len(block['strips'])} strips</h1>",
        f"<p class='sub'>strip_aerotri {_esc(report['software']['version'])}"
        f" · {_esc(report.get('created_utc') or report.get('created'))}"
        + (f" · {_esc(project['crs'])}" if project.get("crs") else "")
        + "</p>",
        _verdict_banner(report),
        _plain(report),
        "<p class='sub'>The tolerances are those of the Russian production rules for "
        "analytical phototriangulation (called R4 below); a <em>model</em> is the 3D model "
        "of one pair of "
        "overlapping photos, a <em>strip</em> one flight line of photos.</p>",
        f"<p>Construction: {_esc(block['construction'])} (every "
        f"{'strip' if block['construction'] == 'strips' else 'model'} its own 3D "
        f"similarity, all at once onto the control and onto each other{_esc(deformation)});"
        f" sigma0 {_fmt(block['sigma0'])}, redundancy {block['redundancy']}.</p>",
        "<h2>Accuracy at control and check points (given − adjusted, metres)</h2>",
        _table(STAT_HEADER, stats, digits=3),
        _figure(
            figure,
            "The block in plan: photo centres by strip, control and check points; the check "
            "points' plan residuals (given − adjusted) as arrows, their scale in the key.",
            "photo centres by strip, control, check points and their plan residuals",
        ),
        "<h2>Strips</h2>",
        _table(
            ["strip", "photos", "models", "scale [m per strip unit]", "rejections"],
            strips,
            digits=[0, 0, 0, 3, 0],
        ),
        _joins(report),
        "<h2>Tolerance verdicts at the check points (R4 §1.7.7)</h2>",
        criteria_table(report["tolerances"]["criteria"]),
        _bundle(report),
        calibration,
        "<h2>Control and check points</h2>",
        _points(report, "control", "Control points (residuals of the components used)"),
        _points(report, "check", "Check points (not used in the adjustment)"),
        "<h2>Observations rejected as blunders</h2>",
        _rejections(rejections),
        "<h2>Warnings</h2>",
        "<ul>" + "".join(f"<li>{_esc(w)}</li>" for w in others) + "</ul>"
        if others
        else "<p class='na'>none</p>",
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"
