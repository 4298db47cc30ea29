"""GNSS centres and IMU attitudes in the bundle refinement's results and reports.

A 12-photo film strip of :func:`simulate_strip` (seed 1; crs = "local" except
for one test on EPSG:32634) with its own control; GNSS centres are the true
centres plus 5 cm noise and a planted 1 m blunder in east on one photo, IMU
attitudes the true attitudes plus 0.005 deg noise.  Residuals are recomputed
here from the refined centres and attitudes (scipy rotations, pyproj
geodesy); redundancy numbers from the dense design matrix.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.bundle.adjust import _right_jacobian_inv
from strip_aerotri.bundle.refine import GnssCentres, ImuAttitudes, refine_bundle
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.geodesy import GroundCRS, enu_rotation
from strip_aerotri.geometry.collinearity import collinearity_jacobians as _collinearity
from strip_aerotri.ground.polynomials import GroundOptions
from strip_aerotri.pipeline import triangulate
from strip_aerotri.report.html import _html_tables
from strip_aerotri.report.record import build_report
from strip_aerotri.simulate import simulate_strip

SIGMA_GNSS = 0.05  # m, both components
SIGMA_IMU_DEG = 0.005
BLUNDER_PHOTO = 5  # strip position of the photo with the 1 m GNSS blunder
# The blunder is tested and listed, not rejected (rejection: test_bundle_gnss_imu_rejection.py)
REPORT = BlunderOptions(action="report")
NO_IMU_PHOTO = 3  # strip position of the photo without an IMU attitude
# Keys of report.json's "bundle" section before the GNSS / IMU sections were added.
OLD_BUNDLE_KEYS = {
    "frame",
    "sigma0",
    "redundancy",
    "iterations",
    "converged",
    "n_observations",
    "control",
    "check",
    "point_std_median_m",
    "centre_std_median_m",
    "rejections",
    "strip_method_check",
}
# The keys since, the old ones and each addition (docs/outputs.md).
NEW_BUNDLE_KEYS = OLD_BUNDLE_KEYS | {"gnss", "imu", "check_with_weak", "restored_points"}


def strip(crs: str):
    sim = simulate_strip(12, seed=1, crs=crs)
    route = "projected" if crs == "local" else "geocentric"
    result = triangulate(
        sim.observations, sim.control, sim.crs, ground_options=GroundOptions(route=route)
    )
    return sim, result


def true_opk(sim) -> np.ndarray:
    """True omega, phi, kappa (rad), image -> site axes ("local" only)."""
    return Rotation.from_matrix(np.array(sim.truth.photo_rotations_local)).as_euler("XYZ")


def observations(sim, seed: int = 7):
    """GNSS for every photo plus one unknown photo '9999' (blunder planted), IMU for 11."""
    ids = sim.observations.photo_ids
    m = len(ids)
    rng = np.random.default_rng(seed)
    xyz = sim.truth.photo_centres_crs + rng.normal(0.0, SIGMA_GNSS, (m, 3))
    xyz[BLUNDER_PHOTO, 0] += 1.0  # 1 m in X: east for "local" and for UTM
    gnss = GnssCentres((*ids, "9999"), np.vstack([xyz, xyz[:1]]), SIGMA_GNSS, SIGMA_GNSS)
    imu = None
    if sim.crs == "local":
        keep = [j for j in range(m) if j != NO_IMU_PHOTO]
        opk = true_opk(sim) + rng.normal(0.0, np.radians(SIGMA_IMU_DEG), (m, 3))
        imu = ImuAttitudes.from_degrees(
            tuple(ids[j] for j in keep), np.degrees(opk[keep]), SIGMA_IMU_DEG
        )
    return gnss, imu


@pytest.fixture(scope="module")
def local_run():
    sim, result = strip("local")
    gnss, imu = observations(sim)
    with pytest.warns(StripAerotriWarning, match="'9999' are not in the strip"):
        refined = refine_bundle(result, gnss=gnss, imu=imu, blunders=REPORT)
    return sim, result, gnss, imu, refined


def test_counts_and_ids(local_run) -> None:
    sim, _, _, _, refined = local_run
    ids = sim.observations.photo_ids
    g, i = refined.gnss, refined.imu
    assert (g.n_given, g.n_used, g.unmatched) == (13, 12, ("9999",))
    assert g.photo_ids == ids and list(g.photo_index) == list(range(12))
    assert (i.n_given, i.n_used, i.unmatched) == (11, 11, ())
    assert ids[NO_IMU_PHOTO] not in i.photo_ids and len(set(i.photo_ids)) == 11
    np.testing.assert_array_equal(g.sigma_xy, SIGMA_GNSS)
    np.testing.assert_array_equal(g.sigma_z, SIGMA_GNSS)
    np.testing.assert_allclose(i.sigma, np.radians(SIGMA_IMU_DEG), rtol=1e-15)
    # image coordinates + control components + 3 per GNSS centre and IMU attitude
    c = sim.control
    n_ctrl = 2 * int(c.uses_xy.sum()) + int(c.uses_h.sum())
    assert refined.n_observations == 2 * sim.observations.photo.size + n_ctrl + 3 * 12 + 3 * 11


def test_residuals_are_observed_minus_adjusted(local_run) -> None:
    _, _, gnss, imu, refined = local_run
    # GNSS: "local" has the site axes as east, north, up
    expected = gnss.xyz[:12] - refined.photo_centres
    np.testing.assert_allclose(refined.gnss.residuals, expected, rtol=0, atol=1e-9)
    assert refined.gnss.rms == pytest.approx(np.sqrt(np.mean(expected**2, axis=0)), abs=1e-12)
    assert refined.gnss.max_plan == pytest.approx(np.max(np.hypot(*expected[:, :2].T)))
    # IMU: rotation vector of R_adj.T R_imu, about the adjusted photo's axes
    idx = refined.imu.photo_index
    r_adj = Rotation.from_euler("XYZ", refined.photo_opk[idx])
    r_imu = Rotation.from_euler("XYZ", imu.opk)
    v = (r_adj.inv() * r_imu).as_rotvec()
    np.testing.assert_allclose(refined.imu.residuals, v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(refined.imu.residuals_deg, np.degrees(v), rtol=0, atol=1e-10)
    d_opk = imu.opk - refined.photo_opk[idx]
    np.testing.assert_allclose(refined.imu.opk_differences, d_opk, rtol=0, atol=1e-12)
    # both well inside the noise: 0.005 deg is 8.7e-5 rad
    assert np.max(np.abs(v)) < 4 * np.radians(SIGMA_IMU_DEG)


def dense_redundancy(sim, refined, gnss, imu) -> tuple[np.ndarray, np.ndarray]:
    """Exact redundancy numbers (1 - diag of the hat matrix, whitened) of GNSS, IMU rows."""
    obs = sim.observations
    m, p = obs.n_photos, obs.n_points
    _, _, jac_photo, jac_point = _collinearity(
        refined.photo_centres_frame,
        refined.photo_rotations_frame,
        refined.points_frame,
        obs.photo,
        obs.point,
        obs.principal_distance,
    )
    k = obs.photo.size
    n = 6 * m + 3 * p
    rows = [np.zeros((2 * k, n))]
    for i in range(2):
        for j in range(6):
            rows[0][2 * np.arange(k) + i, 6 * obs.photo + j] = jac_photo[:, i, j] / obs.sigma
        for j in range(3):
            rows[0][2 * np.arange(k) + i, 6 * m + 3 * obs.point + j] = (
                jac_point[:, i, j] / obs.sigma
            )
    c = sim.control
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    for r, pid in enumerate(c.point_ids):
        comps = [0, 1] * bool(c.uses_xy[r]) + [2] * bool(c.uses_h[r])
        for comp in comps:
            row = np.zeros(n)
            sig = c.sigma_xy[r] if comp < 2 else c.sigma_h[r]
            row[6 * m + 3 * lookup[pid] + comp] = 1.0 / sig
            rows.append(row[None])
    a_gnss = np.zeros((3 * m, n))
    for comp in range(3):
        a_gnss[3 * np.arange(m) + comp, 6 * np.arange(m) + comp] = 1.0 / SIGMA_GNSS
    idx = refined.imu.photo_index
    r_imu = Rotation.from_euler("XYZ", imu.opk).as_matrix()
    e = Rotation.from_matrix(
        np.swapaxes(r_imu, 1, 2) @ refined.photo_rotations_frame[idx]
    ).as_rotvec()
    jac = _right_jacobian_inv(e) / np.radians(SIGMA_IMU_DEG)
    a_imu = np.zeros((3 * idx.size, n))
    for a in range(3):
        for b in range(3):
            a_imu[3 * np.arange(idx.size) + a, 6 * idx + 3 + b] = jac[:, a, b]
    design = np.vstack([*rows, a_gnss, a_imu])
    hat = np.einsum("ij,jk,ik->i", design, np.linalg.inv(design.T @ design), design)
    r = 1.0 - hat
    assert r.sum() == pytest.approx(refined.redundancy, abs=1e-6)
    return r[-3 * (m + idx.size) : -3 * idx.size].reshape(m, 3), r[-3 * idx.size :].reshape(-1, 3)


def test_redundancy_numbers_and_w_are_exact(local_run) -> None:
    sim, _, gnss, imu, refined = local_run
    assert not any(r.applied for r in refined.rejections)  # every observation is in
    r_gnss, r_imu = dense_redundancy(sim, refined, gnss, imu)
    np.testing.assert_allclose(refined.gnss.redundancy, r_gnss, rtol=0, atol=1e-7)
    np.testing.assert_allclose(refined.imu.redundancy, r_imu, rtol=0, atol=1e-7)
    # w = v / (sigma sqrt(r)) on axes that are the frame's (all of them for "local")
    w = refined.gnss.residuals / (SIGMA_GNSS * np.sqrt(r_gnss))
    np.testing.assert_allclose(refined.gnss.w, w, rtol=1e-6)
    w = refined.imu.residuals / (np.radians(SIGMA_IMU_DEG) * np.sqrt(r_imu))
    np.testing.assert_allclose(refined.imu.w, w, rtol=1e-6)
    # measured: GNSS r 0.27-0.46 in plan and 0.62-0.83 in height; IMU r 0.83-0.96
    assert 0.2 < r_gnss.min() and r_gnss.max() < 0.9
    assert 0.75 < r_imu.min() and r_imu.max() < 1.0


def test_planted_gnss_blunder_shows_on_its_photo(local_run) -> None:
    sim, _, _, _, refined = local_run
    g = refined.gnss
    # the largest residual and the largest |w| of all components: east of that photo
    assert np.unravel_index(np.argmax(np.abs(g.residuals)), g.residuals.shape) == (
        BLUNDER_PHOTO,
        0,
    )
    assert np.unravel_index(np.argmax(np.abs(g.w)), g.w.shape) == (BLUNDER_PHOTO, 0)
    # measured: dE 0.45 m (about r x 1 m, r = 0.45 here), w 13.3; critical 4.19
    # (Bonferroni over 36 components at alpha 0.001); next largest |w| 2.9
    assert 0.3 < g.residuals[BLUNDER_PHOTO, 0] < 0.55
    assert g.w[BLUNDER_PHOTO, 0] > 2 * g.critical
    assert g.critical == pytest.approx(4.19, abs=0.01)
    assert list(np.flatnonzero(g.failed)) == [BLUNDER_PHOTO]
    assert not refined.imu.failed.any()
    photo = sim.observations.photo_ids[BLUNDER_PHOTO]
    listed = [r for r in refined.rejections if r.stage == "gnss"]
    assert [(r.photos, r.component, r.applied) for r in listed] == [((photo,), "E", False)]
    notes = [w for w in refined.warnings if w.startswith("gnss:")]
    assert len(notes) == 1 and f"photo {photo} would be rejected" in notes[0]


def test_report_json_has_the_sections_with_the_numbers(local_run) -> None:
    sim, result, _, _, refined = local_run
    run = dataclasses.replace(result, refined=refined)
    rep = build_report(run)
    json.dumps(rep, allow_nan=False)
    bundle = rep["bundle"]
    assert set(bundle) == NEW_BUNDLE_KEYS
    assert bundle["restored_points"] == list(run.restored_points)
    g, i = bundle["gnss"], bundle["imu"]
    ids = list(sim.observations.photo_ids)
    assert (g["n_given"], g["n_used"], g["n_unmatched"], g["unmatched_photos"]) == (
        13,
        12,
        1,
        ["9999"],
    )
    assert (i["n_given"], i["n_used"], i["n_unmatched"]) == (11, 11, 0)
    assert g["residual"] == i["residual"] == "observed - adjusted"
    assert g["sigma_xy_m"] == g["sigma_z_m"] == SIGMA_GNSS
    assert i["sigma_deg"] == pytest.approx(SIGMA_IMU_DEG, rel=1e-12)
    assert [ph["photo"] for ph in g["photos"]] == ids
    assert [ph["photo"] for ph in i["photos"]] == list(refined.imu.photo_ids)
    v = refined.gnss.residuals
    got = np.array([[ph["dE_m"], ph["dN_m"], ph["dU_m"]] for ph in g["photos"]])
    np.testing.assert_array_equal(got, v)
    np.testing.assert_array_equal([ph["w"] for ph in g["photos"]], refined.gnss.w)
    np.testing.assert_array_equal(
        [ph["redundancy"] for ph in g["photos"]], refined.gnss.redundancy
    )
    assert [g["rms_e_m"], g["rms_n_m"], g["rms_u_m"]] == list(np.sqrt(np.mean(v**2, axis=0)))
    assert g["max_plan_m"] == pytest.approx(np.max(np.hypot(v[:, 0], v[:, 1])), rel=1e-15)
    assert g["max_abs_w_photo"] == ids[BLUNDER_PHOTO]
    assert g["max_abs_w"] == pytest.approx(refined.gnss.w[BLUNDER_PHOTO, 0], rel=1e-15)
    assert g["n_failed"] == 1 and g["critical_w"] == refined.gnss.critical
    assert [ph["failed"] for ph in g["photos"]].index(True) == BLUNDER_PHOTO
    assert g["redundancy_sum"] == pytest.approx(refined.gnss.redundancy.sum())
    rot = np.array([[ph["rx_deg"], ph["ry_deg"], ph["rz_deg"]] for ph in i["photos"]])
    np.testing.assert_allclose(rot, refined.imu.residuals_deg, rtol=1e-15)
    d_opk = np.array([[ph[k] for k in ("d_omega_deg", "d_phi_deg", "d_kappa_deg")]
                      for ph in i["photos"]])  # fmt: skip
    np.testing.assert_allclose(d_opk, refined.imu.opk_differences_deg, rtol=1e-15)
    np.testing.assert_allclose(i["rms_deg"], np.sqrt(np.mean(rot**2, axis=0)), rtol=1e-12)
    assert i["n_failed"] == 0
    html = "\n".join(_html_tables(rep))
    assert "Bundle refinement: GNSS centres and IMU attitudes" in html
    assert "GNSS centres (observed − adjusted, m)" in html
    assert "IMU attitudes (observed − adjusted, degrees)" in html
    assert html.count("<span class='fail'>FAIL</span>") == 1


def test_without_gnss_and_imu_nothing_is_added(local_run) -> None:
    _, result, _, _, _ = local_run
    with warnings.catch_warnings():
        warnings.simplefilter("error", StripAerotriWarning)
        refined = refine_bundle(result)
    assert refined.gnss is None and refined.imu is None
    assert not any("GNSS" in w or "IMU" in w for w in refined.warnings)
    rep = build_report(dataclasses.replace(result, refined=refined))
    assert set(rep["bundle"]) == NEW_BUNDLE_KEYS
    assert rep["bundle"]["gnss"] is None and rep["bundle"]["imu"] is None
    html = "\n".join(_html_tables(rep))
    assert "GNSS" not in html and "IMU" not in html
    # no refinement at all: no bundle section, as before
    plain = build_report(result)
    assert plain["bundle"] is None
    assert "GNSS" not in "\n".join(_html_tables(plain))


def test_without_precision_residuals_only(local_run) -> None:
    _, result, gnss, imu, refined = local_run
    with pytest.warns(StripAerotriWarning, match="not in the strip"):
        quick = refine_bundle(result, gnss=gnss, imu=imu, compute_precision=False, blunders=REPORT)
    np.testing.assert_allclose(quick.gnss.residuals, refined.gnss.residuals, atol=1e-9)
    assert np.isnan(quick.gnss.w).all() and np.isnan(quick.imu.redundancy).all()
    assert not quick.gnss.failed.any()
    assert not any(w.startswith("gnss:") for w in quick.warnings)
    g = build_report(dataclasses.replace(result, refined=quick))["bundle"]["gnss"]
    assert g["max_abs_w"] is None and g["n_failed"] is None
    assert g["photos"][0]["w"] == [None, None, None] and g["photos"][0]["failed"] is None


def test_gnss_residuals_along_east_north_up_on_a_projected_crs() -> None:
    """EPSG:32634, geocentric route: the frame's X runs along the strip, not east."""
    sim, result = strip("EPSG:32634")
    gnss, _ = observations(sim)
    with pytest.warns(StripAerotriWarning, match="'9999' are not in the strip"):
        refined = refine_bundle(result, gnss=gnss, blunders=REPORT)
    crs = GroundCRS.from_user_input(sim.crs)
    d_ecef = crs.to_ecef(gnss.xyz[:12]) - crs.to_ecef(refined.photo_centres)
    llh = crs.to_geodetic(refined.photo_centres)
    expected = np.einsum("nij,nj->ni", enu_rotation(llh[:, 0], llh[:, 1]), d_ecef)
    np.testing.assert_allclose(refined.gnss.residuals, expected, rtol=0, atol=1e-6)
    g = refined.gnss
    assert np.unravel_index(np.argmax(np.abs(g.w)), g.w.shape) == (BLUNDER_PHOTO, 0)
    assert list(np.flatnonzero(g.failed)) == [BLUNDER_PHOTO]
    # measured: dE 0.40 m, w 12.5 (critical 4.19); next largest |w| 3.0
    assert 0.3 < g.residuals[BLUNDER_PHOTO, 0] < 0.55 and g.w[BLUNDER_PHOTO, 0] > 2 * g.critical
