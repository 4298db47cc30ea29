"""``stripaero run``: adjust a project and write its result folder."""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from .options import (
    DOCS_EPILOG,
    common_options,
    echo_progress,
    echo_result,
    echo_warning,
    project_arg,
)

if TYPE_CHECKING:  # the numerical modules are imported when the command runs
    from .._typing import ArrayLike
    from ..report.summary import RunSummary, ToleranceVerdict
    from ..results import BlockResult, Rejection, StripResult

__all__ = ["run"]


def _fmt_m(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.3f} m"


def _tolerance_line(verdict: ToleranceVerdict | None) -> str | None:
    """One line on the tolerance criteria, if the run judged them."""
    if verdict is None:
        return None
    head = f"tolerances for 1:{verdict.map_scale:g}: "
    tail = f" ({verdict.n_unjudged} not judged: too few values)" if verdict.n_unjudged else ""
    if verdict.failed:
        failed = f"{len(verdict.failed)} of {verdict.n_judged} criteria failed"
        return head + f"{failed} ({', '.join(verdict.failed)})" + tail
    return head + f"all {verdict.n_judged} judged criteria met" + tail


def _accuracy_lines(summary: RunSummary, own: str = "") -> list[str]:
    """The control and check points' lines of the summary."""
    control, check = summary.control, summary.check
    lines = [
        f"control: {control.n_plan} plan, {control.n_height} height; "
        f"RMSE plan {_fmt_m(control.rmse_plan)}, height {_fmt_m(control.rmse_height)}{own}"
    ]
    if check.n_plan or check.n_height:
        lines.append(
            f"check points: {check.n_plan} plan, {check.n_height} height; "
            f"RMSE plan {_fmt_m(check.rmse_plan)}, height {_fmt_m(check.rmse_height)}"
        )
    else:
        lines.append("check points: none")
    return lines


def _echo_details(result: StripResult) -> None:
    """Per-pair and per-model figures and the timings on stderr with ``-v``;
    with ``-vv`` also every control and check point's residual (``-v`` lists
    every rejection among the warnings)."""
    strip = result.strip
    rel = strip.relative
    for m, label in enumerate(strip.model_labels):
        tie = (
            ""
            if m == 0
            else f", {int(strip.tie_count[m])} tie points, scale ratio {strip.scale_ratio[m]:.5f}"
        )
        echo_progress(
            f"{label}: {int(rel.n_points[m])} points, sigma0 {rel.sigma0_um[m]:.1f} µm, "
            f"largest y-parallax {rel.max_parallax_um[m]:.1f} µm, "
            f"{int(rel.iterations[m])} iterations{tie}",
            level=1,
        )
    # -vv: every control and check point's residual, and every rejection
    ground = result.refined if result.refined is not None else result.ground
    _echo_timings_and_residuals(
        result.timings,
        result.control.point_ids,
        ground.control_index,
        ground.control_residuals,
        ground.is_check,
    )


def _echo_timings_and_residuals(
    timings: dict[str, float],
    ids: Sequence[str],
    rows: ArrayLike,
    residuals: ArrayLike,
    is_check: ArrayLike,
) -> None:
    """The stages' times with ``-v``; every control and check point's
    residual (given − adjusted, metres) with ``-vv``."""
    for stage, seconds in timings.items():
        echo_progress(f"{stage}: {seconds:.2f} s", level=1)
    import numpy as np

    for row, resid, check in zip(
        np.asarray(rows), np.asarray(residuals), np.asarray(is_check), strict=True
    ):
        what = "check" if check else "control"
        values = ", ".join("-" if v != v else f"{v:+.3f}" for v in resid)
        echo_progress(f"{what} {ids[row]}: dE, dN, dH {values} m", level=2)


#: What each stage's blunder test rejects, for the summary line.
_REJECTED_WHAT = {
    "relative_orientation": "y-parallaxes",
    "tie_points": "tie-point determinations",
    "models": "model point determinations",
    "control": "control coordinates",
    "straight_line": "straight-line conditions",
}


