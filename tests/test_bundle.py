"""Bundle adjustment: recovery of a synthetic truth, sigma0 and precision against
Monte Carlo, GNSS-supported datum, datum defects, Jacobians by finite differences."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from strip_aerotri.bundle.adjust import _imu_residual, _right_jacobian_inv, bundle_adjust
from strip_aerotri.errors import GeometryError
from strip_aerotri.geometry.collinearity import collinearity_jacobians as _collinearity
from strip_aerotri.geometry.rotation import matrix_from_rotvec as _exp_so3
from strip_aerotri.geometry.rotation import rotvec_from_matrix as _log_so3
from strip_aerotri.observations import ImageObservations

C_MM = 152.0  # wide-angle film camera (task statement)
HEIGHT_M = 1200.0
FORMAT_MM = 230.0
SIGMA_MM = 0.005  # 5 micrometres


@dataclass(frozen=True)
class Strip:
    centres: np.ndarray  # (M, 3)
    rotations: np.ndarray  # (M, 3, 3)
    points: np.ndarray  # (P, 3)
    photo: np.ndarray  # (K,)
    point: np.ndarray  # (K,)
    xy: np.ndarray  # (K, 2) noise-free

    def observations(self, rng=None, sigma=SIGMA_MM) -> ImageObservations:
        xy = self.xy if rng is None else self.xy + rng.normal(0.0, sigma, self.xy.shape)
        return ImageObservations(
            photo_ids=tuple(f"{i + 1:03d}" for i in range(self.centres.shape[0])),
            point_ids=tuple(f"p{j:03d}" for j in range(self.points.shape[0])),
            photo=self.photo,
            point=self.point,
            xy=xy,
            sigma=np.full(self.photo.size, sigma),
            principal_distance=C_MM,
        )


def make_strip(
    seed: int = 2345, n_photos: int = 8, points_per_photo: int = 15, overlap: float = 0.6
) -> Strip:
    """Near-vertical strip along X: c = 152 mm, H = 1200 m, 23 cm format.

    Points are scattered over the strip with +-30 m of relief and kept when
    they image inside the format of at least two photos (2-3 with 60 %
    overlap).
    """
    rng = np.random.default_rng(seed)
    footprint = FORMAT_MM * HEIGHT_M / C_MM  # 1816 m
    base = (1.0 - overlap) * footprint
    m = n_photos
    centres = np.column_stack(
        [
            base * np.arange(m) + rng.uniform(-10, 10, m),
            rng.uniform(-10, 10, m),
            HEIGHT_M + rng.uniform(-5, 5, m),
        ]
    )
    angles = rng.uniform(-np.radians(2), np.radians(2), (m, 3))
    rotations = Rotation.from_euler("XYZ", angles).as_matrix()
    n_draw = int(points_per_photo * m / 2.3 * 1.6)
    length = base * (m - 1)
    pts = np.column_stack(
        [
            rng.uniform(-0.3 * footprint, length + 0.3 * footprint, n_draw),
            rng.uniform(-0.42 * footprint, 0.42 * footprint, n_draw),
            rng.uniform(-30.0, 30.0, n_draw),
        ]
    )
    # Project every point into every photo; keep the rays inside the format.
    v = np.einsum("mji,mpj->mpi", rotations, pts[None, :, :] - centres[:, None, :])
    xy = -C_MM * v[..., :2] / v[..., 2:3]
    inside = np.all(np.abs(xy) < 0.5 * FORMAT_MM - 5.0, axis=2)  # (M, Pdraw)
    keep = inside.sum(axis=0) >= 2
    pts, inside, xy = pts[keep], inside[:, keep], xy[:, keep]
    photo, point = np.nonzero(inside)
    return Strip(centres, rotations, pts, photo, point, xy[photo, point])


def full_control(strip: Strip, index) -> tuple[np.ndarray, np.ndarray]:
    ctrl = np.full(strip.points.shape, np.nan)
    ctrl[index] = strip.points[index]
    return ctrl, np.full(strip.points.shape, 0.01)


def corner_points(strip: Strip) -> np.ndarray:
    """Indices of the points nearest the four corners and the middle of the strip."""
    x, y = strip.points[:, 0], strip.points[:, 1]
    targets = [
        (x.min(), y.max()),
        (x.min(), y.min()),
        (x.max(), y.max()),
        (x.max(), y.min()),
        (0.5 * (x.min() + x.max()), y.max()),
    ]
    return np.array([np.argmin(np.hypot(x - tx, y - ty)) for tx, ty in targets])


def perturbed(strip: Strip, rng):
    m, p = strip.centres.shape[0], strip.points.shape[0]
    centres = strip.centres + rng.uniform(-5, 5, (m, 3))
    rot = strip.rotations @ _exp_so3(rng.uniform(-np.radians(1), np.radians(1), (m, 3)))
    points = strip.points + rng.uniform(-5, 5, (p, 3))
    return centres, rot, points


def test_synthetic_strip_has_the_intended_geometry():
    strip = make_strip()
    counts = np.bincount(strip.point)
    per_photo = np.bincount(strip.photo)
    assert strip.centres.shape == (8, 3)
    assert counts.min() >= 2 and counts.max() == 3
    assert per_photo.min() >= 10 and 12 <= per_photo.mean() <= 20


def test_noise_free_recovers_truth_from_perturbed_start():
    strip = make_strip()
    rng = np.random.default_rng(11)
    ctrl, ctrl_sigma = full_control(strip, corner_points(strip)[:4])
    centres0, rot0, points0 = perturbed(strip, rng)
    before = (centres0.copy(), rot0.copy(), points0.copy())
    res = bundle_adjust(
        strip.observations(),
        centres0,
        rot0,
        points0,
        control_xyz=ctrl,
        control_sigma=ctrl_sigma,
    )
    assert res.converged
    np.testing.assert_allclose(res.centres, strip.centres, atol=1e-6, rtol=0)
    np.testing.assert_allclose(res.points, strip.points, atol=1e-6, rtol=0)
    np.testing.assert_allclose(res.rotations, strip.rotations, atol=1e-9, rtol=0)
    assert res.sigma0 < 1e-6
    assert res.history[0] > 100.0 and res.history[-1] < 1e-6
    assert np.max(np.abs(res.residuals_mm)) < 1e-9
    # inputs untouched
    np.testing.assert_array_equal(before[0], centres0)
    np.testing.assert_array_equal(before[1], rot0)
    np.testing.assert_array_equal(before[2], points0)


def test_noisy_sigma0_and_point_std_agree_with_monte_carlo():
    strip = make_strip()
    rng = np.random.default_rng(4321)
    idx = corner_points(strip)
    ctrl_sigma = np.full(strip.points.shape, 0.02)
    n_rep = 30
    estimates, predicted, chi2 = [], [], []
    redundancy = None
    for _ in range(n_rep):
        ctrl = np.full(strip.points.shape, np.nan)
        ctrl[idx] = strip.points[idx] + rng.normal(0.0, 0.02, (idx.size, 3))
        res = bundle_adjust(
            strip.observations(rng),
            strip.centres,
            strip.rotations,
            strip.points,
            control_xyz=ctrl,
            control_sigma=ctrl_sigma,
        )
        assert res.converged
        estimates.append(res.points)
        # std at a priori sigma0 = 1, the quantity the scatter estimates
        predicted.append(res.point_std / res.sigma0)
        chi2.append(res.sigma0**2 * res.redundancy)
        redundancy = res.redundancy
    # each sigma0^2 * r is chi-square(r): two-sided 0.1 % limits per replica
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], redundancy)
    assert np.all((np.array(chi2) > lo) & (np.array(chi2) < hi))
    # mean of 30 sigma0^2 is 1 +- sqrt(2 / (30 r)) (about 0.03 here): allow 4 times
    mean_var = np.mean(chi2) / redundancy
    assert abs(mean_var - 1.0) < 4.0 * np.sqrt(2.0 / (n_rep * redundancy))
    scatter = np.std(np.array(estimates) - strip.points, axis=0)  # (P, 3), truth known
    pred = np.mean(predicted, axis=0)
    free = np.ones(strip.points.shape[0], bool)
    free[idx] = False
    # RMS over the points (not used as control) per axis: within 25 %
    ratio = np.sqrt(np.mean(scatter[free] ** 2, axis=0) / np.mean(pred[free] ** 2, axis=0))
    assert np.all(np.abs(ratio - 1.0) < 0.25), ratio
    # and the median of the per-coordinate ratios (30 replicas: about 13 % each)
    assert abs(np.median(scatter[free] / pred[free]) - 1.0) < 0.25


def test_gnss_centres_and_two_height_points():
    strip = make_strip()
    rng = np.random.default_rng(77)
    m = strip.centres.shape[0]
    gnss = strip.centres + rng.normal(0.0, 0.05, (m, 3))
    x, y = strip.points[:, 0], strip.points[:, 1]
    # one height point near each end, on opposite sides of the strip axis
    h_idx = np.array(
        [
            np.argmin(np.hypot(x - x.min(), y - y.max())),
            np.argmin(np.hypot(x - x.max(), y - y.min())),
        ]
    )
    ctrl = np.full(strip.points.shape, np.nan)
    ctrl[h_idx, 2] = strip.points[h_idx, 2] + rng.normal(0.0, 0.02, 2)
    centres0, rot0, points0 = perturbed(strip, rng)
    res = bundle_adjust(
        strip.observations(rng),
        centres0,
        rot0,
        points0,
        control_xyz=ctrl,
        control_sigma=0.02,
        gnss_centres=gnss,
        gnss_sigma=0.05,
    )
    assert res.converged
    z = (res.points - strip.points) / res.point_std
    assert np.max(np.abs(z)) < 5.0
    assert 0.5 < np.sqrt(np.mean(z**2)) < 2.0
    zc = (res.centres - strip.centres) / res.centre_std
    assert np.max(np.abs(zc)) < 5.0
    # control residuals only where control was given
    assert np.array_equal(np.isfinite(res.control_residuals), np.isfinite(ctrl))
    assert res.n_observations == 2 * strip.photo.size + 2 + 3 * m


def test_imu_and_gnss_define_the_datum_without_ground_control():
    strip = make_strip()
    rng = np.random.default_rng(5)
    centres0, rot0, points0 = perturbed(strip, rng)
    res = bundle_adjust(
        strip.observations(),
        centres0,
        rot0,
        points0,
        gnss_centres=strip.centres,
        gnss_sigma=0.05,
        imu_rotations=strip.rotations,
        imu_sigma=np.radians(0.005),
    )
    np.testing.assert_allclose(res.points, strip.points, atol=1e-6, rtol=0)
    np.testing.assert_allclose(res.rotations, strip.rotations, atol=1e-9, rtol=0)
    assert np.all(res.rotation_std > 0) and np.all(res.rotation_std < np.radians(0.005))
    assert np.all(np.isnan(res.control_residuals))


@pytest.mark.parametrize(
    ("n_full", "message"),
    [(0, "leave free: shift along X; shift along Y; shift along Z; rotation"), (2, "rotation")],
    ids=["no-control", "two-full-points"],
)
def test_too_little_control_raises(n_full, message):
    strip = make_strip()
    ctrl, sigma = full_control(strip, corner_points(strip)[:n_full])
    with pytest.raises(GeometryError, match="datum is not defined") as info:
        bundle_adjust(
            strip.observations(),
            strip.centres,
            strip.rotations,
            strip.points,
            control_xyz=ctrl,
            control_sigma=sigma,
        )
    assert message in str(info.value)
    if n_full == 2:
        # rotation about the line through the two points, nothing else
        assert "1 combination(s)" in str(info.value)


def test_gnss_on_a_straight_line_leaves_the_roll_free():
    strip = make_strip()
    gnss = strip.centres.copy()
    gnss[:, 1:] = [0.0, HEIGHT_M]  # all centres on one line along X
    with pytest.raises(GeometryError, match=r"datum is not defined.*rotation about X"):
        bundle_adjust(
            strip.observations(),
            gnss,
            strip.rotations,
            strip.points,
            gnss_centres=gnss,
            gnss_sigma=0.05,
        )


def test_point_on_one_photo_only_raises_naming_it():
    strip = make_strip()
    obs = strip.observations()
    # drop all but the first ray of point p000
    first = np.flatnonzero(obs.point == 0)[1:]
    keep = np.setdiff1d(np.arange(obs.photo.size), first)
    obs1 = ImageObservations(
        obs.photo_ids,
        obs.point_ids,
        obs.photo[keep],
        obs.point[keep],
        obs.xy[keep],
        obs.sigma[keep],
        C_MM,
    )
    ctrl, sigma = full_control(strip, corner_points(strip))
    with pytest.raises(GeometryError, match="'p000' \\(1 photo"):
        bundle_adjust(
            obs1,
            strip.centres,
            strip.rotations,
            strip.points,
            control_xyz=ctrl,
            control_sigma=sigma,
        )


def test_collinearity_jacobians_match_finite_differences():
    rng = np.random.default_rng(99)
    m, p = 3, 4
    centres = np.column_stack(
        [rng.uniform(0, 1000, m), rng.uniform(-50, 50, m), 1200 + rng.uniform(-5, 5, m)]
    )
    rotations = Rotation.from_rotvec(rng.normal(0, 0.05, (m, 3))).as_matrix()
    points = np.column_stack(
        [rng.uniform(0, 1000, p), rng.uniform(-400, 400, p), rng.uniform(-30, 30, p)]
    )
    photo = np.repeat(np.arange(m), p)
    point = np.tile(np.arange(p), m)
    _, _, jac_photo, jac_point = _collinearity(centres, rotations, points, photo, point, C_MM)
    for j in range(6):
        h = 1e-3 if j < 3 else 1e-6  # m, rad: central differences, truncation O(h^2)
        d = np.zeros((m, 6))
        d[:, j] = h
        plus = _collinearity(
            centres + d[:, :3], rotations @ _exp_so3(d[:, 3:]), points, photo, point, C_MM
        )[0]
        minus = _collinearity(
            centres - d[:, :3], rotations @ _exp_so3(-d[:, 3:]), points, photo, point, C_MM
        )[0]
        np.testing.assert_allclose(
            (plus - minus) / (2 * h), jac_photo[:, :, j], rtol=1e-6, atol=1e-7
        )
    h = 1e-3
    for j in range(3):
        d = np.zeros((p, 3))
        d[:, j] = h
        plus = _collinearity(centres, rotations, points + d, photo, point, C_MM)[0]
        minus = _collinearity(centres, rotations, points - d, photo, point, C_MM)[0]
        np.testing.assert_allclose(
            (plus - minus) / (2 * h), jac_point[:, :, j], rtol=1e-6, atol=1e-9
        )
    # near-vertical photos at H ~ 1200 m: dx/dX is about the image scale c / H = 0.127 mm/m
    np.testing.assert_allclose(jac_point[:, 0, 0], C_MM / 1200, rtol=0.05)


def test_imu_jacobian_and_so3_maps():
    rng = np.random.default_rng(3)
    r = Rotation.from_rotvec(rng.normal(0, 0.3, (5, 3))).as_matrix()
    r_imu = Rotation.from_rotvec(rng.normal(0, 0.3, (5, 3))).as_matrix()
    # exp / log against scipy's Rotation
    w = rng.normal(0, 0.5, (5, 3))
    np.testing.assert_allclose(_exp_so3(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(_log_so3(_exp_so3(w)), w, atol=1e-12)
    np.testing.assert_allclose(
        _exp_so3(np.full((2, 3), 1e-9)),
        Rotation.from_rotvec(np.full((2, 3), 1e-9)).as_matrix(),
        atol=1e-16,
    )
    e = _imu_residual(r, r_imu)
    jac = _right_jacobian_inv(e)
    h = 1e-6
    for j in range(3):
        d = np.zeros((5, 3))
        d[:, j] = h
        fd = (_imu_residual(r @ _exp_so3(d), r_imu) - _imu_residual(r @ _exp_so3(-d), r_imu)) / (
            2 * h
        )
        np.testing.assert_allclose(fd, jac[:, :, j], rtol=1e-7, atol=1e-8)


def test_bad_arguments_raise_value_error():
    strip = make_strip()
    obs = strip.observations()
    with pytest.raises(ValueError, match="Expected `points0` to have shape"):
        bundle_adjust(obs, strip.centres, strip.rotations, strip.points[:-1])
    with pytest.raises(ValueError, match="proper rotation"):
        bundle_adjust(obs, strip.centres, 2.0 * strip.rotations, strip.points)
    with pytest.raises(ValueError, match="without its standard deviations"):
        bundle_adjust(obs, strip.centres, strip.rotations, strip.points, control_xyz=strip.points)
    with pytest.raises(ValueError, match="positive standard deviations"):
        bundle_adjust(
            obs,
            strip.centres,
            strip.rotations,
            strip.points,
            control_xyz=strip.points,
            control_sigma=0.0,
        )


def test_iteration_limit_warns_and_reports_not_converged():
    from strip_aerotri.errors import StripAerotriWarning

    strip = make_strip()
    rng = np.random.default_rng(8)
    ctrl, sigma = full_control(strip, corner_points(strip))
    centres0, rot0, points0 = perturbed(strip, rng)
    with pytest.warns(StripAerotriWarning, match="did not converge in 1 iterations"):
        res = bundle_adjust(
            strip.observations(),
            centres0,
            rot0,
            points0,
            control_xyz=ctrl,
            control_sigma=sigma,
            max_iterations=1,
        )
    assert not res.converged and res.iterations == 1 and res.history.shape == (2,)


def strip_with_weak_first_photo(strip: Strip, n_keep: int) -> tuple[ImageObservations, np.ndarray]:
    """Keep only ``n_keep`` rays on photo 0 (of points seen on 3 photos), drop points left
    with fewer than two rays; returns the observations and the kept point indices."""
    triple = np.flatnonzero(np.bincount(strip.point) == 3)
    on_first = np.intersect1d(strip.point[strip.photo == 0], triple)[:n_keep]
    keep = (strip.photo != 0) | np.isin(strip.point, on_first)
    rays = np.bincount(strip.point[keep], minlength=strip.points.shape[0])
    kept_points = np.flatnonzero(rays >= 2)
    keep &= np.isin(strip.point, kept_points)
    new_index = np.full(strip.points.shape[0], -1)
    new_index[kept_points] = np.arange(kept_points.size)
    obs = strip.observations()
    return (
        ImageObservations(
            obs.photo_ids,
            tuple(obs.point_ids[i] for i in kept_points),
            obs.photo[keep],
            new_index[obs.point[keep]],
            obs.xy[keep],
            obs.sigma[keep],
            C_MM,
        ),
        kept_points,
    )


def test_photo_with_two_points_is_singular_unless_its_centre_is_observed():
    strip = make_strip()
    obs, kept = strip_with_weak_first_photo(strip, 2)
    points = strip.points[kept]
    ctrl = np.full(points.shape, np.nan)
    idx = corner_points(
        Strip(strip.centres, strip.rotations, points, obs.photo, obs.point, obs.xy)
    )
    ctrl[idx] = points[idx]
    args = (obs, strip.centres, strip.rotations, points)
    with pytest.raises(GeometryError, match=r"singular.*photo '001'"):
        bundle_adjust(*args, control_xyz=ctrl, control_sigma=0.01)
    # two rays plus an observed centre: 4 + 3 observations for 6 unknowns
    gnss = np.full(strip.centres.shape, np.nan)
    gnss[0] = strip.centres[0]
    res = bundle_adjust(
        *args, control_xyz=ctrl, control_sigma=0.01, gnss_centres=gnss, gnss_sigma=0.05
    )
    np.testing.assert_allclose(res.centres, strip.centres, atol=1e-6, rtol=0)


def test_poor_start_needs_damping_and_still_converges(monkeypatch):
    import strip_aerotri.bundle.adjust as bundle_module

    damping = []
    solve = bundle_module._solve

    def recording_solve(prob, normals, lam, **kwargs):
        damping.append(lam)
        return solve(prob, normals, lam, **kwargs)

    monkeypatch.setattr(bundle_module, "_solve", recording_solve)
    strip = make_strip()
    rng = np.random.default_rng(3)
    m, p = strip.centres.shape[0], strip.points.shape[0]
    # centres and points +-600 m, rotations +-40 deg: plain Gauss-Newton steps overshoot
    centres0 = strip.centres + rng.uniform(-600, 600, (m, 3))
    rot0 = strip.rotations @ _exp_so3(rng.uniform(-np.radians(40), np.radians(40), (m, 3)))
    points0 = strip.points + rng.uniform(-600, 600, (p, 3))
    ctrl, sigma = full_control(strip, corner_points(strip))
    res = bundle_adjust(
        strip.observations(),
        centres0,
        rot0,
        points0,
        control_xyz=ctrl,
        control_sigma=sigma,
        max_iterations=50,
    )
    assert any(lam > 0 for lam in damping)
    assert res.converged
    np.testing.assert_allclose(res.points, strip.points, atol=1e-6, rtol=0)
    assert np.all(np.diff(res.history) <= 0.0)  # accepted steps never increase the objective


def test_a_block_is_numbered_across_its_strips():
    """The photos of a block, listed strip after strip, are ordered along the
    block's main axis for the band (across the strips): the half-band is
    about the strips times the overlap window, not a strip's length, and the
    adjustment from a perturbed truth is the truth's to the noise."""
    import strip_aerotri.bundle.adjust as bundle_module
    from strip_aerotri.geometry.normals import NormalStructure
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(4, 25, preset="drone", crs="local", seed=3)
    obs, truth = sim.observations, sim.truth
    given = NormalStructure.from_indices(
        obs.n_photos, 6, obs.n_points, obs.photo, obs.point, order="given"
    )
    structures = []
    build = bundle_module.NormalStructure.from_indices

    def recording(*args, **kwargs):
        structures.append(build(*args, **kwargs))
        return structures[-1]

    import unittest.mock

    control = np.full((obs.n_points, 3), np.nan)
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    rows = [lookup[pid] for pid in sim.control.point_ids]
    control[rows] = truth.points_local[rows]
    with unittest.mock.patch.object(bundle_module.NormalStructure, "from_indices", recording):
        res = bundle_adjust(
            obs, truth.photo_centres_local + 0.05, truth.photo_rotations_local,
            truth.points_local - 0.05, control_xyz=control, control_sigma=0.02,
        )  # fmt: skip
    width = structures[0].width
    assert width < 0.6 * given.width  # strip after strip: about two strips' length
    assert width <= 4 * 8  # four strips, a window of at most 8 photos each
    assert res.converged and 0.8 < res.sigma0 < 1.2


