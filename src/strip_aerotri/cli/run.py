"""``stripaero run``: adjust a project and write its result folder."""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Collection, Mapping, Sequence
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import (
    DOCS_EPILOG,
    common_options,
    echo_progress,
    echo_result,
    echo_warning,
    project_arg,
    settings,
)

if TYPE_CHECKING:  # the numerical modules are imported when the command runs
    from .._typing import ArrayLike
    from ..project import Project
    from ..report.files import ResultFolder
    from ..results import BlockResult, Rejection, StripResult

__all__ = ["run"]


def _fmt_m(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.3f} m"


def _tolerance_verdict(report_json: bytes | None) -> str | None:
    """The overall tolerance verdict of report.json, in the words of the report's
    banner and plain summary."""
    import json

    try:
        verdict = json.loads(report_json or b"{}")["tolerances"]["verdict"]["text"]
    except (ValueError, KeyError, TypeError):
        return None
    return f"tolerances (R4 §1.7.7): {verdict}"


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
            effects = {r.effect for r in group if not r.applied}
            why = (
                effects.pop().removeprefix("kept: ")
                if len(effects) == 1 and next(iter(effects)).startswith("kept: ")
                else 'action = "report"'
            )
            counts.append(f"{kept} {what} fail the blunder test, kept ({why})")
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
    type=click.Path(path_type=Path),
    default=None,
    help="Result folder (its results replaced, other files kept). Default: [output] "
    "directory of the project, else 'out' beside strip.toml.",
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
    into the result folder. The results are replaced only when the run
    succeeds; other files in the folder (notes, exports) are kept; a folder
    that is not a previous result is never touched. One run at a time may
    write a folder; Ctrl-C stops with exit code 130 and says which result
    the folder holds.

    \b
    Examples:
      stripaero run examples/film-strip/strip.toml
      stripaero run strip.toml --out results/2024-05 --map-scale 5000
      stripaero -q run strip.toml            # the summary only (no warnings)
    """
    from ..errors import StripAerotriWarning
    from ..project import load_project, output_folder
    from ..report.files import ResultFolder
    from ..report.lock import FolderLock
    from ..results import BlockResult

    started = time.perf_counter()
    echo_progress(f"loading {project_file}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        project = load_project(project_file)
        target = output_folder(project, out)
        lock = FolderLock(target)
        folder = ResultFolder(target, protect=project.input_files)
        # before the lock is taken, so that a Ctrl-C as soon as it exists is told too
        settings().interrupted = _folder_state(folder)
        with lock:
            result, files = _adjust_and_report(project, map_scale)
            # Warnings only once the run has succeeded: a failed run prints its one
            # error line.
            texts = (
                *project.warnings,
                *result.warnings,
                *(str(w.message) for w in caught),
                *_report_warnings(files.get("report.json")),
            )
            for text in _warning_lines(list(dict.fromkeys(texts)), _rejections(result), files):
                echo_warning(text)
            echo_progress(f"writing {len(files)} files to {target}")
            with folder:
                for name, data in files.items():
                    folder.write_bytes(
                        name, data if isinstance(data, bytes) else str(data).encode()
                    )
    _echo_kept(folder)

    if isinstance(result, BlockResult):
        _echo_block_details(result)
        _echo_block(result, project.name, files, target, project.adjustment.block.value)
        return
    _echo_details(result)
    elapsed = time.perf_counter() - started
    n_done = int(result.strip.triangulated.sum())
    # With a bundle refinement the written points come from it: so do the figures.
    final = result.refined if result.refined is not None else result
    control = final.control_statistics
    check = final.check_statistics
    echo_result(f"strip '{project.name}': {len(result.photo_ids)} photos, {n_done} points")
    if result.refined is not None:
        echo_result("bundle refinement: accuracy below is the refined solution's")
        _echo_calibration(result.refined.self_calibration, target, files)
    echo_result(
        f"control: {control.n_plan} plan, {control.n_height} height; "
        f"RMSE plan {_fmt_m(control.rmse_plan)}, height {_fmt_m(float(control.rmse[2]))}"
    )
    if check.n_plan or check.n_height:
        echo_result(
            f"check points: {check.n_plan} plan, {check.n_height} height; "
            f"RMSE plan {_fmt_m(check.rmse_plan)}, height {_fmt_m(float(check.rmse[2]))}"
        )
    else:
        echo_result("check points: none")
    verdict = _tolerance_verdict(files.get("report.json"))
    if verdict:
        echo_result(verdict)
    report_name = _report_name(files)
    if report_name is not None:
        echo_result(f"report: {target / report_name}")
    echo_result(f"results: {target}")
    echo_progress(f"done in {elapsed:.1f} s", level=1)


def _echo_calibration(outcome: Any, target: Path, files: Mapping[str, bytes]) -> None:
    """One line on a self-calibration: the kept parameters and camera.toml."""
    if outcome is None:
        return
    kept = ", ".join(outcome.kept) or "none"
    sigma = "" if outcome.estimate is None else f", sigma0 {outcome.estimate.sigma0:.3g}"
    without = outcome.sigma0_without
    sigma += f" (without: {without:.3g})" if math.isfinite(without) else ""
    written = f"; camera: {target / 'camera.toml'}" if "camera.toml" in files else ""
    echo_result(f"self-calibration: kept {kept}{sigma}{written}")


def _report_warnings(report_json: bytes | None) -> list[str]:
    """The warnings report.json adds to the run's (the plan drift at the map scale)."""
    import json

    try:
        listed = json.loads(report_json or b"{}").get("warnings") or []
    except ValueError:
        return []
    return [str(w) for w in listed]