def _rejections(result: StripResult | BlockResult) -> tuple[Rejection, ...]:
    """Every rejection of a run, the bundle refinement's included."""
    refined = getattr(result, "refined", None)
    more = tuple(getattr(refined, "rejections", ()))
    # a block's strips: the rejections of forming each (a strip's are in its own)
    formed = tuple(r for strip in getattr(result, "strips", ()) for r in strip.rejections)
    return formed + tuple(result.rejections) + more


def _warning_lines(
    texts: list[str], rejections: Sequence[Rejection], files: Collection[str]
) -> list[str]:
    """The warnings to print: with ``-v`` all of them; by default each stage's
    blunder rejections (two or more) summed up in one line, at the place of
    its first, and every other warning as it is."""
    from .options import settings

    described = {r.describe(): r for r in rejections}
    if settings().level >= 1 or not any(t in described for t in texts):
        return texts
    by_stage: dict[str, list[Rejection]] = {}
    lines: list[str | tuple[str]] = []
    for text in texts:
        rejection = described.get(text)
        if rejection is None:
            lines.append(text)
            continue
        if rejection.stage not in by_stage:
            lines.append((rejection.stage,))
        by_stage.setdefault(rejection.stage, []).append(rejection)
    names = dict.fromkeys(n for n in ("report.json", _report_name(files)) if n and n in files)
    listed = " / ".join(names)
    where = f"listed in {listed}; " if listed else ""
    out = []
    for line in lines:
        if isinstance(line, str):
            out.append(line)
            continue
        group = by_stage[line[0]]
        if len(group) == 1:
            out.append(group[0].describe())
            continue
        what = _REJECTED_WHAT.get(line[0], "observations")
        applied = sum(r.applied for r in group)
        counts = [f"{applied} {what} rejected as blunders"] if applied else []
        if applied < len(group):
            kept = len(group) - applied
            counts.append(f'{kept} {what} fail the blunder test, kept (action = "report")')
        out.append(f"{line[0]}: {'; '.join(counts)} ({where}-v lists them here)")
    return out


def _report_name(names: Collection[str]) -> str | None:
    """The human-readable report among the output file names."""
    for preferred in ("report.html", "report.md"):
        if preferred in names:
            return preferred
    for name in names:
        if name.startswith("report.") and not name.endswith(".json"):
            return name
    return "report.json" if "report.json" in names else None


