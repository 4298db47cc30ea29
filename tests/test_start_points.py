"""Start values of the points the strip method left out (bundle/start_points.py)."""

from __future__ import annotations

import dataclasses
import html
import json
import re
import warnings

import numpy as np
import pytest

from strip_aerotri.bundle.refine import refine_bundle
from strip_aerotri.bundle.start_points import restore_points
from strip_aerotri.observations import ImageObservations
from strip_aerotri.options import BlunderOptions
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip
from strip_aerotri.strip.densify import intersect_rays


@pytest.fixture(scope="module")
def truth_strip():
    """A 12-photo drone strip in the local frame: its observations and truth."""
    return simulate_strip(12, preset="drone", seed=3, crs="local")


def _rays_of(obs, point):
    return np.flatnonzero(obs.point == point)


def _with_shift(obs, rows, shift_mm):
    xy = obs.xy.copy()
    xy[rows] += np.asarray(shift_mm)
    return dataclasses.replace(obs, xy=xy)


def _without(obs, rows):
    """The observations without ``rows`` (same ids and point indices)."""
    keep = np.ones(obs.photo.size, bool)
    keep[rows] = False
    return dataclasses.replace(
        obs, photo=obs.photo[keep], point=obs.point[keep], xy=obs.xy[keep],
        sigma=obs.sigma[keep], source_line=np.zeros(0, np.intp),
    )  # fmt: skip


def _page_warnings(page: str) -> list[str]:
    """The items of a report page's list of warnings, as text."""
    section = page.split("<h2>Warnings</h2>", 1)[1].split("<h2>", 1)[0]
    items = re.findall(r"<li>(.*?)</li>", section, flags=re.S)
    return [html.unescape(re.sub(r"<[^>]+>", "", item)) for item in items]


def _points_with(obs, n_rays, count):
    rays = np.bincount(obs.point, minlength=obs.n_points)
    return np.flatnonzero(rays == n_rays)[:count]


def test_points_restored_from_their_agreeing_rays(truth_strip):
    obs, t = truth_strip.observations, truth_strip.truth
    rays = np.bincount(obs.point, minlength=obs.n_points)
    clean = _points_with(obs, 4, 3)
    one_wrong = np.flatnonzero(rays == 5)[:2]
    two_wrong = np.flatnonzero(rays >= 6)[:1]
    assert clean.size == 3 and one_wrong.size == 2 and two_wrong.size == 1
    # a wrong middle ray (0.05-0.07 mm, 30-50 times the noise) on each; two on the last
    bad = [_rays_of(obs, p)[2] for p in one_wrong] + list(_rays_of(obs, two_wrong[0])[[1, 3]])
    shifts = [[0.06, -0.03], [-0.02, 0.05], [0.04, 0.04], [-0.05, -0.02]]
    obs = _with_shift(obs, bad, shifts)
    gone = np.concatenate([clean, one_wrong, two_wrong])
    start = t.points_local.copy()
    start[gone] = np.nan
    out = restore_points(obs, t.photo_centres_local, t.photo_rotations_local, start)
    assert np.array_equal(np.flatnonzero(out.restored), np.sort(gone))
    keep = np.ones(obs.n_points, bool)
    keep[gone] = False
    assert np.array_equal(out.points[keep], t.points_local[keep])  # the others untouched
    # started from the good rays: within a few image-noise footprints of the truth
    # (1.5 µm at 1:13 600 is 2 cm in plan; a wrong ray kept would move it by decimetres)
    err = np.linalg.norm(out.points[gone] - t.points_local[gone], axis=1)
    assert np.all(err < 0.15), err
    assert out.scale >= 1.0


