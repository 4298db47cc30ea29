"""Messages met at the edges of the envelope of projects (simulated strips
with blunders, self-calibration on clean data): each names the point and
the true cause."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip


def test_points_lost_to_blunder_tests_are_not_said_unseen() -> None:
    """A 20-photo film strip with 5 image blunders: control points P0126 and
    P0169 are seen on three photos, but the relative orientation rejected
    the y-parallax of each in both its pairs; the warning names that cause,
    not "seen on fewer than two photos"."""
    sim = simulate_strip(20, preset="film", seed=0, crs="EPSG:32634", image_blunders=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = triangulate(sim.observations, sim.control, sim.crs)
    rejected = {r.point for r in res.strip.rejections if r.stage == "relative_orientation"}
    assert {"P0126", "P0169"} <= rejected
    for pid in ("P0126", "P0169"):
        (line,) = [w for w in res.warnings if w.startswith(f"control point {pid!r}")]
        assert "see the relative_orientation rejections" in line, line
    unseen = [w for w in res.warnings if "(seen on fewer than two photos)" in w]
    assert not any("P0126" in w or "P0169" in w for w in unseen), unseen


def test_tie_point_failures_are_not_said_unseen() -> None:
    """A clean 6-photo film strip whose corner tie P0018 (seen on three
    photos) fails the tie-point test: the point is listed as lost to the
    blunder tests, not as seen on fewer than two photos."""
    sim = simulate_strip(6, preset="film", seed=0, crs="EPSG:32634")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = triangulate(sim.observations, sim.control, sim.crs)
    assert "P0018" in res.strip.rejected_points
    assert not any("P0018" in w and "fewer than two photos" in w for w in res.warnings)
    assert any("P0018" in w and "failed the blunder tests" in w for w in res.warnings)


def test_block_points_lost_to_blunder_tests_are_not_said_unmeasured() -> None:
    """A 3 x 8 film block with 15 image blunders (seed 5): check point P00055
    is measured on a pair, but the relative orientation rejected its
    y-parallaxes; the warning names that stage."""
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(3, 8, preset="film", seed=5, image_blunders=15)
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = adjust_block(sim.observations, sim.control, sim.crs, specs, construction="models")
    (line,) = [w for w in res.warnings if w.startswith("check point 'P00055' is not triangulated")]
    assert "see the relative_orientation rejections" in line, line
    cause = line[line.index("(") + 1 : line.rindex(")")]
    data = (line.kind, line.point, line.cause)  # type: ignore[attr-defined]
    assert data == ("check not triangulated", "P00055", cause)


def _keep_control(control, keep):  # type: ignore[no-untyped-def]
    """``control`` with only its check points and the points of ``keep``."""
    import dataclasses

    import numpy as np

    rows = np.flatnonzero(control.is_check | np.isin(control.point_ids, list(keep)))
    return dataclasses.replace(
        control,
        point_ids=tuple(control.point_ids[i] for i in rows),
        xyz=control.xyz[rows],
        kind=tuple(control.kind[i] for i in rows),
        sigma_xy=control.sigma_xy[rows],
        sigma_h=control.sigma_h[rows],
        source_line=control.source_line[rows] if control.source_line.size else control.source_line,
    )


def test_control_at_one_end_is_warned_of() -> None:
    """A 12-photo film strip with its control at the first end only (two
    full and two height points on photos 1001-1005) runs, and warns, naming
    the control file, that the plan and the height control stop short of
    the strip's far end; its check heights are indeed off by decimetres."""
    from strip_aerotri.plausibility import control_coverage_problems

    sim = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634")
    one_end = _keep_control(sim.control, {"P0002", "P0003", "P0039", "P0043"})
    found = control_coverage_problems(sim.observations, one_end, file="control.csv")
    assert [m.split(" control ")[0] for m in found] == [
        "control.csv: the plan", "control.csv: the height",
    ]  # fmt: skip
    assert "photos 1001 to 1002 of the strip's 1001 to 1012: the 10 photos beyond" in found[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = triangulate(sim.observations, one_end, sim.crs, control_name="control.csv")
    assert found[0] in res.warnings and found[1] in res.warnings
    assert res.check_statistics.rmse[2] > 0.3  # m: what the warning is about


def test_the_simulator_layouts_are_not_warned_of() -> None:
    """Every strip layout of the simulator puts control at both ends: no
    coverage warning on film or drone strips, short or long."""
    from strip_aerotri.plausibility import control_coverage_problems

    for preset, n in (("film", 6), ("film", 30), ("drone", 12), ("drone", 60)):
        for layout in ("ends", "fig4", "every_k_models", "dense", "weak"):
            sim = simulate_strip(n, preset=preset, seed=1, crs="local", control=layout)
            assert control_coverage_problems(sim.observations, sim.control) == [], (
                preset, n, layout,
            )  # fmt: skip


def test_check_points_only_say_no_control_is_given() -> None:
    """Control of check points only: the error says that no control point is
    given (and how many check points there are), not that none is observed
    on two photos."""
    from strip_aerotri.errors import GeometryError

    sim = simulate_strip(6, preset="film", seed=0, crs="EPSG:32634")
    checks = _keep_control(sim.control, set())
    n = int(checks.is_check.sum())
    given = rf"no full, plan or height control point is given \({n} check point"
    with pytest.raises(GeometryError, match=given):
        triangulate(sim.observations, checks, sim.crs)


def test_weak_check_points_are_one_line_unless_verbose() -> None:
    """A drone block flags many check points at its edges as weakly
    determined (16 on a simulated 3 x 15 block): two or more are one line at
    the place of the first, naming five and the count of the others; one
    stays as it is; ``-v`` prints every one."""
    import math

    from strip_aerotri.ground.check_precision import WeakCheck, weak_check_message
    from strip_aerotri.report.summary import Accuracy, RunSummary
    from strip_aerotri.report.verdict import Verdict
    from strip_aerotri.results import PointWarning

    weak = [
        PointWarning.weak_check(
            f"P{i}", weak_check_message(WeakCheck(f"P{i}", 4, 33.0, 0.015, 0.045, 0.01, 0.01))
        )
        for i in range(7)
    ]
    none = Accuracy(0, 0, math.nan, math.nan)
    summary = RunSummary(
        "block", "b", 45, 44, 500, False, "models", none, none, Verdict("na", "nothing"),
        files=("report.json", "report.html"),
    )  # fmt: skip
    texts = ["first", weak[0], "second", *weak[1:], "third"]
    assert summary.warning_lines(texts) == [
        "first",
        "7 check points are weakly determined by their own rays ('P0', 'P1', 'P2', 'P3', "
        "'P4' and 2 more) and left out of the check statistics; measure them on more photos, "
        "farther apart (listed in report.json / report.html; -v lists them here)",
        "second",
        "third",
    ]
    assert summary.warning_lines(["first", weak[0], "second"]) == ["first", weak[0], "second"]
    assert summary.warning_lines(texts, every=True) == texts


def _with_sigma(sim, sigma_mm: float):  # type: ignore[no-untyped-def]
    import dataclasses

    import numpy as np

    obs = sim.observations
    return dataclasses.replace(obs, sigma=np.full(obs.sigma.shape, sigma_mm))


def test_an_image_sigma_in_micrometres_is_warned_of() -> None:
    """A sigma column of 5 meant as µm is read as 5 mm: 1000 times the pairs'
    own scatter of about 5 µm. The run warns, naming the unit of the
    column; the images then weigh nothing against the control (its RMSE
    falls to the millimetre). The given 5 µm raises no warning."""
    from strip_aerotri.plausibility import image_sigma_problems

    sim = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        right = triangulate(sim.observations, sim.control, sim.crs)
        wrong = triangulate(_with_sigma(sim, 5.0), sim.control, sim.crs)
    assert not [w for w in right.warnings if w.startswith("image sigma")]
    (line,) = [w for w in wrong.warnings if w.startswith("image sigma")]
    assert "(5000 µm, median) is 1003 times the scatter" in line
    assert "millimetres whatever [images] units" in line
    assert wrong.control_statistics.rmse_plan < 0.2 * right.control_statistics.rmse_plan
    pairs = right.strip.relative.sigma0_um
    assert image_sigma_problems(pairs, sim.observations.sigma * 4.9) == []
    assert image_sigma_problems(pairs, sim.observations.sigma / 4.9) == []


def test_an_image_sigma_far_too_small_is_named_as_the_likely_cause() -> None:
    """5e-6 mm (metres written as mm): the control tests fail at most of
    the control and the run stops; the error names the image sigma as the
    likely cause."""
    from strip_aerotri.errors import GeometryError

    sim = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        with pytest.raises(GeometryError, match=r"; likely cause: image sigma: .* is 1/997 of"):
            triangulate(_with_sigma(sim, 5e-6), sim.control, sim.crs)


def test_stripaero_check_gives_the_same_doubts(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`stripaero check` warns as the run does: the control at one end only
    and a sigma column of 5 meant as µm; a project without either has no
    such warning."""
    import csv

    from strip_aerotri.project import check_project, load_project

    sim = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634")
    toml = sim.write_project(tmp_path)
    rep = check_project(load_project(toml))
    assert not rep.problems and not [w for w in rep.warnings if "control reach" in w]
    assert not [w for w in rep.warnings if w.startswith("image sigma")]

    control = tmp_path / "control.csv"
    rows = list(csv.DictReader(control.open()))
    keep = {"P0002", "P0003", "P0039", "P0043"}
    with control.open("w", newline="") as f:
        out = csv.DictWriter(f, fieldnames=list(rows[0]))
        out.writeheader()
        out.writerows(r for r in rows if r["type"] == "check" or r["point"] in keep)
    images = tmp_path / "image_points.csv"
    rows = list(csv.DictReader(images.open()))
    with images.open("w", newline="") as f:
        out = csv.DictWriter(f, fieldnames=list(rows[0]))
        out.writeheader()
        out.writerows(dict(r, sigma="5") for r in rows)
    rep = check_project(load_project(toml))
    assert not rep.problems
    assert len([w for w in rep.warnings if "control reaches photos 1001 to" in w]) == 2
    assert [w for w in rep.warnings if w.startswith("image sigma") and "1003 times" in w]


def test_a_control_blunder_rejected_by_two_stages_is_one() -> None:
    """A 1.6 m height blunder at P0218 is rejected by the ground stage and
    again by the bundle (both of stage "control"): the summary names the one
    rejection, not "2 control coordinates rejected"; two different
    coordinates are still two."""
    import dataclasses
    import math

    from strip_aerotri.report.summary import Accuracy, RunSummary
    from strip_aerotri.report.verdict import Verdict
    from strip_aerotri.results import Rejection

    def control(point: str, component: str) -> Rejection:
        return Rejection("control", point, (), component, -0.06, "m", 15.8, 4.16, True, "")

    ground = control("P0218", "height")
    bundle = dataclasses.replace(ground, w=14.5, effect="bundle adjustment")
    assert bundle.describe() != ground.describe()
    none = Accuracy(0, 0, math.nan, math.nan)
    other = control("P0300", "plan")

    def summary(*rejections: Rejection) -> RunSummary:
        return RunSummary(
            "strip", "s", 20, 19, 200, False, "models", none, none, Verdict("na", "n"),
            rejections=rejections, files=("report.json",),
        )  # fmt: skip

    texts = [ground.describe(), "between", bundle.describe()]
    assert summary(ground, bundle).warning_lines(texts) == [ground.describe(), "between"]
    texts = [ground.describe(), other.describe()]
    assert summary(ground, other).warning_lines(texts) == [
        "control: 2 control coordinates rejected as blunders (listed in report.json; "
        "-v lists them here)"
    ]


EXTERNAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "external-strips"


@pytest.mark.skipif(not EXTERNAL.is_dir(), reason="needs ../shared/data/external-strips")
@pytest.mark.parametrize("name", ["drone-80pct", "one-inch-75pct"])
def test_the_external_strips_raise_no_doubt(name: str) -> None:
    """The two strips of an independent simulator (control at both ends, the
    image sigma the file's default of 5 µm against 5 µm and 1.2 µm of
    noise): neither the coverage nor the image sigma warning."""
    from strip_aerotri.project import check_project, load_project

    rep = check_project(load_project(EXTERNAL / name / "strip.toml"))
    assert not rep.problems
    assert not [w for w in rep.warnings if "control reach" in w or w.startswith("image sigma")]


def test_control_points_lost_alike_are_one_line_unless_verbose() -> None:
    """Seven control points of a tilted ff35 strip seen on one photo of a
    model each: one line per cause naming five and the count of the others;
    a cause met once keeps its own line; ``-v`` prints each."""
    import math

    from strip_aerotri.report.summary import Accuracy, RunSummary
    from strip_aerotri.report.verdict import Verdict
    from strip_aerotri.results import PointWarning

    unseen = "seen on fewer than two photos of a model"
    failed = "its observations failed the blunder tests, see the relative_orientation rejections"
    lost = [PointWarning.not_triangulated(f"P{i}", unseen) for i in range(7)]
    odd = PointWarning.not_triangulated("Q", failed)
    assert lost[0] == f"control point 'P0' is not triangulated ({unseen}): left out"
    none = Accuracy(0, 0, math.nan, math.nan)
    summary = RunSummary(
        "strip", "s", 40, 39, 800, False, "models", none, none, Verdict("na", "n"),
        files=("report.json", "report.html"),
    )  # fmt: skip
    texts = [lost[0], odd, *lost[1:], "last"]
    assert summary.warning_lines(texts) == [
        "7 control points are not triangulated ('P0', 'P1', 'P2', 'P3', 'P4' and 2 more) and "
        f"left out (each: {unseen}) (listed in report.json / report.html; -v lists them here)",
        odd,
        "last",
    ]
    assert summary.warning_lines(texts, every=True) == texts
    # lost check points are summed up the same way (each had its own line)
    checks = [PointWarning.not_triangulated(f"C{i}", unseen, check=True) for i in range(3)]
    assert summary.warning_lines(checks) == [
        "3 check points are not triangulated ('C0', 'C1', 'C2') and "
        f"left out (each: {unseen}) (listed in report.json / report.html; -v lists them here)"
    ]


def _lost_control(ids: list[str]):  # type: ignore[no-untyped-def]
    """A 12-photo film strip's result whose control also holds full points
    ``ids`` that no photo sees, and its summary."""
    import dataclasses

    import numpy as np

    from strip_aerotri.observations import ControlType
    from strip_aerotri.report.summary import summarize

    sim = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634")
    c, n = sim.control, len(ids)
    ghosts = dataclasses.replace(
        c,
        point_ids=(*c.point_ids, *ids),
        xyz=np.vstack([c.xyz, np.repeat(c.xyz[:1], n, axis=0)]),
        kind=(*c.kind, *[ControlType.FULL] * n),
        sigma_xy=np.append(c.sigma_xy, [0.02] * n),
        sigma_h=np.append(c.sigma_h, [0.02] * n),
        source_line=np.zeros(len(c.point_ids) + n, dtype=np.intp),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = triangulate(sim.observations, ghosts, sim.crs)
    return result, summarize(result, files=("report.json",))


def test_lost_control_with_quotes_and_commas_in_its_ids_is_one_line() -> None:
    """Control points named ``G'1``, ``G,2`` and ``"G3"`` that no photo sees:
    the warnings carry the ids as data, so the three are one line naming
    each id as the single warnings do (``repr``), whatever the id holds."""
    ids = ["G'1", "G,2", '"G3"']
    result, summary = _lost_control(ids)
    unseen = "seen on fewer than two photos of a model"
    singles = [f"control point {p!r} is not triangulated ({unseen}): left out" for p in ids]
    assert [w for w in result.warnings if "is not triangulated (" in w] == singles
    lines = summary.warning_lines(summary.warnings)
    assert [ln for ln in lines if "not triangulated" in ln] == [
        f"3 control points are not triangulated (\"G'1\", 'G,2', '\"G3\"') and left out "
        f"(each: {unseen}) (listed in report.json; -v lists them here)"
    ]
    assert summary.warning_lines(summary.warnings, every=True) == list(summary.warnings)


def test_point_warnings_are_the_texts_in_report_json() -> None:
    """report.json's ``warnings`` are the run's texts as before (plain JSON
    strings), the point's id kept as data beside them."""
    import json

    from strip_aerotri.report.outputs import strip_outputs
    from strip_aerotri.results import PointWarning

    result, _ = _lost_control(["G'1"])
    (lost,) = [w for w in result.warnings if isinstance(w, PointWarning)]
    assert (lost.kind, lost.point) == ("control not triangulated", "G'1")
    files, _ = strip_outputs(result, html=False)
    record = json.loads(files["report.json"])
    assert record["warnings"] == [str(w) for w in result.warnings]


def test_a_point_warning_is_its_text_and_keeps_its_data() -> None:
    """Equal to its text (the warnings stay strings), immutable, and the same
    record after pickling (a forked figure child) or deep copying."""
    import copy
    import pickle

    from strip_aerotri.results import PointWarning

    w = PointWarning.not_triangulated("A'b, c", "why", check=True)
    assert w == 'check point "A\'b, c" is not triangulated (why): left out'
    assert isinstance(w, str)
    for again in (pickle.loads(pickle.dumps(w)), copy.deepcopy(w)):
        assert type(again) is PointWarning and again == w
        data = (again.kind, again.point, again.cause)
        assert data == ("check not triangulated", "A'b, c", "why")
    with pytest.raises(AttributeError, match="immutable"):
        w.point = "other"  # type: ignore[misc]


def _sigma_column(images: Path, sigma: str) -> None:
    """Every row of ``image_points.csv`` given the ``sigma`` column's text."""
    import csv

    rows = list(csv.DictReader(images.open()))
    with images.open("w", newline="") as f:
        out = csv.DictWriter(f, fieldnames=list(rows[0]))
        out.writeheader()
        out.writerows(dict(r, sigma=sigma) for r in rows)


@pytest.mark.parametrize("kind", ["strip", "block"])
def test_check_warns_of_the_image_sigma_as_the_run_does(tmp_path, kind: str) -> None:  # type: ignore[no-untyped-def]
    """A sigma column of 5 meant as µm, in a strip and in a 3 x 8 block:
    `stripaero check` gives the run's image-sigma warning, word for word."""
    from strip_aerotri.project import check_project, load_project
    from strip_aerotri.project.run import run_project
    from strip_aerotri.simulate import simulate_block

    if kind == "strip":
        toml = simulate_strip(12, preset="film", seed=0, crs="EPSG:32634").write_project(tmp_path)
    else:
        toml = simulate_block(3, 8, preset="film", seed=5).write_project(tmp_path)
    _sigma_column(tmp_path / "image_points.csv", "5")
    project = load_project(toml)
    assert project.is_block is (kind == "block")
    rep = check_project(project)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = run_project(project)
    said = [w for w in result.warnings if w.startswith("image sigma")]
    assert len(said) == 1 and "times the scatter" in said[0]
    assert [w for w in rep.warnings if w.startswith("image sigma")] == said