@click.command(
    epilog=DOCS_EPILOG,
    short_help="Adjust a strip and write the results.",
)
@project_arg
@click.option(
    "-o",
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Result folder (replaced as a whole). Default: [output] directory of the "
    "project, else 'out' beside strip.toml.",
)
@click.option(
    "--map-scale",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    metavar="N",
    help="Map scale denominator (5000 for 1:5000) for the tolerance verdicts of the "
    "report; overrides [report] map_scale.",
)
@common_options
def run(project_file: Path, out: Path | None, map_scale: float | None) -> None:
    """Adjust the strip of STRIP_TOML and write the result folder.

    Loads and validates the project, forms the strip model, fits it to the
    control and writes points.csv, photos.csv, report.json and the report
    into the result folder. The folder is replaced as a whole, only when the
    run succeeds; a folder that is not a previous result is never touched.

    \b
    Examples:
      stripaero run examples/film-strip/strip.toml
      stripaero run strip.toml --out results/2024-05 --map-scale 5000
      stripaero -q run strip.toml            # the summary only (no warnings)
    """
    from ..errors import ConvergenceError, GeometryError, StripAerotriWarning
    from ..project import load_project, output_folder
    from ..project import run as project_run
    from ..report.files import ResultFolder
    from ..report.summary import build_run
    from ..results import BlockResult

    started = time.perf_counter()
    echo_progress(f"loading {project_file}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        project = load_project(project_file)
        target = output_folder(project, out)
        echo_progress(
            f"project '{project.name}': {len(project.photo_ids)} photos, "
            f"{project.observations.n_points} points, {len(project.control.point_ids)} "
            f"control and check points, crs {project.crs}"
        )
        try:
            result = project_run.run_project(project, progress=echo_progress)
        except (GeometryError, ConvergenceError) as exc:
            if str(exc).startswith(tuple(f"{f}:" for f in project.input_files)):
                raise  # the message names its file already
            raise type(exc)(f"{project.path}: {exc}") from exc
        echo_progress("writing the report")
        outputs = build_run(result, project=project, map_scale=map_scale)
        files, summary = outputs.files, outputs.summary

    # Warnings only once the run has succeeded: a failed run prints its one error line.
    texts = dict.fromkeys((*project.warnings, *result.warnings, *(str(w.message) for w in caught)))
    for text in _warning_lines(list(texts), _rejections(result), files):
        echo_warning(text)

    echo_progress(f"writing {len(files)} files to {target}")
    with ResultFolder(target, protect=project.input_files) as folder:
        for name, data in files.items():
            folder.write_bytes(name, data if isinstance(data, bytes) else str(data).encode())

    if isinstance(result, BlockResult):
        _echo_block_details(result)
        _echo_block(summary, target)
        return
    _echo_details(result)
    elapsed = time.perf_counter() - started
    echo_result(f"strip '{summary.name}': {summary.n_photos} photos, {summary.n_points} points")
    if summary.refined:
        echo_result("bundle refinement: accuracy below is the refined solution's")
    for line in _accuracy_lines(summary):
        echo_result(line)
    verdict = _tolerance_line(summary.tolerances)
    if verdict:
        echo_result(verdict)
    if summary.report_name is not None:
        echo_result(f"report: {target / summary.report_name}")
    echo_result(f"results: {target}")
    echo_progress(f"done in {elapsed:.1f} s", level=1)


def _echo_block_details(result: BlockResult) -> None:
    """With ``-v`` every strip's models and tie points, the joins and the
    timings; with ``-vv`` also every control and check point's residual."""
    import numpy as np

    for spec, strip in zip(result.specs, result.strips, strict=True):
        rel = strip.relative
        echo_progress(
            f"strip {spec.name}: {strip.n_models} models, y-parallax sigma0 "
            f"{float(np.median(rel.sigma0_um)):.1f} µm (median of its pairs), "
            f"{len(strip.rejections)} rejections",
            level=1,
        )
    for join in result.joins:
        a, b = (result.specs[i].name for i in join.strips)
        echo_progress(
            f"strips {a} / {b}: {join.n_points} common points, mean plan "
            f"{join.mean_plan_m:.3f} m, largest {join.max_plan_m:.3f} m, transfer "
            f"{join.mean_transfer_um:.0f} µm",
            level=1,
        )
    _echo_timings_and_residuals(
        result.timings,
        result.control.point_ids,
        result.control_index,
        result.control_residuals,
        result.is_check,
    )


def _echo_block(summary: RunSummary, target: Path) -> None:
    """The summary of a block's run."""
    echo_result(
        f"block '{summary.name}': {summary.n_strips} strips, {summary.n_photos} photos, "
        f"{summary.n_points} points"
    )
    fit = summary.control_fit
    own = (
        ""
        if fit is None
        else f" (the {(summary.construction or 'model').rstrip('s')}s' own determinations: "
        f"{_fmt_m(fit.rmse_plan)}, {_fmt_m(fit.rmse_height)})"
    )
    for line in _accuracy_lines(summary, own):
        echo_result(line)
    join = summary.join
    if join is not None:
        a, b = join.strips
        echo_result(
            f"common points of the strips: largest mean discrepancy {_fmt_m(join.mean_plan_m)} "
            f"plan, {_fmt_m(join.mean_height_m)} height (strips {a} / {b})"
        )
    if join is not None and join.transfer_strips is not None:
        a, b = join.transfer_strips
        verdict = "within" if join.transfer_passed else "above"
        echo_result(
            f"transfer errors of the free block: largest mean {join.mean_transfer_um:.0f} µm "
            f"(strips {a} / {b}), {verdict} R4's {join.transfer_limit_um:.0f} µm"
        )
    tolerance = _tolerance_line(summary.tolerances)
    if tolerance is not None:
        echo_result(tolerance)
    echo_result(f"report: {target / 'report.html'}")
    echo_result(f"results: {target}")
