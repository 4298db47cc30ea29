"""The self-calibration's image observation equation in the observations'
space (bundle/_observation_space.py): the true positions' sweeps, the rows'
Jacobians against finite differences of ``v = x̂ - x_obs``, and a plain
refinement untouched."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import _observation_space as mapped

from strip_aerotri.bundle import _observation_space as space
from strip_aerotri.bundle import adjust
from strip_aerotri.geometry.camera_model import BROWN_PARAMETERS, CameraModel, ShutterMotion
from strip_aerotri.geometry.collinearity import project
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.observations import ImageObservations

C = 100.0
READOUT = 120.0
#: every Brown/Fraser parameter, of the size a calibrated camera's corrections have
THETA = np.array([0.3, 0.02, -0.03, -3e-6, 2e-10, -1e-14, 2e-6, -1e-6, 2e-4, -1e-4])
MOTION = np.array([[0.4, 0.2, -0.3], [-0.3, 0.1, 0.2]])


def _network(seed: int = 3) -> tuple[ImageObservations, np.ndarray, np.ndarray, np.ndarray]:
    """Three tilted photos 480 m apart at 1000 m over 30 points with relief."""
    rng = np.random.default_rng(seed)
    centres = np.column_stack([np.arange(3) * 480.0, np.zeros(3), 1000 + rng.normal(0, 5, 3)])
    rotations = matrix_from_rotvec(rng.normal(0, 0.02, (3, 3)))
    n = 30
    points = np.column_stack(
        [rng.uniform(100, 860, n), rng.uniform(-400, 400, n), rng.uniform(-60, 60, n)]
    )
    photo, point = np.repeat(np.arange(3), n), np.tile(np.arange(n), 3)
    xy, _ = project(centres, rotations, points, photo, point, C)
    keep = np.all(np.abs(xy) < 60.0, axis=1)
    k = int(keep.sum())
    obs = ImageObservations(
        ("a", "b", "c"), tuple(f"p{i}" for i in range(n)), photo[keep], point[keep],
        xy[keep] + rng.normal(0, 0.003, (k, 2)), rng.uniform(0.002, 0.004, k), C,
    )  # fmt: skip
    return obs, centres, rotations, points


def test_sweeps_reach_the_true_positions_in_a_few() -> None:
    """x̂ + Δ(x̂) = x to 1e-12 mm after two sweeps from x_obs, equal to
    Newton's method with numpy's solver; M the inverse of I + ∂Δ/∂x at x̂."""
    model = CameraModel("brown", BROWN_PARAMETERS, C)
    rng = np.random.default_rng(1)
    observed = rng.uniform(-60, 60, (500, 2))
    computed = observed + model.correction(observed, THETA) + rng.normal(0, 0.01, (500, 2))
    out = space.observation_space(model, THETA, computed, observed)
    assert out.converged and out.sweeps == 2
    np.testing.assert_allclose(out.true_xy + model.correction(out.true_xy, THETA), computed,
                               rtol=0, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(out.true_xy, mapped.true_xy(model, THETA, computed, observed),
                               rtol=0, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(out.residuals, out.true_xy - observed, rtol=0, atol=0)
    inverse = np.linalg.inv(np.eye(2) + model.xy_partials(out.true_xy, THETA))
    np.testing.assert_allclose(out.mapping, inverse, rtol=1e-13, atol=1e-15)


def test_sweeps_that_do_not_contract_are_reported() -> None:
    """A c increment of +c (∂Δ/∂x = -I: I + ∂Δ/∂x = 0, singular) has
    no true position: not converged, NaN everywhere, and the bundle's
    linearisation refuses it."""
    model = CameraModel("brown", ("c",), C)
    observed = np.array([[10.0, -20.0], [30.0, 5.0]])
    with np.errstate(divide="ignore", invalid="ignore"):
        out = space.observation_space(model, np.array([C]), observed + 0.01, observed)
    assert not out.converged
    assert np.all(np.isnan(out.residuals)) and np.all(np.isnan(out.mapping))
    obs, centres, rotations, points = _network()
    prob = adjust._make_problem(
        obs, centres, rotations, points, None, None, None, None, None, None, camera=model
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        state = adjust._State(centres, rotations, points, np.array([C]))
        assert adjust._normals(prob, state) is None


def test_premultiply_works_on_strided_views() -> None:
    """``premultiply`` equals a batched matmul, on a view laid out entry by entry."""
    rng = np.random.default_rng(2)
    m = np.eye(2) + rng.normal(0, 1e-3, (7, 2, 2))
    base = rng.normal(size=(2, 6, 7))
    jac = np.moveaxis(base, -1, 0)  # (7, 2, 6), not contiguous
    expect = m @ jac
    space.premultiply(m, jac)
    np.testing.assert_allclose(jac, expect, rtol=1e-15, atol=1e-15)
    np.testing.assert_array_equal(np.moveaxis(base, -1, 0), jac)  # written in place


def _linearised(
    obs: ImageObservations, centres: np.ndarray, rotations: np.ndarray, points: np.ndarray
) -> tuple[adjust._Problem, adjust._Normals]:
    shutter = ShutterMotion(np.array([0, 0, 1]), ("one", "two"), READOUT)
    prob = adjust._make_problem(
        obs, centres, rotations, points, None, None, None, None, None, None,
        camera=CameraModel("brown", BROWN_PARAMETERS, C), motion=shutter,
    )  # fmt: skip
    normals = adjust._normals(prob, adjust._State(centres, rotations, points, THETA, MOTION))
    assert normals is not None
    return prob, normals


def test_rows_are_the_derivatives_of_the_mapped_residuals() -> None:
    """Every column of the image rows (photos, points, the ten camera
    parameters, the shutter's motions) equals the central difference of the
    whitened ``v = x̂ - x_obs`` (x̂ by Newton's method, read at its own row
    by the fixed point on the fraction) at a state away from the solution
    (residuals of 0.1-1 mm, so that x̂ is not x_obs)."""
    obs, centres, rotations, points = _network()
    rng = np.random.default_rng(4)
    centres = centres + rng.normal(0, 0.5, centres.shape)
    points = points + rng.normal(0, 0.5, points.shape)
    prob, normals = _linearised(obs, centres, rotations, points)
    assert prob.motion is not None and prob.camera is not None
    rays = np.arange(prob.photo.size)

    n_photo, n_point = 6 * 3, 3 * points.shape[0]

    def v(x: np.ndarray) -> np.ndarray:
        """Whitened v at the unknowns x: photo and point increments, θ, motions."""
        d_photo = x[:n_photo].reshape(3, 6)
        cen = centres + d_photo[:, :3]
        rot = rotations @ matrix_from_rotvec(d_photo[:, 3:])
        pts = points + x[n_photo : n_photo + n_point].reshape(-1, 3)
        theta, motion = x[n_photo + n_point : -6], x[-6:].reshape(2, 3)

        def at(s: np.ndarray) -> np.ndarray:
            shift = prob.motion.centre_shift(motion, prob.photo, s)
            xy, _ = project(
                cen[prob.photo] + shift, rot[prob.photo], pts[prob.point], rays, rays, C
            )
            return xy

        xhat = mapped.rows_read(at, prob.motion.fractions, prob.camera, theta, prob.xy)
        out: np.ndarray = (xhat - prob.xy) / prob.sigma[:, None]
        return out

    x0 = np.concatenate([np.zeros(n_photo + n_point), THETA, MOTION.ravel()])
    image = normals.image
    np.testing.assert_allclose(image.residual, v(x0), rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(image.residual * prob.sigma[:, None])) > 0.1  # away from the solution
    camera_steps = [1e-4, 1e-5, 1e-5, 1e-9, 1e-13, 1e-17, 1e-8, 1e-8, 1e-6, 1e-6]
    steps = [*([1e-4] * 3 + [1e-7] * 3) * 3, *[1e-4] * n_point, *camera_steps, *[1e-3] * 6]
    photo_of = np.arange(n_photo) // 6
    point_of = np.arange(n_point) // 3
    for i, h in enumerate(steps):
        e = np.zeros_like(x0)
        e[i] = h
        num = (v(x0 + e) - v(x0 - e)) / (2.0 * h)
        if i < n_photo:
            rows = prob.photo == photo_of[i]
            analytic = image.unit_jacobian[rows, :, i % 6]
            assert np.all(num[~rows] == 0.0)
        elif i < n_photo + n_point:
            rows = prob.point == point_of[i - n_photo]
            analytic = image.point_jacobian[rows, :, (i - n_photo) % 3]
        else:
            rows = np.ones(prob.photo.size, bool)
            analytic = image.border_jacobian[:, :, i - n_photo - n_point]
        np.testing.assert_allclose(analytic, num[rows], rtol=1e-6,
                                   atol=1e-6 * np.max(np.abs(num[rows])))  # fmt: skip


def test_c_alone_divides_the_corrected_observations_residuals_by_its_scale() -> None:
    """With c alone Δ = -(x/c) dc is linear: ``x - (x_obs + Δ(x_obs)) = (1 -
    dc/c)(x̂ - x_obs)`` exactly, so the rows are the former ones divided by
    ``1 - dc/c`` (the scaling that pulled c, docs/bundle.md)."""
    obs, centres, rotations, points = _network()
    model = CameraModel("brown", ("c",), C)
    prob = adjust._make_problem(
        obs, centres, rotations, points, None, None, None, None, None, None, camera=model
    )
    dc = np.array([0.4])
    normals = adjust._normals(prob, adjust._State(centres, rotations, points, dc))
    assert normals is not None
    xy, _ = project(centres, rotations, points, prob.photo, prob.point, C)
    former = xy - (prob.xy + model.correction(prob.xy, dc))
    np.testing.assert_allclose(normals.residuals_mm, former / (1.0 - dc[0] / C), rtol=1e-9,
                               atol=1e-14)  # fmt: skip
    np.testing.assert_allclose(normals.image.border_jacobian[:, :, 0],
                               (prob.xy + normals.residuals_mm) / C / (1.0 - dc[0] / C)
                               / prob.sigma[:, None], rtol=1e-12)  # fmt: skip


def test_a_camera_at_zero_gives_the_plain_rows_to_the_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    """A refinement without a camera never maps (the plain path is as
    before); a camera at zero values maps by the identity: its photo and point
    rows and its residuals are the plain ones to the bit."""
    obs, centres, rotations, points = _network()
    plain = adjust._make_problem(
        obs, centres, rotations, points, None, None, None, None, None, None
    )
    camera = adjust._make_problem(
        obs, centres, rotations, points, None, None, None, None, None, None,
        camera=CameraModel("brown", BROWN_PARAMETERS, C),
    )  # fmt: skip

    def refused(*args: object) -> object:
        raise AssertionError("a plain refinement mapped its residuals")

    monkeypatch.setattr(adjust, "observation_space", refused)
    rows_plain = adjust._normals(plain, adjust._State(centres, rotations, points))
    monkeypatch.undo()
    rows_camera = adjust._normals(camera, adjust._State(centres, rotations, points, np.zeros(10)))
    assert rows_plain is not None and rows_camera is not None
    xy, _ = project(centres, rotations, points, plain.photo, plain.point, C)
    np.testing.assert_array_equal(rows_plain.residuals_mm, xy - plain.xy)
    a, b = rows_plain.image, rows_camera.image
    np.testing.assert_array_equal(a.unit_jacobian, b.unit_jacobian)
    np.testing.assert_array_equal(a.point_jacobian, b.point_jacobian)
    np.testing.assert_array_equal(a.residual, b.residual)


def test_without_a_shutter_nothing_of_the_readout_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """A plain refinement and a self-calibration without a rolling shutter
    never project at rows nor pass a readout to the sweeps: their arithmetic
    is as it was (the outputs byte-identical)."""
    obs, centres, rotations, points = _network()

    def refused(*args: object, **kwargs: object) -> object:
        raise AssertionError("a refinement without a shutter read rows")

    sweeps = space.observation_space

    def no_readout(*args: Any, **kwargs: Any) -> space.ObservationSpace:
        readout = args[4] if len(args) > 4 else kwargs.get("readout")
        assert readout is None, "a readout passed without a shutter"
        return sweeps(*args, **kwargs)

    monkeypatch.setattr(adjust, "moving_space", refused)
    monkeypatch.setattr(adjust, "observation_space", no_readout)
    for camera in (None, CameraModel("brown", BROWN_PARAMETERS, C)):
        prob = adjust._make_problem(
            obs, centres, rotations, points, None, None, None, None, None, None, camera=camera
        )
        values = np.zeros(0) if camera is None else THETA
        assert adjust._normals(prob, adjust._State(centres, rotations, points, values)) is not None
