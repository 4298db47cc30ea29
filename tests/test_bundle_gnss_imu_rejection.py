"""GNSS centres and IMU attitudes in the bundle refinement's data snooping.

The set-up of tests/test_bundle_gnss_imu_report.py: a 12-photo film strip of
:func:`simulate_strip` (seed 1, crs = "local", projected route) with its own
control; GNSS centres are the true centres plus 5 cm noise (noise seed 7),
IMU attitudes the true attitudes plus 0.005 deg noise, both for every photo.
Blunders are planted on one photo: 1 m in east of a GNSS centre, 0.5 deg in
kappa of an IMU attitude.  The reference figures are measured on this set-up
(see the comments); the truth is the simulation's.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strip_aerotri.blunders import STAGES, BlunderOptions
from strip_aerotri.bundle.refine import GnssCentres, ImuAttitudes, refine_bundle
from strip_aerotri.errors import GeometryError
from strip_aerotri.ground.polynomials import GroundOptions
from strip_aerotri.pipeline import triangulate
from strip_aerotri.report.html import _html_tables
from strip_aerotri.report.record import build_report
from strip_aerotri.simulate import simulate_strip

SIGMA_GNSS = 0.05  # m, both components
SIGMA_IMU_DEG = 0.005
GNSS_PHOTO = 5  # strip position of the photo with the 1 m GNSS blunder
IMU_PHOTO = 4  # strip position of the photo with the 0.5 deg kappa blunder


@pytest.fixture(scope="module")
def setup():
    sim = simulate_strip(12, seed=1, crs="local")
    result = triangulate(
        sim.observations, sim.control, sim.crs, ground_options=GroundOptions(route="projected")
    )
    m = sim.observations.n_photos
    rng = np.random.default_rng(7)
    xyz = sim.truth.photo_centres_crs + rng.normal(0.0, SIGMA_GNSS, (m, 3))
    # true omega, phi, kappa, image -> site axes ("local")
    opk = Rotation.from_matrix(np.array(sim.truth.photo_rotations_local)).as_euler("XYZ")
    opk = opk + rng.normal(0.0, np.radians(SIGMA_IMU_DEG), (m, 3))
    return sim, result, xyz, opk


def refine(setup, xyz=None, opk=None, **kwargs):
    sim, result, xyz0, opk0 = setup
    ids = sim.observations.photo_ids
    gnss = GnssCentres(ids, xyz0 if xyz is None else xyz, SIGMA_GNSS, SIGMA_GNSS)
    imu = ImuAttitudes.from_degrees(ids, np.degrees(opk0 if opk is None else opk), SIGMA_IMU_DEG)
    return refine_bundle(result, gnss=gnss, imu=imu, **kwargs)


def gnss_blunder(setup) -> np.ndarray:
    xyz = setup[2].copy()
    xyz[GNSS_PHOTO, 0] += 1.0  # east ("local": the site X axis)
    return xyz


def imu_blunder(setup) -> np.ndarray:
    opk = setup[3].copy()
    opk[IMU_PHOTO, 2] += np.radians(0.5)
    return opk


@pytest.fixture(scope="module")
def clean(setup):
    return refine(setup)


def test_stages_and_options() -> None:
    assert {"gnss", "imu"} <= set(STAGES)
    options = BlunderOptions(critical_values={"gnss": 5.0, "imu": 6.0})
    assert options.critical("gnss", 36) == 5.0 and options.critical("imu", 36) == 6.0
    # default: Bonferroni over the stage's tests, as the other stages
    assert BlunderOptions().critical("gnss", 36) == pytest.approx(4.19, abs=0.01)


def test_clean_data_reject_nothing(setup, clean) -> None:
    assert clean.rejections == ()
    assert not clean.gnss.rejected.any() and not clean.imu.rejected.any()
    assert (clean.gnss.n_used, clean.imu.n_used) == (12, 12)
    # measured: largest |w| 2.86 (GNSS) and 2.10 (IMU), critical 4.19
    assert np.nanmax(np.abs(clean.gnss.w)) < clean.gnss.critical
    assert clean.gnss.critical == pytest.approx(4.19, abs=0.01)
    # other noise draws of GNSS and IMU: no false alarm either
    sim = setup[0]
    m = sim.observations.n_photos
    truth_opk = Rotation.from_matrix(np.array(sim.truth.photo_rotations_local)).as_euler("XYZ")
    for seed in range(3):
        rng = np.random.default_rng(100 + seed)
        xyz = sim.truth.photo_centres_crs + rng.normal(0.0, SIGMA_GNSS, (m, 3))
        opk = truth_opk + rng.normal(0.0, np.radians(SIGMA_IMU_DEG), (m, 3))
        refined = refine(setup, xyz, opk, blunders=BlunderOptions(alpha=0.001))
        assert [r for r in refined.rejections if r.stage in ("gnss", "imu")] == [], seed


def test_gnss_blunder_is_rejected(setup, clean) -> None:
    sim = setup[0]
    photo = sim.observations.photo_ids[GNSS_PHOTO]
    refined = refine(setup, gnss_blunder(setup))
    assert len(refined.rejections) == 1
    r = refined.rejections[0]
    assert (r.stage, r.point, r.photos, r.component, r.unit, r.applied) == (
        "gnss",
        "",
        (photo,),
        "E",
        "m",
        True,
    )
    # measured: residual 0.45 m in east before the rejection, w 13.4 > 4.19
    assert 0.3 < r.residual < 0.55 and r.w > 2 * r.critical
    assert r.critical == pytest.approx(4.19, abs=0.01)
    assert "sigma0" in r.effect and "after" in r.effect
    assert any(w.startswith("gnss:") and f"photo {photo} rejected" in w for w in refined.warnings)
    g = refined.gnss
    assert list(np.flatnonzero(g.rejected)) == [GNSS_PHOTO]
    assert not refined.imu.rejected.any()
    assert (g.n_used, g.n_rejected, g.photo_ids) == (11, 1, sim.observations.photo_ids)
    np.testing.assert_array_equal(g.used, ~g.rejected)
    # the rejected centre keeps its residual (observed - adjusted: about the blunder) ...
    expected = gnss_blunder(setup) - refined.photo_centres
    np.testing.assert_allclose(g.residuals, expected, rtol=0, atol=1e-9)
    assert 0.9 < g.residuals[GNSS_PHOTO, 0] < 1.1  # measured 1.008 m
    # ... but no redundancy number or test; statistics over the used centres only
    assert np.isnan(g.redundancy[GNSS_PHOTO]).all() and np.isnan(g.w[GNSS_PHOTO]).all()
    assert not g.failed.any()
    assert np.isfinite(np.delete(g.w, GNSS_PHOTO, axis=0)).all()
    used = np.delete(expected, GNSS_PHOTO, axis=0)
    np.testing.assert_allclose(g.rms, np.sqrt(np.mean(used**2, axis=0)), rtol=1e-12)
    assert g.critical == pytest.approx(4.17, abs=0.01)  # Bonferroni over 33 components
    # one GNSS observation fewer in the final adjustment
    assert refined.n_observations == clean.n_observations - 3
    # the photo's centre comes back to the truth: measured error (0.027, 0.157, -0.043) m
    # with sigma (0.054, 0.059, 0.025) m (2.7 sigma at most); 0.59 m in east if not rejected
    error = refined.photo_centres[GNSS_PHOTO] - sim.truth.photo_centres_crs[GNSS_PHOTO]
    assert np.all(np.abs(error) < 4.0 * refined.centre_std[GNSS_PHOTO])
    kept = refine(setup, gnss_blunder(setup), blunders=BlunderOptions(action="off"))
    error_kept = kept.photo_centres[GNSS_PHOTO] - sim.truth.photo_centres_crs[GNSS_PHOTO]
    assert error_kept[0] > 0.4 and abs(error[0]) < 0.1
    # check points: measured plan / height RMSE 0.0485 / 0.0791 m after the rejection,
    # 0.0490 / 0.0781 m clean (0.0546 / 0.0746 m with the blunder kept)
    for after, before in zip(
        (refined.check_statistics.rmse_plan, refined.check_statistics.rmse[2]),
        (clean.check_statistics.rmse_plan, clean.check_statistics.rmse[2]),
        strict=True,
    ):
        assert after == pytest.approx(before, rel=0.05)


def test_imu_blunder_is_rejected(setup, clean) -> None:
    sim = setup[0]
    photo = sim.observations.photo_ids[IMU_PHOTO]
    refined = refine(setup, opk=imu_blunder(setup))
    assert len(refined.rejections) == 1
    r = refined.rejections[0]
    assert (r.stage, r.point, r.photos, r.component, r.unit, r.applied) == (
        "imu",
        "",
        (photo,),
        "about z",
        "deg",
        True,
    )
    # measured: 0.48 deg about z before the rejection, w 98.5 > 4.19
    assert 0.4 < r.residual < 0.55 and r.w > 10 * r.critical
    i = refined.imu
    assert list(np.flatnonzero(i.rejected)) == [IMU_PHOTO]
    assert not refined.gnss.rejected.any() and i.n_used == 11
    # residual of the rejected attitude: about the blunder (measured 0.503 deg about z)
    assert i.residuals_deg[IMU_PHOTO, 2] == pytest.approx(0.5, abs=0.02)
    assert i.opk_differences_deg[IMU_PHOTO, 2] == pytest.approx(0.5, abs=0.02)
    assert np.isnan(i.w[IMU_PHOTO]).all() and np.isnan(i.redundancy[IMU_PHOTO]).all()
    # the photo's kappa returns to the clean solution's (measured within 0.001 deg)
    d_kappa = np.degrees(refined.photo_opk[IMU_PHOTO, 2] - clean.photo_opk[IMU_PHOTO, 2])
    assert abs(d_kappa) < 0.005
    # check points: measured plan / height RMSE 0.0487 / 0.0779 m after the rejection,
    # 0.0490 / 0.0781 m clean, 0.191 / 0.094 m with the blunder kept
    kept = refine(setup, opk=imu_blunder(setup), blunders=BlunderOptions(action="off"))
    assert kept.check_statistics.rmse_plan > 3 * clean.check_statistics.rmse_plan
    for after, before in zip(
        (refined.check_statistics.rmse_plan, refined.check_statistics.rmse[2]),
        (clean.check_statistics.rmse_plan, clean.check_statistics.rmse[2]),
        strict=True,
    ):
        assert after == pytest.approx(before, rel=0.05)


def test_report_mode_lists_and_changes_nothing(setup) -> None:
    photo = setup[0].observations.photo_ids[GNSS_PHOTO]
    xyz = gnss_blunder(setup)
    listed = refine(setup, xyz, blunders=BlunderOptions(action="report"))
    plain = refine(setup, xyz, blunders=BlunderOptions(action="off"))
    assert [(r.stage, r.photos, r.component, r.applied) for r in listed.rejections] == [
        ("gnss", (photo,), "E", False)
    ]
    assert "would be rejected" in listed.rejections[0].describe()
    assert plain.rejections == ()
    np.testing.assert_array_equal(listed.photo_centres, plain.photo_centres)
    np.testing.assert_array_equal(listed.photo_opk, plain.photo_opk)
    np.testing.assert_array_equal(listed.points, plain.points)
    assert not listed.gnss.rejected.any() and listed.gnss.n_used == 12
    assert list(np.flatnonzero(listed.gnss.failed)) == [GNSS_PHOTO]
    assert listed.rejections[0].w == pytest.approx(abs(listed.gnss.w[GNSS_PHOTO, 0]), rel=1e-6)


def test_critical_value_of_the_stage_suppresses_it(setup) -> None:
    xyz = gnss_blunder(setup)
    high = refine(setup, xyz, blunders=BlunderOptions(critical_values={"gnss": 1000.0}))
    plain = refine(setup, xyz, blunders=BlunderOptions(action="off"))
    assert high.rejections == () and not high.gnss.rejected.any()
    assert high.gnss.critical == 1000.0
    assert high.imu.critical == pytest.approx(4.19, abs=0.01)  # other stages unchanged
    np.testing.assert_array_equal(high.photo_centres, plain.photo_centres)
    # the IMU stage's value does not touch the GNSS tests
    imu_high = refine(setup, xyz, blunders=BlunderOptions(critical_values={"imu": 1000.0}))
    assert [r.stage for r in imu_high.rejections] == ["gnss"]


def test_max_fraction_stops_when_most_gnss_centres_are_wrong(setup) -> None:
    xyz = setup[2].copy()
    rng = np.random.default_rng(3)
    bad = [1, 2, 3, 5, 6, 8, 9, 10]
    xyz[bad] += rng.choice([-1.0, 1.0], (8, 3)) * rng.uniform(0.8, 1.5, (8, 3))
    with pytest.raises(GeometryError, match=r"stage 'gnss'.*GNSS centres.*\(3 of 12 photos\)"):
        refine(setup, xyz)
    # allowed to reject them all, it finds exactly the corrupted ones, one per round
    refined = refine(setup, xyz, blunders=BlunderOptions(max_fraction=1.0))
    assert list(np.flatnonzero(refined.gnss.rejected)) == bad
    assert [r.stage for r in refined.rejections] == ["gnss"] * 8


def test_without_precision_nothing_is_tested(setup) -> None:
    refined = refine(setup, gnss_blunder(setup), compute_precision=False)
    assert refined.rejections == () and not refined.gnss.rejected.any()
    assert np.isnan(refined.gnss.w).all()


def test_report_shows_the_rejection(setup) -> None:
    sim, result = setup[0], setup[1]
    photo = sim.observations.photo_ids[GNSS_PHOTO]
    refined = refine(setup, gnss_blunder(setup))
    run = dataclasses.replace(result, refined=refined, warnings=result.warnings + refined.warnings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = build_report(run)
    json.dumps(rep, allow_nan=False)
    g = rep["bundle"]["gnss"]
    assert (g["n_used"], g["n_rejected"], g["n_failed"]) == (11, 1, 0)
    assert [ph["rejected"] for ph in g["photos"]].index(True) == GNSS_PHOTO
    row = g["photos"][GNSS_PHOTO]
    assert row["w"] == [None, None, None] and row["failed"] is None
    assert row["dE_m"] == pytest.approx(refined.gnss.residuals[GNSS_PHOTO, 0], rel=1e-15)
    assert g["redundancy_sum"] == pytest.approx(np.nansum(refined.gnss.redundancy))
    assert rep["bundle"]["imu"]["n_rejected"] == 0
    assert any(f"photo {photo} rejected" in t for t in rep["bundle"]["rejections"])
    assert any(t.startswith("gnss:") for t in rep["warnings"])
    html = "\n".join(_html_tables(rep))
    assert html.count("<span class='fail'>rejected</span>") == 1


def test_report_mode_lists_each_finding_once_over_the_control_passes() -> None:
    """Geocentric route with plan and height control: the adjustment is repeated
    (passes) until the control's frame coordinates settle; "report" lists what
    the last pass finds, once (each pass used to add its own copy)."""
    sim = simulate_strip(12, seed=1, crs="EPSG:32634")
    xyz = sim.control.xyz.copy()
    full = [j for j, kind in enumerate(sim.control.kind) if kind.name == "FULL"]
    xyz[full[1], 2] += 1.5  # a height blunder in a full control point
    control = dataclasses.replace(sim.control, xyz=xyz)
    report = BlunderOptions(action="report")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = triangulate(
            sim.observations,
            control,
            sim.crs,
            ground_options=GroundOptions(route="geocentric"),
            blunders=report,
        )
        m = sim.observations.n_photos
        gnss_xyz = sim.truth.photo_centres_crs + np.random.default_rng(7).normal(
            0.0, SIGMA_GNSS, (m, 3)
        )
        gnss_xyz[GNSS_PHOTO, 0] += 1.0
        gnss = GnssCentres(sim.observations.photo_ids, gnss_xyz, SIGMA_GNSS, SIGMA_GNSS)
        refined = refine_bundle(result, gnss=gnss, blunders=report)
    described = [r.describe() for r in refined.rejections]
    assert len(described) == len(set(described)) > 1
    assert not any(r.applied for r in refined.rejections)
    # the control blunder stays in and pulls other centres too: the planted one is the worst
    listed = [r for r in refined.rejections if r.stage == "gnss"]
    assert max(listed, key=lambda r: r.w).photos == (sim.observations.photo_ids[GNSS_PHOTO],)