def test_points_whose_rays_disagree_stay_out(truth_strip):
    obs, t = truth_strip.observations, truth_strip.truth
    three = _points_with(obs, 3, 1)[0]
    split = _points_with(obs, 4, 1)[0]
    two, three_of_four = _points_with(obs, 4, 3)[1:]
    # three rays, one wrong: the two left cannot tell which is wrong
    rows = [_rays_of(obs, three)[1]]
    # four rays, two and two: another point's image on two photos (a mismatch)
    rows += list(_rays_of(obs, split)[2:])
    # a point seen on two photos: no check of a ray of its own, however well
    # the two agree; and three of four rays, one wrong: two left agree
    rows += [_rays_of(obs, three_of_four)[1]]
    obs = _with_shift(obs, rows, [0.05, 0.08])
    obs = _without(
        obs, np.concatenate([_rays_of(obs, two)[1:3], _rays_of(obs, three_of_four)[:1]])
    )
    gone = [three, split, two, three_of_four]
    start = t.points_local.copy()
    start[gone] = np.nan
    out = restore_points(obs, t.photo_centres_local, t.photo_rotations_local, start)
    assert not out.restored.any()
    assert np.all(np.isnan(out.points[gone]))


def test_nothing_restored_unless_the_tests_reject(truth_strip):
    obs, t = truth_strip.observations, truth_strip.truth
    gone = _points_with(obs, 4, 2)
    start = t.points_local.copy()
    start[gone] = np.nan
    args = (obs, t.photo_centres_local, t.photo_rotations_local, start)
    for action in ("report", "off"):
        out = restore_points(*args, blunders=BlunderOptions(action=action))
        assert not out.restored.any()
    excluded = BlunderOptions(exclude_points=(obs.point_ids[gone[0]],))
    out = restore_points(*args, blunders=excluded)
    assert np.array_equal(np.flatnonzero(out.restored), gone[1:])
    # and a ray the user excluded does not count: three left still agree
    drop = BlunderOptions(
        exclude_observations=((obs.photo_ids[obs.photo[_rays_of(obs, gone[0])[0]]],
                               obs.point_ids[gone[0]]),)
    )  # fmt: skip
    assert restore_points(*args, blunders=drop).restored[gone].all()


def test_the_refinement_keeps_the_good_rays_of_points_the_strip_method_dropped():
    """A blunder on a point's middle photo made the strip method drop the
    point; the refinement used to leave it out with its good rays."""
    sim = simulate_strip(20, preset="drone", seed=0, image_blunders=12, control="fig4")
    obs = sim.observations
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        strip = triangulate(obs, sim.control, sim.crs)
        refined = refine_bundle(strip)
    blunder = np.zeros(obs.photo.size, bool)
    blunder[list(sim.truth.blunder_observations)] = True
    dropped = np.flatnonzero(~np.all(np.isfinite(strip.points), axis=1))
    good_rays = np.bincount(obs.point[~blunder], minlength=obs.n_points)
    wanted = dropped[good_rays[dropped] >= 3]
    assert wanted.size, "the strip method should drop a point with a wrong ray here"
    assert np.all(np.isfinite(refined.points[wanted]))
    # exactly the blunders rejected: every good ray of those points kept
    assert np.array_equal(~refined.image_used, blunder)
    assert any("intersected from the photos" in w and obs.point_ids[wanted[0]] in w
               for w in refined.warnings)  # fmt: skip
    # and as well determined as the rest (CRS metres, plan and height)
    err = np.abs(refined.points - sim.truth.points_crs)
    typical = np.sqrt(np.nanmean(err**2, axis=0))
    assert np.all(err[wanted] < 4 * typical), (err[wanted], typical)


