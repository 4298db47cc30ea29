"""Tests of the bundle refinement of a strip-method result (refine.py).

Reference figures are measured on strips from :func:`simulate_strip` (film
preset: c = 152.87 mm, 1:8000, 60 % overlap, image noise 5 µm, control noise
2 cm) against the simulator's truth.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.bundle.refine import GnssCentres, ImuAttitudes, refine_bundle, refine_frame
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.geodesy import GroundCRS, enu_rotation
from strip_aerotri.geometry.collinearity import collinearity_jacobians as _collinearity
from strip_aerotri.geometry.rotation import opk_from_matrix
from strip_aerotri.ground.polynomials import GroundOptions
from strip_aerotri.observations import ControlPoints, ControlType
from strip_aerotri.pipeline import triangulate
from strip_aerotri.results import RefinedResult
from strip_aerotri.simulate import simulate_strip


def strip_and_result(crs="EPSG:32634", route="geocentric", **kwargs):
    sim = simulate_strip(12, seed=1, crs=crs, **kwargs)
    result = triangulate(
        sim.observations, sim.control, sim.crs, ground_options=GroundOptions(route=route)
    )
    return sim, result


def true_opk_enu(sim) -> np.ndarray:
    """True omega, phi, kappa (rad) image -> local ENU at each projection centre."""
    truth = sim.truth
    if sim.crs == "local":
        return opk_from_matrix(truth.photo_rotations_local)
    llh = GroundCRS.from_user_input(sim.crs).to_geodetic(truth.photo_centres_crs)
    r_ecef = truth.local_to_ecef.ecef2enu.T @ truth.photo_rotations_local
    return opk_from_matrix(enu_rotation(llh[:, 0], llh[:, 1]) @ r_ecef)


def two_height_points(sim) -> ControlPoints:
    """Check points of the simulation plus two height points: the full control
    point nearest the start on the left and nearest the end on the right."""
    c = sim.control
    lookup = {pid: i for i, pid in enumerate(sim.observations.point_ids)}
    full = np.flatnonzero([k is ControlType.FULL for k in c.kind])
    loc = sim.truth.points_local[[lookup[c.point_ids[i]] for i in full]]
    az = np.radians(sim.truth.heading_deg)
    along = loc[:, 0] * np.sin(az) + loc[:, 1] * np.cos(az)
    left = -loc[:, 0] * np.cos(az) + loc[:, 1] * np.sin(az)
    ends = {int(full[np.argmin(along - 0.1 * left)]), int(full[np.argmax(along - 0.1 * left)])}
    rows = [i for i, k in enumerate(c.kind) if k is ControlType.CHECK or i in ends]
    xyz = c.xyz[rows].copy()
    kinds = tuple(ControlType.HEIGHT if i in ends else ControlType.CHECK for i in rows)
    xyz[[k is ControlType.HEIGHT for k in kinds], :2] = np.nan
    return ControlPoints(
        tuple(c.point_ids[i] for i in rows), xyz, kinds, c.sigma_xy[rows], c.sigma_h[rows]
    )


def test_refinement_is_no_worse_than_the_strip_method_at_check_points():
    sim, result = strip_and_result()
    refined = refine_bundle(result)
    assert isinstance(refined, RefinedResult)
    assert refined.converged and refined.rejections == ()
    strip, bundle = result.check_statistics, refined.check_statistics
    assert bundle.n_plan == strip.n_plan == 50
    # measured (seed 1): strip plan 0.092 m, height 0.120 m; bundle 0.066 m, 0.086 m
    assert bundle.rmse_plan <= strip.rmse_plan
    assert bundle.rmse[2] <= strip.rmse[2]
    assert bundle.rmse_plan < 0.075 and bundle.rmse[2] < 0.095
    # sigma0 ~ 1 with the simulated 5 µm noise and 2 cm control: redundancy 280
    # gives sigma0 within 1 +- 3 sqrt(1 / 560) = 1 +- 0.13
    assert abs(refined.sigma0 - 1.0) < 0.13
    # image residuals: RMS close to the 5 µm noise times sqrt(r / n) (~0.6)
    used = refined.image_residuals_um[refined.image_used]
    assert 2.0 < np.sqrt(np.mean(used**2)) < 5.0
    # the refined points against the truth, all points
    err = refined.points - sim.truth.points_crs
    assert np.sqrt(np.nanmean(err[:, 2] ** 2)) < np.sqrt(
        np.nanmean((result.points - sim.truth.points_crs)[:, 2] ** 2)
    )
    # control residuals are small (2 cm control): used components only
    assert refined.control_statistics.rmse_plan < 0.03
    assert np.all(np.isfinite(refined.point_std[np.isfinite(refined.points[:, 0])]))
    assert set(refined.timings) == {"frame", "bundle", "total"}


@pytest.mark.parametrize(
    ("crs", "route"),
    [("EPSG:32634", "geocentric"), ("EPSG:32634", "projected"), ("local", "projected")],
    ids=["utm-geocentric", "utm-projected", "local"],
)
def test_noise_free_refinement_is_exact(crs, route):
    sim, result = strip_and_result(crs, route, image_noise_mm=0.0, control_noise_m=0.0)
    refined = refine_bundle(result)
    np.testing.assert_allclose(refined.points, sim.truth.points_crs, atol=1e-6, rtol=0)
    np.testing.assert_allclose(
        refined.photo_centres, sim.truth.photo_centres_crs, atol=1e-6, rtol=0
    )
    np.testing.assert_allclose(refined.photo_opk, true_opk_enu(sim), atol=1e-9, rtol=0)
    assert refined.check_statistics.max_plan < 1e-6
    assert refined.check_statistics.max_height < 1e-6
    assert refined.rejections == ()


def gnss_of(sim, rng, sigma=0.05) -> GnssCentres:
    m = sim.observations.n_photos
    xyz = sim.truth.photo_centres_crs + rng.normal(0.0, sigma, (m, 3))
    return GnssCentres(sim.observations.photo_ids, xyz, sigma, sigma)


def test_gnss_centres_and_two_height_points():
    sim, result = strip_and_result()
    rng = np.random.default_rng(12)
    control = two_height_points(sim)
    refined = refine_bundle(result, control=control, gnss=gnss_of(sim, rng))
    stats = refined.check_statistics
    assert stats.n_plan == 50
    assert refined.control_statistics.n_height == 2 and refined.control_statistics.n_plan == 0
    # Projection centres on one line do not fix the roll of each photo about the
    # flight line; tie points fix it only through y-parallaxes at +-75 mm, and
    # it drifts from model to model (about 1e-4 rad per model).  The adjustment
    # says so itself: predicted plan std at the check points about 0.22 m.
    chk = [sim.observations.point_ids.index(control.point_ids[r]) for r in refined.control_index]
    chk = np.array(chk)[refined.is_check]
    std = refined.point_std[chk]
    predicted_plan = float(np.sqrt(np.mean(std[:, 0] ** 2 + std[:, 1] ** 2)))
    predicted_h = float(np.sqrt(np.mean(std[:, 2] ** 2)))
    assert 0.15 < predicted_plan < 0.3 and 0.08 < predicted_h < 0.16
    # measured over seeds 0..7: plan RMSE 0.08..0.38 m, height 0.09..0.16 m; here
    # the errors must agree with the predicted precision (within a factor 2)
    assert 0.5 * predicted_plan < stats.rmse_plan < 2.0 * predicted_plan
    assert stats.rmse[2] < 2.0 * predicted_h
    assert stats.rmse_plan < 0.5 and stats.rmse[2] < 0.25


def test_gnss_imu_and_two_height_points_reach_mapping_accuracy():
    sim, result = strip_and_result()
    rng = np.random.default_rng(12)
    m = sim.observations.n_photos
    sigma_imu = np.radians(0.005)  # a high-grade IMU: 0.005 deg roll / pitch
    opk = true_opk_enu(sim) + rng.normal(0.0, sigma_imu, (m, 3))
    imu = ImuAttitudes(sim.observations.photo_ids, opk, sigma_imu)
    refined = refine_bundle(
        result, control=two_height_points(sim), gnss=gnss_of(sim, rng), imu=imu
    )
    stats = refined.check_statistics
    # The IMU fixes the roll: 8.7e-5 rad at 1223 m is 0.11 m per photo, averaged
    # over the 2-3 photos of a point.  Measured over seeds 0..7: plan RMSE
    # 0.06..0.11 m, height 0.06..0.09 m, i.e. the strip method's accuracy with full
    # control (0.07..0.11 m, 0.05..0.13 m) without ground control.  1:8000 film
    # is flown for 1:1000-1:2000 maps (plan tolerance 0.2-0.4 m): plan 0.15 m
    # and height 0.15 m RMSE are accepted.
    assert stats.rmse_plan < 0.15 and stats.rmse[2] < 0.15
    assert abs(refined.sigma0 - 1.0) < 0.15


def test_control_blunder_is_rejected():
    sim = simulate_strip(12, seed=1)
    c = sim.control
    full = [i for i, k in enumerate(c.kind) if k is ControlType.FULL]
    bad = full[len(full) // 2]
    xyz = c.xyz.copy()
    xyz[bad, 2] += 0.6  # a 0.6 m height blunder on a full point (30 sigma of control)
    control = dataclasses.replace(c, xyz=xyz)
    result = triangulate(sim.observations, control, sim.crs)
    refined = refine_bundle(result, blunders=BlunderOptions())
    control_rejections = [r for r in refined.rejections if r.stage == "control"]
    assert [(r.point, r.component) for r in control_rejections] == [(c.point_ids[bad], "height")]
    r = control_rejections[0]
    # given - adjusted before the rejection: the blunder times its redundancy
    # number (about 0.08: most of it went into the point and its photos)
    assert r.applied and r.w > r.critical and 0.03 < r.residual < 0.1
    assert "after" in r.effect
    row = list(refined.control_index).index(bad)
    assert refined.used_xy[row] and not refined.used_h[row]
    # the rejected height keeps its large residual; the check points are clean
    assert abs(refined.control_residuals[row, 2] - 0.6) < 0.1
    clean = refine_bundle(triangulate(sim.observations, c, sim.crs))
    assert abs(refined.check_statistics.rmse[2] - clean.check_statistics.rmse[2]) < 0.01
    # "report" finds it and changes nothing
    reported = refine_bundle(result, blunders=BlunderOptions(action="report"))
    assert any(not x.applied and x.point == c.point_ids[bad] for x in reported.rejections)
    assert reported.check_statistics.rmse[2] > refined.check_statistics.rmse[2]


def test_image_blunder_is_rejected():
    sim = simulate_strip(12, seed=1)
    obs = sim.observations
    counts = np.bincount(obs.point)
    k = int(np.flatnonzero(counts[obs.point] == 3)[40])  # a ray of a three-ray point
    xy = obs.xy.copy()
    xy[k, 1] += 0.040  # 40 µm in y (8 sigma)
    bad_obs = dataclasses.replace(obs, xy=xy)
    result = triangulate(bad_obs, sim.control, sim.crs, blunders=BlunderOptions(action="off"))
    refined = refine_bundle(result)
    image = [r for r in refined.rejections if r.stage == "bundle"]
    assert len(image) == 1
    assert image[0].point == obs.point_ids[obs.point[k]]
    assert image[0].photos == (obs.photo_ids[obs.photo[k]],)
    assert image[0].component == "y" and image[0].unit == "µm"
    # the residual of the rejected ray showed part of the blunder (measured
    # -20 µm: a ray of a three-ray point has a redundancy share near one half)
    assert -40.0 < image[0].residual < -10.0
    # the point's two other rays could not check each other: the point goes
    # (a wrong ray pulls its point towards itself, and the largest w can be
    # a good neighbour's)
    same_point = obs.point == obs.point[k]
    assert not refined.image_used[same_point].any()
    assert refined.image_used.sum() == obs.photo.size - 3
    assert np.isnan(refined.points[obs.point[k]]).all()


def _frame_inputs(sim):
    """Control (P, 3) with its sigmas (inf where none) in the observations' order."""
    obs, c = sim.observations, sim.control
    p = obs.n_points
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    cx = np.full((p, 3), np.nan)
    cs = np.full((p, 3), np.inf)
    for i, pid in enumerate(c.point_ids):
        j = lookup[pid]
        if c.uses_xy[i]:
            cx[j, :2], cs[j, :2] = c.xyz[i, :2], c.sigma_xy[i]
        if c.uses_h[i]:
            cx[j, 2], cs[j, 2] = c.xyz[i, 2], c.sigma_h[i]
    return cx, cs


