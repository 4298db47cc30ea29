"""Weakly determined check points: the forward intersection's covariance
against a dense finite-difference reference and the normal case, the
intersection angles against all pairs, and the rule on the real FC300X
block (skipped without ../shared)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.geometry.collinearity import project
from strip_aerotri.geometry.intersection_precision import (
    intersection_angles,
    intersection_covariances,
)
from strip_aerotri.geometry.rotation import matrix_from_rotvec

C = 100.0
FC300X = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "uav-block-fc300x"


def _scene(seed: int = 2) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    centres = np.column_stack(
        [np.arange(5) * 300.0, rng.normal(0, 20, 5), 1000 + rng.normal(0, 10, 5)]
    )
    rotations = matrix_from_rotvec(rng.normal(0, 0.02, (5, 3)))
    points = np.column_stack(
        [rng.uniform(0, 1200, 12), rng.uniform(-300, 300, 12), rng.uniform(-50, 50, 12)]
    )
    # point k seen on photos k % 4 .. (k % 4) + 1 + k % 3: 2 to 4 rays each
    pairs = [(j, k) for k in range(12) for j in range(k % 4, min(5, k % 4 + 2 + k % 3))]
    photo = np.array([j for j, _ in pairs])
    point = np.array([k for _, k in pairs])
    return centres, rotations, points, photo, point


def test_covariance_matches_a_dense_finite_difference_inverse() -> None:
    centres, rotations, points, photo, point = _scene()
    sigma = np.linspace(0.002, 0.006, photo.size)
    cov = intersection_covariances(centres, rotations, points, photo, point, C, sigma)
    h = 1e-4
    for k in range(points.shape[0]):
        rows = np.flatnonzero(point == k)
        jac = np.zeros((2 * rows.size, 3))
        for axis in range(3):
            step = np.zeros(3)
            step[axis] = h
            hi, _ = project(centres, rotations, points + step, photo[rows], point[rows], C)
            lo, _ = project(centres, rotations, points - step, photo[rows], point[rows], C)
            jac[:, axis] = ((hi - lo) / (2 * h) / sigma[rows, None]).ravel()
        reference = np.linalg.inv(jac.T @ jac)
        np.testing.assert_allclose(cov[k], reference, rtol=1e-6, atol=1e-12)


def test_two_rays_of_the_normal_case_give_the_parallax_formula() -> None:
    """Two vertical photos, base B at height Z over a point between them:
    sigma_Z = Z² / (B c) · √2 sigma, and across the base the image sigma at
    the photo scale over √2."""
    base, height, sigma = 50.0, 1000.0, 0.005
    centres = np.array([[0.0, 0.0, height], [base, 0.0, height]])
    rotations = np.broadcast_to(np.eye(3), (2, 3, 3)).copy()
    points = np.array([[base / 2, 0.0, 0.0]])
    cov = intersection_covariances(
        centres, rotations, points, np.array([0, 1]), np.array([0, 0]), C, np.full(2, sigma)
    )
    expected_z = height**2 / (base * C) * np.sqrt(2.0) * sigma
    assert np.sqrt(cov[0, 2, 2]) == pytest.approx(expected_z, rel=1e-9)
    assert np.sqrt(cov[0, 1, 1]) == pytest.approx(height / C * sigma / np.sqrt(2.0), rel=1e-9)


def test_one_ray_and_parallel_rays_are_not_determined() -> None:
    centres = np.array([[0.0, 0.0, 1000.0], [0.0, 0.0, 1000.0], [10.0, 0.0, 1000.0]])
    rotations = np.broadcast_to(np.eye(3), (3, 3, 3)).copy()
    points = np.array([[5.0, 3.0, 0.0], [20.0, 0.0, 0.0]])
    photo, point = np.array([0, 1, 2]), np.array([0, 0, 1])  # same centre twice; one ray
    cov = intersection_covariances(centres, rotations, points, photo, point, C, np.full(3, 0.005))
    assert np.all(np.isnan(cov))


def test_angles_are_the_largest_over_all_pairs() -> None:
    centres, _, points, photo, point = _scene(5)
    angles = intersection_angles(centres, points, photo, point)
    for k in range(points.shape[0]):
        rays = [points[k] - centres[j] for j in photo[point == k]]
        units = [r / np.linalg.norm(r) for r in rays]
        best = max(
            np.degrees(np.arccos(np.clip(a @ b, -1, 1)))
            for a, b in itertools.combinations(units, 2)
        )
        assert angles[k] == pytest.approx(best, abs=1e-9)
    one = intersection_angles(centres, points, photo[:1], point[:1])
    assert np.all(np.isnan(one))


@pytest.mark.skipif(not FC300X.is_dir(), reason="needs ../shared/data/uav-block-fc300x")
@pytest.mark.parametrize("adjustment", ['block = "strips"', 'refine = "bundle"'])
def test_fc300x_weak_check_points_are_named_and_left_out(tmp_path, adjustment: str) -> None:  # type: ignore[no-untyped-def]
    """Check point 14 (two photos 5.3 m apart at 50-55 m, rays at 2.5°) and
    78 (two photos, 7°) are weak; the statistics are those of the other 13."""
    import warnings

    import json

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.importers.writer import write_project
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    write_project(import_uav_fc300x(FC300X), tmp_path, force=True)
    toml = tmp_path / "strip.toml"
    toml.write_text(toml.read_text() + f"\n[adjustment]\n{adjustment}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = run_project(load_project(toml))
    weak = [w for w in result.warnings if "is weakly determined" in w]
    assert [w.split("'")[1] for w in weak] == ["14", "78"]
    assert [(w.kind, w.point) for w in weak] == [("weak check", "14"), ("weak check", "78")]
    assert result.weak_checks == ("14", "78")
    assert "meet at 2.5 deg" in weak[0]
    stats = result.check_statistics
    names = np.array(result.control.point_ids)[result.control_index]
    keep = result.is_check & ~np.isin(names, ["14", "78"])
    r = result.control_residuals[keep]
    assert stats.n_plan == 13 == keep.sum()
    assert stats.rmse_plan == pytest.approx(np.sqrt(np.mean(np.sum(r[:, :2] ** 2, axis=1))))
    assert stats.rmse[2] == pytest.approx(np.sqrt(np.mean(r[:, 2] ** 2)))
    if result.refined:
        _block_s_own_check_leaves_them_out_too(result, keep)
    # R4's check-point criteria judge the same 13 points (26 dE, dN)
    from strip_aerotri.report.block import block_tolerances_record

    criteria = {c["name"]: c for c in block_tolerances_record(result, 1000.0, [])["criteria"]}
    mean_plan = criteria["check_mean_plan"]
    assert mean_plan["n"] == 13
    assert mean_plan["value"] == pytest.approx(np.mean(np.hypot(r[:, 0], r[:, 1])), rel=1e-3)
    assert criteria["check_en_limit_share"]["n"] == 26
    # the page's plain summary names them: figures at 13, the 2 listed
    from strip_aerotri.report.block import build_block_report
    from strip_aerotri.report.block_page import _plain

    plain = _plain(json.loads(json.dumps(build_block_report(result))))
    assert "At 13 independent check points" in plain
    assert "2 more check point(s) (14, 78) are listed below but left out of these figures" in plain


def _block_s_own_check_leaves_them_out_too(result, keep) -> None:  # type: ignore[no-untyped-def]
    """After the refinement the block's own transformation at the check
    points (``bundle.block_check``) leaves the weak points out as the
    refinement's statistics do; ``block_check_with_weak`` keeps all 15."""
    import json

    from strip_aerotri.report.block import build_block_report

    own = np.asarray(result.block_control_residuals)
    assert own.shape == result.control_residuals.shape
    assert not np.allclose(own[keep], result.control_residuals[keep])  # not the refinement's
    stats = result.block_check_statistics
    assert stats.n_plan == 13
    assert stats.rmse_plan == pytest.approx(np.sqrt(np.mean(np.sum(own[keep, :2] ** 2, axis=1))))
    assert stats.rmse[2] == pytest.approx(np.sqrt(np.mean(own[keep, 2] ** 2)))
    bundle = json.loads(json.dumps(build_block_report(result)))["bundle"]
    assert bundle["block_check"]["n_plan"] == 13
    every = own[result.is_check]
    assert bundle["block_check_with_weak"]["n_plan"] == 15 == every.shape[0]
    assert bundle["block_check_with_weak"]["rmse_plan_m"] == pytest.approx(
        np.sqrt(np.mean(np.sum(every[:, :2] ** 2, axis=1)))
    )


