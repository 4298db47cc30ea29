"""Rolling shutter in the bundle: the motion's design columns against finite
differences, its cofactors against a dense inverse, a simulated motion
recovered, and a still camera left as it is."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import _observation_space as mapped

from strip_aerotri.bundle.adjust import bundle_adjust
from strip_aerotri.geometry.camera_model import ShutterMotion
from strip_aerotri.geometry.collinearity import collinearity_jacobians, project
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.observations import ImageObservations

C = 100.0
READOUT = 120.0  # mm: the format's height
#: Per strip, the centre's displacement over the readout (m, frame X Y Z).
TRUTH = np.array([[0.9, 0.4, -0.5], [-0.7, 0.3, 0.6]])


def _network(
    motion: np.ndarray | None, seed: int = 5, noise_mm: float = 0.003
) -> tuple[ImageObservations, ShutterMotion, np.ndarray, np.ndarray, np.ndarray]:
    """Two strips of six vertical photos (60 % forward, 30 % side overlap)
    over points with relief; the images of a camera whose centre moves by
    ``motion[g] (t - 1/2)`` while its rows are read."""
    rng = np.random.default_rng(seed)
    xs = np.arange(6) * 480.0
    centres = np.concatenate(
        [np.column_stack([xs, np.full(6, y), 1000 + rng.normal(0, 5, 6)]) for y in (0.0, 840.0)]
    )
    m = centres.shape[0]
    rotations = matrix_from_rotvec(rng.normal(0, 0.01, (m, 3)))
    n = 400
    points = np.column_stack(
        [rng.uniform(60, 2340, n), rng.uniform(-480, 1320, n), rng.uniform(-40, 40, n)]
    )
    photo, point = np.repeat(np.arange(m), n), np.tile(np.arange(n), m)
    xy, _ = project(centres, rotations, points, photo, point, C)
    keep = np.all(np.abs(xy) < READOUT / 2, axis=1)
    photo, point, xy = photo[keep], point[keep], xy[keep]
    shutter = ShutterMotion(np.repeat([0, 1], 6), ("one", "two"), READOUT)
    if motion is not None:  # x = x(S + s(x) d, R, X): the row's time depends on the image y
        for _ in range(30):
            shift = shutter.centre_shift(motion, photo, shutter.fractions(xy))
            xy, _ = project(
                centres[photo] + shift, rotations[photo], points[point],
                np.arange(photo.size), np.arange(photo.size), C,
            )
    k = photo.size
    obs = ImageObservations(
        tuple(f"f{j}" for j in range(m)), tuple(f"p{i}" for i in range(n)), photo, point,
        xy + rng.normal(0, noise_mm, (k, 2)), np.full(k, max(noise_mm, 1e-4)), C,
    )
    return obs, shutter, centres, rotations, points


def _projector(
    shutter: ShutterMotion,
    obs: ImageObservations,
    centres: np.ndarray,
    rotations: np.ndarray,
    points: np.ndarray,
    motion: np.ndarray,
) -> Callable[[np.ndarray], np.ndarray]:
    """The rays' projections (K, 2) as a function of their fractions (K,)."""
    rays = np.arange(obs.photo.size)

    def at(s: np.ndarray) -> np.ndarray:
        moved = centres[obs.photo] + shutter.centre_shift(motion, obs.photo, s)
        xy, _ = project(moved, rotations[obs.photo], points[obs.point], rays, rays, C)
        return xy

    return at


def _control(points: np.ndarray) -> np.ndarray:
    control = np.full_like(points, np.nan)
    control[::12] = points[::12]
    return control


def test_motion_columns_match_finite_differences() -> None:
    """``ShutterMotion.border`` is d x(S + s d, R, X) / d d by central differences."""
    obs, shutter, centres, rotations, points = _network(TRUTH, noise_mm=0.0)
    s = shutter.fractions(obs.xy)
    rays = np.arange(obs.photo.size)

    def image(d: np.ndarray) -> np.ndarray:
        out, _ = project(
            centres[obs.photo] + shutter.centre_shift(d, obs.photo, s), rotations[obs.photo],
            points[obs.point], rays, rays, C,
        )
        return out

    _, _, jac_photo, _ = collinearity_jacobians(
        centres[obs.photo] + shutter.centre_shift(TRUTH, obs.photo, s), rotations[obs.photo],
        points[obs.point], rays, rays, C,
    )
    design = shutter.border(jac_photo[:, :, :3], obs.photo, s)
    assert design.shape == (obs.photo.size, 2, 6)
    for col in range(6):
        e = np.zeros(6)
        e[col] = 1e-3
        fd = (image(TRUTH + e.reshape(2, 3)) - image(TRUTH - e.reshape(2, 3))) / 2e-3
        assert np.allclose(design[:, :, col], fd, rtol=1e-6, atol=1e-10)
    # the other group's columns are zero
    assert not np.any(design[obs.photo == 0][:, :, 3:])
    assert np.all(np.abs(s) <= 0.5)