@pytest.mark.parametrize(("seed", "kind"), [(2, "check"), (5, "full")])
def test_the_block_refinement_keeps_the_good_rays_of_points_the_block_dropped(seed, kind):
    """The same for a block: 120 blunders on a 3 x 15 drone block drop 7
    points (seed 2) in the block's own tests; the refinement used to lose all
    7 with 23 good rays.  Among those restored, check points (seed 2) and a
    full control point (seed 5) take their control rows again."""
    from strip_aerotri.pipeline import triangulate_block
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(3, 15, preset="drone", seed=seed, image_blunders=120)
    obs = sim.observations
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        block = triangulate_block(obs, sim.control, sim.crs, sim.strips, refine="bundle")
    blunder = np.zeros(obs.photo.size, bool)
    blunder[list(sim.truth.blunder_observations)] = True
    note = [w for w in block.warnings if "intersected from the photos" in w]
    assert note, "the block should drop points with a wrong ray here"
    back = [i for i, pid in enumerate(obs.point_ids) if repr(pid) in note[0]]
    assert len(back) >= 2
    assert np.all(np.isfinite(block.points[back]))
    # the result names them all, in point order (the note names five at most)
    n_back = int(note[0].removeprefix("bundle: ").split(" ")[0])
    assert len(block.restored_points) == n_back
    assert {obs.point_ids[i] for i in back} <= set(block.restored_points)
    index_of = {pid: i for i, pid in enumerate(obs.point_ids)}
    at = [index_of[p] for p in block.restored_points]
    assert at == sorted(at) and np.all(np.isfinite(block.points[at]))
    # the summary no longer counts them among the points the block left out
    from strip_aerotri.report.summary import summarize

    said_lost = [
        w for w in block.warnings if "not triangulated" in w and w.point in block.restored_points
    ]
    assert said_lost, "the block's own warning should name a restored control or check point"
    lines = summarize(block).warning_lines(block.warnings)
    assert not any(w in lines for w in said_lost)
    lost_lines = [ln for ln in lines if "not triangulated" in ln]
    assert not any(repr(p) in ln for ln in lost_lines for p in block.restored_points)
    # nor does the page, where report.json keeps both stages' texts
    from strip_aerotri.report.block import build_block_outputs

    files = build_block_outputs(block)
    page = _page_warnings(files["report.html"].decode("utf-8"))
    kept = json.loads(files["report.json"])["warnings"]
    assert all(w in kept for w in said_lost)
    assert not any(w in page for w in said_lost)
    page_lost = [w for w in page if "not triangulated" in w]
    assert not any(repr(p) in w for w in page_lost for p in block.restored_points)
    # their wrong rays are out; each keeps three good rays or more
    ph = {p: i for i, p in enumerate(obs.photo_ids)}
    rejected = {(ph[r.photos[0]], r.point) for r in block.rejections if r.stage == "bundle"}
    for i in back:
        rows = np.flatnonzero(obs.point == i)
        out = np.array([(obs.photo[k], obs.point_ids[i]) in rejected for k in rows])
        assert np.array_equal(out, blunder[rows])
        assert np.count_nonzero(~out) >= 3
    # a restored check point is compared, a restored control point used
    index = list(block.control_index)
    rows = [
        r for r, pid in enumerate(sim.control.point_ids) if pid in {obs.point_ids[i] for i in back}
    ]
    assert kind in {sim.control.kind[r].value for r in rows}
    assert all(r in index for r in rows)
    for r in rows:
        j = index.index(r)
        assert np.all(np.isfinite(block.control_residuals[j][~np.isnan(sim.control.xyz[r])]))
        assert block.is_check[j] == sim.control.is_check[r]
        if not sim.control.is_check[r]:
            assert block.used_xy[j] == sim.control.uses_xy[r]
            assert block.used_h[j] == sim.control.uses_h[r]
        assert np.all(np.isnan(block.block_control_residuals[j]))  # the block had none


