"""The warnings of the points a bundle refinement restored.

The strip method (or the block) warns of each point it leaves out; the
refinement may intersect such a point from its photos and determine it
(:mod:`strip_aerotri.bundle.start_points`), and its note names the points
it restored.  report.json keeps both stages' texts.  The command line
(:meth:`.summary.RunSummary.warning_lines`) and the report pages list the
restored points as restored, not as lost: :func:`without_restored` leaves
them out of the strip method's warnings of points left out.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from ..results import PointWarning

__all__ = ["page_warnings", "without_restored"]


def without_restored(texts: Sequence[str], restored: frozenset[str]) -> list[str]:
    """The strip method's warnings about the points it left out, without
    those the refinement restored and determined: a control or check point's
    own warning left out, the count of the points not triangulated for a
    cause made again without them (and left out when none is left).  Only
    :class:`~strip_aerotri.results.PointWarning` texts are read for their
    points; every other text stays as it is."""
    if not restored:
        return list(texts)
    out: list[str] = []
    for text in texts:
        if not isinstance(text, PointWarning) or not restored.intersection(text.points):
            out.append(text)
        elif text.kind == "points not triangulated":
            left = [p for p in text.points if p not in restored]
            out += [PointWarning.points_not_triangulated(left, text.cause)] if left else []
        elif text.kind not in ("control not triangulated", "check not triangulated"):
            out.append(text)
    return out


def page_warnings(report: Mapping[str, Any], warnings: Iterable[str] = ()) -> list[str]:
    """The warnings a report page lists: report.json's ``warnings`` with the
    points of ``bundle.restored_points`` as restored (:func:`without_restored`).

    ``warnings`` are the result's own warnings, with their points
    (:class:`~strip_aerotri.results.PointWarning`): report.json keeps their
    text alone, and a count of points left out names five of them at most.
    Without them the page lists report.json's warnings as they are.  Texts
    alike (two strips' counts naming the same five points) are matched in
    order: report.json's first with the first of the result's, and so on."""
    restored = frozenset((report.get("bundle") or {}).get("restored_points") or ())
    alike: dict[str, list[PointWarning]] = {}
    for warning in warnings:
        if isinstance(warning, PointWarning):
            alike.setdefault(str(warning), []).append(warning)
    unused = {text: iter(own) for text, own in alike.items()}
    texts = [next(unused[w], w) if w in unused else w for w in report["warnings"]]
    return without_restored(texts, restored)
