"""What a run gives, in short: :class:`RunSummary`, the typed summary that
``stripaero run`` prints (the command computes nothing itself).

:func:`build_run` adjusts nothing: it takes a finished result (one strip or
a block) and writes the files of its result folder (:mod:`.outputs`,
:mod:`.block`) and their summary: the accuracy at the control and check
points, the tolerance verdicts at the map scale, a block's joins and R4's
transfer verdict, the warnings and the timings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..results import AccuracyStatistics, BlockResult, StripResult
from . import outputs
from .block import block_outputs, build_block_report
from .tolerances import TRANSFER_UM, transfer_passed

if TYPE_CHECKING:
    from ..project import Project

__all__ = [
    "Accuracy",
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
    """The tolerance criteria at the map scale 1:``map_scale`` (method.md §7)."""

    map_scale: float
    n_judged: int
    n_unjudged: int
    failed: tuple[str, ...]

    @property
    def passed(self) -> bool:
        return not self.failed


@dataclass(frozen=True)
class JoinVerdict:
    """The join of two strips that fits worst: its mean discrepancies (m) and
    the largest mean transfer error (µm) against R4's limit."""

    strips: tuple[str, str]
    mean_plan_m: float
    mean_height_m: float
    transfer_strips: tuple[str, str] | None = None
    mean_transfer_um: float = math.nan
    transfer_limit_um: float = TRANSFER_UM

    @property
    def transfer_passed(self) -> bool | None:
        return transfer_passed(self.mean_transfer_um)


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
    tolerances : ToleranceVerdict or None
        None without a map scale.
    join : JoinVerdict or None
        A block's worst join (None for a strip).
    warnings : tuple of str
    timings : dict of str to float
        Seconds per stage.
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
    control_fit: Accuracy | None = None
    tolerances: ToleranceVerdict | None = None
    join: JoinVerdict | None = None
    warnings: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    files: tuple[str, ...] = ()

    @property
    def report_name(self) -> str | None:
        """The report to open (``report.html``, else ``report.json``)."""
        for name in ("report.html", "report.json"):
            if name in self.files:
                return name
        return None


@dataclass(frozen=True)
class RunOutputs:
    """The files of a result folder (name -> bytes) and their summary."""

    files: dict[str, bytes]
    summary: RunSummary


def _tolerances(record: Mapping[str, Any]) -> ToleranceVerdict | None:
    tolerances = record.get("tolerances") or {}
    if tolerances.get("map_scale") is None:
        return None
    criteria: Sequence[Mapping[str, Any]] = tolerances.get("criteria") or ()
    judged = [c for c in criteria if c.get("passed") is not None]
    return ToleranceVerdict(
        map_scale=float(tolerances["map_scale"]),
        n_judged=len(judged),
        n_unjudged=len(criteria) - len(judged),
        failed=tuple(str(c["name"]) for c in judged if c["passed"] is False),
    )


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


def summarize(
    result: StripResult | BlockResult,
    record: Mapping[str, Any],
    *,
    name: str,
    files: Sequence[str] = (),
) -> RunSummary:
    """The summary of a run from its result and its ``report.json`` content."""
    import numpy as np

    options = result.options
    construction = "" if options is None else options.block.value
    if isinstance(result, BlockResult):
        fit = result.control_fit_statistics
        return RunSummary(
            kind="block",
            name=name,
            n_strips=len(result.specs),
            n_photos=len(result.photo_ids),
            n_points=int(np.isfinite(result.points).all(axis=1).sum()),
            refined=bool(result.refined),
            construction=construction,
            control=Accuracy.of(result.control_statistics),
            check=Accuracy.of(result.check_statistics),
            control_fit=None if fit is None or result.refined else Accuracy.of(fit),
            tolerances=_tolerances(record),
            join=_join(result),
            warnings=tuple(result.warnings),
            timings=dict(result.timings),
            files=tuple(files),
        )
    final = result.refined if result.refined is not None else result
    return RunSummary(
        kind="strip",
        name=name,
        n_strips=1,
        n_photos=len(result.photo_ids),
        n_points=int(result.strip.triangulated.sum()),
        refined=result.refined is not None,
        construction=construction,
        control=Accuracy.of(final.control_statistics),
        check=Accuracy.of(final.check_statistics),
        tolerances=_tolerances(record),
        warnings=tuple(result.warnings),
        timings=dict(result.timings),
        files=tuple(files),
    )


def build_run(
    result: StripResult | BlockResult,
    *,
    project: Project | None = None,
    map_scale: float | None = None,
) -> RunOutputs:
    """The files of the result folder of ``result`` and their summary.

    ``map_scale`` overrides the project's ``[report] map_scale``.
    """
    scale = map_scale
    if scale is None and project is not None:
        scale = project.report.map_scale
    name = "" if project is None else project.name
    if isinstance(result, BlockResult):
        record = build_block_report(result, project=project, map_scale=scale)
        files = block_outputs(result, record, project=project)
    else:
        files, record = outputs.strip_outputs(result, project=project, map_scale=scale)
    return RunOutputs(files, summarize(result, record, name=name, files=tuple(files)))