def test_a_control_point_the_strip_method_dropped_is_control_again():
    """A wrong ray on the middle photo of every control point seen four
    times or more: the strip method drops two of them; the refinement
    restores them and uses their control, and it rejects exactly the wrong
    rays."""
    sim = simulate_strip(20, preset="drone", seed=2, control="fig4")
    obs, ctl = sim.observations, sim.control
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    rays = np.bincount(obs.point, minlength=obs.n_points)
    used_rows = [
        i for i, pid in enumerate(ctl.point_ids)
        if not ctl.is_check[i] and pid in lookup and rays[lookup[pid]] >= 4
    ]  # fmt: skip
    bad = [np.flatnonzero(obs.point == lookup[ctl.point_ids[i]])[2] for i in used_rows]
    obs = _with_shift(obs, bad, [0.05, 0.03])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        strip = triangulate(obs, ctl, sim.crs)
        refined = refine_bundle(strip)
    dropped = [
        i for i in used_rows if not np.all(np.isfinite(strip.points[lookup[ctl.point_ids[i]]]))
    ]
    assert len(dropped) >= 2
    blunder = np.zeros(obs.photo.size, bool)
    blunder[bad] = True
    assert np.array_equal(~refined.image_used, blunder)
    index = list(refined.control_index)
    for i in dropped:
        j = index.index(i)  # ValueError before: the row was left out
        assert refined.used_xy[j] == ctl.uses_xy[i] and refined.used_h[j] == ctl.uses_h[i]
        given = ~np.isnan(refined.control_residuals[j])
        assert np.all(np.abs(refined.control_residuals[j][given]) < 0.05)


