"""What a run gives, in short: :class:`RunSummary`, the typed summary that
``stripaero run`` prints (the command computes nothing itself and reads no
file back).

:func:`build_run` adjusts nothing: it takes a finished result (one strip or
a block) and makes the files of its result folder (:mod:`.outputs`,
:mod:`.block`) and their summary.  :func:`summarize` makes the summary from
the result alone, by the rules that write ``report.json``: the accuracy at
the control and check points, the overall tolerance verdict at the map
scale (:mod:`.verdict`, the sentence of the page's banner), a block's joins
and R4's transfer verdict, the self-calibration, the estimated observation
weights, the warnings, the
rejections, the timings and the figures ``-v`` shows.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._text import named
from ..results import AccuracyStatistics, BlockResult, PointWarning, Rejection, StripResult
from . import outputs
from .block import block_outputs, block_tolerances_record, build_block_report, joins_record
from .outputs import GEOJSON_LOCAL_NOTE
from .record import drift_warnings, tolerances_record
from .restored import without_restored
from .tolerances import TRANSFER_UM, transfer_passed
from .values import delivered_points
from .verdict import Verdict

if TYPE_CHECKING:
    from ..project import Project
    from ..results import SelfCalibrationOutcome, VarianceComponents
    from .aside import Standby

__all__ = [
    "Accuracy",
    "Calibration",
    "EstimatedWeights",
    "JoinVerdict",
    "RunOutputs",
    "RunSummary",
    "ToleranceVerdict",
    "build_run",
    "summarize",
]


@dataclass(frozen=True)
class Accuracy:
    """Counts and RMSE (metres) of residuals at the control or check points."""

    n_plan: int
    n_height: int
    rmse_plan: float
    rmse_height: float

    @classmethod
    def of(cls, statistics: AccuracyStatistics) -> Accuracy:
        return cls(
            int(statistics.n_plan),
            int(statistics.n_height),
            float(statistics.rmse_plan),
            float(statistics.rmse[2]),
        )


@dataclass(frozen=True)
class ToleranceVerdict:
    """The tolerance criteria at the map scale 1:``map_scale`` (method.md §7):
    how many were judged, how many could not be, and the names of those
    not met."""

    map_scale: float
    n_judged: int
    n_unjudged: int
    failed: tuple[str, ...]

    @property
    def passed(self) -> bool:
        return not self.failed


@dataclass(frozen=True)
class JoinVerdict:
    """The join of two strips that fits worst, and the largest mean transfer
    error against R4's limit.

    Attributes
    ----------
    strips : (str, str)
        The two strips whose common points disagree most (mean plan).
    mean_plan_m, mean_height_m : float
        Their mean discrepancies, metres.
    transfer_strips : (str, str) or None
        The two strips with the largest mean transfer error (None when no
        join has one).
    mean_transfer_um : float
        That error, µm in the image (NaN when none).
    transfer_limit_um : float
        R4's limit (:data:`~.tolerances.TRANSFER_UM`).
    """

    strips: tuple[str, str]
    mean_plan_m: float
    mean_height_m: float
    transfer_strips: tuple[str, str] | None = None
    mean_transfer_um: float = math.nan
    transfer_limit_um: float = TRANSFER_UM

    @property
    def transfer_passed(self) -> bool | None:
        """Within R4's limit (None when no transfer error was computed)."""
        return transfer_passed(self.mean_transfer_um)


@dataclass(frozen=True)
class Calibration:
    """A self-calibration in short: the parameters kept, sigma0 with them
    (None when every parameter was held) and without (NaN when not
    computed), and whether ``camera.toml`` was written."""

    kept: tuple[str, ...]
    sigma0: float | None
    sigma0_without: float
    camera_written: bool

    @classmethod
    def of(
        cls, outcome: SelfCalibrationOutcome | None, files: Sequence[str]
    ) -> Calibration | None:
        if outcome is None:
            return None
        estimate = outcome.estimate
        return cls(
            tuple(outcome.kept),
            None if estimate is None else float(estimate.sigma0),
            float(outcome.sigma0_without),
            "camera.toml" in files,
        )


