"""The overall tolerance verdict in words, one for the page's banner, its plain
summary and the command line, so that the three always say the same thing.

:func:`overall_verdict` reads report.json's ``tolerances`` (and a block's
joins): what was judged, what passed, what could not be judged and why.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = [
    "CRITERION_LABELS",
    "Verdict",
    "criterion_label",
    "overall_verdict",
    "with_verdict",
]

CRITERION_LABELS = {
    "check_mean_plan": "mean plan error at the check points within 0.3 mm at the map scale",
    "y_parallax_interval_decrease": (
        "y-parallaxes of the photo pairs spread like random errors (fewer large than small)"
    ),
    "y_parallax_limit_share": "few large y-parallaxes (at most 1 % beyond 3 × their RMS)",
    "check_en_interval_decrease": (
        "check-point errors spread like random errors (fewer large than small)"
    ),
    "check_en_limit_share": "few large check-point errors (at most 1 % beyond 3 × their RMS)",
}
"""Each criterion of report.json's ``tolerances`` in words a client reads."""

_MAIN = "check_mean_plan"
_SCALE_HINT = "--map-scale or [report] map_scale"


@dataclass(frozen=True)
class Verdict:
    """The overall verdict.

    Attributes
    ----------
    status : str
        ``"pass"`` (everything judged is met and the main criterion was
        judged), ``"fail"`` (at least one criterion is not met) or ``"na"``
        (nothing failed, but the main criterion could not be judged).
    text : str
        One sentence without a final full stop: what was judged, the result,
        and what could not be judged and why.
    """

    status: str
    text: str


def criterion_label(name: str) -> str:
    """A criterion's plain words (its identifier when it has none)."""
    return CRITERION_LABELS.get(name, name.replace("_", " "))


def overall_verdict(
    tolerances: Mapping[str, Any], joins: Sequence[Mapping[str, Any]] = ()
) -> Verdict:
    """The verdict of report.json's ``tolerances`` and a block's ``joins``.

    Parameters
    ----------
    tolerances : mapping
        ``map_scale`` and ``criteria`` (each with ``name``, ``passed``,
        ``n``) as report.json writes them.
    joins : sequence of mapping
        A block's joins (``strips``, ``passed``, ``transfer_passed``).

    Returns
    -------
    Verdict
    """
    scale = tolerances.get("map_scale")
    criteria = list(tolerances.get("criteria") or [])
    failed = [criterion_label(c["name"]) for c in criteria if c.get("passed") is False]
    met = sum(1 for c in criteria if c.get("passed") is True)
    for join in joins:
        pair = " / ".join(join["strips"])
        if join.get("passed") is False:
            failed.append(f"strips {pair} agree within 0.5 mm at the map scale")
        if join.get("transfer_passed") is False:
            failed.append(f"transfer errors of strips {pair} within 40 µm")
        met += sum(1 for k in ("passed", "transfer_passed") if join.get(k) is True)
    main = next((c for c in criteria if c["name"] == _MAIN), None)
    if main is not None and main.get("passed") is None:
        if scale is None:
            missing = (
                "no map scale was given, so the check points' accuracy at a map scale "
                f"(R4's main criterion) was not judged ({_SCALE_HINT})"
            )
        else:
            missing = f"no check points, so the accuracy at 1:{scale:g} was not judged"
    else:
        missing = ""
    at = "" if scale is None else f" at 1:{scale:g}"
    if failed:
        head = f"{len(failed)} of {len(failed) + met} judged criteria not met{at}: " + "; ".join(
            failed
        )
        return Verdict("fail", head + (f"; {missing}" if missing else ""))
    if missing:
        judged = (
            f"the {met} criteria that could be judged are met"
            if met
            else "nothing else could be judged"
        )
        return Verdict("na", f"{missing}; {judged}")
    if not met:
        return Verdict("na", "nothing could be judged")
    return Verdict("pass", f"all {met} criteria met{at}")


def with_verdict(
    tolerances: dict[str, Any], joins: Sequence[Mapping[str, Any]] = ()
) -> dict[str, Any]:
    """``tolerances`` with its ``verdict`` (``status`` and ``text``) added, and
    every criterion with its plain ``label``."""
    for criterion in tolerances["criteria"]:
        criterion["label"] = criterion_label(criterion["name"])
    verdict = overall_verdict(tolerances, joins)
    tolerances["verdict"] = {"status": verdict.status, "text": verdict.text}
    return tolerances