def test_results_per_observation_follow_the_observations_order():
    """The adjustment runs on its rows in the normal structure's order of
    pairs (bundle/adjust.py ``_Problem.rows``); residuals and redundancy
    numbers come back in the observations' own order, whatever it is: the
    observations shuffled give the same adjustment and the same values
    shuffled alike (to 1e-9), and a point behind a photo is named by the
    first such observation as given."""
    strip = make_strip()
    rng = np.random.default_rng(3)
    obs = strip.observations(rng)
    ctrl, ctrl_sigma = full_control(strip, corner_points(strip)[:4])
    start = perturbed(strip, rng)
    perm = rng.permutation(obs.photo.size)
    shuffled = ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo[perm], obs.point[perm], obs.xy[perm],
        obs.sigma[perm], obs.principal_distance,
    )
    a = bundle_adjust(obs, *start, control_xyz=ctrl, control_sigma=ctrl_sigma)
    b = bundle_adjust(shuffled, *start, control_xyz=ctrl, control_sigma=ctrl_sigma)
    np.testing.assert_allclose(b.points, a.points, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.residuals_mm, a.residuals_mm[perm], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b.image_redundancy, a.image_redundancy[perm], rtol=1e-9)
    predicted = (strip.xy - obs.xy)[perm]  # computed minus observed, near the truth
    assert np.sqrt(np.mean((b.residuals_mm - predicted) ** 2)) < SIGMA_MM
    # behind a photo: two points moved above the photos; the first named
    behind = start[2].copy()
    first, second = shuffled.point[0], shuffled.point[1]
    behind[[first, second]] = strip.centres[0] + [0.0, 0.0, 500.0]
    with pytest.raises(GeometryError, match=f"point 'p{first:03d}' lies behind"):
        bundle_adjust(shuffled, start[0], start[1], behind, control_xyz=ctrl,
                      control_sigma=ctrl_sigma)


def test_the_image_rows_centre_columns_are_their_points_negated_on_every_row():
    """The bundle marks its image rows ``unit_shift`` (the engine forms their
    blocks from the distinct products and checks a sample): every row's
    centre columns are its point's negated, to the bit, whitened or not."""
    from strip_aerotri.bundle import adjust

    strip = make_strip()
    rng = np.random.default_rng(8)
    obs = strip.observations(rng)
    obs = ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo, obs.point, obs.xy,
        rng.uniform(0.002, 0.01, obs.photo.size), obs.principal_distance,
    )  # a sigma of its own per observation: the rows whitened unequally
    ctrl, ctrl_sigma = full_control(strip, corner_points(strip)[:4])
    centres, rotations, points = perturbed(strip, rng)
    prob = adjust._make_problem(
        obs, centres, rotations, points, ctrl, ctrl_sigma, None, None, None, None
    )
    normals = adjust._normals(prob, adjust._State(centres, rotations, points))
    assert normals is not None and normals.image.unit_shift
    np.testing.assert_array_equal(
        normals.image.unit_jacobian[..., :3], -normals.image.point_jacobian
    )
