"""``stripaero run``: adjust a project and write its result folder."""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
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
    settings,
)

#: True in the ``stripaero`` script (:func:`.main.main` sets it): a run then owns
#: its process and tunes what is process-wide (glibc's allocator, numpy's
#: unused submodules deferred); a run called in another program's process
#: (click's CliRunner, a test) leaves those alone.
OWNS_PROCESS = False

if TYPE_CHECKING:  # the numerical modules are imported when the command runs
    from ..project import Project
    from ..report.aside import Standby
    from ..report.files import ResultFolder
    from ..report.summary import RunOutputs, RunSummary

__all__ = ["run"]


def _fmt_m(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.3f} m"


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
    from ..project import output_folder
    from ..report.files import ResultFolder
    from ..report.lock import FolderLock
    from .imports import defer_numpy_submodules
    from .loading import loaded
    from .memory import keep_freed_memory

    if OWNS_PROCESS:  # what is process-wide, only where the run owns the process
        keep_freed_memory()  # this process's arrays come and go by the hundred
        defer_numpy_submodules()  # those scipy touches and a run does not use
    started = time.perf_counter()
    echo_progress(f"loading {project_file}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        # loaded by the run's second process while this one imports the run's
        # modules; that process then draws a strip's figures (cli/loading.py)
        with loaded(project_file, caught) as (project, standby):
            target = output_folder(project, out)
            lock = FolderLock(target)
            folder = ResultFolder(target, protect=project.input_files)
            # before the lock is taken, so that a Ctrl-C as soon as it exists is told too
            settings().interrupted = _folder_state(folder)
            with lock:
                outputs = _adjust_and_report(project, map_scale, standby)
                summary, files = outputs.summary, outputs.files
                # Warnings only once the run has succeeded: a failed run prints its one
                # error line.
                texts = (
                    *project.warnings,
                    *summary.warnings,
                    *(str(w.message) for w in caught),
                    *summary.output_warnings,
                )
                for text in summary.warning_lines(texts, every=settings().level >= 1):
                    echo_warning(text, where="report.json")
                echo_progress(f"writing {len(files)} files to {target}")
                with folder:
                    for name, data in files.items():
                        folder.write_bytes(name, data)
    _echo_kept(folder)
    for level, line in summary.details:
        echo_progress(line, level=level)
    if summary.kind == "block":
        _echo_block(summary, target)
        return
    _echo_strip(summary, target)
    echo_progress(f"done in {time.perf_counter() - started:.1f} s", level=1)


#: The line saying that the accuracy printed is the bundle refinement's.
_REFINED_LINE = "bundle refinement: accuracy below is the refined solution's"


def _echo_accuracy(summary: RunSummary, own: str = "") -> None:
    """The control's and the check points' lines (``own``: a block's fit)."""
    control, check = summary.control, summary.check
    echo_result(
        f"control: {control.n_plan} plan, {control.n_height} height; "
        f"RMSE plan {_fmt_m(control.rmse_plan)}, height {_fmt_m(control.rmse_height)}{own}"
    )
    if check.n_plan or check.n_height:
        echo_result(
            f"check points: {check.n_plan} plan, {check.n_height} height; "
            f"RMSE plan {_fmt_m(check.rmse_plan)}, height {_fmt_m(check.rmse_height)}"
        )
    else:
        echo_result("check points: none")


def _echo_strip(summary: RunSummary, target: Path) -> None:
    """The summary of a strip's run."""
    echo_result(f"strip '{summary.name}': {summary.n_photos} photos, {summary.n_points} points")
    if summary.refined:
        # the written points come from the refinement: so do the figures
        echo_result(_REFINED_LINE)
        _echo_calibration(summary, target)
        _echo_weights(summary)
    _echo_accuracy(summary)
    echo_result(f"tolerances (R4 §1.7.7): {summary.verdict.text}")
    if summary.report_name is not None:
        echo_result(f"report: {target / summary.report_name}")
    echo_result(f"results: {target}")


def _echo_calibration(summary: RunSummary, target: Path) -> None:
    """One line on a self-calibration: the kept parameters, sigma0 with them and
    with the camera as given, and camera.toml (the given camera when none is kept)."""
    calibration = summary.calibration
    if calibration is None:
        return
    without = calibration.sigma0_without
    given = _three_digits(without) if math.isfinite(without) else ""
    camera = f"; camera: {target / 'camera.toml'}" if calibration.camera_written else ""
    if calibration.sigma0 is None:  # nothing kept (selfcal: no sigma0 without a kept set)
        # camera.toml follows every self-calibration (docs/outputs.md): the given camera
        echo_result(
            "self-calibration: no parameter kept, the camera is left as given"
            + (f" (sigma0 {given})" if given else "")
            + (f"{camera} (the given camera)" if camera else "")
        )
        return
    sigma0 = _three_digits(calibration.sigma0)
    echo_result(
        f"self-calibration: kept {', '.join(calibration.kept)}, sigma0 {sigma0}"
        + (f" (with the camera as given: {given})" if given else "")
        + camera
    )


def _three_digits(value: float) -> str:
    """``value`` to 3 significant digits, trailing zeros kept (0.38: "0.380",
    so that two sigma0 side by side read alike; 100.0: "100")."""
    text = f"{value:#.3g}"
    return text[:-1] if text.endswith(".") else text


def _echo_weights(summary: RunSummary) -> None:
    """One line on the observation weights estimated from the data: each
    group's sigma as estimated and as given, with its unit."""
    weights = summary.weights
    if weights is None:
        return
    how = (
        f"applied ({weights.iterations} more adjustment(s), "
        + ("settled" if weights.converged else "not settled")
        + ")"
        if weights.applied
        else "not applied"
    )
    groups = "; ".join(
        f"{name} {sigma:.3g} {unit} (given {given:.3g})"
        if estimated
        else f"{name} {given:.3g} {unit} as given (too little redundancy)"
        for name, unit, given, sigma, estimated in weights.groups
    )
    echo_result(f"observation weights estimated from the data, {how}: {groups}")


def _adjust_and_report(
    project: Project, map_scale: float | None, standby: Standby | None
) -> RunOutputs:
    """Adjust the project and make the result folder's files and their summary
    (a strip's figures drawn by ``standby``, cli/loading.py)."""
    from ..errors import ConvergenceError, GeometryError
    from ..project import run as project_run
    from ..report.summary import build_run

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
    return build_run(result, project=project, map_scale=map_scale, standby=standby)


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


def _echo_block(summary: RunSummary, target: Path) -> None:
    """The summary of a block's run."""
    echo_result(
        f"block '{summary.name}': {summary.n_strips} strips, {summary.n_photos} photos, "
        f"{summary.n_points} points"
    )
    if summary.refined:
        echo_result(_REFINED_LINE)
    # as a strip's: the refinement's camera and weights, then its accuracy
    _echo_calibration(summary, target)
    _echo_weights(summary)
    fit = summary.control_fit
    own = (
        ""
        if fit is None
        else f" (the {summary.construction.rstrip('s')}s' own determinations: "
        f"{_fmt_m(fit.rmse_plan)}, {_fmt_m(fit.rmse_height)})"
    )
    _echo_accuracy(summary, own)
    join = summary.join
    if join is not None:
        a, b = join.strips
        echo_result(
            f"common points of the strips: largest mean discrepancy {_fmt_m(join.mean_plan_m)} "
            f"plan, {_fmt_m(join.mean_height_m)} height (strips {a} / {b})"
            # the joins are the block transformation's, also after a refinement
            + (", in the block's transformation" if summary.refined else "")
        )
        if join.transfer_strips is not None:
            a, b = join.transfer_strips
            verdict = "within" if join.transfer_passed else "above"
            echo_result(
                f"transfer errors of the free block: largest mean {join.mean_transfer_um:.0f} "
                f"µm (strips {a} / {b}), {verdict} R4's {join.transfer_limit_um:.0f} µm"
            )
    echo_result(f"tolerances (R4 §1.7.7): {summary.verdict.text}")
    echo_result(f"report: {target / 'report.html'}")
    echo_result(f"results: {target}")