def test_check_points_of_one_geometry_are_never_left_out(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The drone-corridor example: its 30 check points are seen alike (their
    own intersections within 1.9 times the median) while its control sigma
    is 1 cm, below their own intersections' 3-5 cm: none is weak, and its
    check statistics are those of all 30."""
    import shutil
    import warnings

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    example = Path(__file__).resolve().parents[1] / "examples" / "drone-corridor"
    shutil.copytree(example, tmp_path / "p")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = run_project(load_project(tmp_path / "p" / "strip.toml"))
    assert not [w for w in result.warnings if "weakly determined" in w]
    assert result.weak_checks == ()
    assert result.check_statistics.n_plan == 30


@pytest.mark.skipif(not FC300X.is_dir(), reason="needs ../shared/data/uav-block-fc300x")
def test_fc300x_report_lists_the_weak_check_points(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`stripaero run` on the imported block: report.json's check statistics
    are over 13 points, `weakly_determined` names 14 and 78, which stay in
    the per-point listing, and the command prints the warning (one line
    for both; -v prints each)."""
    import json
    import subprocess
    import sys

    project = tmp_path / "fc300x"
    run = [sys.executable, "-m", "strip_aerotri"]
    subprocess.run([*run, "import", "uav-fc300x", str(FC300X), "--out", str(project)], check=True)
    done = subprocess.run(
        [*run, "run", str(project / "strip.toml")], capture_output=True, text=True, check=True
    )
    assert "2 check points are weakly determined by their own rays ('14', '78')" in done.stderr
    report = json.loads((project / "out" / "report.json").read_text())
    check = report["check"]
    assert check["weakly_determined"] == ["14", "78"]
    assert check["statistics"]["n_plan"] == 13
    assert {"14", "78"} <= {p["point"] for p in check["points"]}
    # nothing hidden: the statistics over all 15, from the per-point listing
    every = check["statistics_with_weak"]
    assert every["n_plan"] == 15
    plan = [p["plan_m"] for p in check["points"]]
    assert every["rmse_plan_m"] == pytest.approx(float(np.sqrt(np.mean(np.square(plan)))))
    assert every["rmse_plan_m"] > check["statistics"]["rmse_plan_m"]


def test_the_rule_needs_both_bounds() -> None:
    """Weak: beyond 3 times the control sigma and 3 times the check points'
    median (or not fixed at all); not weak when only one bound is passed."""
    from strip_aerotri.ground.check_precision import WEAK_CHECK_FACTOR, _beyond

    assert WEAK_CHECK_FACTOR == 3.0
    control = np.full(6, 0.02)
    # FC300X-like: one point 40 times the others, far beyond its control sigma
    sigma = np.array([0.014, 0.012, 0.02, 0.016, 0.59, 0.013])
    assert _beyond(sigma, control).tolist() == [False] * 4 + [True, False]
    # all alike and all beyond the control sigma (a tightly controlled design)
    assert not _beyond(np.full(6, 0.09), control).any()
    # an outlier of the geometry still within 3 times its control sigma
    assert not _beyond(np.array([0.005, 0.005, 0.005, 0.05, 0.005, 0.005]), control).any()
    # one ray, or parallel rays: not fixed, weak
    assert _beyond(np.array([0.01, np.nan, 0.01, 0.01, 0.01, 0.01]), control).tolist() == [
        False, True, False, False, False, False,
    ]  # fmt: skip


def test_precision_in_a_map_projection_is_that_of_the_bundle_frame(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The film-strip example (EPSG:2180) refined by the bundle: the check
    points' sigmas from the CRS results (centres and points through ECEF to
    a tangent frame, omega-phi-kappa from east-north-up at each centre) equal
    those from the bundle's own Cartesian frame arrays within 0.1 %."""
    import shutil
    import warnings

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.ground.check_precision import check_point_precision
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    example = Path(__file__).resolve().parents[1] / "examples" / "film-strip"
    shutil.copytree(example, tmp_path / "p")
    toml = tmp_path / "p" / "strip.toml"
    text = toml.read_text()
    toml.write_text(
        text.replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n', 1)
        if "[adjustment]" in text
        else text + '\n[adjustment]\nrefine = "bundle"\n'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = run_project(load_project(toml))
    refined, ground = result.refined, result.ground
    assert refined is not None and not ground.crs.is_local
    obs = result.strip.observations
    rows = ground.control_index[ground.is_check]
    prec = check_point_precision(
        obs, result.control, ground.crs, rows, refined.points, refined.photo_centres,
        refined.photo_opk,
    )  # fmt: skip
    assert prec.rows.size >= 20
    assert np.all(np.isfinite(prec.sigma_plan_m)) and np.all(prec.sigma_height_m > 0)
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    index = np.array([lookup[result.control.point_ids[r]] for r in prec.rows])
    cov = intersection_covariances(
        refined.photo_centres_frame, refined.photo_rotations_frame, refined.points_frame,
        obs.photo, obs.point, obs.principal_distance, obs.sigma,
    )[index]  # fmt: skip
    np.testing.assert_allclose(prec.sigma_plan_m, np.sqrt(cov[:, 0, 0] + cov[:, 1, 1]), rtol=1e-3)
    np.testing.assert_allclose(prec.sigma_height_m, np.sqrt(cov[:, 2, 2]), rtol=1e-3)


def test_a_strip_s_criteria_leave_the_weak_check_points_out() -> None:
    """R4's check-point criteria of a strip judge the check points of its
    statistics: naming one weakly determined leaves it out of their count
    and of the mean plan discrepancy."""
    import dataclasses
    import warnings

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.report.tolerances import tolerance_verdicts
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(8, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = triangulate(sim.observations, sim.control, sim.crs)
    ground = result.ground
    rows = np.flatnonzero(ground.is_check)
    assert rows.size >= 3
    weak = result.control.point_ids[int(ground.control_index[rows[0]])]
    before = {c.name: c for c in tolerance_verdicts(result, 1000.0)}
    after = {
        c.name: c
        for c in tolerance_verdicts(dataclasses.replace(result, weak_checks=(weak,)), 1000.0)
    }
    assert before["check_mean_plan"].n == rows.size
    assert after["check_mean_plan"].n == rows.size - 1
    r = np.asarray(ground.control_residuals)[rows[1:]]
    assert after["check_mean_plan"].value == pytest.approx(np.mean(np.hypot(r[:, 0], r[:, 1])))
    assert after["check_en_limit_share"].n == 2 * (rows.size - 1)


def test_a_strip_s_plain_summary_counts_the_weak_check_points_apart() -> None:
    """A strip with 17 check points given, 15 compared and 2 of them weak:
    the plain summary gives the figures at 13 of 15 (2 not compared) and
    names the 2 weak ones, not "13 of the 17 (the other 4 could not be
    triangulated or compared)"."""
    from strip_aerotri.report.html import _plain_summary

    stats = {"n_plan": 13, "n_height": 13, "rmse_plan_m": 0.03, "rmse_h_m": 0.04}
    report = {
        "inputs": {"n_photos": 10, "n_points_triangulated": 100, "control": {"check": 17}},
        "control": {"statistics": stats},
        "check": {"statistics": stats, "weakly_determined": ["14", "78"]},
        "project": {"crs_name": "local"},
    }
    text = _plain_summary(report, "met")
    assert "At 13 of the 15 independent check points (the other 2 could not be" in text
    assert "2 more check point(s) (14, 78) are listed below but left out" in text
    report["check"]["weakly_determined"] = []
    text = _plain_summary(report, "met")
    assert "At 13 of the 17 independent check points (the other 4 could not be" in text
    assert "left out of these figures" not in text