def test_motion_cofactors_match_a_dense_inverse() -> None:
    """The motions' cofactor block equals that of N^-1 formed densely from a
    finite-difference Jacobian of every observation equation at the solution."""
    obs, shutter, centres, rotations, points = _network(TRUTH, seed=2)
    keep = obs.point < 60  # a small network for the dense reference
    obs = ImageObservations(
        obs.photo_ids, obs.point_ids[:60], obs.photo[keep], obs.point[keep], obs.xy[keep],
        obs.sigma[keep], C,
    )
    points = points[:60]
    control = _control(points)
    res = bundle_adjust(
        obs, centres, rotations, points, control_xyz=control, control_sigma=0.05, motion=shutter
    )
    assert res.motion is not None
    m, p = centres.shape[0], points.shape[0]

    def f(x: np.ndarray) -> np.ndarray:
        d = x[: 6 * m].reshape(m, 6)
        cen = res.centres + d[:, :3]
        rot = res.rotations @ matrix_from_rotvec(d[:, 3:])
        pts = x[6 * m : 6 * m + 3 * p].reshape(p, 3)
        at = _projector(shutter, obs, cen, rot, pts, x[6 * m + 3 * p :].reshape(2, 3))
        xhat = mapped.rows_read(at, shutter.fractions, None, np.zeros(0), obs.xy)
        ctrl = (pts - control) / 0.05
        img = (xhat - obs.xy) / obs.sigma[:, None]
        return np.concatenate([img.ravel(), ctrl[np.isfinite(ctrl)]])

    x0 = np.concatenate([np.zeros(6 * m), res.points.ravel(), res.motion.values.ravel()])
    jac = np.empty((f(x0).size, x0.size))
    for i in range(x0.size):
        e = np.zeros_like(x0)
        e[i] = 1e-6 * max(1.0, abs(x0[i]))
        jac[:, i] = (f(x0 + e) - f(x0 - e)) / (2 * e[i])
    q = np.linalg.inv(jac.T @ jac)
    assert np.allclose(res.motion.cofactor, q[6 * m + 3 * p :, 6 * m + 3 * p :], rtol=2e-3)
    assert res.redundancy == f(x0).size - x0.size


def test_simulated_motion_is_recovered_within_three_sigma() -> None:
    """Per strip the estimated motion agrees with the simulated one within
    3 sigma, over three noise draws; the points come back to the truth."""
    for seed in (1, 2, 3):
        obs, shutter, centres, rotations, points = _network(TRUTH, seed=seed)
        start = dict(control_xyz=_control(points), control_sigma=0.05)
        res = bundle_adjust(obs, centres, rotations, points, motion=shutter, **start)
        assert res.motion is not None
        assert res.motion.group_names == ("one", "two")
        dev = (res.motion.values - TRUTH) / res.motion.std
        assert np.all(np.abs(dev) < 3.0), (seed, dev)
        # along and across the rows well determined; vertically a scale
        # change along the rows, which the points' heights partly take
        assert np.all(res.motion.std[:, :2] < 0.05)
        plain = bundle_adjust(obs, centres, rotations, points, **start)
        err = np.sqrt(np.mean((res.points - points) ** 2))
        err_plain = np.sqrt(np.mean((plain.points - points) ** 2))
        assert err < 0.5 * err_plain, (err, err_plain)


def test_still_camera_is_left_as_it_is() -> None:
    """Without motion the estimates are zero within 3 sigma and the points'
    error against the truth changes by less than 2 %."""
    for seed in (1, 2, 3):
        obs, shutter, centres, rotations, points = _network(None, seed=seed)
        start = dict(control_xyz=_control(points), control_sigma=0.05)
        res = bundle_adjust(obs, centres, rotations, points, motion=shutter, **start)
        plain = bundle_adjust(obs, centres, rotations, points, **start)
        assert res.motion is not None
        assert np.all(np.abs(res.motion.values / res.motion.std) < 3.0)
        check = np.all(np.isnan(_control(points)), axis=1)
        err = np.sqrt(np.mean((res.points[check] - points[check]) ** 2))
        err_plain = np.sqrt(np.mean((plain.points[check] - points[check]) ** 2))
        assert abs(err / err_plain - 1.0) < 0.02, (seed, err, err_plain)