def _dense_redundancy(fr, obs, cx, cs):
    """Exact redundancy numbers (2K image rows, then the given control
    components) from the dense whitened design matrix at the solution."""
    p, m = obs.n_points, obs.n_photos
    _, _, jac_photo, jac_point = _collinearity(
        fr.centres, fr.rotations, fr.points, obs.photo, obs.point, obs.principal_distance
    )
    k = obs.photo.size
    a = np.zeros((2 * k, 6 * m + 3 * p))
    rows = np.arange(2 * k).reshape(k, 2)
    for i in range(2):
        for j in range(6):
            a[rows[:, i], 6 * obs.photo + j] = jac_photo[:, i, j] / obs.sigma
        for j in range(3):
            a[rows[:, i], 6 * m + 3 * obs.point + j] = jac_point[:, i, j] / obs.sigma
    given = np.argwhere(np.isfinite(cx))
    a_c = np.zeros((len(given), a.shape[1]))
    a_c[np.arange(len(given)), 6 * m + 3 * given[:, 0] + given[:, 1]] = (
        1.0 / cs[given[:, 0], given[:, 1]]
    )
    design = np.vstack([a, a_c])
    hat = np.einsum("ij,jk,ik->i", design, np.linalg.inv(design.T @ design), design)
    return 1.0 - hat, given