def _adjust_and_report(
    project: Project, map_scale: float | None
) -> tuple[StripResult | BlockResult, dict[str, bytes]]:
    """Adjust the project and make the result folder's files."""
    from ..errors import ConvergenceError, GeometryError
    from ..project import run as project_run
    from ..results import BlockResult

    echo_progress(
        f"project '{project.name}': {len(project.photo_ids)} photos, "
        f"{project.observations.n_points} points, {len(project.control.point_ids)} "
        f"control and check points, crs {project.crs}"
    )
    from ..report.aside import Standby
    from ..report.html import prepare_drawing

    # A strip's figures are drawn by a process that imports matplotlib on the
    # second core while this one adjusts (report/aside.py).
    with Standby(prepare_drawing) if not project.is_block else nullcontext() as standby:
        try:
            result = project_run.run_project(project, progress=echo_progress)
        except (GeometryError, ConvergenceError) as exc:
            if str(exc).startswith(tuple(f"{f}:" for f in project.input_files)):
                raise  # the message names its file already
            raise type(exc)(f"{project.path}: {exc}") from exc
        echo_progress("writing the report")
        scale = map_scale if map_scale is not None else project.report.map_scale
        if isinstance(result, BlockResult):
            from ..report.block import build_block_outputs

            return result, build_block_outputs(result, project=project, map_scale=scale)
        from ..report import outputs as report

        files = report.build_outputs(result, project=project, map_scale=scale, standby=standby)
        return result, files


def _folder_state(folder: ResultFolder) -> Callable[[], str]:
    """What the result folder holds if the run stops now (for Ctrl-C's line)."""
    from ..report.files import RESULT_MARKER

    target = folder.target
    previous = (target / RESULT_MARKER).is_file()

    def state() -> str:
        if folder.committed:
            return f"'{target}' holds the new result (written before the interrupt)"
        if previous:
            return f"'{target}' holds the previous result, unchanged"
        return f"no result was written to '{target}'"

    return state


def _echo_kept(folder: ResultFolder) -> None:
    """Name the files of the previous folder the run kept, and the exports
    among them that now describe the previous result."""
    if folder.kept:
        echo_progress(f"kept in {folder.target}: {', '.join(folder.kept)}")
    if folder.exports:
        echo_warning(
            f"{folder.target}: {', '.join(folder.exports)} kept, but exported from the previous "
            "result; run stripaero export again to bring them up to date"
        )


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


def _echo_block(
    result: BlockResult,
    name: str,
    files: dict[str, bytes],
    target: Path,
    construction: str = "model",
) -> None:
    """The summary of a block's run."""
    import numpy as np

    n_done = int(np.isfinite(result.points).all(axis=1).sum())
    echo_result(
        f"block '{name}': {len(result.specs)} strips, {len(result.photo_ids)} photos, "
        f"{n_done} points"
    )
    control, check = result.control_statistics, result.check_statistics
    fit = result.control_fit_statistics
    own = (
        ""
        if fit is None or result.refined
        else f" (the {construction.rstrip('s')}s' own determinations: {_fmt_m(fit.rmse_plan)}, "
        f"{_fmt_m(float(fit.rmse[2]))})"
    )
    echo_result(
        f"control: {control.n_plan} plan, {control.n_height} height; "
        f"RMSE plan {_fmt_m(control.rmse_plan)}, height {_fmt_m(float(control.rmse[2]))}{own}"
    )
    if check.n_plan or check.n_height:
        echo_result(
            f"check points: {check.n_plan} plan, {check.n_height} height; "
            f"RMSE plan {_fmt_m(check.rmse_plan)}, height {_fmt_m(float(check.rmse[2]))}"
        )
    else:
        echo_result("check points: none")
    _echo_calibration(result.self_calibration, target, files)
    worst = max(result.joins, key=lambda j: j.mean_plan_m, default=None)
    if worst is not None:
        a, b = (result.specs[i].name for i in worst.strips)
        echo_result(
            f"common points of the strips: largest mean discrepancy {_fmt_m(worst.mean_plan_m)} "
            f"plan, {_fmt_m(worst.mean_height_m)} height (strips {a} / {b})"
        )
    transfer = [j for j in result.joins if math.isfinite(j.mean_transfer_um)]
    if transfer:
        from ..report.block import TRANSFER_UM

        worst = max(transfer, key=lambda j: j.mean_transfer_um)
        a, b = (result.specs[i].name for i in worst.strips)
        verdict = "within" if worst.mean_transfer_um <= TRANSFER_UM else "above"
        echo_result(
            f"transfer errors of the free block: largest mean {worst.mean_transfer_um:.0f} µm "
            f"(strips {a} / {b}), {verdict} R4's {TRANSFER_UM:.0f} µm"
        )
    tolerance = _tolerance_verdict(files.get("report.json"))
    if tolerance is not None:
        echo_result(tolerance)
    echo_result(f"report: {target / 'report.html'}")
    echo_result(f"results: {target}")