def test_bad_groups_are_refused() -> None:
    with pytest.raises(ValueError, match="photo groups"):
        ShutterMotion(np.array([0, 2]), ("a", "b"), READOUT)
    with pytest.raises(ValueError, match="readout"):
        ShutterMotion(np.array([0, 1]), ("a", "b"), 0.0)


def test_data_snooping_with_a_moving_camera_finds_the_blunders() -> None:
    """With the motion estimated, the data snooping tests the residuals of the
    moved centres: three 40 µm image blunders (13 sigma) are rejected and
    nothing else,
    and the motion is still recovered within 3 sigma."""
    from strip_aerotri.bundle.snooping import refine_frame

    obs, shutter, centres, rotations, points = _network(TRUTH, seed=4)
    rays = np.bincount(obs.point)[obs.point]
    rows = np.flatnonzero(rays >= 3)[[10, 300, 600]]  # three rays or more: localisable
    xy = obs.xy.copy()
    xy[rows, 1] += 0.04  # across the base: not a height
    bad = ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo, obs.point, xy, obs.sigma, C
    )
    fr = refine_frame(
        bad, centres, rotations, points, control_xyz=_control(points), control_sigma=0.05,
        motion=shutter,
    )
    found = {(r.point, r.photos) for r in fr.rejections if r.stage == "bundle" and r.applied}
    planted = {(obs.point_ids[obs.point[k]], (obs.photo_ids[obs.photo[k]],)) for k in rows}
    assert found == planted
    assert fr.bundle.motion is not None
    dev = (fr.bundle.motion.values - TRUTH) / fr.bundle.motion.std
    assert np.all(np.abs(dev) < 3.0), dev


def test_camera_and_motion_share_the_border() -> None:
    """With camera parameters and motions in one border, each block of the
    cofactor matrix equals the dense inverse's, and both are recovered."""
    from strip_aerotri.geometry.camera_model import CameraModel, brown_correction

    obs, shutter, centres, rotations, points = _network(TRUTH, seed=6)
    keep = obs.point < 80
    truth_cam = np.zeros(10)
    truth_cam[[3, 8]] = [-3e-6, 2e-4]  # k1 (mm^-2), b1
    measured = obs.xy[keep].copy()
    for _ in range(20):  # m + Δ(m) = the image of the moving camera
        measured = obs.xy[keep] - brown_correction(measured, truth_cam, C)
    obs = ImageObservations(
        obs.photo_ids, obs.point_ids[:80], obs.photo[keep], obs.point[keep], measured,
        obs.sigma[keep], C,
    )
    points = points[:80]
    control = _control(points)
    model = CameraModel("brown", ("k1", "b1"), C)
    res = bundle_adjust(
        obs, centres, rotations, points, control_xyz=control, control_sigma=0.05,
        camera=model, motion=shutter,
    )
    assert res.camera is not None and res.motion is not None
    m, p = centres.shape[0], points.shape[0]

    def f(x: np.ndarray) -> np.ndarray:
        d = x[: 6 * m].reshape(m, 6)
        cen = res.centres + d[:, :3]
        rot = res.rotations @ matrix_from_rotvec(d[:, 3:])
        pts = x[6 * m : 6 * m + 3 * p].reshape(p, 3)
        cam = x[6 * m + 3 * p : 6 * m + 3 * p + 2]
        at = _projector(shutter, obs, cen, rot, pts, x[6 * m + 3 * p + 2 :].reshape(2, 3))
        xhat = mapped.rows_read(at, shutter.fractions, model, cam, obs.xy)
        img = (xhat - obs.xy) / obs.sigma[:, None]
        ctrl = (pts - control) / 0.05
        return np.concatenate([img.ravel(), ctrl[np.isfinite(ctrl)]])

    x0 = np.concatenate(
        [np.zeros(6 * m), res.points.ravel(), res.camera.values, res.motion.values.ravel()]
    )
    jac = np.empty((f(x0).size, x0.size))
    for i in range(x0.size):
        h = 1e-6 * max(1.0, abs(x0[i])) if i < 6 * m + 3 * p else 1e-4 * abs(x0[i]) + 1e-10
        e = np.zeros_like(x0)
        e[i] = h
        jac[:, i] = (f(x0 + e) - f(x0 - e)) / (2 * h)
    q = np.linalg.inv(jac.T @ jac)[6 * m + 3 * p :, 6 * m + 3 * p :]
    assert np.allclose(res.camera.cofactor, q[:2, :2], rtol=2e-3)
    assert np.allclose(res.motion.cofactor, q[2:, 2:], rtol=2e-3)
    assert np.all(np.abs((res.camera.values - truth_cam[[3, 8]]) / res.camera.std) < 3.0)
    assert np.all(np.abs((res.motion.values - TRUTH) / res.motion.std) < 3.0)