@dataclass(frozen=True)
class EstimatedWeights:
    """The refinement's observation weights estimated from the data
    (``[adjustment] weights = "estimated"``, report.json
    ``bundle.variance_components``).

    Attributes
    ----------
    applied : bool
        The delivered adjustment ran with the estimated weights (False: they
        were only estimated, the adjustment kept the given ones).
    iterations : int
        Adjustments run with re-estimated weights after the first.
    converged : bool
        The estimates settled.
    groups : tuple of (str, str, float, float, bool)
        Each observation group's name, the unit of its sigmas (``"µm"``,
        ``"m"`` or ``"deg"``), its sigma as given and as estimated, and
        whether it was estimated (False: too little redundancy, kept as
        given).
    """

    applied: bool
    iterations: int
    converged: bool
    groups: tuple[tuple[str, str, float, float, bool], ...]

    @classmethod
    def of(cls, vc: VarianceComponents | None) -> EstimatedWeights | None:
        if vc is None:
            return None
        return cls(
            bool(vc.applied),
            int(vc.iterations),
            bool(vc.converged),
            tuple(
                (g.name, g.unit, float(g.sigma_apriori), float(g.sigma), bool(g.estimated))
                for g in vc.groups
            ),
        )


@dataclass(frozen=True)
class RunSummary:
    """A run in short, for the command line and for callers.

    Attributes
    ----------
    kind : {"strip", "block"}
    name : str
    n_strips, n_photos, n_points : int
        Strips, photos and triangulated points.
    refined : bool
        The accuracy is the bundle refinement's (the delivered coordinates).
    construction : str
        ``[adjustment] block`` as run.
    control, check : Accuracy
    control_fit : Accuracy or None
        A block's strips (or models) against the control by their own
        determinations (None for a strip, or after a refinement).
    verdict : Verdict
        The overall tolerance verdict, the sentence of the report's banner
        (what was judged at the map scale, what was not and why).
    tolerances : ToleranceVerdict or None
        The criteria at the map scale (None without a map scale).
    join : JoinVerdict or None
        A block's worst join and R4's transfer verdict (None for a strip).
    calibration : Calibration or None
        The self-calibration (None without one).
    weights : EstimatedWeights or None
        The observation weights estimated from the data (None unless asked
        for).
    warnings : tuple of str
        The run's warnings (those about one point
        :class:`~strip_aerotri.results.PointWarning`, which
        :meth:`warning_lines` sums up by their data).
    output_warnings : tuple of str
        The warnings the outputs add (the plan drift at the map scale,
        points.geojson not written); report.json lists both.
    restored : tuple of str
        The points the strip method (a block) left out that the bundle
        refinement restored and determined: counted as restored, not lost
        (:meth:`warning_lines`).
    rejections : tuple of Rejection
        Every rejection of the run: a block's strips', the adjustment's and
        the bundle refinement's.
    timings : dict of str to float
        Seconds per stage.
    details : tuple of (int, str)
        The figures per pair (or strip and join), the timings and the control
        and check points' residuals, each with the verbosity that shows it
        (1 for ``-v``, 2 for ``-vv``).
    files : tuple of str
        The result folder's files.
    """

    kind: str
    name: str
    n_strips: int
    n_photos: int
    n_points: int
    refined: bool
    construction: str
    control: Accuracy
    check: Accuracy
    verdict: Verdict
    control_fit: Accuracy | None = None
    tolerances: ToleranceVerdict | None = None
    join: JoinVerdict | None = None
    calibration: Calibration | None = None
    weights: EstimatedWeights | None = None
    warnings: tuple[str, ...] = ()
    output_warnings: tuple[str, ...] = ()
    restored: tuple[str, ...] = ()
    rejections: tuple[Rejection, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    details: tuple[tuple[int, str], ...] = ()
    files: tuple[str, ...] = ()

    @property
    def report_name(self) -> str | None:
        """The human-readable report among the files (``report.html``, else
        another ``report.*`` that is not JSON, else ``report.json``)."""
        for preferred in ("report.html", "report.md"):
            if preferred in self.files:
                return preferred
        for name in self.files:
            if name.startswith("report.") and not name.endswith(".json"):
                return name
        return "report.json" if "report.json" in self.files else None

    def warning_lines(self, texts: Sequence[str], *, every: bool = False) -> list[str]:
        """The warnings to print, each once in the order given: with ``every``
        (``-v``) all of them, as report.json lists them; else each stage's
        blunder rejections (two or more) summed up in one line, at the place
        of its first, naming the files that list them, and the points the
        refinement restored no longer counted among those the strip method
        left out (the refinement's note names them)."""
        unique = list(dict.fromkeys(texts))
        if every:
            return unique
        names = dict.fromkeys(
            n for n in ("report.json", self.report_name) if n and n in self.files
        )
        listed = " / ".join(names)
        unique = without_restored(unique, frozenset(self.restored))
        return _grouped_per_point(_grouped(unique, self.rejections, listed), listed)


@dataclass(frozen=True)
class RunOutputs:
    """The files of a result folder (name -> bytes) and their summary."""

    files: dict[str, bytes]
    summary: RunSummary


#: What each stage's blunder test rejects, for the summary line.
_REJECTED_WHAT = {
    "relative_orientation": "y-parallaxes",
    "tie_points": "tie-point determinations",
    "models": "model point determinations",
    "control": "control coordinates",
    "straight_line": "straight-line conditions",
}


def _observed(r: Rejection) -> tuple[str, tuple[str, ...], str]:
    """What a rejection is of: its point, photos and component."""
    return r.point, tuple(r.photos), r.component


def _grouped(texts: list[str], rejections: Sequence[Rejection], listed: str) -> list[str]:
    """Each stage's blunder rejections (two or more) among ``texts`` summed up
    in one line at the place of its first (``listed``: the files that list
    them); every other warning as it is."""
    described = {r.describe(): r for r in rejections}
    if not any(t in described for t in texts):
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
    where = f"listed in {listed}; " if listed else ""
    out = []
    for line in lines:
        if isinstance(line, str):
            out.append(line)
            continue
        group = by_stage[line[0]]
        if len({_observed(r) for r in group}) == 1:
            out.append(group[0].describe())
            continue
        what = _REJECTED_WHAT.get(line[0], "observations")
        # an observation rejected by two stages of one name (the ground
        # stage's control test and the bundle's) counts once
        applied = len({_observed(r) for r in group if r.applied})
        counts = [f"{applied} {what} rejected as blunders"] if applied else []
        kept = len({_observed(r) for r in group if not r.applied})
        if kept:
            effects = {r.effect for r in group if not r.applied}
            why = (
                effects.pop().removeprefix("kept: ")
                if len(effects) == 1 and next(iter(effects)).startswith("kept: ")
                else 'action = "report"'
            )
            counts.append(f"{kept} {what} fail the blunder test, kept ({why})")
        out.append(f"{line[0]}: {'; '.join(counts)} ({where}-v lists them here)")
    return out


#: Warnings about one point each (:class:`~strip_aerotri.results.PointWarning`,
#: by kind) that two or more of a kind and cause sum up in one line: the
#: summing line's text before and after the names (with the cause for
#: ``{cause}``).
_PER_POINT = {
    "weak check": (
        "check points are weakly determined by their own rays",
        "and left out of the check statistics; measure them on more photos, farther apart",
    ),
    "control not triangulated": (
        "control points are not triangulated",
        "and left out (each: {cause})",
    ),
    "check not triangulated": (
        "check points are not triangulated",
        "and left out (each: {cause})",
    ),
}


def _grouped_per_point(texts: list[str], listed: str) -> list[str]:
    """Two or more warnings of a kind of :data:`_PER_POINT` and one cause
    among ``texts`` summed up in one line at the place of the first, naming
    five points and the files that list them; every other warning as it is."""
    groups: dict[tuple[str, str], list[tuple[int, PointWarning]]] = {}
    for i, text in enumerate(texts):
        if isinstance(text, PointWarning) and text.kind in _PER_POINT:
            groups.setdefault((text.kind, text.cause), []).append((i, text))
    where = f"listed in {listed}; " if listed else ""
    gone: set[int] = set()
    summed: dict[int, str] = {}
    for (kind, cause), group in groups.items():
        if len(group) < 2:
            continue
        head, tail = _PER_POINT[kind]
        summed[group[0][0]] = (
            f"{len(group)} {head} ({named([w.point for _, w in group])}) "
            f"{tail.format(cause=cause)} ({where}-v lists them here)"
        )
        gone.update(i for i, _ in group[1:])
    return [summed.get(i, t) for i, t in enumerate(texts) if i not in gone]


def _join(result: BlockResult) -> JoinVerdict | None:
    worst = max(result.joins, key=lambda j: j.mean_plan_m, default=None)
    if worst is None:
        return None
    names = result.specs
    a, b = (names[i].name for i in worst.strips)
    transfer = [j for j in result.joins if math.isfinite(j.mean_transfer_um)]
    most = max(transfer, key=lambda j: j.mean_transfer_um, default=None)
    return JoinVerdict(
        strips=(a, b),
        mean_plan_m=float(worst.mean_plan_m),
        mean_height_m=float(worst.mean_height_m),
        transfer_strips=None
        if most is None
        else (names[most.strips[0]].name, names[most.strips[1]].name),
        mean_transfer_um=math.nan if most is None else float(most.mean_transfer_um),
    )


def _verdicts(tolerances: Mapping[str, Any]) -> tuple[Verdict, ToleranceVerdict | None]:
    """The overall verdict that :func:`~.verdict.with_verdict` wrote into
    report.json's ``tolerances``, and its criteria (None without a map
    scale)."""
    verdict = Verdict(str(tolerances["verdict"]["status"]), str(tolerances["verdict"]["text"]))
    if tolerances.get("map_scale") is None:
        return verdict, None
    criteria: Sequence[Mapping[str, Any]] = tolerances.get("criteria") or ()
    judged = [c for c in criteria if c.get("passed") is not None]
    return verdict, ToleranceVerdict(
        map_scale=float(tolerances["map_scale"]),
        n_judged=len(judged),
        n_unjudged=len(criteria) - len(judged),
        failed=tuple(str(c["name"]) for c in judged if c["passed"] is False),
    )


def _residual_details(
    timings: dict[str, float],
    ids: Sequence[str],
    rows: np.ndarray,
    residuals: np.ndarray,
    is_check: np.ndarray,
) -> list[tuple[int, str]]:
    """The stages' times (``-v``); every control and check point's residual,
    given − adjusted, metres (``-vv``)."""
    lines = [(1, f"{stage}: {seconds:.2f} s") for stage, seconds in timings.items()]
    for row, resid, check in zip(  # Python numbers: formatted faster than numpy's
        np.asarray(rows).tolist(),
        np.asarray(residuals, dtype=np.float64).tolist(),
        np.asarray(is_check).tolist(),
        strict=True,
    ):
        what = "check" if check else "control"
        values = ", ".join("-" if v != v else f"{v:+.3f}" for v in resid)
        lines.append((2, f"{what} {ids[row]}: dE, dN, dH {values} m"))
    return lines


def _strip_details(result: StripResult) -> tuple[tuple[int, str], ...]:
    """Per pair and model: points, sigma0, largest y-parallax, iterations, ties."""
    strip = result.strip
    rel = strip.relative
    lines = []
    columns = (  # Python numbers: formatted faster than numpy's
        np.asarray(a).tolist()
        for a in (
            strip.tie_count,
            strip.scale_ratio,
            rel.n_points,
            rel.sigma0_um,
            rel.max_parallax_um,
            rel.iterations,
        )
    )
    ties, ratios, points, sigma0, largest, iterations = columns
    for m, label in enumerate(strip.model_labels):
        tie = "" if m == 0 else f", {int(ties[m])} tie points, scale ratio {ratios[m]:.5f}"
        lines.append(
            (
                1,
                f"{label}: {int(points[m])} points, sigma0 {sigma0[m]:.1f} µm, "
                f"largest y-parallax {largest[m]:.1f} µm, "
                f"{int(iterations[m])} iterations{tie}",
            )
        )
    ground = result.refined if result.refined is not None else result.ground
    lines += _residual_details(
        result.timings,
        result.control.point_ids,
        ground.control_index,
        ground.control_residuals,
        ground.is_check,
    )
    return tuple(lines)


def _block_details(result: BlockResult) -> tuple[tuple[int, str], ...]:
    """Per strip and per join of two strips, then the timings and residuals."""
    lines = [
        (
            1,
            f"strip {spec.name}: {strip.n_models} models, y-parallax sigma0 "
            f"{float(np.median(strip.relative.sigma0_um)):.1f} µm (median of its pairs), "
            f"{len(strip.rejections)} rejections",
        )
        for spec, strip in zip(result.specs, result.strips, strict=True)
    ]
    for join in result.joins:
        a, b = (result.specs[i].name for i in join.strips)
        lines.append(
            (
                1,
                f"strips {a} / {b}: {join.n_points} common points, mean plan "
                f"{join.mean_plan_m:.3f} m, largest {join.max_plan_m:.3f} m, transfer "
                f"{join.mean_transfer_um:.0f} µm",
            )
        )
    lines += _residual_details(
        result.timings,
        result.control.point_ids,
        result.control_index,
        result.control_residuals,
        result.is_check,
    )
    return tuple(lines)


def _rejections(result: StripResult | BlockResult) -> tuple[Rejection, ...]:
    """Every rejection of a run: a block's strips' (a strip's are in its own),
    the adjustment's, then the bundle refinement's."""
    refined = getattr(result, "refined", None)
    more = tuple(getattr(refined, "rejections", ()))
    formed = tuple(r for strip in getattr(result, "strips", ()) for r in strip.rejections)
    return formed + tuple(result.rejections) + more


def _block_summary(
    result: BlockResult, map_scale: float | None, name: str, files: Sequence[str]
) -> RunSummary:
    fit = result.control_fit_statistics
    verdict, tolerances = _verdicts(
        block_tolerances_record(result, map_scale, joins_record(result, map_scale))
    )
    return RunSummary(
        kind="block",
        name=name,
        n_strips=len(result.specs),
        n_photos=len(result.photo_ids),
        n_points=delivered_points(result),
        refined=bool(result.refined),
        construction="" if result.options is None else result.options.block.value,
        control=Accuracy.of(result.control_statistics),
        check=Accuracy.of(result.check_statistics),
        verdict=verdict,
        tolerances=tolerances,
        control_fit=None if fit is None or result.refined else Accuracy.of(fit),
        join=_join(result),
        calibration=Calibration.of(result.self_calibration, files),
        weights=EstimatedWeights.of(result.variance_components),
        warnings=tuple(result.warnings),
        restored=result.restored_points,
        rejections=_rejections(result),
        timings=dict(result.timings),
        details=_block_details(result),
        files=tuple(files),
    )


def summarize(
    result: StripResult | BlockResult,
    *,
    map_scale: float | None = None,
    name: str = "",
    files: Sequence[str] = (),
) -> RunSummary:
    """The summary of a run, from its result alone.

    Parameters
    ----------
    result : StripResult or BlockResult
    map_scale : float, optional
        Map scale denominator of the tolerance verdicts (as given to the
        report).
    name : str
        The project's name.
    files : sequence of str
        The result folder's files (what was written).
    """
    if isinstance(result, BlockResult):
        return _block_summary(result, map_scale, name, files)
    final = result.refined if result.refined is not None else result
    refined = result.refined
    local = (GEOJSON_LOCAL_NOTE,) if result.ground.crs.is_local else ()
    verdict, tolerances = _verdicts(tolerances_record(result, map_scale))
    return RunSummary(
        kind="strip",
        name=name,
        n_strips=1,
        n_photos=len(result.photo_ids),
        # the delivered points (points.csv): the refinement's when there is one
        n_points=delivered_points(result),
        refined=refined is not None,
        construction="" if result.options is None else result.options.block.value,
        control=Accuracy.of(final.control_statistics),
        check=Accuracy.of(final.check_statistics),
        verdict=verdict,
        tolerances=tolerances,
        calibration=None if refined is None else Calibration.of(refined.self_calibration, files),
        weights=None if refined is None else EstimatedWeights.of(refined.variance_components),
        warnings=tuple(result.warnings),
        output_warnings=(*local, *drift_warnings(result, map_scale)),
        restored=result.restored_points,
        rejections=_rejections(result),
        timings=dict(result.timings),
        details=_strip_details(result),
        files=tuple(files),
    )


def build_run(
    result: StripResult | BlockResult,
    *,
    project: Project | None = None,
    map_scale: float | None = None,
    standby: Standby | None = None,
) -> RunOutputs:
    """The files of the result folder of ``result`` and their summary.

    ``map_scale`` overrides the project's ``[report] map_scale``; ``standby``
    draws a strip's figures (:func:`~.outputs.build_outputs`).  The files
    are those of :func:`~.outputs.build_outputs` (a block's, of
    :func:`~.block.build_block_outputs`), byte for byte.
    """
    scale = map_scale
    if scale is None and project is not None:
        scale = project.report.map_scale
    name = "" if project is None else project.name
    if isinstance(result, BlockResult):
        record = build_block_report(result, project=project, map_scale=scale)
        files = block_outputs(result, record, project=project)
    else:
        files, _ = outputs.strip_outputs(result, project=project, map_scale=scale, standby=standby)
    summary = summarize(result, map_scale=scale, name=name, files=tuple(files))
    return RunOutputs(files, summary)