@pytest.mark.parametrize("precision", [False, True], ids=["approximate", "exact"])
def test_redundancy_numbers_against_the_dense_design(precision):
    sim, result = strip_and_result("local", "projected")
    obs = sim.observations
    cx, cs = _frame_inputs(sim)
    g = result.ground
    fr = refine_frame(
        obs, g.photo_centres_work, g.photo_rotations_enu, result.points,
        control_xyz=cx, control_sigma=cs, compute_precision=precision,
    )  # fmt: skip
    r, given = _dense_redundancy(fr, obs, cx, cs)
    assert abs(r.sum() - fr.redundancy) < 1e-6
    k = obs.photo.size
    r_img = r[: 2 * k].reshape(k, 2)
    diff = fr.image_redundancy - r_img
    if precision:
        # from the selected inverse of the banded normal matrix: exact
        np.testing.assert_allclose(fr.image_redundancy, r_img, atol=1e-8)
        np.testing.assert_allclose(fr.bundle.image_redundancy, r_img, atol=1e-8)
        # control: exact from the point cofactors
        r_ctrl = r[2 * k :]
        q = (fr.point_std / fr.sigma0) ** 2
        r_from_std = 1.0 - q[given[:, 0], given[:, 1]] / cs[given[:, 0], given[:, 1]] ** 2
        np.testing.assert_allclose(r_from_std, r_ctrl, atol=1e-8)
    else:
        # the approximation without the precision; measured: RMS 0.066,
        # largest 0.35 (y of two-ray points, where the photos take more than
        # their average share)
        assert np.isnan(fr.bundle.image_redundancy).all()
        assert np.sqrt(np.mean(diff**2)) < 0.08
        assert np.max(np.abs(diff)) < 0.4
        assert abs(np.mean(diff)) < 0.02