def test_an_undetermined_motion_is_named() -> None:
    """A group whose rays are all read on one row (a photo of its own whose
    points lie on its row y = 20 mm, seen by two photos of the other group
    too) has a motion that its centre takes: one GeometryError naming it."""
    from strip_aerotri.errors import GeometryError

    obs, _, centres, rotations, points = _network(None, seed=1, noise_mm=0.0)
    rng = np.random.default_rng(7)
    centre, rotation = centres[11] + [0.0, 30.0, 0.0], rotations[11]
    n, y0 = 12, 20.0
    ray = np.column_stack([np.linspace(-55.0, 5.0, n), np.full(n, y0), np.full(n, -C)])
    depth = (1000.0 + rng.uniform(-40.0, 40.0, n)) / C  # relief: the photo is determined
    row_points = centre + depth[:, None] * (ray @ rotation.T)
    all_centres = np.vstack([centres, centre])
    all_rotations = np.concatenate([rotations, [rotation]])
    all_points = np.vstack([points, row_points])
    new = points.shape[0] + np.arange(n)
    photo = np.concatenate([np.full(n, 12), np.full(n, 11), np.full(n, 10)])
    xy, _ = project(all_centres, all_rotations, all_points, photo, np.tile(new, 3), C)
    assert np.all(np.abs(xy) < READOUT / 2) and np.allclose(xy[:n, 1], y0)
    k = obs.photo.size + 3 * n
    rows = ImageObservations(
        (*obs.photo_ids, "f12"), (*obs.point_ids, *(f"r{i}" for i in range(n))),
        np.concatenate([obs.photo, photo]), np.concatenate([obs.point, np.tile(new, 3)]),
        np.vstack([obs.xy, xy]), np.full(k, 1e-3), C,
    )
    shutter = ShutterMotion(np.repeat([0, 1], [12, 1]), ("one", "two"), READOUT)
    with pytest.raises(GeometryError, match="motion along [XYZ] of 'two' is not determined"):
        bundle_adjust(
            rows, all_centres, all_rotations, all_points, control_xyz=_control(all_points),
            control_sigma=0.05, motion=shutter,
        )


def test_rows_are_read_from_the_sensor_top() -> None:
    """s = t - 1/2 is -1/2 at the sensor's top row (y up) and +1/2 at its
    bottom, whatever the flight axes the coordinates come in."""
    top_bottom_sensor = np.array([[0.3, READOUT / 2], [-0.2, -READOUT / 2], [5.0, 0.0]])
    plus_y = np.array([[0.0, 1.0], [-1.0, 0.0]])  # [images] flight_direction = "+y"
    for turn in (np.eye(2), plus_y, -np.eye(2)):
        shutter = ShutterMotion(np.array([0]), ("a",), READOUT, turn)
        flight = top_bottom_sensor @ turn.T  # f = M s
        assert np.allclose(shutter.fractions(flight), [-0.5, 0.5, 0.0])


