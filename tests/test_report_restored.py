"""The warnings a report page lists when a refinement restored points
(report/restored.py): report.json's texts, the restored points no longer
among the points left out."""

from __future__ import annotations

from strip_aerotri.report.restored import page_warnings
from strip_aerotri.results import PointWarning

CAUSE = "their observations failed the blunder tests"


def _stage_warnings() -> list[str]:
    return [
        "relative_orientation: a plain text",
        PointWarning.not_triangulated("A", "a cause"),
        PointWarning.not_triangulated("B", "a cause", check=True),
        PointWarning.points_not_triangulated(["A", "B", "C", "D", "E", "F", "G"], CAUSE),
        PointWarning.points_not_triangulated(["C"], "seen on fewer than two photos"),
    ]


def test_the_page_lists_restored_points_as_restored():
    """'A' and 'C' restored: A's own warning goes, B's stays; the count of the
    points left out for a cause is made again without them (names beyond
    the five report.json's text shows included), and goes when only
    restored points were in it; every other text stays, in its place."""
    stage = _stage_warnings()
    note = "bundle: 2 point(s) left out before the refinement were intersected: 'A', 'C'"
    report = {
        "warnings": [*(str(w) for w in stage), note],
        "bundle": {"restored_points": ["A", "C"]},
    }
    assert "'F'" not in report["warnings"][3]  # report.json names five of seven
    assert page_warnings(report, stage) == [
        "relative_orientation: a plain text",
        "check point 'B' is not triangulated (a cause): left out",
        f"5 point(s) not triangulated ({CAUSE}): 'B', 'D', 'E', 'F', 'G'",
        note,
    ]


def test_without_restored_points_or_the_results_warnings_the_page_is_report_json():
    stage = _stage_warnings()
    texts = [str(w) for w in stage]
    for bundle in (None, {"restored_points": []}):
        assert page_warnings({"warnings": texts, "bundle": bundle}, stage) == texts
    # report.json alone cannot say which points a count names: kept as it is
    restored = {"warnings": texts, "bundle": {"restored_points": ["A", "C"]}}
    assert page_warnings(restored) == texts


def test_the_pages_must_be_given_the_results_warnings():
    """Without the result's own warnings a page lists the restored points as
    left out again: html_page and block_html take them as a required keyword."""
    import inspect

    from strip_aerotri.report.block_page import block_html
    from strip_aerotri.report.html import html_page

    for page in (html_page, block_html):
        param = inspect.signature(page).parameters["warnings"]
        assert param.kind is inspect.Parameter.KEYWORD_ONLY
        assert param.default is inspect.Parameter.empty


def test_two_strips_counts_alike_are_matched_in_order():
    """Two strips each leave out six points, the first five the same: their
    counts read alike in report.json.  'F' (the first strip's sixth)
    restored: the first count is made again without it, the second stays;
    'G' (the second's) restored: the other way round."""
    first = PointWarning.points_not_triangulated(["A", "B", "C", "D", "E", "F"], CAUSE)
    second = PointWarning.points_not_triangulated(["A", "B", "C", "D", "E", "G"], CAUSE)
    assert str(first) == str(second)
    five = f"5 point(s) not triangulated ({CAUSE}): 'A', 'B', 'C', 'D', 'E'"
    stage = ["S1: a plain text", first, second]
    texts = [str(w) for w in stage]
    for restored, expected in (("F", [five, str(second)]), ("G", [str(first), five])):
        report = {"warnings": texts, "bundle": {"restored_points": [restored]}}
        assert page_warnings(report, stage) == [texts[0], *expected]
    # a text report.json repeats more often than the result: the rest as they are
    report = {"warnings": [*texts, texts[1]], "bundle": {"restored_points": ["F"]}}
    assert page_warnings(report, stage) == [texts[0], five, str(second), texts[1]]