def test_several_image_blunders_are_rejected_in_one_round():
    """Every failing ray that is the largest of its point and of its photo
    goes in the same round: six blunders on a 60-photo drone strip, two
    adjustments (one rejecting round, one to confirm), nothing else rejected."""
    sim = simulate_strip(
        60, preset="drone", crs="local", seed=2, control="every_k_models", control_every=10,
        image_blunders=6,
    )  # fmt: skip
    obs = sim.observations
    result = triangulate(obs, sim.control, sim.crs, blunders=BlunderOptions(action="off"))
    cx, cs = _frame_inputs(sim)
    g = result.ground
    fr = refine_frame(
        obs, g.photo_centres_work, g.photo_rotations_enu, result.points,
        control_xyz=cx, control_sigma=cs,
    )  # fmt: skip
    blundered = np.zeros(obs.photo.size, bool)
    blundered[list(sim.truth.blunder_observations)] = True
    assert blundered.sum() == 6
    np.testing.assert_array_equal(fr.observation_rejected, blundered)
    assert fr.rounds == 2
    assert not fr.control_rejected.any()
    # every ray's residual, the rejected ones' (out of the last adjustment)
    # included, is the collinearity projection at the solution minus the
    # observation (computed here from the image vectors, -c v_xy / v_z)
    b = fr.bundle
    v = np.einsum(
        "kji,kj->ki", b.rotations[obs.photo], fr.points[obs.point] - b.centres[obs.photo]
    )
    expected = -obs.principal_distance * v[:, :2] / v[:, 2:] - obs.xy
    np.testing.assert_allclose(fr.image_residuals_mm, expected, rtol=0, atol=1e-12)


def test_gnss_for_unknown_photos_warns_and_bad_inputs_raise():
    sim, result = strip_and_result()
    rng = np.random.default_rng(3)
    g = gnss_of(sim, rng)
    extra = GnssCentres((*g.photo_ids, "9999"), np.vstack([g.xyz, g.xyz[-1]]), 0.05, 0.05)
    with pytest.warns(StripAerotriWarning, match="'9999' are not in the strip"):
        refined = refine_bundle(result, gnss=extra)
    assert refined.converged
    with pytest.raises(ValueError, match="Expected `xyz` to have shape"):
        GnssCentres(("1",), np.zeros((2, 3)), 0.05, 0.05)
    with pytest.raises(ValueError, match="positive GNSS"):
        GnssCentres(("1",), np.zeros((1, 3)), 0.0, 0.05)
    with pytest.raises(ValueError, match="positive IMU"):
        ImuAttitudes.from_degrees(("1",), [[0.0, 0.0, 0.0]], -1.0)
    imu = ImuAttitudes.from_degrees(("1",), [[1.0, 2.0, 90.0]], 0.01)
    np.testing.assert_allclose(imu.opk, np.radians([[1.0, 2.0, 90.0]]))