def test_a_round_matches_a_point_by_point_computation(truth_strip):
    """The vectorised round (intersections, agreement, the ray to give up)
    against a plain loop over the points on a strip with wrong rays on a
    third of its points and some rays already given up."""
    from strip_aerotri.bundle import start_points as sp

    obs, t = truth_strip.observations, truth_strip.truth
    rng = np.random.default_rng(2345)
    rays_per_point = np.bincount(obs.point, minlength=obs.n_points)
    rows = np.flatnonzero(rays_per_point[obs.point] >= 3)
    wrong = rng.choice(rows, rows.size // 8, replace=False)
    obs = _with_shift(obs, wrong, rng.normal(0.0, 0.04, (wrong.size, 2)))
    c, rot = t.photo_centres_local, t.photo_rotations_local
    rays = sp._rays(obs, c, rot, rows)
    active = rng.random(rays.rows.size) > 0.15
    tolerance = 6.0
    xyz, agree, drop = sp._round(obs, c, rot, rays, active, tolerance)
    assert agree.any() and not agree.all() and np.any(drop >= 0)  # every branch is met
    for g in range(rays.labels.size):  # the oracle: one point at a time
        mine = np.flatnonzero((rays.group == g) & active)
        if not mine.size:
            continue
        a, b = rays.a[mine].sum(axis=0), rays.b[mine].sum(axis=0)
        if np.linalg.matrix_rank(a) < 3:
            assert not agree[g]
            continue
        x = np.linalg.solve(a, b)
        np.testing.assert_allclose(xyz[g], x, rtol=0, atol=1e-9)
        w = sp._normalised_residuals(obs, c, rot, rays.rows[mine], np.tile(x, (mine.size, 1)))
        assert agree[g] == (w.max() <= tolerance)
        if mine.size < 3:
            assert drop[g] == -1
            continue
        fits = []
        for k in mine:
            others = mine[mine != k]
            xk = np.linalg.solve(rays.a[others].sum(axis=0), rays.b[others].sum(axis=0))
            wk = sp._normalised_residuals(
                obs, c, rot, rays.rows[others], np.tile(xk, (others.size, 1))
            )
            fits.append(wk.max())
        assert drop[g] == mine[int(np.argmin(fits))]


def test_stripaero_run_delivers_a_restored_control_point(tmp_path):
    """``stripaero run`` with ``refine = "bundle"`` on a strip whose strip
    method dropped height point P0043 (a wrong ray): points.csv has it as
    height control with its residual, no model behind it (n_models 0), and
    the warning names it as restored; the command line no longer counts it
    among the points left out, report.json keeps both stages' texts and
    lists it in ``bundle.restored_points``."""
    import csv

    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    sim = simulate_strip(40, preset="drone", seed=0, image_blunders=20, control="fig4")
    toml = sim.write_project(tmp_path / "p")
    toml.write_text(
        toml.read_text().replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n')
    )
    result = CliRunner().invoke(cli, ["run", str(toml), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert "intersected from the photos and determined" in result.output
    assert "'P0043'" in result.output.split("intersected from the photos")[1]
    # restored, not lost: neither its own "left out" nor the count of lost points
    assert "P0043' is not triangulated" not in result.output
    assert "not triangulated" not in result.output, result.output
    report = json.loads((tmp_path / "out" / "report.json").read_text("utf-8"))
    assert report["bundle"]["restored_points"] == ["P0043"]
    assert report["inputs"]["control_left_out"] == ["P0043"]  # the strip method's, as before
    stage_texts = [w for w in report["warnings"] if "'P0043'" in w and "not triangulated" in w]
    assert len(stage_texts) == 2, report["warnings"]  # its own, and the count of the lost
    # the page lists it as the command line does: restored (the bundle's note), not lost
    page = _page_warnings((tmp_path / "out" / "report.html").read_text("utf-8"))
    assert not any("not triangulated" in w for w in page), page
    restored_note = [w for w in page if "intersected from the photos and determined" in w]
    assert len(restored_note) == 1 and "'P0043'" in restored_note[0]
    assert len(page) == len(report["warnings"]) - 2  # every other warning as it is
    with open(tmp_path / "out" / "points.csv", newline="") as f:
        rows = {r["point"]: r for r in csv.DictReader(f)}
    row = rows["P0043"]
    assert row["role"] == "control-height" and row["n_models"] == "0"
    assert abs(float(row["dH"])) < 0.01 and row["dE"] == ""


@pytest.mark.parametrize(
    ("base_m", "intersected"),
    [(10.0, True), (6e-4, True), (0.0, False)],
    ids=["base-10m", "rays-1.2e-5rad-apart", "parallel"],
)
def test_rays_intersected_as_densify_intersects_them(base_m: float, intersected: bool):
    """A point's rays are intersected, and judged parallel, by the same rule
    as :func:`intersect_rays` (strip/densify.py: the determinant of the normal
    matrix against its trace cubed, two rays or more).  Three vertical photos
    at 100 m, ``base_m`` apart, see point 'A' at the origin without noise;
    the other points are determined.  Rays 1.2e-5 rad apart (0.6 mm of base:
    the determinant is 3e-12 of the trace cubed, the smallest eigenvalue
    2.4e-11 of the largest) are still intersected by that rule, where the
    eigenvalue ratio of 1e-10 once used here alone refused them; rays from
    one centre never are."""
    c = 50.0  # mm
    ground = np.array([[0.0, 0.0, 0.0], [30.0, 20.0, 1.0], [-25.0, 15.0, -2.0], [5.0, -30.0, 3.0]])
    centres = np.column_stack([np.arange(3) * base_m, np.zeros(3), np.full(3, 100.0)])
    rotations = np.broadcast_to(np.eye(3), (3, 3, 3))  # image axes = frame axes, looking down
    photo, point = np.divmod(np.arange(3 * 4), 4)
    v = ground[point] - centres[photo]
    xy = -c * v[:, :2] / v[:, 2:]
    obs = ImageObservations.from_ids(
        [f"{i}" for i in photo], ["ABCD"[j] for j in point], xy, c, sigma=0.002
    )
    start = ground.copy()
    start[0] = np.nan
    out = restore_points(obs, centres, rotations, start)
    d = np.column_stack([xy, np.full(xy.shape[0], -c)])  # rotations are the identity
    rays = intersect_rays(centres[photo], d, point, 4)
    assert np.isfinite(rays.points[0]).all() == intersected
    assert out.restored.tolist() == [intersected, False, False, False]
    assert np.isfinite(out.points[0]).all() == intersected
    if base_m > 1.0:  # well conditioned: the point itself
        np.testing.assert_allclose(out.points[0], ground[0], rtol=0, atol=1e-9)
