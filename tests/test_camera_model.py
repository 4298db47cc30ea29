"""The camera model of self-calibration: corrections and their partial derivatives."""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.geometry.camera_model import (
    BROWN_PARAMETERS,
    EBNER_PARAMETERS,
    CameraModel,
    brown_correction,
    brown_partials,
    brown_xy_partials,
    ebner_correction,
    ebner_partials,
    ebner_xy_partials,
)
from strip_aerotri.interior import BrownDistortion, distortion_shift, flight_from_sensor

C = 4.5
#: a plausible drone camera's increments (mm, mm^-2, ...)
BROWN = np.array([0.02, 0.01, -0.015, -3e-3, 2e-4, -5e-6, 4e-4, -3e-4, 2e-4, -1e-4])
EBNER = np.array([1e-4, -2e-4, 3e-6, -1e-6, 2e-6, 1e-6, 1e-8, -2e-8, 3e-8, 1e-8, 2e-10, -1e-10])


def _points(n: int = 40, half: float = 3.0, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-half, half, (n, 2))


def _numeric(f, x0: np.ndarray, h: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Central differences of f (returning (K, 2)) w.r.t. each entry of x0."""
    cols = []
    for i in range(x0.size):
        e = np.zeros_like(x0)
        e[i] = h * max(1.0, abs(x0[i]))
        cols.append((f(x0 + e) - f(x0 - e)) / (2.0 * e[i]))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("j", range(10))
def test_brown_partials_match_finite_differences(j: int) -> None:
    xy = _points()
    analytic = brown_partials(xy, BROWN, C)[:, :, j]
    step = 1e-6 * max(1.0, abs(BROWN[j]))
    e = np.zeros(10)
    e[j] = step
    ahead, behind = brown_correction(xy, BROWN + e, C), brown_correction(xy, BROWN - e, C)
    numeric = (ahead - behind) / (2 * step)
    scale = np.max(np.abs(analytic)) + 1e-12
    assert np.max(np.abs(analytic - numeric)) < 1e-7 * scale, BROWN_PARAMETERS[j]


def test_brown_xy_partials_match_finite_differences() -> None:
    xy = _points()
    analytic = brown_xy_partials(xy, BROWN, C)
    h = 1e-6
    for axis in range(2):
        e = np.zeros(2)
        e[axis] = h
        ahead, behind = brown_correction(xy + e, BROWN, C), brown_correction(xy - e, BROWN, C)
        numeric = (ahead - behind) / (2 * h)
        assert np.allclose(analytic[:, :, axis], numeric, atol=1e-9)


@pytest.mark.parametrize("j", range(12))
def test_ebner_partials_match_finite_differences(j: int) -> None:
    xy = _points(half=100.0)
    analytic = ebner_partials(xy, 92.0)[:, :, j]
    e = np.zeros(12)
    e[j] = 1e-3 * max(1e-9, abs(EBNER[j]))
    numeric = (ebner_correction(xy, EBNER + e, 92.0) - ebner_correction(xy, EBNER - e, 92.0)) / (
        2 * e[j]
    )
    assert np.allclose(analytic, numeric, rtol=1e-6, atol=1e-9 * np.max(np.abs(analytic))), (
        EBNER_PARAMETERS[j]
    )


def test_ebner_xy_partials_match_finite_differences() -> None:
    xy = _points(half=100.0)
    analytic = ebner_xy_partials(xy, EBNER, 92.0)
    h = 1e-4
    for axis in range(2):
        e = np.zeros(2)
        e[axis] = h
        ahead = ebner_correction(xy + e, EBNER, 92.0)
        behind = ebner_correction(xy - e, EBNER, 92.0)
        numeric = (ahead - behind) / (2 * h)
        assert np.allclose(analytic[:, :, axis], numeric, rtol=1e-6, atol=1e-10)


def test_ebner_fields_are_orthogonal_over_the_grid() -> None:
    """Ebner's defining property: over the 3 x 3 grid of spacing b the twelve
    correction fields are mutually orthogonal (and none is zero)."""
    b = 92.0
    g = np.array([[x, y] for x in (-b, 0.0, b) for y in (-b, 0.0, b)])
    design = np.swapaxes(ebner_partials(g, b), 1, 2).reshape(9, 12, 2)
    design = np.transpose(design, (0, 2, 1)).reshape(18, 12)
    gram = design.T @ design
    off = gram - np.diag(np.diag(gram))
    assert np.all(np.diag(gram) > 0.0)
    assert np.max(np.abs(off)) < 1e-9 * np.max(np.diag(gram))


def test_zero_parameters_give_zero_correction() -> None:
    xy = _points()
    assert np.array_equal(brown_correction(xy, np.zeros(10), C), np.zeros_like(xy))
    assert np.array_equal(ebner_correction(xy, np.zeros(12), 92.0), np.zeros_like(xy))
    model = CameraModel("brown", BROWN_PARAMETERS, C, flight_matrix=np.array([[0.0, 1], [-1, 0]]))
    assert np.array_equal(model.correction(xy, np.zeros(10)), np.zeros_like(xy))


def test_radial_and_decentring_agree_with_the_distortion_table() -> None:
    """With only k1..p2, the correction is interior.py's [distortion] shift
    (units "mm", model "correction"): the same polynomials."""
    xy = _points()
    v = np.zeros(10)
    v[3:8] = BROWN[3:8]
    d = BrownDistortion(k1=v[3], k2=v[4], k3=v[5], p1=v[6], p2=v[7])
    assert np.allclose(brown_correction(xy, v, C), distortion_shift(xy, d, C), atol=1e-15)


def test_principal_distance_and_point_act_as_stated() -> None:
    """dc scales the reduced coordinates by -dc/c; x0, y0 shift them by -x0, -y0."""
    xy = _points()
    v = np.zeros(10)
    v[0] = 0.05
    assert np.allclose(brown_correction(xy, v, C), -xy * 0.05 / C)
    v = np.zeros(10)
    v[1:3] = [0.01, -0.02]
    assert np.allclose(brown_correction(xy, v, C), -np.array([0.01, -0.02]))


def test_flight_axes_turn_corrections_and_partials() -> None:
    """In flight axes "+y" the correction is the sensor's turned the same way."""
    turn = np.array([[0.0, 1.0], [-1.0, 0.0]])  # flight_from_sensor "+y"
    sensor = _points()
    flight = flight_from_sensor(sensor, "+y")
    model = CameraModel("brown", BROWN_PARAMETERS, C, flight_matrix=turn)
    expect = flight_from_sensor(brown_correction(sensor, BROWN, C), "+y")
    assert np.allclose(model.correction(flight, BROWN), expect)
    numeric = _numeric(lambda v: model.correction(flight, v), BROWN, 1e-6)
    assert np.allclose(model.partials(flight, BROWN), numeric, rtol=1e-6, atol=1e-9)
    h = 1e-6
    for axis in range(2):
        e = np.zeros(2)
        e[axis] = h
        num = (model.correction(flight + e, BROWN) - model.correction(flight - e, BROWN)) / (2 * h)
        assert np.allclose(model.xy_partials(flight, BROWN)[:, :, axis], num, atol=1e-9)


def test_subset_columns_and_errors() -> None:
    model = CameraModel("brown", ("k2", "k1", "b1"), C)
    assert model.estimated == ("k1", "k2", "b1")
    xy = _points()
    full = brown_partials(xy, np.zeros(10), C)
    assert np.array_equal(model.partials(xy, np.zeros(3)), full[:, :, [3, 4, 8]])
    with pytest.raises(ValueError, match="Unknown brown parameter"):
        CameraModel("brown", ("k9",), C)
    with pytest.raises(ValueError, match="grid spacing"):
        CameraModel("ebner", EBNER_PARAMETERS, 152.0)


@pytest.mark.parametrize("family", ["brown", "ebner"])
def test_correction_and_xy_partials_at_once_equal_each_alone(family: str) -> None:
    """The shared evaluation gives correction and xy_partials to the bit, in
    turned flight axes too; xy_partials is M ∂Δ/∂s Mᵀ of the sensor's."""
    turn = np.array([[0.0, 1.0], [-1.0, 0.0]])
    flight = flight_from_sensor(_points(), "+y")
    names, values = (BROWN_PARAMETERS, BROWN) if family == "brown" else (EBNER_PARAMETERS, EBNER)
    model = CameraModel(family, names, C if family == "brown" else 152.0, base_mm=92.0,
                        flight_matrix=turn)  # fmt: skip
    delta, d_xy = model.correction_and_xy_partials(flight, values)
    np.testing.assert_array_equal(delta, model.correction(flight, values))
    np.testing.assert_array_equal(d_xy, model.xy_partials(flight, values))
    sensor = flight @ turn
    own = brown_xy_partials(sensor, values, C) if family == "brown" else ebner_xy_partials(
        sensor, values, 92.0
    )
    np.testing.assert_allclose(d_xy, turn @ own @ turn.T, rtol=1e-15, atol=1e-18)