def _linearised(
    monkeypatch: pytest.MonkeyPatch,
) -> tuple[object, np.ndarray, int, np.ndarray]:
    """The bundle's image rows for seed 6's network with a camera of two
    parameters (k1, b1 at -3e-6, 2e-4) and the simulated motion; the
    camera's values; the number of times the rows' fractions were computed;
    the observation of each row (the bundle's rows are in its structure's
    order)."""
    from strip_aerotri.bundle import adjust
    from strip_aerotri.geometry.camera_model import CameraModel

    obs, shutter, centres, rotations, points = _network(TRUTH, seed=6)
    prob = adjust._make_problem(
        obs, centres, rotations, points, _control(points), 0.05, None, None, None, None,
        camera=CameraModel("brown", ("k1", "b1"), C), motion=shutter,
    )
    camera = np.array([-3e-6, 2e-4])
    calls = [0]
    fractions = ShutterMotion.fractions

    def counted(self: ShutterMotion, xy: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return fractions(self, xy)

    monkeypatch.setattr(ShutterMotion, "fractions", counted)
    normals = adjust._normals(prob, adjust._State(centres, rotations, points, camera, TRUTH))
    monkeypatch.undo()
    assert normals is not None
    return normals.image, camera, calls[0], prob.rows


def test_whitened_rows_equal_rows_whitened_after(monkeypatch: pytest.MonkeyPatch) -> None:
    """The image rows, border included, built from the Jacobians whitened in
    the collinearity's blocks equal those of unwhitened Jacobians mapped to
    the observations' space (premultiplied by ``(I + ∂Δ/∂x - u aᵀ)⁻¹`` from
    numpy's inverse, ``u = (dx/dS) d`` the image's motion over the readout,
    ``a`` the fraction's gradient, ``x̂`` read at its own row by the fixed
    point) times 1/σ: the motion's columns s dx/dS are linear in dx/dS."""
    from strip_aerotri.geometry.camera_model import CameraModel

    image, camera, _, rows = _linearised(monkeypatch)
    obs, shutter, centres, rotations, points = _network(TRUTH, seed=6)
    model = CameraModel("brown", ("k1", "b1"), C)
    at = _projector(shutter, obs, centres, rotations, points, TRUTH)
    true_xy = mapped.rows_read(at, shutter.fractions, model, camera, obs.xy)
    s = shutter.fractions(true_xy)
    rays = np.arange(obs.photo.size)
    moved = points[obs.point] - shutter.centre_shift(TRUTH, obs.photo, s)
    xy, _, jac_photo, jac_point = collinearity_jacobians(
        centres, rotations, moved, obs.photo, rays, C
    )
    # x̂ + Δ(x̂) = x(s(x̂)): every column premultiplied by (I + ∂Δ/∂x - u aᵀ)⁻¹
    u = np.einsum("kij,kj->ki", jac_photo[:, :, :3], TRUTH[shutter.group[obs.photo]])
    a = shutter.fractions(np.eye(2))
    m = np.linalg.inv(np.eye(2) + model.xy_partials(true_xy, camera) - u[:, :, None] * a)
    jac_photo, jac_point = m @ jac_photo, m @ jac_point
    border = np.concatenate(
        [-m @ model.partials(true_xy, camera), shutter.border(jac_photo[:, :, :3], obs.photo, s)],
        axis=2,
    )
    inv_s = 1.0 / obs.sigma
    w = inv_s[:, None, None]
    # the engine's Jacobians are at the first solution's rows, 1e-14 mm / h
    # from x̂'s: the same to 1e-12 of each array's largest entry
    for got, want in (
        (image.unit_jacobian, (jac_photo * w)[rows]),
        (image.point_jacobian, (jac_point * w)[rows]),
        (image.border_jacobian, (border * w)[rows]),
        (image.residual, ((true_xy - obs.xy) * inv_s[:, None])[rows]),
    ):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.max(np.abs(want)))
    assert np.count_nonzero(border[:, :, 2:]) > 0  # the motion's columns are there
    # every row's centre columns are its point's negated (the rows' unit_shift)
    assert image.unit_shift
    np.testing.assert_array_equal(image.unit_jacobian[..., :3], -image.point_jacobian)


def test_fractions_are_computed_thrice_per_linearisation(monkeypatch: pytest.MonkeyPatch) -> None:
    """One build of the normal equations with a moving centre reads the rows'
    fractions three times: at the observations (the first solution), at its
    true positions (the projections) and at theirs (the motion's columns)."""
    assert _linearised(monkeypatch)[2] == 3