def test_tolerance_verdicts_judge_the_refined_points():
    """With the refinement, the check-point criteria read its residuals."""
    from strip_aerotri.report.tolerances import tolerance_verdicts

    sim = simulate_strip(12, seed=1)
    result = triangulate(sim.observations, sim.control, sim.crs, refine="bundle")
    refined, ground = result.refined, result.ground
    assert refined is not None
    ref_plan = np.hypot(*refined.control_residuals[refined.is_check, :2].T)
    ground_plan = np.hypot(*ground.control_residuals[ground.is_check, :2].T)
    assert not np.allclose(ref_plan, ground_plan)  # the two stages differ here
    verdicts = {c.name: c for c in tolerance_verdicts(result, 5000.0)}
    assert verdicts["check_mean_plan"].value == pytest.approx(np.mean(ref_plan))
    unrefined = dataclasses.replace(result, refined=None)
    verdicts0 = {c.name: c for c in tolerance_verdicts(unrefined, 5000.0)}
    assert verdicts0["check_mean_plan"].value == pytest.approx(np.mean(ground_plan))


@pytest.fixture(scope="module")
def refined_run(tmp_path_factory):
    """A 12-photo film strip run by ``stripaero run`` with ``refine = "bundle"``:
    the simulation and the project file."""
    import subprocess
    import sys

    sim = simulate_strip(12, seed=3)
    toml = sim.write_project(tmp_path_factory.mktemp("refined") / "p")
    toml.write_text(
        toml.read_text().replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n')
    )
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    run = subprocess.run(
        [sys.executable, "-c", code, "run", str(toml)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    return sim, toml


def test_points_csv_residuals_are_those_of_the_refined_points(refined_run):
    """With ``refine = "bundle"`` points.csv holds the refined X, Y, H and
    its dE, dN, dH are given minus *those* coordinates (they were the strip
    method's, which did not match the file's own coordinates)."""
    import csv

    sim, toml = refined_run
    given = {
        pid: xyz
        for pid, xyz, kind in zip(
            sim.control.point_ids, sim.control.xyz, sim.control.kind, strict=True
        )
        if kind is ControlType.CHECK
    }
    with open(toml.parent / "out" / "points.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["point"] in given]
    assert len(rows) > 10
    for r in rows:
        adjusted = np.array([float(r["X"]), float(r["Y"]), float(r["H"])])
        resid = np.array([float(r["dE"]), float(r["dN"]), float(r["dH"])])
        # projected CRS: dE, dN along the grid within the meridian convergence
        assert (
            np.hypot(*(given[r["point"]] - adjusted - resid)[:2])
            < 0.002 * np.hypot(*resid[:2]) + 1e-4
        )
        assert abs((given[r["point"]] - adjusted - resid)[2]) < 1e-4


def test_the_report_page_leads_with_the_refined_accuracy(refined_run):
    """With ``refine = "bundle"`` the page's plain summary gives the check
    points of the refinement (the coordinates delivered), names the strip
    method's beside them, and the accuracy table has both."""
    import json

    _, toml = refined_run
    out = toml.parent / "out"
    report = json.loads((out / "report.json").read_text())
    refined = report["bundle"]["check"]["rmse_plan_m"]
    strip = report["check"]["statistics"]["rmse_plan_m"]
    # no weakly determined check point here: the statistics with them are the same
    assert report["check"]["weakly_determined"] == []
    assert report["bundle"]["check_with_weak"] == report["bundle"]["check"]
    assert report["check"]["statistics_with_weak"] == report["check"]["statistics"]
    assert abs(refined - strip) > 5e-4  # the two differ at the page's 3 decimals
    page = (out / "report.html").read_text()
    plain = page[page.index("class='plain'") :].split("</p>")[0]
    assert f"{refined:.3f} m in plan" in plain and "after the rigorous bundle" in plain
    assert f"strip method alone: {strip:.3f} m" in plain
    assert "bundle refinement (delivered): check" in page