@pytest.mark.parametrize("with_camera", [False, True])
def test_residuals_at_the_truth_are_the_measurement_errors(with_camera: bool) -> None:
    """The rows are read where the rays land, at their true positions x̂
    (``x̂ + Δ(x̂) = x(S + s(x̂) d)``): at the true state the residuals are
    the measurements' errors, ``v = -e``, to 1e-12 mm.  Read at the measured
    rows instead, the projections carry ``u aᵀ e`` (here 1e-6 to 1e-5 mm):
    the convention this holds."""
    from strip_aerotri.bundle import adjust
    from strip_aerotri.geometry.camera_model import CameraModel

    obs, shutter, centres, rotations, points = _network(None, seed=8, noise_mm=0.0)
    model = CameraModel("brown", ("k1", "b1"), C) if with_camera else None
    theta = np.array([-3e-6, 2e-4]) if with_camera else np.zeros(0)
    at = _projector(shutter, obs, centres, rotations, points, TRUTH)
    xhat = mapped.rows_read(at, shutter.fractions, model, theta, obs.xy)
    e = np.random.default_rng(9).normal(0.0, 0.003, xhat.shape)
    measured = ImageObservations(
        obs.photo_ids, obs.point_ids, obs.photo, obs.point, xhat + e, np.full(e.shape[0], 0.003), C
    )
    prob = adjust._make_problem(
        measured, centres, rotations, points, _control(points), 0.05, None, None, None, None,
        camera=model, motion=shutter,
    )  # fmt: skip
    normals = adjust._normals(prob, adjust._State(centres, rotations, points, theta, TRUTH))
    assert normals is not None
    np.testing.assert_allclose(normals.residuals_mm, -e[prob.rows], rtol=0, atol=1e-12)
    # the measured rows' projections: x + Δ... off by u aᵀ e, far above the tolerance
    measured_rows = at(shutter.fractions(xhat + e))
    true_rows = at(shutter.fractions(xhat))
    assert np.max(np.abs(measured_rows - true_rows)) > 1e-6


def test_image_velocity_is_the_projections_derivative_in_the_fraction() -> None:
    """``ShutterMotion.image_velocity`` is d x(S + s d, R, X) / ds by central
    differences; ``row_gradient`` is the fractions' gradient in x."""
    obs, shutter, centres, rotations, points = _network(TRUTH, noise_mm=0.0)
    at = _projector(shutter, obs, centres, rotations, points, TRUTH)
    s = shutter.fractions(obs.xy)
    rays = np.arange(obs.photo.size)
    moved = centres[obs.photo] + shutter.centre_shift(TRUTH, obs.photo, s)
    _, vectors = project(moved, rotations[obs.photo], points[obs.point], rays, rays, C)
    velocity = shutter.image_velocity(TRUTH, rotations, obs.photo, vectors, C)
    fd = (at(s + 1e-3) - at(s - 1e-3)) / 2e-3
    np.testing.assert_allclose(velocity, fd, rtol=1e-7, atol=1e-9 * np.max(np.abs(fd)))
    assert np.max(np.abs(velocity)) > 0.05  # mm: the motions move the images
    xy = np.random.default_rng(1).uniform(-60.0, 60.0, (50, 2))
    for turn in (np.eye(2), np.array([[0.0, 1.0], [-1.0, 0.0]])):
        turned = ShutterMotion(np.array([0]), ("a",), READOUT, turn)
        np.testing.assert_allclose(turned.fractions(xy), xy @ turned.row_gradient, rtol=1e-14)


def test_two_passes_reach_the_rows_read() -> None:
    """``moving_space``'s second pass, projecting at its first ``x̂``'s rows,
    meets the reference fixed point to 1e-11 mm and a third pass moves
    nothing, even 1-2 mm from the solution (blunders, first iterations) with
    a motion twice the simulated one; the first pass alone is off by more."""
    from strip_aerotri.bundle._observation_space import moving_space
    from strip_aerotri.geometry.camera_model import CameraModel

    obs, shutter, centres, rotations, points = _network(None, noise_mm=0.0)
    observed = obs.xy + np.random.default_rng(3).normal(0.0, 1.0, obs.xy.shape)
    model, theta = CameraModel("brown", ("k1", "b1"), C), np.array([-3e-6, 2e-4])
    shifts = 2.0 * TRUTH
    rays = (centres, rotations, points[obs.point], obs.photo, C)
    spaces = [moving_space(shutter, shifts, rays, model, theta, observed, k) for k in (1, 2, 3)]
    assert all(sp is not None and sp.converged for sp in spaces)
    one, two, three = (sp.true_xy for sp in spaces if sp is not None)
    at = _projector(shutter, obs, centres, rotations, points, shifts)
    reference = mapped.rows_read(at, shutter.fractions, model, theta, observed)
    np.testing.assert_allclose(two, reference, rtol=0, atol=1e-11)
    np.testing.assert_allclose(three, two, rtol=0, atol=1e-11)
    assert np.max(np.abs(one - reference)) > 1e-10
